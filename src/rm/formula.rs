//! Propositional formulas that guard reward-machine transitions.
//!
//! Grammar (precedence `!` > `&` > `|`):
//! ```text
//! formula := conj ('|' conj)*
//! conj    := unary ('&' unary)*
//! unary   := '!' unary | 'True' | 'False' | PROP | '(' formula ')'
//! ```
//! A proposition is one character of the vocabulary (see [`super::labels`]); an unknown one
//! is an error, never a silent `false`.

use super::labels::{is_prop_char, LabelSet, Vocabulary};
use std::fmt;

#[derive(Clone, Debug, PartialEq, Eq, Hash)]
pub enum Formula {
    True,
    False,
    /// A proposition, by its bit index in the vocabulary.
    Prop(usize),
    Not(Box<Formula>),
    And(Vec<Formula>),
    Or(Vec<Formula>),
}

/// A formula that could not be parsed: what was expected and at which character.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("in formula \"{}\" at column {column}: {problem}", crate::quoted::text(.text))]
pub struct FormulaError {
    pub text: String,
    /// 1-based character column in `text`.
    pub column: usize,
    pub problem: String,
}

impl Formula {
    /// Parses `text` against `vocab`.
    pub fn parse(text: &str, vocab: &Vocabulary) -> Result<Formula, FormulaError> {
        let mut p = Parser {
            chars: text.chars().collect(),
            pos: 0,
            depth: 0,
            vocab,
            text,
        };
        let f = p.disjunction()?;
        p.skip_ws();
        if p.pos < p.chars.len() {
            return Err(p.error(format!("unexpected '{}'", p.chars[p.pos])));
        }
        Ok(f)
    }

    /// Truth value under a label set.
    pub fn eval(&self, labels: LabelSet) -> bool {
        match self {
            Formula::True => true,
            Formula::False => false,
            Formula::Prop(i) => labels.contains(*i),
            Formula::Not(f) => !f.eval(labels),
            Formula::And(fs) => fs.iter().all(|f| f.eval(labels)),
            Formula::Or(fs) => fs.iter().any(|f| f.eval(labels)),
        }
    }

    /// The conjunction that is true on exactly one label set: every proposition of the
    /// vocabulary appears, negated or not. Used for machines learned over observed labels.
    pub fn exactly(labels: LabelSet, vocab: &Vocabulary) -> Formula {
        if vocab.is_empty() {
            return Formula::True;
        }
        Formula::And(
            (0..vocab.len())
                .map(|i| {
                    if labels.contains(i) {
                        Formula::Prop(i)
                    } else {
                        Formula::Not(Box::new(Formula::Prop(i)))
                    }
                })
                .collect(),
        )
    }

    /// Writes the formula with the vocabulary's proposition names and as few parentheses as
    /// the precedence needs; [`Formula::parse`] reads it back to the same tree.
    pub fn display<'a>(&'a self, vocab: &'a Vocabulary) -> impl fmt::Display + 'a {
        Shown { f: self, vocab }
    }
}

struct Shown<'a> {
    f: &'a Formula,
    vocab: &'a Vocabulary,
}

impl fmt::Display for Shown<'_> {
    fn fmt(&self, out: &mut fmt::Formatter<'_>) -> fmt::Result {
        write_formula(self.f, self.vocab, 0, out)
    }
}

/// `level`: 0 = inside `|` or top, 1 = inside `&`, 2 = under `!`.
fn write_formula(
    f: &Formula,
    v: &Vocabulary,
    level: u8,
    out: &mut fmt::Formatter<'_>,
) -> fmt::Result {
    match f {
        Formula::True => write!(out, "True"),
        Formula::False => write!(out, "False"),
        Formula::Prop(i) => write!(out, "{}", v.props()[*i]),
        Formula::Not(g) => {
            write!(out, "!")?;
            write_formula(g, v, 2, out)
        }
        Formula::And(fs) | Formula::Or(fs) => {
            let (sep, own) = if matches!(f, Formula::And(_)) {
                ('&', 1)
            } else {
                ('|', 0)
            };
            let paren = level > own || fs.len() < 2;
            if paren {
                write!(out, "(")?;
            }
            for (k, g) in fs.iter().enumerate() {
                if k > 0 {
                    write!(out, "{sep}")?;
                }
                // A nested operator of the same kind keeps its parentheses so that the tree
                // (not just the meaning) survives a round trip.
                let inner = if std::mem::discriminant(g) == std::mem::discriminant(f) {
                    2
                } else {
                    own + 1
                };
                write_formula(g, v, inner, out)?;
            }
            if paren {
                write!(out, ")")?;
            }
            Ok(())
        }
    }
}

/// Deepest nesting of `!` and parentheses a formula may have (the parser and every
/// recursive walk of the tree recurse once per level).
pub const MAX_DEPTH: usize = 64;

struct Parser<'a> {
    chars: Vec<char>,
    pos: usize,
    /// Current nesting of `!` and `(`.
    depth: usize,
    vocab: &'a Vocabulary,
    text: &'a str,
}

