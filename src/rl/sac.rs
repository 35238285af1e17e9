//! Soft Actor-Critic (Haarnoja et al. 2018) on [`ContinuousEnv`](crate::env::ContinuousEnv).
//!
//! - [`SacConfig`]: hyper-parameters (TOML, paper defaults, expert preset).
//! - [`SacAgent`]: networks, optimisers, temperature; [`SacAgent::update`] is one gradient step.
//! - [`SacTrainer`]: the one training loop (environment steps, replay, updates, checkpoints).
//!
//! ## Rewards are computed at sample time
//! The trainer stores what the environment reported (observations, action, next observation,
//! the environment's reward, labels, `terminated`) and asks a [`RewardFn`] for the rewards of
//! each sampled batch just before the update. [`EnvReward`] returns the stored environment
//! reward; an IRL method passes its current reward model instead. This is the only choice that
//! is correct for f-IRL and MaxEnt IRL, whose reward changes between iterations while the
//! replay buffer persists: rewards written at collection time would be stale. Evaluating the
//! reward on a whole batch also lets a reward network run one batched forward pass.

mod agent;
mod config;
mod episode;
mod trainer;

pub use agent::{draw_noise, ActMode, ActWorkspace, SacAgent, UpdateStats};
pub(crate) use config::{deserialize_table, load_toml, parse_table};
pub use config::{ConfigError, SacConfig};
pub use episode::{EpisodeSummary, RolloutStep};
pub use trainer::{
    episode_seed, CheckpointError, EnvReward, ObserverError, RewardFn, RewardFnError, SacTrainer,
    StepOutcome, TrainingObserver,
};

use crate::env::EnvError;

/// Errors that stop training.
#[derive(Debug, thiserror::Error)]
pub enum SacError {
    #[error("non-finite {what} in the {network} network at update {update}; training stopped")]
    NonFinite {
        network: &'static str,
        what: &'static str,
        update: u64,
    },
    #[error("environment step {step}: {source}")]
    Env {
        step: u64,
        #[source]
        source: EnvError,
    },
    #[error("training observer at environment step {step}: {source}")]
    Observer {
        step: u64,
        #[source]
        source: ObserverError,
    },
    #[error("rewards of the batch sampled at environment step {step}: {source}")]
    Reward {
        step: u64,
        #[source]
        source: RewardFnError,
    },
    #[error("environment has {what} {got}, the agent was built for {expected}")]
    Dimension {
        what: &'static str,
        expected: usize,
        got: usize,
    },
}
