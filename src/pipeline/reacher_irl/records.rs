//! The records of a `reacher --task` run: what its run directory stores (`prepare.json`,
//! `jobs/<algo>_seed<S>.json`, the directory read back) and what a finished run reports, with
//! the error a run fails with and the file writer the run and its reports share.

use super::config::{IrlConfigError, IrlRunConfig};
use super::demos::DemoError;
use super::evaluation::FinalSetScore;
use super::expert_data::ExpertData;
use super::final_policy::FinalPolicy;
use super::job::JobError;
use super::smirl::MachineError;
use super::Algo;
use crate::atomic_file::write_atomic;
use crate::env::reacher::ConfigError;
use crate::env::reacher_task::{BranchTally, ReacherTask};
use crate::irl::algo::UnknownAlgorithm;
use crate::log::LogError;
use crate::nn::codec::CodecError;
use crate::output::OutputError;
use crate::pipeline::reacher_expert::ExpertError;
use crate::rm::equiv::EquivError;
use crate::rm::format::RmFileError;
use crate::rm::lrm::LrmError;
use crate::rm::RewardMachine;
use std::path::{Path, PathBuf};

// Only the doc links of `AlgoSummary` use it.
#[cfg(doc)]
use crate::env::reacher_task::Branch;

/// A run that could not start (bad input: nothing written, [`PipelineError::is_usage`]) or
/// failed while running.
#[derive(Debug, thiserror::Error)]
pub enum PipelineError {
    #[error("no algorithm selected")]
    NoAlgorithm,
    #[error("--seeds must be at least 1")]
    NoSeeds,
    #[error("--seeds {seeds} is more than the limit of {limit} seeds per run")]
    TooManySeeds { seeds: u64, limit: u64 },
    #[error("--seed {seed} + --seeds {seeds} overflows")]
    SeedOverflow { seed: u64, seeds: u64 },
    /// The run's config (the request's, or a run directory's `config.toml`).
    #[error(transparent)]
    Config(IrlConfigError),
    #[error(
        "config: smirl_machine = \"task\" gives {control} the task's own machine; the product \
         controls read the learned one (use \"learned\" or \"one_state\")"
    )]
    TaskMachineForControl { control: Algo },
    /// The demonstrations: bad input when the expert cache is missing or refused
    /// ([`DemoError::Cache`], [`DemoError::Missing`]), else a failure while producing them.
    #[error(transparent)]
    Demos(DemoError),
    /// The request's `[env]` over the task's layout.
    #[error("[env]: {0}")]
    Env(ConfigError),
    /// A run directory's environment over its task's layout.
    #[error(transparent)]
    RunEnv(ConfigError),
    /// The task's own machine.
    #[error(transparent)]
    PerfectMachine(RmFileError),
    /// Writing a file or directory of the run.
    #[error("{}: {source}", path.display())]
    Write {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error(transparent)]
    Log(LogError),
    #[error("none of the {generated} demonstrations completes task '{task}'")]
    NoCompleteDemos { generated: usize, task: ReacherTask },
    #[error(transparent)]
    Branches(ExpertError),
    /// An algorithm's resolved settings in the run's config.
    #[error("{source}")]
    AlgoSettings { algo: Algo, source: IrlConfigError },
    /// The task layout the machine learning reads.
    #[error(transparent)]
    TaskLayout(ConfigError),
    #[error(transparent)]
    Machine(MachineError),
    #[error("LRM cost of the task's machine: {0}")]
    TaskMachineCost(LrmError),
    #[error("LRM cost of the perfect machine: {0}")]
    PerfectMachineCost(LrmError),
    #[error(transparent)]
    StateCounts(EquivError),
    #[error(
        "{}: not a prepared run directory (no {file}: run `reacher prepare --out {}` first, or \
         let it finish)",
        dir.display(),
        dir.display()
    )]
    NotPrepared { dir: PathBuf, file: &'static str },
    /// Reading a file of a run directory.
    #[error("{}: {source}", path.display())]
    Read {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("{}: {source}", path.display())]
    ParsePlan {
        path: PathBuf,
        source: serde_json::Error,
    },
    /// A machine file of a run directory.
    #[error(transparent)]
    MachineFile(RmFileError),
    #[error(transparent)]
    /// A plan (`prepare.json`) that names an algorithm this binary does not know.
    Plan(UnknownAlgorithm),
    /// A run directory's annotated demonstrations.
    #[error("{}: {source}", path.display())]
    ExpertData { path: PathBuf, source: CodecError },
    #[error(
        "{}: algorithm '{algo}' is not in this run (prepared: {})",
        dir.display(),
        prepared.join(", ")
    )]
    AlgoNotInRun {
        dir: PathBuf,
        algo: Algo,
        prepared: Vec<String>,
    },
    #[error("{}: seed {seed} is outside this run's seeds {first}..={last}", dir.display())]
    SeedNotInRun {
        dir: PathBuf,
        seed: u64,
        first: u64,
        last: u64,
    },
    #[error(
        "{}: job index {index} is outside 0..{jobs} (the run has {jobs} jobs)",
        dir.display()
    )]
    JobIndexNotInRun {
        dir: PathBuf,
        index: usize,
        jobs: usize,
    },
    #[error("give --index, or --algo and --seed")]
    NoJobGiven,
    #[error(
        "{}: {} of {jobs} jobs have not finished: {} (run them with `reacher job`, or pass \
         --partial)",
        dir.display(),
        missing.len(),
        missing.join(", ")
    )]
    JobsUnfinished {
        dir: PathBuf,
        /// The unfinished jobs' stems (`<algo>_seed<S>`).
        missing: Vec<String>,
        jobs: usize,
    },
    #[error("{}: no job has finished yet", dir.display())]
    NoJobFinished { dir: PathBuf },
    /// A finished job's record, read back to aggregate.
    #[error(transparent)]
    Record(RecordError),
    #[error("{algo} seed {seed}: no metrics rows")]
    NoMetricsRows { algo: Algo, seed: u64 },
    /// The output directory of `reacher --task`, checked before anything is written.
    #[error(transparent)]
    OutputDir(OutputError),
    /// Starting or committing the output directory.
    #[error(transparent)]
    Output(OutputError),
    /// The first job of `reacher --task` that failed (the others ran on).
    #[error("{source}")]
    JobFailed {
        algo: Algo,
        seed: u64,
        source: Box<JobRunError>,
    },
}

