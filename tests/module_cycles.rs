//! Module-cycle check: reads every `crate::`, `super::` and `self::` path in `src/` (in `use`
//! lines, `pub use` re-exports and inline in code) and fails when modules depend on each other in
//! a cycle, at two levels: top-level modules (`bisect` ↔ `report`) and files (`exec/bindings.rs` ↔
//! `exec/heap.rs`). A cycle means neither side can be read, tested or moved without the other;
//! the failure lists each cycle's members and the concrete references (`file:line` and path) that
//! tie it, so a developer sees which `use` to move.
//!
//! What counts: code only. Comments (doc comments mention paths like `crate::probe::X`), string and
//! char literals, items under `#[cfg(test)]` (test modules legitimately `use super::*`) and files
//! declared by a `#[cfg(test)] mod name;` are skipped. `src/main.rs` is the binary, a crate of its
//! own that only calls the library, and is skipped too. A path resolves to the longest prefix of it
//! that is a module with its own file. Bare relative paths (`use child::X` in a `mod.rs`) are not
//! read: only paths that start at `crate`, `super` or `self`.
//!
//! It reads the source as text, with std only, so it neither depends on nor builds the crate:
//! `rustc --edition 2021 --test tests/module_cycles.rs -o /tmp/cyc && /tmp/cyc --nocapture`
//! from the repository root runs it in seconds. `planted_cycle_is_found` runs the same analysis
//! over `tests/fixtures/cycles/src/`, a tiny tree with a planted cycle, to show it can fail.
use std::collections::{BTreeMap, BTreeSet};
use std::fs;
use std::path::{Path, PathBuf};

/// One token of Rust source: an identifier or number, `::`, a single punctuation character, or
/// `"` standing for a whole string or char literal; with the line it starts on.
#[derive(Clone, Debug)]
struct Token {
    text: String,
    line: usize,
}

/// One reference from a file to another module's file.
#[derive(Clone, Debug)]
struct Edge {
    /// Module path of the referring file (`""` is the crate root).
    from: String,
    /// Module path of the file the path resolves to.
    to: String,
    line: usize,
    /// The path as written, use groups expanded (`crate::vk::heap::MappingSource`).
    text: String,
}

/// The files of one source tree and the references between them.
struct Analysis {
    /// Module path (`""` for the crate root) → file path relative to the analysed folder.
    files: BTreeMap<String, String>,
    edges: Vec<Edge>,
}

impl Analysis {
    /// Cycles between top-level modules (the crate root is `crate`).
    fn module_cycles(&self) -> Vec<Vec<String>> {
        let nodes = self.files.keys().map(|m| top(m)).collect();
        let pairs = self.edges.iter().map(|e| (top(&e.from), top(&e.to)));
        cycles(nodes, pairs.filter(|(a, b)| a != b).collect())
    }

    /// Cycles between files, named by module path.
    fn file_cycles(&self) -> Vec<Vec<String>> {
        let nodes = self.files.keys().cloned().collect();
        cycles(nodes, self.edges.iter().map(|e| (e.from.clone(), e.to.clone())).collect())
    }

    /// Number of top-level modules, the crate root not counted.
    fn top_level_count(&self) -> usize {
        self.files.keys().filter(|m| !m.is_empty()).map(|m| top(m)).collect::<BTreeSet<_>>().len()
    }
}

/// The top-level module a module path belongs to (`crate` for the root).
fn top(module: &str) -> String {
    match module.split("::").next() {
        Some("") | None => "crate".to_string(),
        Some(first) => first.to_string(),
    }
}

/// The module a file (relative to the source folder) holds: `lib.rs` is the root (`""`),
/// `a/mod.rs` is `a`, `a/b.rs` is `a::b`; `None` for binaries (`main.rs`, `bin/`) and other
/// files.
fn module_of(rel: &Path) -> Option<String> {
    let mut parts: Vec<String> = rel.iter().map(|p| p.to_string_lossy().into_owned()).collect();
    let file = parts.pop()?;
    let stem = file.strip_suffix(".rs")?;
    if parts.first().is_some_and(|p| p == "bin") {
        return None;
    }
    match (parts.is_empty(), stem) {
        (true, "main") => return None,
        (true, "lib") | (_, "mod") => {}
        _ => parts.push(stem.to_string()),
    }
    Some(parts.join("::"))
}

