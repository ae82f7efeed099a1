//! One module of a user pipeline as the harness holds it ([`UserModule`]): its name, SPIR-V and
//! reflected interface; and the VK_GOOGLE device extensions its `SPV_GOOGLE_*` extensions need
//! ([`google`]).
use super::error::HarnessError;
use super::reflect::{self, Interface};
use crate::vk::GoogleHlsl;

/// One module of a pipeline: its name, SPIR-V and interface.
#[derive(Clone, Debug)]
pub struct UserModule {
    pub name: String,
    pub words: Vec<u32>,
    pub iface: Interface,
}

impl UserModule {
    pub fn new(name: &str, words: &[u32]) -> Result<UserModule, HarnessError> {
        let m = crate::patches::load(&crate::tools::spirv::bytes(words))
            .map_err(|e| HarnessError::Interface(format!("{name}: {e}")))?;
        let iface =
            reflect::reflect(&m).map_err(|e| HarnessError::Unsupported(format!("{name}: {e}")))?;
        Ok(UserModule { name: name.to_string(), words: words.to_vec(), iface })
    }
}

/// `OpExtension`'s opcode.
const OP_EXTENSION: u32 = 10;

/// The names of the SPIR-V extensions `words` declares (`OpExtension`); words past a truncated
/// instruction are not read.
pub fn spirv_extensions(words: &[u32]) -> Vec<String> {
    let mut out = Vec::new();
    let mut at = 5;
    while let Some(&first) = words.get(at) {
        let (count, op) = ((first >> 16) as usize, first & 0xffff);
        let Some(operands) = words.get(at + 1..at + count.max(1)) else { break };
        if op == OP_EXTENSION {
            let bytes: Vec<u8> = operands.iter().flat_map(|w| w.to_le_bytes()).collect();
            let end = bytes.iter().position(|b| *b == 0).unwrap_or(bytes.len());
            out.push(String::from_utf8_lossy(&bytes[..end]).into_owned());
        }
        at += count.max(1);
    }
    out
}

/// The VK_GOOGLE extensions `modules` need (DXC's `-fspv-reflect` output).
pub fn google<'a>(modules: impl IntoIterator<Item = &'a UserModule>) -> GoogleHlsl {
    google_of(modules.into_iter().map(|m| m.words.as_slice()))
}

/// [`google`] of modules given as their SPIR-V words.
pub fn google_of<'a>(modules: impl IntoIterator<Item = &'a [u32]>) -> GoogleHlsl {
    let mut g = GoogleHlsl::default();
    for words in modules {
        spirv_extensions(words).iter().for_each(|e| g.note(e));
    }
    g
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A module's `OpExtension`s are read; the GOOGLE ones ask for their device extensions, and
    /// a device without one refuses it in one line naming it and what to do (the twin: with it,
    /// nothing is missing; a module without them asks for none).
    #[test]
    fn google_extensions_are_asked_for_and_refused_where_missing() {
        let mut words = vec![0x0723_0203, 0x0001_0500, 0, 16, 0];
        let ext = |name: &str| {
            let mut bytes = name.as_bytes().to_vec();
            bytes.resize((bytes.len() / 4 + 1) * 4, 0);
            let ops: Vec<u32> =
                bytes.chunks(4).map(|c| u32::from_le_bytes(c.try_into().unwrap())).collect();
            let mut i = vec![((ops.len() as u32 + 1) << 16) | OP_EXTENSION];
            i.extend(ops);
            i
        };
        words.extend([(2 << 16) | 17, 4479]); // OpCapability RayTracingKHR
        words.extend(ext("SPV_GOOGLE_hlsl_functionality1"));
        words.extend(ext("SPV_GOOGLE_user_type"));
        words.extend(ext("SPV_KHR_ray_tracing"));
        let names = spirv_extensions(&words);
        assert_eq!(
            names,
            ["SPV_GOOGLE_hlsl_functionality1", "SPV_GOOGLE_user_type", "SPV_KHR_ray_tracing"]
        );
        let mut g = GoogleHlsl::default();
        names.iter().for_each(|n| g.note(n));
        assert!(g.hlsl_functionality1 && g.user_type && !g.decorate_string);
        let lacks_user_type = |e: &std::ffi::CStr| e != ash::google::user_type::NAME;
        let missing = g.missing(lacks_user_type);
        assert_eq!(missing.len(), 1);
        assert!(
            missing[0].starts_with("VK_GOOGLE_user_type (the modules declare SPV_GOOGLE_user_type")
        );
        assert!(missing[0].contains("without -fspv-reflect") && !missing[0].contains('\n'));
        assert!(g.missing(|_| true).is_empty());
        assert_eq!(g.extensions().len(), 2);
        assert!(spirv_extensions(&words[..words.len() - 3]).len() == 2, "a truncated one is left");
        assert_eq!(GoogleHlsl::default().extensions().len(), 0);
    }
}
