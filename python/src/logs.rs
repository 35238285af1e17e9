//! MCAP rollout logs for Python: a log's run metadata and its episodes as NumPy arrays.

use crate::error;
use numpy::{PyArray1, PyArray2, PyArrayMethods, PyReadonlyArray2, PyUntypedArrayMethods};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};
use smirl::log::reader::LoggedEpisode;

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(read_log, m)?)?;
    m.add_function(wrap_pyfunction!(write_log, m)?)?;
    Ok(())
}

/// Rows of equal-length vectors as a 2-D array (`(rows, width)`; width 0 when no row has any).
fn matrix<'py, 'a, T: numpy::Element + Copy + 'a>(
    py: Python<'py>,
    rows: impl Iterator<Item = &'a [T]> + Clone,
    what: &str,
) -> PyResult<Bound<'py, PyArray2<T>>> {
    let n = rows.clone().count();
    let width = rows.clone().next().map_or(0, <[T]>::len);
    let mut flat = Vec::with_capacity(n * width);
    for (i, r) in rows.enumerate() {
        if r.len() != width {
            return Err(error(format!(
                "{what} of step {i} has {} values, the first step's {width}",
                r.len()
            )));
        }
        flat.extend_from_slice(r);
    }
    PyArray1::from_vec(py, flat)
        .reshape([n, width])
        .map_err(error)
}

fn episode<'py>(py: Python<'py>, ep: &LoggedEpisode) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    let s = &ep.start;
    d.set_item("episode", s.episode)?;
    d.set_item("seed", s.seed)?;
    d.set_item("phase", &s.phase)?;
    d.set_item("complete", ep.is_complete())?;
    d.set_item("cancel_step", (s.cancel_step > 0).then_some(s.cancel_step))?;
    d.set_item("balls", PyArray1::from_slice(py, &s.balls))?;
    d.set_item("start_qpos", PyArray1::from_slice(py, &s.qpos))?;
    d.set_item("start_qvel", PyArray1::from_slice(py, &s.qvel))?;
    d.set_item("start_obs", PyArray1::from_slice(py, &s.obs))?;
    d.set_item("start_labels", s.labels)?;
    d.set_item("start_rm_state", s.rm_state)?;
    let steps = &ep.steps;
    d.set_item(
        "actions",
        matrix(py, steps.iter().map(|m| &m.action[..]), "action")?,
    )?;
    d.set_item(
        "qpos",
        matrix(py, steps.iter().map(|m| &m.qpos[..]), "qpos")?,
    )?;
    d.set_item(
        "qvel",
        matrix(py, steps.iter().map(|m| &m.qvel[..]), "qvel")?,
    )?;
    d.set_item(
        "observations",
        matrix(py, steps.iter().map(|m| &m.obs[..]), "observation")?,
    )?;
    let col =
        |f: fn(&smirl::log::schema::StepMsg) -> f64| -> Vec<f64> { steps.iter().map(f).collect() };
    d.set_item("rewards", PyArray1::from_vec(py, col(|m| m.reward)))?;
    d.set_item("rm_rewards", PyArray1::from_vec(py, col(|m| m.rm_reward)))?;
    d.set_item(
        "labels",
        PyArray1::from_vec(py, steps.iter().map(|m| m.labels).collect::<Vec<u32>>()),
    )?;
    d.set_item(
        "label_text",
        PyList::new(py, steps.iter().map(|m| m.label_text.as_str()))?,
    )?;
    d.set_item(
        "rm_states",
        PyArray1::from_vec(py, steps.iter().map(|m| m.rm_state).collect::<Vec<i64>>()),
    )?;
    d.set_item(
        "terminated",
        PyArray1::from_vec(
            py,
            steps.iter().map(|m| m.terminated).collect::<Vec<bool>>(),
        ),
    )?;
    d.set_item(
        "truncated",
        PyArray1::from_vec(py, steps.iter().map(|m| m.truncated).collect::<Vec<bool>>()),
    )?;
    if let Some(e) = &ep.end {
        d.set_item("success", e.success)?;
        d.set_item("env_return", e.env_return)?;
        d.set_item("rm_return", e.rm_return)?;
    }
    Ok(d)
}

