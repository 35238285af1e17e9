//! The reward machine: states, transitions guarded by formulas, a reward per transition.

use super::formula::Formula;
use super::labels::{LabelSet, Vocabulary};

/// One guarded edge `from --formula / reward--> to`.
#[derive(Clone, Debug, PartialEq)]
pub struct Transition {
    pub from: usize,
    pub to: usize,
    pub formula: Formula,
    pub reward: f64,
}

/// Why a machine is not well formed.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum RmError {
    #[error("a reward machine needs at least one state")]
    NoStates,
    #[error("state u{state} is out of range (the machine has {n_states} states)")]
    StateOutOfRange { state: usize, n_states: usize },
    #[error("transitions u{from} -> u{to_a} and u{from} -> u{to_b} are both enabled on label set {{{labels}}}: the machine must be deterministic")]
    Nondeterministic {
        from: usize,
        to_a: usize,
        to_b: usize,
        labels: String,
    },
    #[error("state u{state} is terminal or a failure sink and cannot have outgoing transitions")]
    TransitionFromAbsorbing { state: usize },
    #[error("state u{state} is declared both terminal and failure")]
    TerminalAndFailure { state: usize },
    #[error("transition u{from} -> u{to} has a non-finite reward {reward}")]
    BadReward { from: usize, to: usize, reward: f64 },
}

/// A deterministic reward machine over a vocabulary of propositions.
///
/// Semantics: in state `u`, on label set `l`, the one transition from `u` whose formula holds
/// on `l` is taken and its reward is paid; if none holds the machine stays in `u` with reward
/// 0. Terminal (goal) states and failure sinks are absorbing: no outgoing transitions, reward
/// 0 forever. A task fails only by an explicit transition into a failure sink.
///
/// Stepping is a table look-up: the constructor evaluates every formula on every label set.
#[derive(Clone, Debug)]
pub struct RewardMachine {
    vocab: Vocabulary,
    n_states: usize,
    initial: usize,
    terminal: Vec<bool>,
    failure: Vec<bool>,
    transitions: Vec<Transition>,
    /// `next[u * n_label_sets + l]`.
    next: Vec<u32>,
    /// Reward paid on `(u, l)`, same layout as `next`.
    reward: Vec<f64>,
}

impl PartialEq for RewardMachine {
    /// Structural equality (same states, flags and transitions in the same order). For
    /// behavioural equality see the equivalence check.
    fn eq(&self, other: &Self) -> bool {
        self.vocab == other.vocab
            && self.n_states == other.n_states
            && self.initial == other.initial
            && self.terminal == other.terminal
            && self.failure == other.failure
            && self.transitions == other.transitions
    }
}

impl RewardMachine {
    /// Builds and checks a machine. States are `0..n_states`.
    pub fn new(
        vocab: Vocabulary,
        n_states: usize,
        initial: usize,
        terminal: &[usize],
        failure: &[usize],
        transitions: Vec<Transition>,
    ) -> Result<RewardMachine, RmError> {
        if n_states == 0 {
            return Err(RmError::NoStates);
        }
        let check = |state: usize| {
            if state < n_states {
                Ok(())
            } else {
                Err(RmError::StateOutOfRange { state, n_states })
            }
        };
        check(initial)?;
        let mut is_terminal = vec![false; n_states];
        let mut is_failure = vec![false; n_states];
        for &s in terminal {
            check(s)?;
            is_terminal[s] = true;
        }
        for &s in failure {
            check(s)?;
            if is_terminal[s] {
                return Err(RmError::TerminalAndFailure { state: s });
            }
            is_failure[s] = true;
        }
        let n_labels = vocab.n_label_sets();
        let mut next: Vec<u32> = (0..n_states * n_labels)
            .map(|k| (k / n_labels) as u32)
            .collect();
        let mut reward = vec![0.0; n_states * n_labels];
        let mut chosen: Vec<Option<usize>> = vec![None; n_states * n_labels];
        for (k, t) in transitions.iter().enumerate() {
            check(t.from)?;
            check(t.to)?;
            if is_terminal[t.from] || is_failure[t.from] {
                return Err(RmError::TransitionFromAbsorbing { state: t.from });
            }
            if !t.reward.is_finite() {
                return Err(RmError::BadReward {
                    from: t.from,
                    to: t.to,
                    reward: t.reward,
                });
            }
            for l in vocab.all_label_sets() {
                if !t.formula.eval(l) {
                    continue;
                }
                let cell = t.from * n_labels + l.index();
                if let Some(prev) = chosen[cell] {
                    return Err(RmError::Nondeterministic {
                        from: t.from,
                        to_a: transitions[prev].to,
                        to_b: t.to,
                        labels: vocab.format_labels(l),
                    });
                }
                chosen[cell] = Some(k);
                next[cell] = t.to as u32;
                reward[cell] = t.reward;
            }
        }
        Ok(RewardMachine {
            vocab,
            n_states,
            initial,
            terminal: is_terminal,
            failure: is_failure,
            transitions,
            next,
            reward,
        })
    }

    pub fn vocab(&self) -> &Vocabulary {
        &self.vocab
    }

    pub fn n_states(&self) -> usize {
        self.n_states
    }

    pub fn initial(&self) -> usize {
        self.initial
    }

    pub fn transitions(&self) -> &[Transition] {
        &self.transitions
    }

