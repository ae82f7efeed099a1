//! The remaining descriptor accesses rendered GLSL-like, for `reduce`'s `access.txt`: each
//! access's variable declared (its block printed by `reflect::glsl` where it has one) and the
//! read with its index expression (arithmetic, conversions, constants, built-ins and
//! push-constant members by name; anything else as `%id`), after a comment with its class.
use super::defs::Defs;
use super::index::builtin_name;
use super::Found;
use crate::model::Resource;
use crate::reflect::glsl::Glsl;
use rspirv::dr::{Module, Operand};
use rspirv::spirv::{Op, StorageClass, Word};

/// `access.txt`'s text for `found` in `m`.
pub fn render(m: &Module, found: &[Found]) -> String {
    let d = Defs::new(m);
    let refl = crate::reflect::reflect(m, None).ok();
    let mut out = String::new();
    for f in found {
        let c = &f.class;
        out.push_str(&format!(
            "// {} reads {} {} ({} index{}{}), {} through {}\n",
            c.stage,
            c.resource,
            c.variable,
            c.index,
            if c.index_from.is_empty() {
                String::new()
            } else {
                format!(" from {}", c.index_from.join(", "))
            },
            if c.nonuniform { ", NonUniform" } else { "" },
            c.op,
            c.through
        ));
        let binding = refl.as_ref().and_then(|r| {
            r.bindings.iter().find(|b| Some(b.set) == c.set && Some(b.binding) == c.binding)
        });
        if let Some(b) = binding.and_then(|b| b.block.as_ref().map(|k| (b, k))) {
            let mut g = Glsl::default();
            let dims = if f.index.is_some() { "[]" } else { "" };
            let q = format!("set = {}, binding = {}", b.0.set, b.0.binding);
            let kind = match c.resource {
                Resource::UniformBuffer => "uniform",
                Resource::StorageBuffer
                | Resource::SampledImage
                | Resource::StorageImage
                | Resource::AccelerationStructure => "buffer",
            };
            if let Ok(text) = g.block(&q, kind, &b.1.ty, &format!("{}{dims}", c.variable)) {
                out.push_str(&g.preamble());
                out.push_str(&text);
            }
        }
        let index = f.index.map(|x| expr(&d, x, 0)).unwrap_or_default();
        let index = match (f.index.is_some(), c.nonuniform) {
            (false, _) => String::new(),
            (true, true) => format!("[nonuniformEXT({index})]"),
            (true, false) => format!("[{index}]"),
        };
        if c.resource == Resource::AccelerationStructure {
            let handle = match (c.through.as_str(), c.set, c.binding) {
                ("address", _, _) => format!("accelerationStructureEXT({})", c.variable),
                (_, Some(set), Some(b)) => {
                    let dims = if f.index.is_some() { "[]" } else { "" };
                    out.push_str(&format!("layout(set = {set}, binding = {b}) uniform accelerationStructureEXT {}{dims};\n", c.variable));
                    format!("{}{index}", c.variable)
                }
                _ => format!("{}{index}", c.variable),
            };
            out.push_str(&super::render_as::use_line(&d, f.var, &handle));
            continue;
        }
        out.push_str(&format!("... = {}{index}...;\n\n", c.variable));
    }
    out
}

/// Value `id` as a GLSL-like expression, `depth` deep.
fn expr(d: &Defs, id: Word, depth: u32) -> String {
    let Some(i) = d.get(id) else { return format!("%{id}") };
    if depth > 8 {
        return format!("%{id}");
    }
    let arg = |n: usize| match i.operands.get(n) {
        Some(Operand::IdRef(x)) => expr(d, *x, depth + 1),
        _ => "?".into(),
    };
    let bin = |op: &str| format!("({} {op} {})", arg(0), arg(1));
    match i.class.opcode {
        Op::Constant => match i.operands.first() {
            Some(Operand::LiteralBit32(v)) => format!("{v}u"),
            Some(Operand::LiteralBit64(v)) => format!("{v}ul"),
            _ => format!("%{id}"),
        },
        Op::ConstantNull => "0".into(),
        Op::Undef => "undef".into(),
        Op::SpecConstant => format!("spec_constant(%{id})"),
        Op::IAdd => bin("+"),
        Op::ISub => bin("-"),
        Op::IMul => bin("*"),
        Op::BitwiseAnd => bin("&"),
        Op::BitwiseOr => bin("|"),
        Op::BitwiseXor => bin("^"),
        Op::ShiftLeftLogical => bin("<<"),
        Op::ShiftRightLogical => bin(">>"),
        Op::UDiv | Op::SDiv => bin("/"),
        Op::UMod | Op::SMod | Op::SRem => bin("%"),
        Op::Bitcast | Op::UConvert | Op::SConvert => format!("uint({})", arg(0)),
        Op::CopyObject => arg(0),
        Op::Load => load(d, i.operands.first(), id),
        _ => format!("%{id}"),
    }
}

/// A load's expression: a built-in's name, `push.member`, a variable's name.
fn load(d: &Defs, ptr: Option<&Operand>, id: Word) -> String {
    let Some(Operand::IdRef(p)) = ptr else { return format!("%{id}") };
    let (root, chains) = d.root(*p);
    let members: String =
        chains.iter().rev().flatten().map(|x| format!("[{}]", expr(d, *x, 9))).collect();
    match d.storage_class(root) {
        Some(StorageClass::Input) => match d.builtin(root) {
            Some(b) => builtin_name(b),
            None => d.name(root),
        },
        Some(StorageClass::PushConstant) => format!("{}{members}", d.name(root)),
        _ => format!("{}{members}", d.name(root)),
    }
}
