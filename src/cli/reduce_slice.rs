//! `rtprobe reduce`'s generalization (issue 25's step 5): the matrix's own cells of the reduced
//! shape — the `--filter` predicate's generated cells — run as `rtprobe run` (this executable, a
//! child process, its report `DIR/slice.json`), with the finding's `--inject-fault` when it was
//! injected, the finding's attempts per cell, no confirmation or workaround rounds. Bounded:
//! at most `--slice-cells` cells are planned (a deterministic shard `1/K` of the slice when it
//! generates more); the line says how many ran. When rtprobe's own variant of the shape faults
//! too, the finding joins the matrix's findings: `rtprobe bisect DIR/slice.json` narrows it.
use super::exit::{self, coded};
use super::reduce_job::is_fault;
use crate::model::reduce::Slice;
use crate::model::{Filter, Outcome};
use crate::runner::self_exe;
use anyhow::Result;
use std::path::Path;

/// What the slice runs with.
pub struct SliceArgs<'a> {
    pub predicate: &'a str,
    /// The finding's `--inject-fault` request (`PREDICATE@KIND`), when injected.
    pub injection: Option<&'a str>,
    pub attempts: u32,
    /// The most cells planned (0: no slice).
    pub cap: u32,
    pub device: Option<&'a str>,
}

/// The cells the matrix generates for `predicate` (before the device's support).
fn generated(predicate: &str) -> Result<u32, String> {
    let f = Filter::parse(predicate).map_err(|e| e.to_string())?;
    Ok(crate::matrix::plan::all_cells().0.iter().filter(|c| f.matches(c)).count() as u32)
}

/// The `rtprobe run` arguments of the slice, its shard count.
fn argv(s: &SliceArgs, generated: u32, report: &Path) -> (Vec<String>, u32) {
    let shards = generated.div_ceil(s.cap.max(1)).max(1);
    let mut v: Vec<String> = vec!["run".into(), "--filter".into(), s.predicate.into()];
    if let Some(i) = s.injection {
        v.extend(["--inject-fault".into(), i.into()]);
    }
    v.extend(["--no-confirm".into(), "--patches".into(), "none".into()]);
    v.extend(["--repeat".into(), s.attempts.max(1).to_string()]);
    if shards > 1 {
        v.extend(["--shard".into(), format!("1/{shards}")]);
    }
    if let Some(d) = s.device {
        v.extend(["--device".into(), d.into()]);
    }
    v.extend(["-o".into(), report.display().to_string()]);
    (v, shards)
}

/// Run the slice into `dir/slice.json`; `None` when `cap` is 0 or no predicate was made. A
/// slice that cannot run is a `Slice` whose line says why (the reduction stands).
pub fn run(s: &SliceArgs, dir: &Path) -> Result<Option<Slice>> {
    if s.cap == 0 || s.predicate.is_empty() {
        return Ok(None);
    }
    let report = dir.join("slice.json");
    let generated = match generated(s.predicate) {
        Ok(n) => n,
        Err(e) => {
            let line = format!("the slice not run: the predicate is no --filter ({e})");
            return Ok(Some(Slice { line, ..Slice::default() }));
        }
    };
    let (args, shards) = argv(s, generated, &report);
    let command = format!("rtprobe {}", args.join(" "));
    tracing::info!("reduce: the slice: {command}");
    let out = std::process::Command::new(self_exe::spawn_path())
        .args(&args)
        .stdin(std::process::Stdio::null())
        .output()
        .map_err(|e| coded(exit::BAD_INPUT, self_exe::start_error("the matrix's slice", &e)))?;
    let mut slice = Slice {
        command,
        report: "slice.json".into(),
        generated,
        injection: s.injection.map(String::from),
        ..Slice::default()
    };
    let Some(cells) = read_cells(&report) else {
        let said = String::from_utf8_lossy(&out.stderr).lines().last().unwrap_or("").to_string();
        slice.line = format!("the slice did not run (exit {:?}): {said}", out.status.code());
        return Ok(Some(slice));
    };
    judge(&mut slice, &cells, shards);
    Ok(Some(slice))
}

