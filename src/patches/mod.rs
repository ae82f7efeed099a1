//! SPIR-V rewrites that work around driver faults (`rtprobe patch`, and `as_access=address_patched`
//! cells of the matrix). Each patch is a plain function over `&mut rspirv::dr::Module`, in its own
//! file with the SPIR-V rules it relies on: [`as_to_address`], [`nonuniform`], [`pin_index`].
//! Loading never panics on arbitrary bytes; every output can be checked with `spirv-val`.
pub mod as_to_address;
mod dynamic_access;
pub mod edit;
mod error;
pub mod nonuniform;
pub mod pin_index;
pub mod ssbo_to_address;
pub mod workaround;

use rspirv::binary::{Assemble, Disassemble};
use rspirv::dr::Module;
use std::collections::BTreeMap;

pub use error::PatchError;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PatchName {
    AsToAddress,
    Nonuniform,
    PinIndex,
    SsboToAddress,
}

/// Name, options and one-line description of each patch.
pub const LIST: &[(&str, &str, &str)] = &[
    ("as-to-address", "offset=BYTES mode=direct|table binding=N", "acceleration structures read through descriptors become OpConvertUToAccelerationStructureKHR of a 64-bit address from push constants (table mode: address of a table of addresses, indexed like the descriptor array)"),
    ("nonuniform", "strip=true|false", "decorate every dynamically indexed descriptor access NonUniform (what nonuniformEXT would give), or strip every NonUniform decoration"),
    ("pin-index", "binding=N value=K spec-id=ID", "replace the runtime index of dynamically indexed descriptor arrays by an OpSpecConstant (default value K)"),
    ("ssbo-to-address", "offset=BYTES binding=N", "reads of a storage-buffer descriptor array become PhysicalStorageBuffer loads from a table of buffer addresses in push constants (reads only)"),
];

impl PatchName {
    pub fn parse(s: &str) -> Result<Self, PatchError> {
        match s.trim() {
            "as-to-address" => Ok(PatchName::AsToAddress),
            "nonuniform" => Ok(PatchName::Nonuniform),
            "pin-index" => Ok(PatchName::PinIndex),
            "ssbo-to-address" => Ok(PatchName::SsboToAddress),
            other => Err(PatchError::Unknown(other.into())),
        }
    }

    pub fn as_str(self) -> &'static str {
        match self {
            PatchName::AsToAddress => "as-to-address",
            PatchName::Nonuniform => "nonuniform",
            PatchName::PinIndex => "pin-index",
            PatchName::SsboToAddress => "ssbo-to-address",
        }
    }

    fn keys(self) -> &'static [&'static str] {
        match self {
            PatchName::AsToAddress => &["offset", "mode", "binding"],
            PatchName::Nonuniform => &["strip"],
            PatchName::PinIndex => &["binding", "value", "spec-id"],
            PatchName::SsboToAddress => &["offset", "binding"],
        }
    }
}

/// A panic [`quietly`] caught, with its message ("panic" when it had none).
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
struct Panicked(String);

/// `f`, with a panic caught and returned instead of printed.
fn quietly<T>(f: impl FnOnce() -> T + std::panic::UnwindSafe) -> Result<T, Panicked> {
    let hook = std::panic::take_hook();
    std::panic::set_hook(Box::new(|_| {}));
    let r = std::panic::catch_unwind(f);
    std::panic::set_hook(hook);
    r.map_err(|e| {
        Panicked(
            e.downcast_ref::<&str>()
                .map(|s| s.to_string())
                .or_else(|| e.downcast_ref::<String>().cloned())
                .unwrap_or_else(|| "panic".into()),
        )
    })
}

/// Run `f` on a copy of `m`, catching panics; `m` takes the copy only when `f` succeeds, so a
/// failed patch leaves the module as it was.
fn on_copy<R>(
    m: &mut Module,
    f: impl FnOnce(&mut Module) -> Result<R, PatchError>,
) -> Result<R, PatchError> {
    let mut work = m.clone();
    let r = quietly(std::panic::AssertUnwindSafe(|| f(&mut work)))
        .map_err(|p| PatchError::Internal(p.0))??;
    *m = work;
    Ok(r)
}

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
    let (words, mode_ids) = take_execution_mode_ids(words);
    match quietly(move || rspirv::dr::load_words(&words)) {
        Ok(Ok(mut m)) if m.header.is_some() => {
            for operands in mode_ids {
                m.execution_modes.push(execution_mode_id(&operands)?);
            }
            Ok(m)
        }
        Ok(Ok(_)) => Err(PatchError::NotSpirv("no header".into())),
        Ok(Err(e)) => Err(PatchError::NotSpirv(e.to_string())),
        Err(p) => Err(PatchError::NotSpirv(format!("unparseable ({p})"))),
    }
}

