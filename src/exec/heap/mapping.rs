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

    /// What to chain to each VkPipelineShaderStageCreateInfo.
    pub fn stage_next(&self) -> *const c_void {
        &self.info as *const _ as *const c_void
    }
}
