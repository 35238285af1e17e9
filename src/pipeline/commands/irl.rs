//! The IRL pipeline commands of `reacher`: `reacher --task` (the whole run in one process
//! with progress bars), its three steps `prepare`, `job` and `aggregate` (the same run spread
//! over processes or machines), and `reward` (a baseline's saved reward at fingertip
//! positions). The pipeline itself is [`crate::pipeline::reacher_irl`]; this module turns
//! arguments into its requests, draws progress and prints summaries.

use super::{usage, UsageError};
use crate::env::reacher_task::ReacherTask;
use crate::env::task_file;
use crate::output::{check_not_protected, OutputDir};
use crate::pipeline::reacher_expert::{default_expert_cache, ExpertConfig};
use crate::pipeline::reacher_irl::config::DemoSource;
use crate::pipeline::reacher_irl::demos::{load_expert, DemoError};
use crate::pipeline::reacher_irl::iteration::JobProgress;
use crate::pipeline::reacher_irl::run::{self, open_run, summary_markdown, JobRecord, PreparedRun};
use crate::pipeline::reacher_irl::{
    run_pipeline, Algo, IrlRunConfig, PipelineError, RunObserver, RunRequest,
};
use anyhow::{Context, Result};
use indicatif::{MultiProgress, ProgressBar, ProgressStyle};
use std::path::{Path, PathBuf};
use std::sync::Mutex;

/// The arguments of `reacher --task` and `reacher prepare`.
#[derive(Clone, Debug)]
pub struct IrlRequest {
    /// The task; `None` is refused (nothing to do).
    pub task: Option<ReacherTask>,
    /// Algorithms, comma-separated (see [`Algo::parse_reacher_list`]); `None`:
    /// [`Algo::REACHER_DEFAULT`].
    pub algo: Option<String>,
    /// Seeds per algorithm: `seed`, `seed + 1`, …
    pub seeds: u64,
    /// Base seed (also seeds the demonstrations and LRM).
    pub seed: u64,
    /// [`IrlRunConfig::quick`] instead of [`IrlRunConfig::standard`] (without `config`).
    pub quick: bool,
    /// Run configuration (TOML); overrides the built-in profiles.
    pub config: Option<PathBuf>,
    /// Expert config (TOML) for the expert trained first when the task has none cached;
    /// `None`: [`ExpertConfig::default`].
    pub expert_config: Option<PathBuf>,
    /// Run directory; `None`: `runs/reacher-<task>`.
    pub out: Option<PathBuf>,
    /// Replace an existing run directory (only one this program wrote).
    pub force: bool,
    /// Print the effective configuration as TOML instead of running.
    pub print_config: bool,
    /// No progress bars.
    pub quiet: bool,
}

/// Progress bars of `reacher --task`: a spinner naming the phase, one bar per job.
struct Bars {
    multi: MultiProgress,
    phase: ProgressBar,
    jobs: Mutex<Vec<ProgressBar>>,
    quiet: bool,
}

impl RunObserver for Bars {
    fn phase(&self, name: &str) {
        self.phase.set_message(
            match name {
                "demos" => "generating demonstrations",
                "lrm" => "learning the reward machine (LRM)",
                "irl" => "IRL jobs",
                "reports" => "writing reports",
                other => other,
            }
            .to_string(),
        );
        self.phase.tick();
    }
    fn jobs(&self, labels: &[String], total_env_steps: u64) {
        let style = ProgressStyle::with_template(
            "{prefix:>22} [{bar:30}] {pos}/{len} env steps {msg} ({elapsed}, eta {eta})",
        )
        .expect("valid template")
        .progress_chars("=> ");
        let mut jobs = self.jobs.lock().expect("bars lock");
        for label in labels {
            let bar = if self.quiet {
                ProgressBar::hidden()
            } else {
                self.multi.add(ProgressBar::new(total_env_steps))
            };
            bar.set_style(style.clone());
            bar.set_prefix(label.clone());
            jobs.push(bar);
        }
    }
    fn job_progress(&self, job: usize, p: JobProgress) {
        if let Some(bar) = self.jobs.lock().expect("bars lock").get(job) {
            // A job with its own schedule ([schedule.<algo>]) has its own length.
            bar.set_length(p.total_env_steps);
            bar.set_position(p.env_steps);
            bar.set_message(format!(
                "iter {}/{} success {:.2}",
                p.iteration, p.iterations, p.success_rate
            ));
        }
    }
    fn job_done(&self, job: usize, r: &JobRecord) {
        if let Some(bar) = self.jobs.lock().expect("bars lock").get(job) {
            bar.finish_with_message(format!("done, {}", success_text(r)));
        }
    }
    fn message(&self, text: &str) {
        if self.quiet {
            eprintln!("{text}");
        } else {
            let _ = self.multi.println(text);
        }
    }
}

