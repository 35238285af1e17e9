//! Apprenticeship IRL (Abbeel & Ng 2004), projection method, on the Office observations.
//!
//! Features are the paper's nine high-level label features (eq. 9): one-hot of the
//! proposition of the cell landed on (8) or "no label" (1). Feature expectations
//! `μ = Σ_t γ^t φ(o_{t+1})` over the demonstration horizon, from the start cell. The learner
//! observes cells only (no machine). The policy for a weight vector `w` is the greedy policy
//! of value iteration on the known world model with reward `wᵀ φ(o')` (default), or of
//! Q-learning with the world as simulator ([`PolicySolver::QLearning`], as the paper's TD
//! learning). The learner's μ comes from one rollout of that deterministic policy in the
//! deterministic world, which is exact; its steps count as environment interactions.
//!
//! Projection method: `μ̄₀ = μ(π₀)` for a random initial `w₀`; step i: `w_i = μ_E − μ̄_{i−1}`,
//! margin `t_i = ‖w_i‖`, `π_i` optimal for `w_i`, `μ̄_i` = projection of `μ_E` onto the line
//! through `μ̄_{i−1}` and `μ(π_i)`. Stops when `t_i ≤ ε`.

use super::demos::Demonstration;
use crate::env::office::{OfficeWorld, N_ACTIONS};
use crate::rl::tabular::{
    greedy_actions, q_learning, value_iteration, DetMdp, Iteration, QLearning, TabularError,
};
use crate::rm::LabelSet;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// How the policy for a learned reward is computed.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case", deny_unknown_fields)]
pub enum PolicySolver {
    /// Value iteration on the known world model.
    ValueIteration,
    /// ε-greedy Q-learning for this many environment steps per IRL step.
    QLearning { steps: usize },
}

#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ApprenticeshipConfig {
    /// Discount of feature expectations and of the policy's objective.
    pub gamma: f64,
    /// Stop when the margin `‖μ_E − μ̄‖` falls below this.
    pub epsilon: f64,
    pub max_steps: usize,
    pub solver: PolicySolver,
}

impl Default for ApprenticeshipConfig {
    fn default() -> Self {
        ApprenticeshipConfig {
            gamma: 0.9,
            epsilon: 1e-3,
            max_steps: 30,
            solver: PolicySolver::ValueIteration,
        }
    }
}

/// Why apprenticeship learning cannot start. A setting's message begins with `key = value`,
/// which the Office configuration reads to name the key.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum ApprenticeshipError {
    #[error("gamma = {0} must be in (0, 1)")]
    Gamma(f64),
    #[error("epsilon = {0} must be ≥ 0")]
    Epsilon(f64),
    #[error("q-learning needs steps ≥ 1")]
    QLearningSteps,
    #[error("no non-empty demonstrations")]
    NoDemos,
    #[error(transparent)]
    Tabular(#[from] TabularError),
}

impl ApprenticeshipConfig {
    pub fn validate(&self) -> Result<(), ApprenticeshipError> {
        if !(self.gamma > 0.0 && self.gamma < 1.0) {
            return Err(ApprenticeshipError::Gamma(self.gamma));
        }
        if self.epsilon.is_nan() || self.epsilon < 0.0 {
            return Err(ApprenticeshipError::Epsilon(self.epsilon));
        }
        if let PolicySolver::QLearning { steps: 0 } = self.solver {
            return Err(ApprenticeshipError::QLearningSteps);
        }
        Ok(())
    }
}

/// Index of the label feature of a label set: its first proposition, or `n_props` for none.
pub fn label_feature(labels: LabelSet, n_props: usize) -> usize {
    (0..n_props)
        .find(|&p| labels.contains(p))
        .unwrap_or(n_props)
}

/// What one IRL step produced.
#[derive(Clone, Debug, PartialEq)]
pub struct ApprenticeshipStep {
    /// Reward weights over the label features (one per letter of the map, then "none").
    pub weights: Vec<f64>,
    /// Greedy action per cell.
    pub policy: Vec<u8>,
    /// `‖μ_E − μ̄‖` before this step (the projection method's margin).
    pub margin: f64,
    /// Environment steps used by this IRL step (rollouts, Q-learning).
    pub interactions: usize,
}

/// The projection method's state.
#[derive(Clone, Debug)]
pub struct Apprenticeship {
    world: OfficeWorld,
    mdp: DetMdp,
    cfg: ApprenticeshipConfig,
    horizon: usize,
    n_props: usize,
    mu_expert: Vec<f64>,
    mu_bar: Option<Vec<f64>>,
    /// Weights of the policies π₀..π_i in the mixture whose feature expectation is μ̄.
    mixture: Vec<f64>,
    rng: ChaCha8Rng,
    steps: usize,
    value_warm: Vec<f64>,
}

