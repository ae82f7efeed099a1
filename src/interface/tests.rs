//! Unit tests of the interface check: an engine-like ray tracing pipeline (written for these
//! tests: a camera raygen, a material closest-hit, a sky miss, a sphere intersection) fits the
//! layout that describes it, and each twin — one binding, count, stage, push range, payload or hit
//! attribute changed — is a mismatch that names it.
use super::*;
use crate::shadergen::compile::Compiler;
use ash::vk;
use shaderc::ShaderKind;

const COMMON: &str = r#"#version 460
#extension GL_EXT_ray_tracing : require
#extension GL_EXT_nonuniform_qualifier : require
struct Shade { vec4 color; uint depth; uint flags; };
layout(push_constant) uniform Frame { mat4 view; uvec4 frame; } frame;
"#;

const RAYGEN: &str = r#"
layout(set = 0, binding = 0) uniform accelerationStructureEXT scene;
layout(set = 0, binding = 1, rgba8) uniform writeonly image2D target;
layout(location = 0) rayPayloadEXT Shade shade;
void main() {
    vec3 o = (frame.view * vec4(0.0, 0.0, 0.0, 1.0)).xyz;
    traceRayEXT(scene, gl_RayFlagsOpaqueEXT, 0xFF, 0, 0, 0, o, 0.001, vec3(0.0, 0.0, 1.0), 100.0, 0);
    imageStore(target, ivec2(gl_LaunchIDEXT.xy), shade.color);
}
"#;

const CLOSEST: &str = r#"
struct Material { vec4 albedo; uint texture; uint pad[3]; };
layout(set = 1, binding = 0, std430) readonly buffer Materials { Material m[]; } materials[];
layout(set = 1, binding = 1) uniform sampler2D textures[8];
layout(location = 0) rayPayloadInEXT Shade shade;
hitAttributeEXT vec2 bary;
void main() {
    Material mat = materials[nonuniformEXT(gl_InstanceCustomIndexEXT)].m[gl_PrimitiveID];
    shade.color = mat.albedo * textureLod(textures[mat.texture & 7u], bary, 0.0);
    shade.depth += frame.frame.x;
}
"#;

const MISS: &str = r#"
layout(location = 0) rayPayloadInEXT Shade shade;
void main() { shade.color = vec4(0.2, 0.3, 0.9, 1.0); }
"#;

const SPHERE: &str = r#"
hitAttributeEXT vec2 uv;
void main() { uv = vec2(0.5); reportIntersectionEXT(1.0, 0u); }
"#;

fn compile(kind: ShaderKind, body: &str) -> Vec<u32> {
    Compiler::new().unwrap().compile_glsl(kind, "t.glsl", &format!("{COMMON}{body}")).unwrap()
}

/// The engine's modules in pipeline order: raygen, miss, triangle closest-hit, sphere
/// intersection, sphere closest-hit (the material shader reused).
fn engine() -> Vec<Vec<u32>> {
    vec![
        compile(ShaderKind::RayGeneration, RAYGEN),
        compile(ShaderKind::Miss, MISS),
        compile(ShaderKind::ClosestHit, CLOSEST),
        compile(ShaderKind::Intersection, SPHERE),
        compile(ShaderKind::ClosestHit, CLOSEST),
    ]
}

fn rt_stages() -> vk::ShaderStageFlags {
    vk::ShaderStageFlags::RAYGEN_KHR
        | vk::ShaderStageFlags::MISS_KHR
        | vk::ShaderStageFlags::CLOSEST_HIT_KHR
        | vk::ShaderStageFlags::INTERSECTION_KHR
}

fn layout() -> PipelineDesc {
    let b =
        |set, binding, kind, count| BindingDesc { set, binding, kind, count, stages: rt_stages() };
    PipelineDesc {
        bindings: vec![
            b(0, 0, DescriptorKind::AccelerationStructure, 1),
            b(0, 1, DescriptorKind::StorageImage, 1),
            b(1, 0, DescriptorKind::StorageBuffer, 64),
            b(1, 1, DescriptorKind::CombinedImageSampler, 8),
        ],
        push: Some(PushRange { offset: 0, size: 80, stages: rt_stages() }),
        max_hit_attribute: 32,
        hit_groups: vec![
            HitGroup { closest_hit: Some(2), any_hit: None, intersection: None },
            HitGroup { closest_hit: Some(4), any_hit: None, intersection: Some(3) },
        ],
    }
}

fn fit(modules: &[Vec<u32>], desc: &PipelineDesc) -> Result<(), Mismatch> {
    let m: Vec<&[u32]> = modules.iter().map(|w| w.as_slice()).collect();
    check(&m, desc)
}

