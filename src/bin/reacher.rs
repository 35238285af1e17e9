//! `reacher`: the ReacherDelivery command line — clap argument structs and one call per
//! subcommand into [`smirl::pipeline::commands`], where the work is.
//!
//! - `reacher replay FILE.mcap [--verify] [--allow-partial]`: re-simulate logged episodes, check bit for bit.
//! - `reacher render FILE.mcap [--episode N] --out PIC.png`: draw one episode top-down.
//! - `reacher learn-rm FILES… [--out DIR] [--compare RM.txt]`: learn an RM from logged labels.
//! - `reacher demo --out FILE.mcap`: log scripted demonstrations (not the paper's SAC experts).
//! - `reacher foxglove FILE.mcap --out VIEW.mcap`: the log plus a Foxglove 3D scene.
//! - `reacher expert --task T`: train, evaluate and save the SAC expert of a task, with its
//!   training curve, its training episodes and 16 demonstrations in MCAP.
//! - `reacher draw --algo A --out DIR`: f-IRL's ReacherDraw with one baseline.
//! - `reacher reward FILE --at x,y`: a baseline's saved reward at fingertip positions.
//! - `reacher figure --data CURVES.csv --out FIG.svg`: learning curves as small multiples.
//!
//! - `reacher --task T [--algo A] [--seeds N] [--quick] …`: the IRL pipeline, in one
//!   process; the same run in three steps a scheduler can spread over machines:
//!   `reacher prepare --task T … --out DIR`, `reacher job --run DIR --index I` (one per job),
//!   `reacher aggregate DIR`.
//!
//! Exit status: 0 success, 1 failure while running, 2 bad arguments or config (clap's own
//! errors included). An error is printed once, by `main`.

#![deny(unsafe_code)]
// The doc comments of the argument structs are clap's `--help` text, read in a terminal:
// `<algo>` and `[sac]` there are placeholders and TOML tables, not HTML or links.
#![allow(rustdoc::invalid_html_tags, rustdoc::broken_intra_doc_links)]

use clap::{Args, Parser, Subcommand};
use smirl::env::reacher_task::ReacherTask;
use smirl::pipeline::commands::{
    self,
    draw::DrawRequest,
    expert::{CurveRequest, ExpertRequest},
    figure::FigureRequest,
    irl::IrlRequest,
    irl::JobRequest,
    irl::RetrainRequest,
    logs::DemoRequest,
    logs::LearnRmRequest,
    logs::RenderRequest,
};
use smirl::pipeline::reacher_draw::DrawTarget;
use smirl::pipeline::reacher_irl::Algo;
use std::path::PathBuf;
use std::process::ExitCode;

#[derive(Parser)]
#[command(
    about = "ReacherDelivery: IRL pipeline (--task), rollout logs, replay, offline reward-machine learning",
    version = concat!(env!("CARGO_PKG_VERSION"), " (commit ", env!("SMIRL_GIT_COMMIT"), ")"),
    args_conflicts_with_subcommands = true
)]
struct Cli {
    #[command(subcommand)]
    command: Option<Command>,
    #[command(flatten)]
    pipeline: PipelineArgs,
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
    /// Log scripted demonstrations (a sequence of regions) to an MCAP file.
    Demo(DemoArgs),
    /// Train a task's SAC expert, evaluate it, save it and log 16 demonstrations.
    Expert(ExpertArgs),
    /// Draw an expert's training-curve plots (success and return, moving averages) from the
    /// curve CSV `reacher expert` wrote.
    ExpertCurve(ExpertCurveArgs),
    /// Step 1 of a run: demonstrations, learned machine and config into a run directory
    /// (takes the same options as `reacher --task`); prints the number of jobs.
    Prepare(PipelineArgs),
    /// Step 2: one (algorithm, seed) job of a prepared run (a finished job is not rerun).
    Job(JobArgs),
    /// Step 3: metrics, summary and plots of a run's finished jobs.
    Aggregate(AggregateArgs),
    /// Train a fresh SAC agent on a finished job's final learned reward (held fixed) and judge
    /// it on the ground truth: does the reward solve the task once it stops moving?
    Retrain(RetrainArgs),
    /// f-IRL's own Reacher experiment (ReacherDraw): match a fingertip density with one
    /// baseline (maxent, fkl, rkl, js); forward and reverse KL per iteration.
    Draw(DrawArgs),
    /// Print a baseline's saved reward (rewards/<algo>_seed<k>.bin of maxent, fkl, rkl, js)
    /// at fingertip positions.
    Reward(RewardArgs),
    /// Draw learning curves as small multiples (one panel per task, each algorithm in its own
    /// colour, a second curve of an algorithm dashed) from a curve table: a CSV
    /// `panel,algo,curve,seed,x,y` with one row per point, as experiments/ scripts write it.
    Figure(FigureArgs),
}

