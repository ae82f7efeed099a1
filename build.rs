//! Links the GLSL compiler. By default the shaderc crate (feature `prefer-static-linking`) links
//! the system's `libshaderc_combined.a`; Debian's holds only shaderc's own objects, so this script
//! adds the static glslang and SPIRV-Tools archives after everything else (`glslang-dev`,
//! `spirv-tools`). The binary then needs no shaderc, glslang or SPIRV-Tools at run time.
//!
//! With `--features bundled-shaderc` the shaderc crate builds its own C++ from source (~10 min on
//! 2 cores) and nothing is added here. Without a system shaderc at all, the shaderc crate falls
//! back to that source build by itself; this script says so. A system shaderc without the
//! glslang or SPIRV-Tools archives cannot link: the build stops here naming the packages.
//!
//! What was linked reaches the code as `RTPROBE_SHADERC_BUILD` (the compiler named in reports and
//! bundles) and, for the system compiler, `cfg(system_shaderc)`, with
//! `cfg(shaderc_without_vulkan_1_4)` where its `shaderc/env.h` has no Vulkan 1.4 (Debian 12's).
use std::env;
use std::path::{Path, PathBuf};
use std::process::Command;

/// The archives Debian's libshaderc_combined.a needs, in link order (inside one group, as
/// glslang's libraries refer to each other).
const GLSLANG_LIBS: &[&str] = &[
    "glslang",
    "MachineIndependent",
    "GenericCodeGen",
    "OSDependent",
    "OGLCompiler",
    "SPIRV",
    "HLSL",
];
const SPIRV_TOOLS_LIBS: &[&str] = &["SPIRV-Tools-opt", "SPIRV-Tools"];

const INSTALL: &str = "apt-get install libshaderc-dev glslang-dev spirv-tools (scripts/setup does)";

