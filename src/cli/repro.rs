//! `rtprobe repro CELL --from REPORT -o DIR`: everything needed to re-run one cell elsewhere —
//! its shaders (GLSL, SPIR-V as the worker runs it, `spirv-dis` disassembly), `cell.json` (the
//! cell, scene, injections and the verdict it had), the device's caps JSON, and a README with
//! `rtprobe run --cell-spec DIR/cell.json`, which re-runs exactly that cell.
use super::args::ReproArgs;
use super::bisect::{load_report, report_device};
use super::commands::Globals;
use super::exit::{self, coded};
use crate::bisect::isolation::describe;
use crate::bisect::scope::{cell_by_id, ReportOptions};
use crate::matrix::inject::{for_cell, Injection};
use crate::matrix::plan::PatchMode;
use crate::matrix::Cell;
use crate::report::shaders::{cell_shaders, spirv_bytes, spirv_dis};
use crate::report::write_atomic;
use crate::scene::SceneParams;
use anyhow::{Context, Result};
use serde::{Deserialize, Serialize};
use std::path::Path;

pub const SCHEMA: &str = "rtprobe.cell/1";

/// `cell.json`: what `run --cell-spec` needs to run exactly this cell again.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct CellSpec {
    pub schema: String,
    pub id: String,
    pub description: String,
    pub cell: Cell,
    pub scene: SceneParams,
    /// The `--inject-fault` arguments of the original run that apply to this cell.
    pub inject: Vec<String>,
    pub timeout_s: f64,
    /// `RTPROBE_BINDING_STAGES` of the original run (it changes results: a re-run sets it).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub binding_stages: Option<String>,
    /// The verdict in the original report (for comparison), and its device.
    pub original: serde_json::Value,
}

impl CellSpec {
    pub fn load(path: &Path) -> Result<CellSpec> {
        let bytes = std::fs::read(path).map_err(|e| coded(exit::BAD_INPUT, format!("cannot read {}: {e}", path.display())))?;
        let s: CellSpec = serde_json::from_slice(&bytes).map_err(|e| coded(exit::BAD_INPUT, format!("{} is not an rtprobe cell spec: {e}", path.display())))?;
        if s.schema != SCHEMA {
            return Err(coded(exit::BAD_INPUT, format!("{} has schema {:?}, expected {SCHEMA:?}", path.display(), s.schema)));
        }
        if s.cell.id() != s.id {
            return Err(coded(exit::BAD_INPUT, format!("{}: id {:?} does not match its cell ({})", path.display(), s.id, s.cell.id())));
        }
        s.scene.validate().map_err(|e| coded(exit::BAD_INPUT, format!("{}: scene: {e}", path.display())))?;
        Ok(s)
    }

    /// `a` with the plan, scene and injections replaced by this cell's: an exact filter on every
    /// axis, `--patches all` only for a patched cell (so the plan holds just it), no workaround
    /// retries for a plain one.
    pub fn run_args(&self, a: &super::args::RunArgs) -> Result<super::args::RunArgs> {
        for i in &self.inject {
            Injection::parse(i).map_err(|e| coded(exit::BAD_INPUT, format!("cell spec: {e}")))?;
        }
        let p = &self.scene;
        Ok(super::args::RunArgs {
            filter: vec![crate::report::issue::exact_filter(&self.cell)],
            inject_fault: self.inject.clone(),
            patches: if self.cell.patch.is_some() { PatchMode::All } else { PatchMode::None },
            canaries: self.cell.canary.is_some(),
            seed: p.seed,
            size: format!("{}x{}", p.width, p.height),
            instances: p.instances,
            mesh_detail: p.mesh_detail,
            timeout: self.timeout_s,
            cell_spec: None,
            ..a.clone()
        })
    }
}

fn write(dir: &Path, name: &str, bytes: &[u8]) -> Result<()> {
    write_atomic(&dir.join(name), bytes).context("writing the repro bundle")
}

/// Move the bundle built in `tmp` to `out`: one rename when `out` does not exist, else file by
/// file (the files it holds are replaced; others are left). A failure before this leaves `out`
/// as it was.
fn publish(tmp: &Path, out: &Path) -> Result<()> {
    let ctx = || format!("writing the repro bundle in {}", out.display());
    if !out.exists() {
        return std::fs::rename(tmp, out).with_context(ctx);
    }
    for sub in ["", "shaders"] {
        let from = tmp.join(sub);
        let Ok(entries) = std::fs::read_dir(&from) else { continue };
        std::fs::create_dir_all(out.join(sub)).with_context(ctx)?;
        for e in entries.flatten() {
            if e.path().is_file() {
                std::fs::rename(e.path(), out.join(sub).join(e.file_name())).with_context(ctx)?;
            }
        }
    }
    let _ = std::fs::remove_dir_all(tmp);
    Ok(())
}

