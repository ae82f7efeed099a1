//! A SPIR-V type as a tree ([`Ty`]): scalars with their width, vectors, matrices, arrays (fixed
//! or runtime, with their `ArrayStride`), structs with member names, offsets and matrix layouts,
//! and pointers; its size packed at scalar alignment (the rule `maxPipelineRayPayloadSize` and
//! `maxRayHitAttributeSize` count by, explicit offsets and strides honoured where the module gives
//! them), its extent in an explicitly laid-out block, and its 32-bit words.

/// A scalar type.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Scalar {
    Bool,
    Int { bits: u32, signed: bool },
    Float { bits: u32 },
}

impl Scalar {
    /// Bytes of one value (a bool counts 4, as a 32-bit value in every interface).
    pub fn bytes(self) -> u32 {
        match self {
            Scalar::Bool => 4,
            Scalar::Int { bits, .. } | Scalar::Float { bits } => bits / 8,
        }
    }
}

/// One member of a struct.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Member {
    /// Its `OpMemberName` ("" when the module gives none).
    pub name: String,
    pub offset: Option<u32>,
    /// `MatrixStride` and `RowMajor` of a matrix member (or array of matrices).
    pub matrix: Option<(u32, bool)>,
    pub ty: Ty,
}

/// A struct: its `OpName` ("" when none) and members.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Struct {
    pub name: String,
    pub members: Vec<Member>,
}

/// A SPIR-V type.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Ty {
    Scalar(Scalar),
    Vector(Scalar, u32),
    /// `columns` columns of `rows` scalars.
    Matrix {
        scalar: Scalar,
        columns: u32,
        rows: u32,
    },
    Array {
        elem: Box<Ty>,
        len: u32,
        stride: Option<u32>,
    },
    RuntimeArray {
        elem: Box<Ty>,
        stride: Option<u32>,
    },
    Struct(Struct),
    /// A pointer: its storage class, and its pointee (`None` where the pointee is a struct
    /// already being read, a linked list's `next`).
    Pointer {
        class: rspirv::spirv::StorageClass,
        pointee: Option<Box<Ty>>,
    },
    /// Anything else (images, samplers, acceleration structures, …), by its opcode.
    Opaque(String),
}

impl Ty {
    /// Bytes at scalar alignment: explicit member offsets and array strides where given, else
    /// packed (a runtime array counts 0; a pointer 8).
    pub fn size(&self) -> u32 {
        match self {
            Ty::Scalar(s) => s.bytes(),
            Ty::Vector(s, n) => n * s.bytes(),
            Ty::Matrix { scalar, columns, rows } => columns * rows * scalar.bytes(),
            Ty::Array { elem, len, stride } => len * stride.unwrap_or_else(|| elem.size()),
            Ty::RuntimeArray { .. } | Ty::Opaque(_) => 0,
            Ty::Struct(s) => {
                let (mut end, mut packed) = (0, 0);
                for m in &s.members {
                    let size = m.ty.size();
                    match m.offset {
                        Some(o) => end = end.max(o + size),
                        None => packed += size,
                    }
                }
                end.max(packed)
            }
            Ty::Pointer { .. } => 8,
        }
    }

    /// Bytes spanned in an explicitly laid-out block (offsets, `ArrayStride`, `MatrixStride`
    /// required; `None` for a runtime array or a missing decoration), as `patches::layout`.
    pub fn extent(&self, matrix: Option<(u32, bool)>) -> Option<u32> {
        match self {
            Ty::Scalar(s) => Some(s.bytes()),
            Ty::Vector(s, n) => Some(n * s.bytes()),
            Ty::Matrix { scalar, columns, rows } => {
                let (stride, row_major) = matrix?;
                let comp = scalar.bytes();
                Some(if row_major {
                    (rows.checked_sub(1)?) * stride + columns * comp
                } else {
                    (columns * stride).max(columns.checked_sub(1)? * stride + rows * comp)
                })
            }
            Ty::Array { elem, len, stride } => {
                Some(len.checked_sub(1)? * (*stride)? + elem.extent(matrix)?)
            }
            Ty::Struct(s) => {
                let mut end = 0;
                for m in &s.members {
                    end = end.max(m.offset? + m.ty.extent(m.matrix)?);
                }
                Some(end)
            }
            Ty::Pointer { .. } => Some(8),
            Ty::RuntimeArray { .. } | Ty::Opaque(_) => None,
        }
    }

