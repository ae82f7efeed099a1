//! Finding what a mutant rewrites in a probe module, from what the probe spec says it reads: the
//! probed array (the variable at set 0, binding 2, or the resource heap), the sampler heap, the
//! AS address table and the `probeValue` the probe stores. Nothing is guessed from shapes the
//! probe does not write: a module without the access has no site, and the caller says so.
use crate::patches::edit::{self, id_operand};
use rspirv::dr::{Instruction, Module, Operand};
use rspirv::spirv::{BuiltIn, Decoration, Op, Word};

/// The binding of the probed array (`shadergen::probe_code`: set 0, binding 2).
pub const PROBE_BINDING: u32 = 2;

/// An operand of an instruction inside a function: the instruction's place and the operand's
/// index (rspirv's operands, after the result type and id).
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub struct At {
    pub func: usize,
    pub block: usize,
    pub inst: usize,
    pub operand: usize,
}

impl At {
    pub fn instruction<'m>(&self, m: &'m Module) -> &'m Instruction {
        &m.functions[self.func].blocks[self.block].instructions[self.inst]
    }

    /// The id at the operand.
    pub fn id(&self, m: &Module) -> Option<Word> {
        id_operand(self.instruction(m), self.operand)
    }
}

/// Every instruction in functions with its place.
fn instructions(m: &Module) -> impl Iterator<Item = ((usize, usize, usize), &Instruction)> {
    m.functions.iter().enumerate().flat_map(|(f, func)| {
        func.blocks.iter().enumerate().flat_map(move |(b, block)| {
            block.instructions.iter().enumerate().map(move |(i, inst)| ((f, b, i), inst))
        })
    })
}

/// The place of the instruction defining `id` in a function.
pub fn place(m: &Module, id: Word) -> Option<(usize, usize, usize)> {
    instructions(m).find(|(_, i)| i.result_id == Some(id)).map(|(p, _)| p)
}

/// The global variable of the probed array: decorated `DescriptorSet 0`, `Binding 2`.
pub fn probe_variable(m: &Module) -> Option<Word> {
    edit::descriptor_variables(m).into_iter().find(|v| {
        edit::decoration_literal(m, *v, Decoration::DescriptorSet) == Some(0)
            && edit::decoration_literal(m, *v, Decoration::Binding) == Some(PROBE_BINDING)
    })
}

/// The variable decorated `BuiltIn builtin` (the resource or sampler heap).
pub fn builtin_variable(m: &Module, builtin: BuiltIn) -> Option<Word> {
    m.annotations.iter().find_map(|a| {
        let hit = a.class.opcode == Op::Decorate
            && a.operands.get(1) == Some(&Operand::Decoration(Decoration::BuiltIn))
            && a.operands.get(2) == Some(&Operand::BuiltIn(builtin));
        if hit {
            id_operand(a, 0)
        } else {
            None
        }
    })
}

fn is_chain(op: Op) -> bool {
    matches!(op, Op::AccessChain | Op::InBoundsAccessChain)
}

fn is_untyped_chain(op: Op) -> bool {
    matches!(op, Op::UntypedAccessChainKHR | Op::UntypedInBoundsAccessChainKHR)
}

/// Access chains into `var` (typed: `OpAccessChain var idx…`) with their place.
fn chains_into(m: &Module, var: Word) -> Vec<((usize, usize, usize), &Instruction)> {
    instructions(m)
        .filter(|(_, i)| is_chain(i.class.opcode) && id_operand(i, 0) == Some(var))
        .collect()
}

/// Untyped access chains into the heap `heap` (`OpUntypedAccessChainKHR base-type heap idx…`).
fn untyped_chains_into(m: &Module, heap: Word) -> Vec<((usize, usize, usize), &Instruction)> {
    instructions(m)
        .filter(|(_, i)| is_untyped_chain(i.class.opcode) && id_operand(i, 1) == Some(heap))
        .collect()
}

fn at((func, block, inst): (usize, usize, usize), operand: usize) -> At {
    At { func, block, inst, operand }
}

