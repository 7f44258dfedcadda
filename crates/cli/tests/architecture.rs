//! The house's rules, checked over the source text (ARCHITECTURE.md states them):
//!
//! - inside every crate, no two files import each other, directly or around a loop (an
//!   import: a `use` of, or a path through, `crate::`, `super::` or `self::`, outside
//!   comments, strings and `#[cfg(test)]` modules; it points at the longest module prefix
//!   of the path, so `crate::World` points at `lib.rs`, which re-exports it);
//! - in `lucent_render`, the floor (colour, sampling, the sampler, lanes, AOV layers,
//!   textures, the camera) imports nothing of the crate but the floor;
//! - crates depend on one another only as the crate map allows.
//!
//! `cargo test -p lucent --test architecture -- --nocapture` prints each crate's graph.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

fn workspace() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// The crates: (name, source folder), from each `Cargo.toml` under `crates/`.
fn crates() -> Vec<(String, PathBuf)> {
    let mut out = Vec::new();
    let mut stack = vec![workspace().join("crates")];
    while let Some(dir) = stack.pop() {
        let Ok(entries) = std::fs::read_dir(&dir) else { continue };
        for e in entries.flatten() {
            let p = e.path();
            if p.is_dir() && p.file_name().is_some_and(|n| n != "src" && n != "tests" && n != "target") {
                stack.push(p);
            } else if p.file_name().is_some_and(|n| n == "Cargo.toml") {
                let text = std::fs::read_to_string(&p).expect("Cargo.toml");
                let name = text
                    .lines()
                    .find_map(|l| l.strip_prefix("name = \"").and_then(|r| r.strip_suffix('"')))
                    .expect("a package name")
                    .to_string();
                if dir.join("src").is_dir() {
                    out.push((name, dir.join("src")));
                }
            }
        }
    }
    out.sort();
    out
}

/// Every `.rs` file under `src` with its module path (`lib.rs`/`main.rs`: the root).
fn modules(src: &Path) -> BTreeMap<String, PathBuf> {
    let mut out = BTreeMap::new();
    let mut stack = vec![src.to_path_buf()];
    while let Some(dir) = stack.pop() {
        for e in std::fs::read_dir(&dir).expect("read_dir").flatten() {
            let p = e.path();
            if p.is_dir() {
                if p.file_name().is_some_and(|n| n != "bin") {
                    stack.push(p);
                }
                continue;
            }
            if p.extension().is_none_or(|x| x != "rs") {
                continue;
            }
            let rel = p.strip_prefix(src).expect("under src").with_extension("");
            let mut parts: Vec<String> = rel.iter().map(|c| c.to_string_lossy().into_owned()).collect();
            if parts.last().is_some_and(|l| l == "mod" || l == "lib" || l == "main") {
                parts.pop();
            }
            out.insert(parts.join("::"), p);
        }
    }
    out
}

/// The source without comments, string and character literals, and `#[cfg(test)]`
/// items (what is left is code).
fn code_of(text: &str) -> String {
    let b = text.as_bytes();
    let mut out = String::with_capacity(text.len());
    let mut i = 0;
    while i < b.len() {
        let c = b[i];
        if c == b'/' && b.get(i + 1) == Some(&b'/') {
            while i < b.len() && b[i] != b'\n' {
                i += 1;
            }
        } else if c == b'/' && b.get(i + 1) == Some(&b'*') {
            let mut depth = 0;
            while i < b.len() {
                if b[i] == b'/' && b.get(i + 1) == Some(&b'*') {
                    depth += 1;
                    i += 2;
                } else if b[i] == b'*' && b.get(i + 1) == Some(&b'/') {
                    depth -= 1;
                    i += 2;
                    if depth == 0 {
                        break;
                    }
                } else {
                    i += 1;
                }
            }
        } else if c == b'r' && (b.get(i + 1) == Some(&b'"') || b.get(i + 1) == Some(&b'#')) && !ident(b.get(i.wrapping_sub(1))) {
            // A raw string: r"..." or r#"..."#.
            let mut j = i + 1;
            let mut hashes = 0;
            while b.get(j) == Some(&b'#') {
                hashes += 1;
                j += 1;
            }
            if b.get(j) != Some(&b'"') {
                out.push(c as char);
                i += 1;
                continue;
            }
            j += 1;
            loop {
                if j >= b.len() {
                    break;
                }
                if b[j] == b'"' && (0..hashes).all(|k| b.get(j + 1 + k) == Some(&b'#')) {
                    j += 1 + hashes;
                    break;
                }
                j += 1;
            }
            out.push_str("\"\"");
            i = j;
        } else if c == b'"' {
            i += 1;
            while i < b.len() && b[i] != b'"' {
                i += if b[i] == b'\\' { 2 } else { 1 };
            }
            i += 1;
            out.push_str("\"\"");
        } else if c == b'\'' {
            // A character literal ('a', '\n', '\u{..}'), or a lifetime (kept).
            let close = if b.get(i + 1) == Some(&b'\\') {
                (i + 2..b.len().min(i + 12)).find(|&k| b[k] == b'\'')
            } else if b.get(i + 2) == Some(&b'\'') {
                Some(i + 2)
            } else {
                std::str::from_utf8(&b[i + 1..]).ok().and_then(|s| s.chars().next()).and_then(|ch| {
                    let k = i + 1 + ch.len_utf8();
                    (b.get(k) == Some(&b'\'')).then_some(k)
                })
            };
            match close {
                Some(k) => {
                    out.push_str("' '");
                    i = k + 1;
                }
                None => {
                    out.push('\'');
                    i += 1;
                }
            }
        } else {
            let ch = text[i..].chars().next().expect("a char");
            out.push(ch);
            i += ch.len_utf8();
        }
    }
    strip_test_items(&out)
}