#[derive(Args)]
struct FigureArgs {
    /// The curve table (CSV with the header `panel,algo,curve,seed,x,y`).
    #[arg(long)]
    data: PathBuf,
    /// The SVG to write.
    #[arg(long)]
    out: PathBuf,
    /// The figure's title.
    #[arg(long, default_value = "")]
    title: String,
    #[arg(long, default_value = "environment steps")]
    x_label: String,
    #[arg(long, default_value = "success rate")]
    y_label: String,
    /// The y axis of every panel, `LO,HI` (default: fitted to each panel's data).
    #[arg(long, allow_hyphen_values = true)]
    y_range: Option<String>,
    /// Panels per row.
    #[arg(long, default_value_t = 2)]
    columns: usize,
    /// Moving average of each seed's curve over this many consecutive points (1: none).
    #[arg(long, default_value_t = 1)]
    smooth: usize,
    /// Replace an existing --out.
    #[arg(long)]
    force: bool,
}

#[derive(Args)]
struct RetrainArgs {
    /// A prepared run directory.
    #[arg(long)]
    run: PathBuf,
    /// The job's algorithm.
    #[arg(long, value_parser = Algo::parse_reacher)]
    algo: Algo,
    /// The job's seed (its reward is rewards/<algo>_seed<seed>.*).
    #[arg(long)]
    seed: u64,
    /// SAC environment steps (default: the job's own, IRL iterations x SAC steps per iteration).
    #[arg(long)]
    steps: Option<u64>,
    /// Seed of the fresh SAC agent.
    #[arg(long, default_value_t = 1_000)]
    sac_seed: u64,
    /// Ground-truth evaluations during training, evenly spaced, the last at the end.
    #[arg(long, default_value_t = 5)]
    evaluations: u64,
    /// Set this learned-machine state's weights to zero first (repeatable; smirl and
    /// smirl-smooth): does that state's reward mislead the agent? The table is then
    /// retrain/<algo>_seed<S>_sac<K>_zero<U>[-<V>...].csv.
    #[arg(long, value_name = "U")]
    zero_state: Vec<usize>,
    /// A TOML file of agent settings in place of the job's: a [sac] table (never the
    /// reward, the machine or the environment): is the reward
    /// optimised better another way? The table's name then ends in _<the file's stem>.
    #[arg(long, value_name = "FILE")]
    agent: Option<PathBuf>,
    /// Replace an existing retrain/<algo>_seed<S>_sac<K>.csv.
    #[arg(long)]
    force: bool,
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
    #[arg(long, value_parser = Algo::parse_reacher)]
    algo: Algo,
    /// Target density: gaussian or mixture (overrides the config's `target`).
    #[arg(long)]
    target: Option<DrawTarget>,
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
struct ExpertCurveArgs {
    /// The expert's task (names the plots).
    #[arg(long)]
    task: ReacherTask,
    /// The training-curve CSV (`curve.csv` of an expert run directory).
    #[arg(long)]
    csv: PathBuf,
    /// The success plot (SVG).
    #[arg(long)]
    out: PathBuf,
    /// The return plot (SVG).
    #[arg(long)]
    out_return: PathBuf,
    /// Moving-average window in episodes (the expert config's progress_window).
    #[arg(long, default_value_t = 100)]
    window: usize,
    /// Replace existing plots.
    #[arg(long)]
    force: bool,
}

#[derive(Args)]
struct ExpertArgs {
    /// Task: or, sequential, if, composite (the paper's), blue (positive control), or the
    /// path of a task file (FILE.toml, see docs/tasks.md).
    #[arg(long)]
    task: ReacherTask,
    /// Expert config (TOML: run settings, [sac], [env]); defaults otherwise.
    #[arg(long)]
    config: Option<PathBuf>,
    /// Smoke run: 2 000 training steps and 20 evaluation episodes, to check a task end to end
    /// in seconds. Its policy is no expert, so it stays in --out and is never cached (unless
    /// --cache names a cache).
    #[arg(long, conflicts_with = "config")]
    quick: bool,
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
    /// experiments/experts/cache, the committed experts, which the next build embeds), or
    /// `expert_<name>-<content hash>.policy` for a task file; by default none for a shipped
    /// task and `experts/` beside a task file (where `reacher --task FILE` looks).
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
    /// Learn as plain LRM, with no declared events. By default the events are those the logs'
    /// task declares, read by the event rules of SMIRL's learner (the standard profile's
    /// lrm_* settings), as a run learns its machine.
    #[arg(long)]
    no_events: bool,
}

#[derive(Args)]
struct DemoArgs {
    /// MCAP file to write (an existing file only with --force).
    #[arg(long)]
    out: PathBuf,
    /// Replace an existing --out file.
    #[arg(long)]
    force: bool,
    /// Regions to visit, in order, as the task's letters (default: every region in the task
    /// file's order; Sequential's r, g, b, y).
    #[arg(long)]
    sequence: Option<String>,
    /// A shipped task's name or a task file's path; its machine is tracked and logged.
    #[arg(long, default_value = "sequential")]
    task: String,
    #[arg(long, default_value_t = 20)]
    episodes: u64,
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Chance of each of the task's events per episode, within its own window (default: the
    /// task file's).
    #[arg(long, alias = "cancel-probability")]
    event_probability: Option<f64>,
    /// Also store observations (larger file).
    #[arg(long)]
    observations: bool,
}

#[derive(Args)]
struct PipelineArgs {
    /// Run the IRL pipeline on a task: or, sequential, if, composite, blue, or the path of a
    /// task file (FILE.toml, see docs/tasks.md).
    #[arg(long)]
    task: Option<ReacherTask>,
    /// Algorithms, comma-separated: smirl, smirl-paper, smirl-smooth, maxent, fkl, rkl, js, or
    /// all (those seven); the controls maxent-product and fkl-product run only when named
    /// [default: smirl,smirl-paper,smirl-smooth,maxent,fkl].
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
    /// Expert config (TOML, the fields of `reacher expert --config`) for the expert trained
    /// first when a task file has none cached [default: the standard expert, 150 000 steps].
    #[arg(long, value_name = "FILE")]
    expert_config: Option<PathBuf>,
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

#[derive(Args)]
struct JobArgs {
    /// Run directory written by `reacher prepare`.
    #[arg(long)]
    run: PathBuf,
    /// The job's position in the run (algorithms outer, seeds inner, from 0), e.g. a Slurm
    /// array index.
    #[arg(long, conflicts_with_all = ["algo", "seed"], required_unless_present = "algo")]
    index: Option<usize>,
    /// The job's algorithm (with --seed).
    #[arg(long, requires = "seed", value_parser = Algo::parse_reacher)]
    algo: Option<Algo>,
    #[arg(long, requires = "algo")]
    seed: Option<u64>,
    /// No progress bar.
    #[arg(long)]
    quiet: bool,
}

#[derive(Args)]
struct AggregateArgs {
    /// Run directory written by `reacher prepare`.
    dir: PathBuf,
    /// Aggregate the finished jobs even if some are missing.
    #[arg(long)]
    partial: bool,
}

fn main() -> ExitCode {
    commands::exit_quietly_on_closed_pipe();
    match try_main(Cli::parse()) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {}", commands::error_message(&e));
            ExitCode::from(if commands::is_usage(&e) { 2 } else { 1 })
        }
    }
}

