//! Reward machines for Python: read, write, DOT, stepping, equivalence, and LRM learning.
//!
//! Label sets cross the boundary as strings of proposition letters (`"rc"`: red and cancel
//! hold), the form the machine files and the logs' text use.

use crate::error;
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use smirl::rm::lrm::{self, LabelTrace, LrmConfig};
use smirl::rm::{LabelSet, RewardMachine, Vocabulary};

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyRewardMachine>()?;
    m.add_function(wrap_pyfunction!(learn_rm, m)?)?;
    Ok(())
}

/// Most traces, and most steps in all, one `learn_rm` call takes.
const MAX_TRACES: usize = 100_000;
const MAX_TRACE_STEPS: usize = 10_000_000;

fn labels(vocab: &Vocabulary, text: &str) -> PyResult<LabelSet> {
    vocab.parse_labels(text).map_err(|e| {
        PyValueError::new_err(format!(
            "label set {text:?}: {e} (vocabulary \"{}\")",
            vocab.props().iter().collect::<String>()
        ))
    })
}

/// A reward machine (a finite automaton over label sets that pays a reward per transition).
#[pyclass(name = "RewardMachine", module = "smirl._core", frozen)]
#[derive(Clone)]
pub struct PyRewardMachine {
    pub rm: RewardMachine,
}

#[pymethods]
impl PyRewardMachine {
    /// Parses the text of a machine file; `source` names it in error messages.
    #[staticmethod]
    #[pyo3(signature = (text, source = "<string>"))]
    fn from_text(text: &str, source: &str) -> PyResult<Self> {
        smirl::rm::format::parse_rm(text, source)
            .map(|rm| PyRewardMachine { rm })
            .map_err(error)
    }

    /// Reads a machine file (size-limited, as the command-line tools read it).
    #[staticmethod]
    fn read(path: std::path::PathBuf) -> PyResult<Self> {
        smirl::rm::format::read_rm(&path)
            .map(|rm| PyRewardMachine { rm })
            .map_err(error)
    }

    /// A shipped machine: `reacher_<task>` or `office_t<k>`.
    #[staticmethod]
    fn shipped(name: &str) -> PyResult<Self> {
        smirl::rm::perfect::load(name)
            .map(|rm| PyRewardMachine { rm })
            .map_err(error)
    }

    /// The machine in the text format `from_text` reads.
    fn to_text(&self) -> String {
        smirl::rm::format::write_rm(&self.rm)
    }

    /// Writes the machine file (atomically; never over an existing file).
    fn write(&self, path: std::path::PathBuf) -> PyResult<()> {
        if path.exists() {
            return Err(error(format!(
                "{}: already exists; not replaced",
                path.display()
            )));
        }
        smirl::rm::format::save_rm(&path, &self.rm)
            .map_err(|e| error(format!("{}: cannot write: {e}", path.display())))
    }

    /// Graphviz DOT text.
    fn to_dot(&self) -> String {
        smirl::rm::dot::to_dot(&self.rm)
    }

    #[getter]
    fn n_states(&self) -> usize {
        self.rm.n_states()
    }
    #[getter]
    fn initial(&self) -> usize {
        self.rm.initial()
    }
    #[getter]
    fn vocabulary(&self) -> String {
        self.rm.vocab().props().iter().collect()
    }
    #[getter]
    fn terminal_states(&self) -> Vec<usize> {
        self.rm.terminal_states()
    }
    #[getter]
    fn failure_states(&self) -> Vec<usize> {
        self.rm.failure_states()
    }

    /// `(next state, reward)` from state `u` on the label set `labels`.
    fn step(&self, u: usize, labels: &str) -> PyResult<(usize, f64)> {
        if u >= self.rm.n_states() {
            return Err(PyValueError::new_err(format!(
                "state {u} is not a state of this {}-state machine",
                self.rm.n_states()
            )));
        }
        Ok(self.rm.step(u, self::labels(self.rm.vocab(), labels)?))
    }

    /// `[(state, reward), …]` along a label trace from the initial state.
    fn run(&self, trace: Vec<String>) -> PyResult<Vec<(usize, f64)>> {
        let trace = trace
            .iter()
            .map(|t| labels(self.rm.vocab(), t))
            .collect::<PyResult<Vec<_>>>()?;
        Ok(self.rm.run(&trace))
    }

    /// Whether both machines pay the same rewards on every label sequence (over `alphabet`,
    /// a list of label sets, when given).
    #[pyo3(signature = (other, alphabet = None))]
    fn equivalent(&self, other: &PyRewardMachine, alphabet: Option<Vec<String>>) -> PyResult<bool> {
        let alphabet = alphabet
            .map(|a| {
                a.iter()
                    .map(|t| labels(self.rm.vocab(), t))
                    .collect::<PyResult<Vec<_>>>()
            })
            .transpose()?;
        smirl::rm::equiv::equivalent(&self.rm, &other.rm, alphabet.as_deref()).map_err(error)
    }

