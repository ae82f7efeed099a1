//! `run --resume REPORT`: the run's arguments taken from the report it continues — device,
//! scene, filters, skips, injections, canaries, patches, confirmation, isolation, deadlines,
//! shard, validation, lane evidence, mutants, repeats, workers and threads — so that `rtprobe run --resume REPORT` alone
//! finishes the run. An argument given here (on the command line or through its variable) that
//! differs from the report's is refused: that would be another run. What the report does not
//! keep (`--baseline`, `--junit`, `--output-dir`, `--flakes`, `--dump`) is given again; the
//! interrupt message prints the whole command ([`command`]).
use super::args::RunArgs;
use super::commands::Globals;
use super::exit::{self, coded};
use crate::model::{RunReport, SceneParams};
use anyhow::Result;
use std::path::Path;

/// The arguments that make the scene.
const SCENE: &[&str] = &["seed", "size", "instances", "mesh_detail", "scene"];

/// Which arguments were given, and the report they are held to.
struct Given<'a> {
    path: &'a Path,
    explicit: &'a [String],
}

impl Given<'_> {
    fn explicit(&self, id: &str) -> bool {
        self.explicit.iter().any(|e| e == id)
    }

    /// `given` (clap id `id`, flag `flag`) becomes the report's `theirs` unless it was given; a
    /// given value that differs is refused.
    fn take<T: PartialEq>(
        &self,
        id: &str,
        flag: &str,
        given: &mut T,
        theirs: T,
        show: impl Fn(&T) -> String,
    ) -> Result<()> {
        if !self.explicit(id) {
            *given = theirs;
            return Ok(());
        }
        if *given == theirs {
            return Ok(());
        }
        let what = if SCENE.contains(&id) { "scene" } else { flag };
        Err(coded(
            exit::BAD_INPUT,
            format!(
                "cannot resume {}: its {what} differs ({flag} {} in the report, {} here); leave {flag} out to resume with the report's, or give another run its own -o",
                self.path.display(),
                show(&theirs),
                show(given)
            ),
        ))
    }

    /// `given` becomes the report's unless it was given (no refusal: it changes no result).
    fn keep<T>(&self, id: &str, given: &mut T, theirs: T) {
        if !self.explicit(id) {
            *given = theirs;
        }
    }
}

fn list(v: &[String]) -> String {
    if v.is_empty() {
        "none".into()
    } else {
        v.iter().map(|s| format!("'{s}'")).collect::<Vec<_>>().join(" ")
    }
}

fn scene(g: &Given, a: &mut RunArgs, p: &SceneParams) -> Result<()> {
    g.take("seed", "--seed", &mut a.seed, p.seed, u64::to_string)?;
    let size = format!("{}x{}", p.width, p.height);
    let normal = |s: &String| s.trim().to_ascii_lowercase();
    let mut given = normal(&a.size);
    g.take("size", "--size", &mut given, size, String::clone)?;
    a.size = given;
    let file = p.file.as_ref().map(|f| std::path::PathBuf::from(&f.path));
    let show = |f: &Option<std::path::PathBuf>| {
        f.as_ref().map_or("none (the procedural scene)".into(), |p| p.display().to_string())
    };
    let mut given = a.scene.as_ref().map(|s| std::path::absolute(s).unwrap_or(s.clone()));
    g.take("scene", "--scene", &mut given, file, show)?;
    a.scene = given;
    if p.file.is_some() {
        // The file's instance count: `--instances` makes nothing then.
        return g.take(
            "mesh_detail",
            "--mesh-detail",
            &mut a.mesh_detail,
            p.mesh_detail,
            u32::to_string,
        );
    }
    g.take("instances", "--instances", &mut a.instances, p.instances, u32::to_string)?;
    g.take("mesh_detail", "--mesh-detail", &mut a.mesh_detail, p.mesh_detail, u32::to_string)
}

fn plan_options(g: &Given, a: &mut RunArgs, r: &RunReport) -> Result<()> {
    let o = &r.options;
    g.take("filter", "--filter", &mut a.filter, o.filters.clone(), |v| list(v))?;
    let mut inject: Vec<String> =
        a.inject_fault.iter().filter(|s| !s.trim().is_empty()).cloned().collect();
    g.take("inject_fault", "--inject-fault", &mut inject, o.inject.clone(), |v| list(v))?;
    a.inject_fault = inject;
    g.take("canaries", "--canaries", &mut a.canaries, o.canaries, bool::to_string)?;
    let name = |p: &crate::model::PatchMode| {
        serde_json::to_value(p).ok().and_then(|v| v.as_str().map(String::from)).unwrap_or_default()
    };
    g.take("patches", "--patches", &mut a.patches, o.patches, name)?;
    g.take("shard", "--shard", &mut a.shard, o.shard.clone(), |s| {
        s.clone().unwrap_or_else(|| "none".into())
    })?;
    if !o.skips.is_empty() && !g.explicit("skips") {
        a.skip_patterns = Some(o.skips.clone());
    }
    Ok(())
}

