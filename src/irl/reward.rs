//! Learned reward models that plug into SAC, and the (64, 64) MLP reward of f-IRL / MaxEnt.
//!
//! A [`RewardModel`] maps a batch of observations, each paired with a reward-machine state,
//! to rewards, and learns from **per-state loss coefficients**: every IRL objective in this
//! module tree is a surrogate `L` with `∇θ L = Σ_i c_i ∇θ r_θ(o_i, u_i)`
//! (see [`super::firl`] and [`super::smirl`]), so a model only needs that weighted backward
//! pass and an optimiser step. Losses are minimised.
//!
//! Models that ignore the RM state (the MLP) accept an empty `rm_state` slice.

use crate::atomic_file::write_atomic;
use crate::nn::{Adam, AdamConfig, BackwardMode, Mlp, MlpArch, MlpWorkspace, NnError};
use nalgebra::DMatrix;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use std::path::Path;

/// Bad input to a reward model.
#[derive(Debug, thiserror::Error)]
pub enum RewardError {
    #[error("{len} observation values are not whole rows of width {obs_dim}")]
    ObsShape { len: usize, obs_dim: usize },
    #[error("{what} has length {got}, expected {expected}")]
    Length {
        what: &'static str,
        got: usize,
        expected: usize,
    },
    #[error("reward-machine state {state} is out of range (the model has {n_states} states)")]
    RmStateOutOfRange { state: u32, n_states: usize },
    #[error("observation column {column} is out of range for width {obs_dim}")]
    ColumnOutOfRange { column: usize, obs_dim: usize },
    #[error("loss coefficient {index} is {value}, not finite")]
    NonFiniteCoefficient { index: usize, value: f64 },
    #[error("invalid reward-model configuration: {0}")]
    Config(String),
    #[error("{path}: {source}")]
    Io {
        path: String,
        #[source]
        source: std::io::Error,
    },
    #[error(transparent)]
    Nn(#[from] NnError),
}

/// How a reward model takes its optimiser steps.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct RewardOptimConfig {
    /// `true`: Adam (PyTorch's formula); `false`: plain gradient descent.
    pub adam: bool,
    pub lr: f32,
    /// L2 penalty λ: the step uses ∇L + λθ (Adam with PyTorch's `weight_decay`).
    pub l2: f32,
}

impl RewardOptimConfig {
    pub fn adam(lr: f32) -> Self {
        Self {
            adam: true,
            lr,
            l2: 0.0,
        }
    }

    pub fn sgd(lr: f32) -> Self {
        Self {
            adam: false,
            lr,
            l2: 0.0,
        }
    }

    fn validate(&self) -> Result<(), RewardError> {
        if !(self.lr.is_finite() && self.lr > 0.0) {
            return Err(RewardError::Config(format!(
                "learning rate must be positive, got {}",
                self.lr
            )));
        }
        if !(self.l2.is_finite() && self.l2 >= 0.0) {
            return Err(RewardError::Config(format!(
                "l2 must be non-negative, got {}",
                self.l2
            )));
        }
        Ok(())
    }
}

/// The optimiser behind [`RewardOptimConfig`], over a fixed list of tensors.
#[derive(Clone, Debug)]
pub(crate) struct TensorOptimizer {
    config: RewardOptimConfig,
    adam: Option<Adam>,
}

impl TensorOptimizer {
    /// Changes the learning rate of the following steps (Adam keeps its moment estimates).
    pub(crate) fn set_lr(&mut self, lr: f32) {
        self.config.lr = lr;
        if let Some(adam) = &mut self.adam {
            adam.config.lr = lr;
        }
    }

    pub(crate) fn new(config: RewardOptimConfig, lens: &[usize]) -> Result<Self, RewardError> {
        config.validate()?;
        let adam = config
            .adam
            .then(|| Adam::new(AdamConfig::with_lr(config.lr), lens));
        Ok(Self { config, adam })
    }

