//! Guards for label sets the demonstrations never showed in a state.
//!
//! LRM's machine is a table over the *observed* (state, label set) cells; every other cell
//! means "stay". An agent meets combinations the expert never produced — the cancel firing
//! while the fingertip is on red (`{r, c}`) in a state where only `{r}` and `{c}` were seen,
//! or the cancel after red in a state where only `{r, c}` was seen — and "stay" then keeps
//! asking for blue, a failure once the cancel has fired. On the development range no IF or
//! Composite machine read with "stay" tracks its task, against 112 and 37 of 113 with trees
//! (`experiments/lrm/ablation.md`).
//!
//! [`Guards::Tree`] replaces the exact guards of each state by a decision tree over the
//! propositions, fitted to that state's defined cells (observed cells, and the stays implied
//! by stutter invariance, as in `merge.rs`). A tree agrees with the table on every defined
//! cell, so the learned machine's behaviour on the demonstrations (and its LRM cost) is
//! unchanged; an unseen label set follows the tree, i.e. it is read by the propositions that
//! decided the transitions the state was seen to take. Splits maximise the information gain
//! over the distinct defined label sets, with one rule ahead of the gain:
//!
//! **Events first, where they matter.** The task declares which propositions are *events*,
//! true on a single step by construction ([`LrmConfig::events`](super::LrmConfig::events);
//! Reacher's cancel `c`, while a ball proposition holds as long as the fingertip touches the
//! ball). In a state whose defined cells show an event to matter — two defined label sets
//! that differ only by it lead to different targets — an informative split on it is taken
//! before any split on another proposition, so an unseen label set holding it is read as
//! that event. Assumption: where an event is shown to change the state, it overrides what
//! the lasting propositions of the same step say ("unless" semantics: IF's `{b, c}` is the
//! cancel, not blue). Where the cells show it changes nothing (OR's and Sequential's cancel)
//! or show nothing about it, it is one proposition among the others and an unseen `{g, c}`
//! is read by its ball. Reason for reading it first: an event is gone on the
//! next step, a lasting proposition is still true then and the machine reads it on that
//! step; reading the event first loses nothing, reading the other first loses the event for
//! good. The hand-written IF and Composite machines make the same choice (`c` before
//! `b&!c`). Declared, not inferred: measured on the Reacher demonstrations, "never true on
//! two consecutive steps" also holds for red (the fingertip flickers at the 2 cm contact
//! radius while the IF expert waits there) and for the final ball (the episode ends on it).
//!
//! Ties (equal gain) go to the lower proposition index, so the result is deterministic.

use super::merge::Cell;
use crate::rm::formula::Formula;
use crate::rm::labels::{LabelSet, Vocabulary};
use crate::rm::machine::{RewardMachine, Transition};

/// How the learned machine reads label sets that no demonstration showed in a state.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Guards {
    /// LRM's reading: each transition is guarded by the exact observed label sets; any
    /// other label set leaves the state unchanged.
    #[default]
    Exact,
    /// A decision tree per state over the propositions, events first (see the module docs).
    Tree,
}

impl Guards {
    pub fn name(self) -> &'static str {
        match self {
            Guards::Exact => "exact",
            Guards::Tree => "tree",
        }
    }
}

/// One state's tree: a leaf is a (target, reward) class.
enum Node {
    Leaf(usize),
    Split {
        prop: usize,
        yes: Box<Node>,
        no: Box<Node>,
    },
}

/// Shannon entropy (nats) of the class counts of `samples`.
fn entropy(samples: &[(LabelSet, usize)], n_classes: usize) -> f64 {
    let mut counts = vec![0usize; n_classes];
    for &(_, c) in samples {
        counts[c] += 1;
    }
    let n = samples.len() as f64;
    counts
        .iter()
        .filter(|&&k| k > 0)
        .map(|&k| {
            let p = k as f64 / n;
            -p * p.ln()
        })
        .sum()
}

