//! `office`: the Office Gridworld experiments (paper section 4.2, figures 4 and 5) for one
//! task, every requested algorithm and seed, into one output directory.
//!
//! Writes into the output directory: `metrics.csv` (one row per algorithm, seed and IRL
//! step), `summary.csv`, `success.svg` (mean ± std over seeds per algorithm) and, for the
//! algorithms that sample the environment, `success_vs_interactions.svg`; per SMIRL seed the
//! reward machine (`rm_smirl_seed<S>.txt` and `.dot`); the learned reward weights
//! (`weights_<algo>_seed<S>.csv`); with `write_demos`, each seed's demonstrations
//! (`demos_seed<S>.csv`). Arguments and configuration are checked before anything runs (a
//! [`UsageError`](super::UsageError)); results are written to a temporary directory that is
//! renamed to the output directory only when complete.

use super::usage;
use crate::atomic_file::write_atomic;
use crate::env::office::OfficeTask;
use crate::output::OutputDir;
use crate::pipeline::office::{
    self as office, demonstrations, demonstrations_table, Algo, OfficeConfig, OfficeRun,
};
use crate::report::{aggregate_over_seeds, CsvTable, LinePlot, Series};
use anyhow::{bail, Context, Result};
use std::path::{Path, PathBuf};

/// The arguments of `office`.
#[derive(Clone, Debug)]
pub struct OfficeRequest {
    /// A shipped task's name (`0`-`4`, the paper's) or the path of a task file
    /// ([`crate::env::office::task`]).
    pub task: String,
    /// smirl, maxent, apprenticeship or all.
    pub algo: String,
    /// Number of seeds, 1..=[`MAX_SEEDS`].
    pub seeds: u64,
    /// Base seed: the runs use seed, seed+1, ...
    pub seed: u64,
    /// Output directory: must not exist or be empty (or `force`, for one this program wrote).
    pub out: PathBuf,
    /// TOML configuration (see [`OfficeConfig`]); `None`: the defaults.
    pub config: Option<PathBuf>,
    pub force: bool,
    /// Also write each seed's demonstrations.
    pub write_demos: bool,
}

/// `office`: checks the request (bad input is a usage error, before anything is written),
/// runs every (algorithm, seed), reporting progress on stderr, and writes the results.
pub fn run(args: OfficeRequest) -> Result<()> {
    let plan = plan(&args).map_err(|e| usage(format!("{e:#}")))?;
    execute(&plan)
}

/// Most seeds one run takes (every seed's run is kept in memory until the reports).
pub const MAX_SEEDS: u64 = 1_000;

/// Everything checked before the run starts.
struct Plan {
    task: OfficeTask,
    algos: Vec<Algo>,
    seeds: Vec<u64>,
    cfg: OfficeConfig,
    output: OutputDir,
    write_demos: bool,
}

/// Checks the task, algorithms, seeds, config and output directory; any error here is bad
/// input.
fn plan(args: &OfficeRequest) -> Result<Plan> {
    let task = OfficeTask::from_argument(&args.task)?;
    let algos = if args.algo == "all" {
        Algo::OFFICE.to_vec()
    } else {
        match Algo::parse_in(&args.algo, &Algo::OFFICE) {
            Ok(a) => vec![a],
            Err(_) => bail!(
                "unknown algorithm {:?} (expected smirl, maxent, apprenticeship or all)",
                args.algo
            ),
        }
    };
    if args.seeds == 0 {
        bail!("--seeds must be at least 1");
    }
    if args.seeds > MAX_SEEDS {
        bail!(
            "--seeds {} is more than the limit of {MAX_SEEDS} seeds per run",
            args.seeds
        );
    }
    let cfg = match &args.config {
        None => OfficeConfig::default(),
        Some(path) => {
            let text = crate::config_text::read_text_file(path)
                .with_context(|| format!("reading config {}", path.display()))?;
            OfficeConfig::from_toml(&text).with_context(|| format!("config {}", path.display()))?
        }
    };
    let output = OutputDir::check(&args.out, args.force)?;
    let seeds = (0..args.seeds)
        .map(|i| args.seed.checked_add(i))
        .collect::<Option<Vec<u64>>>()
        .context("seed range overflows u64")?;
    Ok(Plan {
        task,
        algos,
        seeds,
        cfg,
        output,
        write_demos: args.write_demos,
    })
}

/// Runs every (algorithm, seed), keeping the runs in memory, then writes the results into a
/// fresh `.partial` directory that becomes the output directory when complete.
fn execute(plan: &Plan) -> Result<()> {
    let mut runs: Vec<OfficeRun> = Vec::new();
    for &algo in &plan.algos {
        for &seed in &plan.seeds {
            let r = office::run(&plan.task, algo, seed, &plan.cfg, &mut |line| {
                eprintln!("[task {}] {line}", plan.task.name())
            })?;
            eprintln!(
                "[task {}] {} seed {seed}: final success {} after {} IRL steps, {:.2} s",
                plan.task.name(),
                algo.name(),
                r.final_success(),
                r.steps.len() - 1,
                r.timings.total_s
            );
            runs.push(r);
        }
    }
    let partial = plan.output.begin()?;
    if let Err(e) = write_outputs(plan, &runs, &partial) {
        // Only the directory this run created (and marked) is removed.
        let _ = std::fs::remove_dir_all(&partial);
        return Err(e);
    }
    plan.output.commit(&partial)?;
    eprintln!("results in {}", plan.output.path().display());
    Ok(())
}

