//! The module's global definitions, names and decorations by id ([`Index`]), read once, and the
//! type tree of a type id ([`Index::ty`]). Every lookup is an `Option`: a module that names an id
//! it never defines reads as missing, never as a panic.
use super::error::ReflectError;
use super::ty::{Member, Scalar, Struct, Ty};
use rspirv::dr::{Instruction, Module, Operand};
use rspirv::spirv::{Decoration, Op, StorageClass, Word};
use std::cell::Cell;
use std::collections::HashMap;

/// Nesting beyond this is refused (no real interface type is that deep).
const MAX_DEPTH: u32 = 64;
/// Type nodes built for one module at most.
const MAX_NODES: u32 = 1 << 20;

/// Definitions, names and decorations by id.
pub struct Index<'m> {
    pub defs: HashMap<Word, &'m Instruction>,
    names: HashMap<Word, &'m str>,
    member_names: HashMap<(Word, u32), &'m str>,
    decorations: HashMap<Word, Vec<&'m Instruction>>,
    member_decorations: HashMap<(Word, u32), Vec<(Decoration, u32)>>,
    member_ids: HashMap<(Word, u32), Vec<(Decoration, Word)>>,
    /// Type nodes still allowed to be built (a module of types nested as a wide DAG would
    /// otherwise expand exponentially).
    budget: Cell<u32>,
}

fn literal(o: Option<&Operand>) -> Option<u32> {
    match o? {
        Operand::LiteralBit32(v) => Some(*v),
        _ => None,
    }
}

pub fn id(o: Option<&Operand>) -> Option<Word> {
    match o? {
        Operand::IdRef(w) => Some(*w),
        _ => None,
    }
}

impl<'m> Index<'m> {
    pub fn new(m: &'m Module) -> Index<'m> {
        let mut x = Index {
            defs: HashMap::new(),
            names: HashMap::new(),
            member_names: HashMap::new(),
            decorations: HashMap::new(),
            member_decorations: HashMap::new(),
            member_ids: HashMap::new(),
            budget: Cell::new(MAX_NODES),
        };
        for i in &m.types_global_values {
            if let Some(r) = i.result_id {
                x.defs.insert(r, i);
            }
        }
        for n in &m.debug_names {
            match (n.class.opcode, n.operands.as_slice()) {
                (Op::Name, [Operand::IdRef(t), Operand::LiteralString(s)]) => {
                    x.names.insert(*t, s);
                }
                (
                    Op::MemberName,
                    [Operand::IdRef(t), Operand::LiteralBit32(k), Operand::LiteralString(s)],
                ) => {
                    x.member_names.insert((*t, *k), s);
                }
                _ => {}
            }
        }
        for a in &m.annotations {
            match (a.class.opcode, a.operands.as_slice()) {
                (Op::Decorate | Op::DecorateId, [Operand::IdRef(t), ..]) => {
                    x.decorations.entry(*t).or_default().push(a)
                }
                (
                    Op::MemberDecorate,
                    [Operand::IdRef(t), Operand::LiteralBit32(k), Operand::Decoration(d), rest @ ..],
                ) => {
                    let v = literal(rest.first()).unwrap_or(0);
                    x.member_decorations.entry((*t, *k)).or_default().push((*d, v));
                }
                (
                    Op::MemberDecorateIdEXT,
                    [Operand::IdRef(t), Operand::LiteralBit32(k), Operand::Decoration(d), rest @ ..],
                ) => {
                    if let Some(v) = id(rest.first()) {
                        x.member_ids.entry((*t, *k)).or_default().push((*d, v));
                    }
                }
                _ => {}
            }
        }
        x
    }

    /// An id-valued member decoration (`OpMemberDecorateIdEXT`).
    pub fn member_id(&self, st: Word, k: u32, d: Decoration) -> Option<Word> {
        self.member_ids.get(&(st, k))?.iter().find(|(x, _)| *x == d).map(|(_, v)| *v)
    }

    pub fn def(&self, id: Word) -> Option<&'m Instruction> {
        self.defs.get(&id).copied()
    }