    /// Adds the L2 term to the gradients and updates the parameters.
    pub(crate) fn step(&mut self, tensors: &mut [(&mut [f32], &mut [f32])]) {
        let l2 = self.config.l2;
        if l2 > 0.0 {
            for (p, g) in tensors.iter_mut() {
                for (g, p) in g.iter_mut().zip(p.iter()) {
                    *g += l2 * p;
                }
            }
        }
        match &mut self.adam {
            Some(adam) => {
                let mut view: Vec<(&mut [f32], &[f32])> =
                    tensors.iter_mut().map(|(p, g)| (&mut **p, &**g)).collect();
                adam.step_tensors(&mut view);
            }
            None => {
                let lr = self.config.lr;
                for (p, g) in tensors.iter_mut() {
                    for (p, g) in p.iter_mut().zip(g.iter()) {
                        *p -= lr * g;
                    }
                }
            }
        }
    }
}

/// A learned reward r_θ(o, u) over observations o and reward-machine states u.
pub trait RewardModel {
    /// Width of the observations the model reads.
    fn obs_dim(&self) -> usize;

    /// Rewards of the row-major observations `obs` (`n × obs_dim`) paired with `rm_state`
    /// (length n; may be empty for models that ignore the RM state) into `out` (length n).
    fn reward_batch(
        &mut self,
        obs: &[f32],
        rm_state: &[u32],
        out: &mut [f32],
    ) -> Result<(), RewardError>;

    /// Computes and stores ∇θ L = Σ_i `coeffs[i]` · ∇θ r_θ(obs_i, rm_state_i), replacing the
    /// previously stored gradient.
    fn backward(
        &mut self,
        obs: &[f32],
        rm_state: &[u32],
        coeffs: &[f64],
    ) -> Result<(), RewardError>;

    /// One optimiser step (with the L2 penalty, if configured) on the stored gradient.
    fn step(&mut self);

    /// Sets the learning rate of the following optimiser steps (a schedule).
    fn set_lr(&mut self, lr: f32);

    /// `backward` then `step`.
    fn update(&mut self, obs: &[f32], rm_state: &[u32], coeffs: &[f64]) -> Result<(), RewardError> {
        self.backward(obs, rm_state, coeffs)?;
        self.step();
        Ok(())
    }

    /// Number of parameters.
    fn num_params(&self) -> usize;
    /// The parameters, flattened in a fixed order.
    fn params(&self) -> Vec<f32>;
    /// Replaces the parameters (same order and length as [`RewardModel::params`]).
    fn set_params(&mut self, params: &[f32]) -> Result<(), RewardError>;
    /// The stored gradient of the last `backward`, in the order of `params` (without the L2
    /// term, which `step` adds).
    fn grad(&self) -> Vec<f32>;
    /// Writes the parameters to `path` atomically.
    fn save(&self, path: &Path) -> Result<(), RewardError>;
}

/// Checks a batch's shapes and returns its row count.
pub(crate) fn check_batch(
    obs: &[f32],
    obs_dim: usize,
    rm_state: &[u32],
    rm_state_required: bool,
    other: (&'static str, usize),
) -> Result<usize, RewardError> {
    if obs_dim == 0 || !obs.len().is_multiple_of(obs_dim) {
        return Err(RewardError::ObsShape {
            len: obs.len(),
            obs_dim,
        });
    }
    let n = obs.len() / obs_dim;
    if rm_state_required || !rm_state.is_empty() {
        check_len("rm_state", rm_state.len(), n)?;
    }
    check_len(other.0, other.1, n)?;
    Ok(n)
}

/// `what` has length `got`; it must be `expected`.
pub(crate) fn check_len(
    what: &'static str,
    got: usize,
    expected: usize,
) -> Result<(), RewardError> {
    if got == expected {
        Ok(())
    } else {
        Err(RewardError::Length {
            what,
            got,
            expected,
        })
    }
}

pub(crate) fn check_coefficients(coeffs: &[f64]) -> Result<(), RewardError> {
    match coeffs.iter().position(|c| !c.is_finite()) {
        Some(index) => Err(RewardError::NonFiniteCoefficient {
            index,
            value: coeffs[index],
        }),
        None => Ok(()),
    }
}

/// Configuration of the MLP reward.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct MlpRewardConfig {
    /// Observation columns fed to the network (e.g. all 17 Reacher columns, or only the
    /// fingertip `OBS_TIP` to match the KDE's state marginal).
    pub input_columns: Vec<usize>,
    /// Hidden layer sizes (the paper: 64, 64).
    pub hidden: Vec<usize>,
    /// Output clamp: r ∈ [−clamp, clamp] (the paper: 10). The clamp has zero gradient where
    /// it is active, as `torch.clamp`.
    pub clamp: f32,
    pub optim: RewardOptimConfig,
    /// Seed of the initial weights.
    pub seed: u64,
}

