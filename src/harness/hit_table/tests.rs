//! The hit table over ray types: a shadow ray (offset 1, stride 2) on meshes of three
//! geometries reaches records 1, 3 and 5, the spheres start after them; the twins: strides that
//! make two ray types share a record, a non-constant stride, a gap in the offsets, and a hit
//! shader whose payload two ray types share are each refused in one line.
use super::*;
use crate::harness::groups::groups;
use crate::harness::ray_types;
use shaderc::ShaderKind;

fn module(kind: ShaderKind, name: &str, body: &str) -> UserModule {
    let glsl = format!("#version 460\n#extension GL_EXT_ray_tracing : require\n{body}\n");
    let words = crate::shadergen::compile::Compiler::new()
        .unwrap()
        .compile_glsl(kind, name, &glsl)
        .unwrap();
    UserModule::new(name, &words).unwrap()
}

/// A raygen tracing one ray per `(offset, stride, miss, payload location)` given as GLSL
/// expressions, payload 0 a vec4, payload 1 a float.
fn raygen(rays: &[(&str, &str, &str, u32)]) -> UserModule {
    let traces: String = rays
        .iter()
        .map(|(o, s, m, p)| format!("    traceRayEXT(tlas, 0u, 0xFF, {o}, {s}, {m}, vec3(0), 0.0, vec3(1), 1.0, {p});\n"))
        .collect();
    let body = format!(
        "layout(set = 0, binding = 0) uniform accelerationStructureEXT tlas;\n\
         layout(push_constant) uniform P {{ uint k; }} pc;\n\
         layout(location = 0) rayPayloadEXT vec4 color;\n\
         layout(location = 1) rayPayloadEXT float shadow;\n\
         void main() {{\n{traces}}}\n"
    );
    module(ShaderKind::RayGeneration, "r.rgen", &body)
}

fn error<T: std::fmt::Debug>(r: Result<T, HarnessError>) -> String {
    let s = r.unwrap_err().to_string();
    assert!(!s.contains('\n'), "{s}");
    s
}

#[test]
fn a_shadow_ray_type_gets_a_record_per_geometry_and_the_spheres_follow() {
    let r = raygen(&[("0", "0", "0", 0), ("1", "2", "1", 1)]);
    let t = layout(&[&r], 2, 3).unwrap();
    let (tri, proc) = (Some((Geometry::Triangles, 1)), Some((Geometry::Procedural, 1)));
    let want = vec![
        Some((Geometry::Triangles, 0)),
        tri,
        None,
        tri,
        None,
        tri,
        Some((Geometry::Procedural, 0)),
        proc,
    ];
    assert_eq!((t.records, t.procedural), (want, 6));
    // One geometry per BLAS: the stride does not move the record.
    let t = layout(&[&r], 2, 1).unwrap();
    assert_eq!((t.records.len(), t.procedural), (4, 2));
    // Nothing traces: the triangle group and the procedural one, as before ray types.
    let plain = module(ShaderKind::RayGeneration, "p.rgen", "void main() {}");
    let t = layout(&[&plain], 1, 3).unwrap();
    assert_eq!((t.records.len(), t.procedural), (2, 1));
}

#[test]
fn strides_that_share_a_record_or_are_unknown_are_refused() {
    // Stride 1 for both ray types: geometry 1 of type 0 is record 1, type 1's geometry 0.
    let r = raygen(&[("0", "1", "0", 0), ("1", "1", "1", 1)]);
    let e = error(layout(&[&r], 2, 3));
    assert!(
        e.contains("reaches hit record 1") && e.contains("sbtRecordStride 0 or at least"),
        "{e}"
    );
    let r = raygen(&[("0", "pc.k", "0", 0)]);
    let e = error(layout(&[&r], 1, 3));
    assert!(e.contains("sbtRecordStride is not a constant"), "{e}");
    assert!(layout(&[&r], 1, 1).is_ok(), "one geometry: any stride reaches record 0");
    // Stride 17: the driver uses its 4 low bits (1), so no table laid out for 17 is right.
    let r = raygen(&[("0", "17", "0", 0)]);
    let e = error(layout(&[&r], 1, 3));
    assert!(e.contains("sbtRecordStride 17") && e.contains("4 low bits"), "{e}");
    assert!(layout(&[&raygen(&[("0", "15", "0", 0)])], 1, 3).is_ok(), "stride 15 runs");
}

#[test]
fn offsets_with_a_gap_are_refused_naming_it() {
    let r = raygen(&[("0", "0", "0", 0), ("2", "0", "1", 1)]);
    let e = error(ray_types::count(&[&r]));
    assert!(e.contains("offset 2 but none uses offset 1"), "{e}");
    let r = raygen(&[("0", "0", "0", 0), ("pc.k", "0", "1", 1)]);
    assert!(error(ray_types::count(&[&r])).contains("SBT record offset is not a constant"));
}

/// Hit shaders go to the ray type whose payload they receive; two ray types with one payload
/// structure, or an any-hit without a payload, need `--hit-group`, which settles them.
#[test]
fn hit_shaders_go_by_payload_and_ambiguity_names_hit_group() {
    let miss = module(
        ShaderKind::Miss,
        "m.rmiss",
        "layout(location = 0) rayPayloadInEXT vec4 c;\nvoid main() {}",
    );
    let chit = |name: &str, ty: &str| {
        module(
            ShaderKind::ClosestHit,
            name,
            &format!(
                "layout(location = 3) rayPayloadInEXT {ty} p;\nvoid main() {{ p = {ty}(0); }}"
            ),
        )
    };
    let r = raygen(&[("0", "0", "0", 0), ("1", "2", "0", 1)]);
    let (shade, shadow) = (chit("shade.rchit", "vec4"), chit("shadow.rchit", "float"));
    let g = groups(&[&r, &miss, &shade, &shadow]).unwrap();
    assert_eq!((g.types[0].hit[0], g.types[1].hit[0]), (Some(2), Some(3)));
    // Both ray types carry a vec4: ambiguous.
    let same = module(
        ShaderKind::RayGeneration,
        "r.rgen",
        "layout(set = 0, binding = 0) uniform accelerationStructureEXT tlas;\n\
        layout(location = 0) rayPayloadEXT vec4 a;\nlayout(location = 1) rayPayloadEXT vec4 b;\n\
        void main() { traceRayEXT(tlas, 0u, 0xFF, 0, 0, 0, vec3(0), 0.0, vec3(1), 1.0, 0);\n\
        traceRayEXT(tlas, 0u, 0xFF, 1, 0, 0, vec3(0), 0.0, vec3(1), 1.0, 1); }",
    );
    let e = error(groups(&[&same, &miss, &shade]).map(|_| ()));
    assert!(e.contains("ray types 0 and 1 alike") && e.contains("--hit-group"), "{e}");
    let mut given = shade.clone();
    given.ray_type = Some(1);
    let g = groups(&[&same, &miss, &given]).unwrap();
    assert_eq!((g.types[0].hit[0], g.types[1].hit[0]), (None, Some(2)));
    given.ray_type = Some(2);
    assert!(
        error(groups(&[&same, &miss, &given]).map(|_| ())).contains("--hit-group 2=shade.rchit")
    );
    let alpha = module(ShaderKind::AnyHit, "alpha.rahit", "void main() {}");
    let e = error(groups(&[&r, &miss, &alpha]).map(|_| ()));
    assert!(
        e.contains("alpha.rahit (any_hit) has no incoming payload") && e.contains("--hit-group"),
        "{e}"
    );
}
