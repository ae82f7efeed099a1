//! SPIR-V in → out for an acceleration structure access's fault: GLSL written for these tests
//! (an engine's shadow ray and ray-query shadow, an AS array) compiled by shaderc, the fault
//! inserted after each AS descriptor load and tied to the cull mask of each ray the handle
//! traces, held to spirv-val; the twins: no AS load, an AS from an address (`as-to-address`'s
//! output), a handle that traces nothing.
use super::tests::{marked, reaches, valid};
use super::*;
use crate::model::{IndexSource, Resource, Stage};
use crate::patches::{assemble, compiled, PatchName};
use rspirv::spirv::{Op, Word};
use shaderc::ShaderKind;

/// A closest-hit shading with a shadow ray through the scene TLAS, and with a ray query
/// through one of two cascades' TLASes (an array at a constant index); a lit counter SSBO.
const SHADOW: &str = r#"#version 460
#extension GL_EXT_ray_tracing : require
#extension GL_EXT_ray_query : require
layout(set = 0, binding = 0) uniform accelerationStructureEXT scene;
layout(set = 0, binding = 1) uniform accelerationStructureEXT cascades[2];
layout(set = 0, binding = 2) buffer Lit { uint hits; } lit;
layout(location = 0) rayPayloadInEXT vec4 shade;
layout(location = 1) rayPayloadEXT bool shadowed;
void main() {
    vec3 at = gl_WorldRayOriginEXT + gl_WorldRayDirectionEXT * gl_HitTEXT;
    vec3 sun = normalize(vec3(0.3, 0.8, -0.5));
    shadowed = true;
    traceRayEXT(scene, gl_RayFlagsTerminateOnFirstHitEXT | gl_RayFlagsSkipClosestHitShaderEXT,
                0xFF, 0, 0, 1, at, 0.01, sun, 100.0, 1);
    rayQueryEXT q;
    rayQueryInitializeEXT(q, cascades[1], gl_RayFlagsTerminateOnFirstHitEXT, 0xFF, at, 0.01, sun, 100.0);
    while (rayQueryProceedEXT(q)) {}
    bool far = rayQueryGetIntersectionTypeEXT(q, true) != gl_RayQueryCommittedIntersectionNoneEXT;
    atomicAdd(lit.hits, 1u);
    shade = vec4(shadowed || far ? 0.2 : 1.0);
}
"#;

/// The same scene TLAS loaded but never traced: its fault would have nothing to feed.
const UNTRACED: &str = r#"#version 460
#extension GL_EXT_ray_tracing : require
#extension GL_EXT_ray_query : require
layout(set = 0, binding = 0) uniform accelerationStructureEXT scene;
layout(location = 0) rayPayloadInEXT vec4 shade;
void main() {
    rayQueryEXT q;
    rayQueryInitializeEXT(q, scene, 0u, 0xFF, vec3(0.0), 0.0, vec3(1.0, 0.0, 0.0), 1.0);
    shade = vec4(1.0);
}
"#;

fn shadow() -> Module {
    compiled(ShaderKind::ClosestHit, "shadow.rchit", SHADOW)
}

fn request(s: &str) -> Request {
    Request::parse(s).unwrap()
}

fn body(m: &Module) -> impl Iterator<Item = &rspirv::dr::Instruction> {
    m.functions.iter().flat_map(|f| f.blocks.iter().flat_map(|b| b.instructions.iter()))
}

/// Each ray's cull mask operand: the trace's third, the query's fourth.
fn cull_masks(m: &Module) -> Vec<Word> {
    body(m)
        .filter_map(|i| match i.class.opcode {
            Op::TraceRayKHR => crate::patches::edit::id_operand(i, 2),
            Op::RayQueryInitializeKHR => crate::patches::edit::id_operand(i, 3),
            _ => None,
        })
        .collect()
}

#[test]
fn acceleration_structure_loads_are_literal_accesses() {
    let m = shadow();
    let found: Vec<Access> = sites::find(&m)
        .iter()
        .filter(|s| s.access.resource == Resource::AccelerationStructure)
        .map(|s| s.access)
        .collect();
    let want = Access {
        stage: Stage::ClosestHit,
        resource: Resource::AccelerationStructure,
        index: IndexSource::Literal,
    };
    assert_eq!(found, [want; 2]);
}

