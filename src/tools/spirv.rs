//! SPIRV-Tools, resolved once for every user (`patch`, the shader views of reports, later
//! `reduce`): `spirv-val`, `spirv-dis`, `spirv-as`, `spirv-reduce`, each the newest of the sid
//! root's (SPIRV-Tools 2026.x there) and PATH's (2023.1 on Debian 12). A validator that fails a
//! module because it does not know something the module uses — an opcode, a capability, Slang's
//! source-language tag — is [`Validation::TooOld`], never an invalid module.
use super::Tool;
use std::path::Path;

/// The SPIRV-Tools programs rtprobe uses.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SpirvTool {
    Val,
    Dis,
    As,
    Reduce,
}

impl SpirvTool {
    pub fn name(self) -> &'static str {
        match self {
            SpirvTool::Val => "spirv-val",
            SpirvTool::Dis => "spirv-dis",
            SpirvTool::As => "spirv-as",
            SpirvTool::Reduce => "spirv-reduce",
        }
    }
}

/// `SPIRV-Tools v2026.4 unknown hash, …` → ((2026, 4), "v2026.4").
pub fn parse_version(out: &str) -> Option<((u32, u32), String)> {
    let at = out.find("SPIRV-Tools v")? + "SPIRV-Tools ".len();
    let word = out[at..].split_whitespace().next()?.trim_end_matches(',');
    let mut it = word.trim_start_matches('v').split(['.', '-']).map(|p| p.parse::<u32>().ok());
    Some(((it.next()??, it.next()??), word.to_string()))
}

/// The newest `t` of this machine, if any.
pub fn tool(t: SpirvTool) -> Option<&'static Tool> {
    super::find(t.name(), None, parse_version)
}

/// How to validate a module: its Vulkan environment and the layout options its blocks need.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct ValOptions {
    /// `--target-env`, e.g. "vulkan1.2".
    pub env: String,
    /// `--scalar-block-layout` (the module needs the scalarBlockLayout feature).
    pub scalar_block_layout: bool,
    /// `--uniform-buffer-standard-layout` (uniformBufferStandardLayout).
    pub uniform_buffer_standard_layout: bool,
}

impl ValOptions {
    /// The environment a module of SPIR-V `version` (the header word) is checked in: Vulkan 1.3
    /// for SPIR-V 1.6, else Vulkan 1.2 (which accepts SPIR-V 1.0 to 1.5).
    pub fn for_version(version: u32) -> ValOptions {
        let env = if version >= 0x0001_0600 { "vulkan1.3" } else { "vulkan1.2" };
        ValOptions { env: env.into(), ..ValOptions::default() }
    }

    /// The command-line flags.
    pub fn args(&self) -> Vec<String> {
        let mut a = vec!["--target-env".to_string(), self.env.clone()];
        if self.scalar_block_layout {
            a.push("--scalar-block-layout".into());
        }
        if self.uniform_buffer_standard_layout {
            a.push("--uniform-buffer-standard-layout".into());
        }
        a
    }

    /// `vulkan1.2, --scalar-block-layout` for messages.
    pub fn describe(&self) -> String {
        self.args()[1..].join(" ")
    }
}

/// What `spirv-val` said.
#[derive(Clone, Debug, PartialEq)]
pub enum Validation {
    /// No spirv-val here.
    Unavailable,
    Valid,
    /// The module is invalid: the validator's message, on one line.
    Invalid(String),
    /// The validator does not know something the module uses (`what`): a newer one is needed.
    TooOld {
        validator: String,
        what: String,
    },
}

/// The words as little-endian bytes.
pub fn bytes(words: &[u32]) -> Vec<u8> {
    words.iter().flat_map(|w| w.to_le_bytes()).collect()
}

/// `words` written to `<tag>.spv` in a fresh private folder (removed when the folder is
/// dropped): never a predictable name in /tmp, where a planted link would be written through.
fn temp_module(
    tag: &str,
    words: &[u32],
) -> std::io::Result<(crate::tempdir::TempDir, std::path::PathBuf)> {
    let dir = crate::tempdir::TempDir::named("rtprobe-spv")?;
    let path = dir.path().join(format!("{tag}.spv"));
    std::fs::write(&path, bytes(words))?;
    Ok((dir, path))
}

