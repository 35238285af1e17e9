//! Replay of a fresh log is bit-exact and detects tampering; `learn-rm` on logged scripted
//! Sequential demonstrations recovers the task's machine.

use smirl::env::reacher::{CancelConfig, ReacherConfig};
use smirl::log::demo::{log_scripted_demos, DemoSpec};
use smirl::log::{read_log, LogOptions};
use smirl::pipeline::offline_rm::{compare, learn_from_files};
use smirl::pipeline::replay::replay;
use smirl::rm::lrm::LrmConfig;
use smirl::rm::perfect;
use std::path::Path;

fn sequential_demos(path: &Path, episodes: u64, cancel_probability: f64, observations: bool) {
    let env = ReacherConfig {
        cancel: Some(CancelConfig {
            probability: cancel_probability,
            earliest_step: 1,
            latest_step: 8,
        }),
        ..ReacherConfig::default()
    };
    log_scripted_demos(
        path,
        &DemoSpec {
            task: "sequential".into(),
            sequence: "rgby".into(),
            episodes,
            seed: 7,
            stop_when_done: true,
            env,
            event_probability: None,
            reward_machine: Some(perfect::reacher("sequential").unwrap()),
        },
        LogOptions {
            observations,
            ..LogOptions::default()
        },
    )
    .unwrap();
}

#[test]
fn fresh_log_replays_bit_exactly_and_tampering_is_detected() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("demo.mcap");
    sequential_demos(&path, 6, 0.5, true);
    let log = read_log(&path).unwrap();
    assert!(log.episodes.iter().all(|e| e.end.as_ref().unwrap().success));
    let report = replay(&log).unwrap();
    assert!(report.all_match(), "{report}");
    assert!(
        report.setting_notes.is_empty(),
        "{:?}",
        report.setting_notes
    );
    assert_eq!(report.steps, log.steps());
    assert!(report.episodes.iter().all(|e| e.seed_reproduces_start));

    // One bit of one action changed: the replay diverges exactly there.
    let mut tampered = log.clone();
    let a = &mut tampered.episodes[3].steps[20].action[1];
    *a = f32::from_bits(a.to_bits() ^ 1);
    let report = replay(&tampered).unwrap();
    assert_eq!(report.mismatches(), 1, "{report}");
    let m = report.episodes[3].mismatch.as_ref().unwrap();
    assert_eq!(m.step, 21, "{m}");
    assert!(
        m.what.starts_with("qpos") || m.what.starts_with("qvel"),
        "{m}"
    );

    // A changed logged label is caught too.
    let mut tampered = log.clone();
    tampered.episodes[1].steps[5].labels ^= 0b100;
    let m = replay(&tampered).unwrap().episodes[1]
        .mismatch
        .clone()
        .unwrap();
    assert_eq!((m.step, m.what.as_str()), (6, "labels"));

    // A model XML that is not the one the run record names is refused, not mismatched.
    let mut damaged = log.clone();
    damaged.model_xml = Some(
        damaged
            .model_xml
            .unwrap()
            .replace("damping=\"1\"", "damping=\"2\""),
    );
    let e = replay(&damaged).unwrap_err().to_string();
    assert!(e.contains("hashes to") && e.contains("demo.mcap"), "{e}");

    // A log from another MuJoCo version is flagged as such.
    let mut other = log.clone();
    other.run.mujoco_version = "3.1.0".into();
    let r = replay(&other).unwrap();
    assert!(
        r.version_differs && r.setting_notes[0].contains("MuJoCo 3.1.0"),
        "{r}"
    );
}

#[test]
fn learn_rm_on_sequential_demo_logs_recovers_the_task() {
    let dir = tempfile::tempdir().unwrap();
    let (a, b) = (dir.path().join("a.mcap"), dir.path().join("b.mcap"));
    // Two files, as `learn-rm FILES…` takes them; no cancel events (see below).
    sequential_demos(&a, 15, 0.0, false);
    sequential_demos(&b, 15, 0.0, false);
    // The log records the schedule that ran (the config's), not the task file's chance.
    let events = read_log(&a).unwrap().run.task_layout().unwrap().events;
    assert_eq!(events[0].probability, 0.0);
    let cfg = LrmConfig {
        merge: false,
        threads: 1,
        ..LrmConfig::default()
    };
    let result = learn_from_files(&[a, b], &cfg, false).unwrap();
    assert_eq!(result.traces.traces.len(), 30);
    assert!(result.traces.traces[0].rewards.is_some());
    let reference = perfect::reacher("sequential").unwrap();
    let c = compare(&result.learned.rm, &reference, &result.traces.traces).unwrap();
    // Episodes end when the task is done, so the logs cannot show that the goal state is
    // absorbing: the learned machine agrees with the perfect one up to the goal.
    assert!(c.equivalent_until_done, "{c:?}\n{:?}", result.learned.rm);
    assert_eq!(result.learned.rm.n_states(), 4);
}

#[test]
fn replay_prints_label_runs_compactly() {
    use smirl::pipeline::replay::label_runs;
    use smirl::rm::{LabelSet, Vocabulary};
    let v = Vocabulary::new("rgbyc");
    let (r, y, c) = (LabelSet(1), LabelSet(1 << 3), LabelSet(1 << 4));
    let mut trace = vec![
        LabelSet::EMPTY,
        c,
        LabelSet::EMPTY,
        r,
        r,
        r,
        LabelSet::EMPTY,
    ];
    trace.extend(std::iter::repeat_n(y, 78));
    assert_eq!(label_runs(&v, &trace), "c@2 r@4\u{2013}6 y@8\u{2013}85");
    assert_eq!(label_runs(&v, &[]), "");
    assert_eq!(label_runs(&v, &[LabelSet(1 | 1 << 4)]), "rc@1");
}
