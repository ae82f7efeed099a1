//! Push data of a heap cell (vkCmdPushDataEXT): the probes' push block at offset 0, the probed
//! array's heap index at [`PUSH_INDEX_OFFSET`] and, at [`PUSH_INDEX_ADDRESS_OFFSET`], the address
//! of a buffer holding the same index.
use super::sizes::fns;
use crate::probe::PUSH_CONSTANT_BYTES;
use crate::vk::heap as h;
use crate::vk::Gpu;
use ash::vk;
use std::ffi::c_void;

/// Push-data offset of the probed array's heap index (right after the probes' push block).
pub const PUSH_INDEX_OFFSET: u32 = PUSH_CONSTANT_BYTES;
/// Push-data offset of the address of the buffer holding that index (`mapped_indirect_index`).
pub const PUSH_INDEX_ADDRESS_OFFSET: u32 = PUSH_CONSTANT_BYTES + 8;

/// The push data: `pc` (the probes' push block), then `heap_index` and `index_address` at their
/// offsets.
pub(super) fn bytes(pc: &[u8], heap_index: u32, index_address: u64) -> Vec<u8> {
    let mut data = pc.to_vec();
    data.resize(PUSH_INDEX_OFFSET as usize, 0);
    data.extend_from_slice(&heap_index.to_le_bytes());
    data.resize(PUSH_INDEX_ADDRESS_OFFSET as usize, 0);
    data.extend_from_slice(&index_address.to_le_bytes());
    data
}

/// Record vkCmdPushDataEXT of `data` at offset 0 into `cmd`.
pub(super) fn push(gpu: &Gpu, cmd: vk::CommandBuffer, data: &[u8]) {
    let info = h::PushDataInfo {
        s_type: h::STRUCTURE_TYPE_PUSH_DATA_INFO_EXT,
        p_next: std::ptr::null(),
        offset: 0,
        data: h::HostAddressRangeConst {
            address: data.as_ptr() as *const c_void,
            size: data.len(),
        },
    };
    // SAFETY: `data` outlives the call, which copies it into the command buffer.
    unsafe { (fns(gpu).cmd_push_data)(cmd, &info) };
}
