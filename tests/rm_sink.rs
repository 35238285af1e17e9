//! The sink for touches the demonstrations never make in a state (`rm::transform::sink_unseen`).

use smirl::rm::format::{parse_rm, write_rm};
use smirl::rm::transform::sink_unseen;
use smirl::rm::{Formula, LabelSet, RewardMachine, Transition, Vocabulary};

const VOCAB: &str = "rgbyc";

fn labels(vocab: &Vocabulary, text: &str) -> LabelSet {
    vocab.parse_labels(text).unwrap()
}

fn trace(vocab: &Vocabulary, steps: &[&str]) -> Vec<LabelSet> {
    steps.iter().map(|s| labels(vocab, s)).collect()
}

/// IF as LRM learns it at some bases: blue (no cancel) → 1, cancel → 2; nothing out of 1 or 2.
fn if_machine(vocab: &Vocabulary) -> RewardMachine {
    let f = |text: &str| Formula::parse(text, vocab).unwrap();
    RewardMachine::new(
        vocab.clone(),
        3,
        0,
        &[],
        &[],
        vec![
            Transition {
                from: 0,
                to: 1,
                formula: f("b&!c"),
                reward: 0.0,
            },
            Transition {
                from: 0,
                to: 2,
                formula: f("c"),
                reward: 0.0,
            },
        ],
    )
    .unwrap()
}

#[test]
fn a_touch_never_seen_in_a_state_enters_the_sink_and_stays() {
    let v = Vocabulary::new(VOCAB);
    let rm = if_machine(&v);
    let traces = vec![
        trace(&v, &["", "b", "b", "", "r"]), // normal branch: 0 sees b, 1 sees b and r
        trace(&v, &["", "c", "", "r", "r"]), // cancel branch: 0 sees c, 2 sees r
    ];
    let balls = labels(&v, "rgby");
    let (sunk, sink) = sink_unseen(&rm, &traces, balls, &[true; 3]);
    assert_eq!(sink, Some(3));
    assert_eq!(sunk.n_states(), 4);
    // Blue after the cancel: never in a demonstration → the sink, for good.
    assert_eq!(sunk.next_state(2, labels(&v, "b")), 3);
    for l in v.all_label_sets() {
        assert_eq!(sunk.next_state(3, l), 3);
    }
    assert!(!sunk.is_failure(3) && !sunk.is_terminal(3));
    // What the demonstrations did stays where it went.
    assert_eq!(sunk.next_state(2, labels(&v, "r")), 2);
    assert_eq!(sunk.next_state(1, labels(&v, "r")), 1);
    assert_eq!(sunk.next_state(0, labels(&v, "b")), 1);
    // Existing transitions keep priority over an unseen proposition on the same label set.
    assert_eq!(sunk.next_state(0, labels(&v, "rc")), 2);
    // Unseen touches elsewhere; the cancel is not among the propositions, so it never sinks.
    assert_eq!(sunk.next_state(0, labels(&v, "r")), 3);
    assert_eq!(sunk.next_state(1, labels(&v, "g")), 3);
    assert_eq!(sunk.next_state(1, labels(&v, "c")), 1);
    // No demonstration enters the sink.
    for t in &traces {
        assert!(sunk.run(t).iter().all(|&(u, _)| u != 3));
    }
    // Written and read back to the same behaviour.
    let back = parse_rm(&write_rm(&sunk), "sunk").unwrap();
    for u in 0..4 {
        for l in v.all_label_sets() {
            assert_eq!(back.next_state(u, l), sunk.next_state(u, l));
        }
    }
}

#[test]
fn every_touch_seen_everywhere_leaves_the_machine_as_is() {
    let v = Vocabulary::new(VOCAB);
    let rm = if_machine(&v);
    let traces = vec![trace(&v, &["rgby", "b", "rgby"]), trace(&v, &["c", "rgby"])];
    let (same, sink) = sink_unseen(&rm, &traces, labels(&v, "rgby"), &[true; 3]);
    assert_eq!(sink, None);
    assert_eq!(same, rm);
}

#[test]
fn a_state_whose_transitions_take_every_label_set_gets_no_sink_edge() {
    let v = Vocabulary::new(VOCAB);
    let rm = RewardMachine::new(
        v.clone(),
        2,
        0,
        &[],
        &[],
        vec![Transition {
            from: 0,
            to: 1,
            formula: Formula::True,
            reward: 0.0,
        }],
    )
    .unwrap();
    // State 0 sees nothing, but its `True` guard takes every label set; state 1 never sees g.
    let (sunk, sink) = sink_unseen(&rm, &[trace(&v, &["", "r"])], labels(&v, "rg"), &[true; 2]);
    assert_eq!(sink, Some(2));
    assert_eq!(sunk.transitions().iter().filter(|t| t.from == 0).count(), 1);
    assert_eq!(sunk.next_state(0, labels(&v, "g")), 1);
    assert_eq!(sunk.next_state(1, labels(&v, "g")), 2);
    assert_eq!(sunk.next_state(1, labels(&v, "r")), 1);
}

/// Only the states flagged in `from` get a sink edge (`smirl_sink_after_events`: the states
/// entered after the cancel).
#[test]
fn only_flagged_states_lead_to_the_sink() {
    let v = Vocabulary::new(VOCAB);
    let rm = if_machine(&v);
    let traces = vec![
        trace(&v, &["", "b", "b", "", "r"]),
        trace(&v, &["", "c", "", "r", "r"]),
    ];
    let after_cancel: Vec<bool> = rm
        .reachable_without(labels(&v, "c"))
        .iter()
        .map(|&r| !r)
        .collect();
    assert_eq!(after_cancel, vec![false, false, true]);
    let (sunk, sink) = sink_unseen(&rm, &traces, labels(&v, "rgby"), &after_cancel);
    assert_eq!(sink, Some(3));
    assert_eq!(sunk.next_state(2, labels(&v, "b")), 3);
    assert_eq!(sunk.next_state(2, labels(&v, "r")), 2);
    // Unseen touches before the cancel stay where they are, as without the sink.
    assert_eq!(sunk.next_state(0, labels(&v, "r")), 0);
    assert_eq!(sunk.next_state(1, labels(&v, "g")), 1);
    assert!(sunk
        .transitions()
        .iter()
        .filter(|t| t.to == 3)
        .all(|t| t.from == 2));
}
