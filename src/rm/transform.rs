//! Machine-to-machine transformations.

use super::formula::Formula;
use super::labels::{LabelSet, Vocabulary};
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

/// The machine with one more state, a sink, that a proposition of `props` enters from every
/// state `u` with `from[u]` in which no trace of `traces` (read from the initial state) makes
/// it true: what the traces never do in a state leads out of them for good. The sink has no transitions out and
/// is neither terminal nor a failure state — no reward, no end of an episode; what being there
/// is worth is left to whatever learns rewards on the machine. Existing transitions keep
/// priority: a label set one of them takes stays where it went. Returns the machine and the
/// sink's index, `None` (and the machine as is) when every proposition of `props` was seen in
/// every state.
pub fn sink_unseen(
    rm: &RewardMachine,
    traces: &[Vec<LabelSet>],
    props: LabelSet,
    from: &[bool],
) -> (RewardMachine, Option<usize>) {
    assert_eq!(from.len(), rm.n_states(), "one flag per state");
    // seen[u]: the propositions true on some label set read in state u.
    let mut seen = vec![0u32; rm.n_states()];
    for trace in traces {
        let mut u = rm.initial();
        for &labels in trace {
            seen[u] |= labels.0;
            u = rm.next_state(u, labels);
        }
    }
    let sink = rm.n_states();
    let mut transitions = rm.transitions().to_vec();
    for (u, &seen_u) in seen.iter().enumerate() {
        if !from[u] || rm.is_terminal(u) || rm.is_failure(u) {
            continue;
        }
        let unseen: Vec<Formula> = (0..rm.vocab().len())
            .filter(|&p| props.contains(p) && seen_u & (1 << p) == 0)
            .map(Formula::Prop)
            .collect();
        let taken: Vec<Formula> = rm
            .transitions()
            .iter()
            .filter(|t| t.from == u)
            .map(|t| t.formula.clone())
            .collect();
        let formula = match (disjunction(unseen), disjunction(taken)) {
            (None, _) => continue,
            (Some(unseen), None) => unseen,
            (Some(unseen), Some(taken)) => {
                Formula::And(vec![unseen, Formula::Not(Box::new(taken))])
            }
        };
        // Every such label set already taken (a `True` guard): nothing left to sink.
        if !rm.vocab().all_label_sets().any(|l| formula.eval(l)) {
            continue;
        }
        transitions.push(Transition {
            from: u,
            to: sink,
            formula,
            reward: 0.0,
        });
    }
    if transitions.len() == rm.transitions().len() {
        return (rm.clone(), None);
    }
    let machine = RewardMachine::new(
        rm.vocab().clone(),
        sink + 1,
        rm.initial(),
        &rm.terminal_states(),
        &rm.failure_states(),
        transitions,
    )
    .expect("a sink entered only on label sets no transition takes keeps the machine valid");
    (machine, Some(sink))
}

/// `a | b | …` without the one-term wrapper; `None` for no terms.
fn disjunction(mut terms: Vec<Formula>) -> Option<Formula> {
    match terms.len() {
        0 => None,
        1 => terms.pop(),
        _ => Some(Formula::Or(terms)),
    }
}
