//! Shader inputs of `rtprobe patch` and `run --shader` ([`InputOptions`]): whether an input is
//! SPIR-V or GLSL, a GLSL input's stage (its file name, or `patch --stage`), compiling it (`-I`,
//! `-D` like glslang's, `--target-env`); and where `patch`'s outputs, unpatched copies and host
//! contract go.
use super::args::PatchArgs;
use super::exit::{self, coded};
use super::out::errln;
use crate::shadergen::compile::{GlslOptions, TargetEnv};
use anyhow::{Context, Result};
use std::path::{Path, PathBuf};

/// One input, read and compiled.
pub struct Input {
    pub path: PathBuf,
    /// The name messages use.
    pub name: String,
    pub words: Vec<u32>,
    /// FNV-1a 128 (hex) of what made `words`: a SPIR-V file's bytes; a GLSL file's contents,
    /// every include it reaches, the defines and the target environment.
    pub identity: String,
}

/// The stage names `--stage` and file names use, with their shaderc kinds.
const STAGES: &[(&str, shaderc::ShaderKind)] = &[
    ("rgen", shaderc::ShaderKind::RayGeneration),
    ("rchit", shaderc::ShaderKind::ClosestHit),
    ("rahit", shaderc::ShaderKind::AnyHit),
    ("rmiss", shaderc::ShaderKind::Miss),
    ("rint", shaderc::ShaderKind::Intersection),
    ("rcall", shaderc::ShaderKind::Callable),
    ("vert", shaderc::ShaderKind::Vertex),
    ("frag", shaderc::ShaderKind::Fragment),
    ("comp", shaderc::ShaderKind::Compute),
];

fn kind(stage: &str) -> Option<shaderc::ShaderKind> {
    STAGES.iter().find(|s| s.0 == stage).map(|s| s.1)
}

/// The stage a file name says: its extension, or the one before `.glsl` (`gbuffer.rchit.glsl`).
pub fn stage_from_name(path: &Path) -> Option<&'static str> {
    let name = path.file_name()?.to_string_lossy().to_lowercase();
    let name = name.strip_suffix(".glsl").unwrap_or(&name);
    let ext = name.rsplit_once('.')?.1;
    STAGES.iter().find(|s| s.0 == ext).map(|s| s.0)
}

/// Whether `bytes` (from `path`) are SPIR-V: a `.spv` file, or one starting with the magic number.
fn is_spirv(path: &Path, bytes: &[u8]) -> bool {
    let magic = bytes.get(..4).map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]));
    path.extension().is_some_and(|e| e == "spv")
        || matches!(magic, Some(0x0723_0203) | Some(0x0302_2307))
}

/// A `-D` value: `NAME`, `NAME=VALUE` or `NAME(A,B)=BODY` (a function-like macro, as glslang's
/// `-D` takes it), as (name with its parameter list, value).
pub fn parse_define(d: &str) -> Result<(String, Option<String>)> {
    let (name, value) = match d.split_once('=') {
        Some((n, v)) => (n.trim(), Some(v.to_string())),
        None => (d.trim(), None),
    };
    let ident = |s: &str| {
        s.chars().next().is_some_and(|c| c.is_ascii_alphabetic() || c == '_')
            && s.chars().all(|c| c.is_ascii_alphanumeric() || c == '_')
    };
    let ok = match name.split_once('(') {
        None => ident(name),
        Some((head, params)) => {
            let params = params.strip_suffix(')').unwrap_or("!");
            ident(head) && (params.trim().is_empty() || params.split(',').all(|p| ident(p.trim())))
        }
    };
    if !ok {
        return Err(coded(
            exit::USAGE,
            format!(
                "-D {d:?}: NAME must be a GLSL identifier, or NAME(A,B) for a function-like macro"
            ),
        ));
    }
    Ok((name.to_string(), value))
}

/// How inputs are read: what `patch` and `run --shader` share.
pub struct InputOptions<'a> {
    /// Every input is GLSL, whatever its name or first bytes (`patch --glsl`).
    pub glsl: bool,
    /// The stage of the one GLSL input (`patch --stage`).
    pub stage: Option<&'a str>,
    pub include_dirs: &'a [PathBuf],
    pub defines: &'a [String],
    pub target_env: TargetEnv,
    /// What the error for a GLSL input without a stage in its name adds (`, or pass --stage`).
    pub stage_hint: &'static str,
}