fn write_file(dir: &Path, name: &str, text: &str) -> Result<()> {
    let path = dir.join(name);
    write_atomic(&path, text.as_bytes()).with_context(|| format!("writing {}", path.display()))
}

/// Writes every output file into `dir` (the run's `.partial` directory, already created).
fn write_outputs(plan: &Plan, runs: &[OfficeRun], dir: &Path) -> Result<()> {
    let task = plan.task.name().to_string();
    let mut metrics = CsvTable::new([
        "task",
        "algo",
        "seed",
        "step",
        "env_interactions",
        "gt_return",
        "success",
        "objective",
        "mixture_return",
        "elapsed_s",
    ]);
    for r in runs {
        for s in &r.steps {
            metrics.push([
                task.clone(),
                r.algo.name().to_string(),
                r.seed.to_string(),
                s.step.to_string(),
                s.env_interactions.to_string(),
                s.gt_return.to_string(),
                (s.success as u8).to_string(),
                s.objective.to_string(),
                s.mixture_return.to_string(),
                format!("{:.4}", s.elapsed_s),
            ]);
        }
    }
    write_file(dir, "metrics.csv", &metrics.to_csv())?;

    let mut summary = CsvTable::new([
        "task",
        "algo",
        "seed",
        "final_success",
        "irl_steps",
        "converged",
        "rm_states",
        "refines_perfect",
        "demos_s",
        "rm_learning_s",
        "irl_s",
        "total_s",
        "final_mixture_return",
    ]);
    for r in runs {
        summary.push([
            task.clone(),
            r.algo.name().to_string(),
            r.seed.to_string(),
            (r.final_success() as u8).to_string(),
            (r.steps.len() - 1).to_string(),
            r.converged.to_string(),
            r.rm.as_ref()
                .map_or(String::new(), |m| m.n_states().to_string()),
            r.refines_perfect.map_or(String::new(), |b| b.to_string()),
            format!("{:.4}", r.timings.demos_s),
            format!("{:.4}", r.timings.rm_learning_s),
            format!("{:.4}", r.timings.irl_s),
            format!("{:.4}", r.timings.total_s),
            r.steps
                .last()
                .map_or(f64::NAN, |s| s.mixture_return)
                .to_string(),
        ]);
        let mut w = CsvTable::new(
            std::iter::once("rm_state".to_string()).chain(r.weight_columns.iter().cloned()),
        );
        for (u, row) in r.weights.iter().enumerate() {
            w.push(std::iter::once(u.to_string()).chain(row.iter().map(|x| x.to_string())));
        }
        write_file(
            dir,
            &format!("weights_{}_seed{}.csv", r.algo.name(), r.seed),
            &w.to_csv(),
        )?;
        if let Some(rm) = &r.rm {
            write_file(
                dir,
                &format!("rm_{}_seed{}.txt", r.algo.name(), r.seed),
                &crate::rm::format::write_rm(rm),
            )?;
            write_file(
                dir,
                &format!("rm_{}_seed{}.dot", r.algo.name(), r.seed),
                &crate::rm::dot::to_dot(rm),
            )?;
        }
    }
    write_file(dir, "summary.csv", &summary.to_csv())?;

    let mut plot = LinePlot::new(
        &plan.task.title(),
        "IRL step",
        "ground-truth return (success rate)",
    );
    plot.y_range = Some((-0.05, 1.05));
    for &algo in &plan.algos {
        let curves: Vec<Vec<(f64, f64)>> = runs
            .iter()
            .filter(|r| r.algo == algo)
            .map(|r| {
                r.steps
                    .iter()
                    .map(|s| (s.step as f64, s.gt_return))
                    .collect()
            })
            .collect();
        plot.series.push(
            Series::new(algo.label(), aggregate_over_seeds(&curves)).with_colour(algo.colour()),
        );
    }
    write_file(dir, "success.svg", &plot.to_svg())?;

    // Figure 5's x-axis: environment interactions, for the algorithms that sample them.
    let mut by_interactions = LinePlot::new(
        &format!("{} (sampling algorithms)", plan.task.title()),
        "environment interactions",
        "ground-truth return (success rate)",
    );
    by_interactions.y_range = Some((-0.05, 1.05));
    for &algo in &plan.algos {
        let curves: Vec<Vec<(f64, f64)>> = runs
            .iter()
            .filter(|r| r.algo == algo && r.steps.iter().any(|s| s.env_interactions > 0))
            .map(|r| {
                r.steps
                    .iter()
                    .map(|s| (s.env_interactions as f64, s.gt_return))
                    .collect()
            })
            .collect();
        if !curves.is_empty() {
            by_interactions.series.push(
                Series::new(algo.label(), aggregate_over_seeds(&curves)).with_colour(algo.colour()),
            );
        }
    }
    if !by_interactions.series.is_empty() {
        write_file(
            dir,
            "success_vs_interactions.svg",
            &by_interactions.to_svg(),
        )?;
    }

    if plan.write_demos {
        for &seed in &plan.seeds {
            let demos = demonstrations(&plan.task, &plan.cfg.demos, seed);
            write_file(
                dir,
                &format!("demos_seed{seed}.csv"),
                &demonstrations_table(&demos, plan.task.world()).to_csv(),
            )?;
        }
    }
    Ok(())
}
