//! `reacher`: the ReacherDelivery command line — a thin clap front over library functions.
//!
//! - `reacher replay FILE.mcap [--verify] [--allow-partial]`: re-simulate logged episodes, check bit for bit.
//! - `reacher render FILE.mcap [--episode N] --out PIC.png`: draw one episode top-down.
//! - `reacher learn-rm FILES… [--out DIR] [--compare RM.txt]`: learn an RM from logged labels.
//! - `reacher demo --out FILE.mcap`: log scripted demonstrations (not the paper's SAC experts).
//! - `reacher foxglove FILE.mcap --out VIEW.mcap`: the log plus a Foxglove 3D scene.
//! - `reacher expert --task T`: train, evaluate and save the SAC expert of a task, with its
//!   training curve, its training episodes and 16 demonstrations in MCAP.
//!
//! - `reacher --task T [--algo A] [--seeds N] [--quick] …`: the IRL pipeline (see `irl_cli`),
//!   in one process; the same run in three steps a scheduler can spread over machines:
//!   `reacher prepare --task T … --out DIR`, `reacher job --run DIR --index I` (one per job),
//!   `reacher aggregate DIR`.
//!
//! Exit status: 0 success, 1 failure while running, 2 bad arguments or config.

use anyhow::{bail, Context, Result};
use clap::{Args, Parser, Subcommand};
use smirl::env::reacher::ReacherConfig;
use smirl::log::demo::{log_scripted_demos, DemoSpec};
use smirl::log::{read_log, LogOptions};
use smirl::output::{check_file, OutputDir};
use smirl::pipeline::offline_rm::{compare, learn_from_files};
use smirl::pipeline::replay::replay;
use smirl::rm::lrm::LrmConfig;
use std::path::PathBuf;
use std::process::ExitCode;

#[derive(Parser)]
#[command(
    about = "ReacherDelivery: IRL pipeline (--task), rollout logs, replay, offline reward-machine learning",
    args_conflicts_with_subcommands = true
)]
struct Cli {
    #[command(subcommand)]
    command: Option<Command>,
    #[command(flatten)]
    pipeline: irl_cli::PipelineArgs,
}

#[derive(Subcommand)]
enum Command {
    /// Re-simulate every episode of a rollout log and compare with it bit for bit.
    Replay {
        file: PathBuf,
        /// Exit with status 1 if any episode differs from the log, the log holds no
        /// episode, or it was cut short (unless --allow-partial).
        #[arg(long)]
        verify: bool,
        /// Accept a log cut short (its complete episodes are used).
        #[arg(long)]
        allow_partial: bool,
    },
    /// Draw one logged episode top-down as PNG (arena, balls, arm poses, fingertip path,
    /// touches, cancel step).
    Render(RenderArgs),
    /// Learn a reward machine from the label traces of rollout logs.
    LearnRm(LearnRmArgs),
    /// Write a copy of a log with a Foxglove 3D scene (/scene: foxglove.SceneUpdate, /tf:
    /// foxglove.FrameTransforms) of the arm, balls, touches and cancel events.
    Foxglove(FoxgloveArgs),
    /// Log scripted demonstrations (ball sequence) to an MCAP file.
    Demo(DemoArgs),
    /// Train a task's SAC expert, evaluate it, save it and log 16 demonstrations.
    Expert(ExpertArgs),
    /// Step 1 of a run: demonstrations, learned machine and config into a run directory
    /// (takes the same options as `reacher --task`); prints the number of jobs.
    Prepare(irl_cli::PipelineArgs),
    /// Step 2: one (algorithm, seed) job of a prepared run (a finished job is not rerun).
    Job(irl_cli::JobArgs),
    /// Step 3: metrics, summary and plots of a run's finished jobs.
    Aggregate(irl_cli::AggregateArgs),
    /// f-IRL's own Reacher experiment (ReacherDraw): match a fingertip density with one
    /// baseline (maxent, fkl, rkl, js); forward and reverse KL per iteration.
    Draw(DrawArgs),
    /// Print a baseline's saved reward (rewards/<algo>_seed<k>.bin of maxent, fkl, rkl, js)
    /// at fingertip positions.
    Reward(RewardArgs),
}

