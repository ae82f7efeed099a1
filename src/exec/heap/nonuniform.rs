//! The NonUniform word scan: how a SPIR-V module's accesses into each descriptor heap are
//! decorated, read from its words (no SPIR-V library).

/// SPIR-V opcodes and enumerants the NonUniform check reads (SPIR-V 1.6 unified spec;
/// SPV_KHR_untyped_pointers; SPV_EXT_descriptor_heap).
const OP_LOAD: u32 = 61;
const OP_DECORATE: u32 = 71;
const OP_SAMPLED_IMAGE: u32 = 86;
const OP_UNTYPED_ACCESS_CHAIN: u32 = 4419;
const OP_UNTYPED_IN_BOUNDS_ACCESS_CHAIN: u32 = 4420;
const DECORATION_BUILTIN: u32 = 11;
const DECORATION_NON_UNIFORM: u32 = 5300;
const BUILTIN_SAMPLER_HEAP: u32 = 5122;
const BUILTIN_RESOURCE_HEAP: u32 = 5123;

/// The module's instructions as (opcode, operands), stopping at a malformed word count (0, or
/// past the end).
fn instructions(words: &[u32]) -> impl Iterator<Item = (u32, &[u32])> {
    let mut i = 5; // after the header
    std::iter::from_fn(move || {
        let first = *words.get(i)?;
        let (count, op) = ((first >> 16) as usize, first & 0xffff);
        if count == 0 {
            return None;
        }
        let operands = words.get(i + 1..i + count)?;
        i += count;
        Some((op, operands))
    })
}

/// How a module's accesses into one descriptor heap (`layout(descriptor_heap)` arrays:
/// `OpUntypedAccessChainKHR` / `OpUntypedInBoundsAccessChainKHR` on the variable decorated
/// `BuiltIn ResourceHeapEXT` / `SamplerHeapEXT`) are decorated: `None` without such an access,
/// `Some(true)` when every one has `NonUniform` on its index, on itself, on the descriptor loaded
/// through it or on the sampled image made from that (where SPIR-V 2.16.2 and
/// VUID-RuntimeSpirv-NonUniform-06274 accept it), `Some(false)` when one has none of these.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct HeapNonUniform {
    pub resource: Option<bool>,
    pub sampler: Option<bool>,
}

