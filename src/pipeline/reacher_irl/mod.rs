//! `reacher --task`: the paper's continuous experiment (section 4.3, figure 7) — SMIRL and the
//! baselines (continuous MaxEnt IRL, f-IRL fkl/rkl/js) on ReacherDelivery, evaluated on the
//! ground-truth task at every IRL iteration.
//!
//! Phases of a run ([`run::run_pipeline`]):
//! 1. **Demonstrations** ([`demos`]): the task's cached SAC expert (the paper) or the scripted
//!    controller; episodes end at the task's goal. Failed demonstrations are dropped.
//! 2. **Reward machine** (SMIRL only, [`smirl::learn_machine`], [`smirl::annotate`]): LRM's
//!    Tabu search on the demos' label traces, without rewards, then every expert observation
//!    o_t is annotated with the learned state u_{t−1} its labels are read in. The run reports
//!    the learned machine's size and whether it refines the perfect one along the demos
//!    (`rm::equiv::refines`).
//! 3. **IRL**: one job per (algorithm, seed) ([`job::run_job`]) on a pool of worker threads,
//!    each algorithm's loop in one file — [`smirl::train`] (SAC on ReacherDelivery × learned
//!    RM, δ_r(u, o) = w_uᵀ φ(o); `smirl` uses the paper's φ = labels, `smirl-smooth` the
//!    documented smooth variant φ_k = exp(−d_k²/2σ²), reported as a separate algorithm, never
//!    in place of `smirl`) and [`firl::train`] (continuous MaxEnt and f-IRL fkl/rkl/js: SAC on
//!    the plain 17-dim observation, a (64, 64) reward net on the fingertip clamped ±10). What
//!    every loop shares is in [`episodes`] (the environment, an episode, the SAC phase, the
//!    rollouts); [`evaluation`] watches each job from outside (ground truth after every
//!    iteration, logs, progress).
//! 4. **Reports** ([`run`]): metrics CSV, mean ± std plots over seeds, learned RM (text +
//!    DOT), reward parameters, MCAP logs, a summary table. Everything is written into
//!    `<out>.partial` and renamed to `<out>` at the end.

pub mod config;
pub mod demos;
pub mod episodes;
pub mod evaluation;
pub mod firl;
pub mod job;
pub mod run;
pub mod smirl;

pub use config::{DemoPadding, DemoSource, IrlConfigError, IrlRunConfig};
pub use episodes::AgentBatch;
pub use job::{reward_lr, run_job, Coefficients, ExpertData, JobResult, MetricsRow};
pub use run::{run_pipeline, PipelineError, RunObserver, RunRequest, RunSummary};

use crate::irl::firl::Divergence;
use std::fmt;
use std::str::FromStr;

/// An IRL algorithm of the comparison.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Algo {
    /// SMIRL with the paper's label features.
    Smirl,
    /// SMIRL with smooth distance features (documented variant).
    SmirlSmooth,
    /// Continuous MaxEnt IRL.
    MaxEnt,
    /// f-IRL, forward KL.
    Fkl,
    /// f-IRL, reverse KL.
    Rkl,
    /// f-IRL, Jensen–Shannon.
    Js,
}

impl Algo {
    pub const ALL: [Algo; 6] = [
        Algo::Smirl,
        Algo::SmirlSmooth,
        Algo::MaxEnt,
        Algo::Fkl,
        Algo::Rkl,
        Algo::Js,
    ];

    /// The default set of `reacher --task` (README.md, "ReacherDelivery IRL").
    pub const DEFAULT: [Algo; 4] = [Algo::Smirl, Algo::SmirlSmooth, Algo::MaxEnt, Algo::Fkl];

    pub fn name(self) -> &'static str {
        match self {
            Algo::Smirl => "smirl",
            Algo::SmirlSmooth => "smirl-smooth",
            Algo::MaxEnt => "maxent",
            Algo::Fkl => "fkl",
            Algo::Rkl => "rkl",
            Algo::Js => "js",
        }
    }

    /// SMIRL variants act on the product with a learned machine.
    pub fn uses_rm(self) -> bool {
        matches!(self, Algo::Smirl | Algo::SmirlSmooth)
    }

    /// The f-divergence of an f-IRL algorithm.
    pub fn divergence(self) -> Option<Divergence> {
        match self {
            Algo::Fkl => Some(Divergence::Fkl),
            Algo::Rkl => Some(Divergence::Rkl),
            Algo::Js => Some(Divergence::Js),
            _ => None,
        }
    }

    /// Parses a comma-separated list (`all` = every algorithm); duplicates are dropped.
    pub fn parse_list(s: &str) -> Result<Vec<Algo>, String> {
        let mut out = Vec::new();
        for part in s.split(',').map(str::trim) {
            let algos: Vec<Algo> = if part == "all" {
                Algo::ALL.to_vec()
            } else {
                vec![part.parse()?]
            };
            for a in algos {
                if !out.contains(&a) {
                    out.push(a);
                }
            }
        }
        Ok(out)
    }
}

impl fmt::Display for Algo {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for Algo {
    type Err = String;
    fn from_str(s: &str) -> Result<Algo, String> {
        Algo::ALL
            .into_iter()
            .find(|a| a.name() == s)
            .ok_or_else(|| {
                format!(
                    "unknown algorithm '{s}' (expected one of: smirl, smirl-smooth, maxent, fkl, \
                     rkl, js, all)"
                )
            })
    }
}
