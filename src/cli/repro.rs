//! `rtprobe repro CELL --from REPORT -o DIR`: everything needed to re-run one cell elsewhere —
//! its shaders (GLSL, SPIR-V as the worker runs it, `spirv-dis` disassembly), `cell.json` (the
//! cell, scene, injections and the verdict it had), the device's caps JSON, and a README with
//! `rtprobe run --cell-spec DIR/cell.json`, which re-runs exactly that cell.
use super::args::ReproArgs;
use super::commands::Globals;
use super::exit::{self, coded};
use super::out::outln;
use super::shared::{load_report, report_device};
use crate::atomic::write_atomic;
use crate::bisect::isolation::describe;
use crate::bisect::scope::{cell_by_id, ReportOptions};
use crate::model::bundle::{BundleModule, CellSpec, SCHEMA};
use crate::model::inject::for_cell;
use crate::model::Injection;
use crate::model::PatchMode;
use crate::model::{Cell, CellReport, RunReport};
use crate::report::shaders::{cell_shaders, spirv_bytes, spirv_dis, Shader};
use anyhow::{Context, Result};
use std::path::Path;

impl CellSpec {
    pub fn load(path: &Path) -> Result<CellSpec> {
        let bytes = std::fs::read(path)
            .map_err(|e| coded(exit::BAD_INPUT, format!("cannot read {}: {e}", path.display())))?;
        let s: CellSpec = serde_json::from_slice(&bytes).map_err(|e| {
            coded(exit::BAD_INPUT, format!("{} is not an rtprobe cell spec: {e}", path.display()))
        })?;
        if s.schema != SCHEMA {
            return Err(coded(
                exit::BAD_INPUT,
                format!("{} has schema {:?}, expected {SCHEMA:?}", path.display(), s.schema),
            ));
        }
        if s.cell.id() != s.id {
            return Err(coded(
                exit::BAD_INPUT,
                format!(
                    "{}: id {:?} does not match its cell ({})",
                    path.display(),
                    s.id,
                    s.cell.id()
                ),
            ));
        }
        s.scene
            .validate()
            .map_err(|e| coded(exit::BAD_INPUT, format!("{}: scene: {e}", path.display())))?;
        Ok(s)
    }

    /// The bundle's `shaders/` folder next to `path` when the spec lists modules (each must be
    /// there), else `None` (compile the GLSL).
    pub fn spirv_dir(&self, path: &Path) -> Result<Option<std::path::PathBuf>> {
        if self.modules.is_empty() {
            return Ok(None);
        }
        let dir = path.parent().unwrap_or(Path::new(".")).join("shaders");
        for m in &self.modules {
            if m.file.contains('/') || !dir.join(&m.file).is_file() {
                return Err(coded(
                    exit::BAD_INPUT,
                    format!(
                        "{}: the bundle's SPIR-V {} is missing",
                        path.display(),
                        dir.join(&m.file).display()
                    ),
                ));
            }
        }
        Ok(Some(dir))
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
            filter: vec![crate::model::registry::exact_filter(&self.cell)],
            inject_fault: self.inject.clone(),
            patches: if self.cell.patch.is_some() { PatchMode::All } else { PatchMode::None },
            canaries: self.cell.canary.is_some(),
            seed: p.seed,
            size: format!("{}x{}", p.width, p.height),
            instances: p.instances,
            mesh_detail: p.mesh_detail,
            // A `--scene` run's file, loaded again by path (its hash held to the bundle's by
            // `cli::run`'s `cell_spec_args`).
            scene: p.file.as_ref().map(|f| std::path::PathBuf::from(&f.path)),
            timeout: self.timeout_s,
            cell_spec: None,
            spirv_dir: None,
            // The original run's way (an older bundle without it: this run's `--pipelines`).
            pipelines: self.pipelines.unwrap_or(a.pipelines),
            ..a.clone()
        })
    }
}

fn write(dir: &Path, name: &str, bytes: &[u8]) -> Result<()> {
    write_atomic(&dir.join(name), bytes).context("writing the repro bundle")
}

/// The bundle's staging folder beside `out`, `.NAME.tmp-PID-K`, made new (`create_dir`, by
/// [`crate::tempdir::first_free`]: a name that is taken — a killed run's, a live one of this pid
/// in another pid namespace, a planted link — is neither entered nor removed).
fn staging_dir(out: &Path, name: &str) -> Result<std::path::PathBuf> {
    crate::tempdir::first_free(|k| {
        let tmp = out.with_file_name(format!(".{name}.tmp-{}-{k}", std::process::id()));
        std::fs::create_dir(&tmp).map(|()| tmp)
    })
    .map_err(|e| {
        coded(
            exit::BAD_INPUT,
            format!("cannot make a staging folder beside {}: {e}", out.display()),
        )
    })
}

