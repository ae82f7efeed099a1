//! Raw bindings for VK_KHR_pipeline_binary, which ash 0.38 (Vulkan headers 1.3.281) predates,
//! laid out member for member as in Vulkan 1.4.363's `vulkan_core.h` (extension number 484): the
//! feature / property structs (chained only when the driver lists the extension), the device
//! create-info struct that turns the driver's internal cache off, the key, data and create-info
//! structs, and the five device commands, loaded with `vkGetDeviceProcAddr` ([`BinaryFns`]) only
//! on devices created with the extension. [`BinaryFns`] wraps them in the three things rtprobe
//! does: read the global pipeline key, capture a pipeline's binaries as bytes, and turn stored
//! bytes back into `VkPipelineBinaryKHR` handles.
//!
//! Rules relied on (Vulkan 1.4.363, "Pipeline Binaries"): a pipeline created with
//! `VK_PIPELINE_CREATE_2_CAPTURE_DATA_BIT_KHR` or from binaries cannot use a `VkPipelineCache`
//! (VUID-vkCreateRayTracingPipelinesKHR-pNext-09616 / -09617); binaries saved under another
//! global key (`vkGetPipelineKeyKHR` with no create info) "must be assumed invalid"; the binaries
//! given at creation must be exactly those the driver returned for the same create info
//! (VUID-VkPipelineBinaryInfoKHR-binaryCount-09603).
use super::error::{VkError, VkResultExt};
use ash::vk;
use std::ffi::{c_void, CStr};

pub const NAME: &CStr = c"VK_KHR_pipeline_binary";
/// `VK_MAX_PIPELINE_BINARY_KEY_SIZE_KHR`.
pub const MAX_KEY_SIZE: usize = 32;
/// `VK_PIPELINE_CREATE_2_CAPTURE_DATA_BIT_KHR`.
pub const PIPELINE_CREATE_2_CAPTURE_DATA: vk::PipelineCreateFlags2KHR =
    vk::PipelineCreateFlags2KHR::from_raw(0x8000_0000);
/// `VK_PIPELINE_BINARY_MISSING_KHR` (a success code).
pub const PIPELINE_BINARY_MISSING: vk::Result = vk::Result::from_raw(1_000_483_000);

/// `VkPipelineBinaryKHR`: a non-dispatchable handle.
#[repr(transparent)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct PipelineBinary(pub u64);

