//! SMIRL's mechanisms outside LRM, ablated on the development range: runs the `smirl` job of
//! seed S of a prepared run directory (`reacher prepare --algo smirl`) with one or more
//! mechanisms off, and writes it as `reacher job` would, under
//! `<run>/ablation/<mechanism>[+<mechanism>…]/` (`jobs/smirl_seed<S>.json`, its reward and log),
//! beside the run's own jobs with every mechanism on.
//! `experiments/reacher/mechanisms/ablation.py` runs its plan and makes the table.
//!
//! `cargo run --release --bin smirl_ablation -- --run DIR --seed S --without clock[,shaping…]`
//!
//! Mechanisms (`--without`, in this order in the directory name): `clock`,
//! `counterfactual_states`, `event_gated_visits`, `shaping` (`[smirl] shaping` = 0),
//! `final_phase` (no final phase: the loop's own policy is reported), `reset_agent`
//! (`[final] reset_steps` = 0) and `selection_cut`. The plan runs the first four only: the
//! other three change nothing before the final choice, and a job's record holds every
//! candidate with its learned return, cut return and final-set score, so the table reads their
//! ablations from the job with every mechanism on (`tests/mechanism_ablation.rs` checks that
//! this gives what a run without them reports). A job whose record exists is not run again.

use anyhow::{Context, Result};
use clap::Parser;
use smirl::pipeline::reacher_irl::records::PreparedRun;
use smirl::pipeline::reacher_irl::run::open_run;
use smirl::pipeline::reacher_irl::{Algo, IrlRunConfig};
use std::path::PathBuf;

/// The mechanisms this binary turns off, by name, in directory-name order.
const MECHANISMS: [&str; 7] = [
    "clock",
    "counterfactual_states",
    "event_gated_visits",
    "shaping",
    "final_phase",
    "reset_agent",
    "selection_cut",
];

/// `config` with `mechanism` off.
fn turn_off(c: &mut IrlRunConfig, mechanism: &str) {
    match mechanism {
        "clock" => c.mechanisms.clock = false,
        "counterfactual_states" => c.mechanisms.counterfactual_states = false,
        "event_gated_visits" => c.mechanisms.event_gated_visits = false,
        "shaping" => c.smirl_shaping = 0.0,
        "final_phase" => {
            c.final_sac_steps = 0;
            c.final_checkpoints = 0;
            c.final_reset_steps = 0;
        }
        "reset_agent" => c.final_reset_steps = 0,
        "selection_cut" => c.mechanisms.selection_cut = false,
        other => unreachable!("{other} is checked against MECHANISMS"),
    }
}

/// The mechanisms of `--without`, each known and once, in [`MECHANISMS`] order.
#[derive(Clone, Debug)]
struct Without(Vec<&'static str>);

fn parse_mechanisms(text: &str) -> Result<Without, String> {
    let given: Vec<&str> = text.split(',').map(str::trim).collect();
    if let Some(g) = given.iter().find(|g| !MECHANISMS.contains(g)) {
        return Err(format!(
            "{g}: not a mechanism this ablation turns off (one of {})",
            MECHANISMS.join(", ")
        ));
    }
    let out: Vec<&'static str> = MECHANISMS
        .iter()
        .copied()
        .filter(|m| given.contains(m))
        .collect();
    if out.len() != given.len() {
        return Err(format!("{text}: a mechanism named twice"));
    }
    Ok(Without(out))
}

#[derive(Parser)]
#[command(
    about = "SMIRL's job of a prepared run directory with mechanisms turned off",
    version = concat!(env!("CARGO_PKG_VERSION"), " (commit ", env!("SMIRL_GIT_COMMIT"), ")")
)]
struct Args {
    /// A run directory prepared by `reacher prepare --algo smirl`.
    #[arg(long = "run")]
    run_dir: PathBuf,
    /// The job's seed, one of the run's own.
    #[arg(long)]
    seed: u64,
    /// The mechanisms turned off, comma-separated (see the module docs).
    #[arg(long, value_parser = parse_mechanisms)]
    without: Without,
}

fn main() -> Result<()> {
    let Args {
        run_dir,
        seed,
        without: Without(without),
    } = Args::parse();
    let run = open_run(&run_dir).with_context(|| format!("{}", run_dir.display()))?;
    // The run's own plan decides which seeds exist (the ablation adds no job of its own).
    run.job(Algo::Smirl, seed)?;
    let mut config = run.config.clone();
    for m in &without {
        turn_off(&mut config, m);
    }
    let name = without.join("+");
    let dir = run_dir.join("ablation").join(&name);
    std::fs::create_dir_all(&dir).with_context(|| format!("creating {}", dir.display()))?;
    // The job reads the prepared inputs from memory and writes only under `dir`.
    let variant = PreparedRun {
        dir: dir.clone(),
        config,
        ..run
    };
    let threads = variant.config.threads;
    let (record, ran) = variant
        .run_job(Algo::Smirl, seed, &|| threads, &|_| {})
        .map_err(|e| anyhow::anyhow!(e.to_string()))
        .with_context(|| format!("smirl seed {seed} without {name} in {}", dir.display()))?;
    let last = record.rows.last().map_or(f64::NAN, |r| r.success_rate);
    println!(
        "smirl seed {seed} without {name}: last iteration {last:.2}{} ({:.0} s)",
        if ran { "" } else { ", already done" },
        record.wall_secs
    );
    Ok(())
}
