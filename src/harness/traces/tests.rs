//! An nvpro-style closest-hit that traces a shadow ray (miss index 1, its own `bool` payload,
//! closest-hit skipped) gets a miss per index, each receiving its ray's payload; the twins: the
//! same ray without the skip flag, a computed miss index, SBT offsets with a gap, two payloads at
//! one index and a given miss with the wrong payload are each refused in one line. With SBT
//! offset 1 the shadow ray is a ray type of its own.
use super::super::supply::supply;
use super::*;
use shaderc::ShaderKind;

fn module(kind: ShaderKind, name: &str, glsl: &str) -> UserModule {
    let words =
        crate::shadergen::compile::Compiler::new().unwrap().compile_glsl(kind, name, glsl).unwrap();
    UserModule::new(name, &words).unwrap()
}

/// A closest-hit tracing a shadow ray with `flags` (statements setting the local `flags`), SBT
/// offset `offset` and miss index `miss`.
fn shadowing(flags: &str, offset: &str, miss: &str) -> UserModule {
    let glsl = format!(
        r#"#version 460
#extension GL_EXT_ray_tracing : require
struct Shade {{ vec3 color; float dist; }};
layout(set = 0, binding = 0) uniform accelerationStructureEXT scene;
layout(push_constant) uniform P {{ uint missIndex; }} p;
layout(location = 0) rayPayloadInEXT Shade shade;
layout(location = 1) rayPayloadEXT bool shadowed;
hitAttributeEXT vec2 bary;
void main() {{
    shadowed = true;
    vec3 at = gl_WorldRayOriginEXT + gl_WorldRayDirectionEXT * gl_HitTEXT;
    uint flags;
    {flags}
    traceRayEXT(scene, flags, 0xFF, {offset}, 0, {miss}, at, 0.001, vec3(0, 1, 0), 100.0, 1);
    shade.color = shadowed ? vec3(0.1) : vec3(bary, 1.0);
    shade.dist = gl_HitTEXT;
}}
"#
    );
    module(ShaderKind::ClosestHit, "shadow.rchit", &glsl)
}

const SKIP: &str = "flags = gl_RayFlagsTerminateOnFirstHitEXT | gl_RayFlagsOpaqueEXT | gl_RayFlagsSkipClosestHitShaderEXT;";

fn error(r: Result<Vec<UserModule>, HarnessError>) -> String {
    let e = r.map(|m| m.iter().map(|m| m.name.clone()).collect::<Vec<_>>()).unwrap_err();
    let s = e.to_string();
    assert!(!s.contains('\n'), "{s}");
    s
}

#[test]
fn a_shadow_ray_gets_its_own_miss_with_its_payload() {
    let m = shadowing(SKIP, "0", "1");
    let t = &m.iface.reflection.traces;
    assert_eq!(t.len(), 1);
    assert_eq!(
        (t[0].miss_index, t[0].sbt_offset, t[0].has_flag(FLAG_SKIP_CLOSEST_HIT)),
        (Some(1), Some(0), true)
    );
    let all = supply(vec![m]).unwrap();
    let names: Vec<&str> = all.iter().map(|m| m.name.as_str()).collect();
    assert_eq!(names, ["supplied raygen", "shadow.rchit", "supplied miss", "supplied miss 1"]);
    let incoming = |k: usize| all[k].iface.reflection.incoming_payload.as_ref().unwrap().ty.shape();
    let shade = all[1].iface.reflection.incoming_payload.as_ref().unwrap().ty.shape();
    assert_eq!(incoming(2), shade);
    assert_eq!(incoming(3), all[1].iface.reflection.traces[0].payload.shape());
    assert_ne!(incoming(3), shade);
}

#[test]
fn a_shadow_ray_that_would_invoke_the_closest_hit_is_refused() {
    let e = error(supply(vec![shadowing("flags = gl_RayFlagsOpaqueEXT;", "0", "1")]));
    assert!(e.contains("payload `shadowed`") && e.contains("shadow.rchit (closest_hit)"), "{e}");
    assert!(e.contains("Ray Tracing Pipeline Interface"), "{e}");
    // Flags that are the skip only on some paths are not known to skip.
    let sometimes = format!("{SKIP} if (gl_HitTEXT > 1.0) flags = gl_RayFlagsOpaqueEXT;");
    let m = shadowing(&sometimes, "0", "1");
    assert_eq!(m.iface.reflection.traces[0].flags, None);
    let e = error(supply(vec![m]));
    assert!(e.contains("payload `shadowed`") && e.contains("flags are not a constant"), "{e}");
}

