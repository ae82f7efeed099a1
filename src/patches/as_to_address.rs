//! `as-to-address`: every acceleration structure read through a descriptor (a `UniformConstant`
//! variable of `OpTypeAccelerationStructureKHR`, or an array of them) becomes
//! `OpConvertUToAccelerationStructureKHR` of a 64-bit device address taken from push constants —
//! the known workaround for drivers that fault reading the AS descriptor. Each descriptor (set,
//! binding) gets its own push-constant address ([`super::push::Slots`]): two TLASes never share
//! one.
//!
//! SPIR-V rules relied on:
//! - `OpConvertUToAccelerationStructureKHR` (SPV_KHR_ray_tracing / SPV_KHR_ray_query) turns a
//!   64-bit unsigned device address into an AS object usable wherever a loaded AS is; the rewritten
//!   `OpLoad` keeps its result id, so every user stays valid. It needs the `RayTracingKHR` or
//!   `RayQueryKHR` capability: a module of `SPV_NV_ray_tracing` (older DXC, GLSL's
//!   GL_NV_ray_tracing; `OpTypeAccelerationStructureNV` is the same opcode) gets `RayTracingKHR`
//!   and `SPV_KHR_ray_tracing` added, and its pipeline then needs VK_KHR_ray_tracing_pipeline:
//!   Vulkan's SPIR-V environment (1.4.360, vk.xml `<spirvcapability name="RayTracingKHR">`)
//!   enables that capability only through the `rayTracingPipeline` feature of
//!   VK_KHR_ray_tracing_pipeline, while `RayTracingNV` is enabled by VK_NV_ray_tracing.
//! - The push-constant member is appended past the block ([`super::push`]).
//! - `direct` mode (default for single variables) reads the AS address itself from the block;
//!   `table` mode (default for arrays, or on request) reads the address of the descriptor's own
//!   table of 64-bit addresses and loads element `index` through a `PhysicalStorageBuffer`
//!   pointer, which needs the `PhysicalStorageBuffer64` addressing model, the
//!   `PhysicalStorageBufferAddresses` capability and an `Aligned` operand.
//! - From SPIR-V 1.4 an entry point's interface lists every global it references: the removed
//!   variables leave it, a new push-constant variable joins it.
//!
//! Handled shapes: `OpLoad %var`, and `OpLoad (OpAccessChain %var %index)`. Any other use of the
//! variable (passing its pointer to a function, copying it) is refused, naming the instruction.
use super::edit::{self, id_operand};
use super::layout::Rules;
use super::push::{self, SlotKey, SlotKind, Slots};
use super::PatchError;
use rspirv::dr::{Instruction, Module, Operand};
use rspirv::spirv::{Capability, Decoration, Op, StorageClass, Word};
use std::collections::{BTreeMap, HashMap, HashSet};

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Mode {
    Direct,
    Table,
}

#[derive(Clone, Debug, Default)]
pub struct Options {
    /// Default: `table` for arrays, `direct` for single variables.
    pub mode: Option<Mode>,
    /// Only AS variables of this descriptor set (default: every set).
    pub set: Option<u32>,
    /// Only AS variables with this binding (default: every binding).
    pub binding: Option<u32>,
}

/// One descriptor's address: where it is and what it holds.
#[derive(Clone, Debug, PartialEq)]
pub struct Entry {
    pub set: u32,
    pub binding: u32,
    pub offset: u32,
    pub mode: Mode,
    /// The array's length (None: a single variable or a runtime array).
    pub elements: Option<u32>,
}

#[derive(Clone, Debug, PartialEq)]
pub struct Report {
    pub rewritten_loads: usize,
    pub removed_variables: usize,
    pub entries: Vec<Entry>,
    /// `RayTracingKHR` and `SPV_KHR_ray_tracing` were added to an `SPV_NV_ray_tracing` module.
    pub added_khr: bool,
}

/// An AS descriptor variable.
struct Var {
    id: Word,
    set: u32,
    binding: u32,
    array: bool,
    /// The array's length, when a constant.
    elements: Option<u32>,
}

struct Site {
    func: usize,
    block: usize,
    inst: usize,
    var: Word,
    /// None: direct load of a non-array variable.
    index: Option<Word>,
}

const NAME: &str = "as-to-address";