#[derive(Args)]
struct RewardArgs {
    /// The reward file.
    file: PathBuf,
    /// Fingertip positions `x,y` (m), e.g. `--at 0.21,0 --at -0.0591,0.0104`.
    #[arg(long, required = true, allow_hyphen_values = true)]
    at: Vec<String>,
}

#[derive(Args)]
struct DrawArgs {
    /// maxent, fkl, rkl or js.
    #[arg(long)]
    algo: smirl::pipeline::reacher_irl::Algo,
    /// Target density: gaussian or mixture (overrides the config's `target`).
    #[arg(long)]
    target: Option<smirl::pipeline::reacher_draw::DrawTarget>,
    /// Run config (TOML, the fields of `DrawConfig`); f-IRL's settings otherwise.
    #[arg(long, conflicts_with = "quick")]
    config: Option<PathBuf>,
    /// Smoke profile: 6 short iterations (seconds).
    #[arg(long)]
    quick: bool,
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Run directory (config.toml, metrics.csv, summary.json, density.png); must not exist or
    /// be empty (or --force to replace one this program wrote).
    #[arg(long)]
    out: PathBuf,
    #[arg(long)]
    force: bool,
    /// No per-estimate lines.
    #[arg(long)]
    quiet: bool,
}

#[derive(Args)]
struct ExpertArgs {
    /// Task: or, sequential, if, composite (the paper's), blue (positive control).
    #[arg(long)]
    task: smirl::env::reacher_task::ReacherTask,
    /// Expert config (TOML: run settings, [sac], [env]); defaults otherwise.
    #[arg(long)]
    config: Option<PathBuf>,
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Continue a killed run from its last checkpoint in --out (or start one if --out has no
    /// checkpoint).
    #[arg(long)]
    resume: bool,
    /// Run directory (checkpoint, curve, evaluation, demos); default target/expert-runs/TASK.
    /// Must not exist or be empty, unless --resume (or --force to start over in one this
    /// program wrote).
    #[arg(long)]
    out: Option<PathBuf>,
    /// Start over in an existing run directory (only one this program wrote).
    #[arg(long, conflicts_with = "resume")]
    force: bool,
    /// Policy cache the trained actor is also copied to, as `expert_<task>.policy` (e.g.
    /// experiments/experts/cache, the committed experts, which the next build embeds); by
    /// default it stays in --out only.
    #[arg(long)]
    cache: Option<PathBuf>,
    /// Log every N-th training episode to OUT/train.mcap (1 = all, 0 = no training log; a
    /// resumed run writes the next free train.K.mcap).
    #[arg(long, default_value_t = 1, value_name = "N")]
    train_log_every: u64,
    /// No progress bar (e.g. for logs).
    #[arg(long)]
    quiet: bool,
}

#[derive(Args)]
struct RenderArgs {
    file: PathBuf,
    /// Episode id as `reacher replay` lists it [default: the first logged episode].
    #[arg(long)]
    episode: Option<u64>,
    /// PNG file to write (an existing file only with --force).
    #[arg(long)]
    out: PathBuf,
    /// Replace an existing --out file.
    #[arg(long)]
    force: bool,
    /// Side of the arena picture in pixels.
    #[arg(long, default_value_t = 480)]
    size: u32,
    /// Accept a log cut short (its complete episodes are used).
    #[arg(long)]
    allow_partial: bool,
    /// Arm poses drawn, evenly spaced over the episode.
    #[arg(long, default_value_t = 5)]
    poses: usize,
}

#[derive(Args)]
struct FoxgloveArgs {
    file: PathBuf,
    /// MCAP file to write (an existing file only with --force).
    #[arg(long)]
    out: PathBuf,
    /// Replace an existing --out file.
    #[arg(long)]
    force: bool,
    /// Accept a log cut short (its complete chunks are exported).
    #[arg(long)]
    allow_partial: bool,
}

#[derive(Args)]
struct LearnRmArgs {
    #[arg(required = true)]
    files: Vec<PathBuf>,
    /// Directory for learned_rm.txt and learned_rm.dot (existing ones only with --force).
    #[arg(long, default_value = ".")]
    out: PathBuf,
    /// Replace existing learned_rm.txt / learned_rm.dot in --out.
    #[arg(long)]
    force: bool,
    /// Reference machine to check equivalence with (e.g. assets/rm/reacher_sequential.txt).
    #[arg(long)]
    compare: Option<PathBuf>,
    /// Most states of the learned machine (LRM's u_max).
    #[arg(long, default_value_t = 10)]
    max_states: usize,
    /// Tabu search steps.
    #[arg(long, default_value_t = 100)]
    steps: usize,
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Accept logs cut short (their complete episodes are used).
    #[arg(long)]
    allow_partial: bool,
    /// Keep the search's machine instead of merging reward-indistinguishable states (demos
    /// that only ever show the task in order cannot tell its states apart by reward).
    #[arg(long)]
    no_merge: bool,
}

#[derive(Args)]
struct DemoArgs {
    /// MCAP file to write (an existing file only with --force).
    #[arg(long)]
    out: PathBuf,
    /// Replace an existing --out file.
    #[arg(long)]
    force: bool,
    /// Balls to visit, in order (r, g, b, y).
    #[arg(long, default_value = "rgby")]
    sequence: String,
    /// Task name; its perfect machine (assets/rm/reacher_<task>.txt) is tracked if it exists.
    #[arg(long, default_value = "sequential")]
    task: String,
    #[arg(long, default_value_t = 20)]
    episodes: u64,
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Chance of a cancel event per episode (the environment default is 0.5).
    #[arg(long)]
    cancel_probability: Option<f64>,
    /// Also store observations (larger file).
    #[arg(long)]
    observations: bool,
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        None => irl_cli::run(cli.pipeline),
        Some(Command::Replay {
            file,
            verify,
            allow_partial,
        }) => run_replay(file, verify, allow_partial),
        Some(Command::Render(args)) => run_render(args),
        Some(Command::LearnRm(args)) => run_learn_rm(args),
        Some(Command::Foxglove(args)) => run_foxglove(args),
        Some(Command::Demo(args)) => run_demo(args),
        Some(Command::Expert(args)) => run_expert(args),
        Some(Command::Prepare(args)) => irl_cli::prepare(args),
        Some(Command::Job(args)) => irl_cli::job(args),
        Some(Command::Aggregate(args)) => irl_cli::aggregate(args),
        Some(Command::Draw(args)) => run_draw(args),
        Some(Command::Reward(args)) => run_reward(args),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            if e.downcast_ref::<UsageError>().is_some()
                || e.downcast_ref::<irl_cli::PipelineUsage>().is_some()
            {
                ExitCode::from(2)
            } else {
                ExitCode::FAILURE
            }
        }
    }
}

