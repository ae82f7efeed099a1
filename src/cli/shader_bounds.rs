//! `run --shader`'s descriptor-index check, before any variant runs: the given modules with
//! every descriptor-array access recording its index and reading a clamped one
//! (`patches::index_bounds`), traced once in a child on the run's own data. An index at or past
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
use crate::model::index_bounds::{IndexBounds, IndexedArray, FIXED_RULE, RULE};
use crate::model::DescriptorModel;
use crate::patches::index_bounds::{self as pass, Probe, Slot};
use anyhow::Result;

/// Checks after a size-up before giving up (each size-up can move the harness's data).
const ROUNDS: usize = 3;

/// The probe's place and slots for `plan`'s modules: every binding they declare, at the first
/// free set-0 binding (the supplied raygen goes after it).
fn probe(plan: &ShaderPlan) -> (Probe, Vec<bool>) {
    let mut slots: Vec<Slot> = Vec::new();
    let mut runtime = Vec::new();
    for b in plan.modules.iter().flat_map(|m| m.iface.bindings.iter()) {
        match slots.iter_mut().position(|s| (s.set, s.binding) == (b.set, b.binding)) {
            Some(k) => slots[k].count = slots[k].count.min(b.count),
            None => {
                slots.push(Slot { set: b.set, binding: b.binding, count: b.count });
                runtime.push(b.runtime);
            }
        }
    }
    let binding = crate::harness::free_binding(&plan.modules);
    (Probe { set: 0, binding, slots }, runtime)
}

/// The given modules instrumented, or `None` when no module indexes a descriptor array.
fn instrument(ctx: &Ctx, p: &Probe) -> Result<Option<Vec<JobModule>>> {
    let mut out = Vec::new();
    let mut any = 0;
    for m in &ctx.unpatched {
        let bytes: Vec<u8> = m.words.iter().flat_map(|w| w.to_le_bytes()).collect();
        let mut module = crate::patches::load(&bytes)
            .map_err(|e| coded(exit::INTERNAL, format!("the index check: {}: {e}", m.name)))?;
        any += pass::apply(&mut module, p).instrumented;
        out.push(JobModule { words: crate::patches::assemble(&module), ..m.clone() });
    }
    Ok((any > 0).then_some(out))
}

/// One check: the arrays' largest indices, or why there are none.
fn once(ctx: &Ctx, plan: &ShaderPlan) -> Result<Result<Vec<IndexedArray>, String>> {
    let (p, runtime) = probe(plan);
    let Some(modules) = instrument(ctx, &p)? else { return Ok(Ok(vec![])) };
    let mut c = ctx.clone();
    (c.repeat, c.validate, c.gpu_av) = (1, false, false);
    c.unpatched = modules.clone();
    let key = Target::Binding { set: p.set, binding: p.binding, element: None };
    c.fills.0.push(Fill { target: key, bytes: vec![0; 4 * p.slots.len()] });
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
    Ok(Ok(p
        .slots
        .iter()
        .zip(runtime)
        .enumerate()
        .filter_map(|(k, (s, runtime))| {
            Some(IndexedArray {
                set: s.set,
                binding: s.binding,
                elements: s.count,
                runtime,
                largest: word(k)?,
            })
        })
        .filter(|a| a.elements > 1 || a.runtime || a.largest > 0)
        .collect()))
}

/// The one line for an index past a binding the harness may not size up.
fn refusal(a: &IndexedArray, given: bool) -> anyhow::Error {
    let what = if a.runtime && given {
        format!("{} descriptors, as --array-size gave", a.elements)
    } else if a.runtime {
        format!("{} descriptors, the most --array-size allows", a.elements)
    } else {
        format!("an array of {}", a.elements)
    };
    let fix = if a.runtime {
        let size = (a.largest as u64 + 1).next_power_of_two();
        format!("give --array-size {size} or more (descriptors are numbered over every array, so the data moves with the size)")
    } else {
        "--fill the words the index is read from (rtprobe puts small integers in every integer word, docs/your-shader.md)".into()
    };
    coded(
        exit::BAD_INPUT,
        format!(
            "the shader indexes set {} binding {} ({what}) with {} on this run's data: an index past its binding is undefined ({}), so no result would be evidence; {fix}",
            a.set, a.binding, a.largest, if a.runtime { RULE } else { FIXED_RULE }
        ),
    )
}

/// Check the run's indices, sizing runtime arrays up where the harness's own data goes past
/// them; `given`: `--array-size` was.
pub fn check(ctx: &mut Ctx, plan: &mut ShaderPlan, given: bool) -> Result<IndexBounds> {
    let unchecked = IndexBounds::unchecked;
    if ctx.model == DescriptorModel::DescriptorHeap {
        return Ok(unchecked("descriptor heap arrays are not instrumented yet"));
    }
    if plan.injection.is_some() {
        return Ok(unchecked("--inject-fault's fault is in every module"));
    }
    let most = crate::harness::sizes::MAX_ARRAY_SIZE;
    let mut grown = None;
    for _ in 0..ROUNDS {
        let arrays = match once(ctx, plan)? {
            Ok(arrays) => arrays,
            Err(why) => return Ok(IndexBounds { grown, ..unchecked(&why) }),
        };
        let lines: Vec<String> = arrays.iter().map(IndexedArray::line).collect();
        tracing::info!("descriptor indices: {}", lines.join(", "));
        let outside: Vec<&IndexedArray> = arrays.iter().filter(|a| a.outside()).collect();
        if outside.is_empty() {
            return Ok(IndexBounds { arrays, grown, unchecked: None });
        }
        let need = outside.iter().map(|a| a.largest as u64 + 1).max().unwrap_or(0);
        if let Some(a) = outside.iter().find(|a| !a.runtime || given || need > most as u64) {
            return Err(refusal(a, given));
        }
        // A power of two above the need: the data moves with the size (descriptors are
        // numbered over every array), and the harness's own words make sums of two below
        // twice the scene's bound, so headroom settles it in one more check.
        let size = need.next_power_of_two().min(most as u64) as u32;
        let from = grown.map_or(outside[0].elements, |(f, _)| f);
        grown = Some((from, size));
        ctx.sizes.array = Some(size);
        plan.modules = ctx.sizes.apply(std::mem::take(&mut plan.modules));
    }
    Ok(IndexBounds {
        grown,
        ..unchecked("the harness's data kept moving past the sized-up arrays")
    })
}