impl<'a> InputOptions<'a> {
    pub fn of_patch(a: &'a PatchArgs) -> InputOptions<'a> {
        InputOptions {
            glsl: a.glsl,
            stage: a.stage.as_deref(),
            include_dirs: &a.include_dirs,
            defines: &a.defines,
            target_env: a.target_env,
            stage_hint: ", or pass --stage",
        }
    }
}

/// `-I`, `-D` and `--target-env` as compile options for `input`.
fn glsl_options(a: &InputOptions, input: &Path) -> Result<GlslOptions> {
    for d in a.include_dirs {
        if !d.is_dir() {
            return Err(coded(exit::USAGE, format!("-I {}: not a directory", d.display())));
        }
    }
    let defines = a.defines.iter().map(|d| parse_define(d)).collect::<Result<_>>()?;
    Ok(GlslOptions {
        input: Some(input.to_path_buf()),
        include_dirs: a.include_dirs.to_vec(),
        defines,
        target: a.target_env,
    })
}

/// Compile the GLSL `bytes` of `path` (its stage from `--stage`, else its name): the words and
/// the input's identity ([`Input::identity`]).
fn compile(a: &InputOptions, path: &Path, bytes: &[u8], name: &str) -> Result<(Vec<u32>, String)> {
    let stage = match a.stage {
        Some(s) => s,
        None => stage_from_name(path).ok_or_else(|| {
            coded(exit::USAGE, format!("{name}: cannot tell the stage of this GLSL from its name: name it .rgen, .rchit, .rahit, .rmiss, .rint, .rcall, .comp, .vert or .frag (also NAME.rchit.glsl){}", a.stage_hint))
        })?,
    };
    let k = kind(stage).ok_or_else(|| {
        coded(
            exit::USAGE,
            format!(
                "--stage {stage:?}: use rgen, rchit, rahit, rmiss, rint, rcall, vert, frag or comp"
            ),
        )
    })?;
    let src = crate::shadergen::include::decode(bytes);
    let opts = glsl_options(a, path)?;
    if let Some(note) = opts.target.mapping_note() {
        if crate::shadergen::glslang::needed_by(&src).is_none() {
            errln!("rtprobe: note: {note}");
        }
    }
    let mut c = crate::shadergen::compile::Compiler::new()
        .map_err(|e| coded(exit::NO_SHADER_COMPILER, e))?;
    let words = c
        .compile_user_glsl(k, name, &src, &opts)
        .map_err(|e| coded(exit::BAD_INPUT, first_error(&e.to_string())))?;
    Ok((words, glsl_identity(&c.input_files(name, &src, &opts), &opts)))
}

/// [`Input::identity`] of a GLSL input made of `files` (the root's name first is not assumed:
/// only the contents count, so the same sources in another folder are the same input).
fn glsl_identity(files: &[(String, String)], o: &GlslOptions) -> String {
    let mut h = crate::stable_hash::StableHash::default();
    h.str(o.target.name());
    for (name, value) in &o.defines {
        h.str(name).str(value.as_deref().unwrap_or("\u{0}"));
    }
    let mut contents: Vec<&str> = files.iter().map(|(_, c)| c.as_str()).collect();
    contents.sort_unstable();
    for c in contents {
        h.str(c);
    }
    format!("{:032x}", h.finish())
}

/// The longest compile error line shown.
const ERROR_LINE: usize = 400;

/// A compiler's message as one line: its first error and how many more there are (the
/// compilers print every error, each on a line, which `rtprobe` joins with ` | `).
fn first_error(message: &str) -> String {
    let lines: Vec<&str> = message
        .split('\n')
        .flat_map(|l| l.split(" | "))
        .map(str::trim)
        .filter(|l| !l.is_empty())
        .collect();
    let errors: Vec<&str> = lines.iter().copied().filter(|l| l.contains("error:")).collect();
    let (first, more) = match errors.split_first() {
        Some((f, rest)) => (*f, rest.len()),
        None => (lines.first().copied().unwrap_or(message), 0),
    };
    let mut line: String = first.chars().take(ERROR_LINE).collect();
    if line.len() < first.len() {
        line.push('…');
    }
    match more {
        0 => line,
        1 => format!("{line} (and 1 more error)"),
        n => format!("{line} (and {n} more errors)"),
    }
}

/// Every input of `patch`, as SPIR-V words.
pub fn read(a: &PatchArgs) -> Result<Vec<Input>> {
    if a.stage.is_some() && a.inputs.len() > 1 {
        return Err(coded(exit::USAGE, "--stage overrides the stage of one GLSL input; name several by their stage (.rgen, .rchit, ...)"));
    }
    read_with(&InputOptions::of_patch(a), &a.inputs)
}

/// Every input in `paths`, read as `a` says, as SPIR-V words.
pub fn read_with(a: &InputOptions, paths: &[PathBuf]) -> Result<Vec<Input>> {
    let mut out = Vec::new();
    for path in paths {
        let name = crate::shadergen::include::display(path);
        let bytes = std::fs::read(path)
            .with_context(|| format!("reading {}", path.display()))
            .map_err(|e| coded(exit::BAD_INPUT, format!("{e:#}")))?;
        let (words, identity) = if !a.glsl && is_spirv(path, &bytes) {
            let m = crate::patches::load(&bytes)
                .map_err(|e| coded(exit::BAD_INPUT, format!("{name}: {e}")))?;
            let identity = hash_hex(&bytes);
            let words = if bytes.starts_with(&0x0723_0203u32.to_le_bytes()) {
                bytes
                    .chunks_exact(4)
                    .map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]]))
                    .collect()
            } else {
                crate::patches::assemble(&m)
            };
            (words, identity)
        } else {
            compile(a, path, &bytes, &name)?
        };
        out.push(Input { path: path.clone(), name, words, identity });
    }
    Ok(out)
}