fn main() {
    println!("cargo::rerun-if-changed=build.rs");
    for v in [
        "SHADERC_LIB_DIR",
        "VULKAN_SDK",
        "SHADERC_NO_PKG_CONFIG",
        "PKG_CONFIG_PATH",
        "PKG_CONFIG_LIBDIR",
    ] {
        println!("cargo::rerun-if-env-changed={v}");
    }
    println!("cargo::rustc-check-cfg=cfg(system_shaderc)");
    println!("cargo::rustc-check-cfg=cfg(shaderc_without_vulkan_1_4)");
    let built = "shaderc built from source";
    if env::var_os("CARGO_FEATURE_BUNDLED_SHADERC").is_some() {
        return name(built);
    }
    // The shaderc crate's own overrides: what they point at is the user's to complete.
    for v in ["SHADERC_LIB_DIR", "VULKAN_SDK"] {
        if let Some(dir) = env::var_os(v) {
            println!(
                "cargo::warning=rtprobe: shaderc from {v}={}; nothing added to its link",
                Path::new(&dir).display()
            );
            return name(&format!("shaderc from {v}"));
        }
    }
    // Where the shaderc crate looks: pkg-config's libdir, else the multiarch directory (always,
    // with .cargo/config.toml's SHADERC_NO_PKG_CONFIG).
    let dir = env::var_os("SHADERC_NO_PKG_CONFIG")
        .is_none()
        .then(|| pkg_config(&["--variable=libdir", "shaderc"]))
        .flatten()
        .map(PathBuf::from)
        .unwrap_or_else(multiarch_dir);
    if env::var_os("SHADERC_NO_PKG_CONFIG").is_none() {
        println!(
            "cargo::warning=rtprobe: SHADERC_NO_PKG_CONFIG is not set (.cargo/config.toml sets it): \
             the shaderc crate may link libshaderc.so through pkg-config"
        );
    }
    if !dir.join("libshaderc_combined.a").is_file() {
        if dir.join("libshaderc.so").exists() {
            panic!(
                "rtprobe: {} has libshaderc.so but not libshaderc_combined.a, which rtprobe links \
                 statically (Debian's libshaderc.so.1 does not carry glslang or SPIRV-Tools): {INSTALL}, \
                 or build with --features bundled-shaderc",
                dir.display()
            );
        }
        println!(
            "cargo::warning=rtprobe: no system shaderc in {} ({INSTALL}); the shaderc crate builds \
             its bundled copy from source instead (about 10 minutes on 2 cores; \
             --features bundled-shaderc asks for that on purpose)",
            dir.display()
        );
        return name(built);
    }
    let glslang_dir = pkg_config(&["--variable=libdir", "glslang"]).map(PathBuf::from);
    let spirv_dir = pkg_config(&["--variable=libdir", "SPIRV-Tools"]).map(PathBuf::from);
    let mut archives = Vec::new();
    let mut missing = Vec::new();
    for (libs, at) in [(GLSLANG_LIBS, &glslang_dir), (SPIRV_TOOLS_LIBS, &spirv_dir)] {
        for lib in libs {
            let file = format!("lib{lib}.a");
            let found = [at.as_deref(), Some(dir.as_path())]
                .into_iter()
                .flatten()
                .map(|d| d.join(&file))
                .find(|p| p.is_file());
            match found {
                Some(p) => archives.push(p),
                None => missing.push(file),
            }
        }
    }
    if !missing.is_empty() {
        panic!(
            "rtprobe: the system shaderc ({}) needs the static glslang and SPIRV-Tools libraries, \
             and {} are missing: {INSTALL}, or build with --features bundled-shaderc",
            dir.join("libshaderc_combined.a").display(),
            missing.join(", ")
        );
    }
    // Link arguments come after every crate and its native libraries on the linker's command
    // line, so these archives resolve what shaderc_combined (inside shaderc-sys) leaves undefined.
    println!("cargo::rustc-link-arg=-Wl,--start-group");
    for a in &archives {
        println!("cargo::rustc-link-arg={}", a.display());
    }
    println!("cargo::rustc-link-arg=-Wl,--end-group");
    println!("cargo::rustc-link-arg=-lstdc++");
    println!("cargo::rustc-cfg=system_shaderc");
    // shaderc before 2024 has no Vulkan 1.4 environment and silently compiles for its default.
    let include =
        pkg_config(&["--variable=includedir", "shaderc"]).unwrap_or("/usr/include".into());
    let env_h =
        std::fs::read_to_string(Path::new(&include).join("shaderc/env.h")).unwrap_or_default();
    if !env_h.contains("shaderc_env_version_vulkan_1_4") {
        println!("cargo::rustc-cfg=shaderc_without_vulkan_1_4");
    }
    let shaderc = pkg_config(&["--modversion", "shaderc"]).unwrap_or_else(|| "?".into());
    let spirv = pkg_config(&["--modversion", "SPIRV-Tools"]).unwrap_or_else(|| "?".into());
    name(&format!(
        "system shaderc {shaderc}, glslang {}, SPIRV-Tools {spirv}",
        glslang_version().unwrap_or_else(|| "?".into())
    ))
}

fn name(s: &str) {
    println!("cargo::rustc-env=RTPROBE_SHADERC_BUILD={s}");
}

/// `pkg-config ARGS`' one line of output, when it succeeds and says something.
fn pkg_config(args: &[&str]) -> Option<String> {
    let out = Command::new("pkg-config").args(args).output().ok()?;
    let s = String::from_utf8(out.stdout).ok()?.trim().to_string();
    (out.status.success() && !s.is_empty()).then_some(s)
}

/// Debian's multiarch library directory (what the shaderc crate searches without pkg-config).
fn multiarch_dir() -> PathBuf {
    let arch = env::var("CARGO_CFG_TARGET_ARCH").unwrap_or_default();
    let arch = if arch == "x86" { "i386".to_string() } else { arch };
    PathBuf::from(format!("/usr/lib/{arch}-linux-gnu"))
}

/// glslang's version from its `build_info.h` (Debian's glslang.pc has an empty Version).
fn glslang_version() -> Option<String> {
    let include =
        pkg_config(&["--variable=includedir", "glslang"]).unwrap_or("/usr/include".into());
    let h = std::fs::read_to_string(Path::new(&include).join("glslang/build_info.h")).ok()?;
    let part = |name: &str| {
        h.lines()
            .find_map(|l| l.strip_prefix(&format!("#define GLSLANG_VERSION_{name} ")))
            .map(|v| v.trim().to_string())
    };
    Some(format!("{}.{}.{}", part("MAJOR")?, part("MINOR")?, part("PATCH")?))
}
