//! Benchmark: rollout-logging overhead against the same environment loop without a logger
//! (same run, interleaved repetitions, medians), bytes per step on disk, and replay speed.
//! The logged loop goes through the training hook as SAC's trainer drives it
//! ([`TrainingLog`]: Sequential's machine tracked along the labels, its state and reward
//! logged), so the figures are those of a training log.
//!
//! `cargo run --release --bin mcap_bench -- --reps 7 --episodes 200`

#![deny(unsafe_code)]

use anyhow::Result;
use clap::Parser;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use smirl::env::reacher::{ReacherConfig, ReacherDelivery};
use smirl::env::reacher_task::ReacherTask;
use smirl::env::ContinuousEnv;
use smirl::log::{read_log, LogOptions, RolloutLogger, RunHeader};
use smirl::pipeline::replay::replay;
use smirl::pipeline::training_log::TrainingLog;
use smirl::rl::sac::{EpisodeSummary, TrainingObserver};
use smirl::rm::RewardMachine;
use std::time::Instant;

mod common;
use common::median;

#[derive(Parser)]
#[command(about = "MCAP logging overhead, bytes/step and replay speed")]
struct Args {
    #[arg(long, default_value_t = 7)]
    reps: usize,
    /// Episodes (of 100 steps) per repetition.
    #[arg(long, default_value_t = 200)]
    episodes: u64,
}

/// CPU time this thread has run, in seconds (Linux `schedstat`, nanosecond resolution). Unlike
/// wall time it does not count the time the thread waited for a core, so it isolates what the
/// logger costs the environment's thread on a machine whose other core is busy.
fn thread_cpu_secs() -> Result<f64> {
    let text = std::fs::read_to_string("/proc/thread-self/schedstat")?;
    let ns: f64 = text
        .split_whitespace()
        .next()
        .and_then(|t| t.parse().ok())
        .ok_or_else(|| anyhow::anyhow!("unexpected /proc/thread-self/schedstat: {text:?}"))?;
    Ok(ns * 1e-9)
}

/// Runs the episodes with a smooth random policy (precomputed), optionally logging through
/// the training hook.
fn run(
    env: &mut ReacherDelivery,
    actions: &[[f32; 2]],
    episodes: u64,
    mut log: Option<&mut TrainingLog>,
) -> Result<f64> {
    let mut obs = vec![0.0f32; env.obs_dim()];
    let t = thread_cpu_secs()?;
    let mut k = 0;
    let observer_err = |e| anyhow::anyhow!("{e}");
    for ep in 0..episodes {
        env.reset(ep, &mut obs);
        if let Some(l) = log.as_deref_mut() {
            l.episode_started(env, ep, &obs).map_err(observer_err)?;
        }
        let mut length = 0;
        loop {
            let a = &actions[k % actions.len()];
            k += 1;
            length += 1;
            let step = env.step(a, &mut obs)?;
            if let Some(l) = log.as_deref_mut() {
                l.stepped(env, a, &step, &obs).map_err(observer_err)?;
            }
            if step.truncated {
                break;
            }
        }
        if let Some(l) = log.as_deref_mut() {
            let summary = EpisodeSummary {
                index: ep,
                env_return: 0.0,
                final_reward: 0.0,
                length,
                terminated: false,
            };
            l.episode_ended(env, &summary).map_err(observer_err)?;
        }
    }
    Ok(thread_cpu_secs()? - t)
}

