//! `as-to-address`: every acceleration structure read through a descriptor (a `UniformConstant`
//! variable of `OpTypeAccelerationStructureKHR`, or an array of them) becomes
//! `OpConvertUToAccelerationStructureKHR` of a 64-bit device address taken from push constants —
//! the known workaround for drivers that fault reading the AS descriptor.
//!
//! SPIR-V rules relied on:
//! - `OpConvertUToAccelerationStructureKHR` (SPV_KHR_ray_tracing / SPV_KHR_ray_query) turns a
//!   64-bit unsigned device address into an AS object usable wherever a loaded AS is; the rewritten
//!   `OpLoad` keeps its result id, so every user stays valid.
//! - A push-constant block is a `Block`-decorated struct in `PushConstant` storage with explicit
//!   member `Offset`s; appending a member at an unused 8-aligned offset leaves the others intact.
//! - `direct` mode reads the AS address itself from the block (non-array variables); `table` mode
//!   (arrays, or on request) reads the address of a table of 64-bit addresses and loads element
//!   `index` through a `PhysicalStorageBuffer` pointer, which needs the `PhysicalStorageBuffer64`
//!   addressing model, the `PhysicalStorageBufferAddresses` capability and an `Aligned` operand.
//! - From SPIR-V 1.4 an entry point's interface lists every global it references: the removed
//!   variables leave it, a new push-constant variable joins it.
//!
//! Handled shapes: `OpLoad %var`, and `OpLoad (OpAccessChain %var %index)`. Any other use of the
//! variable (passing its pointer to a function, copying it) is refused, naming the instruction.
use super::edit::{self, id_operand};
use super::PatchError;
use rspirv::dr::{Instruction, Module, Operand};
use rspirv::spirv::{Decoration, Op, StorageClass, Word};
use std::collections::HashSet;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Mode {
    Direct,
    Table,
}

#[derive(Clone, Debug, Default)]
pub struct Options {
    /// Byte offset of the new 64-bit push-constant member (default: the end of the existing block
    /// rounded up to 8, or 0 when the module has none).
    pub offset: Option<u32>,
    /// Default: `table` when any AS variable is an array, else `direct`.
    pub mode: Option<Mode>,
    /// Only the AS variable with this binding (default: every AS descriptor variable).
    pub binding: Option<u32>,
}

#[derive(Clone, Debug, PartialEq)]
pub struct Report {
    pub rewritten_loads: usize,
    pub removed_variables: usize,
    pub offset: u32,
    pub mode: Mode,
}

struct Site {
    func: usize,
    block: usize,
    inst: usize,
    /// None: direct load of a non-array variable.
    index: Option<Word>,
}

const NAME: &str = "as-to-address";

