//! A task's environment for Python: ReacherDelivery × the task's perfect machine, one at a
//! time (`ReacherCore`) or many stepped together without the GIL (`ReacherBatch`).
//!
//! The observation is the product's: the environment's observation, then the perfect
//! machine's state one-hot (the task is not Markovian in the environment's observation
//! alone). The reward is the machine's (plus sub-goal shaping when asked for); an episode
//! terminates when the machine reaches its goal or a failure sink and is truncated at the
//! task's episode length — the environment the committed experts were trained on.

use crate::error;
use numpy::{PyArray1, PyArray2, PyArrayMethods, PyReadonlyArray2, PyUntypedArrayMethods};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use smirl::env::product::ProductEnv;
use smirl::env::reacher::{ReacherConfig, ReacherDelivery};
use smirl::env::reacher_task::{task_env, Branch, CancelBranch, ReacherTask, SubgoalPotential};
use smirl::env::ContinuousEnv;
use smirl::rm::{LabelSet, RewardMachine};

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<ReacherCore>()?;
    m.add_class::<ReacherBatch>()?;
    m.add_function(wrap_pyfunction!(task_names, m)?)?;
    Ok(())
}

/// Most environments one batch may hold.
const MAX_BATCH: usize = 4096;

/// Names of the shipped ReacherDelivery tasks.
#[pyfunction]
fn task_names() -> Vec<&'static str> {
    smirl::env::task_file::SHIPPED.to_vec()
}

type TaskEnv = ProductEnv<ReacherDelivery, SubgoalPotential>;

/// `(observation, reward, terminated, truncated, info)`, Gymnasium's step.
type StepTuple<'py> = (
    Bound<'py, PyArray1<f32>>,
    f64,
    bool,
    bool,
    Bound<'py, PyDict>,
);

/// A labelled region for a picture: `(name, x, y, radius)`.
type Region = (String, f64, f64, f64);

/// What every environment of a task shares.
pub(crate) struct TaskSpec {
    pub(crate) task: ReacherTask,
    pub(crate) config: ReacherConfig,
    pub(crate) rm: RewardMachine,
    branches: Option<CancelBranch>,
    shaping: f64,
    gamma: f64,
}

impl TaskSpec {
    pub(crate) fn new(task: &str, shaping: f64, gamma: f64) -> PyResult<TaskSpec> {
        let task = ReacherTask::resolve(task).map_err(error)?;
        if !shaping.is_finite() || shaping < 0.0 {
            return Err(PyValueError::new_err(format!(
                "shaping must be a finite number ≥ 0, got {shaping}"
            )));
        }
        if !(gamma > 0.0 && gamma <= 1.0) {
            return Err(PyValueError::new_err(format!(
                "gamma must be in (0, 1], got {gamma}"
            )));
        }
        let rm = task.perfect_rm().map_err(error)?;
        let config = task.env_config(&ReacherConfig::default()).map_err(error)?;
        let branches = CancelBranch::of(&rm, task.layout().events());
        Ok(TaskSpec {
            task,
            config,
            branches,
            rm,
            shaping,
            gamma,
        })
    }

    pub(crate) fn env(&self) -> PyResult<TaskEnv> {
        task_env(
            self.task.clone(),
            self.config.clone(),
            self.shaping,
            self.gamma,
        )
        .map_err(error)
    }
}

/// One environment and what its episode has done so far.
struct Slot {
    env: TaskEnv,
    obs: Vec<f32>,
    /// The episode has entered the machine's cancel branch (conditional tasks).
    cancelled: bool,
    done: bool,
}

impl Slot {
    fn new(spec: &TaskSpec) -> PyResult<Slot> {
        let env = spec.env()?;
        let obs = vec![0.0; env.obs_dim()];
        Ok(Slot {
            env,
            obs,
            cancelled: false,
            done: true,
        })
    }

    fn reset(&mut self, spec: &TaskSpec, seed: u64) {
        self.env.reset(seed, &mut self.obs);
        self.cancelled = spec
            .branches
            .as_ref()
            .is_some_and(|b| b.is_cancelled(self.env.rm_state()));
        self.done = false;
    }

