//! No code outside the task loader knows the shipped tasks' scene (issue 53): what a task
//! holds — its regions (the paper's four coloured balls), its events (the cancel) and their
//! letters — comes from the task's layout, never from a name, a letter or a count written in
//! the code.
//!
//! **What is read**: every Rust file under `src/` (the binaries too), without its comments
//! (doc comments included: naming `"rgby"` as an example is fine) and without the items under
//! a `#[cfg(test)]` attribute (test modules build the shipped tasks' labels by hand). Other
//! files (the built-in scene's MJCF, task files, machines, scripts, docs) are not read.
//!
//! **What is flagged**, with the file and the line:
//! - a string literal with a ball colour as a whole word (`red`, `green`, `blue`, `yellow`,
//!   any case; `"reacher_blue"` too, `"bluer"` not);
//! - a string literal made only of the shipped letters `r`, `g`, `b`, `y`, `c` (`"rgby"`,
//!   `"rgbyc"`, `"c"`);
//! - a character literal among those letters (`'c'`, the cancel's letter; `'r'`);
//! - an identifier with a ball colour as one of its words (`RED`, `is_blue`, `GreenBall`), and
//!   a constant (an upper-case identifier) with `CANCEL` or `BALL`/`BALLS` as one of its
//!   words;
//! - a count of the four-ball scene: `2 * 4` or `4 * 2` (the four regions' observation
//!   columns), `16` or `17` on a line that names an observation (`8 + 2·4`, plus the cancel
//!   flag), an array of length 4 or 5 (`[_; 4]`: four regions, five label bits) on a line
//!   that names regions, balls, goals, letters or positions, and a label set written as a
//!   number (`LabelSet(0b1111)`, `LabelSet(16)`).
//!
//! **What it cannot see**: a count written another way (`3 + 1`, a loop bound, a length
//! that only matches four by accident of the data), a colour or letter built at run time
//! (`format!("r{}", …)`, `char::from(b'c')` with a byte literal outside the letters), a
//! shipped task's schedule or radius written as numbers (a test's `CancelConfig` of
//! probability 0.5 over steps 1–8, the shipped tasks' schedule), anything behind another `cfg`
//! than `cfg(test)`, and code that merely treats "the first event" or "the last label bit"
//! specially without naming it. Lower-case `cancel` identifiers are not flagged: the run
//! config's `[env.cancel]` and the reward files' `cancel` column are file formats (a task's
//! one event, whatever its letter), and renaming them would change what files read.

mod rust_source;

use rust_source::{Kind, Segment};
use std::path::Path;

/// The task loader: files that may name what the shipped tasks hold. Today each is here only
/// for the shipped task named `blue`; a file here that names nothing the check sees fails
/// the test, so the list cannot outgrow its reasons.
const LOADER: &[(&str, &str)] = &[
    (
        "src/env/task_file.rs",
        "reads task files and names the shipped tasks (`blue`, the Markovian positive control, \
         among them)",
    ),
    (
        "src/assets.rs",
        "the built-in copies of the shipped task files, machines and expert policies, looked up \
         by their shipped names",
    ),
    (
        "src/rm/perfect.rs",
        "the names of the shipped machine files (`reacher_blue`), whose texts `assets` holds",
    ),
];

/// Single lines outside the loader that the check flags but that hold no ball, colour or
/// letter of a task: (file, text on the line, why). An entry that no longer matches a flagged
/// line fails the test.
const ALLOWED: &[(&str, &str, &str)] = &[(
    "src/pipeline/render.rs",
    "const REGION_PALETTE: [Rgb; 4]",
    "colours for regions whose anchor names no geom, cycled over any number of regions: the \
     palette's length, not a count of regions",
)];

const COLOURS: [&str; 4] = ["red", "green", "blue", "yellow"];
/// The shipped tasks' letters: the four balls', then the cancel's.
const LETTERS: &str = "rgbyc";

