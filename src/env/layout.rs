//! The layout of a ReacherDelivery task: its scene, its labelled regions and its exogenous
//! events, and what follows from them — the observation's columns, the label bits, the
//! vocabulary. A task file declares it ([`super::task_file`]); the environment, the labelling
//! function, the learners' features and the logs read it from here, so no code outside the
//! task loader knows how many regions or events a task has, or what they are called.
//!
//! **Observation** (`f32`): `[cos q0, cos q1, sin q0, sin q1, q̇0, q̇1, tip_x, tip_y,
//! tip − region_i (x, y) for each region in file order, one flag per event]`: 8 + 2·R + E
//! values for R regions and E events. An event's flag is 1 on the step it fires, 0 otherwise,
//! so the labelling function is a function of the observation.
//!
//! **Label bits**: region `k` is bit `k`, event `e` is bit `R + e`; the vocabulary lists the
//! letters in the same order.

use super::scene_files::SceneFile;
use crate::rm::{LabelSet, Vocabulary};
use serde::{Deserialize, Serialize};
use std::fmt;
use std::path::PathBuf;
use std::sync::Arc;

/// Most labelled regions of a task.
pub const MAX_REGIONS: usize = 8;
/// Most exogenous events of a task.
pub const MAX_EVENTS: usize = 4;
/// Half the side of the arena (its walls are at ±0.3 m): every region lies inside.
pub const ARENA_HALF_WIDTH: f64 = 0.3;

/// A letter a region or event may have: one ASCII letter or digit.
pub fn is_task_letter(c: char) -> bool {
    c.is_ascii_alphanumeric()
}

/// A region's radius: more than 0, inside the arena.
pub fn radius_fits(radius: f64) -> bool {
    radius > 0.0 && radius <= ARENA_HALF_WIDTH
}

/// An event's probability: in [0, 1].
pub fn probability_ok(probability: f64) -> bool {
    (0.0..=1.0).contains(&probability)
}

/// An event's window of 1-based steps: it starts at 1 or later and is not empty.
pub fn window_ok(earliest: usize, latest: usize) -> bool {
    earliest >= 1 && earliest <= latest
}

/// Observation columns of the arm's joint velocities.
pub const OBS_JOINT_VEL: [usize; 2] = [4, 5];
/// Observation columns of the fingertip position.
pub const OBS_TIP: [usize; 2] = [6, 7];
/// Observation columns before the first region's offset (joint state and fingertip).
pub const OBS_ARM: usize = 8;

/// What a region's centre is attached to in the scene.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Anchor {
    Body(String),
    Site(String),
}

impl Anchor {
    pub fn name(&self) -> &str {
        match self {
            Anchor::Body(n) | Anchor::Site(n) => n,
        }
    }
}

impl fmt::Display for Anchor {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Anchor::Body(n) => write!(f, "body '{n}'"),
            Anchor::Site(n) => write!(f, "site '{n}'"),
        }
    }
}

/// A labelled region: its proposition holds while the fingertip is strictly within `radius`
/// of its centre.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Region {
    pub letter: char,
    pub anchor: Anchor,
    pub radius: f64,
    /// Where the layout puts the centre when it is not randomised (x, y); the anchor's place
    /// in the scene when the file gives none.
    pub position: [f64; 2],
    /// The anchor is a body with slide joints `<body>_x`, `<body>_y`, so a layout can move it.
    pub movable: bool,
}

/// An exogenous event: with `probability`, an episode has it on one step drawn uniformly
/// from `earliest_step..=latest_step` (1-based), and its proposition holds on that step only.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Event {
    pub letter: char,
    pub probability: f64,
    pub earliest_step: usize,
    pub latest_step: usize,
}

/// Where a task's scene comes from: the built-in model or an MJCF file. Written as
/// `"builtin"` or the file's path.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(from = "String", into = "String")]
pub enum Scene {
    Builtin,
    File(PathBuf),
}

/// How a task file names the built-in scene.
pub const BUILTIN_SCENE: &str = "builtin";

impl From<String> for Scene {
    fn from(s: String) -> Scene {
        if s == BUILTIN_SCENE {
            Scene::Builtin
        } else {
            Scene::File(PathBuf::from(s))
        }
    }
}

impl From<Scene> for String {
    fn from(s: Scene) -> String {
        match s {
            Scene::Builtin => BUILTIN_SCENE.into(),
            Scene::File(p) => p.display().to_string(),
        }
    }
}

impl fmt::Display for Scene {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Scene::Builtin => f.write_str(crate::assets::REACHER_XML_NAME),
            Scene::File(p) => write!(f, "{}", p.display()),
        }
    }
}

/// A file scene as its task loaded it: the scene file's text and the files it reads, the
/// bytes the task's expert key hashes and its logs carry.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct LoadedScene {
    pub text: Arc<str>,
    pub files: Arc<[SceneFile]>,
}

/// A task's scene, regions and events (see the module documentation for what follows from
/// them).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TaskLayout {
    pub scene: Scene,
    pub regions: Vec<Region>,
    pub events: Vec<Event>,
    /// A file scene's bytes as its task loaded them, which the environment compiles its model
    /// from (`env::physics_scene::scene_model`), so that a run steps the scene its key and
    /// logs record, whatever happens to the files afterwards. `None` for the built-in scene
    /// and for a layout read back from a record, which names its scene only.
    #[serde(skip)]
    pub loaded: Option<LoadedScene>,
}

