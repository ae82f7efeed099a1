//! Which words of a buffer block or push-constant block hold integers, read from the module's
//! types (members by their `Offset`, arrays by their `ArrayStride`, vectors component by
//! component; nested structs and arrays walked). The harness fills 32-bit integer words with
//! small integers below `scene::INDEX_BOUND`, every 64-bit integer and `PhysicalStorageBuffer`
//! pointer with the device address of its zero-filled sink buffer (an engine's `uint64_t
//! vertexAddress` is dereferenced: a small integer there is a wild pointer and a crash blamed on
//! the driver), and every other word with floats: an index read from a
//! buffer (`uvec3 ind = indices[mesh].i[gl_PrimitiveID]; vertices[mesh].v[ind.x]`) or from push
//! constants (a material index) then stays inside the arrays it indexes. Float bits read as an
//! integer (0x3F80xxxx) index a billion elements past the end: bounds-checked on lavapipe's
//! descriptor path, a crash through a device address.
use crate::patches::edit;
use rspirv::dr::{Module, Operand};
use rspirv::spirv::{Decoration, Op, StorageClass, Word};
use std::collections::BTreeSet;

/// Words walked at most in one block's fixed part (a bigger fixed array keeps floats past it).
const MAX_WORDS: u32 = 1 << 20;

/// The integer words of one layout, as byte offsets.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Words {
    /// 32-bit integers: a small integer.
    pub low: BTreeSet<u32>,
    /// The first byte of each 64-bit integer or pointer: the sink's address.
    pub addr: BTreeSet<u32>,
}

impl Words {
    /// Both layouts' words in one; a word that is an address in either stays one (a small
    /// integer read as half a pointer would be a wild pointer).
    fn merge(&mut self, o: &Words) {
        self.addr.extend(&o.addr);
        self.low.extend(&o.low);
        let taken: BTreeSet<u32> = self.addr.iter().flat_map(|a| [*a, a + 4]).collect();
        self.low.retain(|w| !taken.contains(w));
    }
}

/// The integer words of a block: its fixed part, and a runtime array at its end (its offset,
/// its stride, the integer words of one element relative to the element's start).
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct IntWords {
    pub fixed: Words,
    pub tail: Option<(u32, u32, Words)>,
}

/// What the harness puts in one 4-byte word.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Fill {
    Float,
    SmallInt,
    /// The low half of the sink's device address.
    AddressLow,
    /// Its high half.
    AddressHigh,
}

impl IntWords {
    /// What the word at byte `offset` holds.
    pub fn at(&self, offset: u32) -> Fill {
        let of = |w: &Words, o: u32| {
            if w.addr.contains(&o) {
                Fill::AddressLow
            } else if o >= 4 && w.addr.contains(&(o - 4)) {
                Fill::AddressHigh
            } else if w.low.contains(&o) {
                Fill::SmallInt
            } else {
                Fill::Float
            }
        };
        match self.tail {
            Some((start, stride, ref w)) if offset >= start && stride > 0 => {
                of(w, (offset - start) % stride)
            }
            _ => of(&self.fixed, offset),
        }
    }

    /// Whether no word is an integer.
    pub fn is_empty(&self) -> bool {
        let none = |w: &Words| w.low.is_empty() && w.addr.is_empty();
        none(&self.fixed) && self.tail.as_ref().is_none_or(|t| none(&t.2))
    }

    /// The words of two blocks aliased at one binding: the fixed parts merged; runtime tails
    /// merged when they start and stride alike, else the one holding addresses (or the first)
    /// kept, the other's tail words then filled as the kept one says.
    pub fn merge(&mut self, o: &IntWords) {
        self.fixed.merge(&o.fixed);
        match (&mut self.tail, &o.tail) {
            (Some((s, st, w)), Some((s2, st2, w2))) if (*s, *st) == (*s2, *st2) => w.merge(w2),
            (Some((_, _, w)), Some(t)) if w.addr.is_empty() && !t.2.addr.is_empty() => {
                self.tail = Some(t.clone())
            }
            (None, Some(t)) => self.tail = Some(t.clone()),
            (Some(_), _) | (None, None) => {}
        }
    }
}

