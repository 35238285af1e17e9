//! Ground-truth evaluation of Office policies, and the greedy policy for a learned reward.
//!
//! A policy is deterministic on the product of the world with a *model* machine (the learned
//! RM for SMIRL, the one-state machine for the baselines): `action[u * n_cells + cell]`. It is
//! rolled out from the start cell for a fixed horizon without reset (as the paper trains),
//! with the task's perfect machine tracking the ground truth alongside. The world and the
//! policy are deterministic, so one rollout is the exact expected return.

use crate::env::office::{OfficeEpisode, OfficeWorld};
use crate::rl::tabular::{policy_iteration, DetMdp, TabularError};
use crate::rm::RewardMachine;

/// Outcome of one ground-truth rollout.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Evaluation {
    /// Sum of the perfect machine's rewards over the horizon.
    pub gt_return: f64,
    /// The task was completed within the horizon.
    pub success: bool,
    /// The task failed (plant) before being completed.
    pub failed: bool,
    /// Steps until completion, when it happened.
    pub steps_to_success: Option<usize>,
}

/// Rolls out `policy` for `horizon` steps: indexed by model product state (stationary, length
/// `|U|·n_cells`) or by time and state (length `horizon·|U|·n_cells`, `t`-major).
pub fn evaluate_policy(
    world: &OfficeWorld,
    model_rm: &RewardMachine,
    policy: &[u8],
    gt_rm: &RewardMachine,
    horizon: usize,
) -> Evaluation {
    let n_cells = world.labels().len();
    let n_prod = model_rm.n_states() * n_cells;
    let stationary = policy.len() == n_prod;
    assert!(
        stationary || policy.len() == horizon * n_prod,
        "policy must cover the model product (per time step or not)"
    );
    let mut episode = OfficeEpisode::new(world, gt_rm, false);
    // The model machine reads the start cell's labels first, as along its training traces.
    let mut u = model_rm.next_state(model_rm.initial(), world.label(world.start()));
    let mut out = Evaluation {
        gt_return: 0.0,
        success: false,
        failed: false,
        steps_to_success: None,
    };
    for t in 0..horizon {
        let offset = if stationary { 0 } else { t * n_prod };
        let a = policy[offset + u * n_cells + episode.cell()] as usize;
        let step = episode.step(a);
        u = model_rm.next_state(u, step.labels);
        out.gt_return += step.reward;
        if step.completed {
            out.success = true;
            out.steps_to_success = Some(t + 1);
        }
        if step.failed {
            out.failed = true;
        }
    }
    out
}

/// The optimal stationary policy of the discounted MDP with `reward` (exact policy
/// iteration). `warm` carries the policy between calls (warm start); pass an empty vector
/// first.
pub fn greedy_policy(
    mdp: &DetMdp,
    reward: &[f64],
    gamma: f64,
    warm: &mut Vec<u8>,
) -> Result<Vec<u8>, TabularError> {
    if warm.len() != mdp.n_states() {
        warm.clear();
        warm.resize(mdp.n_states(), 0);
    }
    policy_iteration(mdp, reward, gamma, warm, 10_000)?;
    Ok(warm.clone())
}
