//! `reacher expert`: trains a task's SAC expert (or resumes a killed run), evaluates it with
//! stochastic and mean actions, saves the policy (and a cache copy), plots the training curve,
//! logs 16 demonstrations and writes `summary.json`, all in one run directory.

use super::usage;
use crate::env::reacher_task::ReacherTask;
use crate::log::{LogOptions, RolloutLogger};
use crate::output::{check_file, check_not_input, create_parent, OutputDir};
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
    let task = args.task;
    let mut config = match (&args.config, args.quick) {
        (Some(_), true) => return Err(usage("--quick and --config exclude each other")),
        (Some(path), false) => ExpertConfig::load(path).map_err(usage)?,
        (None, true) => ExpertConfig::smoke(),
        (None, false) => ExpertConfig::default(),
    };
    config.env = task.env_config(&config.env).map_err(usage)?;
    config
        .validate()
        .map_err(|e| usage(format!("expert config: {e}")))?;
    let out = args
        .out
        .unwrap_or_else(|| PathBuf::from(format!("target/expert-runs/{task}")));
    let checkpoint = out.join("expert.ckpt");
    // --resume continues the run whose checkpoint is in --out, or starts one there.
    if !(args.resume && checkpoint.is_file()) {
        let output = OutputDir::check(&out, args.force).map_err(|e| {
            usage(if out.join("expert.ckpt").exists() {
                format!("{e} (pass --resume to continue the run in it)")
            } else {
                e.to_string()
            })
        })?;
        output.create()?;
    }

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
        let path = free_log_path(&out, "train");
        let header = rx::train_log_header(task.clone(), &config, args.seed)?;
        let options = LogOptions {
            every_nth_episode: args.train_log_every,
            ..LogOptions::default()
        };
        Some(RolloutLogger::create(&path, header, options)?)
    } else {
        None
    };
    let started = std::time::Instant::now();
    let (mut policy, outcome) = rx::train_task_expert(
        task.clone(),
        &config,
        args.seed,
        &checkpoint,
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
    let train_secs = started.elapsed().as_secs_f64();
    if let Some(steps) = outcome.resumed_at {
        println!("resumed from the checkpoint at {steps} steps");
    }

    let eval_seed = eval_seed(args.seed);
    let episodes = config.eval_episodes;
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
    // A smoke policy is no expert: the default cache would hand it to `reacher --task FILE`.
    let cache = args.cache.clone().or_else(|| {
        (!args.quick)
            .then(|| rx::default_expert_cache(&task))
            .flatten()
    });
    let cached = match &cache {
        Some(cache) => {
            std::fs::create_dir_all(cache)
                .with_context(|| format!("cannot create {}", cache.display()))?;
            let path = rx::expert_cache_path(cache, task.clone());
            policy.save(&path)?;
            Some(path)
        }
        None => None,
    };

    let curve_svg = out.join("curve.svg");
    rx::write_curve_svg(
        &curve_svg,
        &out.join("curve_return.svg"),
        task.clone(),
        &outcome.curve,
        config.progress_window,
    )?;

    let demos_path = out.join("demos.mcap");
    let header = rx::demo_log_header(&policy, &config.env, args.seed)?;
    let options = LogOptions {
        observations: true,
        ..LogOptions::default()
    };
    let mut logger = RolloutLogger::create(&demos_path, header, options)?;
    let demos = rx::generate_demos(
        &mut policy,
        task.clone(),
        &config.env,
        rx::PAPER_DEMOS,
        args.seed,
        Some(&mut logger),
    )?;
    logger.finish()?;
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
    println!(
        "expert {task}: {} steps in {:.0} s; success over {episodes} episodes: stochastic {:.2}, mean action {:.2}; task return {:.3} / {:.3}; {}/{} demos successful",
        summary.env_steps,
        train_secs,
        stochastic.success_rate,
        mean.success_rate,
        stochastic.mean_task_return,
        mean.mean_task_return,
        demo_successes,
        demos.len()
    );
    println!(
        "episodes with an event: stochastic {}/{} successful, mean action {}/{}",
        stochastic.cancel_successes,
        stochastic.cancel_episodes,
        mean.cancel_successes,
        mean.cancel_episodes
    );
    if let (Some(st), Some(me), Some(de)) = (stochastic.branches, mean.branches, demo_branches) {
        println!("branches, stochastic: {st}");
        println!("branches, mean action: {me}");
        println!("branches, the {} demonstrations: {de}", demos.len());
    }
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
