//! Uniform replay buffer for off-policy learning.
//!
//! Storage is flat, preallocated `f32` arrays (one row of `obs_dim` values per transition), a
//! ring overwriting the oldest transition once full. Besides observations and actions it keeps
//! the environment's reward, the labels and the `terminated` flag, so any reward function can
//! be evaluated at **sample time** from stored data (see [`crate::rl::sac::RewardFn`]).

use crate::nn::codec::{ByteReader, ByteWriter, CodecError};
use crate::rm::LabelSet;
use nalgebra::DMatrix;
use rand::Rng;

/// A sampled mini-batch, one column per transition. Preallocated by [`ReplayBatch::new`] and
/// refilled in place by [`ReplayBuffer::sample_into`].
#[derive(Clone, Debug)]
pub struct ReplayBatch {
    /// Observations before the step (`obs_dim × B`).
    pub obs: DMatrix<f32>,
    /// Actions taken (`act_dim × B`).
    pub actions: DMatrix<f32>,
    /// Observations after the step (`obs_dim × B`).
    pub next_obs: DMatrix<f32>,
    /// The environment's reward of each step.
    pub env_rewards: Vec<f32>,
    /// Labels true after each step.
    pub labels: Vec<LabelSet>,
    /// 1.0 when the step ended the episode inside the environment (no bootstrapping), else 0.0.
    pub terminated: Vec<f32>,
    /// Buffer index of each sampled transition.
    pub indices: Vec<usize>,
}

impl ReplayBatch {
    pub fn new(obs_dim: usize, act_dim: usize, batch: usize) -> Self {
        Self {
            obs: DMatrix::zeros(obs_dim, batch),
            actions: DMatrix::zeros(act_dim, batch),
            next_obs: DMatrix::zeros(obs_dim, batch),
            env_rewards: vec![0.0; batch],
            labels: vec![LabelSet::EMPTY; batch],
            terminated: vec![0.0; batch],
            indices: vec![0; batch],
        }
    }

    pub fn len(&self) -> usize {
        self.indices.len()
    }

    pub fn is_empty(&self) -> bool {
        self.indices.is_empty()
    }
}

/// Ring buffer of transitions.
#[derive(Clone, Debug)]
pub struct ReplayBuffer {
    obs_dim: usize,
    act_dim: usize,
    capacity: usize,
    len: usize,
    next: usize,
    obs: Vec<f32>,
    actions: Vec<f32>,
    next_obs: Vec<f32>,
    env_rewards: Vec<f32>,
    labels: Vec<LabelSet>,
    terminated: Vec<f32>,
}

impl ReplayBuffer {
    /// Preallocates room for `capacity` transitions.
    pub fn new(obs_dim: usize, act_dim: usize, capacity: usize) -> Self {
        assert!(capacity > 0, "replay capacity must be positive");
        Self {
            obs_dim,
            act_dim,
            capacity,
            len: 0,
            next: 0,
            obs: vec![0.0; capacity * obs_dim],
            actions: vec![0.0; capacity * act_dim],
            next_obs: vec![0.0; capacity * obs_dim],
            env_rewards: vec![0.0; capacity],
            labels: vec![LabelSet::EMPTY; capacity],
            terminated: vec![0.0; capacity],
        }
    }

    pub fn len(&self) -> usize {
        self.len
    }

    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    pub fn capacity(&self) -> usize {
        self.capacity
    }

    pub fn obs_dim(&self) -> usize {
        self.obs_dim
    }

    pub fn act_dim(&self) -> usize {
        self.act_dim
    }

    /// Stores one transition, overwriting the oldest when full.
    pub fn push(
        &mut self,
        obs: &[f32],
        action: &[f32],
        next_obs: &[f32],
        env_reward: f32,
        labels: LabelSet,
        terminated: bool,
    ) {
        let (o, a, i) = (self.obs_dim, self.act_dim, self.next);
        self.obs[i * o..(i + 1) * o].copy_from_slice(obs);
        self.actions[i * a..(i + 1) * a].copy_from_slice(action);
        self.next_obs[i * o..(i + 1) * o].copy_from_slice(next_obs);
        self.env_rewards[i] = env_reward;
        self.labels[i] = labels;
        self.terminated[i] = if terminated { 1.0 } else { 0.0 };
        self.next = (i + 1) % self.capacity;
        self.len = (self.len + 1).min(self.capacity);
    }