fn run_reward(args: RewardArgs) -> Result<()> {
    let points = args
        .at
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
    let r = smirl::pipeline::reacher_irl::job::baseline_reward_at(&args.file, &points)
        .map_err(|e| UsageError(e.to_string()))?;
    for (p, r) in points.iter().zip(r) {
        println!("{} {} {r}", p[0], p[1]);
    }
    Ok(())
}

fn run_draw(args: DrawArgs) -> Result<()> {
    use smirl::pipeline::reacher_draw::{self as draw, DrawConfig};
    let mut config = match (&args.config, args.quick) {
        (Some(path), _) => DrawConfig::load(path).map_err(|e| UsageError(e.to_string()))?,
        (None, true) => DrawConfig::quick(),
        (None, false) => DrawConfig::default(),
    };
    if let Some(target) = args.target {
        config.target = target;
    }
    if args.algo.uses_rm() {
        return Err(UsageError(format!(
            "--algo {}: ReacherDraw runs maxent, fkl, rkl or js (no labelled events for SMIRL)",
            args.algo
        ))
        .into());
    }
    let output = OutputDir::check(&args.out, args.force).map_err(|e| UsageError(e.to_string()))?;
    let partial = output.begin()?;
    let result = draw::run_draw(args.algo, &config, args.seed, |row| {
        if !args.quiet {
            eprintln!(
                "iteration {:>5}  env steps {:>7}  KL(target||agent) {:>8.3}  KL(agent||target) {:>8.3}  {:.0} s",
                row.iteration, row.env_steps, row.forward_kl, row.reverse_kl, row.wall_secs
            );
        }
    })?;
    let summary = draw::write_run(&partial, args.algo, args.seed, &config, &result)
        .map_err(anyhow::Error::msg)?;
    output.commit(&partial)?;
    println!(
        "{} {} seed {}: forward KL {:.3} -> {:.3} ({:.0} %), reverse KL {:.3} -> {:.3} ({:.0} %), {:.0} s; wrote {}",
        summary.algo,
        config.target.name(),
        args.seed,
        summary.first_forward_kl,
        summary.last_forward_kl,
        100.0 * summary.forward_ratio,
        summary.first_reverse_kl,
        summary.last_reverse_kl,
        100.0 * summary.reverse_ratio,
        summary.wall_secs,
        args.out.display()
    );
    Ok(())
}

