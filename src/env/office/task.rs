//! The Office task file: a map and the task's reward machine, by path, in TOML.
//!
//! ```toml
//! name = "3"                          # optional: how outputs name the task (default: the file stem)
//! description = "coffee and mail, then office"   # optional: plot titles
//! map = "paper.map"                   # the map file (see `map`), relative to this file
//! machine = "../rm/office_t3.txt"     # the task's reward machine (RM text format), relative to this file
//! ```
//!
//! The machine is the task's ground truth: the expert acts optimally on it and evaluation
//! scores with it; no learner reads it. Its propositions are letters of the map; it is read
//! over the map's letters (in the map's bit order), ignoring those it does not name. Some
//! path from the start must complete it without entering a failure state.
//!
//! The paper's tasks 0–4 are shipped (`assets/office/task<N>.toml` over
//! `assets/office/paper.map` and `assets/rm/office_t<N>.txt`), built into the binaries and
//! found by their names `0`–`4` ([`OfficeTask::shipped`]).
//!
//! Errors name the file, the line and the key or limit. **Limits**: the map's (see [`super::map`]),
//! at most [`MAX_TASK_STATES`] machine states, shortest trips to the goal of at most
//! [`MAX_TRIP_STEPS`] steps from anywhere the agent can be, names of at most [`MAX_NAME_CHARS`] characters
//! from `A–Z a–z 0–9 _ . -`, descriptions of at most [`MAX_DESCRIPTION_CHARS`] characters;
//! files of at most [`crate::config_text::MAX_TEXT_FILE_BYTES`].

use super::map::{parse_map, MapError, OfficeMap};
use super::{OfficeWorld, N_ACTIONS};
use crate::rm::format::{parse_rm, RmFileError};
use crate::rm::transform::over_vocabulary;
use crate::rm::RewardMachine;
use std::collections::VecDeque;
use std::io;
use std::path::{Component, Path, PathBuf};

/// Most states of a task's machine (demonstrations record its state in a byte).
pub const MAX_TASK_STATES: usize = 256;
/// Longest shortest path to the task's goal, from anywhere the agent can be: the expert's
/// discount (γ = 0.9) and tolerance tell a shortest path from a longer one up to about this
/// length.
pub const MAX_TRIP_STEPS: usize = 150;
/// Longest task name.
pub const MAX_NAME_CHARS: usize = 64;
/// Longest task description.
pub const MAX_DESCRIPTION_CHARS: usize = 200;

/// Names of the shipped tasks (the paper's tasks 0–4).
pub const SHIPPED: [&str; 5] = ["0", "1", "2", "3", "4"];

/// The shipped files, by their path in the source tree.
const SHIPPED_FILES: [(&str, &str); 11] = [
    (
        "assets/office/paper.map",
        include_str!("../../../assets/office/paper.map"),
    ),
    (
        "assets/office/task0.toml",
        include_str!("../../../assets/office/task0.toml"),
    ),
    (
        "assets/office/task1.toml",
        include_str!("../../../assets/office/task1.toml"),
    ),
    (
        "assets/office/task2.toml",
        include_str!("../../../assets/office/task2.toml"),
    ),
    (
        "assets/office/task3.toml",
        include_str!("../../../assets/office/task3.toml"),
    ),
    (
        "assets/office/task4.toml",
        include_str!("../../../assets/office/task4.toml"),
    ),
    (
        "assets/rm/office_t0.txt",
        include_str!("../../../assets/rm/office_t0.txt"),
    ),
    (
        "assets/rm/office_t1.txt",
        include_str!("../../../assets/rm/office_t1.txt"),
    ),
    (
        "assets/rm/office_t2.txt",
        include_str!("../../../assets/rm/office_t2.txt"),
    ),
    (
        "assets/rm/office_t3.txt",
        include_str!("../../../assets/rm/office_t3.txt"),
    ),
    (
        "assets/rm/office_t4.txt",
        include_str!("../../../assets/rm/office_t4.txt"),
    ),
];

/// The path of the paper's map among the shipped files.
const PAPER_MAP: &str = "assets/office/paper.map";

