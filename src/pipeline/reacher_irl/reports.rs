//! The reports of a finished `reacher --task` run, written from its jobs' records into the run
//! directory: `metrics.csv`, `final_policy.csv`, `summary.csv`, `summary.md`, the plots and
//! `run.json`, and each SMIRL job's reward trace CSV.

use super::evaluation::FinalSetScore;
use super::final_policy::{FinalCandidate, FinalPolicy};
use super::iteration::RewardTraceRow;
use super::records::{
    write_file, AlgoSummary, JobRecord, PipelineError, PreparedRun, RmFacts, RunSummary,
};
use super::{Algo, MetricsRow};
use crate::env::reacher_task::{Branch, BranchTally, EventBranch, ReacherTask};
use crate::report::{aggregate_over_seeds, CsvTable, LinePlot, Series};
use std::fmt::Write as _;
use std::path::Path;

fn mean_std(xs: &[f64]) -> (f64, f64) {
    let n = xs.len().max(1) as f64;
    let m = xs.iter().sum::<f64>() / n;
    let v = xs.iter().map(|x| (x - m) * (x - m)).sum::<f64>() / n;
    (m, v.sqrt())
}

/// Writes metrics.csv, the summaries, the plots and run.json of `records` into the run
/// directory.
pub(super) fn write_reports(
    run: &PreparedRun,
    records: &[(Algo, JobRecord)],
    wall_secs: Option<f64>,
) -> Result<RunSummary, PipelineError> {
    let dir = &run.dir;
    let task = run.prepared.task.clone();
    let conditional = EventBranch::of(&run.perfect, task.layout().events()).is_some();

    write_file(&dir.join("metrics.csv"), &metrics_table(records).to_csv())?;
    if records.iter().any(|(_, r)| r.final_policy.is_some()) {
        write_file(
            &dir.join("final_policy.csv"),
            &final_policy_table(records).to_csv(),
        )?;
    }

    let mut plots = Plots::new(&task, conditional);
    let mut summaries = Vec::new();
    for algo in algos_in_order(records) {
        let runs: Vec<&JobRecord> = records
            .iter()
            .filter(|(a, _)| *a == algo)
            .map(|(_, r)| r)
            .collect();
        plots.add(algo, &runs);
        summaries.push(algo_summary(algo, &runs, conditional)?);
    }
    plots.write(dir)?;

    write_file(
        &dir.join("summary.csv"),
        &summary_table(&task, &summaries).to_csv(),
    )?;
    let p = &run.prepared;
    write_file(
        &dir.join("summary.md"),
        &summary_markdown(task.clone(), &summaries, p.rm.as_ref(), p.rm_paper.as_ref()),
    )?;
    let summary = RunSummary {
        out: dir.clone(),
        task: task.name().into(),
        demos_kept: p.demos_kept,
        demos_generated: p.demos_generated,
        demo_branches: p.demo_branches,
        rm: p.rm.clone(),
        rm_paper: p.rm_paper.clone(),
        algos: summaries,
        wall_secs: wall_secs.unwrap_or(f64::NAN),
    };
    write_file(
        &dir.join("run.json"),
        &serde_json::to_string_pretty(&run_json(run, records, &summary)).expect("JSON serialises"),
    )?;
    Ok(summary)
}

/// The algorithms of `records`, in the order they first appear.
fn algos_in_order(records: &[(Algo, JobRecord)]) -> Vec<Algo> {
    let mut seen = Vec::new();
    for &(a, _) in records {
        if !seen.contains(&a) {
            seen.push(a);
        }
    }
    seen
}

/// A branch without evaluation episodes counts as failed (it cannot be shown solved).
fn branch_rate(row: &MetricsRow, b: Branch) -> f64 {
    row.branches.and_then(|t| t.rate(b)).unwrap_or(0.0)
}

