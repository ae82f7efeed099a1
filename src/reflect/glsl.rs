//! A type tree as GLSL ([`Glsl`]): struct definitions first, each struct once under a name made
//! unique and a valid identifier (`type.ConstantBuffer.X` → `type_ConstantBuffer_X`), members
//! renamed where they collide with a GLSL keyword; blocks with `layout(offset = N)` on each member
//! so the module's offsets are kept. Pointers print as `uint64_t` (same size and alignment: the
//! address, not a `buffer_reference`). Nested structs take the offsets of the enclosing block's
//! layout rule (`scalar`), which may differ from the module's where it used std430 padding inside
//! them; the members of a block itself keep theirs. Also the scalars of a value, as GLSL lvalues
//! ([`scalars`]), for code that reads or writes every word of it.
use super::ty::{Scalar, Struct, Ty};
use std::collections::BTreeSet;

/// A type GLSL cannot declare.
#[derive(Clone, Debug, thiserror::Error, PartialEq, Eq)]
#[error("GLSL has no type for {0}")]
pub struct GlslError(pub String);

/// Struct definitions and extensions collected while declaring.
#[derive(Default)]
pub struct Glsl {
    structs: Vec<(Struct, String)>,
    defs: Vec<String>,
    extensions: BTreeSet<&'static str>,
}

const KEYWORDS: &[&str] = &[
    "input",
    "output",
    "sample",
    "filter",
    "common",
    "partition",
    "active",
    "buffer",
    "shared",
    "coherent",
    "volatile",
    "restrict",
    "readonly",
    "writeonly",
    "uniform",
    "in",
    "out",
    "inout",
    "layout",
    "struct",
    "precision",
    "highp",
    "mediump",
    "lowp",
    "smooth",
    "flat",
    "patch",
    "centroid",
    "invariant",
    "texture",
    "image",
    "sampler",
    "main",
    "true",
    "false",
    "void",
    "class",
    "union",
    "enum",
    "typedef",
    "template",
    "this",
    "packed",
    "goto",
    "switch",
    "default",
    "inline",
    "noinline",
    "public",
    "static",
    "extern",
    "external",
    "interface",
    "long",
    "short",
    "double",
    "half",
    "fixed",
    "unsigned",
    "superp",
    "cast",
    "namespace",
    "using",
    "row_major",
];

/// `s` as a GLSL identifier (`fallback` when empty).
pub fn ident(s: &str, fallback: &str) -> String {
    let mut out: String =
        s.chars().map(|c| if c.is_ascii_alphanumeric() { c } else { '_' }).collect();
    while out.contains("__") {
        out = out.replace("__", "_");
    }
    let out = out.trim_matches('_').to_string();
    let out = if out.is_empty() { fallback.to_string() } else { out };
    let out = if out.starts_with(|c: char| c.is_ascii_digit()) || out.starts_with("gl_") {
        format!("x{out}")
    } else {
        out
    };
    if KEYWORDS.contains(&out.as_str()) || is_type_word(&out) {
        format!("{out}_")
    } else {
        out
    }
}

fn is_type_word(s: &str) -> bool {
    let base = s.trim_end_matches(|c: char| c.is_ascii_digit() || c == 'x');
    matches!(
        base,
        "bool"
            | "int"
            | "uint"
            | "float"
            | "vec"
            | "ivec"
            | "uvec"
            | "bvec"
            | "dvec"
            | "mat"
            | "dmat"
    )
}

