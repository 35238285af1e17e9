//! The crate's imports flow one way: the top-level modules follow the layering `src/lib.rs`
//! draws, and no set of source files imports each other in a circle.
//!
//! Imports are read from the source text: every path that starts with `crate::` or `super::`,
//! in `use` trees (with their braces) and in code, resolved to the longest prefix that names a
//! source file's module. Comments and string literals are skipped.

mod rust_source;

use rust_source::Kind;
use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;

/// Layer of each top-level module (`src/lib.rs`): a module imports only modules of a lower
/// layer, and the shared utilities (layer 0) import only each other.
fn layer(module: &str) -> Option<u32> {
    Some(match module {
        "assets" | "atomic_file" | "config_text" | "input_file" | "output" | "quoted"
        | "short_float" => 0,
        "mujoco" | "rm" | "nn" | "report" => 1,
        "env" => 2,
        "rl" | "log" => 3,
        "irl" => 4,
        "pipeline" => 5,
        _ => return None,
    })
}

type Module = Vec<String>;

/// `src/a/b.rs` and `src/a/b/mod.rs` → `[a, b]`; `src/lib.rs` → `[]`.
fn module_of(src: &Path, file: &Path) -> Module {
    let rel = file.strip_prefix(src).unwrap().with_extension("");
    let mut parts: Module = rel
        .iter()
        .map(|p| p.to_string_lossy().into_owned())
        .collect();
    if matches!(parts.last().map(String::as_str), Some("mod" | "lib")) {
        parts.pop();
    }
    parts
}

/// The source with comments, string and character literals replaced by spaces.
fn code_only(text: &str) -> String {
    rust_source::segments(text)
        .iter()
        .map(|s| if s.kind == Kind::Code { s.text } else { " " })
        .collect()
}

#[derive(Clone, Debug, PartialEq)]
enum Token {
    Ident(String),
    PathSep,
    Open,
    Close,
    Comma,
    Other,
}

fn tokens(code: &str) -> Vec<Token> {
    let c: Vec<char> = code.chars().collect();
    let mut out = Vec::new();
    let mut i = 0;
    while i < c.len() {
        let ch = c[i];
        if ch.is_alphabetic() || ch == '_' {
            let start = i;
            while i < c.len() && (c[i].is_alphanumeric() || c[i] == '_') {
                i += 1;
            }
            out.push(Token::Ident(c[start..i].iter().collect()));
            continue;
        }
        out.push(match ch {
            ':' if c.get(i + 1) == Some(&':') => {
                i += 1;
                Token::PathSep
            }
            '{' => Token::Open,
            '}' => Token::Close,
            ',' => Token::Comma,
            c if c.is_whitespace() => {
                i += 1;
                continue;
            }
            _ => Token::Other,
        });
        i += 1;
    }
    out
}

/// Every path the tokens name from `start`: `a::b::{c, d::e}` gives `a::b::c` and
/// `a::b::d::e`; returns the paths and the index after them.
fn paths_at(t: &[Token], mut i: usize, prefix: Vec<String>, out: &mut Vec<Vec<String>>) -> usize {
    let mut path = prefix;
    loop {
        match t.get(i) {
            Some(Token::Ident(s)) => {
                path.push(s.clone());
                i += 1;
            }
            Some(Token::Open) => {
                i += 1;
                loop {
                    match t.get(i) {
                        Some(Token::Close) => return i + 1,
                        Some(Token::Comma) => i += 1,
                        None => return i,
                        _ => i = paths_at(t, i, path.clone(), out),
                    }
                }
            }
            _ => {
                out.push(path);
                return i;
            }
        }
        if t.get(i) == Some(&Token::PathSep) {
            i += 1;
        } else {
            out.push(path);
            return i;
        }
    }
}

/// The modules `file_module` refers to with `crate::` or `super::` paths.
fn imports(code: &str, file_module: &Module) -> Vec<Module> {
    let t = tokens(code);
    let mut paths = Vec::new();
    let mut i = 0;
    while i < t.len() {
        let starts = matches!(&t[i], Token::Ident(s) if s == "crate" || s == "super")
            && t.get(i + 1) == Some(&Token::PathSep)
            && (i == 0 || t[i - 1] != Token::PathSep);
        if starts {
            i = paths_at(&t, i, Vec::new(), &mut paths);
        } else {
            i += 1;
        }
    }
    // `super` of module a::b is a, whether its file is `a/b.rs` or `a/b/mod.rs`.
    paths
        .into_iter()
        .filter_map(|p| {
            let mut base: Module = Vec::new();
            let mut rest = p.as_slice();
            if rest.first().map(String::as_str) == Some("crate") {
                rest = &rest[1..];
            } else {
                base = file_module.clone();
                while rest.first().map(String::as_str) == Some("super") {
                    base.pop()?;
                    rest = &rest[1..];
                }
            }
            base.extend(rest.iter().cloned());
            Some(base)
        })
        .collect()
}

