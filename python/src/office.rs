//! Office gridworld tasks for Python: the world of a task's map with its reward machine.
//!
//! The agent moves on the grid (actions 0–3: up, right, down, left, as `OfficeWorld::step`
//! numbers them); the machine reads the label of the cell entered and pays its reward. An
//! episode terminates when the machine reaches its goal or a failure state and is truncated
//! after `max_steps` steps.

use crate::error;
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use smirl::env::office::task::OfficeTask;

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<OfficeCore>()?;
    m.add_function(wrap_pyfunction!(office_task_names, m)?)?;
    Ok(())
}

/// Longest episode an Office environment may ask for.
const MAX_OFFICE_STEPS: usize = 100_000;

/// Names of the shipped Office tasks.
#[pyfunction]
fn office_task_names() -> Vec<&'static str> {
    smirl::env::office::task::SHIPPED.to_vec()
}

/// One Office task: a shipped name (`"0"`–`"4"`) or a task file's path.
#[pyclass(module = "smirl._core", frozen)]
pub struct OfficeCore {
    task: OfficeTask,
    max_steps: usize,
    state: std::sync::Mutex<(usize, usize, usize)>,
}

#[pymethods]
impl OfficeCore {
    #[new]
    #[pyo3(signature = (task, max_steps = 100))]
    fn new(task: &str, max_steps: usize) -> PyResult<Self> {
        if max_steps == 0 || max_steps > MAX_OFFICE_STEPS {
            return Err(PyValueError::new_err(format!(
                "max_steps must be in 1..={MAX_OFFICE_STEPS}, got {max_steps}"
            )));
        }
        let task = OfficeTask::from_argument(task).map_err(error)?;
        let start = (task.world().start(), task.rm().initial(), 0);
        Ok(OfficeCore {
            task,
            max_steps,
            state: std::sync::Mutex::new(start),
        })
    }

    #[getter]
    fn name(&self) -> String {
        self.task.name().to_string()
    }
    #[getter]
    fn title(&self) -> String {
        self.task.title()
    }
    #[getter]
    fn width(&self) -> usize {
        self.task.world().width()
    }
    #[getter]
    fn height(&self) -> usize {
        self.task.world().height()
    }
    #[getter]
    fn n_cells(&self) -> usize {
        self.task.world().n_cells()
    }
    #[getter]
    fn n_rm_states(&self) -> usize {
        self.task.rm().n_states()
    }
    #[getter]
    fn max_steps(&self) -> usize {
        self.max_steps
    }
    #[getter]
    fn reward_machine(&self) -> String {
        smirl::rm::format::write_rm(self.task.rm())
    }
    /// The map file's text (`docs/office.md` describes the format).
    #[getter]
    fn map_text(&self) -> String {
        smirl::env::office::map::write_map(self.task.map())
    }

    /// Back to the start cell and the machine's initial state: `(cell, rm_state)`.
    fn reset(&self) -> (usize, usize) {
        let mut s = self.state.lock().unwrap_or_else(|p| p.into_inner());
        *s = (self.task.world().start(), self.task.rm().initial(), 0);
        (s.0, s.1)
    }

    /// One move: `((cell, rm_state), reward, terminated, truncated, info)`.
    #[allow(clippy::type_complexity)]
    fn step<'py>(
        &self,
        py: Python<'py>,
        action: i64,
    ) -> PyResult<((usize, usize), f64, bool, bool, Bound<'py, PyDict>)> {
        if !(0..4).contains(&action) {
            return Err(PyValueError::new_err(format!(
                "action must be 0, 1, 2 or 3, got {action}"
            )));
        }
        let mut s = self.state.lock().unwrap_or_else(|p| p.into_inner());
        let (cell, u, t) = *s;
        let rm = self.task.rm();
        if rm.is_absorbing(u) || t >= self.max_steps {
            return Err(error("step after the episode ended: call reset first"));
        }
        let world = self.task.world();
        let next = world.step(cell, action as usize);
        let labels = world.label(next);
        let (v, reward) = rm.step(u, labels);
        *s = (next, v, t + 1);
        let terminated = rm.is_absorbing(v);
        let truncated = !terminated && t + 1 >= self.max_steps;
        let info = PyDict::new(py);
        info.set_item("labels", rm.vocab().format_labels(labels))?;
        info.set_item("xy", world.xy(next))?;
        info.set_item("success", rm.is_terminal(v) && !rm.is_failure(v))?;
        info.set_item("failure", rm.is_failure(v))?;
        Ok(((next, v), reward, terminated, truncated, info))
    }
}
