//! Small, rule-abiding edits of an `rspirv::dr::Module` shared by the patches: fresh ids, finding
//! or adding types / constants / capabilities, finding definitions and users, and removing ids
//! with every decoration, name and entry-point interface entry that mentions them.
use rspirv::dr::{Instruction, Module, Operand};
use rspirv::spirv::{Capability, Decoration, Op, StorageClass, Word};
use std::collections::HashSet;

pub fn next_id(m: &mut Module) -> Word {
    let h = m.header.as_mut().expect("loaded modules have a header");
    let id = h.bound;
    h.bound += 1;
    id
}

pub fn def(m: &Module, id: Word) -> Option<&Instruction> {
    m.types_global_values
        .iter()
        .chain(m.functions.iter().flat_map(|f| {
            f.parameters.iter().chain(f.blocks.iter().flat_map(|b| b.instructions.iter()))
        }))
        .find(|i| i.result_id == Some(id))
}

pub fn id_operand(i: &Instruction, n: usize) -> Option<Word> {
    match i.operands.get(n) {
        Some(Operand::IdRef(w)) => Some(*w),
        _ => None,
    }
}

/// The id an operand names, if it is an id.
pub fn id_from(o: &Operand) -> Option<Word> {
    match o {
        Operand::IdRef(w) => Some(*w),
        _ => None,
    }
}

/// (width, signed) of the integer type of value `id`.
pub fn int_type_of(m: &Module, id: Word) -> Option<(u32, bool)> {
    let ty = def(m, def(m, id)?.result_type?)?;
    match (ty.class.opcode, ty.operands.first(), ty.operands.get(1)) {
        (Op::TypeInt, Some(Operand::LiteralBit32(w)), Some(Operand::LiteralBit32(s))) => {
            Some((*w, *s == 1))
        }
        _ => None,
    }
}

/// Give the load or store `i` an `Aligned align` memory operand (keeping its other memory
/// operands; the `Aligned` literal comes first among them, as the lowest bit with a literal).
/// `first` is the index of the memory-operand mask (1 for `OpLoad`, 2 for `OpStore`).
pub fn set_aligned(i: &mut Instruction, first: usize, align: u32) {
    use rspirv::spirv::MemoryAccess;
    match i.operands.get(first).cloned() {
        Some(Operand::MemoryAccess(f)) if f.contains(MemoryAccess::ALIGNED) => {}
        Some(Operand::MemoryAccess(f)) => {
            i.operands[first] = Operand::MemoryAccess(f | MemoryAccess::ALIGNED);
            i.operands.insert(first + 1, Operand::LiteralBit32(align));
        }
        _ => {
            i.operands.truncate(first);
            i.operands.push(Operand::MemoryAccess(MemoryAccess::ALIGNED));
            i.operands.push(Operand::LiteralBit32(align));
        }
    }
}

pub fn has_decoration(m: &Module, id: Word, d: Decoration) -> bool {
    m.annotations.iter().any(|a| {
        a.class.opcode == Op::Decorate
            && id_operand(a, 0) == Some(id)
            && matches!(a.operands.get(1), Some(Operand::Decoration(x)) if *x == d)
    })
}

pub fn decoration_literal(m: &Module, id: Word, d: Decoration) -> Option<u32> {
    m.annotations.iter().find_map(|a| {
        let ok = a.class.opcode == Op::Decorate
            && id_operand(a, 0) == Some(id)
            && matches!(a.operands.get(1), Some(Operand::Decoration(x)) if *x == d);
        match (ok, a.operands.get(2)) {
            (true, Some(Operand::LiteralBit32(v))) => Some(*v),
            _ => None,
        }
    })
}

pub fn decorate(m: &mut Module, id: Word, d: Decoration, extra: &[Operand]) {
    let mut ops = vec![Operand::IdRef(id), Operand::Decoration(d)];
    ops.extend_from_slice(extra);
    m.annotations.push(Instruction::new(Op::Decorate, None, None, ops));
}