impl Parser<'_> {
    fn error(&self, problem: String) -> FormulaError {
        FormulaError {
            text: self.text.to_string(),
            column: self.pos + 1,
            problem,
        }
    }

    fn skip_ws(&mut self) {
        while self.pos < self.chars.len() && self.chars[self.pos].is_whitespace() {
            self.pos += 1;
        }
    }

    fn peek(&mut self) -> Option<char> {
        self.skip_ws();
        self.chars.get(self.pos).copied()
    }

    fn disjunction(&mut self) -> Result<Formula, FormulaError> {
        let mut terms = vec![self.conjunction()?];
        while self.peek() == Some('|') {
            self.pos += 1;
            terms.push(self.conjunction()?);
        }
        Ok(if terms.len() == 1 {
            terms.pop().unwrap()
        } else {
            Formula::Or(terms)
        })
    }

    fn conjunction(&mut self) -> Result<Formula, FormulaError> {
        let mut terms = vec![self.unary()?];
        while self.peek() == Some('&') {
            self.pos += 1;
            terms.push(self.unary()?);
        }
        Ok(if terms.len() == 1 {
            terms.pop().unwrap()
        } else {
            Formula::And(terms)
        })
    }

    fn unary(&mut self) -> Result<Formula, FormulaError> {
        if self.depth >= MAX_DEPTH {
            return Err(self.error(format!(
                "nested more than {MAX_DEPTH} deep ('!' and parentheses)"
            )));
        }
        self.depth += 1;
        let f = self.unary_inner();
        self.depth -= 1;
        f
    }

    fn unary_inner(&mut self) -> Result<Formula, FormulaError> {
        match self.peek() {
            None => {
                Err(self
                    .error("expected a proposition, '!', '(' or True/False, found the end".into()))
            }
            Some('!') => {
                self.pos += 1;
                Ok(Formula::Not(Box::new(self.unary()?)))
            }
            Some('(') => {
                self.pos += 1;
                let f = self.disjunction()?;
                if self.peek() != Some(')') {
                    return Err(self.error("expected ')'".into()));
                }
                self.pos += 1;
                // `(a)` and `(a&b)` parse to the bare inner tree; only a parenthesised
                // single-element list could not come back, and the parser never makes one.
                Ok(f)
            }
            Some(_) if self.keyword("True") => Ok(Formula::True),
            Some(_) if self.keyword("False") => Ok(Formula::False),
            Some(c) if is_prop_char(c) => match self.vocab.index_of(c) {
                Ok(i) => {
                    self.pos += 1;
                    Ok(Formula::Prop(i))
                }
                Err(e) => Err(self.error(e.to_string())),
            },
            Some(c) => Err(self.error(format!(
                "expected a proposition, '!', '(' or True/False, found '{}'",
                crate::quoted::text(&c.to_string())
            ))),
        }
    }

    fn keyword(&mut self, word: &str) -> bool {
        let w: Vec<char> = word.chars().collect();
        let end = self.pos + w.len();
        let matches = self.chars.get(self.pos..end) == Some(&w[..])
            && !self
                .chars
                .get(end)
                .is_some_and(|c| c.is_ascii_alphanumeric());
        if matches {
            self.pos = end;
        }
        matches
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn v() -> Vocabulary {
        Vocabulary::new("rgbyc")
    }

    #[test]
    fn truth_tables() {
        let v = v();
        type Truth = fn(bool, bool) -> bool;
        let cases: &[(&str, Truth)] = &[
            ("r&g", |a, b| a && b),
            ("r|g", |a, b| a || b),
            ("!r", |a, _| !a),
            ("r&!g", |a, b| a && !b),
            ("!(r|g)", |a, b| !(a || b)),
            ("True", |_, _| true),
            ("False", |_, _| false),
        ];
        for (text, truth) in cases {
            let f = Formula::parse(text, &v).unwrap();
            for bits in 0..4u32 {
                let (r, g) = (bits & 1 == 1, bits & 2 == 2);
                assert_eq!(f.eval(LabelSet(bits)), truth(r, g), "{text} on r={r} g={g}");
            }
        }
    }

    #[test]
    fn precedence_not_and_or() {
        let v = v();
        // r | g & !b  ==  r | (g & (!b))
        let f = Formula::parse("r | g & !b", &v).unwrap();
        for bits in 0..8u32 {
            let (r, g, b) = (bits & 1 == 1, bits & 2 == 2, bits & 4 == 4);
            assert_eq!(f.eval(LabelSet(bits)), r || (g && !b));
        }
    }

    #[test]
    fn display_round_trips() {
        let v = v();
        for text in [
            "r&g",
            "r|g&!b",
            "(r|g)&!c",
            "!(r&g)",
            "True",
            "((r|g)|b)",
            "y&!c&!(r|g)",
        ] {
            let f = Formula::parse(text, &v).unwrap();
            let shown = f.display(&v).to_string();
            assert_eq!(Formula::parse(&shown, &v).unwrap(), f, "{text} -> {shown}");
        }
        assert_eq!(
            Formula::parse("(r|g)&!c", &v)
                .unwrap()
                .display(&v)
                .to_string(),
            "(r|g)&!c"
        );
    }

    #[test]
    fn errors_name_the_problem() {
        let v = v();
        let e = Formula::parse("r&x", &v).unwrap_err();
        assert_eq!(e.column, 3);
        assert!(e.problem.contains("unknown proposition 'x'"), "{e}");
        assert!(Formula::parse("r&", &v)
            .unwrap_err()
            .problem
            .contains("end"));
        assert!(Formula::parse("(r", &v)
            .unwrap_err()
            .problem
            .contains("')'"));
        assert!(Formula::parse("r g", &v).is_err());
    }

    #[test]
    fn exactly_is_true_on_one_set() {
        let v = v();
        let target = v.parse_labels("rc").unwrap();
        let f = Formula::exactly(target, &v);
        for l in v.all_label_sets() {
            assert_eq!(f.eval(l), l == target);
        }
    }
}