/// metrics.csv: one row per job and evaluated iteration; the final phase's chosen and randomly
/// picked candidates beside the loop's own policy on the job's last row (success on the lower
/// branch, then each branch's).
fn metrics_table(records: &[(Algo, JobRecord)]) -> CsvTable {
    let mut metrics = CsvTable::new([
        "algo",
        "seed",
        "iteration",
        "env_steps",
        "success_rate",
        "task_return",
        "env_return",
        "learned_reward",
        "surrogate_loss",
        "success_normal",
        "success_cancel",
        "episodes_normal",
        "episodes_cancel",
        "progress",
        "final_ball",
        "expert_support",
        "chosen_success_rate",
        "chosen_success_normal",
        "chosen_success_cancel",
        "random_success_rate",
        "random_success_normal",
        "random_success_cancel",
    ]);
    let optional = |x: Option<f64>| x.map_or(String::new(), |x| format!("{x}"));
    let candidate_cells = |c: Option<&FinalCandidate>| -> [String; 3] {
        match c {
            Some(c) => {
                let rate = |b: Branch| {
                    c.branches
                        .and_then(|t| t.rate(b))
                        .map_or(String::new(), |x| format!("{x}"))
                };
                [
                    format!("{}", c.success_rate),
                    rate(Branch::Normal),
                    rate(Branch::Event),
                ]
            }
            None => Default::default(),
        }
    };
    for (_, r) in records {
        let last = r.rows.len().saturating_sub(1);
        for (i, row) in r.rows.iter().enumerate() {
            let final_policy = r.final_policy.as_ref().filter(|_| i == last);
            let [chosen, chosen_normal, chosen_cancel] =
                candidate_cells(final_policy.map(FinalPolicy::chosen));
            let [random, random_normal, random_cancel] =
                candidate_cells(final_policy.and_then(FinalPolicy::random));
            let branch = |f: &dyn Fn(&BranchTally, Branch) -> String| -> [String; 2] {
                Branch::ALL.map(|b| row.branches.as_ref().map_or(String::new(), |t| f(t, b)))
            };
            let [rate_normal, rate_cancel] =
                branch(&|t, b| t.rate(b).map_or(String::new(), |x| format!("{x}")));
            let [n_normal, n_cancel] = branch(&|t, b| t.episodes[b.index()].to_string());
            metrics.push([
                r.algo.clone(),
                r.seed.to_string(),
                row.iteration.to_string(),
                row.env_steps.to_string(),
                format!("{}", row.success_rate),
                format!("{}", row.task_return),
                format!("{:.6}", row.env_return),
                format!("{:.6}", row.learned_reward),
                format!("{:.6}", row.surrogate_loss),
                rate_normal,
                rate_cancel,
                n_normal,
                n_cancel,
                optional(row.progress),
                optional(row.final_ball),
                optional(row.expert_support),
                chosen,
                chosen_normal,
                chosen_cancel,
                random,
                random_normal,
                random_cancel,
            ]);
        }
    }
    metrics
}

/// The curves of every algorithm over environment steps, mean ± std over its seeds.
struct Plots {
    success: LinePlot,
    task_return: LinePlot,
    branches: LinePlot,
    progress: LinePlot,
    /// The task has two branches: the per-branch plot is drawn.
    conditional: bool,
}

impl Plots {
    fn new(task: &ReacherTask, conditional: bool) -> Plots {
        let mut success = LinePlot::new(
            &format!("ReacherDelivery {task}: ground-truth success"),
            "environment steps",
            "success rate",
        );
        success.y_range = Some((0.0, 1.0));
        let task_return = LinePlot::new(
            &format!("ReacherDelivery {task}: task return"),
            "environment steps",
            "task return",
        );
        let mut branches = LinePlot::new(
            &format!("ReacherDelivery {task}: success per branch"),
            "environment steps",
            "success rate",
        );
        branches.y_range = Some((0.0, 1.0));
        let mut progress = LinePlot::new(
            &format!(
                "ReacherDelivery {task}: sub-goals completed (solid) and end ball touched (dashed)"
            ),
            "environment steps",
            "fraction",
        );
        progress.y_range = Some((0.0, 1.0));
        Plots {
            success,
            task_return,
            branches,
            progress,
            conditional,
        }
    }

    /// `algo`'s curves from its jobs `runs`.
    fn add(&mut self, algo: Algo, runs: &[&JobRecord]) {
        let curve = |f: &dyn Fn(&MetricsRow) -> f64| -> Vec<Vec<(f64, f64)>> {
            runs.iter()
                .map(|r| {
                    r.rows
                        .iter()
                        .map(|row| (row.env_steps as f64, f(row)))
                        .collect()
                })
                .collect()
        };
        if self.conditional {
            for b in Branch::ALL {
                self.branches.series.push(
                    Series::new(
                        format!("{} ({b})", algo.name()),
                        aggregate_over_seeds(&curve(&|r| branch_rate(r, b))),
                    )
                    .with_colour(algo.colour())
                    .with_dashes(b == Branch::Event),
                );
            }
        }
        self.success.series.push(
            Series::new(
                algo.name(),
                aggregate_over_seeds(&curve(&|r| r.success_rate)),
            )
            .with_colour(algo.colour()),
        );
        // Jobs from before the progress metric have none: no curve for them.
        if runs
            .iter()
            .all(|r| r.rows.iter().all(|row| row.progress.is_some()))
        {
            self.progress.series.push(
                Series::new(
                    format!("{} sub-goals", algo.name()),
                    aggregate_over_seeds(&curve(&|r| r.progress.unwrap_or(0.0))),
                )
                .with_colour(algo.colour()),
            );
            self.progress.series.push(
                Series::new(
                    format!("{} end ball", algo.name()),
                    aggregate_over_seeds(&curve(&|r| r.final_ball.unwrap_or(0.0))),
                )
                .with_colour(algo.colour())
                .with_dashes(true),
            );
        }
        self.task_return.series.push(
            Series::new(
                algo.name(),
                aggregate_over_seeds(&curve(&|r| r.task_return)),
            )
            .with_colour(algo.colour()),
        );
    }

