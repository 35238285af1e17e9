//! Environments: ReacherDelivery (MuJoCo) and OfficeWorld, with their labelling functions.
//!
//! Continuous environments implement [`ContinuousEnv`], the interface the RL and IRL code
//! trains against. Observations and actions cross it as `f32` (what the networks use);
//! physics inside stays `f64`.

pub mod office;

use crate::rm::LabelSet;

/// What one environment step reports besides the next observation.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EnvStep {
    /// The environment's own reward.
    pub reward: f64,
    /// Propositions true after the step (the labelling function's output).
    pub labels: LabelSet,
    /// The episode ended inside the environment (e.g. a task finished).
    pub terminated: bool,
    /// The episode was cut by the time limit.
    pub truncated: bool,
}

/// A bad call into an environment.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum EnvError {
    #[error("action has {got} components, the environment takes {expected}")]
    ActionLength { expected: usize, got: usize },
    #[error("action component {index} is {value}, not a finite number")]
    ActionNotFinite { index: usize, value: f32 },
    #[error("step called before reset")]
    NotReset,
    #[error("simulation failed: {0}")]
    Simulation(String),
}

/// A continuous-control environment in the Gymnasium style.
pub trait ContinuousEnv {
    fn obs_dim(&self) -> usize;
    fn act_dim(&self) -> usize;
    /// Starts an episode whose randomness comes from `seed` only; writes the first
    /// observation into `obs` (length `obs_dim`).
    fn reset(&mut self, seed: u64, obs: &mut [f32]);
    /// Applies `action` (length `act_dim`; components are clipped to [-1, 1]) and writes the
    /// next observation into `obs`.
    fn step(&mut self, action: &[f32], obs: &mut [f32]) -> Result<EnvStep, EnvError>;
}

/// Checks an action's length and finiteness; the shared first step of every `step`.
pub fn check_action(action: &[f32], expected: usize) -> Result<(), EnvError> {
    if action.len() != expected {
        return Err(EnvError::ActionLength {
            expected,
            got: action.len(),
        });
    }
    match action.iter().position(|a| !a.is_finite()) {
        Some(index) => Err(EnvError::ActionNotFinite {
            index,
            value: action[index],
        }),
        None => Ok(()),
    }
}

pub mod episode;
pub mod layout;
pub mod physics_scene;
pub mod placement;
pub mod product;
pub mod reacher;
pub mod reacher_controller;
pub mod reacher_task;
pub mod scene_files;
pub mod scene_xml;
pub mod task_file;