pub fn add_capability(m: &mut Module, c: Capability) {
    if !m
        .capabilities
        .iter()
        .any(|i| matches!(i.operands.first(), Some(Operand::Capability(x)) if *x == c))
    {
        m.capabilities.push(Instruction::new(
            Op::Capability,
            None,
            None,
            vec![Operand::Capability(c)],
        ));
    }
}

pub fn add_extension(m: &mut Module, name: &str) {
    if !m
        .extensions
        .iter()
        .any(|i| matches!(i.operands.first(), Some(Operand::LiteralString(x)) if x == name))
    {
        m.extensions.push(Instruction::new(
            Op::Extension,
            None,
            None,
            vec![Operand::LiteralString(name.into())],
        ));
    }
}

/// SPIR-V version of the module as (major, minor).
pub fn version(m: &Module) -> (u8, u8) {
    m.header
        .as_ref()
        .map(|h| (((h.version >> 16) & 0xff) as u8, ((h.version >> 8) & 0xff) as u8))
        .unwrap_or((1, 0))
}

/// `OpTypeInt width signedness`, added at the front of the globals (it depends on nothing).
pub fn type_int(m: &mut Module, width: u32, signed: bool) -> Word {
    let found = m.types_global_values.iter().find(|i| {
        i.class.opcode == Op::TypeInt
            && i.operands == [Operand::LiteralBit32(width), Operand::LiteralBit32(signed as u32)]
    });
    if let Some(i) = found {
        return i.result_id.expect("types have ids");
    }
    if width == 64 {
        add_capability(m, Capability::Int64);
    }
    let id = next_id(m);
    m.types_global_values.insert(
        0,
        Instruction::new(
            Op::TypeInt,
            None,
            Some(id),
            vec![Operand::LiteralBit32(width), Operand::LiteralBit32(signed as u32)],
        ),
    );
    id
}

/// `OpTypeBool`, found or appended.
pub fn type_bool(m: &mut Module) -> Word {
    let found = m.types_global_values.iter().find(|i| i.class.opcode == Op::TypeBool);
    if let Some(id) = found.and_then(|i| i.result_id) {
        return id;
    }
    let id = next_id(m);
    m.types_global_values.push(Instruction::new(Op::TypeBool, None, Some(id), vec![]));
    id
}

/// `OpTypePointer sc pointee`, found or appended.
pub fn type_pointer(m: &mut Module, sc: StorageClass, pointee: Word) -> Word {
    let found = m.types_global_values.iter().find(|i| {
        i.class.opcode == Op::TypePointer
            && i.operands == [Operand::StorageClass(sc), Operand::IdRef(pointee)]
    });
    if let Some(i) = found {
        return i.result_id.expect("types have ids");
    }
    let id = next_id(m);
    m.types_global_values.push(Instruction::new(
        Op::TypePointer,
        None,
        Some(id),
        vec![Operand::StorageClass(sc), Operand::IdRef(pointee)],
    ));
    id
}

/// `OpConstant ty value` (32- or 64-bit literal by `wide`), found or appended.
pub fn constant(m: &mut Module, ty: Word, value: u64, wide: bool) -> Word {
    let lit = if wide { Operand::LiteralBit64(value) } else { Operand::LiteralBit32(value as u32) };
    let found = m.types_global_values.iter().find(|i| {
        i.class.opcode == Op::Constant && i.result_type == Some(ty) && i.operands == [lit.clone()]
    });
    if let Some(i) = found {
        return i.result_id.expect("constants have ids");
    }
    let id = next_id(m);
    m.types_global_values.push(Instruction::new(Op::Constant, Some(ty), Some(id), vec![lit]));
    id
}

/// The length of array type `d` (an `OpTypeArray`), when a plain constant.
pub fn array_length(m: &Module, d: &Instruction) -> Option<u32> {
    let len = def(m, id_operand(d, 1)?)?;
    match (len.class.opcode, len.operands.first()) {
        (Op::Constant, Some(Operand::LiteralBit32(v))) => Some(*v),
        _ => None,
    }
}

pub fn is_constant(m: &Module, id: Word) -> bool {
    def(m, id).is_some_and(|d| {
        matches!(
            d.class.opcode,
            Op::Constant
                | Op::ConstantComposite
                | Op::ConstantNull
                | Op::SpecConstant
                | Op::SpecConstantOp
                | Op::ConstantTrue
                | Op::ConstantFalse
        )
    })
}

