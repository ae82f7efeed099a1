//! Pipeline binaries (VK_KHR_pipeline_binary) kept between runs, one file per pipeline, under
//! `<pipeline cache folder>/pipeline-binaries-<vendor>-<device>-<driverVersion>-<UUID>/<global
//! key>/<pipeline identity>.bin`. The global key folder is the spec's rule: binaries saved under
//! another global pipeline key "must be assumed invalid" (Vulkan 1.4.363, "Generating the Pipeline
//! Key"), so another key never finds them. The file name is rtprobe's own identity of everything
//! that makes the pipeline ([`super::pipeline_id`]), the heap mapping structs included.
//!
//! How a pipeline is made with a store ([`BinaryStore::make`]): its file read, checked (magic,
//! version, lengths, checksum) and handed to `vkCreatePipelineBinariesKHR`, the pipeline created
//! from the binaries (no pipeline cache, no shader modules); when there is no file, or it fails a
//! check or the driver refuses it, the pipeline is compiled with
//! `VK_PIPELINE_CREATE_2_CAPTURE_DATA_BIT_KHR` (no `VkPipelineCache` may be given then, so a cold
//! run compiles with the driver's own cache only) and its binaries are read back, written
//! atomically (temporary file + rename, no fsync: a torn file fails the checksum; workers racing
//! on one pipeline write the same bytes) and
//! the captured data released. A capture or save that fails leaves the pipeline usable.
use super::pipeline::{self, Desc, Pipeline, Source};
use crate::model::{BinaryStats, BinaryStatus};
use crate::vk::binary::{BinaryData, BinaryFns};
use crate::vk::{Gpu, VkError};
use std::path::{Path, PathBuf};
use std::sync::Mutex;

/// Why stored bytes are not a binary file of this format.
#[derive(Debug, PartialEq, Eq, thiserror::Error)]
pub enum FormatError {
    #[error("not a pipeline binary file (bad magic)")]
    Magic,
    #[error("pipeline binary file version {0}, this rtprobe writes {VERSION}")]
    Version(u32),
    #[error("pipeline binary file truncated")]
    Truncated,
    #[error("pipeline binary file checksum mismatch (corrupt)")]
    Checksum,
    #[error("pipeline binary key of {0} bytes (at most {max})", max = crate::vk::binary::MAX_KEY_SIZE)]
    KeySize(usize),
    #[error("pipeline binary file holds no binary")]
    Empty,
}

const MAGIC: &[u8; 4] = b"RTPB";
const VERSION: u32 = 1;

/// The file's bytes: magic, version, count, then per binary its key (length-prefixed) and data
/// (length-prefixed), then a 128-bit FNV-1a checksum of everything before it.
pub fn encode(binaries: &[BinaryData]) -> Vec<u8> {
    let mut b = MAGIC.to_vec();
    b.extend(VERSION.to_le_bytes());
    b.extend((binaries.len() as u32).to_le_bytes());
    for x in binaries {
        b.extend((x.key.len() as u32).to_le_bytes());
        b.extend(&x.key);
        b.extend((x.data.len() as u64).to_le_bytes());
        b.extend(&x.data);
    }
    let sum = checksum(&b);
    b.extend(sum.to_le_bytes());
    b
}

fn checksum(b: &[u8]) -> u128 {
    let mut h = super::pipeline_id::StableHash::default();
    h.bytes(b);
    h.finish()
}

/// A reader over the file's bytes that fails with [`FormatError::Truncated`] past the end.
struct Reader<'a>(&'a [u8]);

impl<'a> Reader<'a> {
    fn take(&mut self, n: usize) -> Result<&'a [u8], FormatError> {
        if n > self.0.len() {
            return Err(FormatError::Truncated);
        }
        let (head, rest) = self.0.split_at(n);
        self.0 = rest;
        Ok(head)
    }

    fn u32(&mut self) -> Result<u32, FormatError> {
        Ok(u32::from_le_bytes(self.take(4)?.try_into().expect("4 bytes")))
    }

    fn u64(&mut self) -> Result<u64, FormatError> {
        Ok(u64::from_le_bytes(self.take(8)?.try_into().expect("8 bytes")))
    }
}

