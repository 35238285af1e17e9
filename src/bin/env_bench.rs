//! Benchmark: ReacherDelivery steps per second against the raw FFI step loop on the same
//! model, measured in the same run (interleaved repetitions, medians); and what one episode
//! reset costs in environment steps (f-IRL resets 1 000 times per iteration for 30-step
//! episodes, so a reset worth many steps is a large share of its sampling).
//!
//! `cargo run --release --bin env_bench -- --reps 7 --steps 20000`

use clap::Parser;
use smirl::env::reacher::{ReacherConfig, ReacherDelivery, FRAME_SKIP};
use smirl::env::reacher_task::ReacherTask;
use smirl::env::ContinuousEnv;
use smirl::mujoco::{self, Data};
use std::sync::Arc;
use std::time::Instant;

#[derive(Parser)]
#[command(about = "ReacherDelivery steps/s vs the raw mj_step loop")]
struct Args {
    /// Repetitions of each measurement (the median is reported).
    #[arg(long, default_value_t = 7)]
    reps: usize,
    /// Environment steps per repetition.
    #[arg(long, default_value_t = 20_000)]
    steps: usize,
}

fn median(mut xs: Vec<f64>) -> f64 {
    xs.sort_by(f64::total_cmp);
    xs[xs.len() / 2]
}

fn main() -> anyhow::Result<()> {
    let args = Args::parse();
    anyhow::ensure!(
        args.reps > 0 && args.steps > 0,
        "--reps and --steps must be positive"
    );
    let config = ReacherTask::shipped("composite")?.env_config(&ReacherConfig::default())?;
    let mut env = ReacherDelivery::new(config)?;
    let mut raw = Data::new(Arc::clone(env.model()))?;
    let action = [0.3f32, -0.2];
    let ctrl = [0.3f64, -0.2];
    let mut obs = vec![0.0f32; env.obs_dim()];

    let (mut raw_rates, mut env_rates, mut reset_costs) = (vec![], vec![], vec![]);
    let resets = (args.steps / 10).max(1);
    for rep in 0..args.reps {
        raw.reset();
        let t = Instant::now();
        mujoco::raw_step_loop(&mut raw, &ctrl, args.steps, FRAME_SKIP);
        raw_rates.push(args.steps as f64 / t.elapsed().as_secs_f64());

        let t = Instant::now();
        let mut episode = 0u64;
        env.reset(episode, &mut obs);
        for _ in 0..args.steps {
            let step = env.step(&action, &mut obs)?;
            if step.truncated {
                episode += 1;
                env.reset(episode, &mut obs);
            }
        }
        env_rates.push(args.steps as f64 / t.elapsed().as_secs_f64());

        let t = Instant::now();
        for episode in 0..resets {
            env.reset(episode as u64, &mut obs);
        }
        let reset_secs = t.elapsed().as_secs_f64() / resets as f64;
        reset_costs.push(reset_secs * env_rates[rep]);
        eprintln!(
            "rep {rep}: raw {:.0} steps/s, env {:.0} steps/s",
            raw_rates[rep], env_rates[rep]
        );
    }
    let ratios: Vec<f64> = env_rates
        .iter()
        .zip(&raw_rates)
        .map(|(e, r)| e / r)
        .collect();
    let (raw_med, env_med) = (median(raw_rates), median(env_rates));
    let reset_cost = median(reset_costs);
    println!(
        "MuJoCo {} ({} steps x {} reps, {FRAME_SKIP} mj_step per env step)",
        mujoco::version_string(),
        args.steps,
        args.reps
    );
    println!(
        "raw FFI loop      : {raw_med:>9.0} steps/s ({:.1} us/step)",
        1e6 / raw_med
    );
    println!(
        "ReacherDelivery   : {env_med:>9.0} steps/s ({:.1} us/step)",
        1e6 / env_med
    );
    println!(
        "ratio env/raw     : {:.3} (median of per-rep ratios; target >= 0.9)",
        median(ratios)
    );
    println!(
        "episode reset     : {:.1} us = {reset_cost:.2} env steps (median per rep; target <= 1)",
        reset_cost * 1e6 / env_med
    );
    Ok(())
}
