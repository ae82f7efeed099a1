//! GLSL → SPIR-V with shaderc (Vulkan 1.2 / SPIR-V 1.5, no optimization: the driver must see
//! the shape the cell asks for); sources with GL_EXT_descriptor_heap, which shaderc's glslang
//! predates, go to an external glslangValidator ([`super::glslang`]). Each distinct source is
//! compiled once per process. User GLSL (`patch --glsl`) may pick another target and use
//! `#include` ([`super::include`]) and defines.
use super::include::Includes;
use super::Role;
use std::collections::HashMap;
use std::hash::{Hash, Hasher};
use std::path::PathBuf;
use std::sync::Arc;
use std::time::Instant;

pub use super::error::CompileError;

pub struct Compiler {
    inner: shaderc::Compiler,
    cache: HashMap<u64, Arc<Vec<u32>>>,
    /// Milliseconds [`Compiler::precompile`] spent on a cached source, handed to the first
    /// [`Compiler::compile`] that takes it (so that cell's timings still show its compile).
    precompiled_ms: HashMap<u64, f64>,
}

/// The shaderc this binary links (the `shaderc` crate built from source, with the glslang of that
/// release); a test holds it to Cargo.lock.
pub const SHADERC: &str = "shaderc-rs 0.10.1 (shaderc built from source)";

/// Whether `glsl` needs the external glslangValidator (it enables GL_EXT_descriptor_heap).
pub fn uses_heap(glsl: &str) -> bool {
    glsl.contains(&format!("#extension {} ", super::glslang::HEAP_EXTENSION))
}

/// The compiler [`Compiler::compile`] uses for `glsl`, with its version.
pub fn compiler_for(glsl: &str) -> String {
    if !uses_heap(glsl) {
        return SHADERC.into();
    }
    match super::glslang::find() {
        Some(g) => g.describe(),
        None => "glslangValidator (not found here)".into(),
    }
}

pub fn source_hash(role: Role, glsl: &str) -> u64 {
    let mut h = std::collections::hash_map::DefaultHasher::new();
    role.hash(&mut h);
    glsl.hash(&mut h);
    h.finish()
}

impl Compiler {
    pub fn new() -> Result<Self, CompileError> {
        Ok(Self {
            inner: shaderc::Compiler::new().map_err(|_| CompileError::Init)?,
            cache: HashMap::new(),
            precompiled_ms: HashMap::new(),
        })
    }

    /// Compile the uncached shaderc sources among `sources` on `threads` threads (one shaderc
    /// compiler each: a compiler is not shared between threads) into the cache. A source that
    /// fails is left out: [`Compiler::compile`] meets the same error at the cell's turn and
    /// reports it there. Sources for the external glslangValidator are left to `compile`.
    /// `progress(k, n)` is called as each source is done.
    pub fn precompile(
        &mut self,
        sources: &[(Role, &str)],
        threads: usize,
        progress: &(dyn Fn(usize, usize) + Sync),
    ) {
        let mut seen = std::collections::HashSet::new();
        let todo: Vec<(u64, Role, &str)> = sources
            .iter()
            .map(|&(role, glsl)| (source_hash(role, glsl), role, glsl))
            .filter(|&(key, _, glsl)| {
                !uses_heap(glsl) && !self.cache.contains_key(&key) && seen.insert(key)
            })
            .collect();
        if todo.is_empty() {
            return;
        }
        let compiled = crate::pool::map(
            todo.len(),
            threads,
            || Compiler::new().ok(),
            |c, i| {
                let (_, role, glsl) = todo[i];
                let t = Instant::now();
                c.compile_glsl(role.kind(), role.file_name(), glsl)
                    .ok()
                    .map(|words| (words, t.elapsed().as_secs_f64() * 1e3))
            },
            progress,
        );
        for (&(key, _, _), (words, ms)) in
            todo.iter().zip(compiled).filter_map(|(t, c)| Some(t).zip(c.flatten()))
        {
            self.cache.insert(key, Arc::new(words));
            self.precompiled_ms.insert(key, ms);
        }
    }

