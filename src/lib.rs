//! smirl — reward learning with structural motifs.
//!
//! Learns a reward machine (a finite automaton over labelled events) from demonstrations and
//! runs inverse RL on the product of that machine with the environment (SMIRL), next to the
//! baselines the paper compares against. Module layering:
//!
//! ```text
//! 1  mujoco (safe MuJoCo wrapper)   rm (reward machines: type, formats, product, LRM
//!                                       learning)   nn (MLP, Adam)   report (plots, tables)
//! 2  env (ReacherDelivery, OfficeWorld, labelling functions, tasks)
//! 3  rl (SAC, tabular solvers, replay buffer, counterfactual RM states)   log (MCAP)
//! 4  irl (the algorithms' pieces: Algo, apprenticeship, MaxEnt, f-IRL losses, KDE, kNN
//!        divergence, SMIRL's linear reward)
//! 5  pipeline (the experiments; `commands` serves the binaries)
//! ```
//!
//! A module imports only modules of lower layers (`tests/module_layering.rs` checks it).
//!
//! Where to start reading:
//! - **continuous SMIRL**: `pipeline/reacher_irl/smirl.rs` — learn the machine, annotate the
//!   demonstrations, then per iteration SAC on the product with counterfactual states,
//!   rollouts, feature expectations, reward step; **f-IRL and continuous MaxEnt**:
//!   `pipeline/reacher_irl/firl.rs`; the loop both run, top to bottom, is
//!   `pipeline/reacher_irl/irl_loop.rs`, each with its own reward update; what it calls is
//!   `pipeline/reacher_irl/episodes.rs` (the environment, an episode) and `agent_phases.rs`
//!   (the SAC phase, the rollouts), and what watches them (ground truth, logs, progress) `pipeline/reacher_irl/evaluation.rs`.
//! - **SAC**: `rl/sac/agent.rs` (one update, top to bottom) and `rl/sac/trainer.rs` (the
//!   training loop, rewards computed when a batch is sampled).
//! - **Office SMIRL, MaxEnt and apprenticeship**: `pipeline/office.rs` over `irl/tabular`.
//! - **LRM**: `rm/lrm/mod.rs` (the Tabu search in `rm/lrm/search.rs`).
//! - **The binaries** (`src/bin/reacher.rs`, `src/bin/office.rs`) only parse arguments and
//!   call `pipeline::commands`.
//!
//! `atomic_file` (the atomic write every saved file goes through), `input_file` (every input
//! file is read under a size limit), `config_text` (the limit of text inputs, line of a
//! TOML key for errors), `output` (where a command may write: output directories and files
//! are checked, never replaced unless ours),
//! `assets` (the model, reward machines and committed experts built into the binaries),
//! `quoted` (input quoted readably in errors) and `short_float` (serde helpers for readable
//! configs) import nothing of the crate but each other and serve every layer.
//!
//! `unsafe` is denied everywhere but in four places, each allowed by name: the MuJoCo wrapper
//! (`mujoco`, the FFI), the `sgemm` call (`nn::gemm`), the AVX-512 product kernel
//! (`nn::gemm_unpacked`) and restoring SIGPIPE's default action
//! (`pipeline::commands::exit_quietly_on_closed_pipe`).

#![deny(unsafe_code)]

pub mod assets;
pub mod atomic_file;
pub mod config_text;
pub mod env;
pub mod input_file;
pub mod irl;
pub mod log;
#[allow(unsafe_code)]
pub mod mujoco;
pub mod nn;
pub mod output;
pub mod pipeline;
pub mod quoted;
pub mod report;
pub mod rl;
pub mod rm;
pub mod short_float;

/// Git commit the crate was built from, empty when unknown.
pub const GIT_COMMIT: &str = env!("SMIRL_GIT_COMMIT");
