//! `rtprobe reduce`'s workaround on the original (issue 25's step 6): each differential patch
//! that applies to the user's *original* modules (`run --shader`'s variants, planned without the
//! injection), run with the finding's evidence (its attempts per candidate) as `run --shader`
//! runs a variant, and judged with its differential check (`shader_exec::compare_all`) against
//! the original. A verified patch (no fault, no validation message, outputs identical to the
//! original's where it ran) is written `DIR/patched-PATCH.spv` with its host contract
//! `DIR/patched-PATCH.contract.json`.
//!
//! An injected finding is a stand-in for a driver that faults on one shape. `run --shader`
//! injects before it patches, so its fault follows the access into the patched form and every
//! patch "fails" there. Here the finding's request is applied again to each *patched* original:
//! where the patch removed the shape (an SSBO read turned into an address read) nothing matches
//! and no fault is put in; where the shape remains (`nonuniform` only decorates it) the fault is
//! put in and the patch fails as it would on such a driver. The reference is the original
//! without the injection (the injected code adds zero at run time). The verdict says so: it
//! shows the patch removes the faulting shape and keeps the outputs, not that a real driver's
//! fault goes with it.
use super::exit::{self, coded};
use super::reduce_job::is_fault;
use super::shader_exec::{self, Ctx, Ran};
use super::shader_plan::ShaderPlan;
use crate::harness::child::JobModule;
use crate::harness::inject::{self, Request};
use crate::model::reduce::ReduceWorkaround;
use crate::model::{stats, Incidence, Outcome};
use crate::tools::spirv as spirv_tools;
use anyhow::Result;
use std::path::Path;

/// One patched variant ready to run: its name, modules (re-injected), contract, faults put in.
struct Candidate<'a> {
    name: String,
    modules: Vec<JobModule>,
    contract: &'a crate::model::contract::HostContract,
    injected: Option<usize>,
}

/// The variant's modules with `injection` applied again; how many faults it put in.
fn reinject(modules: &[JobModule], injection: Option<&Request>) -> (Vec<JobModule>, Option<usize>) {
    let Some(r) = injection else { return (modules.to_vec(), None) };
    let mut faults = 0;
    let out = modules
        .iter()
        .map(|j| {
            let Ok(mut m) = crate::patches::load(&spirv_tools::bytes(&j.words)) else {
                // A module that cannot be read back cannot be shown free of the fault: counted
                // as still holding it, so the patch is never "verified" by a failed parse.
                tracing::warn!(
                    "{}: the patched module could not be read to re-apply the injection",
                    j.name
                );
                faults += 1;
                return j.clone();
            };
            let done = inject::inject(&mut m, r);
            faults += done.sites.len();
            JobModule {
                name: j.name.clone(),
                words: crate::patches::assemble(&m),
                ray_type: j.ray_type,
            }
        })
        .collect();
    (out, Some(faults))
}

/// The verdict of one variant's attempts, judged against the original's; `proof` is whether
/// its passes are evidence enough ([`proof`]).
fn verdict(
    c: &Candidate,
    ran: &[Ran],
    (compared, injected): (bool, bool),
    proof: Result<(), String>,
) -> ReduceWorkaround {
    let faulted = ran.iter().filter(|r| is_fault(r.attempt.attempt.outcome)).count() as u32;
    let messages: u64 = ran.iter().map(|r| r.attempt.validation_messages).sum();
    let differs = ran.iter().find_map(|r| r.attempt.differs.clone());
    let failed = ran.iter().find(|r| {
        let o = r.attempt.attempt.outcome;
        !is_fault(o) && o != Outcome::Pass
    });
    let clean = faulted == 0 && messages == 0 && differs.is_none() && failed.is_none();
    let verified = clean && proof.is_ok();
    let n = ran.len();
    let line = if verified {
        let outputs = if compared {
            "outputs identical to the original's"
        } else {
            "outputs not compared: the original produced none"
        };
        let model = match c.injected {
            Some(0) => "; the injection re-applied matches no access: the patch removes the injected fault's shape (a stand-in for a driver fault, not proof against a real one)",
            _ => "",
        };
        format!("{}: verified on the original — {n} of {n} attempts pass, 0 validation messages, {outputs}{model}", c.name)
    } else if let (true, Err(why)) = (clean, &proof) {
        format!("{}: not verified — {n} of {n} attempts pass, but {why}", c.name)
    } else if faulted > 0 {
        let why = match c.injected {
            Some(k) if k > 0 => format!(
                " (the shape remains: the injection re-applied put {k} fault{} in)",
                if k == 1 { "" } else { "s" }
            ),
            _ => String::new(),
        };
        format!("{}: not verified — {faulted} of {n} attempts fault{why}", c.name)
    } else if let Some(d) = &differs {
        format!("{}: not verified — {d}", c.name)
    } else if messages > 0 {
        format!("{}: not verified — {messages} validation messages", c.name)
    } else {
        let what = failed.and_then(|r| r.attempt.attempt.detail.clone()).unwrap_or_default();
        format!("{}: not verified — an attempt did not run: {what}", c.name)
    };
    ReduceWorkaround {
        patch: c.name.clone(),
        verified,
        line,
        attempts: n as u32,
        faulted,
        validation_messages: messages,
        differs,
        compared,
        injected_faults: c.injected.filter(|_| injected),
        host_contract: c.contract.sentence(),
        files: vec![],
        contract_file: None,
    }
}