fn fit(samples: &[(LabelSet, usize)], n_props: usize, events: u32, n_classes: usize) -> Node {
    let first = samples[0].1;
    if samples.iter().all(|&(_, c)| c == first) {
        return Node::Leaf(first);
    }
    let h = entropy(samples, n_classes);
    // (informative split on an event, gain, proposition): an event first, then the larger
    // gain; ties keep the lower proposition.
    let mut best: Option<(bool, f64, usize)> = None;
    for prop in 0..n_props {
        let (yes, no): (Vec<_>, Vec<_>) = samples.iter().partition(|(l, _)| l.contains(prop));
        if yes.is_empty() || no.is_empty() {
            continue;
        }
        let n = samples.len() as f64;
        let gain = h
            - yes.len() as f64 / n * entropy(&yes, n_classes)
            - no.len() as f64 / n * entropy(&no, n_classes);
        let event = events >> prop & 1 == 1 && gain > 1e-12;
        let better = match best {
            None => true,
            Some((e, g, _)) => (event && !e) || (event == e && gain > g + 1e-12),
        };
        if better {
            best = Some((event, gain, prop));
        }
    }
    // Distinct label sets with different classes differ in some proposition, so an impure
    // sample always has a split with both sides non-empty.
    let (_, _, prop) = best.expect("an impure set of distinct label sets has a split");
    let (yes, no): (Vec<_>, Vec<_>) = samples.iter().partition(|(l, _)| l.contains(prop));
    Node::Split {
        prop,
        yes: Box::new(fit(&yes, n_props, events, n_classes)),
        no: Box::new(fit(&no, n_props, events, n_classes)),
    }
}

/// The events among `events` that the state's defined cells show to matter: an event `e`
/// matters when two defined label sets `l` and `l ∪ {e}` (`e ∉ l`) lead to different
/// (target, reward) classes. Only those are read first; an event the cells show to change
/// nothing (the cancel of a task that ignores it) or show nothing about is one proposition
/// among the others.
fn events_that_matter(samples: &[(LabelSet, usize)], events: u32) -> u32 {
    let mut out = 0;
    for &(l, c) in samples {
        let with = l.0 & events;
        if with == 0 {
            continue;
        }
        for e in (0..32).filter(|&e| with >> e & 1 == 1) {
            let without = l.0 & !(1 << e);
            if samples.iter().any(|&(m, d)| m.0 == without && d != c) {
                out |= 1 << e;
            }
        }
    }
    out
}

/// Collects (path conjunction, class) for every leaf.
fn leaves(node: &Node, path: &mut Vec<Formula>, out: &mut Vec<(Formula, usize)>) {
    match node {
        Node::Leaf(c) => {
            let f = match path.len() {
                0 => Formula::True,
                1 => path[0].clone(),
                _ => Formula::And(path.clone()),
            };
            out.push((f, *c));
        }
        Node::Split { prop, yes, no } => {
            path.push(Formula::Prop(*prop));
            leaves(yes, path, out);
            path.pop();
            path.push(Formula::Not(Box::new(Formula::Prop(*prop))));
            leaves(no, path, out);
            path.pop();
        }
    }
}

/// The machine over `n` states whose state `u` follows a tree fitted to its defined cells
/// `cells[u * labels.len() + l]` (observed label set `labels[l]`); a state without defined
/// cells stays on everything.
pub(crate) fn tree_machine(
    vocab: &Vocabulary,
    labels: &[LabelSet],
    n: usize,
    cells: &[Option<Cell>],
    events: u32,
) -> RewardMachine {
    let l_n = labels.len();
    let mut transitions = Vec::new();
    for u in 0..n {
        // Classes: distinct (target, reward) pairs of the state's defined cells.
        let mut classes: Vec<(usize, f64)> = Vec::new();
        let mut samples: Vec<(LabelSet, usize)> = Vec::new();
        for (l, &ls) in labels.iter().enumerate() {
            let Some(c) = cells[u * l_n + l] else {
                continue;
            };
            let k = match classes
                .iter()
                .position(|&(t, r)| t == c.target && r.to_bits() == c.reward.to_bits())
            {
                Some(k) => k,
                None => {
                    classes.push((c.target, c.reward));
                    classes.len() - 1
                }
            };
            samples.push((ls, k));
        }
        if samples.is_empty() {
            continue;
        }
        let tree = fit(
            &samples,
            vocab.len(),
            events_that_matter(&samples, events),
            classes.len(),
        );
        let mut found = Vec::new();
        leaves(&tree, &mut Vec::new(), &mut found);
        for (k, &(target, reward)) in classes.iter().enumerate() {
            if target == u && reward == 0.0 {
                continue;
            }
            let mut fs: Vec<Formula> = found
                .iter()
                .filter(|(_, c)| *c == k)
                .map(|(f, _)| f.clone())
                .collect();
            let formula = if fs.len() == 1 {
                fs.pop().expect("one leaf")
            } else {
                Formula::Or(fs)
            };
            transitions.push(Transition {
                from: u,
                to: target,
                formula,
                reward,
            });
        }
    }
    RewardMachine::new(vocab.clone(), n.max(1), 0, &[], &[], transitions)
        .expect("the leaves of one tree are disjoint and the targets are states")
}

