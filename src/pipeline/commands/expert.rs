//! `reacher expert`: trains a task's SAC expert (or resumes a killed run), evaluates it with
//! stochastic and mean actions, saves the policy (and a cache copy), plots the training curve,
//! logs 16 demonstrations and writes `summary.json`, all in one run directory.

use super::usage;
use crate::env::reacher_task::ReacherTask;
use crate::log::{LogOptions, RolloutLogger};
use crate::output::{check_file, check_not_input, create_parent, OutputDir};
use crate::pipeline::expert::ExpertOutcome;
use crate::pipeline::reacher_expert::{self as rx, ExpertConfig};
use crate::rl::sac::ActMode;
use anyhow::{Context, Result};
use indicatif::{ProgressBar, ProgressStyle};
use std::path::{Path, PathBuf};

/// The arguments of `reacher expert`.
#[derive(Clone, Debug)]
pub struct ExpertRequest {
    pub task: ReacherTask,
    /// Expert config (TOML); `None`: [`ExpertConfig::default`].
    pub config: Option<PathBuf>,
    /// Smoke run ([`ExpertConfig::smoke`]); its policy goes to `cache` only if one is named.
    pub quick: bool,
    pub seed: u64,
    /// Continue the run whose checkpoint is in `out`, or start one there.
    pub resume: bool,
    /// Run directory; `None`: `target/expert-runs/<task>`.
    pub out: Option<PathBuf>,
    /// Start over in an existing run directory (only one this program wrote).
    pub force: bool,
    /// Policy cache the trained actor is also copied to, as `expert_<task>.policy`
    /// (`expert_<task>-<content hash>.policy` for a task file); `None`: none for a shipped
    /// task, `experts/` beside a task file.
    pub cache: Option<PathBuf>,
    /// Log every N-th training episode to `train.mcap` (0: no training log).
    pub train_log_every: u64,
    /// No progress bar.
    pub quiet: bool,
}

/// Seed of the evaluation episodes, apart from the training and demonstration seeds.
fn eval_seed(seed: u64) -> u64 {
    seed ^ 0x00e7_a100_0000_0000
}

/// `reacher expert`: the config and run directory are checked before training starts (bad
/// ones are usage errors); prints the training log, the evaluation per branch and the files
/// written.
pub fn run(args: ExpertRequest) -> Result<()> {
    let task = args.task.clone();
    let config = resolve_config(&args)?;
    let out = args
        .out
        .clone()
        .unwrap_or_else(|| PathBuf::from(format!("target/expert-runs/{task}")));
    let checkpoint = out.join("expert.ckpt");
    // --resume continues the run whose checkpoint is in --out, or starts one there.
    if !(args.resume && checkpoint.is_file()) {
        let output = OutputDir::check(&out, args.force).map_err(|e| {
            usage(if checkpoint.exists() {
                format!("{e} (pass --resume to continue the run in it)")
            } else {
                e.to_string()
            })
        })?;
        output.create()?;
    }

    let started = std::time::Instant::now();
    let (mut policy, outcome) = train(&args, &config, &out, &checkpoint)?;
    let train_secs = started.elapsed().as_secs_f64();
    if let Some(steps) = outcome.resumed_at {
        println!("resumed from the checkpoint at {steps} steps");
    }

    let episodes = config.eval_episodes;
    let eval_seed = eval_seed(args.seed);
    let stochastic = rx::evaluate_expert(
        &mut policy,
        &config.env,
        episodes,
        ActMode::Sample,
        eval_seed,
    )?;
    let mean = rx::evaluate_expert(&mut policy, &config.env, episodes, ActMode::Mean, eval_seed)?;

    let policy_path = out.join("expert.policy");
    policy.save(&policy_path)?;
    let cached = save_to_cache(&args, &policy)?;
    let curve_svg = out.join("curve.svg");
    rx::write_curve_svg(
        &curve_svg,
        &out.join("curve_return.svg"),
        task.clone(),
        &outcome.curve,
        config.progress_window,
    )?;
    let demos_path = out.join("demos.mcap");
    let demos = log_demos(&mut policy, &task, &config, args.seed, &demos_path)?;
    let demo_successes = demos.iter().filter(|d| d.success).count();
    let demo_branches = rx::branch_tally(task.clone(), &demos)?;

    let summary = rx::ExpertRunSummary {
        task: task.name().into(),
        seed: args.seed,
        env_steps: outcome.trainer.env_steps(),
        episodes: outcome.trainer.episodes(),
        train_seconds: train_secs,
        resumed_at: outcome.resumed_at,
        eval_episodes: episodes,
        success_stochastic: stochastic.success_rate,
        success_mean: mean.success_rate,
        task_return_stochastic: stochastic.mean_task_return,
        task_return_mean: mean.mean_task_return,
        length_stochastic: stochastic.mean_length,
        length_mean: mean.mean_length,
        cancel_episodes_stochastic: stochastic.cancel_episodes,
        cancel_successes_stochastic: stochastic.cancel_successes,
        cancel_episodes_mean: mean.cancel_episodes,
        cancel_successes_mean: mean.cancel_successes,
        branches_stochastic: stochastic.branches,
        branches_mean: mean.branches,
        demo_branches,
        demos: demos.len(),
        demo_successes,
        git_commit: crate::GIT_COMMIT.into(),
    };
    rx::write_run_summary(&out.join("summary.json"), &summary)?;
    print_summary(&task, &summary, train_secs);
    println!(
        "wrote {} (checkpoint), {}, {}, {}, {} and {}",
        checkpoint.display(),
        policy_path.display(),
        cached.map_or("(no --cache)".to_string(), |p| p.display().to_string()),
        curve_svg.display(),
        demos_path.display(),
        out.join("summary.json").display()
    );
    Ok(())
}