#[derive(Clone, Debug, PartialEq)]
enum Token<'a> {
    Ident(&'a str),
    Number(&'a str),
    Punct(char),
    Str(&'a str),
    Char(&'a str),
}

/// The tokens of a file's code and literals, each with its line; comments are left out.
fn tokens<'a>(segments: &[Segment<'a>]) -> Vec<(Token<'a>, usize)> {
    let mut out = Vec::new();
    for s in segments {
        match s.kind {
            Kind::Comment => {}
            Kind::Str => out.push((Token::Str(s.text), s.line)),
            Kind::Char => out.push((Token::Char(s.text), s.line)),
            Kind::Code => {
                let mut line = s.line;
                let mut rest = s.text;
                while let Some(c) = rest.chars().next() {
                    let word = |rest: &'a str, more: fn(char) -> bool| {
                        let n = rest.find(|c: char| !more(c)).unwrap_or(rest.len());
                        &rest[..n]
                    };
                    let (token, len) = if c.is_alphabetic() || c == '_' {
                        let w = word(rest, |c| c.is_alphanumeric() || c == '_');
                        (Some(Token::Ident(w)), w.len())
                    } else if c.is_ascii_digit() {
                        // Digits, suffixes and underscores; no decimal point (`1.0` is two
                        // numbers, which no rule below minds).
                        let w = word(rest, |c| c.is_alphanumeric() || c == '_');
                        (Some(Token::Number(w)), w.len())
                    } else if c.is_whitespace() {
                        (None, c.len_utf8())
                    } else {
                        (Some(Token::Punct(c)), c.len_utf8())
                    };
                    if let Some(t) = token {
                        out.push((t, line));
                    }
                    line += rest[..len].matches('\n').count();
                    rest = &rest[len..];
                }
            }
        }
    }
    out
}

/// The tokens without the items that a `#[cfg(test)]` attribute puts under it (with the
/// attribute and the item's other attributes).
fn without_test_items<'a>(t: &[(Token<'a>, usize)]) -> Vec<(Token<'a>, usize)> {
    let cfg_test = [
        Token::Punct('#'),
        Token::Punct('['),
        Token::Ident("cfg"),
        Token::Punct('('),
        Token::Ident("test"),
        Token::Punct(')'),
        Token::Punct(']'),
    ];
    let mut out = Vec::new();
    let mut i = 0;
    while i < t.len() {
        let at_cfg_test =
            t.len() - i >= cfg_test.len() && (0..cfg_test.len()).all(|k| t[i + k].0 == cfg_test[k]);
        if !at_cfg_test {
            out.push(t[i].clone());
            i += 1;
            continue;
        }
        // The item ends at its first `;` outside brackets, or with the braces it opens.
        i += cfg_test.len();
        let mut depth = 0usize;
        while i < t.len() {
            let tok = &t[i].0;
            i += 1;
            match tok {
                Token::Punct('(' | '[') => depth += 1,
                Token::Punct(')' | ']') => depth = depth.saturating_sub(1),
                Token::Punct(';') if depth == 0 => break,
                Token::Punct('{') => depth += 1,
                Token::Punct('}') => {
                    depth = depth.saturating_sub(1);
                    if depth == 0 {
                        break;
                    }
                }
                _ => {}
            }
        }
    }
    out
}

/// The words of an identifier: `GreenBall` → green, ball; `N_BALLS` → n, balls.
fn ident_words(ident: &str) -> Vec<String> {
    let mut words = Vec::new();
    for part in ident.split('_').filter(|p| !p.is_empty()) {
        let mut word = String::new();
        let chars: Vec<char> = part.chars().collect();
        for (k, &c) in chars.iter().enumerate() {
            let lower_before = k > 0 && chars[k - 1].is_lowercase();
            if c.is_uppercase() && lower_before && !word.is_empty() {
                words.push(std::mem::take(&mut word));
            }
            word.extend(c.to_lowercase());
        }
        words.push(word);
    }
    words
}

/// The parsed value of an integer literal (`16`, `0b1111`, `0x1f`, `4usize`), if it is one.
fn integer(text: &str) -> Option<u64> {
    let t = text.replace('_', "");
    let (digits, radix) = match t.get(..2) {
        Some("0b") => (&t[2..], 2),
        Some("0o") => (&t[2..], 8),
        Some("0x") => (&t[2..], 16),
        _ => (&t[..], 10),
    };
    let end = digits
        .find(|c: char| !c.is_digit(radix))
        .unwrap_or(digits.len());
    u64::from_str_radix(&digits[..end], radix).ok()
}

/// Words of identifiers that say a line is about the regions.
const REGION_WORDS: [&str; 10] = [
    "region",
    "regions",
    "ball",
    "balls",
    "goal",
    "goals",
    "letter",
    "letters",
    "position",
    "positions",
];

type Tokens<'a> = [(Token<'a>, usize)];

