//! The Office Gridworld of the QRM paper (Toro Icarte et al. 2018), as used by SMIRL's
//! discrete experiments, and any other grid world written as a map file.
//!
//! A world is read from a map file ([`map`]: walls, letters, start) and a task from a task
//! file ([`task`]: the map and the task's reward machine). The paper's map (12 × 9 cells, 4 × 3
//! rooms of 3 × 3 cells) and tasks 0–4 are shipped files (`assets/office/`).
//!
//! Cell index = `y * width + x` (x left to right, y bottom to top). Actions: 0 = up (y+1),
//! 1 = right (x+1), 2 = down, 3 = left. Moves are deterministic; a move through a wall leaves
//! the agent in place. The label of a step is the letter of the cell the agent lands on (at
//! most one proposition per cell), over the map's letters.
//!
//! The transition table (cells × 4 actions) is computed once in [`OfficeWorld::from_map`].

pub mod map;
pub mod task;

pub use map::{parse_map, read_map, write_map, MapError, OfficeMap};
pub use task::{OfficeTask, OfficeTaskError};

use crate::rm::{LabelSet, RewardMachine, Vocabulary};

pub const N_ACTIONS: usize = 4;

/// Action names, by index.
pub const ACTION_NAMES: [&str; N_ACTIONS] = ["up", "right", "down", "left"];

/// The world: transition table and labels.
#[derive(Clone, Debug, PartialEq)]
pub struct OfficeWorld {
    vocab: Vocabulary,
    width: usize,
    height: usize,
    start: usize,
    /// `next[cell * 4 + action]`.
    next: Vec<u32>,
    labels: Vec<LabelSet>,
}

impl OfficeWorld {
    /// The world of a map.
    pub fn from_map(map: &OfficeMap) -> OfficeWorld {
        let (width, height) = (map.width(), map.height());
        let n_cells = width * height;
        let mut next = vec![0u32; n_cells * N_ACTIONS];
        for c in 0..n_cells {
            let (x, y) = (c % width, c / width);
            for a in 0..N_ACTIONS {
                let to = match a {
                    0 if y + 1 < height && map.open_up(x, y) => c + width,
                    1 if x + 1 < width && map.open_right(x, y) => c + 1,
                    2 if y > 0 && map.open_up(x, y - 1) => c - width,
                    3 if x > 0 && map.open_right(x - 1, y) => c - 1,
                    _ => c,
                };
                next[c * N_ACTIONS + a] = to as u32;
            }
        }
        let vocab = map.vocab().clone();
        let labels = (0..n_cells)
            .map(|c| match map.letter(c % width, c / width) {
                Some(letter) => match vocab.index_of(letter) {
                    Ok(bit) => LabelSet::EMPTY.with(bit),
                    Err(_) => LabelSet::EMPTY,
                },
                None => LabelSet::EMPTY,
            })
            .collect();
        let (sx, sy) = map.start();
        OfficeWorld {
            vocab,
            width,
            height,
            start: sy * width + sx,
            next,
            labels,
        }
    }

    /// The map of the paper (`assets/office/paper.map`, built into the binaries).
    pub fn paper() -> OfficeWorld {
        OfficeWorld::from_map(&task::paper_map())
    }

    pub fn vocab(&self) -> &Vocabulary {
        &self.vocab
    }

    pub fn width(&self) -> usize {
        self.width
    }

    pub fn height(&self) -> usize {
        self.height
    }

    pub fn n_cells(&self) -> usize {
        self.labels.len()
    }

    /// Cell index of `(x, y)`.
    #[inline]
    pub fn cell(&self, x: usize, y: usize) -> usize {
        y * self.width + x
    }

    /// `(x, y)` of a cell index.
    #[inline]
    pub fn xy(&self, cell: usize) -> (usize, usize) {
        (cell % self.width, cell / self.width)
    }

    pub fn start(&self) -> usize {
        self.start
    }

    /// The cell reached from `cell` by `action`.
    #[inline]
    pub fn step(&self, cell: usize, action: usize) -> usize {
        self.next[cell * N_ACTIONS + action] as usize
    }

    /// The labelling function: the propositions true on `cell`.
    #[inline]
    pub fn label(&self, cell: usize) -> LabelSet {
        self.labels[cell]
    }

    /// The whole transition table, `next[cell * 4 + action]`.
    pub fn transition_table(&self) -> &[u32] {
        &self.next
    }

    /// Labels of all cells, by cell index.
    pub fn labels(&self) -> &[LabelSet] {
        &self.labels
    }

    /// Cells whose label contains proposition `prop`.
    pub fn cells_with(&self, prop: char) -> Vec<usize> {
        match self.vocab.index_of(prop) {
            Ok(bit) => (0..self.n_cells())
                .filter(|&c| self.labels[c].contains(bit))
                .collect(),
            Err(_) => Vec::new(),
        }
    }
}

/// Outcome of one [`OfficeEpisode::step`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OfficeStep {
    pub cell: usize,
    pub labels: LabelSet,
    /// Task reward paid by the machine on this step.
    pub reward: f64,
    /// The machine state after the step.
    pub rm_state: usize,
    /// The task was completed on this step.
    pub completed: bool,
    /// The task failed on this step (plant).
    pub failed: bool,
}

/// The world stepped together with a task's reward machine.
///
/// With `reset_on_end = false` (how the paper trains) the agent keeps moving after the
/// machine reaches a goal or failure state; the machine then stays absorbed and pays nothing
/// more. With `reset_on_end = true` the agent returns to the start cell and the machine to its
/// initial state right after the ending step.
#[derive(Clone, Debug)]
pub struct OfficeEpisode<'a> {
    world: &'a OfficeWorld,
    rm: &'a RewardMachine,
    reset_on_end: bool,
    cell: usize,
    u: usize,
}

impl<'a> OfficeEpisode<'a> {
    pub fn new(world: &'a OfficeWorld, rm: &'a RewardMachine, reset_on_end: bool) -> Self {
        OfficeEpisode {
            world,
            rm,
            reset_on_end,
            cell: world.start(),
            u: rm.initial(),
        }
    }

    pub fn cell(&self) -> usize {
        self.cell
    }

    pub fn rm_state(&self) -> usize {
        self.u
    }

    pub fn reset(&mut self) {
        self.cell = self.world.start();
        self.u = self.rm.initial();
    }

    /// Moves by `action` (0–3; another value is the caller's bug and panics).
    pub fn step(&mut self, action: usize) -> OfficeStep {
        let cell = self.world.step(self.cell, action);
        let labels = self.world.label(cell);
        let was_absorbed = self.rm.is_absorbing(self.u);
        let (u, reward) = self.rm.step(self.u, labels);
        let completed = !was_absorbed && self.rm.is_terminal(u);
        let failed = !was_absorbed && self.rm.is_failure(u);
        self.cell = cell;
        self.u = u;
        let out = OfficeStep {
            cell,
            labels,
            reward,
            rm_state: u,
            completed,
            failed,
        };
        if self.reset_on_end && (completed || failed) {
            self.reset();
        }
        out
    }
}