/// Remove the global definitions of `ids` and every annotation, name and entry-point interface
/// entry that names them.
pub fn remove_ids(m: &mut Module, ids: &HashSet<Word>) {
    m.types_global_values.retain(|i| !i.result_id.is_some_and(|r| ids.contains(&r)));
    let names = |i: &Instruction| id_operand(i, 0).is_some_and(|t| ids.contains(&t));
    m.annotations.retain(|i| !names(i));
    m.debug_names.retain(|i| !names(i));
    for ep in &mut m.entry_points {
        // OpEntryPoint: model, function id, name, interface ids...
        let head = 3.min(ep.operands.len());
        let (fixed, iface) = ep.operands.split_at(head);
        let kept: Vec<Operand> = iface
            .iter()
            .filter(|o| !matches!(o, Operand::IdRef(w) if ids.contains(w)))
            .cloned()
            .collect();
        ep.operands = fixed.iter().cloned().chain(kept).collect();
    }
    for f in &mut m.functions {
        for b in &mut f.blocks {
            b.instructions.retain(|i| !i.result_id.is_some_and(|r| ids.contains(&r)));
        }
    }
}

/// Add `var` to the interface of every entry point (SPIR-V 1.4+ lists all referenced globals).
pub fn add_to_interfaces(m: &mut Module, var: Word) {
    let (major, minor) = version(m);
    if (major, minor) < (1, 4) {
        return;
    }
    for ep in &mut m.entry_points {
        if !ep.operands.iter().skip(3).any(|o| *o == Operand::IdRef(var)) {
            ep.operands.push(Operand::IdRef(var));
        }
    }
}

/// The storage class and pointee of a pointer type id.
pub fn pointer_info(m: &Module, ptr_ty: Word) -> Option<(StorageClass, Word)> {
    let d = def(m, ptr_ty)?;
    match (d.class.opcode, d.operands.first(), d.operands.get(1)) {
        (Op::TypePointer, Some(Operand::StorageClass(sc)), Some(Operand::IdRef(p))) => {
            Some((*sc, *p))
        }
        _ => None,
    }
}

/// Global descriptor variables (those with a DescriptorSet decoration).
pub fn descriptor_variables(m: &Module) -> Vec<Word> {
    m.types_global_values
        .iter()
        .filter(|i| i.class.opcode == Op::Variable)
        .filter_map(|i| i.result_id)
        .filter(|id| has_decoration(m, *id, Decoration::DescriptorSet))
        .collect()
}

/// Every instruction (in functions) that names `id` among its operands.
pub fn users(m: &Module, id: Word) -> Vec<Word> {
    m.functions
        .iter()
        .flat_map(|f| f.blocks.iter().flat_map(|b| b.instructions.iter()))
        .filter(|i| i.operands.contains(&Operand::IdRef(id)))
        .filter_map(|i| i.result_id)
        .collect()
}

/// A member decoration of struct `st`'s member `member`: `Some(literal)` when present (`Some(0)`
/// for decorations without a literal).
pub fn member_decoration(m: &Module, st: Word, member: u32, d: Decoration) -> Option<u32> {
    m.annotations.iter().find_map(|a| {
        let hit = a.class.opcode == Op::MemberDecorate
            && id_operand(a, 0) == Some(st)
            && a.operands.get(1) == Some(&Operand::LiteralBit32(member))
            && matches!(a.operands.get(2), Some(Operand::Decoration(x)) if *x == d);
        hit.then(|| match a.operands.get(3) {
            Some(Operand::LiteralBit32(v)) => *v,
            _ => 0,
        })
    })
}

/// Ids the address-table loads need (see [`table_entry`]).
pub struct TableTypes {
    pub pc_var: Word,
    pub member: Word,
    pub ptr_pc_u64: Word,
    pub u64_t: Word,
    pub ptr_psb_u64: Word,
    pub eight: Word,
}

