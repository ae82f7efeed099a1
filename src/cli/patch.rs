//! `rtprobe patch`: read SPIR-V modules or compile GLSL ([`super::patch_inputs`]), validate each
//! input with the options it needs, apply the requested patches to all of them as one pipeline,
//! validate each result with its input's options, optionally run both pipelines on the device
//! (`--verify`, [`super::patch_verify`]: in a child process), and write the results and the host contract atomically — or fail with one line
//! and write nothing.
use super::args::PatchArgs;
use super::commands::Globals;
use super::exit::{self, coded};
use super::out::{errln, outln};
use super::patch_inputs::{self, Dest, Input};
use super::patch_verify::verify;
use crate::atomic::write_atomic;
use crate::patches::layout::Rules;
use crate::patches::pipeline::{self, Applied, Stage};
use crate::patches::{self, PatchName, Validation};
use crate::tools::spirv::{self as spirv_tools, ValOptions};
use anyhow::{Context, Result};
use std::collections::BTreeMap;
use std::io::Write;

fn list() -> u8 {
    for (name, opts, what) in patches::LIST {
        outln!("{name:<16} [{opts}]\n    {what}");
    }
    exit::OK
}

/// The patches and their `KEY=VALUE` options.
fn requested(a: &PatchArgs) -> Result<(Vec<PatchName>, BTreeMap<String, String>)> {
    if a.inputs.is_empty() {
        return Err(coded(exit::USAGE, "patch needs an input file (or --list)"));
    }
    if a.apply.is_empty() {
        return Err(coded(exit::USAGE, "patch needs --apply PATCH[,PATCH...] (see --list)"));
    }
    let names = a
        .apply
        .iter()
        .map(|n| PatchName::parse(n))
        .collect::<Result<Vec<_>, _>>()
        .map_err(|e| coded(exit::USAGE, e.to_string()))?;
    if a.verify && names.contains(&PatchName::PinIndex) {
        return Err(coded(exit::USAGE, "--verify cannot check pin-index: it replaces the runtime index by a spec constant, so the patched pipeline reads another element by design and would differ; verify the other patches without it"));
    }
    let mut options = BTreeMap::new();
    for o in &a.options {
        let (k, v) = o
            .split_once('=')
            .ok_or_else(|| coded(exit::USAGE, format!("--option {o:?} is not KEY=VALUE")))?;
        options.insert(k.trim().to_string(), v.trim().to_string());
    }
    Ok((names, options))
}

/// The validator's name for messages.
fn validator() -> String {
    spirv_tools::tool(spirv_tools::SpirvTool::Val).map(|t| t.describe()).unwrap_or_default()
}

fn too_old(name: &str, validator: &str, what: &str) -> anyhow::Error {
    coded(
        exit::BAD_INPUT,
        format!(
            "{name}: {validator} is too old for {what}: the module is not checked by it; a newer \
             SPIRV-Tools (2026.x in the sid root of scripts/setup-sid) validates it, or pass \
             --no-spirv-val to patch without validation"
        ),
    )
}

/// Validate an input with the options it needs: its layout rules and the options its outputs
/// are checked with (`None`: not validated). A problem already in the input is said as such.
fn check_input(
    input: &Input,
    skip: bool,
    warned: &mut bool,
) -> Result<(Rules, Option<ValOptions>)> {
    if skip {
        return Ok((Rules::Standard, None));
    }
    match spirv_tools::validate_input(&input.words) {
        (Validation::Valid, o) => {
            Ok((if o.scalar_block_layout { Rules::Scalar } else { Rules::Standard }, Some(o)))
        }
        (Validation::Unavailable, _) => {
            if !std::mem::replace(warned, true) {
                errln!("rtprobe: warning: spirv-val is not installed (apt-get install spirv-tools, or scripts/setup-sid for SPIRV-Tools 2026.x): neither inputs nor outputs are validated");
            }
            Ok((Rules::Standard, None))
        }
        (Validation::TooOld { validator, what }, _) => Err(too_old(&input.name, &validator, &what)),
        (Validation::Invalid(msg), o) => Err(coded(
            exit::BAD_INPUT,
            format!(
                "{} fails spirv-val before any patch ({}, {}): {msg} — the input itself is invalid; fix it, or pass --no-spirv-val",
                input.name,
                validator(),
                o.describe()
            ),
        )),
    }
}

/// Validate a patched module with its input's options: a failure now is the patch's.
fn check_output(name: &str, words: &[u32], opts: Option<&ValOptions>) -> Result<()> {
    let Some(o) = opts else {
        return Ok(());
    };
    match spirv_tools::validate(words, o) {
        Validation::Valid | Validation::Unavailable => Ok(()),
        Validation::TooOld { validator, what } => Err(too_old(name, &validator, &what)),
        Validation::Invalid(msg) => Err(coded(
            exit::BAD_INPUT,
            format!(
                "the patched {name} fails spirv-val ({}, {}; its input passes), nothing written: {msg}",
                validator(),
                o.describe()
            ),
        )),
    }
}

