//! The rays the modules trace, against the pipeline the harness builds from them. [`miss_payloads`]
//! says which miss shaders the pipeline needs: one per constant `MissIndex` any `OpTraceRayKHR`
//! uses, each receiving that ray's payload (the miss record is `pMissShaderBindingTable->stride ×
//! missIndex` from the table's start, and "All data accessed must be less than
//! pMissShaderBindingTable->size bytes from the base address": Vulkan 1.4.360, Ray Tracing,
//! Shader Binding Table Indexing Rules). [`check`] holds every stage a traced ray can invoke to
//! its payload: "The ray payload for a shader invoked by a ray tracing command must be the same
//! structure for all shader stages using the payload for that ray" (Vulkan 1.4.360, Shader
//! Interfaces, Ray Tracing Pipeline Interface) — a closest-hit unless the ray's constant flags
//! skip it (`gl_RayFlagsSkipClosestHitShaderEXT`), an any-hit unless they make it opaque, the
//! miss at its index — of the hit groups of the ray's type (its constant SBT record offset,
//! `ray_types`; the hit table in `hit_table`).
use super::error::HarnessError;
use super::groups::{Groups, TypeGroups};
use super::module::UserModule;
use crate::reflect::{Trace, Ty, FLAG_OPAQUE, FLAG_SKIP_CLOSEST_HIT};

/// The pipeline's `maxPipelineRayRecursionDepth` for `modules` on a device allowing `max`: 2
/// (at most `max`) when only the raygen traces, else `max` itself — a closest-hit or miss that
/// traces may recurse as deep as its own guard, and "This command must not cause a shader call
/// instruction to be executed from a shader invocation with a recursion depth greater than the
/// value of maxPipelineRayRecursionDepth used to create the bound ray tracing pipeline"
/// (VUID-vkCmdTraceRaysKHR-maxPipelineRayRecursionDepth-03679, Vulkan 1.4.360): a guard deeper
/// than the device allows is the shader's undefined behaviour, which no pipeline can avoid.
pub fn recursion_depth(modules: &[&UserModule], max: u32) -> Result<u32, HarnessError> {
    let deep =
        modules.iter().find(|m| m.iface.stage != "raygen" && !m.iface.reflection.traces.is_empty());
    match deep {
        Some(m) if max < 2 => Err(unsupported(format!("{} ({}) traces a ray, but this device's maxRayRecursionDepth is {max}: its trace would run at depth 2, past the limit, which is undefined (VUID-vkCmdTraceRaysKHR-maxPipelineRayRecursionDepth-03679, Vulkan 1.4.360); run it on a device allowing 2 or more", m.name, m.iface.stage))),
        Some(_) => Ok(max),
        None => Ok(max.clamp(1, 2)),
    }
}

/// The ray type's groups ray `t` reaches in `g` (none: a non-constant or unknown offset).
fn type_of(g: &Groups, t: &Trace) -> Option<TypeGroups> {
    t.sbt_offset.and_then(|k| g.types.get(k as usize)).copied()
}

/// The stages a ray `t` can invoke in the pipeline `g` makes of `modules`: its miss, its ray
/// type's closest-hits unless its constant flags skip them (any-hit and intersection shaders
/// cannot trace, so they are left out).
fn invoked<'a>(modules: &'a [&UserModule], g: &Groups, t: &Trace) -> Vec<&'a UserModule> {
    let miss = t.miss_index.and_then(|k| g.misses.get(k as usize)).map(|&i| modules[i]);
    let hits = match type_of(g, t) {
        Some(ty) if !t.has_flag(FLAG_SKIP_CLOSEST_HIT) => ty.hit,
        _ => [None, None],
    };
    miss.into_iter().chain(hits.into_iter().flatten().map(|i| modules[i])).collect()
}

/// Whether the pipeline recurses without a bound rtprobe can see: a ray traced by a hit or miss
/// shader can invoke a stage that traces again, so the depth reached is the shaders' own guard's
/// (a payload depth counter), which rtprobe cannot read. The sentence names the cycle's first
/// pair and the rule that makes a guard past the device's limit undefined.
pub fn unbounded_recursion(modules: &[&UserModule]) -> Option<String> {
    let g = super::groups::groups(modules).ok()?;
    for m in modules.iter().filter(|m| m.iface.stage != "raygen") {
        for t in &m.iface.reflection.traces {
            let again =
                invoked(modules, &g, t).into_iter().find(|s| !s.iface.reflection.traces.is_empty());
            if let Some(s) = again {
                return Some(format!("{} traces rays that invoke {}, which traces again: the depth reached is your shaders' own guard's, which rtprobe cannot see; a fault is the driver's only if that guard stops at the device's maxRayRecursionDepth, past which a trace is undefined (VUID-vkCmdTraceRaysKHR-maxPipelineRayRecursionDepth-03679, Vulkan 1.4.360)", m.name, s.name));
            }
        }
    }
    None
}

/// Miss indices beyond this are refused (no engine has that many miss shaders).
pub const MAX_MISS_INDEX: u32 = 63;

fn unsupported(s: String) -> HarnessError {
    HarnessError::Unsupported(s)
}

