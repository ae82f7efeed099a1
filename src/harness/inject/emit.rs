//! The instructions of an injected fault, placed right after a descriptor access and fed by its
//! value: the first scalar of the value as 32 bits ([`bits`]), then either a volatile load
//! through an invalid `PhysicalStorageBuffer` address plus `bits & 0` ([`device`]) or a loop
//! counting by two from 0 until it equals `bits | 1`, an odd number it never reaches ([`hang`]);
//! the fault's result then feeds the access's value in all its uses (`feed`: its first scalar, and
//! every component when that scalar is a vector's). An acceleration structure's handle has no
//! bits: its fault takes the constant 0 and feeds the cull mask of each ray the handle traces
//! ([`Tie::Handle`], `super::handle`).
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

/// The first scalar of an access's value: how it was reached, and 32 bits of it.
pub struct Leaf {
    /// The extractions, then the conversion to 32 bits.
    pub code: Vec<Instruction>,
    pub bits: Word,
    /// The access's value and each composite on the way down, with its type.
    path: Vec<(Word, Word)>,
    leaf: Word,
    leaf_ty: Word,
}

/// What a fault is fed by and feeds: an access's value (`value`, and 32 bits of its first
/// scalar), or an acceleration structure handle (the constant 0 in, its rays' cull masks out).
pub enum Tie {
    Value(Word, Leaf),
    Handle(Word),
}

impl Tie {
    /// The fault's input instructions and its 32 bits.
    fn input(&self, m: &mut Module) -> (Vec<Instruction>, Word) {
        match self {
            Tie::Value(_, l) => (l.code.clone(), l.bits),
            Tie::Handle(_) => {
                let u32_t = edit::type_int(m, 32, false);
                (vec![], edit::constant(m, u32_t, 0, false))
            }
        }
    }

    /// `bump` (zero at run time) fed into what uses the access in function `f`: the value's
    /// uses renamed to the bumped value (its instructions returned, to follow the fault), or
    /// the handle's cull masks XOR-ed with it (inserted before each consumer).
    fn feed(&self, m: &mut Module, f: usize, bump: Word) -> Vec<Instruction> {
        match self {
            Tie::Value(value, l) => match feed(m, l, bump) {
                Some((code, new)) => {
                    rename(m, f, *value, new);
                    code
                }
                None => vec![],
            },
            Tie::Handle(h) => {
                super::handle::feed(m, f, *h, bump);
                vec![]
            }
        }
    }
}

/// Instructions computing 32 bits of `value`'s first scalar (its first component, member or
/// element, recursively); `None` for a value of no such type.
pub fn bits(m: &mut Module, value: Word) -> Option<Leaf> {
    let u32_t = edit::type_int(m, 32, false);
    let mut ty = edit::def(m, value)?.result_type?;
    let (mut v, mut code, mut path) = (value, Vec::new(), Vec::new());
    for _ in 0..32 {
        let d = edit::def(m, ty)?.clone();
        let id = next_id(m);
        let conv = |o: Op, operands: Vec<Operand>| Some((o, operands));
        let step = match d.class.opcode {
            Op::TypeVector | Op::TypeMatrix | Op::TypeArray | Op::TypeStruct => {
                let elem = id_operand(&d, 0)?;
                code.push(op(
                    Op::CompositeExtract,
                    Some(elem),
                    id,
                    vec![Operand::IdRef(v), Operand::LiteralBit32(0)],
                ));
                path.push((v, ty));
                (v, ty) = (id, elem);
                continue;
            }
            Op::TypeInt if d.operands.first() == Some(&Operand::LiteralBit32(32)) => {
                return Some(Leaf { code, bits: v, path, leaf: v, leaf_ty: ty })
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
                code.push(op(Op::ConvertPtrToU, Some(u64_t), wide, vec![Operand::IdRef(v)]));
                conv(Op::UConvert, vec![Operand::IdRef(wide)])
            }
            _ => None,
        };
        let (o, operands) = step?;
        code.push(op(o, Some(u32_t), id, operands));
        return Some(Leaf { code, bits: id, path, leaf: v, leaf_ty: ty });
    }
    None
}