/// Move the bundle built in `tmp` to `out` by renames, so that `out` is either what it was or
/// the whole new bundle: a missing or empty `out` is replaced; a non-empty one only with
/// `force` (moved aside first, removed once the new bundle is in place, put back on failure).
fn publish(tmp: &Path, out: &Path, force: bool) -> Result<()> {
    let ctx = || format!("writing the repro bundle in {}", out.display());
    let old = out.with_file_name(format!(
        ".{}.old-{}",
        out.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default(),
        std::process::id()
    ));
    let empty = match std::fs::read_dir(out) {
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => None,
        Err(_) if !out.is_dir() => {
            return Err(coded(
                exit::BAD_INPUT,
                format!("{} exists and is not a directory", out.display()),
            ))
        }
        Err(e) => {
            return Err(coded(exit::BAD_INPUT, format!("cannot read {}: {e}", out.display())))
        }
        Ok(mut entries) => Some(entries.next().is_none()),
    };
    let aside = match empty {
        None => false,
        Some(true) => {
            std::fs::remove_dir(out).with_context(ctx)?;
            false
        }
        Some(false) if !force => {
            return Err(coded(
                exit::BAD_INPUT,
                format!(
                    "{} exists and is not empty; --force replaces it (its files are removed)",
                    out.display()
                ),
            ))
        }
        Some(false) => {
            std::fs::rename(out, &old).with_context(ctx)?;
            true
        }
    };
    if let Err(e) = std::fs::rename(tmp, out) {
        if aside {
            let _ = std::fs::rename(&old, out);
        }
        return Err(e).with_context(ctx);
    }
    if aside {
        let _ = std::fs::remove_dir_all(&old);
    }
    Ok(())
}

/// Refuse `out` before anything is written: it must name a folder (not `/`, `.` or `..`); a
/// non-empty one is replaced only with `force`, and only when it is a repro bundle (has
/// `cell.json`) that holds neither the `--from` report nor the current directory.
fn check_out(out: &Path, from: &Path, force: bool) -> Result<()> {
    let refuse = |what: String| Err(coded(exit::BAD_INPUT, what));
    if out.file_name().is_none() {
        return refuse(format!(
            "-o {} does not name a folder; give a new folder such as -o repro",
            out.display()
        ));
    }
    let Ok(mut entries) = std::fs::read_dir(out) else {
        return Ok(());
    };
    let canon = |p: &Path| std::fs::canonicalize(p).ok();
    let dir = canon(out);
    let inside =
        |p: Option<std::path::PathBuf>| matches!((&dir, p), (Some(d), Some(p)) if p.starts_with(d));
    if inside(std::env::current_dir().ok().and_then(|c| canon(&c))) {
        return refuse(format!(
            "{} holds the current directory; give -o a new folder",
            out.display()
        ));
    }
    if entries.next().is_none() {
        return Ok(());
    }
    if !force {
        return refuse(format!("{} exists and is not empty; --force replaces it if it is a repro bundle (its files are removed)", out.display()));
    }
    if !out.join("cell.json").is_file() {
        return refuse(format!("{} is not a repro bundle (no cell.json); --force replaces only a bundle: give -o a new folder or remove it yourself", out.display()));
    }
    if inside(canon(from)) {
        return refuse(format!(
            "{} holds the --from report {}; give -o another folder",
            out.display(),
            from.display()
        ));
    }
    Ok(())
}

