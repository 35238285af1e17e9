//! The label sequences an environment with touched regions and exogenous events can produce,
//! and whether a machine learned without rewards tracks a reference machine on all of them.
//!
//! A learned machine carries no rewards (rewards are what IRL learns), so "the learned machine
//! is the task's" cannot mean equal rewards. It means: on every label sequence the task can
//! produce, up to the step where the reference reaches a goal or failure state (where the episode
//! ends), the reference's state is a function of the learned machine's. Then a reward on the
//! learned machine's transitions (what SMIRL's δ_r(u, o) = w_uᵀ L(o) reads) can pay what the
//! reference pays, including where it ends the task; a learned machine may have more states
//! than the reference (a refinement), never fewer distinctions.

use super::labels::LabelSet;
use super::machine::RewardMachine;
use std::collections::{HashMap, VecDeque};

/// The label sequences of a scene of disjoint regions and once-per-episode events: an episode
/// starts off every region (the arm's reset pose), at each step the fingertip is in at most
/// one region (`touches`, discs that do not overlap), a region is entered only from a step in
/// no region (the fingertip moves continuously and the discs are apart), and each event
/// (`events`) holds on at most one step of an episode, alone or with a touch.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LabelLanguage {
    pub touches: LabelSet,
    pub events: LabelSet,
}

/// Where a sequence of [`LabelLanguage`] is: the region of the last step (empty when none;
/// `None` before the first step) and the events that have fired.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct LanguageState {
    touch: Option<LabelSet>,
    fired: LabelSet,
}

impl LabelLanguage {
    /// Every label set a step can read: no region or one, with any set of events.
    pub fn alphabet(&self) -> Vec<LabelSet> {
        let singles = std::iter::once(LabelSet::EMPTY).chain(
            (0..32)
                .filter(|&k| self.touches.contains(k))
                .map(|k| LabelSet::EMPTY.with(k)),
        );
        let mut out = Vec::new();
        for touch in singles {
            let mut sub = self.events.0;
            loop {
                out.push(LabelSet(touch.0 | sub));
                if sub == 0 {
                    break;
                }
                sub = (sub - 1) & self.events.0;
            }
        }
        out.sort();
        out
    }

    pub fn start(&self) -> LanguageState {
        LanguageState {
            touch: None,
            fired: LabelSet::EMPTY,
        }
    }

    /// The state after reading `l` in `s`, or `None` when no episode reads `l` there.
    pub fn step(&self, s: LanguageState, l: LabelSet) -> Option<LanguageState> {
        let touch = LabelSet(l.0 & self.touches.0);
        let events = LabelSet(l.0 & self.events.0);
        let allowed = touch.0.count_ones() <= 1
            && match s.touch {
                None => touch.is_empty(),
                Some(last) => touch.is_empty() || last.is_empty() || touch == last,
            }
            && events.0 & s.fired.0 == 0
            && l.0 & !(self.touches.0 | self.events.0) == 0;
        allowed.then_some(LanguageState {
            touch: Some(touch),
            fired: LabelSet(s.fired.0 | events.0),
        })
    }
}

/// Two label sequences of `language` that end in the same state of the learned machine and
/// in reference states that pay differently on some continuation.
#[derive(Clone, Debug, PartialEq)]
pub struct Undetermined {
    pub first: Vec<LabelSet>,
    pub second: Vec<LabelSet>,
}

/// How the reference's failure states count.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Failures {
    /// As the reference has them: a state from which a touch fails differs from one where
    /// it does not.
    Kept,
    /// A step into a failure state reads as a stay: what the expert's demonstrations can
    /// show, since no demonstration fails (IF's "blue touched" and "cancelled" both wait for
    /// red, and only a touch of blue, which the expert never makes after the cancel, tells
    /// them apart).
    AsStays,
}

/// The reference's next state, with `failures`.
fn reference_step(reference: &RewardMachine, v: usize, l: LabelSet, failures: Failures) -> usize {
    let next = reference.next_state(v, l);
    match failures {
        Failures::AsStays if reference.is_failure(next) => v,
        _ => next,
    }
}

/// The classes of reference states that pay the same rewards and end (goal, failure) alike
/// on every continuation over `alphabet`, steps read with `failures` (Moore's partition
/// refinement): two reference states of one class need no learned state to tell them apart.
fn reference_classes(
    reference: &RewardMachine,
    alphabet: &[LabelSet],
    failures: Failures,
) -> Vec<usize> {
    let n = reference.n_states();
    let mut class: Vec<usize> = (0..n)
        .map(|v| usize::from(reference.is_terminal(v)) + 2 * usize::from(reference.is_failure(v)))
        .collect();
    loop {
        let signature = |v: usize| -> (usize, Vec<(usize, u64)>) {
            let row = alphabet
                .iter()
                .map(|&l| {
                    let next = if reference.is_absorbing(v) {
                        v
                    } else {
                        reference_step(reference, v, l, failures)
                    };
                    (class[next], reference.reward(v, l).to_bits())
                })
                .collect();
            (class[v], row)
        };
        let mut ids: HashMap<(usize, Vec<(usize, u64)>), usize> = HashMap::new();
        let next: Vec<usize> = (0..n)
            .map(|v| {
                let k = ids.len();
                *ids.entry(signature(v)).or_insert(k)
            })
            .collect();
        let stable = ids.len() == class.iter().collect::<std::collections::HashSet<_>>().len();
        class = next;
        if stable {
            return class;
        }
    }
}