/// The binaries a file holds, or why it is no valid file (nothing of it reaches the driver then).
pub fn decode(bytes: &[u8]) -> Result<Vec<BinaryData>, FormatError> {
    if bytes.len() < 12 + 16 {
        return Err(if bytes.starts_with(MAGIC) || bytes.len() < 4 {
            FormatError::Truncated
        } else {
            FormatError::Magic
        });
    }
    let (body, sum) = bytes.split_at(bytes.len() - 16);
    let mut r = Reader(body);
    if r.take(4)? != MAGIC {
        return Err(FormatError::Magic);
    }
    let version = r.u32()?;
    if version != VERSION {
        return Err(FormatError::Version(version));
    }
    if checksum(body) != u128::from_le_bytes(sum.try_into().expect("16 bytes")) {
        return Err(FormatError::Checksum);
    }
    let n = r.u32()? as usize;
    let mut out = Vec::with_capacity(n.min(64));
    for _ in 0..n {
        let k = r.u32()? as usize;
        if k == 0 || k > crate::vk::binary::MAX_KEY_SIZE {
            return Err(FormatError::KeySize(k));
        }
        let key = r.take(k)?.to_vec();
        let len = usize::try_from(r.u64()?).map_err(|_| FormatError::Truncated)?;
        out.push(BinaryData { key, data: r.take(len)?.to_vec() });
    }
    if out.is_empty() {
        return Err(FormatError::Empty);
    }
    if !r.0.is_empty() {
        return Err(FormatError::Truncated);
    }
    Ok(out)
}

/// The folder of a device's and driver's binaries (`p`: its properties) under `root`.
pub fn device_dir(root: &Path, p: &ash::vk::PhysicalDeviceProperties) -> PathBuf {
    let uuid: String = p.pipeline_cache_uuid.iter().map(|b| format!("{b:02x}")).collect();
    root.join(format!(
        "pipeline-binaries-{:04x}-{:04x}-{:08x}-{uuid}",
        p.vendor_id, p.device_id, p.driver_version
    ))
}

fn hex(b: &[u8]) -> String {
    b.iter().map(|x| format!("{x:02x}")).collect()
}

/// One worker's binaries: the folder of its device, driver and global key, and what it did.
pub struct BinaryStore {
    dir: PathBuf,
    stats: Mutex<BinaryStats>,
}

impl BinaryStore {
    /// The store of `gpu` (created with pipeline binaries) under `root`, and its status for the
    /// report.
    pub fn open(gpu: &Gpu, root: &Path) -> Result<(BinaryStore, BinaryStatus), VkError> {
        let fns = gpu.binary.as_ref().expect("pipeline binaries enabled");
        let key = hex(&fns.global_key()?);
        let dir = device_dir(root, &gpu.info.properties.core).join(&key);
        let status = BinaryStatus {
            dir: Some(dir.clone()),
            global_key: key,
            properties: properties(gpu),
            ..Default::default()
        };
        Ok((BinaryStore { dir, stats: Mutex::new(BinaryStats::default()) }, status))
    }

    fn path(&self, id: u128) -> PathBuf {
        self.dir.join(format!("{id:032x}.bin"))
    }

    fn stats(&self) -> std::sync::MutexGuard<'_, BinaryStats> {
        self.stats.lock().unwrap_or_else(|p| p.into_inner())
    }

    /// What this worker did so far.
    pub fn totals(&self) -> BinaryStats {
        self.stats().clone()
    }

    /// The pipeline `d` (identity `id`): from its stored binaries, else compiled with capture and
    /// its binaries stored (see the module doc). Only an error of the compile itself is returned.
    pub fn make(&self, gpu: &Gpu, d: &Desc, id: u128) -> Result<Pipeline, VkError> {
        let fns = gpu.binary.as_ref().expect("pipeline binaries enabled");
        if let Some(stored) = self.read(id) {
            match from_binaries(gpu, fns, d, &stored) {
                Ok(p) => {
                    self.stats().loaded += 1;
                    return Ok(p);
                }
                Err(e) if e.is_device_lost() => return Err(e),
                Err(e) => self.refused(format!("stored binaries refused: {e}")),
            }
        }
        let p = pipeline::create(gpu, Source::Capture, d)?;
        match fns.capture(p.raw) {
            Ok(data) => self.save(id, &data),
            Err(e) => self.stats().note(format!("capture failed: {e}")),
        }
        Ok(p)
    }

    /// The stored binaries of `id`, when its file exists and passes the checks.
    fn read(&self, id: u128) -> Option<Vec<BinaryData>> {
        let bytes = match std::fs::read(self.path(id)) {
            Ok(b) => b,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => return None,
            Err(e) => {
                self.refused(format!("unreadable: {e}"));
                return None;
            }
        };
        self.stats().bytes_read += bytes.len() as u64;
        match decode(&bytes) {
            Ok(b) => Some(b),
            Err(e) => {
                self.refused(e.to_string());
                None
            }
        }
    }

    fn refused(&self, why: String) {
        tracing::warn!("pipeline binaries under {}: {why}", self.dir.display());
        let mut s = self.stats();
        s.refused += 1;
        s.note(why);
    }

    fn save(&self, id: u128, data: &[BinaryData]) {
        let bytes = encode(data);
        // No fsync: a file cut short by a power loss fails the checksum and is replaced.
        let written = crate::atomic::write_atomic_with(&self.path(id), &bytes, false);
        let mut s = self.stats();
        match written {
            Ok(()) => {
                s.captured += 1;
                s.bytes_written += bytes.len() as u64;
            }
            Err(e) => s.note(format!("not saved: {e}")),
        }
    }
}