fn ident(c: Option<&u8>) -> bool {
    c.is_some_and(|c| c.is_ascii_alphanumeric() || *c == b'_')
}

/// Removes every item that follows `#[cfg(test)]` (a `mod` with its braces, a `use`).
fn strip_test_items(code: &str) -> String {
    let mut out = String::new();
    let mut rest = code;
    while let Some(k) = rest.find("#[cfg(test)]") {
        out.push_str(&rest[..k]);
        let after = &rest[k + "#[cfg(test)]".len()..];
        // The item ends at its first `;` before any `{`, or at the brace that closes it.
        let semi = after.find(';');
        let brace = after.find('{');
        let end = match (semi, brace) {
            (Some(s), Some(b)) if s < b => s + 1,
            (Some(s), None) => s + 1,
            (_, Some(b)) => {
                let mut depth = 0;
                let mut end = after.len();
                for (j, ch) in after[b..].char_indices() {
                    match ch {
                        '{' => depth += 1,
                        '}' => {
                            depth -= 1;
                            if depth == 0 {
                                end = b + j + 1;
                                break;
                            }
                        }
                        _ => {}
                    }
                }
                end
            }
            (None, None) => after.len(),
        };
        rest = &after[end..];
    }
    out.push_str(rest);
    out
}

/// Expands a `use` tree (`a::{b, c::{d, e as f}}`) into its paths, each with the name it
/// binds (`f` for `e as f`; the last segment otherwise).
fn expand(tree: &str) -> Vec<(String, String)> {
    let mut t = String::new();
    // Whitespace matters only around `as`.
    for w in tree.split_whitespace() {
        if w == "as" || t.ends_with(" as") {
            t.push(' ');
        }
        t.push_str(w);
    }
    let mut out = Vec::new();
    expand_into("", &t, &mut out);
    out
}

fn expand_into(prefix: &str, tree: &str, out: &mut Vec<(String, String)>) {
    match tree.find('{') {
        None => {
            let (path, alias) = match tree.split_once(" as ") {
                Some((p, a)) => (p, a.to_string()),
                None => (tree, tree.rsplit("::").next().unwrap_or(tree).to_string()),
            };
            out.push((format!("{prefix}{path}"), alias));
        }
        Some(k) => {
            let head = &tree[..k];
            let inner = &tree[k + 1..tree.rfind('}').unwrap_or(tree.len())];
            let mut depth = 0;
            let mut start = 0;
            for (j, ch) in inner.char_indices() {
                match ch {
                    '{' => depth += 1,
                    '}' => depth -= 1,
                    ',' if depth == 0 => {
                        if j > start {
                            expand_into(&format!("{prefix}{head}"), &inner[start..j], out);
                        }
                        start = j + 1;
                    }
                    _ => {}
                }
            }
            if start < inner.len() {
                expand_into(&format!("{prefix}{head}"), &inner[start..], out);
            }
        }
    }
}

