//! Sizes and alignments of explicitly laid-out SPIR-V types (push constants, uniform and storage
//! blocks, physical-storage-buffer data), by Vulkan's "Offset and Stride Assignment" (Vulkan
//! 1.4.360, chapters/interfaces.adoc). The patches use them to place a new push-constant member
//! past everything a block holds, and to state the alignment of loads they write.
//!
//! Rules relied on (quoted from that section):
//! - "A scalar of size N has a scalar alignment of N"; a vector's and an array's scalar alignment
//!   is its component's / element's; a structure's the largest of its members'.
//! - Base alignment: a scalar's is its scalar alignment; "A two-component vector has a base
//!   alignment equal to twice its scalar alignment. A three- or four-component vector has a base
//!   alignment equal to four times its scalar alignment"; an array's is its element's; "A
//!   structure has a base alignment equal to the largest base alignment of any of its members";
//!   a column-major matrix of C columns and R rows is a C-element array of R-vectors, a row-major
//!   one an R-element array of C-vectors.
//! - Push constants are aligned by base alignment unless the scalarBlockLayout feature is enabled
//!   (then by scalar alignment), and without that feature "The Offset decoration of a member
//!   must not place it between the end of a structure, an array, or a matrix and the next
//!   multiple of the alignment of that structure, array, or matrix." So the first free offset
//!   after a struct, array or matrix member is its end rounded up to its base alignment (spirv-val
//!   checks exactly this: "member 1 at offset 40 overlaps previous member ending at offset 47").
//! - A matrix spans its `MatrixStride` times its column count (column-major; spirv-val's size) or
//!   `(R - 1) × stride + C × component` (row-major); an array `(N - 1) × ArrayStride` plus its
//!   last element; a structure up to its furthest member's end.
use super::edit::{self, def, id_operand};
use rspirv::dr::{Instruction, Module, Operand};
use rspirv::spirv::{Decoration, Op, StorageClass, Word};

/// Which alignment rules a module's blocks follow (the validator option it passed with).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Rules {
    /// Base alignment, padding after structs, arrays and matrices reserved (std430).
    #[default]
    Standard,
    /// Scalar alignment, no reserved padding (the scalarBlockLayout feature).
    Scalar,
}

fn literal(i: &Instruction, n: usize) -> Option<u32> {
    match i.operands.get(n) {
        Some(Operand::LiteralBit32(v)) => Some(*v),
        _ => None,
    }
}

/// A matrix member's layout: (MatrixStride, RowMajor).
pub type MatrixLayout = (u32, bool);

/// The matrix layout of member `k` of struct `st`, if it has a `MatrixStride`.
fn member_matrix(m: &Module, st: Word, k: u32) -> Option<MatrixLayout> {
    edit::member_decoration(m, st, k, Decoration::MatrixStride)
        .map(|s| (s, edit::member_decoration(m, st, k, Decoration::RowMajor).is_some()))
}

/// Bytes a value of type `ty` spans in an explicitly laid-out block: scalars, vectors, matrices
/// (with the enclosing member's `matrix` layout), arrays, structs, physical-storage-buffer
/// pointers (8). `None` for what has no fixed extent (runtime arrays, spec-constant lengths,
/// missing decorations).
pub fn extent(m: &Module, ty: Word, matrix: Option<MatrixLayout>) -> Option<u32> {
    let d = def(m, ty)?;
    match d.class.opcode {
        Op::TypeInt | Op::TypeFloat => literal(d, 0).map(|bits| bits / 8),
        Op::TypeVector => Some(extent(m, id_operand(d, 0)?, None)? * literal(d, 1)?),
        Op::TypeMatrix => {
            let column = def(m, id_operand(d, 0)?)?;
            let (cols, rows) = (literal(d, 1)?, literal(column, 1)?);
            let comp = extent(m, id_operand(column, 0)?, None)?;
            let (stride, row_major) = matrix?;
            Some(if row_major {
                (rows - 1) * stride + cols * comp
            } else {
                (cols * stride).max((cols - 1) * stride + rows * comp)
            })
        }
        Op::TypeArray => {
            let len = edit::array_length(m, d)?;
            let stride = edit::decoration_literal(m, ty, Decoration::ArrayStride)?;
            Some(len.checked_sub(1)? * stride + extent(m, id_operand(d, 0)?, matrix)?)
        }
        Op::TypeStruct => {
            let mut end = 0;
            for (k, o) in d.operands.iter().enumerate() {
                let Operand::IdRef(member_ty) = o else {
                    return None;
                };
                let k = k as u32;
                let offset = edit::member_decoration(m, ty, k, Decoration::Offset)?;
                end = end.max(offset + extent(m, *member_ty, member_matrix(m, ty, k))?);
            }
            Some(end)
        }
        Op::TypePointer => match d.operands.first() {
            Some(Operand::StorageClass(StorageClass::PhysicalStorageBuffer)) => Some(8),
            _ => None,
        },
        _ => None,
    }
}

