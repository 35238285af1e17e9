//! Text format for reward machines, in the style of the QRM reward-machine files.
//!
//! ```text
//! # Office task 1: coffee, then office.      <- '#' starts a comment (whole line or trailing)
//! vocabulary: ABCDcmo*                       <- the propositions, one character each, in bit order
//! states: 4                                  <- states are 0 .. states-1
//! initial: 0
//! terminal: 2                                <- goal states, separated by spaces or commas; may be empty
//! failure: 3                                 <- failure sinks; may be empty
//! (0, 1, 'c&!*', 0)                          <- transition (from, to, 'formula', reward)
//! (0, 3, '*', 0)
//! (1, 2, 'o&!*', 1)
//! (1, 3, '*', 0)
//! ```
//!
//! - The header lines `vocabulary:`, `states:` and `initial:` are required, `terminal:` and
//!   `failure:` optional (empty when absent); each may appear once, in any order, and
//!   transitions may come before or after them.
//! - A formula uses the grammar of [`super::formula`] (`&`, `|`, `!`, parentheses, `True`,
//!   `False`, one character per proposition). Formulas cannot contain `'`, `,` or `#`, so
//!   quoting and comments are unambiguous.
//! - A (state, label set) pair that no transition covers stays in place with reward 0.
//!   Terminal and failure states are absorbing and may not have outgoing transitions, and at
//!   most one transition may hold on any label set from a state (checked on all `2^|P|` label
//!   sets, not only those a domain can produce).
//! - Rewards are decimal numbers; [`write_rm`] prints them in Rust's shortest round-trip form,
//!   so read → write → read gives back the same machine.
//!
//! Errors name the file, the 1-based line and what was expected.
//!
//! **Limits** (checked while parsing, before anything is allocated from them): at most
//! [`MAX_STATES`] states, [`MAX_TRANSITIONS`] transitions, [`MAX_LINE_CHARS`] characters per
//! line, formulas nested at most [`super::formula::MAX_DEPTH`] deep; [`read_rm`] reads at
//! most [`crate::config_text::MAX_TEXT_FILE_BYTES`].

use super::formula::Formula;
use super::labels::Vocabulary;
use super::machine::{RewardMachine, RmError, Transition};
use crate::quoted;
use std::fmt::Write as _;
use std::io;
use std::path::Path;

/// Why a reward-machine file could not be read.
#[derive(Debug, thiserror::Error)]
pub enum RmFileError {
    #[error("{file}: cannot read: {error}")]
    Io { file: String, error: io::Error },
    /// The text does not follow the format; `line` is 1-based.
    #[error("{file}:{line}: {problem}")]
    Syntax {
        file: String,
        line: usize,
        problem: String,
    },
    /// The lines parse but do not describe a valid machine (no line to blame).
    #[error("{file}: {error}")]
    Invalid { file: String, error: RmError },
}

impl RmFileError {
    /// The 1-based line the error is about, when there is one.
    pub fn line(&self) -> Option<usize> {
        match self {
            RmFileError::Syntax { line, .. } => Some(*line),
            _ => None,
        }
    }
}

/// Most states of a machine read from a file (its table has states × 2^|P| cells).
pub const MAX_STATES: usize = 1_000;
/// Most transition lines.
pub const MAX_TRANSITIONS: usize = 10_000;
/// Longest line, in characters.
pub const MAX_LINE_CHARS: usize = 4_096;

/// A header value and the line it came from.
struct Header<T> {
    value: T,
    line: usize,
}

