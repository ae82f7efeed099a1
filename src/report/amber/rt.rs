//! The Amber script of a descriptor-indexing ray tracing cell: rtprobe's scene as AmberScript
//! acceleration structures (each mesh one BLAS with one `GEOMETRY TRIANGLES` per range of its
//! triangles, vertices unindexed in index order so primitive ids stay; the procedural sphere's
//! AABB; a TLAS with every instance's transform, custom index and SBT offset, as
//! `scene::gpu` builds them), every shader as `SPIRV-HEX`, the shader groups and binding tables in
//! `exec::pipeline`'s order, the bindings, the trace, and the expected records.
use super::parts::{self, fmt_f32, TLAS_BINDING};
use crate::model::SceneParams;
use crate::probe::spec::ProbeSpec;
use crate::report::shaders::Shader;
use crate::scene::{Geometry, Mesh, Scene, SPHERE_AABB};
use crate::shadergen::Role;

/// The AmberScript shader type and name of a ray tracing role.
fn amber_shader(role: Role) -> Option<(&'static str, &'static str)> {
    match role {
        Role::Raygen => Some(("ray_generation", "raygen")),
        Role::Miss => Some(("miss", "miss")),
        Role::ProbeMiss => Some(("miss", "probe_miss")),
        Role::ClosestHitTriangles => Some(("closest_hit", "chit_triangles")),
        Role::ClosestHitProcedural => Some(("closest_hit", "chit_procedural")),
        Role::Intersection => Some(("intersection", "intersection")),
        Role::AnyHit => Some(("any_hit", "any_hit")),
        Role::Callable => Some(("callable", "callable")),
        Role::Vertex | Role::Fragment | Role::Compute => None,
    }
}

/// A BLAS of `mesh`: one geometry per range of its triangles, each triangle's three vertices.
fn blas(name: &str, mesh: &Mesh) -> String {
    let mut s = format!("ACCELERATION_STRUCTURE BOTTOM_LEVEL {name}\n");
    for range in &mesh.geometries {
        s += "  GEOMETRY TRIANGLES\n    FLAGS OPAQUE\n";
        for tri in &mesh.indices[range.start as usize..range.end as usize] {
            let v: Vec<String> =
                tri.iter().flat_map(|&i| mesh.positions[i as usize]).map(fmt_f32).collect();
            s += &format!("    {}\n", v.join(" "));
        }
        s += "  END\n";
    }
    s + "END\n"
}

/// The scene's acceleration structures: a BLAS per mesh an instance uses and one for the sphere,
/// then the TLAS `scene` (instances in `Scene::instances` order, so `gl_InstanceID` matches).
pub fn scene(params: &SceneParams) -> String {
    let scene = Scene::build(params);
    let mut s = format!("# rtprobe's scene (seed {}, {} instances, mesh detail {}): opaque geometry, instance mask 0xFF, no instance flags.\n", params.seed, params.instances, params.mesh_detail);
    let used = |m: usize| scene.instances.iter().any(|i| i.geometry == Geometry::Mesh(m));
    for (m, mesh) in scene.meshes.iter().enumerate().filter(|(m, _)| used(*m)) {
        s += &blas(&format!("mesh{m}"), mesh);
    }
    let aabb: Vec<String> = SPHERE_AABB.iter().copied().map(fmt_f32).collect();
    s += &format!(
        "ACCELERATION_STRUCTURE BOTTOM_LEVEL sphere\n  GEOMETRY AABBS\n    FLAGS OPAQUE\n    {}\n  END\nEND\n",
        aabb.join(" ")
    );
    s += "ACCELERATION_STRUCTURE TOP_LEVEL scene\n";
    for i in &scene.instances {
        let name = match i.geometry {
            Geometry::Mesh(m) => format!("mesh{m}"),
            Geometry::Sphere => "sphere".into(),
        };
        s += &format!(
            "  BOTTOM_LEVEL_INSTANCE {name}\n    INDEX {}\n    OFFSET {}\n    MASK 0xFF\n    TRANSFORM\n",
            i.custom_index,
            i.sbt_offset()
        );
        for row in &i.transform {
            let r: Vec<String> = row.iter().copied().map(fmt_f32).collect();
            s += &format!("      {}\n", r.join(" "));
        }
        s += "    END\n  END\n";
    }
    s + "END\n\n"
}