/// The pipeline `d` made from `stored` binaries; the binary handles are destroyed after.
fn from_binaries(
    gpu: &Gpu,
    fns: &BinaryFns,
    d: &Desc,
    stored: &[BinaryData],
) -> Result<Pipeline, VkError> {
    let handles = fns.load_binaries(stored)?;
    let p = pipeline::create(gpu, Source::Binaries(&handles), d);
    fns.destroy(&handles);
    p
}

/// `VkPhysicalDevicePipelineBinaryPropertiesKHR` by member name (empty without the extension).
pub(super) fn properties(gpu: &Gpu) -> std::collections::BTreeMap<String, bool> {
    let Some(p) = gpu.info.properties.pipeline_binary else {
        return Default::default();
    };
    let on = |b: ash::vk::Bool32| b == ash::vk::TRUE;
    [
        ("pipelineBinaryInternalCache", on(p.pipeline_binary_internal_cache)),
        ("pipelineBinaryInternalCacheControl", on(p.pipeline_binary_internal_cache_control)),
        ("pipelineBinaryPrefersInternalCache", on(p.pipeline_binary_prefers_internal_cache)),
        (
            "pipelineBinaryPrecompiledInternalCache",
            on(p.pipeline_binary_precompiled_internal_cache),
        ),
        ("pipelineBinaryCompressedData", on(p.pipeline_binary_compressed_data)),
    ]
    .into_iter()
    .map(|(k, v)| (k.to_string(), v))
    .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn two() -> Vec<BinaryData> {
        vec![
            BinaryData { key: vec![1; 20], data: b"first binary".to_vec() },
            BinaryData { key: vec![2; 32], data: vec![0xAB; 1000] },
        ]
    }

    #[test]
    fn a_file_reads_back_what_was_written() {
        assert_eq!(decode(&encode(&two())).unwrap(), two());
    }

    /// Twins of the round trip: every damaged file is refused before the driver sees it.
    #[test]
    fn damaged_files_are_refused_with_their_reason() {
        let good = encode(&two());
        assert_eq!(decode(&good[..good.len() - 1]), Err(FormatError::Checksum));
        assert_eq!(decode(&good[..10]), Err(FormatError::Truncated));
        assert_eq!(decode(b""), Err(FormatError::Truncated));
        let mut flipped = good.clone();
        flipped[40] ^= 1;
        assert_eq!(decode(&flipped), Err(FormatError::Checksum));
        let mut magic = good.clone();
        magic[0] = b'X';
        assert_eq!(decode(&magic), Err(FormatError::Magic));
        let mut version = good.clone();
        version[4] = 9;
        assert_eq!(decode(&version), Err(FormatError::Version(9)));
        assert_eq!(decode(&encode(&[])), Err(FormatError::Empty));
        let long_key = [BinaryData { key: vec![0; 33], data: vec![1] }];
        assert_eq!(decode(&encode(&long_key)), Err(FormatError::KeySize(33)));
        assert_eq!(decode(&[0u8; 64]), Err(FormatError::Magic));
    }

    #[test]
    fn the_folder_names_device_driver_and_uuid() {
        let p = ash::vk::PhysicalDeviceProperties {
            vendor_id: 0x10de,
            device_id: 0x2335,
            driver_version: 0x9127_c100,
            pipeline_cache_uuid: [3; 16],
            ..Default::default()
        };
        let d = device_dir(Path::new("/c"), &p);
        assert_eq!(
            d,
            Path::new("/c")
                .join(format!("pipeline-binaries-10de-2335-9127c100-{}", "03".repeat(16)))
        );
        assert_eq!(hex(&[0, 255, 16]), "00ff10");
    }
}
