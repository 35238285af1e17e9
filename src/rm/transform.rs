//! Machine-to-machine transformations.

use super::formula::Formula;
use super::labels::Vocabulary;
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

/// The same machine read over a larger vocabulary `vocab` (e.g. a world's letters, in the
/// world's bit order): every formula names the same propositions, so the machine ignores the
/// letters it did not have. `Err(p)`: proposition `p` of the machine is not in `vocab`. A
/// machine already over `vocab` is returned as is.
pub fn over_vocabulary(rm: &RewardMachine, vocab: &Vocabulary) -> Result<RewardMachine, char> {
    if rm.vocab() == vocab {
        return Ok(rm.clone());
    }
    let index: Vec<usize> = rm
        .vocab()
        .props()
        .iter()
        .map(|&p| vocab.index_of(p).map_err(|_| p))
        .collect::<Result<_, char>>()?;
    fn renamed(f: &Formula, index: &[usize]) -> Formula {
        match f {
            Formula::True => Formula::True,
            Formula::False => Formula::False,
            Formula::Prop(p) => Formula::Prop(index[*p]),
            Formula::Not(g) => Formula::Not(Box::new(renamed(g, index))),
            Formula::And(gs) => Formula::And(gs.iter().map(|g| renamed(g, index)).collect()),
            Formula::Or(gs) => Formula::Or(gs.iter().map(|g| renamed(g, index)).collect()),
        }
    }
    let transitions = rm
        .transitions()
        .iter()
        .map(|t| Transition {
            formula: renamed(&t.formula, &index),
            ..t.clone()
        })
        .collect();
    Ok(RewardMachine::new(
        vocab.clone(),
        rm.n_states(),
        rm.initial(),
        &rm.terminal_states(),
        &rm.failure_states(),
        transitions,
    )
    .expect("formulas over the same propositions keep a valid machine valid"))
}
