//! The SAC expert training loop: runs [`SacTrainer`] on an environment's own reward for a
//! step budget, checkpoints periodically, resumes a killed run exactly, records a training
//! curve and measures the success rate.
//!
//! Environment-agnostic: the caller passes the environment (for the paper, ReacherDelivery in
//! product with the task's reward machine, see [`super::reacher_expert`]) and a success
//! predicate on finished episodes. Progress goes to a callback so a command can draw a
//! progress bar.
//!
//! Files, next to each other: the checkpoint (`<name>`, see [`SacTrainer::save_checkpoint`])
//! and the training curve (`<name>.curve.csv`, one row per training episode). Both are written
//! atomically at every checkpoint; on resume, curve rows beyond the checkpoint are dropped.
//! A run that hits NaN/inf stops with an error and leaves the last good checkpoint in place.

use crate::atomic_file::write_atomic;
use crate::env::ContinuousEnv;
use crate::rl::sac::{
    ActMode, CheckpointError, ConfigError, EnvReward, EpisodeSummary, SacConfig, SacError,
    SacTrainer, TrainingObserver, UpdateStats,
};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// One training run of [`train_expert`]: the SAC settings and the run's length, checkpoints,
/// evaluation and progress window. (A task expert's config file,
/// [`super::reacher_expert::ExpertConfig`], holds these next to its environment.)
#[derive(Clone, Debug, PartialEq)]
pub struct TrainingPlan {
    pub sac: SacConfig,
    /// Training stops at the first episode boundary at or after this many environment steps.
    pub total_steps: u64,
    /// A checkpoint is taken at the first episode boundary after every this many steps.
    pub checkpoint_every: u64,
    /// Deterministic (mean-action) evaluation episodes after training.
    pub eval_episodes: u64,
    /// Step limit of an evaluation episode (the environment's own limit normally ends it).
    pub eval_max_steps: u64,
    /// Window (in episodes) of the recent success rate and return reported as progress.
    pub progress_window: usize,
}

/// One training episode of the curve.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CurvePoint {
    /// Environment steps at the end of the episode.
    pub env_steps: u64,
    pub episode: u64,
    pub env_return: f64,
    pub length: u64,
    pub success: bool,
}

/// Reported after every episode.
#[derive(Clone, Copy, Debug)]
pub struct ExpertProgress {
    pub env_steps: u64,
    pub total_steps: u64,
    pub episodes: u64,
    /// Success rate over the last `progress_window` episodes.
    pub recent_success: f64,
    /// Mean return over the last `progress_window` episodes.
    pub recent_return: f64,
    pub last_update: Option<UpdateStats>,
    /// Set when a checkpoint was just written.
    pub checkpointed: bool,
}

/// A finished expert run.
#[derive(Debug)]
pub struct ExpertOutcome {
    pub trainer: SacTrainer,
    pub curve: Vec<CurvePoint>,
    /// Environment steps of the checkpoint the run resumed from, if it did.
    pub resumed_at: Option<u64>,
    pub eval: Vec<EpisodeSummary>,
    /// Fraction of evaluation episodes judged successful.
    pub success_rate: f64,
}

