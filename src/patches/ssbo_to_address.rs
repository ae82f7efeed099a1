//! `ssbo-to-address`: a dynamically indexed storage-buffer descriptor array becomes loads through
//! `PhysicalStorageBuffer` pointers taken from an address table, so the descriptor selection
//! disappears and only a memory load is dynamic. Each array (set, binding) reads its own table,
//! whose address is its own push-constant member ([`super::push::Slots`]): three arrays never
//! share one table.
//!
//! Handled shape (and only this one; anything else is refused, naming the instruction): a
//! `StorageBuffer` variable that is an array of a `Block` struct, reached by
//! `OpAccessChain %var %index [%member...]` and then read: loads through that chain, and through
//! further access chains and copies of it (glslang chains to the member at once; DXC and Slang
//! often chain to the element first, then to its members). Stores, atomics, `OpArrayLength`,
//! function calls and every other use are refused.
//!
//! SPIR-V rules relied on:
//! - The table's address is a 64-bit push-constant member ([`super::push`]); element `index` of
//!   the table is the element buffer's device address.
//! - `OpConvertUToPtr` to a `PhysicalStorageBuffer` pointer to the same `Block` struct (with its
//!   explicit `Offset`s and `ArrayStride`s) is a valid pointer to the buffer's contents; access
//!   chains and copies of it keep the `PhysicalStorageBuffer` storage class, so their result types
//!   are re-pointed to `PhysicalStorageBuffer` pointers of the same pointee.
//! - Every load through a `PhysicalStorageBuffer` pointer needs an `Aligned` memory operand: the
//!   loaded type's scalar alignment ([`super::layout::scalar_alignment`]) holds for any block
//!   layout, since every layout aligns at least to it.
//! - The module needs `PhysicalStorageBuffer64` addressing and `PhysicalStorageBufferAddresses`.
use super::edit::{self, id_operand};
use super::layout::{self, Rules};
use super::push::{self, SlotKey, SlotKind, Slots};
use super::PatchError;
use rspirv::dr::{Instruction, Module, Operand};
use rspirv::spirv::{Decoration, Op, StorageClass, Word};
use std::collections::{BTreeMap, HashMap, HashSet};

#[derive(Clone, Debug, Default)]
pub struct Options {
    /// Only SSBO arrays of this descriptor set (default: every set).
    pub set: Option<u32>,
    /// Only the SSBO array at this binding (default: every SSBO array).
    pub binding: Option<u32>,
}

/// One array's table: where its address is and how many entries it needs.
#[derive(Clone, Debug, PartialEq)]
pub struct Entry {
    pub set: u32,
    pub binding: u32,
    pub offset: u32,
    /// The array's length (None: a runtime array).
    pub elements: Option<u32>,
}

#[derive(Clone, Debug, PartialEq)]
pub struct Report {
    pub rewritten_loads: usize,
    pub entries: Vec<Entry>,
}

const NAME: &str = "ssbo-to-address";

/// A storage-buffer descriptor array.
struct Var {
    block: Word,
    set: u32,
    binding: u32,
    elements: Option<u32>,
}

/// The storage-buffer descriptor arrays `opts` selects.
fn ssbo_arrays(m: &Module, opts: &Options) -> Result<BTreeMap<Word, Var>, PatchError> {
    let mut vars = BTreeMap::new();
    let mut old_style = false;
    for v in m.types_global_values.iter().filter(|i| i.class.opcode == Op::Variable) {
        let (Some(id), Some(ptr)) = (v.result_id, v.result_type) else {
            continue;
        };
        let Some((sc, pointee)) = edit::pointer_info(m, ptr) else {
            continue;
        };
        let Some(arr) = edit::def(m, pointee) else {
            continue;
        };
        let elements = match arr.class.opcode {
            Op::TypeArray => edit::array_length(m, arr),
            Op::TypeRuntimeArray => None,
            _ => continue,
        };
        let Some(block) = id_operand(arr, 0) else {
            continue;
        };
        old_style |=
            sc == StorageClass::Uniform && edit::has_decoration(m, block, Decoration::BufferBlock);
        if sc != StorageClass::StorageBuffer || !edit::has_decoration(m, block, Decoration::Block) {
            continue;
        }
        let set = edit::decoration_literal(m, id, Decoration::DescriptorSet).unwrap_or(0);
        let binding = edit::decoration_literal(m, id, Decoration::Binding).unwrap_or(0);
        if opts.set.is_some_and(|s| s != set) || opts.binding.is_some_and(|b| b != binding) {
            continue;
        }
        vars.insert(id, Var { block, set, binding, elements });
    }
    if vars.is_empty() {
        let what = if old_style {
            "no storage-buffer descriptor array in StorageBuffer storage (the Uniform + BufferBlock \
             arrays of SPIR-V 1.0-1.3 are not rewritten: compile for SPIR-V 1.4 or later)"
        } else {
            "no storage-buffer descriptor array"
        };
        return Err(PatchError::NothingToPatch { patch: NAME, what: what.into() });
    }
    Ok(vars)
}

