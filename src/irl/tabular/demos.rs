//! Office experts and their demonstrations (paper appendix B).
//!
//! The expert acts optimally on the product of the world with the task's perfect reward
//! machine (value iteration, γ = 0.9, reward 1 on completing the task): every trip it makes
//! is a shortest path to completion that avoids plants. An episode of horizon K: optimal
//! trip; on completion the machine restarts from its initial state and the expert takes k
//! uniformly random steps; then optimal again from wherever it stands; repeat until K steps.
//! A random step onto a plant ends the episode ("game over"). Ties among optimal actions are
//! broken uniformly at random with the demonstration seed, so the same seed gives the same
//! demonstrations and different seeds give different (equally optimal) paths.

use crate::env::office::{OfficeTask, OfficeWorld, N_ACTIONS};
use crate::rl::tabular::{optimal_action_masks, value_iteration, DetMdp, Iteration};
use crate::rm::{LabelSet, RewardMachine};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// Discount of the expert's value iteration; any γ < 1 makes optimal = shortest.
const EXPERT_GAMMA: f64 = 0.9;

/// An optimal policy for one task: the set of optimal actions in every product state.
#[derive(Clone, Debug)]
pub struct OfficeExpert {
    world: OfficeWorld,
    rm: RewardMachine,
    /// Bit mask of optimal actions at `u * n_cells + cell`.
    masks: Vec<u32>,
}

impl OfficeExpert {
    /// The expert of `task`, on the task's world and machine.
    pub fn new(task: &OfficeTask) -> OfficeExpert {
        let world = task.world();
        let rm = task.rm();
        let n_cells = world.n_cells();
        let product = DetMdp::product(world.transition_table(), N_ACTIONS, world.labels(), rm)
            .expect("a task's world and machine have consistent shapes");
        let mut reward = vec![0.0; product.n_pairs()];
        for u in 0..rm.n_states() {
            for c in 0..n_cells {
                for a in 0..N_ACTIONS {
                    let c2 = world.step(c, a);
                    reward[(u * n_cells + c) * N_ACTIONS + a] = rm.reward(u, world.label(c2));
                }
            }
        }
        let it = Iteration {
            gamma: EXPERT_GAMMA,
            tol: 1e-13,
            max_sweeps: 10_000,
        };
        let values = value_iteration(&product, &reward, it, None)
            .expect("a task's world and machine have consistent shapes");
        // Q-values of shortest and longer paths differ by ≥ γ^d (1 − γ) ≫ 1e-9 for d < 150.
        let masks = optimal_action_masks(&values.q, N_ACTIONS, 1e-9);
        OfficeExpert {
            world: world.clone(),
            rm: rm.clone(),
            masks,
        }
    }

    /// The perfect machine the expert follows.
    pub fn rm(&self) -> &RewardMachine {
        &self.rm
    }

    /// Bit mask of the optimal actions in `(cell, u)`.
    pub fn optimal_actions(&self, cell: usize, u: usize) -> u32 {
        self.masks[u * self.world.labels().len() + cell]
    }

    /// Demonstrations per appendix B.
    pub fn demonstrations(&self, cfg: &DemoConfig) -> Vec<Demonstration> {
        let mut rng = ChaCha8Rng::seed_from_u64(cfg.seed);
        (0..cfg.n_demos)
            .map(|_| self.episode(cfg, &mut rng))
            .collect()
    }

    fn episode(&self, cfg: &DemoConfig, rng: &mut ChaCha8Rng) -> Demonstration {
        let rm = &self.rm;
        let mut demo = Demonstration {
            start_cell: self.world.start(),
            start_labels: self.world.label(self.world.start()),
            ..Demonstration::default()
        };
        let mut cell = self.world.start();
        let mut u = rm.initial();
        let mut random_left = 0usize;
        let mut trip_start = Some((0usize, cell, u));
        for t in 0..cfg.horizon {
            let action = if random_left > 0 {
                rng.gen_range(0..N_ACTIONS)
            } else {
                let mask = self.optimal_actions(cell, u);
                pick_bit(mask, rng)
            };
            random_left = random_left.saturating_sub(1);
            let next = self.world.step(cell, action);
            let labels = self.world.label(next);
            let (u2, reward) = rm.step(u, labels);
            demo.actions.push(action as u8);
            demo.cells.push(next as u16);
            demo.labels.push(labels);
            demo.rm_states.push(u2 as u8);
            demo.rewards.push(reward);
            cell = next;
            if rm.is_failure(u2) {
                break;
            }
            if rm.is_terminal(u2) {
                if let Some((start_t, start_cell, start_u)) = trip_start.take() {
                    demo.trips.push(Trip {
                        start_t,
                        end_t: t + 1,
                        start_cell,
                        start_u,
                    });
                }
                u = rm.initial();
                random_left = cfg.random_steps;
            } else {
                u = u2;
            }
            if random_left == 0 && trip_start.is_none() {
                trip_start = Some((t + 1, cell, u));
            }
        }
        demo
    }
}

/// Uniform choice among the set bits of a non-empty mask.
fn pick_bit(mask: u32, rng: &mut ChaCha8Rng) -> usize {
    debug_assert!(mask != 0);
    let mut k = rng.gen_range(0..mask.count_ones());
    let mut m = mask;
    loop {
        let a = m.trailing_zeros();
        if k == 0 {
            return a as usize;
        }
        k -= 1;
        m &= m - 1;
    }
}

/// How demonstrations are made.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DemoConfig {
    pub n_demos: usize,
    /// Episode horizon K.
    pub horizon: usize,
    /// Random steps k after each completed trip.
    pub random_steps: usize,
    pub seed: u64,
}

/// A trip made entirely by the optimal policy, from `start_t` (its first action) to `end_t`
/// (exclusive: the step that completed the task is `end_t − 1`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Trip {
    pub start_t: usize,
    pub end_t: usize,
    pub start_cell: usize,
    /// The perfect machine's state when the trip began.
    pub start_u: usize,
}

impl Trip {
    pub fn len(&self) -> usize {
        self.end_t - self.start_t
    }

    pub fn is_empty(&self) -> bool {
        self.end_t == self.start_t
    }
}

/// One expert episode: the start cell and its labels and, per step t, the action taken, the cell landed on,
/// its labels, the perfect machine's state after the step (before its restart after a
/// completed trip) and the task reward.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Demonstration {
    pub start_cell: usize,
    /// Labels of the start cell, `L(o_0)`.
    pub start_labels: LabelSet,
    pub actions: Vec<u8>,
    pub cells: Vec<u16>,
    pub labels: Vec<LabelSet>,
    pub rm_states: Vec<u8>,
    pub rewards: Vec<f64>,
    /// The optimal trips completed in this episode.
    pub trips: Vec<Trip>,
}

impl Demonstration {
    pub fn len(&self) -> usize {
        self.actions.len()
    }

    pub fn is_empty(&self) -> bool {
        self.actions.is_empty()
    }

    /// The label trace `L(o_0), L(o_1), …, L(o_T)` (the start cell's labels first).
    pub fn label_trace(&self) -> Vec<LabelSet> {
        std::iter::once(self.start_labels)
            .chain(self.labels.iter().copied())
            .collect()
    }

    /// Cell before step t (`o_t`; `o_0` is the start cell).
    pub fn cell_before(&self, t: usize) -> usize {
        if t == 0 {
            self.start_cell
        } else {
            self.cells[t - 1] as usize
        }
    }
}
