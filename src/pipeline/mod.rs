//! End-to-end pipelines behind the binaries (experts, demonstrations, IRL, evaluation).
pub mod expert;
pub mod office;
