//! A whole `reacher --task` run: demos, RM learning, the (algorithm, seed) jobs on a thread
//! pool, and the run directory.
//!
//! Run directory (written as `<out>.partial`, renamed to `<out>` when complete):
//! - `config.toml` — the effective configuration; `run.json` — task, algorithms, seeds,
//!   demo and RM facts, wall times, git commit.
//! - `metrics.csv` — one row per (algorithm, seed, IRL iteration): ground-truth success rate
//!   and returns (no wall times, so the same seed gives the same file bit for bit); for IF and
//!   Composite also the success rate and episode count of each branch (`success_normal`,
//!   `success_cancel`, …), and `success_rate` is the lower of the two branch rates.
//! - `summary.csv`, `summary.md` — final success/return (and, for IF and Composite, each
//!   branch's success) mean ± std over seeds per algorithm.
//! - `success.svg`, `task_return.svg` — mean ± std over seeds vs environment steps; for IF and
//!   Composite also `success_branches.svg`, each branch's success per algorithm;
//!   `progress.svg`, the partial progress the paper's figure credits: the fraction of the
//!   task's sub-goals completed along the perfect machine and the fraction of episodes that
//!   touched a ball that can end the task (`progress`, `final_ball` in `metrics.csv`).
//! - `rm/` — `perfect.txt`/`.dot`, and for SMIRL `learned.txt`/`.dot` and `report.txt`.
//! - `rewards/<algo>_seed<S>.*` — learned reward parameters; for SMIRL also
//!   `rewards/<algo>_seed<S>.trace.csv`, the weights and data gradient of every IRL iteration.
//! - `logs/demos.mcap`, `logs/<algo>_seed<S>.mcap` — demos and sampled agent/eval episodes.

use super::config::{DemoPadding, DemoSource, IrlRunConfig, SmirlMachine};
use super::demos::{load_expert, make_demos, DemoError};
use super::final_policy::FinalPolicy;
use super::job::{run_job, ExpertData, JobInputs, JobProgress, JobResult, RewardTraceRow};
use super::smirl::{annotate, label_traces, learn_machine, lrm_config, task_machine};
use super::Algo;
use crate::atomic_file::write_atomic;
use crate::env::reacher::{EVENTS, VOCABULARY};
use crate::env::reacher_task::{Branch, BranchTally, CancelBranch, ReacherTask};
use crate::log::{LogOptions, RolloutLogger, RunHeader};
use crate::output::OutputDir;
use crate::pipeline::reacher_expert::Demo;
use crate::pipeline::reacher_expert::{branch_tally, ExpertPolicy};
use crate::report::{aggregate_over_seeds, CsvTable, LinePlot, Series};
use crate::rm::dot::to_dot;
use crate::rm::equiv::{refines, state_counts};
use crate::rm::format::parse_rm;
use crate::rm::format::write_rm;
use crate::rm::lrm::{trace_cost, trace_reading};
use crate::rm::{LabelSet, RewardMachine};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Mutex;
use std::time::Instant;

/// What to run.
#[derive(Clone, Debug)]
pub struct RunRequest {
    pub task: ReacherTask,
    pub algos: Vec<Algo>,
    /// Number of seeds; job seeds are `seed, seed + 1, …`.
    pub seeds: u64,
    /// Base seed (also the demonstrations' and LRM's seed).
    pub seed: u64,
    pub config: IrlRunConfig,
    /// Final run directory.
    pub out: PathBuf,
    /// Replace an existing `out` (only one this program wrote, see [`crate::output`]).
    pub force: bool,
}

/// A run that could not start (bad input: nothing written) or failed while running.
#[derive(Debug, thiserror::Error)]
pub enum PipelineError {
    /// Bad input, found before anything was written.
    #[error("{0}")]
    Usage(String),
    #[error("{0}")]
    Run(String),
}

/// Receives progress (the binary draws progress bars from it).
pub trait RunObserver: Sync {
    /// A phase starts (`"demos"`, `"lrm"`, `"irl"`, `"reports"`).
    fn phase(&self, _name: &str) {}
    /// The jobs of the IRL phase, in order (labels such as `smirl seed 1`).
    fn jobs(&self, _labels: &[String], _total_env_steps: u64) {}
    fn job_progress(&self, _job: usize, _progress: JobProgress) {}
    fn job_done(&self, _job: usize, _record: &JobRecord) {}
    fn message(&self, _text: &str) {}
}

/// An observer that ignores everything.
pub struct Silent;
impl RunObserver for Silent {}

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
    /// Jobs with a final-policy phase (SMIRL): the reported policy's success (the lower
    /// branch for a conditional task), mean and std over seeds.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub final_policy_success: Option<(f64, f64)>,
    /// ... and per branch of a conditional task, in [`Branch::ALL`] order.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub final_policy_branch_success: Option<[(f64, f64); 2]>,
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
    pub algos: Vec<AlgoSummary>,
    pub wall_secs: f64,
}

fn mean_std(xs: &[f64]) -> (f64, f64) {
    let n = xs.len().max(1) as f64;
    let m = xs.iter().sum::<f64>() / n;
    let v = xs.iter().map(|x| (x - m) * (x - m)).sum::<f64>() / n;
    (m, v.sqrt())
}

/// Most seeds per algorithm in one run (each is a job of minutes to hours).
pub const MAX_SEEDS: u64 = 1_000;

fn io(path: &Path, e: impl std::fmt::Display) -> PipelineError {
    PipelineError::Run(format!("{}: {e}", path.display()))
}

