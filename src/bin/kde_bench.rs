//! Benchmark of the grid KDE against the naive double loop at f-IRL's per-iteration size:
//! fit 30 000 fingertip positions, evaluate at 30 000 queries (bandwidth 0.02).
//!
//! Four data sets: fingertip positions of ReacherDelivery rollouts under a uniformly random
//! policy (1000 episodes × 30 steps — clustered, the hard case for a grid), points uniform in
//! the reachable disc, the same fingertips beside a one-hot of a random state of a 12-state
//! machine (14-D: the density state of the product controls), and a policy that dwells: half
//! of the fingertips within 5 mm of one spot, beside a one-hot of a 5-state machine (7-D: an
//! agent resting at a ball, where a query's cells hold thousands of points). The naive loop is
//! timed on a subset of the queries and scaled to 30 000 (it is linear in the number of
//! queries); every time is the median of several repetitions in this run. Results go to
//! stdout and to `--out` (default `experiments/irl/kde_bench.txt`).

#![deny(unsafe_code)]

use anyhow::{Context, Result};
use clap::Parser;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use smirl::env::reacher::{ReacherConfig, ReacherDelivery, OBS_TIP};
use smirl::env::reacher_task::ReacherTask;
use smirl::env::ContinuousEnv;
use smirl::irl::kde::{brute_force_density, select_columns, Kde};
use std::fmt::Write as _;
use std::path::PathBuf;
use std::time::Instant;

mod common;
use common::median;

#[derive(Parser)]
#[command(about = "Grid Epanechnikov KDE vs the naive double loop (fit + evaluate)")]
struct Args {
    /// Fitted points and queries.
    #[arg(long, default_value_t = 30_000)]
    points: usize,
    /// Queries evaluated by the naive loop (its time is scaled to `points` queries).
    #[arg(long, default_value_t = 1_000)]
    naive_queries: usize,
    #[arg(long, default_value_t = 0.02)]
    bandwidth: f64,
    /// Repetitions; the median is reported.
    #[arg(long, default_value_t = 5)]
    reps: usize,
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Report file (an existing one only with --force).
    #[arg(long, default_value = "experiments/irl/kde_bench.txt")]
    out: PathBuf,
    /// Replace an existing --out file.
    #[arg(long)]
    force: bool,
}

/// Fingertip positions of random-policy episodes of 30 steps.
fn reacher_tips(n: usize, seed: u64) -> Result<Vec<f64>> {
    let config = ReacherTask::shipped("composite")?.env_config(&ReacherConfig::default())?;
    let mut env = ReacherDelivery::new(config).context("creating the env")?;
    let obs_dim = env.obs_dim();
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut obs = vec![0.0f32; obs_dim];
    let mut rows = Vec::with_capacity(n * obs_dim);
    let mut episode = 0u64;
    while rows.len() < n * obs_dim {
        env.reset(seed.wrapping_mul(1_000_003).wrapping_add(episode), &mut obs);
        episode += 1;
        for _ in 0..30 {
            let a = [rng.gen_range(-1.0..1.0), rng.gen_range(-1.0..1.0)];
            env.step(&a, &mut obs).context("stepping the env")?;
            rows.extend_from_slice(&obs);
            if rows.len() == n * obs_dim {
                break;
            }
        }
    }
    Ok(select_columns(&rows, obs_dim, &OBS_TIP)?)
}

fn disc_points(n: usize, seed: u64) -> Vec<f64> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    (0..n)
        .flat_map(|_| {
            let r = 0.21 * rng.gen_range(0.0f64..1.0).sqrt();
            let a = rng.gen_range(0.0..std::f64::consts::TAU);
            [r * a.cos(), r * a.sin()]
        })
        .collect()
}

/// `tips` with every other one moved to within 5 mm of `spot`.
fn dwelling(tips: &[f64], spot: [f64; 2], seed: u64) -> Vec<f64> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut out = tips.to_vec();
    for tip in out.chunks_exact_mut(2).step_by(2) {
        let r = 0.005 * rng.gen_range(0.0f64..1.0).sqrt();
        let a = rng.gen_range(0.0..std::f64::consts::TAU);
        tip.copy_from_slice(&[spot[0] + r * a.cos(), spot[1] + r * a.sin()]);
    }
    out
}

struct Row {
    name: &'static str,
    grid_s: f64,
    naive_s: f64,
    max_rel_err: f64,
}

/// `tips` (x, y rows) each after a one-hot of a machine state drawn uniformly of `states`.
fn with_machine_states(tips: &[f64], states: usize, seed: u64) -> Vec<f64> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut rows = Vec::with_capacity(tips.len() / 2 * (states + 2));
    for tip in tips.chunks_exact(2) {
        let u = rng.gen_range(0..states);
        rows.extend((0..states).map(|s| if s == u { 1.0 } else { 0.0 }));
        rows.extend_from_slice(tip);
    }
    rows
}

