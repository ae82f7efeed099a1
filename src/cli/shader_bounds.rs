//! `run --shader`'s descriptor-index check, before any variant runs: the given modules with
//! every descriptor-array access recording its index, whether it differed within the subgroup,
//! and reading a clamped one (`patches::index_bounds`), traced once in a child on the run's own
//! data — the probe's buffer alone in the set after the highest one, so it is the last in
//! (set, binding) order (the harness's data of every other buffer is what the variants get) and
//! no set's last binding changes (a profile's variable descriptor count stays where it was). The
//! indices are as the device under test computed them: the refusal says so and names
//! `--no-index-check`. An index at or past
//! its binding is undefined (`model::index_bounds::RULE`), so a fault it brings is the input's,
//! not the driver's: the harness's data (small integers below the scene's bound in every integer
//! word, so `base + offset` can reach twice it) sizes runtime arrays up to cover it, unless
//! `--array-size` was given; an index past a fixed-size array, or past a size the user gave, is
//! one line and exit 9. A check that cannot run (a heap model, an injected fault, a fault of its
//! own) is said in the report; the run goes on as before.
use super::exit::{self, coded};
use super::shader_exec::{self, Ctx};
use super::shader_plan::ShaderPlan;
use crate::harness::child::JobModule;
use crate::harness::fill::{Fill, Target};
use crate::model::index_bounds::{IndexBounds, IndexSeen, IndexedArray, FIXED_RULE, RULE};
use crate::model::DescriptorModel;
use crate::patches::index_bounds::{self as pass, Probe, Slot};
use anyhow::Result;

/// Checks before giving up (each size-up can move the harness's data).
const ROUNDS: usize = 3;

/// The probe's place and slots for `plan`'s modules: each binding as each declaration declares
/// it — a fixed-size one held to its own size, a runtime-sized one to the descriptors the harness
/// binds (the largest declaration's, `harness::bindings`) — and the probe's buffer at binding 0
/// of the set after the highest.
fn probe(plan: &ShaderPlan, vote: bool) -> Probe {
    let all = || plan.modules.iter().flat_map(|m| m.iface.bindings.iter());
    let bound = |set, binding| {
        all().filter(|b| (b.set, b.binding) == (set, binding)).map(|b| b.count).max().unwrap_or(0)
    };
    let mut slots: Vec<Slot> = Vec::new();
    for b in all() {
        let count = if b.runtime { bound(b.set, b.binding) } else { b.count };
        let slot = Slot { set: b.set, binding: b.binding, fixed: !b.runtime, count };
        if !slots.contains(&slot) {
            slots.push(slot);
        }
    }
    let set = slots.iter().map(|s| s.set.saturating_add(1)).max().unwrap_or(0);
    Probe { set, binding: 0, slots, vote }
}

/// The given modules instrumented (`None`: no module indexes a descriptor array), or why the
/// pass cannot see every access.
fn instrument(ctx: &Ctx, p: &Probe) -> Result<Result<Option<Vec<JobModule>>, String>> {
    let mut out = Vec::new();
    let mut total = pass::Report::default();
    for m in &ctx.unpatched {
        let bytes: Vec<u8> = m.words.iter().flat_map(|w| w.to_le_bytes()).collect();
        let mut module = crate::patches::load(&bytes)
            .map_err(|e| coded(exit::INTERNAL, format!("the index check: {}: {e}", m.name)))?;
        let r = pass::apply(&mut module, p);
        (total.instrumented, total.skipped, total.escaped) = (
            total.instrumented + r.instrumented,
            total.skipped + r.skipped,
            total.escaped + r.escaped,
        );
        out.push(JobModule { words: crate::patches::assemble(&module), ..m.clone() });
    }
    if total.escaped > 0 {
        return Ok(Err("a descriptor array is used other than by indexing it (passed to a function, copied, taken whole), and the check does not follow it".into()));
    }
    if total.skipped > 0 {
        return Ok(Err("a descriptor-array index is wider than 32 bits, or an array's size is one the check cannot read".into()));
    }
    Ok(Ok((total.instrumented > 0).then_some(out)))
}