/// A log cut short is refused (exit 1) unless `allow_partial`; with it, a warning.
fn check_partial(log: &smirl::log::RolloutLog, allow_partial: bool) -> Result<()> {
    if let Some(rec) = &log.recovery {
        if !allow_partial {
            bail!(
                "{}: {rec}; pass --allow-partial to use its complete episodes",
                log.path.display()
            );
        }
        eprintln!("warning: {}: {rec}", log.path.display());
    }
    Ok(())
}

fn run_replay(file: PathBuf, verify: bool, allow_partial: bool) -> Result<()> {
    let log = read_log(&file)?;
    // Listing a partial log is harmless; verifying one is not a pass.
    check_partial(&log, allow_partial || !verify)?;
    let report = replay(&log)?;
    println!("{report}");
    if verify && report.episodes.is_empty() {
        bail!("{}: the log holds no episode to verify", file.display());
    }
    if verify && !report.all_match() {
        if report.version_differs {
            bail!(
                "{}: replay differs from the log (logged with MuJoCo {}, this is {})",
                file.display(),
                log.run.mujoco_version,
                smirl::mujoco::version_string()
            );
        }
        bail!(
            "{}: {} episode(s) differ from the log",
            file.display(),
            report.mismatches()
        );
    }
    Ok(())
}

fn run_render(args: RenderArgs) -> Result<()> {
    use smirl::pipeline::render::{render_episode, write_png, RenderOptions};
    check_file(&args.out, args.force).map_err(|e| UsageError(e.to_string()))?;
    let log = read_log(&args.file)?;
    check_partial(&log, args.allow_partial)?;
    let options = RenderOptions {
        size: args.size,
        poses: args.poses,
    };
    let picture = render_episode(&log, args.episode, &options)?;
    write_png(&args.out, &picture)?;
    let touches: Vec<String> = picture
        .touches
        .iter()
        .map(|(step, ball)| format!("{ball}@{step}"))
        .collect();
    println!(
        "wrote {}: episode {} [{}], {} steps, touches [{}], cancel {}{}",
        args.out.display(),
        picture.episode,
        picture.phase,
        picture.steps,
        touches.join(" "),
        picture
            .cancel_step
            .map_or("none".to_string(), |s| format!("at step {s}")),
        picture
            .branch
            .map_or(String::new(), |b| format!(", {b} branch"))
    );
    Ok(())
}

