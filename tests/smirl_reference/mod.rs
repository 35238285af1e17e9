//! Reference computations of continuous SMIRL's MaxEnt quantities, written directly from the
//! formulas of `smirl::irl::smirl`'s module docs. The library trains through per-state loss
//! coefficients and the reward model's backward pass; these are the independent oracles the
//! tests compare that path with, so they live with the tests, not in the library.

#![allow(dead_code)]

use smirl::irl::reward::{RewardError, RewardModel};
use smirl::irl::smirl::{maxent_coefficients, AnnotatedTrajectories, FeatureMap, LinearRmReward};

/// The batch is `Σ lengths` rows of `obs_dim` observations, each with its RM state.
fn check(t: &AnnotatedTrajectories<'_>, obs_dim: usize) -> Result<(), RewardError> {
    let rows: usize = t.lengths.iter().sum();
    if t.lengths.is_empty() || t.obs.len() != rows * obs_dim || t.rm_state.len() != rows {
        return Err(RewardError::Config(format!(
            "{} values and {} states are not {rows} rows of {obs_dim}",
            t.obs.len(),
            t.rm_state.len()
        )));
    }
    Ok(())
}

fn state(u: u32, n_states: usize) -> Result<usize, RewardError> {
    if (u as usize) < n_states {
        Ok(u as usize)
    } else {
        Err(RewardError::RmStateOutOfRange { state: u, n_states })
    }
}

/// μ(u) = 1/N Σ_τ Σ_t 1[u_t = u] φ(o_t), as an `n_states × n_features` row-major matrix.
pub fn feature_expectations(
    features: &FeatureMap,
    n_states: usize,
    trajs: &AnnotatedTrajectories<'_>,
) -> Result<Vec<f64>, RewardError> {
    check(trajs, features.obs_dim())?;
    let k = features.len();
    let mut mu = vec![0.0; n_states * k];
    let mut phi = vec![0.0; k];
    for (row, &u) in trajs
        .obs
        .chunks_exact(features.obs_dim())
        .zip(trajs.rm_state)
    {
        let u = state(u, n_states)?;
        features.features(row, &mut phi);
        for (m, p) in mu[u * k..(u + 1) * k].iter_mut().zip(&phi) {
            *m += p;
        }
    }
    let n = trajs.lengths.len() as f64;
    mu.iter_mut().for_each(|m| *m /= n);
    Ok(mu)
}

/// The log-likelihood ascent direction μ_D − μ_π (without the L2 term), `n_states ×
/// n_features` row-major.
pub fn maxent_gradient(
    features: &FeatureMap,
    n_states: usize,
    expert: &AnnotatedTrajectories<'_>,
    agent: &AnnotatedTrajectories<'_>,
) -> Result<Vec<f64>, RewardError> {
    let mu_d = feature_expectations(features, n_states, expert)?;
    let mu_pi = feature_expectations(features, n_states, agent)?;
    Ok(mu_d.iter().zip(&mu_pi).map(|(d, p)| d - p).collect())
}

/// The sample log-likelihood surrogate ℓ̂(w) = 1/N_D Σ_D R_w(τ) − 1/N_A Σ_A R_w(τ) − λ/2 ‖w‖²
/// for weights `w` (`n_states × n_features` row-major) and L2 coefficient `l2`.
pub fn log_likelihood_surrogate(
    features: &FeatureMap,
    n_states: usize,
    weights: &[f64],
    l2: f64,
    expert: &AnnotatedTrajectories<'_>,
    agent: &AnnotatedTrajectories<'_>,
) -> Result<f64, RewardError> {
    let k = features.len();
    if weights.len() != n_states * k {
        return Err(RewardError::Config(format!(
            "{} weights for {n_states} states × {k} features",
            weights.len()
        )));
    }
    let mean_return = |t: &AnnotatedTrajectories<'_>| -> Result<f64, RewardError> {
        check(t, features.obs_dim())?;
        let mut phi = vec![0.0; k];
        let mut sum = 0.0;
        for (row, &u) in t.obs.chunks_exact(features.obs_dim()).zip(t.rm_state) {
            let u = state(u, n_states)?;
            features.features(row, &mut phi);
            sum += weights[u * k..(u + 1) * k]
                .iter()
                .zip(&phi)
                .map(|(w, p)| w * p)
                .sum::<f64>();
        }
        Ok(sum / t.lengths.len() as f64)
    };
    let norm2: f64 = weights.iter().map(|w| w * w).sum();
    Ok(mean_return(expert)? - mean_return(agent)? - 0.5 * l2 * norm2)
}

/// One MaxEnt step as the IRL loop takes it: the per-state coefficients of −ℓ̂ (+1/N_A at
/// agent rows, −1/N_D at expert rows), the model's backward pass, one optimiser step.
pub fn maxent_step(
    model: &mut LinearRmReward,
    expert: &AnnotatedTrajectories<'_>,
    agent: &AnnotatedTrajectories<'_>,
) -> Result<(), RewardError> {
    let (agent_c, expert_c) = maxent_coefficients(expert, agent);
    let obs: Vec<f32> = agent.obs.iter().chain(expert.obs).copied().collect();
    let states: Vec<u32> = agent
        .rm_state
        .iter()
        .chain(expert.rm_state)
        .copied()
        .collect();
    let coeffs: Vec<f64> = agent_c.into_iter().chain(expert_c).collect();
    model.update(&obs, &states, &coeffs)
}