/// A trace's payload as the messages name it.
fn said(t: &Trace) -> String {
    match t.payload_name.as_str() {
        "" => format!("a payload of type {}", t.payload.leaves()),
        n => format!("payload `{n}` ({})", t.payload.leaves()),
    }
}

/// Per miss index 0..=max used, the payload type the rays with that index carry and what it is
/// ("NAME's payload `p`"; `None`: no ray uses the index). `raygen` is the supplied raygen's
/// payload and what it is (it traces with miss index 0). A non-constant or too large index, or two payload types at one index, is
/// refused in one line.
pub fn miss_payloads(
    modules: &[UserModule],
    raygen: Option<(&Ty, &str)>,
) -> Result<Vec<Option<(Ty, String)>>, HarnessError> {
    let mut out: Vec<Option<(Ty, String)>> = Vec::new();
    let supplied = raygen.map(|(ty, what)| (0, ty.clone(), what.to_string()));
    let traced = modules.iter().flat_map(|m| m.iface.reflection.traces.iter().map(move |t| (m, t)));
    let mut rays = Vec::new();
    for (m, t) in traced {
        let Some(k) = t.miss_index else {
            return Err(unsupported(format!("{} traces a ray whose miss index is not a constant; rtprobe supplies one miss shader per constant index: make the index a literal", m.name)));
        };
        if k > MAX_MISS_INDEX {
            return Err(unsupported(format!("{} traces a ray with miss index {k}; rtprobe supplies miss shaders up to index {MAX_MISS_INDEX}", m.name)));
        }
        rays.push((k, t.payload.clone(), format!("{}'s payload `{}`", m.name, t.payload_name)));
    }
    for (k, ty, who) in supplied.into_iter().chain(rays) {
        let k = k as usize;
        if out.len() <= k {
            out.resize(k + 1, None);
        }
        match &out[k] {
            Some((seen, first)) if seen.shape() != ty.shape() => {
                return Err(unsupported(format!("{who} and {first} are traced with miss index {k} but differ ({} and {}): one miss shader cannot receive both; give your miss shaders with --shader", ty.leaves(), seen.leaves())));
            }
            Some(_) => {}
            None => out[k] = Some((ty, who)),
        }
    }
    Ok(out)
}

/// `stage` receives its incoming payload from ray `t` traced by `tracer`: the same structure.
/// A ray whose flags are no constant may skip the stage: refused as unknown, not as invalid.
fn receives(tracer: &str, t: &Trace, stage: &UserModule) -> Result<(), HarnessError> {
    let Some(p) = &stage.iface.reflection.incoming_payload else { return Ok(()) };
    if p.ty.shape() == t.payload.shape() {
        return Ok(());
    }
    let (ray, theirs) = (said(t), format!("{} ({})", stage.name, stage.iface.stage));
    let got = format!("`{}` ({})", p.name, p.ty.leaves());
    if t.flags.is_none() && stage.iface.stage != "miss" {
        return Err(unsupported(format!(
            "{tracer} traces a ray with {ray} whose flags are not a constant where it traces (a function parameter or a computed value), so rtprobe cannot tell whether it skips {theirs}, which receives {got}: pass the flags as a literal, or compile with `glslangValidator -V -Os` and give the .spv so they fold"
        )));
    }
    Err(HarnessError::Interface(format!(
        "{tracer} traces a ray with {ray} that {theirs} would receive as {got}: every stage a ray invokes must use its payload's structure (Vulkan 1.4.360, Ray Tracing Pipeline Interface); set gl_RayFlagsSkipClosestHitShaderEXT (or Opaque for an any-hit) on that ray if it skips the stage, or give the stages that ray really invokes"
    )))
}

/// Every ray the modules trace against the stages of the pipeline `groups` makes of them: its
/// miss, and its ray type's closest-hits (unless skipped), any-hit (unless opaque) and
/// intersection shader; the hit table laid out over the harness scene's meshes
/// (`hit_table::layout`: strides that make two ray types share a record are refused).
pub fn check(modules: &[UserModule]) -> Result<(), HarnessError> {
    let refs: Vec<&UserModule> = modules.iter().collect();
    let g = super::groups::groups(&refs)?;
    let geometries = crate::scene::GEOMETRIES_PER_MESH;
    super::hit_table::layout(&refs, g.types.len() as u32, geometries)?;
    for m in modules {
        for t in &m.iface.reflection.traces {
            let Some(ty) = type_of(&g, t) else {
                return Err(unsupported(format!("{} traces a ray whose SBT record offset is not a constant; pass it as a literal", m.name)));
            };
            let miss = t.miss_index.and_then(|k| g.misses.get(k as usize));
            let Some(&miss) = miss else {
                return Err(unsupported(format!(
                    "{} traces a ray with a miss index the pipeline has no miss shader for",
                    m.name
                )));
            };
            receives(&m.name, t, &modules[miss])?;
            if !t.has_flag(FLAG_SKIP_CLOSEST_HIT) {
                let procedural = ty.intersection.is_some().then_some(ty.hit[1]).flatten();
                for k in ty.hit[0].into_iter().chain(procedural) {
                    receives(&m.name, t, &modules[k])?;
                }
            }
            if let Some(k) = ty.any_hit.filter(|_| !t.has_flag(FLAG_OPAQUE)) {
                receives(&m.name, t, &modules[k])?;
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests;
