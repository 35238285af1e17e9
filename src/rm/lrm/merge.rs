//! Post-processing of a learned machine: merging states that the rewards cannot tell apart.
//!
//! The LRM objective rewards predicting the next label, so the search splits states of the
//! task into sub-states that predict, e.g., which letter the expert's path crosses next
//! (the paper's learned Office task-3 machine had 6 states for 4). Those extra states pay the
//! same rewards as the state they split. We merge them back, RPNI-style, with the observed
//! rewards as the outputs:
//!
//! - A cell `(u, l)` is *defined* when the traces read `l` in `u` (its target and mean reward
//!   are then observed), or when `u = delta(v, l) != v` for some defined `(v, l)` (then
//!   `u` stays on `l` with reward 0: the stutter invariance the search keeps). All other
//!   cells are "don't care": no trace says what they do.
//! - Merging two states merges their defined cells; two defined cells on the same label
//!   must have the same mean reward (else the merge is refused) and their targets are merged
//!   in turn (so the quotient stays deterministic), recursively.
//! - With `fill_unobserved` off (the default of the learner) a cell without observations
//!   counts as what the machine does there, stay with reward 0, so only states with the same
//!   reward behaviour merge and the quotient is equivalent to the learned machine (Mealy
//!   minimisation, with "don't care" only for the implied stays). With it on, an unobserved
//!   cell takes whatever the other state does: fewer states, but a sub-goal never seen in a
//!   state may start paying there (over-generalisation when the traces lack
//!   counter-examples: measured on Reacher Sequential, where the state after red never sees
//!   yellow).
//! - States are tried in pairs `(p, q)`, `p < q`, in the search's breadth-first numbering,
//!   and passes repeat until no merge succeeds.
//!
//! By construction the quotient pays exactly the observed rewards on every trace (every step
//! of a trace reads a defined cell, and the quotient's state is the block of the learned
//! state), keeps the stutter invariance, and is never larger than the learned machine. What
//! it generalises is only what no trace contradicts: a distinction of states that no reward
//! in the data depends on is dropped.

use crate::rm::equiv::REWARD_TOL;

#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Cell {
    /// Target state (an original state id; compare blocks with `find`).
    pub target: usize,
    pub reward: f64,
    /// Number of observations behind `reward` (0 for an implied stay).
    pub weight: f64,
}

#[derive(Clone)]
struct Partition {
    parent: Vec<usize>,
    /// Merged cells of each block, at the block's root: `cells[root * L + l]`.
    cells: Vec<Option<Cell>>,
}

impl Partition {
    fn find(&self, mut u: usize) -> usize {
        while self.parent[u] != u {
            u = self.parent[u];
        }
        u
    }
}

/// Merges reward-compatible states of a machine with `n` states over `l_n` labels whose
/// defined cells are `cells[u * l_n + l]`. Returns the block of each state (block ids are
/// the smallest state of each block) and the merged cells indexed by block root.
pub(crate) fn merge_states(
    n: usize,
    l_n: usize,
    cells: Vec<Option<Cell>>,
    fill_unobserved: bool,
) -> (Vec<usize>, Vec<Option<Cell>>) {
    let mut part = Partition {
        parent: (0..n).collect(),
        cells,
    };
    loop {
        let mut merged_any = false;
        for q in 1..n {
            for p in 0..q {
                if part.find(p) == part.find(q) {
                    continue;
                }
                if let Some(next) = try_merge(&part, l_n, p, q, fill_unobserved) {
                    part = next;
                    merged_any = true;
                }
            }
        }
        if !merged_any {
            break;
        }
    }
    let blocks = (0..n).map(|u| part.find(u)).collect();
    (blocks, part.cells)
}

