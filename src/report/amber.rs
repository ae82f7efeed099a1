//! An Amber script (google/amber, `docs/amber_script.md`) for a repro bundle: the cell's SPIR-V
//! as `SPIRV-HEX` (the exact binary the worker runs, patched where the cell says), the GLSL as
//! comments, the probed descriptor array and push constants as buffers, one dispatch, and the
//! expected records as `EXPECT` lines. Written only where the cell fits AmberScript; otherwise
//! [`script`] says why, for the bundle's README.
//!
//! What fits: compute cells of `descriptor_model=descriptor_indexing` reading storage or uniform
//! buffers (every index source; the nonuniform and pin-index patches are in the SPIR-V), with no
//! injected fault. AmberScript has compute, graphics and (since 2024) ray tracing pipelines with
//! acceleration structures, but not VK_EXT_descriptor_buffer, VK_EXT_descriptor_heap, device
//! addresses in push constants, or a per-attempt die; rtprobe does not (yet) write its scene, SBT
//! or image arrays in AmberScript.
use crate::model::Injection;
use crate::model::{Cell, DescriptorModel, IndexSource, Resource, Stage};
use crate::probe::{self, RECORD_SIZE};
use crate::report::shaders::Shader;
use crate::scene::Scene;
use crate::model::SceneParams;

/// Set and binding of the records buffer and of the probed array (`shadergen::probe_code`; a
/// test holds the generated GLSL to them).
pub const RECORDS_BINDING: u32 = 0;
pub const PROBE_BINDING: u32 = 2;
/// The compute probe's workgroup (`local_size_x/y`).
const GROUP: u32 = 8;

/// The script for `cell`, or why none is written (a sentence for the README).
pub fn script(cell: &Cell, shaders: &[Shader], scene: &SceneParams, inject: Option<&Injection>, origin: &str) -> Result<String, String> {
    fits(cell, inject)?;
    let [shader] = shaders else {
        return Err(format!("the cell has {} shaders; a compute cell has one", shaders.len()));
    };
    Ok(write(cell, shader, scene, origin))
}

/// Why `cell` does not fit, checked axis by axis.
fn fits(cell: &Cell, inject: Option<&Injection>) -> Result<(), String> {
    if cell.canary.is_some() {
        return Err("canaries are not probe cells (they hang or fault on purpose)".into());
    }
    if let Some(i) = inject {
        return Err(format!("the cell has an injected fault ({}): Amber cannot reproduce rtprobe's injection (a load through a device address in push constants, per-attempt dice)", i.spec));
    }
    match cell.descriptor_model {
        DescriptorModel::DescriptorIndexing => {}
        DescriptorModel::DescriptorBuffer => return Err("Amber has no VK_EXT_descriptor_buffer".into()),
        DescriptorModel::DescriptorHeap => return Err("Amber has no VK_EXT_descriptor_heap".into()),
    }
    match cell.stage {
        Stage::Compute => {}
        Stage::Raygen | Stage::ClosestHit | Stage::AnyHit | Stage::Miss | Stage::Intersection | Stage::Callable => {
            return Err("ray tracing cell: Amber has ray tracing pipelines and acceleration structures, but rtprobe does not write its scene (16+ transformed instances, multi-geometry BLAS, the procedural AABB, its SBT layout) in AmberScript yet (not implemented)".into())
        }
        Stage::Fragment => return Err("graphics cell: rtprobe writes Amber scripts for compute cells only (not implemented)".into()),
    }
    match cell.resource {
        Resource::StorageBuffer | Resource::UniformBuffer => {}
        Resource::SampledImage | Resource::StorageImage => return Err("image arrays: rtprobe does not write its probe images in AmberScript yet (not implemented)".into()),
        Resource::AccelerationStructure => return Err("acceleration-structure cells need rtprobe's probe TLAS variants (and device addresses for as_access=address), not written in AmberScript".into()),
    }
    match cell.patch {
        None | Some(crate::model::cell::Workaround::Nonuniform | crate::model::cell::Workaround::PinIndex | crate::model::cell::Workaround::AsToAddress) => Ok(()),
        Some(crate::model::cell::Workaround::SsboToAddress) => Err("the ssbo-to-address patch reads buffers through device addresses in push constants, which AmberScript cannot provide".into()),
    }
}