impl Glsl {
    /// The scalar's type name, noting the extension it needs.
    fn scalar(&mut self, s: Scalar) -> Result<&'static str, GlslError> {
        let name = match s {
            Scalar::Bool => "bool",
            Scalar::Int { bits: 32, signed: true } => "int",
            Scalar::Int { bits: 32, signed: false } => "uint",
            Scalar::Float { bits: 32 } => "float",
            Scalar::Float { bits: 64 } => "double",
            Scalar::Int { bits: 64, signed: true } => "int64_t",
            Scalar::Int { bits: 64, signed: false } => "uint64_t",
            Scalar::Int { bits: 16, signed: true } => "int16_t",
            Scalar::Int { bits: 16, signed: false } => "uint16_t",
            Scalar::Float { bits: 16 } => "float16_t",
            Scalar::Int { bits: 8, signed: true } => "int8_t",
            Scalar::Int { bits: 8, signed: false } => "uint8_t",
            other => return Err(GlslError(format!("{other:?}"))),
        };
        if !matches!(name, "bool" | "int" | "uint" | "float" | "double") {
            self.extensions.insert("GL_EXT_shader_explicit_arithmetic_types");
        }
        Ok(name)
    }

    /// The type name of a vector or matrix's component scalar as a prefix (`u`, `f16`, …).
    fn prefix(&mut self, s: Scalar) -> Result<&'static str, GlslError> {
        Ok(match self.scalar(s)? {
            "bool" => "b",
            "int" => "i",
            "uint" => "u",
            "float" => "",
            "double" => "d",
            "int64_t" => "i64",
            "uint64_t" => "u64",
            "int16_t" => "i16",
            "uint16_t" => "u16",
            "float16_t" => "f16",
            "int8_t" => "i8",
            _ => "u8",
        })
    }

    /// `ty` declared as `name`: `vec3 name`, `Shade name[4]`, `uint name[]`.
    pub fn declare(&mut self, ty: &Ty, name: &str) -> Result<String, GlslError> {
        let mut dims = String::new();
        let mut t = ty;
        loop {
            match t {
                Ty::Array { elem, len, .. } => {
                    dims.push_str(&format!("[{len}]"));
                    t = elem;
                }
                Ty::RuntimeArray { elem, .. } => {
                    dims.push_str("[]");
                    t = elem;
                }
                _ => break,
            }
        }
        Ok(format!("{} {name}{dims}", self.base(t)?))
    }

    fn base(&mut self, t: &Ty) -> Result<String, GlslError> {
        Ok(match t {
            Ty::Scalar(s) => self.scalar(*s)?.to_string(),
            Ty::Vector(s, n) => format!("{}vec{n}", self.prefix(*s)?),
            Ty::Matrix { scalar, columns, rows } => match self.prefix(*scalar)? {
                p @ ("" | "d" | "f16") => format!("{p}mat{columns}x{rows}"),
                _ => return Err(GlslError(format!("a matrix of {scalar:?}"))),
            },
            Ty::Struct(s) => self.structure(s)?,
            Ty::Pointer { .. } => self.scalar(Scalar::Int { bits: 64, signed: false })?.to_string(),
            Ty::Array { .. } | Ty::RuntimeArray { .. } => {
                return Err(GlslError("an array in a base type".into()))
            }
            Ty::Opaque(op) => return Err(GlslError(op.clone())),
        })
    }

    /// The name of struct `s`, defining it first if new.
    fn structure(&mut self, s: &Struct) -> Result<String, GlslError> {
        if let Some((_, n)) = self.structs.iter().find(|(x, _)| x == s) {
            return Ok(n.clone());
        }
        let base = ident(&s.name, "Struct");
        let mut name = base.clone();
        let mut k = 2;
        while self.structs.iter().any(|(_, n)| *n == name) {
            name = format!("{base}_{k}");
            k += 1;
        }
        let members = self.members(s, false)?;
        self.structs.push((s.clone(), name.clone()));
        self.defs.push(format!("struct {name} {{\n{members}}};\n"));
        Ok(name)
    }

    /// One line per member (`layout(offset = N)` first when `offsets`), names made unique.
    pub fn members(&mut self, s: &Struct, offsets: bool) -> Result<String, GlslError> {
        let mut out = String::new();
        let mut seen = BTreeSet::new();
        for (k, m) in s.members.iter().enumerate() {
            let mut name = ident(&m.name, &format!("m{k}"));
            if !seen.insert(name.clone()) {
                name = format!("{name}_{k}");
                seen.insert(name.clone());
            }
            let layout = match (offsets, m.offset) {
                (true, Some(o)) => format!("layout(offset = {o}) "),
                _ => String::new(),
            };
            let major = match m.matrix {
                Some((_, true)) if offsets => "layout(row_major) ",
                _ => "",
            };
            out.push_str(&format!("    {layout}{major}{};\n", self.declare(&m.ty, &name)?));
        }
        Ok(out)
    }

    /// The member names [`Glsl::members`] gives struct `s`'s members.
    pub fn member_names(s: &Struct) -> Vec<String> {
        let mut seen = BTreeSet::new();
        (0..s.members.len())
            .map(|k| {
                let mut name = ident(&s.members[k].name, &format!("m{k}"));
                if !seen.insert(name.clone()) {
                    name = format!("{name}_{k}");
                    seen.insert(name.clone());
                }
                name
            })
            .collect()
    }

    /// A block: `layout(<qualifiers>) <storage> Name { members with offsets } instance;`.
    pub fn block(
        &mut self,
        qualifiers: &str,
        storage: &str,
        s: &Struct,
        instance: &str,
    ) -> Result<String, GlslError> {
        self.extensions.insert("GL_EXT_scalar_block_layout");
        let name = ident(&s.name, "Block");
        let members = self.members(s, true)?;
        Ok(format!("layout({qualifiers}, scalar) {storage} {name}_ {{\n{members}}} {instance};\n"))
    }

    /// The `#extension` lines and struct definitions, in order.
    pub fn preamble(&self) -> String {
        let ext: String =
            self.extensions.iter().map(|e| format!("#extension {e} : require\n")).collect();
        format!("{ext}{}", self.defs.concat())
    }
}

/// Leaves beyond this make the value too big to mirror word by word.
pub const MAX_SCALARS: usize = 4096;

/// Every scalar of a value of type `ty` reached as `lvalue`, in order: (its type, its lvalue).
/// Runtime arrays, pointers and opaque types are errors naming the member.
pub fn scalars(ty: &Ty, lvalue: &str) -> Result<Vec<(Scalar, String)>, GlslError> {
    let mut out = Vec::new();
    leaves(ty, lvalue.to_string(), &mut out)?;
    Ok(out)
}

fn leaves(ty: &Ty, at: String, out: &mut Vec<(Scalar, String)>) -> Result<(), GlslError> {
    if out.len() > MAX_SCALARS {
        return Err(GlslError(format!("a value of more than {MAX_SCALARS} scalars")));
    }
    match ty {
        Ty::Scalar(s) => out.push((*s, at)),
        Ty::Vector(s, n) => out.extend((0..*n).map(|i| (*s, format!("{at}[{i}]")))),
        Ty::Matrix { scalar, columns, rows } => {
            for c in 0..*columns {
                out.extend((0..*rows).map(|r| (*scalar, format!("{at}[{c}][{r}]"))));
            }
        }
        Ty::Array { elem, len, .. } => {
            for i in 0..*len {
                leaves(elem, format!("{at}[{i}]"), out)?;
            }
        }
        Ty::Struct(s) => {
            for (m, name) in s.members.iter().zip(Glsl::member_names(s)) {
                leaves(&m.ty, format!("{at}.{name}"), out)?;
            }
        }
        Ty::RuntimeArray { .. } => return Err(GlslError(format!("{at}, a runtime array"))),
        Ty::Pointer { .. } => return Err(GlslError(format!("{at}, a pointer"))),
        Ty::Opaque(op) => return Err(GlslError(format!("{at}, an {op}"))),
    }
    Ok(())
}