/// The arguments of `reacher job`: the run and the job, by index or by algorithm and seed.
#[derive(Clone, Debug)]
pub struct JobRequest {
    /// Run directory written by `reacher prepare`.
    pub run: PathBuf,
    /// The job's position in the run (algorithms outer, seeds inner, from 0).
    pub index: Option<usize>,
    /// The job's algorithm and seed (both, instead of `index`).
    pub algo: Option<Algo>,
    pub seed: Option<u64>,
    /// No progress bar.
    pub quiet: bool,
}

fn pipeline_error(e: PipelineError) -> anyhow::Error {
    match e {
        e if e.is_usage() => usage(e),
        e => anyhow::anyhow!(e.to_string()),
    }
}

/// The run request of `reacher --task` / `reacher prepare` (`None`: `--print-config`
/// printed the config, nothing to run).
fn request(args: &IrlRequest) -> Result<Option<RunRequest>> {
    let Some(task) = args.task.clone() else {
        return Err(usage(format!(
            "nothing to do: give --task <{}|FILE.toml> or a subcommand (see --help)",
            task_file::SHIPPED.join("|")
        )));
    };
    let algos = match &args.algo {
        Some(s) => Algo::parse_reacher_list(s).map_err(usage)?,
        None => Algo::REACHER_DEFAULT.to_vec(),
    };
    let mut config = match (&args.config, args.quick) {
        (Some(path), _) => IrlRunConfig::load(path).map_err(usage)?,
        (None, true) => IrlRunConfig::quick(),
        (None, false) => IrlRunConfig::standard(),
    };
    if args.print_config {
        print!("{}", config.to_toml());
        return Ok(None);
    }
    config = config.over_task(&task).map_err(usage)?;
    let out = args
        .out
        .clone()
        .unwrap_or_else(|| PathBuf::from(format!("runs/reacher-{}", task.name())));
    if let Some(path) = &args.expert_config {
        // Read before any work, whether or not an expert is trained.
        let expert = ExpertConfig::load(path).map_err(usage)?;
        expert
            .validate()
            .map_err(|e| usage(format!("expert config {}: {e}", path.display())))?;
        if config.demo_source != DemoSource::Expert {
            return Err(usage(format!(
                "--expert-config {}: this run's demonstrations are scripted (demo_source), so no expert is trained",
                path.display()
            )));
        }
    }
    if config.demo_source == DemoSource::Expert {
        train_missing_expert(&task, args.expert_config.as_deref(), args.quiet)?;
    }
    Ok(Some(RunRequest {
        task,
        algos,
        seeds: args.seeds,
        seed: args.seed,
        config,
        out,
        force: args.force,
    }))
}

/// Trains the expert of a task file that has none in its cache yet, as `reacher expert
/// --task FILE [--config EXPERT]` would (the default expert config unless `expert_config`
/// names one, seed 0, run directory `<cache>/runs/<name>-<hash>`), so that `reacher --task
/// FILE` runs from a task file alone. A shipped task's committed expert, or any expert already
/// cached, is used as it is.
fn train_missing_expert(
    task: &ReacherTask,
    expert_config: Option<&Path>,
    quiet: bool,
) -> Result<()> {
    match load_expert(task.clone(), None) {
        Err(DemoError::Missing { path, .. }) => {
            let cache =
                default_expert_cache(task).context("a missing expert has a cache directory")?;
            let hash = &task.task().content_hash[..16];
            let out = cache.join("runs").join(format!("{}-{hash}", task.name()));
            eprintln!(
                "no expert for task {} in {path}: training one first (run directory {})",
                task.task().source,
                out.display()
            );
            super::expert::run(super::expert::ExpertRequest {
                task: task.clone(),
                config: expert_config.map(Path::to_path_buf),
                quick: false,
                seed: 0,
                resume: out.join("expert.ckpt").is_file(),
                out: Some(out),
                force: false,
                cache: Some(cache),
                train_log_every: 0,
                quiet,
            })
        }
        Ok(_) => {
            if let Some(path) = expert_config {
                eprintln!(
                    "the expert of task {} is already cached: --expert-config {} is not used",
                    task.task().source,
                    path.display()
                );
            }
            Ok(())
        }
        // Other problems (a foreign or stale file) are reported by the run's own checks.
        Err(_) => Ok(()),
    }
}