/// Write `words` to `dest` (atomically, or to stdout).
fn write_module(dest: &Dest, words: &[u32]) -> Result<()> {
    let bytes = spirv_tools::bytes(words);
    match dest {
        Dest::Stdout => std::io::stdout().write_all(&bytes).context("writing to stdout"),
        Dest::File(p) => write_atomic(p, &bytes)
            .with_context(|| format!("writing {}", p.display()))
            .map_err(|e| coded(exit::BAD_INPUT, format!("{e:#}"))),
    }
}

/// What the command prints: to stdout, or to stderr when the module goes to stdout.
fn say(info_out: bool, line: &str) {
    if info_out {
        outln!("{line}");
    } else {
        errln!("{line}");
    }
}

pub fn patch(g: &Globals, a: &PatchArgs) -> Result<u8> {
    if a.list {
        return Ok(list());
    }
    let (names, options) = requested(a)?;
    let inputs = patch_inputs::read(a)?;
    let (outs, unpatched, contract_path) = patch_inputs::destinations(a, &inputs)?;
    let mut warned = false;
    let mut stages = Vec::new();
    let mut val = Vec::new();
    for i in &inputs {
        let (rules, opts) = check_input(i, a.no_spirv_val, &mut warned)?;
        let module = patches::load(&spirv_tools::bytes(&i.words))
            .map_err(|e| coded(exit::BAD_INPUT, format!("{}: {e}", i.name)))?;
        stages.push(Stage { file: i.name.clone(), module, rules });
        val.push(opts);
    }
    let before: Vec<String> = if a.disassemble {
        stages.iter().map(|s| patches::disassemble(&s.module)).collect()
    } else {
        Vec::new()
    };
    let applied = pipeline::apply(&mut stages, &names, &options, a.max_push_constants)
        .map_err(|e| coded(exit::BAD_INPUT, e.to_string()))?;
    let patched: Vec<Vec<u32>> = stages.iter().map(|s| patches::assemble(&s.module)).collect();
    for ((s, words), opts) in stages.iter().zip(&patched).zip(&val) {
        check_output(&s.file, words, opts.as_ref())?;
    }
    let scalar = stages.iter().any(|s| s.rules == Rules::Scalar);
    let verified = if a.verify {
        verify(g, a, &inputs, &patched, &applied.contract, scalar)?
    } else {
        Vec::new()
    };
    if a.verify {
        crate::runner::groups::handle_interrupts(crate::runner::groups::Left::Writing);
    }
    for (p, i) in unpatched.iter().zip(&inputs) {
        write_module(&Dest::File(p.clone()), &i.words)?;
    }
    for (d, words) in outs.iter().zip(&patched) {
        write_module(d, words)?;
    }
    report(a, &stages, &before, &outs, &applied, contract_path.as_deref(), &verified)
}

/// Write the contract and print what was done.
fn report(
    a: &PatchArgs,
    stages: &[Stage],
    before: &[String],
    outs: &[Dest],
    applied: &Applied,
    contract_path: Option<&std::path::Path>,
    verified: &[String],
) -> Result<u8> {
    let info_out = !outs.contains(&Dest::Stdout);
    let c = &applied.contract;
    let contract_written = match contract_path {
        Some(p) if !c.is_empty() => {
            let json = serde_json::to_vec_pretty(c).context("contract JSON")?;
            write_atomic(p, &json)
                .map_err(|e| coded(exit::BAD_INPUT, format!("writing {}: {e:#}", p.display())))?;
            Some(p)
        }
        _ => None,
    };
    for w in &applied.warnings {
        errln!("rtprobe: warning: {w}");
    }
    for l in &applied.lines {
        say(info_out, l);
    }
    if a.disassemble {
        for (s, b) in stages.iter().zip(before) {
            if stages.len() > 1 {
                say(info_out, &format!("--- {}", s.file));
            }
            let d = patches::diff(b, &patches::disassemble(&s.module));
            say(info_out, d.trim_end());
        }
    }
    if !c.is_empty() {
        say(info_out, &c.sentence());
    }
    for v in verified {
        say(info_out, v);
    }
    if let Some(p) = contract_written {
        say(info_out, &format!("wrote {} (host contract)", p.display()));
    }
    for d in outs {
        if let Dest::File(p) = d {
            say(info_out, &format!("wrote {}", p.display()));
        }
    }
    Ok(exit::OK)
}