    /// The type's structure without its names: what "the same structure" of the Ray Tracing
    /// Pipeline Interface compares (`{vec4<f32>, f32, u32}`; offsets, strides and matrix layouts
    /// where the module gives them, since they make another layout of the same members).
    pub fn structure(&self) -> String {
        let s = |s: &Scalar| match s {
            Scalar::Bool => "bool".to_string(),
            Scalar::Int { bits, signed: true } => format!("i{bits}"),
            Scalar::Int { bits, signed: false } => format!("u{bits}"),
            Scalar::Float { bits } => format!("f{bits}"),
        };
        let stride = |st: &Option<u32>| st.map(|v| format!(" /{v}")).unwrap_or_default();
        match self {
            Ty::Scalar(x) => s(x),
            Ty::Vector(x, n) => format!("vec{n}<{}>", s(x)),
            Ty::Matrix { scalar, columns, rows } => format!("mat{columns}x{rows}<{}>", s(scalar)),
            Ty::Array { elem, len, stride: st } => {
                format!("[{}; {len}{}]", elem.structure(), stride(st))
            }
            Ty::RuntimeArray { elem, stride: st } => {
                format!("[{}{}]", elem.structure(), stride(st))
            }
            Ty::Struct(st) => {
                let m: Vec<String> = st
                    .members
                    .iter()
                    .map(|m| {
                        let at = m.offset.map(|o| format!("@{o} ")).unwrap_or_default();
                        let mx =
                            m.matrix.map(|(v, r)| format!(" /{v}{}", if r { "r" } else { "" }));
                        format!("{at}{}{}", m.ty.structure(), mx.unwrap_or_default())
                    })
                    .collect();
                format!("{{{}}}", m.join(", "))
            }
            Ty::Pointer { class, pointee } => match pointee {
                Some(p) => format!("ptr<{class:?}, {}>", p.structure()),
                None => format!("ptr<{class:?}, …>"),
            },
            Ty::Opaque(op) => op.clone(),
        }
    }

    /// Its scalars in order, flattened through vectors, matrices (column by column), arrays and
    /// structs, each with its explicit offset where the module gives one (`f32 f32 u32`): how
    /// [`crate::interface`] compares payloads, callable data and hit attributes.
    pub fn leaves(&self) -> String {
        let mut out = Vec::new();
        self.push_leaves(None, &mut out);
        out.join(" ")
    }

    fn push_leaves(&self, at: Option<u32>, out: &mut Vec<String>) {
        let tag = |t: String| match at {
            Some(o) => format!("{t}@{o}"),
            None => t,
        };
        match self {
            Ty::Scalar(_) | Ty::Vector(..) | Ty::Matrix { .. } => {
                let (scalar, n) = match self {
                    Ty::Scalar(x) => (*x, 1),
                    Ty::Vector(x, n) => (*x, *n),
                    Ty::Matrix { scalar, columns, rows } => (*scalar, columns * rows),
                    _ => unreachable!("matched above"),
                };
                let name = Ty::Scalar(scalar).structure();
                out.push(tag(name.clone()));
                out.extend((1..n).map(|_| name.clone()));
            }
            Ty::Array { elem, len, .. } => (0..*len).for_each(|_| elem.push_leaves(None, out)),
            Ty::Struct(st) => {
                for (k, m) in st.members.iter().enumerate() {
                    m.ty.push_leaves(if k == 0 { at.or(m.offset) } else { m.offset }, out);
                }
            }
            Ty::RuntimeArray { .. } | Ty::Pointer { .. } | Ty::Opaque(_) => {
                out.push(tag(self.structure()))
            }
        }
    }

    /// The number of scalars in it (a runtime array, pointer or opaque type: none).
    pub fn scalars(&self) -> u32 {
        match self {
            Ty::Scalar(_) => 1,
            Ty::Vector(_, n) => *n,
            Ty::Matrix { columns, rows, .. } => columns * rows,
            Ty::Array { elem, len, .. } => len * elem.scalars(),
            Ty::Struct(s) => s.members.iter().map(|m| m.ty.scalars()).sum(),
            Ty::RuntimeArray { .. } | Ty::Pointer { .. } | Ty::Opaque(_) => 0,
        }
    }

    /// The same type without names (struct and member names cleared): two stages' payloads
    /// match when their shapes are equal.
    pub fn shape(&self) -> Ty {
        match self {
            Ty::Array { elem, len, stride } => {
                Ty::Array { elem: Box::new(elem.shape()), len: *len, stride: *stride }
            }
            Ty::RuntimeArray { elem, stride } => {
                Ty::RuntimeArray { elem: Box::new(elem.shape()), stride: *stride }
            }
            Ty::Struct(s) => Ty::Struct(Struct {
                name: String::new(),
                members: s
                    .members
                    .iter()
                    .map(|m| Member { name: String::new(), ty: m.ty.shape(), ..m.clone() })
                    .collect(),
            }),
            Ty::Pointer { class, pointee } => Ty::Pointer {
                class: *class,
                pointee: pointee.as_ref().map(|p| Box::new(p.shape())),
            },
            other => other.clone(),
        }
    }
}
