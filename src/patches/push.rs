//! The push-constant addresses of the address patches (`as-to-address`, `ssbo-to-address`): where
//! each descriptor's address goes in the pipeline's push range ([`Slots`], one per pipeline, so
//! every descriptor — set, binding — has its own 8 bytes, the same in every stage that reads it,
//! past every stage's own push data), and the 64-bit member each module's block gets there.
//!
//! SPIR-V rules relied on:
//! - A push-constant block is a `Block`-decorated struct in `PushConstant` storage with an
//!   explicit `Offset` on every member (Vulkan "Offset and Stride Assignment"); a member appended
//!   at an offset past the block's end ([`super::layout::block_end`]) leaves the others intact,
//!   and the numeric order of offsets need not follow member order.
//! - A 64-bit member is 8-byte aligned and needs the `Int64` capability.
//! - Every id must be declared before it is used ("Operand requires a previous definition"): a
//!   struct can only name a member type declared before it, so an existing `OpTypeInt 64` found
//!   after the block struct is moved in front of it (an `OpTypeInt` refers to no other id).
//! - An entry point may statically use at most one push-constant variable; a module without one
//!   gets a new block (and, from SPIR-V 1.4, the variable joins every entry point's interface).
//! - "The Offset decoration for any member of a push constant block must not cause the space
//!   required for that member to extend outside the range [0, maxPushConstantsSize)" (Vulkan
//!   1.4.360, chapters/interfaces.adoc, Push Constant Interface): [`Slots`] refuses an address
//!   past the limit it is given (128 bytes, the minimum every device has, unless told more).
use super::edit;
use super::layout::{self, Rules};
use super::PatchError;
use rspirv::dr::{Instruction, Module, Operand};
use rspirv::spirv::{Decoration, Op, StorageClass, Word};
use std::collections::BTreeMap;

/// What a push-constant address stands for.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum SlotKind {
    /// The device address of one acceleration structure.
    AsAddress,
    /// The address of a table of acceleration-structure addresses (one per array element).
    AsTable,
    /// The address of a table of buffer device addresses (one per array element).
    BufferTable,
}

/// One descriptor's push-constant address: its kind, set and binding.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub struct SlotKey {
    pub kind: SlotKind,
    pub set: u32,
    pub binding: u32,
}

/// The push-constant offsets of one pipeline's addresses: from `start` (past every stage's
/// block), 8 bytes each, never past `limit` (maxPushConstantsSize).
#[derive(Clone, Debug)]
pub struct Slots {
    /// (u64: an offset near u32::MAX must not wrap to 0 and alias another stage's push data)
    next: u64,
    limit: u32,
    taken: BTreeMap<SlotKey, u32>,
}

impl Slots {
    /// Slots from `start` (rounded up to 8) to `limit`.
    pub fn new(start: u32, limit: u32) -> Slots {
        Slots { next: u64::from(start).div_ceil(8) * 8, limit, taken: BTreeMap::new() }
    }

    /// The offset of `key`'s address: the one it has, else the next free one.
    pub fn offset(&mut self, key: SlotKey, patch: &'static str) -> Result<u32, PatchError> {
        if let Some(o) = self.taken.get(&key) {
            return Ok(*o);
        }
        let o = self.next;
        if o + 8 > u64::from(self.limit) {
            return Err(PatchError::BadOption {
                patch,
                what: format!(
                    "the push-constant range would end at byte {}, past maxPushConstantsSize {} \
                     (128 is what every device has; --max-push-constants for a device with more)",
                    o + 8,
                    self.limit
                ),
            });
        }
        self.next += 8;
        // (below `limit`, a u32, by the check above)
        let o = o as u32;
        self.taken.insert(key, o);
        Ok(o)
    }

    /// Every address placed so far, by key.
    pub fn taken(&self) -> &BTreeMap<SlotKey, u32> {
        &self.taken
    }
}