pub fn repro(g: &Globals, a: &ReproArgs) -> Result<u8> {
    let report = load_report(&a.from)?;
    let ro = ReportOptions::of(&report).map_err(|e| coded(exit::BAD_INPUT, format!("{}: {e}", a.from.display())))?;
    let cell = cell_by_id(&a.cell).ok_or_else(|| coded(exit::BAD_INPUT, format!("{:?} is not a cell id (see `rtprobe run --list`)", a.cell)))?;
    let entry = report.cells.iter().find(|c| c.id == a.cell);
    let inject: Vec<&Injection> = for_cell(&ro.inject, &cell).into_iter().collect();
    let shaders = cell_shaders(&cell, inject.first().map(|i| i.fault)).map_err(|e| coded(exit::INTERNAL, format!("{}: {e}", cell.id())))?;
    let name = a.out.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_else(|| "repro".into());
    let tmp = a.out.with_file_name(format!(".{name}.tmp-{}", std::process::id()));
    if let Some(parent) = a.out.parent().filter(|p| !p.as_os_str().is_empty()) {
        std::fs::create_dir_all(parent).map_err(|e| coded(exit::BAD_INPUT, format!("cannot create {}: {e}", parent.display())))?;
    }
    let built = build(g, a, &report, &ro, cell, entry, &inject, &shaders, &tmp);
    let result = built.and_then(|()| publish(&tmp, &a.out));
    let _ = std::fs::remove_dir_all(&tmp);
    result?;
    println!("repro bundle: {} ({} shaders); re-run: rtprobe run --cell-spec {}/cell.json", a.out.display(), shaders.len(), a.out.display());
    Ok(exit::OK)
}

/// Write the bundle into `dir` (a temporary directory).
#[allow(clippy::too_many_arguments)]
fn build(
    g: &Globals,
    a: &ReproArgs,
    report: &crate::report::run_report::RunReport,
    ro: &ReportOptions,
    cell: Cell,
    entry: Option<&crate::report::run_report::CellReport>,
    inject: &[&Injection],
    shaders: &[crate::report::shaders::Shader],
    dir: &Path,
) -> Result<()> {
    let mut listing = Vec::new();
    let mut disassembled = true;
    for s in shaders {
        let f = s.role.file_name();
        write(dir, &format!("shaders/{f}.glsl"), s.glsl.as_bytes())?;
        write(dir, &format!("shaders/{f}.spv"), &spirv_bytes(&s.spirv))?;
        match spirv_dis(&s.spirv) {
            Some(d) => write(dir, &format!("shaders/{f}.spvasm"), d.as_bytes())?,
            None => disassembled = false,
        }
        listing.push(f);
    }
    let spec = CellSpec {
        schema: SCHEMA.into(),
        id: cell.id(),
        description: describe(&cell),
        cell,
        scene: report.scene.params,
        inject: inject.iter().map(|i| i.spec.clone()).collect(),
        timeout_s: ro.timeout_s,
        binding_stages: report.options["binding_stages"].as_str().map(String::from),
        original: serde_json::json!({
            "report": a.from,
            "device": report.device,
            "outcome": entry.map(|c| c.outcome),
            "reason": entry.and_then(|c| c.reason.clone()),
            "incidence": entry.and_then(|c| c.incidence.clone()),
        }),
    };
    write(dir, "cell.json", &(serde_json::to_vec_pretty(&spec)? ))?;
    // The caps of the report's device, when it is on this machine.
    let caps_note = match report_device(g, report) {
        Ok((inst, info)) => {
            let caps = crate::caps::caps_json(&info, inst.loader_version, None);
            write(dir, "caps.json", &serde_json::to_vec_pretty(&caps)?)?;
            "caps.json: `rtprobe caps --json` of the device (without the device-creation check)".to_string()
        }
        Err(e) => format!("no caps.json: {e:#}"),
    };
    let readme = format!(
        "rtprobe repro bundle: {}\n{}\n\nOriginal verdict: {} ({})\nInjected: {}\n\nRe-run exactly this cell (same scene, same injection):\n\n    rtprobe run --cell-spec {}/cell.json\n\nFiles:\n  cell.json       the cell, scene parameters, injections, original verdict\n  shaders/        {}: GLSL as generated, SPIR-V as the worker runs it (patched where the cell says){}\n  {}\n\nNo .amber file: rtprobe does not write Amber scripts (see README, \"Repro bundles\").\n",
        spec.id,
        spec.description,
        entry.map(|c| c.outcome.as_str()).unwrap_or("not in the report"),
        entry.and_then(|c| c.reason.clone()).unwrap_or_default(),
        if spec.inject.is_empty() { "nothing".into() } else { spec.inject.join("; ") },
        a.out.display(),
        listing.join(", "),
        if disassembled { ", .spvasm from spirv-dis" } else { "; spirv-dis is not installed, so no .spvasm" },
        caps_note
    );
    write(dir, "README.txt", readme.as_bytes())
}
