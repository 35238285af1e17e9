//! Machine-to-machine transformations.

use super::machine::{RewardMachine, Transition};

/// The machine of a task that restarts when it is completed, as in the paper's expert
/// demonstrations (appendix B: after a completed trip the agent goes on and completes the
/// task again, earning the reward again): every transition into a terminal state goes to the
/// initial state instead (keeping its reward), and the terminal states, now unreachable, are
/// removed. Failure sinks stay absorbing. A machine without terminal states is returned as is.
pub fn restart_on_goal(rm: &RewardMachine) -> RewardMachine {
    if rm.terminal_states().is_empty() {
        return rm.clone();
    }
    // New numbering: the non-terminal states in order.
    let mut new_id = vec![usize::MAX; rm.n_states()];
    let mut n = 0;
    for (u, id) in new_id.iter_mut().enumerate() {
        if !rm.is_terminal(u) {
            *id = n;
            n += 1;
        }
    }
    let initial = new_id[rm.initial()];
    let transitions = rm
        .transitions()
        .iter()
        .map(|t| Transition {
            from: new_id[t.from],
            to: if rm.is_terminal(t.to) {
                initial
            } else {
                new_id[t.to]
            },
            formula: t.formula.clone(),
            reward: t.reward,
        })
        .collect();
    let failure: Vec<usize> = rm.failure_states().iter().map(|&u| new_id[u]).collect();
    RewardMachine::new(rm.vocab().clone(), n, initial, &[], &failure, transitions)
        .expect("renumbering a valid machine keeps it valid")
}
