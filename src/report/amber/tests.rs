use super::*;
use crate::model::{AsAccess, DescriptorModel, IndexSource, Resource, Workaround};
use crate::probe::{self, Record, RECORD_SIZE};
use crate::report::shaders::cell_shaders;
use crate::scene::Scene;

fn cell(stage: Stage, resource: Resource, index: IndexSource) -> Cell {
    Cell::new(stage, resource, index, DescriptorModel::DescriptorIndexing)
}

fn compute(resource: Resource, index: IndexSource) -> Cell {
    cell(Stage::Compute, resource, index)
}

fn small() -> SceneParams {
    SceneParams { width: 16, height: 8, ..SceneParams::default() }
}

fn text_of(c: &Cell, scene: &SceneParams) -> String {
    script(c, &cell_shaders(c, None, false).unwrap(), scene, None, false, "test").unwrap()
}

/// The EXPECT lines' values, split into words.
fn expects(text: &str) -> Vec<Vec<String>> {
    text.lines()
        .filter(|l| l.starts_with("EXPECT records IDX "))
        .map(|l| l.split(" EQ ").nth(1).unwrap().split(' ').map(String::from).collect())
        .collect()
}

/// The records a correct driver writes for `c`: the reference's, as bytes.
fn reference_bytes(c: &Cell, params: &SceneParams) -> Vec<u8> {
    let scene = Scene::build(params);
    let sref = crate::reference::SceneReference::compute(&scene);
    crate::reference::expected(c, &scene, &sref).iter().flat_map(|e| e.record.to_bytes()).collect()
}

#[test]
fn a_compute_buffer_cell_has_its_spirv_glsl_buffers_and_expectations() {
    let c = compute(Resource::StorageBuffer, IndexSource::PushConstant);
    let shaders = cell_shaders(&c, None, false).unwrap();
    let text = script(&c, &shaders, &small(), None, false, "test").unwrap();
    assert!(text.starts_with("#!amber\n"));
    // The last byte runs into END: Amber's hex parser loops on trailing whitespace.
    let data = text.split("SPIRV-HEX\n").nth(1).unwrap().split("END").next().unwrap();
    assert!(data.ends_with(|c: char| c.is_ascii_hexdigit()), "{:?}", &data[data.len() - 8..]);
    let hex: Vec<u8> = text
        .split("SPIRV-HEX\n")
        .nth(1)
        .unwrap()
        .split("END")
        .next()
        .unwrap()
        .split_whitespace()
        .map(|b| u8::from_str_radix(b, 16).unwrap())
        .collect();
    assert_eq!(hex, crate::report::shaders::spirv_bytes(&shaders[0].spirv));
    assert!(text.contains("#   layout(set = 0, binding = 2, std430) readonly buffer ProbeBuffer"));
    let slots = probe::slot_count(c.resource, small().instances);
    assert!(text.contains(&format!("BUFFER slot{} DATA_TYPE vec4<float> STD430 DATA ", slots - 1)));
    assert!(!text.contains(&format!("BUFFER slot{slots} ")));
    assert!(
        text.contains("BIND BUFFER_ARRAY slot0 slot1 ")
            && text.contains(" AS storage DESCRIPTOR_SET 0 BINDING 2\n")
    );
    assert!(text.contains("RUN probe_pipeline 2 1 1\n"));
    // The records STRUCT is probe::Record's layout.
    assert!(text.contains("STRUCT record STRIDE 80\n  uint32 flags OFFSET 0\n"), "{text}");
    assert!(
        text.contains("  float t OFFSET 20\n  vec2<float> bary OFFSET 24\n")
            && text.contains("  vec4<float> value OFFSET 48\n")
    );
    // One EXPECT per pixel; pixel 0 reads the push-constant slot's element 0.
    let e = expects(&text);
    assert_eq!(e.len(), small().pixels());
    assert_eq!(e[0][0], probe::FLAG_PROBE.to_string());
    assert_eq!(e[0][8], probe::PUSH_SLOT.to_string());
    let want = probe::resource_value(c.resource, probe::PUSH_SLOT, 0);
    let got: Vec<f32> = e[0][12..16].iter().map(|v| v.parse().unwrap()).collect();
    assert_eq!(got, want);
    let pc = text.lines().find(|l| l.starts_with("BUFFER pc ")).unwrap();
    assert!(pc.contains(&format!("DATA 16 8 {} ", probe::PUSH_SLOT)), "{pc}");
}