/// Gives each event cell that no trace reads the state the traces reach when the event comes
/// *before* the touch that entered the state (see [`LrmConfig::commute_events`]): for a state
/// `u` entered from `p` on an observed label `k` without an event, and an event label `l`
/// undefined in `u`, the candidate is `delta(delta(p, l), k)`, where `(p, l)` is observed
/// and `(delta(p, l), k)` observed: a stay that stutter invariance implies for an unobserved
/// cell says nothing about where the touch leads after the event, so it gives no candidate. An
/// entry counts only where the traces show the event to change what follows: `delta(p, l)`
/// and the state `p` reaches on `l` without its events (`without_events[l]`; `p` itself when
/// `p` never reads that set) must not be [`observed_equivalence`]-equivalent. An event whose
/// state the demonstrations leave exactly as they leave the state without it (the cancel of a
/// task that ignores it, read as a split of "after red") shows no effect to carry over. The
/// cell is filled only when every counted entry into `u` that gives a candidate gives the
/// same one. Decided on the cells as given, so the order of states does not matter; observed
/// cells and every trace's path are unchanged.
///
/// [`LrmConfig::commute_events`]: super::LrmConfig::commute_events
pub(crate) fn commute_events(
    n: usize,
    l_n: usize,
    cells: &mut [Option<Cell>],
    events: &[usize],
    without_events: &[Option<usize>],
) {
    // Read from the cells as given, so a filled cell never feeds another fill.
    let given = cells.to_vec();
    let given = &given;
    let observed = move |w: usize, k: usize| given[w * l_n + k].filter(|c| c.weight > 0.0);
    let class = observed_equivalence(n, l_n, given);
    let class = &class;
    // Whether the event label `l` read in `p` leads to a state that the traces leave
    // otherwise than the state `p` reaches on `l` without its events.
    let shows_effect = move |p: usize, l: usize, q: usize| {
        let plain = without_events[l]
            .and_then(|k0| observed(p, k0))
            .map_or(p, |c| c.target);
        class[q] != class[plain]
    };
    for u in 0..n {
        for &l in events {
            if given[u * l_n + l].is_some() {
                continue;
            }
            let mut candidates = (0..n).filter(|&p| p != u).flat_map(|p| {
                (0..l_n)
                    .filter(|k| !events.contains(k))
                    .filter(move |&k| observed(p, k).is_some_and(|c| c.target == u))
                    .filter_map(move |k| {
                        let q = observed(p, l)?.target;
                        if !shows_effect(p, l, q) {
                            return None;
                        }
                        // Only what the traces show after `q`: the stay that stutter
                        // invariance implies for an unobserved cell is no evidence of where
                        // the touch leads once the event has come.
                        observed(q, k).map(|c| c.target)
                    })
            });
            let Some(first) = candidates.next() else {
                continue;
            };
            // A stay is what an undefined cell already does; defining it would only take the
            // cell away from the guards' generalisation.
            if first != u && candidates.all(|v| v == first) {
                cells[u * l_n + l] = Some(Cell {
                    target: first,
                    reward: 0.0,
                    weight: 0.0,
                });
            }
        }
    }
}

/// The coarsest equivalence of states under which equivalent states leave on the same
/// observed labels to equivalent states (a bisimulation of the observed cells that move: a
/// stay and an unobserved cell do not count): `class[u]` is `u`'s class. Two states that the
/// traces leave in the same way, such as two copies of "after red" told apart only by whether
/// a cancel came during the touch, are equivalent; states that the traces leave on different
/// labels, or on the same label to inequivalent states, are not.
pub(crate) fn observed_equivalence(n: usize, l_n: usize, cells: &[Option<Cell>]) -> Vec<usize> {
    let moves = |u: usize, l: usize| {
        cells[u * l_n + l]
            .filter(|c| c.weight > 0.0 && c.target != u)
            .map(|c| c.target)
    };
    let mut class = vec![0usize; n];
    loop {
        // Each state's signature under the current classes; equal signatures, one class.
        let signatures: Vec<(usize, Vec<Option<usize>>)> = (0..n)
            .map(|u| {
                (
                    class[u],
                    (0..l_n).map(|l| moves(u, l).map(|v| class[v])).collect(),
                )
            })
            .collect();
        let mut distinct: Vec<&(usize, Vec<Option<usize>>)> = Vec::new();
        let next: Vec<usize> = signatures
            .iter()
            .map(|s| match distinct.iter().position(|d| *d == s) {
                Some(k) => k,
                None => {
                    distinct.push(s);
                    distinct.len() - 1
                }
            })
            .collect();
        // Refinement only splits classes, so an unchanged count is the fixed point.
        let stable = distinct.len() == class.iter().max().map_or(0, |m| m + 1);
        class = next;
        if stable {
            return class;
        }
    }
}