/// The AS descriptor variables `opts` selects.
fn as_variables(m: &Module, opts: &Options) -> Result<Vec<Var>, PatchError> {
    let as_types: HashSet<Word> = m
        .types_global_values
        .iter()
        .filter(|i| i.class.opcode == Op::TypeAccelerationStructureKHR)
        .filter_map(|i| i.result_id)
        .collect();
    if as_types.is_empty() {
        return Err(PatchError::NothingToPatch {
            patch: NAME,
            what: "the module declares no acceleration structure type".into(),
        });
    }
    let mut vars = Vec::new();
    for v in m.types_global_values.iter().filter(|i| i.class.opcode == Op::Variable) {
        let (Some(id), Some(ptr)) = (v.result_id, v.result_type) else {
            continue;
        };
        let Some((StorageClass::UniformConstant, pointee)) = edit::pointer_info(m, ptr) else {
            continue;
        };
        let set = edit::decoration_literal(m, id, Decoration::DescriptorSet).unwrap_or(0);
        let binding = edit::decoration_literal(m, id, Decoration::Binding).unwrap_or(0);
        let var = |array, elements| Var { id, set, binding, array, elements };
        if as_types.contains(&pointee) {
            vars.push(var(false, None));
        } else if let Some(d) = edit::def(m, pointee) {
            let elem = id_operand(d, 0).filter(|e| as_types.contains(e));
            match (d.class.opcode, elem) {
                (Op::TypeArray, Some(_)) => vars.push(var(true, edit::array_length(m, d))),
                (Op::TypeRuntimeArray, Some(_)) => vars.push(var(true, None)),
                _ => {}
            }
        }
    }
    vars.retain(|v| {
        opts.set.is_none_or(|s| v.set == s) && opts.binding.is_none_or(|b| v.binding == b)
    });
    if vars.is_empty() {
        let what = match (opts.set, opts.binding) {
            (None, None) => "no acceleration structure is read through a descriptor".into(),
            (s, b) => format!(
                "no acceleration-structure descriptor at{}{}",
                s.map(|s| format!(" set {s}")).unwrap_or_default(),
                b.map(|b| format!(" binding {b}")).unwrap_or_default()
            ),
        };
        return Err(PatchError::NothingToPatch { patch: NAME, what });
    }
    Ok(vars)
}

/// Every load of the variables `var_ids` (directly or through a one-index access chain), and the
/// ids to remove with them (the variables and their chains); shapes not handled are refused.
fn load_sites(
    m: &Module,
    var_ids: &HashSet<Word>,
) -> Result<(Vec<Site>, HashSet<Word>), PatchError> {
    let mut chains: HashMap<Word, (Word, Word)> = HashMap::new(); // chain id -> (var, index id)
    let mut sites = Vec::new();
    let mut removed: HashSet<Word> = var_ids.clone();
    for (fi, f) in m.functions.iter().enumerate() {
        for (bi, b) in f.blocks.iter().enumerate() {
            for (ii, i) in b.instructions.iter().enumerate() {
                let var_used = i
                    .operands
                    .iter()
                    .find_map(|o| edit::id_from(o).filter(|w| var_ids.contains(w)));
                let chain_used = i
                    .operands
                    .iter()
                    .find_map(|o| edit::id_from(o).and_then(|w| chains.get(&w)).copied());
                let refuse = |what: String| PatchError::Unsupported {
                    patch: NAME,
                    id: i.result_id.unwrap_or(0),
                    what,
                };
                match (i.class.opcode, var_used, chain_used) {
                    (Op::AccessChain | Op::InBoundsAccessChain, Some(var), _) => {
                        if i.operands.len() != 2 || id_operand(i, 0) != Some(var) {
                            return Err(refuse("an access chain into an AS array with more than one index".into()));
                        }
                        let id = i.result_id.expect("chains have ids");
                        chains.insert(id, (var, id_operand(i, 1).expect("index operand")));
                        removed.insert(id);
                    }
                    (Op::Load, Some(var), _) => sites.push(Site { func: fi, block: bi, inst: ii, var, index: None }),
                    (Op::Load, None, Some((var, idx))) => {
                        sites.push(Site { func: fi, block: bi, inst: ii, var, index: Some(idx) })
                    }
                    (op, Some(_), _) | (op, None, Some(_)) => {
                        return Err(refuse(format!("Op{op:?} uses an acceleration-structure descriptor in a way this patch does not rewrite")))
                    }
                    _ => {}
                }
            }
        }
    }
    if sites.is_empty() {
        return Err(PatchError::NothingToPatch {
            patch: NAME,
            what: "acceleration-structure descriptors are declared but never loaded".into(),
        });
    }
    Ok((sites, removed))
}

