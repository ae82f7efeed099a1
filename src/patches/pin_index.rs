//! `pin-index`: the runtime index of dynamically indexed descriptor-array accesses becomes an
//! `OpSpecConstant` (default value given) — turning a dynamic-index shader into its spec-constant
//! form, the main isolation step when bisecting a fault.
//!
//! SPIR-V rules relied on: an `OpSpecConstant` of the index's integer type, decorated `SpecId`, is a
//! valid (dynamically uniform) access-chain index; `SpecId`s must be unique in the module, so a
//! fresh one is chosen unless given. The `NonUniform` decorations on the replaced chain and the
//! objects derived from it stay valid (they only permit non-uniformity).
use super::dynamic_access;
use super::edit;
use super::PatchError;
use rspirv::dr::{Instruction, Module, Operand};
use rspirv::spirv::{Decoration, Op};

#[derive(Clone, Debug, Default)]
pub struct Options {
    /// Only accesses to the variable with this binding (default: every dynamic access).
    pub binding: Option<u32>,
    /// The spec constant's default value (default 0).
    pub value: u32,
    /// Its SpecId (default: one more than the largest in the module, or 0).
    pub spec_id: Option<u32>,
}

#[derive(Clone, Debug, PartialEq)]
pub struct Report {
    pub pinned: usize,
    pub spec_id: u32,
}

pub fn apply(m: &mut Module, opts: &Options) -> Result<Report, PatchError> {
    const NAME: &str = "pin-index";
    let accesses: Vec<_> = dynamic_access::find(m)
        .into_iter()
        .filter(|a| opts.binding.is_none_or(|b| dynamic_access::binding(m, a.var) == Some(b)))
        .collect();
    if accesses.is_empty() {
        let what = match opts.binding {
            Some(b) => format!("no dynamically indexed descriptor array at binding {b}"),
            None => "no dynamically indexed descriptor array".into(),
        };
        return Err(PatchError::NothingToPatch { patch: NAME, what });
    }
    let used: Vec<u32> = m
        .annotations
        .iter()
        .filter_map(|a| match (a.class.opcode, a.operands.get(1), a.operands.get(2)) {
            (
                Op::Decorate,
                Some(Operand::Decoration(Decoration::SpecId)),
                Some(Operand::LiteralBit32(v)),
            ) => Some(*v),
            _ => None,
        })
        .collect();
    let spec_id = match opts.spec_id {
        Some(id) if used.contains(&id) => {
            return Err(PatchError::BadOption {
                patch: NAME,
                what: format!("spec-id={id} is already used by the module"),
            })
        }
        Some(id) => id,
        None => used.iter().max().map(|v| v + 1).unwrap_or(0),
    };
    // One spec constant per index type.
    let mut by_type: std::collections::HashMap<u32, u32> = Default::default();
    for a in &accesses {
        let ty =
            edit::def(m, a.index).and_then(|d| d.result_type).ok_or(PatchError::Unsupported {
                patch: NAME,
                id: a.index,
                what: "index without a type".into(),
            })?;
        let sc = match by_type.get(&ty) {
            Some(sc) => *sc,
            None => {
                let sc = edit::next_id(m);
                m.types_global_values.push(Instruction::new(
                    Op::SpecConstant,
                    Some(ty),
                    Some(sc),
                    vec![Operand::LiteralBit32(opts.value)],
                ));
                edit::decorate(m, sc, Decoration::SpecId, &[Operand::LiteralBit32(spec_id)]);
                by_type.insert(ty, sc);
                sc
            }
        };
        m.functions[a.func].blocks[a.block].instructions[a.inst].operands[1] = Operand::IdRef(sc);
    }
    if by_type.len() > 1 {
        return Err(PatchError::Unsupported {
            patch: NAME,
            id: accesses[0].chain,
            what: "dynamic indices of different integer types share one SpecId".into(),
        });
    }
    Ok(Report { pinned: accesses.len(), spec_id })
}