    /// Observation of stored transition `index` (for reward functions needing all data).
    pub fn obs(&self, index: usize) -> &[f32] {
        &self.obs[index * self.obs_dim..(index + 1) * self.obs_dim]
    }

    pub fn next_obs(&self, index: usize) -> &[f32] {
        &self.next_obs[index * self.obs_dim..(index + 1) * self.obs_dim]
    }

    /// Fills `batch` with transitions drawn uniformly with replacement.
    ///
    /// # Panics
    /// When the buffer is empty or the batch has other dimensions.
    pub fn sample_into(&self, rng: &mut impl Rng, batch: &mut ReplayBatch) {
        assert!(self.len > 0, "sampling from an empty replay buffer");
        assert_eq!(batch.obs.nrows(), self.obs_dim, "batch obs dim");
        assert_eq!(batch.actions.nrows(), self.act_dim, "batch act dim");
        let (o, a) = (self.obs_dim, self.act_dim);
        let ReplayBatch {
            obs,
            actions,
            next_obs,
            env_rewards,
            labels,
            terminated,
            indices,
        } = batch;
        let cols = obs
            .as_mut_slice()
            .chunks_exact_mut(o)
            .zip(next_obs.as_mut_slice().chunks_exact_mut(o))
            .zip(actions.as_mut_slice().chunks_exact_mut(a))
            .enumerate();
        for (j, ((ob, nob), ac)) in cols {
            let i = rng.gen_range(0..self.len);
            indices[j] = i;
            ob.copy_from_slice(&self.obs[i * o..(i + 1) * o]);
            nob.copy_from_slice(&self.next_obs[i * o..(i + 1) * o]);
            ac.copy_from_slice(&self.actions[i * a..(i + 1) * a]);
            env_rewards[j] = self.env_rewards[i];
            labels[j] = self.labels[i];
            terminated[j] = self.terminated[i];
        }
    }

    /// Appends the filled part of the buffer (for checkpoints).
    pub fn write(&self, w: &mut ByteWriter) {
        w.usize(self.obs_dim);
        w.usize(self.act_dim);
        w.usize(self.capacity);
        w.usize(self.len);
        w.usize(self.next);
        let (o, a, n) = (self.obs_dim, self.act_dim, self.len);
        w.f32s(&self.obs[..n * o]);
        w.f32s(&self.actions[..n * a]);
        w.f32s(&self.next_obs[..n * o]);
        w.f32s(&self.env_rewards[..n]);
        let labels: Vec<u32> = self.labels[..n].iter().map(|l| l.0).collect();
        w.u32s(&labels);
        w.f32s(&self.terminated[..n]);
    }

    /// Reads a buffer written by [`ReplayBuffer::write`]; it must have the same dimensions and
    /// capacity as `self`, whose contents it replaces.
    pub fn read_into(&mut self, r: &mut ByteReader) -> Result<(), CodecError> {
        let dims = [
            ("replay obs dim", self.obs_dim),
            ("replay act dim", self.act_dim),
            ("replay capacity", self.capacity),
        ];
        for (what, want) in dims {
            let got = r.usize(what)?;
            if got != want {
                return Err(CodecError::Invalid {
                    what,
                    problem: format!("{got} stored, {want} expected"),
                });
            }
        }
        let len = r.usize("replay length")?;
        let next = r.usize("replay position")?;
        if len > self.capacity || next >= self.capacity || (len < self.capacity && next != len) {
            return Err(CodecError::Invalid {
                what: "replay length",
                problem: format!(
                    "length {len} / position {next} / capacity {}",
                    self.capacity
                ),
            });
        }
        let (o, a) = (self.obs_dim, self.act_dim);
        r.f32s_into(&mut self.obs[..len * o], "replay observations")?;
        r.f32s_into(&mut self.actions[..len * a], "replay actions")?;
        r.f32s_into(&mut self.next_obs[..len * o], "replay next observations")?;
        r.f32s_into(&mut self.env_rewards[..len], "replay rewards")?;
        let labels = r.u32s("replay labels")?;
        if labels.len() != len {
            return Err(CodecError::Invalid {
                what: "replay labels",
                problem: format!("{} stored, {len} expected", labels.len()),
            });
        }
        for (dst, src) in self.labels.iter_mut().zip(labels) {
            *dst = LabelSet(src);
        }
        r.f32s_into(&mut self.terminated[..len], "replay terminated flags")?;
        self.len = len;
        self.next = next;
        Ok(())
    }
}