/// The run's expert config on its task (a bad one is a usage error).
fn resolve_config(args: &ExpertRequest) -> Result<ExpertConfig> {
    let mut config = match (&args.config, args.quick) {
        (Some(_), true) => return Err(usage("--quick and --config exclude each other")),
        (Some(path), false) => ExpertConfig::load(path).map_err(usage)?,
        (None, true) => ExpertConfig::smoke(),
        (None, false) => ExpertConfig::default(),
    };
    config.env = args.task.env_config(&config.env).map_err(usage)?;
    config
        .validate()
        .map_err(|e| usage(format!("expert config: {e}")))?;
    Ok(config)
}

/// Trains (or resumes) the expert with a progress bar, logging every N-th training episode to
/// `train.mcap` when asked.
fn train(
    args: &ExpertRequest,
    config: &ExpertConfig,
    out: &Path,
    checkpoint: &Path,
) -> Result<(rx::ExpertPolicy, ExpertOutcome)> {
    let task = &args.task;
    let bar = if args.quiet {
        ProgressBar::hidden()
    } else {
        ProgressBar::new(config.total_steps)
    };
    bar.set_style(
        ProgressStyle::with_template(
            "{prefix} [{elapsed_precise}] {wide_bar} {pos}/{len} steps ({per_sec}, eta {eta}) {msg}",
        )
        .expect("valid template"),
    );
    bar.set_prefix(format!("expert {task}"));
    let mut train_logger = if args.train_log_every > 0 {
        let path = free_log_path(out, "train");
        let header = rx::train_log_header(task.clone(), config, args.seed)?;
        let options = LogOptions {
            every_nth_episode: args.train_log_every,
            ..LogOptions::default()
        };
        Some(RolloutLogger::create(&path, header, options)?)
    } else {
        None
    };
    let trained = rx::train_task_expert(
        task.clone(),
        config,
        args.seed,
        checkpoint,
        args.resume,
        |p| {
            bar.set_position(p.env_steps.min(p.total_steps));
            bar.set_message(format!(
                "recent success {:.2}, return {:.2}{}",
                p.recent_success,
                p.recent_return,
                if p.checkpointed { " [checkpoint]" } else { "" }
            ));
        },
        train_logger.as_mut(),
    )?;
    bar.finish_and_clear();
    if let Some(l) = train_logger {
        let s = l.finish()?;
        println!(
            "training log {}: {} episodes, {} steps, {:.1} B/step",
            s.path.display(),
            s.episodes_logged,
            s.steps_logged,
            s.bytes as f64 / s.steps_logged.max(1) as f64
        );
    }
    Ok(trained)
}

/// Copies the policy to the cache `--cache` names, or to the task's default cache (none for a
/// shipped task). A smoke policy is no expert: the default cache would hand it to
/// `reacher --task FILE`, so `--quick` goes to a named cache only.
fn save_to_cache(args: &ExpertRequest, policy: &rx::ExpertPolicy) -> Result<Option<PathBuf>> {
    let cache = args.cache.clone().or_else(|| {
        (!args.quick)
            .then(|| rx::default_expert_cache(&args.task))
            .flatten()
    });
    let Some(cache) = cache else {
        return Ok(None);
    };
    std::fs::create_dir_all(&cache)
        .with_context(|| format!("cannot create {}", cache.display()))?;
    let path = rx::expert_cache_path(&cache, args.task.clone());
    policy.save(&path)?;
    Ok(Some(path))
}

