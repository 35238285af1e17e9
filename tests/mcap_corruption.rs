//! Corruption is not truncation (issue 16). Regression tests: on the previous main, a bit
//! flipped in a chunk's length field (footer intact) was taken for truncation, `replay
//! --verify` replayed a quarter of the episodes and exited 0; a log without episodes
//! "verified"; a damaged string length made the reader ask for ~4 GB.

use smirl::env::reacher::ReacherConfig;
use smirl::log::demo::{log_scripted_demos, DemoSpec};
use smirl::log::{read_log_bytes, LogError, LogOptions, RolloutLogger, RunHeader};
use std::path::Path;
use std::process::Command;

fn demo_bytes(dir: &Path, episodes: u64) -> Vec<u8> {
    let path = dir.join("demo.mcap");
    log_scripted_demos(
        &path,
        &DemoSpec {
            task: "sequential".into(),
            sequence: "rgby".into(),
            episodes,
            seed: 7,
            stop_when_done: true,
            env: ReacherConfig::default(),
            event_probability: None,
            reward_machine: None,
        },
        LogOptions {
            chunk_size: 8 << 10,
            ..LogOptions::default()
        },
    )
    .unwrap();
    std::fs::read(&path).unwrap()
}

/// Offsets of the top-level records with `opcode` (each record: opcode, u64 length, body).
fn records(bytes: &[u8], opcode: u8) -> Vec<usize> {
    let mut at = mcap::MAGIC.len();
    let mut found = Vec::new();
    while at + 9 <= bytes.len() - mcap::MAGIC.len() {
        let len = u64::from_le_bytes(bytes[at + 1..at + 9].try_into().unwrap()) as usize;
        if bytes[at] == opcode {
            found.push(at);
        }
        at += 9 + len;
    }
    found
}

fn reacher(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_reacher"))
        .args(args)
        .output()
        .unwrap()
}

#[test]
fn a_damaged_chunk_length_in_a_finished_log_is_corruption() {
    let dir = tempfile::tempdir().unwrap();
    let good = demo_bytes(dir.path(), 12);
    let chunks = records(&good, mcap::records::op::CHUNK);
    assert!(chunks.len() >= 4, "{} chunks", chunks.len());
    let second = chunks[1];
    // Every single-bit flip of the length field: longer (runs past the footer or into the
    // next records) or shorter (cuts the chunk).
    for bit in 0..64 {
        let mut bad = good.clone();
        bad[second + 1 + bit / 8] ^= 1 << (bit % 8);
        match read_log_bytes(&bad, Path::new("flipped.mcap")) {
            Err(LogError::Corrupt { .. }) | Err(LogError::Mcap { .. }) => {}
            Err(e) => panic!("bit {bit}: unexpected error kind: {e}"),
            Ok(log) => panic!(
                "bit {bit}: read as {} episodes, recovery {:?}",
                log.episodes.len(),
                log.recovery
            ),
        }
    }
    // On the command line: `replay --verify` exits 1 and names the file; `learn-rm` and
    // `render` refuse it too.
    let mut bad = good.clone();
    bad[second + 6] ^= 0x10;
    let path = dir.path().join("flipped.mcap");
    std::fs::write(&path, &bad).unwrap();
    let p = path.to_str().unwrap();
    for args in [
        vec!["replay", p, "--verify"],
        vec!["replay", p, "--verify", "--allow-partial"],
        vec!["learn-rm", p, "--out", dir.path().to_str().unwrap()],
    ] {
        let o = reacher(&args);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(1), "{args:?}: {err}");
        assert!(err.contains("flipped.mcap"), "{err}");
    }
}