#[test]
fn uniform_spec_constant_compute_cells_specialize_and_use_std140() {
    let c = compute(Resource::UniformBuffer, IndexSource::SpecConstant);
    let text = text_of(&c, &small());
    assert!(text.contains(&format!("ATTACH probe SPECIALIZE 0 AS uint32 {}", probe::SPEC_SLOT)));
    assert!(
        text.contains("STD140 DATA") && text.contains(" AS uniform DESCRIPTOR_SET 0 BINDING 2")
    );
    assert!(text.contains("DEVICE_FEATURE shaderUniformBufferArrayDynamicIndexing"));
}

/// The twin of a bug `ProbeSpec` fixed: `dynamic_element` reads the packed buffer at the
/// spec-constant slot; the script specializes it and binds the packed buffer there, and its
/// EXPECTs hold against what a correct driver reads there.
#[test]
fn a_dynamic_element_cell_specializes_the_slot_and_binds_the_packed_buffer() {
    let c = compute(Resource::StorageBuffer, IndexSource::DynamicElement);
    let text = text_of(&c, &small());
    assert!(text.contains(&format!("ATTACH probe SPECIALIZE 0 AS uint32 {}\n", probe::PACKED_SLOT)));
    let slots = probe::slot_count(c.resource, small().instances);
    let names: Vec<String> = (0..slots)
        .map(|k| if k == probe::PACKED_SLOT { "packed".into() } else { format!("slot{k}") })
        .collect();
    assert!(text.contains(&format!(
        "  BIND BUFFER_ARRAY {} AS storage DESCRIPTOR_SET 0 BINDING 2\n",
        names.join(" ")
    )));
    let (failures, n) = check(&text, RECORDS, &reference_bytes(&c, &small())).unwrap();
    assert_eq!((failures, n), (vec![], small().pixels()));
}

#[test]
fn a_lenient_dynamic_cell_expects_no_value_and_says_why() {
    let c = compute(Resource::StorageBuffer, IndexSource::Dynamic);
    let text = text_of(&c, &small());
    assert!(text.contains("No value in the EXPECTs: the index is dynamic without nonuniformEXT"));
    assert!(expects(&text).iter().all(|e| e.len() == 12));
}

/// The ray tracing script: rtprobe's scene exactly (custom indices, SBT offsets, transforms and
/// triangles read back bit for bit), the groups and tables in the worker's order, and EXPECTs
/// that hold against the reference's records.
#[test]
fn a_closest_hit_cell_has_the_scene_groups_and_expectations() {
    let c = cell(Stage::ClosestHit, Resource::StorageBuffer, IndexSource::Dynamic);
    let c = Cell { nonuniform: true, ..c };
    let params = small();
    let text = text_of(&c, &params);
    let scene = Scene::build(&params);
    let indices: Vec<u32> = text
        .lines()
        .filter_map(|l| l.trim().strip_prefix("INDEX "))
        .map(|v| v.parse().unwrap())
        .collect();
    assert_eq!(indices, scene.instances.iter().map(|i| i.custom_index).collect::<Vec<_>>());
    let offsets: Vec<u32> = text
        .lines()
        .filter_map(|l| l.trim().strip_prefix("OFFSET "))
        .map(|v| v.parse().unwrap())
        .collect();
    assert_eq!(offsets, scene.instances.iter().map(|i| i.sbt_offset()).collect::<Vec<_>>());
    // Transforms: three rows of four floats after each TRANSFORM, parsed as Amber does (f64, then f32).
    let lines: Vec<&str> = text.lines().collect();
    let mut k = 0;
    for (at, _) in lines.iter().enumerate().filter(|(_, l)| l.trim() == "TRANSFORM") {
        for r in 0..3 {
            let row: Vec<f32> = lines[at + 1 + r]
                .split_whitespace()
                .map(|v| v.parse::<f64>().unwrap() as f32)
                .collect();
            assert_eq!(row, scene.instances[k].transform[r], "instance {k} row {r}");
        }
        k += 1;
    }
    assert_eq!(k, scene.instances.len());
    // Each mesh: one GEOMETRY per range; mesh 0's first triangle's vertices in index order.
    let mesh0 = text
        .split("ACCELERATION_STRUCTURE BOTTOM_LEVEL mesh0\n")
        .nth(1)
        .unwrap()
        .split("\nEND\n")
        .next()
        .unwrap();
    assert_eq!(mesh0.matches("GEOMETRY TRIANGLES").count(), scene.meshes[0].geometries.len());
    let first: Vec<f32> = mesh0
        .lines()
        .nth(2)
        .unwrap()
        .split_whitespace()
        .map(|v| v.parse::<f64>().unwrap() as f32)
        .collect();
    let m = &scene.meshes[0];
    let want: Vec<f32> = m.indices[0].iter().flat_map(|&i| m.positions[i as usize]).collect();
    assert_eq!(first, want);
    assert!(text.contains("ACCELERATION_STRUCTURE BOTTOM_LEVEL sphere\n  GEOMETRY AABBS\n    FLAGS OPAQUE\n    -0.5 -0.5 -0.5 0.5 0.5 0.5\n"));
    for l in [
        "SHADER ray_generation raygen SPIRV-HEX",
        "PIPELINE raytracing probe_pipeline\n",
        "SHADER closest_hit chit_procedural SPIRV-HEX",
        "  SHADER_GROUP g_hit_procedural chit_procedural intersection\n",
        "  SHADER_BINDING_TABLE sbt_miss\n    g_miss\n    g_probe_miss\n  END\n",
        "  SHADER_BINDING_TABLE sbt_hit\n    g_hit_triangles\n    g_hit_procedural\n  END\n",
        "  MAX_RAY_RECURSION_DEPTH 1\n",
        "  BIND ACCELERATION_STRUCTURE scene DESCRIPTOR_SET 0 BINDING 1\n",
        "RUN probe_pipeline RAYGEN sbt_raygen MISS sbt_miss HIT sbt_hit 16 8 1\n",
    ] {
        assert!(text.contains(l), "{l:?} missing");
    }
    let (failures, n) = check(&text, RECORDS, &reference_bytes(&c, &params)).unwrap();
    assert!(failures.is_empty(), "{failures:?}");
    let sref = crate::reference::SceneReference::compute(&scene);
    assert_eq!(n, params.pixels() - sref.ambiguous_pixels());
    assert!(n > 0);
}

