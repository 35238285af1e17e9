//! Tabular MaxEnt IRL (Ziebart et al. 2008) on a deterministic MDP with a reward linear in
//! one-hot features: `r(s, a) = θ[f(s, a)]` (or 0 when `(s, a)` has no feature).
//!
//! The model is the exact finite-horizon MaxEnt distribution over action sequences of each
//! demonstration's length T from its start state, `P(τ) ∝ exp(Σ_t r(s_t, a_t))`. Per
//! iteration: soft backward pass (log-sum-exp value iteration, one per distinct demonstration
//! length), forward pass (expected state-action visitation from the demonstrations' start
//! states), gradient of the mean log-likelihood `μ_demo − μ_π` in feature space, one Adam
//! ascent step. The log-likelihood is concave in θ.

use crate::rl::tabular::{expected_visitation, soft_backward, DetMdp, FiniteSoftPolicy};
use std::collections::BTreeMap;

/// Marks a state-action pair without a feature (reward 0).
pub const NO_FEATURE: u32 = u32::MAX;

/// One-hot features of state-action pairs: `r(s, a) = θ[f(s, a)]` (Office; the continuous
/// SMIRL reward reads observations through `irl::smirl::FeatureMap` instead).
#[derive(Clone, Debug, PartialEq)]
pub struct StateActionFeatures {
    pub n_features: usize,
    /// Feature of `(s, a)` at `s * A + a`, or [`NO_FEATURE`].
    pub feature: Vec<u32>,
}

impl StateActionFeatures {
    /// The reward table `r(s, a) = θ[f(s, a)]` written into `out`.
    pub fn reward_into(&self, theta: &[f64], out: &mut [f64]) {
        for (r, &f) in out.iter_mut().zip(&self.feature) {
            *r = if f == NO_FEATURE {
                0.0
            } else {
                theta[f as usize]
            };
        }
    }

    pub fn reward(&self, theta: &[f64]) -> Vec<f64> {
        let mut out = vec![0.0; self.feature.len()];
        self.reward_into(theta, &mut out);
        out
    }
}

/// A MaxEnt IRL problem could not be set up.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum MaxEntError {
    #[error("feature map covers {got} state-action pairs, the MDP has {expected}")]
    FeatureShape { expected: usize, got: usize },
    #[error("feature index {index} at pair {pair} is out of range ({n} features)")]
    FeatureOutOfRange { pair: usize, index: u32, n: usize },
    #[error("demonstration {demo} step {step}: state {state} / action {action} out of range")]
    DemoOutOfRange {
        demo: usize,
        step: usize,
        state: u32,
        action: u8,
    },
    #[error("demonstration {demo} step {step}: its state does not follow from the previous step")]
    DemoInconsistent { demo: usize, step: usize },
    #[error("no non-empty demonstrations")]
    NoDemos,
    #[error("bad setting: {0}")]
    Config(String),
    #[error(transparent)]
    Tabular(#[from] crate::rl::tabular::TabularError),
}

/// How θ is updated.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Optimizer {
    /// L-BFGS (memory 10) with a backtracking (Armijo) line search: the log-likelihood is
    /// smooth and concave, so this reaches the convergence test in few steps.
    #[default]
    Lbfgs,
    /// Adam with step size `lr` (first-order, as most MaxEnt implementations).
    Adam,
}

/// Optimiser settings.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct MaxEntConfig {
    pub optimizer: Optimizer,
    /// Adam step size (unused by L-BFGS).
    pub lr: f64,
    /// Maximum number of IRL (gradient) steps.
    pub max_steps: usize,
    /// Converged when every component of the per-demonstration gradient is below this.
    pub grad_tol: f64,
    /// Discount inside the trajectory distribution (1 = Ziebart's exact model).
    pub gamma: f64,
    /// L2 penalty on θ (0 = plain maximum likelihood).
    pub l2: f64,
}

impl Default for MaxEntConfig {
    fn default() -> Self {
        MaxEntConfig {
            optimizer: Optimizer::Lbfgs,
            lr: 0.2,
            max_steps: 300,
            grad_tol: 1e-3,
            gamma: 1.0,
            l2: 0.0,
        }
    }
}

impl MaxEntConfig {
    pub fn validate(&self) -> Result<(), MaxEntError> {
        if !(self.lr > 0.0 && self.lr.is_finite()) {
            return Err(MaxEntError::Config(format!("lr = {} must be > 0", self.lr)));
        }
        if self.grad_tol.is_nan() || self.grad_tol <= 0.0 {
            return Err(MaxEntError::Config(format!(
                "grad_tol = {} must be > 0",
                self.grad_tol
            )));
        }
        if !(0.0..=1.0).contains(&self.gamma) {
            return Err(MaxEntError::Config(format!(
                "gamma = {} must be in [0, 1]",
                self.gamma
            )));
        }
        if !(self.l2 >= 0.0 && self.l2.is_finite()) {
            return Err(MaxEntError::Config(format!("l2 = {} must be ≥ 0", self.l2)));
        }
        Ok(())
    }
}

