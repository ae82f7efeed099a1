//! `pin-index`: the runtime index of dynamically indexed descriptor-array accesses becomes an
//! `OpSpecConstant` (default value given) — turning a dynamic-index shader into its spec-constant
//! form, the main isolation step when bisecting a fault. Each descriptor (set, binding) gets its
//! own `SpecId` ([`SpecIds`], shared by a pipeline's stages so a descriptor has the same one in
//! every stage), so the host can pin each array to its own element.
//!
//! SPIR-V rules relied on: an access-chain index may be any scalar integer, of either signedness
//! and width ("Indexes must be scalar integer type"), so one 32-bit unsigned `OpSpecConstant`
//! replaces indices of every integer type (int, uint, 64-bit) alike; `SpecId`s must be unique in
//! a module, so fresh ones are chosen unless given. The `NonUniform` decorations on the replaced
//! chain and the objects derived from it stay valid (they only permit non-uniformity).
use super::dynamic_access;
use super::edit;
use super::PatchError;
use rspirv::dr::{Instruction, Module, Operand};
use rspirv::spirv::{Decoration, Op};
use std::collections::{BTreeMap, BTreeSet};

#[derive(Clone, Debug, Default)]
pub struct Options {
    /// Only accesses to variables of this descriptor set (default: every set).
    pub set: Option<u32>,
    /// Only accesses to the variable with this binding (default: every dynamic access).
    pub binding: Option<u32>,
    /// The spec constants' default value (default 0).
    pub value: u32,
}

/// A descriptor pinned: its set, binding and SpecId.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Pinned {
    pub set: u32,
    pub binding: u32,
    pub spec_id: u32,
}

#[derive(Clone, Debug, PartialEq)]
pub struct Report {
    pub pinned: usize,
    pub descriptors: Vec<Pinned>,
}

const NAME: &str = "pin-index";

/// The SpecIds of one pipeline's pinned descriptors: from `first` when given (each must be free
/// in every module), else past every SpecId any of its modules uses.
#[derive(Clone, Debug)]
pub struct SpecIds {
    next: u32,
    given: bool,
    used: BTreeSet<u32>,
    by_descriptor: BTreeMap<(u32, u32), u32>,
}

/// The SpecIds `m` decorates.
pub fn used(m: &Module) -> BTreeSet<u32> {
    m.annotations
        .iter()
        .filter_map(|a| match (a.class.opcode, a.operands.get(1), a.operands.get(2)) {
            (
                Op::Decorate,
                Some(Operand::Decoration(Decoration::SpecId)),
                Some(Operand::LiteralBit32(v)),
            ) => Some(*v),
            _ => None,
        })
        .collect()
}

impl SpecIds {
    /// `used`: every SpecId of the pipeline's modules; `first`: the `spec-id` option.
    pub fn new(used: BTreeSet<u32>, first: Option<u32>) -> SpecIds {
        let next = first.unwrap_or_else(|| used.iter().max().map_or(0, |v| v + 1));
        SpecIds { next, given: first.is_some(), used, by_descriptor: BTreeMap::new() }
    }

    /// The SpecId of descriptor (set, binding).
    fn of(&mut self, set: u32, binding: u32) -> Result<u32, PatchError> {
        if let Some(id) = self.by_descriptor.get(&(set, binding)) {
            return Ok(*id);
        }
        let id = self.next;
        if self.given && self.used.contains(&id) {
            return Err(PatchError::BadOption {
                patch: NAME,
                what: format!("spec-id={id} is already used by the module"),
            });
        }
        self.next += 1;
        self.by_descriptor.insert((set, binding), id);
        Ok(id)
    }
}