/// The pipeline: groups raygen; miss, probe miss; triangle hits (closest hit, any hit where the
/// cell has one), procedural hits (closest hit, any hit, intersection); callable — the SBTs in
/// that order, as `exec::pipeline::rt_groups` and its SBT regions lay them out.
fn pipeline(shaders: &[Shader], spec: &ProbeSpec, array: &[String], depth: u32) -> String {
    let has = |r: Role| shaders.iter().any(|s| s.role == r);
    let name = |r: Role| amber_shader(r).map(|(_, n)| n).unwrap_or("?");
    let any = if has(Role::AnyHit) { " any_hit" } else { "" };
    // `raytracing`: what Amber's parser takes (ToPipelineType), though its docs say `ray_tracing`.
    let mut s = String::from("PIPELINE raytracing probe_pipeline\n");
    s += "  SHADER_GROUP g_raygen raygen\n  SHADER_GROUP g_miss miss\n  SHADER_GROUP g_probe_miss probe_miss\n";
    s += &format!("  SHADER_GROUP g_hit_triangles {}{any}\n", name(Role::ClosestHitTriangles));
    s += &format!(
        "  SHADER_GROUP g_hit_procedural {}{any} {}\n",
        name(Role::ClosestHitProcedural),
        name(Role::Intersection)
    );
    let callable = has(Role::Callable);
    if callable {
        s += "  SHADER_GROUP g_callable callable\n";
    }
    s += "  SHADER_BINDING_TABLE sbt_raygen\n    g_raygen\n  END\n";
    s += "  SHADER_BINDING_TABLE sbt_miss\n    g_miss\n    g_probe_miss\n  END\n";
    s += "  SHADER_BINDING_TABLE sbt_hit\n    g_hit_triangles\n    g_hit_procedural\n  END\n";
    if callable {
        s += "  SHADER_BINDING_TABLE sbt_callable\n    g_callable\n  END\n";
    }
    s += &format!("  MAX_RAY_RECURSION_DEPTH {depth}\n");
    s += &parts::binds(spec, array);
    s += &format!(
        "  BIND ACCELERATION_STRUCTURE scene DESCRIPTOR_SET 0 BINDING {TLAS_BINDING}\nEND\n\n"
    );
    s
}

/// The script's body after its header: scene, shaders, buffers, pipeline, trace, expectations.
pub fn body(
    cell: &crate::model::Cell,
    shaders: &[Shader],
    scene_params: &SceneParams,
    lanes: bool,
) -> String {
    let spec = ProbeSpec::of(cell);
    let depth = crate::shadergen::generate(cell).recursion_depth;
    let mut s = String::from("DEVICE_FEATURE RayTracingPipelineFeaturesKHR.rayTracingPipeline\nDEVICE_FEATURE AccelerationStructureFeaturesKHR.accelerationStructure\nDEVICE_FEATURE BufferDeviceAddressFeatures.bufferDeviceAddress\n\n");
    s += &scene(scene_params);
    for sh in shaders {
        if let Some((kind, name)) = amber_shader(sh.role) {
            s += &parts::shader(kind, name, sh);
        }
    }
    s += &parts::records(scene_params);
    s += &parts::push_constants(&spec, scene_params);
    let (buffers, array) = parts::probed_array(&spec, scene_params.instances);
    s += &buffers;
    s += "\n";
    s += &pipeline(shaders, &spec, &array, depth);
    let callable =
        if shaders.iter().any(|s| s.role == Role::Callable) { " CALL sbt_callable" } else { "" };
    s += &format!(
        "RUN probe_pipeline RAYGEN sbt_raygen MISS sbt_miss HIT sbt_hit{callable} {} {} 1\n\n",
        scene_params.width, scene_params.height
    );
    s + &super::expect::expectations(cell, scene_params, lanes)
}
