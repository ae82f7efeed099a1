//! The `VkPipelineCache` persisted between runs, one file per device and driver: its name is made
//! of vendorID, deviceID, driverVersion and pipelineCacheUUID, so another driver never reads it.
//! Stored bytes reach the driver only after their `VkPipelineCacheHeaderVersionOne` (Vulkan spec,
//! "Pipeline Cache": headerSize ≥ 32, headerVersion 1, vendorID, deviceID, the 16-byte
//! pipelineCacheUUID, little-endian on every supported host) matches this device; a short,
//! mismatching or unreadable file is ignored with a warning and replaced at the next save.
//!
//! Saving (at a worker's end): the file on disk (written meanwhile by another worker) is merged
//! into this worker's cache with `vkMergePipelineCaches`, then the whole is written atomically
//! (a temporary file per process, then rename). Two workers saving at the same instant: the last
//! rename wins, and the next run merges again.
use crate::vk::{Gpu, VkError, VkResultExt};
use ash::vk;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// Why a stored cache is not used, or this worker's is not saved.
#[derive(Debug, thiserror::Error)]
pub enum CacheError {
    /// The file exists but cannot be read.
    #[error("{0}")]
    Unreadable(std::io::Error),
    /// The stored header is not this device's ([`header_mismatch`]'s reason).
    #[error("{0}")]
    Header(String),
    #[error("vkGetPipelineCacheData: {0}")]
    GetData(vk::Result),
    /// The driver's own data fails the header check (the reason).
    #[error("the driver's vkGetPipelineCacheData output is not a valid cache ({0}); not saved")]
    DriverData(String),
    #[error(transparent)]
    Write(#[from] crate::atomic::WriteError),
}

/// `sizeof(VkPipelineCacheHeaderVersionOne)`.
const HEADER_LEN: usize = 32;

/// The cache folder: `$RTPROBE_CACHE_DIR`, else `$XDG_CACHE_HOME/rtprobe`, else
/// `~/.cache/rtprobe`; `None` when none of them is set.
pub fn default_dir() -> Option<PathBuf> {
    let var = |k: &str| std::env::var_os(k).filter(|v| !v.is_empty()).map(PathBuf::from);
    var("RTPROBE_CACHE_DIR")
        .or_else(|| var("XDG_CACHE_HOME").map(|d| d.join("rtprobe")))
        .or_else(|| var("HOME").map(|h| h.join(".cache").join("rtprobe")))
}

/// The cache file of a device and driver (`p`: its properties).
pub fn file_name(p: &vk::PhysicalDeviceProperties) -> String {
    let uuid: String = p.pipeline_cache_uuid.iter().map(|b| format!("{b:02x}")).collect();
    format!(
        "pipeline-cache-{:04x}-{:04x}-{:08x}-{uuid}.bin",
        p.vendor_id, p.device_id, p.driver_version
    )
}

/// Why `bytes` cannot be this device's pipeline cache data (`None`: the header matches).
pub fn header_mismatch(bytes: &[u8], props: &vk::PhysicalDeviceProperties) -> Option<String> {
    if bytes.len() < HEADER_LEN {
        return Some(format!("{} bytes, shorter than the {HEADER_LEN}-byte header", bytes.len()));
    }
    let u32_at = |o: usize| u32::from_le_bytes(bytes[o..o + 4].try_into().expect("4 bytes"));
    let (size, version, vendor, device) = (u32_at(0), u32_at(4), u32_at(8), u32_at(12));
    if (size as usize) < HEADER_LEN || size as usize > bytes.len() {
        return Some(format!("header size {size} (file {} bytes)", bytes.len()));
    }
    if version != vk::PipelineCacheHeaderVersion::ONE.as_raw() as u32 {
        return Some(format!("header version {version}, not 1"));
    }
    if (vendor, device) != (props.vendor_id, props.device_id) {
        return Some(format!(
            "vendor/device {vendor:#x}/{device:#x}, this device is {:#x}/{:#x}",
            props.vendor_id, props.device_id
        ));
    }
    if bytes[16..32] != props.pipeline_cache_uuid {
        return Some("pipelineCacheUUID differs from this driver's".into());
    }
    None
}

/// What a worker's pipeline cache started from (recorded in the report).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Loaded {
    pub path: PathBuf,
    /// Bytes handed to the driver (0: none, or the file was ignored).
    pub loaded_bytes: u64,
    /// Why an existing file was ignored.
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub ignored: Option<String>,
}

/// The stored bytes for this device if they are usable; `Err`: why they were ignored.
fn read_valid(
    path: &Path,
    props: &vk::PhysicalDeviceProperties,
) -> Result<Option<Vec<u8>>, CacheError> {
    match std::fs::read(path) {
        Ok(b) => match header_mismatch(&b, props) {
            None => Ok(Some(b)),
            Some(why) => Err(CacheError::Header(why)),
        },
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(None),
        Err(e) => Err(CacheError::Unreadable(e)),
    }
}