    pub fn name(&self, id: Word) -> &'m str {
        self.names.get(&id).copied().unwrap_or("")
    }

    /// The decoration `d` of `id`: its first extra operand (a literal or an id), `Some(None)`
    /// when it has none.
    pub fn decoration(&self, id: Word, d: Decoration) -> Option<Option<&'m Operand>> {
        self.decorations.get(&id)?.iter().find_map(|a| match a.operands.get(1) {
            Some(Operand::Decoration(x)) if *x == d => Some(a.operands.get(2)),
            _ => None,
        })
    }

    pub fn has(&self, id: Word, d: Decoration) -> bool {
        self.decoration(id, d).is_some()
    }

    pub fn literal(&self, id: Word, d: Decoration) -> Option<u32> {
        literal(self.decoration(id, d)?)
    }

    pub fn member(&self, st: Word, k: u32, d: Decoration) -> Option<u32> {
        self.member_decorations.get(&(st, k))?.iter().find(|(x, _)| *x == d).map(|(_, v)| *v)
    }

    /// The value of 32-bit constant `id` (`OpConstant` or a spec constant's default).
    pub fn constant(&self, id: Word) -> Option<u32> {
        let d = self.def(id)?;
        match d.class.opcode {
            Op::Constant | Op::SpecConstant => literal(d.operands.first()),
            _ => None,
        }
    }

    /// The scalar type `id`.
    pub fn scalar(&self, id: Word) -> Option<Scalar> {
        let d = self.def(id)?;
        match d.class.opcode {
            Op::TypeBool => Some(Scalar::Bool),
            Op::TypeInt => Some(Scalar::Int {
                bits: literal(d.operands.first())?,
                signed: literal(d.operands.get(1))? == 1,
            }),
            Op::TypeFloat => Some(Scalar::Float { bits: literal(d.operands.first())? }),
            _ => None,
        }
    }

    /// The type tree of type `id`.
    pub fn ty(&self, id: Word) -> Result<Ty, ReflectError> {
        self.ty_at(id, &mut Vec::new())
    }

    fn ty_at(&self, tid: Word, open: &mut Vec<Word>) -> Result<Ty, ReflectError> {
        let bad = |what: &str| ReflectError::Malformed(format!("type %{tid}: {what}"));
        if open.len() as u32 > MAX_DEPTH || self.budget.get() == 0 {
            return Err(bad("nested too deep, or too many types"));
        }
        self.budget.set(self.budget.get() - 1);
        let d = self.def(tid).ok_or_else(|| bad("not defined"))?;
        let op = |n| id(d.operands.get(n)).ok_or_else(|| bad("operand missing"));
        let scalar = |t| self.scalar(t).ok_or_else(|| bad("not a scalar component"));
        Ok(match d.class.opcode {
            Op::TypeBool | Op::TypeInt | Op::TypeFloat => Ty::Scalar(scalar(tid)?),
            Op::TypeVector => Ty::Vector(scalar(op(0)?)?, literal(d.operands.get(1)).unwrap_or(0)),
            Op::TypeMatrix => {
                let column = self.def(op(0)?).ok_or_else(|| bad("no column type"))?;
                Ty::Matrix {
                    scalar: scalar(id(column.operands.first()).unwrap_or(0))?,
                    columns: literal(d.operands.get(1)).unwrap_or(0),
                    rows: literal(column.operands.get(1)).unwrap_or(0),
                }
            }
            Op::TypeArray => Ty::Array {
                elem: Box::new(self.ty_at(op(0)?, open)?),
                len: self.constant(op(1)?).ok_or_else(|| bad("array length not a constant"))?,
                stride: self.literal(tid, Decoration::ArrayStride),
            },
            Op::TypeRuntimeArray => Ty::RuntimeArray {
                elem: Box::new(self.ty_at(op(0)?, open)?),
                stride: self.literal(tid, Decoration::ArrayStride),
            },
            Op::TypeStruct => {
                open.push(tid);
                let r = self.structure(tid, d, open);
                open.pop();
                Ty::Struct(r?)
            }
            Op::TypePointer => {
                let class = match d.operands.first() {
                    Some(Operand::StorageClass(c)) => *c,
                    _ => return Err(bad("pointer without storage class")),
                };
                let p = op(1)?;
                let pointee =
                    if open.contains(&p) { None } else { Some(Box::new(self.ty_at(p, open)?)) };
                Ty::Pointer { class, pointee }
            }
            other => Ty::Opaque(format!("Op{other:?}")),
        })
    }

    fn structure(
        &self,
        st: Word,
        d: &Instruction,
        open: &mut Vec<Word>,
    ) -> Result<Struct, ReflectError> {
        let mut members = Vec::with_capacity(d.operands.len());
        for (k, o) in d.operands.iter().enumerate() {
            let k = k as u32;
            let t = id(Some(o)).ok_or_else(|| {
                ReflectError::Malformed(format!("struct %{st}: member {k} is not a type"))
            })?;
            let matrix = self
                .member(st, k, Decoration::MatrixStride)
                .map(|s| (s, self.member(st, k, Decoration::RowMajor).is_some()));
            members.push(Member {
                name: self.member_names.get(&(st, k)).copied().unwrap_or("").to_string(),
                offset: self.member(st, k, Decoration::Offset),
                matrix,
                ty: self.ty_at(t, open)?,
            });
        }
        Ok(Struct { name: self.name(st).to_string(), members })
    }

    /// The storage class and pointee of pointer type `ptr`.
    pub fn pointer(&self, ptr: Word) -> Option<(StorageClass, Word)> {
        let d = self.def(ptr)?;
        match (d.class.opcode, d.operands.first(), id(d.operands.get(1))) {
            (Op::TypePointer, Some(Operand::StorageClass(c)), Some(p)) => Some((*c, p)),
            _ => None,
        }
    }
}