/// Why a training run stopped.
#[derive(Debug, thiserror::Error)]
pub enum TrainingError {
    #[error(transparent)]
    Config(#[from] ConfigError),
    #[error(transparent)]
    Sac(#[from] SacError),
    #[error(transparent)]
    Checkpoint(#[from] CheckpointError),
    #[error("{path}: {problem}")]
    Curve { path: String, problem: String },
    #[error("{0} exists: pass --resume to continue that run, or remove it to start over")]
    CheckpointExists(String),
}

/// Path of the training curve that belongs to `checkpoint`.
pub fn curve_path(checkpoint: &Path) -> PathBuf {
    let mut name = checkpoint.as_os_str().to_owned();
    name.push(".curve.csv");
    PathBuf::from(name)
}

const CURVE_HEADER: &str = "env_steps,episode,env_return,length,success";

fn write_curve(path: &Path, curve: &[CurvePoint]) -> Result<(), TrainingError> {
    let mut s = String::with_capacity(32 * curve.len() + 64);
    s.push_str(CURVE_HEADER);
    s.push('\n');
    for p in curve {
        let _ = writeln!(
            s,
            "{},{},{},{},{}",
            p.env_steps,
            p.episode,
            p.env_return,
            p.length,
            u8::from(p.success)
        );
    }
    write_atomic(path, s.as_bytes()).map_err(|e| TrainingError::Curve {
        path: path.display().to_string(),
        problem: e.to_string(),
    })
}

/// Reads a curve written by this module, keeping rows up to `env_steps`.
pub fn read_curve(path: &Path, up_to_steps: u64) -> Result<Vec<CurvePoint>, TrainingError> {
    let bad = |problem: String| TrainingError::Curve {
        path: path.display().to_string(),
        problem,
    };
    let text = crate::input_file::read_text(path, crate::input_file::MAX_DATA_FILE_BYTES)
        .map_err(|e| bad(e.to_string()))?;
    let mut lines = text.lines();
    if lines.next() != Some(CURVE_HEADER) {
        return Err(bad(format!("first line is not `{CURVE_HEADER}`")));
    }
    let mut curve = Vec::new();
    for (i, line) in lines.enumerate() {
        let f: Vec<&str> = line.split(',').collect();
        let row = || bad(format!("line {}: malformed row {line:?}", i + 2));
        if f.len() != 5 {
            return Err(row());
        }
        let p = CurvePoint {
            env_steps: f[0].parse().map_err(|_| row())?,
            episode: f[1].parse().map_err(|_| row())?,
            env_return: f[2]
                .parse::<f64>()
                .ok()
                .filter(|r| r.is_finite())
                .ok_or_else(row)?,
            length: f[3].parse().map_err(|_| row())?,
            success: match f[4] {
                "0" => false,
                "1" => true,
                _ => return Err(row()),
            },
        };
        if p.env_steps <= up_to_steps {
            curve.push(p);
        }
    }
    Ok(curve)
}

fn save(
    trainer: &SacTrainer,
    checkpoint: &Path,
    curve: &[CurvePoint],
) -> Result<(), TrainingError> {
    write_curve(&curve_path(checkpoint), curve)?;
    trainer.save_checkpoint(checkpoint)?;
    Ok(())
}

/// Trains (or, with `resume`, continues) a SAC expert on `env`'s own reward, checkpointing to
/// `checkpoint`, then evaluates it with mean actions. `success` judges finished episodes;
/// `observer` (e.g. a [`super::training_log::TrainingLog`]) sees every training episode.
///
/// Without `resume`, an existing checkpoint is refused rather than overwritten; with
/// `resume` and no checkpoint yet, the run starts from scratch.
#[allow(clippy::too_many_arguments)]
pub fn train_expert<E, S, P>(
    env: &mut E,
    plan: &TrainingPlan,
    seed: u64,
    checkpoint: &Path,
    resume: bool,
    mut success: S,
    mut progress: P,
    mut observer: Option<&mut (dyn TrainingObserver<E> + '_)>,
) -> Result<ExpertOutcome, TrainingError>
where
    E: ContinuousEnv + ?Sized,
    S: FnMut(&EpisodeSummary) -> bool,
    P: FnMut(&ExpertProgress),
{
    plan.sac.validate()?;
    let (obs_dim, act_dim) = (env.obs_dim(), env.act_dim());
    let (mut trainer, mut curve, resumed_at) = if checkpoint.exists() {
        if !resume {
            return Err(TrainingError::CheckpointExists(
                checkpoint.display().to_string(),
            ));
        }
        let trainer = SacTrainer::resume(checkpoint, &plan.sac, obs_dim, act_dim)?;
        let steps = trainer.env_steps();
        let curve = read_curve(&curve_path(checkpoint), steps)?;
        (trainer, curve, Some(steps))
    } else {
        (
            SacTrainer::new(&plan.sac, obs_dim, act_dim, seed)?,
            Vec::new(),
            None,
        )
    };
    let every = plan.checkpoint_every.max(1);
    let mut next_checkpoint = (trainer.env_steps() / every + 1) * every;
    let window = plan.progress_window.max(1);
    while trainer.env_steps() < plan.total_steps || !trainer.at_episode_boundary() {
        let outcome = trainer.step_observed(env, &mut EnvReward, observer.as_deref_mut())?;
        let Some(ep) = outcome.episode else { continue };
        curve.push(CurvePoint {
            env_steps: trainer.env_steps(),
            episode: ep.index,
            env_return: ep.env_return,
            length: ep.length,
            success: success(&ep),
        });
        let mut checkpointed = false;
        if trainer.env_steps() >= next_checkpoint {
            save(&trainer, checkpoint, &curve)?;
            next_checkpoint = (trainer.env_steps() / every + 1) * every;
            checkpointed = true;
        }
        let recent = &curve[curve.len().saturating_sub(window)..];
        progress(&ExpertProgress {
            env_steps: trainer.env_steps(),
            total_steps: plan.total_steps,
            episodes: trainer.episodes(),
            recent_success: recent.iter().filter(|p| p.success).count() as f64
                / recent.len() as f64,
            recent_return: recent.iter().map(|p| p.env_return).sum::<f64>() / recent.len() as f64,
            last_update: outcome.update,
            checkpointed,
        });
    }
    save(&trainer, checkpoint, &curve)?;
    // Evaluation resets are seeded apart from training resets.
    let eval = trainer.evaluate(
        env,
        plan.eval_episodes,
        ActMode::Mean,
        seed ^ 0x5eed_e7a1_0000_0000,
        plan.eval_max_steps,
    )?;
    let successes = eval.iter().filter(|e| success(e)).count();
    let success_rate = if eval.is_empty() {
        0.0
    } else {
        successes as f64 / eval.len() as f64
    };
    Ok(ExpertOutcome {
        trainer,
        curve,
        resumed_at,
        eval,
        success_rate,
    })
}
