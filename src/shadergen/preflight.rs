//! Checks on user GLSL before a compiler sees it. The `#version` line: glslang, given a desktop
//! version below 150 or none (it then assumes 110), fails on its own built-in declarations and
//! prints all of them — thousands of lines — to the process's stdout; one line saying what to
//! write is said instead. And the extensions a source enables, so that one the bundled compiler
//! does not know can go to a newer glslangValidator.

/// The first directive of `glsl` when it is `#version N [profile]`: (N, profile). Blank lines,
/// comments and a byte-order mark may come before it; anything else means there is none.
pub fn version_line(glsl: &str) -> Option<(u32, Option<String>)> {
    let mut rest = glsl.trim_start_matches('\u{feff}');
    loop {
        rest = rest.trim_start();
        if let Some(r) = rest.strip_prefix("//") {
            rest = r.split_once('\n').map_or("", |(_, after)| after);
        } else if let Some(r) = rest.strip_prefix("/*") {
            rest = r.split_once("*/").map_or("", |(_, after)| after);
        } else {
            break;
        }
    }
    let line = rest.strip_prefix('#')?.lines().next()?;
    let mut words = line.split_whitespace();
    if words.next()? != "version" {
        return None;
    }
    let n = words.next()?.parse().ok()?;
    Some((n, words.next().map(str::to_string)))
}

/// The lowest desktop `#version` of each stage (ray tracing 460, compute 420, others 150).
fn min_version(kind: shaderc::ShaderKind) -> u32 {
    use shaderc::ShaderKind as K;
    match kind {
        K::RayGeneration | K::ClosestHit | K::AnyHit | K::Miss | K::Intersection | K::Callable => {
            460
        }
        K::Compute => 420,
        _ => 150,
    }
}

/// Why `glsl` cannot be compiled as a `kind` shader because of its `#version` (missing, or a
/// desktop version below the stage's minimum), or `None`.
pub fn version_problem(kind: shaderc::ShaderKind, glsl: &str) -> Option<String> {
    let min = min_version(kind);
    match version_line(glsl) {
        None => Some(format!(
            "no #version line: Vulkan GLSL starts with one (`#version {min}` for this stage)"
        )),
        Some((v, None)) if v < min => {
            Some(format!("#version {v}: this stage needs #version {min} or above"))
        }
        Some((v, Some(p))) if p == "es" && min == 460 => {
            Some(format!("#version {v} es: ray tracing shaders need a desktop #version 460"))
        }
        _ => None,
    }
}

/// The extension named by glslang's "extension not supported: NAME" in a compile message.
pub fn unknown_extension(message: &str) -> Option<String> {
    let at = message.find("extension not supported: ")? + "extension not supported: ".len();
    let name: String =
        message[at..].chars().take_while(|c| c.is_ascii_alphanumeric() || *c == '_').collect();
    (!name.is_empty()).then_some(name)
}

#[cfg(test)]
mod tests {
    use super::*;
    use shaderc::ShaderKind as K;

    #[test]
    fn version_lines_are_found_after_comments_only() {
        assert_eq!(version_line("#version 460\nvoid main(){}"), Some((460, None)));
        assert_eq!(
            version_line("// x\n/* y\n */\n  #  version 310 es\n"),
            Some((310, Some("es".into())))
        );
        assert_eq!(version_line("#extension GL_EXT_ray_tracing : require\n#version 460\n"), None);
        assert_eq!(version_line(""), None);
    }

    #[test]
    fn missing_and_low_versions_are_refused_per_stage() {
        assert!(version_problem(K::RayGeneration, "void main(){}")
            .unwrap()
            .contains("no #version"));
        assert!(version_problem(K::Compute, "#version 110\n").unwrap().contains("420"));
        assert!(version_problem(K::Miss, "#version 450\n").unwrap().contains("460"));
        assert!(version_problem(K::Miss, "#version 460 es\n").is_some());
        assert_eq!(version_problem(K::Miss, "#version 460\n"), None);
        assert_eq!(version_problem(K::Compute, "#version 310 es\n"), None);
        assert_eq!(version_problem(K::Fragment, "#version 450\n"), None);
    }

    #[test]
    fn unknown_extensions_are_read_from_glslang_messages() {
        let m = "ser.rgen:3: error: '#extension' : extension not supported: GL_EXT_shader_invocation_reorder | ser.rgen:8: error";
        assert_eq!(unknown_extension(m).unwrap(), "GL_EXT_shader_invocation_reorder");
        assert_eq!(
            unknown_extension("ser.rgen:8: error: 'hitObjectEXT' : undeclared identifier"),
            None
        );
    }
}
