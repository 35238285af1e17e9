//! LRM's mechanisms ablated on the development range, without SAC: for each task and base
//! seed, the demonstrations `reacher prepare --task T --seed B` makes (the standard config),
//! and the machine LRM learns from them under each variant: `standard` (`smirl`'s learner),
//! one mechanism off at a time, `paper` (`smirl-paper`'s, the paper's eq. 1) and
//! `without_contested` (the mechanisms the fold rule of docs/method.md does not keep on the
//! evidence, off together).
//!
//! `cargo run --release --bin lrm_ablation -- --tasks or,if --bases 0,3-105 --out rows.csv`
//!
//! One CSV row per (task, base, variant), appended and flushed as it is computed (a run cut
//! short keeps its rows; a (task, base, variant) already in `--out` is skipped):
//! `determined` says whether the task's perfect machine's state is a function of the learned
//! machine's on every label sequence the task can produce, until the task ends
//! (`rm::language::undetermined`); the perfect machine is read by this report only, after
//! learning. `cost` is the learned machine's LRM cost under its variant's objective,
//! `perfect_cost` the perfect machine's under the same reading of the traces.

use anyhow::{bail, Context, Result};
use clap::Parser;
use smirl::env::reacher_task::ReacherTask;
use smirl::irl::Algo;
use smirl::pipeline::reacher_irl::demos::{load_expert, make_demos};
use smirl::pipeline::reacher_irl::smirl::{label_traces, lrm_config};
use smirl::pipeline::reacher_irl::IrlRunConfig;
use smirl::rm::language::{undetermined, Failures, LabelLanguage, Undetermined};
use smirl::rm::lrm::{learn_rm, observed_label_sets, trace_cost, trace_reading, Guards, LrmConfig};
use smirl::rm::LabelSet;
use std::collections::HashSet;
use std::io::Write;

fn parse_bases(text: &str) -> Result<Vec<u64>> {
    let mut out = Vec::new();
    for part in text.split(',').filter(|p| !p.is_empty()) {
        match part.split_once('-') {
            Some((a, b)) => {
                let (a, b): (u64, u64) = (a.parse()?, b.parse()?);
                if b < a || b - a > 100_000 {
                    bail!("--bases: bad range {part}");
                }
                out.extend(a..=b);
            }
            None => out.push(part.parse().with_context(|| format!("--bases: {part}"))?),
        }
    }
    Ok(out)
}

#[derive(Parser)]
#[command(about = "LRM's mechanisms ablated without SAC: one CSV row per (task, base, variant)")]
struct Args {
    /// Shipped task names, comma-separated.
    #[arg(long, default_value = "or,sequential,if,composite")]
    tasks: String,
    /// Base seeds: numbers and ranges `a-b`, comma-separated.
    #[arg(long, default_value = "0")]
    bases: String,
    /// CSV the rows are appended to (a row already in it is not computed again).
    #[arg(long)]
    out: String,
}