/// Reads a rollout log: `{"run": {...}, "metadata": {...}, "model_xml": str | None,
/// "episodes": [{...}, ...], "recovery": str | None}`. A file cut short is refused unless
/// `allow_partial`, which recovers its complete chunks as `reacher replay --allow-partial`
/// does.
#[pyfunction]
#[pyo3(signature = (path, allow_partial = false))]
fn read_log<'py>(
    py: Python<'py>,
    path: std::path::PathBuf,
    allow_partial: bool,
) -> PyResult<Bound<'py, PyDict>> {
    let log = py
        .allow_threads(|| smirl::log::reader::read_log(&path))
        .map_err(error)?;
    if let (Some(r), false) = (&log.recovery, allow_partial) {
        return Err(error(format!(
            "{}: {r}; pass allow_partial=True to read what was recovered",
            path.display()
        )));
    }
    let out = PyDict::new(py);
    let run = PyDict::new(py);
    let r = &log.run;
    run.set_item("schema_version", r.schema_version)?;
    run.set_item("env", &r.env)?;
    run.set_item("task", &r.task)?;
    run.set_item("seed", r.seed)?;
    run.set_item("vocabulary", &r.vocabulary)?;
    run.set_item("obs_dim", r.obs_dim)?;
    run.set_item("act_dim", r.act_dim)?;
    run.set_item("step_duration_ns", r.step_duration_ns)?;
    run.set_item("model_xml_name", &r.model_xml_name)?;
    run.set_item("git_commit", &r.git_commit)?;
    run.set_item("mujoco_version", &r.mujoco_version)?;
    run.set_item("config_json", r.config.to_string())?;
    run.set_item("reward_machine", r.reward_machine.as_deref())?;
    out.set_item("run", run)?;
    out.set_item("metadata", log.metadata.clone())?;
    out.set_item("model_xml", log.model_xml.as_deref())?;
    out.set_item("recovery", log.recovery.as_ref().map(|r| r.to_string()))?;
    let episodes = PyList::empty(py);
    for ep in &log.episodes {
        episodes.append(episode(py, ep)?)?;
    }
    out.set_item("episodes", episodes)?;
    Ok(out)
}

/// Most episodes one `write_log` call takes.
const MAX_WRITE_EPISODES: usize = 1_000_000;

