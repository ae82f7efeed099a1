//! The set/binding → heap mapping chained to every shader stage of a heap pipeline
//! (VkShaderDescriptorSetAndBindingMappingInfoEXT): records and scene TLAS at constant offsets,
//! the probed array (binding 2) as the cell's `heap_access` says.
use super::layout::HeapLayout;
use super::push::{PUSH_INDEX_ADDRESS_OFFSET, PUSH_INDEX_OFFSET};
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

/// The members of `data` that `source` says it holds, in declaration order (see
/// [`PipelineMapping::words`]).
fn source_words(source: MappingSource, data: &h::MappingSourceData) -> Vec<u32> {
    let null = |p: *const vk::SamplerCreateInfo<'static>| u32::from(!p.is_null());
    // SAFETY: each arm reads the union member that `source` names, the one `probe_source` and
    // `constant` write for it.
    unsafe {
        match source {
            MappingSource::HeapWithConstantOffset => {
                let c = data.constant_offset;
                vec![c.heap_offset, c.heap_array_stride, null(c.p_embedded_sampler)]
                    .into_iter()
                    .chain([c.sampler_heap_offset, c.sampler_heap_array_stride])
                    .collect()
            }
            MappingSource::HeapWithPushIndex => {
                let p = data.push_index;
                vec![
                    p.heap_offset,
                    p.push_offset,
                    p.heap_index_stride,
                    p.heap_array_stride,
                    null(p.p_embedded_sampler),
                    p.use_combined_image_sampler_index,
                    p.sampler_heap_offset,
                    p.sampler_push_offset,
                    p.sampler_heap_index_stride,
                    p.sampler_heap_array_stride,
                ]
            }
            MappingSource::HeapWithIndirectIndex => {
                let i = data.indirect_index;
                vec![
                    i.heap_offset,
                    i.push_offset,
                    i.address_offset,
                    i.heap_index_stride,
                    i.heap_array_stride,
                    null(i.p_embedded_sampler),
                    i.use_combined_image_sampler_index,
                    i.sampler_heap_offset,
                    i.sampler_push_offset,
                    i.sampler_address_offset,
                    i.sampler_heap_index_stride,
                    i.sampler_heap_array_stride,
                ]
            }
            MappingSource::HeapWithShaderRecordIndex => {
                let r = data.shader_record_index;
                vec![
                    r.heap_offset,
                    r.shader_record_offset,
                    r.heap_index_stride,
                    r.heap_array_stride,
                    null(r.p_embedded_sampler),
                    r.use_combined_image_sampler_index,
                    r.sampler_heap_offset,
                    r.sampler_shader_record_offset,
                    r.sampler_heap_index_stride,
                    r.sampler_heap_array_stride,
                ]
            }
        }
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
        let mapping =
            |binding: u32, (source, source_data): (MappingSource, h::MappingSourceData)| {
                h::SetAndBindingMapping {
                    s_type: h::STRUCTURE_TYPE_DESCRIPTOR_SET_AND_BINDING_MAPPING_EXT,
                    p_next: std::ptr::null(),
                    descriptor_set: 0,
                    first_binding: binding,
                    binding_count: 1,
                    resource_mask: h::SPIRV_RESOURCE_TYPE_ALL,
                    source,
                    source_data,
                }
            };
        let mut mappings = vec![
            mapping(0, (MappingSource::HeapWithConstantOffset, constant(l.records, 0))),
            mapping(1, (MappingSource::HeapWithConstantOffset, constant(l.tlas, 0))),
        ];
        mappings.extend(probe.map(|p| mapping(2, p)));
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
            w.extend(source_words(m.source, &m.source_data));
        }
        w
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
}