/// The paper's 16 demonstrations of the expert's stochastic policy, logged to `path` with
/// their observations.
fn log_demos(
    policy: &mut rx::ExpertPolicy,
    task: &ReacherTask,
    config: &ExpertConfig,
    seed: u64,
    path: &Path,
) -> Result<Vec<rx::Demo>> {
    let header = rx::demo_log_header(policy, &config.env, seed)?;
    let options = LogOptions {
        observations: true,
        ..LogOptions::default()
    };
    let mut logger = RolloutLogger::create(path, header, options)?;
    let demos = rx::generate_demos(
        policy,
        task.clone(),
        &config.env,
        rx::PAPER_DEMOS,
        seed,
        Some(&mut logger),
    )?;
    logger.finish()?;
    Ok(demos)
}

/// The run's outcome: steps, time, success with stochastic and mean actions, demonstrations,
/// episodes with an event, and each branch where the task has two.
fn print_summary(task: &ReacherTask, s: &rx::ExpertRunSummary, train_secs: f64) {
    println!(
        "expert {task}: {} steps in {:.0} s; success over {} episodes: stochastic {:.2}, mean action {:.2}; task return {:.3} / {:.3}; {}/{} demos successful",
        s.env_steps,
        train_secs,
        s.eval_episodes,
        s.success_stochastic,
        s.success_mean,
        s.task_return_stochastic,
        s.task_return_mean,
        s.demo_successes,
        s.demos
    );
    println!(
        "episodes with an event: stochastic {}/{} successful, mean action {}/{}",
        s.cancel_successes_stochastic,
        s.cancel_episodes_stochastic,
        s.cancel_successes_mean,
        s.cancel_episodes_mean
    );
    if let (Some(st), Some(me), Some(de)) =
        (s.branches_stochastic, s.branches_mean, s.demo_branches)
    {
        println!("branches, stochastic: {st}");
        println!("branches, mean action: {me}");
        println!("branches, the {} demonstrations: {de}", s.demos);
    }
}

/// `DIR/STEM.mcap`, or `DIR/STEM.K.mcap` with the first K ≥ 1 for which neither the file nor
/// its unfinished `.part` exists (a resumed run must not overwrite the log of the first).
fn free_log_path(dir: &Path, stem: &str) -> PathBuf {
    let taken = |p: &PathBuf| p.exists() || p.with_extension("mcap.part").exists();
    let first = dir.join(format!("{stem}.mcap"));
    if !taken(&first) {
        return first;
    }
    (1..)
        .map(|k| dir.join(format!("{stem}.{k}.mcap")))
        .find(|p| !taken(p))
        .expect("some index is free")
}

/// The arguments of `reacher expert-curve`.
#[derive(Clone, Debug)]
pub struct CurveRequest {
    pub task: ReacherTask,
    /// A training-curve CSV that `reacher expert` wrote (`curve.csv`, one row per episode).
    pub csv: PathBuf,
    /// The success plot.
    pub out: PathBuf,
    /// The return plot.
    pub out_return: PathBuf,
    /// Moving-average window in episodes (the expert config's `progress_window`).
    pub window: usize,
    /// Replace existing plots.
    pub force: bool,
}

/// `reacher expert-curve`: draws a training curve's success and return plots from its CSV,
/// with the function `reacher expert` draws them with (so a plot can be redrawn, e.g. after a
/// change to the plotting code, without retraining). Existing plots are replaced only with
/// `force`.
pub fn redraw_curve(args: CurveRequest) -> Result<()> {
    if args.window == 0 {
        return Err(usage("--window must be at least 1"));
    }
    if args.out == args.out_return {
        return Err(usage("--out and --out-return name the same file"));
    }
    for path in [&args.out, &args.out_return] {
        check_file(path, args.force).map_err(usage)?;
        check_not_input(path, &[&args.csv]).map_err(usage)?;
    }
    let curve = crate::pipeline::expert::read_curve(&args.csv, u64::MAX).map_err(usage)?;
    for path in [&args.out, &args.out_return] {
        create_parent(path)?;
    }
    rx::write_curve_svg(&args.out, &args.out_return, args.task, &curve, args.window)?;
    println!(
        "{} and {} ({} episodes)",
        args.out.display(),
        args.out_return.display(),
        curve.len()
    );
    Ok(())
}