    fn __repr__(&self) -> String {
        format!(
            "RewardMachine(states={}, vocabulary=\"{}\")",
            self.rm.n_states(),
            self.vocabulary()
        )
    }
}

/// Learns a reward machine from label traces with LRM's Tabu search.
///
/// `traces`: label traces, one label-set string per step; `rewards`: optionally, each
/// trace's per-step rewards; `events`: the propositions the domain declares exogenous
/// events; `rules`: `"smirl"` (SMIRL's learner, as `reacher learn-rm` and SMIRL's jobs run it:
/// tree guards and the event rules of docs/method.md) or `"paper"` (the paper's eq. 1, as
/// `smirl-paper` runs it). Returns `(machine, stats)`.
#[pyfunction]
#[pyo3(signature = (traces, vocabulary, rewards = None, events = "", max_states = 10,
                    max_steps = 100, seed = 0, starts = 4, merge = true, threads = 1,
                    rules = "smirl"))]
#[allow(clippy::too_many_arguments)]
fn learn_rm(
    py: Python<'_>,
    traces: Vec<Vec<String>>,
    vocabulary: &str,
    rewards: Option<Vec<Vec<f64>>>,
    events: &str,
    max_states: usize,
    max_steps: usize,
    seed: u64,
    starts: usize,
    merge: bool,
    threads: usize,
    rules: &str,
) -> PyResult<(
    PyRewardMachine,
    std::collections::HashMap<&'static str, f64>,
)> {
    let vocab = Vocabulary::parse(vocabulary).map_err(|e| PyValueError::new_err(e.to_string()))?;
    if traces.len() > MAX_TRACES {
        return Err(PyValueError::new_err(format!(
            "{} traces; learn_rm takes at most {MAX_TRACES}",
            traces.len()
        )));
    }
    let steps: usize = traces.iter().map(Vec::len).sum();
    if steps > MAX_TRACE_STEPS {
        return Err(PyValueError::new_err(format!(
            "{steps} steps in all; learn_rm takes at most {MAX_TRACE_STEPS}"
        )));
    }
    if let Some(r) = &rewards {
        if r.len() != traces.len() {
            return Err(PyValueError::new_err(format!(
                "{} traces but {} reward lists",
                traces.len(),
                r.len()
            )));
        }
    }
    if starts == 0 || starts > 64 || threads == 0 || threads > 256 {
        return Err(PyValueError::new_err(
            "starts must be in 1..=64 and threads in 1..=256",
        ));
    }
    if max_states == 0 || max_states > lrm::MAX_STATES || max_steps > lrm::MAX_SEARCH_STEPS {
        return Err(PyValueError::new_err(format!(
            "max_states must be in 1..={} and max_steps at most {}",
            lrm::MAX_STATES,
            lrm::MAX_SEARCH_STEPS
        )));
    }
    let mut label_traces = Vec::with_capacity(traces.len());
    for (k, t) in traces.iter().enumerate() {
        let labels = t
            .iter()
            .map(|l| labels(&vocab, l))
            .collect::<PyResult<Vec<_>>>()
            .map_err(|e| PyValueError::new_err(format!("trace {k}: {e}")))?;
        label_traces.push(LabelTrace {
            labels,
            rewards: rewards.as_ref().map(|r| r[k].clone()),
        });
    }
    let smirl_rules = match rules {
        "smirl" => true,
        "paper" => false,
        other => {
            return Err(PyValueError::new_err(format!(
                "rules must be \"smirl\" or \"paper\", got \"{other}\""
            )))
        }
    };
    let cfg = LrmConfig {
        max_states,
        max_steps,
        seed,
        starts,
        merge,
        threads,
        events: labels(&vocab, events)?,
        ..LrmConfig::default()
    };
    let cfg = if smirl_rules {
        // SMIRL's learner keeps the machine in place while a label set holds, as the CLI's.
        smirl::pipeline::reacher_irl::smirl::with_event_rules(LrmConfig {
            stutter_invariant: true,
            ..cfg
        })
    } else {
        cfg
    };
    let learned = py
        .allow_threads(|| lrm::learn_rm(&vocab, &label_traces, &cfg))
        .map_err(error)?;
    let stats = [
        ("cost", learned.cost),
        ("search_states", learned.stats.search_states as f64),
        ("steps", learned.stats.steps as f64),
        ("distinct_traces", learned.stats.distinct_traces as f64),
        ("elapsed_secs", learned.stats.elapsed_secs),
    ]
    .into_iter()
    .collect();
    Ok((PyRewardMachine { rm: learned.rm }, stats))
}
