//! The set/binding → heap mapping chained to every shader stage of a heap pipeline
//! (VkShaderDescriptorSetAndBindingMappingInfoEXT): records and scene TLAS at constant offsets,
//! the probed array (binding 2) as the cell's `heap_access` says.
use super::layout::HeapLayout;
use super::push::{PUSH_INDEX_ADDRESS_OFFSET, PUSH_INDEX_OFFSET};
use crate::model::comparison::BindingMapping;
use crate::model::HeapAccess;
use crate::vk::heap::{self as h, MappingSource};
use ash::vk;
use std::ffi::c_void;

/// A constant-offset mapping source: `heap_offset`, arrays at `stride`.
fn constant(heap_offset: u32, stride: u32) -> h::MappingSourceData {
    h::MappingSourceData {
        constant_offset: h::MappingConstantOffset {
            heap_offset,
            heap_array_stride: stride,
            p_embedded_sampler: std::ptr::null(),
            sampler_heap_offset: 0,
            sampler_heap_array_stride: 0,
        },
    }
}

/// Where binding 2 (the probed array) comes from for a cell reaching the heap `access`-wise, for
/// a heap laid out as `l`; `None` for direct cells (the probe reads the heap itself).
fn probe_source(
    access: HeapAccess,
    l: &HeapLayout,
) -> Option<(MappingSource, h::MappingSourceData)> {
    let stride = l.probe_stride;
    match access {
        HeapAccess::MappedConstantOffset => {
            Some((MappingSource::HeapWithConstantOffset, constant(l.probe, stride)))
        }
        HeapAccess::MappedPushIndex => Some((
            MappingSource::HeapWithPushIndex,
            h::MappingSourceData {
                push_index: h::MappingPushIndex {
                    heap_offset: 0,
                    push_offset: PUSH_INDEX_OFFSET,
                    heap_index_stride: stride,
                    heap_array_stride: stride,
                    p_embedded_sampler: std::ptr::null(),
                    use_combined_image_sampler_index: vk::FALSE,
                    sampler_heap_offset: 0,
                    sampler_push_offset: PUSH_INDEX_OFFSET,
                    sampler_heap_index_stride: 0,
                    sampler_heap_array_stride: 0,
                },
            },
        )),
        HeapAccess::MappedIndirectIndex => Some((
            MappingSource::HeapWithIndirectIndex,
            h::MappingSourceData {
                indirect_index: h::MappingIndirectIndex {
                    heap_offset: 0,
                    push_offset: PUSH_INDEX_ADDRESS_OFFSET,
                    address_offset: 0,
                    heap_index_stride: stride,
                    heap_array_stride: stride,
                    p_embedded_sampler: std::ptr::null(),
                    use_combined_image_sampler_index: vk::FALSE,
                    sampler_heap_offset: 0,
                    sampler_push_offset: PUSH_INDEX_ADDRESS_OFFSET,
                    sampler_address_offset: 0,
                    sampler_heap_index_stride: 0,
                    sampler_heap_array_stride: 0,
                },
            },
        )),
        HeapAccess::MappedShaderRecordIndex => Some((
            MappingSource::HeapWithShaderRecordIndex,
            h::MappingSourceData {
                shader_record_index: h::MappingShaderRecordIndex {
                    heap_offset: 0,
                    shader_record_offset: 0,
                    heap_index_stride: stride,
                    heap_array_stride: stride,
                    p_embedded_sampler: std::ptr::null(),
                    use_combined_image_sampler_index: vk::FALSE,
                    sampler_heap_offset: 0,
                    sampler_shader_record_offset: 0,
                    sampler_heap_index_stride: 0,
                    sampler_heap_array_stride: 0,
                },
            },
        )),
        HeapAccess::Direct => None,
    }
}