    fn step(&mut self, spec: &TaskSpec, action: &[f32]) -> Result<StepOut, String> {
        if self.done {
            return Err("step after the episode ended: call reset first".into());
        }
        let p = self
            .env
            .step_product(action, &mut self.obs)
            .map_err(|e| e.to_string())?;
        if let Some(b) = &spec.branches {
            self.cancelled |= b.is_cancelled(p.rm_state);
        }
        self.done = p.step.terminated || p.step.truncated;
        Ok(StepOut {
            reward: p.step.reward,
            terminated: p.step.terminated,
            truncated: p.step.truncated,
            labels: p.step.labels,
            rm_state: p.rm_state,
            task_reward: p.task_reward,
            env_reward: p.env_reward,
            success: p.success,
            failure: p.failure,
        })
    }

    fn branch(&self, spec: &TaskSpec) -> Option<Branch> {
        spec.branches.as_ref().map(|_| {
            if self.cancelled {
                Branch::Cancelled
            } else {
                Branch::Normal
            }
        })
    }
}

struct StepOut {
    reward: f64,
    terminated: bool,
    truncated: bool,
    labels: LabelSet,
    rm_state: usize,
    task_reward: f64,
    env_reward: f64,
    success: bool,
    failure: bool,
}

fn seed_of(seed: i128) -> PyResult<u64> {
    u64::try_from(seed)
        .map_err(|_| PyValueError::new_err(format!("seed must be in 0..2^64, got {seed}")))
}

/// One ReacherDelivery environment of a task (a shipped name or a task file's path), with its
/// perfect machine. `unsendable`: the
/// MuJoCo data is not `Sync`, so Python may use an environment only from the thread that made
/// it (another thread gets an exception, never a data race).
#[pyclass(module = "smirl._core", unsendable)]
pub struct ReacherCore {
    spec: TaskSpec,
    slot: Slot,
    ready: bool,
}

#[pymethods]
impl ReacherCore {
    #[new]
    #[pyo3(signature = (task, shaping = 0.0, gamma = 0.99))]
    fn new(task: &str, shaping: f64, gamma: f64) -> PyResult<Self> {
        let spec = TaskSpec::new(task, shaping, gamma)?;
        let slot = Slot::new(&spec)?;
        Ok(ReacherCore {
            spec,
            slot,
            ready: false,
        })
    }

    #[getter]
    fn task(&self) -> String {
        self.spec.task.name().to_string()
    }
    #[getter]
    fn obs_dim(&self) -> usize {
        self.slot.env.obs_dim()
    }
    #[getter]
    fn act_dim(&self) -> usize {
        self.slot.env.act_dim()
    }
    #[getter]
    fn max_steps(&self) -> usize {
        self.spec.config.max_steps
    }
    #[getter]
    fn n_rm_states(&self) -> usize {
        self.spec.rm.n_states()
    }
    #[getter]
    fn vocabulary(&self) -> String {
        self.spec.rm.vocab().props().iter().collect()
    }
    /// The perfect machine, in the text format of `assets/rm/`.
    #[getter]
    fn reward_machine(&self) -> String {
        smirl::rm::format::write_rm(&self.spec.rm)
    }
    #[getter]
    fn has_branches(&self) -> bool {
        self.spec.branches.is_some()
    }

