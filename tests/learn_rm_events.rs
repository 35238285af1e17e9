//! `reacher learn-rm` reads the events the logs' task declares (the `/run` record's task
//! layout) and learns with them as SMIRL's learner does; logs whose tasks declare different
//! events are refused (exit 2) before any search. Regression: `learn-rm` ran LRM with no
//! events at all, so a machine learned offline from a run's logs read the cancel as any touch.

use smirl::env::reacher::ReacherConfig;
use smirl::log::demo::{log_scripted_demos, DemoSpec};
use smirl::log::LogOptions;
use smirl::pipeline::offline_rm::{traces_from_files, OfflineRmError};
use smirl::pipeline::reacher_irl::smirl::with_event_rules;
use smirl::rm::format::{read_rm, write_rm};
use smirl::rm::lrm::{learn_rm, LrmConfig};
use smirl::rm::LabelSet;
use std::path::{Path, PathBuf};
use std::process::Command;

/// Red, green and blue at the paper's places; `y` and `c` are events (the letters of the
/// shipped tasks' yellow ball and cancel, at the same label bits).
const TASK: &str = r#"scene = "builtin"
machine = "two_events.txt"
episode_steps = 100
randomize_layout = false

[[region]]
letter = "r"
body = "red"
radius = 0.02
position = [0.0975, 0.1689]

[[region]]
letter = "g"
body = "green"
radius = 0.02
position = [-0.0182, -0.1034]

[[region]]
letter = "b"
body = "blue"
radius = 0.02
position = [-0.0591, 0.0104]

[[event]]
letter = "y"
probability = 1.0
earliest_step = 2
latest_step = 4

[[event]]
letter = "c"
probability = 0.5
earliest_step = 1
latest_step = 8
"#;

const MACHINE: &str =
    "vocabulary: rgbyc\nstates: 3\ninitial: 0\nterminal: 2\n(0, 1, 'r', 0)\n(1, 2, 'g', 1)\n";

fn log(path: &Path, task: &str, sequence: &str, machine: Option<&Path>) {
    log_scripted_demos(
        path,
        &DemoSpec {
            task: task.into(),
            sequence: sequence.into(),
            episodes: 24,
            seed: 3,
            stop_when_done: true,
            env: ReacherConfig::default(),
            event_probability: None,
            reward_machine: machine.map(|p| read_rm(p).unwrap()),
        },
        LogOptions::default(),
    )
    .unwrap();
}

/// Logs of the shipped IF task (event `c`) and of the task above (events `y`, `c`).
fn logs(dir: &Path) -> (PathBuf, PathBuf) {
    let if_log = dir.join("if.mcap");
    let if_rm = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/rm/reacher_if.txt");
    log(&if_log, "if", "br", Some(&if_rm));
    std::fs::write(dir.join("two_events.txt"), MACHINE).unwrap();
    let task = dir.join("two_events.toml");
    std::fs::write(&task, TASK).unwrap();
    let other = dir.join("two_events.mcap");
    log(
        &other,
        task.to_str().unwrap(),
        "rg",
        Some(&dir.join("two_events.txt")),
    );
    (if_log, other)
}

fn reacher(dir: &Path, args: &[&str]) -> (i32, String) {
    let o = Command::new(env!("CARGO_BIN_EXE_reacher"))
        .args(args)
        .current_dir(dir)
        .output()
        .unwrap();
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    );
    (o.status.code().unwrap_or(-1), text)
}

/// What `learn-rm` learns by default on these traces with `events`: SMIRL's event rules.
fn expected_config(events: LabelSet) -> LrmConfig {
    with_event_rules(LrmConfig {
        merge: true,
        stutter_invariant: true,
        events,
        ..LrmConfig::default()
    })
}

#[test]
fn learn_rm_learns_with_the_events_the_logs_task_declares() {
    let dir = tempfile::tempdir().unwrap();
    let (if_log, other) = logs(dir.path());

    // The events are the task's, wherever its letters put them.
    let traces = traces_from_files(std::slice::from_ref(&if_log), false).unwrap();
    assert_eq!(traces.events, LabelSet(1 << 4));
    let two = traces_from_files(std::slice::from_ref(&other), false).unwrap();
    assert_eq!(two.vocabulary, traces.vocabulary);
    assert_eq!(two.events, LabelSet(1 << 3 | 1 << 4));

    // The command learns what LRM learns with the declared cancel, which is not what it
    // learns without it on these traces.
    std::fs::create_dir(dir.path().join("with")).unwrap();
    let (code, text) = reacher(dir.path(), &["learn-rm", "if.mcap", "--out", "with"]);
    assert_eq!(code, 0, "{text}");
    assert!(
        text.contains("events: c (declared by the logs' task)"),
        "{text}"
    );
    let learned = std::fs::read_to_string(dir.path().join("with/learned_rm.txt")).unwrap();
    let with = learn_rm(
        &traces.vocabulary,
        &traces.traces,
        &expected_config(traces.events),
    )
    .unwrap();
    let without = learn_rm(
        &traces.vocabulary,
        &traces.traces,
        &expected_config(LabelSet::EMPTY),
    )
    .unwrap();
    assert_eq!(learned, write_rm(&with.rm));
    assert_ne!(
        write_rm(&with.rm),
        write_rm(&without.rm),
        "the events change nothing on these traces: the test cannot tell"
    );

    // --no-events learns as plain LRM, as the command did before.
    std::fs::create_dir(dir.path().join("plain")).unwrap();
    let (code, text) = reacher(
        dir.path(),
        &["learn-rm", "if.mcap", "--out", "plain", "--no-events"],
    );
    assert_eq!(code, 0, "{text}");
    assert!(text.contains("events: none (--no-events)"), "{text}");
    let plain = LrmConfig {
        merge: true,
        stutter_invariant: true,
        ..LrmConfig::default()
    };
    let plain = learn_rm(&traces.vocabulary, &traces.traces, &plain).unwrap();
    assert_eq!(
        std::fs::read_to_string(dir.path().join("plain/learned_rm.txt")).unwrap(),
        write_rm(&plain.rm)
    );
}

#[test]
fn logs_of_tasks_with_other_events_are_refused_before_the_search() {
    let dir = tempfile::tempdir().unwrap();
    let (if_log, other) = logs(dir.path());
    let err = traces_from_files(&[if_log, other], false).unwrap_err();
    assert!(
        matches!(&err, OfflineRmError::Events { path, .. } if path.ends_with("two_events.mcap")),
        "{err}"
    );
    std::fs::create_dir(dir.path().join("out")).unwrap();
    let (code, text) = reacher(
        dir.path(),
        &["learn-rm", "if.mcap", "two_events.mcap", "--out", "out"],
    );
    assert_eq!(code, 2, "{text}");
    assert!(
        text.contains("two_events.mcap") && text.contains("events \"yc\""),
        "{text}"
    );
    assert_eq!(
        std::fs::read_dir(dir.path().join("out")).unwrap().count(),
        0
    );
}