/// A module's `use` declarations: (whether it re-exports, the tree's text).
fn uses(code: &str) -> Vec<(bool, String)> {
    let bytes = code.as_bytes();
    let mut out = Vec::new();
    let mut search = 0;
    while let Some(k) = code[search..].find("use ") {
        let at = search + k;
        search = at + 4;
        if ident(bytes.get(at.wrapping_sub(1))) {
            continue;
        }
        let Some(end) = code[at..].find(';') else { break };
        let before = code[..at].trim_end();
        let public = before.ends_with("pub") || before.ends_with(')') && before.rfind("pub(").is_some_and(|p| p + 12 >= before.len());
        out.push((public, code[at + 4..at + end].to_string()));
    }
    out
}

/// The paths a module's code names through `crate::`, `super::` or `self::`.
fn paths_in(code: &str) -> Vec<String> {
    let mut out = Vec::new();
    let bytes = code.as_bytes();
    for (_, tree) in uses(code) {
        if tree.starts_with("crate") || tree.starts_with("super") || tree.starts_with("self") {
            out.extend(expand(&tree).into_iter().map(|(p, _)| p));
        }
    }
    // Paths written in the code.
    for key in ["crate::", "super::"] {
        let mut from = 0;
        while let Some(k) = code[from..].find(key) {
            let at = from + k;
            from = at + key.len();
            if ident(bytes.get(at.wrapping_sub(1))) || bytes.get(at.wrapping_sub(1)) == Some(&b':') {
                continue;
            }
            let end = code[at..].find(|c: char| !(c.is_alphanumeric() || c == '_' || c == ':')).map_or(code.len(), |e| at + e);
            out.push(code[at..end].trim_end_matches(':').to_string());
        }
    }
    out
}

/// Whether `code` writes a path that starts with `child::` (not after `::` or inside
/// another name).
fn names_child(code: &str, child: &str) -> bool {
    let key = format!("{child}::");
    let b = code.as_bytes();
    let mut from = 0;
    while let Some(k) = code[from..].find(&key) {
        let at = from + k;
        from = at + key.len();
        if !ident(b.get(at.wrapping_sub(1))) && b.get(at.wrapping_sub(1)) != Some(&b':') {
            return true;
        }
    }
    false
}

/// A file's code cut by its inline modules (`mod name { ... }`): each part with the module
/// path its paths are written in (the file's own module for what is outside them).
fn inline_modules(module: &str, code: &str) -> Vec<(String, String)> {
    let mut out = Vec::new();
    let mut outside = String::new();
    let mut rest = code;
    loop {
        // The next `mod NAME {` (not `mod NAME;`).
        let found = rest.match_indices("mod ").find_map(|(k, _)| {
            let before = rest[..k].chars().next_back();
            if before.is_some_and(|c| c.is_alphanumeric() || c == '_') {
                return None;
            }
            let after = &rest[k + 4..];
            let name_len = after.find(|c: char| !(c.is_alphanumeric() || c == '_'))?;
            let (name, tail) = after.split_at(name_len);
            let brace = tail.trim_start().starts_with('{').then(|| k + 4 + name_len + tail.find('{').unwrap_or(0))?;
            (!name.is_empty()).then(|| (k, name.to_string(), brace))
        });
        let Some((k, name, brace)) = found else { break };
        outside.push_str(&rest[..k]);
        let mut depth = 0;
        let mut end = rest.len();
        for (j, ch) in rest[brace..].char_indices() {
            match ch {
                '{' => depth += 1,
                '}' => {
                    depth -= 1;
                    if depth == 0 {
                        end = brace + j + 1;
                        break;
                    }
                }
                _ => {}
            }
        }
        let inner = if module.is_empty() { name } else { format!("{module}::{name}") };
        out.extend(inline_modules(&inner, &rest[brace + 1..end.saturating_sub(1).max(brace + 1)]));
        rest = &rest[end..];
    }
    outside.push_str(rest);
    out.push((module.to_string(), outside));
    out
}

/// Module paths and what each re-exports.
struct Crate {
    mods: BTreeMap<String, PathBuf>,
    /// Per module: name -> the absolute path (segments) it re-exports.
    exports: BTreeMap<String, BTreeMap<String, Vec<String>>>,
    /// The modules that are a folder's face (`lib.rs`, `main.rs`, `mod.rs`).
    faces: BTreeSet<String>,
}