/// One check: the arrays' largest indices, or why there are none.
fn once(
    ctx: &Ctx,
    plan: &ShaderPlan,
    (vote, max_sets): (bool, u32),
) -> Result<Result<Vec<IndexedArray>, String>> {
    let p = probe(plan, vote);
    if p.set >= max_sets {
        return Ok(Err(format!(
            "no descriptor set is free for the check's buffer (the pipeline uses sets up to {}, maxBoundDescriptorSets {max_sets})",
            p.set.saturating_sub(1)
        )));
    }
    let modules = match instrument(ctx, &p)? {
        Ok(Some(modules)) => modules,
        Ok(None) => return Ok(Ok(vec![])),
        Err(why) => return Ok(Err(why)),
    };
    let mut c = ctx.clone();
    (c.repeat, c.validate, c.gpu_av) = (1, false, false);
    c.unpatched = modules.clone();
    let key = Target::Binding { set: p.set, binding: p.binding, element: None };
    c.fills.0.push(Fill { target: key, bytes: p.initial() });
    let run = shader_exec::run_variant(&c, "index-bounds", &modules, None)?;
    let first = run.ran.into_iter().next();
    let label = format!("storage buffer set {} binding {}[0]", p.set, p.binding);
    let Some(parts) = first.as_ref().and_then(|r| r.parts.as_ref()) else {
        let why = first.and_then(|r| r.attempt.attempt.detail).unwrap_or_default();
        return Ok(Err(format!("the check's own trace did not finish: {why}")));
    };
    let Some(seen) = parts.iter().find(|q| q.label == label) else {
        return Ok(Err(format!("the check's buffer ({label}) was not read back")));
    };
    let word = |k: usize| {
        seen.bytes.get(4 * k..4 * k + 4).map(|b| u32::from_le_bytes(b.try_into().unwrap()))
    };
    let n = p.slots.len();
    // Group g's largest, flags and smallest of slot k.
    let seen = |g: usize, k: usize| -> Option<IndexSeen> {
        let flags = word(3 * g * n + n + k)?;
        (flags & 1 != 0).then_some(IndexSeen {
            largest: word(3 * g * n + k)?,
            smallest: word(3 * g * n + 2 * n + k)?,
            nonuniform: vote.then_some(flags & 2 != 0),
        })
    };
    Ok(Ok(p
        .slots
        .iter()
        .enumerate()
        .map(|(k, s)| IndexedArray {
            set: s.set,
            binding: s.binding,
            elements: s.count,
            runtime: !s.fixed,
            seen: seen(0, k),
            undecorated: seen(1, k),
        })
        .filter(|a| a.elements > 1 || a.runtime || a.seen.is_some())
        .collect()))
}

/// The one line for an index past a binding the harness may not size up.
fn refusal(a: &IndexedArray, given: bool) -> anyhow::Error {
    let most = crate::harness::sizes::MAX_ARRAY_SIZE as u64;
    let largest = a.largest();
    let index = match largest as i32 {
        i if i < 0 => format!("{largest} ({i} if the index is signed)"),
        _ => largest.to_string(),
    };
    let need = (largest as u64 + 1).next_power_of_two();
    let what = match (a.runtime, given) {
        (true, true) => format!("{} descriptors, as --array-size gave", a.elements),
        (true, false) => format!("a runtime array of {}", a.elements),
        (false, _) => format!("an array of {}", a.elements),
    };
    let fix = if a.runtime && need <= most {
        format!("give --array-size {need} or more (descriptors are numbered over every array, so the data moves with the size)")
    } else {
        "--fill the words the index is read from (rtprobe puts small integers in every integer word, docs/your-shader.md), or give --spec a value that keeps a spec-constant index inside".into()
    };
    coded(
        exit::BAD_INPUT,
        format!(
            "the shader indexes set {} binding {} ({what}) with {index} on this run's data, as this device computed it: an index past its binding is undefined ({}), so no result would be evidence; {fix}, or --no-index-check to run it as given",
            a.set, a.binding, if a.runtime { RULE } else { FIXED_RULE }
        ),
    )
}