/// Why a task could not be loaded.
#[derive(Debug, thiserror::Error)]
pub enum OfficeTaskError {
    #[error("{file}: cannot read: {error}")]
    Io { file: String, error: io::Error },
    /// Not a shipped name and no such file.
    #[error("unknown Office task {name} (the shipped tasks are {}; a task file is given by its path)", SHIPPED.join(", "))]
    Unknown { name: String },
    /// The TOML does not parse, or has an unknown or missing key (the message names the line
    /// when there is one).
    #[error("{file}: {message}")]
    Toml { file: String, message: String },
    /// A key's value is not acceptable.
    #[error("{file}:{line}: `{key}`: {problem}")]
    Key {
        file: String,
        line: usize,
        key: &'static str,
        problem: String,
    },
    /// A file the task names cannot be read.
    #[error("{file}:{line}: `{key}` = {path:?}: cannot read {resolved}: {error}")]
    Referenced {
        file: String,
        line: usize,
        key: &'static str,
        path: String,
        resolved: String,
        error: io::Error,
    },
    #[error(transparent)]
    Map(#[from] MapError),
    #[error(transparent)]
    Machine(#[from] RmFileError),
    /// A proposition of the machine is no letter of the map.
    #[error("{machine}{}: proposition '{prop}' of the machine is not a letter of the map {map} (its letters are \"{letters}\")", line.map(|l| format!(":{l}")).unwrap_or_default())]
    NotOnMap {
        machine: String,
        line: Option<usize>,
        prop: char,
        map: String,
        letters: String,
    },
    #[error("{machine}: the machine has {states} states, more than the limit of {MAX_TASK_STATES} for an Office task")]
    TooManyStates { machine: String, states: usize },
    /// No path from the start completes the task.
    #[error("{file}: no path from the start cell ({x}, {y}) of {map} reaches a goal state of {machine} without entering a failure state")]
    Unreachable {
        file: String,
        map: String,
        machine: String,
        x: usize,
        y: usize,
    },
    /// A trip is too long for the expert to tell shortest paths apart.
    #[error("{file}: from some cell of {map} a shortest path to a goal state of {machine} takes {steps} steps, more than the limit of {MAX_TRIP_STEPS}")]
    TripTooLong {
        file: String,
        map: String,
        machine: String,
        steps: usize,
    },
}

/// A task: the world of its map and its reward machine.
#[derive(Clone, Debug)]
pub struct OfficeTask {
    name: String,
    description: String,
    file: String,
    map_file: String,
    machine_file: String,
    map: OfficeMap,
    world: OfficeWorld,
    rm: RewardMachine,
}

/// The TOML of a task file.
#[derive(serde::Deserialize)]
#[serde(deny_unknown_fields)]
struct TaskToml {
    name: Option<String>,
    #[serde(default)]
    description: String,
    map: String,
    machine: String,
}

impl OfficeTask {
    /// A shipped task by name (`0`–`4`).
    pub fn shipped(name: &str) -> Result<OfficeTask, OfficeTaskError> {
        if !SHIPPED.contains(&name) {
            return Err(OfficeTaskError::Unknown {
                name: name.to_string(),
            });
        }
        load_with(
            Path::new(&format!("assets/office/task{name}.toml")),
            &read_shipped,
        )
    }

    /// The task of a task file.
    pub fn load(path: &Path) -> Result<OfficeTask, OfficeTaskError> {
        load_with(path, &|p: &Path| crate::config_text::read_text_file(p))
    }

    /// A shipped name, else the path of a task file (a path that names no file and looks like
    /// a name is an unknown task).
    pub fn from_argument(task: &str) -> Result<OfficeTask, OfficeTaskError> {
        if SHIPPED.contains(&task) {
            return OfficeTask::shipped(task);
        }
        let path = Path::new(task);
        if !path.exists() && path.extension().is_none() && path.components().count() <= 1 {
            return Err(OfficeTaskError::Unknown {
                name: task.to_string(),
            });
        }
        OfficeTask::load(path)
    }

    /// How outputs name the task.
    pub fn name(&self) -> &str {
        &self.name
    }

    pub fn description(&self) -> &str {
        &self.description
    }

    /// `Office task <name>: <description>` (without the colon when there is no description).
    pub fn title(&self) -> String {
        if self.description.is_empty() {
            format!("Office task {}", self.name)
        } else {
            format!("Office task {}: {}", self.name, self.description)
        }
    }

    /// The task file, as messages name it.
    pub fn file(&self) -> &str {
        &self.file
    }

    /// The map file, as messages name it.
    pub fn map_file(&self) -> &str {
        &self.map_file
    }

    /// The machine file, as messages name it.
    pub fn machine_file(&self) -> &str {
        &self.machine_file
    }

    pub fn map(&self) -> &OfficeMap {
        &self.map
    }

    pub fn world(&self) -> &OfficeWorld {
        &self.world
    }

    /// The task's (perfect) reward machine, over the map's letters.
    pub fn rm(&self) -> &RewardMachine {
        &self.rm
    }
}

/// The paper's map, parsed from the shipped file.
pub(super) fn paper_map() -> OfficeMap {
    parse_map(shipped_text(PAPER_MAP).unwrap_or_default(), PAPER_MAP)
        .expect("the shipped paper map parses (a test reads it)")
}

fn shipped_text(path: &str) -> Option<&'static str> {
    SHIPPED_FILES
        .iter()
        .find(|(p, _)| *p == path)
        .map(|(_, text)| *text)
}

/// Reads a shipped file by its (lexically normalised) path in the source tree.
fn read_shipped(path: &Path) -> io::Result<String> {
    let key = normalise(path).to_string_lossy().replace('\\', "/");
    shipped_text(&key)
        .map(str::to_string)
        .ok_or_else(|| io::Error::new(io::ErrorKind::NotFound, "no shipped file of that name"))
}

/// `a/b/../c` → `a/c`, `./a` → `a` (without reading the file system).
fn normalise(path: &Path) -> PathBuf {
    let mut out = PathBuf::new();
    for c in path.components() {
        match c {
            Component::CurDir => {}
            Component::ParentDir if out.file_name().is_some() => {
                out.pop();
            }
            other => out.push(other.as_os_str()),
        }
    }
    out
}

/// Loads a task, reading its files with `read`.
fn load_with(
    path: &Path,
    read: &dyn Fn(&Path) -> io::Result<String>,
) -> Result<OfficeTask, OfficeTaskError> {
    let file = path.display().to_string();
    let text = read(path).map_err(|error| OfficeTaskError::Io {
        file: file.clone(),
        error,
    })?;
    let toml: TaskToml = toml::from_str(&text).map_err(|e| OfficeTaskError::Toml {
        file: file.clone(),
        message: crate::config_text::toml_error_message(&text, &e),
    })?;
    let line_of = |key: &str| crate::config_text::key_line(&text, key).unwrap_or(1);
    let key_error = |key: &'static str, problem: String| OfficeTaskError::Key {
        file: file.clone(),
        line: line_of(key),
        key,
        problem,
    };

