//! ReacherDelivery tasks as files: a TOML task file names the scene, the labelled regions,
//! the exogenous events, the episode length, the region layout and the task's perfect reward
//! machine. `docs/tasks.md` is the reference of the format; the paper's four tasks and `blue`
//! ship as `assets/tasks/<name>.toml` (built into the binaries, [`crate::assets::task_file`]).
//!
//! ```toml
//! scene = "builtin"                      # the built-in model, or an MJCF path
//! machine = "../rm/reacher_if.txt"       # the perfect machine, relative to this file
//! episode_steps = 100
//! randomize_layout = false
//!
//! [[region]]                             # label bit 0, 1, ... in file order
//! letter = "r"
//! body = "red"                           # or site = "..."
//! radius = 0.02
//! position = [0.0975, 0.1689]            # moves the body (a mocap body, or one with slides)
//!
//! [[event]]                              # label bits after the regions', in file order
//! letter = "c"
//! probability = 0.5
//! earliest_step = 1
//! latest_step = 8
//! ```
//!
//! [`Task::load`] checks everything against the scene and the machine before any work, and
//! every error names the file, the line and the key.

use super::layout::{is_task_letter, probability_ok, radius_fits, window_ok};
pub use super::layout::{
    Anchor, Event, LoadedScene, Region, Scene, TaskLayout, ARENA_HALF_WIDTH, BUILTIN_SCENE,
    MAX_EVENTS, MAX_REGIONS,
};
use super::placement::Placement;
use super::scene_files::{compile_in_memory, read_scene_files, SceneFile, SceneFileKind};
use crate::config_text::{key_line, read_text_file, toml_error_message};
use crate::mujoco::{Data, Model, ObjectKind, IN_MEMORY_DIR};
use crate::rm::format::{parse_rm, RmFileError};
use crate::rm::{LabelSet, RewardMachine};
use serde::Deserialize;
use sha2::{Digest, Sha256};
use std::path::{Component, Path, PathBuf};
use std::sync::Arc;

/// Longest episode a task or run config may ask for (episodes are buffered whole).
pub const MAX_EPISODE_STEPS: usize = 10_000;
/// Most regions of a randomised layout (each reset draws them apart from each other in an
/// annulus that holds about this many).
pub const MAX_RANDOMIZED_REGIONS: usize = 6;
/// A fixed layout position lies within ±this (m) in x and y: inside the walls with room for a
/// ball, the range [`super::reacher::ReacherConfig::ball_layout`] accepts.
pub const SLIDE_RANGE: f64 = 0.27;
/// The annulus a randomised layout draws centres in (m), as [`super::reacher`] does.
pub const RANDOM_LAYOUT_MAX_RADIUS: f64 = 0.19;
/// The body whose position is the fingertip.
pub const FINGERTIP_BODY: &str = "fingertip";
pub use super::scene_files::{
    MAX_ASSET_BYTES, MAX_ASSET_FILES, MAX_INCLUDED_BYTES, MAX_INCLUDED_FILES,
};

/// The shipped tasks (`assets/tasks/<name>.toml`): the paper's four and the baselines'
/// Markovian positive control `blue`.
pub const SHIPPED: [&str; 5] = ["or", "sequential", "if", "composite", "blue"];