impl Crate {
    /// A path written in module `here`, made absolute (`None`: not a path of this crate).
    fn absolute(&self, here: &str, path: &str) -> Option<Vec<String>> {
        let mut segs: Vec<&str> = path.split("::").filter(|s| !s.is_empty()).collect();
        let mut base: Vec<&str> = if here.is_empty() { Vec::new() } else { here.split("::").collect() };
        match segs.first().copied() {
            Some("crate") => {
                base.clear();
                segs.remove(0);
            }
            Some("self") => {
                segs.remove(0);
            }
            Some("super") => {
                while segs.first() == Some(&"super") {
                    segs.remove(0);
                    base.pop()?;
                }
            }
            // A child module by its bare name.
            Some(first) => {
                let child = if here.is_empty() { first.to_string() } else { format!("{here}::{first}") };
                if !self.mods.contains_key(&child) {
                    return None;
                }
            }
            None => return None,
        }
        Some(base.into_iter().chain(segs).map(str::to_string).collect())
    }

    /// The module that defines what an absolute path names: its longest module prefix,
    /// followed through re-exports (`crate::World` is `world`'s, when `lib.rs` has
    /// `pub use world::World`).
    fn defining(&self, full: &[String], depth: u32) -> Option<String> {
        let n = (0..=full.len()).rev().find(|&n| self.mods.contains_key(&full[..n].join("::")))?;
        let m = full[..n].join("::");
        // (Through the re-exports of a folder's face, `lib.rs` or `mod.rs`, only: a file that
        // hands on another's item is imported when used for it.)
        if depth < 8 && self.faces.contains(&m) {
            if let Some(next) = full.get(n).and_then(|name| self.exports.get(&m)?.get(name)) {
                let mut target = next.clone();
                target.extend(full[n + 1..].iter().cloned());
                if let Some(d) = self.defining(&target, depth + 1) {
                    return Some(d);
                }
            }
        }
        Some(m)
    }

    fn resolve(&self, here: &str, path: &str) -> Option<String> {
        self.defining(&self.absolute(here, path)?, 0)
    }
}

/// Each crate's graph: module -> the modules it imports.
fn graph(src: &Path) -> BTreeMap<String, BTreeSet<String>> {
    let mods = modules(src);
    let codes: BTreeMap<String, String> =
        mods.iter().map(|(m, f)| (m.clone(), code_of(&std::fs::read_to_string(f).expect("source")))).collect();
    let faces = mods
        .iter()
        .filter(|(_, f)| f.file_name().is_some_and(|n| n == "lib.rs" || n == "main.rs" || n == "mod.rs"))
        .map(|(m, _)| m.clone())
        .collect();
    let mut krate = Crate { mods, exports: BTreeMap::new(), faces };
    for (m, code) in &codes {
        let mut ex = BTreeMap::new();
        for (public, tree) in uses(code) {
            if !public {
                continue;
            }
            for (path, alias) in expand(&tree) {
                if let Some(abs) = krate.absolute(m, &path) {
                    ex.insert(alias, abs);
                }
            }
        }
        krate.exports.insert(m.clone(), ex);
    }
    let mut g = BTreeMap::new();
    for (m, code) in &codes {
        let mut to = BTreeSet::new();
        // Paths through a child module by its bare name (`child::f()`, `use child::X`).
        let prefix = if m.is_empty() { String::new() } else { format!("{m}::") };
        let children: Vec<&str> =
            krate.mods.keys().filter_map(|c| c.strip_prefix(&prefix)).filter(|c| !c.is_empty() && !c.contains("::")).collect();
        for child in children {
            if names_child(code, child) {
                to.insert(format!("{prefix}{child}"));
            }
        }
        // Each inline module's paths from where they stand (`super::` in `mod imp { }` of
        // `a.rs` is `a`).
        for (inner, part) in inline_modules(m, code) {
            let mut paths = paths_in(&part);
            for (_, tree) in uses(&part) {
                paths.extend(expand(&tree).into_iter().map(|(p, _)| p));
            }
            for p in paths {
                if let Some(t) = krate.resolve(&inner, &p) {
                    if &t != m {
                        to.insert(t);
                    }
                }
            }
        }
        g.insert(m.clone(), to);
    }
    g
}

