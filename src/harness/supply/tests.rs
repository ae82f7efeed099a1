//! A closest-hit alone (a struct payload: nested struct, vec3, array, int, bool) gets a raygen
//! and a miss that compile, validate and fit it; a payload holding a pointer or a 64-bit value
//! is refused naming it; a pipeline with both stages is left alone.
use super::*;
use crate::interface::{self, BindingDesc, HitGroup, PipelineDesc};
use crate::reflect::Count;
use crate::tools::spirv::{validate_input, Validation};
use ash::vk;

const CHIT: &str = r#"#version 460
#extension GL_EXT_ray_tracing : require
struct Surface { vec3 normal; float t; };
struct Shade { Surface surface; vec3 color; uint bounce[2]; int material; bool lit; };
layout(set = 0, binding = 4) readonly buffer Colors { vec4 c[]; } colors;
layout(location = 0) rayPayloadInEXT Shade shade;
hitAttributeEXT vec2 bary;
void main() {
    shade.surface.t = gl_HitTEXT;
    shade.color = colors.c[gl_InstanceCustomIndexEXT].rgb * bary.x;
    shade.bounce[1] = 1u;
    shade.material = -gl_PrimitiveID;
    shade.lit = true;
}
"#;

fn module(kind: ShaderKind, name: &str, glsl: &str) -> UserModule {
    let words =
        crate::shadergen::compile::Compiler::new().unwrap().compile_glsl(kind, name, glsl).unwrap();
    UserModule::new(name, &words).unwrap()
}

/// What a pipeline of `modules` provides: every binding they declare, seen by every stage; one
/// triangle hit group of the closest-hit.
fn desc(modules: &[UserModule]) -> PipelineDesc {
    let all = vk::ShaderStageFlags::RAYGEN_KHR
        | vk::ShaderStageFlags::MISS_KHR
        | vk::ShaderStageFlags::CLOSEST_HIT_KHR;
    let mut bindings = Vec::new();
    for m in modules {
        let v = interface::ModuleInterface::of(&m.iface.reflection);
        for r in v.resources {
            let count = r.array.unwrap_or(1).max(1);
            bindings.push(BindingDesc {
                set: r.set,
                binding: r.binding,
                kind: r.kind,
                count,
                stages: all,
            });
        }
    }
    let chit = modules.iter().position(|m| m.iface.stage == "closest_hit");
    PipelineDesc {
        bindings,
        push: None,
        max_hit_attribute: 32,
        hit_groups: vec![HitGroup { closest_hit: chit, any_hit: None, intersection: None }],
    }
}

#[test]
fn a_closest_hit_alone_gets_a_raygen_and_miss_that_fit_it() {
    let chit = module(ShaderKind::ClosestHit, "shade.rchit", CHIT);
    let incoming = chit.iface.reflection.incoming_payload.clone().unwrap();
    let all = supply(vec![chit]).unwrap();
    let stages: Vec<&str> = all.iter().map(|m| m.iface.stage.as_str()).collect();
    assert_eq!(stages, ["raygen", "closest_hit", "miss"]);
    for m in &all {
        match validate_input(&m.words).0 {
            Validation::Valid | Validation::Unavailable => {}
            other => panic!("{}: {other:?}", m.name),
        }
    }
    // the raygen sends the closest-hit's payload type; the miss receives it
    let sent = &all[0].iface.reflection.payloads[0];
    assert_eq!(sent.ty.shape(), incoming.ty.shape());
    let missed = all[2].iface.reflection.incoming_payload.as_ref().unwrap();
    assert_eq!(missed.ty.shape(), incoming.ty.shape());
    // TLAS and words buffer after the user's highest set-0 binding (4); 4+3+2+1+1 = 11 words
    let b: Vec<(u32, Count)> =
        all[0].iface.reflection.bindings.iter().map(|b| (b.binding, b.count)).collect();
    assert_eq!(b, [(5, Count::One), (6, Count::One)]);
    let words = all[0].iface.bindings[1].clone();
    assert_eq!(
        (words.kind, words.writable),
        (super::super::reflect::BindingKind::StorageBuffer(SIZE * SIZE * 11 * 4), true)
    );
    let ws: Vec<&[u32]> = all.iter().map(|m| m.words.as_slice()).collect();
    interface::check(&ws, &desc(&all)).unwrap();
    // Twin: a miss expecting another payload does not fit
    let mut other = all;
    other[2] = module(ShaderKind::Miss, "sky.rmiss", "#version 460\n#extension GL_EXT_ray_tracing : require\nlayout(location = 0) rayPayloadInEXT vec4 sky;\nvoid main() { sky = vec4(1.0); }\n");
    let ws: Vec<&[u32]> = other.iter().map(|m| m.words.as_slice()).collect();
    assert!(matches!(
        interface::check(&ws, &desc(&other)),
        Err(interface::Mismatch::Payload { .. })
    ));
}

