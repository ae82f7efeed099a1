//! What a driver engineer asks first, from the cell's probe spec (`probe::spec`), the records'
//! comparison and the device: expected against actual values (which slot and element each value
//! is), the descriptor layout (binding, type, array size, binding flags; a heap's mapping, record
//! bytes and byte offsets), the index values with the scene's custom-index range and whether
//! they stay in bounds, and the SBT layout (`exec::pipeline::sbt_layout`, the worker's own
//! arithmetic) with the recursion depth.
use super::text::{comparisons, worst};
use super::types::{Facts, SbtProps};
use crate::model::{Cell, CellReport, DescriptorModel, HeapAccess, Resource, RunReport, Stage};
use crate::probe::spec::{Access, Base, ProbeSpec, ReadIndex, SlotSource};
use crate::probe::{self, ELEMENTS};
use crate::shadergen::Role;

pub(super) fn of(
    report: &RunReport,
    cell: &Cell,
    entry: Option<&CellReport>,
    sbt: Option<SbtProps>,
) -> Facts {
    Facts {
        values: values(cell, entry, report.scene.params.instances),
        layout: layout(cell, entry, report.scene.params.instances),
        index: index(cell, &report.scene.params),
        sbt: sbt_text(cell, entry, sbt),
    }
}

/// `[4.0, 33.0, 1014.0, 2.25]` as four floats.
pub(super) fn parse_value(s: &str) -> Option<[f32; 4]> {
    let v: Vec<f32> = s
        .trim()
        .strip_prefix('[')?
        .strip_suffix(']')?
        .split(',')
        .map(|x| x.trim().parse().ok())
        .collect::<Option<_>>()?;
    v.try_into().ok()
}

/// Which (slot, element) of the probed array holds `v` (`probe::resource_value`), if one does.
pub(super) fn whose(resource: Resource, slots: u32, v: [f32; 4]) -> Option<(u32, u32)> {
    (0..slots.max(64))
        .flat_map(|s| (0..ELEMENTS).map(move |e| (s, e)))
        .find(|&(s, e)| probe::resource_value(resource, s, e) == v)
}

/// Expected against actual at the first mismatching pixel of the latest mismatching attempt,
/// each value named by the slot and element that hold it; or what happened instead of records.
fn values(cell: &Cell, entry: Option<&CellReport>, instances: u32) -> String {
    let Some(cmp) = comparisons(entry).find(|c| !c.passed()) else {
        let a = entry.and_then(worst);
        return match a {
            Some(a) => format!(
                "No records to compare: the attempt ended `{}` in phase {}.",
                a.outcome.as_str(),
                a.phase.map(|p| p.as_str()).unwrap_or("unknown")
            ),
            None => "No attempt of this cell is in the run report.".into(),
        };
    };
    let Some(m) = cmp.examples.first() else {
        return format!("{} of {} compared pixels differ.", cmp.mismatched_pixels, cmp.compared);
    };
    let at = format!("pixel ({}, {}), field `{}`", m.pixel[0], m.pixel[1], m.field);
    let slots = probe::slot_count(cell.resource, instances);
    let heap = cmp.heap.as_ref();
    let name = |s: &str| match parse_value(s).and_then(|v| whose(cell.resource, slots, v)) {
        Some((slot, e)) => {
            let byte =
                heap.map(|h| format!(", heap byte {}", h.probe_offset + slot * h.probe_stride));
            format!("`{s}` = slot {slot} element {e}{}", byte.unwrap_or_default())
        }
        None if m.field == "value" => format!("`{s}` (no element of the array holds it)"),
        None => format!("`{s}`"),
    };
    let slot_of = |s: &str| parse_value(s).and_then(|v| whose(cell.resource, slots, v));
    let offset = match (heap, slot_of(&m.expected), slot_of(&m.actual)) {
        (Some(h), Some((se, _)), Some((sa, _))) if se != sa => format!(
            " The descriptor read is {} × {} = {} bytes {} the expected one.",
            se.abs_diff(sa),
            h.probe_stride,
            se.abs_diff(sa) * h.probe_stride,
            if sa < se { "before" } else { "after" }
        ),
        _ => String::new(),
    };
    format!(
        "at {at}: expected {}, got {}.{offset} {} of {} compared pixels differ ({} of them on the probed value).",
        name(&m.expected),
        name(&m.actual),
        cmp.mismatched_pixels,
        cmp.compared,
        cmp.by_field.get("value").copied().unwrap_or(0)
    )
}