    let name = match toml.name {
        Some(name) => name,
        None => path
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_default(),
    };
    if name.is_empty()
        || name.chars().count() > MAX_NAME_CHARS
        || !name
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || matches!(c, '_' | '.' | '-'))
    {
        return Err(key_error(
            "name",
            format!(
                "{name:?} is not a task name (1 to {MAX_NAME_CHARS} characters of A-Z a-z 0-9 _ . -; without `name`, the file's stem is used)"
            ),
        ));
    }
    if toml.description.chars().count() > MAX_DESCRIPTION_CHARS
        || toml.description.chars().any(char::is_control)
    {
        return Err(key_error(
            "description",
            format!("one line of at most {MAX_DESCRIPTION_CHARS} characters"),
        ));
    }

    let dir = path.parent().unwrap_or(Path::new(""));
    let referenced = |key: &'static str, rel: &str| -> Result<(String, String), OfficeTaskError> {
        if rel.is_empty() {
            return Err(key_error(key, "an empty path".into()));
        }
        let resolved = dir.join(rel);
        let shown = resolved.display().to_string();
        match read(&resolved) {
            Ok(text) => Ok((shown, text)),
            Err(error) => Err(OfficeTaskError::Referenced {
                file: file.clone(),
                line: line_of(key),
                key,
                path: rel.to_string(),
                resolved: shown,
                error,
            }),
        }
    };
    let (map_file, map_text) = referenced("map", &toml.map)?;
    let (machine_file, machine_text) = referenced("machine", &toml.machine)?;
    let map = parse_map(&map_text, &map_file)?;
    let machine = parse_rm(&machine_text, &machine_file)?;
    if machine.n_states() > MAX_TASK_STATES {
        return Err(OfficeTaskError::TooManyStates {
            machine: machine_file,
            states: machine.n_states(),
        });
    }
    let rm = over_vocabulary(&machine, map.vocab()).map_err(|prop| OfficeTaskError::NotOnMap {
        line: machine_text
            .lines()
            .position(|l| l.trim_start().starts_with("vocabulary"))
            .map(|k| k + 1),
        machine: machine_file.clone(),
        prop,
        map: map_file.clone(),
        letters: map.vocab().to_string(),
    })?;
    let world = OfficeWorld::from_map(&map);
    match trip_lengths(&world, &rm) {
        (None, _) => {
            let (x, y) = map.start();
            return Err(OfficeTaskError::Unreachable {
                file,
                map: map_file,
                machine: machine_file,
                x,
                y,
            });
        }
        (_, Some(steps)) if steps > MAX_TRIP_STEPS => {
            return Err(OfficeTaskError::TripTooLong {
                file,
                map: map_file,
                machine: machine_file,
                steps,
            });
        }
        _ => {}
    }
    Ok(OfficeTask {
        name,
        description: toml.description,
        file,
        map_file,
        machine_file,
        map,
        world,
        rm,
    })
}