/// Every `.rs` file under `dir`, sorted.
fn rust_files(dir: &Path) -> Vec<PathBuf> {
    let mut out = Vec::new();
    let mut todo = vec![dir.to_path_buf()];
    while let Some(d) = todo.pop() {
        let entries = fs::read_dir(&d).unwrap_or_else(|e| panic!("reading {}: {e}", d.display()));
        for entry in entries {
            let path = entry.expect("directory entry").path();
            if path.is_dir() {
                todo.push(path);
            } else if path.extension().is_some_and(|x| x == "rs") {
                out.push(path);
            }
        }
    }
    out.sort();
    out
}

fn is_ident(text: &str) -> bool {
    text.chars().next().is_some_and(|c| c.is_alphanumeric() || c == '_')
}

/// Index just past the string literal whose opening quote is at `i - 1` (escapes honoured).
fn skip_string(c: &[char], mut i: usize) -> usize {
    while i < c.len() && c[i] != '"' {
        i += if c[i] == '\\' { 2 } else { 1 };
    }
    i + 1
}

/// Index just past the raw string starting at `i` (the `#`s or the quote after `r`), or `None`
/// when no quote follows the `#`s (a raw identifier such as `r#type`).
fn skip_raw_string(c: &[char], i: usize) -> Option<usize> {
    let hashes = c[i..].iter().take_while(|&&ch| ch == '#').count();
    if c.get(i + hashes) != Some(&'"') {
        return None;
    }
    let mut j = i + hashes + 1;
    while j < c.len() {
        if c[j] == '"' && c[j + 1..].iter().take(hashes).filter(|&&ch| ch == '#').count() == hashes
        {
            return Some(j + 1 + hashes);
        }
        j += 1;
    }
    Some(j)
}

/// Index just past the (possibly nested) block comment starting at `i`.
fn skip_block_comment(c: &[char], mut i: usize) -> usize {
    let mut depth = 0;
    while i < c.len() {
        if c[i] == '/' && c.get(i + 1) == Some(&'*') {
            depth += 1;
            i += 2;
        } else if c[i] == '*' && c.get(i + 1) == Some(&'/') {
            depth -= 1;
            i += 2;
            if depth == 0 {
                return i;
            }
        } else {
            i += 1;
        }
    }
    i
}

/// Index just past the char literal whose quote is at `i`, or `None` for a lifetime (`'a`).
fn skip_char(c: &[char], i: usize) -> Option<usize> {
    if c.get(i + 1) == Some(&'\\') {
        let close = c.get(i + 3..)?.iter().position(|&ch| ch == '\'')?;
        return Some(i + 3 + close + 1);
    }
    (c.get(i + 2) == Some(&'\'')).then_some(i + 3)
}

/// The end of the word (identifier, number, prefixed literal or raw identifier) starting at
/// `start`, and its token text: `"` for a literal.
fn scan_word(c: &[char], start: usize) -> (usize, String) {
    let mut i = start;
    while i < c.len() && (c[i].is_alphanumeric() || c[i] == '_') {
        i += 1;
    }
    let word: String = c[start..i].iter().collect();
    let next = c.get(i).copied();
    match (word.as_str(), next) {
        ("r" | "br" | "cr", Some('#' | '"')) => match skip_raw_string(c, i) {
            Some(end) => (end, "\"".to_string()),
            None => scan_word(c, i + 1),
        },
        ("b" | "c", Some('"')) => (skip_string(c, i + 1), "\"".to_string()),
        ("b", Some('\'')) => (skip_char(c, i).unwrap_or(i + 1), "\"".to_string()),
        _ => (i, word),
    }
}