/// Demonstrations in the MDP: per demonstration, its `(s_t, a_t)` pairs for t = 0..T.
pub type StateActionDemo = Vec<(u32, u8)>;

/// Demonstrations of one length: one backward pass serves them all.
#[derive(Clone, Debug)]
struct LengthGroup {
    horizon: usize,
    /// Start distribution (counts, not normalised) over states.
    starts: Vec<f64>,
}

/// What one gradient evaluation found.
#[derive(Clone, Debug, PartialEq)]
pub struct GradientInfo {
    /// Mean log-likelihood of the demonstrations (with γ = 1; minus the L2 penalty).
    pub log_likelihood: f64,
    /// Largest component of the per-demonstration gradient, in absolute value.
    pub grad_max: f64,
}

/// MaxEnt IRL state: problem, parameters θ, Adam moments, reusable buffers.
#[derive(Clone, Debug)]
pub struct MaxEntIrl<'a> {
    mdp: &'a DetMdp,
    features: &'a StateActionFeatures,
    cfg: MaxEntConfig,
    groups: Vec<LengthGroup>,
    n_demos: f64,
    /// Mean feature counts of the demonstrations.
    mu_demo: Vec<f64>,
    /// Σ over demonstrations of Σ_t r(s_t, a_t) is `demo_pair_counts · r`.
    demo_pair_counts: Vec<f64>,
    pub theta: Vec<f64>,
    adam_m: Vec<f64>,
    adam_v: Vec<f64>,
    /// L-BFGS curvature pairs (s, y) of the loss −log-likelihood, oldest first.
    lbfgs_pairs: std::collections::VecDeque<(Vec<f64>, Vec<f64>)>,
    /// Log-likelihood information and gradient at the current θ, when known.
    current: Option<(GradientInfo, Vec<f64>)>,
    steps: usize,
    // Buffers.
    reward: Vec<f64>,
    policy: FiniteSoftPolicy,
    sa_visits: Vec<f64>,
    work: Vec<f64>,
    grad: Vec<f64>,
}

