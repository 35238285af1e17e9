//! Benchmark of the LRM learner on expert-like Office traces (and ReacherDelivery OR /
//! Sequential): per task, the median time of several runs, the cost, the state counts and
//! whether the learned machine is equivalent to (and refines) the perfect one.
//!
//! `cargo run --release --bin lrm_bench -- [--steps 100000] [--reps 5] [--threads 2]`
//!
//! The reference figure to compare against is printed by the same run: the perfect machine's
//! own cost on the traces (the learner should reach it or less). The target from the issue is
//! under 5 s per Office task at 100 000 transitions on 2 cores.

use anyhow::{bail, Context, Result};
use smirl::rm::equiv::{counterexample, refines, state_counts};
use smirl::rm::lrm::synthetic::{expert_like_traces, ExpertStyle};
use smirl::rm::lrm::{learn_rm, observed_label_sets, trace_cost, LrmConfig};
use smirl::rm::perfect;
use smirl::rm::transform::restart_on_goal;
use std::time::Instant;

struct Args {
    steps: usize,
    reps: usize,
    threads: usize,
    seed: u64,
    search_steps: usize,
    max_states: usize,
}

fn parse_args() -> Result<Args> {
    let mut a = Args {
        steps: 100_000,
        reps: 5,
        threads: 2,
        seed: 1,
        search_steps: LrmConfig::default().max_steps,
        max_states: LrmConfig::default().max_states,
    };
    let mut it = std::env::args().skip(1);
    while let Some(flag) = it.next() {
        let mut value = |name: &str| -> Result<usize> {
            let v = it.next().with_context(|| format!("{name} needs a value"))?;
            v.parse()
                .with_context(|| format!("{name}: expected a number, got {v:?}"))
        };
        match flag.as_str() {
            "--steps" => a.steps = value("--steps")?,
            "--reps" => a.reps = value("--reps")?.max(1),
            "--threads" => a.threads = value("--threads")?.max(1),
            "--seed" => a.seed = value("--seed")? as u64,
            "--search-steps" => a.search_steps = value("--search-steps")?,
            "--max-states" => a.max_states = value("--max-states")?.max(1),
            other => {
                bail!("unknown argument {other:?} (expected --steps, --reps, --threads, --seed, --search-steps, --max-states)")
            }
        }
    }
    Ok(a)
}

fn median(mut xs: Vec<f64>) -> f64 {
    xs.sort_by(f64::total_cmp);
    xs[xs.len() / 2]
}

fn main() -> Result<()> {
    let args = parse_args()?;
    println!(
        "lrm_bench: {} transitions per task, median of {} runs, {} threads, seed {}, git {}",
        args.steps,
        args.reps,
        args.threads,
        args.seed,
        if smirl::GIT_COMMIT.is_empty() {
            "unknown"
        } else {
            smirl::GIT_COMMIT
        }
    );
    println!(
        "{:<20} {:>8} {:>9} {:>10} {:>10} {:>6} {:>7} {:>7} {:>6} {:>8} {:>8}",
        "task",
        "median_s",
        "compr_pos",
        "cost",
        "perf_cost",
        "raw_u",
        "final_u",
        "perf_u",
        "equiv",
        "refines",
        "raw_ref"
    );
    let tasks: Vec<(&str, ExpertStyle)> = vec![
        ("office_t1", ExpertStyle::office()),
        ("office_t2", ExpertStyle::office()),
        ("office_t3", ExpertStyle::office()),
        ("office_t4", ExpertStyle::office()),
        ("office_t0", ExpertStyle::office()),
        ("reacher_or", ExpertStyle::reacher()),
        ("reacher_sequential", ExpertStyle::reacher()),
    ];
    for (name, style) in tasks {
        let perfect_rm = perfect::load(name).with_context(|| format!("loading {name}"))?;
        let traces = expert_like_traces(&perfect_rm, &style, args.steps, args.seed);
        let cfg = LrmConfig {
            threads: args.threads,
            seed: args.seed,
            max_steps: args.search_steps,
            max_states: args.max_states,
            ..LrmConfig::default()
        };
        let mut times = Vec::new();
        let mut last = None;
        for _ in 0..args.reps {
            let t0 = Instant::now();
            let learned = learn_rm(perfect_rm.vocab(), &traces, &cfg)?;
            times.push(t0.elapsed().as_secs_f64());
            last = Some(learned);
        }
        let learned = last.expect("reps >= 1");
        let target = if style.one_trip {
            perfect_rm.clone()
        } else {
            restart_on_goal(&perfect_rm)
        };
        let alphabet = observed_label_sets(&traces);
        let equiv = counterexample(&learned.rm, &target, Some(&alphabet))?;
        let label_traces: Vec<&[smirl::rm::LabelSet]> =
            traces.iter().map(|t| t.labels.as_slice()).collect();
        let refi = refines(&learned.rm, &target, label_traces.iter().copied());
        let raw_refi = refines(&learned.raw, &target, label_traces.iter().copied());
        let perf_counts = state_counts(&target, Some(&alphabet))?;
        println!(
            "{:<20} {:>8.3} {:>9} {:>10.1} {:>10.1} {:>6} {:>7} {:>7} {:>6} {:>8} {:>8}",
            name,
            median(times),
            learned.stats.compressed_positions,
            learned.cost,
            trace_cost(&target, &traces)?,
            learned.raw.n_states(),
            learned.rm.n_states(),
            perf_counts.minimal,
            equiv.is_none(),
            refi.refines,
            raw_refi.refines,
        );
        if let Some(cx) = equiv {
            let v = perfect_rm.vocab();
            let shown: Vec<String> = cx
                .iter()
                .map(|&l| format!("{{{}}}", v.format_labels(l)))
                .collect();
            println!("    counter-example: {}", shown.join(" "));
        }
    }
    Ok(())
}