/// Splits Rust source into tokens, dropping whitespace and comments and folding each string or
/// char literal into one `"` token, so paths in doc comments or strings are never read.
fn tokenize(src: &str) -> Vec<Token> {
    let c: Vec<char> = src.chars().collect();
    let (mut i, mut line, mut out) = (0, 1, Vec::new());
    while i < c.len() {
        let start = i;
        let next = c.get(i + 1).copied();
        let text = match c[i] {
            '/' if next == Some('/') => {
                i += c[i..].iter().position(|&ch| ch == '\n').unwrap_or(c.len() - i);
                None
            }
            '/' if next == Some('*') => {
                i = skip_block_comment(&c, i);
                None
            }
            '"' => {
                i = skip_string(&c, i + 1);
                Some("\"".to_string())
            }
            '\'' => {
                i = skip_char(&c, i).unwrap_or(i + 1);
                Some(if i == start + 1 { "'" } else { "\"" }.to_string())
            }
            ':' if next == Some(':') => {
                i += 2;
                Some("::".to_string())
            }
            ch if ch.is_alphanumeric() || ch == '_' => {
                let (end, word) = scan_word(&c, i);
                i = end;
                Some(word)
            }
            ch => {
                i += 1;
                (!ch.is_whitespace()).then(|| ch.to_string())
            }
        };
        if let Some(text) = text {
            out.push(Token { text, line });
        }
        line += c[start..i.min(c.len())].iter().filter(|&&ch| ch == '\n').count();
    }
    out
}

/// Whether `toks` starts with `#[cfg(test)]`.
fn is_cfg_test(toks: &[Token]) -> bool {
    let want = ["#", "[", "cfg", "(", "test", ")", "]"];
    toks.len() >= want.len() && toks.iter().zip(want).all(|(t, w)| t.text == w)
}

/// Index just past the item starting at `i`: its `;` or the `}` closing its body, whichever comes
/// first outside brackets (or, for a field or statement, before the enclosing block's closer).
fn item_end(toks: &[Token], mut i: usize) -> usize {
    let mut depth = 0i32;
    while i < toks.len() {
        match toks[i].text.as_str() {
            "(" | "[" | "{" => depth += 1,
            ")" | "]" | "}" => {
                depth -= 1;
                if depth < 0 {
                    return i;
                }
                if depth == 0 && toks[i].text == "}" {
                    return i + 1;
                }
            }
            ";" if depth == 0 => return i + 1,
            _ => {}
        }
        i += 1;
    }
    i
}

/// Drops every item under `#[cfg(test)]` (test modules, test-only helpers); returns the tokens
/// kept and the names of the test-only modules this file declares as files (`mod tests;`).
fn drop_test_items(toks: &[Token]) -> (Vec<Token>, Vec<String>) {
    let (mut kept, mut test_mods, mut i) = (Vec::new(), Vec::new(), 0);
    while i < toks.len() {
        if !is_cfg_test(&toks[i..]) {
            kept.push(toks[i].clone());
            i += 1;
            continue;
        }
        let end = item_end(toks, i + 7);
        if let [.., m, name, semi] = &toks[i..end] {
            if m.text == "mod" && semi.text == ";" {
                test_mods.push(name.text.clone());
            }
        }
        i = end;
    }
    (kept, test_mods)
}

/// Reads the path or use tree starting at `i` (`crate::a::{b, c::D}`), pushing each full path,
/// with the line of its last segment, onto `out`; returns the index just past it.
fn parse_tree(
    toks: &[Token],
    mut i: usize,
    mut path: Vec<String>,
    out: &mut Vec<(Vec<String>, usize)>,
) -> usize {
    let mut line = toks.get(i).map_or(0, |t| t.line);
    while let Some(t) = toks.get(i) {
        if t.text == "{" {
            i += 1;
            while toks.get(i).is_some_and(|t| t.text != "}") {
                i = parse_tree(toks, i, path.clone(), out);
                // `as name`, then the comma.
                while toks.get(i).is_some_and(|t| t.text != "," && t.text != "}") {
                    i += 1;
                }
                if toks.get(i).is_some_and(|t| t.text == ",") {
                    i += 1;
                }
            }
            return i + 1;
        }
        if t.text == "*" {
            out.push((path, t.line));
            return i + 1;
        }
        if !is_ident(&t.text) {
            break;
        }
        path.push(t.text.clone());
        line = t.line;
        i += 1;
        if toks.get(i).is_some_and(|t| t.text == "::") {
            i += 1;
        } else {
            break;
        }
    }
    if !path.is_empty() {
        out.push((path, line));
    }
    i
}

