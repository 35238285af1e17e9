//! Partial progress along the perfect machines (issue 14's metric): the fraction of a task's
//! sub-goals an episode completed, and whether it touched a ball that can end the task, on
//! hand-written label traces with known answers.

use smirl::env::reacher_task::{ReacherTask, TaskProgress};
use smirl::rm::LabelSet;

/// Runs `trace` (label sets as strings over the task's letters, one per step) through the
/// task's perfect machine; returns (fraction of sub-goals, end ball touched).
fn progress(task: ReacherTask, trace: &[&str]) -> (f64, bool) {
    let rm = task.perfect_rm().unwrap();
    let p = TaskProgress::of(&rm, &task.layout());
    let mut u = rm.initial();
    let mut t = p.start(u);
    for step in trace {
        let labels: LabelSet = rm.vocab().parse_labels(step).unwrap();
        let v = rm.next_state(u, labels);
        p.track(&mut t, u, v, labels);
        u = v;
    }
    (t.fraction(), t.touched_final_ball())
}

#[test]
fn sub_goals_completed_on_known_traces() {
    let ring = "assets/scenes/six_targets_ring.toml"; // t6, t1, t2, t3: f, a, b, c
    let cases: [(&str, &[&str], f64, bool); 18] = [
        ("or", &["", "r"], 0.5, false), // OR: red or green, then blue
        ("or", &["", "b"], 0.0, true),  // the end location without the sub-goal before it
        ("or", &["g", "", "b"], 1.0, true),
        ("sequential", &["r", "", "g"], 0.5, false),
        ("sequential", &["g", "r", "b", "y"], 0.25, true), // only red counts: order matters
        ("sequential", &["r", "g", "b", "y"], 1.0, true),
        ("composite", &["", "r", ""], 1.0 / 3.0, false),
        ("composite", &["g", "b", "y"], 1.0, true),
        ("composite", &["r", "c", "y"], 1.0, true), // the cancel removes blue: 2 of 2 done
        ("if", &["r", "r", "b", "", "r"], 1.0, true), // waiting on red does nothing; blue, red
        ("if", &["c", "", "b"], 0.0, false),        // blue after the cancel: failure, nothing done
        ("if", &["r", "b"], 0.5, true),             // the end ball touched early, then blue: 1 of 2
        ("blue", &["r", "g", "y"], 0.0, false),     // the positive control: blue alone counts
        ("blue", &["c", "", "b"], 1.0, true),       // the cancel plays no part
        ("blue", &["yb"], 1.0, true),
        // Another scene: its own letters, `c` a target (t3, the end) and no event.
        (ring, &["f", "", "a"], 0.5, false),
        (ring, &["c"], 0.0, true),
        (ring, &["f", "a", "b", "c"], 1.0, true),
    ];
    for (task, trace, fraction, end) in cases {
        let (f, e) = progress(ReacherTask::resolve(task).unwrap(), trace);
        assert!(
            (f - fraction).abs() < 1e-12,
            "{task:?} {trace:?}: {f} != {fraction}"
        );
        assert_eq!(e, end, "{task:?} {trace:?}");
    }
}
