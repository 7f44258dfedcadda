//! The files of a Mitsuba scene: the one loaded and those its `<include filename=...>`
//! elements name, depth first (each read once per inclusion; a cycle or a chain deeper
//! than [`MAX_INCLUDE_DEPTH`] is an error at the `<include>` that closes it), and the
//! folders its `<path value=...>` elements add to where files are looked for (Mitsuba's
//! file resolver: the including file's folder, then those paths, then the scene's own).

use crate::error::ImportError;
use roxmltree::{Document, Node, NodeId};
use std::collections::HashMap;
use std::path::{Path, PathBuf};

/// The deepest elements may nest (the XML parser recurses per level: thousands of levels
/// overflowed a thread's stack; Mitsuba scenes nest a handful).
const MAX_DEPTH: usize = 256;

/// The line and column of the first element nested deeper than [`MAX_DEPTH`], found by a
/// scan of the tags (comments, processing instructions, CDATA and quoted attribute values
/// skipped) before the parser sees the text.
fn too_deep(text: &str) -> Option<(usize, usize)> {
    let b = text.as_bytes();
    let (mut i, mut depth) = (0usize, 0usize);
    while let Some(off) = b[i..].iter().position(|&c| c == b'<') {
        let start = i + off;
        let rest = &text[start..];
        let skip_to = |end: &str| rest.find(end).map_or(b.len(), |k| start + k + end.len());
        if rest.starts_with("<!--") {
            i = skip_to("-->");
        } else if rest.starts_with("<![CDATA[") {
            i = skip_to("]]>");
        } else if rest.starts_with("<?") {
            i = skip_to("?>");
        } else if rest.starts_with("<!") {
            i = skip_to(">");
        } else if rest.starts_with("</") {
            depth = depth.saturating_sub(1);
            i = skip_to(">");
        } else {
            // An opening tag: to its '>' outside quotes; '/>' closes it at once.
            let mut j = start + 1;
            let mut quote = 0u8;
            while j < b.len() && !(quote == 0 && b[j] == b'>') {
                match (quote, b[j]) {
                    (0, q @ (b'"' | b'\'')) => quote = q,
                    (q, c) if q == c => quote = 0,
                    _ => {}
                }
                j += 1;
            }
            if !(j > start && b.get(j.wrapping_sub(1)) == Some(&b'/')) {
                depth += 1;
                if depth > MAX_DEPTH {
                    let line = text[..start].matches('\n').count() + 1;
                    let column = start - text[..start].rfind('\n').map_or(0, |k| k + 1) + 1;
                    return Some((line, column));
                }
            }
            i = (j + 1).min(b.len());
        }
        if i >= b.len() {
            break;
        }
    }
    None
}

type R<T> = Result<T, ImportError>;

/// How deep includes may nest.
pub(super) const MAX_INCLUDE_DEPTH: usize = 16;

/// Most files one scene may include in all.
const MAX_FILES: usize = 256;

/// A scene's files.
pub(super) struct Files {
    /// Each file's path and text; the first is the scene itself.
    pub texts: Vec<(PathBuf, String)>,
    /// Which file an `<include>` (file index, element) brings in.
    pub includes: HashMap<(usize, NodeId), usize>,
    /// Folders `<path>` elements named, in order.
    pub search: Vec<PathBuf>,
    /// Each file's folder (where its own relative names are looked for first).
    pub dirs: Vec<PathBuf>,
}

/// Parses one file's text as the reader does.
pub(super) fn parse<'t>(path: &Path, text: &'t str) -> R<Document<'t>> {
    if let Some((line, column)) = too_deep(text) {
        return Err(ImportError::At {
            path: path.to_path_buf(),
            line: line as u32,
            column: column as u32,
            msg: format!("elements nest deeper than {MAX_DEPTH} levels"),
        });
    }
    Document::parse_with_options(text, roxmltree::ParsingOptions { allow_dtd: false, nodes_limit: 1 << 22 }).map_err(|e| {
        let p = e.pos();
        ImportError::At { path: path.to_path_buf(), line: p.row, column: p.col, msg: e.to_string() }
    })
}