/// Runs the command `cli` names.
fn try_main(cli: Cli) -> anyhow::Result<()> {
    use commands::{draw, expert, irl, logs};
    match cli.command {
        None => irl::run(cli.pipeline.into()),
        Some(Command::Replay {
            file,
            verify,
            allow_partial,
        }) => logs::replay(&file, verify, allow_partial),
        Some(Command::Render(a)) => logs::render(RenderRequest {
            file: a.file,
            episode: a.episode,
            out: a.out,
            force: a.force,
            size: a.size,
            allow_partial: a.allow_partial,
            poses: a.poses,
        }),
        Some(Command::LearnRm(a)) => logs::learn_rm(LearnRmRequest {
            files: a.files,
            out: a.out,
            force: a.force,
            compare: a.compare,
            max_states: a.max_states,
            steps: a.steps,
            seed: a.seed,
            allow_partial: a.allow_partial,
            no_merge: a.no_merge,
            no_events: a.no_events,
        }),
        Some(Command::Foxglove(a)) => logs::foxglove(&a.file, &a.out, a.force, a.allow_partial),
        Some(Command::Demo(a)) => logs::demo(DemoRequest {
            out: a.out,
            force: a.force,
            sequence: a.sequence,
            task: a.task,
            episodes: a.episodes,
            seed: a.seed,
            event_probability: a.event_probability,
            observations: a.observations,
        }),
        Some(Command::Expert(a)) => expert::run(ExpertRequest {
            task: a.task,
            config: a.config,
            quick: a.quick,
            seed: a.seed,
            resume: a.resume,
            out: a.out,
            force: a.force,
            cache: a.cache,
            train_log_every: a.train_log_every,
            quiet: a.quiet,
        }),
        Some(Command::ExpertCurve(a)) => expert::redraw_curve(CurveRequest {
            task: a.task,
            csv: a.csv,
            out: a.out,
            out_return: a.out_return,
            window: a.window,
            force: a.force,
        }),
        Some(Command::Prepare(a)) => irl::prepare(a.into()),
        Some(Command::Job(a)) => irl::job(JobRequest {
            run: a.run,
            index: a.index,
            algo: a.algo,
            seed: a.seed,
            quiet: a.quiet,
        }),
        Some(Command::Aggregate(a)) => irl::aggregate(&a.dir, a.partial),
        Some(Command::Retrain(a)) => irl::retrain(RetrainRequest {
            run: a.run,
            algo: a.algo,
            seed: a.seed,
            steps: a.steps,
            sac_seed: a.sac_seed,
            evaluations: a.evaluations,
            zero_states: a.zero_state,
            agent: a.agent,
            force: a.force,
        }),
        Some(Command::Draw(a)) => draw::run(DrawRequest {
            algo: a.algo,
            target: a.target,
            config: a.config,
            quick: a.quick,
            seed: a.seed,
            out: a.out,
            force: a.force,
            quiet: a.quiet,
        }),
        Some(Command::Reward(a)) => irl::reward(&a.file, &a.at),
        Some(Command::Figure(a)) => commands::figure::run(FigureRequest {
            data: a.data,
            out: a.out,
            title: a.title,
            x_label: a.x_label,
            y_label: a.y_label,
            y_range: a.y_range,
            columns: a.columns,
            smooth: a.smooth,
            force: a.force,
        }),
    }
}

impl From<PipelineArgs> for IrlRequest {
    fn from(a: PipelineArgs) -> Self {
        IrlRequest {
            task: a.task,
            algo: a.algo,
            seeds: a.seeds,
            seed: a.seed,
            quick: a.quick,
            config: a.config,
            expert_config: a.expert_config,
            out: a.out,
            force: a.force,
            print_config: a.print_config,
            quiet: a.quiet,
        }
    }
}