#[test]
fn any_hit_and_callable_cells_add_their_shaders_and_table() {
    let any =
        text_of(&cell(Stage::AnyHit, Resource::UniformBuffer, IndexSource::Literal), &small());
    assert!(any.contains("  SHADER_GROUP g_hit_triangles chit_triangles any_hit\n  SHADER_GROUP g_hit_procedural chit_procedural any_hit intersection\n"));
    let call = text_of(
        &cell(Stage::Callable, Resource::StorageBuffer, IndexSource::PushConstant),
        &small(),
    );
    assert!(call.contains("  SHADER_BINDING_TABLE sbt_callable\n    g_callable\n  END\n"));
    assert!(call.contains(" HIT sbt_hit CALL sbt_callable 16 8 1\n"));
}

/// The checker reads EXPECTs as Amber's verifier does: a planted wrong value, a wrong integer,
/// a t outside the tolerance and an offset outside the buffer each fail, on their own line.
#[test]
fn the_checker_fails_a_planted_wrong_expectation() {
    let c = cell(Stage::Raygen, Resource::StorageBuffer, IndexSource::Literal);
    let params = small();
    let text = text_of(&c, &params);
    let bytes = reference_bytes(&c, &params);
    assert_eq!(check(&text, RECORDS, &bytes).unwrap().0, Vec::<String>::new());
    let line = text.lines().position(|l| l.starts_with("EXPECT records IDX 0 ")).unwrap();
    let replace = |f: &dyn Fn(&mut Vec<String>)| -> String {
        let mut lines: Vec<String> = text.lines().map(String::from).collect();
        let (head, tail) = lines[line].split_once(" EQ ").unwrap();
        let mut w: Vec<String> = tail.split(' ').map(String::from).collect();
        f(&mut w);
        lines[line] = format!("{head} EQ {}", w.join(" "));
        lines.join("\n")
    };
    let wrong_value = replace(&|w| w[14] = "1003.5".into());
    let (f, _) = check(&wrong_value, RECORDS, &bytes).unwrap();
    assert_eq!(f.len(), 1, "{f:?}");
    assert!(
        f[0].starts_with(&format!("line {}: Verifier failed: ", line + 1))
            && f[0].ends_with("at index 14"),
        "{f:?}"
    );
    let wrong_slot = replace(&|w| w[8] = (probe::LITERAL_SLOT + 1).to_string());
    assert_eq!(check(&wrong_slot, RECORDS, &bytes).unwrap().0.len(), 1);
    // Within the tolerance a float passes; outside it fails.
    let near = replace(&|w| w[5] = "0.0005".into());
    assert!(check(&near, RECORDS, &bytes).unwrap().0.is_empty());
    let far = replace(&|w| w[5] = "0.002".into());
    assert_eq!(check(&far, RECORDS, &bytes).unwrap().0.len(), 1);
    let outside = text.replace(
        "EXPECT records IDX 0 ",
        &format!("EXPECT records IDX {} ", params.pixels() * RECORD_SIZE),
    );
    assert!(check(&outside, RECORDS, &bytes).unwrap().0[0]
        .contains("is not a record inside the buffer"));
    // And a records buffer the driver left unwritten fails every EXPECT.
    let unwritten: Vec<u8> = vec![0xff; bytes.len()];
    let (f, n) = check(&text, RECORDS, &unwritten).unwrap();
    assert!(f.len() >= n, "{} failures for {n} EXPECTs", f.len());
}

