//! The instructions of an injected fault, placed right after a descriptor access and fed by its
//! value: the first scalar of the value as 32 bits ([`bits`]), then either a volatile load
//! through an invalid `PhysicalStorageBuffer` address plus `bits & 0` ([`device`]) or a loop
//! counting by two from 0 until it equals `bits | 1`, an odd number it never reaches ([`hang`]).
//! Each fault's last instruction is named `rtprobe_injected_*` ([`MARKER`]) so it can be
//! counted after a patch rewrote the module.
use crate::patches::edit::{self, id_operand, next_id};
use rspirv::dr::{Block, Instruction, Module, Operand};
use rspirv::spirv::{LoopControl, MemoryAccess, Op, StorageClass, Word};

/// The prefix of the `OpName` each injected fault carries.
pub const MARKER: &str = "rtprobe_injected_";

/// The address the device fault reads at: the one the matrix's invalid-address canary uses
/// (`exec::CANARY_BAD_ADDRESS`), in no allocation of any driver's.
pub const BAD_ADDRESS: u64 = 0xdead_0000_0000;

fn op(o: Op, ty: Option<Word>, id: Word, operands: Vec<Operand>) -> Instruction {
    Instruction::new(o, ty, Some(id), operands)
}

/// `OpTypeBool`, found or appended.
fn type_bool(m: &mut Module) -> Word {
    if let Some(id) = m
        .types_global_values
        .iter()
        .find(|i| i.class.opcode == Op::TypeBool)
        .and_then(|i| i.result_id)
    {
        return id;
    }
    let id = next_id(m);
    m.types_global_values.push(op(Op::TypeBool, None, id, vec![]));
    id
}

/// Instructions computing 32 bits of `value`'s first scalar (its first component, member or
/// element, recursively), and their id; `None` for a value of no such type.
pub fn bits(m: &mut Module, value: Word) -> Option<(Vec<Instruction>, Word)> {
    let u32_t = edit::type_int(m, 32, false);
    let mut ty = edit::def(m, value)?.result_type?;
    let (mut v, mut out) = (value, Vec::new());
    for _ in 0..32 {
        let d = edit::def(m, ty)?.clone();
        let id = next_id(m);
        let conv = |o: Op, operands: Vec<Operand>| Some((o, operands));
        let step = match d.class.opcode {
            Op::TypeVector | Op::TypeMatrix | Op::TypeArray | Op::TypeStruct => {
                let elem = id_operand(&d, 0)?;
                out.push(op(
                    Op::CompositeExtract,
                    Some(elem),
                    id,
                    vec![Operand::IdRef(v), Operand::LiteralBit32(0)],
                ));
                (v, ty) = (id, elem);
                continue;
            }
            Op::TypeInt if d.operands.first() == Some(&Operand::LiteralBit32(32)) => {
                return Some((out, v))
            }
            Op::TypeInt => conv(Op::UConvert, vec![Operand::IdRef(v)]),
            Op::TypeFloat if d.operands.first() == Some(&Operand::LiteralBit32(32)) => {
                conv(Op::Bitcast, vec![Operand::IdRef(v)])
            }
            Op::TypeFloat => conv(Op::ConvertFToU, vec![Operand::IdRef(v)]),
            Op::TypeBool => {
                let (one, zero) =
                    (edit::constant(m, u32_t, 1, false), edit::constant(m, u32_t, 0, false));
                conv(Op::Select, vec![Operand::IdRef(v), Operand::IdRef(one), Operand::IdRef(zero)])
            }
            Op::TypePointer => {
                let u64_t = edit::type_int(m, 64, false);
                let wide = next_id(m);
                out.push(op(Op::ConvertPtrToU, Some(u64_t), wide, vec![Operand::IdRef(v)]));
                conv(Op::UConvert, vec![Operand::IdRef(wide)])
            }
            _ => None,
        };
        let (o, operands) = step?;
        out.push(op(o, Some(u32_t), id, operands));
        return Some((out, id));
    }
    None
}