/// Gives each event cell of the initial state that no trace reads the state the traces reach
/// when the event comes on the first step together with the label that left the initial
/// state (see [`LrmConfig::initial_events`]): for an event label `l` undefined in state 0,
/// with `k` = the label id of `l`'s set without its events (`without_events[l]`), the cell
/// becomes `delta(delta(0, k), l)` when `(0, k)` is observed and leaves state 0 and
/// `(delta(0, k), l)` is defined. Only when no other state enters state 0: the initial state
/// is then "before the first label" (the initial-state split's), whose events the
/// demonstrations show only if a cancel fired on their first step. Decided on the cells as
/// given; observed cells and every trace's path are unchanged.
///
/// [`LrmConfig::initial_events`]: super::LrmConfig::initial_events
pub(crate) fn initial_events(
    n: usize,
    l_n: usize,
    cells: &mut [Option<Cell>],
    events: &[usize],
    without_events: &[Option<usize>],
) {
    let given = cells.to_vec();
    let observed = |w: usize, k: usize| given[w * l_n + k].filter(|c| c.weight > 0.0);
    let reentered = (1..n).any(|p| (0..l_n).any(|k| observed(p, k).is_some_and(|c| c.target == 0)));
    if reentered {
        return;
    }
    for &l in events {
        if given[l].is_some() {
            continue;
        }
        let Some(k) = without_events[l] else {
            continue;
        };
        let Some(first) = observed(0, k).map(|c| c.target).filter(|&v| v != 0) else {
            continue;
        };
        if let Some(c) = given[first * l_n + l] {
            cells[l] = Some(Cell {
                target: c.target,
                reward: 0.0,
                weight: 0.0,
            });
        }
    }
}

fn try_merge(
    part: &Partition,
    l_n: usize,
    p: usize,
    q: usize,
    fill_unobserved: bool,
) -> Option<Partition> {
    let mut part = part.clone();
    let mut pending = vec![(p, q)];
    while let Some((a, b)) = pending.pop() {
        let (ra, rb) = (part.find(a), part.find(b));
        if ra == rb {
            continue;
        }
        let (root, other) = (ra.min(rb), ra.max(rb));
        for l in 0..l_n {
            let x = part.cells[root * l_n + l];
            let y = part.cells[other * l_n + l];
            let merged = match (x, y) {
                (Some(x), Some(y)) => {
                    if (x.reward - y.reward).abs() > REWARD_TOL {
                        return None;
                    }
                    pending.push((x.target, y.target));
                    let w = x.weight + y.weight;
                    let reward = if w > 0.0 {
                        (x.reward * x.weight + y.reward * y.weight) / w
                    } else {
                        x.reward
                    };
                    Some(Cell {
                        target: x.target,
                        reward,
                        weight: w,
                    })
                }
                // One side has no observation: without `fill_unobserved` it does what a
                // missing transition does (stay, reward 0), so the other must do the same.
                (Some(x), None) => {
                    if !fill_unobserved && (x.reward != 0.0 || part.find(x.target) != root) {
                        return None;
                    }
                    Some(x)
                }
                (None, Some(y)) => {
                    if !fill_unobserved && (y.reward != 0.0 || part.find(y.target) != other) {
                        return None;
                    }
                    Some(y)
                }
                (None, None) => None,
            };
            part.cells[root * l_n + l] = merged;
            part.cells[other * l_n + l] = None;
        }
        part.parent[other] = root;
    }
    Some(part)
}

