//! The records of a `reacher --task` run: what its run directory stores (`prepare.json`,
//! `jobs/<algo>_seed<S>.json`, the directory read back) and what a finished run reports, with
//! the error a run fails with and the file writer the run and its reports share.

use super::config::IrlRunConfig;
use super::evaluation::FinalSetScore;
use super::expert_data::ExpertData;
use super::final_policy::FinalPolicy;
use super::Algo;
use crate::atomic_file::write_atomic;
use crate::env::reacher_task::{BranchTally, ReacherTask};
use crate::rm::RewardMachine;
use std::path::{Path, PathBuf};

// Only the doc links of `AlgoSummary` use it.
#[cfg(doc)]
use crate::env::reacher_task::Branch;

/// A run that could not start (bad input: nothing written) or failed while running.
#[derive(Debug, thiserror::Error)]
pub enum PipelineError {
    /// Bad input, found before anything was written.
    #[error("{0}")]
    Usage(String),
    #[error("{0}")]
    Run(String),
}

/// A plan (`prepare.json`) that names an algorithm this binary does not know.
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct UnknownAlgo(pub String);

/// Facts about the learned machine.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct RmFacts {
    pub learned_states: usize,
    pub learned_reachable: usize,
    pub perfect_states: usize,
    /// Along the demonstrations, the perfect machine's state is a function of the learned one.
    pub refines_perfect: bool,
    pub ambiguous_steps: usize,
    pub total_steps: usize,
    pub lrm_cost: f64,
    pub lrm_secs: f64,
}

/// Final numbers of one algorithm over seeds.
#[derive(Clone, Debug, serde::Serialize)]
pub struct AlgoSummary {
    pub algo: String,
    pub seeds: usize,
    pub final_success_mean: f64,
    pub final_success_std: f64,
    pub final_return_mean: f64,
    pub final_return_std: f64,
    /// Conditional tasks: final success on each branch's evaluation episodes, mean and std
    /// over seeds, in [`Branch::ALL`] order.
    pub final_branch_success: Option<[(f64, f64); 2]>,
    /// Jobs with a final phase: the reported (chosen) policy's success (the lower
    /// branch for a conditional task), mean and std over seeds.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub final_policy_success: Option<(f64, f64)>,
    /// ... and per branch of a conditional task, in [`Branch::ALL`] order.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub final_policy_branch_success: Option<[(f64, f64); 2]>,
    /// The final phase's candidate drawn at random (the choice's yardstick), as
    /// `final_policy_success`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub random_policy_success: Option<(f64, f64)>,
    /// ... and per branch of a conditional task.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub random_policy_branch_success: Option<[(f64, f64); 2]>,
    /// Mean wall time of a job (seconds).
    pub job_secs_mean: f64,
}

/// What a finished run reports.
#[derive(Clone, Debug, serde::Serialize)]
pub struct RunSummary {
    pub out: PathBuf,
    pub task: String,
    pub demos_kept: usize,
    pub demos_generated: usize,
    /// Conditional tasks: the kept demonstrations per branch.
    pub demo_branches: Option<BranchTally>,
    pub rm: Option<RmFacts>,
    /// smirl-paper's machine, when the run has that algorithm.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub rm_paper: Option<RmFacts>,
    pub algos: Vec<AlgoSummary>,
    pub wall_secs: f64,
}

pub(super) fn io(path: &Path, e: impl std::fmt::Display) -> PipelineError {
    PipelineError::Run(format!("{}: {e}", path.display()))
}

pub(super) fn write_file(path: &Path, text: &str) -> Result<(), PipelineError> {
    write_atomic(path, text.as_bytes()).map_err(|e| io(path, e))
}

/// What `reacher prepare` decided and measured, stored as `prepare.json` in the run directory.
/// It is written last, so its presence means the directory is prepared.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct Prepared {
    pub task: ReacherTask,
    /// Algorithm names, in job order.
    pub algos: Vec<String>,
    /// Job seeds, in job order.
    pub seeds: Vec<u64>,
    /// Base seed (demonstrations and LRM).
    pub seed: u64,
    pub demos_kept: usize,
    pub demos_generated: usize,
    pub demo_branches: Option<BranchTally>,
    pub rm: Option<RmFacts>,
    /// smirl-paper's machine, when the run has that algorithm.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rm_paper: Option<RmFacts>,
    pub prepare_secs: f64,
    pub git_commit: String,
}

impl Prepared {
    /// The (algorithm, seed) jobs, in the order `--index` counts them: algorithms outer,
    /// seeds inner.
    pub fn jobs(&self) -> Result<Vec<(Algo, u64)>, UnknownAlgo> {
        let algos = self
            .algos
            .iter()
            .map(|a| Algo::parse_in(a, &Algo::REACHER_NAMED))
            .collect::<Result<Vec<_>, _>>()
            .map_err(UnknownAlgo)?;
        Ok(algos
            .iter()
            .flat_map(|&a| self.seeds.iter().map(move |&s| (a, s)))
            .collect())
    }
}

/// A prepared run directory, read back: everything a job needs.
pub struct PreparedRun {
    pub dir: PathBuf,
    pub prepared: Prepared,
    pub config: IrlRunConfig,
    pub perfect: RewardMachine,
    /// SMIRL's (and smirl-smooth's) learned machine.
    pub learned: Option<RewardMachine>,
    /// The demonstrations, annotated with `learned`'s states when there is one.
    pub expert: ExpertData,
    /// smirl-paper's learned machine and the demonstrations annotated with it.
    pub paper: Option<(RewardMachine, ExpertData)>,
}

/// One finished job as `jobs/<algo>_seed<S>.json` (written last by the job: its presence
/// means the job is done).
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct JobRecord {
    pub algo: String,
    pub seed: u64,
    pub rows: Vec<super::MetricsRow>,
    /// The final phase (`final_policy.csv`); absent in jobs without one (`smirl-paper`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub final_policy: Option<FinalPolicy>,
    /// The loop's own final policy (after its last iteration) on the final set
    /// ([`super::evaluation::final_set_episodes`]); `None` in records written before it
    /// existed.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub loop_final_set: Option<FinalSetScore>,
    pub wall_secs: f64,
}

impl JobRecord {
    /// The success rate the job reports: its final policy's where it has one, else the
    /// last IRL iteration's. The two differ when the final phase picked a checkpoint over a
    /// co-trained policy that dipped at the last iteration.
    pub fn reported_success(&self) -> f64 {
        match &self.final_policy {
            Some(final_policy) => final_policy.chosen().success_rate,
            None => self.rows.last().map_or(0.0, |r| r.success_rate),
        }
    }
}

/// A job's record keeps everything of its result but the reward trace (written beside it).
impl From<super::JobResult> for JobRecord {
    fn from(result: super::JobResult) -> Self {
        JobRecord {
            algo: result.algo.name().into(),
            seed: result.seed,
            rows: result.rows,
            final_policy: result.final_policy,
            loop_final_set: result.loop_final_set,
            wall_secs: result.wall_secs,
        }
    }
}