/// FNV-1a 128 of `bytes`, hex.
pub fn hash_hex(bytes: &[u8]) -> String {
    format!("{:032x}", crate::stable_hash::StableHash::default().bytes(bytes).finish())
}

/// Where one output goes.
#[derive(Clone, Debug, PartialEq)]
pub enum Dest {
    File(PathBuf),
    Stdout,
}

/// `NAME.patched.spv` (`NAME.spv` → `NAME.patched.spv`) in `dir`, or beside the input.
fn default_name(input: &Path, dir: Option<&Path>, tag: &str) -> PathBuf {
    let file = input.file_name().map(|f| f.to_string_lossy().into_owned()).unwrap_or_default();
    let stem = file.strip_suffix(".spv").unwrap_or(&file);
    let name = format!("{stem}.{tag}.spv");
    match dir {
        Some(d) => d.join(name),
        None => input.with_file_name(name),
    }
}

/// The outputs of `inputs` (`-o`: a file for one input, a folder for several, `-`), then the
/// unpatched copies (`--emit-unpatched`) and the contract's path (`--contract`, else beside the
/// first output; none for stdout).
pub fn destinations(
    a: &PatchArgs,
    inputs: &[Input],
) -> Result<(Vec<Dest>, Vec<PathBuf>, Option<PathBuf>)> {
    let several = inputs.len() > 1;
    let outs: Vec<Dest> = match &a.out {
        Some(o) if o.as_os_str() == "-" => {
            if several {
                return Err(coded(exit::USAGE, "-o - writes one module to stdout: give one input"));
            }
            vec![Dest::Stdout]
        }
        Some(o) if several => {
            inputs.iter().map(|i| Dest::File(default_name(&i.path, Some(o), "patched"))).collect()
        }
        Some(o) => vec![Dest::File(o.clone())],
        None => inputs.iter().map(|i| Dest::File(default_name(&i.path, None, "patched"))).collect(),
    };
    let unpatched = match &a.emit_unpatched {
        None => Vec::new(),
        Some(p) if several => {
            inputs.iter().map(|i| default_name(&i.path, Some(p), "unpatched")).collect()
        }
        Some(p) => vec![p.clone()],
    };
    let contract = a.contract.clone().or_else(|| match (&outs[0], several) {
        (Dest::Stdout, _) => None,
        (Dest::File(f), false) => {
            let s = f.to_string_lossy();
            Some(PathBuf::from(format!("{}.contract.json", s.strip_suffix(".spv").unwrap_or(&s))))
        }
        (Dest::File(f), true) => Some(f.with_file_name("pipeline.contract.json")),
    });
    Ok((outs, unpatched, contract))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The identity of a GLSL input covers what it includes and its defines: an edited header,
    /// or another `-D`, is another input; the same files read again are the same one (the twin);
    /// a file that includes nothing new is not changed by an unrelated header.
    #[test]
    fn a_glsl_inputs_identity_covers_its_includes_and_defines() {
        let d = crate::tempdir::tempdir().unwrap();
        let hit = d.path().join("hit.rchit");
        std::fs::write(&hit, "#version 460\n#extension GL_EXT_ray_tracing : require\n#include \"common.glsl\"\nlayout(location = 0) rayPayloadInEXT vec4 p;\nvoid main() { p = vec4(K); }\n").unwrap();
        let header = d.path().join("common.glsl");
        let id = |defines: &[String]| {
            let o = InputOptions {
                glsl: false,
                stage: None,
                include_dirs: &[],
                defines,
                target_env: TargetEnv::default(),
                stage_hint: "",
            };
            read_with(&o, std::slice::from_ref(&hit)).unwrap().remove(0).identity
        };
        std::fs::write(&header, "#define K 1.0\n").unwrap();
        let first = id(&[]);
        assert_eq!(id(&[]), first, "the same files are the same input");
        std::fs::write(&header, "#define K 2.0\n").unwrap();
        let edited = id(&[]);
        assert_ne!(edited, first, "an edited header is another input");
        assert_ne!(id(&["EXTRA=1".to_string()]), edited, "another -D is another input");
        std::fs::write(d.path().join("unrelated.glsl"), "// not included\n").unwrap();
        assert_eq!(id(&[]), edited);
    }

    #[test]
    fn a_compile_error_is_its_first_error_and_a_count() {
        let many: String = (1..=300)
            .map(|k| format!("x.rchit:{k}: error: 'v{k}' : undeclared identifier\n"))
            .collect::<String>()
            + "300 errors generated.";
        let one = first_error(&format!("GLSL compile error: {}", many.replace('\n', " | ")));
        assert_eq!(
            one,
            "GLSL compile error: x.rchit:1: error: 'v1' : undeclared identifier (and 299 more errors)"
        );
        let single = "x.rchit:7: error: 'y' : undeclared identifier";
        assert_eq!(first_error(single), single);
        let long = format!("x.rchit:1: error: {}", "z".repeat(5000));
        assert!(first_error(&long).chars().count() <= ERROR_LINE + 1);
    }

    #[test]
    fn stages_come_from_names() {
        assert_eq!(stage_from_name(Path::new("a/raygen.rgen")), Some("rgen"));
        assert_eq!(stage_from_name(Path::new("gbuffer.rchit.glsl")), Some("rchit"));
        assert_eq!(stage_from_name(Path::new("SHADOW.RMISS")), Some("rmiss"));
        assert_eq!(stage_from_name(Path::new("common.glsl")), None);
        assert_eq!(stage_from_name(Path::new("x.spv")), None);
    }

    #[test]
    fn defines_take_function_like_macros() {
        assert_eq!(parse_define("N=3").unwrap(), ("N".into(), Some("3".into())));
        assert_eq!(parse_define("DEBUG").unwrap(), ("DEBUG".into(), None));
        assert_eq!(
            parse_define("SQ(x)=((x)*(x))").unwrap(),
            ("SQ(x)".into(), Some("((x)*(x))".into()))
        );
        assert_eq!(parse_define("MIX(a, b)=a+b").unwrap().0, "MIX(a, b)");
        assert!(parse_define("1BAD=2").is_err());
        assert!(parse_define("F(x=1").is_err());
        assert!(parse_define("F(1x)=1").is_err());
    }

    #[test]
    fn outputs_default_beside_their_inputs() {
        assert_eq!(
            default_name(Path::new("s/a.rgen"), None, "patched"),
            PathBuf::from("s/a.rgen.patched.spv")
        );
        assert_eq!(
            default_name(Path::new("s/a.spv"), Some(Path::new("o")), "patched"),
            PathBuf::from("o/a.patched.spv")
        );
        assert!(is_spirv(Path::new("x.bin"), &0x0723_0203u32.to_le_bytes()));
        assert!(is_spirv(Path::new("junk.spv"), b"not spir-v"));
        assert!(!is_spirv(Path::new("x.rgen"), b"#version 460"));
    }
}