/// Where an instruction is: (function, block, instruction).
type At = (usize, usize, usize);

/// The reads of the SSBO arrays.
#[derive(Default)]
struct Reads {
    /// Access chains on an array variable: where, var, index.
    roots: Vec<(At, Word, Word)>,
    /// Pointers derived from a root (chains on them, copies), to re-point to PhysicalStorageBuffer.
    derived: Vec<At>,
    /// Loads through any of them.
    loads: Vec<At>,
    /// The roots' result ids.
    root_ids: HashSet<Word>,
}

/// Collect the chains into `vars`, the pointers derived from them and their loads; refuse every
/// other use. One forward pass: blocks come in dominance order, so a pointer's definition is
/// seen before its uses.
fn reads(m: &Module, vars: &BTreeMap<Word, Var>) -> Result<Reads, PatchError> {
    let mut r = Reads::default();
    let mut pointers: HashSet<Word> = HashSet::new();
    for (fi, f) in m.functions.iter().enumerate() {
        for (bi, b) in f.blocks.iter().enumerate() {
            for (ii, i) in b.instructions.iter().enumerate() {
                let at = (fi, bi, ii);
                let ids: Vec<Word> = i.operands.iter().filter_map(edit::id_from).collect();
                let uses_var = ids.iter().any(|w| vars.contains_key(w));
                let uses_ptr = ids.iter().any(|w| pointers.contains(w));
                let refuse = |what: String| PatchError::Unsupported {
                    patch: NAME,
                    id: i.result_id.unwrap_or(0),
                    what,
                };
                let chain = matches!(i.class.opcode, Op::AccessChain | Op::InBoundsAccessChain);
                let base = id_operand(i, 0);
                match i.class.opcode {
                    _ if chain && uses_var => {
                        let var = base.filter(|b| vars.contains_key(b)).ok_or_else(|| {
                            refuse("an SSBO array used as an access-chain index".into())
                        })?;
                        let id = i.result_id.expect("chains have ids");
                        r.roots.push((at, var, id_operand(i, 1).expect("index")));
                        r.root_ids.insert(id);
                        pointers.insert(id);
                    }
                    _ if uses_var => {
                        return Err(refuse(format!(
                            "Op{:?} uses a storage-buffer array directly",
                            i.class.opcode
                        )))
                    }
                    _ if (chain || i.class.opcode == Op::CopyObject)
                        && base.is_some_and(|b| pointers.contains(&b)) =>
                    {
                        r.derived.push(at);
                        pointers.insert(i.result_id.expect("chains have ids"));
                    }
                    Op::Load if base.is_some_and(|b| pointers.contains(&b)) => r.loads.push(at),
                    _ if uses_ptr => {
                        return Err(refuse(format!(
                            "Op{:?} on an SSBO element (only loads are rewritten)",
                            i.class.opcode
                        )))
                    }
                    _ => {}
                }
            }
        }
    }
    if r.roots.is_empty() {
        return Err(PatchError::NothingToPatch {
            patch: NAME,
            what: "the storage-buffer arrays are never read".into(),
        });
    }
    Ok(r)
}