/// The absolute module path `segs` names when written in module `base`; `None` when it climbs
/// above the crate root.
fn absolute(base: &[String], segs: &[String]) -> Option<Vec<String>> {
    let mut abs = Vec::new();
    for (k, seg) in segs.iter().enumerate() {
        match seg.as_str() {
            "crate" if k == 0 => {}
            "self" if k == 0 => abs = base.to_vec(),
            "self" => {}
            "super" => {
                if k == 0 {
                    abs = base.to_vec();
                }
                abs.pop()?;
            }
            _ => abs.push(seg.clone()),
        }
    }
    Some(abs)
}

/// Whether a path starts at token `i`: `crate::`, `super::` or `self::` not inside another path.
fn is_path_start(toks: &[Token], i: usize) -> bool {
    matches!(toks[i].text.as_str(), "crate" | "super" | "self")
        && toks.get(i + 1).is_some_and(|t| t.text == "::")
        && (i == 0 || toks[i - 1].text != "::")
}

/// Whether a bare path starts at token `i` whose first segment is a child module of `base`
/// (`use child::Item;` or `child::f()` in a `mod.rs`).
fn is_child_path(toks: &[Token], i: usize, base: &[String], modules: &BTreeSet<String>) -> bool {
    is_ident(&toks[i].text)
        && toks.get(i + 1).is_some_and(|t| t.text == "::")
        && (i == 0 || toks[i - 1].text != "::")
        && modules.contains(&[base, std::slice::from_ref(&toks[i].text)].concat().join("::"))
}

/// Every path in a file of module `module`: (line, path as written, absolute path). Inline
/// `mod name { ... }` blocks move `self` and `super` one level down while inside them.
fn paths_in(toks: &[Token], module: &str, modules: &BTreeSet<String>) -> Paths {
    let file_base: Vec<String> =
        module.split("::").filter(|s| !s.is_empty()).map(String::from).collect();
    let (mut out, mut inline, mut depth, mut i) = (Vec::new(), Vec::<(String, usize)>::new(), 0, 0);
    while i < toks.len() {
        match toks[i].text.as_str() {
            "{" => {
                depth += 1;
                if i >= 2 && toks[i - 2].text == "mod" {
                    inline.push((toks[i - 1].text.clone(), depth));
                }
            }
            "}" => {
                if inline.last().is_some_and(|(_, d)| *d == depth) {
                    inline.pop();
                }
                depth = depth.saturating_sub(1);
            }
            _ => {}
        }
        let mut base = file_base.clone();
        base.extend(inline.iter().map(|(name, _)| name.clone()));
        let bare = is_child_path(toks, i, &base, modules);
        if !is_path_start(toks, i) && !bare {
            i += 1;
            continue;
        }
        let mut found = Vec::new();
        i = parse_tree(toks, i, Vec::new(), &mut found);
        for (mut segs, line) in found {
            if bare {
                segs.insert(0, "self".into());
            }
            if let Some(abs) = absolute(&base, &segs) {
                // A group's `self` (`use crate::a::{self, B}`) names the module itself.
                let shown = segs.strip_suffix(&["self".to_string()]).unwrap_or(&segs);
                out.push((line, shown.join("::"), abs));
            }
        }
    }
    out
}

/// The module with its own file that owns `abs`: its longest prefix found in `files`.
fn owner(files: &BTreeMap<String, String>, abs: &[String]) -> String {
    (0..=abs.len())
        .rev()
        .map(|n| abs[..n].join("::"))
        .find(|m| files.contains_key(m))
        .unwrap_or_default()
}

/// Per module, the names its `pub use` items re-export and the absolute path each stands for.
type Reexports = BTreeMap<String, BTreeMap<String, Vec<String>>>;