fn write_file(path: &Path, text: &str) -> Result<(), PipelineError> {
    write_atomic(path, text.as_bytes()).map_err(|e| io(path, e))
}

fn log_header(
    task: ReacherTask,
    seed: u64,
    config: &IrlRunConfig,
    what: &str,
    perfect: &RewardMachine,
) -> Result<RunHeader, PipelineError> {
    // Replay reads the environment config from `env` (time limit, cancel schedule).
    let json = serde_json::json!({ "run": what, "env": config.env, "irl_config": config });
    let mut header = RunHeader::reacher_shipped(task.name(), seed, json);
    header.reward_machine = Some(write_rm(perfect));
    Ok(header)
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
    pub prepare_secs: f64,
    pub git_commit: String,
}

impl Prepared {
    /// The (algorithm, seed) jobs, in the order `--index` counts them: algorithms outer,
    /// seeds inner.
    pub fn jobs(&self) -> Result<Vec<(Algo, u64)>, String> {
        let algos = self
            .algos
            .iter()
            .map(|a| Algo::parse_in(a, &Algo::REACHER))
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
    pub learned: Option<RewardMachine>,
    pub expert: ExpertData,
}

/// One finished job as `jobs/<algo>_seed<S>.json` (written last by the job: its presence
/// means the job is done).
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct JobRecord {
    pub algo: String,
    pub seed: u64,
    pub rows: Vec<super::MetricsRow>,
    /// SMIRL's final-policy phase (`final_policy.csv`); absent in jobs without one.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub final_policy: Option<FinalPolicy>,
    pub wall_secs: f64,
}

impl JobRecord {
    /// The success rate the job reports: its final policy's where it has one (SMIRL), else the
    /// last IRL iteration's. The two differ when the final phase picked a checkpoint over a
    /// co-trained policy that dipped at the last iteration.
    pub fn reported_success(&self) -> f64 {
        match &self.final_policy {
            Some(final_policy) => final_policy.chosen().success_rate,
            None => self.rows.last().map_or(0.0, |r| r.success_rate),
        }
    }
}

const PREPARED_FILE: &str = "prepare.json";
const EXPERT_DATA_FILE: &str = "expert_data.bin";

fn job_stem(algo: Algo, seed: u64) -> String {
    format!("{}_seed{seed}", algo.name())
}

/// Checks a request before anything is written: algorithms, seeds, config and (for expert
/// demonstrations) the expert cache, which is loaded. Returns the expert and the last seed.
fn check_request(request: &RunRequest) -> Result<(Option<ExpertPolicy>, u64), PipelineError> {
    let RunRequest {
        task,
        ref algos,
        seeds,
        seed,
        ref config,
        ..
    } = *request;
    let usage = PipelineError::Usage;
    if algos.is_empty() {
        return Err(usage("no algorithm selected".into()));
    }
    if seeds == 0 {
        return Err(usage("--seeds must be at least 1".into()));
    }
    if seeds > MAX_SEEDS {
        return Err(usage(format!(
            "--seeds {seeds} is more than the limit of {MAX_SEEDS} seeds per run"
        )));
    }
    let last_seed = seed
        .checked_add(seeds - 1)
        .ok_or_else(|| usage(format!("--seed {seed} + --seeds {seeds} overflows")))?;
    config
        .validate("config")
        .map_err(|e| usage(e.to_string()))?;
    let expert = match config.demo_source {
        DemoSource::Expert => Some(load_expert(task, config.cache_dir()).map_err(|e| match e {
            DemoError::Cache { .. } => usage(e.to_string()),
            other => PipelineError::Run(other.to_string()),
        })?),
        DemoSource::Scripted => None,
    };
    Ok((expert, last_seed))
}

/// Phase 1 of a run (`reacher prepare`): checks the request, then writes into `dir` (created
/// if missing) the config, the perfect machine, the demonstrations (`logs/demos.mcap`), for
/// SMIRL the learned machine and its report, the annotated expert data the jobs read, and
/// last `prepare.json`. Bad input is [`PipelineError::Usage`], found before anything is
/// written.
pub fn prepare(
    request: &RunRequest,
    dir: &Path,
    observer: &dyn RunObserver,
) -> Result<Prepared, PipelineError> {
    let started = Instant::now();
    let RunRequest {
        task,
        ref algos,
        seed,
        ref config,
        ..
    } = *request;
    let (mut expert, last_seed) = check_request(request)?;
    let perfect = task
        .perfect_rm()
        .map_err(|e| PipelineError::Run(e.to_string()))?;

    for sub in ["rm", "rewards", "logs", "jobs"] {
        std::fs::create_dir_all(dir.join(sub)).map_err(|e| io(dir, e))?;
    }
    write_file(&dir.join("config.toml"), &config.to_toml())?;
    write_file(&dir.join("rm/perfect.txt"), &write_rm(&perfect))?;
    write_file(&dir.join("rm/perfect.dot"), &to_dot(&perfect))?;

    // 1. Demonstrations.
    observer.phase("demos");
    let demo_log = dir.join("logs/demos.mcap");
    let mut logger = RolloutLogger::create(
        &demo_log,
        log_header(task, seed, config, "demonstrations", &perfect)?,
        LogOptions {
            observations: true,
            ..LogOptions::default()
        },
    )
    .map_err(|e| PipelineError::Run(e.to_string()))?;
    let all_demos = make_demos(task, config, expert.as_mut(), seed, Some(&mut logger))
        .map_err(|e| PipelineError::Run(e.to_string()))?;
    logger
        .finish()
        .map_err(|e| PipelineError::Run(e.to_string()))?;
    let demos_generated = all_demos.len();
    let demos: Vec<Demo> = all_demos.into_iter().filter(|d| d.success).collect();
    if demos.is_empty() {
        return Err(PipelineError::Run(format!(
            "none of the {demos_generated} demonstrations completes task '{task}'"
        )));
    }
    let demo_branches =
        branch_tally(task, &demos).map_err(|e| PipelineError::Run(e.to_string()))?;
    observer.message(&format!(
        "demonstrations: {} of {demos_generated} complete the task ({} source), {} steps{}",
        demos.len(),
        config.demo_source.name(),
        demos.iter().map(|d| d.steps.len()).sum::<usize>(),
        demo_branches.map_or(String::new(), |t| format!(
            "; {} take the normal branch, {} the cancel branch",
            t.episodes[Branch::Normal.index()],
            t.episodes[Branch::Cancelled.index()]
        ))
    ));

    // 2. Reward machine (SMIRL only).
    let mut rm_facts = None;
    let learned = if algos.iter().any(|a| a.uses_rm()) {
        observer.phase("lrm");
        let lrm = lrm_config(config, seed);
        let (rm, cost, secs) = match config.smirl_machine {
            SmirlMachine::Learned => {
                learn_machine(&demos, config, seed).map_err(PipelineError::Run)?
            }
            SmirlMachine::Task => {
                let rm = task_machine(&perfect).map_err(PipelineError::Run)?;
                let cost =
                    trace_cost(&rm, &label_traces(&demos), trace_reading(&lrm)).map_err(|e| {
                        PipelineError::Run(format!("LRM cost of the task's machine: {e}"))
                    })?;
                (rm, cost, 0.0)
            }
        };
        let traces: Vec<Vec<LabelSet>> = demos.iter().map(|d| d.labels()).collect();
        let r = refines(&rm, &perfect, traces.iter().map(|t| t.as_slice()));
        let counts = state_counts(&rm, None).map_err(|e| PipelineError::Run(e.to_string()))?;
        let facts = RmFacts {
            learned_states: rm.n_states(),
            learned_reachable: counts.reachable,
            perfect_states: perfect.n_states(),
            refines_perfect: r.refines,
            ambiguous_steps: r.ambiguous_steps,
            total_steps: r.total_steps,
            lrm_cost: cost,
            lrm_secs: secs,
        };
        let mut report = String::new();
        if config.smirl_machine == SmirlMachine::Task {
            let _ = writeln!(
                report,
                "smirl_machine = \"task\": the \"learned\" machine below is the task's own \
                 (goal and failure states made ordinary, rewards 0), not LRM's: an oracle"
            );
        }
        let _ = writeln!(
            report,
            "learned machine: {} states ({} reachable); perfect machine: {} states",
            facts.learned_states, facts.learned_reachable, facts.perfect_states
        );
        let _ = writeln!(
            report,
            "refines the perfect machine along the {} demonstrations: {} ({} of {} steps ambiguous)",
            demos.len(),
            facts.refines_perfect,
            facts.ambiguous_steps,
            facts.total_steps
        );
        // The perfect machine's cost on the same traces says whether a machine that fails to
        // refine the task lost the search or won it (LRM's objective prefers it).
        let perfect_cost = trace_cost(&perfect, &label_traces(&demos), trace_reading(&lrm))
            .map_err(|e| PipelineError::Run(format!("LRM cost of the perfect machine: {e}")))?;
        let _ = writeln!(
            report,
            "LRM cost {:.3} (the perfect machine's on the same traces: {:.3}), {:.2} s",
            cost, perfect_cost, secs
        );
        let _ = writeln!(
            report,
            "guards for label sets unseen in a state: {} (events read first: \"{}\")",
            config.lrm_guards.name(),
            rm.vocab().format_labels(EVENTS)
        );
        for (u, seen) in r.seen_with.iter().enumerate() {
            let _ = writeln!(
                report,
                "learned state {u} seen with perfect states {seen:?}"
            );
        }
        write_file(&dir.join("rm/learned.txt"), &write_rm(&rm))?;
        write_file(&dir.join("rm/learned.dot"), &to_dot(&rm))?;
        write_file(&dir.join("rm/report.txt"), &report)?;
        observer.message(
            report
                .lines()
                .take(2)
                .collect::<Vec<_>>()
                .join("; ")
                .as_str(),
        );
        rm_facts = Some(facts);
        Some(rm)
    } else {
        None
    };
    let hold_to = match config.demo_padding {
        DemoPadding::Hold => Some(config.env.max_steps),
        DemoPadding::None => None,
    };
    let expert_data = annotate(&demos, learned.as_ref(), hold_to);
    let path = dir.join(EXPERT_DATA_FILE);
    write_atomic(&path, &expert_data.to_bytes()).map_err(|e| io(&path, e))?;
    let prepared = Prepared {
        task,
        algos: algos.iter().map(|a| a.name().to_string()).collect(),
        seeds: (seed..=last_seed).collect(),
        seed,
        demos_kept: demos.len(),
        demos_generated,
        demo_branches,
        rm: rm_facts,
        prepare_secs: started.elapsed().as_secs_f64(),
        git_commit: crate::GIT_COMMIT.into(),
    };
    write_file(
        &dir.join(PREPARED_FILE),
        &(serde_json::to_string_pretty(&prepared).expect("JSON serialises") + "\n"),
    )?;
    Ok(prepared)
}

/// Reads a directory `prepare` finished. A directory it did not finish (no `prepare.json`)
/// or whose files do not parse is [`PipelineError::Usage`].
pub fn open_run(dir: &Path) -> Result<PreparedRun, PipelineError> {
    let usage = PipelineError::Usage;
    let marker = dir.join(PREPARED_FILE);
    if !marker.is_file() {
        return Err(usage(format!(
            "{}: not a prepared run directory (no {PREPARED_FILE}: run `reacher prepare --out {}` \
             first, or let it finish)",
            dir.display(),
            dir.display()
        )));
    }
    let read = |name: &str| {
        let path = dir.join(name);
        std::fs::read_to_string(&path).map_err(|e| usage(format!("{}: {e}", path.display())))
    };
    let prepared: Prepared = serde_json::from_str(&read(PREPARED_FILE)?)
        .map_err(|e| usage(format!("{}: {e}", marker.display())))?;
    let config = IrlRunConfig::load(&dir.join("config.toml")).map_err(|e| usage(e.to_string()))?;
    let rm_file = |name: &str| -> Result<RewardMachine, PipelineError> {
        let path = dir.join(name);
        parse_rm(&read(name)?, &path.display().to_string()).map_err(|e| usage(e.to_string()))
    };
    let perfect = rm_file("rm/perfect.txt")?;
    let jobs = prepared.jobs().map_err(usage)?;
    let learned = if jobs.iter().any(|(a, _)| a.uses_rm()) {
        Some(rm_file("rm/learned.txt")?)
    } else {
        None
    };
    let data_path = dir.join(EXPERT_DATA_FILE);
    let bytes =
        std::fs::read(&data_path).map_err(|e| usage(format!("{}: {e}", data_path.display())))?;
    let expert = ExpertData::from_bytes(&bytes)
        .map_err(|e| usage(format!("{}: {e}", data_path.display())))?;
    Ok(PreparedRun {
        dir: dir.to_path_buf(),
        prepared,
        config,
        perfect,
        learned,
        expert,
    })
}

impl PreparedRun {
    /// The job `(algo, seed)` of this run, or a usage error naming what is not in the plan.
    pub fn job(&self, algo: Algo, seed: u64) -> Result<(Algo, u64), PipelineError> {
        let jobs = self.prepared.jobs().map_err(PipelineError::Usage)?;
        if !jobs.iter().any(|&(a, _)| a == algo) {
            return Err(PipelineError::Usage(format!(
                "{}: algorithm '{algo}' is not in this run (prepared: {})",
                self.dir.display(),
                self.prepared.algos.join(", ")
            )));
        }
        if !self.prepared.seeds.contains(&seed) {
            return Err(PipelineError::Usage(format!(
                "{}: seed {seed} is outside this run's seeds {}..={}",
                self.dir.display(),
                self.prepared.seeds[0],
                self.prepared.seeds[self.prepared.seeds.len() - 1]
            )));
        }
        Ok((algo, seed))
    }