/// Check the run's indices, sizing runtime arrays up where the harness's own data goes past
/// them; `given`: `--array-size` was; `device`: whether it has subgroup vote in every ray
/// tracing stage, and its `maxBoundDescriptorSets`.
pub fn check(
    ctx: &mut Ctx,
    plan: &mut ShaderPlan,
    (given, device): (bool, (bool, u32)),
) -> Result<IndexBounds> {
    if ctx.model == DescriptorModel::DescriptorHeap {
        return Ok(IndexBounds::unchecked("descriptor heap arrays are not instrumented yet"));
    }
    if plan.injection.is_some() {
        return Ok(IndexBounds::unchecked("--inject-fault's fault is in every module"));
    }
    let most = crate::harness::sizes::MAX_ARRAY_SIZE as u64;
    let mut grown: Option<(u32, u32)> = None;
    for round in 0..ROUNDS {
        let arrays = match once(ctx, plan, device)? {
            Ok(arrays) => arrays,
            Err(why) => return Ok(IndexBounds { grown, ..IndexBounds::unchecked(&why) }),
        };
        let lines: Vec<String> = arrays.iter().map(IndexedArray::line).collect();
        tracing::info!("descriptor indices: {}", lines.join(", "));
        let Some(worst) = arrays.iter().filter(|a| a.outside()).max_by_key(|a| a.largest()) else {
            return Ok(IndexBounds { arrays, grown, unchecked: None });
        };
        let need = (worst.largest() as u64 + 1).next_power_of_two();
        if let Some(a) = arrays.iter().find(|a| a.outside() && !a.runtime) {
            return Err(refusal(a, given));
        }
        if given || need > most {
            return Err(refusal(worst, given));
        }
        if round + 1 == ROUNDS {
            // Still past after every size-up: the data keeps moving with the size.
            return Err(refusal(worst, given));
        }
        // A power of two above the need: the data moves with the size (descriptors are
        // numbered over every array), and the harness's own words make sums of two below
        // twice the scene's bound, so headroom settles it in one more check.
        grown = Some((grown.map_or(worst.elements, |(from, _)| from), need as u32));
        ctx.sizes.array = Some(need as u32);
        plan.modules = ctx.sizes.apply(std::mem::take(&mut plan.modules));
    }
    unreachable!("every round returns or sizes up, and the last returns")
}

#[cfg(test)]
mod tests {
    use super::*;

    fn array(largest: u32, runtime: bool) -> IndexedArray {
        IndexedArray {
            set: 1,
            binding: 2,
            elements: 64,
            runtime,
            seen: Some(IndexSeen { smallest: 0, largest, nonuniform: None }),
            undecorated: None,
        }
    }

    /// The refusal names the index as the shader computed it (a negative one as negative), asks
    /// for a size only where one can hold it, and always names `--no-index-check`.
    #[test]
    fn refusals_give_advice_that_can_be_followed() {
        let e = refusal(&array(119, true), true).to_string();
        assert!(e.contains("(64 descriptors, as --array-size gave) with 119"), "{e}");
        assert!(
            e.contains("give --array-size 128 or more") && e.contains("--no-index-check"),
            "{e}"
        );
        let e = refusal(&array(-89i32 as u32, true), false).to_string();
        assert!(e.contains("with 4294967207 (-89 if the index is signed)"), "{e}");
        assert!(!e.contains("--array-size 4294967296") && e.contains("--fill"), "{e}");
        let e = refusal(&array(70, false), false).to_string();
        assert!(e.contains("(an array of 64)") && e.contains("SPIR-V"), "{e}");
        assert_eq!(e.lines().count(), 1);
    }
}