fn bench(name: &'static str, fit: &[f64], queries: &[f64], dim: usize, args: &Args) -> Result<Row> {
    let h = args.bandwidth;
    let nq = queries.len() / dim;
    let mut out = vec![0.0; nq];
    let mut grid_times = Vec::new();
    for _ in 0..args.reps {
        let t = Instant::now();
        let kde = Kde::fit(fit, dim, h)?;
        kde.density_batch(queries, &mut out);
        grid_times.push(t.elapsed().as_secs_f64());
        std::hint::black_box(&out);
    }
    let sub = args.naive_queries.min(nq);
    let mut naive = vec![0.0; sub];
    let mut naive_times = Vec::new();
    for _ in 0..args.reps {
        let t = Instant::now();
        for (q, o) in queries.chunks_exact(dim).take(sub).zip(naive.iter_mut()) {
            *o = brute_force_density(fit, dim, h, q);
        }
        naive_times.push(t.elapsed().as_secs_f64() * nq as f64 / sub as f64);
        std::hint::black_box(&naive);
    }
    let max_rel_err = naive
        .iter()
        .zip(&out)
        .map(|(b, g)| (b - g).abs() / b.abs().max(1e-300))
        .filter(|e| e.is_finite())
        .fold(0.0, f64::max);
    Ok(Row {
        name,
        grid_s: median(grid_times),
        naive_s: median(naive_times),
        max_rel_err,
    })
}

fn main() -> Result<()> {
    let args = Args::parse();
    smirl::output::check_file(&args.out, args.force)?;
    anyhow::ensure!(args.reps >= 1, "--reps must be at least 1");
    anyhow::ensure!(args.points >= 1, "--points must be at least 1");
    anyhow::ensure!(
        args.naive_queries >= 1,
        "--naive-queries must be at least 1"
    );
    let n = args.points;
    let tips = reacher_tips(2 * n, args.seed)?;
    let (tip_fit, tip_query) = tips.split_at(2 * n);
    let disc = disc_points(2 * n, args.seed ^ 0x5eed);
    let (disc_fit, disc_query) = disc.split_at(2 * n);
    const STATES: usize = 12;
    let product_fit = with_machine_states(tip_fit, STATES, args.seed ^ 0xf17);
    let product_query = with_machine_states(tip_query, STATES, args.seed ^ 0x9e7);
    const DWELL_STATES: usize = 5;
    let spot = [tip_fit[0], tip_fit[1]];
    let dwell_fit = with_machine_states(
        &dwelling(tip_fit, spot, args.seed ^ 0xd1),
        DWELL_STATES,
        args.seed ^ 0xd2,
    );
    let dwell_query = with_machine_states(
        &dwelling(tip_query, spot, args.seed ^ 0xd3),
        DWELL_STATES,
        args.seed ^ 0xd4,
    );
    let rows = [
        bench("reacher random-policy tips", tip_fit, tip_query, 2, &args)?,
        bench("uniform in reachable disc", disc_fit, disc_query, 2, &args)?,
        bench(
            "tips + 12-state one-hot",
            &product_fit,
            &product_query,
            STATES + 2,
            &args,
        )?,
        bench(
            "dwelling tips + 5-state",
            &dwell_fit,
            &dwell_query,
            DWELL_STATES + 2,
            &args,
        )?,
    ];
    let mut text = String::new();
    writeln!(
        text,
        "kde_bench: Epanechnikov KDE, 2-D, 14-D and 7-D, bandwidth {}, fit {n} points + evaluate {n} queries; \
         median of {} reps; naive loop timed on {} queries and scaled to {n}",
        args.bandwidth, args.reps, args.naive_queries
    )?;
    writeln!(text, "commit {}", smirl::GIT_COMMIT)?;
    writeln!(
        text,
        "{:<28} {:>12} {:>12} {:>9} {:>14}",
        "data", "grid (s)", "naive (s)", "speed-up", "max rel. err"
    )?;
    for r in &rows {
        writeln!(
            text,
            "{:<28} {:>12.4} {:>12.3} {:>8.0}x {:>14.2e}",
            r.name,
            r.grid_s,
            r.naive_s,
            r.naive_s / r.grid_s,
            r.max_rel_err
        )?;
    }
    print!("{text}");
    if let Some(dir) = args.out.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    }
    let tmp = args.out.with_extension("txt.tmp");
    std::fs::write(&tmp, &text).with_context(|| format!("writing {}", tmp.display()))?;
    std::fs::rename(&tmp, &args.out)
        .with_context(|| format!("renaming {} to {}", tmp.display(), args.out.display()))?;
    Ok(())
}