/// Binding 2's mapping of a cell reaching the heap `access`-wise, in the words of
/// VkDescriptorSetAndBindingMappingEXT (for the vendor issue); a direct cell's shader reads the heap
/// itself.
pub fn describe(access: HeapAccess, l: &HeapLayout) -> String {
    let Some((source, data)) = probe_source(access, l) else {
        return "none: the shader indexes the resource heap itself (layout(descriptor_heap)), the array at heap index 0".into();
    };
    // Each arm reads the union member `source` says is written (probe_source writes exactly it).
    unsafe {
        match source {
            MappingSource::HeapWithConstantOffset => {
                let d = data.constant_offset;
                format!(
                    "HEAP_WITH_CONSTANT_OFFSET {{ heapOffset {}, heapArrayStride {} }}",
                    d.heap_offset, d.heap_array_stride
                )
            }
            MappingSource::HeapWithPushIndex => {
                let d = data.push_index;
                format!("HEAP_WITH_PUSH_INDEX {{ heapOffset {}, pushOffset {}, heapIndexStride {}, heapArrayStride {} }} (push data holds heap index {})", d.heap_offset, d.push_offset, d.heap_index_stride, d.heap_array_stride, l.probe_index())
            }
            MappingSource::HeapWithIndirectIndex => {
                let d = data.indirect_index;
                format!("HEAP_WITH_INDIRECT_INDEX {{ heapOffset {}, pushOffset {}, addressOffset {}, heapIndexStride {}, heapArrayStride {} }} (the addressed buffer holds heap index {})", d.heap_offset, d.push_offset, d.address_offset, d.heap_index_stride, d.heap_array_stride, l.probe_index())
            }
            MappingSource::HeapWithShaderRecordIndex => {
                let d = data.shader_record_index;
                format!("HEAP_WITH_SHADER_RECORD_INDEX {{ heapOffset {}, shaderRecordOffset {}, heapIndexStride {}, heapArrayStride {} }} (every record holds heap index {})", d.heap_offset, d.shader_record_offset, d.heap_index_stride, d.heap_array_stride, l.probe_index())
            }
        }
    }
}

/// A member of a mapping source struct as the driver gets it.
#[derive(Clone, Copy)]
enum Member {
    U32(u32),
    Bool(vk::Bool32),
    Sampler(*const vk::SamplerCreateInfo<'static>),
}

impl Member {
    /// The member as a word of the pipeline's identity (a sampler pointer: whether it is set).
    fn word(self) -> u32 {
        match self {
            Member::U32(v) | Member::Bool(v) => v,
            Member::Sampler(p) => u32::from(!p.is_null()),
        }
    }