fn write(cell: &Cell, shader: &Shader, scene: &SceneParams, origin: &str) -> String {
    let mut s = String::from("#!amber\n");
    s += &format!("# rtprobe repro: {}\n# {}\n# {origin}\n", cell.id(), crate::bisect::isolation::describe(cell));
    s += "# Not run by rtprobe: no Amber was available where this was written.\n";
    s += "# The probed array is a runtime descriptor array (SPIR-V RuntimeDescriptorArray";
    if cell.nonuniform || cell.patch == Some(crate::model::cell::Workaround::Nonuniform) {
        s += ", NonUniform indexing";
    }
    s += "): the device must enable VkPhysicalDeviceDescriptorIndexingFeatures for it, which\n# AmberScript's DEVICE_FEATURE list does not name (run with an Amber whose device enables them).\n";
    let (kind, dyn_feature) = match cell.resource {
        Resource::UniformBuffer => ("uniform", "shaderUniformBufferArrayDynamicIndexing"),
        _ => ("storage", "shaderStorageBufferArrayDynamicIndexing"),
    };
    s += &format!("DEVICE_FEATURE {dyn_feature}\n\n");
    s += &format!("# The GLSL rtprobe generated; the SPIR-V below is what the worker runs ({}", shader.compiler);
    if !shader.patched.is_empty() {
        s += &format!(", then patched with {}", shader.patched.join(", "));
    }
    s += "):\n";
    for l in shader.glsl.lines() {
        s += &format!("#   {l}\n");
    }
    s += "SHADER compute probe SPIRV-HEX\n";
    for chunk in super::shaders::spirv_bytes(&shader.spirv).chunks(32) {
        let line: Vec<String> = chunk.iter().map(|b| format!("{b:02x}")).collect();
        s += &line.join(" ");
        s += "\n";
    }
    s += "END\n\n";

    let (w, h) = (scene.width, scene.height);
    let slots = probe::slot_count(cell.resource, scene.instances);
    let words = scene.pixels() * RECORD_SIZE / 4;
    s += &format!("# Records: {w}x{h} of {RECORD_SIZE} bytes, unwritten ones read flags 0xffffffff.\n");
    s += &format!("BUFFER records DATA_TYPE uint32 SIZE {words} FILL 4294967295\n");
    let pc = probe::push_constants(w, h, scene.instances, cell.resource);
    let pc_words = u32_words(&pc.to_bytes(0)[..probe::PUSH_BLOCK_BYTES as usize]);
    let names: Vec<String> = probe::PUSH_FIELDS.iter().map(|f| if f.glsl_type == "uvec2" { format!("{}.xy", f.glsl_name) } else { f.glsl_name.to_string() }).collect();
    s += &format!("# Push constants ({}).\n", names.join(" "));
    s += &format!("BUFFER pc DATA_TYPE uint32 DATA {} END\n", pc_words.join(" "));
    let layout = if cell.resource == Resource::UniformBuffer { "STD140" } else { "STD430" };
    s += &format!("# The probed array: {slots} {kind} buffers of {} vec4, slot s element e = (s+1, kind*16+1, 1000+4s+e, 0.25+e).\n", probe::ELEMENTS);
    for slot in 0..slots {
        let vals: Vec<String> = (0..probe::ELEMENTS).flat_map(|e| probe::resource_value(cell.resource, slot, e)).map(fmt_f32).collect();
        s += &format!("BUFFER slot{slot} DATA_TYPE vec4<float> {layout} DATA {} END\n", vals.join(" "));
    }
    s += "\nPIPELINE compute probe_pipeline\n  ATTACH probe";
    if cell.index == IndexSource::SpecConstant {
        s += &format!(" SPECIALIZE 0 AS uint32 {}", probe::SPEC_SLOT);
    }
    s += &format!("\n  BIND BUFFER records AS storage DESCRIPTOR_SET 0 BINDING {RECORDS_BINDING}\n");
    let names: Vec<String> = (0..slots).map(|k| format!("slot{k}")).collect();
    s += &format!("  BIND BUFFER_ARRAY {} AS {kind} DESCRIPTOR_SET 0 BINDING {PROBE_BINDING}\n", names.join(" "));
    s += "  BIND BUFFER pc AS push_constant\nEND\n\n";
    s += &format!("RUN probe_pipeline {} {} 1\n\n", w.div_ceil(GROUP), h.div_ceil(GROUP));
    s += &expectations(cell, scene);
    s
}