/// `reacher prepare`: writes `<out>.partial`, renamed to `<out>` when complete, and prints the
/// number of jobs. A directory already prepared for the same plan and config is left as it is
/// (so a resubmitted sweep does not redo it); any other existing `<out>` is refused.
pub fn prepare(args: IrlRequest) -> Result<()> {
    let Some(request) = request(&args)? else {
        return Ok(());
    };
    let out = &request.out;
    let planned_jobs = request.algos.len() as u64 * request.seeds;
    check_not_protected(out).map_err(usage)?;
    if out.exists() {
        let existing = open_run(out).map_err(|_| {
            usage(format!(
                "{} exists and is not a prepared run directory: not touching it (choose another --out)",
                out.display()
            ))
        })?;
        let same = existing.prepared.task == request.task
            && existing.prepared.algos
                == request
                    .algos
                    .iter()
                    .map(|a| a.name().to_string())
                    .collect::<Vec<_>>()
            && existing.prepared.seed == request.seed
            && existing.prepared.seeds.len() as u64 == request.seeds
            && existing.config == request.config;
        if !same {
            return Err(usage(format!(
                "{} is already prepared for another task, plan or config: not touching it",
                out.display()
            )));
        }
        println!("{} is already prepared", out.display());
        println!("jobs: {planned_jobs}");
        return Ok(());
    }
    let output = OutputDir::check(out, false).map_err(usage)?;
    let partial = output.begin()?;
    let prepared = run::prepare(&request, &partial, &run::Silent).map_err(pipeline_error)?;
    output.commit(&partial)?;
    println!(
        "prepared {}: task {}, {} of {} demonstrations kept{}",
        out.display(),
        prepared.task,
        prepared.demos_kept,
        prepared.demos_generated,
        prepared.rm.as_ref().map_or(String::new(), |rm| format!(
            ", learned machine with {} states",
            rm.learned_states
        ))
    );
    println!("jobs: {planned_jobs}");
    Ok(())
}

/// Opens a prepared run for `job`, `aggregate` or `retrain`, refusing the `<out>.partial`
/// working directory of a `reacher --task` run: it is renamed to `<out>` when that run ends,
/// and a command working in it would recreate the `.partial` directory after the rename.
fn open_finished_run(dir: &Path) -> Result<PreparedRun> {
    if crate::output::is_work_in_progress(dir) {
        let out = dir.with_extension("");
        return Err(usage(format!(
            "{}: the working directory of a run still being written (or one that stopped): \
             use {} once the run has finished",
            dir.display(),
            out.display()
        )));
    }
    open_run(dir).map_err(pipeline_error)
}

/// `reacher job`: runs one job of a prepared run (a finished job is not rerun) and prints its
/// final success rate.
pub fn job(args: JobRequest) -> Result<()> {
    let run: PreparedRun = open_finished_run(&args.run)?;
    let (algo, seed) = match (args.index, args.algo, args.seed) {
        (Some(i), _, _) => run.job_at(i),
        (None, Some(a), Some(s)) => run.job(a, s),
        _ => Err(PipelineError::NoJobGiven),
    }
    .map_err(pipeline_error)?;
    let bar = if args.quiet {
        ProgressBar::hidden()
    } else {
        ProgressBar::new(run.config.sac_steps_per_iteration * run.config.irl_iterations as u64)
    };
    bar.set_style(
        ProgressStyle::with_template(
            "{prefix} [{bar:30}] {pos}/{len} env steps {msg} ({elapsed}, eta {eta})",
        )
        .expect("valid template")
        .progress_chars("=> "),
    );
    bar.set_prefix(format!("{algo} seed {seed}"));
    // One job per process: its rollouts and evaluations may use every thread of the run.
    let threads = run.config.threads;
    let (record, ran) = run
        .run_job(algo, seed, &|| threads, &|p: JobProgress| {
            bar.set_position(p.env_steps);
            bar.set_message(format!(
                "iter {}/{} success {:.2}",
                p.iteration, p.iterations, p.success_rate
            ));
        })
        // The job's message as it displays (its typed sources are already in it).
        .map_err(|e| anyhow::anyhow!(e.to_string()))
        .with_context(|| format!("{algo} seed {seed} in {}", args.run.display()))?;
    bar.finish_and_clear();
    if ran {
        println!(
            "{algo} seed {seed}: {} ({:.0} s)",
            success_text(&record),
            record.wall_secs
        );
    } else {
        println!(
            "{algo} seed {seed}: already done, {}",
            success_text(&record)
        );
    }
    Ok(())
}

