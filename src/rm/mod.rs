//! Reward machines: labels and formulas, the machine type, and (in submodules) text/DOT
//! formats, the product with an environment, LRM learning and equivalence checking.

pub mod dot;
pub mod equiv;
pub mod format;
pub mod formula;
pub mod labels;
pub mod language;
pub mod lrm;
pub mod machine;
pub mod perfect;
pub mod product;
pub mod transform;

pub use formula::{Formula, FormulaError};
pub use labels::{LabelSet, UnknownProposition, Vocabulary, VocabularyError, MAX_PROPS};
pub use machine::{RewardMachine, RmError, Transition};
