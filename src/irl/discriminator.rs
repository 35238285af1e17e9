//! A logistic discriminator between expert and agent states whose logit estimates the
//! log density ratio log(ρ_E/ρ_θ): f-IRL's density ratio when the expert is given by
//! demonstrations rather than by a density.
//!
//! **Why.** f-IRL's reference code fits a KDE to the *agent's* states only when the expert is
//! an analytic density (ReacherDraw); with expert *samples* it trains a classifier D(s) with
//! expert states labelled 1 and agent states 0, whose logit z(s) = log D − log(1 − D) is, at the
//! optimum with equal class weights, log ρ_E(s) − log ρ_θ(s). Fitting a KDE to 16
//! demonstrations instead makes ρ_E exactly zero a kernel radius away from them, so rkl's
//! −log u is flat (+log 1/ε) over every state the expert did not visit (the positive
//! controls, experiments/reacher/controls/results.md). The classifier's logit extrapolates smoothly and is clamped to ±[`LOGIT_CLAMP`].
//!
//! **Training.** Binary cross-entropy with logits, `batch` expert and `batch` agent states per
//! step drawn with replacement (as the reference code does), Adam with PyTorch's L2
//! `weight_decay`, the logit clamped to ±10 in the loss too (the clamp's gradient is zero
//! outside, as `torch.clamp`'s). The network persists across IRL iterations and takes `steps`
//! steps on each iteration's agent states. Per state of a 2B batch, with labels y ∈ {1, 0}
//! and σ the logistic function, ∂(mean BCE)/∂z = (σ(z) − y) / 2B.
//!
//! Differences from the reference (`SMMIRLDisc`): a ReLU MLP instead of the tanh residual
//! network (this crate's [`Mlp`]), and the settings of [`DiscriminatorConfig::firl`].

use crate::nn::{Adam, AdamConfig, BackwardMode, Mlp, MlpArch, MlpWorkspace};
use nalgebra::DMatrix;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// Magnitude bound of the logit (the reference's `clamp_magnitude`).
pub const LOGIT_CLAMP: f32 = 10.0;

/// Settings of the discriminator.
#[derive(Clone, Debug, PartialEq)]
pub struct DiscriminatorConfig {
    pub hidden: Vec<usize>,
    /// States of each class per step.
    pub batch: usize,
    /// Optimiser steps per call of [`Discriminator::train`].
    pub steps: usize,
    pub lr: f32,
    /// L2 penalty added to the gradient (PyTorch's `weight_decay`).
    pub weight_decay: f32,
}

impl DiscriminatorConfig {
    /// The reference code's sample-based settings (lr 3e-4, weight decay 1e-4, batch 800 of
    /// each class), with a (64, 64) ReLU network and 100 steps per IRL iteration instead of
    /// 1 200: its sample-based runs take 200 IRL iterations, the ReacherDraw schedule here 800,
    /// and the network is kept between iterations, so it still takes 80 000 steps in all.
    pub fn firl() -> Self {
        Self {
            hidden: vec![64, 64],
            batch: 800,
            steps: 100,
            lr: 3e-4,
            weight_decay: 1e-4,
        }
    }
}

/// Bad input to the discriminator.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum DiscriminatorError {
    #[error("{what}: {len} values are not whole rows of width {obs_dim}")]
    Shape {
        what: &'static str,
        len: usize,
        obs_dim: usize,
    },
    #[error("{what} holds no state")]
    Empty { what: &'static str },
    #[error("observation column {column} is out of range for width {obs_dim}")]
    Column { column: usize, obs_dim: usize },
    #[error("discriminator setting {0}")]
    Config(String),
    #[error("the discriminator's parameters are no longer finite")]
    Diverged,
}

/// The classifier and its optimiser state.
pub struct Discriminator {
    config: DiscriminatorConfig,
    /// Observation columns the classifier reads (f-IRL's `state_indices`).
    columns: Vec<usize>,
    net: Mlp,
    adam: Adam,
    rng: ChaCha8Rng,
    ws: MlpWorkspace,
    x: DMatrix<f32>,
    d_out: DMatrix<f32>,
}

impl Discriminator {
    pub fn new(
        config: DiscriminatorConfig,
        columns: &[usize],
        seed: u64,
    ) -> Result<Self, DiscriminatorError> {
        if columns.is_empty() {
            return Err(DiscriminatorError::Config(
                "needs at least one column".into(),
            ));
        }
        if config.batch == 0 || config.hidden.contains(&0) {
            return Err(DiscriminatorError::Config(
                "batch and hidden sizes must be positive".into(),
            ));
        }
        let lr_ok = config.lr.is_finite() && config.lr > 0.0;
        let decay_ok = config.weight_decay.is_finite() && config.weight_decay >= 0.0;
        if !(lr_ok && decay_ok) {
            return Err(DiscriminatorError::Config(format!(
                "lr {} must be positive and weight decay {} non-negative",
                config.lr, config.weight_decay
            )));
        }
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let net = Mlp::new(&MlpArch::new(columns.len(), &config.hidden, 1), &mut rng);
        let adam = Adam::for_mlp(AdamConfig::with_lr(config.lr), &net);
        let rows = 2 * config.batch;
        Ok(Self {
            ws: net.workspace(rows),
            x: DMatrix::zeros(columns.len(), rows),
            d_out: DMatrix::zeros(1, rows),
            columns: columns.to_vec(),
            net,
            adam,
            rng,
            config,
        })
    }