#[test]
fn the_engine_reads_as_declared_and_fits_its_layout() {
    let m = engine();
    let chit = ModuleInterface::read(&m[2]).unwrap();
    assert_eq!(chit.stage, vk::ShaderStageFlags::CLOSEST_HIT_KHR);
    assert_eq!(
        chit.resources,
        vec![
            view::Resource {
                set: 1,
                binding: 0,
                kind: DescriptorKind::StorageBuffer,
                array: Some(0)
            },
            view::Resource {
                set: 1,
                binding: 1,
                kind: DescriptorKind::CombinedImageSampler,
                array: Some(8)
            },
        ]
    );
    // mat4 + uvec4; Shade is vec4 + 2 uints; two floats of barycentrics
    assert_eq!(
        (chit.push, chit.incoming_payload.map(|p| p.size), chit.hit_attribute.map(|a| a.size)),
        (Some((0, 80)), Some(24), Some(8))
    );
    let sent = ModuleInterface::read(&m[0]).unwrap().payloads;
    assert_eq!(
        sent.iter().map(|p| p.structure.as_str()).collect::<Vec<_>>(),
        ["{vec4<f32>, u32, u32}"]
    );
    assert_eq!(fit(&m, &layout()), Ok(()));
}

/// Each twin changes one thing the pipeline provides, or one module: the mismatch names it.
#[test]
fn every_twin_is_a_mismatch_naming_what_does_not_fit() {
    let m = engine();
    let with = |f: &dyn Fn(&mut PipelineDesc)| {
        let mut d = layout();
        f(&mut d);
        fit(&m, &d).unwrap_err()
    };
    let e = with(&|d| d.bindings[1].kind = DescriptorKind::UniformBuffer);
    assert!(matches!(e, Mismatch::Kind { set: 0, binding: 1, .. }), "{e}");
    assert!(
        e.to_string().contains("set 0 binding 1") && e.to_string().contains("storage image"),
        "{e}"
    );
    let e = with(&|d| d.bindings[3].count = 4);
    assert!(matches!(e, Mismatch::Count { set: 1, binding: 1, shader: 8, layout: 4, .. }), "{e}");
    let e = with(&|d| {
        d.bindings.remove(2);
    });
    assert!(matches!(e, Mismatch::NoBinding { set: 1, binding: 0, .. }), "{e}");
    let e = with(&|d| d.bindings[2].stages = vk::ShaderStageFlags::RAYGEN_KHR);
    assert!(matches!(e, Mismatch::NotVisible { set: 1, binding: 0, .. }), "{e}");
    let e = with(&|d| d.push = Some(PushRange { offset: 0, size: 64, stages: rt_stages() }));
    assert!(matches!(e, Mismatch::Push { start: 0, end: 80, .. }), "{e}");
    let e = with(&|d| d.push = None);
    assert!(e.to_string().contains("range for it is none"), "{e}");
    let e = with(&|d| d.max_hit_attribute = 4);
    assert!(matches!(&e, Mismatch::HitAttribute { got, .. } if got.contains("8 bytes")), "{e}");
    // modules: a miss shader expecting another payload, an intersection writing more than the
    // closest-hit reads, a triangle closest-hit reading three floats
    let mut other = m.clone();
    other[1] = compile(
        ShaderKind::Miss,
        "layout(location = 0) rayPayloadInEXT vec4 sky;\nvoid main() { sky = vec4(1.0); }\n",
    );
    let e = fit(&other, &layout()).unwrap_err();
    assert!(matches!(&e, Mismatch::Payload { got, .. } if got == "vec4<f32> (16 bytes)"), "{e}");
    let mut other = m.clone();
    other[3] = compile(ShaderKind::Intersection, "hitAttributeEXT vec4 uvw;\nvoid main() { uvw = vec4(0.5); reportIntersectionEXT(1.0, 0u); }\n");
    let e = fit(&other, &layout()).unwrap_err();
    assert!(
        matches!(&e, Mismatch::HitAttribute { got, .. } if got.contains("8 bytes"))
            && e.to_string().contains("writes vec4<f32> (16 bytes)"),
        "{e}"
    );
    let mut other = m.clone();
    other[2] = compile(
        ShaderKind::ClosestHit,
        &CLOSEST.replace(
            "hitAttributeEXT vec2 bary;",
            "hitAttributeEXT vec3 bary3;\nvec2 bary = bary3.xy;",
        ),
    );
    let e = fit(&other, &layout()).unwrap_err();
    assert!(matches!(&e, Mismatch::HitAttribute { got, .. } if got.contains("12 bytes")), "{e}");
    // not SPIR-V at all
    let e = fit(&[vec![0x0723_0203, 0, 0, 9, 0, 0x0009_0011]], &layout()).unwrap_err();
    assert!(matches!(e, Mismatch::Unreadable { module: 0, .. }), "{e}");
    assert!(matches!(fit(&[vec![1, 2, 3]], &layout()), Err(Mismatch::Unreadable { .. })));
}