fn worker_options(g: &Given, a: &mut RunArgs, r: &RunReport) -> Result<()> {
    let o = &r.options;
    g.take("timeout", "--timeout", &mut a.timeout, o.timeout_s, f64::to_string)?;
    if let Some(s) = o.setup_timeout_s {
        g.take("setup_timeout", "--setup-timeout", &mut a.setup_timeout, s, f64::to_string)?;
    }
    g.take("no_confirm", "--no-confirm", &mut a.no_confirm, !o.confirm, bool::to_string)?;
    let iso = |i: &crate::model::Isolation| {
        serde_json::to_value(i).ok().and_then(|v| v.as_str().map(String::from)).unwrap_or_default()
    };
    g.take("isolation", "--isolation", &mut a.isolation, o.isolation, iso)?;
    // These change no verdict: the report's unless given.
    g.keep("repeat", &mut a.repeat, o.repeat);
    g.keep("jobs", &mut a.jobs, o.jobs);
    g.keep("threads", &mut a.threads, o.threads);
    let cache = o.pipeline_cache.as_ref().map(|p| p.display().to_string());
    g.keep("pipeline_cache", &mut a.pipeline_cache, Some(cache.unwrap_or_else(|| "off".into())));
    Ok(())
}

/// What the probe records (`--lane-evidence`, which changes results) and the mutants tried
/// (`--mutants`, `--mutant`, `--mutants-sample`: no cell's verdict depends on them, so they are
/// the report's unless one of them is given).
fn probe_options(g: &Given, a: &mut RunArgs, r: &RunReport) -> Result<()> {
    let o = &r.options;
    let mode = |m: &crate::model::LaneMode| {
        serde_json::to_value(m).ok().and_then(|v| v.as_str().map(String::from)).unwrap_or_default()
    };
    g.take("lane_evidence", "--lane-evidence", &mut a.lane_evidence, o.lane_evidence, mode)?;
    if !["mutants", "mutant", "mutants_sample"].iter().any(|id| g.explicit(id)) {
        a.mutants = !o.mutants.is_empty();
        a.mutant = o.mutants.iter().map(|m| m.as_str().to_string()).collect();
        a.mutants_sample = o.mutants_sample.clone();
    }
    Ok(())
}

/// `a` and `g` completed from the report at `path` (which `report` holds) for `--resume`; the
/// device is the report's unless `--device` is given (`run` finds it by identity).
pub fn args(
    g: &Globals,
    a: &RunArgs,
    path: &Path,
    report: &RunReport,
) -> Result<(Globals, RunArgs)> {
    let given = Given { path, explicit: &a.explicit };
    let mut a = a.clone();
    scene(&given, &mut a, &report.scene.params)?;
    plan_options(&given, &mut a, report)?;
    worker_options(&given, &mut a, report)?;
    probe_options(&given, &mut a, report)?;
    let o = &report.options;
    let mut mode = (g.validate, g.gpu_av);
    let show = |m: &(bool, bool)| match m {
        (_, true) => "gpu-av".to_string(),
        (true, false) => "core".into(),
        (false, false) => "off".into(),
    };
    given.take("validate", "--validate", &mut mode, (o.validate, o.gpu_av), show)?;
    Ok((Globals { validate: mode.0, gpu_av: mode.1 }, a))
}

/// A path as a shell reads it back (quoted when it holds anything but plain characters).
fn shell(s: &str) -> String {
    let plain = |c: char| c.is_ascii_alphanumeric() || "/._-+:=@,".contains(c);
    if !s.is_empty() && s.chars().all(plain) {
        s.to_string()
    } else {
        format!("'{}'", s.replace('\'', "'\\''"))
    }
}

