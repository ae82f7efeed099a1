//! GLSL → SPIR-V with shaderc (Vulkan 1.2 / SPIR-V 1.5, no optimization: the driver must see
//! the shape the cell asks for); sources that enable an extension shaderc's glslang predates
//! (GL_EXT_descriptor_heap, ...) go to an external glslangValidator ([`super::glslang`]). Each
//! distinct source is compiled once per process, and kept on disk between runs when the worker
//! has a cache folder ([`super::disk_cache`]: a warm run compiles nothing). User GLSL (`patch --glsl`) may pick another
//! target and use `#include` ([`super::include`]) and defines.
//!
//! shaderc is the system's (shaderc 2023.2 with glslang 12 on Debian 12, linked statically by
//! build.rs) or, with `--features bundled-shaderc`, its own copy built from source; [`SHADERC`]
//! says which. Debian 12's predates Vulkan 1.4: [`TargetEnv::compiled_as`].
use super::disk_cache::{DiskCache, KeyParts, Lookup};
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
    /// Compiles kept between runs (`None`: every source is compiled in this process).
    disk: Option<DiskCache>,
    /// Sources this compiler (and its precompile threads) compiled, not found in a cache.
    pub compiled: usize,
}

/// The shaderc this binary links: the `shaderc` crate over the system's shaderc, glslang and
/// SPIRV-Tools (their versions, from build.rs), or over its own copy built from source
/// (`bundled-shaderc`). Reports and bundles name it; a test holds the crate version to Cargo.lock.
pub const SHADERC: &str = concat!("shaderc-rs 0.10.1 (", env!("RTPROBE_SHADERC_BUILD"), ")");

/// Whether shaderc is the system's (glslang 12 on Debian 12), not the bundled build.
pub const SYSTEM_SHADERC: bool = cfg!(system_shaderc);
/// Whether the linked shaderc knows a Vulkan 1.4 environment (the system's 2023.2 does not).
pub const KNOWS_VULKAN_1_4: bool = !cfg!(shaderc_without_vulkan_1_4);

/// A compile of `glsl` kept in `disk`; a damaged file is said and left to be written again.
fn kept_in(disk: &DiskCache, role: Role, glsl: &str) -> Option<Vec<u32>> {
    let key = disk_key(role, glsl);
    match disk.load(key) {
        Lookup::Hit(words) => Some(words),
        Lookup::Miss => None,
        Lookup::Corrupt(why) => {
            tracing::warn!("{}: {why}; compiled again", disk.path(key).display());
            None
        }
    }
}

/// Whether `glsl` needs the external glslangValidator (it enables an extension of
/// [`super::glslang::EXTENSIONS`], such as GL_EXT_descriptor_heap).
pub fn uses_external(glsl: &str) -> bool {
    super::glslang::needed_by(glsl).is_some()
}