/// The integer words of block struct `st` (`None` when a member lacks its layout decorations).
pub fn of_block(m: &Module, st: Word) -> Option<IntWords> {
    let d = edit::def(m, st)?;
    let mut out = IntWords::default();
    for (k, o) in d.operands.iter().enumerate() {
        let ty = edit::id_from(o)?;
        let offset = edit::member_decoration(m, st, k as u32, Decoration::Offset)?;
        let t = edit::def(m, ty)?;
        if t.class.opcode == Op::TypeRuntimeArray {
            let stride = edit::decoration_literal(m, ty, Decoration::ArrayStride)?;
            let mut w = Words::default();
            walk(m, edit::id_operand(t, 0)?, 0, &mut w)?;
            out.tail = Some((offset, stride, w));
        } else {
            walk(m, ty, offset, &mut out.fixed)?;
        }
    }
    Some(out)
}

/// Record the integer words of a value of type `ty` at byte `base`.
fn walk(m: &Module, ty: Word, base: u32, out: &mut Words) -> Option<()> {
    let d = edit::def(m, ty)?;
    match d.class.opcode {
        Op::TypeInt => {
            match d.operands.first() {
                Some(Operand::LiteralBit32(32)) => {
                    out.low.insert(base);
                }
                Some(Operand::LiteralBit32(64)) => {
                    out.addr.insert(base);
                }
                // 8- and 16-bit integers share a word with others: left as they are.
                _ => {}
            }
            Some(())
        }
        Op::TypeVector => {
            let comp = edit::id_operand(d, 0)?;
            let n = match d.operands.get(1) {
                Some(Operand::LiteralBit32(n)) => *n,
                _ => return None,
            };
            let size = component_bytes(m, comp);
            (0..n).try_for_each(|i| walk(m, comp, base + i * size, out))
        }
        Op::TypeArray => {
            let n = edit::array_length(m, d)?;
            let stride = edit::decoration_literal(m, ty, Decoration::ArrayStride)?;
            let elem = edit::id_operand(d, 0)?;
            let n = n.min(MAX_WORDS / stride.div_ceil(4).max(1));
            (0..n).try_for_each(|i| walk(m, elem, base + i * stride, out))
        }
        Op::TypeStruct => (0..d.operands.len() as u32).try_for_each(|k| {
            let member = edit::id_from(&d.operands[k as usize])?;
            let offset = edit::member_decoration(m, ty, k, Decoration::Offset)?;
            walk(m, member, base + offset, out)
        }),
        Op::TypePointer
            if d.operands.first()
                == Some(&Operand::StorageClass(StorageClass::PhysicalStorageBuffer)) =>
        {
            out.addr.insert(base);
            Some(())
        }
        // Floats, matrices (of floats), other pointers and the rest: no integer word.
        _ => Some(()),
    }
}