/// The address a variable's loads read: its push member (direct) or its table (table mode).
enum Source {
    Direct { pc_var: Word, member: Word, ptr_pc_u64: Word, u64_t: Word },
    Table(edit::TableTypes),
}

/// Rewrite every AS descriptor `opts` selects, each reading its own address at the offset
/// `slots` gives its descriptor, placed in the push block under `rules`.
pub fn apply(
    m: &mut Module,
    opts: &Options,
    slots: &mut Slots,
    rules: Rules,
) -> Result<Report, PatchError> {
    let vars = as_variables(m, opts)?;
    let var_ids: HashSet<Word> = vars.iter().map(|v| v.id).collect();
    let (sites, removed) = load_sites(m, &var_ids)?;
    let mode_of = |v: &Var| opts.mode.unwrap_or(if v.array { Mode::Table } else { Mode::Direct });
    if let Some(v) = vars.iter().find(|v| v.array && mode_of(v) == Mode::Direct) {
        return Err(PatchError::BadOption {
            patch: NAME,
            what: format!("mode=direct cannot address the elements of the AS array at set {} binding {}; use mode=table", v.set, v.binding),
        });
    }
    let mut entries = Vec::new();
    for v in &vars {
        let kind = if mode_of(v) == Mode::Table { SlotKind::AsTable } else { SlotKind::AsAddress };
        let offset = slots.offset(SlotKey { kind, set: v.set, binding: v.binding }, NAME)?;
        entries.push(Entry {
            set: v.set,
            binding: v.binding,
            offset,
            mode: mode_of(v),
            elements: v.elements,
        });
    }
    // Members in offset order, so the block's offsets grow with its members.
    let mut order: Vec<usize> = (0..vars.len()).collect();
    order.sort_by_key(|k| entries[*k].offset);
    let mut sources: BTreeMap<Word, Source> = BTreeMap::new();
    for k in order {
        let (pc_var, member) = push::u64_member(m, entries[k].offset, rules, NAME)?;
        let source = match entries[k].mode {
            Mode::Table => Source::Table(edit::TableTypes::new(m, pc_var, member)),
            Mode::Direct => {
                let u32_t = edit::type_int(m, 32, false);
                let u64_t = edit::type_int(m, 64, false);
                Source::Direct {
                    pc_var,
                    member: edit::constant(m, u32_t, member as u64, false),
                    ptr_pc_u64: edit::type_pointer(m, StorageClass::PushConstant, u64_t),
                    u64_t,
                }
            }
        };
        sources.insert(vars[k].id, source);
    }
    let added_khr = khr_capability(m);
    let n_sites = sites.len();
    rewrite_loads(m, sites, &sources);
    edit::remove_ids(m, &removed);
    Ok(Report { rewritten_loads: n_sites, removed_variables: var_ids.len(), entries, added_khr })
}

/// Give an `SPV_NV_ray_tracing` module the capability `OpConvertUToAccelerationStructureKHR`
/// needs (`RayTracingKHR`, with `SPV_KHR_ray_tracing`); true when it was missing.
fn khr_capability(m: &mut Module) -> bool {
    let has = |m: &Module, c: Capability| {
        m.capabilities.iter().any(|i| i.operands.first() == Some(&Operand::Capability(c)))
    };
    if has(m, Capability::RayTracingKHR) || has(m, Capability::RayQueryKHR) {
        return false;
    }
    edit::add_capability(m, Capability::RayTracingKHR);
    edit::add_extension(m, "SPV_KHR_ray_tracing");
    true
}

