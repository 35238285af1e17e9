//! Benchmark of the LRM learner: per task, with and without rewards, the median time of
//! several runs, the cost of the learned machine against the perfect one's, the state counts
//! and whether the learned machine refines / is equivalent to the perfect one.
//!
//! `cargo run --release --bin lrm_bench -- [--steps 100000] [--reps 3] [--threads 2]`
//!
//! Traces: Office tasks 0–4 from the real experts of paper appendix B
//! ([`OfficeExpert::demonstrations`]: optimal trips on the grid, 5 random steps after each
//! completed trip, episodes of 100 steps, a plant ends the episode); ReacherDelivery OR,
//! Sequential, IF and Composite from the synthetic expert-like generator (no Reacher expert
//! exists without SAC training), which walks to the task's regions and fires its events
//! (the letters of the shipped task's layout).
//!
//! The target is the perfect machine restarted after its goal for Office (the demonstrations
//! repeat the task), the perfect machine itself for Reacher (one trip per episode).
//! - `cost` / `perf_cost`: the learner's objective for the learned machine (before merging)
//!   and for the target on the same traces (with rewards the target's reward term is 0).
//! - `refines`: along every trace, the target's state is a function of the learned state
//!   (`raw` machine without rewards, merged machine with rewards), over the states each step
//!   is *read in* (initial state and the states after every step but the last): the state
//!   after a trace's last step is never used (not by the objective, not by SMIRL's
//!   annotation u_{t-1}), and no trace can say what it is (an Office plant only ever ends an
//!   episode).
//! - `equiv`: with rewards, the merged machine pays the same rewards as the target on every
//!   sequence over the label sets read at a non-final step of some trace; without rewards
//!   (nothing to compare outputs with) the raw machine and the target refine each other
//!   along the traces (a bijection of states).
//!
//! The speed target is under 5 s per Office task at 100 000 transitions on 2 cores.

#![deny(unsafe_code)]

use anyhow::{Context, Result};
use clap::Parser;
use smirl::env::office::OfficeTask;
use smirl::env::reacher_task::ReacherTask;
use smirl::irl::tabular::{DemoConfig, OfficeExpert};
use smirl::rm::equiv::{counterexample, refines, state_counts};
use smirl::rm::lrm::synthetic::{expert_like_traces, ExpertStyle};
use smirl::rm::lrm::{learn_rm, trace_cost, LabelTrace, LrmConfig, TraceReading};
use smirl::rm::transform::restart_on_goal;
use smirl::rm::{LabelSet, RewardMachine};
use std::time::Instant;

mod common;
use common::median;

#[derive(Parser)]
#[command(about = "LRM learner benchmark: time, cost and equivalence per task")]
struct Args {
    /// Transitions per task.
    #[arg(long, default_value_t = 100_000)]
    steps: usize,
    /// Runs per task; the median time is reported.
    #[arg(long, default_value_t = 3, value_parser = at_least_one)]
    reps: usize,
    /// Threads of the learner's search.
    #[arg(long, default_value_t = 2, value_parser = at_least_one)]
    threads: usize,
    /// Seed of the traces and the search.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Tabu search steps per start.
    #[arg(long, default_value_t = LrmConfig::default().max_steps)]
    search_steps: usize,
    /// Most states of a learned machine.
    #[arg(long, default_value_t = LrmConfig::default().max_states, value_parser = at_least_one)]
    max_states: usize,
    /// Starts of the tabu search.
    #[arg(long, default_value_t = LrmConfig::default().starts, value_parser = at_least_one)]
    starts: usize,
    /// A start ends after this many steps without improving (0 = run all search steps).
    #[arg(long, default_value_t = LrmConfig::default().patience)]
    patience: usize,
    /// No split move and no initial-state split (with `--starts 1 --patience 0`: the
    /// reference search).
    #[arg(long = "no-split", action = clap::ArgAction::SetFalse)]
    split_moves: bool,
    /// When merging, let an unobserved cell take the behaviour of the state it merges with.
    #[arg(long)]
    fill_unobserved: bool,
    /// Only the tasks whose name starts with this (`office_`, `reacher_or`, …).
    #[arg(long)]
    only: Option<String>,
}

/// A count of at least one.
fn at_least_one(text: &str) -> Result<usize, String> {
    match text.parse::<usize>() {
        Ok(n) if n >= 1 => Ok(n),
        _ => Err(format!(
            "expected a whole number of at least 1, got {text:?}"
        )),
    }
}

/// Label sets read at a non-final step of some trace (those whose effect is observable).
fn read_label_sets(traces: &[LabelTrace]) -> Vec<LabelSet> {
    let mut v: Vec<LabelSet> = traces
        .iter()
        .flat_map(|t| t.labels[..t.labels.len().saturating_sub(1)].iter().copied())
        .collect();
    v.sort();
    v.dedup();
    v
}