/// `None` when `reference`'s state (up to states that behave alike, read with `failures`) is
/// a function of `learned`'s on every sequence of `language` over `alphabet` while
/// `reference` has not reached a goal or failure state (see the module docs); else two
/// sequences that tell it otherwise, the second a shortest one. Breadth-first over the
/// product of the two machines and the language.
pub fn undetermined(
    learned: &RewardMachine,
    reference: &RewardMachine,
    language: &LabelLanguage,
    alphabet: &[LabelSet],
    failures: Failures,
) -> Option<Undetermined> {
    type Node = (usize, usize, LanguageState);
    let class = reference_classes(reference, alphabet, failures);
    let start: Node = (learned.initial(), reference.initial(), language.start());
    let mut parent: HashMap<Node, Option<(Node, LabelSet)>> = HashMap::from([(start, None)]);
    let mut seen_with: HashMap<usize, Node> = HashMap::new();
    let mut queue = VecDeque::from([start]);
    let path_to = |parent: &HashMap<Node, Option<(Node, LabelSet)>>, mut at: Node| {
        let mut seq = Vec::new();
        while let Some(Some((prev, l))) = parent.get(&at) {
            seq.push(*l);
            at = *prev;
        }
        seq.reverse();
        seq
    };
    while let Some(node) = queue.pop_front() {
        let (u, v, s) = node;
        if reference.is_absorbing(v) {
            continue;
        }
        match seen_with.get(&u) {
            Some(&other) if class[other.1] != class[v] => {
                return Some(Undetermined {
                    first: path_to(&parent, other),
                    second: path_to(&parent, node),
                })
            }
            Some(_) => {}
            None => {
                seen_with.insert(u, node);
            }
        }
        for &l in alphabet {
            let Some(s2) = language.step(s, l) else {
                continue;
            };
            let next = (
                learned.next_state(u, l),
                reference_step(reference, v, l, failures),
                s2,
            );
            if let std::collections::hash_map::Entry::Vacant(e) = parent.entry(next) {
                e.insert(Some((node, l)));
                queue.push_back(next);
            }
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rm::format::parse_rm;
    use crate::rm::perfect;

    fn language() -> LabelLanguage {
        // rgbyc: the four balls, then the cancel.
        LabelLanguage {
            touches: LabelSet(0b1111),
            events: LabelSet(0b10000),
        }
    }

    fn machine(text: &str) -> RewardMachine {
        parse_rm(&format!("vocabulary: rgbyc\n{text}"), "test").unwrap()
    }

    #[test]
    fn the_language_starts_off_the_balls_and_fires_each_event_once() {
        let lang = language();
        assert_eq!(lang.alphabet().len(), 10);
        let (r, g, c) = (LabelSet(1), LabelSet(2), LabelSet(16));
        assert!(lang.step(lang.start(), r).is_none());
        let s = lang.step(lang.start(), c).unwrap();
        assert!(lang.step(s, c).is_none() && lang.step(s, LabelSet(r.0 | c.0)).is_none());
        let on_red = lang
            .step(s, LabelSet::EMPTY)
            .and_then(|s| lang.step(s, r))
            .unwrap();
        assert!(lang.step(on_red, g).is_none() && lang.step(on_red, r).is_some());
    }

    /// IF: a learned machine with IF's states tracks it either way; one that merges "blue
    /// touched" with "cancelled" tracks it only with failures read as stays (only a touch of
    /// blue after the cancel, which no demonstration makes, tells them apart); one that
    /// ignores the cancel tracks it in no reading.
    #[test]
    fn if_machines_are_told_apart_by_what_they_track() {
        let perfect = perfect::load("reacher_if").unwrap();
        let lang = language();
        let alphabet = lang.alphabet();
        let tracks = |rm: &RewardMachine, failures| {
            undetermined(rm, &perfect, &lang, &alphabet, failures).is_none()
        };
        let exact =
            machine("states: 3\ninitial: 0\n(0, 2, 'c', 0)\n(0, 1, 'b&!c', 0)\n(1, 1, 'r', 0)");
        assert!(tracks(&exact, Failures::AsStays) && tracks(&exact, Failures::Kept));
        let merged = machine("states: 2\ninitial: 0\n(0, 1, 'c|b', 0)");
        assert!(tracks(&merged, Failures::AsStays) && !tracks(&merged, Failures::Kept));
        let blind = machine("states: 2\ninitial: 0\n(0, 1, 'b', 0)");
        let cx = undetermined(&blind, &perfect, &lang, &alphabet, Failures::AsStays).unwrap();
        // A shortest counter-example: the cancel alone leaves the blind machine in its start.
        assert_eq!(cx.first, Vec::<LabelSet>::new());
        assert_eq!(cx.second, vec![LabelSet(16)]);
    }
}