    fn check(
        &self,
        what: &'static str,
        obs: &[f32],
        obs_dim: usize,
    ) -> Result<usize, DiscriminatorError> {
        if obs_dim == 0 || obs.len() % obs_dim != 0 {
            return Err(DiscriminatorError::Shape {
                what,
                len: obs.len(),
                obs_dim,
            });
        }
        if let Some(&column) = self.columns.iter().find(|&&c| c >= obs_dim) {
            return Err(DiscriminatorError::Column { column, obs_dim });
        }
        let n = obs.len() / obs_dim;
        if n == 0 {
            return Err(DiscriminatorError::Empty { what });
        }
        Ok(n)
    }

    /// `config.steps` optimiser steps on expert (label 1) against agent (label 0) states,
    /// both row-major `obs_dim` wide; returns the mean BCE of the last step.
    pub fn train(
        &mut self,
        expert_obs: &[f32],
        agent_obs: &[f32],
        obs_dim: usize,
    ) -> Result<f64, DiscriminatorError> {
        let n_expert = self.check("expert states", expert_obs, obs_dim)?;
        let n_agent = self.check("agent states", agent_obs, obs_dim)?;
        let batch = self.config.batch;
        let rows = 2 * batch;
        let mut loss = 0.0;
        for _ in 0..self.config.steps {
            for j in 0..rows {
                let (obs, n) = if j < batch {
                    (expert_obs, n_expert)
                } else {
                    (agent_obs, n_agent)
                };
                let row = self.rng.gen_range(0..n);
                for (k, &c) in self.columns.iter().enumerate() {
                    self.x[(k, j)] = obs[row * obs_dim + c];
                }
            }
            let z = self.net.forward(&self.x, &mut self.ws);
            loss = 0.0;
            for j in 0..rows {
                let label = if j < batch { 1.0 } else { 0.0 };
                let raw = z[(0, j)];
                let zc = raw.clamp(-LOGIT_CLAMP, LOGIT_CLAMP);
                // BCE with logits: softplus(z) − y z, computed stably.
                loss += f64::from(zc.max(0.0) - zc * label + (-zc.abs()).exp().ln_1p());
                let sigma = 1.0 / (1.0 + (-zc).exp());
                let inside = raw.abs() <= LOGIT_CLAMP;
                self.d_out[(0, j)] = if inside {
                    (sigma - label) / rows as f32
                } else {
                    0.0
                };
            }
            loss /= rows as f64;
            self.net.backward(
                &self.x,
                &mut self.ws,
                &self.d_out,
                None,
                BackwardMode::Params,
            );
            let wd = self.config.weight_decay;
            if wd > 0.0 {
                for layer in &mut self.net.layers {
                    for (g, p) in layer.grad_w.iter_mut().zip(layer.w.iter()) {
                        *g += wd * p;
                    }
                    for (g, p) in layer.grad_b.iter_mut().zip(layer.b.iter()) {
                        *g += wd * p;
                    }
                }
            }
            self.adam.step_mlp(&mut self.net);
        }
        if !self.net.params_finite() {
            return Err(DiscriminatorError::Diverged);
        }
        Ok(loss)
    }

    /// The clamped logit, the estimate of log(ρ_E/ρ_θ), at every row of `obs`.
    pub fn log_ratio(&self, obs: &[f32], obs_dim: usize) -> Result<Vec<f64>, DiscriminatorError> {
        let n = self.check("states", obs, obs_dim)?;
        const CHUNK: usize = 4096;
        let mut out = Vec::with_capacity(n);
        let mut start = 0;
        while start < n {
            let len = CHUNK.min(n - start);
            let mut x = DMatrix::zeros(self.columns.len(), len);
            for j in 0..len {
                for (k, &c) in self.columns.iter().enumerate() {
                    x[(k, j)] = obs[(start + j) * obs_dim + c];
                }
            }
            let mut ws = self.net.workspace(len);
            let z = self.net.forward(&x, &mut ws);
            out.extend(
                z.iter()
                    .map(|&v| f64::from(v.clamp(-LOGIT_CLAMP, LOGIT_CLAMP))),
            );
            start += len;
        }
        Ok(out)
    }
}
