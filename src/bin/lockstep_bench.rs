//! Benchmark: one iteration's agent rollouts of f-IRL/MaxEnt (`--episodes` sampled episodes
//! of 100 steps of ReacherDelivery, a (64, 64) SAC actor, the trajectories kept for the reward
//! update) played one at a time against lockstep play at several batch
//! widths and thread counts, and against the environment alone (the same episodes' steps with
//! fixed actions: the physics limit). Interleaved repetitions; medians of per-repetition
//! ratios. Every lockstep variant is checked to give the one-at-a-time trajectories.
//!
//! `cargo run --release --bin lockstep_bench -- --reps 5 --episodes 300`

#![deny(unsafe_code)]

use anyhow::{ensure, Result};
use clap::Parser;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use smirl::env::reacher::{ReacherConfig, ReacherDelivery, ACT_DIM};
use smirl::env::reacher_task::ReacherTask;
use smirl::env::ContinuousEnv;
use smirl::pipeline::reacher_irl::episodes::{
    play_episode, AgentBatch, EpisodeSpec, GroundTruthTask,
};
use smirl::pipeline::reacher_irl::lockstep::{play_lockstep, Keep, Lockstep};
use smirl::rl::sac::{draw_noise, episode_seed, ActMode, SacAgent, SacConfig};
use std::time::Instant;

mod common;
use common::median;

#[derive(Parser)]
#[command(about = "Lockstep rollouts vs one-at-a-time rollouts vs the environment alone")]
struct Args {
    /// Repetitions of each measurement (medians are reported).
    #[arg(long, default_value_t = 5)]
    reps: usize,
    /// Episodes per measurement (f-IRL's standard schedule: 300).
    #[arg(long, default_value_t = 300)]
    episodes: u64,
    /// Lockstep batch widths, comma-separated.
    #[arg(long, default_value = "1,8,32,300")]
    batches: String,
    /// Also measure lockstep on this many threads (batch 32); 1 = not.
    #[arg(long, default_value_t = 2)]
    threads: usize,
}

fn main() -> Result<()> {
    let args = Args::parse();
    ensure!(
        args.reps > 0 && args.episodes > 0,
        "--reps and --episodes must be positive"
    );
    let batches: Vec<usize> = args
        .batches
        .split(',')
        .map(|b| b.trim().parse::<usize>())
        .collect::<Result<_, _>>()?;
    ensure!(batches.iter().all(|&b| b > 0), "--batches must be positive");
    let composite = ReacherTask::shipped("composite")?;
    let rm = composite.perfect_rm()?;
    let task = GroundTruthTask::of(&rm, &composite.layout());
    let mut env = ReacherDelivery::new(composite.env_config(&ReacherConfig::default())?)?;
    let obs_dim = env.obs_dim();
    let mut init = ChaCha8Rng::seed_from_u64(0);
    let mut agent = SacAgent::new(&SacConfig::default(), obs_dim, ACT_DIM, &mut init);
    let steps = env.config().max_steps;
    let specs: Vec<EpisodeSpec<'_>> = (0..args.episodes)
        .map(|i| EpisodeSpec {
            mode: ActMode::Sample,
            reset_seed: episode_seed(7, i),
            stop_when_decided: false,
            with_branch: false,
            phase: "agent",
        })
        .collect();
    let total_steps = args.episodes as f64 * steps as f64;

    // Variants: (label, batch, threads).
    let mut variants: Vec<(String, usize, usize)> = batches
        .iter()
        .map(|&b| (format!("lockstep batch {b:>3}, 1 thread "), b, 1))
        .collect();
    if args.threads > 1 {
        variants.push((
            format!("lockstep batch  32, {} threads", args.threads),
            32,
            args.threads,
        ));
    }
    let mut one_rates = Vec::new();
    let mut env_rates = Vec::new();
    let mut rates: Vec<Vec<f64>> = vec![Vec::new(); variants.len()];
    let mut ratios: Vec<Vec<f64>> = vec![Vec::new(); variants.len()];
    let mut env_ratios: Vec<Vec<f64>> = vec![Vec::new(); variants.len()];
    for rep in 0..args.reps {
        // One at a time, the noise drawn as it goes from one generator.
        let t = Instant::now();
        let mut rng = ChaCha8Rng::seed_from_u64(rep as u64);
        let mut reference = AgentBatch::default();
        for &spec in &specs {
            let mut len = 0;
            play_episode(&mut agent, &mut env, &task, spec, &mut rng, None, |a, u| {
                reference.push_step(a, u);
                len += 1;
            })
            .map_err(anyhow::Error::msg)?;
            reference.lengths.push(len);
        }
        let one = total_steps / t.elapsed().as_secs_f64();
        one_rates.push(one);

        // The environment alone: the same resets and steps, a fixed action.
        let t = Instant::now();
        let mut obs = vec![0.0f32; obs_dim];
        for spec in &specs {
            env.reset(spec.reset_seed, &mut obs);
            for _ in 0..steps {
                env.step(&[0.3, -0.2], &mut obs)?;
            }
        }
        let env_only = total_steps / t.elapsed().as_secs_f64();
        env_rates.push(env_only);

        for (v, (_, batch, threads)) in variants.iter().enumerate() {
            let t = Instant::now();
            let mut rng = ChaCha8Rng::seed_from_u64(rep as u64);
            let mut noise = vec![0.0f32; specs.len() * steps * ACT_DIM];
            draw_noise(&mut rng, &mut noise);
            let threads_now = || *threads;
            let plan = Lockstep {
                batch: *batch,
                threads: &threads_now,
            };
            let keep = Keep {
                log: false,
                steps: true,
            };
            let played = play_lockstep(&agent.actor, &env, &task, &specs, Some(&noise), plan, keep)
                .map_err(anyhow::Error::msg)?;
            let mut batch_steps = AgentBatch::default();
            for p in played {
                batch_steps.append(p.steps.unwrap_or_default());
            }
            let rate = total_steps / t.elapsed().as_secs_f64();
            ensure!(
                batch_steps.obs == reference.obs && batch_steps.lengths == reference.lengths,
                "{}: trajectories differ from one-at-a-time play",
                variants[v].0
            );
            rates[v].push(rate);
            ratios[v].push(rate / one);
            env_ratios[v].push(rate / env_only);
        }
        eprintln!("rep {rep}: one at a time {one:.0} steps/s, env alone {env_only:.0} steps/s");
    }
    println!(
        "{} episodes x {steps} steps, (64, 64) actor, {} reps (interleaved; medians)",
        args.episodes, args.reps
    );
    println!(
        "env alone (fixed action)        : {:>8.0} steps/s",
        median(&env_rates)
    );
    println!(
        "one at a time                   : {:>8.0} steps/s   ({:.3} of env alone)",
        median(&one_rates),
        median(
            one_rates
                .iter()
                .zip(&env_rates)
                .map(|(o, e)| o / e)
                .collect::<Vec<_>>()
        )
    );
    for (v, (label, _, _)) in variants.iter().enumerate() {
        println!(
            "{label}: {:>8.0} steps/s   x{:.2} one at a time, {:.3} of env alone",
            median(&rates[v]),
            median(&ratios[v]),
            median(&env_ratios[v])
        );
    }
    Ok(())
}
