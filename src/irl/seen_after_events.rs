//! What demonstrations do after an exogenous event, learned state by learned state: the
//! propositions they make true in each state of the learned machine once an event (the cancel)
//! has been read.
//!
//! Why: a learned machine can share one state between "after blue" and "after a cancel" (IF's
//! `0 -(c|b)-> 1`), and demonstrations, which never fail, give it no failure state; so a
//! learned reward hardly charges a policy that touches blue after the cancel, which the task
//! fails. The demonstrations still show, state by state, what the expert does once the cancel
//! has come — IF's never touch blue then. SMIRL's final phase (the selection cut,
//! `IrlRunConfig::selection_cut`) scores a candidate's learned return only up to its first touch
//! that no demonstration makes there.
//! Before any event nothing is judged: there the expert's behaviour is the task's, and an
//! agent's other touches are the way it moves. The rule assumes "unless" events: after one,
//! a touch the expert never makes is off the task.
//!
//! Touches are read as entries: a region counts on the step its touch begins, not on the steps
//! the fingertip stays on it. Why: the expert brushes a region for one step where an agent
//! lingers for two or three, so the steps after a touch that entered a state would look, read
//! as labels, like a touch no demonstration makes there.

use crate::rm::LabelSet;

/// Per learned state, the propositions of `props` some trajectory made true there after an
/// event of `events` had been read.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct SeenAfterEvents {
    events: LabelSet,
    props: LabelSet,
    seen: Vec<LabelSet>,
}

impl SeenAfterEvents {
    /// From annotated trajectories (concatenated, `lengths` each): step t read `labels[t]` in
    /// learned state `states[t]`. A step's labels count once an event came on an earlier step;
    /// the event's own step is read before it. A proposition counts only on a step it is true
    /// on and was not on the step before (the first step of a trajectory follows no labels).
    /// States outside `0..n_states` are ignored.
    pub fn new(
        n_states: usize,
        states: &[u32],
        labels: &[LabelSet],
        lengths: &[usize],
        events: LabelSet,
        props: LabelSet,
    ) -> SeenAfterEvents {
        let mut table = SeenAfterEvents {
            events,
            props,
            seen: vec![LabelSet::EMPTY; n_states],
        };
        let mut steps = states.iter().zip(labels);
        for &len in lengths {
            let mut walk = Walk::default();
            for (&u, &l) in steps.by_ref().take(len) {
                let touched = walk.step(&table, l);
                if let (Some(touched), Some(seen)) = (touched, table.seen.get_mut(u as usize)) {
                    seen.0 |= touched;
                }
            }
        }
        table
    }

    /// The propositions of `props` seen in state `u` after an event.
    pub fn in_state(&self, u: usize) -> LabelSet {
        self.seen.get(u).copied().unwrap_or(LabelSet::EMPTY)
    }

    /// The index of the first step of an episode (read as in [`SeenAfterEvents::new`]) that,
    /// after an event, makes true a proposition of `props` that no trajectory made true in
    /// its state after an event; `None` when there is none.
    pub fn first_unseen(&self, states: &[u32], labels: &[LabelSet]) -> Option<usize> {
        let mut walk = Walk::default();
        for (t, (&u, &l)) in states.iter().zip(labels).enumerate() {
            let touched = walk.step(self, l);
            if touched.is_some_and(|p| p & !self.in_state(u as usize).0 != 0) {
                return Some(t);
            }
        }
        None
    }
}

/// Where a trajectory is: whether an event has come, and the labels of the step before.
#[derive(Default)]
struct Walk {
    after_event: bool,
    before: LabelSet,
}

impl Walk {
    /// Reads one step's labels: the propositions of `table.props` that count as touched on it
    /// after an event (`None` before any), then whether an event came.
    fn step(&mut self, table: &SeenAfterEvents, labels: LabelSet) -> Option<u32> {
        let touched = labels.0 & table.props.0 & !self.before.0;
        let counted = self.after_event.then_some(touched);
        self.after_event |= labels.0 & table.events.0 != 0;
        self.before = labels;
        counted
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const RED: LabelSet = LabelSet(1);
    const BLUE: LabelSet = LabelSet(1 << 2);
    const CANCEL: LabelSet = LabelSet(1 << 4);
    const BALLS: LabelSet = LabelSet(0b1111);

    /// IF's merged machine: state 1 is both "after blue" and "after the cancel". One
    /// demonstration per branch: blue then red; the cancel on step 1, then red.
    fn if_merged() -> SeenAfterEvents {
        let states = [0, 0, 1, 1, /* cancel branch */ 0, 1, 1];
        let empty = LabelSet::EMPTY;
        let labels = [empty, BLUE, BLUE, RED, CANCEL, empty, RED];
        SeenAfterEvents::new(2, &states, &labels, &[4, 3], CANCEL, BALLS)
    }

    #[test]
    fn only_touches_after_an_event_are_seen() {
        let seen = if_merged();
        // Blue in state 1 was touched after blue, never after the cancel.
        assert_eq!(seen.in_state(1), RED);
        assert_eq!(seen.in_state(0), LabelSet::EMPTY);
        assert_eq!(seen.in_state(7), LabelSet::EMPTY);
    }

    #[test]
    fn blue_after_the_cancel_is_the_first_unseen_touch() {
        let seen = if_merged();
        let empty = LabelSet::EMPTY;
        // The cancel, blue on the way, then red.
        let states = [0, 1, 1, 1];
        assert_eq!(
            seen.first_unseen(&states, &[CANCEL, empty, BLUE, RED]),
            Some(2)
        );
        // Straight to red after the cancel, or the normal branch: nothing unseen.
        assert_eq!(seen.first_unseen(&states, &[CANCEL, empty, RED, RED]), None);
        assert_eq!(
            seen.first_unseen(&[0, 0, 1, 1], &[empty, BLUE, BLUE, RED]),
            None
        );
        // A touch on the cancel's own step is read before the cancel.
        assert_eq!(
            seen.first_unseen(&[0, 1], &[LabelSet(CANCEL.0 | BLUE.0), RED]),
            None
        );
    }

    /// The expert touches red for one step, an agent stays on it for two after the cancel: the
    /// second step, in the state red entered, is no new touch, while a touch of blue there is.
    #[test]
    fn a_ball_held_from_the_step_before_is_no_new_touch() {
        let empty = LabelSet::EMPTY;
        let states = [0, 0, 1, 1];
        let expert = [CANCEL, RED, empty, empty];
        let seen = SeenAfterEvents::new(2, &states, &expert, &[4], CANCEL, BALLS);
        assert_eq!(seen.first_unseen(&states, &[CANCEL, RED, RED, empty]), None);
        assert_eq!(
            seen.first_unseen(&states, &[CANCEL, RED, empty, BLUE]),
            Some(3)
        );
        assert_eq!(seen.in_state(0), RED);
    }
}