/// Each site's `OpLoad` becomes `OpConvertUToAccelerationStructureKHR` of its variable's address
/// (`sources`). Last site first, so indices stay valid.
fn rewrite_loads(m: &mut Module, mut sites: Vec<Site>, sources: &BTreeMap<Word, Source>) {
    sites.sort_by_key(|s| std::cmp::Reverse((s.func, s.block, s.inst)));
    for s in sites {
        let (new, addr) = match &sources[&s.var] {
            Source::Table(t) => edit::table_entry(m, t, s.index),
            Source::Direct { pc_var, member, ptr_pc_u64, u64_t } => {
                let (pm, base) = (edit::next_id(m), edit::next_id(m));
                let new = vec![
                    Instruction::new(
                        Op::AccessChain,
                        Some(*ptr_pc_u64),
                        Some(pm),
                        vec![Operand::IdRef(*pc_var), Operand::IdRef(*member)],
                    ),
                    Instruction::new(Op::Load, Some(*u64_t), Some(base), vec![Operand::IdRef(pm)]),
                ];
                (new, base)
            }
        };
        let block = &mut m.functions[s.func].blocks[s.block];
        let load = &mut block.instructions[s.inst];
        *load = Instruction::new(
            Op::ConvertUToAccelerationStructureKHR,
            load.result_type,
            load.result_id,
            vec![Operand::IdRef(addr)],
        );
        for (k, i) in new.into_iter().enumerate() {
            block.instructions.insert(s.inst + k, i);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The patch on one module, its addresses from `offset` (default: past its block).
    fn patch(m: &mut Module, offset: Option<u32>) -> Result<Report, PatchError> {
        let start = match offset {
            Some(o) => o,
            None => push::end(m, Rules::Standard, NAME)?,
        };
        apply(m, &Options::default(), &mut Slots::new(start, 256), Rules::Standard)
    }

    fn module(glsl: &str) -> Module {
        crate::patches::compiled(shaderc::ShaderKind::RayGeneration, "t.rgen", glsl)
    }

    const CAMERA: &str = include_str!("../../tests/shaders/engine_camera.rgen");

    #[test]
    fn push_blocks_with_matrices_arrays_and_small_types_are_sized_from_their_decorations() {
        // engine_camera.rgen (std430): mat4 0..64; row-major mat3x4 = 4 rows of 3 floats, stride
        // 16: 64..124; vec3 128..140; u16 140..142; u64 144..152; Light[2] at 160, stride 16,
        // Light 15 bytes: 160..191; u8 frame 192..193 -> first free 8-aligned offset 200.
        let mut m = module(CAMERA);
        let r = patch(&mut m, None).expect("sized without --option offset");
        assert_eq!(r.entries[0].offset, 200);
        let v = crate::patches::validate(&crate::patches::assemble(&m));
        assert_eq!(v, crate::patches::Validation::Valid);
        // an offset inside the block is refused, one past it accepted
        let err = patch(&mut module(CAMERA), Some(192)).unwrap_err();
        assert!(err.to_string().contains("overlaps") && err.to_string().contains("193"), "{err}");
        assert_eq!(patch(&mut module(CAMERA), Some(200)).unwrap().entries[0].offset, 200);
    }

    #[test]
    fn material_block_with_nested_structs_and_column_major_matrices() {
        let glsl = r#"#version 460
#extension GL_EXT_ray_tracing : require
#extension GL_EXT_shader_explicit_arithmetic_types : require
struct Tex { uint index; float16_t scale; };
struct Material { mat2x3 uvTransform; Tex tex[3]; double roughness; };
layout(set = 0, binding = 0) uniform accelerationStructureEXT tlas;
layout(push_constant, std430) uniform Push { Material mat; int8_t flags; } pc;
layout(location = 0) rayPayloadEXT vec4 color;
void main() {
    color = vec4(pc.mat.uvTransform[1], float(pc.mat.roughness) + float(pc.mat.tex[2].scale) + float(pc.flags));
    traceRayEXT(tlas, gl_RayFlagsOpaqueEXT, 0xFF, 0, 0, 0, vec3(0.0), 0.001, vec3(0.0, 0.0, 1.0), 100.0, 0);
}
"#;
        // Material: mat2x3 column-major (2 columns of vec3, stride 16) 0..28; Tex[3] at 32, stride 8
        // (uint + f16 padded to 4-byte alignment) -> 32..54; double at 56..64; Material size 64;
        // flags at 64..65 -> 72.
        let mut m = module(glsl);
        let st = m
            .types_global_values
            .iter()
            .find(|i| {
                i.class.opcode == Op::TypeStruct
                    && edit::has_decoration(&m, i.result_id.unwrap(), Decoration::Block)
            })
            .and_then(|i| i.result_id)
            .unwrap();
        assert_eq!(crate::patches::layout::block_end(&m, st, Rules::Standard), Some(65));
        assert_eq!(patch(&mut m, None).unwrap().entries[0].offset, 72);
    }
}