/// The access's value with `bump` (a u32, zero at run time but not to a compiler) added to its
/// first scalar and, when that scalar is a vector's, to every component of that vector (a
/// shader reading only a texel's alpha still uses the fault): the instructions and the new
/// value, which replaces the access's value in every use, so the fault's result reaches what
/// the shader writes and no compiler may drop it. `None` for a pointer (no arithmetic on it):
/// the fault then only depends on the access.
fn feed(m: &mut Module, l: &Leaf, bump: Word) -> Option<(Vec<Instruction>, Word)> {
    let mut out = Vec::new();
    let mut cur = bumped(m, l.leaf_ty, l.leaf, bump, &mut out)?;
    let mut path = l.path.iter().rev().peekable();
    if let Some(&&(vector, ty)) = path.peek() {
        let d = edit::def(m, ty)?.clone();
        if d.class.opcode == Op::TypeVector {
            path.next();
            cur = insert(m, &mut out, (vector, ty), cur, 0);
            let lanes = match d.operands.get(1) {
                Some(Operand::LiteralBit32(n)) => *n,
                _ => 1,
            };
            for k in 1..lanes {
                let x = next_id(m);
                out.push(op(
                    Op::CompositeExtract,
                    Some(l.leaf_ty),
                    x,
                    vec![Operand::IdRef(vector), Operand::LiteralBit32(k)],
                ));
                let y = bumped(m, l.leaf_ty, x, bump, &mut out)?;
                cur = insert(m, &mut out, (cur, ty), y, k);
            }
        }
    }
    for &(composite, ty) in path {
        cur = insert(m, &mut out, (composite, ty), cur, 0);
    }
    Some((out, cur))
}

/// `composite` (of type `ty`) with `part` at `index`, appended to `out`: its id.
fn insert(
    m: &mut Module,
    out: &mut Vec<Instruction>,
    (composite, ty): (Word, Word),
    part: Word,
    index: u32,
) -> Word {
    let next = next_id(m);
    out.push(op(
        Op::CompositeInsert,
        Some(ty),
        next,
        vec![Operand::IdRef(part), Operand::IdRef(composite), Operand::LiteralBit32(index)],
    ));
    next
}

/// The scalar `x` of type `ty` with `bump` added (for a bool: flipped when `bump` is not 0),
/// its instructions appended to `out`; `None` for a type without arithmetic.
fn bumped(
    m: &mut Module,
    ty: Word,
    x: Word,
    bump: Word,
    out: &mut Vec<Instruction>,
) -> Option<Word> {
    let d = edit::def(m, ty)?.clone();
    let id = Operand::IdRef;
    let new = next_id(m);
    match d.class.opcode {
        Op::TypeInt => {
            let width = match d.operands.first() {
                Some(Operand::LiteralBit32(w)) => *w,
                _ => return None,
            };
            let b = if width == 32 {
                bump
            } else {
                let (t, c) = (edit::type_int(m, width, false), next_id(m));
                out.push(op(Op::UConvert, Some(t), c, vec![id(bump)]));
                c
            };
            out.push(op(Op::IAdd, Some(ty), new, vec![id(x), id(b)]));
        }
        Op::TypeFloat => {
            let c = next_id(m);
            out.push(op(Op::ConvertUToF, Some(ty), c, vec![id(bump)]));
            out.push(op(Op::FAdd, Some(ty), new, vec![id(x), id(c)]));
        }
        Op::TypeBool => {
            let (u32_t, bool_t) = (edit::type_int(m, 32, false), edit::type_bool(m));
            let (zero, c) = (edit::constant(m, u32_t, 0, false), next_id(m));
            out.push(op(Op::INotEqual, Some(bool_t), c, vec![id(bump), id(zero)]));
            out.push(op(Op::LogicalNotEqual, Some(bool_t), new, vec![id(x), id(c)]));
        }
        _ => return None,
    }
    Some(new)
}

