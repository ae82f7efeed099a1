//! GLSL → SPIR-V compiles kept on disk between runs (`<cache dir>/glsl/<key>.spv`, beside the
//! pipeline caches), so that a warm run compiles nothing it compiled before.
//!
//! A file's name is its [`key`]: a stable 128-bit hash ([`crate::stable_hash`]) of everything
//! that decides the SPIR-V — the shader kind and file name, the source, the text of its
//! includes, its defines, the target environment, and the compiler with its version (shaderc
//! and the glslang and SPIRV-Tools it links, or the external glslangValidator's version) and
//! rtprobe's. Its content: a magic, the key again, a checksum of the SPIR-V, then the SPIR-V
//! words. A file that is short, not this key's, fails its checksum or does not start with the
//! SPIR-V magic is [`Lookup::Corrupt`]: the caller compiles afresh and writes the file again.
//! Files are written atomically (tmp + rename); two workers writing the same key write the same
//! bytes. It is rtprobe's own compiler's cache, not the driver's: the run's re-runs alone
//! (confirm, repeats, verifying repeats) read it and still compile their pipelines afresh; the
//! workers of bisect, repro and GPU-AV, and mutant workers (a mutant rewrites the SPIR-V) get no
//! cache folder, so they never read it.
use crate::stable_hash::StableHash;
use std::path::{Path, PathBuf};

const MAGIC: &[u8; 8] = b"RTPGLSL1";
const HEADER: usize = 8 + 16 + 16;
const SPIRV_MAGIC: u32 = 0x0723_0203;

/// What decides a compile's SPIR-V, hashed into its [`key`].
pub struct KeyParts<'a> {
    /// shaderc's shader kind, as its debug name.
    pub kind: &'a str,
    pub file: &'a str,
    pub glsl: &'a str,
    /// The text of each included file, in inclusion order (none for rtprobe's generated GLSL).
    pub includes: &'a [(&'a str, &'a str)],
    pub defines: &'a [(String, Option<String>)],
    pub target: &'a str,
    /// The compiler and its version (`compile::compiler_for`).
    pub compiler: &'a str,
}

/// The key of a compile: every part, each after its length (so two lists never meet by
/// concatenation), and rtprobe's version.
pub fn key(p: &KeyParts) -> u128 {
    let mut h = StableHash::default();
    h.str(env!("CARGO_PKG_VERSION")).str(p.compiler).str(p.target).str(p.kind).str(p.file);
    h.str(p.glsl).u64(p.includes.len() as u64);
    for (name, text) in p.includes {
        h.str(name).str(text);
    }
    h.u64(p.defines.len() as u64);
    for (name, value) in p.defines {
        h.str(name).u64(u64::from(value.is_some())).str(value.as_deref().unwrap_or(""));
    }
    h.finish()
}

/// What a lookup found.
#[derive(Debug, PartialEq)]
pub enum Lookup {
    Hit(Vec<u32>),
    Miss,
    /// A file is there but cannot be this key's SPIR-V (the reason).
    Corrupt(String),
}

/// The folder of kept compiles.
#[derive(Clone, Debug)]
pub struct DiskCache {
    dir: PathBuf,
}

impl DiskCache {
    /// The GLSL cache under the cache folder `cache_dir` (the pipeline caches' folder).
    pub fn under(cache_dir: &Path) -> Self {
        DiskCache { dir: cache_dir.join("glsl") }
    }

    pub fn path(&self, key: u128) -> PathBuf {
        self.dir.join(format!("{key:032x}.spv"))
    }

    pub fn load(&self, key: u128) -> Lookup {
        match std::fs::read(self.path(key)) {
            Ok(bytes) => match decode(&bytes, key) {
                Ok(words) => Lookup::Hit(words),
                Err(why) => Lookup::Corrupt(why),
            },
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => Lookup::Miss,
            Err(e) => Lookup::Corrupt(format!("unreadable: {e}")),
        }
    }

    /// Keep `words` under `key` (best effort: a failure is returned for a warning).
    pub fn store(&self, key: u128, words: &[u32]) -> Result<(), crate::atomic::WriteError> {
        crate::atomic::write_atomic_with(&self.path(key), &encode(key, words), false)
    }
}

fn checksum(payload: &[u8]) -> u128 {
    StableHash::default().bytes(payload).finish()
}

