//! What one IRL iteration hands on: the batch of its reward update ([`Coefficients`]), the
//! ground-truth evaluation it is watched with ([`MetricsRow`], [`JobProgress`]) and, for SMIRL,
//! how the weights moved ([`RewardTraceRow`]); and why a step of an IRL loop fails
//! ([`StepError`]).

use super::episodes::EpisodeError;
use super::lockstep::LockstepError;
use crate::env::reacher::{ConfigError, ReacherError};
use crate::env::reacher_task::BranchTally;
use crate::irl::firl::SurrogateError;
use crate::irl::kde::KdeError;
use crate::irl::reward::RewardError;
use crate::rl::crm::CrmError;
use crate::rl::sac::{ConfigError as SacConfigError, SacError};

/// A step of an IRL job's loop that failed: its episodes, SAC, the reward, the density
/// ratios or the batch of a reward update.
#[derive(Debug, thiserror::Error)]
pub enum StepError {
    #[error(transparent)]
    Episode(#[from] EpisodeError),
    #[error(transparent)]
    Lockstep(#[from] LockstepError),
    #[error(transparent)]
    Environment(#[from] ReacherError),
    /// The run's environment config names no task layout.
    #[error(transparent)]
    TaskLayout(#[from] ConfigError),
    #[error(transparent)]
    SacConfig(#[from] SacConfigError),
    #[error("SAC: {0}")]
    Sac(SacError),
    #[error(transparent)]
    Counterfactual(#[from] CrmError),
    #[error(transparent)]
    Reward(#[from] RewardError),
    #[error("reward update: {0}")]
    RewardUpdate(RewardError),
    #[error("expert KDE: {0}")]
    ExpertKde(KdeError),
    /// The agent's density (f-IRL's ratio).
    #[error(transparent)]
    Kde(#[from] KdeError),
    #[error(transparent)]
    Surrogate(#[from] SurrogateError),
    #[error("{states} learned-machine states for {rows} observations")]
    StateCount { states: usize, rows: usize },
    #[error("state {state} is not a state of the {n}-state machine")]
    UnknownState { state: u32, n: usize },
    #[error("no agent trajectories")]
    NoAgentTrajectories,
    #[error("f-IRL needs agent trajectories of one fixed length")]
    UnequalAgentLengths,
    #[error("f-IRL needs density ratios")]
    NoRatios,
    #[error("f-IRL has no density ratios at the demonstrations")]
    NoExpertRatios,
    #[error("no demonstration {0}")]
    NoDemonstration(usize),
    #[error(
        "demonstration {k} has {len} steps, the agent's trajectories {horizon}: f-IRL's \
         covariance batch needs one length"
    )]
    DemonstrationLength {
        k: usize,
        len: usize,
        horizon: usize,
    },
    #[error("{rewards} learned rewards for {steps} selection steps")]
    SelectionRewards { rewards: usize, steps: usize },
}

/// One row of the metrics table: the ground-truth evaluation after `iteration` IRL
/// iterations (0 = the untrained policy).
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct MetricsRow {
    pub iteration: usize,
    pub env_steps: u64,
    /// Fraction of evaluation episodes in which the task's perfect machine reached its goal;
    /// for a conditional task (IF, Composite) the lower of the two branches' rates.
    pub success_rate: f64,
    /// Conditional tasks: evaluation episodes and successes per branch.
    pub branches: Option<BranchTally>,
    /// Mean sum of the perfect machine's rewards.
    pub task_return: f64,
    /// Mean sum of the environment's own (distance) rewards.
    pub env_return: f64,
    /// Mean learned reward per step of the agent's rollouts this iteration.
    pub learned_reward: f64,
    /// The algorithm's surrogate loss Σ c_i r(o_i) before this iteration's update.
    pub surrogate_loss: f64,
    /// Mean fraction of the task's sub-goals completed along the perfect machine
    /// (`env::reacher_task::TaskProgress`); `None` in jobs run before the metric existed.
    #[serde(default)]
    pub progress: Option<f64>,
    /// Fraction of evaluation episodes that touched a ball which can end the task (the
    /// paper's "end location"); `None` in jobs run before the metric existed.
    #[serde(default)]
    pub final_ball: Option<f64>,
    /// Fraction of this iteration's agent fingertip states inside the support of the expert's
    /// Epanechnikov KDE (within `kde_bandwidth` of some demonstration state): where f-IRL's
    /// density ratio can be anything but 0. `None` before the first rollouts and in jobs run
    /// before the measurement existed.
    #[serde(default)]
    pub expert_support: Option<f64>,
}

/// One iteration of a SMIRL job's reward trace: how the weights moved and why.
#[derive(Clone, Debug, PartialEq)]
pub struct RewardTraceRow {
    pub iteration: usize,
    /// The loss gradient without L2 (μ_π − μ_D under the configured normalisation) before
    /// this iteration's update.
    pub data_gradient: Vec<f32>,
    /// The weights after this iteration's update.
    pub weights: Vec<f32>,
}

/// Progress of a job, for progress bars.
#[derive(Clone, Copy, Debug)]
pub struct JobProgress {
    pub iteration: usize,
    pub iterations: usize,
    pub env_steps: u64,
    pub total_env_steps: u64,
    /// Success rate of the last evaluation.
    pub success_rate: f64,
}

/// The batch of one reward update: rows, their learned-machine states (SMIRL) and loss
/// coefficients.
#[derive(Clone, Debug, PartialEq)]
pub struct Coefficients {
    /// Row-major observations, one task observation wide.
    pub obs: Vec<f32>,
    /// Learned-machine state of each row (empty for the baselines).
    pub states: Vec<u32>,
    pub coeffs: Vec<f64>,
}
