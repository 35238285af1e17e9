//! Comparing reward machines: behavioural equivalence (same reward on every label
//! sequence) with a shortest counter-example, refinement along traces, and state counts.
//!
//! Two machines are *equivalent* when, started in their initial states and fed the same label
//! sequence, they pay the same reward at every step (up to [`REWARD_TOL`]). The check is a
//! breadth-first search of the product automaton, so the first difference found is on a
//! shortest sequence. The label sets may be restricted (`alphabet`), e.g. to those observed in
//! demonstrations: a machine learned from expert traces has never seen a plant, so it cannot
//! know what a plant does, and equivalence over the observed label sets is the most one can
//! ask of it.

use super::labels::{LabelSet, Vocabulary};
use super::machine::RewardMachine;
use std::collections::{BTreeMap, VecDeque};

/// Rewards closer than this are the same (learned rewards are means of observations).
pub const REWARD_TOL: f64 = 1e-9;

#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum EquivError {
    #[error("the machines have different vocabularies (\"{a}\" and \"{b}\")")]
    VocabularyMismatch { a: String, b: String },
    #[error("label set {labels:#x} is not a label set of the vocabulary \"{vocabulary}\"")]
    LabelOutOfRange { labels: u32, vocabulary: String },
}

fn check_alphabet(v: &Vocabulary, alphabet: &[LabelSet]) -> Result<(), EquivError> {
    match alphabet.iter().find(|l| l.index() >= v.n_label_sets()) {
        Some(l) => Err(EquivError::LabelOutOfRange {
            labels: l.0,
            vocabulary: v.to_string(),
        }),
        None => Ok(()),
    }
}

/// The label sets to explore: the given alphabet (deduplicated, sorted) or all of them.
fn letters(v: &Vocabulary, alphabet: Option<&[LabelSet]>) -> Result<Vec<LabelSet>, EquivError> {
    match alphabet {
        Some(a) => {
            check_alphabet(v, a)?;
            let mut a = a.to_vec();
            a.sort();
            a.dedup();
            Ok(a)
        }
        None => Ok(v.all_label_sets().collect()),
    }
}

/// A shortest label sequence on whose last step the machines pay different rewards, or
/// `None` when they are equivalent (over `alphabet` when given, else over all label sets).
pub fn counterexample(
    a: &RewardMachine,
    b: &RewardMachine,
    alphabet: Option<&[LabelSet]>,
) -> Result<Option<Vec<LabelSet>>, EquivError> {
    if a.vocab() != b.vocab() {
        return Err(EquivError::VocabularyMismatch {
            a: a.vocab().to_string(),
            b: b.vocab().to_string(),
        });
    }
    let letters = letters(a.vocab(), alphabet)?;
    let nb = b.n_states();
    let pair = |ua: usize, ub: usize| ua * nb + ub;
    // parent[p] = (previous pair, label) on a shortest path from the initial pair.
    let mut parent: Vec<Option<(usize, LabelSet)>> = vec![None; a.n_states() * nb];
    let mut seen = vec![false; a.n_states() * nb];
    let start = pair(a.initial(), b.initial());
    seen[start] = true;
    let mut queue = VecDeque::from([start]);
    let path_to = |mut p: usize, parent: &[Option<(usize, LabelSet)>]| {
        let mut trace = Vec::new();
        while let Some((prev, l)) = parent[p] {
            trace.push(l);
            p = prev;
        }
        trace.reverse();
        trace
    };
    while let Some(p) = queue.pop_front() {
        let (ua, ub) = (p / nb, p % nb);
        for &l in &letters {
            let (va, ra) = a.step(ua, l);
            let (vb, rb) = b.step(ub, l);
            if (ra - rb).abs() > REWARD_TOL {
                let mut trace = path_to(p, &parent);
                trace.push(l);
                return Ok(Some(trace));
            }
            let q = pair(va, vb);
            if !seen[q] {
                seen[q] = true;
                parent[q] = Some((p, l));
                queue.push_back(q);
            }
        }
    }
    Ok(None)
}

/// Whether the machines pay the same rewards on every label sequence (over `alphabet`).
pub fn equivalent(
    a: &RewardMachine,
    b: &RewardMachine,
    alphabet: Option<&[LabelSet]>,
) -> Result<bool, EquivError> {
    Ok(counterexample(a, b, alphabet)?.is_none())
}