/// A module's push-constant block: its variable and struct.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Block {
    pub var: Word,
    pub st: Word,
}

/// The module's push-constant block, if it has one.
pub fn block(m: &Module, patch: &'static str) -> Result<Option<Block>, PatchError> {
    let var = m.types_global_values.iter().find(|i| {
        i.class.opcode == Op::Variable
            && i.operands.first() == Some(&Operand::StorageClass(StorageClass::PushConstant))
    });
    let Some((var, ptr)) = var.and_then(|v| Some((v.result_id?, v.result_type?))) else {
        return Ok(None);
    };
    let (_, st) = edit::pointer_info(m, ptr).ok_or(PatchError::Unsupported {
        patch,
        id: var,
        what: "push-constant variable without pointer type".into(),
    })?;
    Ok(Some(Block { var, st }))
}

/// The lowest member offset of block struct `st` (0 when it has none).
pub fn start(m: &Module, st: Word) -> u32 {
    let n = edit::def(m, st).map_or(0, |d| d.operands.len() as u32);
    (0..n).filter_map(|k| edit::member_decoration(m, st, k, Decoration::Offset)).min().unwrap_or(0)
}

/// The first byte after the module's push data under `rules` (0 without a block).
pub fn end(m: &Module, rules: Rules, patch: &'static str) -> Result<u32, PatchError> {
    let Some(b) = block(m, patch)? else {
        return Ok(0);
    };
    // Sized from its Offset / ArrayStride / MatrixStride decorations; a block without them is
    // not a valid Vulkan push-constant block.
    layout::block_end(m, b.st, rules).ok_or(PatchError::Unsupported {
        patch,
        id: b.st,
        what: "the push-constant block lacks the Offset / ArrayStride / MatrixStride decorations \
               that give its size"
            .into(),
    })
}

/// A 64-bit member at `offset` in the module's push-constant block (appended past the block's
/// end under `rules`, or the one already there, or a new block). Returns (variable, member index).
pub fn u64_member(
    m: &mut Module,
    offset: u32,
    rules: Rules,
    patch: &'static str,
) -> Result<(Word, u32), PatchError> {
    if offset % 8 != 0 {
        return Err(PatchError::BadOption {
            patch,
            what: format!("offset={offset} is not 8-byte aligned"),
        });
    }
    let u64_t = edit::type_int(m, 64, false);
    let Some(b) = block(m, patch)? else {
        return Ok((new_block(m, u64_t, offset), 0));
    };
    let members: Vec<Word> = edit::def(m, b.st)
        .map(|d| d.operands.iter().filter_map(edit::id_from).collect())
        .unwrap_or_default();
    for (k, ty) in members.iter().enumerate() {
        let at = edit::member_decoration(m, b.st, k as u32, Decoration::Offset);
        if at == Some(offset) && *ty == u64_t {
            return Ok((b.var, k as u32));
        }
    }
    let end = end(m, rules, patch)?;
    if offset < end {
        return Err(PatchError::BadOption {
            patch,
            what: format!("offset={offset} overlaps the push-constant block, which ends at {end}"),
        });
    }
    hoist_before(m, u64_t, b.st);
    let k = members.len() as u32;
    if let Some(s) = m.types_global_values.iter_mut().find(|i| i.result_id == Some(b.st)) {
        s.operands.push(Operand::IdRef(u64_t));
    }
    m.annotations.push(member_offset(b.st, k, offset));
    Ok((b.var, k))
}

/// Move the global `ty` (an instruction that refers to no other id, such as `OpTypeInt`) in front
/// of `user` when it comes after it.
fn hoist_before(m: &mut Module, ty: Word, user: Word) {
    let g = &mut m.types_global_values;
    let (Some(t), Some(u)) = (
        g.iter().position(|i| i.result_id == Some(ty)),
        g.iter().position(|i| i.result_id == Some(user)),
    ) else {
        return;
    };
    if t > u {
        let inst = g.remove(t);
        g.insert(u, inst);
    }
}

