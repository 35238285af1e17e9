//! A tiny continuous task for the SAC tests: a point on [−1, 1] that must reach a target.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use smirl::env::{check_action, ContinuousEnv, EnvError, EnvStep};
use smirl::rm::LabelSet;

/// Observation `[x, target − x]`; action moves x by at most 0.1; reward −|x − target|;
/// episodes are truncated after `horizon` steps.
pub struct PointReach {
    pub x: f32,
    pub target: f32,
    pub t: usize,
    pub horizon: usize,
    pub started: bool,
}

impl PointReach {
    pub fn new(horizon: usize) -> Self {
        Self {
            x: 0.0,
            target: 0.5,
            t: 0,
            horizon,
            started: false,
        }
    }
    fn write_obs(&self, obs: &mut [f32]) {
        obs[0] = self.x;
        obs[1] = self.target - self.x;
    }
}

impl ContinuousEnv for PointReach {
    fn obs_dim(&self) -> usize {
        2
    }
    fn act_dim(&self) -> usize {
        1
    }
    fn reset(&mut self, seed: u64, obs: &mut [f32]) {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        self.x = rng.gen_range(-1.0..1.0);
        self.t = 0;
        self.started = true;
        self.write_obs(obs);
    }
    fn step(&mut self, action: &[f32], obs: &mut [f32]) -> Result<EnvStep, EnvError> {
        if !self.started {
            return Err(EnvError::NotReset);
        }
        check_action(action, 1)?;
        self.x = (self.x + 0.1 * action[0].clamp(-1.0, 1.0)).clamp(-1.0, 1.0);
        self.t += 1;
        self.write_obs(obs);
        Ok(EnvStep {
            reward: -f64::from((self.x - self.target).abs()),
            labels: LabelSet::EMPTY,
            terminated: false,
            truncated: self.t >= self.horizon,
        })
    }
}