#[test]
fn computed_miss_indices_offsets_and_clashing_payloads_are_refused() {
    let e = error(supply(vec![shadowing(SKIP, "0", "p.missIndex")]));
    assert!(e.contains("miss index is not a constant"), "{e}");
    let e = error(supply(vec![shadowing(SKIP, "2", "1")]));
    assert!(e.contains("offset 2 but none uses offset 1"), "{e}");
    let e = error(supply(vec![shadowing(SKIP, "p.missIndex", "1")]));
    assert!(e.contains("SBT record offset is not a constant"), "{e}");
    // Miss index 0: the supplied raygen's payload (a Shade) and the shadow ray's bool.
    let e = error(supply(vec![shadowing(SKIP, "0", "0")]));
    assert!(
        e.contains("shadow.rchit's payload `shadowed`") && e.contains("miss index 0 but differ"),
        "{e}"
    );
}

/// A shadow ray of its own ray type (SBT record offset 1): skipping the closest-hit it keeps an
/// empty hit group; without the skip, a supplied closest-hit of that type receives its `bool`,
/// and the shading closest-hit (type 0) is not held to it.
#[test]
fn a_shadow_ray_type_gets_an_empty_group_or_a_supplied_closest_hit() {
    let all = supply(vec![shadowing(SKIP, "1", "1")]).unwrap();
    let names: Vec<&str> = all.iter().map(|m| m.name.as_str()).collect();
    assert_eq!(names, ["supplied raygen", "shadow.rchit", "supplied miss", "supplied miss 1"]);
    let refs: Vec<&UserModule> = all.iter().collect();
    let g = super::super::groups::groups(&refs).unwrap();
    assert_eq!((g.types.len(), g.types[0].hit[0], g.types[1]), (2, Some(1), TypeGroups::default()));
    let all = supply(vec![shadowing("flags = gl_RayFlagsOpaqueEXT;", "1", "1")]).unwrap();
    let made = all.iter().find(|m| m.name == "supplied closest-hit 1").unwrap();
    assert_eq!(made.ray_type, Some(1));
    let p = made.iface.reflection.incoming_payload.as_ref().unwrap();
    assert_eq!(p.ty.shape(), all[1].iface.reflection.traces[0].payload.shape());
}

#[test]
fn a_given_miss_with_another_payload_is_refused() {
    let miss = module(
        ShaderKind::Miss,
        "sky.rmiss",
        "#version 460\n#extension GL_EXT_ray_tracing : require\n\
         layout(location = 0) rayPayloadInEXT vec4 sky;\nvoid main() { sky = vec4(1.0); }\n",
    );
    let e = error(supply(vec![shadowing(SKIP, "0", "1"), miss]));
    assert!(e.contains("sky.rmiss (miss)"), "{e}");
}

/// The tutorials' helper: `traceShadow(origin, flags)` traces with a parameter's flags. The trace
/// is found in the called function; unoptimized, the flags are a parameter, so a closest-hit
/// that would receive another payload is refused as unknown, not as invalid; with a literal in
/// the helper it runs, and with a literal lacking the skip flag it is invalid.
#[test]
fn a_trace_in_a_called_function_is_found() {
    let helper = |flags: &str| {
        let glsl = format!(
            r#"#version 460
#extension GL_EXT_ray_tracing : require
layout(set = 0, binding = 0) uniform accelerationStructureEXT scene;
layout(location = 0) rayPayloadInEXT vec4 color;
layout(location = 1) rayPayloadEXT bool shadowed;
bool traceShadow(vec3 at, uint flags) {{
    shadowed = true;
    traceRayEXT(scene, {flags}, 0xFF, 0, 0, 1, at, 0.001, vec3(0, 1, 0), 100.0, 1);
    return shadowed;
}}
void main() {{
    const uint skip = gl_RayFlagsOpaqueEXT | gl_RayFlagsSkipClosestHitShaderEXT;
    color = traceShadow(gl_WorldRayOriginEXT, skip) ? vec4(0.1) : vec4(1.0);
}}
"#
        );
        module(ShaderKind::ClosestHit, "helper.rchit", &glsl)
    };
    let m = helper("flags");
    assert_eq!((m.iface.reflection.traces.len(), m.iface.reflection.traces[0].flags), (1, None));
    let e = supply(vec![m]).map(|_| ()).unwrap_err();
    assert!(matches!(e, HarnessError::Unsupported(_)), "{e}");
    assert!(e.to_string().contains("not a constant where it traces"), "{e}");
    let literal = "gl_RayFlagsOpaqueEXT | gl_RayFlagsSkipClosestHitShaderEXT";
    assert!(supply(vec![helper(literal)]).is_ok());
    let e = supply(vec![helper("gl_RayFlagsNoneEXT")]).map(|_| ()).unwrap_err();
    assert!(matches!(e, HarnessError::Interface(_)), "{e}");
}