fn ray_tracing(stage: Stage) -> bool {
    match stage {
        Stage::Raygen
        | Stage::ClosestHit
        | Stage::AnyHit
        | Stage::Miss
        | Stage::Intersection
        | Stage::Callable => true,
        Stage::Fragment | Stage::Compute => false,
    }
}

/// Whether the device feature that makes rtprobe set UPDATE_AFTER_BIND for `resource` was
/// enabled in the attempt (`exec::bindings::layout::binding_flags`).
fn update_after_bind(resource: Resource, entry: Option<&CellReport>) -> bool {
    let feature = match resource {
        Resource::StorageBuffer => "descriptorBindingStorageBufferUpdateAfterBind",
        Resource::UniformBuffer => "descriptorBindingUniformBufferUpdateAfterBind",
        Resource::SampledImage => "descriptorBindingSampledImageUpdateAfterBind",
        Resource::StorageImage => "descriptorBindingStorageImageUpdateAfterBind",
        Resource::AccelerationStructure => "descriptorBindingAccelerationStructureUpdateAfterBind",
    };
    entry.and_then(worst).is_some_and(|a| a.device_features.iter().any(|f| f == feature))
}

/// Set 0's bindings and the probed array's size, type and binding flags, or the heap's mapping.
fn layout(cell: &Cell, entry: Option<&CellReport>, instances: u32) -> String {
    let spec = ProbeSpec::of(cell);
    let n = probe::slot_count(spec.resource, instances);
    let ty = format!("{:?}", crate::exec::resources::descriptor_type(spec.resource));
    let tlas = if ray_tracing(spec.stage) {
        ", binding 1 the scene TLAS (ACCELERATION_STRUCTURE_KHR)"
    } else {
        ""
    };
    let packed = match spec.access {
        Access::Packed => format!("; slot {} holds the packed resource (index=dynamic_element)", probe::PACKED_SLOT),
        Access::Slot { .. } => String::new(),
        Access::AddressTable => "; the probed acceleration structure is read through a device-address table, not this binding".into(),
    };
    let array = format!(
        "binding 2 the probed array: {n} × {ty}, every element written before the trace{packed}"
    );
    match spec.model {
        DescriptorModel::DescriptorIndexing => {
            let uab = if update_after_bind(spec.resource, entry) {
                " | UPDATE_AFTER_BIND (set layout UPDATE_AFTER_BIND_POOL)"
            } else {
                ""
            };
            format!("descriptor set 0 (descriptor indexing): binding 0 the records (STORAGE_BUFFER){tlas}, {array}, binding flags PARTIALLY_BOUND{uab}; push constants {} bytes, every stage.", probe::PUSH_CONSTANT_BYTES)
        }
        DescriptorModel::DescriptorBuffer => format!("VK_EXT_descriptor_buffer: set 0 (layout DESCRIPTOR_BUFFER_BIT_EXT, no binding flags) in one descriptor buffer bound with vkCmdSetDescriptorBufferOffsetsEXT (set 0 → buffer index 0, offset 0), each binding's descriptors written at vkGetDescriptorSetLayoutBindingOffsetEXT's offset with the device's descriptor size as stride (both the device's; the report does not record them): binding 0 the records{tlas}, {array}; push constants {} bytes.", probe::PUSH_CONSTANT_BYTES),
        DescriptorModel::DescriptorHeap => heap_layout(cell, entry, &array),
    }
}

/// A heap cell's mapping and offsets, from the attempt's heap detail.
fn heap_layout(cell: &Cell, entry: Option<&CellReport>, array: &str) -> String {
    let Some(h) = comparisons(entry).find_map(|c| c.heap.as_ref()) else {
        return format!("VK_EXT_descriptor_heap ({}): {array}; the mapping and byte offsets are recorded with a comparison, and no attempt of this cell got that far.", cell.heap_access.map(|h| h.as_str()).unwrap_or("?"));
    };
    let record = if h.shader_record.is_empty() {
        "no shader record data".into()
    } else {
        format!(
            "shader record data `{}` after every SBT handle (heap index, then base: u32 LE)",
            h.shader_record
        )
    };
    format!(
        "VK_EXT_descriptor_heap: set 0 binding 2 → {}; {}; {record}; the array's element 0 at resource-heap byte {}, stride {}: slot s at byte {} + s × {}.",
        h.mapping, mapping_entries(h), h.probe_offset, h.probe_stride, h.probe_offset, h.probe_stride
    )
}