    /// success.svg, task_return.svg, progress.svg (when a curve has it) and, for a
    /// conditional task, success_branches.svg.
    fn write(&self, dir: &Path) -> Result<(), PipelineError> {
        write_file(&dir.join("success.svg"), &self.success.to_svg())?;
        write_file(&dir.join("task_return.svg"), &self.task_return.to_svg())?;
        if !self.progress.series.is_empty() {
            write_file(&dir.join("progress.svg"), &self.progress.to_svg())?;
        }
        if self.conditional {
            write_file(&dir.join("success_branches.svg"), &self.branches.to_svg())?;
        }
        Ok(())
    }
}

/// `algo`'s final figures over its jobs `runs`: the loop's own policy at the last evaluated
/// iteration, and the final phase's chosen and randomly picked candidates when every job has
/// them.
fn algo_summary(
    algo: Algo,
    runs: &[&JobRecord],
    conditional: bool,
) -> Result<AlgoSummary, PipelineError> {
    let last = |f: &dyn Fn(&MetricsRow) -> f64| -> Result<Vec<f64>, PipelineError> {
        runs.iter()
            .map(|r| {
                r.rows
                    .last()
                    .map(f)
                    .ok_or_else(|| PipelineError::NoMetricsRows { algo, seed: r.seed })
            })
            .collect()
    };
    let (sm, ss) = mean_std(&last(&|r| r.success_rate)?);
    let (rm_, rs) = mean_std(&last(&|r| r.task_return)?);
    let final_branch_success = if conditional {
        let normal = mean_std(&last(&|r| branch_rate(r, Branch::Normal))?);
        let cancel = mean_std(&last(&|r| branch_rate(r, Branch::Event))?);
        Some([normal, cancel])
    } else {
        None
    };
    let pick =
        |f: &dyn Fn(&FinalPolicy) -> Option<&FinalCandidate>| -> Option<Vec<FinalCandidate>> {
            runs.iter()
                .map(|r| r.final_policy.as_ref().and_then(f).cloned())
                .collect()
        };
    let success =
        |c: &[FinalCandidate]| mean_std(&c.iter().map(|c| c.success_rate).collect::<Vec<_>>());
    let branch_success = |c: &[FinalCandidate]| {
        Branch::ALL.map(|b| {
            let rates: Vec<f64> = c
                .iter()
                .map(|c| c.branches.and_then(|t| t.rate(b)).unwrap_or(0.0))
                .collect();
            mean_std(&rates)
        })
    };
    let chosen = pick(&|f| Some(f.chosen()));
    let random = pick(&|f| f.random());
    let (wm, _) = mean_std(&runs.iter().map(|r| r.wall_secs).collect::<Vec<_>>());
    Ok(AlgoSummary {
        algo: algo.name().into(),
        seeds: runs.len(),
        final_success_mean: sm,
        final_success_std: ss,
        final_return_mean: rm_,
        final_return_std: rs,
        final_branch_success,
        final_policy_success: chosen.as_deref().map(success),
        final_policy_branch_success: chosen
            .as_deref()
            .filter(|_| conditional)
            .map(branch_success),
        random_policy_success: random.as_deref().map(success),
        random_policy_branch_success: random
            .as_deref()
            .filter(|_| conditional)
            .map(branch_success),
        job_secs_mean: wm,
    })
}