#[cfg(test)]
mod tests {
    use super::*;

    // Labels: 0 = {r}, 1 = {c} (the event), 2 = {g}.
    const L_N: usize = 3;
    const EVENTS: [usize; 1] = [1];

    fn seen(target: usize) -> Option<Cell> {
        Some(Cell {
            target,
            reward: 0.0,
            weight: 1.0,
        })
    }

    fn cells(n: usize, observed: &[(usize, usize, usize)]) -> Vec<Option<Cell>> {
        let mut cells = vec![None; n * L_N];
        for &(u, l, v) in observed {
            cells[u * L_N + l] = seen(v);
        }
        cells
    }

    /// 0 -r-> 1, 0 -c-> 2, 2 -r-> 3: "r, then c" is read as "c, then r".
    #[test]
    fn an_unseen_event_goes_where_the_event_before_the_touch_goes() {
        let mut c = cells(5, &[(0, 0, 1), (0, 1, 2), (2, 0, 3)]);
        commute_events(5, L_N, &mut c, &EVENTS, &[None; L_N]);
        assert_eq!(c[L_N + 1].map(|c| (c.target, c.weight)), Some((3, 0.0)));
        // Observed cells and cells of other labels are untouched; state 3 has no entry whose
        // commuted path is defined.
        assert_eq!(c[0], seen(1));
        assert_eq!(c[L_N + 2], None);
        assert_eq!(c[3 * L_N + 1], None);
    }

    /// Two entries into 1 (on r and on g) whose commuted paths end in different states: no
    /// evidence which one holds, the cell stays undefined.
    #[test]
    fn entries_that_disagree_leave_the_cell_undefined() {
        let observed = [(0, 0, 1), (0, 2, 1), (0, 1, 2), (2, 0, 3), (2, 2, 4)];
        let mut c = cells(5, &observed);
        commute_events(5, L_N, &mut c, &EVENTS, &[None; L_N]);
        assert_eq!(c[L_N + 1], None);
        // When they agree, it is filled.
        let observed = [(0, 0, 1), (0, 2, 1), (0, 1, 2), (2, 0, 3), (2, 2, 3)];
        let mut c = cells(5, &observed);
        commute_events(5, L_N, &mut c, &EVENTS, &[None; L_N]);
        assert_eq!(c[L_N + 1].map(|c| c.target), Some(3));
    }

    /// Initial events, with label 2 read as the empty set ({c} without its event): the
    /// split's initial state 0 leaves on it for 1, where the cancel leads to 2; a cancel on
    /// the first step is read the same way.
    const WITHOUT_EVENTS: [Option<usize>; L_N] = [None, Some(2), None];

    #[test]
    fn a_first_step_event_is_read_as_after_the_first_label() {
        let mut c = cells(4, &[(0, 2, 1), (1, 1, 2), (1, 0, 3)]);
        initial_events(4, L_N, &mut c, &EVENTS, &WITHOUT_EVENTS);
        assert_eq!(c[1].map(|c| (c.target, c.weight)), Some((2, 0.0)));
        // Only the initial state's event cells: state 1's and the touches' are untouched.
        assert_eq!(c[0], None);
        assert_eq!(c[L_N + 1], seen(2));
        // An event the traces do show on the first step keeps its observed target.
        let mut c = cells(4, &[(0, 2, 1), (0, 1, 3), (1, 1, 2)]);
        initial_events(4, L_N, &mut c, &EVENTS, &WITHOUT_EVENTS);
        assert_eq!(c[1], seen(3));
    }