#[test]
fn a_truncated_log_is_used_only_with_allow_partial() {
    let dir = tempfile::tempdir().unwrap();
    let good = demo_bytes(dir.path(), 12);
    let chunks = records(&good, mcap::records::op::CHUNK);
    let cut = &good[..chunks[3] + 20];
    let log = read_log_bytes(cut, Path::new("cut.mcap")).unwrap();
    let recovery = log.recovery.as_ref().expect("flagged as cut short");
    assert!(recovery.complete_episodes > 0 && recovery.complete_episodes < 12);
    let path = dir.path().join("cut.mcap");
    std::fs::write(&path, cut).unwrap();
    let p = path.to_str().unwrap();
    let out = dir.path().join("rm");
    let o_out = out.to_str().unwrap();
    for args in [
        vec!["replay", p, "--verify"],
        vec!["learn-rm", p, "--out", o_out],
        vec!["render", p, "--out", "/nonexistent-dir-for-test/x.png"],
    ] {
        let o = reacher(&args);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_ne!(o.status.code(), Some(0), "{args:?}: {err}");
    }
    let o = reacher(&["replay", p, "--verify", "--allow-partial"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let o = reacher(&["replay", p]);
    assert!(o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("incomplete"));
}

#[test]
fn a_log_without_episodes_does_not_verify() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("empty.mcap");
    let or = smirl::env::reacher_task::ReacherTask::shipped("or").unwrap();
    let header = RunHeader::of_task("or", or.task(), 0, serde_json::json!({}));
    RolloutLogger::create(&path, header, LogOptions::default())
        .unwrap()
        .finish()
        .unwrap();
    let o = reacher(&["replay", path.to_str().unwrap(), "--verify"]);
    assert_eq!(o.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&o.stderr).contains("no episode"));
}

#[test]
fn damaged_string_lengths_are_errors_not_huge_allocations() {
    let dir = tempfile::tempdir().unwrap();
    let good = demo_bytes(dir.path(), 2);
    let metadata = records(&good, mcap::records::op::METADATA);
    let attachments = records(&good, mcap::records::op::ATTACHMENT);
    assert!(!metadata.is_empty() && !attachments.is_empty());
    // The metadata's name length, and its map's byte length; the attachment's name length.
    let name_len = metadata[0] + 9;
    let name = u32::from_le_bytes(good[name_len..name_len + 4].try_into().unwrap()) as usize;
    let map_len = name_len + 4 + name;
    let attachment_name = attachments[0] + 9 + 16;
    // A chunk's compression string (after three u64 and a u32): found by the long fuzzing
    // pass, the chunk header was parsed before its lengths were checked.
    let chunk = records(&good, mcap::records::op::CHUNK)[0];
    let compression = chunk + 9 + 8 + 8 + 8 + 4;
    for at in [name_len, map_len, attachment_name, compression] {
        let mut bad = good.clone();
        bad[at..at + 4].copy_from_slice(&u32::MAX.to_le_bytes());
        let e = read_log_bytes(&bad, Path::new("long.mcap")).unwrap_err();
        assert!(
            matches!(e, LogError::Corrupt { .. }) && e.to_string().contains("declares"),
            "{e}"
        );
        // Under a 1 GiB address-space limit the command fails cleanly (no abort).
        let path = dir.path().join("long.mcap");
        std::fs::write(&path, &bad).unwrap();
        let o = Command::new("sh")
            .arg("-c")
            .arg(format!(
                "ulimit -v 1048576; exec {} replay {}",
                env!("CARGO_BIN_EXE_reacher"),
                path.display()
            ))
            .output()
            .unwrap();
        assert_eq!(
            o.status.code(),
            Some(1),
            "{}",
            String::from_utf8_lossy(&o.stderr)
        );
    }
}

/// Regression (issue 57, found by the supervised fuzzer): a record's opcode damaged into a
/// footer's (0x07 -> 0x02) ended the reading there, and since the real footer and magic were
/// intact at the end, the log read as complete with the later chunks' episodes silently gone.
#[test]
fn a_record_damaged_into_a_footer_is_corruption_not_an_early_end() {
    let dir = tempfile::tempdir().unwrap();
    let good = demo_bytes(dir.path(), 6);
    let full = read_log_bytes(&good, Path::new("good.mcap")).unwrap();
    assert!(full.recovery.is_none() && full.episodes.len() == 6);
    let index = records(&good, mcap::records::op::MESSAGE_INDEX)[0];
    let mut bad = good.clone();
    bad[index] = mcap::records::op::FOOTER;
    match read_log_bytes(&bad, Path::new("bad.mcap")) {
        Err(LogError::Corrupt { problem, .. }) => assert!(problem.contains("footer"), "{problem}"),
        Err(e) => panic!("unexpected error: {e}"),
        Ok(log) => panic!(
            "read with {} of 6 episodes (recovery {:?})",
            log.episodes.len(),
            log.recovery
        ),
    }
}