/// "final success X" of the policy a job reports, and the last IRL iteration's where a final
/// policy was chosen (the two differ: a job can report 0.65 from a final policy whose last
/// iteration scored 0.00).
fn success_text(record: &JobRecord) -> String {
    let reported = record.reported_success();
    match (&record.final_policy, record.rows.last()) {
        (Some(_), Some(last)) => format!(
            "final success {reported:.2} (final policy; last IRL iteration {:.2})",
            last.success_rate
        ),
        _ => format!("final success {reported:.2}"),
    }
}

/// `reacher aggregate`: metrics, summary and plots of a prepared run's finished jobs (all of
/// them unless `partial`); prints the summary table.
pub fn aggregate(dir: &Path, partial: bool) -> Result<()> {
    let run = open_finished_run(dir)?;
    let summary = run::aggregate(&run, partial, None).map_err(pipeline_error)?;
    println!(
        "{}",
        summary_markdown(
            run.prepared.task,
            &summary.algos,
            summary.rm.as_ref(),
            summary.rm_paper.as_ref(),
        )
    );
    println!("wrote {}", dir.join("metrics.csv").display());
    Ok(())
}

/// `reacher --task`: the whole IRL pipeline in this process, with progress bars (unless
/// `quiet`); prints the summary table. On a failure while running, the incomplete output is
/// left in `<out>.partial`.
pub fn run(args: IrlRequest) -> Result<()> {
    let Some(request) = request(&args)? else {
        return Ok(());
    };
    let (task, out) = (request.task.clone(), request.out.clone());
    let multi = MultiProgress::new();
    let phase = if args.quiet {
        ProgressBar::hidden()
    } else {
        multi.add(ProgressBar::new_spinner())
    };
    phase.set_style(
        ProgressStyle::with_template("{spinner} {msg} ({elapsed})").expect("valid template"),
    );
    phase.enable_steady_tick(std::time::Duration::from_millis(200));
    let bars = Bars {
        multi,
        phase,
        jobs: Mutex::new(Vec::new()),
        quiet: args.quiet,
    };
    let summary = match run_pipeline(&request, &bars) {
        Ok(s) => s,
        Err(e) if e.is_usage() => return Err(usage(e)),
        Err(e) => {
            return Err(anyhow::anyhow!(e.to_string())).with_context(|| {
                format!(
                    "reacher --task {task} (incomplete output left in {}.partial)",
                    out.display()
                )
            })
        }
    };
    bars.phase.finish_and_clear();
    println!(
        "\n{}",
        summary_markdown(
            task,
            &summary.algos,
            summary.rm.as_ref(),
            summary.rm_paper.as_ref(),
        )
    );
    println!(
        "run directory: {} (total wall time {:.0} s)",
        summary.out.display(),
        summary.wall_secs
    );
    Ok(())
}

/// `reacher reward FILE --at x,y …`: prints a baseline's saved reward at fingertip positions,
/// one `x y reward` line per position. A position that is not two finite numbers, or a file
/// that is not a baseline reward, is bad input.
pub fn reward(file: &Path, at: &[String]) -> Result<()> {
    let points = at
        .iter()
        .map(|p| {
            let xy: Vec<f64> = p
                .split(',')
                .map(|v| v.trim().parse::<f64>())
                .collect::<Result<_, _>>()
                .map_err(|_| UsageError(format!("--at {p}: expected x,y (two numbers)")))?;
            match xy[..] {
                [x, y] if x.is_finite() && y.is_finite() => Ok([x, y]),
                _ => Err(UsageError(format!(
                    "--at {p}: expected x,y (two finite numbers)"
                ))),
            }
        })
        .collect::<Result<Vec<_>, _>>()?;
    let r = crate::pipeline::reacher_irl::job::baseline_reward_at(file, &points).map_err(usage)?;
    for (p, r) in points.iter().zip(r) {
        println!("{} {} {r}", p[0], p[1]);
    }
    Ok(())
}