/// What the recorded `VkDescriptorSetAndBindingMappingEXT` entries add to binding 2's mapping:
/// its set, bindings and resource mask, its sampler members, and the other entries' offsets; or
/// that the report predates them.
pub(super) fn mapping_entries(h: &crate::model::comparison::HeapDetail) -> String {
    let Some(probe) = h.mappings.iter().find(|m| m.first_binding == 2) else {
        return "the run's rtprobe did not record the VkDescriptorSetAndBindingMappingEXT entries (descriptorSet, firstBinding, bindingCount, the sampler members): a re-run of the cell does".into();
    };
    let sampler = match probe.sampler_fields() {
        f if f.is_empty() => String::new(),
        f => format!(", sampler members {f}"),
    };
    let others: Vec<String> = h
        .mappings
        .iter()
        .filter(|m| m.first_binding != 2)
        .map(|m| {
            let offset = m.fields.iter().find(|(n, _)| n == "heapOffset").map(|(_, v)| v.as_str());
            format!(
                "binding {} {} heapOffset {}",
                m.first_binding,
                m.source_member,
                offset.unwrap_or("?")
            )
        })
        .collect();
    format!(
        "its VkDescriptorSetAndBindingMappingEXT: {}{sampler}; {}",
        probe.header(),
        if others.is_empty() { "no other entry".to_string() } else { others.join(", ") }
    )
}

/// The smallest and largest base a hit's dynamic value adds (`Base::value`).
fn base_range(base: Base, instances: u32) -> (u32, u32) {
    let all: Vec<u32> =
        (0..instances).flat_map(|i| [base.value(i, false), base.value(i, true)]).collect();
    (all.iter().copied().min().unwrap_or(0), all.iter().copied().max().unwrap_or(0))
}

fn base_text(base: Base) -> String {
    match base {
        Base::None | Base::PushData => format!("push constant dynBase = {}", probe::DYNAMIC_BASE),
        Base::ShaderRecord => format!(
            "the hit group's shader record dynBase (triangles {}, procedural {})",
            probe::RECORD_BASE_TRIANGLES,
            probe::RECORD_BASE_PROCEDURAL
        ),
        Base::InstanceBuffer => {
            "loaded per instance from a bases buffer (1 + gl_InstanceID % 2) through a device address in push constants".into()
        }
    }
}

/// The index the probe uses, its range over the scene, and whether it stays in bounds.
fn index(cell: &Cell, params: &crate::model::SceneParams) -> String {
    let spec = ProbeSpec::of(cell);
    let n = probe::slot_count(spec.resource, params.instances);
    let (what, lo, hi) = match spec.slot {
        SlotSource::Literal => (
            format!("literal {} in the GLSL", probe::LITERAL_SLOT),
            probe::LITERAL_SLOT,
            probe::LITERAL_SLOT,
        ),
        SlotSource::SpecConstant => (
            format!(
                "specialization constant 0 = {} (its default in the SPIR-V: 0)",
                probe::SPEC_SLOT
            ),
            probe::SPEC_SLOT,
            probe::SPEC_SLOT,
        ),
        SlotSource::PushConstant => (
            format!("push constant pushSlot = {}", probe::PUSH_SLOT),
            probe::PUSH_SLOT,
            probe::PUSH_SLOT,
        ),
        SlotSource::Dynamic => dynamic_index(&spec, params, n),
    };
    let qualifier = match (spec.access, spec.read) {
        (Access::Slot { nonuniform: true }, _) => ", with nonuniformEXT",
        (_, ReadIndex::Undefined) => ", without nonuniformEXT on a non-uniform index: the read is undefined (VUID-RuntimeSpirv-None-10148)",
        (_, ReadIndex::Pinned) => ", pinned to the spec-constant slot by the pin-index patch",
        (_, ReadIndex::Defined) => "",
    };
    let bounds = if hi < n { "in bounds" } else { "OUT OF BOUNDS" };
    let element = match spec.stage {
        Stage::ClosestHit | Stage::AnyHit | Stage::Intersection => {
            "(gl_PrimitiveID + gl_GeometryIndexEXT + gl_InstanceID) & 3"
        }
        Stage::Raygen | Stage::Miss | Stage::Callable | Stage::Compute | Stage::Fragment => {
            "((x >> 1) ^ y) & 3 of the pixel"
        }
    };
    format!("slot = {what}{qualifier}: slots {lo}..={hi} of the {n} bound ({bounds}); element = {element}, of {ELEMENTS}.")
}