pub fn heap_nonuniform(words: &[u32]) -> HeapNonUniform {
    let mut nonuniform = std::collections::HashSet::new();
    let (mut resource_heap, mut sampler_heap) = (None, None);
    for (op, o) in instructions(words) {
        match (op, o) {
            (OP_DECORATE, [id, d, ..]) if *d == DECORATION_NON_UNIFORM => {
                nonuniform.insert(*id);
            }
            (OP_DECORATE, [id, d, b, ..])
                if *d == DECORATION_BUILTIN && *b == BUILTIN_RESOURCE_HEAP =>
            {
                resource_heap = Some(*id)
            }
            (OP_DECORATE, [id, d, b, ..])
                if *d == DECORATION_BUILTIN && *b == BUILTIN_SAMPLER_HEAP =>
            {
                sampler_heap = Some(*id)
            }
            _ => {}
        }
    }
    // What is made from an id: loads through a pointer, sampled images from an image or sampler.
    let mut made_from: std::collections::HashMap<u32, Vec<u32>> = std::collections::HashMap::new();
    for (op, o) in instructions(words) {
        match (op, o) {
            (OP_LOAD, [_, result, pointer, ..]) => {
                made_from.entry(*pointer).or_default().push(*result)
            }
            (OP_SAMPLED_IMAGE, [_, result, image, sampler]) => {
                made_from.entry(*image).or_default().push(*result);
                made_from.entry(*sampler).or_default().push(*result);
            }
            _ => {}
        }
    }
    let uses = |id: &u32| made_from.get(id).into_iter().flatten().copied().collect::<Vec<u32>>();
    let mut out = HeapNonUniform::default();
    for (op, o) in instructions(words) {
        // OpUntyped(InBounds)AccessChainKHR: result type, result, base type, base, indexes...
        if let (
            OP_UNTYPED_ACCESS_CHAIN | OP_UNTYPED_IN_BOUNDS_ACCESS_CHAIN,
            [_, result, _, base, first, ..],
        ) = (op, o)
        {
            let loads = uses(result);
            let sampled: Vec<u32> = loads.iter().flat_map(&uses).collect();
            let decorated = [*result, *first]
                .iter()
                .chain(&loads)
                .chain(&sampled)
                .any(|id| nonuniform.contains(id));
            let slot = if Some(*base) == resource_heap {
                &mut out.resource
            } else if Some(*base) == sampler_heap {
                &mut out.sampler
            } else {
                continue;
            };
            *slot = Some(slot.unwrap_or(true) && decorated);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nonuniform_decorations_are_found_and_their_absence_too() {
        // OpCapability Shader; %10 the resource heap; %30 = an access chain into it at index %20.
        let header = [0x0723_0203, 0x0001_0600, 0, 40, 0];
        let module = |decoration: &[u32]| -> Vec<u32> {
            let base = [
                (2 << 16) | 17,
                1,
                (4 << 16) | OP_DECORATE,
                10,
                DECORATION_BUILTIN,
                BUILTIN_RESOURCE_HEAP,
            ];
            header
                .iter()
                .chain(&base)
                .chain(decoration)
                .chain(&[(6 << 16) | OP_UNTYPED_ACCESS_CHAIN, 1, 30, 2, 10, 20])
                .copied()
                .collect()
        };
        // OpDecorate %20 NonUniform
        assert_eq!(
            heap_nonuniform(&module(&[(3 << 16) | OP_DECORATE, 20, DECORATION_NON_UNIFORM]))
                .resource,
            Some(true)
        );
        // OpDecorate %20 Binding 2... with a NonUniform-valued operand: must not count
        assert_eq!(
            heap_nonuniform(&module(&[(4 << 16) | OP_DECORATE, 20, 33, DECORATION_NON_UNIFORM]))
                .resource,
            Some(false)
        );
        assert_eq!(heap_nonuniform(&module(&[])).resource, Some(false));
        assert_eq!(heap_nonuniform(&header), HeapNonUniform::default());
        // a zero word count ends nowhere near an infinite loop
        assert_eq!(heap_nonuniform(&[0, 0, 0, 0, 0, 0, 0]), HeapNonUniform::default());
    }

    /// Per heap: an untyped access chain into the sampler heap whose index is decorated, one into
    /// the resource heap whose index is not (what glslang 16.6 emits when it keeps one qualifier
    /// and drops the other), and a module with no heap access at all.
    #[test]
    fn heap_accesses_are_judged_per_heap_by_their_own_decoration() {
        let header = [0x0723_0203, 0x0001_0600, 0, 40, 0];
        let decorate = |id: u32, d: u32, extra: &[u32]| -> Vec<u32> {
            [vec![((3 + extra.len() as u32) << 16) | OP_DECORATE, id, d], extra.to_vec()].concat()
        };
        let chain = |result: u32, base: u32, index: u32| {
            vec![(6 << 16) | OP_UNTYPED_ACCESS_CHAIN, 1, result, 2, base, index]
        };
        let module = |parts: Vec<Vec<u32>>| -> Vec<u32> {
            header.iter().copied().chain(parts.into_iter().flatten()).collect()
        };
        // %10 resource heap, %11 sampler heap; %20 / %21 indices; %30 / %31 chains.
        let builtins = vec![
            decorate(10, DECORATION_BUILTIN, &[BUILTIN_RESOURCE_HEAP]),
            decorate(11, DECORATION_BUILTIN, &[BUILTIN_SAMPLER_HEAP]),
        ];
        let m = module(
            [
                builtins.clone(),
                vec![decorate(21, DECORATION_NON_UNIFORM, &[])],
                vec![chain(30, 10, 20), chain(31, 11, 21)],
            ]
            .concat(),
        );
        assert_eq!(
            heap_nonuniform(&m),
            HeapNonUniform { resource: Some(false), sampler: Some(true) }
        );
        // decorated on the chain's result instead of the index counts too
        let m = module(
            [
                builtins.clone(),
                vec![decorate(30, DECORATION_NON_UNIFORM, &[])],
                vec![chain(30, 10, 20)],
            ]
            .concat(),
        );
        assert_eq!(heap_nonuniform(&m), HeapNonUniform { resource: Some(true), sampler: None });
        // a NonUniform elsewhere does not vouch for an undecorated heap access
        let m = module(
            [builtins, vec![decorate(99, DECORATION_NON_UNIFORM, &[])], vec![chain(31, 11, 21)]]
                .concat(),
        );
        assert!(instructions(&m).any(|(op, o)| op == OP_DECORATE && o[1] == DECORATION_NON_UNIFORM));
        assert_eq!(heap_nonuniform(&m), HeapNonUniform { resource: None, sampler: Some(false) });
        assert_eq!(heap_nonuniform(&header), HeapNonUniform::default());
        // decorated on the sampled image made from the loaded sampler (where the VUID wants it)
        let m = module(vec![
            decorate(11, DECORATION_BUILTIN, &[BUILTIN_SAMPLER_HEAP]),
            decorate(41, DECORATION_NON_UNIFORM, &[]),
            chain(31, 11, 21),
            vec![(4 << 16) | OP_LOAD, 3, 40, 31],
            vec![(5 << 16) | OP_SAMPLED_IMAGE, 4, 41, 39, 40],
        ]);
        assert_eq!(heap_nonuniform(&m), HeapNonUniform { resource: None, sampler: Some(true) });
        // truncated or zero word counts: no panic, no loop
        assert_eq!(
            heap_nonuniform(&[0x0723_0203, 0, 0, 0, 0, (9 << 16) | OP_UNTYPED_ACCESS_CHAIN, 1]),
            HeapNonUniform::default()
        );
        assert_eq!(heap_nonuniform(&[0x0723_0203, 0, 0, 0, 0, 0, 0, 0]), HeapNonUniform::default());
    }
}