/// Every path of one file: (line, path as written, absolute path).
type Paths = Vec<(usize, String, Vec<String>)>;

fn reexports(
    parsed: &BTreeMap<String, (String, Vec<Token>)>,
    paths: &BTreeMap<&String, Paths>,
) -> Reexports {
    let mut out = Reexports::new();
    for (module, (_, toks)) in parsed {
        // The lines of `pub use` / `pub(crate) use` items (to their `;`), whose paths are the
        // re-exports.
        let mut lines = BTreeSet::new();
        for (k, t) in toks.iter().enumerate() {
            let public =
                k >= 1 && (toks[k - 1].text == "pub" || (k >= 4 && toks[k - 4].text == "pub"));
            if t.text == "use" && public {
                let end = toks[k..].iter().find(|t| t.text == ";").map_or(t.line, |e| e.line);
                lines.extend(t.line..=end);
            }
        }
        for (line, _, abs) in &paths[module] {
            if let Some(name) = abs.last().filter(|_| lines.contains(line)) {
                out.entry(module.clone()).or_default().insert(name.clone(), abs.clone());
            }
        }
    }
    out
}

/// `abs` with every re-exported name replaced by what it stands for (`crate::model::Cell` is
/// `crate::model::cell::Cell` when `model` says `pub use cell::Cell`): a facade is no
/// dependency of its users on its other children.
fn through_reexports(
    files: &BTreeMap<String, String>,
    reexports: &Reexports,
    mut abs: Vec<String>,
) -> Vec<String> {
    for _ in 0..8 {
        let module = owner(files, &abs);
        let depth = module.split("::").filter(|s| !s.is_empty()).count();
        let target = abs
            .get(depth)
            .and_then(|name| reexports.get(&module)?.get(name))
            .filter(|t| **t != abs[..=depth]);
        match target {
            Some(t) => abs = [t.as_slice(), &abs[depth + 1..]].concat(),
            None => break,
        }
    }
    abs
}

/// Reads every `.rs` file under `src` into files and the references between them.
fn analyze(src: &Path) -> Analysis {
    let mut parsed = BTreeMap::new();
    let mut test_only = Vec::new();
    for path in rust_files(src) {
        let rel = path.strip_prefix(src).expect("file under the source folder");
        let Some(module) = module_of(rel) else {
            continue;
        };
        let text = fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        let (toks, test_mods) = drop_test_items(&tokenize(&text));
        let prefix = if module.is_empty() { String::new() } else { format!("{module}::") };
        test_only.extend(test_mods.into_iter().map(|m| format!("{prefix}{m}")));
        let rel = rel.to_string_lossy().replace('\\', "/");
        parsed.insert(module, (rel, toks));
    }
    let excluded = |m: &str| test_only.iter().any(|t| m == t || m.starts_with(&format!("{t}::")));
    parsed.retain(|m, _| !excluded(m));
    let files: BTreeMap<String, String> =
        parsed.iter().map(|(m, (rel, _))| (m.clone(), rel.clone())).collect();
    let modules: BTreeSet<String> = files.keys().cloned().collect();
    let paths: BTreeMap<&String, _> =
        parsed.iter().map(|(m, (_, toks))| (m, paths_in(toks, m, &modules))).collect();
    let reexports = reexports(&parsed, &paths);
    let mut edges = Vec::new();
    for (from, found) in paths {
        for (line, text, abs) in found {
            let to = owner(&files, &through_reexports(&files, &reexports, abs));
            if to != *from {
                edges.push(Edge { from: from.clone(), to, line, text });
            }
        }
    }
    Analysis { files, edges }
}

/// Tarjan's strongly connected components over a graph of named nodes.
struct Tarjan<'a> {
    adj: &'a BTreeMap<String, BTreeSet<String>>,
    index: BTreeMap<&'a str, usize>,
    low: BTreeMap<&'a str, usize>,
    stack: Vec<&'a str>,
    on_stack: BTreeSet<&'a str>,
    found: Vec<Vec<String>>,
}

