//! An external `glslangValidator` for what shaderc's bundled glslang (mid-2025) cannot compile:
//! GLSL with `GL_EXT_descriptor_heap` (`layout(descriptor_heap)`, glslang >= 16.2). Found on PATH
//! (`RTPROBE_GLSLANG` overrides) and accepted by the version it prints; used only for sources
//! that enable that extension, compiled for Vulkan 1.3 / SPIR-V 1.6 without optimization.
use super::error::CompileError;
use super::Role;
use std::path::PathBuf;
use std::process::{Command, Stdio};
use std::sync::OnceLock;

/// The GLSL extension only this compiler handles.
pub const HEAP_EXTENSION: &str = "GL_EXT_descriptor_heap";
/// The first glslang release with GL_EXT_descriptor_heap.
pub const MIN_VERSION: (u32, u32) = (16, 2);

#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Glslang {
    pub path: PathBuf,
    /// "16.6.0"
    pub version: String,
}

/// `Glslang Version: 11:16.6.0` → (16, 6).
pub fn parse_version(out: &str) -> Option<(u32, u32)> {
    let line = out.lines().find(|l| l.starts_with("Glslang Version:"))?;
    let v = line.rsplit(':').next()?.trim();
    let mut it = v.split('.').map(|p| p.parse::<u32>().ok());
    Some((it.next()??, it.next()??))
}

/// The heap-capable glslangValidator of this machine, looked up once per process.
pub fn find() -> Option<&'static Glslang> {
    static FOUND: OnceLock<Option<Glslang>> = OnceLock::new();
    FOUND
        .get_or_init(|| {
            let path = PathBuf::from(
                std::env::var_os("RTPROBE_GLSLANG").unwrap_or_else(|| "glslangValidator".into()),
            );
            let out = Command::new(&path).arg("--version").stdin(Stdio::null()).output().ok()?;
            let text = String::from_utf8_lossy(&out.stdout);
            let v = parse_version(&text)?;
            let version = text
                .lines()
                .find(|l| l.starts_with("Glslang Version:"))?
                .rsplit(':')
                .next()?
                .trim()
                .to_string();
            (v >= MIN_VERSION).then_some(Glslang { path, version })
        })
        .as_ref()
}

/// Why heap GLSL cannot be compiled here, for `not_implemented` reasons.
pub fn missing_reason() -> String {
    format!(
        "no GLSL compiler with {HEAP_EXTENSION} here (glslangValidator >= {}.{} on PATH or RTPROBE_GLSLANG; shaderc's bundled glslang predates it; scripts/in-sid has one)",
        MIN_VERSION.0, MIN_VERSION.1
    )
}

fn stage(role: Role) -> &'static str {
    match role {
        Role::Raygen => "rgen",
        Role::Miss | Role::ProbeMiss => "rmiss",
        Role::ClosestHitTriangles | Role::ClosestHitProcedural => "rchit",
        Role::Intersection => "rint",
        Role::AnyHit => "rahit",
        Role::Callable => "rcall",
        Role::Vertex => "vert",
        Role::Fragment => "frag",
        Role::Compute => "comp",
    }
}

/// Compile `glsl` with the external glslangValidator (uncached; [`super::compile::Compiler`] caches).
pub fn compile(role: Role, glsl: &str) -> Result<Vec<u32>, CompileError> {
    let file = role.file_name().to_string();
    let g = find()
        .ok_or_else(|| CompileError::Glsl { file: file.clone(), message: missing_reason() })?;
    let dir = TempDir::new().map_err(|e| CompileError::Glsl {
        file: file.clone(),
        message: format!("temporary folder: {e}"),
    })?;
    let src = dir.0.join(&file);
    let spv = dir.0.join("out.spv");
    std::fs::write(&src, glsl)
        .map_err(|e| CompileError::Glsl { file: file.clone(), message: e.to_string() })?;
    let out = Command::new(&g.path)
        .args(["-V", "--target-env", "vulkan1.3", "-S", stage(role), "-o"])
        .arg(&spv)
        .arg(&src)
        .stdin(Stdio::null())
        .output()
        .map_err(|e| CompileError::Glsl {
            file: file.clone(),
            message: format!("{}: {e}", g.path.display()),
        })?;
    if !out.status.success() {
        let msg = String::from_utf8_lossy(&out.stdout).to_string()
            + &String::from_utf8_lossy(&out.stderr);
        return Err(CompileError::Glsl {
            file,
            message: format!("glslang {}: {}", g.version, msg.trim().replace('\n', " | ")),
        });
    }
    let bytes = std::fs::read(&spv)
        .map_err(|e| CompileError::Glsl { file: file.clone(), message: e.to_string() })?;
    if bytes.len() % 4 != 0 || bytes.is_empty() {
        return Err(CompileError::Glsl {
            file,
            message: "glslangValidator wrote no SPIR-V".into(),
        });
    }
    Ok(bytes.chunks_exact(4).map(|w| u32::from_le_bytes([w[0], w[1], w[2], w[3]])).collect())
}

/// A private folder under the system temp dir, removed on drop.
struct TempDir(PathBuf);

impl TempDir {
    fn new() -> std::io::Result<TempDir> {
        static N: std::sync::atomic::AtomicU32 = std::sync::atomic::AtomicU32::new(0);
        let n = N.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        let p = std::env::temp_dir().join(format!("rtprobe-glslang-{}-{n}", std::process::id()));
        std::fs::create_dir_all(&p)?;
        Ok(TempDir(p))
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn versions_parse_and_old_glslang_is_refused() {
        assert_eq!(parse_version("Glslang Version: 11:16.6.0\nESSL Version: ..."), Some((16, 6)));
        assert_eq!(parse_version("Glslang Version: 11:12.0.0"), Some((12, 0)));
        assert!(parse_version("Glslang Version: 11:12.0.0").unwrap() < MIN_VERSION);
        assert_eq!(parse_version("garbage"), None);
    }
}
