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

use super::config::{DemoSource, IrlRunConfig, SmirlMachine};
use super::demos::{load_expert, make_demos};
use super::expert_data::ExpertData;
use super::iteration::JobProgress;
use super::job::{run_job, JobInputs, JobResult};
use super::lockstep::{Lockstep, LOCKSTEP_BATCH};
use super::records::{io, write_file};
use super::reports::{reward_trace_csv, write_reports};
use super::smirl::{
    annotate, label_traces, learn_machine, lrm_config, one_state_machine, task_machine,
};
use super::Algo;
use crate::atomic_file::write_atomic;
use crate::env::reacher_task::{Branch, ReacherTask};
use crate::input_file::{read_text, MAX_DATA_FILE_BYTES};
use crate::log::{LogOptions, RolloutLogger, RunHeader};
use crate::output::OutputDir;
use crate::pipeline::reacher_expert::Demo;
use crate::pipeline::reacher_expert::{branch_tally, ExpertPolicy};
use crate::rm::dot::to_dot;
use crate::rm::equiv::{refines, state_counts};
use crate::rm::format::parse_rm;
use crate::rm::format::write_rm;
use crate::rm::lrm::{trace_cost, trace_reading, Guards};
use crate::rm::{LabelSet, RewardMachine};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Mutex;
use std::time::Instant;

pub use super::records::{
    AlgoSummary, JobRecord, JobRunError, MissingMachine, PipelineError, Prepared, PreparedRun,
    RecordError, RmFacts, RunSummary,
};
pub use super::reports::summary_markdown;

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

/// Most seeds per algorithm in one run (each is a job of minutes to hours).
pub const MAX_SEEDS: u64 = 1_000;

fn log_header(
    task: ReacherTask,
    seed: u64,
    config: &IrlRunConfig,
    what: &str,
    perfect: &RewardMachine,
) -> Result<RunHeader, PipelineError> {
    // Replay reads the environment config from `env` (time limit, cancel schedule).
    let json = serde_json::json!({ "run": what, "env": config.env, "irl_config": config });
    let mut header = RunHeader::of_task(task.id(), task.task(), seed, json);
    header.reward_machine = Some(write_rm(perfect));
    Ok(header)
}

const PREPARED_FILE: &str = "prepare.json";
const EXPERT_DATA_FILE: &str = "expert_data.bin";
const EXPERT_DATA_PAPER_FILE: &str = "expert_data_paper.bin";

fn job_stem(algo: Algo, seed: u64) -> String {
    format!("{}_seed{seed}", algo.name())
}

/// Checks a request before anything is written: algorithms, seeds, config and (for expert
/// demonstrations) the expert cache, which is loaded. Returns the expert and the last seed.
fn check_request(request: &RunRequest) -> Result<(Option<ExpertPolicy>, u64), PipelineError> {
    let RunRequest {
        ref task,
        ref algos,
        seeds,
        seed,
        ref config,
        ..
    } = *request;
    let task = task.clone();
    if algos.is_empty() {
        return Err(PipelineError::NoAlgorithm);
    }
    if seeds == 0 {
        return Err(PipelineError::NoSeeds);
    }
    if seeds > MAX_SEEDS {
        return Err(PipelineError::TooManySeeds {
            seeds,
            limit: MAX_SEEDS,
        });
    }
    let last_seed = seed
        .checked_add(seeds - 1)
        .ok_or(PipelineError::SeedOverflow { seed, seeds })?;
    config.validate("config").map_err(PipelineError::Config)?;
    // The controls learn on the machine LRM learns; the task's own would hand them ground truth.
    if let Some(control) = algos.iter().find(|a| a.is_product_control()) {
        if config.smirl_machine == SmirlMachine::Task {
            return Err(PipelineError::TaskMachineForControl { control: *control });
        }
    }
    let expert = match config.demo_source {
        DemoSource::Expert => Some(load_expert(task, None).map_err(PipelineError::Demos)?),
        DemoSource::Scripted => None,
    };
    Ok((expert, last_seed))
}