impl TaskLayout {
    pub fn n_regions(&self) -> usize {
        self.regions.len()
    }

    pub fn n_events(&self) -> usize {
        self.events.len()
    }

    /// Length of an observation.
    pub fn obs_dim(&self) -> usize {
        OBS_ARM + 2 * self.regions.len() + self.events.len()
    }

    /// Observation columns of fingertip − region `k` (x, y).
    pub fn region_columns(&self, k: usize) -> [usize; 2] {
        [OBS_ARM + 2 * k, OBS_ARM + 2 * k + 1]
    }

    /// Observation column of event `e`'s flag.
    pub fn event_column(&self, e: usize) -> usize {
        OBS_ARM + 2 * self.regions.len() + e
    }

    /// Label bit of event `e`.
    pub fn event_bit(&self, e: usize) -> usize {
        self.regions.len() + e
    }

    /// The label bits of the regions: the agent's own touches.
    pub fn touches(&self) -> LabelSet {
        (0..self.regions.len()).fold(LabelSet::EMPTY, |s, k| s.with(k))
    }

    /// The label bits of the exogenous events.
    pub fn events(&self) -> LabelSet {
        (0..self.events.len()).fold(LabelSet::EMPTY, |s, e| s.with(self.event_bit(e)))
    }

    /// The propositions in label-bit order: regions, then events.
    pub fn letters(&self) -> String {
        self.region_letters() + &self.event_letters()
    }

    /// The regions' letters in label-bit order.
    pub fn region_letters(&self) -> String {
        self.regions.iter().map(|r| r.letter).collect()
    }

    /// The events' letters in label-bit order.
    pub fn event_letters(&self) -> String {
        self.events.iter().map(|e| e.letter).collect()
    }

    pub fn vocabulary(&self) -> Vocabulary {
        Vocabulary::new(&self.letters())
    }

    /// The region of label bit `k`, if it is one.
    pub fn region(&self, k: usize) -> Option<&Region> {
        self.regions.get(k)
    }

    /// Region centres of the layout when it is not randomised, in label-bit order.
    pub fn positions(&self) -> Vec<[f64; 2]> {
        self.regions.iter().map(|r| r.position).collect()
    }

    /// The rules every layout a task file declares keeps, on their own: a layout read from
    /// elsewhere (a log's run record) is checked with them before anything is built from it,
    /// since the vocabulary, the environment's event draws and the drawings assume them.
    pub fn check(&self) -> Result<(), LayoutProblem> {
        let too_many = |what, count, limit| LayoutProblem::TooMany { what, count, limit };
        if self.regions.len() > MAX_REGIONS {
            return Err(too_many("regions", self.regions.len(), MAX_REGIONS));
        }
        if self.events.len() > MAX_EVENTS {
            return Err(too_many("events", self.events.len(), MAX_EVENTS));
        }
        let letters: Vec<char> = self.letters().chars().collect();
        for (i, &c) in letters.iter().enumerate() {
            if !is_task_letter(c) {
                return Err(LayoutProblem::BadLetter(c));
            }
            if letters[..i].contains(&c) {
                return Err(LayoutProblem::LetterTwice(c));
            }
        }
        for r in &self.regions {
            if !radius_fits(r.radius) {
                return Err(LayoutProblem::Radius {
                    letter: r.letter,
                    radius: r.radius,
                });
            }
            if !r.position.iter().all(|v| v.is_finite()) {
                return Err(LayoutProblem::Position {
                    letter: r.letter,
                    position: r.position,
                });
            }
        }
        for e in &self.events {
            if !probability_ok(e.probability) {
                return Err(LayoutProblem::Probability {
                    letter: e.letter,
                    probability: e.probability,
                });
            }
            if !window_ok(e.earliest_step, e.latest_step) {
                return Err(LayoutProblem::EventWindow {
                    letter: e.letter,
                    earliest: e.earliest_step,
                    latest: e.latest_step,
                });
            }
        }
        Ok(())
    }
}

/// A rule of [`TaskLayout::check`] a layout breaks.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum LayoutProblem {
    #[error("{count} {what}, at most {limit}")]
    TooMany {
        what: &'static str,
        count: usize,
        limit: usize,
    },
    #[error("letter '{}' is not one ASCII letter or digit", crate::quoted::text(&.0.to_string()))]
    BadLetter(char),
    #[error("letter '{0}' names two regions or events (it appears twice)")]
    LetterTwice(char),
    #[error("region '{letter}': radius {} must be more than 0 and at most {ARENA_HALF_WIDTH} m", crate::quoted::number(*.radius))]
    Radius { letter: char, radius: f64 },
    #[error("region '{letter}': position ({}, {}) is not finite", crate::quoted::number(.position[0]), crate::quoted::number(.position[1]))]
    Position { letter: char, position: [f64; 2] },
    #[error("event '{letter}': probability {} is not in [0, 1]", crate::quoted::number(*.probability))]
    Probability { letter: char, probability: f64 },
    #[error(
        "event '{letter}': earliest_step ({earliest}) must be between 1 and latest_step ({latest})"
    )]
    EventWindow {
        letter: char,
        earliest: usize,
        latest: usize,
    },
}