pub fn repro(g: &Globals, a: &ReproArgs) -> Result<u8> {
    let report = load_report(&a.from)?;
    let ro = ReportOptions::of(&report)
        .map_err(|e| coded(exit::BAD_INPUT, format!("{}: {e}", a.from.display())))?;
    let cell = cell_by_id(&a.cell).ok_or_else(|| {
        coded(exit::BAD_INPUT, format!("{:?} is not a cell id (see `rtprobe run --list`)", a.cell))
    })?;
    let entry = report.cells.iter().find(|c| c.id == a.cell);
    let inject: Vec<&Injection> = for_cell(&ro.inject, &cell).into_iter().collect();
    let lanes = crate::report::shaders::lanes_in(&report, &cell);
    let shaders = cell_shaders(&cell, inject.first().map(|i| i.fault), lanes)
        .map_err(|e| coded(exit::compiler_or(&e, exit::INTERNAL), format!("{}: {e}", cell.id())))?;
    check_out(&a.out, &a.from, a.force)?;
    let name = a
        .out
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| "repro".into());
    if let Some(parent) = a.out.parent().filter(|p| !p.as_os_str().is_empty()) {
        std::fs::create_dir_all(parent).map_err(|e| {
            coded(exit::BAD_INPUT, format!("cannot create {}: {e}", parent.display()))
        })?;
    }
    let tmp = staging_dir(&a.out, &name)?;
    let bundle =
        Bundle { g, a, report: &report, ro: &ro, cell, entry, inject: &inject, shaders: &shaders };
    let built = bundle.build(&tmp);
    let result = built.and_then(|()| publish(&tmp, &a.out, a.force));
    let _ = std::fs::remove_dir_all(&tmp);
    result?;
    outln!(
        "repro bundle: {} ({} shaders); re-run: rtprobe run --cell-spec {}/cell.json",
        a.out.display(),
        shaders.len(),
        a.out.display()
    );
    Ok(exit::OK)
}

/// What a repro bundle is made of: one cell of a report, with its injections and shaders.
struct Bundle<'a> {
    g: &'a Globals,
    a: &'a ReproArgs,
    report: &'a RunReport,
    ro: &'a ReportOptions,
    cell: Cell,
    /// The cell's entry in the report (None: not in it).
    entry: Option<&'a CellReport>,
    inject: &'a [&'a Injection],
    shaders: &'a [Shader],
}

/// The shader files written into the bundle, for its README.
struct Listing {
    /// Each shader's file stem.
    files: Vec<&'static str>,
    /// `spirv-dis` disassembled every module.
    disassembled: bool,
}

impl Bundle<'_> {
    /// Write the bundle into `dir` (a temporary directory).
    fn build(&self, dir: &Path) -> Result<()> {
        let (modules, listing) = self.write_shaders(dir)?;
        let spec = self.spec(modules);
        write(dir, "cell.json", &(serde_json::to_vec_pretty(&spec)?))?;
        let caps_note = self.write_caps(dir)?;
        let amber_note = self.write_amber(dir)?;
        let readme = self.readme(&spec, &listing, &caps_note, &amber_note);
        write(dir, "README.txt", readme.as_bytes())
    }

    /// Each shader's GLSL, SPIR-V and (with `spirv-dis`) disassembly under `shaders/`.
    fn write_shaders(&self, dir: &Path) -> Result<(Vec<BundleModule>, Listing)> {
        let mut modules = Vec::new();
        let mut listing = Listing { files: Vec::new(), disassembled: true };
        for s in self.shaders {
            let f = s.role.file_name();
            modules.push(BundleModule {
                file: format!("{f}.spv"),
                compiler: s.compiler.clone(),
                patched: s.patched.iter().map(|p| p.to_string()).collect(),
            });
            write(dir, &format!("shaders/{f}.glsl"), s.glsl.as_bytes())?;
            write(dir, &format!("shaders/{f}.spv"), &spirv_bytes(&s.spirv))?;
            match spirv_dis(&s.spirv) {
                Some(d) => write(dir, &format!("shaders/{f}.spvasm"), d.as_bytes())?,
                None => listing.disassembled = false,
            }
            listing.files.push(f);
        }
        Ok((modules, listing))
    }

    /// `cell.json`: what `run --cell-spec` re-runs, and the verdict the cell had.
    fn spec(&self, modules: Vec<BundleModule>) -> CellSpec {
        let (report, entry, cell) = (self.report, self.entry, self.cell);
        CellSpec {
            schema: SCHEMA.into(),
            id: cell.id(),
            description: describe(&cell),
            cell,
            scene: report.scene.params.clone(),
            inject: self.inject.iter().map(|i| i.spec.clone()).collect(),
            timeout_s: self.ro.timeout_s,
            binding_stages: report.options.binding_stages.clone(),
            pipelines: report.options.pipelines,
            original: serde_json::json!({
                "report": self.a.from,
                "device": report.device,
                "outcome": entry.map(|c| c.outcome),
                "reason": entry.and_then(|c| c.reason.clone()),
                "incidence": entry.and_then(|c| c.incidence.clone()),
            }),
            modules,
        }
    }

    /// The caps of the report's device, when it is on this machine; the README's line about it.
    fn write_caps(&self, dir: &Path) -> Result<String> {
        Ok(match report_device(self.g, self.report) {
            Ok((inst, info, _)) => {
                let caps = crate::caps::caps_json(&info, inst.loader_version, None);
                write(dir, "caps.json", &serde_json::to_vec_pretty(&caps)?)?;
                "caps.json: `rtprobe caps --json` of the device (without the device-creation check)"
                    .to_string()
            }
            Err(e) => format!("no caps.json: {e:#}"),
        })
    }

    /// The cell as an Amber script, or why there is none; the README's line about it.
    fn write_amber(&self, dir: &Path) -> Result<String> {
        let a = self.a;
        let origin = format!("from {} (rtprobe {})", a.from.display(), env!("CARGO_PKG_VERSION"));
        let script = crate::report::amber::script(
            &self.cell,
            self.shaders,
            &self.report.scene.params,
            self.inject.first().copied(),
            crate::report::shaders::lanes_in(self.report, &self.cell),
            &origin,
        );
        Ok(match script {
            Ok(text) => {
                write(dir, "cell.amber", text.as_bytes())?;
                "cell.amber      an Amber script of the same cell, the reproducer without rtprobe: its SPIR-V, scene, buffers and expected records (`amber -d -v 1.2 cell.amber`; see its header)".to_string()
            }
            Err(why) => format!(
                "no cell.amber: {why};\n                  {}",
                crate::report::amber::NO_STANDALONE
            ),
        })
    }

    /// README.txt: the cell, its verdict, how to re-run it and what each file is.
    fn readme(
        &self,
        spec: &CellSpec,
        listing: &Listing,
        caps_note: &str,
        amber_note: &str,
    ) -> String {
        let entry = self.entry;
        let made_by: std::collections::BTreeSet<&str> =
            self.shaders.iter().map(|s| s.compiler.as_str()).collect();
        format!(
            "rtprobe repro bundle: {}\n{}\n\nOriginal verdict: {} ({})\nInjected: {}\n\nRe-run exactly this cell (same scene, same injection, the SPIR-V in shaders/):\n\n    rtprobe run --cell-spec {}/cell.json\n\nFiles:\n  cell.json       the cell, scene parameters, injections, original verdict, the SPIR-V modules and their compiler\n  shaders/        {}: GLSL as generated, SPIR-V as the worker runs it (patched where the cell says){}\n  {}\n  {}\n\nThe SPIR-V was compiled by {}. `run --cell-spec` runs these .spv files, not a fresh compile, so a\nmachine with another compiler runs the same binary.\n",
            spec.id,
            spec.description,
            entry.map(|c| c.outcome.as_str()).unwrap_or("not in the report"),
            entry.and_then(|c| c.reason.clone()).unwrap_or_default(),
            if spec.inject.is_empty() { "nothing".into() } else { spec.inject.join("; ") },
            self.a.out.display(),
            listing.files.join(", "),
            if listing.disassembled { ", .spvasm from spirv-dis" } else { "; spirv-dis is not installed, so no .spvasm" },
            caps_note,
            amber_note,
            made_by.into_iter().collect::<Vec<_>>().join(" and "),
        )
    }
}