/// summary.csv: one row per algorithm.
fn summary_table(task: &ReacherTask, summaries: &[AlgoSummary]) -> CsvTable {
    let mut table = CsvTable::new([
        "task",
        "algo",
        "seeds",
        "final_success_mean",
        "final_success_std",
        "final_return_mean",
        "final_return_std",
        "final_success_normal_mean",
        "final_success_normal_std",
        "final_success_cancel_mean",
        "final_success_cancel_std",
        "chosen_success_mean",
        "chosen_success_std",
        "random_success_mean",
        "random_success_std",
    ]);
    for s in summaries {
        let branch_cells = match s.final_branch_success {
            Some([(nm, ns), (cm, cs)]) => [nm, ns, cm, cs].map(|x| format!("{x:.3}")),
            None => Default::default(),
        };
        let [nm, ns, cm, cs] = branch_cells;
        let pair = |x: Option<(f64, f64)>| match x {
            Some((m, sd)) => [format!("{m:.3}"), format!("{sd:.3}")],
            None => Default::default(),
        };
        let [chosen_m, chosen_s] = pair(s.final_policy_success);
        let [random_m, random_s] = pair(s.random_policy_success);
        table.push([
            task.name().to_string(),
            s.algo.clone(),
            s.seeds.to_string(),
            format!("{:.3}", s.final_success_mean),
            format!("{:.3}", s.final_success_std),
            format!("{:.3}", s.final_return_mean),
            format!("{:.3}", s.final_return_std),
            nm,
            ns,
            cm,
            cs,
            chosen_m,
            chosen_s,
            random_m,
            random_s,
        ]);
    }
    table
}

/// run.json: the summary, the run's plan and settings, and each job's wall time.
fn run_json(
    run: &PreparedRun,
    records: &[(Algo, JobRecord)],
    summary: &RunSummary,
) -> serde_json::Value {
    let (p, config) = (&run.prepared, &run.config);
    serde_json::json!({
        "summary": summary,
        "seeds": p.seeds,
        "demo_source": config.demo_source.name(),
        "smirl_machine": config.smirl_machine.name(),
        "final_sac_steps": config.final_sac_steps,
        "final_checkpoints": config.final_checkpoints,
        "git_commit": crate::GIT_COMMIT,
        "prepare_git_commit": p.git_commit,
        "prepare_secs": p.prepare_secs,
        "jobs": records.iter().map(|(_, r)| serde_json::json!({
            "algo": r.algo, "seed": r.seed, "wall_secs": r.wall_secs})).collect::<Vec<_>>(),
    })
}

/// The candidates of every job's final-policy phase, one row each: `candidate` 0 is the
/// co-trained policy of the last IRL iteration, `chosen` marks the reported one, `random` the
/// one drawn at random (the choice's yardstick), `final_set_*` the success on the final set (`evaluation::final_set_episodes`; candidate 0's
/// is the loop's own final policy's), beside `success_*` on the per-iteration evaluation's
/// episodes.
fn final_policy_table(records: &[(Algo, JobRecord)]) -> CsvTable {
    let mut table = CsvTable::new([
        "algo",
        "seed",
        "candidate",
        "env_steps",
        "learned_return",
        "chosen",
        "success_rate",
        "success_normal",
        "success_cancel",
        "progress",
        "final_ball",
        "random",
        "final_set_episodes",
        "final_set_success_rate",
        "final_set_success_normal",
        "final_set_success_cancel",
    ]);
    for (_, r) in records {
        let Some(f) = &r.final_policy else { continue };
        for (i, c) in f.candidates.iter().enumerate() {
            let rate_of = |branches: Option<BranchTally>, b: Branch| {
                branches
                    .and_then(|t| t.rate(b))
                    .map_or(String::new(), |x| format!("{x}"))
            };
            let rate = |b: Branch| rate_of(c.branches, b);
            let final_set = |f: &dyn Fn(&FinalSetScore) -> String| {
                c.final_set.as_ref().map_or(String::new(), f)
            };
            table.push([
                r.algo.clone(),
                r.seed.to_string(),
                i.to_string(),
                c.env_steps.to_string(),
                format!("{:.6}", c.learned_return),
                u8::from(i == f.chosen).to_string(),
                format!("{}", c.success_rate),
                rate(Branch::Normal),
                rate(Branch::Event),
                format!("{}", c.progress),
                format!("{}", c.final_ball),
                u8::from(f.random == Some(i)).to_string(),
                final_set(&|s| s.episodes.to_string()),
                final_set(&|s| format!("{}", s.success_rate)),
                final_set(&|s| rate_of(s.branches, Branch::Normal)),
                final_set(&|s| rate_of(s.branches, Branch::Event)),
            ]);
        }
    }
    table
}