impl<'a> MaxEntIrl<'a> {
    /// Checks the problem and prepares the demonstration statistics; θ starts at 0.
    pub fn new(
        mdp: &'a DetMdp,
        features: &'a StateActionFeatures,
        demos: &[StateActionDemo],
        cfg: MaxEntConfig,
    ) -> Result<MaxEntIrl<'a>, MaxEntError> {
        cfg.validate()?;
        let n_sa = mdp.n_pairs();
        let n_a = mdp.n_actions();
        if features.feature.len() != n_sa {
            return Err(MaxEntError::FeatureShape {
                expected: n_sa,
                got: features.feature.len(),
            });
        }
        if let Some(pair) = features
            .feature
            .iter()
            .position(|&f| f != NO_FEATURE && f as usize >= features.n_features)
        {
            return Err(MaxEntError::FeatureOutOfRange {
                pair,
                index: features.feature[pair],
                n: features.n_features,
            });
        }
        let mut by_len: BTreeMap<usize, Vec<f64>> = BTreeMap::new();
        let mut demo_pair_counts = vec![0.0; n_sa];
        let mut n_demos = 0usize;
        for (i, demo) in demos.iter().enumerate() {
            if demo.is_empty() {
                continue;
            }
            for (t, &(s, a)) in demo.iter().enumerate() {
                if s as usize >= mdp.n_states() || a as usize >= n_a {
                    return Err(MaxEntError::DemoOutOfRange {
                        demo: i,
                        step: t,
                        state: s,
                        action: a,
                    });
                }
                if t > 0 {
                    let (ps, pa) = demo[t - 1];
                    if mdp.next(ps as usize, pa as usize) != s as usize {
                        return Err(MaxEntError::DemoInconsistent { demo: i, step: t });
                    }
                }
                // Discounted like the model's visitation (γ^t; 1 for the exact model).
                demo_pair_counts[s as usize * n_a + a as usize] += cfg.gamma.powi(t as i32);
            }
            n_demos += 1;
            by_len
                .entry(demo.len())
                .or_insert_with(|| vec![0.0; mdp.n_states()])[demo[0].0 as usize] += 1.0;
        }
        if n_demos == 0 {
            return Err(MaxEntError::NoDemos);
        }
        let n_demos = n_demos as f64;
        let mut mu_demo = vec![0.0; features.n_features];
        for (k, &c) in demo_pair_counts.iter().enumerate() {
            let f = features.feature[k];
            if f != NO_FEATURE && c != 0.0 {
                mu_demo[f as usize] += c / n_demos;
            }
        }
        let groups = by_len
            .into_iter()
            .map(|(horizon, starts)| LengthGroup { horizon, starts })
            .collect();
        let nf = features.n_features;
        Ok(MaxEntIrl {
            mdp,
            features,
            cfg,
            groups,
            n_demos,
            mu_demo,
            demo_pair_counts,
            theta: vec![0.0; nf],
            adam_m: vec![0.0; nf],
            adam_v: vec![0.0; nf],
            lbfgs_pairs: std::collections::VecDeque::new(),
            current: None,
            steps: 0,
            reward: vec![0.0; n_sa],
            policy: FiniteSoftPolicy::default(),
            sa_visits: vec![0.0; n_sa],
            work: Vec::new(),
            grad: vec![0.0; nf],
        })
    }

    /// Mean feature counts of the demonstrations.
    pub fn demo_feature_counts(&self) -> &[f64] {
        &self.mu_demo
    }

    /// Number of gradient steps taken.
    pub fn steps(&self) -> usize {
        self.steps
    }

    /// The current reward table `r(s, a)`.
    pub fn reward(&self) -> Vec<f64> {
        self.features.reward(&self.theta)
    }

    /// Gradient of the mean log-likelihood at `theta` (per demonstration, in feature space)
    /// into `grad`, and the mean log-likelihood itself. Also leaves the expected
    /// state-action visitation (summed over demonstrations, divided by their number) in
    /// [`MaxEntIrl::expected_pair_visits`].
    pub fn gradient_at(
        &mut self,
        theta: &[f64],
        grad: &mut [f64],
    ) -> Result<GradientInfo, MaxEntError> {
        self.features.reward_into(theta, &mut self.reward);
        self.sa_visits.fill(0.0);
        let mut log_z = 0.0;
        // One backward pass for the longest demonstrations serves every shorter length.
        let longest = self.groups.last().map_or(0, |g| g.horizon);
        soft_backward(
            self.mdp,
            &self.reward,
            self.cfg.gamma,
            longest,
            &mut self.policy,
        )?;
        for g in &self.groups {
            let v0 = self.policy.values_at(g.horizon);
            for (s, &c) in g.starts.iter().enumerate() {
                if c != 0.0 {
                    log_z += c * v0[s];
                }
            }
            expected_visitation(
                self.mdp,
                self.policy.suffix_policy(g.horizon),
                &g.starts,
                g.horizon,
                self.cfg.gamma,
                &mut self.sa_visits,
                &mut self.work,
            )?;
        }
        let inv_n = 1.0 / self.n_demos;
        grad.copy_from_slice(&self.mu_demo);
        let mut demo_return = 0.0;
        for (k, &f) in self.features.feature.iter().enumerate() {
            if f != NO_FEATURE {
                grad[f as usize] -= self.sa_visits[k] * inv_n;
                demo_return += self.demo_pair_counts[k] * theta[f as usize];
            }
        }
        let mut penalty = 0.0;
        for (g, &th) in grad.iter_mut().zip(theta) {
            *g -= self.cfg.l2 * th;
            penalty += 0.5 * self.cfg.l2 * th * th;
        }
        let grad_max = grad.iter().fold(0.0f64, |m, g| m.max(g.abs()));
        Ok(GradientInfo {
            log_likelihood: (demo_return - log_z) * inv_n - penalty,
            grad_max,
        })
    }

    /// Expected visitation of each state-action pair per demonstration, from the last
    /// gradient evaluation.
    pub fn expected_pair_visits(&self) -> Vec<f64> {
        self.sa_visits.iter().map(|v| v / self.n_demos).collect()
    }

    /// One optimiser step on the log-likelihood; returns the gradient information at the
    /// parameters before the step.
    pub fn step(&mut self) -> Result<GradientInfo, MaxEntError> {
        match self.cfg.optimizer {
            Optimizer::Adam => self.adam_step(),
            Optimizer::Lbfgs => self.lbfgs_step(),
        }
    }

    fn adam_step(&mut self) -> Result<GradientInfo, MaxEntError> {
        let info = match self.current.take() {
            Some((info, g)) => {
                self.grad.copy_from_slice(&g);
                info
            }
            None => {
                let theta = std::mem::take(&mut self.theta);
                let mut grad = std::mem::take(&mut self.grad);
                let info = self.gradient_at(&theta, &mut grad);
                self.theta = theta;
                self.grad = grad;
                info?
            }
        };
        self.steps += 1;
        let (b1, b2, eps) = (0.9, 0.999, 1e-8);
        let t = self.steps as i32;
        let (c1, c2) = (1.0 - f64::powi(b1, t), 1.0 - f64::powi(b2, t));
        for i in 0..self.theta.len() {
            let g = self.grad[i];
            self.adam_m[i] = b1 * self.adam_m[i] + (1.0 - b1) * g;
            self.adam_v[i] = b2 * self.adam_v[i] + (1.0 - b2) * g * g;
            let m_hat = self.adam_m[i] / c1;
            let v_hat = self.adam_v[i] / c2;
            self.theta[i] += self.cfg.lr * m_hat / (v_hat.sqrt() + eps);
        }
        Ok(info)
    }

    /// L-BFGS on the loss f = −log-likelihood (gradient −g): two-loop recursion for the
    /// direction, backtracking until the Armijo condition holds.
    fn lbfgs_step(&mut self) -> Result<GradientInfo, MaxEntError> {
        const MEMORY: usize = 10;
        let n = self.theta.len();
        let (info, g) = match self.current.take() {
            Some(c) => c,
            None => {
                let theta = self.theta.clone();
                let mut g = vec![0.0; n];
                let info = self.gradient_at(&theta, &mut g)?;
                (info, g)
            }
        };
        self.steps += 1;
        let loss = -info.log_likelihood;
        let grad_f: Vec<f64> = g.iter().map(|x| -x).collect();
        let dot = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(x, y)| x * y).sum::<f64>();
        // Two-loop recursion: r ≈ H ∇f.
        let mut q = grad_f.clone();
        let mut alphas = Vec::with_capacity(self.lbfgs_pairs.len());
        for (s, y) in self.lbfgs_pairs.iter().rev() {
            let rho = 1.0 / dot(y, s);
            let a = rho * dot(s, &q);
            q.iter_mut().zip(y).for_each(|(qi, yi)| *qi -= a * yi);
            alphas.push((a, rho));
        }
        let scale = match self.lbfgs_pairs.back() {
            Some((s, y)) => dot(s, y) / dot(y, y),
            None => 1.0 / grad_f.iter().fold(1e-12f64, |m, x| m.max(x.abs())),
        };
        q.iter_mut().for_each(|x| *x *= scale);
        for ((s, y), (a, rho)) in self.lbfgs_pairs.iter().zip(alphas.into_iter().rev()) {
            let b = rho * dot(y, &q);
            q.iter_mut().zip(s).for_each(|(qi, si)| *qi += (a - b) * si);
        }
        let mut dir: Vec<f64> = q.iter().map(|x| -x).collect();
        let mut slope = dot(&dir, &grad_f);
        if slope.is_nan() || slope >= 0.0 {
            // Not a descent direction (stale curvature): fall back to steepest descent.
            self.lbfgs_pairs.clear();
            let s = 1.0 / grad_f.iter().fold(1e-12f64, |m, x| m.max(x.abs()));
            dir = grad_f.iter().map(|x| -x * s).collect();
            slope = dot(&dir, &grad_f);
        }
        if slope == 0.0 {
            // Zero gradient: already optimal.
            self.current = Some((info.clone(), g));
            return Ok(info);
        }
        let mut step = 1.0;
        let mut trial = vec![0.0; n];
        let mut g_trial = vec![0.0; n];
        for _ in 0..40 {
            for i in 0..n {
                trial[i] = self.theta[i] + step * dir[i];
            }
            let t_info = self.gradient_at(&trial, &mut g_trial)?;
            let t_loss = -t_info.log_likelihood;
            if t_loss.is_finite() && t_loss <= loss + 1e-4 * step * slope {
                let s: Vec<f64> = dir.iter().map(|d| step * d).collect();
                let y: Vec<f64> = g_trial.iter().zip(&g).map(|(gt, g0)| -(gt - g0)).collect();
                if dot(&s, &y) > 1e-12 {
                    if self.lbfgs_pairs.len() == MEMORY {
                        self.lbfgs_pairs.pop_front();
                    }
                    self.lbfgs_pairs.push_back((s, y));
                }
                std::mem::swap(&mut self.theta, &mut trial);
                self.current = Some((t_info, g_trial));
                return Ok(info);
            }
            step *= 0.5;
        }
        // No decrease found along the direction (flat to rounding): stay, forget curvature.
        self.lbfgs_pairs.clear();
        self.current = Some((info.clone(), g));
        Ok(info)
    }

    /// Gradient information at the current θ (computed if the optimiser does not know it).
    pub fn current_info(&mut self) -> Result<GradientInfo, MaxEntError> {
        if let Some((info, _)) = &self.current {
            return Ok(info.clone());
        }
        let theta = self.theta.clone();
        let mut g = vec![0.0; theta.len()];
        let info = self.gradient_at(&theta, &mut g)?;
        self.current = Some((info.clone(), g));
        Ok(info)
    }

    /// Whether a gradient evaluation meets the convergence tolerance.
    pub fn converged(&self, info: &GradientInfo) -> bool {
        info.grad_max < self.cfg.grad_tol
    }

    pub fn config(&self) -> &MaxEntConfig {
        &self.cfg
    }
}
