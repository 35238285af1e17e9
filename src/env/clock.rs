//! The agent's clock: one more observation entry, the share of the episode's steps still to
//! come (1 at reset, 0 from the time limit on).
//!
//! Why every learner may get it: the cancel of ReacherDelivery comes only on early steps, so
//! an observation without time is not Markovian for a task that depends on it — an agent that
//! cannot tell step 9 from step 1 may keep waiting for an event that can no longer come
//! (Pardo et al. 2018, "Time limits in reinforcement learning", give the remaining time as
//! input for this reason). Nothing about it is specific to reward machines: the product
//! ([`super::product::ProductEnv`]) puts it after the one-hot machine state, [`Clocked`]
//! after a plain environment's observation. Rewards never read it.

use super::{ContinuousEnv, EnvError, EnvStep};

/// The observation entry a clock adds, if any.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Clock {
    /// No entry.
    #[default]
    None,
    /// `(horizon − t) / horizon` after step t, clamped at 0; `horizon` ≥ 1.
    CountDown(usize),
}

impl Clock {
    /// The clock of a run's settings: none, or the count-down over `horizon` steps.
    ///
    /// # Panics
    /// If a count-down is asked for with `horizon` 0 (a programming error: an episode has at
    /// least one step; configs are validated before).
    pub fn of(clock: bool, horizon: usize) -> Clock {
        if clock {
            assert!(horizon > 0, "a clock needs an episode of at least one step");
            Clock::CountDown(horizon)
        } else {
            Clock::None
        }
    }

    /// Observation entries the clock adds (1 or 0).
    pub fn dim(self) -> usize {
        usize::from(self != Clock::None)
    }

    /// The entry after `steps` steps of the episode (`None` without a clock).
    pub fn value(self, steps: usize) -> Option<f32> {
        match self {
            Clock::None => None,
            Clock::CountDown(horizon) => {
                Some((horizon - steps.min(horizon)) as f32 / horizon as f32)
            }
        }
    }
}

/// `inner` with the [`Clock`]'s entry after its observation; steps, rewards and labels are
/// the inner environment's. With [`Clock::None`] it is `inner` itself, observation for
/// observation.
pub struct Clocked<E> {
    inner: E,
    clock: Clock,
    steps: usize,
}

impl<E: ContinuousEnv> Clocked<E> {
    pub fn new(inner: E, clock: Clock) -> Clocked<E> {
        Clocked {
            inner,
            clock,
            steps: 0,
        }
    }

    pub fn inner(&self) -> &E {
        &self.inner
    }

    pub fn clock(&self) -> Clock {
        self.clock
    }

    fn write_clock(&self, obs: &mut [f32]) {
        if let Some(v) = self.clock.value(self.steps) {
            obs[self.inner.obs_dim()] = v;
        }
    }
}

impl<E: ContinuousEnv> ContinuousEnv for Clocked<E> {
    fn obs_dim(&self) -> usize {
        self.inner.obs_dim() + self.clock.dim()
    }

    fn act_dim(&self) -> usize {
        self.inner.act_dim()
    }

    fn reset(&mut self, seed: u64, obs: &mut [f32]) {
        let n = self.inner.obs_dim();
        self.inner.reset(seed, &mut obs[..n]);
        self.steps = 0;
        self.write_clock(obs);
    }

    fn step(&mut self, action: &[f32], obs: &mut [f32]) -> Result<EnvStep, EnvError> {
        let n = self.inner.obs_dim();
        let step = self.inner.step(action, &mut obs[..n])?;
        self.steps += 1;
        self.write_clock(obs);
        Ok(step)
    }
}
