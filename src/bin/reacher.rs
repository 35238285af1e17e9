//! `reacher`: the ReacherDelivery command line — a thin clap front over library functions.
//!
//! - `reacher replay FILE.mcap [--verify]`: re-simulate logged episodes, check bit for bit.
//! - `reacher learn-rm FILES… [--out DIR] [--compare RM.txt]`: learn an RM from logged labels.
//! - `reacher demo --out FILE.mcap`: log scripted demonstrations (not the paper's SAC experts).

use anyhow::{bail, Context, Result};
use clap::{Args, Parser, Subcommand};
use smirl::env::reacher::ReacherConfig;
use smirl::log::demo::{log_scripted_demos, DemoSpec};
use smirl::log::{read_log, LogOptions};
use smirl::pipeline::offline_rm::{compare, learn_from_files};
use smirl::pipeline::replay::replay;
use smirl::rm::lrm::LrmConfig;
use std::path::PathBuf;

#[derive(Parser)]
#[command(about = "ReacherDelivery: rollout logs, replay, offline reward-machine learning")]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Re-simulate every episode of a rollout log and compare with it bit for bit.
    Replay {
        file: PathBuf,
        /// Exit with status 1 if any episode differs from the log.
        #[arg(long)]
        verify: bool,
    },
    /// Learn a reward machine from the label traces of rollout logs.
    LearnRm(LearnRmArgs),
    /// Log scripted demonstrations (ball sequence) to an MCAP file.
    Demo(DemoArgs),
}

#[derive(Args)]
struct LearnRmArgs {
    #[arg(required = true)]
    files: Vec<PathBuf>,
    /// Directory for learned_rm.txt and learned_rm.dot.
    #[arg(long, default_value = ".")]
    out: PathBuf,
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
    /// Keep the search's machine instead of merging reward-indistinguishable states (demos
    /// that only ever show the task in order cannot tell its states apart by reward).
    #[arg(long)]
    no_merge: bool,
}

#[derive(Args)]
struct DemoArgs {
    #[arg(long)]
    out: PathBuf,
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

fn main() -> Result<()> {
    match Cli::parse().command {
        Command::Replay { file, verify } => run_replay(file, verify),
        Command::LearnRm(args) => run_learn_rm(args),
        Command::Demo(args) => run_demo(args),
    }
}

fn run_replay(file: PathBuf, verify: bool) -> Result<()> {
    let log = read_log(&file)?;
    if let Some(rec) = &log.recovery {
        eprintln!("warning: {}: {rec}", file.display());
    }
    let report = replay(&log)?;
    println!("{report}");
    if verify && (!report.all_match() || report.episodes.is_empty()) {
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

fn run_learn_rm(args: LearnRmArgs) -> Result<()> {
    let cfg = LrmConfig {
        max_states: args.max_states,
        max_steps: args.steps,
        seed: args.seed,
        merge: !args.no_merge,
        ..LrmConfig::default()
    };
    let result = learn_from_files(&args.files, &cfg)?;
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
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("cannot create {}", args.out.display()))?;
    let txt = args.out.join("learned_rm.txt");
    smirl::rm::format::save_rm(&txt, &learned.rm)
        .with_context(|| format!("cannot write {}", txt.display()))?;
    let dot = args.out.join("learned_rm.dot");
    write_atomically(&dot, &smirl::rm::dot::to_dot(&learned.rm))?;
    println!("wrote {} and {}", txt.display(), dot.display());
    if let Some(reference) = &args.compare {
        let reference_rm = smirl::rm::format::read_rm(reference)?;
        let c = compare(&learned.rm, &reference_rm, &result.traces.traces)?;
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

fn write_atomically(path: &std::path::Path, text: &str) -> Result<()> {
    let tmp = path.with_extension("tmp");
    std::fs::write(&tmp, text).with_context(|| format!("cannot write {}", tmp.display()))?;
    std::fs::rename(&tmp, path).with_context(|| format!("cannot write {}", path.display()))
}

fn run_demo(args: DemoArgs) -> Result<()> {
    let rm_path = smirl::rm::perfect::path(&format!("reacher_{}", args.task));
    let reward_machine = if rm_path.exists() {
        Some(smirl::rm::format::read_rm(&rm_path)?)
    } else {
        None
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