    /// SPIR-V words for `glsl`, and the milliseconds spent compiling (0 when cached).
    pub fn compile(
        &mut self,
        role: Role,
        glsl: &str,
    ) -> Result<(Arc<Vec<u32>>, f64), CompileError> {
        let key = source_hash(role, glsl);
        if let Some(s) = self.cache.get(&key) {
            return Ok((s.clone(), self.precompiled_ms.remove(&key).unwrap_or(0.0)));
        }
        let t = Instant::now();
        let words = Arc::new(if uses_heap(glsl) {
            super::glslang::compile(role, glsl)?
        } else {
            self.compile_glsl(role.kind(), role.file_name(), glsl)?
        });
        self.cache.insert(key, words.clone());
        Ok((words, t.elapsed().as_secs_f64() * 1e3))
    }

    /// Compile one generated GLSL source (uncached; Vulkan 1.2, no includes or defines).
    pub fn compile_glsl(
        &mut self,
        kind: shaderc::ShaderKind,
        file: &str,
        glsl: &str,
    ) -> Result<Vec<u32>, CompileError> {
        self.compile_user_glsl(kind, file, glsl, &GlslOptions::default())
    }

    /// Compile GLSL with `#include` resolution, macro definitions and a target environment
    /// (`rtprobe patch`). Errors are one line, each naming its file, line and include chain. A
    /// missing or too old `#version` is refused before the compiler sees it
    /// ([`super::preflight`]); a source enabling an extension the bundled glslang does not know
    /// goes, when it is a file (`o.input`), to the newest glslangValidator here.
    pub fn compile_user_glsl(
        &mut self,
        kind: shaderc::ShaderKind,
        file: &str,
        glsl: &str,
        o: &GlslOptions,
    ) -> Result<Vec<u32>, CompileError> {
        if let Some(why) = super::preflight::version_problem(kind, glsl) {
            return Err(CompileError::Glsl { file: file.to_string(), message: why });
        }
        let includes =
            o.input.as_ref().map(|input| Includes::new(input, file, glsl, &o.include_dirs));
        let mut opts = shaderc::CompileOptions::new().map_err(|_| CompileError::Init)?;
        let (env, spirv) = o.target.versions();
        opts.set_target_env(shaderc::TargetEnv::Vulkan, env as u32);
        opts.set_target_spirv(spirv);
        for (name, value) in &o.defines {
            opts.add_macro_definition(name, value.as_deref());
        }
        if let Some(inc) = &includes {
            opts.set_include_callback(move |req, ty, from, depth| {
                inc.resolve(req, ty, from, depth)
            });
        }
        let out = self.inner.compile_into_spirv(glsl, kind, file, "main", Some(&opts));
        let e = match out {
            Ok(a) => return Ok(a.as_binary().to_vec()),
            Err(e) => e,
        };
        let message = match &includes {
            Some(inc) => inc.annotate(&e.to_string()),
            None => e.to_string().replace('\n', " | "),
        };
        match (super::preflight::unknown_extension(&message), &o.input) {
            (Some(ext), Some(input)) => external(kind, input, o, &ext),
            _ => Err(CompileError::Glsl { file: file.to_string(), message }),
        }
    }
}

/// Compile the file `input` with the newest glslangValidator, for the extension `ext` the bundled
/// compiler does not know; when it knows it neither (or there is none), one line saying so and
/// where a newer one is (the sid root of `scripts/setup-sid`).
fn external(
    kind: shaderc::ShaderKind,
    input: &std::path::Path,
    o: &GlslOptions,
    ext: &str,
) -> Result<Vec<u32>, CompileError> {
    let file = super::include::display(input);
    let hint = match crate::tools::sid_root() {
        Some(root) => format!("the sid root at {} has none newer", root.display()),
        None => "no sid root here (RTPROBE_SID_ROOT, default /var/lib/rtprobe/sid-root): \
                 scripts/setup-sid makes one with glslang 16.6"
            .into(),
    };
    let unknown = |by: String| CompileError::Glsl {
        file: file.clone(),
        message: format!("{ext} is not known to {by}; {hint}"),
    };
    let Some(g) = crate::tools::glslang() else {
        return Err(unknown(format!(
            "the bundled compiler ({SHADERC}) and no glslangValidator is installed"
        )));
    };
    let stage = super::glslang::stage_name(kind)
        .ok_or_else(|| unknown(format!("the bundled compiler ({SHADERC})")))?;
    super::glslang::compile_file(g, stage, input, &o.glslang_args()).map_err(|e| match e {
        CompileError::Glsl { message, .. }
            if message.contains(&format!("extension not supported: {ext}")) =>
        {
            unknown(format!("the bundled compiler ({SHADERC}) nor to {}", g.describe()))
        }
        e => e,
    })
}

