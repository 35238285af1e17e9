//! f-IRL (Ni et al., CoRL 2020) and continuous MaxEnt IRL as per-state loss coefficients.
//!
//! Both objectives are surrogates whose gradient with respect to the reward parameters θ is a
//! weighted sum of reward gradients at visited states,
//!
//! ```text
//! ∇θ L = Σ_s c_s ∇θ r_θ(s),      c_s = ∂L / ∂r_θ(s),
//! ```
//!
//! so this module only computes the coefficients `c_s`; the reward model's backward pass
//! (see [`super::reward::RewardModel::backward`]) turns them into parameter gradients. Both
//! losses are **minimised** (gradient *descent* on θ).
//!
//! # f-IRL
//!
//! The SMIRL paper's appendix D theorem (from Ni et al.): for the soft-optimal agent's state
//! marginal ρ_θ and the expert's ρ_E,
//!
//! ```text
//! ∇θ D_f(ρ_E ‖ ρ_θ) = 1/(α T) · Cov_{τ∼ρ_θ(τ)}( Σ_t h_f(u(s_t)),  Σ_t ∇θ r_θ(s_t) ),
//! u = ρ_E / ρ_θ,     h_f(u) = f(u) − f′(u) u.
//! ```
//!
//! With N agent trajectories of length T, A_i = Σ_t h_f(u(s_it)) (a constant: no gradient
//! flows through the densities) and B_i = Σ_t r_θ(s_it), the surrogate is
//! `L = Cov_i(A_i, B_i) / T` with the *population* covariance
//! `Cov(A, B) = mean(A·B) − mean(A)·mean(B)` (the 1/N form, as in the reference code), and
//! the temperature α folded into the learning rate. Since ∂Cov/∂B_i = (A_i − Ā)/N and
//! ∂B_i/∂r(s_it) = 1,
//!
//! ```text
//! c_it = (A_i − Ā) / (N T)     (the same for every step t of trajectory i).
//! ```
//!
//! Sign: a trajectory with above-average A_i gets a positive coefficient, so descent
//! *lowers* the reward along it. For fkl, A_i = −Σ u: trajectories that sit where the expert
//! density is high relative to the agent's have low A_i and get their reward raised.
//!
//! **Density ratio guard.** With the compactly supported Epanechnikov KDE, ρ_E is exactly
//! zero at agent states farther than one bandwidth from every expert state, and log u would
//! be −∞ (rkl). The ratio is therefore computed as `u = (ρ_E + ε) / (ρ_θ + ε)` with
//! `ε = density_eps` ([`DEFAULT_DENSITY_EPS`] = 1e-8, far below the density one fitted
//! point contributes, ~1e-1 for 30 000 points in 2-D at h = 0.02). Where both densities are
//! zero the ratio is 1 (no evidence either way). The reference implementation adds its
//! epsilon to the expert density only; the agent density at its own samples is never zero,
//! so the two agree there.
//!
//! # Continuous MaxEnt IRL
//!
//! `L = T · (mean of r over agent states − mean of r over expert states)`, as in the f-IRL
//! code base. With n_A agent states and n_E expert states, `c = T / n_A` at every agent
//! state and `c = −T / n_E` at every expert state. (With N trajectories of length T,
//! `T / n_A = 1 / N`: per-trajectory normalised feature expectations, the MaxEnt gradient.)

use super::kde::{Kde, KdeError};
use std::fmt;
use std::str::FromStr;

/// Default ε of the density-ratio guard (see the module docs).
pub const DEFAULT_DENSITY_EPS: f64 = 1e-8;

/// The f-divergence f-IRL minimises between the expert's and the agent's state marginals.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Divergence {
    /// Forward KL, KL(ρ_E ‖ ρ_θ).
    Fkl,
    /// Reverse KL, KL(ρ_θ ‖ ρ_E).
    Rkl,
    /// Jensen–Shannon (times 2).
    Js,
}

impl Divergence {
    pub const ALL: [Divergence; 3] = [Divergence::Fkl, Divergence::Rkl, Divergence::Js];