fn main() -> Result<()> {
    let Args { tasks, bases, out } = Args::parse();
    let bases = parse_bases(&bases)?;
    let header = "task,base,variant,demos,states,cost,perfect_cost,determined,counterexample,determined_seen,counterexample_seen,determined_failures,counterexample_failures,secs";
    let done: HashSet<(String, u64, String)> = match std::fs::read_to_string(&out) {
        Ok(text) => text
            .lines()
            .skip(1)
            .filter_map(|l| {
                let f: Vec<&str> = l.split(',').collect();
                Some((
                    f.first()?.to_string(),
                    f.get(1)?.parse().ok()?,
                    f.get(2)?.to_string(),
                ))
            })
            .collect(),
        Err(_) => HashSet::new(),
    };
    let fresh = !std::path::Path::new(&out).exists();
    let mut file = std::fs::OpenOptions::new()
        .create(true)
        .append(true)
        .open(&out)
        .with_context(|| format!("{out}: cannot open"))?;
    if fresh {
        writeln!(file, "{header}")?;
    }
    for name in tasks.split(',') {
        let task = ReacherTask::shipped(name)?;
        let perfect = task.perfect_rm()?;
        let layout = task.layout();
        let mut config = IrlRunConfig::standard().over_task(&task)?;
        config.threads = 1;
        let mut expert = load_expert(task.clone(), None)?;
        for &base in &bases {
            let demos = make_demos(task.clone(), &config, Some(&mut expert), base, None)?;
            let demos: Vec<_> = demos.into_iter().filter(|d| d.success).collect();
            let traces = label_traces(&demos);
            // The touches the demonstrations show (no learner can know what an untouched
            // ball does), with every event; and the label sets they show.
            let observed = observed_label_sets(&traces);
            let language = LabelLanguage {
                touches: observed.iter().fold(LabelSet::EMPTY, |a, l| {
                    LabelSet(a.0 | l.0 & layout.touches().0)
                }),
                events: layout.events(),
            };
            let alphabet = language.alphabet();
            let standard = lrm_config(&config, base, Algo::Smirl).map_err(anyhow::Error::msg)?;
            let paper = lrm_config(&config, base, Algo::SmirlPaper).map_err(anyhow::Error::msg)?;
            for (variant, cfg) in all_variants(&standard, &paper) {
                if done.contains(&(name.to_string(), base, variant.to_string())) {
                    continue;
                }
                let learned = learn_rm(&layout.vocabulary(), &traces, &cfg)?;
                let perfect_cost = trace_cost(&perfect, &traces, trace_reading(&cfg))?;
                let check = |alphabet: &[LabelSet], failures| {
                    undetermined(&learned.rm, &perfect, &language, alphabet, failures)
                };
                let cx = check(&alphabet, Failures::AsStays);
                let cx_failures = check(&alphabet, Failures::Kept);
                let cx_seen = check(&observed, Failures::AsStays);
                let text = |s: &[LabelSet]| {
                    s.iter()
                        .map(|&l| match perfect.vocab().format_labels(l) {
                            t if t.is_empty() => "-".to_string(),
                            t => t,
                        })
                        .collect::<Vec<_>>()
                        .join(" ")
                };
                let cx_text = |cx: &Option<Undetermined>| {
                    cx.as_ref().map_or(String::new(), |c| {
                        format!("{} / {}", text(&c.first), text(&c.second))
                    })
                };
                writeln!(
                    file,
                    "{name},{base},{variant},{},{},{:.4},{:.4},{},{},{},{},{},{},{:.3}",
                    demos.len(),
                    learned.rm.n_states(),
                    learned.cost,
                    perfect_cost,
                    cx.is_none(),
                    cx_text(&cx),
                    cx_seen.is_none(),
                    cx_text(&cx_seen),
                    cx_failures.is_none(),
                    cx_text(&cx_failures),
                    learned.stats.elapsed_secs
                )?;
                file.flush()?;
            }
        }
    }
    Ok(())
}

/// The mechanisms that move some development base's machine away from the task's in
/// experiments/lrm/ablation.md, turned off together.
fn without_contested(c: &mut LrmConfig) {
    c.commute_events = false;
    c.event_stutter = false;
    c.predict_events = true;
}

/// `standard`, each mechanism of `standard` turned off alone, and `paper`.
fn all_variants(standard: &LrmConfig, paper: &LrmConfig) -> Vec<(&'static str, LrmConfig)> {
    let with = |f: fn(&mut LrmConfig)| {
        let mut c = standard.clone();
        f(&mut c);
        c
    };
    vec![
        ("standard", standard.clone()),
        ("no_initial_events", with(|c| c.initial_events = false)),
        ("exact_guards", with(|c| c.guards = Guards::Exact)),
        ("no_commute_events", with(|c| c.commute_events = false)),
        ("no_event_stutter", with(|c| c.event_stutter = false)),
        ("predict_events", with(|c| c.predict_events = true)),
        ("paper", paper.clone()),
        ("without_contested", with(without_contested)),
    ]
}
