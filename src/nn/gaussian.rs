//! Tanh-squashed diagonal Gaussian head: the policy distribution of SAC.
//!
//! The network outputs, per sample (one column), `act_dim` means followed by `act_dim`
//! log-standard-deviations. The log-std is clamped to [`LOG_STD_MIN`, `LOG_STD_MAX`]
//! (zero gradient outside). With noise ε ~ N(0, I): u = μ + σ ε, a = tanh(u), and
//!
//! log π(a) = Σ_i [ log N(u_i; μ_i, σ_i) − log(1 − tanh²(u_i)) ],
//!
//! the change of variables through tanh. The correction uses the stable identity
//! log(1 − tanh² u) = 2 (log 2 − u − softplus(−2u)).

use nalgebra::DMatrix;

pub const LOG_STD_MIN: f32 = -20.0;
pub const LOG_STD_MAX: f32 = 2.0;
const HALF_LOG_2PI: f32 = 0.918_938_5;

fn softplus(x: f32) -> f32 {
    x.max(0.0) + (-x.abs()).exp().ln_1p()
}

/// log(1 − tanh² u), computed without cancellation.
pub fn log_one_minus_tanh_sq(u: f32) -> f32 {
    2.0 * (std::f32::consts::LN_2 - u - softplus(-2.0 * u))
}

/// Samples actions with the reparameterisation trick.
///
/// `head` is the network output (`2A × B`), `eps` standard-normal noise (`A × B`); writes
/// `actions` (`A × B`), the pre-squash values `pre` (`A × B`, needed by [`backward`]) and
/// `log_prob` (`B`).
pub fn sample(
    head: &DMatrix<f32>,
    eps: &DMatrix<f32>,
    pre: &mut DMatrix<f32>,
    actions: &mut DMatrix<f32>,
    log_prob: &mut [f32],
) {
    let a_dim = eps.nrows();
    assert_eq!(head.nrows(), 2 * a_dim, "head rows");
    let cols = head
        .as_slice()
        .chunks_exact(2 * a_dim)
        .zip(eps.as_slice().chunks_exact(a_dim))
        .zip(pre.as_mut_slice().chunks_exact_mut(a_dim))
        .zip(actions.as_mut_slice().chunks_exact_mut(a_dim))
        .zip(log_prob.iter_mut());
    for ((((h, e), u), a), lp) in cols {
        let (mean, log_std) = h.split_at(a_dim);
        let mut sum = 0.0;
        for i in 0..a_dim {
            let ls = log_std[i].clamp(LOG_STD_MIN, LOG_STD_MAX);
            u[i] = mean[i] + ls.exp() * e[i];
            a[i] = u[i].tanh();
            sum += -0.5 * e[i] * e[i] - ls - HALF_LOG_2PI - log_one_minus_tanh_sq(u[i]);
        }
        *lp = sum;
    }
}

/// Back-propagates through [`sample`] (ε held fixed): given ∂L/∂a (`A × B`) and ∂L/∂log π
/// (`B`), writes ∂L/∂head (`2A × B`).
pub fn backward(
    head: &DMatrix<f32>,
    eps: &DMatrix<f32>,
    actions: &DMatrix<f32>,
    d_actions: &DMatrix<f32>,
    d_log_prob: &[f32],
    d_head: &mut DMatrix<f32>,
) {
    let a_dim = eps.nrows();
    let cols = head
        .as_slice()
        .chunks_exact(2 * a_dim)
        .zip(eps.as_slice().chunks_exact(a_dim))
        .zip(actions.as_slice().chunks_exact(a_dim))
        .zip(d_actions.as_slice().chunks_exact(a_dim))
        .zip(d_log_prob)
        .zip(d_head.as_mut_slice().chunks_exact_mut(2 * a_dim));
    for (((((h, e), a), da), &dlp), dh) in cols {
        let log_std = &h[a_dim..];
        let (d_mean, d_log_std) = dh.split_at_mut(a_dim);
        for i in 0..a_dim {
            let ls = log_std[i];
            let inside = (LOG_STD_MIN..=LOG_STD_MAX).contains(&ls);
            let sigma = ls.clamp(LOG_STD_MIN, LOG_STD_MAX).exp();
            // ∂a/∂u = 1 − a²; ∂(−log(1 − tanh² u))/∂u = 2 tanh u = 2a.
            let du = da[i] * (1.0 - a[i] * a[i]) + dlp * 2.0 * a[i];
            d_mean[i] = du;
            // u depends on the log-std through σ ε; the Gaussian term adds −1 (∂(−log σ)).
            let d_ls = du * sigma * e[i] - dlp;
            d_log_std[i] = if inside { d_ls } else { 0.0 };
        }
    }
}

/// Deterministic (mean) actions: a = tanh(μ).
pub fn mean_action(head: &DMatrix<f32>, actions: &mut DMatrix<f32>) {
    let a_dim = actions.nrows();
    for (h, a) in head
        .as_slice()
        .chunks_exact(2 * a_dim)
        .zip(actions.as_mut_slice().chunks_exact_mut(a_dim))
    {
        for i in 0..a_dim {
            a[i] = h[i].tanh();
        }
    }
}
