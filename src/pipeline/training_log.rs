//! Logging SAC's own training episodes to a rollout log: a [`TrainingObserver`] that writes
//! every episode the trainer plays (reset seed, initial state, actions, states, labels, and
//! the task machine's state and reward tracked along the labels), so that `reacher replay`
//! can re-simulate training like any other rollout. The gradient updates between steps do not
//! matter to replay: the actions are recorded.
//!
//! The trainer may act in a product environment (SMIRL's learned machine, an expert's task
//! machine with shaping); what is logged is always the ReacherDelivery inside it, with the
//! environment's own reward, and the machine tracked is the task's (the one named in the
//! log's `/run` record), as for every other phase of a run.

use crate::env::product::{Potential, ProductEnv};
use crate::env::reacher::ReacherDelivery;
use crate::env::{ContinuousEnv, EnvStep};
use crate::log::RolloutLogger;
use crate::rl::sac::{EpisodeSummary, ObserverError, TrainingObserver};
use crate::rm::RewardMachine;

/// What the training log reads of the environment a trainer acts in.
pub trait ReacherView {
    /// The ReacherDelivery being simulated.
    fn reacher(&self) -> &ReacherDelivery;
    /// The last step as ReacherDelivery itself reported it (its own reward and time limit),
    /// given the step the trainer saw. `terminated` stays as the trainer saw it (the episode
    /// ended there).
    fn inner_step(&self, seen: &EnvStep) -> EnvStep;
}

impl ReacherView for ReacherDelivery {
    fn reacher(&self) -> &ReacherDelivery {
        self
    }
    fn inner_step(&self, seen: &EnvStep) -> EnvStep {
        *seen
    }
}

impl<P: Potential> ReacherView for ProductEnv<ReacherDelivery, P> {
    fn reacher(&self) -> &ReacherDelivery {
        self.inner()
    }
    fn inner_step(&self, seen: &EnvStep) -> EnvStep {
        let inner = self.inner();
        EnvStep {
            reward: self.last_step().map_or(seen.reward, |s| s.env_reward),
            labels: seen.labels,
            terminated: seen.terminated,
            // The product clears `truncated` when its machine ends the episode on the same
            // step; replay compares with the environment's own flag.
            truncated: inner.steps() >= inner.config().max_steps,
        }
    }
}

/// A [`TrainingObserver`] writing the trainer's episodes to `logger` under `phase`
/// (sampled by the logger's `every_nth_episode` like any other episode).
///
/// An episode still running when this observer is dropped stays unfinished in the log, and
/// its continuation is not logged (the IRL loop avoids this by finishing SAC's episode in
/// progress before it pauses training for rollouts and evaluation).
pub struct TrainingLog<'a> {
    logger: &'a mut RolloutLogger,
    task_rm: &'a RewardMachine,
    phase: &'a str,
    /// Task machine state and success so far of the logged episode in progress.
    open: Option<(usize, bool)>,
}

impl<'a> TrainingLog<'a> {
    pub fn new(
        logger: &'a mut RolloutLogger,
        task_rm: &'a RewardMachine,
        phase: &'a str,
    ) -> TrainingLog<'a> {
        TrainingLog {
            logger,
            task_rm,
            phase,
            open: None,
        }
    }
}

impl<E: ReacherView + ?Sized> TrainingObserver<E> for TrainingLog<'_> {
    fn episode_started(
        &mut self,
        env: &E,
        reset_seed: u64,
        obs: &[f32],
    ) -> Result<(), ObserverError> {
        let u = self.task_rm.initial();
        let logged = self.logger.begin_reacher_episode(
            env.reacher(),
            reset_seed,
            self.phase,
            Some(u),
            &obs[..env.reacher().obs_dim()],
        )?;
        self.open = logged.then_some((u, false));
        Ok(())
    }

    fn stepped(
        &mut self,
        env: &E,
        action: &[f32],
        step: &EnvStep,
        obs: &[f32],
    ) -> Result<(), ObserverError> {
        let Some((u, success)) = self.open.as_mut() else {
            return Ok(());
        };
        let (next, reward) = self.task_rm.step(*u, step.labels);
        *u = next;
        *success |= self.task_rm.is_terminal(next) && !self.task_rm.is_failure(next);
        self.logger.reacher_step(
            env.reacher(),
            action,
            &env.inner_step(step),
            Some((next, reward)),
            &obs[..env.reacher().obs_dim()],
        )?;
        Ok(())
    }

    fn episode_ended(&mut self, _env: &E, _episode: &EpisodeSummary) -> Result<(), ObserverError> {
        if let Some((_, success)) = self.open.take() {
            self.logger.end_episode(success)?;
        }
        Ok(())
    }
}