#[cfg(test)]
mod tests {
    use crate::cli::args::{Cli, Command};
    use crate::model::bundle::CellSpec;
    use crate::model::PipelineMode;
    use clap::Parser;

    /// `run --cell-spec` makes the cell's pipelines the way the original run did (the bundle's
    /// `pipelines`), not this run's `--pipelines`; a bundle from before the field keeps this
    /// run's.
    #[test]
    fn a_bundle_reruns_with_the_original_runs_pipelines() {
        let Command::Run(a) =
            Cli::try_parse_from(["rtprobe", "run", "--pipelines", "linked"]).unwrap().command
        else {
            panic!("not run")
        };
        let spec = |pipelines: &str| -> CellSpec {
            serde_json::from_value(serde_json::json!({
                "schema": "rtprobe.cell/1", "id": "x", "description": "x",
                "cell": crate::model::Cell::new(
                    crate::model::Stage::Raygen,
                    crate::model::Resource::StorageBuffer,
                    crate::model::IndexSource::Dynamic,
                    crate::model::DescriptorModel::DescriptorIndexing),
                "scene": crate::model::SceneParams::default(), "inject": [], "timeout_s": 5.0,
                "original": {}, "pipelines": serde_json::from_str::<serde_json::Value>(pipelines).unwrap(),
            }))
            .unwrap()
        };
        assert_eq!(spec("\"whole\"").run_args(&a).unwrap().pipelines, PipelineMode::Whole);
        assert_eq!(spec("\"linked\"").run_args(&a).unwrap().pipelines, PipelineMode::Linked);
        // An older bundle: this run's `--pipelines linked`.
        assert_eq!(spec("null").run_args(&a).unwrap().pipelines, PipelineMode::Linked);
    }
}
