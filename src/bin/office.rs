//! `office`: the Office Gridworld experiments (paper section 4.2, figures 4 and 5).
//!
//! ```text
//! office --task 3|path/to/task.toml --algo smirl|maxent|apprenticeship|all --seeds 3 --seed 0 --out runs/office-t3 [--config office.toml] [--force]
//! ```
//! Writes into `--out`: `metrics.csv` (one row per algorithm, seed and IRL step),
//! `summary.csv`, `success.svg` (mean ± std over seeds per algorithm), per SMIRL seed the
//! reward machine (`rm_smirl_seed<S>.txt` and `.dot`), and the learned reward weights
//! (`weights_<algo>_seed<S>.csv`). Arguments and configuration are checked before anything
//! is written; results are written to a temporary directory that is renamed to `--out` only
//! when complete. The work is [`smirl::pipeline::commands::office`]; this file parses the
//! arguments.
//!
//! Exit status: 0 success, 1 failure while running, 2 bad arguments or config.

#![deny(unsafe_code)]

use clap::Parser;
use smirl::pipeline::commands::{self, office::OfficeRequest};
use std::path::PathBuf;
use std::process::ExitCode;

#[derive(Parser, Debug)]
#[command(
    name = "office",
    about = "Office Gridworld IRL experiments (SMIRL and baselines)"
)]
struct Args {
    /// A shipped task (0-4, the paper's) or the path of a task file (docs/office.md).
    #[arg(long, allow_hyphen_values = true)]
    task: String,
    /// smirl, maxent, apprenticeship or all.
    #[arg(long, default_value = "all")]
    algo: String,
    /// Number of seeds.
    #[arg(long, default_value_t = 3)]
    seeds: u64,
    /// Base seed: the runs use seed, seed+1, ...
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Output directory (must not exist or be empty; with --force, an earlier output of this
    /// program is replaced).
    #[arg(long)]
    out: PathBuf,
    /// TOML configuration (see `OfficeConfig`).
    #[arg(long)]
    config: Option<PathBuf>,
    /// Replace an existing output directory (only one this program wrote; never `.`, an
    /// ancestor of the working directory or the home directory).
    #[arg(long)]
    force: bool,
    /// Also write each seed's demonstrations (`demos_seed<S>.csv`).
    #[arg(long)]
    write_demos: bool,
}

fn main() -> ExitCode {
    smirl::pipeline::commands::exit_quietly_on_closed_pipe();
    let args = match Args::try_parse() {
        Ok(a) => a,
        Err(e) => {
            let _ = e.print();
            return ExitCode::from(if e.use_stderr() { 2 } else { 0 });
        }
    };
    let request = OfficeRequest {
        task: args.task,
        algo: args.algo,
        seeds: args.seeds,
        seed: args.seed,
        out: args.out,
        config: args.config,
        force: args.force,
        write_demos: args.write_demos,
    };
    match commands::office::run(request) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("office: error: {}", commands::error_message(&e));
            ExitCode::from(if commands::is_usage(&e) { 2 } else { 1 })
        }
    }
}