/// Parses the text of a reward-machine file; `source` names it in error messages.
pub fn parse_rm(text: &str, source: &str) -> Result<RewardMachine, RmFileError> {
    let syntax = |line: usize, problem: String| RmFileError::Syntax {
        file: source.to_string(),
        line,
        problem,
    };

    let mut vocab: Option<Header<Vocabulary>> = None;
    let mut n_states: Option<Header<usize>> = None;
    let mut initial: Option<Header<usize>> = None;
    let mut terminal: Option<Header<Vec<usize>>> = None;
    let mut failure: Option<Header<Vec<usize>>> = None;
    // Transition lines are parsed once the vocabulary is known (it may come later).
    let mut transition_lines: Vec<(usize, &str)> = Vec::new();

    for (k, raw) in text.lines().enumerate() {
        let line_no = k + 1;
        if raw.chars().count() > MAX_LINE_CHARS {
            return Err(syntax(
                line_no,
                format!("the line is longer than the limit of {MAX_LINE_CHARS} characters"),
            ));
        }
        let line = strip_comment(raw).trim();
        if line.is_empty() {
            continue;
        }
        if line.starts_with('(') {
            if transition_lines.len() == MAX_TRANSITIONS {
                return Err(syntax(
                    line_no,
                    format!("more than the limit of {MAX_TRANSITIONS} transitions"),
                ));
            }
            transition_lines.push((line_no, line));
            continue;
        }
        let Some((key, value)) = line.split_once(':') else {
            return Err(syntax(
                line_no,
                format!(
                    "expected a header 'key: value' (vocabulary, states, initial, terminal, failure) or a transition '(from, to, 'formula', reward)', found \"{}\"",
                    quoted::text(line)
                ),
            ));
        };
        let key = key.trim();
        let value = value.trim();
        let duplicate = |name: &str, first: usize| {
            syntax(
                line_no,
                format!("'{name}:' appears twice (first on line {first})"),
            )
        };
        match key {
            "vocabulary" => {
                if let Some(h) = &vocab {
                    return Err(duplicate(key, h.line));
                }
                let v = Vocabulary::parse(value)
                    .map_err(|e| syntax(line_no, format!("bad vocabulary \"{}\": {e}", quoted::text(value))))?;
                vocab = Some(Header {
                    value: v,
                    line: line_no,
                });
            }
            "states" => {
                if let Some(h) = &n_states {
                    return Err(duplicate(key, h.line));
                }
                let n = parse_state(value).map_err(|p| syntax(line_no, p))?;
                if n == 0 {
                    return Err(syntax(line_no, "expected at least 1 state, found 0".into()));
                }
                if n > MAX_STATES {
                    return Err(syntax(
                        line_no,
                        format!("{n} states is more than the limit of {MAX_STATES}"),
                    ));
                }
                n_states = Some(Header {
                    value: n,
                    line: line_no,
                });
            }
            "initial" => {
                if let Some(h) = &initial {
                    return Err(duplicate(key, h.line));
                }
                let u = parse_state(value).map_err(|p| syntax(line_no, p))?;
                initial = Some(Header {
                    value: u,
                    line: line_no,
                });
            }
            "terminal" | "failure" => {
                let slot = if key == "terminal" {
                    &mut terminal
                } else {
                    &mut failure
                };
                if let Some(h) = slot {
                    return Err(duplicate(key, h.line));
                }
                let states = value
                    .split(|c: char| c == ',' || c.is_whitespace())
                    .filter(|s| !s.is_empty())
                    .map(parse_state)
                    .collect::<Result<Vec<_>, _>>()
                    .map_err(|p| syntax(line_no, p))?;
                *slot = Some(Header {
                    value: states,
                    line: line_no,
                });
            }
            other => {
                return Err(syntax(
                    line_no,
                    format!(
                        "unknown header '{}:' (expected vocabulary, states, initial, terminal or failure)",
                        quoted::text(other)
                    ),
                ))
            }
        }
    }

    let last_line = text.lines().count().max(1);
    let missing = |name: &str| {
        syntax(
            last_line,
            format!("missing the '{name}:' line before the end of the file"),
        )
    };
    let vocab = vocab.ok_or_else(|| missing("vocabulary"))?.value;
    let n_states = n_states.ok_or_else(|| missing("states"))?;
    let initial = initial.ok_or_else(|| missing("initial"))?;
    let n = n_states.value;
    let in_range = |u: usize, line: usize, what: &str| {
        if u < n {
            Ok(())
        } else {
            Err(syntax(
                line,
                format!(
                    "{what} state {u} is out of range: 'states: {n}' (line {}) allows 0..{}",
                    n_states.line,
                    n - 1
                ),
            ))
        }
    };
    in_range(initial.value, initial.line, "initial")?;
    let mut is_terminal = vec![false; n];
    if let Some(h) = &terminal {
        for &u in &h.value {
            in_range(u, h.line, "terminal")?;
            is_terminal[u] = true;
        }
    }
    if let Some(h) = &failure {
        for &u in &h.value {
            in_range(u, h.line, "failure")?;
            if is_terminal[u] {
                return Err(syntax(
                    h.line,
                    format!("state {u} is declared both terminal and failure"),
                ));
            }
        }
    }
    let is_failure = {
        let mut f = vec![false; n];
        if let Some(h) = &failure {
            h.value.iter().for_each(|&u| f[u] = true);
        }
        f
    };

    // Transitions, with the checks the constructor would do, so each error names its line.
    let n_labels = vocab.n_label_sets();
    let mut owner: Vec<Option<(usize, usize)>> = vec![None; n * n_labels]; // (line, to)
    let mut transitions = Vec::with_capacity(transition_lines.len());
    for &(line_no, line) in &transition_lines {
        let t = parse_transition(line, &vocab).map_err(|p| syntax(line_no, p))?;
        in_range(t.from, line_no, "source")?;
        in_range(t.to, line_no, "target")?;
        if is_terminal[t.from] || is_failure[t.from] {
            return Err(syntax(
                line_no,
                format!(
                    "state {} is {} (absorbing) and cannot have outgoing transitions",
                    t.from,
                    if is_terminal[t.from] {
                        "terminal"
                    } else {
                        "a failure sink"
                    }
                ),
            ));
        }
        for l in vocab.all_label_sets() {
            if !t.formula.eval(l) {
                continue;
            }
            let cell = &mut owner[t.from * n_labels + l.index()];
            if let Some((other_line, other_to)) = *cell {
                return Err(syntax(
                    line_no,
                    format!(
                        "nondeterministic: from state {} on label set {{{}}} this transition (to {}) and the one on line {other_line} (to {other_to}) both hold",
                        t.from,
                        vocab.format_labels(l),
                        t.to
                    ),
                ));
            }
            *cell = Some((line_no, t.to));
        }
        transitions.push(t);
    }

    RewardMachine::new(
        vocab,
        n,
        initial.value,
        &terminal.map(|h| h.value).unwrap_or_default(),
        &failure.map(|h| h.value).unwrap_or_default(),
        transitions,
    )
    .map_err(|error| RmFileError::Invalid {
        file: source.to_string(),
        error,
    })
}

