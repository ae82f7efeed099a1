//! An external `glslangValidator` for what shaderc's bundled glslang (mid-2025) cannot compile:
//! GLSL with `GL_EXT_descriptor_heap` (`layout(descriptor_heap)`, glslang >= 16.2). Found on PATH
//! (`RTPROBE_GLSLANG` overrides) and accepted by the version it prints; used only for sources
//! that enable that extension, compiled for Vulkan 1.3 / SPIR-V 1.6 without optimization.
use super::error::CompileError;
use super::Role;
use crate::tools::Tool;
use std::path::PathBuf;

/// The GLSL extension only this compiler handles.
pub const HEAP_EXTENSION: &str = "GL_EXT_descriptor_heap";
/// The first glslang release with GL_EXT_descriptor_heap.
pub const MIN_VERSION: (u32, u32) = (16, 2);

/// The heap-capable glslangValidator of this machine: the newest of the sid root's and PATH's
/// (`RTPROBE_GLSLANG` replaces the PATH lookup; [`crate::tools`]), accepted from [`MIN_VERSION`].
pub fn find() -> Option<&'static Tool> {
    crate::tools::glslang().filter(|g| g.version >= MIN_VERSION)
}

/// Why heap GLSL cannot be compiled here, for `not_implemented` reasons.
pub fn missing_reason() -> String {
    format!(
        "no GLSL compiler with {HEAP_EXTENSION} here (glslangValidator >= {}.{} on PATH, RTPROBE_GLSLANG, or the sid root of scripts/setup-sid; shaderc's bundled glslang predates it)",
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
    let out = g
        .command()
        .args(["-V", "--target-env", "vulkan1.3", "-S", stage(role), "-o"])
        .arg(&spv)
        .arg(&src)
        .output()
        .map_err(|e| CompileError::Glsl {
            file: file.clone(),
            message: format!("{}: {e}", g.describe()),
        })?;
    if !out.status.success() {
        let msg = String::from_utf8_lossy(&out.stdout).to_string()
            + &String::from_utf8_lossy(&out.stderr);
        return Err(CompileError::Glsl {
            file,
            message: format!("glslang {}: {}", g.version_text, msg.trim().replace('\n', " | ")),
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

/// The `-S` stage name of a shaderc kind (the stages `rtprobe patch` compiles).
pub fn stage_name(kind: shaderc::ShaderKind) -> Option<&'static str> {
    use shaderc::ShaderKind as K;
    Some(match kind {
        K::RayGeneration => "rgen",
        K::ClosestHit => "rchit",
        K::AnyHit => "rahit",
        K::Miss => "rmiss",
        K::Intersection => "rint",
        K::Callable => "rcall",
        K::Vertex => "vert",
        K::Fragment => "frag",
        K::Compute => "comp",
        _ => return None,
    })
}

/// Compile the user's GLSL file `input` with glslangValidator `g` (which reads it and its
/// includes itself) as `stage`, with `args` (`--target-env`, `-I`, `-D`) before the file.
/// Errors are one line.
pub fn compile_file(
    g: &Tool,
    stage: &str,
    input: &std::path::Path,
    args: &[String],
) -> Result<Vec<u32>, CompileError> {
    let file = super::include::display(input);
    let err = |message: String| CompileError::Glsl { file: file.clone(), message };
    let dir = TempDir::new().map_err(|e| err(format!("temporary folder: {e}")))?;
    let spv = dir.0.join("out.spv");
    let out = g
        .command()
        .args(["-V", "-S", stage])
        .args(args)
        .arg("-o")
        .arg(&spv)
        .arg(input)
        .output()
        .map_err(|e| err(format!("{}: {e}", g.describe())))?;
    if !out.status.success() {
        let msg = String::from_utf8_lossy(&out.stdout).to_string()
            + &String::from_utf8_lossy(&out.stderr);
        let lines: Vec<&str> = msg
            .lines()
            .map(str::trim)
            .filter(|l| l.starts_with("ERROR:") && !l.contains("compilation errors"))
            .collect();
        let text =
            if lines.is_empty() { msg.trim().replace('\n', " | ") } else { lines.join(" | ") };
        return Err(err(format!("{}: {text}", g.describe())));
    }
    let bytes = std::fs::read(&spv).map_err(|e| err(e.to_string()))?;
    if bytes.len() % 4 != 0 || bytes.is_empty() {
        return Err(err("glslangValidator wrote no SPIR-V".into()));
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
    fn old_glslang_is_refused() {
        let v = crate::tools::parse_glslang_version("Glslang Version: 11:12.0.0").unwrap().0;
        assert!(v < MIN_VERSION);
        assert!(
            crate::tools::parse_glslang_version("Glslang Version: 11:16.6.0").unwrap().0
                >= MIN_VERSION
        );
    }
}