fn encode(key: u128, words: &[u32]) -> Vec<u8> {
    let payload: Vec<u8> = words.iter().flat_map(|w| w.to_le_bytes()).collect();
    let mut out = Vec::with_capacity(HEADER + payload.len());
    out.extend_from_slice(MAGIC);
    out.extend_from_slice(&key.to_le_bytes());
    out.extend_from_slice(&checksum(&payload).to_le_bytes());
    out.extend_from_slice(&payload);
    out
}

/// The SPIR-V of a file, or why it is not `key`'s.
fn decode(bytes: &[u8], key: u128) -> Result<Vec<u32>, String> {
    if bytes.len() < HEADER + 4 || &bytes[..8] != MAGIC {
        return Err(format!("{} bytes without the header", bytes.len()));
    }
    let u128_at = |o: usize| u128::from_le_bytes(bytes[o..o + 16].try_into().expect("16 bytes"));
    let payload = &bytes[HEADER..];
    if u128_at(8) != key {
        return Err("another key's file".into());
    }
    if payload.len() % 4 != 0 || checksum(payload) != u128_at(24) {
        return Err("checksum mismatch".into());
    }
    let words: Vec<u32> =
        payload.chunks_exact(4).map(|c| u32::from_le_bytes(c.try_into().expect("4"))).collect();
    if words[0] != SPIRV_MAGIC {
        return Err("not SPIR-V".into());
    }
    Ok(words)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parts<'a>(glsl: &'a str, defines: &'a [(String, Option<String>)]) -> KeyParts<'a> {
        KeyParts {
            kind: "RayGeneration",
            file: "probe.rgen",
            glsl,
            includes: &[],
            defines,
            target: "vulkan1.2",
            compiler: "shaderc x",
        }
    }

    /// Every part of the key changes it; the same parts give the same key.
    #[test]
    fn every_part_changes_the_key() {
        let base = key(&parts("void main(){}", &[]));
        assert_eq!(base, key(&parts("void main(){}", &[])));
        let d = [("A".to_string(), Some("1".to_string()))];
        let d0 = [("A".to_string(), None)];
        let mut all = vec![key(&parts("void main(){ }", &[])), key(&parts("void main(){}", &d))];
        all.push(key(&parts("void main(){}", &d0)));
        all.push(key(&KeyParts { target: "vulkan1.3", ..parts("void main(){}", &[]) }));
        all.push(key(&KeyParts { compiler: "shaderc y", ..parts("void main(){}", &[]) }));
        all.push(key(&KeyParts { kind: "Miss", ..parts("void main(){}", &[]) }));
        all.push(key(&KeyParts { file: "p.rmiss", ..parts("void main(){}", &[]) }));
        all.push(key(&KeyParts { includes: &[("a.glsl", "x")], ..parts("void main(){}", &[]) }));
        all.push(key(&KeyParts { includes: &[("a.glsl", "y")], ..parts("void main(){}", &[]) }));
        for (i, k) in all.iter().enumerate() {
            assert_ne!(*k, base, "part {i} left the key unchanged");
        }
    }

    /// A stored file reads back; garbage, a flipped bit, a truncated file, another key's file
    /// and non-SPIR-V are each `Corrupt`, never a hit.
    #[test]
    fn a_damaged_file_is_corrupt_never_a_hit() {
        let d = crate::tempdir::tempdir().unwrap();
        let c = DiskCache::under(d.path());
        let words = vec![SPIRV_MAGIC, 0x0001_0500, 7, 9, 1];
        assert_eq!(c.load(1), Lookup::Miss);
        c.store(1, &words).unwrap();
        assert_eq!(c.load(1), Lookup::Hit(words.clone()));
        let good = std::fs::read(c.path(1)).unwrap();
        let corrupt = |bytes: &[u8], k: u128| {
            std::fs::write(c.path(k), bytes).unwrap();
            matches!(c.load(k), Lookup::Corrupt(_))
        };
        let mut flipped = good.clone();
        *flipped.last_mut().unwrap() ^= 1;
        assert!(corrupt(&flipped, 1), "a flipped bit");
        assert!(corrupt(&good[..good.len() - 4], 1), "truncated");
        assert!(corrupt(b"garbage garbage garbage garbage garbage garbage", 1), "garbage");
        assert!(corrupt(&good, 2), "another key's file under this key");
        let not_spirv = encode(3, &[1, 2, 3]);
        assert!(corrupt(&not_spirv, 3), "not SPIR-V");
    }
}
