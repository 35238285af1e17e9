//! SMIRL's learned reward for Python: δ_r(u, o) = w_uᵀ φ(o) read from a run directory's
//! `rewards/<algo>_seed<k>.json`, evaluated in Rust on batches of observations.

use crate::error;
use numpy::{PyArray1, PyReadonlyArray1, PyReadonlyArray2, PyUntypedArrayMethods};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use smirl::irl::reward::{RewardModel, RewardOptimConfig};
use smirl::irl::smirl::LinearRmReward;

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyLearnedReward>()
}

/// Most rows one `reward` call takes.
const MAX_ROWS: usize = 1 << 22;

/// A learned linear reward over a reward machine's states (SMIRL's `smirl_seed<k>.json`).
#[pyclass(name = "LearnedReward", module = "smirl._core", unsendable)]
pub struct PyLearnedReward {
    reward: LinearRmReward,
    out: Vec<f32>,
}

#[pymethods]
impl PyLearnedReward {
    /// Reads a reward file SMIRL wrote (size-limited and checked as `reacher retrain` reads it).
    #[staticmethod]
    fn read(path: std::path::PathBuf) -> PyResult<Self> {
        // The optimiser is never stepped here; any valid setting will do.
        let optim = RewardOptimConfig::adam(1e-3);
        let reward = LinearRmReward::load(&path, optim).map_err(error)?;
        Ok(PyLearnedReward {
            reward,
            out: Vec::new(),
        })
    }

    /// Number of machine states the reward has weights for.
    #[getter]
    fn n_states(&self) -> usize {
        self.reward.n_states()
    }

    /// Width of the observations it reads (the environment's observation without the
    /// machine's one-hot).
    #[getter]
    fn obs_dim(&self) -> usize {
        self.reward.obs_dim()
    }

    /// The weights w_u of state `u`.
    fn weights(&self, u: usize) -> PyResult<Vec<f32>> {
        if u >= self.reward.n_states() {
            return Err(PyValueError::new_err(format!(
                "state {u} is out of range (the reward has {} states)",
                self.reward.n_states()
            )));
        }
        Ok(self.reward.weights(u).to_vec())
    }

    /// δ_r(u_i, o_i) for each row: `obs` is `(n, obs_dim)` float32 (the observation after the
    /// step), `states` `(n,)` uint32 (the machine state before it).
    fn reward<'py>(
        &mut self,
        py: Python<'py>,
        obs: PyReadonlyArray2<'py, f32>,
        states: PyReadonlyArray1<'py, u32>,
    ) -> PyResult<Bound<'py, PyArray1<f32>>> {
        let shape = obs.shape();
        let (n, d) = (shape[0], shape[1]);
        if d != self.reward.obs_dim() {
            return Err(PyValueError::new_err(format!(
                "obs has {d} columns, the reward reads {}",
                self.reward.obs_dim()
            )));
        }
        if states.len() != n {
            return Err(PyValueError::new_err(format!(
                "{} states for {n} observations",
                states.len()
            )));
        }
        if n > MAX_ROWS {
            return Err(PyValueError::new_err(format!(
                "{n} rows, at most {MAX_ROWS} per call"
            )));
        }
        let obs = obs.as_array();
        let rows: Vec<f32> = obs.iter().copied().collect();
        let states: Vec<u32> = states.as_array().iter().copied().collect();
        self.out.clear();
        self.out.resize(n, 0.0);
        self.reward
            .reward_batch(&rows, &states, &mut self.out)
            .map_err(error)?;
        Ok(PyArray1::from_slice(py, &self.out))
    }
}