#[cfg(test)]
mod tests {
    use super::*;

    const R: u32 = 1;
    const B: u32 = 1 << 2;
    const C: u32 = 1 << 4;

    fn vocab() -> Vocabulary {
        Vocabulary::new("rgbyc")
    }

    /// One state (0) of a machine with `n` states, defined on `seen` (label set, target).
    fn machine(n: usize, seen: &[(u32, usize)], events: u32) -> RewardMachine {
        let labels: Vec<LabelSet> = seen.iter().map(|&(l, _)| LabelSet(l)).collect();
        let mut cells = vec![None; n * labels.len()];
        for (k, &(_, target)) in seen.iter().enumerate() {
            cells[k] = Some(Cell {
                target,
                reward: 0.0,
                weight: 1.0,
            });
        }
        tree_machine(&vocab(), &labels, n, &cells, events)
    }

    #[test]
    fn an_unseen_set_holding_an_event_is_read_as_the_event() {
        // IF's start state: red (wait there), blue and the cancel each seen alone.
        let seen = [(0, 0), (R, 1), (B, 2), (C, 3)];
        let rm = machine(4, &seen, C);
        assert_eq!(rm.next_state(0, LabelSet(R | C)), 3);
        // Without the event rule the tie goes to the lower proposition (red): the cancel
        // would be lost.
        assert_eq!(machine(4, &seen, 0).next_state(0, LabelSet(R | C)), 1);
    }

    #[test]
    fn an_event_seen_only_with_another_proposition_is_read_alone() {
        // Composite after red: the cancel was seen only while on red.
        let seen = [(0, 0), (R, 0), (B, 1), (R | C, 1)];
        let rm = machine(2, &seen, C);
        assert_eq!(rm.next_state(0, LabelSet(C)), 1);
        assert_eq!(rm.next_state(0, LabelSet(R)), 0);
    }

    /// OR's and Sequential's start state: the cancel seen alone and with red, changing
    /// nothing either time ({c} stays as {} does, {r, c} goes where {r} goes). An unseen
    /// {g, c} is then read by its ball, not as the cancel: the cells show the event does not
    /// matter here, so it is not read first.
    #[test]
    fn an_event_the_cells_show_to_change_nothing_is_not_read_first() {
        const G: u32 = 1 << 1;
        let seen = [(0, 0), (C, 0), (R, 1), (R | C, 1), (G, 2)];
        let rm = machine(3, &seen, C);
        assert_eq!(rm.next_state(0, LabelSet(G | C)), 2);
        assert_eq!(rm.next_state(0, LabelSet(B | C)), 0);
        // A state where the cancel does change something (IF's start) reads it first.
        let seen = [(0, 0), (C, 2), (R, 0), (G, 1)];
        assert_eq!(machine(3, &seen, C).next_state(0, LabelSet(G | C)), 2);
    }

    #[test]
    fn a_state_without_defined_cells_stays() {
        let rm = machine(2, &[], C);
        for l in vocab().all_label_sets() {
            assert_eq!(rm.next_state(0, l), 0);
            assert_eq!(rm.next_state(1, l), 1);
        }
    }

    #[test]
    fn the_tree_agrees_with_every_defined_cell() {
        // Random tables: 3 states, random subsets of the 32 label sets, random targets and
        // rewards (two values, so reward classes are split too).
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        let v = vocab();
        for _ in 0..200 {
            let labels: Vec<LabelSet> = v.all_label_sets().filter(|_| rng.gen_bool(0.4)).collect();
            let n = 3;
            let cells: Vec<Option<Cell>> = (0..n * labels.len())
                .map(|_| {
                    rng.gen_bool(0.7).then(|| Cell {
                        target: rng.gen_range(0..n),
                        reward: if rng.gen_bool(0.2) { 1.0 } else { 0.0 },
                        weight: 1.0,
                    })
                })
                .collect();
            let rm = tree_machine(&v, &labels, n, &cells, C);
            for u in 0..n {
                for (l, &ls) in labels.iter().enumerate() {
                    if let Some(c) = cells[u * labels.len() + l] {
                        assert_eq!(rm.step(u, ls), (c.target, c.reward), "state {u}, {ls:?}");
                    }
                }
            }
        }
    }
}