impl<'a> Tarjan<'a> {
    fn visit(&mut self, v: &'a str) {
        let n = self.index.len();
        self.index.insert(v, n);
        self.low.insert(v, n);
        self.stack.push(v);
        self.on_stack.insert(v);
        let adj = self.adj;
        for w in adj.get(v).into_iter().flatten() {
            let w = w.as_str();
            if !self.index.contains_key(w) {
                self.visit(w);
                let low = self.low[v].min(self.low[w]);
                self.low.insert(v, low);
            } else if self.on_stack.contains(w) {
                let low = self.low[v].min(self.index[w]);
                self.low.insert(v, low);
            }
        }
        if self.low[v] == self.index[v] {
            let mut scc = Vec::new();
            while let Some(w) = self.stack.pop() {
                self.on_stack.remove(w);
                scc.push(w.to_string());
                if w == v {
                    break;
                }
            }
            self.found.push(scc);
        }
    }
}

/// The strongly connected components of more than one node, each sorted, in sorted order.
fn cycles(nodes: BTreeSet<String>, edges: Vec<(String, String)>) -> Vec<Vec<String>> {
    let mut adj: BTreeMap<String, BTreeSet<String>> =
        nodes.into_iter().map(|n| (n, BTreeSet::new())).collect();
    for (a, b) in edges {
        adj.entry(b.clone()).or_default();
        adj.entry(a).or_default().insert(b);
    }
    let mut t = Tarjan {
        adj: &adj,
        index: BTreeMap::new(),
        low: BTreeMap::new(),
        stack: Vec::new(),
        on_stack: BTreeSet::new(),
        found: Vec::new(),
    };
    for v in adj.keys() {
        if !t.index.contains_key(v.as_str()) {
            t.visit(v);
        }
    }
    let mut found: Vec<Vec<String>> = t.found.into_iter().filter(|c| c.len() > 1).collect();
    for c in &mut found {
        c.sort();
    }
    found.sort();
    found
}

/// Each cycle's members, then the references that tie it: every edge between two of its members
/// under `node` (top-level module or file), one line per `file:line` with the paths it holds.
fn describe(a: &Analysis, kind: &str, found: &[Vec<String>], node: fn(&str) -> String) -> String {
    let mut out = String::new();
    for members in found {
        out += &format!("{kind} cycle: {{{}}}\n", members.join(", "));
        let inside = |m: &str| members.contains(&node(m));
        let mut lines: BTreeMap<(&str, usize, String, String), BTreeSet<&str>> = BTreeMap::new();
        for e in a.edges.iter().filter(|e| inside(&e.from) && inside(&e.to)) {
            let (from, to) = (node(&e.from), node(&e.to));
            if from != to {
                let at = (a.files[&e.from].as_str(), e.line, from, to);
                lines.entry(at).or_default().insert(&e.text);
            }
        }
        for ((file, line, from, to), texts) in lines {
            let texts = texts.into_iter().collect::<Vec<_>>().join(", ");
            out += &format!("  src/{file}:{line}  {texts}  ({from} -> {to})\n");
        }
    }
    out
}

/// A module path as shown in a file-level cycle: `crate` for the root.
fn shown_module(module: &str) -> String {
    if module.is_empty() {
        "crate".to_string()
    } else {
        module.to_string()
    }
}

#[test]
fn no_module_cycles() {
    let root = Path::new(option_env!("CARGO_MANIFEST_DIR").unwrap_or("."));
    let a = analyze(&root.join("src"));
    let (modules, files) = (a.module_cycles(), a.file_cycles());
    let n = modules.len() + files.len();
    let detail = if n == 0 {
        String::new()
    } else {
        format!(" ({} between top-level modules, {} between files)", modules.len(), files.len())
    };
    println!(
        "module_cycles: {} top-level modules, {} files, {n} cycles{detail}",
        a.top_level_count(),
        a.files.len()
    );
    if n > 0 {
        let report = describe(&a, "top-level module", &modules, top)
            + &describe(&a, "file", &files, shown_module);
        panic!("modules depend on each other in a cycle; move a `use` to break it:\n{report}");
    }
}