/// A task file as written (before it is checked against its scene and machine).
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct TaskText {
    scene: String,
    machine: String,
    episode_steps: usize,
    randomize_layout: bool,
    #[serde(default)]
    region: Vec<RegionText>,
    #[serde(default)]
    event: Vec<EventText>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RegionText {
    letter: String,
    body: Option<String>,
    site: Option<String>,
    radius: f64,
    position: Option<[f64; 2]>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct EventText {
    letter: String,
    probability: f64,
    earliest_step: usize,
    latest_step: usize,
}

/// A checked ReacherDelivery task. Label bit `k` is region `k` for `k < regions.len()`, then
/// the events in file order; the perfect machine's vocabulary lists the same letters in the
/// same order.
#[derive(Clone, Debug)]
pub struct Task {
    /// The shipped name, or the task file's stem.
    pub name: String,
    /// Where the task came from: `assets/tasks/<name>.toml` or the file's path.
    pub source: String,
    pub scene: Scene,
    pub regions: Vec<Region>,
    pub events: Vec<Event>,
    pub episode_steps: usize,
    pub randomize_layout: bool,
    /// The perfect machine: trains the expert and judges success; no learner reads it.
    pub machine: Arc<RewardMachine>,
    pub machine_source: String,
    /// SHA-256 of the task file, its scene (with the files the scene reads) and its machine
    /// (hex): the key of its expert.
    pub content_hash: String,
    /// The task file's text (logs record it).
    pub text: String,
    /// The scene's MJCF text (logs attach it; the environment compiles it).
    pub scene_xml: Arc<str>,
    /// The files the scene reads: included files, then mesh, skin, height-field and texture
    /// files (logs attach them). Shared, as every log of the task carries them.
    pub scene_files: Arc<[SceneFile]>,
}

/// Why a task could not be loaded.
#[derive(Debug, thiserror::Error)]
pub enum TaskFileError {
    #[error("{file}: cannot read: {error}")]
    Io { file: String, error: std::io::Error },
    #[error("{file}: {message}")]
    Toml { file: String, message: String },
    /// A value that breaks a rule; `line` is 1-based.
    #[error("{file}:{}: `{key}`: {problem}", line.map_or("?".to_string(), |l| l.to_string()))]
    Invalid {
        file: String,
        line: Option<usize>,
        key: String,
        problem: Box<TaskProblem>,
    },
    #[error("no shipped task named '{0}' (shipped: or, sequential, if, composite, blue); a task file's path must end in .toml")]
    UnknownName(String),
}

impl TaskFileError {
    /// The problem, when the file parsed but breaks a rule.
    pub fn problem(&self) -> Option<&TaskProblem> {
        match self {
            TaskFileError::Invalid { problem, .. } => Some(&**problem),
            _ => None,
        }
    }
}

/// The rule a task file breaks.
#[derive(Debug, thiserror::Error)]
pub enum TaskProblem {
    #[error("cannot load the scene: {0}")]
    Scene(String),
    #[error("the scene {scene} has no body '{FINGERTIP_BODY}' (the arm's fingertip)")]
    NoFingertip { scene: String },
    #[error("the scene {scene} is not a ReacherDelivery arm: {problem}")]
    NotAnArm { scene: String, problem: String },
    #[error("no {anchor} in the scene {scene}")]
    UnknownAnchor { anchor: Anchor, scene: String },
    #[error("a region names exactly one of `body` or `site`")]
    AnchorCount,
    #[error("'{0}' is not one proposition letter (a single ASCII letter or digit)")]
    BadLetter(String),
    #[error("letter '{letter}' is defined twice (first on line {first})")]
    LetterTwice { letter: char, first: usize },
    #[error("{count} {what}, more than the limit of {limit}")]
    TooMany {
        what: &'static str,
        count: usize,
        limit: usize,
    },
    #[error("radius {0} must be more than 0 and the region must fit in the arena (±{ARENA_HALF_WIDTH} m)")]
    Radius(f64),
    #[error("position ({x}, {y}) with radius {radius} does not lie inside the arena (±{ARENA_HALF_WIDTH} m) and the layout range (±{SLIDE_RANGE} m)")]
    OutsideArena { x: f64, y: f64, radius: f64 },
    #[error("{anchor} is neither a mocap body nor a body with slide joints '{name}_x' and '{name}_y', so a layout cannot move it", name = anchor.name())]
    NotMovable { anchor: Anchor },
    #[error("probability {0} must be in [0, 1]")]
    Probability(f64),
    #[error("event window {earliest}..={latest} must lie within the episode's steps 1..={episode_steps}")]
    EventWindow {
        earliest: usize,
        latest: usize,
        episode_steps: usize,
    },
    #[error("episode_steps {0} must be between 1 and {MAX_EPISODE_STEPS}")]
    EpisodeSteps(usize),
    #[error(transparent)]
    Machine(RmFileError),
    #[error("proposition '{letter}' of the machine {machine} is defined by no region or event")]
    UndefinedProposition { letter: char, machine: String },
    #[error("the machine {machine} lists the propositions '{machine_letters}'; the task defines '{task_letters}' (regions, then events, in file order) and the machine must list exactly these, in this order")]
    VocabularyOrder {
        machine: String,
        machine_letters: String,
        task_letters: String,
    },
}

/// Where the files a task file refers to are read from.
enum Origin<'a> {
    /// A shipped task: its machine is a shipped machine (`assets/rm/<name>.txt`).
    Shipped,
    /// A task file on disk in directory `dir`.
    Dir(&'a Path),
}

impl Task {
    /// A shipped task by name (`composite`), or a task file by path (`my/task.toml`).
    pub fn resolve(name_or_path: &str) -> Result<Task, TaskFileError> {
        if SHIPPED.contains(&name_or_path) {
            return Task::shipped(name_or_path);
        }
        if name_or_path.ends_with(".toml") || Path::new(name_or_path).is_file() {
            return Task::load(Path::new(name_or_path));
        }
        Err(TaskFileError::UnknownName(name_or_path.into()))
    }

    /// A shipped task, `assets/tasks/<name>.toml`.
    pub fn shipped(name: &str) -> Result<Task, TaskFileError> {
        let source = format!("assets/tasks/{name}.toml");
        let text = crate::assets::task_file(name)
            .ok_or_else(|| TaskFileError::UnknownName(name.into()))?;
        Task::parse(text, name, &source, Origin::Shipped)
    }

    /// Reads and checks a task file.
    pub fn load(path: &Path) -> Result<Task, TaskFileError> {
        let source = path.display().to_string();
        let text = read_text_file(path).map_err(|error| TaskFileError::Io {
            file: source.clone(),
            error,
        })?;
        let name = path
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_else(|| "task".into());
        let dir = path.parent().unwrap_or(Path::new(""));
        Task::parse(&text, &name, &source, Origin::Dir(dir))
    }

    fn parse(text: &str, name: &str, source: &str, origin: Origin) -> Result<Task, TaskFileError> {
        let raw: TaskText = toml::from_str(text).map_err(|e| TaskFileError::Toml {
            file: source.into(),
            message: toml_error_message(text, &e),
        })?;
        let bad = |key: String, problem: TaskProblem| {
            let line = locate(text, &key);
            TaskFileError::Invalid {
                file: source.into(),
                line,
                key,
                problem: Box::new(problem),
            }
        };

        // Sizes first, before anything is built from them.
        if raw.region.len() > MAX_REGIONS {
            return Err(bad(
                "region".into(),
                TaskProblem::TooMany {
                    what: "regions",
                    count: raw.region.len(),
                    limit: MAX_REGIONS,
                },
            ));
        }
        if raw.event.len() > MAX_EVENTS {
            return Err(bad(
                "event".into(),
                TaskProblem::TooMany {
                    what: "events",
                    count: raw.event.len(),
                    limit: MAX_EVENTS,
                },
            ));
        }
        if raw.randomize_layout && raw.region.len() > MAX_RANDOMIZED_REGIONS {
            return Err(bad(
                "randomize_layout".into(),
                TaskProblem::TooMany {
                    what: "regions in a randomised layout",
                    count: raw.region.len(),
                    limit: MAX_RANDOMIZED_REGIONS,
                },
            ));
        }
        if raw.episode_steps == 0 || raw.episode_steps > MAX_EPISODE_STEPS {
            return Err(bad(
                "episode_steps".into(),
                TaskProblem::EpisodeSteps(raw.episode_steps),
            ));
        }

        // Letters: one character each, each defined once.
        let mut letters: Vec<(char, usize)> = Vec::new();
        let all = raw
            .region
            .iter()
            .enumerate()
            .map(|(i, r)| (format!("region[{i}].letter"), &r.letter))
            .chain(
                raw.event
                    .iter()
                    .enumerate()
                    .map(|(i, e)| (format!("event[{i}].letter"), &e.letter)),
            );
        for (key, letter) in all {
            let mut chars = letter.chars();
            let c = match (chars.next(), chars.next()) {
                (Some(c), None) if is_task_letter(c) => c,
                _ => return Err(bad(key, TaskProblem::BadLetter(letter.clone()))),
            };
            let line = locate(text, &key).unwrap_or(0);
            if let Some(&(_, first)) = letters.iter().find(|(l, _)| *l == c) {
                return Err(bad(key, TaskProblem::LetterTwice { letter: c, first }));
            }
            letters.push((c, line));
        }

        // The scene: its files readable within the limits, loadable, with the arm and its
        // fingertip. The files are read first, so that a missing or oversized one is named
        // before MuJoCo compiles anything; a text that is no XML is left to MuJoCo's message.
        // The scene is then compiled from memory as its logs compile it, so that two files
        // memory cannot tell apart, or a file MuJoCo reads that a log would not carry, stop
        // the task here rather than its replay.
        let scene_problem =
            |e: &dyn std::fmt::Display| bad("scene".into(), TaskProblem::Scene(e.to_string()));
        let (scene, model, files) = match raw.scene.as_str() {
            BUILTIN_SCENE => (
                Scene::Builtin,
                Model::from_xml_str(crate::assets::REACHER_XML, crate::assets::REACHER_XML_NAME)
                    .map_err(|e| scene_problem(&e))?,
                None,
            ),
            path => {
                let path = match origin {
                    Origin::Dir(dir) => dir.join(path),
                    Origin::Shipped => PathBuf::from(path),
                };
                let files = match read_scene_files(&path) {
                    Ok(files) => files,
                    Err(e) if e.is_syntax() => {
                        return Err(match Model::from_xml_path(&path) {
                            Err(mujoco) => scene_problem(&mujoco),
                            Ok(_) => scene_problem(&e),
                        })
                    }
                    Err(e) => return Err(scene_problem(&e)),
                };
                let source = path.display().to_string();
                let text = String::from_utf8_lossy(&files.main);
                let model = compile_in_memory(&text, &files.files, &source).map_err(|e| {
                    let mut message = e.to_string();
                    if message.contains(&format!("{IN_MEMORY_DIR}/")) {
                        message.push_str(&format!(
                            " (the scene is compiled from memory, as its logs compile it: \
                             {IN_MEMORY_DIR}/<name> is the scene's file <name>)"
                        ));
                    }
                    bad("scene".into(), TaskProblem::Scene(message))
                })?;
                (Scene::File(path), model, Some((files.main, files.files)))
            }
        };
        let scene_name = scene.to_string();
        check_arm(&model, &scene_name).map_err(|p| bad("scene".into(), p))?;
        let mut data = Data::new(Arc::new(model))
            .map_err(|e| bad("scene".into(), TaskProblem::Scene(e.to_string())))?;
        data.forward()
            .map_err(|e| bad("scene".into(), TaskProblem::Scene(e.to_string())))?;
        let model = data.model().clone();

        // Regions: anchors in the scene, radii and positions inside the arena.
        let mut regions = Vec::with_capacity(raw.region.len());
        for (i, r) in raw.region.iter().enumerate() {
            let key = |k: &str| format!("region[{i}].{k}");
            let anchor = match (&r.body, &r.site) {
                (Some(b), None) => Anchor::Body(b.clone()),
                (None, Some(s)) => Anchor::Site(s.clone()),
                _ => return Err(bad(format!("region[{i}]"), TaskProblem::AnchorCount)),
            };
            let anchor_key = key(if r.body.is_some() { "body" } else { "site" });
            let unknown = || {
                bad(
                    anchor_key.clone(),
                    TaskProblem::UnknownAnchor {
                        anchor: anchor.clone(),
                        scene: scene_name.clone(),
                    },
                )
            };
            let scene_position = match &anchor {
                Anchor::Body(b) => {
                    data.body_xpos(model.id(ObjectKind::Body, b).map_err(|_| unknown())?)
                }
                Anchor::Site(s) => {
                    data.site_xpos(model.id(ObjectKind::Site, s).map_err(|_| unknown())?)
                }
            };
            let movable = match &anchor {
                Anchor::Body(b) => Placement::find(&model, b).is_some(),
                Anchor::Site(_) => false,
            };
            if !radius_fits(r.radius) {
                return Err(bad(key("radius"), TaskProblem::Radius(r.radius)));
            }
            if (r.position.is_some() || raw.randomize_layout) && !movable {
                let k = if r.position.is_some() {
                    key("position")
                } else {
                    "randomize_layout".into()
                };
                return Err(bad(k, TaskProblem::NotMovable { anchor }));
            }
            let position = r.position.unwrap_or([scene_position[0], scene_position[1]]);
            let [x, y] = position;
            let reach = if raw.randomize_layout {
                RANDOM_LAYOUT_MAX_RADIUS + r.radius
            } else {
                x.abs().max(y.abs()) + r.radius
            };
            let slide_ok =
                r.position.is_none() || (x.abs() <= SLIDE_RANGE && y.abs() <= SLIDE_RANGE);
            if !(x.is_finite() && y.is_finite() && reach <= ARENA_HALF_WIDTH && slide_ok) {
                let k = if r.position.is_some() {
                    key("position")
                } else {
                    anchor_key.clone()
                };
                return Err(bad(
                    k,
                    TaskProblem::OutsideArena {
                        x,
                        y,
                        radius: r.radius,
                    },
                ));
            }
            regions.push(Region {
                letter: letters[i].0,
                anchor,
                radius: r.radius,
                position,
                movable,
            });
        }

        // Events: a probability and a window inside the episode.
        let mut events = Vec::with_capacity(raw.event.len());
        for (i, e) in raw.event.iter().enumerate() {
            let key = |k: &str| format!("event[{i}].{k}");
            if !probability_ok(e.probability) {
                return Err(bad(
                    key("probability"),
                    TaskProblem::Probability(e.probability),
                ));
            }
            let window = TaskProblem::EventWindow {
                earliest: e.earliest_step,
                latest: e.latest_step,
                episode_steps: raw.episode_steps,
            };
            if !window_ok(e.earliest_step, e.latest_step) {
                return Err(bad(key("earliest_step"), window));
            }
            if e.latest_step > raw.episode_steps {
                return Err(bad(key("latest_step"), window));
            }
            events.push(Event {
                letter: letters[raw.region.len() + i].0,
                probability: e.probability,
                earliest_step: e.earliest_step,
                latest_step: e.latest_step,
            });
        }

        // The machine: its propositions are the task's letters, in label-bit order.
        let (machine_text, machine_source) = read_machine(&raw.machine, &origin)
            .map_err(|e| bad("machine".into(), TaskProblem::Machine(e)))?;
        let machine = parse_rm(&machine_text, &machine_source)
            .map_err(|e| bad("machine".into(), TaskProblem::Machine(e)))?;
        let task_letters: String = letters.iter().map(|(c, _)| *c).collect();
        let machine_letters: String = machine.vocab().props().iter().collect();
        if let Some(&letter) = machine
            .vocab()
            .props()
            .iter()
            .find(|c| !task_letters.contains(**c))
        {
            return Err(bad(
                "machine".into(),
                TaskProblem::UndefinedProposition {
                    letter,
                    machine: machine_source,
                },
            ));
        }
        if machine_letters != task_letters {
            return Err(bad(
                "machine".into(),
                TaskProblem::VocabularyOrder {
                    machine: machine_source,
                    machine_letters,
                    task_letters,
                },
            ));
        }

        let (scene_text, scene_files) =
            files.unwrap_or_else(|| (crate::assets::REACHER_XML.as_bytes().to_vec(), Vec::new()));
        let content_hash = content_hash(text, &scene_text, &machine_text, &scene_files);

        Ok(Task {
            name: name.into(),
            source: source.into(),
            scene,
            regions,
            events,
            episode_steps: raw.episode_steps,
            randomize_layout: raw.randomize_layout,
            machine: Arc::new(machine),
            machine_source,
            content_hash,
            text: text.into(),
            scene_xml: String::from_utf8_lossy(&scene_text).into(),
            scene_files: scene_files.into(),
        })
    }

    /// The label bits of the regions (the agent's own touches).
    pub fn region_labels(&self) -> LabelSet {
        (0..self.regions.len()).fold(LabelSet::EMPTY, |s, k| s.with(k))
    }

    /// The task's scene, regions and events; a file scene with the bytes this task read.
    pub fn layout(&self) -> TaskLayout {
        TaskLayout {
            scene: self.scene.clone(),
            regions: self.regions.clone(),
            events: self.events.clone(),
            loaded: match self.scene {
                Scene::Builtin => None,
                Scene::File(_) => Some(LoadedScene {
                    text: Arc::clone(&self.scene_xml),
                    files: Arc::clone(&self.scene_files),
                }),
            },
        }
    }
}

/// The arm the environment drives: joints `joint0`, `joint1`, two actuators, a fingertip.
fn check_arm(model: &Model, scene: &str) -> Result<(), TaskProblem> {
    if model.id(ObjectKind::Body, FINGERTIP_BODY).is_err() {
        return Err(TaskProblem::NoFingertip {
            scene: scene.into(),
        });
    }
    for joint in ["joint0", "joint1"] {
        if model.id(ObjectKind::Joint, joint).is_err() {
            return Err(TaskProblem::NotAnArm {
                scene: scene.into(),
                problem: format!("no joint '{joint}'"),
            });
        }
    }
    if model.nu() != 2 {
        return Err(TaskProblem::NotAnArm {
            scene: scene.into(),
            problem: format!("{} actuators, the arm has 2", model.nu()),
        });
    }
    Ok(())
}

/// SHA-256 (hex) of a task's parts, each after its length: the task file, the scene file
/// and the machine; then each included file's name and bytes; then, when the scene names any,
/// a marker and each asset file's name and bytes. A scene that reads no other file hashes to
/// the three parts alone, the key the committed experts are named by.
fn content_hash(text: &str, scene: &[u8], machine: &str, files: &[SceneFile]) -> String {
    let mut hash = Sha256::new();
    let mut part = |bytes: &[u8]| {
        hash.update((bytes.len() as u64).to_le_bytes());
        hash.update(bytes);
    };
    for bytes in [text.as_bytes(), scene, machine.as_bytes()] {
        part(bytes);
    }
    let of_kind = |kind| files.iter().filter(move |f| f.kind == kind);
    for file in of_kind(SceneFileKind::Include) {
        part(file.name.as_bytes());
        part(&file.bytes);
    }
    if of_kind(SceneFileKind::Asset).next().is_some() {
        part(b"asset files");
    }
    for file in of_kind(SceneFileKind::Asset) {
        part(file.name.as_bytes());
        part(&file.bytes);
    }
    hash.finalize().iter().map(|b| format!("{b:02x}")).collect()
}

/// The machine's text and how messages name it. A shipped task's machine path resolves
/// inside the shipped assets (`assets/tasks/../rm/x.txt` is `assets/rm/x.txt`).
fn read_machine(path: &str, origin: &Origin) -> Result<(String, String), RmFileError> {
    match origin {
        Origin::Dir(dir) => {
            let full = dir.join(path);
            let name = full.display().to_string();
            read_text_file(&full)
                .map(|t| (t, name.clone()))
                .map_err(|error| RmFileError::Io { file: name, error })
        }
        Origin::Shipped => {
            let full = normalize(&Path::new("assets/tasks").join(path));
            let name = full.display().to_string();
            let text = full
                .strip_prefix("assets/rm")
                .ok()
                .and_then(|p| p.to_str())
                .and_then(|p| p.strip_suffix(".txt"))
                .and_then(crate::rm::perfect::text);
            text.map(|t| (t.to_string(), name.clone()))
                .ok_or_else(|| RmFileError::Io {
                    file: name,
                    error: std::io::Error::new(
                        std::io::ErrorKind::NotFound,
                        "not a shipped reward machine",
                    ),
                })
        }
    }
}

/// `a/b/../c` → `a/c` (no file system access).
fn normalize(path: &Path) -> PathBuf {
    let mut out = PathBuf::new();
    for c in path.components() {
        match c {
            Component::ParentDir => {
                out.pop();
            }
            Component::CurDir => {}
            other => out.push(other),
        }
    }
    out
}

/// The 1-based line of a key such as `region[2].radius`: the key's own line in the third
/// element of the array, or the element's own start (its `[[region]]` header, or the `{` of
/// `region = [{ … }, { … }]`) when the key is not written there. Read from the parsed
/// document's spans, so every way TOML writes an array of tables finds its line.
fn locate(text: &str, key: &str) -> Option<usize> {
    let Some((array, rest)) = key.split_once('[') else {
        return key_line(text, key);
    };
    let (index, field) = rest.split_once(']')?;
    let index: usize = index.parse().ok()?;
    let field = field.trim_start_matches('.');
    let doc = toml_edit::ImDocument::parse(text).ok()?;
    let span = match doc.as_table().get(array)? {
        toml_edit::Item::ArrayOfTables(tables) => {
            let table = tables.get(index)?;
            let key = table.get_key_value(field).and_then(|(k, _)| k.span());
            key.or_else(|| table.span())
        }
        toml_edit::Item::Value(toml_edit::Value::Array(values)) => {
            let value = values.get(index)?;
            let table = value.as_inline_table();
            let key = table
                .and_then(|t| t.get_key_value(field))
                .and_then(|(k, _)| k.span());
            key.or_else(|| value.span())
        }
        _ => None,
    }?;
    Some(text[..span.start].matches('\n').count() + 1)
}
