//! The Office Gridworld of the QRM paper (Toro Icarte et al. 2018), as used by SMIRL's
//! discrete experiments.
//!
//! 12 columns (x = 0..11, left to right) × 9 rows (y = 0..8, bottom to top), made of 4 × 3
//! rooms of 3 × 3 cells. Cell index = `y * 12 + x`. Actions: 0 = up (y+1), 1 = right (x+1),
//! 2 = down, 3 = left. Moves are deterministic; a move through a wall (any room border that is
//! not one of the listed doors, or the outer border) leaves the agent in place. The label of a
//! step is the letter of the cell the agent lands on (at most one proposition per cell), over
//! the vocabulary `"ABCDcmo*"`. Stepping on a plant `*` fails every task.
//!
//! The transition table (108 cells × 4 actions) is computed once in [`OfficeWorld::new`].

use crate::rm::format::RmFileError;
use crate::rm::{LabelSet, RewardMachine, Vocabulary};

pub const WIDTH: usize = 12;
pub const HEIGHT: usize = 9;
pub const N_CELLS: usize = WIDTH * HEIGHT;
pub const N_ACTIONS: usize = 4;
/// The Office vocabulary: letters A–D, coffee, mail, office, plant.
pub const VOCABULARY: &str = "ABCDcmo*";
/// Agent's start cell (x, y).
pub const START: (usize, usize) = (2, 1);

/// Open passages between two neighbouring cells in different rooms.
const DOORS: [((usize, usize), (usize, usize)); 12] = [
    ((1, 2), (1, 3)),
    ((1, 5), (1, 6)),
    ((2, 1), (3, 1)),
    ((2, 7), (3, 7)),
    ((4, 5), (4, 6)),
    ((5, 1), (6, 1)),
    ((5, 7), (6, 7)),
    ((7, 5), (7, 6)),
    ((8, 1), (9, 1)),
    ((8, 7), (9, 7)),
    ((10, 2), (10, 3)),
    ((10, 5), (10, 6)),
];

/// Objects: proposition character and the cells that carry it.
const OBJECTS: [(char, &[(usize, usize)]); 8] = [
    ('A', &[(1, 1)]),
    ('B', &[(1, 7)]),
    ('C', &[(10, 7)]),
    ('D', &[(10, 1)]),
    ('c', &[(8, 2), (3, 6)]),
    ('m', &[(7, 4)]),
    ('o', &[(4, 4)]),
    ('*', &[(4, 1), (7, 1), (4, 7), (7, 7), (1, 4), (10, 4)]),
];

/// Action names, by index.
pub const ACTION_NAMES: [&str; N_ACTIONS] = ["up", "right", "down", "left"];

/// Cell index of `(x, y)`.
#[inline]
pub fn cell(x: usize, y: usize) -> usize {
    y * WIDTH + x
}

/// `(x, y)` of a cell index.
#[inline]
pub fn xy(cell: usize) -> (usize, usize) {
    (cell % WIDTH, cell / WIDTH)
}

/// The map: transition table and labels.
#[derive(Clone, Debug)]
pub struct OfficeWorld {
    vocab: Vocabulary,
    /// `next[cell * 4 + action]`.
    next: Vec<u32>,
    labels: Vec<LabelSet>,
}

impl Default for OfficeWorld {
    fn default() -> Self {
        OfficeWorld::new()
    }
}