#[test]
fn planted_cycle_is_found() {
    let root = Path::new(option_env!("CARGO_MANIFEST_DIR").unwrap_or("."));
    let a = analyze(&root.join("tests/fixtures/cycles/src"));
    let names = |v: &[&str]| v.iter().map(ToString::to_string).collect::<Vec<_>>();
    // `c::tests` is declared under `#[cfg(test)]`: not a file of the graph.
    let files: Vec<&str> = a.files.keys().map(String::as_str).collect();
    assert_eq!(files, ["", "a", "a::x", "a::y", "b", "c", "d", "d::e", "f", "f::g", "h"]);
    assert_eq!(a.module_cycles(), vec![names(&["a", "b"])]);
    // `d` and its child reach each other by a bare child path and `super::`; `f` is a facade
    // only, so `h`'s `crate::f::G` is an edge to `f::g`, and no cycle.
    assert_eq!(a.file_cycles(), vec![names(&["a::x", "b"]), names(&["d", "d::e"])]);
    assert!(a.edges.iter().any(|e| e.from == "h" && e.to == "f::g"), "{:#?}", a.edges);
    assert!(!a.edges.iter().any(|e| e.from == "h" && e.to == "f"), "{:#?}", a.edges);
    let has = |from: &str, to: &str, text: &str| {
        a.edges.iter().any(|e| e.from == from && e.to == to && e.text == text)
    };
    assert!(has("a::x", "b", "crate::b::Y"), "{:#?}", a.edges);
    assert!(has("b", "a::x", "super::a::x::f"), "inline path after tricky literals");
    assert!(has("a::x", "c", "crate::c::C"), "nested use group expanded");
    assert!(has("a::y", "b", "super::super::b::Y"), "super chain");
    // Comments, literals, test-only items and inline-module `super` make no edge: the only edge
    // touching `c` is the real one above, and nothing points at the crate root.
    let touching_c: Vec<&Edge> = a.edges.iter().filter(|e| e.from == "c" || e.to == "c").collect();
    assert_eq!(touching_c.len(), 1, "{touching_c:#?}");
    assert!(a.edges.iter().all(|e| !e.to.is_empty()), "{:#?}", a.edges);
    let report = describe(&a, "top-level module", &a.module_cycles(), top);
    assert!(report.contains("src/a/x.rs:"), "{report}");
    assert!(report.contains("src/a/x.rs:4  crate::b, crate::b::Y  (a -> b)"), "{report}");
    println!("{report}{}", describe(&a, "file", &a.file_cycles(), shown_module));
}

/// The bottom layer's modules: they may use each other and nothing else of the crate.
const BOTTOM: &[&str] = &["model", "atomic", "pool", "tools", "tempdir"];

/// References from a bottom-layer module to a module above it.
fn above_the_bottom(a: &Analysis) -> Vec<String> {
    let bottom = |m: &str| BOTTOM.contains(&top(m).as_str());
    a.edges
        .iter()
        .filter(|e| bottom(&e.from) && !bottom(&e.to))
        .map(|e| format!("  src/{}:{}  {}", a.files[&e.from], e.line, e.text))
        .collect()
}

#[test]
fn the_data_layer_imports_nothing_above_it() {
    let root = Path::new(option_env!("CARGO_MANIFEST_DIR").unwrap_or("."));
    let a = analyze(&root.join("src"));
    let up = above_the_bottom(&a);
    println!("module_cycles: {} references from {BOTTOM:?} to modules above them", up.len());
    assert!(up.is_empty(), "the data layer reaches up:\n{}", up.join("\n"));
    // Twin: an edge from `model` up to `report` is listed.
    let planted = Analysis {
        files: [
            ("model::x".to_string(), "model/x.rs".to_string()),
            ("report".to_string(), "report.rs".to_string()),
        ]
        .into(),
        edges: vec![Edge {
            from: "model::x".into(),
            to: "report".into(),
            line: 3,
            text: "crate::report::f".into(),
        }],
    };
    assert_eq!(above_the_bottom(&planted), ["  src/model/x.rs:3  crate::report::f"]);
}