/// An any-hit (receiving the primary ray's `Shade`) is held to the shadow ray's payload unless
/// that ray's flags make every geometry opaque.
#[test]
fn an_any_hit_is_held_to_the_payload_unless_the_ray_is_opaque() {
    let ahit = module(
        ShaderKind::AnyHit,
        "alpha.rahit",
        "#version 460\n#extension GL_EXT_ray_tracing : require\n\
         struct Shade { vec3 color; float dist; };\n\
         layout(location = 0) rayPayloadInEXT Shade s;\nvoid main() { if (s.dist < 0.5) ignoreIntersectionEXT; }\n",
    );
    let skip_only = "flags = gl_RayFlagsSkipClosestHitShaderEXT;";
    let e = error(supply(vec![shadowing(skip_only, "0", "1"), ahit.clone()]));
    assert!(e.contains("alpha.rahit (any_hit)"), "{e}");
    assert!(supply(vec![shadowing(SKIP, "0", "1"), ahit]).is_ok());
}

/// A closest-hit that traces gets the device's whole recursion depth, and is refused on a device
/// allowing depth 1 (its trace would be undefined); a pipeline where only the raygen traces
/// keeps 2.
#[test]
fn a_tracing_hit_shader_gets_the_devices_recursion_depth() {
    let all = supply(vec![shadowing(SKIP, "0", "1")]).unwrap();
    let refs: Vec<&UserModule> = all.iter().collect();
    assert_eq!(recursion_depth(&refs, 31).unwrap(), 31);
    let e = recursion_depth(&refs, 1).unwrap_err().to_string();
    assert!(e.starts_with("shadow.rchit (closest_hit) traces a ray") && e.contains("03679"), "{e}");
    // The shadow ray skips the closest-hit and its miss does not trace: bounded.
    assert_eq!(unbounded_recursion(&refs), None);
    // The same ray invoking the closest-hit recurses as deep as the shader's own guard.
    let reflective = module(
        ShaderKind::ClosestHit,
        "mirror.rchit",
        r#"#version 460
#extension GL_EXT_ray_tracing : require
struct Shade { vec3 color; float dist; };
layout(set = 0, binding = 0) uniform accelerationStructureEXT scene;
layout(location = 0) rayPayloadInEXT Shade shade;
layout(location = 1) rayPayloadEXT Shade bounce;
void main() {
    bounce.color = vec3(0.0);
    bounce.dist = shade.dist + 1.0;
    if (shade.dist < 4.0) {
        traceRayEXT(scene, 0u, 0xFF, 0, 0, 0, gl_WorldRayOriginEXT, 0.001, vec3(0, 0, 1), 100.0, 1);
    }
    shade.color = bounce.color * 0.5 + vec3(0.1);
    shade.dist = gl_HitTEXT;
}
"#,
    );
    let all = supply(vec![reflective]).unwrap();
    let refs: Vec<&UserModule> = all.iter().collect();
    let r = unbounded_recursion(&refs).unwrap();
    assert!(
        r.starts_with("mirror.rchit traces rays that invoke mirror.rchit, which traces again"),
        "{r}"
    );
    let plain = module(
        ShaderKind::ClosestHit,
        "plain.rchit",
        "#version 460\n#extension GL_EXT_ray_tracing : require\n\
         layout(location = 0) rayPayloadInEXT vec4 c;\nvoid main() { c = vec4(1.0); }\n",
    );
    let all = supply(vec![plain]).unwrap();
    let refs: Vec<&UserModule> = all.iter().collect();
    assert_eq!(recursion_depth(&refs, 31).unwrap(), 2);
    assert_eq!(recursion_depth(&refs, 1).unwrap(), 1);
}