/// The scalar alignment of `ty` (see the module doc); pointers to physical storage buffers are
/// 64-bit scalars.
pub fn scalar_alignment(m: &Module, ty: Word) -> Option<u32> {
    let d = def(m, ty)?;
    match d.class.opcode {
        Op::TypeInt | Op::TypeFloat => literal(d, 0).map(|bits| bits / 8),
        Op::TypeVector | Op::TypeMatrix | Op::TypeArray | Op::TypeRuntimeArray => {
            scalar_alignment(m, id_operand(d, 0)?)
        }
        Op::TypeStruct => d
            .operands
            .iter()
            .map(|o| match o {
                Operand::IdRef(t) => scalar_alignment(m, *t),
                _ => None,
            })
            .try_fold(1, |a, b| Some(a.max(b?))),
        Op::TypePointer => Some(8),
        _ => None,
    }
}

/// The base alignment of `ty` (see the module doc), `row_major` for a matrix member.
pub fn base_alignment(m: &Module, ty: Word, row_major: bool) -> Option<u32> {
    let d = def(m, ty)?;
    let vector = |comp: Word, n: u32| -> Option<u32> {
        let s = scalar_alignment(m, comp)?;
        Some(if n == 2 {
            2 * s
        } else if n >= 3 {
            4 * s
        } else {
            s
        })
    };
    match d.class.opcode {
        Op::TypeInt | Op::TypeFloat | Op::TypePointer => scalar_alignment(m, ty),
        Op::TypeVector => vector(id_operand(d, 0)?, literal(d, 1)?),
        Op::TypeMatrix => {
            let column = def(m, id_operand(d, 0)?)?;
            let n = if row_major { literal(d, 1)? } else { literal(column, 1)? };
            vector(id_operand(column, 0)?, n)
        }
        Op::TypeArray | Op::TypeRuntimeArray => base_alignment(m, id_operand(d, 0)?, row_major),
        Op::TypeStruct => d
            .operands
            .iter()
            .enumerate()
            .map(|(k, o)| match o {
                Operand::IdRef(t) => {
                    base_alignment(m, *t, member_matrix(m, ty, k as u32).is_some_and(|x| x.1))
                }
                _ => None,
            })
            .try_fold(1, |a, b| Some(a.max(b?))),
        _ => None,
    }
}

/// Whether the padding after a member of type `ty` is reserved under the standard rules.
fn padded(m: &Module, ty: Word) -> bool {
    def(m, ty)
        .is_some_and(|d| matches!(d.class.opcode, Op::TypeStruct | Op::TypeArray | Op::TypeMatrix))
}