impl MlpRewardConfig {
    /// The paper's reward network: (64, 64) ReLU, clamped to ±10, Adam.
    pub fn paper(input_columns: Vec<usize>, lr: f32, seed: u64) -> Self {
        Self {
            input_columns,
            hidden: vec![64, 64],
            clamp: 10.0,
            optim: RewardOptimConfig::adam(lr),
            seed,
        }
    }
}

/// Largest batch pushed through the network at once (bounds the workspace memory).
const MLP_CHUNK: usize = 4096;

/// r_θ(o) = clamp(MLP(`o[input_columns]`), ±clamp); ignores the RM state.
pub struct MlpReward {
    config: MlpRewardConfig,
    obs_dim: usize,
    net: Mlp,
    optim: TensorOptimizer,
    /// Accumulated ∂L/∂θ per tensor (W, b of each layer), over the chunks of a batch.
    grad: Vec<Vec<f32>>,
    ws: Option<MlpWorkspace>,
    input: DMatrix<f32>,
}

impl MlpReward {
    pub fn new(config: MlpRewardConfig, obs_dim: usize) -> Result<MlpReward, RewardError> {
        if config.input_columns.is_empty() {
            return Err(RewardError::Config("no input columns".into()));
        }
        if let Some(&column) = config.input_columns.iter().find(|&&c| c >= obs_dim) {
            return Err(RewardError::ColumnOutOfRange { column, obs_dim });
        }
        if config.hidden.contains(&0) {
            return Err(RewardError::Config("a hidden layer has size 0".into()));
        }
        if !(config.clamp.is_finite() && config.clamp > 0.0) {
            return Err(RewardError::Config(format!(
                "clamp must be positive, got {}",
                config.clamp
            )));
        }
        let arch = MlpArch::new(config.input_columns.len(), &config.hidden, 1);
        let net = Mlp::new(&arch, &mut ChaCha8Rng::seed_from_u64(config.seed));
        let lens = net.tensor_lens();
        let optim = TensorOptimizer::new(config.optim, &lens)?;
        Ok(MlpReward {
            obs_dim,
            grad: lens.iter().map(|&n| vec![0.0; n]).collect(),
            optim,
            net,
            ws: None,
            input: DMatrix::zeros(config.input_columns.len(), 0),
            config,
        })
    }

    pub fn config(&self) -> &MlpRewardConfig {
        &self.config
    }

    pub fn network(&self) -> &Mlp {
        &self.net
    }

    /// Loads parameters saved by [`RewardModel::save`] (same architecture only).
    pub fn load(&mut self, path: &Path) -> Result<(), RewardError> {
        Ok(self.net.load(path)?)
    }

    /// Runs the network on rows `rows` of `obs`; the raw (unclamped) outputs are in
    /// `self.ws.output()`.
    fn forward_chunk(&mut self, obs: &[f32], rows: std::ops::Range<usize>) {
        let b = rows.len();
        let cols = &self.config.input_columns;
        if self.input.ncols() != b {
            self.input = DMatrix::zeros(cols.len(), b);
        }
        for (k, r) in rows.enumerate() {
            let row = &obs[r * self.obs_dim..(r + 1) * self.obs_dim];
            let dst = &mut self.input.as_mut_slice()[k * cols.len()..(k + 1) * cols.len()];
            for (d, &c) in dst.iter_mut().zip(cols) {
                *d = row[c];
            }
        }
        if self.ws.as_ref().map(|w| w.batch()) != Some(b) {
            self.ws = Some(self.net.workspace(b));
        }
        let ws = self.ws.as_mut().expect("workspace set above");
        self.net.forward(&self.input, ws);
    }
}

