//! `ssbo-to-address`: a dynamically indexed storage-buffer descriptor array becomes loads through
//! `PhysicalStorageBuffer` pointers taken from an address table, so the descriptor selection
//! disappears and only a memory load is dynamic.
//!
//! Handled shape (and only this one; anything else is refused, naming the instruction):
//! a `StorageBuffer` variable that is an array of a `Block` struct, read as
//! `OpLoad (OpAccessChain %var %index %member...)` — reads only. Stores, atomics,
//! `OpArrayLength`, copies of the pointer and access chains without a member index are refused.
//!
//! SPIR-V rules relied on:
//! - The table's address is a 64-bit member appended to the push-constant block (as in
//!   `as-to-address`); element `index` of the table is the buffer's device address.
//! - `OpConvertUToPtr` to a `PhysicalStorageBuffer` pointer to the same `Block` struct (with its
//!   explicit `Offset`s and `ArrayStride`s) is a valid pointer to the buffer's contents; access
//!   chains through it keep the `PhysicalStorageBuffer` storage class, so their result types are
//!   re-pointed to `PhysicalStorageBuffer` pointers of the same pointee.
//! - A load through a `PhysicalStorageBuffer` pointer needs an `Aligned` memory operand; 4 is a
//!   correct (conservative) alignment for every 32-bit-component type.
//! - The module needs `PhysicalStorageBuffer64` addressing and `PhysicalStorageBufferAddresses`.
use super::edit::{self, id_operand};
use super::PatchError;
use rspirv::dr::{Instruction, Module, Operand};
use rspirv::spirv::{Decoration, MemoryAccess, Op, StorageClass, Word};
use std::collections::{HashMap, HashSet};

#[derive(Clone, Debug, Default)]
pub struct Options {
    /// Byte offset of the table address in the push-constant block (default: its end, 8-aligned).
    pub offset: Option<u32>,
    /// Only the SSBO array at this binding (default: every SSBO array).
    pub binding: Option<u32>,
}

#[derive(Clone, Debug, PartialEq)]
pub struct Report {
    pub rewritten_loads: usize,
    pub offset: u32,
}

const NAME: &str = "ssbo-to-address";

/// The storage-buffer descriptor arrays `opts` selects: variable -> its `Block` struct.
fn ssbo_arrays(m: &Module, opts: &Options) -> Result<HashMap<Word, Word>, PatchError> {
    let mut vars: HashMap<Word, Word> = HashMap::new();
    for v in m.types_global_values.iter().filter(|i| i.class.opcode == Op::Variable) {
        let (Some(id), Some(ptr)) = (v.result_id, v.result_type) else {
            continue;
        };
        let Some((StorageClass::StorageBuffer, pointee)) = edit::pointer_info(m, ptr) else {
            continue;
        };
        let Some(arr) = edit::def(m, pointee) else {
            continue;
        };
        if !matches!(arr.class.opcode, Op::TypeArray | Op::TypeRuntimeArray) {
            continue;
        }
        let Some(block) = id_operand(arr, 0) else {
            continue;
        };
        if !edit::has_decoration(m, block, Decoration::Block) {
            continue;
        }
        if opts
            .binding
            .is_some_and(|b| edit::decoration_literal(m, id, Decoration::Binding) != Some(b))
        {
            continue;
        }
        vars.insert(id, block);
    }
    if vars.is_empty() {
        return Err(PatchError::NothingToPatch {
            patch: NAME,
            what: "no storage-buffer descriptor array".into(),
        });
    }
    Ok(vars)
}

/// An access chain into an SSBO array (at function `func`, block `block`, instruction `inst`).
struct Chain {
    func: usize,
    block: usize,
    inst: usize,
    id: Word,
    var: Word,
    index: Word,
}

/// The SSBO arrays' reads: the access chains into `vars`, their ids, and the loads through them
/// (function, block, instruction); other shapes are refused.
type Reads = (Vec<Chain>, HashSet<Word>, Vec<(usize, usize, usize)>);

/// Collect chains into the vars and their loads; refuse other shapes.
fn reads(m: &Module, vars: &HashMap<Word, Word>) -> Result<Reads, PatchError> {
    let mut chains: Vec<Chain> = Vec::new();
    let mut chain_ids: HashSet<Word> = HashSet::new();
    let mut loads: Vec<(usize, usize, usize)> = Vec::new();
    for (fi, f) in m.functions.iter().enumerate() {
        for (bi, b) in f.blocks.iter().enumerate() {
            for (ii, i) in b.instructions.iter().enumerate() {
                let uses_var = i
                    .operands
                    .iter()
                    .any(|o| matches!(o, Operand::IdRef(w) if vars.contains_key(w)));
                let uses_chain = i
                    .operands
                    .iter()
                    .any(|o| matches!(o, Operand::IdRef(w) if chain_ids.contains(w)));
                let refuse = |what: &str| PatchError::Unsupported {
                    patch: NAME,
                    id: i.result_id.unwrap_or(0),
                    what: what.into(),
                };
                match i.class.opcode {
                    Op::AccessChain | Op::InBoundsAccessChain if uses_var => {
                        if id_operand(i, 0).is_none_or(|b| !vars.contains_key(&b)) {
                            return Err(refuse("an SSBO array used as an access-chain index"));
                        }
                        if i.operands.len() < 3 {
                            return Err(refuse(
                                "an access chain to a whole buffer block (no member index)",
                            ));
                        }
                        let id = i.result_id.expect("chains have ids");
                        chain_ids.insert(id);
                        chains.push(Chain {
                            func: fi,
                            block: bi,
                            inst: ii,
                            id,
                            var: id_operand(i, 0).expect("base"),
                            index: id_operand(i, 1).expect("index"),
                        });
                    }
                    Op::Load if uses_chain => loads.push((fi, bi, ii)),
                    _ if uses_var => {
                        return Err(refuse(&format!(
                            "Op{:?} uses a storage-buffer array directly",
                            i.class.opcode
                        )))
                    }
                    _ if uses_chain => {
                        return Err(refuse(&format!(
                            "Op{:?} on an SSBO element (only loads are rewritten)",
                            i.class.opcode
                        )))
                    }
                    _ => {}
                }
            }
        }
    }
    if chains.is_empty() {
        return Err(PatchError::NothingToPatch {
            patch: NAME,
            what: "the storage-buffer arrays are never read".into(),
        });
    }
    Ok((chains, chain_ids, loads))
}