/// Whether an identifier on the line of token `k` has one of `words` among its words.
fn line_names(t: &Tokens<'_>, k: usize, words: &[&str]) -> bool {
    let line = t[k].1;
    let before = t[..k].iter().rev().take_while(|(_, l)| *l == line);
    let after = t[k..].iter().take_while(|(_, l)| *l == line);
    before.chain(after).any(|(tok, _)| {
        matches!(tok, Token::Ident(w) if ident_words(w).iter().any(|x| words.contains(&x.as_str())))
    })
}

fn string_finding(s: &str) -> Option<String> {
    let words: Vec<String> = (s.split(|c: char| !c.is_alphabetic()))
        .map(str::to_lowercase)
        .collect();
    if let Some(c) = COLOURS.iter().find(|c| words.iter().any(|w| w == *c)) {
        Some(format!("a string names the ball colour {c:?}: {s:?}"))
    } else if (s.len() > 1 || s == "c") && s.chars().all(|c| LETTERS.contains(c)) {
        // Single letters other than the cancel's are too common ("x", "y") to flag.
        Some(format!("a string of the shipped letters: {s:?}"))
    } else {
        None
    }
}

fn ident_finding(t: &Tokens<'_>, k: usize, w: &str) -> Option<String> {
    let words = ident_words(w);
    let constant = w.chars().any(char::is_alphabetic) && !w.chars().any(char::is_lowercase);
    let at = |d: usize| t.get(k + d).map(|(tok, _)| tok);
    if let Some(c) = COLOURS.iter().find(|c| words.iter().any(|x| x == *c)) {
        Some(format!("the identifier {w} names the ball colour {c:?}"))
    } else if constant && (words.iter()).any(|x| ["cancel", "ball", "balls"].contains(&x.as_str()))
    {
        Some(format!("the constant {w} names the cancel or the balls"))
    } else if w == "LabelSet"
        && at(1) == Some(&Token::Punct('('))
        && matches!(at(2), Some(Token::Number(n)) if integer(n) != Some(0))
    {
        Some("a label set written as a number".to_string())
    } else {
        None
    }
}

fn number_finding(t: &Tokens<'_>, k: usize, n: &str) -> Option<String> {
    let v = integer(n)?;
    let at = |d: usize| t.get(k + d).map(|(tok, _)| tok);
    let times = match (at(1), at(2)) {
        (Some(Token::Punct('*')), Some(Token::Number(m))) => integer(m),
        _ => None,
    };
    let array_length =
        k > 0 && t[k - 1].0 == Token::Punct(';') && at(1) == Some(&Token::Punct(']'));
    if matches!((v, times), (2, Some(4)) | (4, Some(2))) {
        Some("2 · 4, the observation columns of four regions".to_string())
    } else if matches!(v, 16 | 17) && line_names(t, k, &["obs"]) {
        Some(format!(
            "{n}, the four-ball observation's width, on a line about observations"
        ))
    } else if matches!(v, 4 | 5) && array_length && line_names(t, k, &REGION_WORDS) {
        Some(format!("an array of length {n} on a line about regions"))
    } else {
        None
    }
}

/// What names the shipped tasks' balls, colours, letters or counts in `text`: (line, what).
fn findings(text: &str) -> Vec<(usize, String)> {
    let t = without_test_items(&tokens(&rust_source::segments(text)));
    let mut out = Vec::new();
    for (k, (tok, line)) in t.iter().enumerate() {
        let what = match tok {
            Token::Str(s) => string_finding(s),
            Token::Char(c) => {
                (c.len() == 1 && LETTERS.contains(*c)).then(|| format!("the shipped letter '{c}'"))
            }
            Token::Ident(w) => ident_finding(&t, k, w),
            Token::Number(n) => number_finding(&t, k, n),
            Token::Punct(_) => None,
        };
        if let Some(what) = what {
            out.push((*line, what));
        }
    }
    out
}

fn repo_path(p: &Path) -> String {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    p.strip_prefix(root)
        .unwrap()
        .to_string_lossy()
        .replace('\\', "/")
}

