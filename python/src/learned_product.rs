//! The environment SMIRL's agent learns in, for Python: ReacherDelivery × a run's *learned*
//! machine, paying the run's learned reward. The observation is the environment's, then the
//! learned state's one-hot, as in `reacher job`. Episodes never terminate early: they are truncated at the
//! episode length, whatever the task's machine says, so nothing of the task reaches the agent.
//! The task's perfect machine is stepped beside it only to fill `info` (`success`, `failure`,
//! `task_rm_state`, and `branch` for a conditional task) for judging the policy.

use crate::error;
use numpy::PyArray1;
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use smirl::env::product::{NoShaping, ProductEnv};
use smirl::env::reacher::{ReacherDelivery, ReacherError};
use smirl::env::reacher_task::{Branch, EventBranch};
use smirl::env::ContinuousEnv;
use smirl::irl::reward::{RewardModel, RewardOptimConfig};
use smirl::irl::smirl::LinearRmReward;
use smirl::pipeline::reacher_irl::run::open_run;
use smirl::rm::RewardMachine;
use std::path::PathBuf;

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<LearnedProductCore>()
}

type StepTuple<'py> = (
    Bound<'py, PyArray1<f32>>,
    f64,
    bool,
    bool,
    Bound<'py, PyDict>,
);

/// ReacherDelivery × a learned machine with a learned reward (see the module docs).
#[pyclass(module = "smirl._core", unsendable)]
pub struct LearnedProductCore {
    env: ProductEnv<ReacherDelivery, NoShaping>,
    reward: LinearRmReward,
    perfect: RewardMachine,
    branches: Option<EventBranch>,
    /// The task's machine entered its event branch this episode (tasks that have one).
    event_branch: bool,
    task_state: usize,
    task_done: bool,
    obs: Vec<f32>,
    inner_dim: usize,
    max_steps: usize,
    ready: bool,
    task: String,
}

impl LearnedProductCore {
    fn in_event_branch(&self) -> bool {
        let branches = self.branches.as_ref();
        branches.is_some_and(|b| b.in_event_branch(self.task_state))
    }
}

#[pymethods]
impl LearnedProductCore {
    /// The product of the run directory `run` (made by `reacher --task` or `prepare`) for the
    /// reward `rewards/<algo>_seed<seed>.json`; `machine` replaces the run's learned machine
    /// (`rm/learned.txt`) by another machine file.
    #[new]
    #[pyo3(signature = (run, algo = "smirl", seed = 0, machine = None))]
    fn new(run: PathBuf, algo: &str, seed: u64, machine: Option<PathBuf>) -> PyResult<Self> {
        let prepared = open_run(&run).map_err(error)?;
        let learned = match machine {
            Some(path) => smirl::rm::format::read_rm(&path).map_err(error)?,
            None => prepared.learned.clone().ok_or_else(|| {
                error(format!(
                    "{}: the run has no learned machine (rm/learned.txt)",
                    run.display()
                ))
            })?,
        };
        let path = run.join("rewards").join(format!("{algo}_seed{seed}.json"));
        // Never stepped: any valid optimiser setting will do.
        let reward = LinearRmReward::load(&path, RewardOptimConfig::adam(1e-3)).map_err(error)?;
        if reward.n_states() != learned.n_states() {
            return Err(PyValueError::new_err(format!(
                "{} has weights for {} states, the machine has {}",
                path.display(),
                reward.n_states(),
                learned.n_states()
            )));
        }
        let config = &prepared.config;
        let inner = ReacherDelivery::new(config.env.clone()).map_err(|e: ReacherError| error(e))?;
        let inner_dim = inner.obs_dim();
        if reward.obs_dim() != inner_dim {
            return Err(PyValueError::new_err(format!(
                "{} reads observations of {} values, the environment gives {inner_dim}",
                path.display(),
                reward.obs_dim()
            )));
        }
        let env = ProductEnv::new(inner, learned);
        let obs = vec![0.0; env.obs_dim()];
        Ok(LearnedProductCore {
            task: prepared.prepared.task.name().to_string(),
            branches: EventBranch::of(&prepared.perfect, prepared.prepared.task.layout().events()),
            event_branch: false,
            perfect: prepared.perfect,
            task_state: 0,
            task_done: false,
            max_steps: config.env.max_steps,
            inner_dim,
            obs,
            reward,
            env,
            ready: false,
        })
    }

    #[getter]
    fn task(&self) -> String {
        self.task.clone()
    }
    #[getter]
    fn obs_dim(&self) -> usize {
        self.env.obs_dim()
    }
    #[getter]
    fn act_dim(&self) -> usize {
        self.env.act_dim()
    }
    #[getter]
    fn max_steps(&self) -> usize {
        self.max_steps
    }
    #[getter]
    fn n_rm_states(&self) -> usize {
        self.env.rm().n_states()
    }
    /// The learned machine, in the text format of `assets/rm/`.
    #[getter]
    fn reward_machine(&self) -> String {
        smirl::rm::format::write_rm(self.env.rm())
    }

    /// Starts an episode whose randomness comes from `seed` only; returns the observation.
    fn reset<'py>(&mut self, py: Python<'py>, seed: i128) -> PyResult<Bound<'py, PyArray1<f32>>> {
        let seed = u64::try_from(seed)
            .map_err(|_| PyValueError::new_err(format!("seed must be in 0..2**64, got {seed}")))?;
        self.env.reset(seed, &mut self.obs);
        self.task_state = self.perfect.initial();
        self.event_branch = self.in_event_branch();
        self.task_done = false;
        self.ready = true;
        Ok(PyArray1::from_slice(py, &self.obs))
    }

    /// One step: `(observation, learned reward, False, truncated, info)`.
    fn step<'py>(&mut self, py: Python<'py>, action: Vec<f32>) -> PyResult<StepTuple<'py>> {
        if !self.ready {
            return Err(error(
                "step called before reset, or after the episode ended",
            ));
        }
        let u = self.env.rm_state() as u32;
        let p = self
            .env
            .step_product(&action, &mut self.obs)
            .map_err(error)?;
        let mut r = [0.0f32];
        self.reward
            .reward_batch(&self.obs[..self.inner_dim], &[u], &mut r)
            .map_err(error)?;
        // The task's machine, for judging only; it stops where the task ends.
        let (mut success, mut failure) = (false, false);
        if !self.task_done {
            self.task_state = self.perfect.next_state(self.task_state, p.step.labels);
            success = self.perfect.is_terminal(self.task_state);
            failure = self.perfect.is_failure(self.task_state);
            self.task_done = success || failure;
            self.event_branch |= self.in_event_branch();
        }
        let truncated = p.step.truncated || p.step.terminated;
        self.ready = !truncated;
        let info = PyDict::new(py);
        info.set_item("labels", self.env.rm().vocab().format_labels(p.step.labels))?;
        info.set_item("rm_state", p.rm_state)?;
        info.set_item("task_rm_state", self.task_state)?;
        info.set_item("success", success)?;
        info.set_item("failure", failure)?;
        info.set_item("task_done", self.task_done)?;
        info.set_item("env_reward", p.env_reward)?;
        if self.branches.is_some() {
            let branch = if self.event_branch {
                Branch::Event
            } else {
                Branch::Normal
            };
            info.set_item("branch", branch.name())?;
        }
        Ok((
            PyArray1::from_slice(py, &self.obs),
            f64::from(r[0]),
            false,
            truncated,
            info,
        ))
    }
}
