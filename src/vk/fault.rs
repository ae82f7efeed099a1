//! VK_EXT_device_fault: after a device loss, ask the driver what faulted (description, faulting
//! addresses, vendor codes) so the report can carry it.
use super::Gpu;
use crate::model::{FaultAddress, FaultInfo, FaultVendorInfo};
use ash::vk;

fn cstr(bytes: &[std::ffi::c_char]) -> String {
    let b: Vec<u8> = bytes.iter().take_while(|c| **c != 0).map(|c| *c as u8).collect();
    String::from_utf8_lossy(&b).into_owned()
}

/// The driver's fault report, or `None` where VK_EXT_device_fault is not enabled, or the query
/// itself fails (then the reason is returned as the description).
// The raw pointers into the vectors are set one by one after the struct is made.
#[allow(clippy::field_reassign_with_default)]
pub fn query(gpu: &Gpu) -> Option<FaultInfo> {
    let ext = gpu.fault.as_ref()?;
    let f = ext.fp().get_device_fault_info_ext;
    let mut counts = vk::DeviceFaultCountsEXT::default();
    let r = unsafe { f(gpu.device.handle(), &mut counts, std::ptr::null_mut()) };
    if r != vk::Result::SUCCESS && r != vk::Result::INCOMPLETE {
        return Some(FaultInfo {
            description: format!("vkGetDeviceFaultInfoEXT (counts) returned {r}"),
            ..Default::default()
        });
    }
    let mut addrs =
        vec![vk::DeviceFaultAddressInfoEXT::default(); counts.address_info_count as usize];
    let mut vendor =
        vec![vk::DeviceFaultVendorInfoEXT::default(); counts.vendor_info_count as usize];
    let mut info = vk::DeviceFaultInfoEXT::default();
    info.p_address_infos = if addrs.is_empty() { std::ptr::null_mut() } else { addrs.as_mut_ptr() };
    info.p_vendor_infos =
        if vendor.is_empty() { std::ptr::null_mut() } else { vendor.as_mut_ptr() };
    info.p_vendor_binary_data = std::ptr::null_mut();
    let vendor_binary_bytes = counts.vendor_binary_size;
    counts.vendor_binary_size = 0;
    let r = unsafe { f(gpu.device.handle(), &mut counts, &mut info) };
    if r != vk::Result::SUCCESS && r != vk::Result::INCOMPLETE {
        return Some(FaultInfo {
            description: format!("vkGetDeviceFaultInfoEXT returned {r}"),
            ..Default::default()
        });
    }
    Some(FaultInfo {
        description: cstr(&info.description),
        addresses: addrs
            .iter()
            .take(counts.address_info_count as usize)
            .map(|a| FaultAddress {
                kind: format!("{:?}", a.address_type),
                address: format!("{:#x}", a.reported_address),
                precision: a.address_precision,
            })
            .collect(),
        vendor: vendor
            .iter()
            .take(counts.vendor_info_count as usize)
            .map(|v| FaultVendorInfo {
                description: cstr(&v.description),
                code: v.vendor_fault_code,
                data: v.vendor_fault_data,
            })
            .collect(),
        vendor_binary_bytes,
    })
}
