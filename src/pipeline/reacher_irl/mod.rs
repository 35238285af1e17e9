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
//!    each algorithm in one file — [`smirl::train`] (SAC on ReacherDelivery × learned
//!    RM, δ_r(u, o) = w_uᵀ φ(o); `smirl` uses the paper's φ = labels, `smirl-smooth` the
//!    documented smooth variant φ_k = exp(−d_k²/2σ²), reported as a separate algorithm, never
//!    in place of `smirl`) and [`firl::train`] (continuous MaxEnt and f-IRL fkl/rkl/js: SAC on
//!    the plain 17-dim observation, a (64, 64) reward net on the fingertip clamped ±10), each
//!    the loop of [`irl_loop`] (SAC, rollouts, reward update, evaluation, per iteration) with
//!    its own reward. What every loop shares is in [`episodes`] (the environment, an episode),
//!    [`agent_phases`] (the SAC phase, the rollouts) and [`iteration`] (what an iteration
//!    hands on); [`evaluation`] watches each job from outside (ground truth after every
//!    iteration, logs, progress); every job but `smirl-paper`'s ends with [`final_policy`], SAC
//!    on the final reward held fixed and the policy of highest learned return reported beside
//!    the loop's.
//! 4. **Reports** ([`reports`], from the jobs' [`records`]): metrics CSV, mean ± std plots
//!    over seeds, a summary table; beside them ([`run`]) the learned RM (text + DOT), reward
//!    parameters and MCAP logs. Everything is written into `<out>.partial` and renamed to
//!    `<out>` at the end.

pub mod agent_phases;
pub mod config;
pub mod demos;
pub mod episodes;
pub mod evaluation;
pub mod expert_data;
pub mod final_policy;
pub mod firl;
mod irl_loop;
pub mod iteration;
pub mod job;
pub mod lockstep;
pub mod records;
pub mod reports;
pub mod retrain;
pub mod run;
pub mod smirl;

pub use config::{DemoSource, IrlConfigError, IrlRunConfig, SmirlMachine};
pub use episodes::AgentBatch;
pub use expert_data::ExpertData;
pub use iteration::{Coefficients, MetricsRow};
pub use job::{run_job, JobResult};
pub use run::{run_pipeline, PipelineError, RunObserver, RunRequest, RunSummary};

/// The algorithms of the comparison (`Algo::REACHER` runs here).
pub use crate::irl::Algo;
