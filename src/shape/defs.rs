//! One module's definitions by id, with what the classifier asks of them: a pointer's root
//! variable and the access chains on the way, a variable's storage class, built-in,
//! decorations, name and the values stored to it.
use rspirv::dr::{Instruction, Module, Operand};
use rspirv::spirv::{BuiltIn, Decoration, Op, StorageClass, Word};
use std::collections::HashMap;

/// Definitions by result id, over a module.
pub struct Defs<'m> {
    pub m: &'m Module,
    by_id: HashMap<Word, &'m Instruction>,
}

fn id_at(i: &Instruction, n: usize) -> Option<Word> {
    match i.operands.get(n) {
        Some(Operand::IdRef(w)) => Some(*w),
        _ => None,
    }
}

/// Whether `op` makes a pointer into its base pointer (operand 0) with index operands.
pub fn is_chain(op: Op) -> bool {
    matches!(
        op,
        Op::AccessChain | Op::InBoundsAccessChain | Op::PtrAccessChain | Op::InBoundsPtrAccessChain
    )
}

impl<'m> Defs<'m> {
    pub fn new(m: &'m Module) -> Defs<'m> {
        let globals = m.types_global_values.iter();
        let funcs = m.functions.iter().flat_map(|f| {
            f.def
                .iter()
                .chain(f.parameters.iter())
                .chain(f.blocks.iter().flat_map(|b| b.instructions.iter()))
        });
        let by_id = globals.chain(funcs).filter_map(|i| Some((i.result_id?, i))).collect();
        Defs { m, by_id }
    }

    pub fn get(&self, id: Word) -> Option<&'m Instruction> {
        self.by_id.get(&id).copied()
    }

    /// The variable (or other value) a pointer derives from, and the indices of every chain on
    /// the way, the chain on the variable itself last.
    pub fn root(&self, mut ptr: Word) -> (Word, Vec<Vec<Word>>) {
        let mut indices = Vec::new();
        for _ in 0..64 {
            let Some(i) = self.get(ptr) else { break };
            match i.class.opcode {
                op if is_chain(op) => {
                    indices.push(
                        i.operands
                            .iter()
                            .skip(1)
                            .filter_map(|o| match o {
                                Operand::IdRef(w) => Some(*w),
                                _ => None,
                            })
                            .collect(),
                    );
                }
                Op::CopyObject | Op::Bitcast => {}
                _ => break,
            }
            let Some(base) = id_at(i, 0) else { break };
            ptr = base;
        }
        (ptr, indices)
    }

    /// The storage class of variable `id`.
    pub fn storage_class(&self, id: Word) -> Option<StorageClass> {
        let v = self.get(id)?;
        match (v.class.opcode, v.operands.first()) {
            (Op::Variable, Some(Operand::StorageClass(sc))) => Some(*sc),
            _ => None,
        }
    }

    /// The pointee type of pointer value `id`.
    pub fn pointee(&self, id: Word) -> Option<&'m Instruction> {
        let t = self.get(self.get(id)?.result_type?)?;
        match t.class.opcode {
            Op::TypePointer => self.get(id_at(t, 1)?),
            _ => None,
        }
    }

    pub fn builtin(&self, id: Word) -> Option<BuiltIn> {
        self.m.annotations.iter().find_map(|a| {
            match (a.class.opcode, id_at(a, 0), a.operands.get(1), a.operands.get(2)) {
                (
                    Op::Decorate,
                    Some(t),
                    Some(Operand::Decoration(Decoration::BuiltIn)),
                    Some(Operand::BuiltIn(b)),
                ) if t == id => Some(*b),
                _ => None,
            }
        })
    }

    pub fn decorated(&self, id: Word, d: Decoration) -> bool {
        self.decoration(id, d).is_some()
    }

    /// A decoration's first literal (0 for one without).
    pub fn decoration(&self, id: Word, d: Decoration) -> Option<u32> {
        self.m.annotations.iter().find_map(|a| {
            let hit = a.class.opcode == Op::Decorate
                && id_at(a, 0) == Some(id)
                && a.operands.get(1) == Some(&Operand::Decoration(d));
            hit.then(|| match a.operands.get(2) {
                Some(Operand::LiteralBit32(v)) => *v,
                _ => 0,
            })
        })
    }

    /// `OpName` of `id`, else `%id`.
    pub fn name(&self, id: Word) -> String {
        self.m
            .debug_names
            .iter()
            .find_map(|n| match (n.class.opcode, id_at(n, 0), n.operands.get(1)) {
                (Op::Name, Some(t), Some(Operand::LiteralString(s)))
                    if t == id && !s.is_empty() =>
                {
                    Some(s.clone())
                }
                _ => None,
            })
            .unwrap_or_else(|| format!("%{id}"))
    }

    /// Every value stored to variable `var` or through a chain into it, and whether it starts
    /// with a value (an initializer, or an `OpCopyMemory` into it: then as good as dynamic).
    pub fn stored_values(&self, var: Word) -> (Vec<Word>, bool) {
        let body =
            self.m.functions.iter().flat_map(|f| f.blocks.iter().flat_map(|b| &b.instructions));
        let mut values = Vec::new();
        let mut known = self.get(var).is_some_and(|v| v.operands.len() > 1);
        for i in body {
            let Some(p) = id_at(i, 0) else { continue };
            match i.class.opcode {
                Op::Store if self.root(p).0 == var => values.extend(id_at(i, 1)),
                Op::CopyMemory if self.root(p).0 == var => known = true,
                _ => {}
            }
        }
        (values, known)
    }
}