/// A dynamic index: its expression, and its lowest and highest value over the scene.
fn dynamic_index(
    spec: &ProbeSpec,
    params: &crate::model::SceneParams,
    n: u32,
) -> (String, u32, u32) {
    match spec.stage {
        Stage::ClosestHit | Stage::AnyHit | Stage::Intersection => {
            let mask = probe::dyn_mask(spec.resource, params.instances);
            let (blo, bhi) = base_range(spec.base, params.instances);
            // A `--scene` file's custom indices need the file: without it, the whole mask.
            let scene = match crate::scene::Scene::of(params) {
                Ok(s) => s,
                Err(e) => {
                    let text = format!("base + (gl_InstanceCustomIndexEXT & {mask:#x}), base = {}; the scene file's custom indices unknown ({e})", base_text(spec.base));
                    return (text, blo, bhi + mask);
                }
            };
            let customs: Vec<u32> = scene.instances.iter().map(|i| i.custom_index).collect();
            let (cmin, cmax) = (
                customs.iter().min().copied().unwrap_or(0),
                customs.iter().max().copied().unwrap_or(0),
            );
            let masked: Vec<u32> = customs.iter().map(|c| c & mask).collect();
            let (mlo, mhi) = (
                masked.iter().min().copied().unwrap_or(0),
                masked.iter().max().copied().unwrap_or(0),
            );
            (
                format!("base + (gl_InstanceCustomIndexEXT & {mask:#x}), base = {}; the scene's custom indices {cmin}..={cmax} (masked {mlo}..={mhi})", base_text(spec.base)),
                blo + mlo,
                bhi + mhi,
            )
        }
        Stage::Fragment => (format!("the pixel's 8×8 tile number mod {n}"), 0, n - 1),
        Stage::Raygen | Stage::Miss | Stage::Callable | Stage::Compute => {
            (format!("(x + y × width) mod {n}"), 0, n - 1)
        }
    }
}

/// The SBT layout and recursion depth of a ray tracing cell (empty for others).
fn sbt_text(cell: &Cell, entry: Option<&CellReport>, props: Option<SbtProps>) -> String {
    let spec = ProbeSpec::of(cell);
    if !ray_tracing(spec.stage) {
        return String::new();
    }
    let shaders = crate::shadergen::generate(cell);
    let counts = crate::exec::pipeline::sbt_counts(&shaders);
    let has = |r: Role| shaders.get(r).is_some();
    let any = if has(Role::AnyHit) { " + any-hit" } else { "" };
    let record_data =
        spec.heap == Some(HeapAccess::MappedShaderRecordIndex) || spec.base == Base::ShaderRecord;
    let rec = if record_data { std::mem::size_of::<probe::ShaderRecordData>() as u64 } else { 0 };
    let data = comparisons(entry)
        .find_map(|c| c.heap.as_ref())
        .filter(|h| !h.shader_record.is_empty())
        .map(|h| format!(" `{}`", h.shader_record))
        .unwrap_or_default();
    let groups = format!(
        "raygen | miss: primary, AS probe | hit: 0 triangles (closest-hit{any}), 1 procedural (intersection + closest-hit{any}){}",
        if counts.callable > 0 { " | callable 0" } else { "" }
    );
    let layout = match props {
        Some(p) => {
            let l = crate::exec::pipeline::sbt_layout(counts, p.handle_size as u64, p.handle_alignment as u64, p.base_alignment as u64, rec);
            format!("each record a {}-byte handle + {rec} bytes of data{data}, stride {}; raygen region {} bytes, miss at +{}, hit at +{}{}", p.handle_size, l.stride, l.raygen_size, l.miss_off, l.hit_off, if counts.callable > 0 { format!(", callable at +{}", l.call_off) } else { String::new() })
        }
        None => format!("each record the handle + {rec} bytes of data{data}, stride align(handle + {rec}, shaderGroupHandleAlignment) (the device is not on this machine: its handle size is unknown here)"),
    };
    let max =
        props.map(|p| format!(" (device maximum {})", p.max_recursion_depth)).unwrap_or_default();
    format!(
        "groups {groups}; instance SBT offsets: triangle meshes 0, the sphere 1; traceRayEXT sbtRecordOffset 0, sbtRecordStride 0, missIndex 0; {layout}; maxPipelineRayRecursionDepth {}{max}.",
        shaders.recursion_depth
    )
}