/// A SMIRL reward trace as a long table: one row per (iteration, RM state, feature), the
/// feature named by its proposition (label bit k is feature k).
pub(super) fn reward_trace_csv(trace: &[RewardTraceRow], letters: &str) -> CsvTable {
    let features: Vec<char> = letters.chars().collect();
    let mut table = CsvTable::new([
        "iteration",
        "rm_state",
        "feature",
        "weight",
        "data_gradient",
    ]);
    for row in trace {
        for (i, (w, g)) in row.weights.iter().zip(&row.data_gradient).enumerate() {
            table.push([
                row.iteration.to_string(),
                (i / features.len()).to_string(),
                features[i % features.len()].to_string(),
                format!("{w:.6}"),
                format!("{g:.6}"),
            ]);
        }
    }
    table
}

/// The per-branch cells of a summary row: mean ± std of the normal and the event branch; empty
/// cells in a conditional task's table for a row without them, none for other tasks.
fn branch_cells(branches: Option<[(f64, f64); 2]>, conditional: bool) -> String {
    match branches {
        Some([(nm, ns), (cm, cs)]) => format!(" {nm:.2} ± {ns:.2} | {cm:.2} ± {cs:.2} |"),
        None if conditional => " | |".to_string(),
        None => String::new(),
    }
}

/// The summary table as Markdown (also printed by the binary).
pub fn summary_markdown(
    task: ReacherTask,
    summaries: &[AlgoSummary],
    rm: Option<&RmFacts>,
    rm_paper: Option<&RmFacts>,
) -> String {
    let mut s = String::new();
    let conditional = summaries.iter().any(|a| a.final_branch_success.is_some());
    if conditional {
        let _ = writeln!(
            s,
            "| task | algorithm | seeds | final success (lower branch) | normal branch | event branch | final task return | job wall time (s) |"
        );
        let _ = writeln!(s, "|---|---|---|---|---|---|---|---|");
    } else {
        let _ = writeln!(
            s,
            "| task | algorithm | seeds | final success | final task return | job wall time (s) |"
        );
        let _ = writeln!(s, "|---|---|---|---|---|---|");
    }
    for a in summaries {
        let branches = branch_cells(a.final_branch_success, conditional);
        let _ = writeln!(
            s,
            "| {task} | {} | {} | {:.2} ± {:.2} |{branches} {:.2} ± {:.2} | {:.0} |",
            a.algo,
            a.seeds,
            a.final_success_mean,
            a.final_success_std,
            a.final_return_mean,
            a.final_return_std,
            a.job_secs_mean
        );
    }
    let with_final: Vec<&AlgoSummary> = summaries
        .iter()
        .filter(|a| a.final_policy_success.is_some())
        .collect();
    if !with_final.is_empty() {
        let _ = writeln!(
            s,
            "\nFinal phase (SAC on the final learned reward held fixed; candidates in \
             final_policy.csv): success{} of the loop's own policy (last iteration), of the \
             candidate of highest learned return (chosen: the reported policy) and of one \
             candidate drawn at random from the job's seed:\n",
            if conditional { " (lower branch)" } else { "" }
        );
        let _ = writeln!(
            s,
            "| task | algorithm | seeds | loop's own policy | chosen | random pick |"
        );
        let _ = writeln!(s, "|---|---|---|---|---|---|");
        let cell = |x: Option<(f64, f64)>| {
            x.map_or("—".to_string(), |(m, sd)| format!("{m:.2} ± {sd:.2}"))
        };
        for a in with_final {
            let _ = writeln!(
                s,
                "| {task} | {} | {} | {:.2} ± {:.2} | {} | {} |",
                a.algo,
                a.seeds,
                a.final_success_mean,
                a.final_success_std,
                cell(a.final_policy_success),
                cell(a.random_policy_success)
            );
        }
        if conditional {
            let _ = writeln!(
                s,
                "\nThe chosen policy per branch:\n\n| task | algorithm | seeds | success (lower branch) | normal branch | event branch |\n|---|---|---|---|---|---|"
            );
            for a in summaries
                .iter()
                .filter(|a| a.final_policy_success.is_some())
            {
                let (m, sd) = a.final_policy_success.unwrap_or_default();
                let branches = branch_cells(a.final_policy_branch_success, conditional);
                let _ = writeln!(
                    s,
                    "| {task} | {} | {} | {m:.2} ± {sd:.2} |{branches}",
                    a.algo, a.seeds
                );
            }
        }
    }
    for (name, facts) in [("Learned RM", rm), ("smirl-paper's learned RM", rm_paper)] {
        if let Some(f) = facts {
            let _ = writeln!(
                s,
                "\n{name}: {} states ({} reachable; perfect: {}), refines the perfect machine \
                 along the demos: {}.",
                f.learned_states, f.learned_reachable, f.perfect_states, f.refines_perfect
            );
        }
    }
    s
}