fn main() -> Result<()> {
    let args = Args::parse();
    anyhow::ensure!(
        args.reps > 0 && args.episodes > 0,
        "--reps and --episodes must be positive"
    );
    let task = ReacherTask::shipped("sequential")?;
    let env_config = task.env_config(&ReacherConfig::default())?;
    let mut env = ReacherDelivery::new(env_config.clone())?;
    let task_rm: RewardMachine = task.perfect_rm()?;
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    let mut a = [0.0f32; 2];
    let actions: Vec<[f32; 2]> = (0..10_000)
        .map(|_| {
            for x in &mut a {
                *x = (0.8 * *x + 0.5 * rng.gen_range(-1.0f32..1.0)).clamp(-1.0, 1.0);
            }
            a
        })
        .collect();
    let steps = args.episodes as f64 * 100.0;
    let dir = tempfile_dir()?;
    let (mut plain, mut logged, mut bytes) = (vec![], vec![], vec![]);
    let (mut wall_overheads, mut cpu_overheads) = (vec![], vec![]);
    let mut last_file = None;
    for rep in 0..args.reps {
        let wall = Instant::now();
        let cpu_plain = run(&mut env, &actions, args.episodes, None)?;
        let t_plain = wall.elapsed().as_secs_f64();
        let path = dir.join(format!("bench{rep}.mcap"));
        let mut header = RunHeader::of_task(
            task.id(),
            task.task(),
            rep as u64,
            serde_json::json!({ "env": env_config }),
        );
        header.reward_machine = Some(smirl::rm::format::write_rm(&task_rm));
        let t = Instant::now();
        let cpu0 = thread_cpu_secs()?;
        let mut logger = RolloutLogger::create(&path, header, LogOptions::default())?;
        let mut log = TrainingLog::new(&mut logger, &task_rm, "train");
        run(&mut env, &actions, args.episodes, Some(&mut log))?;
        let summary = logger.finish()?;
        let cpu_logged = thread_cpu_secs()? - cpu0;
        // Everything the logger costs, including creating and finishing the file.
        let t_logged = t.elapsed().as_secs_f64();
        eprintln!(
            "rep {rep}: wall {:.2} / {:.2} us/step, env-thread CPU {:.2} / {:.2} us/step (plain / logged)",
            1e6 * t_plain / steps,
            1e6 * t_logged / steps,
            1e6 * cpu_plain / steps,
            1e6 * cpu_logged / steps
        );
        wall_overheads.push(t_logged / t_plain - 1.0);
        cpu_overheads.push(cpu_logged / cpu_plain - 1.0);
        plain.push(t_plain);
        logged.push(t_logged);
        bytes.push(summary.bytes as f64 / summary.steps_logged as f64);
        last_file = Some(path);
    }
    let path = last_file.expect("at least one repetition");
    let log = read_log(&path)?;
    let mut replay_rates = vec![];
    let mut all_match = true;
    for _ in 0..args.reps.min(3) {
        let r = replay(&log)?;
        all_match &= r.all_match();
        replay_rates.push(r.steps as f64 / r.elapsed_secs);
    }
    let (p, l) = (median(plain), median(logged));
    println!(
        "MuJoCo {}, {} reps x {} episodes x 100 steps, default LogOptions (zstd, no observations), \
         logged through the training hook with Sequential's machine tracked",
        smirl::mujoco::version_string(),
        args.reps,
        args.episodes
    );
    println!("env alone        : {:>7.2} us/step", 1e6 * p / steps);
    println!("env + logger     : {:>7.2} us/step", 1e6 * l / steps);
    println!(
        "logging overhead : {:>7.2} % of the env thread's CPU time per step (median of per-rep ratios; target <= 5 %)",
        100.0 * median(cpu_overheads)
    );
    println!(
        "  (wall clock    : {:>7.2} %; includes waiting for a core while the machine is loaded)",
        100.0 * median(wall_overheads)
    );
    println!(
        "bytes per step   : {:>7.1} B on disk (target <= 100)",
        median(bytes)
    );
    println!(
        "replay           : {:>7.0} steps/s, bit-exact: {all_match} (target >= 10000)",
        median(replay_rates)
    );
    std::fs::remove_dir_all(&dir).ok();
    Ok(())
}

fn tempfile_dir() -> Result<std::path::PathBuf> {
    let dir = std::env::temp_dir().join(format!("smirl_mcap_bench_{}", std::process::id()));
    // create_dir, not create_dir_all: the directory must be new, since it is removed at the end.
    std::fs::create_dir(&dir)?;
    Ok(dir)
}
