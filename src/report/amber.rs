//! An Amber script (google/amber, `docs/amber_script.md`) for a repro bundle: the cell's SPIR-V
//! as `SPIRV-HEX` (the exact binary the worker runs, patched where the cell says), the GLSL as
//! comments, the probed descriptor array and push constants as buffers, one dispatch, and the
//! expected records as `EXPECT` lines. Written only where the cell fits AmberScript; otherwise
//! [`script`] says why, for the bundle's README.
//!
//! What fits, judged on the cell's probe spec (`probe::spec::ProbeSpec`; what it needs and this
//! writer cannot express is refused with that reason): compute cells of
//! `descriptor_model=descriptor_indexing` reading storage or uniform buffers (every index source:
//! the spec constant specialized wherever the GLSL declares it, `index=dynamic_element`'s packed
//! buffer bound at the spec-constant slot; the nonuniform and pin-index patches are in the
//! SPIR-V), with no device address in push constants and no injected fault. AmberScript has
//! compute, graphics and (since 2024) ray tracing pipelines with acceleration structures, but not
//! VK_EXT_descriptor_buffer, VK_EXT_descriptor_heap, device addresses in push constants, or a
//! per-attempt die; rtprobe does not (yet) write its scene, SBT or image arrays in AmberScript.
use crate::model::Injection;
use crate::model::SceneParams;
use crate::model::{Cell, DescriptorModel, Resource, Stage, Workaround};
use crate::probe::spec::{Access, Base, ElementMap, ProbeSpec, ReadIndex, Sampler};
use crate::probe::{self, RECORD_SIZE};
use crate::report::shaders::Shader;
use crate::scene::Scene;

/// Set and binding of the records buffer and of the probed array (`shadergen::probe_code`; a
/// test holds the generated GLSL to them).
pub const RECORDS_BINDING: u32 = 0;
pub const PROBE_BINDING: u32 = 2;
/// The compute probe's workgroup (`local_size_x/y`).
const GROUP: u32 = 8;

/// Why a cell gets no Amber script (a sentence for the bundle's README).
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum Unfit {
    #[error("canaries are not probe cells (they hang or fault on purpose)")]
    Canary,
    /// The injection's spec.
    #[error("the cell has an injected fault ({0}): Amber cannot reproduce rtprobe's injection (a load through a device address in push constants, per-attempt dice)")]
    Injected(String),
    #[error("Amber has no VK_EXT_descriptor_buffer")]
    DescriptorBuffer,
    #[error("Amber has no VK_EXT_descriptor_heap")]
    DescriptorHeap,
    #[error("ray tracing cell: Amber has ray tracing pipelines and acceleration structures, but rtprobe does not write its scene (16+ transformed instances, multi-geometry BLAS, the procedural AABB, its SBT layout) in AmberScript yet (not implemented)")]
    RayTracing,
    #[error(
        "graphics cell: rtprobe writes Amber scripts for compute cells only (not implemented)"
    )]
    Graphics,
    #[error("image arrays: rtprobe does not write its probe images in AmberScript yet (not implemented)")]
    ImageArrays,
    #[error("acceleration-structure cells need rtprobe's probe TLAS variants (and device addresses for as_access=address), not written in AmberScript")]
    AccelerationStructure,
    /// The push-constant addresses the probe reads.
    #[error("the probe reads device addresses from push constants ({0}), which AmberScript cannot provide")]
    PushAddresses(String),
    #[error(
        "the dynamic value's base is in an SBT shader record, which a compute pipeline has not"
    )]
    ShaderRecordBase,
    #[error("separate samplers from a sampler heap: Amber has no VK_EXT_descriptor_heap")]
    SamplerHeap,
    #[error("rtprobe has no packed {0} buffer to bind at the spec-constant slot (index=dynamic_element)")]
    NoPackedBuffer(Resource),
    #[error("the probe reads an address table, not a descriptor: AmberScript cannot provide device addresses")]
    AddressTable,
    /// The number of shaders of a cell taken for a compute cell.
    #[error("the cell has {0} shaders; a compute cell has one")]
    ShaderCount(usize),
}

/// The script for `cell`, or why none is written (a sentence for the README).
pub fn script(
    cell: &Cell,
    shaders: &[Shader],
    scene: &SceneParams,
    inject: Option<&Injection>,
    origin: &str,
) -> Result<String, Unfit> {
    fits(cell, inject)?;
    let [shader] = shaders else {
        return Err(Unfit::ShaderCount(shaders.len()));
    };
    Ok(write(cell, shader, scene, origin))
}

