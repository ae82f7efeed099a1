//! An external `glslangValidator` for what the glslang inside shaderc cannot compile: GLSL that
//! enables an extension of [`EXTENSIONS`], such as `GL_EXT_descriptor_heap`
//! (`layout(descriptor_heap)`, glslang >= 16.2). The newest of the sid root's and PATH's
//! (`RTPROBE_GLSLANG` replaces the PATH lookup; [`crate::tools`]), accepted by the version it
//! prints. rtprobe's heap shaders are compiled for Vulkan 1.3 /
//! SPIR-V 1.6 without optimization; user GLSL (`patch --glsl`) for its own target, with its `-I`
//! and `-D`.
use super::error::CompileError;
use super::Role;
use crate::tools::Tool;

/// The GLSL extension of rtprobe's heap shaders, which only this compiler handles.
pub const HEAP_EXTENSION: &str = "GL_EXT_descriptor_heap";
/// Extensions newer than the glslang in shaderc (the system's 12, the bundled 15.3): a source that
/// enables one is compiled by this glslangValidator.
pub const EXTENSIONS: &[&str] = &[HEAP_EXTENSION, "GL_EXT_shader_invocation_reorder"];
/// The first glslang release with GL_EXT_descriptor_heap (it has all of [`EXTENSIONS`]).
pub const MIN_VERSION: (u32, u32) = (16, 2);

/// The first extension of [`EXTENSIONS`] that `glsl` enables (`#extension NAME : ...`).
pub fn needed_by(glsl: &str) -> Option<&'static str> {
    glsl.lines().find_map(|l| {
        let rest = l.trim_start().strip_prefix('#')?.trim_start().strip_prefix("extension")?;
        let name = rest.split(|c: char| c == ':' || c.is_whitespace()).find(|w| !w.is_empty())?;
        EXTENSIONS.iter().find(|e| **e == name).copied()
    })
}

/// The heap-capable glslangValidator of this machine: the newest of the sid root's and PATH's
/// (`RTPROBE_GLSLANG` replaces the PATH lookup; [`crate::tools`]), accepted from [`MIN_VERSION`].
pub fn find() -> Option<&'static Tool> {
    crate::tools::glslang().filter(|g| g.version >= MIN_VERSION)
}

/// Why heap GLSL cannot be compiled here, for `not_implemented` reasons.
pub fn missing_reason() -> String {
    missing_for(HEAP_EXTENSION)
}

/// Why GLSL enabling `extension` (one of [`EXTENSIONS`]) cannot be compiled here.
pub fn missing_for(extension: &str) -> String {
    let root = match crate::tools::sid_root() {
        Some(r) => format!("the sid root at {} has none that new", r.display()),
        None => "no sid root here (RTPROBE_SID_ROOT, default /var/lib/rtprobe/sid-root): \
                 scripts/setup-sid makes one with glslang 16.6"
            .into(),
    };
    format!(
        "no GLSL compiler with {extension} here: the glslang in shaderc predates it, and no \
         glslangValidator >= {}.{} is on PATH or in RTPROBE_GLSLANG; {root}",
        MIN_VERSION.0, MIN_VERSION.1
    )
}

fn stage(role: Role) -> &'static str {
    stage_of_kind(role.kind())
}

/// glslangValidator's `-S` name of a shaderc kind (`patch --glsl`'s stages).
pub fn stage_of_kind(kind: shaderc::ShaderKind) -> &'static str {
    use shaderc::ShaderKind as K;
    match kind {
        K::RayGeneration => "rgen",
        K::ClosestHit => "rchit",
        K::AnyHit => "rahit",
        K::Miss => "rmiss",
        K::Intersection => "rint",
        K::Callable => "rcall",
        K::Vertex => "vert",
        K::Fragment => "frag",
        _ => "comp",
    }
}

/// Compile `glsl` with the external glslangValidator (uncached; [`super::compile::Compiler`] caches).
pub fn compile(role: Role, glsl: &str) -> Result<Vec<u32>, CompileError> {
    compile_with(
        role.file_name(),
        stage(role),
        glsl,
        HEAP_EXTENSION,
        &["--target-env", "vulkan1.3"],
    )
}

/// Compile user GLSL that enables `extension` (`patch --glsl`): `args` carry its target, `-I`
/// and `-D`. `file` names it in messages.
pub fn compile_with(
    file: &str,
    stage: &str,
    glsl: &str,
    extension: &str,
    args: &[&str],
) -> Result<Vec<u32>, CompileError> {
    let file = file.to_string();
    let g = find().ok_or_else(|| CompileError::Glsl {
        file: file.clone(),
        message: missing_for(extension),
    })?;
    let dir = crate::tempdir::TempDir::named("rtprobe-glslang")
        .map_err(|e| CompileError::Glsl { file: file.clone(), message: e.to_string() })?;
    // The source keeps its own name (glslang's messages name it), without its folders.
    let base = std::path::Path::new(&file).file_name().map_or("shader".into(), |b| b.to_owned());
    let src = dir.path().join(base);
    let spv = dir.path().join("out.spv");
    std::fs::write(&src, glsl)
        .map_err(|e| CompileError::Glsl { file: file.clone(), message: e.to_string() })?;
    let out = g
        .command()
        .arg("-V")
        .args(args)
        .args(["-S", stage, "-o"])
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
        let msg = msg.replace(&format!("{}/", dir.path().display()), "");
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn old_glslang_is_refused() {
        let v = crate::tools::parse_glslang_version("Glslang Version: 11:12.0.0").unwrap().0;
        assert!(v < MIN_VERSION);
        let new = crate::tools::parse_glslang_version("Glslang Version: 11:16.6.0").unwrap().0;
        assert!(new >= MIN_VERSION);
    }

    #[test]
    fn newer_extensions_are_found_in_extension_lines_only() {
        assert_eq!(
            needed_by("#version 460\n#extension GL_EXT_descriptor_heap : require\n"),
            Some(HEAP_EXTENSION)
        );
        assert_eq!(
            needed_by("  #  extension   GL_EXT_shader_invocation_reorder:enable\n"),
            Some("GL_EXT_shader_invocation_reorder")
        );
        // The NV extension glslang 12 knows, a name in a comment and a longer name are not it.
        assert_eq!(needed_by("#extension GL_NV_shader_invocation_reorder : require\n"), None);
        assert_eq!(needed_by("// #extension GL_EXT_descriptor_heap : require\n"), None);
        assert_eq!(needed_by("#extension GL_EXT_descriptor_heap_more : require\n"), None);
    }
}
