//! What compiling a probe's GLSL can fail with, whichever compiler ran (shaderc in-process, or
//! the external glslangValidator for descriptor-heap GLSL).

#[derive(Debug, thiserror::Error)]
pub enum CompileError {
    #[error("shaderc could not be initialised")]
    Init,
    #[error("{file}: {message}")]
    Glsl { file: String, message: String },
}