impl TableTypes {
    /// The ids for a table whose address is member `member` of push-constant variable `pc_var`
    /// (the module switches to PhysicalStorageBuffer64 addressing).
    pub fn new(m: &mut Module, pc_var: Word, member: u32) -> TableTypes {
        let u32_t = type_int(m, 32, false);
        let u64_t = type_int(m, 64, false);
        enable_physical_storage_buffer(m);
        TableTypes {
            pc_var,
            member: constant(m, u32_t, member as u64, false),
            ptr_pc_u64: type_pointer(m, StorageClass::PushConstant, u64_t),
            u64_t,
            ptr_psb_u64: type_pointer(m, StorageClass::PhysicalStorageBuffer, u64_t),
            eight: constant(m, u64_t, 8, true),
        }
    }
}

/// Instructions loading entry `index` (None: entry 0) of a table of 64-bit addresses whose own
/// address is push-constant member `member`: `OpAccessChain`/`OpLoad` of the member, then
/// `index * 8` added, `OpConvertUToPtr` to a PhysicalStorageBuffer pointer, `OpLoad ... Aligned 8`.
/// Returns the instructions and the id of the loaded address.
pub fn table_entry(
    m: &mut Module,
    t: &TableTypes,
    index: Option<Word>,
) -> (Vec<Instruction>, Word) {
    use rspirv::spirv::MemoryAccess;
    let mut out = Vec::new();
    let pm = next_id(m);
    out.push(Instruction::new(
        Op::AccessChain,
        Some(t.ptr_pc_u64),
        Some(pm),
        vec![Operand::IdRef(t.pc_var), Operand::IdRef(t.member)],
    ));
    let base = next_id(m);
    out.push(Instruction::new(Op::Load, Some(t.u64_t), Some(base), vec![Operand::IdRef(pm)]));
    let at = match index {
        Some(idx) => {
            // The index as a 64-bit unsigned value: UConvert from a narrower integer (its
            // operand may be signed), a Bitcast from a signed 64-bit one, itself when u64.
            let idx64 = match int_type_of(m, idx) {
                Some((64, false)) => idx,
                Some((64, true)) => {
                    let id = next_id(m);
                    out.push(Instruction::new(
                        Op::Bitcast,
                        Some(t.u64_t),
                        Some(id),
                        vec![Operand::IdRef(idx)],
                    ));
                    id
                }
                _ => {
                    let id = next_id(m);
                    out.push(Instruction::new(
                        Op::UConvert,
                        Some(t.u64_t),
                        Some(id),
                        vec![Operand::IdRef(idx)],
                    ));
                    id
                }
            };
            let (off, sum) = (next_id(m), next_id(m));
            out.push(Instruction::new(
                Op::IMul,
                Some(t.u64_t),
                Some(off),
                vec![Operand::IdRef(idx64), Operand::IdRef(t.eight)],
            ));
            out.push(Instruction::new(
                Op::IAdd,
                Some(t.u64_t),
                Some(sum),
                vec![Operand::IdRef(base), Operand::IdRef(off)],
            ));
            sum
        }
        None => base,
    };
    let (p, a) = (next_id(m), next_id(m));
    out.push(Instruction::new(
        Op::ConvertUToPtr,
        Some(t.ptr_psb_u64),
        Some(p),
        vec![Operand::IdRef(at)],
    ));
    out.push(Instruction::new(
        Op::Load,
        Some(t.u64_t),
        Some(a),
        vec![
            Operand::IdRef(p),
            Operand::MemoryAccess(MemoryAccess::ALIGNED),
            Operand::LiteralBit32(8),
        ],
    ));
    (out, a)
}

/// Switch the module to PhysicalStorageBuffer64 addressing (capability, extension before 1.5).
pub fn enable_physical_storage_buffer(m: &mut Module) {
    use rspirv::spirv::AddressingModel;
    add_capability(m, Capability::PhysicalStorageBufferAddresses);
    if version(m) < (1, 5) {
        add_extension(m, "SPV_KHR_physical_storage_buffer");
    }
    if let Some(mm) = m.memory_model.as_mut() {
        mm.operands[0] = Operand::AddressingModel(AddressingModel::PhysicalStorageBuffer64);
    }
}
