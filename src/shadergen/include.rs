//! `#include` resolution for user GLSL (`rtprobe patch --glsl`), behind shaderc's include
//! callback (GL_GOOGLE_include_directive). `#include "x"` looks in the including file's own
//! directory first, then in the search path; `#include <x>` only in the search path. The search
//! path is the input's directory followed by each `-I` directory, in order.
//!
//! Every resolved file remembers which file and line included it, so an error anywhere in the
//! tree can be told as one line: `b.glsl:3: error ... (included from a.glsl:2, from main.rgen:5)`.
use std::cell::RefCell;
use std::collections::HashMap;
use std::path::{Path, PathBuf};

/// Deepest include nesting followed.
pub const MAX_DEPTH: usize = 32;

/// Where a resolved file was included from: (including file, 1-based line).
type Origin = (String, usize);

pub struct Includes {
    search: Vec<PathBuf>,
    origins: RefCell<HashMap<String, Origin>>,
    /// Contents of every file seen, by resolved name (to find the line of an `#include`).
    sources: RefCell<HashMap<String, String>>,
}

/// Source text from a file's bytes, as glslang reads them: UTF-8 when they are, else one
/// character per byte (Latin-1), so a header with a Latin-1 comment still compiles (GLSL
/// source outside comments is ASCII).
pub fn decode(bytes: &[u8]) -> String {
    let bytes = bytes.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(bytes);
    match std::str::from_utf8(bytes) {
        Ok(s) => s.to_string(),
        Err(_) => bytes.iter().map(|&b| b as char).collect(),
    }
}

/// The name a path is shown and resolved under: as built from the search path, with `./`
/// prefixes dropped.
pub fn display(p: &Path) -> String {
    let s = p.to_string_lossy();
    s.strip_prefix("./").unwrap_or(&s).to_string()
}

impl Includes {
    /// `input` is the root file (named `root_name` in messages, with `root_source`); `dirs` are
    /// the `-I` directories.
    pub fn new(input: &Path, root_name: &str, root_source: &str, dirs: &[PathBuf]) -> Self {
        let own = input
            .parent()
            .filter(|p| !p.as_os_str().is_empty())
            .map(Path::to_path_buf)
            .unwrap_or_else(|| PathBuf::from("."));
        let mut search = vec![own];
        search.extend(dirs.iter().cloned());
        let sources = HashMap::from([(root_name.to_string(), root_source.to_string())]);
        Self { search, origins: RefCell::new(HashMap::new()), sources: RefCell::new(sources) }
    }

    /// The include callback: resolve `requested` from `requester`, `depth` includes deep.
    pub fn resolve(
        &self,
        requested: &str,
        ty: shaderc::IncludeType,
        requester: &str,
        depth: usize,
    ) -> shaderc::IncludeCallbackResult {
        // glslang follows an include cycle without end; header guards do not stop it either.
        if depth > MAX_DEPTH {
            return Err(format!(
                "includes nested deeper than {MAX_DEPTH} (an include cycle?) at {requested:?}"
            ));
        }
        let mut candidates = Vec::new();
        if ty == shaderc::IncludeType::Relative {
            if let Some(dir) = Path::new(requester).parent() {
                candidates.push(dir.join(requested));
            }
        }
        candidates.extend(self.search.iter().map(|d| d.join(requested)));
        let found = candidates.iter().find(|p| p.is_file());
        let Some(path) = found else {
            let dirs: Vec<String> = self.search.iter().map(|d| display(d)).collect();
            return Err(format!("cannot find {requested:?} (searched {})", dirs.join(", ")));
        };
        let name = display(path);
        let content = std::fs::read(path)
            .map(|b| decode(&b))
            .map_err(|e| format!("cannot read {name}: {e}"))?;
        let line = self.include_line(requester, requested);
        self.origins.borrow_mut().entry(name.clone()).or_insert((requester.to_string(), line));
        self.sources.borrow_mut().insert(name.clone(), content.clone());
        Ok(shaderc::ResolvedInclude { resolved_name: name, content })
    }

    /// The 1-based line of `requester` that includes `requested` (0 when not found).
    fn include_line(&self, requester: &str, requested: &str) -> usize {
        let sources = self.sources.borrow();
        let Some(src) = sources.get(requester) else {
            return 0;
        };
        src.lines()
            .position(|l| {
                let l = l.trim_start();
                l.starts_with('#')
                    && l.contains("include")
                    && (l.contains(&format!("\"{requested}\""))
                        || l.contains(&format!("<{requested}>")))
            })
            .map_or(0, |i| i + 1)
    }

    /// The contents of every file seen so far (the root first, then the included ones by resolved
    /// name): what a hash of the input must cover.
    pub fn contents(&self) -> Vec<(String, String)> {
        let mut all: Vec<(String, String)> =
            self.sources.borrow().iter().map(|(n, c)| (n.clone(), c.clone())).collect();
        all.sort();
        all
    }