/// Phase 1 of a run (`reacher prepare`): checks the request, then writes into `dir` (created
/// if missing) the config, the perfect machine, the demonstrations (`logs/demos.mcap`), for
/// SMIRL the learned machine and its report, the annotated expert data the jobs read, and
/// last `prepare.json`. Bad input ([`PipelineError::is_usage`]) is found before anything is
/// written.
pub fn prepare(
    request: &RunRequest,
    dir: &Path,
    observer: &dyn RunObserver,
) -> Result<Prepared, PipelineError> {
    let started = Instant::now();
    let RunRequest {
        ref task,
        ref algos,
        seed,
        ref config,
        ..
    } = *request;
    let task = task.clone();
    // The run's environment is its config over the task's layout, as the CLI resolves it.
    let resolved = config.over_task(&task).map_err(PipelineError::Env)?;
    let config = &resolved;
    let (mut expert, last_seed) = check_request(request)?;
    let perfect = task.perfect_rm().map_err(PipelineError::PerfectMachine)?;

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
        log_header(task.clone(), seed, config, "demonstrations", &perfect)?,
        LogOptions {
            observations: true,
            ..LogOptions::default()
        },
    )
    .map_err(PipelineError::Log)?;
    let all_demos = make_demos(
        task.clone(),
        config,
        expert.as_mut(),
        seed,
        Some(&mut logger),
    )
    .map_err(PipelineError::Demos)?;
    logger.finish().map_err(PipelineError::Log)?;
    let demos_generated = all_demos.len();
    let demos: Vec<Demo> = all_demos.into_iter().filter(|d| d.success).collect();
    if demos.is_empty() {
        return Err(PipelineError::NoCompleteDemos {
            generated: demos_generated,
            task,
        });
    }
    let demo_branches = branch_tally(task.clone(), &demos).map_err(PipelineError::Branches)?;
    observer.message(&format!(
        "demonstrations: {} of {demos_generated} complete the task ({} source), {} steps{}",
        demos.len(),
        config.demo_source.name(),
        demos.iter().map(|d| d.steps.len()).sum::<usize>(),
        demo_branches.map_or(String::new(), |t| format!(
            "; {} take the normal branch, {} the event branch",
            t.episodes[Branch::Normal.index()],
            t.episodes[Branch::Event.index()]
        ))
    ));

    // Every demonstration held at its final state to the time limit: the fixed horizon T
    // that MaxEnt IRL and f-IRL assume (without it the learned reward is pushed down wherever
    // the agent stays after finishing the task).
    let hold_to = Some(config.env.max_steps);
    // 2. Reward machines (SMIRL only): SMIRL's, shared by smirl-smooth, and smirl-paper's,
    //    each learned with its algorithm's settings; the demonstrations annotated with each.
    let mut rm_facts = None;
    let mut rm_paper_facts = None;
    let mut expert_data = None;
    for machine in [Machine::Smirl, Machine::Paper] {
        if !algos.iter().any(|&a| Machine::of(a) == Some(machine)) {
            continue;
        }
        observer.phase("lrm");
        let settings =
            config
                .for_algo(machine.algo())
                .map_err(|source| PipelineError::AlgoSettings {
                    algo: machine.algo(),
                    source,
                })?;
        let (rm, facts, report) =
            learn_and_report(&settings, machine.algo(), &demos, &perfect, seed)?;
        let data = annotate(&task.layout(), &demos, Some(&rm), hold_to);
        let stem = machine.stem();
        write_file(&dir.join(format!("rm/{stem}.txt")), &write_rm(&rm))?;
        write_file(&dir.join(format!("rm/{stem}.dot")), &to_dot(&rm))?;
        write_file(&dir.join(machine.report_file()), &report)?;
        let label = match machine {
            Machine::Smirl => String::new(),
            Machine::Paper => format!("{}: ", machine.algo()),
        };
        let head: Vec<&str> = report.lines().take(2).collect();
        observer.message(&format!("{label}{}", head.join("; ")));
        match machine {
            Machine::Smirl => {
                rm_facts = Some(facts);
                expert_data = Some(data);
            }
            Machine::Paper => {
                let path = dir.join(EXPERT_DATA_PAPER_FILE);
                write_atomic(&path, &data.to_bytes()).map_err(|e| io(&path, e))?;
                rm_paper_facts = Some(facts);
            }
        }
    }
    // The demonstrations as the baselines (and SMIRL) read them.
    let expert_data =
        expert_data.unwrap_or_else(|| annotate(&task.layout(), &demos, None, hold_to));
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
        rm_paper: rm_paper_facts,
        prepare_secs: started.elapsed().as_secs_f64(),
        git_commit: crate::GIT_COMMIT.into(),
    };
    write_file(
        &dir.join(PREPARED_FILE),
        &(serde_json::to_string_pretty(&prepared).expect("JSON serialises") + "\n"),
    )?;
    Ok(prepared)
}