/// Strongly connected components of more than one module (Tarjan).
fn loops(g: &BTreeMap<String, BTreeSet<String>>) -> Vec<Vec<String>> {
    struct T<'a> {
        g: &'a BTreeMap<String, BTreeSet<String>>,
        index: BTreeMap<&'a str, usize>,
        low: BTreeMap<&'a str, usize>,
        stack: Vec<&'a str>,
        on: BTreeSet<&'a str>,
        next: usize,
        out: Vec<Vec<String>>,
    }
    fn visit<'a>(t: &mut T<'a>, v: &'a str) {
        t.index.insert(v, t.next);
        t.low.insert(v, t.next);
        t.next += 1;
        t.stack.push(v);
        t.on.insert(v);
        for w in t.g.get(v).into_iter().flatten() {
            let w = w.as_str();
            if !t.g.contains_key(w) {
                continue;
            }
            if !t.index.contains_key(w) {
                visit(t, w);
                let lw = t.low[w];
                let lv = t.low.get_mut(v).expect("visited");
                *lv = (*lv).min(lw);
            } else if t.on.contains(w) {
                let iw = t.index[w];
                let lv = t.low.get_mut(v).expect("visited");
                *lv = (*lv).min(iw);
            }
        }
        if t.low[v] == t.index[v] {
            let mut scc = Vec::new();
            while let Some(w) = t.stack.pop() {
                t.on.remove(w);
                scc.push(w.to_string());
                if w == v {
                    break;
                }
            }
            if scc.len() > 1 {
                scc.sort();
                t.out.push(scc);
            }
        }
    }
    let mut t = T { g, index: BTreeMap::new(), low: BTreeMap::new(), stack: Vec::new(), on: BTreeSet::new(), next: 0, out: Vec::new() };
    for v in g.keys() {
        if !t.index.contains_key(v.as_str()) {
            visit(&mut t, v);
        }
    }
    t.out
}

fn name(m: &str) -> &str {
    if m.is_empty() {
        "(root)"
    } else {
        m
    }
}

#[test]
fn no_file_imports_itself_around_a_loop() {
    let mut found = Vec::new();
    for (krate, src) in crates() {
        let g = graph(&src);
        if std::env::var_os("ARCH_PRINT").is_some() {
            for (m, to) in &g {
                eprintln!("{krate}: {} -> {}", name(m), to.iter().map(|t| name(t)).collect::<Vec<_>>().join(", "));
            }
        }
        for l in loops(&g) {
            let edges: Vec<String> =
                l.iter().flat_map(|a| g[a].iter().filter(|b| l.contains(b)).map(move |b| format!("{} -> {}", name(a), name(b)))).collect();
            found.push(format!("{krate}: {}", edges.join(", ")));
        }
    }
    assert!(found.is_empty(), "files that import each other (around a loop):\n{}", found.join("\n"));
}

/// `lucent_render`'s floor: the modules that import nothing of the crate above them.
const FLOOR: &[&str] = &["color", "sampling", "sampler", "lanes", "aov", "texture", "camera"];

#[test]
fn the_renderer_floor_imports_only_the_floor() {
    let (_, src) = crates().into_iter().find(|(n, _)| n == "lucent_render").expect("lucent_render");
    let g = graph(&src);
    let on_floor = |m: &str| FLOOR.iter().any(|f| m == *f || m.starts_with(&format!("{f}::")));
    let mut bad = Vec::new();
    for f in FLOOR {
        assert!(g.contains_key(*f), "the floor module {f} exists");
    }
    for (m, to) in &g {
        if on_floor(m) {
            for t in to.iter().filter(|t| !on_floor(t)) {
                bad.push(format!("{m} -> {}", name(t)));
            }
        }
    }
    assert!(bad.is_empty(), "the floor imports from above it: {bad:?}");
}

/// Which crate may depend on which (ARCHITECTURE.md's crate map): each crate's
/// `lucent_*`, `rend3r_*` and `saarcor` dependencies must be among these.
const MAY_DEPEND: &[(&str, &[&str])] = &[
    ("lucent_accel", &[]),
    ("lucent_scene", &[]),
    ("lucent_render", &["lucent_accel", "lucent_scene"]),
    ("lucent_cluster", &["lucent_accel", "lucent_scene", "lucent_render"]),
    ("lucent_viewer", &["lucent_accel", "lucent_scene", "lucent_render", "rend3r_isa", "rend3r_machine"]),
    ("rend3r_isa", &[]),
    ("rend3r_machine", &["rend3r_isa", "lucent_accel", "lucent_scene", "lucent_render"]),
    ("rend3r_net", &["rend3r_isa", "rend3r_machine", "lucent_render"]),
    ("saarcor", &["lucent_accel", "lucent_scene", "lucent_render", "rend3r_isa", "rend3r_machine"]),
    ("lucent_py", &["lucent_accel", "lucent_scene", "lucent_render"]),
    ("lucent_fuzzing", &["lucent_accel", "lucent_scene", "lucent_render", "rend3r_isa", "rend3r_machine", "rend3r_net", "lucent_cluster"]),
];

