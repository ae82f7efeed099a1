//! One module of a user pipeline as the harness holds it ([`UserModule`]): its name, SPIR-V and
//! reflected interface; the VK_GOOGLE device extensions its `SPV_GOOGLE_*` extensions need
//! ([`google`]); and everything its capabilities and extensions need ([`needs`]).
use super::capabilities::{self, Needs};
use super::error::HarnessError;
use super::reflect::{self, Interface};
use crate::vk::GoogleHlsl;
use crate::vk::Requirements;

/// One module of a pipeline: its name, SPIR-V and interface.
#[derive(Clone, Debug)]
pub struct UserModule {
    pub name: String,
    pub words: Vec<u32>,
    pub iface: Interface,
    /// The ray type (SBT record offset) whose hit groups hold this hit shader, where
    /// `--hit-group` says it (else `ray_types::assign` reads it from the payload).
    pub ray_type: Option<u32>,
}

impl UserModule {
    pub fn new(name: &str, words: &[u32]) -> Result<UserModule, HarnessError> {
        capabilities::needs([words])
            .map_err(|e| HarnessError::Unsupported(format!("{name}: {e}")))?;
        let m = crate::patches::load(&crate::tools::spirv::bytes(words))
            .map_err(|e| HarnessError::Interface(format!("{name}: {e}")))?;
        let iface =
            reflect::reflect(&m).map_err(|e| HarnessError::Unsupported(format!("{name}: {e}")))?;
        Ok(UserModule { name: name.to_string(), words: words.to_vec(), iface, ray_type: None })
    }
}

/// The names of the SPIR-V extensions `words` declares (`OpExtension`); words past a truncated
/// instruction are not read.
pub fn spirv_extensions(words: &[u32]) -> Vec<String> {
    capabilities::spirv_extensions(words)
}

/// What `modules` need of the device from their capabilities and extensions, set in `req`
/// (given as SPIR-V words; each [`UserModule`] was checked when it was made).
pub fn enable_needs<'a>(
    modules: impl IntoIterator<Item = &'a [u32]>,
    req: &mut Requirements,
) -> Result<Needs, HarnessError> {
    let n = capabilities::needs(modules).map_err(HarnessError::Unsupported)?;
    n.apply(req);
    Ok(n)
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
            let mut i = vec![((ops.len() as u32 + 1) << 16) | 10]; // OpExtension
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
