//! `run --shader --spec ID=VALUE`: specialization constants given on the command line, each
//! value parsed as the type its reflected `SpecId` declares (bool, signed or unsigned integer,
//! float), and the `VkSpecializationInfo` bytes of one stage: the values of the constants that
//! stage declares (an ID it does not declare is left out of its map).
use super::UserModule;
use crate::reflect::{Scalar, SpecConstant};
use serde::{Deserialize, Serialize};

/// One constant's value as the pipeline gets it: its `SpecId` and its bytes (a bool as a
/// 4-byte VkBool32, an integer or float in its own width, little-endian) as the first stage
/// declaring it types it, and the value as given: a stage declaring the ID with another type
/// gets the value in that type's bytes ([`stage_info`]).
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct SpecValue {
    pub id: u32,
    pub bytes: Vec<u8>,
    #[serde(default)]
    pub text: String,
}

/// A `--spec` the modules cannot take.
#[derive(Debug, thiserror::Error, PartialEq, Eq)]
pub enum SpecError {
    #[error("--spec {0}: give ID=VALUE, the constant's SpecId and its value (--spec 3=16)")]
    Syntax(String),
    #[error("--spec {given}: no stage declares SpecId {id}; {known}")]
    UnknownId { given: String, id: u32, known: String },
    #[error("--spec {given}: SpecId {id} is a {ty}; give {what}")]
    BadValue { given: String, id: u32, ty: String, what: String },
    #[error("--spec {given}: SpecId {id} is given twice; give each constant once")]
    Twice { given: String, id: u32 },
    /// Stages declaring one SpecId with different types, and a value that is not one of both.
    /// Each stage gets its own map entry, sized for its own type ("For a constantID
    /// specialization constant declared in a shader, size must match the byte size of the
    /// constantID": VUID-VkSpecializationMapEntry-constantID-00776, Vulkan 1.4.360), so the
    /// types may differ; the value must fit each.
    #[error("--spec {given}: the stages declare SpecId {id} as a {a} and as a {b}, and the value is not one of both: give a value each type can hold")]
    Clash { given: String, id: u32, a: String, b: String },
}

/// A scalar type in words, and what a value of it looks like.
fn describe(s: Scalar) -> (String, String) {
    match s {
        Scalar::Bool => ("bool".into(), "true, false, 1 or 0".into()),
        Scalar::Int { bits, signed: true } => {
            (format!("{bits}-bit int"), format!("an integer that fits in {bits} signed bits"))
        }
        Scalar::Int { bits, signed: false } => {
            (format!("{bits}-bit uint"), format!("a non-negative integer that fits in {bits} bits"))
        }
        Scalar::Float { bits } => (format!("{bits}-bit float"), "a finite number".into()),
    }
}

/// `text` as a value of type `s`, in the bytes the pipeline gets; `None` when it is not one.
fn bytes_of(s: Scalar, text: &str) -> Option<Vec<u8>> {
    match s {
        Scalar::Bool => match text {
            "true" | "1" => Some(1u32.to_le_bytes().to_vec()),
            "false" | "0" => Some(0u32.to_le_bytes().to_vec()),
            _ => None,
        },
        Scalar::Int { bits, signed: true } => {
            let v: i64 = text.parse().ok()?;
            let fits = bits >= 64 || (v >= -(1i64 << (bits - 1)) && v < (1i64 << (bits - 1)));
            fits.then(|| v.to_le_bytes()[..(bits / 8) as usize].to_vec())
        }
        Scalar::Int { bits, signed: false } => {
            let v: u64 = text.parse().ok()?;
            let fits = bits >= 64 || v < (1u64 << bits);
            fits.then(|| v.to_le_bytes()[..(bits / 8) as usize].to_vec())
        }
        Scalar::Float { bits: 32 } => {
            let v: f32 = text.parse().ok().filter(|v: &f32| v.is_finite())?;
            Some(v.to_le_bytes().to_vec())
        }
        Scalar::Float { bits: 64 } => {
            let v: f64 = text.parse().ok().filter(|v: &f64| v.is_finite())?;
            Some(v.to_le_bytes().to_vec())
        }
        // A 16-bit float would need a half conversion rtprobe does not make.
        Scalar::Float { .. } => None,
    }
}