/// Every use of `old` in function `f` made a use of `new`.
fn rename(m: &mut Module, f: usize, old: Word, new: Word) {
    for i in m.functions[f].blocks.iter_mut().flat_map(|b| b.instructions.iter_mut()) {
        for o in i.operands.iter_mut() {
            if *o == Operand::IdRef(old) {
                *o = Operand::IdRef(new);
            }
        }
    }
}

/// `x` compared with a constant no read returns by design, as a u32 0 or 1 (`bump` of [`feed`]).
fn unlikely(m: &mut Module, x: Word) -> (Vec<Instruction>, Word) {
    const MAGIC: u64 = 0x9e37_79b9;
    let (u32_t, bool_t) = (edit::type_int(m, 32, false), edit::type_bool(m));
    let (magic, one, zero) = (
        edit::constant(m, u32_t, MAGIC, false),
        edit::constant(m, u32_t, 1, false),
        edit::constant(m, u32_t, 0, false),
    );
    let (eq, bump) = (next_id(m), next_id(m));
    let id = Operand::IdRef;
    let code = vec![
        op(Op::IEqual, Some(bool_t), eq, vec![id(x), id(magic)]),
        op(Op::Select, Some(u32_t), bump, vec![id(eq), id(one), id(zero)]),
    ];
    (code, bump)
}

/// The device fault after the access at `(f, b, i)`, tied as `tie` says.
pub fn device(m: &mut Module, (f, b, i): (usize, usize, usize), tie: Tie) {
    let u32_t = edit::type_int(m, 32, false);
    let u64_t = edit::type_int(m, 64, false);
    edit::enable_physical_storage_buffer(m);
    let zero_c = edit::constant(m, u32_t, 0, false);
    let bad = edit::constant(m, u64_t, BAD_ADDRESS, true);
    let ptr = edit::type_pointer(m, StorageClass::PhysicalStorageBuffer, u32_t);
    let (zero, wide, addr, p, loaded) =
        (next_id(m), next_id(m), next_id(m), next_id(m), next_id(m));
    let id = Operand::IdRef;
    let (mut code, bits) = tie.input(m);
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
    let (more, bump) = unlikely(m, loaded);
    code.extend(more);
    // The handle's consumers come after the access: feeding them first keeps `i + 1` the
    // place right after it.
    code.extend(tie.feed(m, f, bump));
    m.functions[f].blocks[b].instructions.splice(i + 1..i + 1, code);
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
pub fn hang(m: &mut Module, (f, b, i): (usize, usize, usize), tie: Tie) -> bool {
    let block = &m.functions[f].blocks[b];
    if block.instructions.iter().any(|x| x.class.opcode == Op::LoopMerge) {
        return false;
    }
    let Some(from) = block.label_id() else { return false };
    let u32_t = edit::type_int(m, 32, false);
    let bool_t = edit::type_bool(m);
    let (c0, c1, c2) = (
        edit::constant(m, u32_t, 0, false),
        edit::constant(m, u32_t, 1, false),
        edit::constant(m, u32_t, 2, false),
    );
    let (odd, h, c, merge, count, next, done) =
        (next_id(m), next_id(m), next_id(m), next_id(m), next_id(m), next_id(m), next_id(m));
    let id = Operand::IdRef;
    let (mut code, bits) = tie.input(m);
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
    // After the loop: the count's distance to `bits | 1` (zero, were it ever to end) fed back.
    let (gap, mut after) = (next_id(m), vec![]);
    after.push(op(Op::ISub, Some(u32_t), gap, vec![id(next), id(odd)]));
    after.extend(tie.feed(m, f, gap));
    let func = &mut m.functions[f];
    let mut tail = func.blocks[b].instructions.split_off(i + 1);
    tail.splice(0..0, after);
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