#[test]
fn cells_that_do_not_fit_say_why() {
    let c = compute(Resource::StorageBuffer, IndexSource::Literal);
    let heap = Cell {
        descriptor_model: DescriptorModel::DescriptorHeap,
        heap_access: Some(crate::model::HeapAccess::MappedConstantOffset),
        ..c
    };
    assert_eq!(fits(&heap, None).unwrap_err().to_string(), "Amber has no VK_EXT_descriptor_heap");
    let buf = Cell { descriptor_model: DescriptorModel::DescriptorBuffer, ..c };
    assert_eq!(fits(&buf, None).unwrap_err().to_string(), "Amber has no VK_EXT_descriptor_buffer");
    // Ray tracing: what AmberScript lacks is refused with that reason, and the rest fits.
    let chit = cell(Stage::ClosestHit, Resource::StorageBuffer, IndexSource::Dynamic);
    assert!(fits(&chit, None).is_ok());
    assert_eq!(
        fits(&Cell { index: IndexSource::SpecConstant, ..chit }, None),
        Err(Unfit::RtSpecialization)
    );
    assert_eq!(
        fits(&Cell { base: Some(crate::model::BaseSource::ShaderRecord), ..chit }, None),
        Err(Unfit::ShaderRecordBase)
    );
    assert!(fits(&Cell { base: Some(crate::model::BaseSource::Buffer), ..chit }, None)
        .unwrap_err()
        .to_string()
        .contains("device addresses from push constants (baseAddress)"));
    assert_eq!(fits(&Cell { stage: Stage::Fragment, ..c }, None), Err(Unfit::Graphics));
    assert_eq!(
        fits(&Cell { resource: Resource::SampledImage, ..chit }, None),
        Err(Unfit::ImageArrays)
    );
    let as_cell = Cell {
        resource: Resource::AccelerationStructure,
        as_access: Some(AsAccess::Descriptor),
        ..chit
    };
    assert_eq!(fits(&as_cell, None), Err(Unfit::AccelerationStructure));
    let ssbo = Cell { index: IndexSource::Dynamic, patch: Some(Workaround::SsboToAddress), ..c };
    assert_eq!(fits(&ssbo, None).unwrap_err().to_string(), "the probe reads device addresses from push constants (patchedTable), which AmberScript cannot provide");
    assert!(fits(&compute(Resource::UniformBuffer, IndexSource::DynamicElement), None)
        .unwrap_err()
        .to_string()
        .starts_with("rtprobe has no packed uniform_buffer buffer"));
    assert!(fits(&Cell { patch: Some(Workaround::PinIndex), ..ssbo }, None).is_ok());
    let inj = Injection::parse("stage=compute").unwrap();
    assert!(fits(&c, Some(&inj)).unwrap_err().to_string().contains("injected fault"));
}

#[test]
fn the_bindings_are_the_generated_glsls() {
    for r in [Resource::StorageBuffer, Resource::UniformBuffer] {
        let glsl = &cell_shaders(&compute(r, IndexSource::Literal), None, false).unwrap()[0].glsl;
        assert!(
            glsl.contains(&format!(
                "layout(set = 0, binding = {RECORDS_BINDING}, std430) buffer Records"
            )),
            "{glsl}"
        );
        assert!(glsl.contains(&format!("layout(set = 0, binding = {PROBE_BINDING}, ")), "{glsl}");
        assert!(glsl.contains(&format!("local_size_x = {0}, local_size_y = {0}", compute::GROUP)));
        let rt = crate::shadergen::generate(&cell(Stage::Raygen, r, IndexSource::Literal));
        let rgen = &rt.get(crate::shadergen::Role::Raygen).unwrap().glsl;
        assert!(
            rgen.contains(&format!(
                "layout(set = 0, binding = {}) uniform accelerationStructureEXT sceneTlas",
                parts::TLAS_BINDING
            )),
            "{rgen}"
        );
    }
}

#[test]
fn floats_round_trip_as_amber_reads_them() {
    for v in [1.0f32, 0.25, 1003.0, 17.0, 1e-7, -3.5e-9, 1.0e20, f32::MIN_POSITIVE] {
        let s = parts::fmt_f32(v);
        assert!(s.contains('.'), "{s}: AmberScript reads a number without a '.' as an integer");
        assert_eq!(s.parse::<f64>().unwrap() as f32, v, "{s}");
    }
    assert_eq!(Record::default().to_bytes().len(), RECORD_SIZE);
}