/// A log whose run record carries `layout` (one episode of the IF task's shape).
fn log_with_layout(path: &Path, layout: &smirl::env::layout::TaskLayout) {
    use smirl::log::writer::EpisodeStartRecord;
    use smirl::log::StepRecord;
    use smirl::rm::LabelSet;
    let task = smirl::env::reacher_task::ReacherTask::shipped("if").unwrap();
    let t = task.task();
    let header = RunHeader::reacher(
        "if",
        layout,
        &t.text,
        &t.scene_xml,
        t.scene_files.clone(),
        5,
        serde_json::json!({ "env": ReacherConfig::default() }),
    );
    let mut log = RolloutLogger::create(path, header, LogOptions::default()).unwrap();
    let (qpos, qvel) = (vec![0.0; 10], vec![0.0; 10]);
    let balls = [0.1, 0.12, -0.14, 0.06, -0.06, -0.15, 0.14, -0.07];
    log.begin_episode(&EpisodeStartRecord {
        seed: 1,
        phase: "eval",
        qpos: &qpos,
        qvel: &qvel,
        balls: &balls,
        event_steps: &[Some(3)],
        labels: LabelSet::EMPTY,
        rm_state: None,
        obs: &[],
    })
    .unwrap();
    log.step(&StepRecord {
        action: &[0.0, 0.0],
        reward: 0.0,
        labels: LabelSet::EMPTY,
        rm: None,
        qpos: &qpos,
        qvel: &qvel,
        obs: &[],
        terminated: false,
        truncated: true,
    })
    .unwrap();
    log.finish().unwrap();
}

/// Regression: the run record's task layout was used as it was read, so a log whose layout
/// no task file could declare (a letter twice, an event's probability above 1, an empty event
/// window) made `replay`, `render`, `foxglove` and `learn-rm` panic. Each refuses such a log,
/// naming the file and the rule it breaks, before it builds anything from it.
#[test]
fn a_run_record_with_a_layout_no_task_could_declare_is_refused_not_a_panic() {
    let dir = tempfile::tempdir().unwrap();
    let good = smirl::env::reacher_task::ReacherTask::shipped("if")
        .unwrap()
        .task()
        .layout();
    type Damage = fn(&mut smirl::env::layout::TaskLayout);
    let damages: [(&str, Damage, &str); 5] = [
        ("letter_twice", |l| l.events[0].letter = 'r', "twice"),
        ("bad_letter", |l| l.regions[1].letter = '&', "letter"),
        (
            "probability",
            |l| l.events[0].probability = 2.0,
            "probability",
        ),
        ("window", |l| l.events[0].earliest_step = 0, "step"),
        ("radius", |l| l.regions[0].radius = f64::NAN, "radius"),
    ];
    for (name, damage, says) in damages {
        let mut layout = good.clone();
        damage(&mut layout);
        let path = dir.path().join(format!("{name}.mcap"));
        log_with_layout(&path, &layout);
        let p = path.to_str().unwrap();
        let out = |suffix: &str| {
            let path = dir.path().join(format!("{name}_{suffix}"));
            path.to_str().unwrap().to_string()
        };
        let (png, view, rm_dir) = (out("top.png"), out("view.mcap"), out("rm"));
        for args in [
            vec!["replay", p, "--verify"],
            vec!["render", p, "--out", &png],
            vec!["foxglove", p, "--out", &view],
            vec!["learn-rm", p, "--out", &rm_dir],
        ] {
            let r = reacher(&args);
            let err = String::from_utf8_lossy(&r.stderr);
            assert!(
                matches!(r.status.code(), Some(1 | 2)),
                "{name} {args:?}: {:?} {err}",
                r.status.code()
            );
            assert!(!err.contains("panicked"), "{name} {args:?}: {err}");
            assert!(
                err.contains(says) && err.contains(&format!("{name}.mcap")),
                "{name} {args:?}: {err}"
            );
        }
    }
}

/// The check a log's layout gets refuses nothing a task file declares: every committed task
/// passes it, so a log of any of them replays.
#[test]
fn every_committed_tasks_layout_passes_the_check_a_logs_layout_gets() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut files = Vec::new();
    for dir in ["assets/tasks", "assets/tasks/new", "assets/scenes"] {
        for entry in std::fs::read_dir(root.join(dir)).unwrap() {
            let path = entry.unwrap().path();
            if path.extension().is_some_and(|e| e == "toml") {
                files.push(path);
            }
        }
    }
    assert!(files.len() >= 11, "{files:?}");
    for path in files {
        let task = smirl::env::task_file::Task::load(&path).unwrap();
        assert_eq!(task.layout().check(), Ok(()), "{}", path.display());
    }
}