/// Rewrite every SSBO array `opts` selects: each reads its own table, at the offset `slots`
/// gives its descriptor, placed in the push block under `rules`.
pub fn apply(
    m: &mut Module,
    opts: &Options,
    slots: &mut Slots,
    rules: Rules,
) -> Result<Report, PatchError> {
    let vars = ssbo_arrays(m, opts)?;
    let r = reads(m, &vars)?;
    // Only the arrays actually read get a table.
    let read: Vec<Word> =
        vars.keys().copied().filter(|v| r.roots.iter().any(|x| x.1 == *v)).collect();
    let mut entries = Vec::new();
    for v in &read {
        let var = &vars[v];
        let key = SlotKey { kind: SlotKind::BufferTable, set: var.set, binding: var.binding };
        let offset = slots.offset(key, NAME)?;
        entries.push((
            *v,
            Entry { set: var.set, binding: var.binding, offset, elements: var.elements },
        ));
    }
    entries.sort_by_key(|e| e.1.offset);
    let mut tables: HashMap<Word, edit::TableTypes> = HashMap::new();
    for (v, e) in &entries {
        let (pc_var, member) = push::u64_member(m, e.offset, rules, NAME)?;
        tables.insert(*v, edit::TableTypes::new(m, pc_var, member));
    }
    for at in &r.loads {
        let ty = instruction(m, *at).result_type.expect("loads are typed");
        let align = layout::scalar_alignment(m, ty).unwrap_or(1).max(1);
        edit::set_aligned(instruction_mut(m, *at), 1, align);
    }
    for at in &r.derived {
        repoint(m, *at)?;
    }
    rewrite_roots(m, &r.roots, &vars, &tables)?;
    // NonUniform on the chains is meaningless now (no descriptor); drop it there.
    m.annotations.retain(|a| {
        !(a.class.opcode == Op::Decorate
            && id_operand(a, 0).is_some_and(|t| r.root_ids.contains(&t))
            && matches!(a.operands.get(1), Some(Operand::Decoration(Decoration::NonUniform))))
    });
    let removed: HashSet<Word> = read.iter().copied().collect();
    edit::remove_ids(m, &removed);
    Ok(Report {
        rewritten_loads: r.loads.len(),
        entries: entries.into_iter().map(|e| e.1).collect(),
    })
}

fn instruction(m: &Module, (f, b, i): At) -> &Instruction {
    &m.functions[f].blocks[b].instructions[i]
}

fn instruction_mut(m: &mut Module, (f, b, i): At) -> &mut Instruction {
    &mut m.functions[f].blocks[b].instructions[i]
}

/// The `PhysicalStorageBuffer` pointer type to what the pointer type `ty` points to.
fn psb_pointer(m: &mut Module, ty: Word, id: Word) -> Result<Word, PatchError> {
    let (_, pointee) = edit::pointer_info(m, ty).ok_or(PatchError::Unsupported {
        patch: NAME,
        id,
        what: "a pointer without pointer type".into(),
    })?;
    Ok(edit::type_pointer(m, StorageClass::PhysicalStorageBuffer, pointee))
}

/// A pointer derived from a rewritten chain becomes a `PhysicalStorageBuffer` pointer.
fn repoint(m: &mut Module, at: At) -> Result<(), PatchError> {
    let i = instruction(m, at);
    let (ty, id) = (i.result_type.expect("typed"), i.result_id.unwrap_or(0));
    let psb = psb_pointer(m, ty, id)?;
    instruction_mut(m, at).result_type = Some(psb);
    Ok(())
}

/// Each root chain starts from the element buffer's address (`OpConvertUToPtr` of its table
/// entry) and yields a `PhysicalStorageBuffer` pointer of the same pointee (a copy of the block
/// pointer when it had no member index); last chain first, so positions stay valid.
fn rewrite_roots(
    m: &mut Module,
    roots: &[(At, Word, Word)],
    vars: &BTreeMap<Word, Var>,
    tables: &HashMap<Word, edit::TableTypes>,
) -> Result<(), PatchError> {
    let mut order: Vec<&(At, Word, Word)> = roots.iter().collect();
    order.sort_by_key(|r| std::cmp::Reverse(r.0));
    for &&(at, var, index) in &order {
        let (ty, id) = {
            let i = instruction(m, at);
            (i.result_type.expect("typed"), i.result_id.expect("chains have ids"))
        };
        let psb = psb_pointer(m, ty, id)?;
        let block_ptr =
            edit::type_pointer(m, StorageClass::PhysicalStorageBuffer, vars[&var].block);
        let (mut new, addr) = edit::table_entry(m, &tables[&var], Some(index));
        let blk = edit::next_id(m);
        new.push(Instruction::new(
            Op::ConvertUToPtr,
            Some(block_ptr),
            Some(blk),
            vec![Operand::IdRef(addr)],
        ));
        let ch = instruction_mut(m, at);
        let rest: Vec<Operand> = ch.operands[2..].to_vec();
        *ch = if rest.is_empty() {
            Instruction::new(Op::CopyObject, Some(psb), Some(id), vec![Operand::IdRef(blk)])
        } else {
            let ops = std::iter::once(Operand::IdRef(blk)).chain(rest).collect();
            Instruction::new(ch.class.opcode, Some(psb), Some(id), ops)
        };
        let block = &mut m.functions[at.0].blocks[at.1];
        for (k, i) in new.into_iter().enumerate() {
            block.instructions.insert(at.2 + k, i);
        }
    }
    Ok(())
}