    /// Starts an episode whose randomness comes from `seed` only; returns the observation.
    fn reset<'py>(&mut self, py: Python<'py>, seed: i128) -> PyResult<Bound<'py, PyArray1<f32>>> {
        let seed = seed_of(seed)?;
        self.slot.reset(&self.spec, seed);
        self.ready = true;
        Ok(PyArray1::from_slice(py, &self.slot.obs))
    }

    /// One step: `(observation, reward, terminated, truncated, info)`.
    fn step<'py>(&mut self, py: Python<'py>, action: Vec<f32>) -> PyResult<StepTuple<'py>> {
        if !self.ready {
            return Err(error("step called before reset"));
        }
        let out = self.slot.step(&self.spec, &action).map_err(error)?;
        let info = PyDict::new(py);
        info.set_item("labels", self.spec.rm.vocab().format_labels(out.labels))?;
        info.set_item("rm_state", out.rm_state)?;
        info.set_item("task_reward", out.task_reward)?;
        info.set_item("env_reward", out.env_reward)?;
        info.set_item("success", out.success)?;
        info.set_item("failure", out.failure)?;
        info.set_item("step", self.slot.env.inner().steps())?;
        // The first event's step (the cancel's in the paper's tasks), and every event's.
        let event_steps = self.slot.env.inner().event_steps();
        info.set_item("cancel_step", event_steps.first().copied().flatten())?;
        info.set_item("event_steps", event_steps.to_vec())?;
        if let Some(b) = self.slot.branch(&self.spec) {
            info.set_item("branch", b.name())?;
        }
        Ok((
            PyArray1::from_slice(py, &self.slot.obs),
            out.reward,
            out.terminated,
            out.truncated,
            info,
        ))
    }

    /// Machine state of the current episode.
    #[getter]
    fn rm_state(&self) -> usize {
        self.slot.env.rm_state()
    }

    /// What a top-down picture needs: `(joint angles, fingertip, regions)`, regions as
    /// `(name, x, y, radius)`.
    fn scene(&self) -> ([f64; 2], [f64; 2], Vec<Region>) {
        let inner = self.slot.env.inner();
        let q = inner.qpos();
        let regions = (inner.layout().regions.iter())
            .zip(inner.positions())
            .map(|(r, &[x, y])| (r.anchor.name().to_string(), x, y, r.radius))
            .collect();
        ([q[0], q[1]], inner.fingertip(), regions)
    }
}

/// `n` environments of one task stepped together; `step` releases the GIL and spreads the
/// environments over `threads` threads (the result does not depend on the thread count: each
/// environment's episode depends on its own seed and actions only).
#[pyclass(module = "smirl._core", unsendable)]
pub struct ReacherBatch {
    spec: TaskSpec,
    slots: Vec<Slot>,
    threads: usize,
}

#[pymethods]
impl ReacherBatch {
    #[new]
    #[pyo3(signature = (task, n, shaping = 0.0, gamma = 0.99, threads = 1))]
    fn new(task: &str, n: usize, shaping: f64, gamma: f64, threads: usize) -> PyResult<Self> {
        if n == 0 || n > MAX_BATCH {
            return Err(PyValueError::new_err(format!(
                "a batch holds 1 to {MAX_BATCH} environments, got {n}"
            )));
        }
        if threads == 0 || threads > 256 {
            return Err(PyValueError::new_err(format!(
                "threads must be in 1..=256, got {threads}"
            )));
        }
        let spec = TaskSpec::new(task, shaping, gamma)?;
        let slots = (0..n).map(|_| Slot::new(&spec)).collect::<PyResult<_>>()?;
        Ok(ReacherBatch {
            spec,
            slots,
            threads,
        })
    }

    #[getter]
    fn n(&self) -> usize {
        self.slots.len()
    }
    #[getter]
    fn obs_dim(&self) -> usize {
        self.slots[0].env.obs_dim()
    }
    #[getter]
    fn act_dim(&self) -> usize {
        self.slots[0].env.act_dim()
    }
    #[getter]
    fn max_steps(&self) -> usize {
        self.spec.config.max_steps
    }