    /// The member as the issue names it.
    fn text(self) -> String {
        match self {
            Member::U32(v) => v.to_string(),
            Member::Bool(b) => if b == vk::FALSE { "VK_FALSE" } else { "VK_TRUE" }.into(),
            Member::Sampler(p) if p.is_null() => "NULL".into(),
            Member::Sampler(_) => "an embedded VkSamplerCreateInfo".into(),
        }
    }
}

/// A source's registry name, its `sourceData` member's name and that member's fields.
type Members = (&'static str, &'static str, Vec<(&'static str, Member)>);

/// `source`'s name in the registry, the member of `sourceData` it selects, and that member's
/// fields in declaration order with their names in `vk.xml` (Vulkan 1.4.360).
fn source_members(source: MappingSource, data: &h::MappingSourceData) -> Members {
    use Member::{Bool, Sampler, U32};
    // SAFETY: each arm reads the union member that `source` names, the one `probe_source` and
    // `constant` write for it.
    unsafe {
        match source {
            MappingSource::HeapWithConstantOffset => {
                let c = data.constant_offset;
                (
                    "VK_DESCRIPTOR_MAPPING_SOURCE_HEAP_WITH_CONSTANT_OFFSET_EXT",
                    "constantOffset",
                    vec![
                        ("heapOffset", U32(c.heap_offset)),
                        ("heapArrayStride", U32(c.heap_array_stride)),
                        ("pEmbeddedSampler", Sampler(c.p_embedded_sampler)),
                        ("samplerHeapOffset", U32(c.sampler_heap_offset)),
                        ("samplerHeapArrayStride", U32(c.sampler_heap_array_stride)),
                    ],
                )
            }
            MappingSource::HeapWithPushIndex => {
                let p = data.push_index;
                (
                    "VK_DESCRIPTOR_MAPPING_SOURCE_HEAP_WITH_PUSH_INDEX_EXT",
                    "pushIndex",
                    vec![
                        ("heapOffset", U32(p.heap_offset)),
                        ("pushOffset", U32(p.push_offset)),
                        ("heapIndexStride", U32(p.heap_index_stride)),
                        ("heapArrayStride", U32(p.heap_array_stride)),
                        ("pEmbeddedSampler", Sampler(p.p_embedded_sampler)),
                        ("useCombinedImageSamplerIndex", Bool(p.use_combined_image_sampler_index)),
                        ("samplerHeapOffset", U32(p.sampler_heap_offset)),
                        ("samplerPushOffset", U32(p.sampler_push_offset)),
                        ("samplerHeapIndexStride", U32(p.sampler_heap_index_stride)),
                        ("samplerHeapArrayStride", U32(p.sampler_heap_array_stride)),
                    ],
                )
            }
            MappingSource::HeapWithIndirectIndex => indirect_members(&data.indirect_index),
            MappingSource::HeapWithShaderRecordIndex => record_members(&data.shader_record_index),
        }
    }
}

fn indirect_members(i: &h::MappingIndirectIndex) -> Members {
    use Member::{Bool, Sampler, U32};
    let name = "VK_DESCRIPTOR_MAPPING_SOURCE_HEAP_WITH_INDIRECT_INDEX_EXT";
    (
        name,
        "indirectIndex",
        vec![
            ("heapOffset", U32(i.heap_offset)),
            ("pushOffset", U32(i.push_offset)),
            ("addressOffset", U32(i.address_offset)),
            ("heapIndexStride", U32(i.heap_index_stride)),
            ("heapArrayStride", U32(i.heap_array_stride)),
            ("pEmbeddedSampler", Sampler(i.p_embedded_sampler)),
            ("useCombinedImageSamplerIndex", Bool(i.use_combined_image_sampler_index)),
            ("samplerHeapOffset", U32(i.sampler_heap_offset)),
            ("samplerPushOffset", U32(i.sampler_push_offset)),
            ("samplerAddressOffset", U32(i.sampler_address_offset)),
            ("samplerHeapIndexStride", U32(i.sampler_heap_index_stride)),
            ("samplerHeapArrayStride", U32(i.sampler_heap_array_stride)),
        ],
    )
}

fn record_members(r: &h::MappingShaderRecordIndex) -> Members {
    use Member::{Bool, Sampler, U32};
    let name = "VK_DESCRIPTOR_MAPPING_SOURCE_HEAP_WITH_SHADER_RECORD_INDEX_EXT";
    (
        name,
        "shaderRecordIndex",
        vec![
            ("heapOffset", U32(r.heap_offset)),
            ("shaderRecordOffset", U32(r.shader_record_offset)),
            ("heapIndexStride", U32(r.heap_index_stride)),
            ("heapArrayStride", U32(r.heap_array_stride)),
            ("pEmbeddedSampler", Sampler(r.p_embedded_sampler)),
            ("useCombinedImageSamplerIndex", Bool(r.use_combined_image_sampler_index)),
            ("samplerHeapOffset", U32(r.sampler_heap_offset)),
            ("samplerShaderRecordOffset", U32(r.sampler_shader_record_offset)),
            ("samplerHeapIndexStride", U32(r.sampler_heap_index_stride)),
            ("samplerHeapArrayStride", U32(r.sampler_heap_array_stride)),
        ],
    )
}

/// `resourceMask` by its registry name where rtprobe's one value, else in hex.
fn resource_mask(mask: u32) -> String {
    match mask {
        h::SPIRV_RESOURCE_TYPE_ALL => "VK_SPIRV_RESOURCE_TYPE_ALL_EXT".into(),
        m => format!("{m:#x}"),
    }
}

/// One mapping of set `set`, binding `binding` (all resource types) from `source`.
fn one(
    set: u32,
    binding: u32,
    (source, source_data): (MappingSource, h::MappingSourceData),
) -> h::SetAndBindingMapping {
    h::SetAndBindingMapping {
        s_type: h::STRUCTURE_TYPE_DESCRIPTOR_SET_AND_BINDING_MAPPING_EXT,
        p_next: std::ptr::null(),
        descriptor_set: set,
        first_binding: binding,
        binding_count: 1,
        resource_mask: h::SPIRV_RESOURCE_TYPE_ALL,
        source,
        source_data,
    }
}

/// The set/binding → heap mapping every stage of a heap pipeline gets (boxed: the info points at
/// the mappings).
pub struct PipelineMapping {
    mappings: Vec<h::SetAndBindingMapping>,
    info: h::ShaderSetAndBindingMappingInfo,
}

impl PipelineMapping {
    /// The mapping of a cell reaching the heap `access`-wise, for a heap laid out as `l`. Direct
    /// cells map only the records and TLAS (the probe reads the heap itself).
    pub fn new(access: HeapAccess, l: &HeapLayout) -> Box<PipelineMapping> {
        let probe = probe_source(access, l);
        let mut mappings = vec![
            one(0, 0, (MappingSource::HeapWithConstantOffset, constant(l.records, 0))),
            one(0, 1, (MappingSource::HeapWithConstantOffset, constant(l.tlas, 0))),
        ];
        mappings.extend(probe.map(|p| one(0, 2, p)));
        PipelineMapping::boxed(mappings)
    }

    /// Every `(set, binding, heap offset, array stride)` mapped HEAP_WITH_CONSTANT_OFFSET: the
    /// set/binding descriptors of a `run --shader` heap pipeline, placed in the resource heap.
    pub fn constant_offsets(entries: &[(u32, u32, u32, u32)]) -> Box<PipelineMapping> {
        let mappings = entries
            .iter()
            .map(|&(set, binding, offset, stride)| {
                one(set, binding, (MappingSource::HeapWithConstantOffset, constant(offset, stride)))
            })
            .collect();
        PipelineMapping::boxed(mappings)
    }

    fn boxed(mappings: Vec<h::SetAndBindingMapping>) -> Box<PipelineMapping> {
        let mut b = Box::new(PipelineMapping {
            info: h::ShaderSetAndBindingMappingInfo {
                s_type: h::STRUCTURE_TYPE_SHADER_DESCRIPTOR_SET_AND_BINDING_MAPPING_INFO_EXT,
                p_next: std::ptr::null(),
                mapping_count: mappings.len() as u32,
                p_mappings: std::ptr::null(),
            },
            mappings,
        });
        b.info.p_mappings = b.mappings.as_ptr();
        b
    }

    /// Every member of every mapping struct as words (a pipeline's identity hashes them: binaries
    /// made for one mapping must never serve another). The union member read is the one its
    /// `source` names; the embedded-sampler pointers are always null and count as a 0.
    pub fn words(&self) -> Vec<u32> {
        let mut w = Vec::new();
        for m in &self.mappings {
            w.extend([m.descriptor_set, m.first_binding, m.binding_count, m.resource_mask]);
            w.push(m.source as u32);
            w.extend(source_members(m.source, &m.source_data).2.into_iter().map(|(_, v)| v.word()));
        }
        w
    }

    /// Every mapping as the issue and the report show it: read back from the structs chained to
    /// the stages, never recomputed.
    pub fn entries(&self) -> Vec<BindingMapping> {
        let entry = |m: &h::SetAndBindingMapping| {
            let (source, member, fields) = source_members(m.source, &m.source_data);
            BindingMapping {
                descriptor_set: m.descriptor_set,
                first_binding: m.first_binding,
                binding_count: m.binding_count,
                resource_mask: resource_mask(m.resource_mask),
                source: source.into(),
                source_member: member.into(),
                fields: fields.into_iter().map(|(n, v)| (n.to_string(), v.text())).collect(),
            }
        };
        self.mappings.iter().map(entry).collect()
    }

    /// What to chain to each VkPipelineShaderStageCreateInfo.
    pub fn stage_next(&self) -> *const c_void {
        &self.info as *const _ as *const c_void
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The words a pipeline's identity hashes tell every access and every layout apart: a binary
    /// made for one mapping is never filed under another's identity.
    #[test]
    fn mapping_words_differ_with_the_access_and_the_layout() {
        let l = HeapLayout::new(64, 16, 17, false);
        let accesses = [
            HeapAccess::MappedConstantOffset,
            HeapAccess::MappedPushIndex,
            HeapAccess::MappedIndirectIndex,
            HeapAccess::MappedShaderRecordIndex,
            HeapAccess::Direct,
        ];
        let words: Vec<Vec<u32>> =
            accesses.iter().map(|&a| PipelineMapping::new(a, &l).words()).collect();
        for i in 0..words.len() {
            for j in 0..i {
                assert_ne!(words[i], words[j], "{:?} and {:?}", accesses[i], accesses[j]);
            }
        }
        // The same access over another layout (another stride) differs too.
        let other = HeapLayout::new(64, 32, 17, false);
        for a in accesses.iter().filter(|a| **a != HeapAccess::Direct) {
            assert_ne!(
                PipelineMapping::new(*a, &l).words(),
                PipelineMapping::new(*a, &other).words()
            );
        }
        assert_eq!(
            PipelineMapping::new(HeapAccess::MappedPushIndex, &l).words(),
            PipelineMapping::new(HeapAccess::MappedPushIndex, &l).words()
        );
    }

    /// `run --shader`'s mappings: one constant offset per set and binding, each with its own
    /// place and stride; the twin: another place is another pipeline identity.
    #[test]
    fn constant_offsets_map_each_binding_at_its_place() {
        let m = PipelineMapping::constant_offsets(&[(0, 1, 2048, 16), (1, 0, 4096, 64)]);
        let e = m.entries();
        assert_eq!(e.len(), 2);
        assert_eq!((e[1].descriptor_set, e[1].first_binding), (1, 0));
        assert_eq!(e[1].source, "VK_DESCRIPTOR_MAPPING_SOURCE_HEAP_WITH_CONSTANT_OFFSET_EXT");
        assert_eq!(e[0].fields[0], ("heapOffset".to_string(), "2048".to_string()));
        assert_eq!(e[1].fields[1], ("heapArrayStride".to_string(), "64".to_string()));
        let moved = PipelineMapping::constant_offsets(&[(0, 1, 2048, 16), (1, 0, 4160, 64)]);
        assert_ne!(m.words(), moved.words());
    }

    /// The entries the report records are the structs the stages get: the records and TLAS at
    /// constant offsets, binding 2 by the cell's way, each member under its `vk.xml` name with
    /// the sampler members. The twin: another layout's stride shows in the entry.
    #[test]
    fn entries_are_the_chained_structs_member_by_member() {
        let l = HeapLayout::new(64, 64, 19, false);
        let e = PipelineMapping::new(HeapAccess::MappedShaderRecordIndex, &l).entries();
        let bindings: Vec<(u32, u32, u32)> =
            e.iter().map(|m| (m.descriptor_set, m.first_binding, m.binding_count)).collect();
        assert_eq!(bindings, [(0, 0, 1), (0, 1, 1), (0, 2, 1)]);
        assert_eq!(e[2].text(), "{ descriptorSet 0, firstBinding 2, bindingCount 1, resourceMask VK_SPIRV_RESOURCE_TYPE_ALL_EXT, source VK_DESCRIPTOR_MAPPING_SOURCE_HEAP_WITH_SHADER_RECORD_INDEX_EXT, sourceData.shaderRecordIndex { heapOffset 0, shaderRecordOffset 0, heapIndexStride 64, heapArrayStride 64, pEmbeddedSampler NULL, useCombinedImageSamplerIndex VK_FALSE, samplerHeapOffset 0, samplerShaderRecordOffset 0, samplerHeapIndexStride 0, samplerHeapArrayStride 0 } }");
        assert_eq!(e[1].source_member, "constantOffset");
        assert_eq!(e[1].fields[0], ("heapOffset".to_string(), l.tlas.to_string()));
        let direct = PipelineMapping::new(HeapAccess::Direct, &l).entries();
        assert_eq!(direct.len(), 2, "a direct cell maps only the records and TLAS");
        let other = HeapLayout::new(64, 32, 19, false);
        let o = PipelineMapping::new(HeapAccess::MappedShaderRecordIndex, &other).entries();
        assert!(o[2].text().contains("heapIndexStride 32, heapArrayStride 32"), "{}", o[2].text());
        assert_ne!(o[2], e[2]);
    }
}