/// The first byte after the block struct `st` that a new member may use under `rules`: each
/// member's end, rounded up to its base alignment after a struct, array or matrix under the
/// standard rules. `None` when a member has no fixed extent or lacks its decorations.
pub fn block_end(m: &Module, st: Word, rules: Rules) -> Option<u32> {
    let d = def(m, st)?;
    let mut end = 0;
    for (k, o) in d.operands.iter().enumerate() {
        let Operand::IdRef(ty) = o else {
            return None;
        };
        let k = k as u32;
        let matrix = member_matrix(m, st, k);
        let offset = edit::member_decoration(m, st, k, Decoration::Offset)?;
        let mut e = offset + extent(m, *ty, matrix)?;
        if rules == Rules::Standard && padded(m, *ty) {
            let a = base_alignment(m, *ty, matrix.is_some_and(|x| x.1))?;
            e = e.div_ceil(a) * a;
        }
        end = end.max(e);
    }
    Some(end)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn module(glsl: &str) -> Module {
        crate::patches::compiled(shaderc::ShaderKind::RayGeneration, "t.rgen", glsl)
    }

    fn push_struct(m: &Module) -> Word {
        m.types_global_values
            .iter()
            .find(|i| {
                i.class.opcode == Op::TypeStruct
                    && edit::has_decoration(m, i.result_id.unwrap(), Decoration::Block)
            })
            .and_then(|i| i.result_id)
            .unwrap()
    }

    const HEAD: &str = "#version 460\n#extension GL_EXT_ray_tracing : require\n";

    #[test]
    fn a_nested_struct_reserves_its_padding_under_the_standard_rules() {
        // vec4, vec3, float, int: 36 bytes, base alignment 16 -> the next member may start at 48.
        let glsl = format!("{HEAD}struct Ray {{ vec4 clear; vec3 light; float power; int kind; }};\n\
            layout(push_constant) uniform P {{ Ray ray; }} pc;\n\
            layout(location = 0) rayPayloadEXT vec4 c;\nvoid main() {{ c = pc.ray.clear * float(pc.ray.kind); }}\n");
        let m = module(&glsl);
        let st = push_struct(&m);
        assert_eq!(extent(&m, st, None), Some(36));
        assert_eq!(block_end(&m, st, Rules::Standard), Some(48));
        assert_eq!(block_end(&m, st, Rules::Scalar), Some(36));
    }

    #[test]
    fn arrays_and_matrices_round_to_their_alignment_and_scalars_do_not() {
        // mat3 column-major: 3 columns of 16 -> 48; float[3] stride 4 at 48: 60, rounded to 4 (no
        // change); a trailing vec3 at 64 ends at 76 and needs no rounding.
        let glsl = format!("{HEAD}layout(push_constant) uniform P {{ mat3 m; float w[3]; vec3 tail; }} pc;\n\
            layout(location = 0) rayPayloadEXT vec4 c;\nvoid main() {{ c = vec4(pc.m[2] + pc.tail, pc.w[2]); }}\n");
        let m = module(&glsl);
        let st = push_struct(&m);
        assert_eq!(block_end(&m, st, Rules::Standard), Some(76));
        // A struct array ending the block: Item {vec2; float} spans 12 bytes, stride 16; two items
        // end at 16 + 12 = 28, rounded up to the base alignment 8 (vec2's): 32.
        let glsl = format!("{HEAD}struct Item {{ vec2 uv; float w; }};\n\
            layout(push_constant) uniform P {{ Item items[2]; }} pc;\n\
            layout(location = 0) rayPayloadEXT vec4 c;\nvoid main() {{ c = vec4(pc.items[1].uv, pc.items[1].w, 1.0); }}\n");
        let m = module(&glsl);
        let st = push_struct(&m);
        assert_eq!(extent(&m, st, None), Some(28));
        assert_eq!(block_end(&m, st, Rules::Standard), Some(32));
    }

    #[test]
    fn scalar_alignment_is_the_largest_component() {
        let glsl = format!("{HEAD}#extension GL_EXT_shader_explicit_arithmetic_types : require\n\
            struct S {{ uint16_t a; double b; }};\nlayout(push_constant) uniform P {{ S s; u8vec4 v; }} pc;\n\
            layout(location = 0) rayPayloadEXT vec4 c;\nvoid main() {{ c = vec4(float(pc.s.b) + float(pc.v.x)); }}\n");
        let m = module(&glsl);
        let st = push_struct(&m);
        let d = def(&m, st).unwrap().clone();
        let (s, v) = (id_operand(&d, 0).unwrap(), id_operand(&d, 1).unwrap());
        assert_eq!(scalar_alignment(&m, s), Some(8));
        assert_eq!(scalar_alignment(&m, v), Some(1));
        assert_eq!(base_alignment(&m, v, false), Some(4));
    }
}
