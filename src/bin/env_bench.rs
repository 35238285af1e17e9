//! Benchmark: ReacherDelivery steps per second on the shipped model against the raw FFI step
//! loop on the same model (the limit) and against the environment on the first model
//! (`assets/reacher_delivery_v1.xml`: balls on slide joints, contact pass on), all measured in
//! the same run (interleaved repetitions, medians of per-repetition ratios); and what one
//! episode reset costs in environment steps (f-IRL resets 1 000 times per iteration for
//! 30-step episodes, so a reset worth many steps is a large share of its sampling).
//!
//! `cargo run --release --bin env_bench -- --reps 7 --steps 20000`

#![deny(unsafe_code)]

use clap::Parser;
use smirl::assets::{REACHER_V1_XML, REACHER_V1_XML_NAME};
use smirl::env::reacher::{ReacherConfig, ReacherDelivery, FRAME_SKIP};
use smirl::env::reacher_task::ReacherTask;
use smirl::env::ContinuousEnv;
use smirl::mujoco::{self, Data, Model};
use std::sync::Arc;
use std::time::Instant;

#[derive(Parser)]
#[command(about = "ReacherDelivery steps/s vs the raw mj_step loop and vs the first model")]
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

/// Environment steps per second over `steps` steps of a fixed action, resetting at truncation.
fn env_rate(env: &mut ReacherDelivery, steps: usize, obs: &mut [f32]) -> anyhow::Result<f64> {
    let action = [0.3f32, -0.2];
    let t = Instant::now();
    let mut episode = 0u64;
    env.reset(episode, obs);
    for _ in 0..steps {
        let step = env.step(&action, obs)?;
        if step.truncated {
            episode += 1;
            env.reset(episode, obs);
        }
    }
    Ok(steps as f64 / t.elapsed().as_secs_f64())
}

/// Environment steps per second of the bare `mj_step` loop (FRAME_SKIP calls a step).
fn raw_rate(data: &mut Data, steps: usize) -> f64 {
    data.reset();
    let t = Instant::now();
    mujoco::raw_step_loop(data, &[0.3, -0.2], steps, FRAME_SKIP);
    steps as f64 / t.elapsed().as_secs_f64()
}

fn main() -> anyhow::Result<()> {
    let args = Args::parse();
    anyhow::ensure!(
        args.reps > 0 && args.steps > 0,
        "--reps and --steps must be positive"
    );
    let config = ReacherTask::shipped("composite")?.env_config(&ReacherConfig::default())?;
    let mut env = ReacherDelivery::new(config.clone())?;
    let mut raw = Data::new(Arc::clone(env.model()))?;
    let v1_model = Arc::new(Model::from_xml_str(REACHER_V1_XML, REACHER_V1_XML_NAME)?);
    let mut env_v1 = ReacherDelivery::with_model(Arc::clone(&v1_model), config)?;
    let mut raw_v1 = Data::new(v1_model)?;
    let mut obs = vec![0.0f32; env.obs_dim()];

    let (mut raw_rates, mut env_rates, mut raw_v1_rates, mut env_v1_rates) =
        (vec![], vec![], vec![], vec![]);
    let mut reset_costs = vec![];
    let resets = (args.steps / 10).max(1);
    for rep in 0..args.reps {
        raw_rates.push(raw_rate(&mut raw, args.steps));
        env_rates.push(env_rate(&mut env, args.steps, &mut obs)?);
        raw_v1_rates.push(raw_rate(&mut raw_v1, args.steps));
        env_v1_rates.push(env_rate(&mut env_v1, args.steps, &mut obs)?);

        let t = Instant::now();
        for episode in 0..resets {
            env.reset(episode as u64, &mut obs);
        }
        let reset_secs = t.elapsed().as_secs_f64() / resets as f64;
        reset_costs.push(reset_secs * env_rates[rep]);
        eprintln!(
            "rep {rep}: raw {:.0}, env {:.0}, raw v1 {:.0}, env v1 {:.0} steps/s",
            raw_rates[rep], env_rates[rep], raw_v1_rates[rep], env_v1_rates[rep]
        );
    }
    let ratio = |a: &[f64], b: &[f64]| median(a.iter().zip(b).map(|(x, y)| x / y).collect());
    let env_vs_raw = ratio(&env_rates, &raw_rates);
    let env_vs_v1 = ratio(&env_rates, &env_v1_rates);
    let raw_vs_raw_v1 = ratio(&raw_rates, &raw_v1_rates);
    let v1_env_vs_raw = ratio(&env_v1_rates, &raw_v1_rates);
    let reset_cost = median(reset_costs);
    println!(
        "MuJoCo {} ({} steps x {} reps, {FRAME_SKIP} mj_step per env step, one thread)",
        mujoco::version_string(),
        args.steps,
        args.reps
    );
    for (name, rates) in [
        ("raw FFI loop, shipped model ", &raw_rates),
        ("ReacherDelivery, shipped    ", &env_rates),
        ("raw FFI loop, first model   ", &raw_v1_rates),
        ("ReacherDelivery, first model", &env_v1_rates),
    ] {
        let m = median(rates.clone());
        println!("{name}: {m:>9.0} steps/s ({:.1} us/step)", 1e6 / m);
    }
    println!("ratio env shipped / env first model: {env_vs_v1:.3} (target >= 1.5)");
    println!("ratio env shipped / raw shipped    : {env_vs_raw:.3} (target >= 0.9)");
    println!("ratio raw shipped / raw first model: {raw_vs_raw_v1:.3}");
    println!("ratio env first / raw first model  : {v1_env_vs_raw:.3}");
    println!(
        "episode reset (shipped): {:.1} us = {reset_cost:.2} env steps (median per rep; target <= 1)",
        reset_cost * 1e6 / median(env_rates)
    );
    Ok(())
}