/// rspirv 0.13's loader rejects OpExecutionModeId ("not inside block"), which glslang 12 (the
/// system shaderc's) writes for a compute shader's workgroup size at SPIR-V 1.6
/// (`OpExecutionModeId %main LocalSizeId %c1 %c1 %c1`). Take those instructions out of the words
/// (their operands are returned) so the rest loads; [`load`] puts them back among the execution
/// modes, from where they are assembled unchanged. Words that do not parse are left as they are,
/// for the loader to report.
fn take_execution_mode_ids(words: Vec<u32>) -> (Vec<u32>, Vec<Vec<u32>>) {
    const OP_EXECUTION_MODE_ID: u32 = 331;
    let mut i = 5;
    let mut found = Vec::new();
    while i < words.len() {
        let count = (words[i] >> 16) as usize;
        if count == 0 || i + count > words.len() {
            return (words, vec![]);
        }
        if words[i] & 0xffff == OP_EXECUTION_MODE_ID {
            found.push(i);
        }
        i += count;
    }
    if found.is_empty() {
        return (words, vec![]);
    }
    let mut rest = words[..5].to_vec();
    let mut ops = Vec::new();
    let mut i = 5;
    while i < words.len() {
        let count = (words[i] >> 16) as usize;
        if found.contains(&i) {
            ops.push(words[i + 1..i + count].to_vec());
        } else {
            rest.extend_from_slice(&words[i..i + count]);
        }
        i += count;
    }
    (rest, ops)
}

/// `OpExecutionModeId` from its operands: the entry point, the mode, then ids.
fn execution_mode_id(operands: &[u32]) -> Result<rspirv::dr::Instruction, PatchError> {
    use rspirv::dr::Operand;
    let bad = || PatchError::NotSpirv("malformed OpExecutionModeId".into());
    let (&entry, rest) = operands.split_first().ok_or_else(bad)?;
    let (&mode, ids) = rest.split_first().ok_or_else(bad)?;
    let mode = rspirv::spirv::ExecutionMode::from_u32(mode).ok_or_else(bad)?;
    let mut ops = vec![Operand::IdRef(entry), Operand::ExecutionMode(mode)];
    ops.extend(ids.iter().map(|&id| Operand::IdRef(id)));
    Ok(rspirv::dr::Instruction::new(rspirv::spirv::Op::ExecutionModeId, None, None, ops))
}

/// Apply `patches` in order with `options` (`key=value`, each key belonging to one of them).
/// Returns one line per patch saying what it did.
pub fn apply(
    m: &mut Module,
    patches: &[PatchName],
    options: &BTreeMap<String, String>,
) -> Result<Vec<String>, PatchError> {
    for k in options.keys() {
        if !patches.iter().any(|p| p.keys().contains(&k.as_str())) {
            return Err(PatchError::UnknownOption(k.clone()));
        }
    }
    let o = Options(options);
    patches
        .iter()
        .map(|&p| match p {
            PatchName::AsToAddress => as_to_address_line(m, &o),
            PatchName::Nonuniform => nonuniform_line(m, &o),
            PatchName::PinIndex => pin_index_line(m, &o),
            PatchName::SsboToAddress => ssbo_to_address_line(m, &o),
        })
        .collect()
}

/// The `key=value` options of [`apply`], read for one patch.
struct Options<'a>(&'a BTreeMap<String, String>);

impl Options<'_> {
    /// The number `k=N`, if given.
    fn num(&self, p: PatchName, k: &str) -> Result<Option<u32>, PatchError> {
        self.0
            .get(k)
            .map(|v| {
                v.parse::<u32>().map_err(|_| PatchError::BadOption {
                    patch: p.as_str(),
                    what: format!("{k}={v:?} is not a number"),
                })
            })
            .transpose()
    }

    /// The value `choices` pairs with `k`'s, if given; a value not among them is an error that
    /// names `expected`.
    fn choice<T: Copy>(
        &self,
        p: PatchName,
        k: &str,
        choices: &[(&str, T)],
        expected: &str,
    ) -> Result<Option<T>, PatchError> {
        let Some(v) = self.0.get(k) else {
            return Ok(None);
        };
        match choices.iter().find(|(name, _)| *name == v.as_str()) {
            Some((_, t)) => Ok(Some(*t)),
            None => Err(PatchError::BadOption {
                patch: p.as_str(),
                what: format!("{k}={v:?}: use {expected}"),
            }),
        }
    }
}

/// [`as_to_address`] with `mode`, `offset` and `binding`, and the line saying what it did.
fn as_to_address_line(m: &mut Module, o: &Options) -> Result<String, PatchError> {
    let p = PatchName::AsToAddress;
    let modes = [("direct", as_to_address::Mode::Direct), ("table", as_to_address::Mode::Table)];
    let mode = o.choice(p, "mode", &modes, "direct or table")?;
    let opts =
        as_to_address::Options { offset: o.num(p, "offset")?, mode, binding: o.num(p, "binding")? };
    let r = on_copy(m, |w| as_to_address::apply(w, &opts))?;
    Ok(format!("as-to-address: {} loads rewritten, {} descriptor variables removed, address at push-constant offset {} ({:?} mode)", r.rewritten_loads, r.removed_variables, r.offset, r.mode))
}