fn create(gpu: &Gpu, data: &[u8]) -> Result<vk::PipelineCache, VkError> {
    unsafe {
        gpu.device
            .create_pipeline_cache(&vk::PipelineCacheCreateInfo::default().initial_data(data), None)
    }
    .at("vkCreatePipelineCache")
}

/// This worker's pipeline cache: from the device's file under `dir` when it is valid, else empty.
/// Never shared with an externally-synchronized flag: the prebuild threads use it at once.
pub fn open(gpu: &Gpu, dir: Option<&Path>) -> Result<(vk::PipelineCache, Option<Loaded>), VkError> {
    let Some(dir) = dir else {
        return Ok((create(gpu, &[])?, None));
    };
    let path = dir.join(file_name(&gpu.info.properties.core));
    let mut status = Loaded { path: path.clone(), ..Default::default() };
    let data = match read_valid(&path, &gpu.info.properties.core) {
        Ok(d) => d.unwrap_or_default(),
        Err(why) => {
            tracing::warn!("pipeline cache {} ignored: {why}", path.display());
            status.ignored = Some(why.to_string());
            vec![]
        }
    };
    let cache = match create(gpu, &data) {
        Ok(c) => {
            status.loaded_bytes = data.len() as u64;
            c
        }
        Err(e) if !data.is_empty() => {
            tracing::warn!(
                "pipeline cache {} refused by the driver ({e}); starting empty",
                path.display()
            );
            status.ignored = Some(format!("refused by the driver: {e}"));
            create(gpu, &[])?
        }
        Err(e) => return Err(e),
    };
    Ok((cache, Some(status)))
}

/// Merge what another worker saved meanwhile into `cache`, then write it to `path` atomically;
/// the bytes written. Data that fails the header check itself is not written.
pub fn save(gpu: &Gpu, cache: vk::PipelineCache, path: &Path) -> Result<u64, CacheError> {
    if let Ok(Some(theirs)) = read_valid(path, &gpu.info.properties.core) {
        if let Ok(src) = create(gpu, &theirs) {
            if let Err(e) = unsafe { gpu.device.merge_pipeline_caches(cache, &[src]) } {
                tracing::warn!("vkMergePipelineCaches: {e}; saving this worker's cache alone");
            }
            unsafe { gpu.device.destroy_pipeline_cache(src, None) };
        }
    }
    let data = unsafe { gpu.device.get_pipeline_cache_data(cache) }.map_err(CacheError::GetData)?;
    // A driver whose own data fails the check (lavapipe of Mesa 26.2.6 returns 20 bytes of a
    // 32-byte header) would only make every later run warn: not written.
    if let Some(why) = header_mismatch(&data, &gpu.info.properties.core) {
        return Err(CacheError::DriverData(why));
    }
    crate::atomic::write_atomic(path, &data)?;
    Ok(data.len() as u64)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn props() -> vk::PhysicalDeviceProperties {
        vk::PhysicalDeviceProperties {
            vendor_id: 0x10de,
            device_id: 0x2330,
            pipeline_cache_uuid: [7; 16],
            ..Default::default()
        }
    }

    fn header(size: u32, version: u32, vendor: u32, device: u32, uuid: [u8; 16]) -> Vec<u8> {
        let mut b: Vec<u8> =
            [size, version, vendor, device].iter().flat_map(|v| v.to_le_bytes()).collect();
        b.extend_from_slice(&uuid);
        b.extend_from_slice(b"driver payload");
        b
    }

    #[test]
    fn only_this_devices_header_is_accepted() {
        let p = props();
        assert_eq!(header_mismatch(&header(32, 1, 0x10de, 0x2330, [7; 16]), &p), None);
        assert!(header_mismatch(&header(32, 1, 0x10de, 0x2330, [8; 16]), &p)
            .unwrap()
            .contains("UUID"));
        assert!(header_mismatch(&header(32, 1, 0x1002, 0x2330, [7; 16]), &p)
            .unwrap()
            .contains("vendor"));
        assert!(header_mismatch(&header(32, 1, 0x10de, 0x2331, [7; 16]), &p)
            .unwrap()
            .contains("vendor/device"));
        assert!(header_mismatch(&header(32, 2, 0x10de, 0x2330, [7; 16]), &p)
            .unwrap()
            .contains("version"));
        assert!(header_mismatch(&header(16, 1, 0x10de, 0x2330, [7; 16]), &p)
            .unwrap()
            .contains("header size"));
        assert!(header_mismatch(&header(4096, 1, 0x10de, 0x2330, [7; 16]), &p)
            .unwrap()
            .contains("header size"));
        // Truncated inside the header, and empty.
        assert!(header_mismatch(&header(32, 1, 0x10de, 0x2330, [7; 16])[..20], &p)
            .unwrap()
            .contains("shorter"));
        assert!(header_mismatch(&[], &p).is_some());
    }

    #[test]
    fn the_file_name_names_device_driver_and_uuid() {
        let p = vk::PhysicalDeviceProperties { driver_version: 0x1234_5678, ..props() };
        assert_eq!(
            file_name(&p),
            format!("pipeline-cache-10de-2330-12345678-{}.bin", "07".repeat(16))
        );
    }
}
