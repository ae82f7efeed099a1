//! SPIR-V rewrites that work around driver faults (`rtprobe patch`, and `as_access=address_patched`
//! cells of the matrix). Each patch is a plain function over `&mut rspirv::dr::Module`, in its own
//! file with the SPIR-V rules it relies on: [`as_to_address`], [`nonuniform`], [`pin_index`],
//! [`ssbo_to_address`]; [`pipeline`] runs them over a pipeline's modules together with one set of
//! push-constant addresses ([`push`], sized by [`layout`]) and writes the host contract. Loading
//! never panics on arbitrary bytes; every output can be checked with `spirv-val`
//! ([`crate::tools::spirv`]).
pub mod as_to_address;
mod dynamic_access;
pub mod edit;
mod error;
mod guard;
pub mod layout;
mod name;
pub mod nonuniform;
pub mod pin_index;
pub mod pipeline;
pub mod push;
pub mod ssbo_to_address;
pub mod workaround;

use rspirv::binary::{Assemble, Disassemble};
use rspirv::dr::Module;
use std::collections::BTreeMap;

pub use error::PatchError;
use guard::quietly;
pub use name::{apply_help, PatchName, LIST};

/// Parse a SPIR-V binary (either endianness). Never panics.
pub fn load(bytes: &[u8]) -> Result<Module, PatchError> {
    if bytes.len() < 20 {
        return Err(PatchError::NotSpirv(format!(
            "{} bytes is shorter than a SPIR-V header",
            bytes.len()
        )));
    }
    if bytes.len() % 4 != 0 {
        return Err(PatchError::NotSpirv(format!(
            "{} bytes is not a whole number of 32-bit words",
            bytes.len()
        )));
    }
    let magic = u32::from_le_bytes([bytes[0], bytes[1], bytes[2], bytes[3]]);
    let words: Vec<u32> = match magic {
        0x0723_0203 => {
            bytes.chunks_exact(4).map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]])).collect()
        }
        0x0302_2307 => {
            bytes.chunks_exact(4).map(|c| u32::from_be_bytes([c[0], c[1], c[2], c[3]])).collect()
        }
        _ => return Err(PatchError::NotSpirv(format!("bad magic number {magic:#010x}"))),
    };
    match quietly(move || rspirv::dr::load_words(&words)) {
        Ok(Ok(m)) if m.header.is_some() => Ok(m),
        Ok(Ok(_)) => Err(PatchError::NotSpirv("no header".into())),
        Ok(Err(e)) => Err(PatchError::NotSpirv(e.to_string())),
        Err(p) => Err(PatchError::NotSpirv(format!("unparseable ({p})"))),
    }
}

/// Apply `patches` in order to one module with `options` (`key=value`, each key belonging to one
/// of them), its blocks under the standard layout rules and push constants up to 256 bytes.
/// Returns one line per patch saying what it did.
pub fn apply(
    m: &mut Module,
    patches: &[PatchName],
    options: &BTreeMap<String, String>,
) -> Result<Vec<String>, PatchError> {
    let work = std::mem::replace(m, Module::new());
    let mut stages =
        [pipeline::Stage { file: "module".into(), module: work, rules: layout::Rules::Standard }];
    let r = pipeline::apply(&mut stages, patches, options, 256);
    let [stage] = stages;
    *m = stage.module;
    r.map(|a| a.lines).map_err(|e| e.error)
}

pub fn assemble(m: &Module) -> Vec<u32> {
    m.assemble()
}

pub fn disassemble(m: &Module) -> String {
    m.disassemble()
}

pub use crate::tools::spirv::Validation;

/// Validate `words` with `spirv-val` ([`crate::tools::spirv`]: the newest one here) in the
/// environment of its SPIR-V version, without layout options.
pub fn validate(words: &[u32]) -> Validation {
    let opts = crate::tools::spirv::ValOptions::for_version(words.get(1).copied().unwrap_or(0));
    crate::tools::spirv::validate(words, &opts)
}

/// Line diff (`- ` removed, `+ ` added) of two disassemblies, by longest common subsequence.
pub fn diff(before: &str, after: &str) -> String {
    let a: Vec<&str> = before.lines().collect();
    let b: Vec<&str> = after.lines().collect();
    let (n, m) = (a.len(), b.len());
    let mut lcs = vec![vec![0u32; m + 1]; n + 1];
    for i in (0..n).rev() {
        for j in (0..m).rev() {
            lcs[i][j] =
                if a[i] == b[j] { lcs[i + 1][j + 1] + 1 } else { lcs[i + 1][j].max(lcs[i][j + 1]) };
        }
    }
    let (mut i, mut j, mut out) = (0, 0, String::new());
    while i < n || j < m {
        if i < n && j < m && a[i] == b[j] {
            i += 1;
            j += 1;
        } else if j < m && (i == n || lcs[i][j + 1] >= lcs[i + 1][j]) {
            out += &format!("+ {}\n", b[j]);
            j += 1;
        } else {
            out += &format!("- {}\n", a[i]);
            i += 1;
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn load_never_panics_on_arbitrary_bytes() {
        let mut x = 0x9e37_79b9_u32;
        for len in 0..400usize {
            let mut b = Vec::with_capacity(len);
            for _ in 0..len {
                x ^= x << 13;
                x ^= x >> 17;
                x ^= x << 5;
                b.push(x as u8);
            }
            if len >= 4 && len % 3 == 0 {
                b[..4].copy_from_slice(&0x0723_0203u32.to_le_bytes());
            }
            assert!(load(&b).is_err() || len >= 20);
        }
    }

    #[test]
    fn diff_marks_changed_lines() {
        assert_eq!(diff("a\nb\nc\n", "a\nx\nc\n"), "+ x\n- b\n");
    }
}
