//! The reward machine side of the product MDP `S × U`: a tracker that follows the machine
//! along an environment's labels, pays its reward and exposes its state (as an index and as a
//! one-hot vector to append to an observation). Used by experts, SMIRL and evaluation.

use super::labels::LabelSet;
use super::machine::RewardMachine;

/// What one environment step did to the machine.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RmStep {
    /// Machine state after the step (after the restart, in restarting mode).
    pub state: usize,
    /// Reward the machine paid for this step.
    pub reward: f64,
    /// The step reached a terminal (goal) state.
    pub terminal: bool,
    /// The step reached a failure sink.
    pub failure: bool,
}

/// A reward machine and its current state.
#[derive(Clone, Debug)]
pub struct RmTracker {
    rm: RewardMachine,
    state: usize,
    restart_on_goal: bool,
}

impl RmTracker {
    /// A tracker in the machine's initial state. Reaching a terminal state keeps it there
    /// (absorbing) until [`RmTracker::reset`].
    pub fn new(rm: RewardMachine) -> RmTracker {
        let state = rm.initial();
        RmTracker {
            rm,
            state,
            restart_on_goal: false,
        }
    }

    /// A tracker that goes back to the initial state right after reaching a terminal state
    /// (the step still reports `terminal: true` and the goal reward), for episodes that go on
    /// after the task is completed, as in the paper's expert demonstrations. Failure sinks
    /// stay absorbing.
    pub fn restarting(rm: RewardMachine) -> RmTracker {
        RmTracker {
            restart_on_goal: true,
            ..RmTracker::new(rm)
        }
    }

    pub fn rm(&self) -> &RewardMachine {
        &self.rm
    }

    pub fn state(&self) -> usize {
        self.state
    }

    pub fn n_states(&self) -> usize {
        self.rm.n_states()
    }

    /// Back to the initial state (start of an episode).
    pub fn reset(&mut self) {
        self.state = self.rm.initial();
    }

    /// Advances the machine on the labels of the observation the environment just produced.
    pub fn step(&mut self, labels: LabelSet) -> RmStep {
        let (next, reward) = self.rm.step(self.state, labels);
        let terminal = self.rm.is_terminal(next);
        let failure = self.rm.is_failure(next);
        self.state = if terminal && self.restart_on_goal {
            self.rm.initial()
        } else {
            next
        };
        RmStep {
            state: self.state,
            reward,
            terminal,
            failure,
        }
    }

    /// Writes the one-hot encoding of the current state into `out`.
    ///
    /// # Panics
    /// If `out.len()` is not the number of machine states (a programming error).
    pub fn encode_state(&self, out: &mut [f32]) {
        one_hot(self.state, out);
    }
}

/// Writes the one-hot encoding of `state` into `out` (`out.len()` = number of states).
///
/// # Panics
/// If `state >= out.len()` (a programming error).
pub fn one_hot(state: usize, out: &mut [f32]) {
    assert!(
        state < out.len(),
        "one-hot of state {state} into a buffer of {} states",
        out.len()
    );
    out.fill(0.0);
    out[state] = 1.0;
}