/// Writes a rollout log of a task's episodes given as `(seed, actions)` pairs (`actions`:
/// `(steps, 2)` float32), re-simulating each in the Rust core so the log holds exactly what
/// the `reacher` binary would have logged for those seeds and actions (`reacher replay
/// --verify`, `learn-rm`, `render` and `foxglove` accept it). An episode's actions must end
/// where the episode does (the machine's goal or failure, or the time limit). Refuses an
/// existing `path`. Returns the number of steps written.
#[pyfunction]
#[pyo3(signature = (path, task, episodes, observations = true))]
fn write_log(
    path: std::path::PathBuf,
    task: &str,
    episodes: Vec<(u64, PyReadonlyArray2<'_, f32>)>,
    observations: bool,
) -> PyResult<u64> {
    use smirl::env::ContinuousEnv;
    use smirl::log::{LogOptions, RolloutLogger, RunHeader};
    if path.exists() {
        return Err(error(format!(
            "{}: already exists; not replaced",
            path.display()
        )));
    }
    if episodes.len() > MAX_WRITE_EPISODES {
        return Err(error(format!(
            "{} episodes; write_log takes at most {MAX_WRITE_EPISODES}",
            episodes.len()
        )));
    }
    let spec = crate::env::TaskSpec::new(task, 0.0, 0.99)?;
    let mut env = spec.env()?;
    let act_dim = env.act_dim();
    // Check every episode's actions before the file exists.
    for (k, (_, actions)) in episodes.iter().enumerate() {
        let shape = actions.shape();
        if shape.len() != 2 || shape[1] != act_dim || shape[0] > spec.config.max_steps {
            return Err(error(format!(
                "episode {k}: actions have shape {shape:?}; expected (steps, {act_dim}) with \
                 at most {} steps",
                spec.config.max_steps
            )));
        }
    }
    // Every episode is simulated once before the file exists, so a bad episode (actions
    // past its end, a simulation error) leaves no file behind.
    for (k, (seed, actions)) in episodes.iter().enumerate() {
        simulate(&mut env, *seed, &actions.as_array(), |_, _, _| Ok(()))
            .map_err(|e| error(format!("episode {k}: {e}")))?;
    }
    let config = serde_json::json!({ "env": spec.config, "source": "smirl.write_log (Python)" });
    let seed0 = episodes.first().map_or(0, |e| e.0);
    let mut header = RunHeader::of_task(spec.task.id(), spec.task.task(), seed0, config);
    header.reward_machine = Some(smirl::rm::format::write_rm(&spec.rm));
    let options = LogOptions {
        observations,
        ..LogOptions::default()
    };
    let mut logger = RolloutLogger::create(&path, header, options).map_err(error)?;
    let n_inner = env.inner().obs_dim();
    let mut steps = 0u64;
    for (k, (seed, actions)) in episodes.iter().enumerate() {
        let mut started = false;
        let success = simulate(&mut env, *seed, &actions.as_array(), |env, step, action| {
            if !started {
                started = true;
                let inner_obs = env.inner_obs().to_vec();
                logger
                    .begin_reacher_episode(
                        env.inner(),
                        *seed,
                        "python",
                        Some(env.rm_state()),
                        &inner_obs[..n_inner],
                    )
                    .map_err(|e| e.to_string())?;
            }
            let Some((p, obs)) = step else { return Ok(()) };
            let inner_step = smirl::env::EnvStep {
                reward: p.env_reward,
                ..p.step
            };
            steps += 1;
            logger
                .reacher_step(
                    env.inner(),
                    action,
                    &inner_step,
                    Some((p.rm_state, p.task_reward)),
                    &obs[..n_inner],
                )
                .map_err(|e| e.to_string())
        })
        .map_err(|e| error(format!("episode {k}: {e}")))?;
        logger.end_episode(success).map_err(error)?;
    }
    logger.finish().map_err(error)?;
    Ok(steps)
}

type TaskEnv = smirl::env::product::ProductEnv<
    smirl::env::reacher::ReacherDelivery,
    smirl::env::reacher_task::SubgoalPotential,
>;

/// Runs one episode from `seed` with `actions`, calling `visit` once after the reset (with
/// `None`) and after every step; the episode's actions must end where it does. Returns
/// whether the task was completed.
fn simulate(
    env: &mut TaskEnv,
    seed: u64,
    actions: &numpy::ndarray::ArrayView2<'_, f32>,
    mut visit: impl FnMut(
        &TaskEnv,
        Option<(smirl::env::product::ProductStep, &[f32])>,
        &[f32],
    ) -> Result<(), String>,
) -> Result<bool, String> {
    use smirl::env::ContinuousEnv;
    let mut obs = vec![0.0f32; env.obs_dim()];
    env.reset(seed, &mut obs);
    visit(env, None, &[])?;
    let n = actions.nrows();
    let mut success = false;
    for (t, row) in actions.rows().into_iter().enumerate() {
        let action: Vec<f32> = row.iter().copied().collect();
        let p = env
            .step_product(&action, &mut obs)
            .map_err(|e| format!("step {}: {e}", t + 1))?;
        visit(env, Some((p, &obs)), &action)?;
        success = p.success;
        if (p.step.terminated || p.step.truncated) && t + 1 < n {
            return Err(format!(
                "the episode ends at step {} but has {n} actions",
                t + 1
            ));
        }
    }
    Ok(success)
}