/// Bytes of one vector component (its width / 8; 4 when unknown).
fn component_bytes(m: &Module, comp: Word) -> u32 {
    match edit::def(m, comp).and_then(|c| c.operands.first()) {
        Some(Operand::LiteralBit32(w)) if *w >= 8 => w / 8,
        _ => 4,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn module(glsl: &str) -> Module {
        crate::patches::compiled(shaderc::ShaderKind::RayGeneration, "t.rgen", glsl)
    }

    /// The block struct of the (first) variable in storage class `sc`.
    fn block_of(m: &Module, sc: rspirv::spirv::StorageClass) -> Word {
        let v = m
            .types_global_values
            .iter()
            .find(|i| {
                i.class.opcode == Op::Variable
                    && i.operands.first() == Some(&Operand::StorageClass(sc))
            })
            .expect("variable");
        let (_, p) = edit::pointer_info(m, v.result_type.unwrap()).unwrap();
        let d = edit::def(m, p).unwrap();
        if d.class.opcode == Op::TypeRuntimeArray {
            edit::id_operand(d, 0).unwrap()
        } else {
            p
        }
    }

    #[test]
    fn nested_structs_arrays_vectors_and_the_runtime_tail_are_walked() {
        let glsl = "#version 460\n#extension GL_EXT_ray_tracing : require\n\
            #extension GL_EXT_shader_explicit_arithmetic_types_int64 : require\n\
            #extension GL_EXT_scalar_block_layout : require\n\
            #extension GL_EXT_nonuniform_qualifier : require\n\
            struct Draw { vec3 tint; uint material; };\n\
            layout(push_constant) uniform P { vec4 clear; Draw draw; float exposure; int ids[2]; } pc;\n\
            struct Tri { uvec3 i; float area; uint64_t key; };\n\
            layout(set = 0, binding = 0, scalar) buffer Ind { uint count; Tri t[]; } ind[];\n\
            layout(set = 0, binding = 1, rgba32f) uniform image2D img;\n\
            void main() { Tri t = ind[pc.draw.material].t[pc.ids[1]];\n\
            imageStore(img, ivec2(0), vec4(t.i, t.area + float(t.key) + float(ind[0].count)) * pc.exposure); }\n";
        let m = module(glsl);
        let push = of_block(&m, block_of(&m, rspirv::spirv::StorageClass::PushConstant)).unwrap();
        // clear 0..16, draw.tint 16..28, draw.material 28, exposure 32, ids at 48 (std430
        // array stride 4 in a push block: 36, 40)
        assert_eq!(push.at(28), Fill::SmallInt);
        assert_eq!(
            (push.at(0), push.at(16), push.at(24), push.at(32)),
            (Fill::Float, Fill::Float, Fill::Float, Fill::Float)
        );
        assert_eq!(push.fixed.low.len(), 3, "{push:?}");
        let buf = of_block(&m, block_of(&m, rspirv::spirv::StorageClass::StorageBuffer)).unwrap();
        assert_eq!(buf.at(0), Fill::SmallInt, "count");
        let (start, stride, _) = buf.tail.clone().unwrap();
        // The scalar layout aligns `Tri` to its uint64: element 0 at 8.
        assert_eq!((start, stride), (8, 24));
        for e in [0, 5] {
            let b = start + e * stride;
            let got: Vec<Fill> = (0..6).map(|w| buf.at(b + 4 * w)).collect();
            use Fill::*;
            assert_eq!(
                got,
                [SmallInt, SmallInt, SmallInt, Float, AddressLow, AddressHigh],
                "element {e}"
            );
        }
        assert!(!buf.is_empty() && IntWords::default().is_empty());
    }

    /// Issue #24: a `uint64_t` address and a `buffer_reference` pointer member are address
    /// words (the sink's address, never a small integer); a 32-bit member beside them is not.
    #[test]
    fn sixty_four_bit_integers_and_pointers_are_address_words() {
        let glsl = "#version 460\n#extension GL_EXT_ray_tracing : require\n\
            #extension GL_EXT_shader_explicit_arithmetic_types_int64 : require\n\
            #extension GL_EXT_buffer_reference2 : require\n\
            #extension GL_EXT_scalar_block_layout : require\n\
            layout(buffer_reference, scalar) buffer Verts { vec3 p[]; };\n\
            struct Obj { uint64_t vertexAddress; Verts verts; uint material; };\n\
            layout(set = 0, binding = 0, scalar) buffer Objs { Obj o[]; } objs;\n\
            layout(set = 0, binding = 1, rgba32f) uniform image2D img;\n\
            void main() { Obj o = objs.o[gl_LaunchIDEXT.x];\n\
            imageStore(img, ivec2(0), vec4(Verts(o.vertexAddress).p[0] + o.verts.p[o.material], 1.0)); }\n";
        let m = module(glsl);
        let buf = of_block(&m, block_of(&m, rspirv::spirv::StorageClass::StorageBuffer)).unwrap();
        let (start, stride, _) = buf.tail.clone().unwrap();
        assert_eq!((start, stride), (0, 24));
        use Fill::*;
        let got: Vec<Fill> = (0..6).map(|w| buf.at(stride + 4 * w)).collect();
        assert_eq!(got, [AddressLow, AddressHigh, AddressLow, AddressHigh, SmallInt, Float]);
        // Merged with an aliased block reading those words as 32-bit integers, they stay
        // addresses; its other integer word stays an integer.
        let mut words = IntWords::default();
        let mut w = Words::default();
        w.low.extend([0, 4, 16, 20]);
        words.tail = Some((0, 24, w));
        words.merge(&buf);
        let got: Vec<Fill> = (0..6).map(|w| words.at(24 + 4 * w)).collect();
        assert_eq!(got, [AddressLow, AddressHigh, AddressLow, AddressHigh, SmallInt, SmallInt]);
    }
}