fn run_foxglove(args: FoxgloveArgs) -> Result<()> {
    check_file(&args.out, args.force).map_err(|e| UsageError(e.to_string()))?;
    let s =
        smirl::pipeline::foxglove_scene::export_scene(&args.file, &args.out, args.allow_partial)?;
    println!(
        "wrote {}: {} messages of the log, {} scene states of {} episodes (/scene, /tf); open it in Foxglove and add a 3D panel",
        s.out.display(),
        s.copied,
        s.scenes,
        s.episodes
    );
    Ok(())
}

fn run_learn_rm(args: LearnRmArgs) -> Result<()> {
    let cfg = LrmConfig {
        max_states: args.max_states,
        max_steps: args.steps,
        seed: args.seed,
        merge: !args.no_merge,
        ..LrmConfig::default()
    };
    // Every input and output is checked before the search runs.
    use smirl::rm::lrm::{MAX_SEARCH_STEPS, MAX_STATES};
    if !(1..=MAX_STATES).contains(&args.max_states) {
        return Err(UsageError(format!("--max-states must be in 1..={MAX_STATES}")).into());
    }
    if !(1..=MAX_SEARCH_STEPS).contains(&args.steps) {
        return Err(UsageError(format!("--steps must be in 1..={MAX_SEARCH_STEPS}")).into());
    }
    let txt = args.out.join("learned_rm.txt");
    let dot = args.out.join("learned_rm.dot");
    for path in [&txt, &dot] {
        check_file(path, args.force).map_err(|e| UsageError(e.to_string()))?;
    }
    let reference = match &args.compare {
        Some(path) => Some((
            path,
            smirl::rm::format::read_rm(path).map_err(|e| UsageError(format!("{e:#}")))?,
        )),
        None => None,
    };
    let result = learn_from_files(&args.files, &cfg, args.allow_partial)?;
    for w in &result.traces.warnings {
        eprintln!("warning: {w}");
    }
    let learned = &result.learned;
    println!(
        "{} traces ({} unfinished skipped, rewards: {}), {} transitions",
        result.traces.traces.len(),
        result.traces.skipped_unfinished,
        if result.traces.traces[0].rewards.is_some() {
            "RM rewards"
        } else {
            "none"
        },
        learned.stats.raw_transitions
    );
    println!(
        "learned RM: {} states (search found {}), cost {:.4}",
        learned.rm.n_states(),
        learned.stats.search_states,
        learned.cost
    );
    smirl::rm::format::save_rm(&txt, &learned.rm)
        .with_context(|| format!("cannot write {}", txt.display()))?;
    smirl::atomic_file::write_atomic(&dot, smirl::rm::dot::to_dot(&learned.rm).as_bytes())
        .with_context(|| format!("cannot write {}", dot.display()))?;
    println!("wrote {} and {}", txt.display(), dot.display());
    if let Some((reference, reference_rm)) = &reference {
        let c = compare(&learned.rm, reference_rm, &result.traces.traces)?;
        match c.counterexample {
            None => println!(
                "equivalent to {} (over the observed label sets)",
                reference.display()
            ),
            Some(cex) => println!(
                "NOT equivalent to {}: rewards differ on [{cex}]",
                reference.display()
            ),
        }
        match c.counterexample_until_done {
            None => println!("equivalent until the task is done (sequences stop at the reference's terminal states)"),
            Some(cex) => println!("differs before the task is done: rewards differ on [{cex}]"),
        }
    }
    Ok(())
}

