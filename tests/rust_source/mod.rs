//! Reading the crate's own Rust sources, for the tests that check what the code says
//! (`module_layering`, `task_agnostic_code`): the source files, and each file cut into code,
//! comments, string literals and character literals.

#![allow(dead_code)] // each test binary uses a part

use std::path::{Path, PathBuf};

/// What a piece of source text is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kind {
    Code,
    /// `// …` (with doc comments) or `/* … */` (nested).
    Comment,
    /// A string literal (`"…"`, `r#"…"#`, `b"…"`): the text between the quotes, escapes as
    /// written.
    Str,
    /// A character literal (`'x'`, `'\n'`, `b'x'`): the text between the quotes.
    Char,
}

#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Segment<'a> {
    pub kind: Kind,
    pub text: &'a str,
    /// 1-based line of the segment's first character.
    pub line: usize,
}

/// Every `.rs` file under `dir`, sorted.
pub fn rust_files(dir: &Path) -> Vec<PathBuf> {
    fn walk(dir: &Path, out: &mut Vec<PathBuf>) {
        for entry in std::fs::read_dir(dir).unwrap() {
            let path = entry.unwrap().path();
            if path.is_dir() {
                walk(&path, out);
            } else if path.extension().is_some_and(|e| e == "rs") {
                out.push(path);
            }
        }
    }
    let mut out = Vec::new();
    walk(dir, &mut out);
    out.sort();
    out
}

/// `text` cut into code, comments and literals, in order. A literal's quotes (with a raw
/// string's `r#`) belong to no segment; a `b` before a byte literal stays in the code.
pub fn segments<'a>(text: &'a str) -> Vec<Segment<'a>> {
    let b = text.as_bytes();
    let is_ident = |c: u8| c.is_ascii_alphanumeric() || c == b'_';
    // Each comment and literal: (kind, first byte, its text's start and end, byte after it).
    let mut pieces: Vec<(Kind, usize, usize, usize, usize)> = Vec::new();
    let mut i = 0;
    while i < b.len() {
        let found = if b[i..].starts_with(b"//") {
            let end = text[i..].find('\n').map_or(b.len(), |k| i + k);
            Some((Kind::Comment, i, end, end))
        } else if b[i..].starts_with(b"/*") {
            let (mut j, mut depth) = (i, 0);
            while j < b.len() {
                if b[j..].starts_with(b"/*") {
                    depth += 1;
                    j += 2;
                } else if b[j..].starts_with(b"*/") {
                    depth -= 1;
                    j += 2;
                    if depth == 0 {
                        break;
                    }
                } else {
                    j += 1;
                }
            }
            Some((Kind::Comment, i, j, j))
        } else if b[i] == b'r'
            && (i == 0 || !is_ident(b[i - 1]) || b[i - 1] == b'b' && (i < 2 || !is_ident(b[i - 2])))
        {
            // A raw string: r"…", r#"…"#, br"…" (not a raw identifier such as r#type).
            let hashes = b[i + 1..].iter().take_while(|&&c| c == b'#').count();
            (b.get(i + 1 + hashes) == Some(&b'"')).then(|| {
                let start = i + 2 + hashes;
                let close = format!("\"{}", "#".repeat(hashes));
                let end = text[start..].find(&close).map_or(b.len(), |k| start + k);
                (Kind::Str, start, end, (end + close.len()).min(b.len()))
            })
        } else if b[i] == b'"' {
            let mut j = i + 1;
            while j < b.len() && b[j] != b'"' {
                j += if b[j] == b'\\' { 2 } else { 1 };
            }
            let end = j.min(b.len());
            Some((Kind::Str, i + 1, end, (end + 1).min(b.len())))
        } else if b[i] == b'\'' {
            // A character literal; a lifetime or a label ('a, 'static) has no closing quote
            // after its first character.
            let end = if b.get(i + 1) == Some(&b'\\') {
                // The escaped character, then the closing quote.
                (text.get(i + 3..).and_then(|rest| rest.find('\''))).map(|k| i + 3 + k)
            } else {
                let width = text[i + 1..].chars().next().map_or(0, char::len_utf8);
                (width > 0 && b.get(i + 1 + width) == Some(&b'\'')).then_some(i + 1 + width)
            };
            end.map(|end| (Kind::Char, i + 1, end, end + 1))
        } else {
            None
        };
        match found {
            Some((kind, start, end, after)) => {
                pieces.push((kind, i, start, end, after));
                i = after;
            }
            None => i += text[i..].chars().next().map_or(1, char::len_utf8),
        }
    }
    let newlines: Vec<usize> = text.match_indices('\n').map(|(k, _)| k).collect();
    let line_of = |at: usize| 1 + newlines.partition_point(|&k| k < at);
    let mut out = Vec::new();
    let mut code_start = 0;
    let code = |out: &mut Vec<Segment<'a>>, from: usize, to: usize| {
        if from < to {
            out.push(Segment {
                kind: Kind::Code,
                text: &text[from..to],
                line: line_of(from),
            });
        }
    };
    for (kind, first, start, end, after) in pieces {
        code(&mut out, code_start, first);
        out.push(Segment {
            kind,
            text: &text[start..end],
            line: line_of(start),
        });
        code_start = after;
    }
    code(&mut out, code_start, b.len());
    out
}