fn yn(b: bool) -> &'static str {
    if b {
        "y"
    } else {
        "n"
    }
}

fn main() -> Result<()> {
    let args = Args::parse();
    println!(
        "lrm_bench: {} transitions per task, median of {} runs, {} threads, seed {}, {} starts, patience {}, split moves {}, git {}",
        args.steps,
        args.reps,
        args.threads,
        args.seed,
        args.starts,
        args.patience,
        args.split_moves,
        if smirl::GIT_COMMIT.is_empty() {
            "unknown"
        } else {
            smirl::GIT_COMMIT
        }
    );
    println!(
        "{:<20} {:>4} {:>8} {:>10} {:>10} {:>5} {:>7} {:>6} {:>7} {:>5}",
        "task",
        "rew",
        "median_s",
        "cost",
        "perf_cost",
        "raw_u",
        "final_u",
        "perf_u",
        "refines",
        "equiv"
    );
    let mut tasks: Vec<(String, RewardMachine, Vec<LabelTrace>)> = Vec::new();
    for k in 0..5 {
        let task = OfficeTask::shipped(&k.to_string())
            .with_context(|| format!("the shipped Office task {k}"))?;
        let expert = OfficeExpert::new(&task);
        let demos = expert.demonstrations(&DemoConfig {
            n_demos: args.steps.div_ceil(100),
            horizon: 100,
            random_steps: 5,
            seed: args.seed,
        });
        let traces = demos
            .iter()
            .filter(|d| !d.is_empty())
            .map(|d| LabelTrace {
                labels: d.labels.clone(),
                rewards: Some(d.rewards.clone()),
            })
            .collect();
        tasks.push((format!("office_t{k}"), restart_on_goal(expert.rm()), traces));
    }
    for name in ["or", "sequential", "if", "composite"] {
        let task = ReacherTask::shipped(name)
            .with_context(|| format!("the shipped ReacherDelivery task {name}"))?;
        let rm = task.perfect_rm()?;
        let layout = task.layout();
        let style = ExpertStyle::reacher(&layout.region_letters(), &layout.event_letters());
        let traces = expert_like_traces(&rm, &style, args.steps, args.seed);
        tasks.push((format!("reacher_{name}"), rm, traces));
    }
    for (name, target, traces) in &tasks {
        if args
            .only
            .as_ref()
            .is_some_and(|o| !name.starts_with(o.as_str()))
        {
            continue;
        }
        let alphabet = read_label_sets(traces);
        let read: Vec<&[LabelSet]> = traces
            .iter()
            .map(|t| &t.labels[..t.labels.len().saturating_sub(1)])
            .collect();
        let perf_u = state_counts(target, Some(&alphabet))?.minimal;
        for with_rewards in [false, true] {
            let traces: Vec<LabelTrace> = traces
                .iter()
                .map(|t| LabelTrace {
                    labels: t.labels.clone(),
                    rewards: if with_rewards {
                        t.rewards.clone()
                    } else {
                        None
                    },
                })
                .collect();
            let cfg = LrmConfig {
                threads: args.threads,
                seed: args.seed,
                max_steps: args.search_steps,
                max_states: args.max_states,
                starts: args.starts,
                patience: args.patience,
                split_moves: args.split_moves,
                split_initial: args.split_moves,
                fill_unobserved: args.fill_unobserved,
                // Without rewards merging has nothing to go by (it would merge everything).
                merge: with_rewards,
                ..LrmConfig::default()
            };
            let mut times = Vec::new();
            let mut last = None;
            for _ in 0..args.reps {
                let t0 = Instant::now();
                let learned = learn_rm(target.vocab(), &traces, &cfg)?;
                times.push(t0.elapsed().as_secs_f64());
                last = Some(learned);
            }
            let learned = last.expect("reps >= 1");
            let machine = if with_rewards {
                &learned.rm
            } else {
                &learned.raw
            };
            let fine = refines(machine, target, read.iter().copied());
            let (equiv, cx) = if with_rewards {
                let cx = counterexample(machine, target, Some(&alphabet))?;
                (cx.is_none(), cx)
            } else {
                let back = refines(target, machine, read.iter().copied());
                (fine.refines && back.refines, None)
            };
            println!(
                "{:<20} {:>4} {:>8.3} {:>10.1} {:>10.1} {:>5} {:>7} {:>6} {:>7} {:>5}",
                name,
                yn(with_rewards),
                median(times),
                learned.cost,
                trace_cost(target, &traces, TraceReading::default())?,
                learned.raw.n_states(),
                learned.rm.n_states(),
                perf_u,
                yn(fine.refines),
                yn(equiv),
            );
            if let Some(cx) = cx {
                let v = target.vocab();
                let shown: Vec<String> = cx
                    .iter()
                    .map(|&l| format!("{{{}}}", v.format_labels(l)))
                    .collect();
                println!("    counter-example: {}", shown.join(" "));
            }
        }
    }
    Ok(())
}
