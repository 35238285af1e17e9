//! A Gaussian kernel density of the expert's states, for f-IRL's reverse KL on an expert given
//! by demonstrations.
//!
//! Why it exists: with the Epanechnikov KDE of 2 cm kernels, the density of 16 demonstrations
//! of a reaching task is a chain of separate discs, zero between them. Reverse KL weighs an
//! agent state by −log(ρ_E/ρ_θ), which is the same huge value (log ε) at every state off those
//! discs, however near the expert's path: an agent that leaves its start disc is punished as
//! if it had left the arena, and rkl's agents stop on the expert's first states
//! (experiments/reacher/controls/results.md). f-IRL's own Reacher experiment has an analytic target with
//! no zero, where log ρ_E grades a state by its distance to the target. A Gaussian kernel gives
//! the demonstrations that property: log ρ_E(x) ≈ −d(x)²/(2σ²) + const far from the data,
//! d the distance to the nearest demonstration state.
//!
//! ```text
//! ρ_E(x) = 1/n Σ_i N(x; x_i, σ² I),   log ρ_E(x) = m + log Σ_i exp(−‖x − x_i‖²/(2σ²) − m) − log n − (d/2) log(2πσ²)
//! ```
//!
//! with m = max_i(−‖x − x_i‖²/(2σ²)), so the log-density is finite and exact wherever x is
//! (no underflow far from the data). Exact sum over all fitted points: O(n) per query.

use super::kde::{check_shape, query_columns, select_columns, KdeError};

/// A fitted Gaussian KDE (isotropic, bandwidth σ).
#[derive(Clone, Debug, PartialEq)]
pub struct GaussianKde {
    dim: usize,
    sigma: f64,
    /// Row-major fitted points.
    points: Vec<f64>,
}

impl GaussianKde {
    /// Fits `points` (row-major, `dim` wide) with standard deviation `sigma`.
    pub fn fit(points: &[f64], dim: usize, sigma: f64) -> Result<GaussianKde, KdeError> {
        check_shape(points, dim, sigma)?;
        Ok(GaussianKde {
            dim,
            sigma,
            points: points.to_vec(),
        })
    }

    /// Fits chosen `columns` of row-major `f32` observations of width `obs_dim`.
    pub fn fit_columns(
        obs: &[f32],
        obs_dim: usize,
        columns: &[usize],
        sigma: f64,
    ) -> Result<GaussianKde, KdeError> {
        let pts = select_columns(obs, obs_dim, columns)?;
        GaussianKde::fit(&pts, columns.len(), sigma)
    }

    /// log ρ(x) for one query point of length `dim`.
    pub fn log_density(&self, x: &[f64]) -> f64 {
        let inv = 1.0 / (2.0 * self.sigma * self.sigma);
        let exponent = |p: &[f64]| -> f64 {
            -p.iter().zip(x).map(|(a, b)| (a - b) * (a - b)).sum::<f64>() * inv
        };
        let m = self
            .points
            .chunks_exact(self.dim)
            .map(exponent)
            .fold(f64::NEG_INFINITY, f64::max);
        let sum: f64 = self
            .points
            .chunks_exact(self.dim)
            .map(|p| (exponent(p) - m).exp())
            .sum();
        let n = (self.points.len() / self.dim) as f64;
        let log_norm =
            0.5 * self.dim as f64 * (2.0 * std::f64::consts::PI * self.sigma * self.sigma).ln();
        m + sum.ln() - n.ln() - log_norm
    }

    /// log ρ at chosen `columns` of row-major `f32` observations of width `obs_dim`.
    pub fn log_density_columns(
        &self,
        obs: &[f32],
        obs_dim: usize,
        columns: &[usize],
    ) -> Result<Vec<f64>, KdeError> {
        let queries = query_columns(obs, obs_dim, columns, self.dim)?;
        Ok(queries
            .chunks_exact(self.dim)
            .map(|x| self.log_density(x))
            .collect())
    }
}
