//! The `descriptor_heap` binding path (VK_EXT_descriptor_heap). The cell's set/binding shaders
//! reach a resource heap and a sampler heap through VkShaderDescriptorSetAndBindingMappingInfoEXT
//! chained to every shader stage ("mapped"); `direct` cells read the probed array straight from
//! the heap (`layout(descriptor_heap)`), with only the records and scene TLAS mapped.
//!
//! The resource heap is a buffer with the descriptor-heap usage ([`HeapLayout`]): the records SSBO
//! (binding 0) and the scene TLAS (binding 1) in `slot`-byte slots (the largest buffer / image
//! descriptor, aligned), and the probed array (binding 2) with the stride of its own descriptor
//! type — the stride `layout(descriptor_heap)` arrays index with (OpConstantSizeOfEXT) — then the
//! driver's reserved range. Mapped cells: records at 0, TLAS at `slot`, the array at
//! an index of its stride past them. Direct cells: the array at 0 (so the shader's own index is the
//! heap index, as in the original engine's `heap[base + gl_InstanceCustomIndexEXT]`), records and
//! TLAS after it. The sampler heap holds the probes' samplers (`probe::SAMPLER_MODES`; sampler 0
//! at offset 0 is the one mapped combined image samplers use, direct probes index them with the
//! sampler class's descriptor size as stride), then its reserved range.
//! Descriptors are written with vkWriteResourceDescriptorsEXT / vkWriteSamplerDescriptorsEXT, both
//! heaps bound with vkCmdBind{Resource,Sampler}HeapEXT, and push constants are push data
//! (vkCmdPushDataEXT): the probes' block (`probe::PushConstants`) at offset 0, the probed array's heap index at
//! [`PUSH_INDEX_OFFSET`], and at [`PUSH_INDEX_ADDRESS_OFFSET`] the address of a buffer holding the
//! same index.
//!
//! Bindings 0 and 1 are always HEAP_WITH_CONSTANT_OFFSET. Binding 2 follows the cell's
//! `heap_access`: a constant offset, HEAP_WITH_PUSH_INDEX (the index read from push data),
//! HEAP_WITH_INDIRECT_INDEX (read from the buffer whose address is in push data) or
//! HEAP_WITH_SHADER_RECORD_INDEX (read from the first 4 bytes of every SBT record's shader record
//! data). All ways must read the same descriptors.
//!
//! Files: the heap layout (`layout`), the device's descriptor sizes and heap commands (`sizes`),
//! writing descriptors into heap bytes (`write`), the two heaps created, bound and pushed to
//! (`binding`; `PlacedHeaps`: descriptors at given places, for `run --shader`), push data
//! (`push`), and the set/binding mapping of heap pipelines (`mapping`; constant offsets per
//! set and binding for `run --shader`).
mod binding;
mod layout;
mod mapping;
mod push;
mod sizes;
mod write;

pub use binding::{descriptor_stride, HeapBinding, PlacedHeaps};
pub use layout::HeapLayout;
pub use mapping::{describe as describe_mapping, PipelineMapping};
pub use push::{PUSH_INDEX_ADDRESS_OFFSET, PUSH_INDEX_OFFSET};
pub use write::Placed;
