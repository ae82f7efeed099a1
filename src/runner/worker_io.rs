//! What a worker says, shared by its main loop (`runner::worker`) and its prebuild
//! (`runner::overlap`): each message as one JSON line on stdout ([`send`]), and what of an error
//! no worker can get past ([`halt_of`]).
use super::protocol::WorkerMsg;
use crate::exec::CellError;
use crate::model::Halt;
use crate::shadergen::compile::CompileError;
use std::io::Write;

/// One message, one line, flushed at once (the supervisor's deadlines read it as it comes).
pub(super) fn send(msg: &WorkerMsg) {
    let mut out = std::io::stdout().lock();
    let _ = serde_json::to_writer(&mut out, msg);
    let _ = out.write_all(b"\n");
    let _ = out.flush();
}

/// What of `e` no worker can get past: the shader compiler not starting, in setup or on a
/// prebuild thread alike.
pub(super) fn halt_of(e: &CellError) -> Option<Halt> {
    match e {
        CellError::Compile(CompileError::Init) => Some(Halt::NoShaderCompiler),
        _ => None,
    }
}
