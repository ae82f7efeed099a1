//! A user pipeline's ray types ([`count`]) and which ray type each hit shader serves
//! ([`assign`]). The ray types are the distinct constant SBT record offsets the modules'
//! `OpTraceRayKHR`s use (the DXR / nvpro convention: primary rays offset 0, shadow rays offset 1),
//! contiguous from 0; the harness gives each its own hit groups (`hit_table`). A closest-hit or
//! any-hit serves the ray type whose rays carry its incoming payload's structure (names and
//! locations aside); a module's `ray_type` (`--hit-group K=FILE`) says it where the payload
//! cannot (two ray types with one payload structure, a stage without a payload). An
//! intersection shader has no payload: one serves every ray type's procedural group.
use super::error::HarnessError;
use super::module::UserModule;
use crate::reflect::Ty;

/// SBT record offsets beyond this are refused (no engine has that many ray types).
pub const MAX_RAY_TYPES: u32 = 16;

fn unsupported(s: String) -> HarnessError {
    HarnessError::Unsupported(s)
}

/// The number of ray types `modules` trace: one more than the largest constant SBT record
/// offset (1 when nothing traces), every offset below it used. A non-constant offset, one past
/// [`MAX_RAY_TYPES`], or a gap is refused in one line.
pub fn count(modules: &[&UserModule]) -> Result<u32, HarnessError> {
    let mut used = vec![false];
    for m in modules {
        for t in &m.iface.reflection.traces {
            let Some(k) = t.sbt_offset else {
                return Err(unsupported(format!("{} traces a ray whose SBT record offset is not a constant (a function parameter or a computed value); the harness gives each constant offset a ray type of its own: pass it as a literal, or compile with `glslangValidator -V -Os` and give the .spv so it folds", m.name)));
            };
            if k >= MAX_RAY_TYPES {
                return Err(unsupported(format!("{} traces a ray with SBT record offset {k}; the harness runs ray types (offsets) 0 to {}", m.name, MAX_RAY_TYPES - 1)));
            }
            if used.len() <= k as usize {
                used.resize(k as usize + 1, false);
            }
            used[k as usize] = true;
        }
    }
    used[0] |= modules.iter().all(|m| m.iface.reflection.traces.is_empty());
    if let Some(gap) = used.iter().position(|u| !u) {
        let top = used.len() - 1;
        return Err(unsupported(format!("the rays use SBT record offset {top} but none uses offset {gap}: the harness lays out one hit group per ray type from offset 0 up, so offsets must be 0 to {top} without a gap; trace the missing ray type or renumber the offsets")));
    }
    Ok(used.len() as u32)
}

/// Per ray type, the payload its rays carry and which module's which variable it is; `None`
/// where only non-constant offsets trace (refused by [`count`]).
pub fn payloads(modules: &[&UserModule], types: u32) -> Vec<Option<(Ty, String)>> {
    let mut out = vec![None; types as usize];
    for m in modules {
        for t in &m.iface.reflection.traces {
            let Some(slot) = t.sbt_offset.and_then(|k| out.get_mut(k as usize)) else { continue };
            if slot.is_none() {
                *slot =
                    Some((t.payload.clone(), format!("{}'s payload `{}`", m.name, t.payload_name)));
            }
        }
    }
    out
}

/// The ray type hit shader `m` serves among `types` ray types with `payloads`: its `ray_type`
/// (`--hit-group`), else 0 when there is one, else the one ray type whose payload has its
/// incoming payload's structure. No match, or several, is refused naming `--hit-group`.
pub fn assign(
    m: &UserModule,
    types: u32,
    payloads: &[Option<(Ty, String)>],
) -> Result<Option<u32>, HarnessError> {
    if let Some(k) = m.ray_type {
        if k >= types {
            return Err(unsupported(format!("--hit-group {k}={}: the rays use SBT record offsets 0 to {} only, so no ray reaches hit group {k}; give the offset its rays trace with", m.name, types - 1)));
        }
        return Ok(Some(k));
    }
    if types == 1 {
        return Ok(Some(0));
    }
    if m.iface.stage == "intersection" {
        return Ok(None);
    }
    let Some(p) = &m.iface.reflection.incoming_payload else {
        return Err(unsupported(format!("{} ({}) has no incoming payload it uses (one declared but never read or written is not in the entry point's interface), so rtprobe cannot tell which of the {types} ray types (SBT record offsets 0 to {}) it serves: say it with --hit-group K=FILE", m.name, m.iface.stage, types - 1)));
    };
    let shape = p.ty.shape();
    let matching: Vec<u32> = (0..types)
        .filter(|&k| payloads[k as usize].as_ref().is_some_and(|(ty, _)| ty.shape() == shape))
        .collect();
    match matching.as_slice() {
        [k] => Ok(Some(*k)),
        [] => Err(unsupported(format!("{} ({}) receives `{}` ({}), the payload of none of the rays' {types} ray types (SBT record offsets 0 to {}): say which it serves with --hit-group K=FILE, or give the shaders whose rays carry it", m.name, m.iface.stage, p.name, p.ty.leaves(), types - 1))),
        many => {
            let ks: Vec<String> = many.iter().map(|k| k.to_string()).collect();
            Err(unsupported(format!("{} ({}) receives `{}` ({}), the payload of ray types {} alike, so rtprobe cannot tell which it serves: say it with --hit-group K=FILE", m.name, m.iface.stage, p.name, p.ty.leaves(), ks.join(" and "))))
        }
    }
}