/// The address table's types, its address a new push-constant member; with the member's offset.
fn address_table(m: &mut Module, opts: &Options) -> Result<(edit::TableTypes, u32), PatchError> {
    let (pc_var, member, offset) = super::as_to_address::push_constant_u64(m, opts.offset, NAME)?;
    let u32_t = edit::type_int(m, 32, false);
    let u64_t = edit::type_int(m, 64, false);
    edit::enable_physical_storage_buffer(m);
    let table = edit::TableTypes {
        pc_var,
        member: edit::constant(m, u32_t, member as u64, false),
        ptr_pc_u64: edit::type_pointer(m, StorageClass::PushConstant, u64_t),
        u64_t,
        ptr_psb_u64: edit::type_pointer(m, StorageClass::PhysicalStorageBuffer, u64_t),
        eight: edit::constant(m, u64_t, 8, true),
    };
    Ok((table, offset))
}

pub fn apply(m: &mut Module, opts: &Options) -> Result<Report, PatchError> {
    let vars = ssbo_arrays(m, opts)?;
    let (chains, chain_ids, loads) = reads(m, &vars)?;
    let (table, offset) = address_table(m, opts)?;
    // Loads through rewritten chains need an Aligned operand.
    for (fi, bi, ii) in &loads {
        let l = &mut m.functions[*fi].blocks[*bi].instructions[*ii];
        l.operands.truncate(1);
        l.operands.push(Operand::MemoryAccess(MemoryAccess::ALIGNED));
        l.operands.push(Operand::LiteralBit32(4));
    }
    rewrite_chains(m, &chains, &vars, &table)?;
    // NonUniform on the chains is meaningless now (no descriptor); drop it there.
    m.annotations.retain(|a| {
        !(a.class.opcode == Op::Decorate
            && id_operand(a, 0).is_some_and(|t| chain_ids.contains(&t))
            && matches!(a.operands.get(1), Some(Operand::Decoration(Decoration::NonUniform))))
    });
    let removed: HashSet<Word> = vars.keys().copied().collect();
    edit::remove_ids(m, &removed);
    Ok(Report { rewritten_loads: loads.len(), offset })
}

/// Each chain starts from the buffer's address (`OpConvertUToPtr` of its table entry) and yields
/// a `PhysicalStorageBuffer` pointer of the same pointee; last chain first.
fn rewrite_chains(
    m: &mut Module,
    chains: &[Chain],
    vars: &HashMap<Word, Word>,
    table: &edit::TableTypes,
) -> Result<(), PatchError> {
    // Re-point every chain's result type to PhysicalStorageBuffer.
    let mut psb_of: HashMap<Word, Word> = HashMap::new();
    for c in chains {
        let ty =
            m.functions[c.func].blocks[c.block].instructions[c.inst].result_type.expect("typed");
        let (_, pointee) = edit::pointer_info(m, ty).ok_or(PatchError::Unsupported {
            patch: NAME,
            id: c.id,
            what: "chain without pointer type".into(),
        })?;
        let psb = edit::type_pointer(m, StorageClass::PhysicalStorageBuffer, pointee);
        psb_of.insert(c.id, psb);
    }
    let block_ptrs: HashMap<Word, Word> = vars
        .iter()
        .map(|(v, blk)| (*v, edit::type_pointer(m, StorageClass::PhysicalStorageBuffer, *blk)))
        .collect();
    let mut order: Vec<&Chain> = chains.iter().collect();
    order.sort_by_key(|c| std::cmp::Reverse((c.func, c.block, c.inst)));
    for c in order {
        let (mut new, addr) = edit::table_entry(m, table, Some(c.index));
        let blk = edit::next_id(m);
        new.push(Instruction::new(
            Op::ConvertUToPtr,
            Some(block_ptrs[&c.var]),
            Some(blk),
            vec![Operand::IdRef(addr)],
        ));
        let block = &mut m.functions[c.func].blocks[c.block];
        let ch = &mut block.instructions[c.inst];
        let rest: Vec<Operand> = ch.operands[2..].to_vec();
        *ch = Instruction::new(
            ch.class.opcode,
            Some(psb_of[&c.id]),
            Some(c.id),
            std::iter::once(Operand::IdRef(blk)).chain(rest).collect(),
        );
        for (k, i) in new.into_iter().enumerate() {
            block.instructions.insert(c.inst + k, i);
        }
    }
    Ok(())
}