/// Reads a reward-machine file.
pub fn read_rm(path: &Path) -> Result<RewardMachine, RmFileError> {
    let name = path.display().to_string();
    let text = crate::config_text::read_text_file(path).map_err(|error| RmFileError::Io {
        file: name.clone(),
        error,
    })?;
    parse_rm(&text, &name)
}

/// Writes a machine in the text format; [`parse_rm`] reads it back to an equal machine.
pub fn write_rm(rm: &RewardMachine) -> String {
    let v = rm.vocab();
    let list = |states: Vec<usize>| {
        states
            .iter()
            .map(|u| u.to_string())
            .collect::<Vec<_>>()
            .join(" ")
    };
    let mut out = String::new();
    // `write!` to a String cannot fail.
    let _ = writeln!(out, "# reward machine written by smirl");
    let _ = writeln!(out, "vocabulary: {v}");
    let _ = writeln!(out, "states: {}", rm.n_states());
    let _ = writeln!(out, "initial: {}", rm.initial());
    let _ = writeln!(out, "terminal: {}", list(rm.terminal_states()));
    let _ = writeln!(out, "failure: {}", list(rm.failure_states()));
    for t in rm.transitions() {
        let _ = writeln!(
            out,
            "({}, {}, '{}', {})",
            t.from,
            t.to,
            t.formula.display(v),
            t.reward
        );
    }
    out
}