/// Each cell's id and outcome from the slice's report.
fn read_cells(report: &Path) -> Option<Vec<(String, Outcome)>> {
    let v: serde_json::Value = serde_json::from_slice(&std::fs::read(report).ok()?).ok()?;
    let cells = v["cells"].as_array()?;
    Some(
        cells
            .iter()
            .filter_map(|c| {
                let o: Outcome = serde_json::from_value(c["outcome"].clone()).ok()?;
                Some((c["id"].as_str()?.to_string(), o))
            })
            .collect(),
    )
}

/// The counts and the verdict line of a slice that ran.
fn judge(slice: &mut Slice, cells: &[(String, Outcome)], shards: u32) {
    let ran = |o: Outcome| match o {
        Outcome::Unsupported | Outcome::NotImplemented => false,
        Outcome::Pass | Outcome::Mismatch | Outcome::Error => true,
        Outcome::DeviceLost | Outcome::Crash | Outcome::Timeout => true,
    };
    slice.planned = cells.len() as u32;
    slice.ran = cells.iter().filter(|c| ran(c.1)).count() as u32;
    slice.faulted = cells.iter().filter(|c| is_fault(c.1)).map(|c| c.0.clone()).collect();
    let scope = if shards > 1 {
        format!("shard 1/{shards}: {} of the {} cells it generates", slice.planned, slice.generated)
    } else {
        format!("all {} cells it generates", slice.generated)
    };
    let injected = if slice.injection.is_some() {
        " with the same --inject-fault (the matrix's cells carry the injected shape too; no driver verdict)"
    } else {
        ""
    };
    slice.line = if slice.faulted.is_empty() {
        format!("rtprobe's own cells of this shape pass: {} ran ({scope}){injected}; the fault needs more of the shader than this shape", slice.ran)
    } else {
        format!("rtprobe's own variant of this shape faults too: {} of {} cells that ran ({scope}){injected}; it joins the matrix's findings (rtprobe bisect slice.json narrows it)", slice.faulted.len(), slice.ran)
    };
}

#[cfg(test)]
mod tests {
    use super::*;

    fn args(cap: u32) -> SliceArgs<'static> {
        SliceArgs {
            predicate: "stage=closest_hit,resource=storage_buffer,index=dynamic",
            injection: None,
            attempts: 1,
            cap,
            device: None,
        }
    }

    #[test]
    fn the_slice_is_capped_by_a_shard() {
        let n = generated(args(1).predicate).unwrap();
        assert!(n > 4, "{n}");
        let (v, shards) = argv(&args(4), n, Path::new("s.json"));
        assert_eq!(shards, n.div_ceil(4));
        assert!(v.join(" ").contains(&format!("--shard 1/{shards}")), "{v:?}");
        let (v, shards) = argv(&args(n), n, Path::new("s.json"));
        assert_eq!(shards, 1);
        assert!(!v.iter().any(|a| a == "--shard"), "{v:?}");
    }

    #[test]
    fn a_faulting_cell_joins_the_findings_and_passes_do_not() {
        let mut s = Slice { generated: 3, ..Slice::default() };
        let cells = vec![
            ("a".to_string(), Outcome::Crash),
            ("b".to_string(), Outcome::Pass),
            ("c".to_string(), Outcome::Unsupported),
        ];
        judge(&mut s, &cells, 1);
        assert_eq!((s.planned, s.ran), (3, 2));
        assert_eq!(s.faulted, vec!["a".to_string()]);
        assert!(s.line.contains("faults too: 1 of 2"), "{}", s.line);
        let mut s = Slice { generated: 3, ..Slice::default() };
        judge(&mut s, &cells[1..], 2);
        assert!(s.faulted.is_empty());
        assert!(s.line.contains("pass: 1 ran (shard 1/2"), "{}", s.line);
    }

    #[test]
    fn no_cap_no_slice() {
        let d = crate::tempdir::tempdir().unwrap();
        assert_eq!(run(&args(0), d.path()).unwrap(), None);
    }
}