/// Result of a refinement check along traces.
#[derive(Clone, Debug, PartialEq)]
pub struct Refinement {
    /// Along every trace, the coarse machine's state is a function of the fine machine's.
    pub refines: bool,
    /// For each fine state, the coarse states seen together with it (sorted).
    pub seen_with: Vec<Vec<usize>>,
    /// Steps (counting the initial position of each trace) whose fine state was also seen
    /// with another coarse state: 0 when `refines`.
    pub ambiguous_steps: usize,
    pub total_steps: usize,
}

/// Whether `fine` refines `coarse` along `traces`: each trace is run through both machines
/// from their initial states, and the check is that no state of `fine` is ever paired with
/// two different states of `coarse`. A learned machine that refines the perfect one can stand
/// in for it in the product MDP, since the perfect state (hence the true reward) can be read
/// off the learned state.
pub fn refines<'a, I>(fine: &RewardMachine, coarse: &RewardMachine, traces: I) -> Refinement
where
    I: IntoIterator<Item = &'a [LabelSet]>,
{
    let mut pairs: BTreeMap<(usize, usize), usize> = BTreeMap::new();
    let mut total = 0;
    for trace in traces {
        let (mut uf, mut uc) = (fine.initial(), coarse.initial());
        *pairs.entry((uf, uc)).or_default() += 1;
        total += 1;
        for &l in trace {
            uf = fine.next_state(uf, l);
            uc = coarse.next_state(uc, l);
            *pairs.entry((uf, uc)).or_default() += 1;
            total += 1;
        }
    }
    let mut seen_with = vec![Vec::new(); fine.n_states()];
    for &(uf, uc) in pairs.keys() {
        seen_with[uf].push(uc);
    }
    let ambiguous_steps = pairs
        .iter()
        .filter(|((uf, _), _)| seen_with[*uf].len() > 1)
        .map(|(_, &n)| n)
        .sum();
    Refinement {
        refines: seen_with.iter().all(|s| s.len() <= 1),
        seen_with,
        ambiguous_steps,
        total_steps: total,
    }
}

/// How many states a machine has, three ways.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct StateCounts {
    /// Declared states.
    pub total: usize,
    /// States reachable from the initial state (over the alphabet).
    pub reachable: usize,
    /// States of the smallest machine with the same reward behaviour (over the alphabet).
    /// Absorbing states with reward 0 forever (goal and failure) are one state here.
    pub minimal: usize,
}

/// State counts of `rm`, over `alphabet` when given, else over all label sets.
pub fn state_counts(
    rm: &RewardMachine,
    alphabet: Option<&[LabelSet]>,
) -> Result<StateCounts, EquivError> {
    let letters = letters(rm.vocab(), alphabet)?;
    let reachable = reachable_states(rm, &letters);
    let minimal = minimal_blocks(rm, &letters, &reachable);
    Ok(StateCounts {
        total: rm.n_states(),
        reachable: reachable.len(),
        minimal,
    })
}

fn reachable_states(rm: &RewardMachine, letters: &[LabelSet]) -> Vec<usize> {
    let seen = rm.reachable_on(letters);
    (0..rm.n_states()).filter(|&u| seen[u]).collect()
}

/// Number of classes of reward-equivalent states among `states` (Moore's partition
/// refinement; outputs are the rewards, quantised to [`REWARD_TOL`]).
fn minimal_blocks(rm: &RewardMachine, letters: &[LabelSet], states: &[usize]) -> usize {
    let quantise = |r: f64| (r / REWARD_TOL).round() as i64;
    let mut block = vec![0usize; rm.n_states()];
    // Start from the partition by one-step outputs, refine by successors' blocks.
    let mut signatures: Vec<Vec<i64>> = states
        .iter()
        .map(|&u| letters.iter().map(|&l| quantise(rm.reward(u, l))).collect())
        .collect();
    let mut n_blocks = 0;
    loop {
        let mut ids: BTreeMap<&Vec<i64>, usize> = BTreeMap::new();
        for s in &signatures {
            let next = ids.len();
            ids.entry(s).or_insert(next);
        }
        let new_blocks: Vec<usize> = signatures.iter().map(|s| ids[s]).collect();
        let count = ids.len();
        for (k, &u) in states.iter().enumerate() {
            block[u] = new_blocks[k];
        }
        if count == n_blocks {
            return count;
        }
        n_blocks = count;
        signatures = states
            .iter()
            .map(|&u| {
                let mut s = vec![block[u] as i64];
                for &l in letters {
                    s.push(quantise(rm.reward(u, l)));
                    s.push(block[rm.next_state(u, l)] as i64);
                }
                s
            })
            .collect();
    }
}
