//! Choosing the entry point ([`choose`]), the functions it calls ([`call_tree`]) and the global
//! ids they use ([`used`]).
use super::error::ReflectError;
use rspirv::dr::{Function, Instruction, Module, Operand};
use rspirv::spirv::{ExecutionModel, Op, Word};
use std::collections::HashSet;

/// An entry point: model, function and name.
pub struct Entry {
    pub model: ExecutionModel,
    pub function: Word,
    pub name: String,
}

fn entry(i: &Instruction) -> Option<Entry> {
    match i.operands.as_slice() {
        [Operand::ExecutionModel(model), Operand::IdRef(function), Operand::LiteralString(name), ..] => {
            Some(Entry { model: *model, function: *function, name: name.clone() })
        }
        _ => None,
    }
}

/// The entry point named `name`, or the module's only one.
pub fn choose(m: &Module, name: Option<&str>) -> Result<Entry, ReflectError> {
    let all: Vec<Entry> = m.entry_points.iter().filter_map(entry).collect();
    let names = || all.iter().map(|e| e.name.clone()).collect::<Vec<_>>();
    match name {
        Some(n) => {
            let present = names();
            all.into_iter()
                .find(|e| e.name == n)
                .ok_or(ReflectError::NoSuchEntry { name: n.to_string(), present })
        }
        None if all.len() > 1 => Err(ReflectError::SeveralEntries(names())),
        None => all.into_iter().next().ok_or(ReflectError::NoEntryPoint),
    }
}

/// `function` and every function it calls (transitively), each once.
pub fn call_tree(m: &Module, function: Word) -> Vec<&Function> {
    let mut out = Vec::new();
    let mut todo = vec![function];
    let mut seen = HashSet::new();
    while let Some(f) = todo.pop() {
        if !seen.insert(f) {
            continue;
        }
        let Some(func) =
            m.functions.iter().find(|x| x.def.as_ref().and_then(|d| d.result_id) == Some(f))
        else {
            continue;
        };
        for i in func.blocks.iter().flat_map(|b| &b.instructions) {
            if i.class.opcode == Op::FunctionCall {
                todo.extend(super::index::id(i.operands.first()));
            }
        }
        out.push(func);
    }
    out
}

/// Every id named by an instruction of `function` or a function it calls (transitively).
pub fn used(m: &Module, function: Word) -> HashSet<Word> {
    let body =
        call_tree(m, function).into_iter().flat_map(|f| &f.blocks).flat_map(|b| &b.instructions);
    body.flat_map(|i| &i.operands)
        .filter_map(|o| match o {
            Operand::IdRef(w) => Some(*w),
            _ => None,
        })
        .collect()
}

/// The stage name of an execution model (`patches`' spelling).
pub use crate::patches::pipeline::stage_name;