    pub fn name(self) -> &'static str {
        match self {
            Divergence::Fkl => "fkl",
            Divergence::Rkl => "rkl",
            Divergence::Js => "js",
        }
    }

    /// The generator f with D_f(P ‖ Q) = ∫ f(dP/dQ) dQ, P = ρ_E, Q = ρ_θ, u = ρ_E/ρ_θ:
    /// - fkl: ∫ ρ_E log(ρ_E/ρ_θ) = ∫ ρ_θ u log u                 → f(u) = u log u
    /// - rkl: ∫ ρ_θ log(ρ_θ/ρ_E) = ∫ ρ_θ (−log u)               → f(u) = −log u
    /// - js:  KL(ρ_E‖M) + KL(ρ_θ‖M), M = (ρ_E+ρ_θ)/2           → f(u) = u log u − (1+u) log((1+u)/2)
    pub fn f(self, u: f64) -> f64 {
        match self {
            Divergence::Fkl => u * u.ln(),
            Divergence::Rkl => -u.ln(),
            Divergence::Js => u * u.ln() - (1.0 + u) * ((1.0 + u) / 2.0).ln(),
        }
    }

    /// f′(u):
    /// - fkl: log u + 1
    /// - rkl: −1/u
    /// - js:  log u + 1 − log((1+u)/2) − 1 = log u − log((1+u)/2)
    pub fn f_prime(self, u: f64) -> f64 {
        match self {
            Divergence::Fkl => u.ln() + 1.0,
            Divergence::Rkl => -1.0 / u,
            Divergence::Js => u.ln() - ((1.0 + u) / 2.0).ln(),
        }
    }

    /// h used in the surrogate: h_f(u) = f(u) − f′(u) u without its additive constant,
    /// - fkl: u log u − u (log u + 1)                              = −u
    /// - rkl: −log u + 1                                          = −log u + 1
    /// - js:  u log u − (1+u) log((1+u)/2) − u log u + u log((1+u)/2) = −log(1+u) + log 2,
    ///
    /// so −u, −log u, −log(1+u). A constant shifts every A_i equally and cancels in the
    /// covariance, so the gradient is the same.
    pub fn h(self, u: f64) -> f64 {
        match self {
            Divergence::Fkl => -u,
            Divergence::Rkl => -u.ln(),
            Divergence::Js => -u.ln_1p(),
        }
    }
}

impl fmt::Display for Divergence {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// An unknown divergence name.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("unknown f-divergence {0:?} (expected fkl, rkl or js)")]
pub struct UnknownDivergence(pub String);

impl FromStr for Divergence {
    type Err = UnknownDivergence;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s {
            "fkl" => Ok(Divergence::Fkl),
            "rkl" => Ok(Divergence::Rkl),
            "js" => Ok(Divergence::Js),
            _ => Err(UnknownDivergence(s.to_string())),
        }
    }
}

/// Inconsistent inputs to a surrogate.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum SurrogateError {
    #[error("{len} agent states are not {n_traj} trajectories of length {horizon}")]
    Shape {
        len: usize,
        n_traj: usize,
        horizon: usize,
    },
    #[error("need at least one trajectory of length at least 1")]
    Empty,
    #[error("{what} has length {got}, expected {expected}")]
    Length {
        what: &'static str,
        got: usize,
        expected: usize,
    },
    #[error("density ratio at agent state {index} is {value}, not a finite positive number")]
    BadRatio { index: usize, value: f64 },
    #[error("density guard epsilon must be positive and finite, got {0}")]
    BadEpsilon(f64),
    #[error(transparent)]
    Kde(#[from] KdeError),
}

/// Density ratios u = (ρ_E + ε) / (ρ_θ + ε) (see the module docs for ε).
pub fn density_ratio(
    expert_density: &[f64],
    agent_density: &[f64],
    eps: f64,
) -> Result<Vec<f64>, SurrogateError> {
    if !(eps.is_finite() && eps > 0.0) {
        return Err(SurrogateError::BadEpsilon(eps));
    }
    if expert_density.len() != agent_density.len() {
        return Err(SurrogateError::Length {
            what: "expert density",
            got: expert_density.len(),
            expected: agent_density.len(),
        });
    }
    let u: Vec<f64> = expert_density
        .iter()
        .zip(agent_density)
        .map(|(&e, &a)| (e + eps) / (a + eps))
        .collect();
    if let Some(index) = u.iter().position(|v| !(v.is_finite() && *v > 0.0)) {
        return Err(SurrogateError::BadRatio {
            index,
            value: u[index],
        });
    }
    Ok(u)
}

/// The f-IRL surrogate for one batch of agent trajectories.
#[derive(Clone, Debug, PartialEq)]
pub struct FirlSurrogate {
    pub n_traj: usize,
    pub horizon: usize,
    /// A_i = Σ_t h(u(s_it)) per trajectory.
    pub advantages: Vec<f64>,
    /// c_it = ∂L/∂r(s_it) = (A_i − Ā)/(N T), row-major `n_traj × horizon`.
    pub coefficients: Vec<f64>,
}

