//! GLSL → SPIR-V with shaderc (Vulkan 1.2 / SPIR-V 1.5, no optimization: the driver must see
//! the shape the cell asks for); sources with GL_EXT_descriptor_heap, which shaderc's glslang
//! predates, go to an external glslangValidator ([`super::glslang`]). Each distinct source is
//! compiled once per process.
use super::Role;
use std::collections::HashMap;
use std::hash::{Hash, Hasher};
use std::sync::Arc;
use std::time::Instant;

#[derive(Debug, thiserror::Error)]
pub enum CompileError {
    #[error("shaderc could not be initialised")]
    Init,
    #[error("{file}: {message}")]
    Glsl { file: String, message: String },
}

pub struct Compiler {
    inner: shaderc::Compiler,
    cache: HashMap<u64, Arc<Vec<u32>>>,
}

pub fn source_hash(role: Role, glsl: &str) -> u64 {
    let mut h = std::collections::hash_map::DefaultHasher::new();
    role.hash(&mut h);
    glsl.hash(&mut h);
    h.finish()
}

impl Compiler {
    pub fn new() -> Result<Self, CompileError> {
        Ok(Self { inner: shaderc::Compiler::new().map_err(|_| CompileError::Init)?, cache: HashMap::new() })
    }

    /// SPIR-V words for `glsl`, and the milliseconds spent compiling (0 when cached).
    pub fn compile(&mut self, role: Role, glsl: &str) -> Result<(Arc<Vec<u32>>, f64), CompileError> {
        let key = source_hash(role, glsl);
        if let Some(s) = self.cache.get(&key) {
            return Ok((s.clone(), 0.0));
        }
        let t = Instant::now();
        let heap = glsl.contains(&format!("#extension {} ", super::glslang::HEAP_EXTENSION));
        let words = Arc::new(if heap { super::glslang::compile(role, glsl)? } else { self.compile_glsl(role.kind(), role.file_name(), glsl)? });
        self.cache.insert(key, words.clone());
        Ok((words, t.elapsed().as_secs_f64() * 1e3))
    }

    /// Compile one GLSL source (uncached).
    pub fn compile_glsl(&mut self, kind: shaderc::ShaderKind, file: &str, glsl: &str) -> Result<Vec<u32>, CompileError> {
        let mut opts = shaderc::CompileOptions::new().map_err(|_| CompileError::Init)?;
        opts.set_target_env(shaderc::TargetEnv::Vulkan, shaderc::EnvVersion::Vulkan1_2 as u32);
        opts.set_target_spirv(shaderc::SpirvVersion::V1_5);
        let out = self
            .inner
            .compile_into_spirv(glsl, kind, file, "main", Some(&opts))
            .map_err(|e| CompileError::Glsl { file: file.to_string(), message: e.to_string().replace('\n', " | ") })?;
        Ok(out.as_binary().to_vec())
    }
}