impl RewardModel for MlpReward {
    fn obs_dim(&self) -> usize {
        self.obs_dim
    }

    fn reward_batch(
        &mut self,
        obs: &[f32],
        rm_state: &[u32],
        out: &mut [f32],
    ) -> Result<(), RewardError> {
        let n = check_batch(obs, self.obs_dim, rm_state, false, ("out", out.len()))?;
        let clamp = self.config.clamp;
        let mut start = 0;
        while start < n {
            let end = (start + MLP_CHUNK).min(n);
            self.forward_chunk(obs, start..end);
            let raw = self.ws.as_ref().expect("forward ran").output().as_slice();
            for (o, r) in out[start..end].iter_mut().zip(raw) {
                *o = r.clamp(-clamp, clamp);
            }
            start = end;
        }
        Ok(())
    }

    fn backward(
        &mut self,
        obs: &[f32],
        rm_state: &[u32],
        coeffs: &[f64],
    ) -> Result<(), RewardError> {
        let n = check_batch(obs, self.obs_dim, rm_state, false, ("coeffs", coeffs.len()))?;
        check_coefficients(coeffs)?;
        for g in &mut self.grad {
            g.fill(0.0);
        }
        let clamp = self.config.clamp;
        let mut start = 0;
        while start < n {
            let end = (start + MLP_CHUNK).min(n);
            self.forward_chunk(obs, start..end);
            let ws = self.ws.as_mut().expect("forward ran");
            // ∂L/∂raw = c where the clamp is inactive, 0 where it clips.
            let raw = ws.output().as_slice();
            let d_out = DMatrix::from_iterator(
                1,
                end - start,
                raw.iter().zip(&coeffs[start..end]).map(|(&r, &c)| {
                    if (-clamp..=clamp).contains(&r) {
                        c as f32
                    } else {
                        0.0
                    }
                }),
            );
            self.net
                .backward(&self.input, ws, &d_out, None, BackwardMode::Params);
            for (acc, (_, g)) in self.grad.iter_mut().zip(self.net.tensors_mut()) {
                for (a, g) in acc.iter_mut().zip(g) {
                    *a += g;
                }
            }
            start = end;
        }
        Ok(())
    }

    fn step(&mut self) {
        let mut tensors: Vec<(&mut [f32], &mut [f32])> = self
            .net
            .tensors_mut()
            .map(|(p, _)| p)
            .zip(self.grad.iter_mut().map(|g| g.as_mut_slice()))
            .collect();
        self.optim.step(&mut tensors);
    }

    fn set_lr(&mut self, lr: f32) {
        self.optim.set_lr(lr);
    }

    fn num_params(&self) -> usize {
        self.net.num_params()
    }

    fn params(&self) -> Vec<f32> {
        self.net.params().flat_map(|p| p.iter().copied()).collect()
    }

    fn set_params(&mut self, params: &[f32]) -> Result<(), RewardError> {
        check_len("params", params.len(), self.num_params())?;
        let mut off = 0;
        for (p, _) in self.net.tensors_mut() {
            p.copy_from_slice(&params[off..off + p.len()]);
            off += p.len();
        }
        Ok(())
    }

    fn grad(&self) -> Vec<f32> {
        self.grad.iter().flatten().copied().collect()
    }

    fn save(&self, path: &Path) -> Result<(), RewardError> {
        Ok(self.net.save(path)?)
    }
}

/// Writes `bytes` to `path` atomically, naming the path in the error.
pub(crate) fn save_bytes(path: &Path, bytes: &[u8]) -> Result<(), RewardError> {
    write_atomic(path, bytes).map_err(|source| RewardError::Io {
        path: path.display().to_string(),
        source,
    })
}
