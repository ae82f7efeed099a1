//! One module of a user pipeline as the harness holds it ([`UserModule`]): its name, SPIR-V and
//! reflected interface.
use super::error::HarnessError;
use super::reflect::{self, Interface};

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