#[test]
fn crates_depend_as_the_crate_map_says() {
    let ours = |d: &str| d.starts_with("lucent") || d.starts_with("rend3r") || d == "saarcor";
    let mut bad = Vec::new();
    for (krate, src) in crates() {
        if krate == "lucent" {
            continue; // the command line sits on top of everything
        }
        let toml = std::fs::read_to_string(src.join("../Cargo.toml")).expect("Cargo.toml");
        let deps: Vec<&str> = toml
            .split("[dependencies]")
            .nth(1)
            .map(|s| s.split("\n[").next().unwrap_or(s))
            .unwrap_or("")
            .lines()
            .filter_map(|l| l.split_once('=').map(|(k, _)| k.trim()))
            .filter(|d| ours(d))
            .collect();
        let Some((_, allowed)) = MAY_DEPEND.iter().find(|(n, _)| *n == krate) else {
            bad.push(format!("{krate} is not on the crate map"));
            continue;
        };
        bad.extend(deps.iter().filter(|d| !allowed.contains(d)).map(|d| format!("{krate} -> {d}")));
    }
    assert!(bad.is_empty(), "dependencies the crate map does not allow: {bad:?}");
}

#[test]
fn the_checker_reads_paths_as_rust_does() {
    let e: Vec<(String, String)> = expand("crate::a::{b, c::{d, e as f}, has_alpha}");
    let want = [("crate::a::b", "b"), ("crate::a::c::d", "d"), ("crate::a::c::e", "f"), ("crate::a::has_alpha", "has_alpha")];
    assert_eq!(e, want.map(|(a, b)| (a.to_string(), b.to_string())));
    let parts = inline_modules("a", "use super::x; mod imp { use super::y; mod deep { use super::z; } } fn f() {}");
    assert_eq!(parts.len(), 3, "{parts:?}");
    assert!(parts.iter().any(|(m, c)| m == "a::imp::deep" && c.contains("super::z")));
    assert!(parts.iter().any(|(m, c)| m == "a::imp" && c.contains("super::y") && !c.contains("super::z")));
    assert!(parts.iter().any(|(m, c)| m == "a" && c.contains("super::x") && c.contains("fn f")));
    let code = code_of("// use crate::x;\nuse crate::y::Z; let s = \"crate::q\"; fn f<'a>(c: char) { super::w::g(); }\n#[cfg(test)]\nmod tests { use crate::t; }");
    let p = paths_in(&code);
    assert!(p.contains(&"crate::y::Z".to_string()) && p.contains(&"super::w::g".to_string()), "{p:?}");
    assert!(!p.iter().any(|x| x.contains("::x") || x.contains("::q") || x.contains("::t")), "{p:?}");
    let mut mods = BTreeMap::new();
    for m in ["", "a", "a::b", "c"] {
        mods.insert(m.to_string(), PathBuf::new());
    }
    let mut exports = BTreeMap::new();
    exports.insert(String::new(), [("World".to_string(), vec!["c".to_string(), "World".to_string()])].into_iter().collect());
    let k = Crate { mods, exports, faces: [String::new()].into_iter().collect() };
    assert_eq!(k.resolve("a::b", "super::Thing").as_deref(), Some("a"));
    assert_eq!(k.resolve("a::b", "crate::c::X").as_deref(), Some("c"));
    assert_eq!(k.resolve("a", "self::b::Y").as_deref(), Some("a::b"));
    assert_eq!(k.resolve("a", "b::Y").as_deref(), Some("a::b"));
    assert_eq!(k.resolve("a", "crate::World").as_deref(), Some("c"), "through the root's re-export");
    assert_eq!(k.resolve("a", "glam::Vec3"), None);
    let g: BTreeMap<String, BTreeSet<String>> = [("a", &["b"][..]), ("b", &["c"]), ("c", &["a"]), ("d", &["a"])]
        .iter()
        .map(|(k, v)| (k.to_string(), v.iter().map(|s| s.to_string()).collect()))
        .collect();
    assert_eq!(loops(&g), vec![vec!["a".to_string(), "b".into(), "c".into()]]);
}
