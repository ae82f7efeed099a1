//! `rtprobe patch`: read a SPIR-V binary (or compile GLSL), apply the requested patches, validate
//! with spirv-val, and write the result atomically — or fail with one line and write nothing.
use super::args::PatchArgs;
use super::exit::{self, coded};
use super::out::{errln, out, outln};
use crate::atomic::write_atomic;
use crate::patches::{self, PatchName, Validation};
use crate::shadergen::compile::GlslOptions;
use anyhow::{Context, Result};
use std::collections::BTreeMap;

fn kind(stage: &str) -> Option<shaderc::ShaderKind> {
    use shaderc::ShaderKind as K;
    Some(match stage {
        "rgen" => K::RayGeneration,
        "rchit" => K::ClosestHit,
        "rahit" => K::AnyHit,
        "rmiss" => K::Miss,
        "rint" => K::Intersection,
        "rcall" => K::Callable,
        "vert" => K::Vertex,
        "frag" => K::Fragment,
        "comp" => K::Compute,
        _ => return None,
    })
}

/// `-I`, `-D` and `--target-env` as compile options; a bad `-D` or a missing `-I` directory is a
/// usage error.
fn glsl_options(a: &PatchArgs, input: &std::path::Path) -> Result<GlslOptions> {
    for d in &a.include_dirs {
        if !d.is_dir() {
            return Err(coded(exit::USAGE, format!("-I {}: not a directory", d.display())));
        }
    }
    let mut defines = Vec::new();
    for d in &a.defines {
        let (name, value) = match d.split_once('=') {
            Some((n, v)) => (n.trim(), Some(v.to_string())),
            None => (d.trim(), None),
        };
        let ident = name.chars().next().is_some_and(|c| c.is_ascii_alphabetic() || c == '_')
            && name.chars().all(|c| c.is_ascii_alphanumeric() || c == '_');
        if !ident {
            return Err(coded(exit::USAGE, format!("-D {d:?}: NAME must be a GLSL identifier")));
        }
        defines.push((name.to_string(), value));
    }
    Ok(GlslOptions {
        input: Some(input.to_path_buf()),
        include_dirs: a.include_dirs.clone(),
        defines,
        target: a.target_env,
    })
}

pub fn patch(a: &PatchArgs) -> Result<u8> {
    if a.list {
        for (name, opts, what) in patches::LIST {
            outln!("{name:<14} [{opts}]\n    {what}");
        }
        return Ok(exit::OK);
    }
    let input = a
        .input
        .as_ref()
        .ok_or_else(|| coded(exit::USAGE, "patch needs an input file (or --list)"))?;
    if a.apply.is_empty() {
        return Err(coded(exit::USAGE, "patch needs --apply PATCH[,PATCH...] (see --list)"));
    }
    let out = a.out.as_ref().ok_or_else(|| coded(exit::USAGE, "patch needs -o OUT.spv"))?;
    let names = a
        .apply
        .iter()
        .map(|n| PatchName::parse(n))
        .collect::<Result<Vec<_>, _>>()
        .map_err(|e| coded(exit::USAGE, e.to_string()))?;
    let mut options = BTreeMap::new();
    for o in &a.options {
        let (k, v) = o
            .split_once('=')
            .ok_or_else(|| coded(exit::USAGE, format!("--option {o:?} is not KEY=VALUE")))?;
        options.insert(k.trim().to_string(), v.trim().to_string());
    }
    let bytes = std::fs::read(input).with_context(|| format!("reading {}", input.display()))?;
    let module_bytes = if a.glsl {
        let stage = a.stage.as_deref().ok_or_else(|| {
            coded(
                exit::USAGE,
                "--glsl needs --stage (rgen, rchit, rahit, rmiss, rint, rcall, vert, frag, comp)",
            )
        })?;
        let k = kind(stage).ok_or_else(|| coded(exit::USAGE, format!("--stage {stage:?}: use rgen, rchit, rahit, rmiss, rint, rcall, vert, frag or comp")))?;
        let src = String::from_utf8(bytes).map_err(|_| {
            coded(exit::BAD_INPUT, format!("{} is not UTF-8 GLSL", input.display()))
        })?;
        let opts = glsl_options(a, input)?;
        if let Some(note) = opts.target.mapping_note() {
            if crate::shadergen::glslang::needed_by(&src).is_none() {
                eprintln!("rtprobe: note: {note}");
            }
        }
        let mut c = crate::shadergen::compile::Compiler::new()
            .map_err(|e| coded(exit::NO_SHADER_COMPILER, e))?;
        let name = crate::shadergen::include::display(input);
        let words = c
            .compile_user_glsl(k, &name, &src, &opts)
            .map_err(|e| coded(exit::BAD_INPUT, e.to_string()))?;
        words.iter().flat_map(|w| w.to_le_bytes()).collect()
    } else {
        bytes
    };
    let mut module = patches::load(&module_bytes)
        .map_err(|e| coded(exit::BAD_INPUT, format!("{}: {e}", input.display())))?;
    let before = a.disassemble.then(|| patches::disassemble(&module));
    let lines = patches::apply(&mut module, &names, &options)
        .map_err(|e| coded(exit::BAD_INPUT, format!("{}: {e}", input.display())))?;
    let words = patches::assemble(&module);
    match patches::validate(&words) {
        Validation::Valid => {}
        Validation::Unavailable => errln!("rtprobe: warning: spirv-val is not installed (apt-get install spirv-tools); the output was not validated"),
        Validation::Invalid(msg) => return Err(coded(exit::BAD_INPUT, format!("the patched module fails spirv-val, nothing written: {msg}"))),
    }
    let bytes: Vec<u8> = words.iter().flat_map(|w| w.to_le_bytes()).collect();
    write_atomic(out, &bytes).context("writing the patched module")?;
    for l in lines {
        outln!("{l}");
    }
    if let Some(b) = before {
        out!("{}", patches::diff(&b, &patches::disassemble(&module)));
    }
    outln!("wrote {} ({} bytes)", out.display(), bytes.len());
    Ok(exit::OK)
}