#[test]
fn the_generated_stages_write_every_word_and_the_marker() {
    let chit = module(ShaderKind::ClosestHit, "shade.rchit", CHIT);
    let p = chit.iface.reflection.incoming_payload.clone().unwrap();
    let rgen = raygen_glsl(&p.ty, "p", 0).unwrap();
    for lv in ["payload.surface.normal[2]", "payload.bounce[1]", "payload.lit"] {
        assert!(rgen.contains(&format!("{lv} = ")), "{lv} zeroed: {rgen}");
    }
    assert!(rgen.contains("rtprobeOut.words[base + 10u] = uint(payload.lit);"), "{rgen}");
    assert!(rgen.contains("floatBitsToUint(payload.surface.t)"), "{rgen}");
    let miss = miss_glsl(&p.ty, "p").unwrap();
    assert!(miss.contains("payload.surface.normal[0] = uintBitsToFloat(0x4d495353u);"), "{miss}");
}

#[test]
fn a_payload_with_a_pointer_or_64_bit_value_is_refused_naming_it() {
    let ptr = "#version 460\n#extension GL_EXT_ray_tracing : require\n#extension GL_EXT_buffer_reference : require\n\
        layout(buffer_reference) buffer Node { vec4 v; };\nstruct P { vec4 c; Node node; };\n\
        layout(location = 0) rayPayloadInEXT P p;\nvoid main() { p.c = p.node.v; }\n";
    let e =
        supply(vec![module(ShaderKind::ClosestHit, "node.rchit", ptr)]).unwrap_err().to_string();
    assert!(
        e.contains("node.rchit's payload `p`")
            && e.contains("payload.node, a pointer")
            && e.contains("--shader"),
        "{e}"
    );
    let wide = "#version 460\n#extension GL_EXT_ray_tracing : require\n#extension GL_EXT_shader_explicit_arithmetic_types_int64 : require\n\
        layout(location = 0) rayPayloadInEXT uint64_t id;\nvoid main() { id = 7ul; }\n";
    let e = supply(vec![module(ShaderKind::ClosestHit, "id.rchit", wide)]).unwrap_err().to_string();
    assert!(e.contains("not a 32-bit scalar") && e.contains("--shader"), "{e}");
}

#[test]
fn a_pipeline_with_raygen_and_miss_is_left_alone() {
    let rgen = "#version 460\n#extension GL_EXT_ray_tracing : require\nlayout(location = 0) rayPayloadEXT vec4 c;\n\
        layout(set = 0, binding = 0) uniform accelerationStructureEXT t;\n\
        void main() { traceRayEXT(t, 0u, 0xFF, 0, 0, 0, vec3(0), 0.0, vec3(1), 1.0, 0); }\n";
    let miss = "#version 460\n#extension GL_EXT_ray_tracing : require\nlayout(location = 0) rayPayloadInEXT vec4 c;\nvoid main() { c = vec4(0); }\n";
    let given =
        vec![module(ShaderKind::RayGeneration, "r", rgen), module(ShaderKind::Miss, "m", miss)];
    let words: Vec<Vec<u32>> = given.iter().map(|m| m.words.clone()).collect();
    let out = supply(given).unwrap();
    assert_eq!(out.iter().map(|m| m.words.clone()).collect::<Vec<_>>(), words);
    // Twin: without the miss, one is supplied receiving the raygen's vec4
    let out = supply(vec![module(ShaderKind::RayGeneration, "r", rgen)]).unwrap();
    let p = out[1].iface.reflection.incoming_payload.as_ref().unwrap();
    assert_eq!((out[1].iface.stage.as_str(), p.size), ("miss", 16));
}