/// The compiler [`Compiler::compile`] uses for `glsl`, with its version.
pub fn compiler_for(glsl: &str) -> String {
    if !uses_external(glsl) {
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

/// The disk cache key of a generated source: no includes, no defines, rtprobe's target, and the
/// compiler that [`Compiler::compile`] picks for it.
pub fn disk_key(role: Role, glsl: &str) -> u128 {
    super::disk_cache::key(&KeyParts {
        kind: &format!("{:?}", role.kind()),
        file: role.file_name(),
        glsl,
        includes: &[],
        defines: &[],
        target: TargetEnv::default().compiled_as().name(),
        compiler: &compiler_for(glsl),
    })
}

impl Compiler {
    pub fn new() -> Result<Self, CompileError> {
        Ok(Self {
            inner: shaderc::Compiler::new().map_err(|_| CompileError::Init)?,
            cache: HashMap::new(),
            precompiled_ms: HashMap::new(),
            disk: None,
            compiled: 0,
        })
    }

    /// Keep compiles of generated GLSL under `cache_dir` (`<cache_dir>/glsl`) and read them back
    /// instead of compiling; `None`: compile afresh (bisect, repro, GPU-AV and mutant workers).
    pub fn use_disk_cache(&mut self, cache_dir: Option<&std::path::Path>) {
        self.disk = cache_dir.map(DiskCache::under);
    }

    /// A kept compile of `glsl`; a damaged file is said and left to be written again.
    fn kept(&self, role: Role, glsl: &str) -> Option<Vec<u32>> {
        kept_in(self.disk.as_ref()?, role, glsl)
    }

    fn to_disk(&self, role: Role, glsl: &str, words: &[u32]) {
        if let Some(disk) = &self.disk {
            if let Err(e) = disk.store(disk_key(role, glsl), words) {
                tracing::warn!("GLSL compile not kept: {e}");
            }
        }
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
        let mut todo: Vec<(u64, Role, &str)> = sources
            .iter()
            .map(|&(role, glsl)| (source_hash(role, glsl), role, glsl))
            .filter(|&(key, _, glsl)| {
                !uses_external(glsl) && !self.cache.contains_key(&key) && seen.insert(key)
            })
            .collect();
        // Those kept on disk are read, not compiled: on the threads too (a warm run's whole
        // precompile is these reads and their checksums, else on the worker's cell thread).
        if let Some(disk) = &self.disk {
            let kept = crate::pool::map(
                todo.len(),
                threads,
                || Some(()),
                |_, i| {
                    let (_, role, glsl) = todo[i];
                    let t = Instant::now();
                    kept_in(disk, role, glsl).map(|w| (w, t.elapsed().as_secs_f64() * 1e3))
                },
                &|_, _| {},
            );
            let mut kept = kept.into_iter();
            todo.retain(|&(key, _, _)| {
                let Some((words, ms)) = kept.next().flatten().flatten() else { return true };
                self.cache.insert(key, Arc::new(words));
                self.precompiled_ms.insert(key, ms);
                false
            });
        }
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
        for (&(key, role, glsl), (words, ms)) in
            todo.iter().zip(compiled).filter_map(|(t, c)| Some(t).zip(c.flatten()))
        {
            self.to_disk(role, glsl, &words);
            self.compiled += 1;
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
        let words = match self.kept(role, glsl) {
            Some(words) => Arc::new(words),
            None => {
                let words = if uses_external(glsl) {
                    super::glslang::compile(role, glsl)?
                } else {
                    self.compile_glsl(role.kind(), role.file_name(), glsl)?
                };
                self.compiled += 1;
                self.to_disk(role, glsl, &words);
                Arc::new(words)
            }
        };
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

    /// Every file a GLSL input is made of, by resolved name with its contents: the root and each
    /// `#include` it reaches under `o` (shaderc's preprocessor resolves them, with `o`'s defines,
    /// so an include under a false `#if` is not one). What the input's identity hashes: an
    /// edited header makes another input. A preprocessor error stops at the files seen so far.
    pub fn input_files(
        &mut self,
        file: &str,
        glsl: &str,
        o: &GlslOptions,
    ) -> Vec<(String, String)> {
        let Some(input) = o.input.as_ref() else {
            return vec![(file.to_string(), glsl.to_string())];
        };
        let inc = Includes::new(input, file, glsl, &o.include_dirs);
        if let Ok(mut opts) = shaderc::CompileOptions::new() {
            for (name, value) in &o.defines {
                opts.add_macro_definition(name, value.as_deref());
            }
            opts.set_include_callback(|req, ty, from, depth| inc.resolve(req, ty, from, depth));
            let _ = self.inner.preprocess(glsl, file, "main", Some(&opts));
        }
        inc.contents()
    }

    /// Compile GLSL with `#include` resolution, macro definitions and a target environment
    /// (`rtprobe patch`). Errors are one line, each naming its file, line and include chain. A
    /// missing or too old `#version` is refused before a compiler sees it
    /// ([`super::preflight`]). A source that enables an extension of
    /// [`super::glslang::EXTENSIONS`] goes to the external glslangValidator with the same target,
    /// include folders and defines; one that enables another extension the glslang in shaderc does
    /// not know goes there too when shaderc refuses it.
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
        if let Some(ext) = super::glslang::needed_by(glsl) {
            return external(kind, file, glsl, o, ext);
        }
        let includes =
            o.input.as_ref().map(|input| Includes::new(input, file, glsl, &o.include_dirs));
        let mut opts = shaderc::CompileOptions::new().map_err(|_| CompileError::Init)?;
        let (env, spirv) = o.target.compiled_as().versions();
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
        match super::preflight::unknown_extension(&message) {
            Some(ext) => external(kind, file, glsl, o, &ext),
            None => Err(CompileError::Glsl { file: file.to_string(), message }),
        }
    }
}

/// Compile `glsl` (named `file`) with the external glslangValidator, for the extension `ext`
/// the glslang in shaderc does not know: the same target, include folders (the input's own
/// first) and defines. When that one does not know it either, one line says so.
fn external(
    kind: shaderc::ShaderKind,
    file: &str,
    glsl: &str,
    o: &GlslOptions,
    ext: &str,
) -> Result<Vec<u32>, CompileError> {
    let args = o.glslang_args();
    let args: Vec<&str> = args.iter().map(String::as_str).collect();
    let stage = super::glslang::stage_of_kind(kind);
    super::glslang::compile_with(file, stage, glsl, ext, &args).map_err(|e| match e {
        CompileError::Glsl { file, message }
            if message.contains(&format!("extension not supported: {ext}")) =>
        {
            let by = super::glslang::find().map(|g| g.describe()).unwrap_or_default();
            let message =
                format!("{ext} is known neither to the glslang in shaderc ({SHADERC}) nor to {by}");
            CompileError::Glsl { file, message }
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
    /// The `--target-env` name (shaderc's and glslangValidator's).
    pub fn name(self) -> &'static str {
        match self {
            TargetEnv::Vulkan1_2 => "vulkan1.2",
            TargetEnv::Vulkan1_3 => "vulkan1.3",
            TargetEnv::Vulkan1_4 => "vulkan1.4",
        }
    }

    /// The environment shaderc is asked for. A system shaderc that predates Vulkan 1.4 (Debian
    /// 12's 2023.2) would silently compile it for its default environment instead; rtprobe asks it for
    /// Vulkan 1.3 with SPIR-V 1.6, the SPIR-V version Vulkan 1.4 also uses, and says so
    /// ([`TargetEnv::mapping_note`]). The bundled shaderc and the external glslangValidator know
    /// Vulkan 1.4.
    pub fn compiled_as(self) -> TargetEnv {
        match self {
            TargetEnv::Vulkan1_4 if !KNOWS_VULKAN_1_4 => TargetEnv::Vulkan1_3,
            t => t,
        }
    }

    /// What [`TargetEnv::compiled_as`] changed, in a sentence for the user; `None` when nothing.
    pub fn mapping_note(self) -> Option<String> {
        let as_ = self.compiled_as();
        (as_ != self).then(|| {
            format!(
                "--target-env {}: compiled for {} (SPIR-V 1.6, as {} uses): the system shaderc \
                 this rtprobe links predates Vulkan 1.4 ({SHADERC}); a build with --features \
                 bundled-shaderc compiles for {} itself",
                self.name(),
                as_.name(),
                self.name(),
                self.name()
            )
        })
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
        let own = self.input.as_ref().and_then(|i| i.parent()).map(|d| {
            if d.as_os_str().is_empty() {
                PathBuf::from(".")
            } else {
                d.to_path_buf()
            }
        });
        for d in own.iter().chain(&self.include_dirs) {
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
        assert!(compiler_for("#extension GL_EXT_shader_invocation_reorder : require\n")
            .starts_with("glslangValidator"));
        assert_eq!(compiler_for("#extension GL_NV_shader_invocation_reorder : require\n"), SHADERC);
    }

    #[test]
    fn vulkan1_4_is_mapped_only_for_a_shaderc_without_it() {
        assert_eq!(SHADERC.contains("system shaderc"), SYSTEM_SHADERC, "{SHADERC}");
        const { assert!(KNOWS_VULKAN_1_4 || SYSTEM_SHADERC, "the bundled shaderc knows Vulkan 1.4") };
        for t in [TargetEnv::Vulkan1_2, TargetEnv::Vulkan1_3] {
            assert_eq!((t.compiled_as(), t.mapping_note()), (t, None));
        }
        let t = TargetEnv::Vulkan1_4;
        if !KNOWS_VULKAN_1_4 {
            assert_eq!(t.compiled_as(), TargetEnv::Vulkan1_3);
            let note = t.mapping_note().unwrap();
            assert!(note.contains("compiled for vulkan1.3") && note.contains("glslang "), "{note}");
        } else {
            assert_eq!((t.compiled_as(), t.mapping_note()), (t, None));
        }
    }

    /// A miss shader as an engine writes one: a payload struct, a sky gradient.
    const SKY_MISS: &str = "#version 460\n#extension GL_EXT_ray_tracing : require\n\
        struct HitPayload { vec3 radiance; float hitT; uint flags; };\n\
        layout(location = 0) rayPayloadInEXT HitPayload payload;\n\
        void main() {\n  vec3 d = normalize(gl_WorldRayDirectionEXT);\n\
          float t = 0.5 * (d.y + 1.0);\n\
          payload.radiance = mix(vec3(1.0), vec3(0.5, 0.7, 1.0), t);\n\
          payload.hitT = -1.0;\n  payload.flags |= 1u;\n}\n";

    /// A second compiler over the same cache folder (a warm run's worker) compiles nothing and
    /// gets the same SPIR-V, in `compile` and in `precompile`. Its twins: garbage planted in the
    /// cache file is detected and compiled again (and the file repaired), and a compiler without
    /// the folder (a mutant's or bisect's worker) compiles though the file is there.
    #[test]
    fn a_warm_compiler_reads_kept_compiles_and_recompiles_garbage() {
        let d = crate::tempdir::tempdir().unwrap();
        let mut cold = Compiler::new().unwrap();
        cold.use_disk_cache(Some(d.path()));
        let (words, _) = cold.compile(Role::Miss, SKY_MISS).unwrap();
        assert_eq!(cold.compiled, 1);
        let file = DiskCache::under(d.path()).path(disk_key(Role::Miss, SKY_MISS));
        assert!(file.exists());

        let mut warm = Compiler::new().unwrap();
        warm.use_disk_cache(Some(d.path()));
        assert_eq!(warm.compile(Role::Miss, SKY_MISS).unwrap().0, words);
        let mut warm2 = Compiler::new().unwrap();
        warm2.use_disk_cache(Some(d.path()));
        warm2.precompile(&[(Role::Miss, SKY_MISS)], 2, &|_, _| {});
        assert_eq!(warm2.compile(Role::Miss, SKY_MISS).unwrap().0, words);
        assert_eq!((warm.compiled, warm2.compiled), (0, 0), "a warm run compiles nothing");

        // Garbage in the file: compiled again, the same SPIR-V, and the file is good again.
        let mut bytes = std::fs::read(&file).unwrap();
        let n = bytes.len();
        bytes[n - 8..].copy_from_slice(b"garbage!");
        std::fs::write(&file, &bytes).unwrap();
        for pre in [false, true] {
            let mut c = Compiler::new().unwrap();
            c.use_disk_cache(Some(d.path()));
            if pre {
                std::fs::write(&file, b"not a cache file at all").unwrap();
                c.precompile(&[(Role::Miss, SKY_MISS)], 2, &|_, _| {});
            }
            assert_eq!(c.compile(Role::Miss, SKY_MISS).unwrap().0, words);
            assert_eq!(c.compiled, 1, "the damaged file was compiled again (precompile: {pre})");
        }
        let mut again = Compiler::new().unwrap();
        again.use_disk_cache(Some(d.path()));
        again.compile(Role::Miss, SKY_MISS).unwrap();
        assert_eq!(again.compiled, 0, "the file was written again");

        let mut fresh = Compiler::new().unwrap();
        fresh.use_disk_cache(None);
        assert_eq!(fresh.compile(Role::Miss, SKY_MISS).unwrap().0, words);
        assert_eq!(fresh.compiled, 1, "no folder: compiled afresh");
    }

    /// The precompile reads kept compiles on its threads: each source gets its own file's
    /// SPIR-V whatever thread read it, and only the missing and the damaged ones are compiled.
    #[test]
    fn kept_compiles_read_on_threads_go_to_their_own_sources() {
        let d = crate::tempdir::tempdir().unwrap();
        let skies: Vec<String> =
            (0..7).map(|k| SKY_MISS.replace("0.5, 0.7", &format!("0.{k}, 0.7"))).collect();
        let mut cold = Compiler::new().unwrap();
        cold.use_disk_cache(Some(d.path()));
        let want: Vec<_> = skies.iter().map(|g| cold.compile(Role::Miss, g).unwrap().0).collect();
        assert!(want.windows(2).all(|w| w[0] != w[1]), "distinct sources, distinct SPIR-V");
        // Two files gone, one damaged: those three are compiled, the other four read.
        let file = |g: &str| DiskCache::under(d.path()).path(disk_key(Role::Miss, g));
        std::fs::remove_file(file(&skies[1])).unwrap();
        std::fs::remove_file(file(&skies[4])).unwrap();
        std::fs::write(file(&skies[6]), b"garbage").unwrap();
        let mut warm = Compiler::new().unwrap();
        warm.use_disk_cache(Some(d.path()));
        let sources: Vec<(Role, &str)> = skies.iter().map(|g| (Role::Miss, g.as_str())).collect();
        warm.precompile(&sources, 3, &|_, _| {});
        assert_eq!(warm.compiled, 3, "only the missing and damaged sources compiled");
        for (g, w) in skies.iter().zip(&want) {
            assert_eq!(&warm.compile(Role::Miss, g).unwrap().0, w);
        }
        assert_eq!(warm.compiled, 3, "every source was ready after the precompile");
    }
}