impl Apprenticeship {
    /// Expert feature expectations from `demos` (mean over demonstrations); the rollout
    /// horizon is the longest demonstration.
    pub fn new(
        world: &OfficeWorld,
        demos: &[Demonstration],
        cfg: ApprenticeshipConfig,
        seed: u64,
    ) -> Result<Apprenticeship, ApprenticeshipError> {
        cfg.validate()?;
        let n_props = world.vocab().len();
        let used: Vec<&Demonstration> = demos.iter().filter(|d| !d.is_empty()).collect();
        if used.is_empty() {
            return Err(ApprenticeshipError::NoDemos);
        }
        let mut mu_expert = vec![0.0; n_props + 1];
        for d in &used {
            let mut w = 1.0;
            for &l in &d.labels {
                mu_expert[label_feature(l, n_props)] += w / used.len() as f64;
                w *= cfg.gamma;
            }
        }
        let horizon = used.iter().map(|d| d.len()).max().unwrap_or(0);
        let mdp = DetMdp::new(
            world.labels().len(),
            N_ACTIONS,
            world.transition_table().to_vec(),
        )?;
        Ok(Apprenticeship {
            world: world.clone(),
            mdp,
            cfg,
            horizon,
            n_props,
            mu_expert,
            mu_bar: None,
            mixture: Vec::new(),
            rng: ChaCha8Rng::seed_from_u64(seed),
            steps: 0,
            value_warm: Vec::new(),
        })
    }

    pub fn expert_feature_expectations(&self) -> &[f64] {
        &self.mu_expert
    }

    /// The current margin `‖μ_E − μ̄‖` (infinite before the first step).
    pub fn margin(&self) -> f64 {
        match &self.mu_bar {
            None => f64::INFINITY,
            Some(mb) => dist(&self.mu_expert, mb),
        }
    }

    /// Mixture weights λ of the policies returned so far (one per step, summing to 1): the
    /// mixture "pick π_j with probability λ_j" has feature expectations μ̄ — the projection
    /// method's output policy.
    pub fn mixture_weights(&self) -> &[f64] {
        &self.mixture
    }

    /// Whether the projection method has converged (margin ≤ ε) or used its steps.
    pub fn done(&self) -> bool {
        self.steps >= self.cfg.max_steps || self.margin() <= self.cfg.epsilon
    }

    /// The reward table `wᵀ φ(o')` on cell-action pairs.
    pub fn reward_table(&self, w: &[f64]) -> Vec<f64> {
        (0..self.mdp.n_pairs())
            .map(|k| {
                let c2 = self.mdp.next(k / N_ACTIONS, k % N_ACTIONS);
                w[label_feature(self.world.label(c2), self.n_props)]
            })
            .collect()
    }

    /// One IRL step (the first one starts from random weights).
    pub fn step(&mut self) -> Result<ApprenticeshipStep, TabularError> {
        let margin = self.margin();
        let weights: Vec<f64> = match &self.mu_bar {
            None => (0..=self.n_props)
                .map(|_| self.rng.gen_range(-1.0..1.0))
                .collect(),
            Some(mb) => self.mu_expert.iter().zip(mb).map(|(e, b)| e - b).collect(),
        };
        let reward = self.reward_table(&weights);
        let mut interactions = 0;
        let policy = match self.cfg.solver {
            PolicySolver::ValueIteration => {
                let it = Iteration {
                    gamma: self.cfg.gamma,
                    tol: 1e-10,
                    max_sweeps: 20_000,
                };
                let init = (self.value_warm.len() == self.mdp.n_states())
                    .then_some(self.value_warm.as_slice());
                let values = value_iteration(&self.mdp, &reward, it, init)?;
                let p = greedy_actions(&values.q, N_ACTIONS);
                self.value_warm = values.v;
                p
            }
            PolicySolver::QLearning { steps } => {
                let q = q_learning(
                    &self.mdp,
                    &reward,
                    self.world.start(),
                    &QLearning {
                        gamma: self.cfg.gamma,
                        alpha: 0.5,
                        epsilon: 0.2,
                        steps,
                        episode_len: self.horizon.max(1),
                        seed: self.rng.gen(),
                    },
                )?;
                interactions += steps;
                greedy_actions(&q, N_ACTIONS)
            }
        };
        let mu = self.feature_expectations(&policy);
        interactions += self.horizon;
        self.mu_bar = Some(match self.mu_bar.take() {
            None => {
                self.mixture = vec![1.0];
                mu
            }
            Some(mb) => {
                let d: Vec<f64> = mu.iter().zip(&mb).map(|(m, b)| m - b).collect();
                let dd: f64 = d.iter().map(|x| x * x).sum();
                // Clipped to [0, 1] so that μ̄ stays the feature expectation of a mixture of
                // the policies so far (it is in [0, 1] whenever π_i is optimal for w_i).
                let k = if dd == 0.0 {
                    0.0
                } else {
                    let e: f64 = d
                        .iter()
                        .zip(self.mu_expert.iter().zip(&mb))
                        .map(|(di, (ei, bi))| di * (ei - bi))
                        .sum();
                    (e / dd).clamp(0.0, 1.0)
                };
                self.mixture.iter_mut().for_each(|l| *l *= 1.0 - k);
                self.mixture.push(k);
                mb.iter().zip(&d).map(|(b, di)| b + k * di).collect()
            }
        });
        self.steps += 1;
        Ok(ApprenticeshipStep {
            weights,
            policy,
            margin,
            interactions,
        })
    }

    /// `Σ_t γ^t φ(o_{t+1})` of a deterministic policy over the horizon from the start cell.
    pub fn feature_expectations(&self, policy: &[u8]) -> Vec<f64> {
        let mut mu = vec![0.0; self.n_props + 1];
        let mut c = self.world.start();
        let mut w = 1.0;
        for _ in 0..self.horizon {
            c = self.world.step(c, policy[c] as usize);
            mu[label_feature(self.world.label(c), self.n_props)] += w;
            w *= self.cfg.gamma;
        }
        mu
    }
}

fn dist(a: &[f64], b: &[f64]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y) * (x - y))
        .sum::<f64>()
        .sqrt()
}