/// Whether a patched variant's passes prove the fault gone: for an injected finding only
/// structurally, when the re-applied injection matches no access of it (the injected fault
/// cannot happen); for a real one its passes must
/// miss a fault as frequent as the finding's (its `incidence`, Clopper–Pearson lower bound:
/// `stats::pass_miss`) with probability below `stats::DEFAULT_MAX_MISS` — the rule `run`'s
/// verified workarounds are held to — and, for a real fault, the original (the control, traced
/// in the same round) must have faulted again.
fn proof(
    c: &Candidate,
    ran: &[Ran],
    incidence: Option<&Incidence>,
    control_faults: Option<usize>,
) -> Result<(), String> {
    match c.injected {
        Some(0) => return Ok(()),
        // Passes of a module that still holds the injected fault prove nothing of the patch:
        // an injected finding's workaround is proven only by its absence (docs/your-shader.md).
        Some(k) => {
            return Err(format!("the injected fault is still in the patched modules ({k} access{}): only its absence proves a workaround of an injected finding", if k == 1 { "" } else { "es" }))
        }
        None => {}
    }
    let passes = ran.iter().filter(|r| r.attempt.attempt.outcome == Outcome::Pass).count() as u32;
    let Some(i) = incidence else {
        return Err("the finding has no incidence to hold the passes to".into());
    };
    let m = stats::pass_miss(i.faulted, i.attempts, passes);
    if m >= stats::DEFAULT_MAX_MISS {
        return Err(format!(
            "{} would miss a fault as frequent as the finding's with p = {m:.3} (≥ {})",
            stats::passes_text(passes, passes, Some(m)),
            stats::DEFAULT_MAX_MISS
        ));
    }
    match control_faults {
        Some(0) => {
            Err("the original, traced in the same round as the control, did not fault again".into())
        }
        Some(_) | None => Ok(()),
    }
}

/// Run every applicable patch of `plan` on the original modules (`ctx.unpatched`), `attempts`
/// each (the finding's evidence, as each candidate had), and write the verified ones into `out`.
pub fn verify(
    ctx: &Ctx,
    plan: &ShaderPlan,
    (injection, attempts, incidence): (Option<&Request>, u32, Option<&Incidence>),
    work: &Path,
    out: &Path,
) -> Result<Vec<ReduceWorkaround>> {
    if plan.variants.is_empty() {
        return Ok(vec![]);
    }
    let mut ctx = ctx.clone();
    // A real fault's passes are held to its incidence (`proof`): as many as that needs.
    let needed = crate::report::gpu_av::passes_needed_for(incidence);
    ctx.repeat = if injection.is_some() { attempts.max(1) } else { attempts.max(needed) };
    ctx.dir = work.join("workarounds");
    std::fs::create_dir_all(&ctx.dir)
        .map_err(|e| coded(exit::BAD_INPUT, format!("{}: {e}", ctx.dir.display())))?;
    let candidates: Vec<Candidate> = plan
        .variants
        .iter()
        .map(|v| {
            let (modules, injected) = reinject(&v.modules, injection);
            Candidate { name: v.patch.as_str().into(), modules, contract: &v.contract, injected }
        })
        .collect();
    let mut original = shader_exec::run_variant(&ctx, "original", &ctx.unpatched, None)?.ran;
    let mut patched = Vec::new();
    for c in &candidates {
        let ran = shader_exec::run_variant(&ctx, &c.name, &c.modules, Some(c.contract))?.ran;
        patched.push((c.name.clone(), ran));
    }
    let device = original
        .iter()
        .chain(patched.iter().flat_map(|p| &p.1))
        .find_map(|r| r.device.clone())
        .unwrap_or_default();
    let judged = shader_exec::compare_all(&device, &mut original, &mut patched);
    let compared = judged.uncompared.is_none();
    // The original runs uninjected: for a real fault it is the control, for an injected one
    // the output reference only.
    let control = injection
        .is_none()
        .then(|| original.iter().filter(|r| is_fault(r.attempt.attempt.outcome)).count());
    let mut found = Vec::new();
    for ((c, (_, ran)), planned) in candidates.iter().zip(&patched).zip(&plan.variants) {
        let proven = proof(c, ran, incidence, control);
        let mut w = verdict(c, ran, (compared, injection.is_some()), proven);
        if w.verified {
            write(&mut w, &planned.modules, planned.contract.clone(), out)?;
        }
        found.push(w);
    }
    Ok(found)
}