/// Why `cell` does not fit, checked on its probe spec: what the spec needs that this writer
/// cannot express is refused with that reason.
pub fn fits(cell: &Cell, inject: Option<&Injection>) -> Result<(), Unfit> {
    let spec = ProbeSpec::of(cell);
    if spec.canary.is_some() {
        return Err(Unfit::Canary);
    }
    if let Some(i) = inject {
        return Err(Unfit::Injected(i.spec.clone()));
    }
    match spec.model {
        DescriptorModel::DescriptorIndexing => {}
        DescriptorModel::DescriptorBuffer => return Err(Unfit::DescriptorBuffer),
        DescriptorModel::DescriptorHeap => return Err(Unfit::DescriptorHeap),
    }
    match spec.stage {
        Stage::Compute => {}
        Stage::Raygen
        | Stage::ClosestHit
        | Stage::AnyHit
        | Stage::Miss
        | Stage::Intersection
        | Stage::Callable => return Err(Unfit::RayTracing),
        Stage::Fragment => return Err(Unfit::Graphics),
    }
    match spec.resource {
        Resource::StorageBuffer | Resource::UniformBuffer => {}
        Resource::SampledImage | Resource::StorageImage => return Err(Unfit::ImageArrays),
        Resource::AccelerationStructure => return Err(Unfit::AccelerationStructure),
    }
    let addresses = spec.push_addresses();
    if !addresses.is_empty() {
        return Err(Unfit::PushAddresses(addresses.join(", ")));
    }
    match spec.base {
        // The bases buffer's address was refused above.
        Base::None | Base::PushData | Base::InstanceBuffer => {}
        Base::ShaderRecord => return Err(Unfit::ShaderRecordBase),
    }
    match spec.sampler {
        Sampler::None => {}
        Sampler::Constant | Sampler::Dynamic { .. } => return Err(Unfit::SamplerHeap),
    }
    match (spec.access, spec.element) {
        (
            Access::Slot { .. },
            ElementMap::None | ElementMap::Own | ElementMap::Packed | ElementMap::Layer,
        )
        | (Access::Packed, ElementMap::Packed) => Ok(()),
        (Access::Packed, ElementMap::None | ElementMap::Own | ElementMap::Layer) => {
            Err(Unfit::NoPackedBuffer(spec.resource))
        }
        (
            Access::AddressTable,
            ElementMap::None | ElementMap::Own | ElementMap::Packed | ElementMap::Layer,
        ) => Err(Unfit::AddressTable),
    }
}

fn write(cell: &Cell, shader: &Shader, scene: &SceneParams, origin: &str) -> String {
    let spec = ProbeSpec::of(cell);
    let mut s = String::from("#!amber\n");
    s += &format!(
        "# rtprobe repro: {}\n# {}\n# {origin}\n",
        cell.id(),
        crate::bisect::isolation::describe(cell)
    );
    s += "# Not run by rtprobe: no Amber was available where this was written.\n";
    s += "# The probed array is a runtime descriptor array (SPIR-V RuntimeDescriptorArray";
    if spec.access == (Access::Slot { nonuniform: true })
        || spec.workarounds().any(|w| w == Workaround::Nonuniform)
    {
        s += ", NonUniform indexing";
    }
    s += "): the device must enable VkPhysicalDeviceDescriptorIndexingFeatures for it, which\n# AmberScript's DEVICE_FEATURE list does not name (run with an Amber whose device enables them).\n";
    let (kind, dyn_feature) = match spec.resource {
        Resource::UniformBuffer => ("uniform", "shaderUniformBufferArrayDynamicIndexing"),
        _ => ("storage", "shaderStorageBufferArrayDynamicIndexing"),
    };
    s += &format!("DEVICE_FEATURE {dyn_feature}\n\n");
    s += &format!(
        "# The GLSL rtprobe generated; the SPIR-V below is what the worker runs ({}",
        shader.compiler
    );
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
    let words = scene.pixels() * RECORD_SIZE / 4;
    s += &format!(
        "# Records: {w}x{h} of {RECORD_SIZE} bytes, unwritten ones read flags 0xffffffff.\n"
    );
    s += &format!("BUFFER records DATA_TYPE uint32 SIZE {words} FILL 4294967295\n");
    let pc = probe::push_constants(w, h, scene.instances, spec.resource);
    let pc_words = u32_words(&pc.to_bytes(0)[..probe::PUSH_BLOCK_BYTES as usize]);
    let names: Vec<String> = probe::PUSH_FIELDS
        .iter()
        .map(|f| {
            if f.glsl_type == "uvec2" {
                format!("{}.xy", f.glsl_name)
            } else {
                f.glsl_name.to_string()
            }
        })
        .collect();
    s += &format!("# Push constants ({}).\n", names.join(" "));
    s += &format!("BUFFER pc DATA_TYPE uint32 DATA {} END\n", pc_words.join(" "));
    let (buffers, array) = probed_array(&spec, scene.instances, kind);
    s += &buffers;
    s += "\nPIPELINE compute probe_pipeline\n  ATTACH probe";
    if spec.spec_constant() {
        s += &format!(" SPECIALIZE 0 AS uint32 {}", probe::SPEC_SLOT);
    }
    s +=
        &format!("\n  BIND BUFFER records AS storage DESCRIPTOR_SET 0 BINDING {RECORDS_BINDING}\n");
    s += &format!(
        "  BIND BUFFER_ARRAY {} AS {kind} DESCRIPTOR_SET 0 BINDING {PROBE_BINDING}\n",
        array.join(" ")
    );
    s += "  BIND BUFFER pc AS push_constant\nEND\n\n";
    s += &format!("RUN probe_pipeline {} {} 1\n\n", w.div_ceil(GROUP), h.div_ceil(GROUP));
    s += &expectations(cell, scene);
    s
}