/// The AS descriptor variables `opts` selects: (variable, is an array, AS type).
fn as_variables(m: &Module, opts: &Options) -> Result<Vec<(Word, bool, Word)>, PatchError> {
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
    // AS descriptor variables: var id -> (is array, AS type)
    let mut vars: Vec<(Word, bool, Word)> = Vec::new();
    for v in m.types_global_values.iter().filter(|i| i.class.opcode == Op::Variable) {
        let (Some(id), Some(ptr)) = (v.result_id, v.result_type) else {
            continue;
        };
        let Some((StorageClass::UniformConstant, pointee)) = edit::pointer_info(m, ptr) else {
            continue;
        };
        if as_types.contains(&pointee) {
            vars.push((id, false, pointee));
        } else if let Some(d) = edit::def(m, pointee) {
            if matches!(d.class.opcode, Op::TypeArray | Op::TypeRuntimeArray) {
                if let Some(elem) = id_operand(d, 0).filter(|e| as_types.contains(e)) {
                    vars.push((id, true, elem));
                }
            }
        }
    }
    if let Some(b) = opts.binding {
        vars.retain(|v| edit::decoration_literal(m, v.0, Decoration::Binding) == Some(b));
    }
    if vars.is_empty() {
        let what = match opts.binding {
            Some(b) => format!("no acceleration-structure descriptor at binding {b}"),
            None => "no acceleration structure is read through a descriptor".into(),
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
    let mut chains: std::collections::HashMap<Word, Word> = Default::default(); // chain id -> index id
    let mut sites = Vec::new();
    let mut removed: HashSet<Word> = var_ids.clone();
    for (fi, f) in m.functions.iter().enumerate() {
        for (bi, b) in f.blocks.iter().enumerate() {
            for (ii, i) in b.instructions.iter().enumerate() {
                let uses_var = i
                    .operands
                    .iter()
                    .any(|o| matches!(o, Operand::IdRef(w) if var_ids.contains(w)));
                let uses_chain = i
                    .operands
                    .iter()
                    .any(|o| matches!(o, Operand::IdRef(w) if chains.contains_key(w)));
                match i.class.opcode {
                    Op::AccessChain | Op::InBoundsAccessChain if uses_var => {
                        if i.operands.len() != 2 {
                            return Err(PatchError::Unsupported { patch: NAME, id: i.result_id.unwrap_or(0), what: "an access chain into an AS array with more than one index".into() });
                        }
                        let idx = id_operand(i, 1).expect("index operand");
                        chains.insert(i.result_id.expect("chains have ids"), idx);
                        removed.insert(i.result_id.expect("chains have ids"));
                    }
                    Op::Load if uses_var => sites.push(Site { func: fi, block: bi, inst: ii, index: None }),
                    Op::Load if uses_chain => {
                        let c = id_operand(i, 0).expect("pointer operand");
                        sites.push(Site { func: fi, block: bi, inst: ii, index: Some(chains[&c]) });
                    }
                    _ if uses_var || uses_chain => {
                        return Err(PatchError::Unsupported {
                            patch: NAME,
                            id: i.result_id.unwrap_or(0),
                            what: format!("Op{:?} uses an acceleration-structure descriptor in a way this patch does not rewrite", i.class.opcode),
                        })
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

pub fn apply(m: &mut Module, opts: &Options) -> Result<Report, PatchError> {
    let vars = as_variables(m, opts)?;
    let var_ids: HashSet<Word> = vars.iter().map(|v| v.0).collect();
    let (sites, removed) = load_sites(m, &var_ids)?;
    let any_array = vars.iter().any(|v| v.1);
    let mode = opts.mode.unwrap_or(if any_array { Mode::Table } else { Mode::Direct });
    if mode == Mode::Direct && any_array && sites.iter().any(|s| s.index.is_some()) {
        return Err(PatchError::BadOption {
            patch: NAME,
            what: "mode=direct cannot address the elements of an AS array; use mode=table".into(),
        });
    }

    // Types and the push-constant member.
    let u32_t = edit::type_int(m, 32, false);
    let u64_t = edit::type_int(m, 64, false);
    let (pc_var, member, offset) = push_constant_u64(m, opts.offset, NAME)?;
    let ptr_pc_u64 = edit::type_pointer(m, StorageClass::PushConstant, u64_t);
    let member_c = edit::constant(m, u32_t, member as u64, false);
    let table = if mode == Mode::Table {
        edit::enable_physical_storage_buffer(m);
        Some(edit::TableTypes {
            pc_var,
            member: member_c,
            ptr_pc_u64,
            u64_t,
            ptr_psb_u64: edit::type_pointer(m, StorageClass::PhysicalStorageBuffer, u64_t),
            eight: edit::constant(m, u64_t, 8, true),
        })
    } else {
        None
    };
    let n_sites = sites.len();
    rewrite_loads(m, sites, table.as_ref(), (pc_var, member_c, ptr_pc_u64, u64_t));
    edit::remove_ids(m, &removed);
    Ok(Report { rewritten_loads: n_sites, removed_variables: var_ids.len(), offset, mode })
}

/// Each site's `OpLoad` becomes `OpConvertUToAccelerationStructureKHR` of its address: the table's
/// entry (`table`), else the push-constant member itself (`direct`: the block variable, member
/// constant, pointer type and u64 type). Last site first, so indices stay valid.
fn rewrite_loads(
    m: &mut Module,
    mut sites: Vec<Site>,
    table: Option<&edit::TableTypes>,
    direct: (Word, Word, Word, Word),
) {
    let (pc_var, member_c, ptr_pc_u64, u64_t) = direct;
    sites.sort_by_key(|s| std::cmp::Reverse((s.func, s.block, s.inst)));
    for s in sites {
        let (new, addr) = match table {
            Some(t) => edit::table_entry(m, t, s.index),
            None => {
                let (pm, base) = (edit::next_id(m), edit::next_id(m));
                let new = vec![
                    Instruction::new(
                        Op::AccessChain,
                        Some(ptr_pc_u64),
                        Some(pm),
                        vec![Operand::IdRef(pc_var), Operand::IdRef(member_c)],
                    ),
                    Instruction::new(Op::Load, Some(u64_t), Some(base), vec![Operand::IdRef(pm)]),
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

/// Append a 64-bit member to the module's push-constant block at `offset` (default: the block's
/// end, 8-aligned), creating the block if there is none. Returns (variable, member index, offset).
pub(super) fn push_constant_u64(
    m: &mut Module,
    offset: Option<u32>,
    patch: &'static str,
) -> Result<(Word, u32, u32), PatchError> {
    let u64_t = edit::type_int(m, 64, false);
    let pc_var = m.types_global_values.iter().find(|i| {
        i.class.opcode == Op::Variable
            && i.operands.first() == Some(&Operand::StorageClass(StorageClass::PushConstant))
    });
    match pc_var.and_then(|v| Some((v.result_id?, v.result_type?))) {
        Some((var, ptr)) => append_member(m, (var, ptr), u64_t, offset, patch),
        None => new_block(m, u64_t, offset.unwrap_or(0), patch),
    }
}

/// Append a `u64_t` member to the block of the push-constant variable `var` (of pointer type
/// `ptr`) at `offset`, which must lie past the block's end (default: the end, 8-aligned).
fn append_member(
    m: &mut Module,
    (var, ptr): (Word, Word),
    u64_t: Word,
    offset: Option<u32>,
    patch: &'static str,
) -> Result<(Word, u32, u32), PatchError> {
    let (_, st) = edit::pointer_info(m, ptr).ok_or(PatchError::Unsupported {
        patch,
        id: var,
        what: "push-constant variable without pointer type".into(),
    })?;
    let st_def = edit::def(m, st).cloned().ok_or(PatchError::Unsupported {
        patch,
        id: st,
        what: "push-constant block type not found".into(),
    })?;
    let members = st_def.operands.iter().filter(|o| matches!(o, Operand::IdRef(_))).count();
    // Sized from its Offset / ArrayStride / MatrixStride decorations; a block without them is not
    // a valid Vulkan push-constant block.
    let end = edit::explicit_extent(m, st, None).ok_or(PatchError::Unsupported {
        patch,
        id: st,
        what: "the push-constant block lacks the Offset / ArrayStride / MatrixStride decorations that give its size".into(),
    })?;
    let offset = match offset {
        Some(o) if o < end => {
            return Err(PatchError::BadOption {
                patch,
                what: format!("offset={o} overlaps the push-constant block, which ends at {end}"),
            })
        }
        Some(o) => o,
        None => end.div_ceil(8) * 8,
    };
    check_aligned(offset, patch)?;
    let k = members as u32;
    if let Some(s) = m.types_global_values.iter_mut().find(|i| i.result_id == Some(st)) {
        s.operands.push(Operand::IdRef(u64_t));
    }
    m.annotations.push(member_offset(st, k, offset));
    Ok((var, k, offset))
}

/// A new push-constant block of one `u64_t` member at `offset`, and its variable.
fn new_block(
    m: &mut Module,
    u64_t: Word,
    offset: u32,
    patch: &'static str,
) -> Result<(Word, u32, u32), PatchError> {
    check_aligned(offset, patch)?;
    let st = edit::next_id(m);
    m.types_global_values.push(Instruction::new(
        Op::TypeStruct,
        None,
        Some(st),
        vec![Operand::IdRef(u64_t)],
    ));
    edit::decorate(m, st, Decoration::Block, &[]);
    m.annotations.push(member_offset(st, 0, offset));
    let ptr = edit::type_pointer(m, StorageClass::PushConstant, st);
    let var = edit::next_id(m);
    m.types_global_values.push(Instruction::new(
        Op::Variable,
        Some(ptr),
        Some(var),
        vec![Operand::StorageClass(StorageClass::PushConstant)],
    ));
    edit::add_to_interfaces(m, var);
    Ok((var, 0, offset))
}

/// A 64-bit member's offset must be 8-byte aligned.
fn check_aligned(offset: u32, patch: &'static str) -> Result<(), PatchError> {
    if offset % 8 != 0 {
        return Err(PatchError::BadOption {
            patch,
            what: format!("offset={offset} is not 8-byte aligned"),
        });
    }
    Ok(())
}

/// `OpMemberDecorate %st member Offset offset`.
fn member_offset(st: Word, member: u32, offset: u32) -> Instruction {
    Instruction::new(
        Op::MemberDecorate,
        None,
        None,
        vec![
            Operand::IdRef(st),
            Operand::LiteralBit32(member),
            Operand::Decoration(Decoration::Offset),
            Operand::LiteralBit32(offset),
        ],
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    fn module(glsl: &str) -> Module {
        let mut c = crate::shadergen::compile::Compiler::new().expect("shaderc");
        let words =
            c.compile_glsl(shaderc::ShaderKind::RayGeneration, "t.rgen", glsl).expect("compiles");
        let bytes: Vec<u8> = words.iter().flat_map(|w| w.to_le_bytes()).collect();
        crate::patches::load(&bytes).expect("loads")
    }

    const CAMERA: &str = include_str!("../../tests/shaders/engine_camera.rgen");

    #[test]
    fn push_blocks_with_matrices_arrays_and_small_types_are_sized_from_their_decorations() {
        // engine_camera.rgen (std430): mat4 0..64; row-major mat3x4 = 4 rows of 3 floats, stride
        // 16: 64..124; vec3 128..140; u16 140..142; u64 144..152; Light[2] at 160, stride 16,
        // Light 15 bytes: 160..191; u8 frame 192..193 -> first free 8-aligned offset 200.
        let mut m = module(CAMERA);
        let r = apply(&mut m, &Options::default()).expect("sized without --option offset");
        assert_eq!(r.offset, 200);
        let v = crate::patches::validate(&crate::patches::assemble(&m));
        assert_eq!(v, crate::patches::Validation::Valid);
        // an offset inside the block is refused, one past it accepted
        let err = apply(&mut module(CAMERA), &Options { offset: Some(192), ..Default::default() })
            .unwrap_err();
        assert!(err.to_string().contains("overlaps") && err.to_string().contains("193"), "{err}");
        assert_eq!(
            apply(&mut module(CAMERA), &Options { offset: Some(200), ..Default::default() })
                .unwrap()
                .offset,
            200
        );
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
        assert_eq!(edit::explicit_extent(&m, st, None), Some(65));
        assert_eq!(apply(&mut m, &Options::default()).unwrap().offset, 72);
    }
}