/// A new push-constant block of one `u64_t` member at `offset`, and its variable.
fn new_block(m: &mut Module, u64_t: Word, offset: u32) -> Word {
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
    var
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
    /// An offset near u32::MAX is refused: rounded up to 8 in u32 it wrapped to 0 and put the
    /// address on another stage's push data.
    #[test]
    fn a_start_near_the_top_of_u32_is_refused_not_wrapped() {
        let key = || SlotKey { kind: SlotKind::AsAddress, set: 0, binding: 0 };
        let mut s = Slots::new(u32::MAX - 3, u32::MAX);
        assert!(s.offset(key(), "as-to-address").is_err());
        let mut s = Slots::new(4, 128);
        assert_eq!(s.offset(key(), "as-to-address").unwrap(), 8);
    }

    use super::*;

    fn module(glsl: &str) -> Module {
        crate::patches::compiled(shaderc::ShaderKind::RayGeneration, "t.rgen", glsl)
    }

    #[test]
    fn slots_are_one_per_descriptor_and_bounded() {
        let mut s = Slots::new(20, 48);
        let k = |set, binding| SlotKey { kind: SlotKind::AsAddress, set, binding };
        assert_eq!(s.offset(k(2, 0), "t").unwrap(), 24);
        assert_eq!(s.offset(k(3, 0), "t").unwrap(), 32, "set 3 binding 0 is another descriptor");
        assert_eq!(s.offset(k(2, 0), "t").unwrap(), 24, "the same descriptor, the same address");
        assert_eq!(s.offset(k(4, 0), "t").unwrap(), 40);
        let e = s.offset(k(5, 0), "t").unwrap_err().to_string();
        assert!(e.contains("byte 56") && e.contains("maxPushConstantsSize 48"), "{e}");
    }

    #[test]
    fn a_64_bit_type_declared_after_the_block_is_moved_before_it() {
        // glslang declares types where the code first uses them: uint64_t after the push block.
        let glsl = "#version 460\n#extension GL_EXT_ray_tracing : require\n\
            #extension GL_EXT_shader_explicit_arithmetic_types_int64 : require\n\
            layout(push_constant) uniform P { vec4 tint; } pc;\n\
            layout(location = 0) rayPayloadEXT vec4 c;\n\
            void main() { vec4 t = pc.tint; uint64_t x = uint64_t(gl_LaunchIDEXT.x) * 3ul; c = t * float(x); }\n";
        let mut m = module(glsl);
        let pos = |m: &Module, f: &dyn Fn(&Instruction) -> bool| {
            m.types_global_values.iter().position(f).unwrap()
        };
        let is_u64 = |i: &Instruction| {
            i.class.opcode == Op::TypeInt && i.operands[0] == Operand::LiteralBit32(64)
        };
        let st = block(&m, "t").unwrap().unwrap().st;
        let is_block = move |i: &Instruction| i.result_id == Some(st);
        assert!(pos(&m, &is_u64) > pos(&m, &is_block), "the input declares uint64 late");
        let (_, k) = u64_member(&mut m, 16, Rules::Standard, "t").unwrap();
        assert_eq!(k, 1);
        assert!(pos(&m, &is_u64) < pos(&m, &is_block));
        let v = crate::patches::validate(&crate::patches::assemble(&m));
        assert!(
            matches!(
                v,
                crate::patches::Validation::Valid | crate::patches::Validation::Unavailable
            ),
            "{v:?}"
        );
        // asking again for the same offset gives the same member, an offset inside is refused
        assert_eq!(u64_member(&mut m, 16, Rules::Standard, "t").unwrap().1, 1);
        assert!(u64_member(&mut m, 8, Rules::Standard, "t")
            .unwrap_err()
            .to_string()
            .contains("overlaps"));
    }
}