/// Validate `words` with `opts`.
pub fn validate(words: &[u32], opts: &ValOptions) -> Validation {
    let Some(val) = tool(SpirvTool::Val) else {
        return Validation::Unavailable;
    };
    let Ok((_dir, path)) = temp_module("val", words) else {
        return Validation::Unavailable;
    };
    let out = val.command().args(opts.args()).arg(&path).output();
    let Ok(o) = out else {
        return Validation::Unavailable;
    };
    if o.status.success() {
        return Validation::Valid;
    }
    let msg = String::from_utf8_lossy(&o.stderr).to_string() + &String::from_utf8_lossy(&o.stdout);
    let msg = msg.trim().replace('\n', " | ");
    match too_old(&msg) {
        Some(what) => Validation::TooOld { validator: val.describe(), what },
        None => Validation::Invalid(msg),
    }
}

/// Whether a validator message is about layout rules (a sign the module needs another layout
/// option, such as `--scalar-block-layout`).
fn layout_message(msg: &str) -> bool {
    msg.contains("layout rules")
}

/// Validate an input module with the options its layouts need: its SPIR-V version's environment,
/// then, when only layout rules fail, with `--scalar-block-layout` and also
/// `--uniform-buffer-standard-layout`. Returns the options it passed with (or the first ones'
/// verdict when none passes).
pub fn validate_input(words: &[u32]) -> (Validation, ValOptions) {
    let base = ValOptions::for_version(words.get(1).copied().unwrap_or(0));
    let first = validate(words, &base);
    let Validation::Invalid(msg) = &first else {
        return (first, base);
    };
    if !layout_message(msg) {
        return (first, base);
    }
    let scalar = ValOptions { scalar_block_layout: true, ..base.clone() };
    let both = ValOptions { uniform_buffer_standard_layout: true, ..scalar.clone() };
    for opts in [scalar, both] {
        if validate(words, &opts) == Validation::Valid {
            return (Validation::Valid, opts);
        }
    }
    (first, base)
}

/// What an old validator's message says it does not know (its binary parser's "Invalid …
/// operand: N", "Invalid opcode: N", an unknown extension or SPIR-V version), or `None` when the
/// message is about the module.
pub fn too_old(msg: &str) -> Option<String> {
    if let Some(at) = msg.find("Invalid source language operand: ") {
        let n = number_after(&msg[at + "Invalid source language operand: ".len()..])?;
        return Some(format!("the module's OpSource language {}", source_language(n)));
    }
    if let Some(at) = msg.find("Invalid capability operand: ") {
        let n = number_after(&msg[at + "Invalid capability operand: ".len()..])?;
        let name = rspirv::spirv::Capability::from_u32(n)
            .map(|c| format!("{c:?}"))
            .unwrap_or_else(|| n.to_string());
        return Some(format!("capability {name}"));
    }
    if let Some(at) = msg.find("Invalid opcode: ") {
        let n = number_after(&msg[at + "Invalid opcode: ".len()..])?;
        let name = rspirv::spirv::Op::from_u32(n)
            .map(|o| format!("Op{o:?}"))
            .unwrap_or_else(|| n.to_string());
        return Some(format!("instruction {name}"));
    }
    if msg.contains("Invalid SPIR-V binary version") {
        return Some("the module's SPIR-V version".into());
    }
    let unknown_ext = ["Found unrecognized extension ", "unknown extension "];
    if let Some(e) = unknown_ext.iter().find_map(|p| msg.find(p).map(|at| &msg[at + p.len()..])) {
        return Some(format!("extension {}", e.split_whitespace().next().unwrap_or("")));
    }
    let at = msg.find("Invalid ")?;
    let rest = &msg[at + "Invalid ".len()..];
    let (kind, tail) = rest.split_once(" operand: ")?;
    (kind.len() < 40 && number_after(tail).is_some())
        .then(|| format!("{kind} operand {}", number_after(tail).unwrap_or(0)))
}