    /// The `index`-th job (algorithms outer, seeds inner), as `reacher job --index` counts.
    pub fn job_at(&self, index: usize) -> Result<(Algo, u64), PipelineError> {
        let jobs = self.prepared.jobs().map_err(PipelineError::Usage)?;
        jobs.get(index).copied().ok_or_else(|| {
            PipelineError::Usage(format!(
                "{}: job index {index} is outside 0..{} (the run has {} jobs)",
                self.dir.display(),
                jobs.len(),
                jobs.len()
            ))
        })
    }

    fn record_path(&self, algo: Algo, seed: u64) -> PathBuf {
        self.dir
            .join("jobs")
            .join(format!("{}.json", job_stem(algo, seed)))
    }

    /// Phase 2 (`reacher job`): runs one job and writes its log, reward, reward trace and
    /// last its record `jobs/<algo>_seed<S>.json`. A finished job (record present) is not run
    /// again: its record is returned. A job killed halfway left no record; it starts over and
    /// overwrites its own files.
    pub fn run_job(
        &self,
        algo: Algo,
        seed: u64,
        progress: &(dyn Fn(JobProgress) + Sync),
    ) -> Result<(JobRecord, bool), String> {
        let record_path = self.record_path(algo, seed);
        if record_path.is_file() {
            return read_record(&record_path).map(|r| (r, false));
        }
        // A run directory checked out from git has no `logs/` (ignored: the MCAP files are
        // large) and, before its first job is committed, no `rewards/` or `jobs/`.
        for sub in ["rewards", "logs", "jobs"] {
            let sub = self.dir.join(sub);
            std::fs::create_dir_all(&sub).map_err(|e| format!("{}: {e}", sub.display()))?;
        }
        let result = run_one(
            self.prepared.task,
            algo,
            seed,
            &self.config,
            &self.perfect,
            self.learned.as_ref(),
            &self.expert,
            &self.dir,
            progress,
        )?;
        let record = JobRecord {
            algo: algo.name().into(),
            seed,
            rows: result.rows,
            final_policy: result.final_policy,
            wall_secs: result.wall_secs,
        };
        write_file(
            &record_path,
            &(serde_json::to_string(&record).expect("JSON serialises") + "\n"),
        )
        .map_err(|e| e.to_string())?;
        Ok((record, true))
    }