/// Every `--spec` of `given` checked against the constants `modules` declare.
pub fn parse_all(given: &[String], modules: &[UserModule]) -> Result<Vec<SpecValue>, SpecError> {
    let declared: Vec<&SpecConstant> =
        modules.iter().flat_map(|m| &m.iface.reflection.spec_constants).collect();
    let mut out: Vec<SpecValue> = Vec::new();
    for g in given {
        let (id, value) = g.split_once('=').ok_or_else(|| SpecError::Syntax(g.clone()))?;
        let id: u32 = id.trim().parse().map_err(|_| SpecError::Syntax(g.clone()))?;
        let Some(c) = declared.iter().find(|c| c.spec_id == id) else {
            let mut ids: Vec<u32> = declared.iter().map(|c| c.spec_id).collect();
            ids.sort_unstable();
            ids.dedup();
            let known = if ids.is_empty() {
                "the modules declare no specialization constants: drop --spec".to_string()
            } else {
                let list: Vec<String> = ids.iter().map(u32::to_string).collect();
                format!("give one of the declared IDs: {}", list.join(", "))
            };
            return Err(SpecError::UnknownId { given: g.clone(), id, known });
        };
        let bytes = bytes_of(c.scalar, value.trim()).ok_or_else(|| {
            let (ty, what) = describe(c.scalar);
            SpecError::BadValue { given: g.clone(), id, ty, what }
        })?;
        let other =
            declared.iter().find(|d| d.spec_id == id && bytes_of(d.scalar, value.trim()).is_none());
        if let Some(d) = other {
            let (a, b) = (describe(c.scalar).0, describe(d.scalar).0);
            return Err(SpecError::Clash { given: g.clone(), id, a, b });
        }
        if out.iter().any(|v| v.id == id) {
            return Err(SpecError::Twice { given: g.clone(), id });
        }
        out.push(SpecValue { id, bytes, text: value.trim().to_string() });
    }
    Ok(out)
}

/// `values` in a normal form for the cell id: sorted by ID, each `ID=VALUE` with the value as
/// its declared type reads it back (`true`/`false`, a decimal integer, the shortest decimal
/// that is the float), so `--spec 1=02 --spec 0=5` and `--spec 0=5 --spec 1=2` are one cell.
pub fn canonical(values: &[SpecValue], modules: &[UserModule]) -> Vec<String> {
    let declared: Vec<&SpecConstant> =
        modules.iter().flat_map(|m| &m.iface.reflection.spec_constants).collect();
    let mut sorted: Vec<&SpecValue> = values.iter().collect();
    sorted.sort_by_key(|v| v.id);
    sorted
        .iter()
        .map(|v| {
            let scalar = declared.iter().find(|c| c.spec_id == v.id).map(|c| c.scalar);
            let text = scalar.and_then(|s| value_text(s, &v.bytes));
            format!("{}={}", v.id, text.unwrap_or_else(|| hex(&v.bytes)))
        })
        .collect()
}

/// The bytes of a value of type `s` in words; `None` when they are not one.
fn value_text(s: Scalar, bytes: &[u8]) -> Option<String> {
    let mut wide = [0u8; 8];
    wide.get_mut(..bytes.len())?.copy_from_slice(bytes);
    let unsigned = u64::from_le_bytes(wide);
    Some(match s {
        Scalar::Bool => (unsigned != 0).to_string(),
        Scalar::Int { bits, signed: true } if bits < 64 => {
            let shift = 64 - bits;
            (((unsigned << shift) as i64) >> shift).to_string()
        }
        Scalar::Int { signed: true, .. } => (unsigned as i64).to_string(),
        Scalar::Int { signed: false, .. } => unsigned.to_string(),
        Scalar::Float { bits: 32 } => f32::from_le_bytes(bytes.try_into().ok()?).to_string(),
        Scalar::Float { bits: 64 } => f64::from_le_bytes(bytes.try_into().ok()?).to_string(),
        Scalar::Float { .. } => return None,
    })
}