    pub fn is_terminal(&self, u: usize) -> bool {
        self.terminal[u]
    }

    pub fn is_failure(&self, u: usize) -> bool {
        self.failure[u]
    }

    /// Terminal or failure: the machine can never leave `u`.
    pub fn is_absorbing(&self, u: usize) -> bool {
        self.terminal[u] || self.failure[u]
    }

    pub fn terminal_states(&self) -> Vec<usize> {
        (0..self.n_states).filter(|&u| self.terminal[u]).collect()
    }

    pub fn failure_states(&self) -> Vec<usize> {
        (0..self.n_states).filter(|&u| self.failure[u]).collect()
    }

    /// Next state after seeing `labels` in state `u`.
    #[inline]
    pub fn next_state(&self, u: usize, labels: LabelSet) -> usize {
        self.next[u * self.vocab.n_label_sets() + labels.index()] as usize
    }

    /// Reward paid for seeing `labels` in state `u`.
    #[inline]
    pub fn reward(&self, u: usize, labels: LabelSet) -> f64 {
        self.reward[u * self.vocab.n_label_sets() + labels.index()]
    }

    /// One step: `(next state, reward)`.
    #[inline]
    pub fn step(&self, u: usize, labels: LabelSet) -> (usize, f64) {
        let cell = u * self.vocab.n_label_sets() + labels.index();
        (self.next[cell] as usize, self.reward[cell])
    }

    /// Per state, whether it is reachable from the initial state reading only label sets that
    /// hold none of `events`: the states an agent can reach by its own moves, without an
    /// exogenous event (every label set of the vocabulary counts, including ones no trace
    /// holds, so this errs towards "reachable").
    pub fn reachable_without(&self, events: LabelSet) -> Vec<bool> {
        let letters: Vec<LabelSet> = self
            .vocab
            .all_label_sets()
            .filter(|l| l.0 & events.0 == 0)
            .collect();
        self.reachable_on(&letters)
    }

    /// Per state, whether it is reachable from the initial state reading only `letters`.
    pub fn reachable_on(&self, letters: &[LabelSet]) -> Vec<bool> {
        let mut seen = vec![false; self.n_states()];
        seen[self.initial] = true;
        let mut stack = vec![self.initial];
        while let Some(u) = stack.pop() {
            for &l in letters {
                let v = self.next_state(u, l);
                if !seen[v] {
                    seen[v] = true;
                    stack.push(v);
                }
            }
        }
        seen
    }

    /// Runs the machine from its initial state along a label trace; returns the state and
    /// reward after each step (same length as `trace`).
    pub fn run(&self, trace: &[LabelSet]) -> Vec<(usize, f64)> {
        let mut u = self.initial;
        trace
            .iter()
            .map(|&l| {
                let (v, r) = self.step(u, l);
                u = v;
                (v, r)
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn t(v: &Vocabulary, from: usize, to: usize, f: &str, reward: f64) -> Transition {
        Transition {
            from,
            to,
            formula: Formula::parse(f, v).unwrap(),
            reward,
        }
    }

    /// OR task: (r | g) then b.
    fn or_machine() -> RewardMachine {
        let v = Vocabulary::new("rgbyc");
        let ts = vec![t(&v, 0, 1, "r|g", 0.0), t(&v, 1, 2, "b", 1.0)];
        RewardMachine::new(v, 3, 0, &[2], &[], ts).unwrap()
    }

    #[test]
    fn steps_along_a_trace() {
        let rm = or_machine();
        let v = rm.vocab().clone();
        let trace: Vec<LabelSet> = ["", "b", "g", "", "b", "r"]
            .iter()
            .map(|s| v.parse_labels(s).unwrap())
            .collect();
        let out = rm.run(&trace);
        assert_eq!(
            out.iter().map(|x| x.0).collect::<Vec<_>>(),
            vec![0, 0, 1, 1, 2, 2]
        );
        assert_eq!(
            out.iter().map(|x| x.1).collect::<Vec<_>>(),
            vec![0.0, 0.0, 0.0, 0.0, 1.0, 0.0]
        );
    }

    #[test]
    fn rejects_nondeterminism_and_bad_states() {
        let v = Vocabulary::new("rgbyc");
        let e = RewardMachine::new(
            v.clone(),
            3,
            0,
            &[2],
            &[],
            vec![t(&v, 0, 1, "r", 0.0), t(&v, 0, 2, "r|g", 0.0)],
        )
        .unwrap_err();
        assert!(
            matches!(e, RmError::Nondeterministic { from: 0, .. }),
            "{e}"
        );
        let e =
            RewardMachine::new(v.clone(), 2, 0, &[], &[], vec![t(&v, 0, 5, "r", 0.0)]).unwrap_err();
        assert_eq!(
            e,
            RmError::StateOutOfRange {
                state: 5,
                n_states: 2
            }
        );
        let e = RewardMachine::new(v.clone(), 2, 0, &[1], &[], vec![t(&v, 1, 0, "r", 0.0)])
            .unwrap_err();
        assert_eq!(e, RmError::TransitionFromAbsorbing { state: 1 });
        assert!(RewardMachine::new(v.clone(), 2, 0, &[1], &[1], vec![]).is_err());
        assert!(RewardMachine::new(v, 0, 0, &[], &[], vec![]).is_err());
    }
}
