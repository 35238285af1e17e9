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
use smirl::env::physics_scene::scene_model;
use smirl::env::product::ProductEnv;
use smirl::env::reacher::{ReacherConfig, ReacherDelivery};
use smirl::env::reacher_task::{task_env, Branch, EventBranch, ReacherTask, SubgoalPotential};
use smirl::env::ContinuousEnv;
use smirl::mujoco::ObjectKind;
use smirl::pipeline::render::region_looks;
use smirl::report::raster::Rgb;
use smirl::rm::{LabelSet, RewardMachine};
use std::sync::{mpsc, Arc};
use std::time::{Duration, Instant};

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<ReacherCore>()?;
    m.add_class::<ReacherBatch>()?;
    m.add_function(wrap_pyfunction!(task_names, m)?)?;
    Ok(())
}

/// Most environments one batch may hold.
const MAX_BATCH: usize = 4096;

/// Most threads one batch may step on.
const MAX_THREADS: usize = 256;

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

/// A labelled region for a picture: `(name, x, y, radius, (red, green, blue))`.
type Region = (String, f64, f64, f64, (u8, u8, u8));

/// What every environment of a task shares.
pub(crate) struct TaskSpec {
    pub(crate) task: ReacherTask,
    pub(crate) config: ReacherConfig,
    pub(crate) rm: RewardMachine,
    branches: Option<EventBranch>,
    shaping: f64,
    gamma: f64,
    /// Each region's colour in a picture, in label-bit order.
    region_colours: Vec<(u8, u8, u8)>,
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
        let branches = EventBranch::of(&rm, task.layout().events());
        // The scene as its file gives it: the environment's model may leave the regions' bodies
        // out (they do not touch the arm's physics).
        let layout = task.layout();
        let scene = scene_model(&layout).map_err(error)?;
        let byte = |c: f32| (c.clamp(0.0, 1.0) * 255.0).round() as u8;
        let region_colours = (region_looks(&scene, &layout).into_iter())
            .map(|(Rgb(red, green, blue), _)| (byte(red), byte(green), byte(blue)))
            .collect();
        Ok(TaskSpec {
            task,
            config,
            branches,
            rm,
            shaping,
            gamma,
            region_colours,
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
    /// The episode has entered the machine's event branch (tasks that have one).
    event_branch: bool,
    done: bool,
}

impl Slot {
    fn new(spec: &TaskSpec) -> PyResult<Slot> {
        let env = spec.env()?;
        let obs = vec![0.0; env.obs_dim()];
        Ok(Slot {
            env,
            obs,
            event_branch: false,
            done: true,
        })
    }

    fn reset(&mut self, spec: &TaskSpec, seed: u64) {
        self.env.reset(seed, &mut self.obs);
        self.event_branch = spec
            .branches
            .as_ref()
            .is_some_and(|b| b.in_event_branch(self.env.rm_state()));
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
            self.event_branch |= b.in_event_branch(p.rm_state);
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
            if self.event_branch {
                Branch::Event
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

    /// What a top-down picture needs: the arm's points `(shoulder, elbow, fingertip)` (the
    /// bodies the scene's `joint0` and `joint1` move, and its fingertip) and the regions as
    /// `(name, x, y, radius, rgb)`, each drawn in the colour `reacher render` gives it.
    fn scene(&self) -> PyResult<([[f64; 2]; 3], Vec<Region>)> {
        let inner = self.slot.env.inner();
        let model = inner.model();
        let body_of = |joint: &str| {
            let j = model.id(ObjectKind::Joint, joint).map_err(error)?;
            let [x, y, _] = inner.body_position(model.joint_body(j));
            Ok::<_, PyErr>([x, y])
        };
        let arm = [body_of("joint0")?, body_of("joint1")?, inner.fingertip()];
        let regions = (inner.layout().regions.iter())
            .zip(inner.positions())
            .zip(&self.spec.region_colours)
            .map(|((r, &[x, y]), &rgb)| (r.anchor.name().to_string(), x, y, r.radius, rgb))
            .collect();
        Ok((arm, regions))
    }
}

/// `n` environments of one task stepped together; `step` releases the GIL and spreads the
/// environments over `threads` threads (the result does not depend on the thread count: each
/// environment's episode depends on its own seed and actions only). The calling thread steps
/// the first chunk of environments; each other chunk has a worker thread of its own that lives
/// as long as the batch, so a step costs one hand-over per worker, not a thread start.
#[pyclass(module = "smirl._core", unsendable)]
pub struct ReacherBatch {
    spec: Arc<TaskSpec>,
    /// The environments in chunks of consecutive indices: chunk 0 is stepped by the calling
    /// thread, chunk `k ≥ 1` by worker `k − 1`, which holds it only while it steps it.
    chunks: Vec<Vec<Slot>>,
    workers: Vec<Worker>,
    n: usize,
}

/// A chunk's hand-over to a worker and back: the worker receives the chunk with its actions
/// and returns the chunk with each environment's step result.
type StepResults = Vec<Result<Option<StepOut>, String>>;
type Handover = (Vec<Slot>, Vec<f32>);
type Handback = (Vec<Slot>, StepResults);

/// How long a thread waiting for a hand-over checks for it before it sleeps. Waking a
/// sleeping thread costs about 100 µs on a virtual machine (`experiments/python/speed.py`: at
/// 16 environments two threads stepped no faster than one), more than stepping a chunk of 8
/// environments; a step loop hands over again within this time, so the waiting thread is
/// still awake, and a caller that pauses longer costs this much of a core per step at most.
const HANDOVER_SPIN: Duration = Duration::from_micros(200);

/// `rx.recv()`, checking without sleeping for [`HANDOVER_SPIN`] first.
fn recv_spinning<T>(rx: &mpsc::Receiver<T>) -> Result<T, mpsc::RecvError> {
    let start = Instant::now();
    loop {
        match rx.try_recv() {
            Ok(v) => return Ok(v),
            Err(mpsc::TryRecvError::Disconnected) => return Err(mpsc::RecvError),
            Err(mpsc::TryRecvError::Empty) if start.elapsed() > HANDOVER_SPIN => return rx.recv(),
            Err(mpsc::TryRecvError::Empty) => std::hint::spin_loop(),
        }
    }
}

/// A worker thread that steps the chunks it is handed until the batch drops its sender.
struct Worker {
    to_worker: Option<mpsc::Sender<Handover>>,
    from_worker: mpsc::Receiver<Handback>,
    thread: Option<std::thread::JoinHandle<()>>,
}

impl Worker {
    fn spawn(spec: Arc<TaskSpec>) -> PyResult<Worker> {
        let (to_worker, inbox) = mpsc::channel::<Handover>();
        let (outbox, from_worker) = mpsc::channel::<Handback>();
        let thread = std::thread::Builder::new()
            .name("smirl-batch".into())
            .spawn(move || {
                while let Ok((mut chunk, actions)) = recv_spinning(&inbox) {
                    let results = step_chunk(&spec, &mut chunk, &actions);
                    if outbox.send((chunk, results)).is_err() {
                        break;
                    }
                }
            })
            .map_err(|e| error(format!("cannot start a stepping thread: {e}")))?;
        Ok(Worker {
            to_worker: Some(to_worker),
            from_worker,
            thread: Some(thread),
        })
    }
}

impl Drop for Worker {
    fn drop(&mut self) {
        // Closing the channel ends the worker's loop.
        self.to_worker = None;
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

/// Steps every environment of `chunk` whose episode is running with its row of `actions`.
/// A panic inside an environment becomes that environment's error.
fn step_chunk(spec: &TaskSpec, chunk: &mut [Slot], actions: &[f32]) -> StepResults {
    let a = actions.len() / chunk.len().max(1);
    chunk
        .iter_mut()
        .zip(actions.chunks(a.max(1)))
        .map(|(slot, act)| {
            if slot.done {
                return Ok(None);
            }
            std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| slot.step(spec, act)))
                .unwrap_or_else(|_| Err("the environment panicked while stepping".into()))
                .map(Some)
        })
        .collect()
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
        if threads == 0 || threads > MAX_THREADS {
            return Err(PyValueError::new_err(format!(
                "threads must be in 1..={MAX_THREADS}, got {threads}"
            )));
        }
        let spec = Arc::new(TaskSpec::new(task, shaping, gamma)?);
        let mut slots = (0..n)
            .map(|_| Slot::new(&spec))
            .collect::<PyResult<Vec<_>>>()?;
        let per = n.div_ceil(threads.min(n));
        let mut chunks = Vec::new();
        while !slots.is_empty() {
            let rest = slots.split_off(per.min(slots.len()));
            chunks.push(std::mem::replace(&mut slots, rest));
        }
        let workers = (1..chunks.len())
            .map(|_| Worker::spawn(Arc::clone(&spec)))
            .collect::<PyResult<_>>()?;
        Ok(ReacherBatch {
            spec,
            chunks,
            workers,
            n,
        })
    }

    #[getter]
    fn n(&self) -> usize {
        self.n
    }
    #[getter]
    fn obs_dim(&self) -> usize {
        self.chunks[0][0].env.obs_dim()
    }
    #[getter]
    fn act_dim(&self) -> usize {
        self.chunks[0][0].env.act_dim()
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
        self.usable()?;
        if indices.len() != seeds.len() {
            return Err(PyValueError::new_err(format!(
                "{} indices but {} seeds",
                indices.len(),
                seeds.len()
            )));
        }
        let n = self.n;
        let per = self.chunks[0].len();
        for (&i, &s) in indices.iter().zip(&seeds) {
            if i >= n {
                return Err(PyValueError::new_err(format!(
                    "index {i} is not below the batch size {n}"
                )));
            }
            let seed = seed_of(s)?;
            self.chunks[i / per][i % per].reset(&self.spec, seed);
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
        self.usable()?;
        let n = self.n;
        let a = self.act_dim();
        if actions.shape() != [n, a] {
            return Err(PyValueError::new_err(format!(
                "actions have shape {:?}, the batch takes ({n}, {a})",
                actions.shape()
            )));
        }
        let actions: Vec<f32> = actions.as_array().iter().copied().collect();
        let results = py.allow_threads(|| self.step_all(&actions))?;
        let mut rewards = vec![0.0; n];
        let mut terminated = vec![false; n];
        let mut truncated = vec![false; n];
        let mut success = vec![false; n];
        let mut states = vec![0i64; n];
        let slots = self.chunks.iter().flatten();
        for (i, (r, slot)) in results.into_iter().zip(slots).enumerate() {
            states[i] = slot.env.rm_state() as i64;
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
    /// Hands chunks 1.. to their workers, steps chunk 0 here, and takes the chunks back, in
    /// index order. A chunk a worker does not return (its thread died) leaves the batch
    /// unusable: every later call says so.
    fn step_all(&mut self, actions: &[f32]) -> PyResult<StepResults> {
        let a = actions.len() / self.n;
        let per = self.chunks[0].len();
        let mut handed = 0;
        for (k, worker) in self.workers.iter().enumerate() {
            let chunk = std::mem::take(&mut self.chunks[k + 1]);
            let from = (k + 1) * per * a;
            let rows = actions[from..from + chunk.len() * a].to_vec();
            let sent = worker.to_worker.as_ref().map(|tx| tx.send((chunk, rows)));
            if !matches!(sent, Some(Ok(()))) {
                break;
            }
            handed += 1;
        }
        let mut results = step_chunk(&self.spec, &mut self.chunks[0], &actions[..per * a]);
        let mut lost = handed < self.workers.len();
        for (k, worker) in self.workers.iter().take(handed).enumerate() {
            match recv_spinning(&worker.from_worker) {
                Ok((chunk, r)) => {
                    self.chunks[k + 1] = chunk;
                    results.extend(r);
                }
                Err(_) => lost = true,
            }
        }
        if lost {
            return Err(error(
                "a stepping thread of this batch died; the batch is unusable, make a new one",
            ));
        }
        Ok(results)
    }

    /// Refuses to work on a batch that lost a chunk.
    fn usable(&self) -> PyResult<()> {
        if self.chunks.iter().map(Vec::len).sum::<usize>() == self.n {
            Ok(())
        } else {
            Err(error(
                "a stepping thread of this batch died; the batch is unusable, make a new one",
            ))
        }
    }

    fn observations<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f32>> {
        let d = self.chunks[0][0].obs.len();
        let flat: Vec<f32> = self
            .chunks
            .iter()
            .flatten()
            .flat_map(|s| s.obs.iter().copied())
            .collect();
        PyArray1::from_vec(py, flat)
            .reshape([self.n, d])
            .expect("n × obs_dim elements")
    }
}