/// Bytes as hex, for a value whose type is unknown.
fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

/// The map entries and data of one stage: the values of `values` whose constant `module`
/// declares, packed in order.
pub fn stage_info(
    module: &UserModule,
    values: &[SpecValue],
) -> (Vec<ash::vk::SpecializationMapEntry>, Vec<u8>) {
    let (mut entries, mut data) = (Vec::new(), Vec::new());
    let declared = &module.iface.reflection.spec_constants;
    for v in values {
        let Some(c) = declared.iter().find(|c| c.spec_id == v.id) else { continue };
        let bytes = bytes_of(c.scalar, &v.text).unwrap_or_else(|| v.bytes.clone());
        entries.push(ash::vk::SpecializationMapEntry {
            constant_id: v.id,
            offset: data.len() as u32,
            size: bytes.len(),
        });
        data.extend_from_slice(&bytes);
    }
    (entries, data)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn module(glsl: &str) -> UserModule {
        let words = crate::patches::assemble(&crate::patches::compiled(
            shaderc::ShaderKind::Miss,
            "t",
            glsl,
        ));
        UserModule::new("t.rmiss", &words).unwrap()
    }

    const SPEC: &str = "#version 460\n#extension GL_EXT_ray_tracing : require\n\
        layout(constant_id = 3) const uint COUNT = 4u;\n\
        layout(constant_id = 5) const float SCALE = 0.5;\n\
        layout(constant_id = 7) const bool ON = false;\n\
        layout(constant_id = 9) const int OFF = -1;\n\
        layout(location = 0) rayPayloadInEXT vec4 c;\n\
        void main() { c = vec4(float(COUNT) * SCALE + float(OFF), ON ? 1.0 : 0.0, 0.0, 1.0); }\n";

    #[test]
    fn values_take_the_declared_types_bytes() {
        let m = module(SPEC);
        let given: Vec<String> =
            ["3=16", "5=2.5", "7=true", "9=-3"].iter().map(|s| s.to_string()).collect();
        let v = parse_all(&given, std::slice::from_ref(&m)).unwrap();
        assert_eq!(
            v[0],
            SpecValue { id: 3, bytes: 16u32.to_le_bytes().to_vec(), text: "16".into() }
        );
        assert_eq!(v[1].bytes, 2.5f32.to_le_bytes());
        assert_eq!(v[2].bytes, 1u32.to_le_bytes());
        assert_eq!(v[3].bytes, (-3i32).to_le_bytes());
        let (entries, data) = stage_info(&m, &v);
        assert_eq!(entries.len(), 4);
        assert_eq!((entries[1].constant_id, entries[1].offset, entries[1].size), (5, 4, 4));
        assert_eq!(data.len(), 16);
    }

    /// The twins: an ID no stage declares, a value not of the type, a negative uint, a
    /// missing `=`, an ID given twice: each one line naming what to give.
    #[test]
    fn bad_ids_and_values_are_refused() {
        let owned = module(SPEC);
        let m = std::slice::from_ref(&owned);
        let one = |s: &str| parse_all(&[s.to_string()], m);
        let e = one("4=1").unwrap_err();
        assert!(
            matches!(&e, SpecError::UnknownId { id: 4, .. })
                && e.to_string().contains("declared IDs: 3, 5, 7, 9"),
            "{e}"
        );
        assert!(matches!(one("3=-1"), Err(SpecError::BadValue { id: 3, .. })));
        assert!(matches!(one("3=1.5"), Err(SpecError::BadValue { .. })));
        assert!(matches!(one("5=wide"), Err(SpecError::BadValue { id: 5, .. })));
        assert!(matches!(one("7=yes"), Err(SpecError::BadValue { id: 7, .. })));
        assert!(matches!(one("3"), Err(SpecError::Syntax(_))));
        assert!(matches!(one("x=3"), Err(SpecError::Syntax(_))));
        let twice = parse_all(&["3=1".into(), "3=2".into()], m);
        assert!(matches!(twice, Err(SpecError::Twice { id: 3, .. })));
        for e in [one("4=1"), one("3=-1"), one("3")] {
            assert!(!e.unwrap_err().to_string().contains('\n'));
        }
    }

    /// Two stages declaring SpecId 3 as a uint and as a bool, or as a uint and a float: each
    /// stage gets the value in its own type's bytes; a value one type cannot hold is refused.
    #[test]
    fn one_spec_id_of_two_types_gets_each_stage_its_bytes() {
        let other = |ty: &str, v: &str| {
            module(&format!(
                "#version 460\n#extension GL_EXT_ray_tracing : require\n\
                layout(constant_id = 3) const {ty} K = {v};\n\
                layout(location = 0) rayPayloadInEXT vec4 c;\n\
                void main() {{ c = vec4(float(K)); }}\n"
            ))
        };
        let given = ["3=1".to_string()];
        let (uint, boolean) = (module(SPEC), other("bool", "true"));
        let v = parse_all(&given, &[module(SPEC), other("bool", "true")]).unwrap();
        assert_eq!(stage_info(&uint, &v).1, 1u32.to_le_bytes());
        assert_eq!(stage_info(&boolean, &v).1, 1u32.to_le_bytes());
        let float = other("float", "0.5");
        let v = parse_all(&["3=2".to_string()], &[module(SPEC), other("float", "0.5")]).unwrap();
        assert_eq!(stage_info(&float, &v).1, 2.0f32.to_le_bytes());
        assert_eq!(stage_info(&uint, &v).1, 2u32.to_le_bytes());
        let e = parse_all(&["3=2".into()], &[module(SPEC), other("bool", "true")]).unwrap_err();
        assert!(matches!(e, SpecError::Clash { id: 3, .. }), "{e}");
        assert!(e.to_string().contains("not one of both"), "{e}");
        assert!(parse_all(&given, &[module(SPEC), other("uint", "2u")]).is_ok());
    }

    /// Issue 24: the order given and each value's spelling do not change the normal form; a
    /// different value does (the twin).
    #[test]
    fn the_normal_form_sorts_and_spells_values_one_way() {
        let m = module(SPEC);
        let norm = |given: &[&str]| {
            let given: Vec<String> = given.iter().map(|s| s.to_string()).collect();
            canonical(
                &parse_all(&given, std::slice::from_ref(&m)).unwrap(),
                std::slice::from_ref(&m),
            )
        };
        let a = norm(&["9=-3", "3=16", "7=true", "5=2.5"]);
        assert_eq!(a, ["3=16", "5=2.5", "7=true", "9=-3"]);
        assert_eq!(norm(&["5=2.50", "3=016", "7=1", "9=-03"]), a);
        assert_eq!(norm(&["3=+16", "5=25e-1", "9=-3", "7=true"]), a);
        assert_ne!(norm(&["3=17", "5=2.5", "7=true", "9=-3"]), a);
        assert_ne!(norm(&["3=16", "5=2.5", "7=false", "9=-3"]), a);
    }

    /// A stage that does not declare a constant gets no entry for it.
    #[test]
    fn stages_get_only_their_own_constants() {
        let plain = module(
            "#version 460\n#extension GL_EXT_ray_tracing : require\n\
            layout(location = 0) rayPayloadInEXT vec4 c;\nvoid main() { c = vec4(1.0); }\n",
        );
        let v = vec![SpecValue { id: 3, bytes: vec![1, 0, 0, 0], text: "1".into() }];
        assert!(stage_info(&plain, &v).0.is_empty());
        assert_eq!(stage_info(&module(SPEC), &v).0.len(), 1);
    }
}