/// The device fault after `bits`' instructions: returns them all (to insert after the access).
pub fn device(m: &mut Module, mut code: Vec<Instruction>, bits: Word) -> Vec<Instruction> {
    let u32_t = edit::type_int(m, 32, false);
    let u64_t = edit::type_int(m, 64, false);
    edit::enable_physical_storage_buffer(m);
    let zero_c = edit::constant(m, u32_t, 0, false);
    let bad = edit::constant(m, u64_t, BAD_ADDRESS, true);
    let ptr = edit::type_pointer(m, StorageClass::PhysicalStorageBuffer, u32_t);
    let (zero, wide, addr, p, loaded) =
        (next_id(m), next_id(m), next_id(m), next_id(m), next_id(m));
    let id = Operand::IdRef;
    code.extend([
        op(Op::BitwiseAnd, Some(u32_t), zero, vec![id(bits), id(zero_c)]),
        op(Op::UConvert, Some(u64_t), wide, vec![id(zero)]),
        op(Op::IAdd, Some(u64_t), addr, vec![id(wide), id(bad)]),
        op(Op::ConvertUToPtr, Some(ptr), p, vec![id(addr)]),
        op(
            Op::Load,
            Some(u32_t),
            loaded,
            vec![
                id(p),
                Operand::MemoryAccess(MemoryAccess::VOLATILE | MemoryAccess::ALIGNED),
                Operand::LiteralBit32(4),
            ],
        ),
    ]);
    name(m, loaded, "device");
    code
}

fn name(m: &mut Module, id: Word, kind: &str) {
    m.debug_names.push(Instruction::new(
        Op::Name,
        None,
        None,
        vec![Operand::IdRef(id), Operand::LiteralString(format!("{MARKER}{kind}"))],
    ));
}

/// The endless loop after instruction `at` of function `f`: block `at.0` is split after the
/// access (and `code`), the rest moving to the loop's merge block. `false` (nothing changed)
/// when that block is a loop header: its back edges must keep reaching its `OpLoopMerge`.
pub fn hang(
    m: &mut Module,
    f: usize,
    (b, i): (usize, usize),
    mut code: Vec<Instruction>,
    bits: Word,
) -> bool {
    let block = &m.functions[f].blocks[b];
    if block.instructions.iter().any(|x| x.class.opcode == Op::LoopMerge) {
        return false;
    }
    let Some(from) = block.label_id() else { return false };
    let u32_t = edit::type_int(m, 32, false);
    let bool_t = type_bool(m);
    let (c0, c1, c2) = (
        edit::constant(m, u32_t, 0, false),
        edit::constant(m, u32_t, 1, false),
        edit::constant(m, u32_t, 2, false),
    );
    let (odd, h, c, merge, count, next, done) =
        (next_id(m), next_id(m), next_id(m), next_id(m), next_id(m), next_id(m), next_id(m));
    let id = Operand::IdRef;
    let label = |l| Some(Instruction::new(Op::Label, None, Some(l), vec![]));
    let branch = |to| Instruction::new(Op::Branch, None, None, vec![id(to)]);
    code.push(op(Op::BitwiseOr, Some(u32_t), odd, vec![id(bits), id(c1)]));
    code.push(branch(h));
    let header = Block {
        label: label(h),
        instructions: vec![
            op(Op::Phi, Some(u32_t), count, vec![id(c0), id(from), id(next), id(c)]),
            op(Op::IAdd, Some(u32_t), next, vec![id(count), id(c2)]),
            op(Op::IEqual, Some(bool_t), done, vec![id(next), id(odd)]),
            Instruction::new(
                Op::LoopMerge,
                None,
                None,
                vec![id(merge), id(c), Operand::LoopControl(LoopControl::NONE)],
            ),
            Instruction::new(Op::BranchConditional, None, None, vec![id(done), id(merge), id(c)]),
        ],
    };
    let cont = Block { label: label(c), instructions: vec![branch(h)] };
    name(m, done, "hang");
    let func = &mut m.functions[f];
    let tail = func.blocks[b].instructions.split_off(i + 1);
    func.blocks[b].instructions.extend(code);
    // The rest's successors now come from the merge block.
    for x in func.blocks.iter_mut().flat_map(|bl| bl.instructions.iter_mut()) {
        if x.class.opcode == Op::Phi {
            for o in x.operands.iter_mut().skip(1).step_by(2) {
                if *o == id(from) {
                    *o = id(merge);
                }
            }
        }
    }
    let rest = Block { label: label(merge), instructions: tail };
    func.blocks.splice(b + 1..b + 1, [header, cont, rest]);
    true
}