/// The command that finishes the run writing `out`: `rtprobe run --resume OUT`, with the
/// arguments the report does not keep, as they were given.
pub fn command(a: &RunArgs, out: &Path) -> String {
    let mut c = format!("rtprobe run --resume {}", shell(&out.display().to_string()));
    let paths = [
        ("--baseline", &a.baseline),
        ("--junit", &a.junit),
        ("--output-dir", &a.output_dir),
        ("--flakes", &a.flakes),
        ("--dump", &a.dump),
    ];
    for (flag, p) in paths {
        if let Some(p) = p {
            c += &format!(" {flag} {}", shell(&p.display().to_string()));
        }
    }
    if a.allow_improvements {
        c += " --allow-improvements";
    }
    c
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(args: &[&str]) -> RunArgs {
        #[derive(clap::Parser)]
        struct T {
            #[command(flatten)]
            run: RunArgs,
        }
        let m = <T as clap::CommandFactory>::command()
            .get_matches_from(std::iter::once("t").chain(args.iter().copied()));
        let mut a = <T as clap::FromArgMatches>::from_arg_matches(&m).unwrap().run;
        a.explicit = m
            .ids()
            .filter(|id| {
                m.value_source(id.as_str()) == Some(clap::parser::ValueSource::CommandLine)
            })
            .map(|id| id.as_str().to_string())
            .collect();
        a
    }

    fn report() -> RunReport {
        let mut r = RunReport::for_tests(vec![]);
        r.options.filters = vec!["stage=raygen".into()];
        r.options.inject = vec!["stage=raygen@value".into()];
        r.options.canaries = true;
        r.options.timeout_s = 7.0;
        r.options.jobs = Some(3);
        r.scene.params.seed = 5;
        r
    }

    #[test]
    fn a_bare_resume_takes_everything_from_the_report() {
        let g = Globals { validate: false, gpu_av: false };
        let r = report();
        let (g2, a) = args(&g, &parse(&["--resume", "r.json"]), Path::new("r.json"), &r).unwrap();
        assert_eq!(a.filter, vec!["stage=raygen".to_string()]);
        assert_eq!(a.inject_fault, vec!["stage=raygen@value".to_string()]);
        assert!(a.canaries);
        assert_eq!((a.seed, a.timeout, a.jobs), (5, 7.0, Some(3)));
        assert!(!g2.validate);
        // Its twin: the defaults a fresh run would take differ from the report's on each of these.
        let fresh = parse(&[]);
        assert!(
            fresh.filter.is_empty() && !fresh.canaries && fresh.seed == 1 && fresh.timeout == 20.0
        );
    }

    #[test]
    fn a_differing_option_given_explicitly_is_refused_and_an_equal_one_kept() {
        let g = Globals { validate: false, gpu_av: false };
        let r = report();
        let p = Path::new("r.json");
        let e =
            args(&g, &parse(&["--resume", "r.json", "--filter", "stage=miss"]), p, &r).unwrap_err();
        let line = format!("{e:#}");
        assert!(
            line.contains(
                "its --filter differs (--filter 'stage=raygen' in the report, 'stage=miss' here)"
            ),
            "{line}"
        );
        assert_eq!(exit::code_for(&e), exit::BAD_INPUT);
        assert!(args(&g, &parse(&["--resume", "r.json", "--seed", "5"]), p, &r).is_ok());
        assert!(args(&g, &parse(&["--resume", "r.json", "--seed", "6"]), p, &r).is_err());
        // More repeats are no other run.
        let (_, a) = args(&g, &parse(&["--resume", "r.json", "--repeat", "9"]), p, &r).unwrap();
        assert_eq!(a.repeat, Some(9));
    }

    /// The options of the other branches (lane evidence, mutants) come from the report too: a
    /// run with `--lane-evidence force --mutant index-zero` resumes as such, and an explicit
    /// other `--lane-evidence` is refused.
    #[test]
    fn lane_evidence_and_mutants_come_from_the_report() {
        use crate::model::{LaneMode, Mutant};
        let g = Globals { validate: false, gpu_av: false };
        let mut r = report();
        r.options.lane_evidence = LaneMode::Force;
        r.options.mutants = vec![Mutant::IndexZero];
        r.options.mutants_sample = Some("4:1".into());
        let p = Path::new("r.json");
        let (_, a) = args(&g, &parse(&["--resume", "r.json"]), p, &r).unwrap();
        assert_eq!(a.lane_evidence, LaneMode::Force);
        assert!(a.mutants && a.mutant == ["index-zero"]);
        assert_eq!(a.mutants_sample.as_deref(), Some("4:1"));
        // Its twin: a fresh run's defaults differ on each.
        let fresh = parse(&[]);
        assert!(fresh.lane_evidence == LaneMode::Auto && !fresh.mutants && fresh.mutant.is_empty());
        let e =
            args(&g, &parse(&["--resume", "r.json", "--lane-evidence", "off"]), p, &r).unwrap_err();
        assert!(format!("{e:#}").contains("its --lane-evidence differs"), "{e:#}");
        // Mutants given here are this run's (they change no verdict).
        let (_, a) =
            args(&g, &parse(&["--resume", "r.json", "--mutant", "value-bits"]), p, &r).unwrap();
        assert_eq!((a.mutant.clone(), a.mutants_sample), (vec!["value-bits".to_string()], None));
    }

    #[test]
    fn the_printed_command_carries_what_the_report_does_not_keep() {
        let a = parse(&["--baseline", "b.json", "--junit", "my dir/j.xml", "--allow-improvements"]);
        assert_eq!(
            command(&a, Path::new("reports/run-1.json")),
            "rtprobe run --resume reports/run-1.json --baseline b.json --junit 'my dir/j.xml' --allow-improvements"
        );
    }
}