    /// The jobs of the plan that have no record yet.
    pub fn missing_jobs(&self) -> Result<Vec<(Algo, u64)>, PipelineError> {
        Ok(self
            .prepared
            .jobs()
            .map_err(PipelineError::Usage)?
            .into_iter()
            .filter(|&(a, s)| !self.record_path(a, s).is_file())
            .collect())
    }
}

fn read_record(path: &Path) -> Result<JobRecord, String> {
    let text = std::fs::read_to_string(path).map_err(|e| format!("{}: {e}", path.display()))?;
    serde_json::from_str(&text).map_err(|e| format!("{}: {e}", path.display()))
}

/// Phase 3 (`reacher aggregate`): metrics, summary, plots and `run.json` from the finished
/// jobs' records. Missing jobs are a usage error listing them, unless `allow_partial`
/// (then the finished ones are aggregated). `wall_secs` is the whole run's wall time when one
/// process ran it (`reacher --task`).
pub fn aggregate(
    run: &PreparedRun,
    allow_partial: bool,
    wall_secs: Option<f64>,
) -> Result<RunSummary, PipelineError> {
    let missing = run.missing_jobs()?;
    if !missing.is_empty() && !allow_partial {
        let names: Vec<String> = missing.iter().map(|&(a, s)| job_stem(a, s)).collect();
        return Err(PipelineError::Usage(format!(
            "{}: {} of {} jobs have not finished: {} (run them with `reacher job`, or pass \
             --partial)",
            run.dir.display(),
            missing.len(),
            run.prepared.jobs().map_err(PipelineError::Usage)?.len(),
            names.join(", ")
        )));
    }
    let mut records = Vec::new();
    for (algo, seed) in run.prepared.jobs().map_err(PipelineError::Usage)? {
        if missing.contains(&(algo, seed)) {
            continue;
        }
        let record = read_record(&run.record_path(algo, seed)).map_err(PipelineError::Usage)?;
        records.push((algo, record));
    }
    if records.is_empty() {
        return Err(PipelineError::Usage(format!(
            "{}: no job has finished yet",
            run.dir.display()
        )));
    }
    write_reports(run, &records, wall_secs)
}

/// Runs everything in one process and writes the run directory: [`prepare`], every job on a
/// pool of `threads` workers, [`aggregate`] — the same three phases `reacher prepare`, `job`
/// and `aggregate` run one process each. Bad input (algorithm list, expert cache) is reported
/// as [`PipelineError::Usage`] before anything is written.
pub fn run_pipeline(
    request: &RunRequest,
    observer: &dyn RunObserver,
) -> Result<RunSummary, PipelineError> {
    let started = Instant::now();
    let out = &request.out;
    let output =
        OutputDir::check(out, request.force).map_err(|e| PipelineError::Usage(e.to_string()))?;
    check_request(request)?;
    // From here on, output goes to <out>.partial.
    let partial = output
        .begin()
        .map_err(|e| PipelineError::Run(e.to_string()))?;
    prepare(request, &partial, observer)?;
    let run = open_run(&partial)?;

    observer.phase("irl");
    let jobs = run.prepared.jobs().map_err(PipelineError::Run)?;
    let labels: Vec<String> = jobs.iter().map(|(a, s)| format!("{a} seed {s}")).collect();
    observer.jobs(
        &labels,
        run.config.sac_steps_per_iteration * run.config.irl_iterations as u64,
    );
    let next = AtomicUsize::new(0);
    let failures: Mutex<Vec<Option<String>>> = Mutex::new(jobs.iter().map(|_| None).collect());
    std::thread::scope(|scope| {
        for _ in 0..run.config.threads.min(jobs.len()) {
            scope.spawn(|| loop {
                let i = next.fetch_add(1, Ordering::SeqCst);
                let Some(&(algo, job_seed)) = jobs.get(i) else {
                    break;
                };
                match run.run_job(algo, job_seed, &|p| observer.job_progress(i, p)) {
                    Ok((record, _)) => observer.job_done(i, &record),
                    Err(e) => {
                        failures
                            .lock()
                            .expect("no job panics while holding the lock")[i] = Some(e)
                    }
                }
            });
        }
    });
    if let Some(e) = failures
        .into_inner()
        .expect("workers finished")
        .into_iter()
        .flatten()
        .next()
    {
        return Err(PipelineError::Run(e));
    }

    observer.phase("reports");
    let mut summary = aggregate(&run, false, Some(started.elapsed().as_secs_f64()))?;
    // Complete: replace the previous run directory (checked to be ours).
    output
        .commit(&partial)
        .map_err(|e| PipelineError::Run(e.to_string()))?;
    summary.out = out.clone();
    summary.wall_secs = started.elapsed().as_secs_f64();
    Ok(summary)
}

/// Writes metrics.csv, the summaries, the plots and run.json of `records` into the run
/// directory.
fn write_reports(
    run: &PreparedRun,
    records: &[(Algo, JobRecord)],
    wall_secs: Option<f64>,
) -> Result<RunSummary, PipelineError> {
    let dir = &run.dir;
    let task = run.prepared.task;
    let mut metrics = CsvTable::new([
        "algo",
        "seed",
        "iteration",
        "env_steps",
        "success_rate",
        "task_return",
        "env_return",
        "learned_reward",
        "surrogate_loss",
        "success_normal",
        "success_cancel",
        "episodes_normal",
        "episodes_cancel",
        "progress",
        "final_ball",
        "expert_support",
    ]);
    let optional = |x: Option<f64>| x.map_or(String::new(), |x| format!("{x}"));
    for (_, r) in records {
        for row in &r.rows {
            let branch = |f: &dyn Fn(&BranchTally, Branch) -> String| -> [String; 2] {
                Branch::ALL.map(|b| row.branches.as_ref().map_or(String::new(), |t| f(t, b)))
            };
            let [rate_normal, rate_cancel] =
                branch(&|t, b| t.rate(b).map_or(String::new(), |x| format!("{x}")));
            let [n_normal, n_cancel] = branch(&|t, b| t.episodes[b.index()].to_string());
            metrics.push([
                r.algo.clone(),
                r.seed.to_string(),
                row.iteration.to_string(),
                row.env_steps.to_string(),
                format!("{}", row.success_rate),
                format!("{}", row.task_return),
                format!("{:.6}", row.env_return),
                format!("{:.6}", row.learned_reward),
                format!("{:.6}", row.surrogate_loss),
                rate_normal,
                rate_cancel,
                n_normal,
                n_cancel,
                optional(row.progress),
                optional(row.final_ball),
                optional(row.expert_support),
            ]);
        }
    }
    write_file(&dir.join("metrics.csv"), &metrics.to_csv())?;
    if records.iter().any(|(_, r)| r.final_policy.is_some()) {
        write_file(
            &dir.join("final_policy.csv"),
            &final_policy_table(records).to_csv(),
        )?;
    }

    let algos: Vec<Algo> = {
        let mut seen = Vec::new();
        for &(a, _) in records {
            if !seen.contains(&a) {
                seen.push(a);
            }
        }
        seen
    };
    let mut summaries = Vec::new();
    let mut success_plot = LinePlot::new(
        &format!("ReacherDelivery {task}: ground-truth success"),
        "environment steps",
        "success rate",
    );
    success_plot.y_range = Some((0.0, 1.0));
    let mut return_plot = LinePlot::new(
        &format!("ReacherDelivery {task}: task return"),
        "environment steps",
        "task return",
    );
    let conditional = CancelBranch::of(&run.perfect).is_some();
    let mut branch_plot = LinePlot::new(
        &format!("ReacherDelivery {task}: success per branch"),
        "environment steps",
        "success rate",
    );
    branch_plot.y_range = Some((0.0, 1.0));
    let mut progress_plot = LinePlot::new(
        &format!(
            "ReacherDelivery {task}: sub-goals completed (solid) and end ball touched (dashed)"
        ),
        "environment steps",
        "fraction",
    );
    progress_plot.y_range = Some((0.0, 1.0));
    for &algo in &algos {
        let runs: Vec<&JobRecord> = records
            .iter()
            .filter(|(a, _)| *a == algo)
            .map(|(_, r)| r)
            .collect();
        let curve = |f: &dyn Fn(&super::MetricsRow) -> f64| -> Vec<Vec<(f64, f64)>> {
            runs.iter()
                .map(|r| {
                    r.rows
                        .iter()
                        .map(|row| (row.env_steps as f64, f(row)))
                        .collect()
                })
                .collect()
        };
        // A branch without evaluation episodes counts as failed (it cannot be shown solved).
        let branch_rate = |row: &super::MetricsRow, b: Branch| -> f64 {
            row.branches.and_then(|t| t.rate(b)).unwrap_or(0.0)
        };
        if conditional {
            for b in Branch::ALL {
                branch_plot.series.push(Series {
                    name: format!("{} ({b})", algo.name()),
                    points: aggregate_over_seeds(&curve(&|r| branch_rate(r, b))),
                });
            }
        }
        success_plot.series.push(Series {
            name: algo.name().into(),
            points: aggregate_over_seeds(&curve(&|r| r.success_rate)),
        });
        // Jobs from before the progress metric have none: no curve for them.
        if runs
            .iter()
            .all(|r| r.rows.iter().all(|row| row.progress.is_some()))
        {
            progress_plot.series.push(Series {
                name: format!("{} sub-goals", algo.name()),
                points: aggregate_over_seeds(&curve(&|r| r.progress.unwrap_or(0.0))),
            });
            progress_plot.series.push(Series {
                name: format!("{} end ball", algo.name()),
                points: aggregate_over_seeds(&curve(&|r| r.final_ball.unwrap_or(0.0))),
            });
        }
        return_plot.series.push(Series {
            name: algo.name().into(),
            points: aggregate_over_seeds(&curve(&|r| r.task_return)),
        });
        let last = |f: &dyn Fn(&super::MetricsRow) -> f64| -> Result<Vec<f64>, PipelineError> {
            runs.iter()
                .map(|r| {
                    r.rows.last().map(f).ok_or_else(|| {
                        PipelineError::Usage(format!("{algo} seed {}: no metrics rows", r.seed))
                    })
                })
                .collect()
        };
        let (sm, ss) = mean_std(&last(&|r| r.success_rate)?);
        let (rm_, rs) = mean_std(&last(&|r| r.task_return)?);
        let final_branch_success = if conditional {
            let normal = mean_std(&last(&|r| branch_rate(r, Branch::Normal))?);
            let cancel = mean_std(&last(&|r| branch_rate(r, Branch::Cancelled))?);
            Some([normal, cancel])
        } else {
            None
        };
        // The reported policies of the final-policy phase, when every seed has one.
        let chosen: Option<Vec<_>> = runs
            .iter()
            .map(|r| r.final_policy.as_ref().map(FinalPolicy::chosen))
            .collect();
        let final_policy_success = chosen
            .as_ref()
            .map(|c| mean_std(&c.iter().map(|c| c.success_rate).collect::<Vec<_>>()));
        let final_policy_branch_success = chosen.as_ref().filter(|_| conditional).map(|c| {
            Branch::ALL.map(|b| {
                let rates: Vec<f64> = c
                    .iter()
                    .map(|c| c.branches.and_then(|t| t.rate(b)).unwrap_or(0.0))
                    .collect();
                mean_std(&rates)
            })
        });
        let (wm, _) = mean_std(&runs.iter().map(|r| r.wall_secs).collect::<Vec<_>>());
        summaries.push(AlgoSummary {
            algo: algo.name().into(),
            seeds: runs.len(),
            final_success_mean: sm,
            final_success_std: ss,
            final_return_mean: rm_,
            final_return_std: rs,
            final_branch_success,
            final_policy_success,
            final_policy_branch_success,
            job_secs_mean: wm,
        });
    }
    write_file(&dir.join("success.svg"), &success_plot.to_svg())?;
    write_file(&dir.join("task_return.svg"), &return_plot.to_svg())?;
    if !progress_plot.series.is_empty() {
        write_file(&dir.join("progress.svg"), &progress_plot.to_svg())?;
    }
    if conditional {
        write_file(&dir.join("success_branches.svg"), &branch_plot.to_svg())?;
    }
    let mut table = CsvTable::new([
        "task",
        "algo",
        "seeds",
        "final_success_mean",
        "final_success_std",
        "final_return_mean",
        "final_return_std",
        "final_success_normal_mean",
        "final_success_normal_std",
        "final_success_cancel_mean",
        "final_success_cancel_std",
    ]);
    for s in &summaries {
        let branch_cells = match s.final_branch_success {
            Some([(nm, ns), (cm, cs)]) => [nm, ns, cm, cs].map(|x| format!("{x:.3}")),
            None => Default::default(),
        };
        let [nm, ns, cm, cs] = branch_cells;
        table.push([
            task.name().to_string(),
            s.algo.clone(),
            s.seeds.to_string(),
            format!("{:.3}", s.final_success_mean),
            format!("{:.3}", s.final_success_std),
            format!("{:.3}", s.final_return_mean),
            format!("{:.3}", s.final_return_std),
            nm,
            ns,
            cm,
            cs,
        ]);
    }
    write_file(&dir.join("summary.csv"), &table.to_csv())?;
    let p = &run.prepared;
    write_file(
        &dir.join("summary.md"),
        &summary_markdown(task, &summaries, p.rm.as_ref()),
    )?;
    let summary = RunSummary {
        out: dir.clone(),
        task: task.name().into(),
        demos_kept: p.demos_kept,
        demos_generated: p.demos_generated,
        demo_branches: p.demo_branches,
        rm: p.rm.clone(),
        algos: summaries,
        wall_secs: wall_secs.unwrap_or(f64::NAN),
    };
    let config = &run.config;
    let run_json = serde_json::json!({
        "summary": summary,
        "seeds": p.seeds,
        "demo_source": config.demo_source.name(),
        "demo_cancel": config.demo_cancel.name(),
        "demo_padding": config.demo_padding.name(),
        "smirl_normalisation": config.smirl_normalisation.name(),
        "smirl_machine": config.smirl_machine.name(),
        "smirl_label_features": config.smirl_label_features.name(),
        "smirl_shaping": config.smirl_shaping,
        "smirl_counterfactual": config.smirl_counterfactual,
        "reward_lr_decay": config.reward_lr_decay,
        "git_commit": crate::GIT_COMMIT,
        "prepare_git_commit": p.git_commit,
        "prepare_secs": p.prepare_secs,
        "jobs": records.iter().map(|(_, r)| serde_json::json!({
            "algo": r.algo, "seed": r.seed, "wall_secs": r.wall_secs})).collect::<Vec<_>>(),
    });
    write_file(
        &dir.join("run.json"),
        &serde_json::to_string_pretty(&run_json).expect("JSON serialises"),
    )?;
    Ok(summary)
}

/// One job with its MCAP logger, reward file and (SMIRL) reward trace, in run directory
/// `dir`.
#[allow(clippy::too_many_arguments)]
fn run_one(
    task: ReacherTask,
    algo: Algo,
    seed: u64,
    config: &IrlRunConfig,
    perfect: &RewardMachine,
    learned: Option<&RewardMachine>,
    expert: &ExpertData,
    dir: &Path,
    progress: &(dyn Fn(JobProgress) + Sync),
) -> Result<JobResult, String> {
    // The algorithm's own schedule, if the config gives it one.
    let config = &config.for_algo(algo).map_err(|e| e.to_string())?;
    let stem = job_stem(algo, seed);
    let reward_path = dir.join("rewards").join(format!(
        "{stem}.{}",
        if algo.uses_rm() { "json" } else { "bin" }
    ));
    let mut logger = if config.log_every_nth_episode > 0 {
        let header = log_header(task, seed, config, &format!("irl {algo}"), perfect)
            .map_err(|e| e.to_string())?;
        Some(
            RolloutLogger::create(
                &dir.join("logs").join(format!("{stem}.mcap")),
                header,
                LogOptions {
                    every_nth_episode: config.log_every_nth_episode,
                    ..LogOptions::default()
                },
            )
            .map_err(|e| e.to_string())?,
        )
    } else {
        None
    };
    let inputs = JobInputs {
        algo,
        seed,
        settings: config,
        perfect_rm: perfect,
        learned_rm: learned,
        expert,
        reward_path: Some(&reward_path),
    };
    let result = run_job(&inputs, logger.as_mut(), progress).map_err(|e| e.to_string())?;
    if let Some(l) = logger {
        l.finish().map_err(|e| e.to_string())?;
    }
    if !result.reward_trace.is_empty() {
        let path = dir.join("rewards").join(format!("{stem}.trace.csv"));
        write_file(&path, &reward_trace_csv(&result.reward_trace).to_csv())
            .map_err(|e| e.to_string())?;
    }
    Ok(result)
}

/// The candidates of every job's final-policy phase, one row each: `candidate` 0 is the
/// co-trained policy of the last IRL iteration, `chosen` marks the reported one, `agent` says
/// whose policy it is (`co-trained`, or `fresh` with `smirl_final_fresh_steps`).
fn final_policy_table(records: &[(Algo, JobRecord)]) -> CsvTable {
    let mut table = CsvTable::new([
        "algo",
        "seed",
        "candidate",
        "env_steps",
        "learned_return",
        "chosen",
        "success_rate",
        "success_normal",
        "success_cancel",
        "progress",
        "final_ball",
        "agent",
    ]);
    for (_, r) in records {
        let Some(f) = &r.final_policy else { continue };
        for (i, c) in f.candidates.iter().enumerate() {
            let rate = |b: Branch| {
                c.branches
                    .and_then(|t| t.rate(b))
                    .map_or(String::new(), |x| format!("{x}"))
            };
            table.push([
                r.algo.clone(),
                r.seed.to_string(),
                i.to_string(),
                c.env_steps.to_string(),
                format!("{:.6}", c.learned_return),
                u8::from(i == f.chosen).to_string(),
                format!("{}", c.success_rate),
                rate(Branch::Normal),
                rate(Branch::Cancelled),
                format!("{}", c.progress),
                format!("{}", c.final_ball),
                c.agent.name().to_string(),
            ]);
        }
    }
    table
}

/// A SMIRL reward trace as a long table: one row per (iteration, RM state, feature), the
/// feature named by its proposition (label bit k is feature k).
fn reward_trace_csv(trace: &[RewardTraceRow]) -> CsvTable {
    let features: Vec<char> = VOCABULARY.chars().collect();
    let mut table = CsvTable::new([
        "iteration",
        "rm_state",
        "feature",
        "weight",
        "data_gradient",
    ]);
    for row in trace {
        for (i, (w, g)) in row.weights.iter().zip(&row.data_gradient).enumerate() {
            table.push([
                row.iteration.to_string(),
                (i / features.len()).to_string(),
                features[i % features.len()].to_string(),
                format!("{w:.6}"),
                format!("{g:.6}"),
            ]);
        }
    }
    table
}

/// The per-branch cells of a summary row: mean ± std of the normal and the cancel branch; empty
/// cells in a conditional task's table for a row without them, none for other tasks.
fn branch_cells(branches: Option<[(f64, f64); 2]>, conditional: bool) -> String {
    match branches {
        Some([(nm, ns), (cm, cs)]) => format!(" {nm:.2} ± {ns:.2} | {cm:.2} ± {cs:.2} |"),
        None if conditional => " | |".to_string(),
        None => String::new(),
    }
}

/// The summary table as Markdown (also printed by the binary).
pub fn summary_markdown(
    task: ReacherTask,
    summaries: &[AlgoSummary],
    rm: Option<&RmFacts>,
) -> String {
    let mut s = String::new();
    let conditional = summaries.iter().any(|a| a.final_branch_success.is_some());
    if conditional {
        let _ = writeln!(
            s,
            "| task | algorithm | seeds | final success (lower branch) | normal branch | cancel branch | final task return | job wall time (s) |"
        );
        let _ = writeln!(s, "|---|---|---|---|---|---|---|---|");
    } else {
        let _ = writeln!(
            s,
            "| task | algorithm | seeds | final success | final task return | job wall time (s) |"
        );
        let _ = writeln!(s, "|---|---|---|---|---|---|");
    }
    for a in summaries {
        let branches = branch_cells(a.final_branch_success, conditional);
        let _ = writeln!(
            s,
            "| {task} | {} | {} | {:.2} ± {:.2} |{branches} {:.2} ± {:.2} | {:.0} |",
            a.algo,
            a.seeds,
            a.final_success_mean,
            a.final_success_std,
            a.final_return_mean,
            a.final_return_std,
            a.job_secs_mean
        );
    }
    let with_final: Vec<&AlgoSummary> = summaries
        .iter()
        .filter(|a| a.final_policy_success.is_some())
        .collect();
    if !with_final.is_empty() {
        let _ = writeln!(
            s,
            "\nFinal policy (SAC on the final reward held fixed; of the candidates in \
             final_policy.csv — the co-trained policy, its checkpoints and any fresh agent's — \
             the one of highest learned return):\n"
        );
        let _ = writeln!(
            s,
            "| task | algorithm | seeds | success{} |",
            if conditional {
                " (lower branch) | normal branch | cancel branch"
            } else {
                ""
            }
        );
        let _ = writeln!(
            s,
            "|---|---|---|---|{}",
            if conditional { "---|---|" } else { "" }
        );
        for a in with_final {
            let (m, sd) = a.final_policy_success.unwrap_or_default();
            let branches = branch_cells(a.final_policy_branch_success, conditional);
            let _ = writeln!(
                s,
                "| {task} | {} | {} | {m:.2} ± {sd:.2} |{branches}",
                a.algo, a.seeds
            );
        }
    }
    if let Some(f) = rm {
        let _ = writeln!(
            s,
            "\nLearned RM: {} states ({} reachable; perfect: {}), refines the perfect machine \
             along the demos: {}.",
            f.learned_states, f.learned_reachable, f.perfect_states, f.refines_perfect
        );
    }
    s
}
