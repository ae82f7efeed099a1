//! What a worker says, shared by its main loop (`runner::worker`) and its prebuild
//! (`runner::overlap`, `runner::held`): each message as one JSON line on stdout ([`send`]), an
//! overlapped cell's phase as a prebuild step ([`send_overlapped`]), and what of an error no
//! worker can get past ([`halt_of`]).
use super::protocol::WorkerMsg;
use crate::exec::CellError;
use crate::model::{Halt, Phase};
use crate::shadergen::compile::CompileError;
use std::io::Write;

/// One message, one line, flushed at once (the supervisor's deadlines read it as it comes).
pub(super) fn send(msg: &WorkerMsg) {
    let mut out = std::io::stdout().lock();
    let _ = serde_json::to_writer(&mut out, msg);
    let _ = out.write_all(b"\n");
    let _ = out.flush();
}

/// An overlapped cell (`runner::overlap`) entering `phase`: a `prebuild` step naming the cell,
/// which the supervisor blames a death during the prebuild on.
pub(super) fn send_overlapped(cell: &str, phase: Phase) {
    let step = super::protocol::overlapped_step(cell, phase);
    send(&WorkerMsg::Phase { phase: Phase::Prebuild, step: Some(step) });
}

/// What of `e` no worker can get past: the shader compiler not starting, in setup or on a
/// prebuild thread alike.
pub(super) fn halt_of(e: &CellError) -> Option<Halt> {
    match e {
        CellError::Compile(CompileError::Init) => Some(Halt::NoShaderCompiler),
        _ => None,
    }
}