/// The probed array's buffers (one per slot; with the packed descriptor, the packed buffer too)
/// and the names bound at the array's elements, in slot order: the packed buffer at
/// `probe::PACKED_SLOT` where the spec reads it, as the worker binds it.
fn probed_array(spec: &ProbeSpec, instances: u32, kind: &str) -> (String, Vec<String>) {
    let slots = probe::slot_count(spec.resource, instances);
    let layout = if spec.resource == Resource::UniformBuffer { "STD140" } else { "STD430" };
    let mut s = format!("# The probed array: {slots} {kind} buffers of {} vec4, slot s element e = (s+1, kind*16+1, 1000+4s+e, 0.25+e).\n", probe::ELEMENTS);
    for slot in 0..slots {
        if spec.packed() && slot == probe::PACKED_SLOT {
            continue;
        }
        let vals: Vec<String> = (0..probe::ELEMENTS)
            .flat_map(|e| probe::resource_value(spec.resource, slot, e))
            .map(fmt_f32)
            .collect();
        s += &format!(
            "BUFFER slot{slot} DATA_TYPE vec4<float> {layout} DATA {} END\n",
            vals.join(" ")
        );
    }
    let mut names: Vec<String> = (0..slots).map(|k| format!("slot{k}")).collect();
    if spec.packed() {
        let vals: Vec<String> = probe::packed_bytes(spec.resource, slots)
            .chunks(4)
            .map(|b| fmt_f32(f32::from_le_bytes([b[0], b[1], b[2], b[3]])))
            .collect();
        s += &format!(
            "# index=dynamic_element: the packed buffer, bound at the spec-constant slot {} in place of that slot's own, holds every\n# slot's elements (slot s element e at v[{}*s+e]); the dynamic value selects inside it.\n",
            probe::PACKED_SLOT,
            probe::ELEMENTS
        );
        s += &format!("BUFFER packed DATA_TYPE vec4<float> {layout} DATA {} END\n", vals.join(" "));
        names[probe::PACKED_SLOT as usize] = "packed".into();
    }
    (s, names)
}