/// The verified variant's patched modules (those its contract says a patch changed; without
/// any injection) and its contract, in `out`.
fn write(
    w: &mut ReduceWorkaround,
    modules: &[JobModule],
    contract: crate::model::contract::HostContract,
    out: &Path,
) -> Result<()> {
    let patched =
        |m: &&JobModule| contract.modules.iter().any(|c| c.file == m.name && !c.patched.is_empty());
    let changed: Vec<&JobModule> = modules.iter().filter(patched).collect();
    for (k, m) in changed.iter().enumerate() {
        let name = if changed.len() == 1 {
            format!("patched-{}.spv", w.patch)
        } else {
            format!("patched-{}-{}.spv", w.patch, k + 1)
        };
        put(out, &name, &spirv_tools::bytes(&m.words))?;
        w.files.push(format!("{name} ({})", m.name));
    }
    let name = format!("patched-{}.contract.json", w.patch);
    put(out, &name, &serde_json::to_vec_pretty(&contract)?)?;
    w.contract_file = Some(name);
    Ok(())
}

fn put(dir: &Path, name: &str, bytes: &[u8]) -> Result<()> {
    let p = dir.join(name);
    crate::atomic::write_atomic(&p, bytes)
        .map_err(|e| coded(exit::BAD_INPUT, format!("writing {}: {e}", p.display())))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::contract::HostContract;
    use crate::model::shader_run::ShaderAttempt;
    use crate::model::Attempt;

    fn ran(outcome: Outcome, messages: u64, differs: Option<&str>) -> Ran {
        let attempt = ShaderAttempt {
            validation_messages: messages,
            differs: differs.map(String::from),
            ..ShaderAttempt::bare(Attempt::new(outcome, true))
        };
        Ran { attempt, parts: None, device: None }
    }

    fn judged(injected: Option<usize>, attempts: &[Ran]) -> ReduceWorkaround {
        let contract = HostContract::default();
        let c = Candidate {
            name: "ssbo-to-address".into(),
            modules: vec![],
            contract: &contract,
            injected,
        };
        let proven = proof(&c, attempts, Some(&incidence(3, 3)), None);
        verdict(&c, attempts, (true, injected.is_some()), proven)
    }

    fn incidence(faulted: u32, attempts: u32) -> Incidence {
        Incidence { faulted, attempts, reproduced_alone: None, miss_probability: 0.0 }
    }

    /// Passes of a patch the injection still matches, or of a real fault, prove nothing below
    /// the finding's miss probability, nor without a control that faulted again.
    #[test]
    fn passes_are_held_to_the_incidence_and_the_control() {
        let contract = HostContract::default();
        let c = |injected| Candidate {
            name: "ssbo-to-address".into(),
            modules: vec![],
            contract: &contract,
            injected,
        };
        let pass = || ran(Outcome::Pass, 0, None);
        let one = [pass()];
        let many: Vec<Ran> = (0..20).map(|_| pass()).collect();
        let i = incidence(3, 3);
        let e = proof(&c(None), &one, Some(&i), Some(3)).unwrap_err();
        assert!(e.contains("would miss"), "{e}");
        assert!(proof(&c(None), &many, Some(&i), Some(3)).is_ok());
        let e = proof(&c(None), &many, Some(&i), Some(0)).unwrap_err();
        assert!(e.contains("did not fault again"), "{e}");
        assert!(proof(&c(None), &many, None, Some(3)).is_err());
        assert!(proof(&c(Some(2)), &one, Some(&i), None).is_err());
        // The reviewer's case: many passes while the injected fault is still there.
        let e = proof(&c(Some(1)), &many, Some(&i), Some(3)).unwrap_err();
        assert!(e.contains("still in the patched modules (1 access)"), "{e}");
        assert!(proof(&c(Some(0)), &one, Some(&i), None).is_ok());
        let w = verdict(&c(None), &one, (true, false), proof(&c(None), &one, Some(&i), Some(3)));
        assert!(!w.verified && w.line.contains("1 of 1 attempts pass, but"), "{}", w.line);
    }

    #[test]
    fn verified_only_without_fault_message_or_difference() {
        let pass = || ran(Outcome::Pass, 0, None);
        let w = judged(Some(0), &[pass(), pass()]);
        assert!(w.verified, "{}", w.line);
        assert!(w.line.contains("removes the injected fault's shape"), "{}", w.line);
        let w = judged(Some(1), &[pass(), ran(Outcome::Crash, 0, None)]);
        assert!(!w.verified);
        assert!(w.line.contains("1 of 2 attempts fault (the shape remains"), "{}", w.line);
        let w = judged(None, &[ran(Outcome::Pass, 2, None)]);
        assert!(!w.verified && w.line.contains("2 validation messages"), "{}", w.line);
        let w = judged(None, &[ran(Outcome::Pass, 0, Some("out differs in 3 of 4 texels"))]);
        assert!(!w.verified && w.line.contains("differs in 3"), "{}", w.line);
        let w = judged(None, &[ran(Outcome::Error, 0, None)]);
        assert!(!w.verified && w.line.contains("did not run"), "{}", w.line);
    }

    #[test]
    fn reinjecting_nothing_leaves_the_modules() {
        let m = vec![JobModule { name: "a".into(), words: vec![1, 2, 3], ray_type: None }];
        let (out, n) = reinject(&m, None);
        assert_eq!((out[0].words.clone(), n), (vec![1, 2, 3], None));
    }
}