/// The shortest number of steps to a goal state, without entering a failure state, from
/// every (cell, machine state) that can be reached from the start (`None`: no goal from
/// there): the longest and the start's own.
fn trip_lengths(world: &OfficeWorld, rm: &RewardMachine) -> (Option<usize>, Option<usize>) {
    let n_cells = world.n_cells();
    let n = n_cells * rm.n_states();
    let live = |u: usize| !rm.is_terminal(u) && !rm.is_failure(u);
    let start = rm.initial() * n_cells + world.start();
    // Forward: the live states reachable from the start; their edges, reversed.
    let mut reachable = vec![false; n];
    let mut predecessors: Vec<Vec<u32>> = vec![Vec::new(); n];
    let mut dist: Vec<Option<usize>> = vec![None; n];
    let mut queue = VecDeque::from([start]);
    reachable[start] = true;
    let mut goal_adjacent = VecDeque::new();
    while let Some(s) = queue.pop_front() {
        let (u, cell) = (s / n_cells, s % n_cells);
        for action in 0..N_ACTIONS {
            let next = world.step(cell, action);
            let v = rm.next_state(u, world.label(next));
            if rm.is_terminal(v) {
                if dist[s].is_none() {
                    dist[s] = Some(1);
                    goal_adjacent.push_back(s);
                }
                continue;
            }
            if !live(v) {
                continue;
            }
            let t = v * n_cells + next;
            predecessors[t].push(s as u32);
            if !reachable[t] {
                reachable[t] = true;
                queue.push_back(t);
            }
        }
    }
    // Backward from the states one step from a goal.
    let mut queue = goal_adjacent;
    while let Some(t) = queue.pop_front() {
        let d = dist[t].unwrap_or(0);
        for &s in &predecessors[t] {
            let s = s as usize;
            if dist[s].is_none() {
                dist[s] = Some(d + 1);
                queue.push_back(s);
            }
        }
    }
    let longest = (0..n)
        .filter(|&s| reachable[s])
        .filter_map(|s| dist[s])
        .max();
    (dist[start], longest)
}
