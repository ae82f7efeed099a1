//! The checks of [`check`]: resources, push constants, payloads and callable data, hit
//! attributes (the rules are in the module doc).
use super::error::Mismatch;
use super::layout::PipelineDesc;
use super::view::{IoShape, ModuleInterface};

/// The first way `modules` (SPIR-V words, in the pipeline's stage order) do not fit `pipeline`.
pub fn check(modules: &[&[u32]], pipeline: &PipelineDesc) -> Result<(), Mismatch> {
    let read =
        modules.iter().enumerate().map(|(k, w)| read(k, w)).collect::<Result<Vec<_>, _>>()?;
    check_read(&read, pipeline)
}

/// Module `k` of a pipeline read, or why it cannot be.
pub fn read(k: usize, words: &[u32]) -> Result<ModuleInterface, Mismatch> {
    ModuleInterface::read(words).map_err(|source| Mismatch::Unreadable {
        module: k,
        stage: ash::vk::ShaderStageFlags::empty(),
        source,
    })
}

/// [`check`] of modules already read (a caller that checks many pipelines of the same modules
/// reads each once).
pub fn check_read(read: &[ModuleInterface], pipeline: &PipelineDesc) -> Result<(), Mismatch> {
    for m in read {
        resources(m, pipeline)?;
        push(m, pipeline)?;
    }
    calls(read)?;
    hit_attributes(read, pipeline)
}

fn resources(m: &ModuleInterface, p: &PipelineDesc) -> Result<(), Mismatch> {
    for r in &m.resources {
        let (set, binding, stage) = (r.set, r.binding, m.stage);
        let shader = r.kind.as_str();
        let Some(b) = p.bindings.iter().find(|b| b.set == set && b.binding == binding) else {
            return Err(Mismatch::NoBinding { set, binding, stage, shader });
        };
        if !b.stages.contains(stage) {
            return Err(Mismatch::NotVisible { set, binding, stage });
        }
        if !b.kind.backs(r.kind) {
            let layout = b.kind.as_str();
            return Err(Mismatch::Kind { set, binding, stage, shader, layout });
        }
        let needed = r.array.unwrap_or(1);
        if needed > b.count {
            return Err(Mismatch::Count { set, binding, stage, shader: needed, layout: b.count });
        }
    }
    Ok(())
}

fn push(m: &ModuleInterface, p: &PipelineDesc) -> Result<(), Mismatch> {
    let Some((start, end)) = m.push else { return Ok(()) };
    let fits = p.push.is_some_and(|r| {
        r.stages.contains(m.stage) && start >= r.offset && end <= r.offset + r.size
    });
    if fits {
        return Ok(());
    }
    let range = match p.push {
        Some(r) if r.stages.contains(m.stage) => format!("{}..{}", r.offset, r.offset + r.size),
        Some(_) | None => "none".into(),
    };
    Err(Mismatch::Push { stage: m.stage, start, end, range })
}

/// Incoming payloads and callable data against what the pipeline's stages send. A pipeline whose
/// stages send none (a raygen that traces no ray, as the canaries' do) never invokes the stages
/// that receive them, so there is nothing to match: the Ray Tracing Pipeline Interface rules bind
/// a receiving stage to the payload of the `OpTraceRayKHR` that invokes it.
fn calls(read: &[ModuleInterface]) -> Result<(), Mismatch> {
    let sent: Vec<&IoShape> = read.iter().flat_map(|m| &m.payloads).collect();
    let passed: Vec<&IoShape> = read.iter().flat_map(|m| &m.callable_data).collect();
    let list = |v: &[&IoShape]| v.iter().map(|s| s.to_string()).collect::<Vec<_>>().join("; ");
    for m in read {
        let unsent = m.incoming_payload.as_ref().filter(|s| !sent.is_empty() && !sent.contains(s));
        if let Some(got) = unsent {
            let (got, sent) = (got.to_string(), list(&sent));
            return Err(Mismatch::Payload { stage: m.stage, got, sent });
        }
        let unpassed =
            m.incoming_callable_data.as_ref().filter(|s| !passed.is_empty() && !passed.contains(s));
        if let Some(got) = unpassed {
            let (got, sent) = (got.to_string(), list(&passed));
            return Err(Mismatch::CallableData { stage: m.stage, got, sent });
        }
    }
    Ok(())
}

/// Every hit attribute within the device's limit; per hit group, the closest-hit and any-hit
/// attribute is the intersection shader's, or two floats (8 bytes) without one.
fn hit_attributes(read: &[ModuleInterface], p: &PipelineDesc) -> Result<(), Mismatch> {
    for m in read {
        if let Some(a) = m.hit_attribute.as_ref().filter(|a| a.size > p.max_hit_attribute) {
            let expected =
                format!("the device's maxRayHitAttributeSize is {}", p.max_hit_attribute);
            return Err(Mismatch::HitAttribute { stage: m.stage, got: a.to_string(), expected });
        }
    }
    let barycentrics = IoShape::barycentrics();
    for g in &p.hit_groups {
        let written = g.intersection.and_then(|i| read.get(i)?.hit_attribute.clone());
        let (want, what) = match (g.intersection, written) {
            (Some(_), Some(s)) => {
                let what = format!("its intersection shader writes {s}");
                (s, what)
            }
            (Some(_), None) => continue,
            (None, _) => {
                (barycentrics.clone(), format!("a triangle hit's attribute is {barycentrics}"))
            }
        };
        for k in [g.closest_hit, g.any_hit].into_iter().flatten() {
            let Some(m) = read.get(k) else { continue };
            let fits = |a: &IoShape| match g.intersection {
                Some(_) => *a == want,
                None => a.is_barycentrics(),
            };
            if let Some(a) = m.hit_attribute.as_ref().filter(|a| !fits(a)) {
                let (got, expected) = (a.to_string(), what);
                return Err(Mismatch::HitAttribute { stage: m.stage, got, expected });
            }
        }
    }
    Ok(())
}