/// The arguments of `reacher retrain`.
#[derive(Clone, Debug)]
pub struct RetrainRequest {
    /// A prepared run whose job (`algo`, `seed`) has finished.
    pub run: PathBuf,
    pub algo: Algo,
    pub seed: u64,
    /// SAC steps; `None`: the job's own budget.
    pub steps: Option<u64>,
    pub sac_seed: u64,
    pub evaluations: u64,
    /// Learned-machine states whose weights are zeroed first (the table's name then ends in
    /// `_zero<U>-<V>…`).
    pub zero_states: Vec<usize>,
    /// A file of agent settings in place of the job's (the table's name then ends in
    /// `_<its stem>`).
    pub agent: Option<PathBuf>,
    /// Replace an existing `retrain/<algo>_seed<S>_sac<K>.csv`.
    pub force: bool,
}

/// `reacher retrain`: a fresh SAC agent on a finished job's final learned reward, judged on
/// the ground truth every `steps / evaluations` steps; the table goes to
/// `<run>/retrain/<algo>_seed<S>_sac<K>.csv` and standard output.
pub fn retrain(args: RetrainRequest) -> Result<()> {
    use crate::env::reacher_task::Branch;
    use crate::pipeline::reacher_irl::retrain::{load, retrain, AgentSettings, Retraining};
    let run = open_finished_run(&args.run)?;
    run.job(args.algo, args.seed).map_err(usage)?;
    let agent = match &args.agent {
        Some(path) => Some(AgentSettings::load(path).map_err(usage)?),
        None => None,
    };
    let agent_name = agent
        .as_ref()
        .map_or(String::new(), |a| format!("_{}", a.name));
    let request = Retraining {
        algo: args.algo,
        seed: args.seed,
        steps: args.steps,
        sac_seed: args.sac_seed,
        evaluations: args.evaluations,
        zero_states: args.zero_states.clone(),
        agent,
    };
    let loaded = load(&run, &request).map_err(usage)?;
    let zeroed = if args.zero_states.is_empty() {
        String::new()
    } else {
        let states: Vec<String> = args.zero_states.iter().map(|u| u.to_string()).collect();
        format!("_zero{}", states.join("-"))
    };
    let out = args.run.join("retrain").join(format!(
        "{}_seed{}_sac{}{zeroed}{agent_name}.csv",
        args.algo, args.seed, args.sac_seed
    ));
    crate::output::check_file(&out, args.force).map_err(usage)?;
    let header =
        "env_steps,success_rate,success_normal,success_cancel,progress,final_ball,task_return,learned_return,alpha,entropy,critic_loss,policy_value";
    println!("{header}");
    let mut table = format!("{header}\n");
    retrain(loaded, |p| {
        let e = &p.evaluation;
        let branch = |b: Branch| {
            e.branches
                .and_then(|t| t.rate(b))
                .map_or(String::new(), |r| format!("{r}"))
        };
        let a = &p.agent;
        let line = format!(
            "{},{},{},{},{},{},{},{},{},{},{},{}",
            p.env_steps,
            e.success_rate,
            branch(Branch::Normal),
            branch(Branch::Event),
            e.progress,
            e.final_ball,
            e.task_return,
            p.learned_return,
            a.alpha,
            a.entropy,
            a.critic_loss,
            a.policy_value
        );
        println!("{line}");
        table.push_str(&line);
        table.push('\n');
    })
    .map_err(|e| anyhow::anyhow!(e.to_string()))?;
    // Only `retrain/` itself is created: a run directory that went away while the agent
    // trained is not recreated around the table (the table is on standard output).
    let retrain_dir = out.parent().expect("a file in retrain/");
    match std::fs::create_dir(retrain_dir) {
        Err(e) if e.kind() != std::io::ErrorKind::AlreadyExists => {
            return Err(e).with_context(|| format!("cannot create {}", retrain_dir.display()));
        }
        _ => {}
    }
    crate::atomic_file::write_atomic(&out, table.as_bytes())
        .with_context(|| format!("cannot write {}", out.display()))?;
    Ok(())
}
