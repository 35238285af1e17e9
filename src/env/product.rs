//! The product of a continuous environment with a reward machine (paper appendix B, MDP-RM):
//! observation ⊕ one-hot machine state, reward from the machine, episode ends when the
//! machine reaches a terminal (goal) state or a failure sink.
//!
//! Optional potential-based shaping (Ng, Harada & Russell 1999) adds
//! `F = γ·Φ(o', u') − Φ(o, u)` to the machine's reward, with `Φ = 0` once the machine is in a
//! terminal or failure state. Shaping of this form leaves the optimal policies of the product
//! MDP unchanged, so experts trained with it are experts of the task; it only gives SAC a
//! gradient toward the current sub-goal where the task reward is a single sparse 1.

use super::{ContinuousEnv, EnvError, EnvStep};
use crate::rm::product::{one_hot, RmTracker};
use crate::rm::RewardMachine;

/// A potential over (inner observation, machine state).
pub trait Potential {
    fn potential(&self, obs: &[f32], rm_state: usize) -> f64;
}

/// What a product step adds to the inner environment's report.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ProductStep {
    /// The step as the learner sees it: `reward` is the machine's reward (+ shaping),
    /// `terminated` is set when the machine reached a terminal or failure state.
    pub step: EnvStep,
    /// The inner environment's own reward.
    pub env_reward: f64,
    /// The machine's reward alone (no shaping): the task's ground-truth reward.
    pub task_reward: f64,
    /// Machine state after the step.
    pub rm_state: usize,
    /// The task was completed on this step.
    pub success: bool,
    /// The machine entered a failure sink on this step.
    pub failure: bool,
}

/// `inner` × reward machine, itself a [`ContinuousEnv`].
pub struct ProductEnv<E, P = NoShaping> {
    inner: E,
    tracker: RmTracker,
    potential: P,
    shaping_scale: f64,
    gamma: f64,
    inner_obs: Vec<f32>,
    last_potential: f64,
    last: Option<ProductStep>,
}

/// No shaping: the machine's reward only.
#[derive(Clone, Copy, Debug, Default)]
pub struct NoShaping;

impl Potential for NoShaping {
    fn potential(&self, _obs: &[f32], _rm_state: usize) -> f64 {
        0.0
    }
}

impl<E: ContinuousEnv> ProductEnv<E, NoShaping> {
    pub fn new(inner: E, rm: RewardMachine) -> Self {
        ProductEnv::with_shaping(inner, rm, NoShaping, 0.0, 0.99)
    }
}

impl<E: ContinuousEnv, P: Potential> ProductEnv<E, P> {
    /// The product with shaping `scale · (γ·Φ(o', u') − Φ(o, u))`; `gamma` must be the
    /// learner's discount for the optimal policies to be preserved.
    pub fn with_shaping(inner: E, rm: RewardMachine, potential: P, scale: f64, gamma: f64) -> Self {
        let inner_obs = vec![0.0; inner.obs_dim()];
        ProductEnv {
            inner,
            tracker: RmTracker::new(rm),
            potential,
            shaping_scale: scale,
            gamma,
            inner_obs,
            last_potential: 0.0,
            last: None,
        }
    }

    pub fn inner(&self) -> &E {
        &self.inner
    }

    /// The same product (machine, shaping) around `inner`, another environment like
    /// this one's inner, as new: for playing episodes side by side.
    pub fn around(&self, inner: E) -> Self
    where
        P: Clone,
    {
        let mut tracker = self.tracker.clone();
        tracker.reset();
        ProductEnv {
            inner_obs: vec![0.0; inner.obs_dim()],
            inner,
            tracker,
            potential: self.potential.clone(),
            shaping_scale: self.shaping_scale,
            gamma: self.gamma,
            last_potential: 0.0,
            last: None,
        }
    }

    pub fn inner_mut(&mut self) -> &mut E {
        &mut self.inner
    }

    pub fn rm(&self) -> &RewardMachine {
        self.tracker.rm()
    }

    pub fn rm_state(&self) -> usize {
        self.tracker.state()
    }

    /// Details of the last step (`None` right after a reset).
    pub fn last_step(&self) -> Option<&ProductStep> {
        self.last.as_ref()
    }

    /// Inner observation of the last reset/step.
    pub fn inner_obs(&self) -> &[f32] {
        &self.inner_obs
    }

    fn shaped_potential(&self, rm_state: usize) -> f64 {
        if self.tracker.rm().is_absorbing(rm_state) || self.shaping_scale == 0.0 {
            0.0
        } else {
            self.shaping_scale * self.potential.potential(&self.inner_obs, rm_state)
        }
    }

    fn write_obs(&self, obs: &mut [f32]) {
        let n = self.inner_obs.len();
        let k = self.tracker.n_states();
        obs[..n].copy_from_slice(&self.inner_obs);
        one_hot(self.tracker.state(), &mut obs[n..n + k]);
    }

    /// A step with the full product report.
    pub fn step_product(
        &mut self,
        action: &[f32],
        obs: &mut [f32],
    ) -> Result<ProductStep, EnvError> {
        let inner = self.inner.step(action, &mut self.inner_obs)?;
        let rm = self.tracker.step(inner.labels);
        let potential = self.shaped_potential(rm.state);
        let shaping = self.gamma * potential - self.last_potential;
        self.last_potential = potential;
        let done = rm.terminal || rm.failure;
        let step = ProductStep {
            step: EnvStep {
                reward: rm.reward + shaping,
                labels: inner.labels,
                terminated: done || inner.terminated,
                truncated: inner.truncated && !done,
            },
            env_reward: inner.reward,
            task_reward: rm.reward,
            rm_state: rm.state,
            success: rm.terminal,
            failure: rm.failure,
        };
        self.write_obs(obs);
        self.last = Some(step);
        Ok(step)
    }
}

impl<E: ContinuousEnv, P: Potential> ContinuousEnv for ProductEnv<E, P> {
    fn obs_dim(&self) -> usize {
        self.inner.obs_dim() + self.tracker.n_states()
    }

    fn act_dim(&self) -> usize {
        self.inner.act_dim()
    }

    fn reset(&mut self, seed: u64, obs: &mut [f32]) {
        self.inner.reset(seed, &mut self.inner_obs);
        self.tracker.reset();
        self.last_potential = self.shaped_potential(self.tracker.state());
        self.last = None;
        self.write_obs(obs);
    }

    fn step(&mut self, action: &[f32], obs: &mut [f32]) -> Result<EnvStep, EnvError> {
        self.step_product(action, obs).map(|p| p.step)
    }
}