#[test]
fn no_code_outside_the_task_loader_names_balls_colours_or_letters() {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let files = rust_source::rust_files(&src);
    for (loader, _) in LOADER {
        assert!(
            files.iter().any(|f| repo_path(f) == *loader),
            "{loader}: in the loader list but no such file"
        );
    }
    let mut wrong = Vec::new();
    let mut allowed_used = vec![false; ALLOWED.len()];
    for f in &files {
        let file = repo_path(f);
        let text = std::fs::read_to_string(f).unwrap();
        let found = findings(&text);
        if LOADER.iter().any(|(l, _)| *l == file) {
            // A loader file that names nothing needs no place in the list.
            assert!(
                !found.is_empty(),
                "{file}: in LOADER but names nothing the check sees"
            );
            continue;
        }
        let lines: Vec<&str> = text.lines().collect();
        for (line, what) in found {
            let on_line = lines.get(line - 1).copied().unwrap_or("");
            let allowed = ALLOWED
                .iter()
                .position(|(a, snippet, _)| *a == file && on_line.contains(snippet));
            match allowed {
                Some(a) => allowed_used[a] = true,
                None => wrong.push(format!("{file}:{line}: {what}\n    {}", on_line.trim())),
            }
        }
    }
    assert!(
        wrong.is_empty(),
        "code outside the task loader names what the shipped tasks hold (read it from the \
         task's layout, or see this test's LOADER and ALLOWED):\n{}",
        wrong.join("\n")
    );
    let stale: Vec<_> = (ALLOWED.iter().zip(&allowed_used))
        .filter(|(_, &used)| !used)
        .map(|((f, s, _), _)| format!("{f}: {s:?}"))
        .collect();
    assert!(
        stale.is_empty(),
        "allowed lines that are no longer flagged: {stale:?}"
    );
}

/// The check sees a violation in code, and not the same text in a comment, a doc comment or a
/// test module: it cannot pass because it reads nothing.
#[test]
fn the_check_flags_code_and_skips_comments_and_tests() {
    let flagged = |text: &str| {
        findings(text)
            .into_iter()
            .map(|(l, _)| l)
            .collect::<Vec<_>>()
    };
    let code = "fn goals() -> String {\n    \"rgby\".into()\n}\n";
    assert_eq!(flagged(code), [2]);
    for (text, expected) in [
        ("let noise = Some(('c', 0.01));", vec![1]),
        ("const CANCEL: usize = 4;", vec![1]),
        ("let is_red = true;", vec![1]),
        ("let body = \"Blue ball\";", vec![1]),
        ("let obs_dim = 8 + 2 * 4;", vec![1]),
        ("let obs = [0.0; 17];", vec![1]),
        ("let regions: [Region; 4] = layout.regions();", vec![1]),
        ("let l = LabelSet(0b1111);", vec![1]),
        ("let s = \"reacher_blue\";", vec![1]),
        // Not violations: other words, other letters, other counts.
        (
            "let s = \"bluer\"; let v = \"ABCDcmo\"; let x = 2 * 3;",
            vec![],
        ),
        ("let q: [f64; 4] = rgba; let required = 1;", vec![]),
        ("let cancel = CancelConfig::default();", vec![]),
    ] {
        assert_eq!(flagged(text), expected, "{text}");
    }
    let hidden = "// \"rgby\"\n/// the letters \"rgby\"\n/* 'c' */\nfn f() {}\n\
                  #[cfg(test)]\nmod tests {\n    fn g() { let v = \"rgby\"; let c = 'c'; }\n}\n\
                  #[cfg(test)]\nconst RED: [usize; 4] = [0; 4];\n\
                  fn h() -> &'static str { \"rgby\" }\n";
    assert_eq!(
        flagged(hidden),
        [11],
        "only the last line's code is flagged"
    );
}

#[test]
fn segments_tell_code_comments_and_literals_apart() {
    let text = "let s = r#\"a \"q\" b\"#; // c \"x\"\n/* d /* e */ */ let c = '\\'';\n\
                fn f<'a>(x: &'a str) -> u8 { b'x' }\nlet y = br\"\\\"; let z = \"é\\\"\";";
    let got: Vec<(Kind, &str, usize)> = rust_source::segments(text)
        .into_iter()
        .filter(|s| s.kind != Kind::Code)
        .map(|s| (s.kind, s.text, s.line))
        .collect();
    assert_eq!(
        got,
        [
            (Kind::Str, "a \"q\" b", 1),
            (Kind::Comment, "// c \"x\"", 1),
            (Kind::Comment, "/* d /* e */ */", 2),
            (Kind::Char, "\\'", 2),
            (Kind::Char, "x", 3),
            (Kind::Str, "\\", 4),
            (Kind::Str, "é\\\"", 4),
        ]
    );
    let code: String = rust_source::segments(text)
        .iter()
        .filter(|s| s.kind == Kind::Code)
        .map(|s| s.text)
        .collect();
    assert!(code.contains("fn f<'a>(x: &'a str) -> u8 { b }"), "{code}");
}