/// The learned machines of a run, one per setting of LRM's mechanisms an algorithm reads.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Machine {
    /// `smirl`'s and `smirl-smooth`'s, and the product controls': `rm/learned.txt`, the
    /// demonstrations annotated with it in `expert_data.bin`.
    Smirl,
    /// `smirl-paper`'s (LRM as the paper's eq. 1): `rm/learned_paper.txt`,
    /// `expert_data_paper.bin`.
    Paper,
}

impl Machine {
    fn of(algo: Algo) -> Option<Machine> {
        match algo {
            Algo::SmirlPaper => Some(Machine::Paper),
            a if a.uses_rm() || a.is_product_control() => Some(Machine::Smirl),
            _ => None,
        }
    }

    /// The algorithm whose settings learn it.
    fn algo(self) -> Algo {
        match self {
            Machine::Smirl => Algo::Smirl,
            Machine::Paper => Algo::SmirlPaper,
        }
    }

    fn stem(self) -> &'static str {
        match self {
            Machine::Smirl => "learned",
            Machine::Paper => "learned_paper",
        }
    }

    fn report_file(self) -> &'static str {
        match self {
            Machine::Smirl => "rm/report.txt",
            Machine::Paper => "rm/report_paper.txt",
        }
    }
}

/// Step 1 of SMIRL under `settings` (an algorithm's resolved settings): the machine (LRM's, or
/// the task's with `[smirl] machine = "task"`), its facts and the report of `rm/report.txt`.
fn learn_and_report(
    settings: &IrlRunConfig,
    algo: Algo,
    demos: &[Demo],
    perfect: &RewardMachine,
    seed: u64,
) -> Result<(RewardMachine, RmFacts, String), PipelineError> {
    let config = settings;
    let lrm = lrm_config(config, seed, algo).map_err(PipelineError::TaskLayout)?;
    let (rm, cost, secs) = match config.smirl_machine {
        SmirlMachine::Learned => {
            learn_machine(demos, config, seed, algo).map_err(PipelineError::Machine)?
        }
        SmirlMachine::Task | SmirlMachine::OneState => {
            let rm = match config.smirl_machine {
                SmirlMachine::Task => task_machine(perfect),
                _ => one_state_machine(perfect.vocab()),
            }
            .map_err(PipelineError::Machine)?;
            let cost = trace_cost(&rm, &label_traces(demos), trace_reading(&lrm))
                .map_err(PipelineError::TaskMachineCost)?;
            (rm, cost, 0.0)
        }
    };
    let traces: Vec<Vec<LabelSet>> = demos.iter().map(|d| d.labels()).collect();
    let r = refines(&rm, perfect, traces.iter().map(|t| t.as_slice()));
    let counts = state_counts(&rm, None).map_err(PipelineError::StateCounts)?;
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
    match config.smirl_machine {
        SmirlMachine::Learned => {}
        SmirlMachine::Task => {
            let _ = writeln!(
                report,
                "smirl_machine = \"task\": the \"learned\" machine below is the task's own \
                 (goal and failure states made ordinary, rewards 0), not LRM's: an oracle"
            );
        }
        SmirlMachine::OneState => {
            let _ = writeln!(
                report,
                "smirl_machine = \"one_state\": the \"learned\" machine below has one state, \
                 not LRM's: the control without structure"
            );
        }
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
    let perfect_cost = trace_cost(perfect, &label_traces(demos), trace_reading(&lrm))
        .map_err(PipelineError::PerfectMachineCost)?;
    let _ = writeln!(
        report,
        "LRM cost {:.3} (the perfect machine's on the same traces: {:.3}), {:.2} s",
        cost, perfect_cost, secs
    );
    // Only the tree guards read events (first, where the state shows they matter).
    let events = match lrm.guards {
        Guards::Tree => format!(
            " (events read first: \"{}\")",
            rm.vocab().format_labels(lrm.events)
        ),
        Guards::Exact => String::new(),
    };
    let _ = writeln!(
        report,
        "guards for label sets unseen in a state: {}{events}",
        lrm.guards.name()
    );
    for (u, seen) in r.seen_with.iter().enumerate() {
        let _ = writeln!(
            report,
            "learned state {u} seen with perfect states {seen:?}"
        );
    }
    Ok((rm, facts, report))
}

/// Reads a directory `prepare` finished. A directory it did not finish (no `prepare.json`)
/// or whose files do not parse is bad input ([`PipelineError::is_usage`]).
pub fn open_run(dir: &Path) -> Result<PreparedRun, PipelineError> {
    let marker = dir.join(PREPARED_FILE);
    if !marker.is_file() {
        return Err(PipelineError::NotPrepared {
            dir: dir.into(),
            file: PREPARED_FILE,
        });
    }
    let read = |name: &str| {
        let path = dir.join(name);
        crate::config_text::read_text_file(&path)
            .map_err(|source| PipelineError::Read { path, source })
    };
    let prepared: Prepared =
        serde_json::from_str(&read(PREPARED_FILE)?).map_err(|source| PipelineError::ParsePlan {
            path: marker.clone(),
            source,
        })?;
    let config = IrlRunConfig::load(&dir.join("config.toml"))
        .map_err(PipelineError::Config)?
        .over_task(&prepared.task)
        .map_err(PipelineError::RunEnv)?;
    let rm_file = |name: &str| -> Result<RewardMachine, PipelineError> {
        let path = dir.join(name);
        parse_rm(&read(name)?, &path.display().to_string()).map_err(PipelineError::MachineFile)
    };
    let perfect = rm_file("rm/perfect.txt")?;
    let jobs = prepared.jobs().map_err(PipelineError::Plan)?;
    let needs = |machine: Machine| jobs.iter().any(|&(a, _)| Machine::of(a) == Some(machine));
    let machine_file = |machine: Machine| -> Result<Option<RewardMachine>, PipelineError> {
        needs(machine)
            .then(|| rm_file(&format!("rm/{}.txt", machine.stem())))
            .transpose()
    };
    let obs_dim = prepared.task.layout().obs_dim();
    let expert_file = |name: &str, machine: Option<&RewardMachine>| {
        let data_path = dir.join(name);
        let bytes =
            crate::input_file::read_bytes(&data_path, crate::nn::codec::MAX_CODEC_FILE_BYTES)
                .map_err(|source| PipelineError::Read {
                    path: data_path.clone(),
                    source,
                })?;
        ExpertData::from_bytes(&bytes, obs_dim)
            .and_then(|e| e.check_machine(machine).map(|()| e))
            .map_err(|source| PipelineError::ExpertData {
                path: data_path,
                source,
            })
    };
    let learned = machine_file(Machine::Smirl)?;
    let expert = expert_file(EXPERT_DATA_FILE, learned.as_ref())?;
    let paper = match machine_file(Machine::Paper)? {
        Some(rm) => {
            let data = expert_file(EXPERT_DATA_PAPER_FILE, Some(&rm))?;
            Some((rm, data))
        }
        None => None,
    };
    Ok(PreparedRun {
        dir: dir.to_path_buf(),
        prepared,
        config,
        perfect,
        learned,
        expert,
        paper,
    })
}

impl PreparedRun {
    /// The learned machine `algo` reads (none for the baselines) and the demonstrations as it
    /// reads them (annotated with that machine's states).
    pub fn inputs_of(
        &self,
        algo: Algo,
    ) -> Result<(Option<&RewardMachine>, &ExpertData), MissingMachine> {
        let missing = |file: &'static str| MissingMachine {
            dir: self.dir.clone(),
            file,
            algo,
        };
        match Machine::of(algo) {
            None => Ok((None, &self.expert)),
            Some(Machine::Smirl) => match &self.learned {
                Some(rm) => Ok((Some(rm), &self.expert)),
                None => Err(missing("rm/learned.txt")),
            },
            Some(Machine::Paper) => match &self.paper {
                Some((rm, data)) => Ok((Some(rm), data)),
                None => Err(missing("rm/learned_paper.txt")),
            },
        }
    }

    /// The job `(algo, seed)` of this run, or a usage error naming what is not in the plan.
    pub fn job(&self, algo: Algo, seed: u64) -> Result<(Algo, u64), PipelineError> {
        let jobs = self.prepared.jobs().map_err(PipelineError::Plan)?;
        if !jobs.iter().any(|&(a, _)| a == algo) {
            return Err(PipelineError::AlgoNotInRun {
                dir: self.dir.clone(),
                algo,
                prepared: self.prepared.algos.clone(),
            });
        }
        if !self.prepared.seeds.contains(&seed) {
            return Err(PipelineError::SeedNotInRun {
                dir: self.dir.clone(),
                seed,
                first: self.prepared.seeds[0],
                last: self.prepared.seeds[self.prepared.seeds.len() - 1],
            });
        }
        Ok((algo, seed))
    }

    /// The `index`-th job (algorithms outer, seeds inner), as `reacher job --index` counts.
    pub fn job_at(&self, index: usize) -> Result<(Algo, u64), PipelineError> {
        let jobs = self.prepared.jobs().map_err(PipelineError::Plan)?;
        jobs.get(index)
            .copied()
            .ok_or_else(|| PipelineError::JobIndexNotInRun {
                dir: self.dir.clone(),
                index,
                jobs: jobs.len(),
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
    /// `threads` says how many threads the job may use at the moment it asks (its rollouts
    /// and evaluations; the job's results do not depend on it).
    pub fn run_job(
        &self,
        algo: Algo,
        seed: u64,
        threads: &(dyn Fn() -> usize + Sync),
        progress: &(dyn Fn(JobProgress) + Sync),
    ) -> Result<(JobRecord, bool), JobRunError> {
        let record_path = self.record_path(algo, seed);
        if record_path.is_file() {
            return Ok((read_record(&record_path)?, false));
        }
        // A run directory checked out from git has no `logs/` (ignored: the MCAP files are
        // large) and, before its first job is committed, no `rewards/` or `jobs/`.
        for sub in ["rewards", "logs", "jobs"] {
            let sub = self.dir.join(sub);
            std::fs::create_dir_all(&sub)
                .map_err(|source| JobRunError::CreateDir { path: sub, source })?;
        }
        let (learned, expert) = self.inputs_of(algo)?;
        let result = run_one(
            self.prepared.task.clone(),
            algo,
            seed,
            &self.config,
            &self.perfect,
            learned,
            expert,
            &self.dir,
            threads,
            progress,
        )?;
        let record = JobRecord::from(result);
        write_file(
            &record_path,
            &(serde_json::to_string(&record).expect("JSON serialises") + "\n"),
        )?;
        Ok((record, true))
    }

    /// The jobs of the plan that have no record yet.
    pub fn missing_jobs(&self) -> Result<Vec<(Algo, u64)>, PipelineError> {
        Ok(self
            .prepared
            .jobs()
            .map_err(PipelineError::Plan)?
            .into_iter()
            .filter(|&(a, s)| !self.record_path(a, s).is_file())
            .collect())
    }
}

fn read_record(path: &Path) -> Result<JobRecord, RecordError> {
    let text = read_text(path, MAX_DATA_FILE_BYTES).map_err(|source| RecordError::Read {
        path: path.into(),
        source,
    })?;
    serde_json::from_str(&text).map_err(|source| RecordError::Parse {
        path: path.into(),
        source,
    })
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
        return Err(PipelineError::JobsUnfinished {
            dir: run.dir.clone(),
            missing: names,
            jobs: run.prepared.jobs().map_err(PipelineError::Plan)?.len(),
        });
    }
    let mut records = Vec::new();
    for (algo, seed) in run.prepared.jobs().map_err(PipelineError::Plan)? {
        if missing.contains(&(algo, seed)) {
            continue;
        }
        let record = read_record(&run.record_path(algo, seed)).map_err(PipelineError::Record)?;
        records.push((algo, record));
    }
    if records.is_empty() {
        return Err(PipelineError::NoJobFinished {
            dir: run.dir.clone(),
        });
    }
    write_reports(run, &records, wall_secs)
}

/// Runs everything in one process and writes the run directory: [`prepare`], every job on a
/// pool of `threads` workers, [`aggregate`] — the same three phases `reacher prepare`, `job`
/// and `aggregate` run one process each. Bad input (algorithm list, expert cache) is reported
/// as bad input ([`PipelineError::is_usage`]) before anything is written.
pub fn run_pipeline(
    request: &RunRequest,
    observer: &dyn RunObserver,
) -> Result<RunSummary, PipelineError> {
    let started = Instant::now();
    let out = &request.out;
    let output = OutputDir::check(out, request.force).map_err(PipelineError::OutputDir)?;
    check_request(request)?;
    // From here on, output goes to <out>.partial.
    let partial = output.begin().map_err(PipelineError::Output)?;
    prepare(request, &partial, observer)?;
    let run = open_run(&partial)?;

    observer.phase("irl");
    let jobs = (run.prepared.jobs()).map_err(PipelineError::Plan)?;
    let labels: Vec<String> = jobs.iter().map(|(a, s)| format!("{a} seed {s}")).collect();
    observer.jobs(
        &labels,
        run.config.sac_steps_per_iteration * run.config.irl_iterations as u64,
    );
    let order = dispatch_order(&jobs, &run.config);
    let next = AtomicUsize::new(0);
    let failures: Mutex<Vec<Option<JobRunError>>> = Mutex::new(jobs.iter().map(|_| None).collect());
    // The run's threads are shared by the jobs running: a worker with no job left lends its
    // thread to the others, and a run of fewer jobs than threads gives each the rest.
    let threads = run.config.threads;
    let workers = threads.min(jobs.len());
    let idle = AtomicUsize::new(0);
    let job_threads = || threads / workers.saturating_sub(idle.load(Ordering::SeqCst)).max(1);
    std::thread::scope(|scope| {
        for _ in 0..workers {
            scope.spawn(|| loop {
                let Some(&i) = order.get(next.fetch_add(1, Ordering::SeqCst)) else {
                    idle.fetch_add(1, Ordering::SeqCst);
                    break;
                };
                let (algo, job_seed) = jobs[i];
                match run.run_job(algo, job_seed, &job_threads, &|p| {
                    observer.job_progress(i, p)
                }) {
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
    if let Some(((algo, seed), e)) = jobs
        .iter()
        .zip(failures.into_inner().expect("workers finished"))
        .find_map(|(&job, e)| e.map(|e| (job, e)))
    {
        return Err(PipelineError::JobFailed {
            algo,
            seed,
            source: Box::new(e),
        });
    }

    observer.phase("reports");
    let mut summary = aggregate(&run, false, Some(started.elapsed().as_secs_f64()))?;
    // Complete: replace the previous run directory (checked to be ours).
    output.commit(&partial).map_err(PipelineError::Output)?;
    summary.out = out.clone();
    summary.wall_secs = started.elapsed().as_secs_f64();
    Ok(summary)
}

/// The order in which the pool starts `jobs` (indices into them): the most planned
/// environment steps first — SAC's, the reward updates' rollouts and the final phase's — ties
/// in plan order. Why: the workers take jobs as they free up, and a long job started last runs
/// alone while the other workers idle (the README's main command, f-IRL's jobs after SMIRL's).
/// A job's results do not depend on when it runs.
fn dispatch_order(jobs: &[(Algo, u64)], config: &IrlRunConfig) -> Vec<usize> {
    let planned = |algo: Algo| {
        config.for_algo(algo).map_or(0, |c| {
            let rollouts = (c.agent_trajectories as u64).saturating_mul(c.env.max_steps as u64);
            let per_iteration = c.sac_steps_per_iteration.saturating_add(rollouts);
            (c.irl_iterations as u64)
                .saturating_mul(per_iteration)
                .saturating_add(c.final_sac_steps)
        })
    };
    let mut order: Vec<usize> = (0..jobs.len()).collect();
    order.sort_by_cached_key(|&i| std::cmp::Reverse(planned(jobs[i].0)));
    order
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
    threads: &(dyn Fn() -> usize + Sync),
    progress: &(dyn Fn(JobProgress) + Sync),
) -> Result<JobResult, JobRunError> {
    // The algorithm's own schedule, if the config gives it one.
    let config = &config.for_algo(algo)?;
    let stem = job_stem(algo, seed);
    let reward_path = dir.join("rewards").join(format!(
        "{stem}.{}",
        if algo.uses_rm() { "json" } else { "bin" }
    ));
    let mut logger = if config.log_every_nth_episode > 0 {
        let header = log_header(task, seed, config, &format!("irl {algo}"), perfect)?;
        Some(RolloutLogger::create(
            &dir.join("logs").join(format!("{stem}.mcap")),
            header,
            LogOptions {
                every_nth_episode: config.log_every_nth_episode,
                ..LogOptions::default()
            },
        )?)
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
        lockstep: Lockstep {
            batch: LOCKSTEP_BATCH,
            threads,
        },
    };
    let result = run_job(&inputs, logger.as_mut(), progress)?;
    if let Some(l) = logger {
        l.finish()?;
    }
    if !result.reward_trace.is_empty() {
        let path = dir.join("rewards").join(format!("{stem}.trace.csv"));
        let letters = (config.env.task_layout())?.letters();
        write_file(
            &path,
            &reward_trace_csv(&result.reward_trace, &letters).to_csv(),
        )?;
    }
    Ok(result)
}
