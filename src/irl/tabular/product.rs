//! MaxEnt IRL on the product of the Office world with a model reward machine.
//!
//! SMIRL (paper Algorithm 1) runs it with the machine learned from the demonstrations; the
//! MaxEnt IRL baseline runs it with the one-state machine, i.e. on observations (cells) only.
//! The reward is `δ_r(u, o) = w_uᵀ L(o)` (paper eq. 10): one weight per (machine state,
//! proposition), paid on the step that lands on cell `o` while the machine is in `u` (the
//! machine then moves on to `δ_u(u, L(o))`, as a reward machine pays on its transitions).
//! Office cells carry at most one proposition, so `L(o)` is one-hot or zero and the features
//! are one-hot (index `u * |P| + p`). The paper's ninth "no label" feature is left out: under
//! MaxEnt every demonstration step has exactly one of the nine features, so that weight only
//! shifts all rewards by a constant and is not identifiable.

use super::demos::Demonstration;
use super::maxent::{
    MaxEntConfig, MaxEntError, MaxEntIrl, StateActionDemo, StateActionFeatures, NO_FEATURE,
};
use crate::env::office::{OfficeWorld, N_ACTIONS};
use crate::rl::tabular::{DetMdp, TabularError};
use crate::rm::{RewardMachine, Vocabulary};

/// The one-state machine (no structure): the product is the world itself.
pub fn trivial_rm(vocab: &Vocabulary) -> RewardMachine {
    RewardMachine::new(vocab.clone(), 1, 0, &[], &[], Vec::new())
        .expect("a one-state machine without transitions is well formed")
}

/// World × model machine, with the label features of δ_r.
#[derive(Clone, Debug)]
pub struct ProductIrl {
    pub model_rm: RewardMachine,
    pub mdp: DetMdp,
    pub features: StateActionFeatures,
    n_cells: usize,
    n_props: usize,
}

impl ProductIrl {
    pub fn new(world: &OfficeWorld, model_rm: RewardMachine) -> Result<ProductIrl, TabularError> {
        let n_cells = world.labels().len();
        let n_props = world.vocab().len();
        let mdp = DetMdp::product(
            world.transition_table(),
            N_ACTIONS,
            world.labels(),
            &model_rm,
        )?;
        let mut feature = vec![NO_FEATURE; mdp.n_pairs()];
        for u in 0..model_rm.n_states() {
            for c in 0..n_cells {
                for a in 0..N_ACTIONS {
                    let labels = world.label(world.step(c, a));
                    if let Some(p) = (0..n_props).find(|&p| labels.contains(p)) {
                        feature[(u * n_cells + c) * N_ACTIONS + a] = (u * n_props + p) as u32;
                    }
                }
            }
        }
        let features = StateActionFeatures {
            n_features: model_rm.n_states() * n_props,
            feature,
        };
        Ok(ProductIrl {
            model_rm,
            mdp,
            features,
            n_cells,
            n_props,
        })
    }

    /// Product state of `(u, cell)`.
    pub fn state(&self, u: usize, cell: usize) -> usize {
        u * self.n_cells + cell
    }

    /// The product start state on `start_cell`: the model machine has read the start
    /// cell's labels `L(o_0)` (as in the label traces it was learned from).
    pub fn start_state(&self, world: &OfficeWorld, start_cell: usize) -> usize {
        let u = self
            .model_rm
            .next_state(self.model_rm.initial(), world.label(start_cell));
        self.state(u, start_cell)
    }

    /// Annotates demonstrations with the model machine's states (run along their label
    /// traces from `L(o_0)`): the `(u_t, o_t)` product state and action of every step.
    pub fn annotate(&self, demos: &[Demonstration]) -> Vec<StateActionDemo> {
        demos
            .iter()
            .map(|d| {
                let mut u = self
                    .model_rm
                    .next_state(self.model_rm.initial(), d.start_labels);
                (0..d.len())
                    .map(|t| {
                        let s = self.state(u, d.cell_before(t));
                        u = self.model_rm.next_state(u, d.labels[t]);
                        (s as u32, d.actions[t])
                    })
                    .collect()
            })
            .collect()
    }

    /// A MaxEnt IRL run on the annotated demonstrations (θ starts at 0).
    pub fn maxent<'a>(
        &'a self,
        annotated: &[StateActionDemo],
        cfg: MaxEntConfig,
    ) -> Result<MaxEntIrl<'a>, MaxEntError> {
        MaxEntIrl::new(&self.mdp, &self.features, annotated, cfg)
    }

    /// θ as a table: one row per machine state, one column per proposition.
    pub fn weight_rows(&self, theta: &[f64]) -> Vec<Vec<f64>> {
        theta.chunks(self.n_props).map(|r| r.to_vec()).collect()
    }
}
