//! What compiling a probe's GLSL can fail with, whichever compiler ran (shaderc in-process, or
//! the external glslangValidator for descriptor-heap GLSL).

#[derive(Debug, thiserror::Error)]
pub enum CompileError {
    /// `shaderc::Compiler::new` failed: no GLSL can be compiled in this process (exit code 12
    /// where the CLI meets it, `cli::exit::NO_SHADER_COMPILER`).
    #[error("the shader compiler (shaderc) could not be started")]
    Init,
    #[error("{file}: {message}")]
    Glsl { file: String, message: String },
}