impl OfficeWorld {
    pub fn new() -> OfficeWorld {
        let vocab = Vocabulary::new(VOCABULARY);
        let same_room =
            |a: (usize, usize), b: (usize, usize)| a.0 / 3 == b.0 / 3 && a.1 / 3 == b.1 / 3;
        let is_door = |a: (usize, usize), b: (usize, usize)| {
            DOORS
                .iter()
                .any(|&(p, q)| (p, q) == (a, b) || (q, p) == (a, b))
        };
        let mut next = vec![0u32; N_CELLS * N_ACTIONS];
        for c in 0..N_CELLS {
            let (x, y) = xy(c);
            for a in 0..N_ACTIONS {
                let target = match a {
                    0 if y + 1 < HEIGHT => Some((x, y + 1)),
                    1 if x + 1 < WIDTH => Some((x + 1, y)),
                    2 if y > 0 => Some((x, y - 1)),
                    3 if x > 0 => Some((x - 1, y)),
                    _ => None,
                };
                let to = match target {
                    Some(t) if same_room((x, y), t) || is_door((x, y), t) => cell(t.0, t.1),
                    _ => c,
                };
                next[c * N_ACTIONS + a] = to as u32;
            }
        }
        let mut labels = vec![LabelSet::EMPTY; N_CELLS];
        for (prop, cells) in OBJECTS {
            let bit = vocab
                .index_of(prop)
                .expect("object letters are in the vocabulary");
            for &(x, y) in cells {
                labels[cell(x, y)] = labels[cell(x, y)].with(bit);
            }
        }
        OfficeWorld {
            vocab,
            next,
            labels,
        }
    }

    pub fn vocab(&self) -> &Vocabulary {
        &self.vocab
    }

    pub fn start(&self) -> usize {
        cell(START.0, START.1)
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
            Ok(bit) => (0..N_CELLS)
                .filter(|&c| self.labels[c].contains(bit))
                .collect(),
            Err(_) => Vec::new(),
        }
    }
}

/// The five Office tasks of the paper.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum OfficeTask {
    /// Reach D.
    ReachD = 0,
    /// Coffee, then office.
    Coffee = 1,
    /// Mail, then office.
    Mail = 2,
    /// Coffee and mail (either order), then office.
    CoffeeAndMail = 3,
    /// Patrol A → B → C → D.
    Patrol = 4,
}

/// A task number outside 0–4.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("unknown Office task {0} (tasks are 0-4)")]
pub struct UnknownTask(pub i64);

impl OfficeTask {
    pub const ALL: [OfficeTask; 5] = [
        OfficeTask::ReachD,
        OfficeTask::Coffee,
        OfficeTask::Mail,
        OfficeTask::CoffeeAndMail,
        OfficeTask::Patrol,
    ];

    pub fn from_index(n: i64) -> Result<OfficeTask, UnknownTask> {
        usize::try_from(n)
            .ok()
            .and_then(|i| OfficeTask::ALL.get(i).copied())
            .ok_or(UnknownTask(n))
    }

    pub fn index(self) -> usize {
        self as usize
    }

    /// Name of the perfect machine among the shipped reward machines (`assets/rm/`).
    pub fn rm_name(self) -> String {
        format!("office_t{}", self.index())
    }

    pub fn description(self) -> &'static str {
        match self {
            OfficeTask::ReachD => "reach D",
            OfficeTask::Coffee => "coffee, then office",
            OfficeTask::Mail => "mail, then office",
            OfficeTask::CoffeeAndMail => "coffee and mail, then office",
            OfficeTask::Patrol => "patrol A, B, C, D",
        }
    }

    /// The task's perfect reward machine, `assets/rm/office_t<N>.txt` (reward 1 on
    /// completion; a plant leads to the failure sink).
    pub fn perfect_rm(self) -> Result<RewardMachine, RmFileError> {
        crate::rm::perfect::load(&self.rm_name())
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_door_is_open_both_ways_and_symmetric() {
        let w = OfficeWorld::new();
        for &((ax, ay), (bx, by)) in DOORS.iter() {
            let (a, b) = (cell(ax, ay), cell(bx, by));
            let fwd = (0..4).find(|&act| w.step(a, act) == b);
            let back = (0..4).find(|&act| w.step(b, act) == a);
            assert!(fwd.is_some() && back.is_some(), "door {a}-{b}");
        }
        // Every move is either a stay or to a 4-neighbour, and reversible.
        for c in 0..N_CELLS {
            for a in 0..4 {
                let d = w.step(c, a);
                if d != c {
                    assert_eq!(w.step(d, (a + 2) % 4), c);
                }
            }
        }
    }
}
