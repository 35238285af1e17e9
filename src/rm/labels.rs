//! Propositions and label sets.
//!
//! A labelling function maps an observation to the set of propositions true in it. Each
//! proposition is one character (`r`, `g`, `A`, `*`, …) so that label sets print compactly
//! (`"cm"`, or `""` for the empty set) and formulas read like the QRM reward-machine files.
//! A label set is a bit mask over the vocabulary's propositions.

use std::fmt;

/// At most this many propositions per vocabulary (the label set is a `u32` bit mask, and
/// the reward machine's transition table has `2^n` columns).
pub const MAX_PROPS: usize = 12;

/// A set of true propositions, as a bit mask over a [`Vocabulary`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct LabelSet(pub u32);

impl LabelSet {
    pub const EMPTY: LabelSet = LabelSet(0);

    pub fn contains(self, prop: usize) -> bool {
        self.0 >> prop & 1 == 1
    }

    pub fn with(self, prop: usize) -> LabelSet {
        LabelSet(self.0 | 1 << prop)
    }

    pub fn is_empty(self) -> bool {
        self.0 == 0
    }

    /// Index of this set in a table with one column per label set.
    pub fn index(self) -> usize {
        self.0 as usize
    }
}

/// Error for a proposition that the vocabulary does not know.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("unknown proposition '{prop}' (the vocabulary is \"{vocabulary}\")")]
pub struct UnknownProposition {
    pub prop: char,
    pub vocabulary: String,
}

/// Why text cannot be a vocabulary.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum VocabularyError {
    #[error("{count} propositions, at most {MAX_PROPS}")]
    TooMany { count: usize },
    #[error("'{}' cannot name a proposition", crate::quoted::text(&.0.to_string()))]
    Reserved(char),
    #[error("proposition '{0}' appears twice")]
    Twice(char),
}

/// The ordered set of propositions of a domain.
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
pub struct Vocabulary {
    props: Vec<char>,
}

impl Vocabulary {
    /// A vocabulary from its propositions, in bit order.
    ///
    /// # Panics
    /// On a duplicate, on more than [`MAX_PROPS`] propositions, or on a character that
    /// formulas reserve (whitespace, `&|!()`, `#`, `,`). Vocabularies are fixed by the code of
    /// a domain, so this is a programming error, not bad input; use [`Vocabulary::parse`]
    /// for text from a file.
    pub fn new(props: &str) -> Vocabulary {
        Vocabulary::parse(props).unwrap_or_else(|e| panic!("invalid vocabulary {props:?}: {e}"))
    }

    /// A vocabulary from text such as `"rgbyc"`, checked.
    pub fn parse(props: &str) -> Result<Vocabulary, VocabularyError> {
        let props: Vec<char> = props.chars().collect();
        if props.len() > MAX_PROPS {
            return Err(VocabularyError::TooMany { count: props.len() });
        }
        for (i, &p) in props.iter().enumerate() {
            if !is_prop_char(p) {
                return Err(VocabularyError::Reserved(p));
            }
            if props[..i].contains(&p) {
                return Err(VocabularyError::Twice(p));
            }
        }
        Ok(Vocabulary { props })
    }

    pub fn len(&self) -> usize {
        self.props.len()
    }

    pub fn is_empty(&self) -> bool {
        self.props.is_empty()
    }

    /// Number of distinct label sets, `2^len`.
    pub fn n_label_sets(&self) -> usize {
        1 << self.props.len()
    }

    pub fn props(&self) -> &[char] {
        &self.props
    }

    /// Bit index of a proposition.
    pub fn index_of(&self, prop: char) -> Result<usize, UnknownProposition> {
        self.props
            .iter()
            .position(|&p| p == prop)
            .ok_or_else(|| UnknownProposition {
                prop,
                vocabulary: self.to_string(),
            })
    }

    /// Parses a label set written as its true propositions, e.g. `"cm"`; `""` is the empty set.
    pub fn parse_labels(&self, text: &str) -> Result<LabelSet, UnknownProposition> {
        text.chars()
            .try_fold(LabelSet::EMPTY, |set, c| Ok(set.with(self.index_of(c)?)))
    }

    /// Writes a label set as its true propositions in vocabulary order.
    pub fn format_labels(&self, labels: LabelSet) -> String {
        self.props
            .iter()
            .enumerate()
            .filter(|&(i, _)| labels.contains(i))
            .map(|(_, &p)| p)
            .collect()
    }

    /// Every label set of this vocabulary, in index order.
    pub fn all_label_sets(&self) -> impl Iterator<Item = LabelSet> {
        (0..self.n_label_sets() as u32).map(LabelSet)
    }
}

impl fmt::Display for Vocabulary {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        self.props.iter().try_for_each(|p| write!(f, "{p}"))
    }
}

/// Characters that may name a proposition: anything printable that formulas and the RM text
/// format do not reserve.
pub fn is_prop_char(c: char) -> bool {
    c.is_ascii_graphic() && !matches!(c, '&' | '|' | '!' | '(' | ')' | '#' | ',' | '\'' | '"')
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parse_and_format_round_trip() {
        let v = Vocabulary::new("ABCDcmo*");
        let l = v.parse_labels("c*").unwrap();
        assert!(l.contains(4) && l.contains(7) && !l.contains(0));
        assert_eq!(v.format_labels(l), "c*");
        assert_eq!(v.parse_labels("").unwrap(), LabelSet::EMPTY);
        assert_eq!(v.n_label_sets(), 256);
    }

    #[test]
    fn unknown_proposition_is_an_error() {
        let v = Vocabulary::new("rgbyc");
        let e = v.parse_labels("rx").unwrap_err();
        assert_eq!(e.prop, 'x');
        assert!(e.to_string().contains("rgbyc"));
    }

    #[test]
    fn bad_vocabularies_are_rejected() {
        assert_eq!(Vocabulary::parse("aa"), Err(VocabularyError::Twice('a')));
        assert_eq!(Vocabulary::parse("a&"), Err(VocabularyError::Reserved('&')));
        assert_eq!(
            Vocabulary::parse("abcdefghijklm"),
            Err(VocabularyError::TooMany { count: 13 })
        );
        assert_eq!(
            VocabularyError::Twice('a').to_string(),
            "proposition 'a' appears twice"
        );
    }
}