/// A `#[repr(C)]` struct that starts with sType/pNext, and a `Default` that sets its sType and
/// zeroes the rest.
macro_rules! raw_struct {
    ($(#[$doc:meta])* $name:ident, $stype:literal; $($field:ident: $ty:ty),* $(,)?) => {
        $(#[$doc])*
        #[repr(C)]
        #[derive(Clone, Copy, Debug)]
        pub struct $name {
            pub s_type: vk::StructureType,
            pub p_next: *mut c_void,
            $(pub $field: $ty),*
        }

        impl $name {
            pub const STRUCTURE_TYPE: vk::StructureType = vk::StructureType::from_raw($stype);
        }

        impl Default for $name {
            fn default() -> Self {
                // SAFETY: plain-old-data; all-zero is a valid value for every member.
                let mut s: Self = unsafe { std::mem::zeroed() };
                s.s_type = Self::STRUCTURE_TYPE;
                s
            }
        }
    };
}

raw_struct!(
    /// `VkPhysicalDevicePipelineBinaryFeaturesKHR`.
    PhysicalDevicePipelineBinaryFeaturesKHR, 1_000_483_000;
    pipeline_binaries: vk::Bool32,
);
raw_struct!(
    /// `VkPhysicalDevicePipelineBinaryPropertiesKHR`.
    PhysicalDevicePipelineBinaryPropertiesKHR, 1_000_483_004;
    pipeline_binary_internal_cache: vk::Bool32,
    pipeline_binary_internal_cache_control: vk::Bool32,
    pipeline_binary_prefers_internal_cache: vk::Bool32,
    pipeline_binary_precompiled_internal_cache: vk::Bool32,
    pipeline_binary_compressed_data: vk::Bool32,
);
raw_struct!(
    /// `VkDevicePipelineBinaryInternalCacheControlKHR` (extends `VkDeviceCreateInfo`).
    DevicePipelineBinaryInternalCacheControlKHR, 1_000_483_008;
    disable_internal_cache: vk::Bool32,
);
raw_struct!(
    /// `VkPipelineBinaryKeyKHR`.
    PipelineBinaryKeyKHR, 1_000_483_003;
    key_size: u32,
    key: [u8; MAX_KEY_SIZE],
);
raw_struct!(
    /// `VkPipelineBinaryCreateInfoKHR`: exactly one of the three sources is set.
    PipelineBinaryCreateInfoKHR, 1_000_483_001;
    p_keys_and_data_info: *const PipelineBinaryKeysAndDataKHR,
    pipeline: vk::Pipeline,
    p_pipeline_create_info: *const c_void,
);
raw_struct!(
    /// `VkPipelineBinaryInfoKHR` (extends every `Vk*PipelineCreateInfo`).
    PipelineBinaryInfoKHR, 1_000_483_002;
    binary_count: u32,
    p_pipeline_binaries: *const PipelineBinary,
);
raw_struct!(
    /// `VkReleaseCapturedPipelineDataInfoKHR`.
    ReleaseCapturedPipelineDataInfoKHR, 1_000_483_005;
    pipeline: vk::Pipeline,
);
raw_struct!(
    /// `VkPipelineBinaryDataInfoKHR`.
    PipelineBinaryDataInfoKHR, 1_000_483_006;
    pipeline_binary: PipelineBinary,
);
raw_struct!(
    /// `VkPipelineBinaryHandlesInfoKHR`.
    PipelineBinaryHandlesInfoKHR, 1_000_483_009;
    pipeline_binary_count: u32,
    p_pipeline_binaries: *mut PipelineBinary,
);

/// `VkPipelineBinaryDataKHR` (no sType).
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct PipelineBinaryDataKHR {
    pub data_size: usize,
    pub p_data: *mut c_void,
}

/// `VkPipelineBinaryKeysAndDataKHR` (no sType).
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct PipelineBinaryKeysAndDataKHR {
    pub binary_count: u32,
    pub p_pipeline_binary_keys: *const PipelineBinaryKeyKHR,
    pub p_pipeline_binary_data: *const PipelineBinaryDataKHR,
}

// SAFETY: each begins with sType/pNext and extends exactly what the registry says it extends.
unsafe impl vk::ExtendsPhysicalDeviceFeatures2 for PhysicalDevicePipelineBinaryFeaturesKHR {}
unsafe impl vk::ExtendsDeviceCreateInfo for PhysicalDevicePipelineBinaryFeaturesKHR {}
unsafe impl vk::ExtendsPhysicalDeviceProperties2 for PhysicalDevicePipelineBinaryPropertiesKHR {}
unsafe impl vk::ExtendsDeviceCreateInfo for DevicePipelineBinaryInternalCacheControlKHR {}
unsafe impl vk::ExtendsRayTracingPipelineCreateInfoKHR for PipelineBinaryInfoKHR {}
unsafe impl vk::ExtendsGraphicsPipelineCreateInfo for PipelineBinaryInfoKHR {}
unsafe impl vk::ExtendsComputePipelineCreateInfo for PipelineBinaryInfoKHR {}

type PfnCreatePipelineBinaries = unsafe extern "system" fn(
    vk::Device,
    *const PipelineBinaryCreateInfoKHR,
    *const vk::AllocationCallbacks<'static>,
    *mut PipelineBinaryHandlesInfoKHR,
) -> vk::Result;
type PfnDestroyPipelineBinary =
    unsafe extern "system" fn(vk::Device, PipelineBinary, *const vk::AllocationCallbacks<'static>);
type PfnGetPipelineKey =
    unsafe extern "system" fn(vk::Device, *const c_void, *mut PipelineBinaryKeyKHR) -> vk::Result;
type PfnGetPipelineBinaryData = unsafe extern "system" fn(
    vk::Device,
    *const PipelineBinaryDataInfoKHR,
    *mut PipelineBinaryKeyKHR,
    *mut usize,
    *mut c_void,
) -> vk::Result;
type PfnReleaseCapturedPipelineData = unsafe extern "system" fn(
    vk::Device,
    *const ReleaseCapturedPipelineDataInfoKHR,
    *const vk::AllocationCallbacks<'static>,
) -> vk::Result;

/// One pipeline binary as bytes: the driver's key (its first `keySize` bytes) and its data.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct BinaryData {
    pub key: Vec<u8>,
    pub data: Vec<u8>,
}

/// The device commands of VK_KHR_pipeline_binary, for one device.
pub struct BinaryFns {
    device: vk::Device,
    create_pipeline_binaries: PfnCreatePipelineBinaries,
    destroy_pipeline_binary: PfnDestroyPipelineBinary,
    get_pipeline_key: PfnGetPipelineKey,
    get_pipeline_binary_data: PfnGetPipelineBinaryData,
    release_captured_pipeline_data: PfnReleaseCapturedPipelineData,
}

impl BinaryFns {
    /// Load the commands from a device created with VK_KHR_pipeline_binary; `Err` names the
    /// first command the driver did not return.
    pub fn load(instance: &ash::Instance, device: &ash::Device) -> Result<BinaryFns, &'static str> {
        let get = |name: &'static CStr| {
            unsafe { (instance.fp_v1_0().get_device_proc_addr)(device.handle(), name.as_ptr()) }
                .ok_or(name.to_str().unwrap_or("?"))
        };
        type Void = unsafe extern "system" fn();
        // SAFETY: each pointer is the driver's entry point of the named command, whose C
        // signature the matching Pfn type reproduces from vulkan_core.h.
        unsafe {
            Ok(BinaryFns {
                device: device.handle(),
                create_pipeline_binaries: std::mem::transmute::<Void, PfnCreatePipelineBinaries>(
                    get(c"vkCreatePipelineBinariesKHR")?,
                ),
                destroy_pipeline_binary: std::mem::transmute::<Void, PfnDestroyPipelineBinary>(
                    get(c"vkDestroyPipelineBinaryKHR")?,
                ),
                get_pipeline_key: std::mem::transmute::<Void, PfnGetPipelineKey>(get(
                    c"vkGetPipelineKeyKHR",
                )?),
                get_pipeline_binary_data: std::mem::transmute::<Void, PfnGetPipelineBinaryData>(
                    get(c"vkGetPipelineBinaryDataKHR")?,
                ),
                release_captured_pipeline_data: std::mem::transmute::<
                    Void,
                    PfnReleaseCapturedPipelineData,
                >(get(
                    c"vkReleaseCapturedPipelineDataKHR",
                )?),
            })
        }
    }

    /// The global pipeline key (`vkGetPipelineKeyKHR` with no create info): binaries saved under
    /// another one are invalid.
    pub fn global_key(&self) -> Result<Vec<u8>, VkError> {
        let mut key = PipelineBinaryKeyKHR::default();
        unsafe { (self.get_pipeline_key)(self.device, std::ptr::null(), &mut key) }
            .result()
            .at("vkGetPipelineKeyKHR")?;
        Ok(key_bytes(&key).to_vec())
    }

    /// The binaries of `pipeline` (created with the capture flag) as bytes; its captured data is
    /// released after, whatever happens.
    pub fn capture(&self, pipeline: vk::Pipeline) -> Result<Vec<BinaryData>, VkError> {
        let info = PipelineBinaryCreateInfoKHR { pipeline, ..Default::default() };
        let handles = self.create(&info);
        let release = ReleaseCapturedPipelineDataInfoKHR { pipeline, ..Default::default() };
        let released = unsafe {
            (self.release_captured_pipeline_data)(self.device, &release, std::ptr::null())
        }
        .result()
        .at("vkReleaseCapturedPipelineDataKHR");
        let handles = handles?;
        let data = handles.iter().map(|&b| self.data(b)).collect::<Result<Vec<_>, _>>();
        self.destroy(&handles);
        released?;
        data
    }

    /// Handles made from stored `binaries`, in their order (destroy them with [`Self::destroy`]
    /// once the pipeline is created).
    pub fn load_binaries(&self, binaries: &[BinaryData]) -> Result<Vec<PipelineBinary>, VkError> {
        let keys: Vec<PipelineBinaryKeyKHR> = binaries
            .iter()
            .map(|b| {
                let mut k = PipelineBinaryKeyKHR {
                    key_size: b.key.len().min(MAX_KEY_SIZE) as u32,
                    ..Default::default()
                };
                k.key[..b.key.len().min(MAX_KEY_SIZE)]
                    .copy_from_slice(&b.key[..b.key.len().min(MAX_KEY_SIZE)]);
                k
            })
            .collect();
        let data: Vec<PipelineBinaryDataKHR> = binaries
            .iter()
            .map(|b| PipelineBinaryDataKHR {
                data_size: b.data.len(),
                p_data: b.data.as_ptr() as *mut c_void,
            })
            .collect();
        let kd = PipelineBinaryKeysAndDataKHR {
            binary_count: binaries.len() as u32,
            p_pipeline_binary_keys: keys.as_ptr(),
            p_pipeline_binary_data: data.as_ptr(),
        };
        self.create(&PipelineBinaryCreateInfoKHR {
            p_keys_and_data_info: &kd,
            ..Default::default()
        })
    }

    pub fn destroy(&self, binaries: &[PipelineBinary]) {
        for &b in binaries.iter().filter(|b| b.0 != 0) {
            unsafe { (self.destroy_pipeline_binary)(self.device, b, std::ptr::null()) };
        }
    }

    /// `vkCreatePipelineBinariesKHR`: the count first, then the handles. On an error the handles
    /// that were made are destroyed.
    fn create(&self, info: &PipelineBinaryCreateInfoKHR) -> Result<Vec<PipelineBinary>, VkError> {
        const CALL: &str = "vkCreatePipelineBinariesKHR";
        let mut h = PipelineBinaryHandlesInfoKHR::default();
        unsafe { (self.create_pipeline_binaries)(self.device, info, std::ptr::null(), &mut h) }
            .result()
            .at(CALL)?;
        let mut out = vec![PipelineBinary::default(); h.pipeline_binary_count as usize];
        h.p_pipeline_binaries = out.as_mut_ptr();
        let r =
            unsafe { (self.create_pipeline_binaries)(self.device, info, std::ptr::null(), &mut h) };
        out.truncate(h.pipeline_binary_count as usize);
        if r != vk::Result::SUCCESS {
            self.destroy(&out);
            let r = if r == vk::Result::INCOMPLETE { vk::Result::ERROR_UNKNOWN } else { r };
            return Err(VkError::from_result(CALL, r));
        }
        Ok(out)
    }

    /// One binary's key and data (`vkGetPipelineBinaryDataKHR`: the size first, then the data).
    fn data(&self, binary: PipelineBinary) -> Result<BinaryData, VkError> {
        const CALL: &str = "vkGetPipelineBinaryDataKHR";
        let info = PipelineBinaryDataInfoKHR { pipeline_binary: binary, ..Default::default() };
        let mut key = PipelineBinaryKeyKHR::default();
        let mut size = 0usize;
        unsafe {
            (self.get_pipeline_binary_data)(
                self.device,
                &info,
                &mut key,
                &mut size,
                std::ptr::null_mut(),
            )
        }
        .result()
        .at(CALL)?;
        let mut data = vec![0u8; size];
        unsafe {
            (self.get_pipeline_binary_data)(
                self.device,
                &info,
                &mut key,
                &mut size,
                data.as_mut_ptr() as *mut c_void,
            )
        }
        .result()
        .at(CALL)?;
        data.truncate(size);
        Ok(BinaryData { key: key_bytes(&key).to_vec(), data })
    }
}