/// The Vulkan environment GLSL is compiled for (`--target-env`'s names and help are in
/// `cli::values`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum TargetEnv {
    /// Vulkan 1.2, SPIR-V 1.5 (what rtprobe's own shaders use).
    #[default]
    Vulkan1_2,
    /// Vulkan 1.3, SPIR-V 1.6.
    Vulkan1_3,
    /// Vulkan 1.4, SPIR-V 1.6.
    Vulkan1_4,
}

impl TargetEnv {
    /// glslangValidator's `--target-env` name.
    pub fn name(self) -> &'static str {
        match self {
            TargetEnv::Vulkan1_2 => "vulkan1.2",
            TargetEnv::Vulkan1_3 => "vulkan1.3",
            TargetEnv::Vulkan1_4 => "vulkan1.4",
        }
    }

    fn versions(self) -> (shaderc::EnvVersion, shaderc::SpirvVersion) {
        match self {
            TargetEnv::Vulkan1_2 => (shaderc::EnvVersion::Vulkan1_2, shaderc::SpirvVersion::V1_5),
            TargetEnv::Vulkan1_3 => (shaderc::EnvVersion::Vulkan1_3, shaderc::SpirvVersion::V1_6),
            TargetEnv::Vulkan1_4 => (shaderc::EnvVersion::Vulkan1_4, shaderc::SpirvVersion::V1_6),
        }
    }
}

/// How user GLSL is compiled.
#[derive(Clone, Debug, Default)]
pub struct GlslOptions {
    /// The input file: with it, `#include` is resolved from its directory, then `include_dirs`.
    pub input: Option<PathBuf>,
    pub include_dirs: Vec<PathBuf>,
    /// `-D NAME[=VALUE]`.
    pub defines: Vec<(String, Option<String>)>,
    pub target: TargetEnv,
}

impl GlslOptions {
    /// The same options as glslangValidator arguments: target, the input's directory and each
    /// `-I` (glslang searches the including file's directory first, as [`Includes`] does), `-D`.
    pub fn glslang_args(&self) -> Vec<String> {
        let mut a = vec!["--target-env".to_string(), self.target.name().to_string()];
        let own =
            self.input.as_ref().and_then(|i| i.parent()).filter(|p| !p.as_os_str().is_empty());
        for d in own.into_iter().chain(self.include_dirs.iter().map(|d| d.as_path())) {
            a.push(format!("-I{}", d.display()));
        }
        for (name, value) in &self.defines {
            a.push(match value {
                Some(v) => format!("-D{name}={v}"),
                None => format!("-D{name}"),
            });
        }
        a
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_shaderc_named_is_the_one_cargo_locked() {
        let lock = include_str!("../../Cargo.lock");
        let at = lock.find("name = \"shaderc\"\nversion = \"").expect("shaderc in Cargo.lock");
        let version =
            lock[at..].lines().nth(1).unwrap().trim_start_matches("version = ").trim_matches('"');
        assert!(SHADERC.contains(&format!(" {version} ")), "{SHADERC} vs Cargo.lock {version}");
    }

    #[test]
    fn heap_sources_name_glslang() {
        assert_eq!(compiler_for("#version 460\nvoid main() {}\n"), SHADERC);
        assert!(compiler_for("#version 460\n#extension GL_EXT_descriptor_heap : require\n")
            .starts_with("glslangValidator"));
    }
}
