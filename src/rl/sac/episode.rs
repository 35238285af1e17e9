//! What the agent's rollouts and the trainer's episodes report: the types both use, so that
//! `agent` (acting, updates) and `trainer` (the training loop) do not import each other.

use crate::env::EnvStep;

/// A finished episode.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EpisodeSummary {
    /// 0-based episode index.
    pub index: u64,
    /// Sum of the environment's rewards.
    pub env_return: f64,
    /// The environment's reward of the last step.
    pub final_reward: f64,
    pub length: u64,
    /// Ended by the environment (else by the time limit).
    pub terminated: bool,
}

/// One step of [`super::SacAgent::rollout`].
#[derive(Clone, Copy, Debug)]
pub struct RolloutStep<'a> {
    /// 0-based step index within the episode.
    pub t: u64,
    pub obs: &'a [f32],
    pub action: &'a [f32],
    pub next_obs: &'a [f32],
    pub env_step: EnvStep,
}