/// The valid bytes of a key (its first `keySize`, at most [`MAX_KEY_SIZE`]).
fn key_bytes(k: &PipelineBinaryKeyKHR) -> &[u8] {
    &k.key[..(k.key_size as usize).min(MAX_KEY_SIZE)]
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::mem::{offset_of, size_of};

    /// Sizes and offsets a C compiler gives vulkan_core.h 1.4.363's definitions on 64-bit targets.
    #[test]
    fn layouts_match_the_c_header() {
        assert_eq!(size_of::<PhysicalDevicePipelineBinaryFeaturesKHR>(), 24);
        assert_eq!(size_of::<PhysicalDevicePipelineBinaryPropertiesKHR>(), 40);
        assert_eq!(
            offset_of!(PhysicalDevicePipelineBinaryPropertiesKHR, pipeline_binary_compressed_data),
            32
        );
        assert_eq!(size_of::<PipelineBinaryKeyKHR>(), 56);
        assert_eq!(offset_of!(PipelineBinaryKeyKHR, key), 20);
        assert_eq!(size_of::<PipelineBinaryDataKHR>(), 16);
        assert_eq!(size_of::<PipelineBinaryKeysAndDataKHR>(), 24);
        assert_eq!(offset_of!(PipelineBinaryKeysAndDataKHR, p_pipeline_binary_keys), 8);
        assert_eq!(size_of::<PipelineBinaryCreateInfoKHR>(), 40);
        assert_eq!(offset_of!(PipelineBinaryCreateInfoKHR, p_pipeline_create_info), 32);
        assert_eq!(size_of::<PipelineBinaryInfoKHR>(), 32);
        assert_eq!(offset_of!(PipelineBinaryInfoKHR, p_pipeline_binaries), 24);
        assert_eq!(size_of::<PipelineBinaryHandlesInfoKHR>(), 32);
        assert_eq!(size_of::<PipelineBinaryDataInfoKHR>(), 24);
        assert_eq!(size_of::<ReleaseCapturedPipelineDataInfoKHR>(), 24);
        assert_eq!(size_of::<DevicePipelineBinaryInternalCacheControlKHR>(), 24);
        assert_eq!(size_of::<PipelineBinary>(), 8);
    }

    #[test]
    fn defaults_carry_their_structure_type_and_the_key_is_cut_to_its_size() {
        assert_eq!(PipelineBinaryKeyKHR::default().s_type.as_raw(), 1_000_483_003);
        assert_eq!(PipelineBinaryHandlesInfoKHR::default().s_type.as_raw(), 1_000_483_009);
        assert_eq!(
            DevicePipelineBinaryInternalCacheControlKHR::default().s_type.as_raw(),
            1_000_483_008
        );
        let mut k = PipelineBinaryKeyKHR { key_size: 3, ..Default::default() };
        k.key[..4].copy_from_slice(&[1, 2, 3, 4]);
        assert_eq!(key_bytes(&k), &[1, 2, 3]);
        // A driver's size past the array never reads beyond it.
        k.key_size = 99;
        assert_eq!(key_bytes(&k).len(), MAX_KEY_SIZE);
    }
}
