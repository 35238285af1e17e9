//! `reacher draw`: f-IRL's own Reacher experiment (ReacherDraw) with one baseline, into a run
//! directory.

use super::{usage, UsageError};
use crate::output::OutputDir;
use crate::pipeline::reacher_draw::{self as draw, DrawConfig, DrawTarget};
use crate::pipeline::reacher_irl::Algo;
use anyhow::Result;
use std::path::PathBuf;

/// The arguments of `reacher draw`.
#[derive(Clone, Debug)]
pub struct DrawRequest {
    /// maxent, fkl, rkl or js (SMIRL needs labelled events, which ReacherDraw has not).
    pub algo: Algo,
    /// Target density; overrides the config's `target`.
    pub target: Option<DrawTarget>,
    /// Run config (TOML); `None`: [`DrawConfig::quick`] with `quick`, f-IRL's settings
    /// otherwise.
    pub config: Option<PathBuf>,
    pub quick: bool,
    pub seed: u64,
    /// The run directory: must not exist or be empty (or `force`, for one this program wrote).
    pub out: PathBuf,
    pub force: bool,
    /// No per-estimate lines on stderr.
    pub quiet: bool,
}

/// `reacher draw`: runs the baseline, writes the run directory and prints the first and last
/// KL estimates.
pub fn run(args: DrawRequest) -> Result<()> {
    let mut config = match (&args.config, args.quick) {
        (Some(path), _) => DrawConfig::load(path).map_err(usage)?,
        (None, true) => DrawConfig::quick(),
        (None, false) => DrawConfig::default(),
    };
    if let Some(target) = args.target {
        config.target = target;
    }
    if !matches!(args.algo, Algo::MaxEnt | Algo::Fkl | Algo::Rkl | Algo::Js) {
        return Err(UsageError(format!(
            "--algo {}: ReacherDraw runs maxent, fkl, rkl or js (no labelled events for SMIRL)",
            args.algo
        ))
        .into());
    }
    let output = OutputDir::check(&args.out, args.force).map_err(usage)?;
    let partial = output.begin()?;
    let result = draw::run_draw(args.algo, &config, args.seed, |row| {
        if !args.quiet {
            eprintln!(
                "iteration {:>5}  env steps {:>7}  KL(target||agent) {:>8.3}  KL(agent||target) {:>8.3}  {:.0} s",
                row.iteration, row.env_steps, row.forward_kl, row.reverse_kl, row.wall_secs
            );
        }
    })?;
    let summary = draw::write_run(&partial, args.algo, args.seed, &config, &result)
        .map_err(anyhow::Error::msg)?;
    output.commit(&partial)?;
    println!(
        "{} {} seed {}: forward KL {:.3} -> {:.3} ({:.0} %), reverse KL {:.3} -> {:.3} ({:.0} %), {:.0} s; wrote {}",
        summary.algo,
        config.target.name(),
        args.seed,
        summary.first_forward_kl,
        summary.last_forward_kl,
        100.0 * summary.forward_ratio,
        summary.first_reverse_kl,
        summary.last_reverse_kl,
        100.0 * summary.reverse_ratio,
        summary.wall_secs,
        args.out.display()
    );
    Ok(())
}
