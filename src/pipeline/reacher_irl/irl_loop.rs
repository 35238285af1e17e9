//! The IRL loop, written once ([`iterate`]): per iteration,
//!
//! 1. SAC on the reward being learned ([`IrlPhases::sac_phase`]),
//! 2. fresh rollouts of the stochastic policy ([`IrlPhases::rollouts`]),
//! 3. the algorithm's reward update from them ([`IrlPhases::reward_update`]: its loss
//!    coefficients and reward steps),
//! 4. what the iteration is measured by ([`IrlPhases::record`]).
//!
//! Two kinds of job run it. The Reacher comparison's (`run`, `JobPhases`): the untrained
//! policy is evaluated first, every iteration ends with the ground-truth evaluation of the job's
//! watch, and the final phase ([`final_policy`]) follows on the final reward when the settings
//! ask for one; what an algorithm brings there is its reward (`RewardLearner`): SMIRL's
//! (`super::smirl::train`) and f-IRL's and continuous MaxEnt's (`super::firl::train`).
//! ReacherDraw's (`crate::pipeline::reacher_draw::run_draw`): its own lockstep rollouts, the
//! fingertip density's coefficients, and KL estimates as the record.

use super::agent_phases::{train_sac, RolloutStream};
use super::config::IrlRunConfig;
use super::episodes::{AgentBatch, JobEnv};
use super::evaluation::{JobWatch, UpdateFacts};
use super::final_policy::{self, FinalPhase, FinalPolicy, ScoredReward};
use super::iteration::StepError;
use crate::rl::sac::SacTrainer;

/// The four phases of one IRL iteration, as a kind of job runs them.
pub trait IrlPhases {
    /// What the rollouts hand to the reward update.
    type Batch;
    /// What the reward update hands to the record.
    type Facts;
    type Error;

    /// Phase 1: SAC on the current reward.
    fn sac_phase(&mut self, iteration: usize) -> Result<(), Self::Error>;
    /// Phase 2: fresh episodes of the stochastic policy.
    fn rollouts(&mut self, iteration: usize) -> Result<Self::Batch, Self::Error>;
    /// Phase 3: the loss coefficients at `batch` (and the expert's), then the reward steps.
    fn reward_update(
        &mut self,
        iteration: usize,
        batch: Self::Batch,
    ) -> Result<Self::Facts, Self::Error>;
    /// Phase 4: the iteration's measurement.
    fn record(&mut self, iteration: usize, facts: Self::Facts) -> Result<(), Self::Error>;
}

/// Runs IRL iterations 1..=`iterations` of `phases` (see the module docs).
pub fn iterate<P: IrlPhases>(phases: &mut P, iterations: usize) -> Result<(), P::Error> {
    for iteration in 1..=iterations {
        phases.sac_phase(iteration)?;
        let batch = phases.rollouts(iteration)?;
        let facts = phases.reward_update(iteration, batch)?;
        phases.record(iteration, facts)?;
    }
    Ok(())
}

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
    let mut job = JobPhases {
        learner: &mut *learner,
        sac: &mut *sac,
        env: &mut *env,
        settings,
        rollouts: RolloutStream::new(seed),
        watch: &mut *watch,
    };
    iterate(&mut job, settings.irl_iterations)?;
    // The final phase: SAC goes on with the final reward, now fixed.
    final_phase
        .map(|phase| {
            let mut reward = learner.sac_reward()?;
            final_policy::train(sac, env, &mut reward, phase, settings.irl_iterations, watch)
        })
        .transpose()
}

/// A Reacher job's iterations: `learner`'s reward, `sac` acting in `env`, every phase shown
/// to the job's `watch`.
struct JobPhases<'j, 'w, 'l, E, L> {
    learner: &'j mut L,
    sac: &'j mut SacTrainer,
    env: &'j mut E,
    settings: &'j IrlRunConfig,
    rollouts: RolloutStream,
    watch: &'j mut JobWatch<'w, 'l>,
}

impl<E: JobEnv, L: RewardLearner> IrlPhases for JobPhases<'_, '_, '_, E, L> {
    type Batch = AgentBatch;
    type Facts = UpdateFacts;
    type Error = StepError;

    fn sac_phase(&mut self, iteration: usize) -> Result<(), StepError> {
        let steps = self.settings.sac_steps_per_iteration;
        let mut reward = self.learner.sac_reward()?;
        train_sac(
            self.sac,
            self.env,
            &mut reward,
            steps,
            iteration,
            self.watch,
        )
    }

    fn rollouts(&mut self, _iteration: usize) -> Result<AgentBatch, StepError> {
        let n = self.settings.agent_trajectories;
        (self.rollouts).collect(&mut self.sac.agent, self.env, n, self.watch)
    }

    fn reward_update(
        &mut self,
        iteration: usize,
        batch: AgentBatch,
    ) -> Result<UpdateFacts, StepError> {
        self.learner.update(iteration, batch)
    }

    /// The ground-truth evaluation of the iteration's policy.
    fn record(&mut self, iteration: usize, facts: UpdateFacts) -> Result<(), StepError> {
        let env_steps = self.sac.env_steps();
        (self.watch).iteration_done(
            iteration,
            env_steps,
            &mut self.sac.agent,
            self.env,
            Some(facts),
        )
    }
}
