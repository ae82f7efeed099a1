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
pub mod index_bounds;
pub mod layout;
mod name;
pub mod nonuniform;
pub mod pin_index;
pub mod pipeline;
pub mod push;
pub mod ssbo_to_address;
pub mod uniformity;
pub mod workaround;

use rspirv::binary::{Assemble, Disassemble};
use rspirv::dr::Module;
use std::collections::BTreeMap;

pub use error::PatchError;
pub(crate) use guard::on_copy;
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
    let (words, mode_ids) = take_execution_mode_ids(words);
    match quietly(move || load_words(&words)) {
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

/// rspirv's loader, taking `OpUntypedVariableKHR` at module scope too: SPV_KHR_untyped_pointers
/// declares the descriptor heaps of `layout(descriptor_heap)` shaders so (`BuiltIn
/// ResourceHeapEXT` / `SamplerHeapEXT`), and rspirv 0.13's loader refuses every module-scope
/// instruction it does not sort as a type, constant or `OpVariable`. Such a variable reaches the
/// loader as an `OpVariable` (its leading operands are the same: result type, result, storage
/// class), is kept among the globals in its place, and gets its own opcode back after.
struct UntypedLoader {
    inner: rspirv::dr::Loader,
    in_function: bool,
    untyped: std::collections::HashSet<u32>,
}

impl rspirv::binary::Consumer for UntypedLoader {
    fn initialize(&mut self) -> rspirv::binary::ParseAction {
        self.inner.initialize()
    }
    fn finalize(&mut self) -> rspirv::binary::ParseAction {
        self.inner.finalize()
    }
    fn consume_header(&mut self, h: rspirv::dr::ModuleHeader) -> rspirv::binary::ParseAction {
        self.inner.consume_header(h)
    }
    fn consume_instruction(
        &mut self,
        mut inst: rspirv::dr::Instruction,
    ) -> rspirv::binary::ParseAction {
        use rspirv::spirv::Op;
        match inst.class.opcode {
            Op::Function => self.in_function = true,
            Op::FunctionEnd => self.in_function = false,
            Op::UntypedVariableKHR if !self.in_function => {
                self.untyped.extend(inst.result_id);
                inst.class = rspirv::dr::Instruction::new(Op::Variable, None, None, vec![]).class;
            }
            _ => {}
        }
        self.inner.consume_instruction(inst)
    }
}

/// Load `words` with [`UntypedLoader`].
fn load_words(words: &[u32]) -> Result<Module, String> {
    use rspirv::spirv::Op;
    let mut l = UntypedLoader {
        inner: rspirv::dr::Loader::new(),
        in_function: false,
        untyped: Default::default(),
    };
    rspirv::binary::parse_words(words, &mut l).map_err(|e| e.to_string())?;
    let mut m = l.inner.module();
    let class = rspirv::dr::Instruction::new(Op::UntypedVariableKHR, None, None, vec![]).class;
    for i in &mut m.types_global_values {
        if i.class.opcode == Op::Variable && i.result_id.is_some_and(|r| l.untyped.contains(&r)) {
            i.class = class;
        }
    }
    Ok(m)
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

/// A module compiled from GLSL by the system's shaderc and loaded, for the unit tests of the
/// passes and of the harness (file name `t.<stage>`).
#[cfg(test)]
pub(crate) fn compiled(kind: shaderc::ShaderKind, file: &str, glsl: &str) -> Module {
    let mut c = crate::shadergen::compile::Compiler::new().expect("shaderc");
    let words = c.compile_glsl(kind, file, glsl).expect("compiles");
    load(&crate::tools::spirv::bytes(&words)).expect("loads")
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

    /// A module-scope `OpUntypedVariableKHR` (a descriptor heap), which rspirv's own loader
    /// refuses, loads and assembles back to the same words.
    #[test]
    fn module_scope_untyped_variables_load_and_round_trip() {
        // OpCapability Shader, UntypedPointersKHR; OpMemoryModel Logical GLSL450;
        // %1 = OpTypeUntypedPointerKHR UniformConstant; %2 = OpUntypedVariableKHR %1 UniformConstant;
        // %3 = OpTypeVoid; %4 = OpTypeFunction %3; %5 = OpFunction %3 None %4; OpLabel; OpReturn.
        let words: Vec<u32> = vec![
            0x0723_0203,
            0x0001_0600,
            0,
            7,
            0,
            (2 << 16) | 17,
            1,
            (2 << 16) | 17,
            4473,
            (3 << 16) | 14,
            0,
            1,
            (3 << 16) | 4417,
            1,
            0,
            (4 << 16) | 4418,
            1,
            2,
            0,
            (2 << 16) | 19,
            3,
            (3 << 16) | 33,
            4,
            3,
            (5 << 16) | 54,
            3,
            5,
            0,
            4,
            (2 << 16) | 248,
            6,
            (1 << 16) | 253,
            (1 << 16) | 56,
        ];
        assert!(rspirv::dr::load_words(&words).is_err(), "rspirv's own loader refuses it");
        let bytes: Vec<u8> = words.iter().flat_map(|w| w.to_le_bytes()).collect();
        let m = load(&bytes).unwrap();
        assert_eq!(m.types_global_values[1].class.opcode, rspirv::spirv::Op::UntypedVariableKHR);
        // The same words after the header (whose generator word rspirv writes as its own).
        let out = assemble(&m);
        assert_eq!((out[1], out[3]), (words[1], words[3]));
        assert_eq!(out[5..], words[5..]);
    }

    #[test]
    fn diff_marks_changed_lines() {
        assert_eq!(diff("a\nb\nc\n", "a\nx\nc\n"), "+ x\n- b\n");
    }
}