impl PipelineError {
    /// Bad input, found before anything was written (the binaries exit with the usage code).
    pub fn is_usage(&self) -> bool {
        use PipelineError as E;
        match self {
            E::Demos(e) => matches!(e, DemoError::Cache { .. } | DemoError::Missing { .. }),
            E::NoAlgorithm
            | E::NoSeeds
            | E::TooManySeeds { .. }
            | E::SeedOverflow { .. }
            | E::Config(_)
            | E::TaskMachineForControl { .. }
            | E::Env(_)
            | E::RunEnv(_)
            | E::NotPrepared { .. }
            | E::Read { .. }
            | E::ParsePlan { .. }
            | E::MachineFile(_)
            | E::Plan(_)
            | E::ExpertData { .. }
            | E::AlgoNotInRun { .. }
            | E::SeedNotInRun { .. }
            | E::JobIndexNotInRun { .. }
            | E::NoJobGiven
            | E::JobsUnfinished { .. }
            | E::NoJobFinished { .. }
            | E::Record(_)
            | E::NoMetricsRows { .. }
            | E::OutputDir(_) => true,
            E::PerfectMachine(_)
            | E::Write { .. }
            | E::Log(_)
            | E::NoCompleteDemos { .. }
            | E::Branches(_)
            | E::AlgoSettings { .. }
            | E::TaskLayout(_)
            | E::Machine(_)
            | E::TaskMachineCost(_)
            | E::PerfectMachineCost(_)
            | E::StateCounts(_)
            | E::Output(_)
            | E::JobFailed { .. } => false,
        }
    }
}

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

pub(super) fn io(path: &Path, source: std::io::Error) -> PipelineError {
    PipelineError::Write {
        path: path.into(),
        source,
    }
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
    pub fn jobs(&self) -> Result<Vec<(Algo, u64)>, UnknownAlgorithm> {
        let algos = self
            .algos
            .iter()
            .map(|a| Algo::parse_in(a, &Algo::REACHER_NAMED))
            .collect::<Result<Vec<_>, _>>()?;
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

/// A prepared run without the machine (and its annotated demonstrations) an algorithm reads.
#[derive(Debug, thiserror::Error)]
#[error("{}: no {file} for {algo}", dir.display())]
pub struct MissingMachine {
    pub dir: PathBuf,
    pub file: &'static str,
    pub algo: Algo,
}

/// A job record (`jobs/<algo>_seed<S>.json`) that cannot be read.
#[derive(Debug, thiserror::Error)]
pub enum RecordError {
    #[error("{}: {source}", path.display())]
    Read {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("{}: {source}", path.display())]
    Parse {
        path: PathBuf,
        source: serde_json::Error,
    },
}

/// One job of a prepared run that failed, before, while or after it ran.
#[derive(Debug, thiserror::Error)]
pub enum JobRunError {
    #[error("{}: {source}", path.display())]
    CreateDir {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error(transparent)]
    MissingMachine(#[from] MissingMachine),
    #[error(transparent)]
    Record(#[from] RecordError),
    /// The algorithm's schedule in the run's config.
    #[error(transparent)]
    Config(#[from] IrlConfigError),
    #[error(transparent)]
    TaskLayout(#[from] ConfigError),
    #[error(transparent)]
    Log(#[from] LogError),
    #[error(transparent)]
    Job(#[from] JobError),
    /// Writing the job's files (the log header, the reward trace, the record).
    #[error(transparent)]
    Write(#[from] PipelineError),
}