/// Pin every dynamic descriptor-array index `opts` selects to its descriptor's spec constant.
pub fn apply(m: &mut Module, opts: &Options, ids: &mut SpecIds) -> Result<Report, PatchError> {
    let lit = |m: &Module, v, d| edit::decoration_literal(m, v, d).unwrap_or(0);
    let accesses: Vec<_> = dynamic_access::find(m)
        .into_iter()
        .filter(|a| {
            opts.set.is_none_or(|s| lit(m, a.var, Decoration::DescriptorSet) == s)
                && opts.binding.is_none_or(|b| lit(m, a.var, Decoration::Binding) == b)
        })
        .collect();
    if accesses.is_empty() {
        let what = match (opts.set, opts.binding) {
            (None, None) => "no dynamically indexed descriptor array".into(),
            (s, b) => format!(
                "no dynamically indexed descriptor array at{}{}",
                s.map(|s| format!(" set {s}")).unwrap_or_default(),
                b.map(|b| format!(" binding {b}")).unwrap_or_default()
            ),
        };
        return Err(PatchError::NothingToPatch { patch: NAME, what });
    }
    let u32_t = edit::type_int(m, 32, false);
    let mut constants: BTreeMap<(u32, u32), u32> = BTreeMap::new();
    let mut descriptors = Vec::new();
    for a in &accesses {
        let key = (lit(m, a.var, Decoration::DescriptorSet), lit(m, a.var, Decoration::Binding));
        let sc = match constants.get(&key) {
            Some(sc) => *sc,
            None => {
                let spec_id = ids.of(key.0, key.1)?;
                let sc = edit::next_id(m);
                m.types_global_values.push(Instruction::new(
                    Op::SpecConstant,
                    Some(u32_t),
                    Some(sc),
                    vec![Operand::LiteralBit32(opts.value)],
                ));
                edit::decorate(m, sc, Decoration::SpecId, &[Operand::LiteralBit32(spec_id)]);
                descriptors.push(Pinned { set: key.0, binding: key.1, spec_id });
                constants.insert(key, sc);
                sc
            }
        };
        m.functions[a.func].blocks[a.block].instructions[a.inst].operands[1] = Operand::IdRef(sc);
    }
    Ok(Report { pinned: accesses.len(), descriptors })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn module(glsl: &str) -> Module {
        crate::patches::compiled(shaderc::ShaderKind::ClosestHit, "t.rchit", glsl)
    }

    const MIXED: &str = "#version 460\n#extension GL_EXT_ray_tracing : require\n\
        #extension GL_EXT_nonuniform_qualifier : require\n\
        layout(set = 2, binding = 0) readonly buffer A { vec4 a[]; } as_[3];\n\
        layout(set = 3, binding = 0) readonly buffer B { vec4 b[]; } bs[3];\n\
        layout(location = 0) rayPayloadInEXT vec4 c;\n\
        void main() { uint u = uint(gl_InstanceCustomIndexEXT) % 3u; int i = gl_PrimitiveID % 3;\n\
        c = as_[nonuniformEXT(u)].a[0] + bs[nonuniformEXT(i)].b[1] + as_[nonuniformEXT(i)].a[2]; }\n";

    #[test]
    fn each_descriptor_gets_its_own_spec_id_whatever_its_index_type() {
        // Set 2 and set 3, both binding 0, indexed by uint and int: binding=0 alone pins both, each
        // with its own SpecId (one 32-bit unsigned spec constant each).
        let mut m = module(MIXED);
        let mut ids = SpecIds::new(used(&m), None);
        let o = Options { binding: Some(0), value: 1, ..Options::default() };
        let r = apply(&mut m, &o, &mut ids).expect("int and uint indices are pinned alike");
        assert_eq!(r.pinned, 3);
        let pairs: Vec<(u32, u32, u32)> =
            r.descriptors.iter().map(|d| (d.set, d.binding, d.spec_id)).collect();
        assert_eq!(pairs, vec![(2, 0, 0), (3, 0, 1)]);
        let specs: Vec<_> =
            m.types_global_values.iter().filter(|i| i.class.opcode == Op::SpecConstant).collect();
        assert_eq!(specs.len(), 2);
        let u32_t = edit::type_int(&mut m.clone(), 32, false);
        assert!(specs.iter().all(|s| s.result_type == Some(u32_t)));
        let v = crate::patches::validate(&crate::patches::assemble(&m));
        assert!(
            matches!(
                v,
                crate::patches::Validation::Valid | crate::patches::Validation::Unavailable
            ),
            "{v:?}"
        );
        // set=3 narrows it to one descriptor; a SpecId the module already uses is refused.
        let mut m = module(MIXED);
        let o = Options { set: Some(3), ..Options::default() };
        let mut ids = SpecIds::new(used(&m), None);
        assert_eq!(apply(&mut m, &o, &mut ids).unwrap().pinned, 1);
        let taken = used(&m);
        let e = apply(&mut module(MIXED), &Options::default(), &mut SpecIds::new(taken, Some(0)));
        assert!(e.unwrap_err().to_string().contains("spec-id=0 is already used"));
    }
}
