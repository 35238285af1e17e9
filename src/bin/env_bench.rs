//! Benchmark: ReacherDelivery steps per second on the model it steps (the shipped scene without
//! its four mocap balls) against the raw FFI step loop on the same model (the limit), against
//! the environment on the whole shipped scene and on the first model
//! (`assets/reacher_delivery_v1.xml`: balls on slide joints, contact pass on), all measured in
//! the same run (interleaved repetitions, medians of per-repetition ratios); and what one
//! episode reset costs in environment steps (f-IRL resets 1 000 times per iteration for
//! 30-step episodes, so a reset worth many steps is a large share of its sampling).
//!
//! `cargo run --release --bin env_bench -- --reps 7 --steps 20000`

#![deny(unsafe_code)]

use clap::Parser;
use smirl::assets::{REACHER_V1_XML, REACHER_V1_XML_NAME, REACHER_XML, REACHER_XML_NAME};
use smirl::env::reacher::{ReacherConfig, ReacherDelivery, FRAME_SKIP};
use smirl::env::reacher_task::ReacherTask;
use smirl::env::ContinuousEnv;
use smirl::mujoco::{self, Data, Model};
use std::sync::Arc;
use std::time::Instant;

mod common;
use common::median;

#[derive(Parser)]
#[command(
    about = "ReacherDelivery steps/s vs the raw mj_step loop and vs the whole and first models"
)]
struct Args {
    /// Repetitions of each measurement (the median is reported).
    #[arg(long, default_value_t = 7)]
    reps: usize,
    /// Environment steps per repetition.
    #[arg(long, default_value_t = 20_000)]
    steps: usize,
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
    // The three models: the one the environment steps (the scene without its balls), the
    // whole shipped scene, and the first scene.
    let mut env = ReacherDelivery::new(config.clone())?;
    let scene_model = Arc::new(Model::from_xml_str(REACHER_XML, REACHER_XML_NAME)?);
    let v1_model = Arc::new(Model::from_xml_str(REACHER_V1_XML, REACHER_V1_XML_NAME)?);
    let mut env_scene = ReacherDelivery::with_model(Arc::clone(&scene_model), config.clone())?;
    let mut env_v1 = ReacherDelivery::with_model(Arc::clone(&v1_model), config)?;
    let mut raw = Data::new(Arc::clone(env.model()))?;
    let mut raw_scene = Data::new(scene_model)?;
    let mut raw_v1 = Data::new(v1_model)?;
    let mut obs = vec![0.0f32; env.obs_dim()];

    // Per repetition: raw, env, raw scene, env scene, raw v1, env v1.
    let mut rates: [Vec<f64>; 6] = Default::default();
    let mut reset_costs = vec![];
    let resets = (args.steps / 10).max(1);
    for rep in 0..args.reps {
        rates[0].push(raw_rate(&mut raw, args.steps));
        rates[1].push(env_rate(&mut env, args.steps, &mut obs)?);
        rates[2].push(raw_rate(&mut raw_scene, args.steps));
        rates[3].push(env_rate(&mut env_scene, args.steps, &mut obs)?);
        rates[4].push(raw_rate(&mut raw_v1, args.steps));
        rates[5].push(env_rate(&mut env_v1, args.steps, &mut obs)?);

        let t = Instant::now();
        for episode in 0..resets {
            env.reset(episode as u64, &mut obs);
        }
        let reset_secs = t.elapsed().as_secs_f64() / resets as f64;
        reset_costs.push(reset_secs * rates[1][rep]);
        let now: Vec<String> = rates.iter().map(|r| format!("{:.0}", r[rep])).collect();
        eprintln!(
            "rep {rep}: raw, env / raw, env scene / raw, env v1: {} steps/s",
            now.join(", ")
        );
    }
    let ratio =
        |a: &[f64], b: &[f64]| median(a.iter().zip(b).map(|(x, y)| x / y).collect::<Vec<_>>());
    let reset_cost = median(reset_costs);
    println!(
        "MuJoCo {} ({} steps x {} reps, {FRAME_SKIP} mj_step per env step, one thread)",
        mujoco::version_string(),
        args.steps,
        args.reps
    );
    let names = [
        "raw FFI loop, physics model  ",
        "ReacherDelivery (physics)    ",
        "raw FFI loop, shipped scene  ",
        "ReacherDelivery, whole scene ",
        "raw FFI loop, first model    ",
        "ReacherDelivery, first model ",
    ];
    for (name, r) in names.iter().zip(&rates) {
        let m = median(r);
        println!("{name}: {m:>9.0} steps/s ({:.1} us/step)", 1e6 / m);
    }
    for (name, a, b, target) in [
        ("env / env on the first model ", 1, 5, " (target >= 1.5)"),
        ("env / raw on the physics model", 1, 0, " (target >= 0.9)"),
        ("env / env on the whole scene  ", 1, 3, ""),
        ("env whole scene / raw scene   ", 3, 2, ""),
        ("env first model / raw first   ", 5, 4, ""),
    ] {
        println!("ratio {name}: {:.3}{target}", ratio(&rates[a], &rates[b]));
    }
    println!(
        "episode reset: {:.1} us = {reset_cost:.2} env steps (median per rep; target <= 1)",
        reset_cost * 1e6 / median(&rates[1])
    );
    Ok(())
}