    /// ` (included from a.glsl:2, from main.rgen:5)` for a resolved file; empty for the root.
    pub fn chain_of(&self, file: &str) -> String {
        let origins = self.origins.borrow();
        let mut parts = Vec::new();
        let mut cur = file.to_string();
        while let Some((from, line)) = origins.get(&cur) {
            if parts.len() > 64 {
                break; // a cycle; glslang stops it by depth, we only describe it
            }
            parts.push(if *line > 0 { format!("{from}:{line}") } else { from.clone() });
            cur = from.clone();
        }
        if parts.is_empty() {
            String::new()
        } else {
            format!(" (included from {})", parts.join(", from "))
        }
    }

    /// shaderc's message (`N compilation errors:` then `FILE:LINE: error: ...` lines) as one
    /// line, each error followed by the include chain of its file.
    pub fn annotate(&self, message: &str) -> String {
        let mut out = String::new();
        for l in message.lines().map(str::trim).filter(|l| !l.is_empty()) {
            if !out.is_empty() {
                out.push_str(if out.ends_with(':') { " " } else { " | " });
            }
            out.push_str(l);
            out.push_str(&self.chain_of(l.split(':').next().unwrap_or_default()));
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tree() -> crate::tempdir::TempDir {
        let d = crate::tempdir::tempdir().unwrap();
        std::fs::create_dir_all(d.path().join("inc/sub")).unwrap();
        std::fs::write(
            d.path().join("main.rgen"),
            "#version 460\n#extension GL_GOOGLE_include_directive : require\n#include \"a.glsl\"\n",
        )
        .unwrap();
        std::fs::write(d.path().join("inc/a.glsl"), "// a\n#include \"sub/b.glsl\"\n").unwrap();
        std::fs::write(d.path().join("inc/sub/b.glsl"), "// b\n").unwrap();
        d
    }

    #[test]
    fn resolves_through_search_path_and_relative_dirs_and_records_the_chain() {
        let d = tree();
        let main = d.path().join("main.rgen");
        let root = display(&main);
        let inc = Includes::new(
            &main,
            &root,
            &std::fs::read_to_string(&main).unwrap(),
            &[d.path().join("inc")],
        );
        let a = inc.resolve("a.glsl", shaderc::IncludeType::Relative, &root, 1).unwrap();
        assert!(a.resolved_name.ends_with("inc/a.glsl"), "{}", a.resolved_name);
        let b =
            inc.resolve("sub/b.glsl", shaderc::IncludeType::Relative, &a.resolved_name, 2).unwrap();
        assert!(b.resolved_name.ends_with("inc/sub/b.glsl"));
        let chain = inc.chain_of(&b.resolved_name);
        assert!(chain.contains(&format!("a.glsl:2, from {root}:3")), "{chain}");
        let msg = inc.annotate(&format!(
            "{}:1: error: 'x' : undeclared\n1 error generated.\n",
            b.resolved_name
        ));
        assert!(!msg.contains('\n'));
        assert!(msg.contains("sub/b.glsl:1: error: 'x' : undeclared (included from"), "{msg}");
    }

    #[test]
    fn latin1_and_utf8_sources_decode() {
        assert_eq!(decode(b"// caf\xe9\n"), "// caf\u{e9}\n");
        assert_eq!(decode("// café\n".as_bytes()), "// café\n");
        assert_eq!(decode(b"\xEF\xBB\xBF#version 460\n"), "#version 460\n");
        // A Latin-1 header is found and read through the include callback.
        let d = tree();
        std::fs::write(d.path().join("inc/latin.glsl"), b"// r\xe9flexion\nfloat k = 1.0;\n")
            .unwrap();
        let main = d.path().join("main.rgen");
        let inc = Includes::new(&main, "main.rgen", "", &[d.path().join("inc")]);
        let r = inc.resolve("latin.glsl", shaderc::IncludeType::Relative, "main.rgen", 1).unwrap();
        assert!(r.content.contains("float k") && r.content.contains('\u{e9}'), "{}", r.content);
    }

    #[test]
    fn a_missing_include_names_what_was_searched_and_who_asked() {
        let d = tree();
        let main = d.path().join("main.rgen");
        let root = display(&main);
        let inc = Includes::new(&main, &root, "", &[]);
        let e = inc.resolve("nope.glsl", shaderc::IncludeType::Standard, &root, 1).unwrap_err();
        assert!(e.contains("cannot find \"nope.glsl\""), "{e}");
        // Without -I the input's own directory is the only place searched; a.glsl lives in inc/.
        assert!(inc.resolve("a.glsl", shaderc::IncludeType::Relative, &root, 1).is_err());
        let e = Includes::new(&main, &root, "", &[d.path().join("inc")])
            .resolve("a.glsl", shaderc::IncludeType::Relative, &root, MAX_DEPTH + 1)
            .unwrap_err();
        assert!(e.contains("include cycle"), "{e}");
    }
}