/// The descriptor index of every access into the probed array: operand 1 of a chain into the
/// binding-2 variable (`heap = false`), or operand 2 (after the base type and the heap) of an
/// untyped chain into the resource heap (`layout(descriptor_heap)`: only the probed array is
/// read from the heap; records and TLAS are mapped bindings).
pub fn descriptor_indices(m: &Module, heap: bool) -> Vec<At> {
    if heap {
        let Some(h) = builtin_variable(m, BuiltIn::ResourceHeapEXT) else { return vec![] };
        untyped_chains_into(m, h).into_iter().map(|(p, i)| at(p, heap_array_index(m, i))).collect()
    } else {
        let Some(v) = probe_variable(m) else { return vec![] };
        chains_into(m, v)
            .into_iter()
            .filter(|(_, i)| i.operands.len() >= 2)
            .map(|(p, _)| at(p, 1))
            .collect()
    }
}

/// The sampler index of every access into the sampler heap (direct sampled-image probes).
pub fn sampler_indices(m: &Module) -> Vec<At> {
    let Some(h) = builtin_variable(m, BuiltIn::SamplerHeapEXT) else { return vec![] };
    untyped_chains_into(m, h).into_iter().map(|(p, i)| at(p, heap_array_index(m, i))).collect()
}

/// The operand of an untyped heap chain that indexes the descriptor array: operand 2 (after the
/// base type and the heap) when the base type is the array itself, operand 3 when it is a block
/// holding the array as member 0 (glslang 16 declares `layout(descriptor_heap) image2D a[]` as
/// `struct { a[] }` with `OffsetIdEXT`, and chains `%heap 0 %slot`): the member index is not the
/// descriptor index, and rewriting it made index-zero a no-op and index-next an invalid member.
fn heap_array_index(m: &Module, chain: &Instruction) -> usize {
    let base_type = id_operand(chain, 0);
    let is_struct = m
        .types_global_values
        .iter()
        .any(|t| t.result_id == base_type && t.class.opcode == Op::TypeStruct);
    if is_struct && chain.operands.len() > 3 {
        3
    } else {
        2
    }
}

/// The element index of every read of the packed buffer (`v[packedElement(…)]`): the last index
/// of a chain `probeBuf[i].v[e]` into the binding-2 variable (`var, i, 0, e`), or of the chain
/// into the buffer an `OpBufferPointerEXT` made from a resource-heap access (`p, 0, e`).
pub fn packed_elements(m: &Module, heap: bool) -> Vec<At> {
    if !heap {
        let Some(v) = probe_variable(m) else { return vec![] };
        return chains_into(m, v)
            .into_iter()
            .filter(|(_, i)| i.operands.len() == 4)
            .map(|(p, _)| at(p, 3))
            .collect();
    }
    let Some(h) = builtin_variable(m, BuiltIn::ResourceHeapEXT) else { return vec![] };
    let heap_chains: Vec<Word> =
        untyped_chains_into(m, h).into_iter().filter_map(|(_, i)| i.result_id).collect();
    let buffers: Vec<Word> = instructions(m)
        .filter(|(_, i)| {
            i.class.opcode == Op::BufferPointerEXT
                && id_operand(i, 0).is_some_and(|c| heap_chains.contains(&c))
        })
        .filter_map(|(_, i)| i.result_id)
        .collect();
    instructions(m)
        .filter(|(_, i)| {
            is_chain(i.class.opcode)
                && i.operands.len() == 3
                && id_operand(i, 0).is_some_and(|b| buffers.contains(&b))
        })
        .map(|(p, _)| at(p, 2))
        .collect()
}

/// What `id` was loaded from, through `OpLoad`.
fn loaded_from(m: &Module, id: Word) -> Option<Word> {
    let d = edit::def(m, id)?;
    (d.class.opcode == Op::Load).then(|| id_operand(d, 0)).flatten()
}

