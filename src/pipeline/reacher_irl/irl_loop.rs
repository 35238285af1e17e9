//! The IRL loop of the Reacher jobs ([`run`]), written once, top to bottom: the untrained
//! policy's evaluation, then per iteration
//!
//! 1. SAC on the reward being learned,
//! 2. fresh rollouts of the stochastic policy,
//! 3. the algorithm's reward update from them (its loss coefficients and reward steps:
//!    [`RewardLearner::update`]),
//! 4. the ground-truth evaluation of the iteration's policy by the job's watch,
//!
//! and the final phase ([`final_policy`]) on the final reward when the settings ask for one.
//! What an algorithm brings is its reward (`RewardLearner`): SMIRL's (`super::smirl::train`)
//! and f-IRL's and continuous MaxEnt's (`super::firl::train`). ReacherDraw
//! (`crate::pipeline::reacher_draw::run_draw`) runs the same four phases in a loop of its own.

use super::agent_phases::{train_sac, RolloutStream};
use super::config::IrlRunConfig;
use super::episodes::{AgentBatch, JobEnv};
use super::evaluation::{JobWatch, UpdateFacts};
use super::final_policy::{self, FinalPhase, FinalPolicy, ScoredReward};
use super::iteration::StepError;
use crate::rl::sac::SacTrainer;

/// An IRL algorithm's learned reward, as the Reacher jobs' loop ([`run`]) uses it.
pub(super) trait RewardLearner {
    /// The current reward as SAC trains on it (and the final phase scores its candidates
    /// with), borrowing the learner.
    type SacReward<'a>: ScoredReward
    where
        Self: 'a;

    /// The current reward for SAC (phase 1 of an iteration, and the final phase).
    fn sac_reward(&mut self) -> Result<Self::SacReward<'_>, StepError>;

    /// Phase 3 of `iteration`: the loss coefficients at the agent's rollouts `batch` and the
    /// demonstrations, then the reward steps; returns what the iteration's metrics row reports
    /// of the update.
    fn update(&mut self, iteration: usize, batch: AgentBatch) -> Result<UpdateFacts, StepError>;
}

/// Runs the settings' IRL iterations of `learner` with `sac` acting in `env` (see the module
/// docs), then `final_phase` if given. `seed` is the job's (its rollouts' streams).
pub(super) fn run<E: JobEnv, L: RewardLearner>(
    learner: &mut L,
    sac: &mut SacTrainer,
    env: &mut E,
    settings: &IrlRunConfig,
    seed: u64,
    final_phase: Option<FinalPhase>,
    watch: &mut JobWatch<'_, '_>,
) -> Result<Option<FinalPolicy>, StepError> {
    // 0. The untrained policy's evaluation.
    watch.iteration_done(0, 0, &mut sac.agent, env, None)?;
    let mut rollouts = RolloutStream::new(seed);
    for iteration in 1..=settings.irl_iterations {
        // 1. SAC on the current reward.
        let steps = settings.sac_steps_per_iteration;
        train_sac(
            sac,
            env,
            &mut learner.sac_reward()?,
            steps,
            iteration,
            watch,
        )?;
        // 2. Fresh episodes of the stochastic policy.
        let batch = rollouts.collect(&mut sac.agent, env, settings.agent_trajectories, watch)?;
        // 3. The algorithm's reward update.
        let facts = learner.update(iteration, batch)?;
        // 4. The ground-truth evaluation of the iteration's policy.
        let env_steps = sac.env_steps();
        watch.iteration_done(iteration, env_steps, &mut sac.agent, env, Some(facts))?;
    }
    // The final phase: SAC goes on with the final reward, now fixed.
    final_phase
        .map(|phase| {
            let mut reward = learner.sac_reward()?;
            final_policy::train(sac, env, &mut reward, phase, settings.irl_iterations, watch)
        })
        .transpose()
}