fn at(path: &Path, doc: &Document, n: Node, msg: String) -> ImportError {
    let p = doc.text_pos_at(n.range().start);
    ImportError::At { path: path.to_path_buf(), line: p.row, column: p.col, msg }
}

/// The first of `dir/name`, each search folder's `name`, `base/name` that exists.
pub(super) fn resolve(name: &str, dir: &Path, search: &[PathBuf], base: &Path) -> Option<PathBuf> {
    let name = name.replace('\\', "/");
    std::iter::once(dir).chain(search.iter().map(PathBuf::as_path)).chain(std::iter::once(base)).map(|d| d.join(&name)).find(|p| p.exists())
}

/// Most bytes a scene file (a scene, an included file, a spectrum) may have.
pub(super) const MAX_TEXT: u64 = 256 << 20;

/// A text file's contents: a regular file of at most [`MAX_TEXT`] bytes, in UTF-8 (a
/// device, a folder or a huge file is refused before it is read).
pub(super) fn read_text(path: &Path) -> Result<String, String> {
    let meta = std::fs::metadata(path).map_err(|e| e.to_string())?;
    if !meta.is_file() {
        return Err("not a regular file".into());
    }
    if meta.len() > MAX_TEXT {
        return Err(format!("{} bytes, more than the {MAX_TEXT} a scene file may have", meta.len()));
    }
    let bytes = std::fs::read(path).map_err(|e| e.to_string())?;
    String::from_utf8(bytes).map_err(|_| "not UTF-8 text".into())
}

/// The scene at `path` (its `text`, files looked for in `base`) and everything it includes.
pub(super) fn gather(path: &Path, base: &Path, text: &str) -> R<Files> {
    let mut files = Files {
        texts: vec![(path.to_path_buf(), text.to_string())],
        includes: HashMap::new(),
        search: Vec::new(),
        dirs: vec![base.to_path_buf()],
    };
    let mut stack = vec![path.canonicalize().unwrap_or_else(|_| path.to_path_buf())];
    visit(&mut files, 0, base, &mut stack)?;
    Ok(files)
}

fn visit(files: &mut Files, k: usize, base: &Path, stack: &mut Vec<PathBuf>) -> R<()> {
    let (path, text) = files.texts[k].clone();
    let doc = parse(&path, &text)?;
    let root = doc.root_element();
    let dir = files.dirs[k].clone();
    for n in root.children().filter(Node::is_element) {
        match n.tag_name().name() {
            "path" => {
                let Some(v) = n.attribute("value") else { return Err(at(&path, &doc, n, "<path> needs a 'value' attribute".into())) };
                files.search.push(dir.join(v.replace('\\', "/")));
            }
            "include" => {
                let Some(name) = n.attribute("filename") else {
                    return Err(at(&path, &doc, n, "<include> needs a 'filename' attribute".into()));
                };
                let Some(found) = resolve(name, &dir, &files.search, base) else {
                    return Err(at(&path, &doc, n, format!("<include>: no file '{name}' in {} or the <path> folders", dir.display())));
                };
                let canon = found.canonicalize().unwrap_or_else(|_| found.clone());
                if stack.contains(&canon) {
                    return Err(at(&path, &doc, n, format!("<include> of {} closes a cycle", found.display())));
                }
                if stack.len() > MAX_INCLUDE_DEPTH {
                    return Err(at(&path, &doc, n, format!("includes nest deeper than {MAX_INCLUDE_DEPTH} files")));
                }
                if files.texts.len() >= MAX_FILES {
                    return Err(at(&path, &doc, n, format!("more than {MAX_FILES} included files")));
                }
                let included = read_text(&found).map_err(|e| at(&path, &doc, n, format!("<include> {}: {e}", found.display())))?;
                let j = files.texts.len();
                files.texts.push((found.clone(), included));
                files.dirs.push(found.parent().map_or_else(|| dir.clone(), Path::to_path_buf));
                files.includes.insert((k, n.id()), j);
                stack.push(canon);
                visit(files, j, base, stack)?;
                stack.pop();
            }
            _ => {}
        }
    }
    Ok(())
}