fn run_demo(args: DemoArgs) -> Result<()> {
    check_file(&args.out, args.force).map_err(|e| UsageError(e.to_string()))?;
    let rm_name = format!("reacher_{}", args.task);
    let reward_machine = match smirl::rm::perfect::text(&rm_name) {
        Some(_) => Some(smirl::rm::perfect::load(&rm_name)?),
        None => None,
    };
    let mut env = ReacherConfig::default();
    if let Some(p) = args.cancel_probability {
        env.cancel.probability = p;
    }
    let spec = DemoSpec {
        task: args.task,
        sequence: args.sequence,
        episodes: args.episodes,
        seed: args.seed,
        stop_when_done: true,
        env,
        reward_machine,
    };
    let options = LogOptions {
        observations: args.observations,
        ..LogOptions::default()
    };
    let s = log_scripted_demos(&args.out, &spec, options)?;
    println!(
        "wrote {}: {} episodes, {} steps, {} bytes ({:.1} B/step)",
        s.path.display(),
        s.episodes_logged,
        s.steps_logged,
        s.bytes,
        s.bytes as f64 / s.steps_logged.max(1) as f64
    );
    Ok(())
}

/// A bad argument or config (exit status 2).
#[derive(Debug)]
struct UsageError(String);

impl std::fmt::Display for UsageError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for UsageError {}