struct Graph {
    files: BTreeSet<Module>,
    edges: BTreeMap<Module, BTreeSet<Module>>,
}

fn graph() -> Graph {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    // The binaries are crates of their own.
    let paths: Vec<_> = rust_source::rust_files(&src)
        .into_iter()
        .filter(|p| !p.starts_with(src.join("bin")))
        .collect();
    let files: BTreeSet<Module> = paths.iter().map(|p| module_of(&src, p)).collect();
    let mut edges: BTreeMap<Module, BTreeSet<Module>> = BTreeMap::new();
    for p in &paths {
        let from = module_of(&src, p);
        let code = code_only(&std::fs::read_to_string(p).unwrap());
        for target in imports(&code, &from) {
            // The longest prefix that is a source file's module.
            let Some(to) = (1..=target.len())
                .rev()
                .map(|k| target[..k].to_vec())
                .find(|m| files.contains(m))
            else {
                continue;
            };
            // A file's own module and its ancestors (whose mod.rs declares it) are no import.
            if to != from && !from.starts_with(&to) {
                edges.entry(from.clone()).or_default().insert(to);
            }
        }
    }
    Graph { files, edges }
}

/// The strongly connected components of more than one file (Tarjan).
fn circles(g: &Graph) -> Vec<BTreeSet<String>> {
    struct State<'a> {
        g: &'a Graph,
        index: BTreeMap<&'a Module, usize>,
        low: BTreeMap<&'a Module, usize>,
        stack: Vec<&'a Module>,
        on: BTreeSet<&'a Module>,
        out: Vec<BTreeSet<String>>,
    }
    fn visit<'a>(s: &mut State<'a>, v: &'a Module) {
        let n = s.index.len();
        s.index.insert(v, n);
        s.low.insert(v, n);
        s.stack.push(v);
        s.on.insert(v);
        let g = s.g;
        for w in g.edges.get(v).into_iter().flatten() {
            if !s.index.contains_key(w) {
                visit(s, w);
                let lw = s.low[w];
                let lv = s.low.get_mut(v).unwrap();
                *lv = (*lv).min(lw);
            } else if s.on.contains(w) {
                let iw = s.index[w];
                let lv = s.low.get_mut(v).unwrap();
                *lv = (*lv).min(iw);
            }
        }
        if s.low[v] == s.index[v] {
            let mut comp = BTreeSet::new();
            loop {
                let w = s.stack.pop().unwrap();
                s.on.remove(w);
                comp.insert(w.join("::"));
                if w == v {
                    break;
                }
            }
            if comp.len() > 1 {
                s.out.push(comp);
            }
        }
    }
    let mut s = State {
        g,
        index: BTreeMap::new(),
        low: BTreeMap::new(),
        stack: Vec::new(),
        on: BTreeSet::new(),
        out: Vec::new(),
    };
    for v in &g.files {
        if !s.index.contains_key(v) {
            visit(&mut s, v);
        }
    }
    s.out
}

#[test]
fn top_level_modules_import_only_lower_layers() {
    let g = graph();
    let mut wrong = Vec::new();
    for (from, targets) in &g.edges {
        let (Some(a), Some(la)) = (from.first(), from.first().and_then(|m| layer(m))) else {
            continue;
        };
        for to in targets {
            let b = &to[0];
            if a == b {
                continue;
            }
            let lb = layer(b).unwrap_or_else(|| panic!("{b}: a top-level module without a layer"));
            let allowed = if la == 0 { lb == 0 } else { lb == 0 || lb < la };
            if !allowed {
                wrong.push(format!("{} imports {}", from.join("::"), to.join("::")));
            }
        }
    }
    assert!(
        wrong.is_empty(),
        "imports against the layering:\n{}",
        wrong.join("\n")
    );
}

#[test]
fn no_files_import_each_other_in_a_circle() {
    let found = circles(&graph());
    assert!(
        found.is_empty(),
        "files that import each other in a circle: {found:?}"
    );
}

#[test]
fn the_reader_sees_use_trees_super_paths_and_skips_comments_and_strings() {
    let code = code_only(
        "use super::{a::X, b};\nuse crate::c::{d::{E, F}};\n// crate::g::h\nlet s = \"crate::i\";\nlet c = '{';\nfn f<'a>() { super::super::j::k(); }",
    );
    let mut got: Vec<String> = imports(&code, &vec!["p".into(), "q".into(), "r".into()])
        .into_iter()
        .map(|m| m.join("::"))
        .collect();
    got.sort();
    assert_eq!(
        got,
        ["c::d::E", "c::d::F", "p::j::k", "p::q::a::X", "p::q::b"]
    );
}
