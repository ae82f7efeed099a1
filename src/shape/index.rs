//! Where a descriptor index comes from: its definitions walked back to their leaves —
//! constants, spec constants, push-constant loads, built-in loads, other loads, function
//! parameters, `OpUndef` — through arithmetic, conversions, selects, phis and the stores to a
//! function-local variable. The source is the matrix's `index` axis value: only constants
//! `literal`, a spec constant among them `spec_constant`, a push constant among them
//! `push_constant`, anything else `dynamic`.
use super::defs::Defs;
use crate::model::IndexSource;
use rspirv::dr::Operand;
use rspirv::spirv::{BuiltIn, Decoration, Op, StorageClass, Word};
use std::collections::HashSet;

/// The leaves of an index expression.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Leaves {
    pub constant: bool,
    pub spec: bool,
    pub push: bool,
    /// Built-ins and other loads, parameters: what makes the index dynamic, named.
    pub dynamic: Vec<String>,
    /// An `OpUndef` reaches the index.
    pub undef: bool,
}

impl Leaves {
    /// The matrix's index source.
    pub fn source(&self) -> IndexSource {
        if !self.dynamic.is_empty() || self.undef {
            IndexSource::Dynamic
        } else if self.push {
            IndexSource::PushConstant
        } else if self.spec {
            IndexSource::SpecConstant
        } else {
            IndexSource::Literal
        }
    }
}

/// The leaves of value `id`.
pub fn leaves(d: &Defs, id: Word) -> Leaves {
    let mut out = Leaves::default();
    walk(d, id, &mut out, &mut HashSet::new());
    out.dynamic.sort();
    out.dynamic.dedup();
    out
}

/// GLSL's name of a built-in, else its SPIR-V name.
pub fn builtin_name(b: BuiltIn) -> String {
    let s = match b {
        BuiltIn::InstanceCustomIndexKHR => "gl_InstanceCustomIndexEXT",
        BuiltIn::InstanceId => "gl_InstanceID",
        BuiltIn::PrimitiveId => "gl_PrimitiveID",
        BuiltIn::RayGeometryIndexKHR => "gl_GeometryIndexEXT",
        BuiltIn::LaunchIdKHR => "gl_LaunchIDEXT",
        BuiltIn::LaunchSizeKHR => "gl_LaunchSizeEXT",
        BuiltIn::HitKindKHR => "gl_HitKindEXT",
        BuiltIn::IncomingRayFlagsKHR => "gl_IncomingRayFlagsEXT",
        BuiltIn::SubgroupLocalInvocationId => "gl_SubgroupInvocationID",
        BuiltIn::LocalInvocationIndex => "gl_LocalInvocationIndex",
        BuiltIn::GlobalInvocationId => "gl_GlobalInvocationID",
        BuiltIn::VertexIndex => "gl_VertexIndex",
        other => return format!("BuiltIn {other:?}"),
    };
    s.to_string()
}

fn walk(d: &Defs, id: Word, out: &mut Leaves, seen: &mut HashSet<Word>) {
    if !seen.insert(id) {
        return;
    }
    let Some(i) = d.get(id) else {
        out.dynamic.push(format!("%{id}"));
        return;
    };
    match i.class.opcode {
        Op::Constant | Op::ConstantNull | Op::ConstantTrue | Op::ConstantFalse => {
            out.constant = true
        }
        Op::ConstantComposite => ids(i).for_each(|x| walk(d, x, out, seen)),
        Op::SpecConstant | Op::SpecConstantTrue | Op::SpecConstantFalse | Op::SpecConstantOp => {
            out.spec = true
        }
        Op::SpecConstantComposite => out.spec = true,
        Op::Undef => out.undef = true,
        Op::FunctionParameter => out.dynamic.push(format!("parameter %{id}")),
        Op::Load => load(d, i.operands.first().and_then(id_of), out, seen),
        Op::Variable => out.dynamic.push(format!("variable %{id}")),
        _ => ids(i).filter(|x| is_value(d, *x)).for_each(|x| walk(d, x, out, seen)),
    }
}

/// A load's leaves: from its pointer's root variable.
fn load(d: &Defs, ptr: Option<Word>, out: &mut Leaves, seen: &mut HashSet<Word>) {
    let Some(ptr) = ptr else { return };
    let (root, chain) = d.root(ptr);
    for x in chain.into_iter().flatten() {
        walk(d, x, out, seen);
    }
    match d.storage_class(root) {
        Some(StorageClass::PushConstant) => out.push = true,
        Some(StorageClass::Function | StorageClass::Private) => {
            let (values, known) = d.stored_values(root);
            // Never written: the load reads an undefined value.
            if values.is_empty() && !known {
                out.undef = true;
            }
            if known {
                out.dynamic.push(format!("copy into {}", d.name(root)));
            }
            for v in values {
                walk(d, v, out, seen);
            }
        }
        Some(StorageClass::Input) => match d.builtin(root) {
            Some(b) => out.dynamic.push(builtin_name(b)),
            None => out.dynamic.push(format!("input {}", d.name(root))),
        },
        _ if d.get(root).is_some_and(|v| v.class.opcode == Op::Undef) => out.undef = true,
        _ => out.dynamic.push(format!("load from {}", d.name(root))),
    }
}

/// Whether `id` names a value (not a type).
fn is_value(d: &Defs, id: Word) -> bool {
    d.get(id).is_some_and(|i| i.result_type.is_some())
}

fn id_of(o: &Operand) -> Option<Word> {
    match o {
        Operand::IdRef(w) => Some(*w),
        _ => None,
    }
}

fn ids(i: &rspirv::dr::Instruction) -> impl Iterator<Item = Word> + '_ {
    i.operands.iter().filter_map(id_of)
}

/// Whether `id` carries a `NonUniform` decoration.
pub fn nonuniform(d: &Defs, id: Word) -> bool {
    d.decorated(id, Decoration::NonUniform)
}