/// Whether `image` (an image or sampled image) is read from the probed array: loaded through a
/// chain into the binding-2 variable or the resource heap, or made by `OpSampledImage` from one.
fn from_probed_array(m: &Module, image: Word, var: Option<Word>, heap: Option<Word>) -> bool {
    let Some(d) = edit::def(m, image) else { return false };
    if d.class.opcode == Op::SampledImage {
        return id_operand(d, 0).is_some_and(|i| from_probed_array(m, i, var, heap));
    }
    let Some(chain) = loaded_from(m, image).and_then(|p| edit::def(m, p)) else { return false };
    (is_chain(chain.class.opcode) && id_operand(chain, 0).is_some() && id_operand(chain, 0) == var)
        || (is_untyped_chain(chain.class.opcode)
            && id_operand(chain, 1).is_some()
            && id_operand(chain, 1) == heap)
}

/// The coordinate operand of every sample from the probed array texture (`textureLod` of the
/// `sampler2DArray` / `texture2DArray` of `index=dynamic_element`: its third component is the
/// layer).
pub fn sample_coordinates(m: &Module) -> Vec<At> {
    let var = probe_variable(m);
    let heap = builtin_variable(m, BuiltIn::ResourceHeapEXT);
    instructions(m)
        .filter(|(_, i)| {
            matches!(i.class.opcode, Op::ImageSampleExplicitLod | Op::ImageSampleImplicitLod)
                && id_operand(i, 0).is_some_and(|s| from_probed_array(m, s, var, heap))
        })
        .map(|(p, _)| at(p, 1))
        .collect()
}

/// The table index of every acceleration structure made from an address
/// (`OpConvertUToAccelerationStructureKHR` of a 64-bit load): the last index of the chain into
/// the table the GLSL indexes (`AsTable(…).a[idx]`, `as_access=address`), or the index
/// `OpUConvert`ed, scaled by 8 and added to the table address (as-to-address's load sequence,
/// `patches::edit::table_entry`, `as_access=address_patched`).
pub fn address_indices(m: &Module) -> Vec<At> {
    let converts: Vec<Word> = instructions(m)
        .filter(|(_, i)| i.class.opcode == Op::ConvertUToAccelerationStructureKHR)
        .filter_map(|(_, i)| id_operand(i, 0))
        .collect();
    let mut out = vec![];
    for addr in converts {
        let Some(ptr) = loaded_from(m, addr) else { continue };
        let Some(d) = edit::def(m, ptr) else { continue };
        if is_chain(d.class.opcode) && d.operands.len() >= 2 {
            out.extend(place(m, ptr).map(|p| at(p, d.operands.len() - 1)));
        } else if d.class.opcode == Op::ConvertUToPtr {
            out.extend(patched_table_index(m, d));
        }
    }
    out
}

/// `ConvertUToPtr(IAdd(base, IMul(UConvert(idx), 8)))`: the `OpUConvert`'s operand.
fn patched_table_index(m: &Module, convert: &Instruction) -> Option<At> {
    let sum = edit::def(m, id_operand(convert, 0)?)?;
    (sum.class.opcode == Op::IAdd).then_some(())?;
    let scaled = (0..2).find_map(|k| {
        let d = edit::def(m, id_operand(sum, k)?)?;
        (d.class.opcode == Op::IMul).then_some(d)
    })?;
    (0..2).find_map(|k| {
        let id = id_operand(scaled, k)?;
        let d = edit::def(m, id)?;
        (d.class.opcode == Op::UConvert).then(|| place(m, id).map(|p| at(p, 0))).flatten()
    })
}

/// The function variable the probe stores its value in (`vec4 probeValue`, named so by the
/// probe contract; shaderc and glslang keep names: rtprobe compiles without optimization).
pub fn probe_value_variable(m: &Module) -> Option<Word> {
    m.debug_names.iter().find_map(|n| {
        let named = n.class.opcode == Op::Name
            && matches!(n.operands.get(1), Some(Operand::LiteralString(s)) if s == "probeValue");
        if named {
            id_operand(n, 0)
        } else {
            None
        }
    })
}

/// The value operand of every store to `var`.
pub fn stores_to(m: &Module, var: Word) -> Vec<At> {
    instructions(m)
        .filter(|(_, i)| i.class.opcode == Op::Store && id_operand(i, 0) == Some(var))
        .map(|(p, _)| at(p, 1))
        .collect()
}