    /// Resets the environments `indices` with `seeds` (one each); returns every
    /// environment's current observation, shape `(n, obs_dim)`.
    fn reset<'py>(
        &mut self,
        py: Python<'py>,
        indices: Vec<usize>,
        seeds: Vec<i128>,
    ) -> PyResult<Bound<'py, PyArray2<f32>>> {
        if indices.len() != seeds.len() {
            return Err(PyValueError::new_err(format!(
                "{} indices but {} seeds",
                indices.len(),
                seeds.len()
            )));
        }
        for (&i, &s) in indices.iter().zip(&seeds) {
            let n = self.slots.len();
            let slot = self.slots.get_mut(i).ok_or_else(|| {
                PyValueError::new_err(format!("index {i} is not below the batch size {n}"))
            })?;
            slot.reset(&self.spec, seed_of(s)?);
        }
        Ok(self.observations(py))
    }

    /// Steps every environment whose episode is running with its row of `actions`
    /// (`(n, act_dim)`, float32). Returns `(observations, rewards, terminated, truncated,
    /// success, rm_states)`; an environment whose episode had already ended is not stepped
    /// and reports reward 0 and terminated (reset it first).
    #[allow(clippy::type_complexity)]
    fn step<'py>(
        &mut self,
        py: Python<'py>,
        actions: PyReadonlyArray2<'py, f32>,
    ) -> PyResult<(
        Bound<'py, PyArray2<f32>>,
        Bound<'py, PyArray1<f64>>,
        Bound<'py, PyArray1<bool>>,
        Bound<'py, PyArray1<bool>>,
        Bound<'py, PyArray1<bool>>,
        Bound<'py, PyArray1<i64>>,
    )> {
        let n = self.slots.len();
        let a = self.act_dim();
        if actions.shape() != [n, a] {
            return Err(PyValueError::new_err(format!(
                "actions have shape {:?}, the batch takes ({n}, {a})",
                actions.shape()
            )));
        }
        let actions: Vec<f32> = actions.as_array().iter().copied().collect();
        let spec = &self.spec;
        let threads = self.threads.min(n);
        let slots = &mut self.slots;
        let results: Vec<Result<Option<StepOut>, String>> = py.allow_threads(|| {
            let per = n.div_ceil(threads);
            let step_chunk = |chunk: &mut [Slot], acts: &[f32]| {
                chunk
                    .iter_mut()
                    .zip(acts.chunks(a))
                    .map(|(slot, act)| {
                        if slot.done {
                            Ok(None)
                        } else {
                            slot.step(spec, act).map(Some)
                        }
                    })
                    .collect::<Vec<_>>()
            };
            // The calling thread steps the first chunk itself: one thread fewer to start.
            let mut chunks = slots.chunks_mut(per).zip(actions.chunks(per * a));
            let (first, first_acts) = chunks.next().expect("a batch holds at least 1 environment");
            std::thread::scope(|s| {
                let handles: Vec<_> = chunks
                    .map(|(chunk, acts)| s.spawn(move || step_chunk(chunk, acts)))
                    .collect();
                let mut results = step_chunk(first, first_acts);
                for h in handles {
                    match h.join() {
                        Ok(r) => results.extend(r),
                        Err(_) => results.push(Err("a stepping thread panicked".into())),
                    }
                }
                results
            })
        });
        let mut rewards = vec![0.0; n];
        let mut terminated = vec![false; n];
        let mut truncated = vec![false; n];
        let mut success = vec![false; n];
        let mut states = vec![0i64; n];
        for (i, r) in results.into_iter().enumerate() {
            states[i] = self.slots[i].env.rm_state() as i64;
            match r.map_err(|e| error(format!("environment {i}: {e}")))? {
                Some(out) => {
                    rewards[i] = out.reward;
                    terminated[i] = out.terminated;
                    truncated[i] = out.truncated;
                    success[i] = out.success;
                }
                None => {
                    terminated[i] = true;
                }
            }
        }
        Ok((
            self.observations(py),
            PyArray1::from_vec(py, rewards),
            PyArray1::from_vec(py, terminated),
            PyArray1::from_vec(py, truncated),
            PyArray1::from_vec(py, success),
            PyArray1::from_vec(py, states),
        ))
    }
}

impl ReacherBatch {
    fn observations<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f32>> {
        let d = self.slots[0].obs.len();
        let flat: Vec<f32> = self
            .slots
            .iter()
            .flat_map(|s| s.obs.iter().copied())
            .collect();
        PyArray1::from_vec(py, flat)
            .reshape([self.slots.len(), d])
            .expect("n × obs_dim elements")
    }
}