/// Payloads compare by structure, not size: a float where the raygen sends a uint in the same
/// bytes is a mismatch (the size-only check let it through), and so are the same scalars grouped
/// otherwise; the same structure under other names is not one. A triangle hit's attribute is
/// two floats however grouped (DXC's struct-wrapped barycentrics), a float and a uint are not.
#[test]
fn the_same_size_with_other_scalars_is_a_mismatch() {
    let m = engine();
    let mut other = m.clone();
    // the same size, another structure (a float where the raygen sends a uint): a mismatch
    // the old size-only check let through; the same structure under other names is not one
    other[1] = compile(
        ShaderKind::Miss,
        "struct Sky { vec4 c; float t; uint i; };\nlayout(location = 0) rayPayloadInEXT Sky sky;\nvoid main() { sky.c = vec4(1.0); }\n",
    );
    let e = fit(&other, &layout()).unwrap_err();
    assert!(matches!(&e, Mismatch::Payload { got, .. } if got.contains("f32, u32}")), "{e}");
    other[1] = compile(
        ShaderKind::Miss,
        "struct Sky { vec4 c; uint t; uint i; };\nlayout(location = 0) rayPayloadInEXT Sky sky;\nvoid main() { sky.c = vec4(1.0); }\n",
    );
    fit(&other, &layout()).unwrap();
    other[1] = compile(
        ShaderKind::Miss,
        "struct Sky { float r; float g; float b; float a; uint t; uint i; };\nlayout(location = 0) rayPayloadInEXT Sky sky;\nvoid main() { sky.r = 1.0; }\n",
    );
    let e = fit(&other, &layout()).unwrap_err();
    assert!(
        matches!(&e, Mismatch::Payload { got, .. } if got.starts_with("{f32, f32, f32, f32, u32, u32}")),
        "{e}"
    );
    // a struct of two floats is the two floats (DXC's BuiltInTriangleIntersectionAttributes is
    // a struct of one float2); a float and a uint in the same 8 bytes are not
    let uv = |decl: &str| {
        let mut o = m.clone();
        let hit = format!(
            "struct UV {{ {decl} }};\nhitAttributeEXT UV uv;\nvec2 bary = vec2(uv.u, uv.v);"
        );
        o[2] =
            compile(ShaderKind::ClosestHit, &CLOSEST.replace("hitAttributeEXT vec2 bary;", &hit));
        fit(&o, &layout())
    };
    uv("float u; float v;").unwrap();
    let e = uv("float u; uint v;").unwrap_err();
    assert!(
        matches!(&e, Mismatch::HitAttribute { got, .. } if got == "{f32, u32} (8 bytes)"),
        "{e}"
    );
}

/// A raygen that traces no ray (as rtprobe's canaries) sends no payload, so the stages that would
/// receive one are never invoked: nothing to mismatch. Its twin, a raygen sending a payload the
/// miss shader does not take, is the mismatch above.
#[test]
fn stages_no_ray_reaches_have_no_payload_to_match() {
    let mut m = engine();
    m[0] = compile(
        ShaderKind::RayGeneration,
        "layout(set = 0, binding = 1, rgba8) uniform writeonly image2D target;\nvoid main() { imageStore(target, ivec2(gl_LaunchIDEXT.xy), vec4(frame.frame)); }\n",
    );
    fit(&m, &layout()).unwrap();
    m[0] = compile(
        ShaderKind::RayGeneration,
        &RAYGEN
            .replace("rayPayloadEXT Shade shade;", "rayPayloadEXT vec4 sky;\nShade shade;")
            .replace("0.0, 0)", "0.0, 0); shade.color = sky"),
    );
    assert!(matches!(fit(&m, &layout()), Err(Mismatch::Payload { .. })));
}

/// Sampled images and samplers may sit behind a combined image sampler; nothing else stands in.
#[test]
fn a_combined_image_sampler_backs_images_and_samplers_only() {
    use DescriptorKind as K;
    assert!(
        K::CombinedImageSampler.backs(K::SampledImage) && K::CombinedImageSampler.backs(K::Sampler)
    );
    assert!(
        !K::SampledImage.backs(K::CombinedImageSampler) && !K::StorageImage.backs(K::SampledImage)
    );
    assert_eq!(K::of_image(1, 2), K::StorageImage);
    assert_eq!(K::of_image(5, 1), K::UniformTexelBuffer);
    assert_eq!(K::of_vk(vk::DescriptorType::COMBINED_IMAGE_SAMPLER), Some(K::CombinedImageSampler));
}