/// [`nonuniform`] (`strip`: remove the decorations instead), and the line saying what it did.
fn nonuniform_line(m: &mut Module, o: &Options) -> Result<String, PatchError> {
    let p = PatchName::Nonuniform;
    let strip = o
        .choice(p, "strip", &[("false", false), ("true", true)], "true or false")?
        .unwrap_or(false);
    let r = on_copy(m, |w| nonuniform::apply(w, strip))?;
    Ok(if strip {
        format!("nonuniform: {} NonUniform decorations stripped", r.stripped)
    } else {
        format!("nonuniform: {} objects decorated NonUniform", r.decorated)
    })
}

/// [`pin_index`] with `binding`, `value` and `spec-id`, and the line saying what it did.
fn pin_index_line(m: &mut Module, o: &Options) -> Result<String, PatchError> {
    let p = PatchName::PinIndex;
    let opts = pin_index::Options {
        binding: o.num(p, "binding")?,
        value: o.num(p, "value")?.unwrap_or(0),
        spec_id: o.num(p, "spec-id")?,
    };
    let r = on_copy(m, |w| pin_index::apply(w, &opts))?;
    Ok(format!(
        "pin-index: {} accesses now index with SpecId {} (default {})",
        r.pinned, r.spec_id, opts.value
    ))
}

/// [`ssbo_to_address`] with `offset` and `binding`, and the line saying what it did.
fn ssbo_to_address_line(m: &mut Module, o: &Options) -> Result<String, PatchError> {
    let p = PatchName::SsboToAddress;
    let opts =
        ssbo_to_address::Options { offset: o.num(p, "offset")?, binding: o.num(p, "binding")? };
    let r = on_copy(m, |w| ssbo_to_address::apply(w, &opts))?;
    Ok(format!("ssbo-to-address: {} loads now read through buffer addresses (table address at push-constant offset {})", r.rewritten_loads, r.offset))
}

pub fn assemble(m: &Module) -> Vec<u32> {
    m.assemble()
}

pub fn disassemble(m: &Module) -> String {
    m.disassemble()
}

/// What `spirv-val` said.
#[derive(Debug, PartialEq)]
pub enum Validation {
    /// spirv-val is not installed.
    Unavailable,
    Valid,
    Invalid(String),
}

/// Run `spirv-val --target-env vulkan1.2` on `words`, if it is installed.
pub fn validate(words: &[u32]) -> Validation {
    // A name no other call in this process uses at the same time (tests validate on several
    // threads; a name from the module's length alone let two calls overwrite each other's file).
    static NEXT: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
    let n = NEXT.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    let dir = std::env::temp_dir().join(format!("rtprobe-val-{}-{n}", std::process::id()));
    let bytes: Vec<u8> = words.iter().flat_map(|w| w.to_le_bytes()).collect();
    if std::fs::write(&dir, bytes).is_err() {
        return Validation::Unavailable;
    }
    // SPIR-V 1.6 (from `patch --glsl --target-env vulkan1.3/1.4`) needs a Vulkan 1.3 environment.
    let env =
        if words.get(1).is_some_and(|v| *v >= 0x0001_0600) { "vulkan1.3" } else { "vulkan1.2" };
    let out =
        std::process::Command::new("spirv-val").args(["--target-env", env]).arg(&dir).output();
    let _ = std::fs::remove_file(&dir);
    match out {
        Err(_) => Validation::Unavailable,
        Ok(o) if o.status.success() => Validation::Valid,
        Ok(o) => {
            Validation::Invalid(String::from_utf8_lossy(&o.stderr).trim().replace('\n', " | "))
        }
    }
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
    fn execution_mode_ids_load_and_assemble_unchanged() {
        // glslang 12 at SPIR-V 1.6: OpExecutionModeId %main LocalSizeId %c1 %c1 %c1.
        let mut b = rspirv::dr::Builder::new();
        b.set_version(1, 6);
        b.capability(rspirv::spirv::Capability::Shader);
        b.memory_model(
            rspirv::spirv::AddressingModel::Logical,
            rspirv::spirv::MemoryModel::GLSL450,
        );
        let void = b.type_void();
        let fn_ty = b.type_function(void, vec![]);
        let uint = b.type_int(32, 0);
        let one = b.constant_bit32(uint, 1);
        let main =
            b.begin_function(void, None, rspirv::spirv::FunctionControl::NONE, fn_ty).unwrap();
        b.begin_block(None).unwrap();
        b.ret().unwrap();
        b.end_function().unwrap();
        b.entry_point(rspirv::spirv::ExecutionModel::GLCompute, main, "main", vec![]);
        let mut m = b.module();
        m.execution_modes.push(execution_mode_id(&[main, 38, one, one, one]).unwrap());
        let words = m.assemble();
        let bytes: Vec<u8> = words.iter().flat_map(|w| w.to_le_bytes()).collect();
        let loaded = load(&bytes).expect("loads despite OpExecutionModeId");
        assert_eq!(assemble(&loaded), words);
        assert!(disassemble(&loaded).contains("OpExecutionModeId %"), "{}", disassemble(&loaded));
        // Its operands are checked, not trusted.
        assert!(execution_mode_id(&[main]).is_err());
        assert!(execution_mode_id(&[main, 0xdead]).is_err());
    }

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