impl FirlSurrogate {
    /// Builds the surrogate from the density ratios u at the `n_traj × horizon` agent states
    /// (row-major: trajectory i's states are `u[i*T..(i+1)*T]`).
    pub fn new(
        divergence: Divergence,
        ratios: &[f64],
        n_traj: usize,
        horizon: usize,
    ) -> Result<FirlSurrogate, SurrogateError> {
        if n_traj == 0 || horizon == 0 {
            return Err(SurrogateError::Empty);
        }
        if ratios.len() != n_traj * horizon {
            return Err(SurrogateError::Shape {
                len: ratios.len(),
                n_traj,
                horizon,
            });
        }
        if let Some(index) = ratios.iter().position(|v| !(v.is_finite() && *v > 0.0)) {
            return Err(SurrogateError::BadRatio {
                index,
                value: ratios[index],
            });
        }
        let advantages: Vec<f64> = ratios
            .chunks_exact(horizon)
            .map(|traj| traj.iter().map(|&u| divergence.h(u)).sum())
            .collect();
        let mean = advantages.iter().sum::<f64>() / n_traj as f64;
        let scale = 1.0 / (n_traj * horizon) as f64;
        let mut coefficients = Vec::with_capacity(n_traj * horizon);
        for a in &advantages {
            coefficients.extend(std::iter::repeat_n((a - mean) * scale, horizon));
        }
        Ok(FirlSurrogate {
            n_traj,
            horizon,
            advantages,
            coefficients,
        })
    }

    /// Builds the surrogate from fitted expert and agent KDEs evaluated at `columns` of the
    /// agent observations (row-major, width `obs_dim`, `n_traj × horizon` rows).
    #[allow(clippy::too_many_arguments)]
    pub fn from_kde(
        divergence: Divergence,
        expert: &Kde,
        agent: &Kde,
        agent_obs: &[f32],
        obs_dim: usize,
        columns: &[usize],
        n_traj: usize,
        horizon: usize,
        density_eps: f64,
    ) -> Result<FirlSurrogate, SurrogateError> {
        let rho_e = expert.density_columns(agent_obs, obs_dim, columns)?;
        let rho_a = agent.density_columns(agent_obs, obs_dim, columns)?;
        let u = density_ratio(&rho_e, &rho_a, density_eps)?;
        FirlSurrogate::new(divergence, &u, n_traj, horizon)
    }

    /// The surrogate's value Cov_i(A_i, B_i)/T for rewards r(s_it) (row-major like the
    /// ratios), B_i = Σ_t r(s_it).
    pub fn loss(&self, rewards: &[f64]) -> Result<f64, SurrogateError> {
        if rewards.len() != self.coefficients.len() {
            return Err(SurrogateError::Length {
                what: "rewards",
                got: rewards.len(),
                expected: self.coefficients.len(),
            });
        }
        let b: Vec<f64> = rewards
            .chunks_exact(self.horizon)
            .map(|t| t.iter().sum())
            .collect();
        Ok(population_covariance(&self.advantages, &b) / self.horizon as f64)
    }
}

/// mean(a·b) − mean(a)·mean(b).
pub fn population_covariance(a: &[f64], b: &[f64]) -> f64 {
    let n = a.len() as f64;
    let ma = a.iter().sum::<f64>() / n;
    let mb = b.iter().sum::<f64>() / n;
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - ma) * (y - mb))
        .sum::<f64>()
        / n
}

/// Per-state coefficients of the continuous MaxEnt IRL loss
/// `T · (mean r over agent states − mean r over expert states)`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MaxEntCoefficients {
    /// ∂L/∂r at every agent state: T / n_agent.
    pub agent: f64,
    /// ∂L/∂r at every expert state: −T / n_expert.
    pub expert: f64,
}

impl MaxEntCoefficients {
    pub fn new(
        n_agent_states: usize,
        n_expert_states: usize,
        horizon: usize,
    ) -> Result<MaxEntCoefficients, SurrogateError> {
        if n_agent_states == 0 || n_expert_states == 0 || horizon == 0 {
            return Err(SurrogateError::Empty);
        }
        let t = horizon as f64;
        Ok(MaxEntCoefficients {
            agent: t / n_agent_states as f64,
            expert: -t / n_expert_states as f64,
        })
    }

    /// The loss value for the given rewards.
    pub fn loss(agent_rewards: &[f64], expert_rewards: &[f64], horizon: usize) -> f64 {
        let mean = |r: &[f64]| r.iter().sum::<f64>() / r.len() as f64;
        horizon as f64 * (mean(agent_rewards) - mean(expert_rewards))
    }
}