/// The expected records as EXPECT lines, or why there are none.
fn expectations(cell: &Cell, params: &SceneParams) -> String {
    if crate::model::undefined_descriptor_read(cell) {
        return "# No EXPECT: the index is dynamic without nonuniformEXT, so which element a lane reads is\n# undefined (VUID-RuntimeSpirv-NonUniform-06274); rtprobe accepts any element of the array there.\n".into();
    }
    let scene = Scene::build(params);
    let sref = crate::reference::SceneReference::compute(&scene);
    let expected = crate::reference::expected(cell, &scene, &sref);
    let mut s = String::from("# Record of pixel (x, y) at byte 64*(x + y*width): flags custom instanceId geometry primitive\n# t bary.x bary.y slot element pad pad2 value.x value.y value.z value.w, as uint32 (floats as bits).\n");
    for (p, e) in expected.iter().enumerate() {
        s += &format!("EXPECT records IDX {} EQ {}\n", p * RECORD_SIZE, u32_words(&e.record.to_bytes()).join(" "));
    }
    s
}

/// Little-endian bytes as AmberScript uint32 values.
fn u32_words(bytes: &[u8]) -> Vec<String> {
    bytes.chunks(4).map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]).to_string()).collect()
}

/// An f32 as AmberScript reads it back exactly (the shortest round-trip form).
fn fmt_f32(v: f32) -> String {
    format!("{v:?}")
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::AsAccess;
    use crate::report::shaders::cell_shaders;

    fn compute(resource: Resource, index: IndexSource) -> Cell {
        Cell::new(Stage::Compute, resource, index, DescriptorModel::DescriptorIndexing)
    }

    fn small() -> SceneParams {
        SceneParams { width: 16, height: 8, ..SceneParams::default() }
    }

    #[test]
    fn a_compute_buffer_cell_has_its_spirv_glsl_buffers_and_expectations() {
        let cell = compute(Resource::StorageBuffer, IndexSource::PushConstant);
        let shaders = cell_shaders(&cell, None).unwrap();
        let text = script(&cell, &shaders, &small(), None, "test").unwrap();
        assert!(text.starts_with("#!amber\n"));
        // The SPIR-V, byte for byte: the magic number little-endian first.
        assert!(text.contains("SHADER compute probe SPIRV-HEX\n03 02 23 07 "), "{}", &text[..400.min(text.len())]);
        let hex: Vec<u8> = text.split("SPIRV-HEX\n").nth(1).unwrap().split("\nEND").next().unwrap().split_whitespace().map(|b| u8::from_str_radix(b, 16).unwrap()).collect();
        assert_eq!(hex, crate::report::shaders::spirv_bytes(&shaders[0].spirv));
        // The GLSL as comments, the buffers, the binding and the dispatch.
        assert!(text.contains("#   layout(set = 0, binding = 2, std430) readonly buffer ProbeBuffer"), "GLSL comment");
        let slots = probe::slot_count(cell.resource, small().instances);
        assert!(text.contains(&format!("BUFFER slot{} DATA_TYPE vec4<float> STD430 DATA ", slots - 1)));
        assert!(!text.contains(&format!("BUFFER slot{slots} ")));
        assert!(text.contains("BIND BUFFER_ARRAY slot0 slot1 ") && text.contains(" AS storage DESCRIPTOR_SET 0 BINDING 2\n"));
        assert!(text.contains("RUN probe_pipeline 2 1 1\n"));
        // One EXPECT per pixel; pixel 0 reads the push-constant slot's element 0.
        assert_eq!(text.matches("\nEXPECT records IDX ").count(), small().pixels());
        let want = probe::resource_value(cell.resource, probe::PUSH_SLOT, 0);
        let line = text.lines().find(|l| l.starts_with("EXPECT records IDX 0 EQ ")).unwrap();
        let words: Vec<u32> = line.split_whitespace().skip(5).map(|w| w.parse().unwrap()).collect();
        assert_eq!(words[0], probe::FLAG_PROBE);
        assert_eq!(words[8], probe::PUSH_SLOT);
        assert_eq!(words[12..16], want.map(f32::to_bits));
        // The push constants carry the slot the shader reads.
        let pc = text.lines().find(|l| l.starts_with("BUFFER pc ")).unwrap();
        assert!(pc.contains(&format!("DATA 16 8 {} ", probe::PUSH_SLOT)), "{pc}");
    }

    #[test]
    fn uniform_spec_constant_cells_specialize_and_use_std140() {
        let cell = compute(Resource::UniformBuffer, IndexSource::SpecConstant);
        let text = script(&cell, &cell_shaders(&cell, None).unwrap(), &small(), None, "test").unwrap();
        assert!(text.contains(&format!("ATTACH probe SPECIALIZE 0 AS uint32 {}", probe::SPEC_SLOT)));
        assert!(text.contains("STD140 DATA") && text.contains(" AS uniform DESCRIPTOR_SET 0 BINDING 2"));
        assert!(text.contains("DEVICE_FEATURE shaderUniformBufferArrayDynamicIndexing"));
    }

    #[test]
    fn a_lenient_dynamic_cell_has_no_expectations_and_says_why() {
        let cell = compute(Resource::StorageBuffer, IndexSource::Dynamic);
        let text = script(&cell, &cell_shaders(&cell, None).unwrap(), &small(), None, "test").unwrap();
        assert!(!text.contains("\nEXPECT "));
        assert!(text.contains("No EXPECT: the index is dynamic without nonuniformEXT"));
    }

    #[test]
    fn cells_that_do_not_fit_say_why() {
        let c = compute(Resource::StorageBuffer, IndexSource::Literal);
        let heap = Cell { descriptor_model: DescriptorModel::DescriptorHeap, heap_access: Some(crate::model::HeapAccess::MappedConstantOffset), ..c };
        assert_eq!(fits(&heap, None).unwrap_err(), "Amber has no VK_EXT_descriptor_heap");
        let buf = Cell { descriptor_model: DescriptorModel::DescriptorBuffer, ..c };
        assert_eq!(fits(&buf, None).unwrap_err(), "Amber has no VK_EXT_descriptor_buffer");
        assert!(fits(&Cell { stage: Stage::ClosestHit, ..c }, None).unwrap_err().starts_with("ray tracing cell"));
        assert!(fits(&Cell { resource: Resource::AccelerationStructure, as_access: Some(AsAccess::Address), ..c }, None).is_err());
        let inj = Injection::parse("stage=compute").unwrap();
        assert!(fits(&c, Some(&inj)).unwrap_err().contains("injected fault"));
        assert!(fits(&c, None).is_ok());
    }

    #[test]
    fn the_bindings_are_the_generated_glsls() {
        for r in [Resource::StorageBuffer, Resource::UniformBuffer] {
            let cell = compute(r, IndexSource::Literal);
            let glsl = &cell_shaders(&cell, None).unwrap()[0].glsl;
            assert!(glsl.contains(&format!("layout(set = 0, binding = {RECORDS_BINDING}, std430) buffer Records")), "{glsl}");
            assert!(glsl.contains(&format!("layout(set = 0, binding = {PROBE_BINDING}, ")), "{glsl}");
            assert!(glsl.contains(&format!("local_size_x = {GROUP}, local_size_y = {GROUP}")));
        }
    }

    #[test]
    fn floats_round_trip() {
        for v in [1.0f32, 0.25, 1003.0, 17.0] {
            assert_eq!(fmt_f32(v).parse::<f32>().unwrap(), v);
        }
    }
}