/// The expected records as EXPECT lines, or why there are none.
fn expectations(cell: &Cell, params: &SceneParams) -> String {
    if ProbeSpec::of(cell).read == ReadIndex::Undefined {
        return format!("# No EXPECT: the index is dynamic without nonuniformEXT, so which element a lane reads is\n# undefined ({}); rtprobe accepts another lane's element there.\n", crate::model::NO_NONUNIFORM_VUID);
    }
    let scene = Scene::build(params);
    let sref = crate::reference::SceneReference::compute(&scene);
    let expected = crate::reference::expected(cell, &scene, &sref);
    let mut s = String::from("# Record of pixel (x, y) at byte 64*(x + y*width): flags custom instanceId geometry primitive\n# t bary.x bary.y slot element pad pad2 value.x value.y value.z value.w, as uint32 (floats as bits).\n");
    for (p, e) in expected.iter().enumerate() {
        s += &format!(
            "EXPECT records IDX {} EQ {}\n",
            p * RECORD_SIZE,
            u32_words(&e.record.to_bytes()).join(" ")
        );
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
    use crate::model::{AsAccess, IndexSource};
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
        let shaders = cell_shaders(&cell, None, false).unwrap();
        let text = script(&cell, &shaders, &small(), None, "test").unwrap();
        assert!(text.starts_with("#!amber\n"));
        // The SPIR-V, byte for byte: the magic number little-endian first.
        assert!(
            text.contains("SHADER compute probe SPIRV-HEX\n03 02 23 07 "),
            "{}",
            &text[..400.min(text.len())]
        );
        let hex: Vec<u8> = text
            .split("SPIRV-HEX\n")
            .nth(1)
            .unwrap()
            .split("\nEND")
            .next()
            .unwrap()
            .split_whitespace()
            .map(|b| u8::from_str_radix(b, 16).unwrap())
            .collect();
        assert_eq!(hex, crate::report::shaders::spirv_bytes(&shaders[0].spirv));
        // The GLSL as comments, the buffers, the binding and the dispatch.
        assert!(
            text.contains("#   layout(set = 0, binding = 2, std430) readonly buffer ProbeBuffer"),
            "GLSL comment"
        );
        let slots = probe::slot_count(cell.resource, small().instances);
        assert!(
            text.contains(&format!("BUFFER slot{} DATA_TYPE vec4<float> STD430 DATA ", slots - 1))
        );
        assert!(!text.contains(&format!("BUFFER slot{slots} ")));
        assert!(
            text.contains("BIND BUFFER_ARRAY slot0 slot1 ")
                && text.contains(" AS storage DESCRIPTOR_SET 0 BINDING 2\n")
        );
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
        let text =
            script(&cell, &cell_shaders(&cell, None, false).unwrap(), &small(), None, "test")
                .unwrap();
        assert!(text.contains(&format!("ATTACH probe SPECIALIZE 0 AS uint32 {}", probe::SPEC_SLOT)));
        assert!(
            text.contains("STD140 DATA") && text.contains(" AS uniform DESCRIPTOR_SET 0 BINDING 2")
        );
        assert!(text.contains("DEVICE_FEATURE shaderUniformBufferArrayDynamicIndexing"));
    }

    /// The twin of a bug `ProbeSpec` fixed: `dynamic_element` reads the packed buffer at the
    /// spec-constant slot, but the script specialized only `index=spec_constant` cells and bound
    /// every slot's own buffer, so on a correct driver every pixel whose slot was not 0 failed.
    /// Now the script specializes the slot and binds the packed buffer there, and what the script
    /// binds, read where the shader reads it, is what its EXPECT lines say.
    #[test]
    fn a_dynamic_element_cell_specializes_the_slot_and_binds_the_packed_buffer() {
        let cell = compute(Resource::StorageBuffer, IndexSource::DynamicElement);
        assert_eq!(cell.id(), "compute.storage_buffer.dynamic_element.descriptor_indexing");
        let text =
            script(&cell, &cell_shaders(&cell, None, false).unwrap(), &small(), None, "test")
                .unwrap();
        assert!(
            text.contains(&format!("ATTACH probe SPECIALIZE 0 AS uint32 {}\n", probe::PACKED_SLOT)),
            "no SPECIALIZE"
        );
        let slots = probe::slot_count(cell.resource, small().instances);
        let names: Vec<String> = (0..slots)
            .map(|k| if k == probe::PACKED_SLOT { "packed".into() } else { format!("slot{k}") })
            .collect();
        assert!(
            text.contains(&format!(
                "  BIND BUFFER_ARRAY {} AS storage DESCRIPTOR_SET 0 BINDING 2\n",
                names.join(" ")
            )),
            "the packed buffer is not bound at the spec slot"
        );
        let packed: Vec<f32> = text
            .lines()
            .find_map(|l| l.strip_prefix("BUFFER packed DATA_TYPE vec4<float> STD430 DATA "))
            .expect("the packed buffer")
            .trim_end_matches(" END")
            .split(' ')
            .map(|v| v.parse().unwrap())
            .collect();
        let want: Vec<f32> = probe::packed_bytes(cell.resource, slots)
            .chunks(4)
            .map(|b| f32::from_le_bytes(b.try_into().unwrap()))
            .collect();
        assert_eq!(packed, want);
        assert!(
            !text.contains(&format!("BUFFER slot{} ", probe::PACKED_SLOT))
                && text.contains(&format!("BUFFER slot{} ", slots - 1))
        );
        // Every pixel is expected exactly, and reads its record's (slot, element) in the packed buffer.
        let expects: Vec<Vec<u32>> = text
            .lines()
            .filter(|l| l.starts_with("EXPECT records IDX "))
            .map(|l| l.split_whitespace().skip(5).map(|w| w.parse().unwrap()).collect())
            .collect();
        assert_eq!(expects.len(), small().pixels());
        for words in &expects {
            let at = probe::packed_element(words[8], words[9]) as usize * 4;
            assert_eq!(
                words[12..16],
                packed[at..at + 4].iter().map(|v| v.to_bits()).collect::<Vec<_>>()
            );
        }
        assert!(expects.iter().any(|w| w[8] != 0 && w[8] != probe::PACKED_SLOT));
    }

    #[test]
    fn a_lenient_dynamic_cell_has_no_expectations_and_says_why() {
        let cell = compute(Resource::StorageBuffer, IndexSource::Dynamic);
        let text =
            script(&cell, &cell_shaders(&cell, None, false).unwrap(), &small(), None, "test")
                .unwrap();
        assert!(!text.contains("\nEXPECT "));
        assert!(text.contains("No EXPECT: the index is dynamic without nonuniformEXT"));
    }

    #[test]
    fn cells_that_do_not_fit_say_why() {
        let c = compute(Resource::StorageBuffer, IndexSource::Literal);
        let heap = Cell {
            descriptor_model: DescriptorModel::DescriptorHeap,
            heap_access: Some(crate::model::HeapAccess::MappedConstantOffset),
            ..c
        };
        assert_eq!(
            fits(&heap, None).unwrap_err().to_string(),
            "Amber has no VK_EXT_descriptor_heap"
        );
        let buf = Cell { descriptor_model: DescriptorModel::DescriptorBuffer, ..c };
        assert_eq!(
            fits(&buf, None).unwrap_err().to_string(),
            "Amber has no VK_EXT_descriptor_buffer"
        );
        assert!(fits(&Cell { stage: Stage::ClosestHit, ..c }, None)
            .unwrap_err()
            .to_string()
            .starts_with("ray tracing cell"));
        assert!(fits(
            &Cell {
                resource: Resource::AccelerationStructure,
                as_access: Some(AsAccess::Address),
                ..c
            },
            None
        )
        .is_err());
        // Refusals come from what the spec needs.
        let ssbo =
            Cell { index: IndexSource::Dynamic, patch: Some(Workaround::SsboToAddress), ..c };
        assert_eq!(fits(&ssbo, None).unwrap_err().to_string(), "the probe reads device addresses from push constants (patchedTable), which AmberScript cannot provide");
        let ubo_packed = compute(Resource::UniformBuffer, IndexSource::DynamicElement);
        assert!(fits(&ubo_packed, None)
            .unwrap_err()
            .to_string()
            .starts_with("rtprobe has no packed uniform_buffer buffer"));
        assert!(fits(&Cell { patch: Some(Workaround::PinIndex), ..ssbo }, None).is_ok());
        let inj = Injection::parse("stage=compute").unwrap();
        assert!(fits(&c, Some(&inj)).unwrap_err().to_string().contains("injected fault"));
        assert!(fits(&c, None).is_ok());
    }

    #[test]
    fn the_bindings_are_the_generated_glsls() {
        for r in [Resource::StorageBuffer, Resource::UniformBuffer] {
            let cell = compute(r, IndexSource::Literal);
            let glsl = &cell_shaders(&cell, None, false).unwrap()[0].glsl;
            assert!(
                glsl.contains(&format!(
                    "layout(set = 0, binding = {RECORDS_BINDING}, std430) buffer Records"
                )),
                "{glsl}"
            );
            assert!(
                glsl.contains(&format!("layout(set = 0, binding = {PROBE_BINDING}, ")),
                "{glsl}"
            );
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