#[test]
fn a_device_fault_follows_each_as_load_and_feeds_its_rays_cull_masks() {
    let mut m = shadow();
    let got = inject(&mut m, &request("stage=closest_hit,resource=acceleration_structure@device"));
    assert_eq!(got.sites.len(), 2, "{got:?}");
    assert!(got.skipped.is_empty(), "{got:?}");
    assert!(got.sites[0].contains("acceleration_structure scene (literal index)"), "{got:?}");
    assert!(got.sites[1].contains("cascades"), "{got:?}");
    assert_eq!(count(&m), 2);
    valid(&m);
    // Every ray's cull mask now depends on a fault: no compiler may drop it.
    let faults = marked(&m);
    let masks = cull_masks(&m);
    assert_eq!(masks.len(), 2);
    for mask in masks {
        assert!(faults.iter().any(|f| reaches(&m, mask, *f, 32)), "cull mask %{mask} is not fed");
    }
    // The SSBO atomic did not match the AS predicate.
    assert!(got.sites.iter().all(|s| !s.contains("storage_buffer")), "{got:?}");
}

#[test]
fn a_hang_follows_an_as_load_and_feeds_its_ray() {
    let mut m = shadow();
    let got = inject(&mut m, &request("resource=acceleration_structure@hang"));
    assert_eq!((got.sites.len(), count(&m)), (2, 2), "{got:?}");
    valid(&m);
    let loops: Vec<Word> =
        body(&m).filter(|i| i.class.opcode == Op::Phi).filter_map(|i| i.result_id).collect();
    for mask in cull_masks(&m) {
        assert!(loops.iter().any(|c| reaches(&m, mask, *c, 32)), "cull mask %{mask} is not fed");
    }
}

/// The twins: a module without an AS load, one whose AS comes from an address (what
/// `as-to-address` writes: `OpConvertUToAccelerationStructureKHR` is no descriptor read), and
/// one whose handle traces no ray get no fault.
#[test]
fn twins_no_as_load_an_address_or_no_ray_get_no_fault() {
    let r = request("resource=acceleration_structure@device");
    let mut plain = compiled(ShaderKind::ClosestHit, "p.rchit", super::tests::HIT);
    assert!(inject(&mut plain, &r).sites.is_empty());
    assert_eq!(count(&plain), 0);

    let mut patched = shadow();
    let lines = crate::patches::apply(&mut patched, &[PatchName::AsToAddress], &Default::default())
        .unwrap();
    assert!(!lines.is_empty());
    let converts =
        body(&patched).filter(|i| i.class.opcode == Op::ConvertUToAccelerationStructureKHR).count();
    assert_eq!(converts, 2, "as-to-address made both AS from addresses");
    assert!(sites::find(&patched)
        .iter()
        .all(|s| s.access.resource != Resource::AccelerationStructure));
    let before = assemble(&patched);
    let got = inject(&mut patched, &r);
    assert!(got.sites.is_empty() && got.skipped.is_empty(), "{got:?}");
    assert_eq!(assemble(&patched), before, "nothing matched: unchanged");

    // The unpatched module with the same request does get faults (the twin's other half).
    assert_eq!(inject(&mut shadow(), &r).sites.len(), 2);

    let mut untraced = compiled(ShaderKind::ClosestHit, "u.rchit", UNTRACED);
    assert_eq!(inject(&mut untraced.clone(), &r).sites.len(), 1, "the query traces it");
    // Remove the query: the handle is loaded, traces nothing, and gets no fault.
    for f in untraced.functions.iter_mut() {
        for b in f.blocks.iter_mut() {
            b.instructions.retain(|i| i.class.opcode != Op::RayQueryInitializeKHR);
        }
    }
    let got = inject(&mut untraced, &r);
    assert!(got.sites.is_empty(), "{got:?}");
    assert!(got.skipped[0].contains("traces no ray"), "{got:?}");
    assert_eq!(count(&untraced), 0);
}
