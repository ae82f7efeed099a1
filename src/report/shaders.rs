//! A cell's shaders as a reader gets them (issue and repro bundle): the GLSL rtprobe generates
//! (with the injected fault, when one applies), the SPIR-V the worker runs (compiled by shaderc,
//! then patched exactly as the worker patches it), and `spirv-dis` disassembly when installed.
use crate::model::FaultKind;
use crate::model::{Cell, Stage};
use crate::shadergen::{self, compile::Compiler, Role};

#[derive(Debug, thiserror::Error)]
pub enum ShaderError {
    #[error("compiling: {0}")]
    Compile(#[from] crate::shadergen::compile::CompileError),
    #[error("patching: {0}")]
    Patch(#[from] crate::patches::PatchError),
}

pub struct Shader {
    pub role: Role,
    pub glsl: String,
    pub spirv: Vec<u32>,
    /// What compiled it, with its version ([`crate::shadergen::compile::compiler_for`]).
    pub compiler: String,
    /// The SPIR-V patches applied after compiling, in order.
    pub patched: Vec<&'static str>,
}

/// The role of the shader that does the probed read of `stage`.
pub fn probed_role(stage: Stage) -> Role {
    Role::probed(stage)
}

/// Whether the worker of `report` generated `cell`'s probe with its lane evidence: the run's
/// `--lane-evidence` and the report's device (`model::lanes::device_ballot`).
pub fn lanes_in(report: &crate::model::RunReport, cell: &Cell) -> bool {
    let supported = crate::model::lanes::device_ballot(&report.device, cell.stage);
    cell.canary.is_none() && report.options.lane_evidence.evidence(supported).recorded()
}

/// Every shader of `cell` with `fault` injected and its lane evidence where `lanes`
/// ([`lanes_in`]), as the worker builds them.
pub fn cell_shaders(
    cell: &Cell,
    fault: Option<FaultKind>,
    lanes: bool,
) -> Result<Vec<Shader>, ShaderError> {
    let gen = shadergen::generate_with(cell, fault, lanes);
    let mut compiler = Compiler::new()?;
    let mut out = Vec::new();
    for s in &gen.shaders {
        let (words, _) = compiler.compile(s.role, &s.glsl)?;
        out.push(Shader {
            role: s.role,
            glsl: s.glsl.clone(),
            spirv: words.to_vec(),
            compiler: crate::shadergen::compile::compiler_for(&s.glsl),
            patched: vec![],
        });
    }
    // The worker's order: address_patched is as-to-address on the descriptor variant, then the
    // cell's own workaround.
    for w in crate::patches::workaround::of_cell(cell) {
        for s in out.iter_mut() {
            if let Some(p) = crate::patches::workaround::patch_module(&s.spirv, w)? {
                s.spirv = p;
                s.patched.push(w.as_str());
            }
        }
    }
    Ok(out)
}

/// `spirv-dis` of `words` (the newest of the sid root's and PATH's, `tools::spirv`), or `None`
/// when it is not installed (or fails).
pub fn spirv_dis(words: &[u32]) -> Option<String> {
    crate::tools::spirv::disassemble(words, false).ok()
}

pub fn spirv_bytes(words: &[u32]) -> Vec<u8> {
    words.iter().flat_map(|w| w.to_le_bytes()).collect()
}