/// Writes `rm` to `path` atomically: a temporary file in the same directory, then a rename,
/// so a crash never leaves a half-written machine under the final name.
pub fn save_rm(path: &Path, rm: &RewardMachine) -> io::Result<()> {
    crate::atomic_file::write_atomic(path, write_rm(rm).as_bytes())
}

fn strip_comment(line: &str) -> &str {
    match line.find('#') {
        Some(k) => &line[..k],
        None => line,
    }
}

fn parse_state(text: &str) -> Result<usize, String> {
    let t = text.trim();
    t.parse::<usize>().map_err(|_| {
        format!(
            "expected a state number (0, 1, 2, ...), found \"{}\"",
            quoted::text(t)
        )
    })
}

/// `(from, to, 'formula', reward)`.
fn parse_transition(line: &str, vocab: &Vocabulary) -> Result<Transition, String> {
    const SHAPE: &str = "(from, to, 'formula', reward)";
    let inner = line
        .strip_prefix('(')
        .and_then(|s| s.strip_suffix(')'))
        .ok_or_else(|| {
            format!(
                "expected a transition {SHAPE}, found \"{}\" (missing ')')",
                quoted::text(line)
            )
        })?;
    let (open, close) = match (inner.find('\''), inner.rfind('\'')) {
        (Some(a), Some(b)) if a < b => (a, b),
        _ => {
            return Err(format!(
                "expected a transition {SHAPE} with the formula in single quotes, found \"{}\"",
                quoted::text(line)
            ))
        }
    };
    let head: Vec<&str> = inner[..open].split(',').map(str::trim).collect();
    if head.len() != 3 || !head[2].is_empty() {
        return Err(format!(
            "expected 'from, to,' before the formula in {SHAPE}, found \"{}\"",
            quoted::text(inner[..open].trim())
        ));
    }
    let from = parse_state(head[0]).map_err(|e| format!("source: {e}"))?;
    let to = parse_state(head[1]).map_err(|e| format!("target: {e}"))?;
    let formula_text = &inner[open + 1..close];
    let formula = Formula::parse(formula_text, vocab).map_err(|e| e.to_string())?;
    let tail = inner[close + 1..].trim();
    let reward_text = tail.strip_prefix(',').map(str::trim).ok_or_else(|| {
        format!(
            "expected ', reward' after the formula in {SHAPE}, found \"{}\"",
            quoted::text(tail)
        )
    })?;
    let reward: f64 = reward_text
        .parse()
        .ok()
        .filter(|r: &f64| r.is_finite())
        .ok_or_else(|| {
            format!(
                "expected a finite reward number, found \"{}\"",
                quoted::text(reward_text)
            )
        })?;
    Ok(Transition {
        from,
        to,
        formula,
        reward,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    const OR_TEXT: &str = "# OR\nvocabulary: rgbyc\nstates: 3\ninitial: 0\nterminal: 2\n(0, 1, 'r|g', 0)\n(1, 2, 'b', 1) # done\n";

    #[test]
    fn parses_and_round_trips() {
        let rm = parse_rm(OR_TEXT, "or.txt").unwrap();
        assert_eq!(rm.n_states(), 3);
        assert_eq!(rm.terminal_states(), vec![2]);
        assert!(rm.failure_states().is_empty());
        let again = parse_rm(&write_rm(&rm), "again").unwrap();
        assert_eq!(again, rm);
    }

    #[test]
    fn errors_carry_file_and_line() {
        let e = parse_rm(&OR_TEXT.replace("'b'", "'x'"), "or.txt").unwrap_err();
        assert_eq!(e.line(), Some(7));
        let msg = e.to_string();
        assert!(msg.starts_with("or.txt:7:"), "{msg}");
        assert!(msg.contains("unknown proposition 'x'"), "{msg}");
    }
}