fn number_after(s: &str) -> Option<u32> {
    s.split(|c: char| !c.is_ascii_digit()).next()?.parse().ok()
}

/// The name of SPIR-V source language `n`.
fn source_language(n: u32) -> String {
    rspirv::spirv::SourceLanguage::from_u32(n)
        .map(|l| format!("{l:?} ({n})"))
        .unwrap_or_else(|| n.to_string())
}

/// `spirv-dis` of `words` (`--raw-id` when `raw_ids`), or why not.
pub fn disassemble(words: &[u32], raw_ids: bool) -> Result<String, String> {
    let dis = tool(SpirvTool::Dis).ok_or("spirv-dis is not installed")?;
    let (_dir, path) = temp_module("dis", words).map_err(|e| e.to_string())?;
    let mut c = dis.command();
    if raw_ids {
        c.arg("--raw-id");
    }
    let out = c.arg(&path).output();
    let o = out.map_err(|e| format!("{}: {e}", dis.describe()))?;
    if !o.status.success() {
        return Err(String::from_utf8_lossy(&o.stderr).trim().replace('\n', " | "));
    }
    Ok(String::from_utf8_lossy(&o.stdout).into_owned())
}

/// `spirv-as --target-env env SOURCE -o OUT`, or why not.
pub fn assemble(source: &Path, out: &Path, env: &str) -> Result<(), String> {
    let a = tool(SpirvTool::As).ok_or("spirv-as is not installed")?;
    let o = a
        .command()
        .args(["--target-env", env])
        .arg(source)
        .arg("-o")
        .arg(out)
        .output()
        .map_err(|e| format!("{}: {e}", a.describe()))?;
    if !o.status.success() {
        return Err(String::from_utf8_lossy(&o.stderr).trim().replace('\n', " | "));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn versions_parse() {
        let v = parse_version("SPIRV-Tools v2026.4 unknown hash, 2026-10-02T11:54:22+00:00\n");
        assert_eq!(v, Some(((2026, 4), "v2026.4".into())));
        assert_eq!(parse_version("SPIRV-Tools v2023.1 unknown hash").unwrap().0, (2023, 1));
        assert_eq!(parse_version("SPIRV-Tools v2024.2-dev abc").unwrap().0, (2024, 2));
        assert_eq!(parse_version("spirv-val: command not found"), None);
    }

    #[test]
    fn an_old_validators_parse_errors_are_its_age_and_module_errors_are_not() {
        let slang = "error: line 4: Invalid source language operand: 11";
        assert_eq!(too_old(slang).unwrap(), "the module's OpSource language Slang (11)");
        let ser = "error: line 2: Invalid capability operand: 5388";
        assert_eq!(too_old(ser).unwrap(), "capability ShaderInvocationReorderEXT");
        assert!(too_old("error: line 9: Invalid opcode: 5337")
            .unwrap()
            .starts_with("instruction Op"));
        assert!(too_old("Invalid SPIR-V binary version 1.7").is_some());
        // A real error in the module is not the validator's age.
        let real =
            "error: line 64: Structure id 41 decorated as Block for variable in PushConstant \
                    storage class must follow relaxed storage buffer layout rules";
        assert_eq!(too_old(real), None);
        assert_eq!(too_old("ID '35[%35]' has not been defined"), None);
        assert!(layout_message(real));
    }

    #[test]
    fn environments_follow_the_spirv_version() {
        assert_eq!(ValOptions::for_version(0x0001_0500).env, "vulkan1.2");
        assert_eq!(ValOptions::for_version(0x0001_0300).env, "vulkan1.2");
        assert_eq!(ValOptions::for_version(0x0001_0600).env, "vulkan1.3");
        let o = ValOptions { scalar_block_layout: true, ..ValOptions::for_version(0x0001_0500) };
        assert_eq!(o.describe(), "vulkan1.2 --scalar-block-layout");
    }
}