    /// A state that re-enters the initial state makes it more than "before the first label":
    /// nothing is filled. Neither is a cell whose path after the first label is undefined.
    #[test]
    fn a_re_entered_initial_state_or_an_undefined_path_is_left_alone() {
        let mut c = cells(4, &[(0, 2, 1), (1, 1, 2), (2, 0, 0)]);
        initial_events(4, L_N, &mut c, &EVENTS, &WITHOUT_EVENTS);
        assert_eq!(c[1], None);
        let mut c = cells(4, &[(0, 2, 1), (1, 0, 3)]);
        initial_events(4, L_N, &mut c, &EVENTS, &WITHOUT_EVENTS);
        assert_eq!(c[1], None);
    }

    /// 0 -r-> 1 and 0 -rc-> 2, both left on g for 3, and 2 seen staying on r: the cancel
    /// during red changes nothing the traces show next, so it is not carried into 1; when 2 is
    /// left for another state that the traces leave otherwise (4 -r-> 1, where 3 stays), it is.
    #[test]
    fn an_event_that_changes_nothing_that_follows_is_not_commuted() {
        // Labels: 0 = r, 1 = rc, 2 = g; rc without its event is r.
        let without = [None, Some(0), None];
        let mut c = cells(5, &[(0, 0, 1), (0, 1, 2), (1, 2, 3), (2, 2, 3), (2, 0, 2)]);
        commute_events(5, L_N, &mut c, &EVENTS, &without);
        assert_eq!(c[L_N + 1], None);
        let mut c = cells(
            5,
            &[
                (0, 0, 1),
                (0, 1, 2),
                (1, 2, 3),
                (2, 2, 4),
                (4, 0, 1),
                (2, 0, 2),
            ],
        );
        commute_events(5, L_N, &mut c, &EVENTS, &without);
        assert_eq!(c[L_N + 1].map(|c| c.target), Some(2));
    }

    /// The same entry with 2's cell on r unobserved, a stay that stutter invariance implies
    /// (weight 0): it shows nothing of where r leads after the cancel, so nothing is filled.
    #[test]
    fn an_implied_stay_gives_no_candidate() {
        let without = [None, Some(0), None];
        let mut c = cells(5, &[(0, 0, 1), (0, 1, 2), (1, 2, 3), (2, 2, 4), (4, 0, 1)]);
        c[2 * L_N] = Some(Cell {
            target: 2,
            reward: 0.0,
            weight: 0.0,
        });
        commute_events(5, L_N, &mut c, &EVENTS, &without);
        assert_eq!(c[L_N + 1], None);
    }

    /// Copies of a state that the traces leave alike are one class; a state left on another
    /// label, or on the same label to a state of another class, is not.
    #[test]
    fn observed_equivalence_joins_states_the_traces_leave_alike() {
        let c = cells(
            6,
            &[
                (0, 0, 1),
                (0, 1, 2),
                (1, 2, 3),
                (2, 2, 3),
                (3, 0, 5),
                (4, 2, 5),
            ],
        );
        let class = observed_equivalence(6, L_N, &c);
        assert_eq!(class[1], class[2]);
        // 4 is left on g like 1 and 2, but for 5, which is not 3's class (3 moves on r).
        assert_ne!(class[4], class[1]);
        assert_ne!(class[0], class[1]);
        // A stay does not count as leaving: 3 with an observed stay on g is still 3's class.
        let mut stay = c.clone();
        stay[3 * L_N + 2] = seen(3);
        assert_eq!(observed_equivalence(6, L_N, &stay), class);
    }

    /// An event that stays where it was seen (0 -c-> 0) commutes to a stay in 1: what an
    /// undefined cell already does, so it is not defined (the guards stay free there).
    #[test]
    fn a_commuted_stay_is_not_written() {
        let mut c = cells(2, &[(0, 0, 1), (0, 1, 0)]);
        commute_events(2, L_N, &mut c, &EVENTS, &[None; L_N]);
        assert_eq!(c[L_N + 1], None);
    }
}