fn run_expert(args: ExpertArgs) -> Result<()> {
    use indicatif::{ProgressBar, ProgressStyle};
    use smirl::pipeline::reacher_expert::ExpertConfig;
    use smirl::pipeline::reacher_expert as rx;
    use smirl::rl::sac::ActMode;

    let task = args.task;
    let config = match &args.config {
        Some(path) => ExpertConfig::load(path).map_err(|e| UsageError(e.to_string()))?,
        None => ExpertConfig::default(),
    };
    config
        .validate()
        .map_err(|e| UsageError(format!("expert config: {e}")))?;
    let out = args
        .out
        .unwrap_or_else(|| PathBuf::from(format!("target/expert-runs/{task}")));
    let checkpoint = out.join("expert.ckpt");
    // --resume continues the run whose checkpoint is in --out, or starts one there.
    if !(args.resume && checkpoint.is_file()) {
        let output = OutputDir::check(&out, args.force).map_err(|e| {
            UsageError(if out.join("expert.ckpt").exists() {
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
        let header = rx::train_log_header(task, &config, args.seed)?;
        let options = LogOptions {
            every_nth_episode: args.train_log_every,
            ..LogOptions::default()
        };
        Some(smirl::log::RolloutLogger::create(&path, header, options)?)
    } else {
        None
    };
    let started = std::time::Instant::now();
    let (mut policy, outcome) = rx::train_task_expert(
        task,
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

    let eval_seed = args.seed ^ 0x00e7_a100_0000_0000;
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
    let cached = match &args.cache {
        Some(cache) => {
            std::fs::create_dir_all(cache)
                .with_context(|| format!("cannot create {}", cache.display()))?;
            let path = rx::expert_cache_path(cache, task);
            policy.save(&path)?;
            Some(path)
        }
        None => None,
    };

    let curve_svg = out.join("curve.svg");
    rx::write_curve_svg(&curve_svg, task, &outcome.curve, config.progress_window)?;

    let demos_path = out.join("demos.mcap");
    let header = rx::demo_log_header(&policy, &config.env, args.seed)?;
    let options = LogOptions {
        observations: true,
        ..LogOptions::default()
    };
    let mut logger = smirl::log::RolloutLogger::create(&demos_path, header, options)?;
    let demos = rx::generate_demos(
        &mut policy,
        task,
        &config.env,
        rx::PAPER_DEMOS,
        args.seed,
        Some(&mut logger),
    )?;
    logger.finish()?;
    let demo_successes = demos.iter().filter(|d| d.success).count();
    let demo_branches = rx::branch_tally(task, &demos)?;

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
        git_commit: smirl::GIT_COMMIT.into(),
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
        "episodes with a cancel event: stochastic {}/{} successful, mean action {}/{}",
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
fn free_log_path(dir: &std::path::Path, stem: &str) -> PathBuf {
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

/// The top-level `reacher --task …` IRL pipeline (kept apart from the subcommands).
mod irl_cli {
    use anyhow::{Context, Result};
    use clap::Args;
    use indicatif::{MultiProgress, ProgressBar, ProgressStyle};
    use smirl::env::reacher_task::ReacherTask;
    use smirl::output::{check_not_protected, OutputDir};
    use smirl::pipeline::reacher_irl::job::JobProgress;
    use smirl::pipeline::reacher_irl::run::{
        self, open_run, summary_markdown, JobRecord, PreparedRun,
    };
    use smirl::pipeline::reacher_irl::{
        run_pipeline, Algo, IrlRunConfig, PipelineError, RunObserver, RunRequest,
    };
    use std::path::PathBuf;
    use std::sync::Mutex;

    /// Bad pipeline input (exit status 2).
    #[derive(Debug)]
    pub struct PipelineUsage(pub String);
    impl std::fmt::Display for PipelineUsage {
        fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
            f.write_str(&self.0)
        }
    }
    impl std::error::Error for PipelineUsage {}

    #[derive(Args)]
    pub struct PipelineArgs {
        /// Run the IRL pipeline on a task: or, sequential, if, composite, blue.
        #[arg(long)]
        task: Option<ReacherTask>,
        /// Algorithms, comma-separated: smirl, smirl-smooth, maxent, fkl, rkl, js, or all
        /// [default: smirl,smirl-smooth,maxent,fkl].
        #[arg(long)]
        algo: Option<String>,
        /// Number of seeds per algorithm (seeds S, S+1, …).
        #[arg(long, default_value_t = 1)]
        seeds: u64,
        /// Base seed S (also seeds the demonstrations and LRM).
        #[arg(long, default_value_t = 0)]
        seed: u64,
        /// Smoke profile (scripted demos, 4 short IRL iterations; a few minutes).
        #[arg(long)]
        quick: bool,
        /// Run configuration (TOML, every top-level field required; see
        /// experiments/reacher/config.toml). Overrides the built-in profile.
        #[arg(long, conflicts_with = "quick")]
        config: Option<PathBuf>,
        /// Run directory [default: runs/reacher-<task>]; must not exist, or be empty.
        #[arg(long)]
        out: Option<PathBuf>,
        /// Replace an existing run directory (only one this program wrote; never `.`, an
        /// ancestor of the working directory or the home directory).
        #[arg(long)]
        force: bool,
        /// Print the effective configuration as TOML and exit.
        #[arg(long)]
        print_config: bool,
        /// No progress bars.
        #[arg(long)]
        quiet: bool,
    }

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
                let last = r.rows.last().map_or(0.0, |x| x.success_rate);
                bar.finish_with_message(format!("done, final success {last:.2}"));
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

    #[derive(Args)]
    pub struct JobArgs {
        /// Run directory written by `reacher prepare`.
        #[arg(long)]
        run: PathBuf,
        /// The job's position in the run (algorithms outer, seeds inner, from 0), e.g. a Slurm
        /// array index.
        #[arg(long, conflicts_with_all = ["algo", "seed"], required_unless_present = "algo")]
        index: Option<usize>,
        /// The job's algorithm (with --seed).
        #[arg(long, requires = "seed")]
        algo: Option<Algo>,
        #[arg(long, requires = "algo")]
        seed: Option<u64>,
        /// No progress bar.
        #[arg(long)]
        quiet: bool,
    }

    #[derive(Args)]
    pub struct AggregateArgs {
        /// Run directory written by `reacher prepare`.
        dir: PathBuf,
        /// Aggregate the finished jobs even if some are missing.
        #[arg(long)]
        partial: bool,
    }

    fn usage(m: String) -> anyhow::Error {
        anyhow::Error::new(PipelineUsage(m))
    }

    fn pipeline_error(e: PipelineError) -> anyhow::Error {
        match e {
            PipelineError::Usage(m) => usage(m),
            PipelineError::Run(m) => anyhow::anyhow!(m),
        }
    }

    /// The run request of `reacher --task` / `reacher prepare` (`None`: `--print-config`
    /// printed the config, nothing to run).
    fn request(args: &PipelineArgs) -> Result<Option<RunRequest>> {
        let Some(task) = args.task else {
            return Err(usage(
                "nothing to do: give --task <or|sequential|if|composite|blue> or a subcommand (see --help)"
                    .into(),
            ));
        };
        let algos = match &args.algo {
            Some(s) => Algo::parse_list(s).map_err(usage)?,
            None => Algo::DEFAULT.to_vec(),
        };
        let config = match (&args.config, args.quick) {
            (Some(path), _) => IrlRunConfig::load(path).map_err(|e| usage(e.to_string()))?,
            (None, true) => IrlRunConfig::quick(),
            (None, false) => IrlRunConfig::standard(),
        };
        if args.print_config {
            print!("{}", config.to_toml());
            return Ok(None);
        }
        let out = args
            .out
            .clone()
            .unwrap_or_else(|| PathBuf::from(format!("runs/reacher-{}", task.name())));
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

    /// `reacher prepare`: writes `<out>.partial`, renamed to `<out>` when complete. A
    /// directory already prepared for the same plan and config is left as it is (so a
    /// resubmitted sweep does not redo it); any other existing `<out>` is refused.
    pub fn prepare(args: PipelineArgs) -> Result<()> {
        let Some(request) = request(&args)? else {
            return Ok(());
        };
        let out = &request.out;
        let planned_jobs = request.algos.len() as u64 * request.seeds;
        check_not_protected(out).map_err(|e| usage(e.to_string()))?;
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
        let output = OutputDir::check(out, false).map_err(|e| usage(e.to_string()))?;
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

    /// `reacher job`: one job of a prepared run.
    pub fn job(args: JobArgs) -> Result<()> {
        let run: PreparedRun = open_run(&args.run).map_err(pipeline_error)?;
        let (algo, seed) = match (args.index, args.algo, args.seed) {
            (Some(i), _, _) => run.job_at(i),
            (None, Some(a), Some(s)) => run.job(a, s),
            _ => Err(PipelineError::Usage(
                "give --index, or --algo and --seed".into(),
            )),
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
        let (record, ran) = run
            .run_job(algo, seed, &|p: JobProgress| {
                bar.set_position(p.env_steps);
                bar.set_message(format!(
                    "iter {}/{} success {:.2}",
                    p.iteration, p.iterations, p.success_rate
                ));
            })
            .map_err(|e| anyhow::anyhow!(e))
            .with_context(|| format!("{algo} seed {seed} in {}", args.run.display()))?;
        bar.finish_and_clear();
        let last = record.rows.last().map_or(0.0, |r| r.success_rate);
        if ran {
            println!(
                "{algo} seed {seed}: final success {last:.2} ({:.0} s)",
                record.wall_secs
            );
        } else {
            println!("{algo} seed {seed}: already done (final success {last:.2})");
        }
        Ok(())
    }

    /// `reacher aggregate`.
    pub fn aggregate(args: AggregateArgs) -> Result<()> {
        let run = open_run(&args.dir).map_err(pipeline_error)?;
        let summary = run::aggregate(&run, args.partial, None).map_err(pipeline_error)?;
        println!(
            "{}",
            summary_markdown(run.prepared.task, &summary.algos, summary.rm.as_ref())
        );
        println!("wrote {}", args.dir.join("metrics.csv").display());
        Ok(())
    }

    pub fn run(args: PipelineArgs) -> Result<()> {
        let Some(request) = request(&args)? else {
            return Ok(());
        };
        let (task, out) = (request.task, request.out.clone());
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
            Err(PipelineError::Usage(m)) => return Err(usage(m)),
            Err(PipelineError::Run(m)) => {
                return Err(anyhow::anyhow!(m)).with_context(|| {
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
            summary_markdown(task, &summary.algos, summary.rm.as_ref())
        );
        println!(
            "run directory: {} (total wall time {:.0} s)",
            summary.out.display(),
            summary.wall_secs
        );
        Ok(())
    }
}
