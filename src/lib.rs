//! smirl — reward learning with structural motifs.
//!
//! Learns a reward machine (a finite automaton over labelled events) from demonstrations and
//! runs inverse RL on the product of that machine with the environment (SMIRL), next to the
//! baselines the paper compares against. Module layering (a lower layer never imports a
//! higher one):
//!
//! ```text
//! mujoco (safe MuJoCo wrapper)     rm (reward machines: type, formats, product, learning)
//!            \                      /
//!             env (ReacherDelivery, OfficeWorld, labelling functions)
//!                        |
//!  nn (MLP, Adam)  ->  rl (SAC, tabular solvers, replay buffer)
//!                        |
//!                  irl (apprenticeship, maxent, f-IRL, kde, smirl)
//!                        |
//!     log (MCAP)  ->  pipeline  ->  report (plots, tables)
//! ```
//!
//! `atomic_file` (the atomic write every saved file goes through), `config_text` (size
//! limit of text inputs, line of a TOML key for errors), `output` (where a command
//! may write: output directories and files are checked, never replaced unless ours),
//! `assets` (the model, reward machines and committed experts built into the binaries) and
//! `short_float` (serde helpers for readable configs) import nothing of the crate and serve
//! every layer.

pub mod assets;
pub mod atomic_file;
pub mod config_text;
pub mod env;
pub mod irl;
pub mod log;
pub mod mujoco;
pub mod nn;
pub mod output;
pub mod pipeline;
pub mod report;
pub mod rl;
pub mod rm;
pub mod short_float;

/// Git commit the crate was built from, empty when unknown.
pub const GIT_COMMIT: &str = env!("SMIRL_GIT_COMMIT");
