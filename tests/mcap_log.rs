//! Rollout log: write → read round trips, sampling, drop safety, truncation recovery, bad
//! files, determinism. The official Python reader is python/tests/test_official_mcap_reader.py.

use smirl::env::reacher::ReacherConfig;
use smirl::log::demo::{log_scripted_demos, DemoSpec};
use smirl::log::schema::{sha256_hex, NO_RM, SCHEMA_VERSION};
use smirl::log::writer::EpisodeStartRecord;
use smirl::log::{
    read_log, read_log_bytes, LogError, LogOptions, RolloutLogger, RunHeader, StepRecord,
};
use smirl::rm::LabelSet;
use std::path::Path;

fn shipped_xml() -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/reacher_delivery.xml")
}

fn header() -> RunHeader {
    let sequential = smirl::env::reacher_task::ReacherTask::shipped("sequential").unwrap();
    let mut h = RunHeader::of_task(
        "sequential",
        sequential.task(),
        42,
        serde_json::json!({"env": ReacherConfig::default(), "note": "round trip"}),
    );
    h.reward_machine = Some("vocabulary: rgbyc\nstates: 1\ninitial: 0\n".into());
    h
}

/// Writes two hand-made episodes with awkward values and reads them back field by field.
#[test]
fn every_message_type_round_trips() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("rt.mcap");
    let opts = LogOptions {
        observations: true,
        ..LogOptions::default()
    };
    let mut log = RolloutLogger::create(&path, header(), opts).unwrap();
    let qpos0: Vec<f64> = (0..10).map(|i| i as f64 * 0.1 - 0.3).collect();
    let qvel0 = vec![
        -0.0,
        f64::MIN_POSITIVE,
        1e300,
        -1e-300,
        0.0,
        0.0,
        0.0,
        0.0,
        0.0,
        0.0,
    ];
    let balls = [0.1, 0.12, -0.14, 0.06, -0.06, -0.15, 0.14, -0.07];
    let obs: Vec<f32> = (0..17).map(|i| i as f32 / 7.0).collect();
    assert!(log
        .begin_episode(&EpisodeStartRecord {
            seed: u64::MAX,
            phase: "eval",
            qpos: &qpos0,
            qvel: &qvel0,
            balls: &balls,
            event_steps: &[Some(37)],
            labels: LabelSet(0b1),
            rm_state: Some(0),
            obs: &obs,
        })
        .unwrap());
    // (action, env reward, label bits, RM state and reward)
    type Row = (Vec<f32>, f64, u32, Option<(usize, f64)>);
    let steps: Vec<Row> = vec![
        (vec![1.0, -1.0], -0.25, 0, Some((0, 0.0))),
        (vec![-0.0, 0.5], -1e-17, 0b10001, Some((3, 1.0))),
        (
            vec![0.125, f32::MIN_POSITIVE],
            0.0,
            0b01000,
            Some((4, -2.5)),
        ),
    ];
    for (k, (a, r, l, rm)) in steps.iter().enumerate() {
        let qpos: Vec<f64> = qpos0.iter().map(|q| q + k as f64).collect();
        log.step(&StepRecord {
            action: a,
            reward: *r,
            labels: LabelSet(*l),
            rm: *rm,
            qpos: &qpos,
            qvel: &qvel0,
            obs: &obs,
            terminated: k == 2,
            truncated: false,
        })
        .unwrap();
    }
    log.end_episode(true).unwrap();
    // A second episode without RM, left open: finish() closes it unsuccessful.
    log.begin_episode(&EpisodeStartRecord {
        seed: 7,
        phase: "train",
        qpos: &qpos0,
        qvel: &qvel0,
        balls: &balls,
        event_steps: &[None],
        labels: LabelSet::EMPTY,
        rm_state: None,
        obs: &obs,
    })
    .unwrap();
    log.step(&StepRecord {
        action: &[0.3, 0.4],
        reward: -0.5,
        labels: LabelSet::EMPTY,
        rm: None,
        qpos: &qpos0,
        qvel: &qvel0,
        obs: &obs,
        terminated: false,
        truncated: true,
    })
    .unwrap();
    let summary = log.finish().unwrap();
    assert_eq!((summary.episodes_logged, summary.steps_logged), (2, 4));
    assert!(path.exists() && !dir.path().join("rt.mcap.part").exists());

    let read = read_log(&path).unwrap();
    assert!(read.recovery.is_none());
    let run = &read.run;
    assert_eq!(run.schema_version, SCHEMA_VERSION);
    assert_eq!(
        (run.env.as_str(), run.task.as_str(), run.seed),
        ("ReacherDelivery", "sequential", 42)
    );
    assert_eq!(run.vocabulary, "rgbyc");
    assert_eq!(run.mujoco_version, smirl::mujoco::version_string());
    assert_eq!(run.git_commit, smirl::GIT_COMMIT);
    assert_eq!(run.crate_version, env!("CARGO_PKG_VERSION"));
    assert_eq!(run.config["note"], "round trip");
    assert!(run
        .reward_machine
        .as_deref()
        .unwrap()
        .starts_with("vocabulary"));
    let xml = std::fs::read_to_string(shipped_xml()).unwrap();
    assert_eq!(read.model_xml.as_deref(), Some(xml.as_str()));
    assert_eq!(run.model_xml_sha256, sha256_hex(&xml));
    let config: serde_json::Value =
        serde_json::from_str(read.config_json.as_deref().unwrap()).unwrap();
    assert_eq!(config, run.config);
    assert_eq!(read.metadata["seed"], "42");
    assert_eq!(read.metadata["model_xml_sha256"], run.model_xml_sha256);

    assert_eq!(read.episodes.len(), 2);
    let e0 = &read.episodes[0];
    assert_eq!(
        (e0.start.episode, e0.start.seed, e0.start.phase.as_str()),
        (0, u64::MAX, "eval")
    );
    let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    assert_eq!(bits(&e0.start.qpos), bits(&qpos0));
    assert_eq!(bits(&e0.start.qvel), bits(&qvel0));
    assert_eq!(e0.start.balls, balls);
    assert_eq!(
        (e0.start.cancel_step, e0.start.labels, e0.start.rm_state),
        (37, 1, 0)
    );
    assert_eq!(e0.start.obs, obs);
    assert_eq!(e0.steps.len(), 3);
    for (k, (s, (a, r, l, rm))) in e0.steps.iter().zip(&steps).enumerate() {
        assert_eq!(s.episode, 0);
        assert_eq!(s.step as usize, k + 1);
        assert_eq!(
            s.action.iter().map(|x| x.to_bits()).collect::<Vec<_>>(),
            a.iter().map(|x| x.to_bits()).collect::<Vec<_>>()
        );
        assert_eq!(s.reward.to_bits(), r.to_bits());
        assert_eq!(s.labels, *l);
        assert_eq!(s.rm_state, rm.unwrap().0 as i64);
        assert_eq!(s.rm_reward.to_bits(), rm.unwrap().1.to_bits());
        assert_eq!(s.terminated, k == 2);
        assert_eq!(s.obs, obs);
        let qpos: Vec<f64> = qpos0.iter().map(|q| q + k as f64).collect();
        assert_eq!(bits(&s.qpos), bits(&qpos));
    }
    assert_eq!(e0.steps[1].label_text, "rc");
    assert_eq!(e0.steps[2].label_text, "y");
    let end0 = e0.end.as_ref().unwrap();
    assert_eq!((end0.length, end0.success, end0.rm_state), (3, true, 4));
    assert_eq!(end0.env_return, -0.25 + -1e-17 + 0.0);
    assert_eq!(end0.rm_return, -1.5);

    let e1 = &read.episodes[1];
    assert_eq!(
        (e1.start.episode, e1.start.cancel_step, e1.start.rm_state),
        (1, 0, NO_RM)
    );
    assert_eq!(e1.steps[0].rm_state, NO_RM);
    assert!(e1.steps[0].truncated);
    let end1 = e1.end.as_ref().unwrap();
    assert_eq!(
        (end1.length, end1.success, end1.rm_state),
        (1, false, NO_RM)
    );
}

fn demo(path: &Path, episodes: u64, options: LogOptions) {
    log_scripted_demos(
        path,
        &DemoSpec {
            task: "sequential".into(),
            sequence: "rgby".into(),
            episodes,
            seed: 100,
            stop_when_done: false,
            env: ReacherConfig::default(),
            event_probability: None,
            reward_machine: None,
        },
        options,
    )
    .unwrap();
}

#[test]
fn every_nth_episode_and_drop_finish_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("nth.mcap");
    demo(
        &path,
        10,
        LogOptions {
            every_nth_episode: 3,
            ..LogOptions::default()
        },
    );
    let log = read_log(&path).unwrap();
    let ids: Vec<u64> = log.episodes.iter().map(|e| e.start.episode).collect();
    assert_eq!(ids, vec![0, 3, 6, 9]);
    assert!(log
        .episodes
        .iter()
        .all(|e| e.steps.len() == 100 && e.end.as_ref().unwrap().success));
    assert_eq!(log.run.every_nth_episode, 3);

    // Dropped without finish(): still a complete, renamed file.
    let dropped = dir.path().join("dropped.mcap");
    {
        let mut log = RolloutLogger::create(&dropped, header(), LogOptions::default()).unwrap();
        log.begin_episode(&EpisodeStartRecord {
            seed: 1,
            phase: "train",
            qpos: &[0.0; 10],
            qvel: &[0.0; 10],
            balls: &[0.0; 8],
            event_steps: &[None],
            labels: LabelSet::EMPTY,
            rm_state: None,
            obs: &[],
        })
        .unwrap();
    }
    let log = read_log(&dropped).unwrap();
    assert!(log.recovery.is_none());
    assert_eq!(log.episodes.len(), 1);
    assert!(!log.episodes[0].end.as_ref().unwrap().success);
}

#[test]
fn same_seed_gives_identical_files() {
    let dir = tempfile::tempdir().unwrap();
    let (a, b) = (dir.path().join("a.mcap"), dir.path().join("b.mcap"));
    demo(&a, 3, LogOptions::default());
    demo(&b, 3, LogOptions::default());
    assert_eq!(std::fs::read(&a).unwrap(), std::fs::read(&b).unwrap());
}

/// Cuts a many-chunk log at several offsets: each prefix is read up to its last complete
/// chunk, exactly, with a recovery note; nothing panics.
#[test]
fn truncated_file_is_recovered_up_to_last_complete_chunk() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("cut.mcap");
    demo(
        &path,
        12,
        LogOptions {
            chunk_size: 8 << 10,
            ..LogOptions::default()
        },
    );
    let bytes = std::fs::read(&path).unwrap();
    let full = read_log(&path).unwrap();
    let summary = mcap::Summary::read(&bytes).unwrap().unwrap();
    assert!(
        summary.chunk_indexes.len() >= 5,
        "{} chunks",
        summary.chunk_indexes.len()
    );
    // Messages in each chunk, and where each chunk ends.
    let chunk_ends: Vec<(u64, usize)> = summary
        .chunk_indexes
        .iter()
        .map(|ci| {
            let n = summary.stream_chunk(&bytes, ci).unwrap().count();
            (ci.chunk_start_offset + ci.chunk_length, n)
        })
        .collect();
    let data_end = chunk_ends.last().unwrap().0 as usize;
    let mut cuts: Vec<usize> = chunk_ends
        .iter()
        .flat_map(|&(end, _)| [end as usize - 1, end as usize + 3])
        .collect();
    // Inside the data, in the summary section, inside the footer.
    cuts.extend([
        data_end / 3,
        data_end / 2 + 17,
        data_end + 40,
        bytes.len() - 30,
    ]);
    for cut in cuts {
        let got = read_log_bytes(&bytes[..cut], Path::new("cut.mcap"));
        let expected_messages: usize = chunk_ends
            .iter()
            .filter(|&&(end, _)| end as usize <= cut)
            .map(|&(_, n)| n)
            .sum();
        match got {
            Ok(log) => {
                let rec = log
                    .recovery
                    .as_ref()
                    .expect("a cut file is flagged as recovered");
                assert_eq!(log.messages as usize, expected_messages, "cut at {cut}");
                assert!(rec
                    .to_string()
                    .contains(&format!("recovered {expected_messages} messages")));
                // What was recovered is a prefix of the full log.
                for (e, f) in log.episodes.iter().zip(&full.episodes) {
                    assert_eq!(e.start, f.start);
                    assert_eq!(e.steps[..], f.steps[..e.steps.len()]);
                }
            }
            // Cut before the chunk holding the run record: an error naming the file.
            Err(e) => {
                assert_eq!(expected_messages, 0, "cut at {cut}: {e}");
                assert!(e.to_string().contains("cut.mcap"));
            }
        }
    }
}

#[test]
fn bad_files_are_errors_naming_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let p = |name: &str| dir.path().join(name);

    let missing = read_log(&p("missing.mcap")).unwrap_err();
    assert!(matches!(missing, LogError::Io { .. }) && missing.to_string().contains("missing.mcap"));

    for (name, bytes) in [
        ("empty.mcap", vec![]),
        (
            "text.mcap",
            b"hello, this is not an mcap file at all".to_vec(),
        ),
        (
            "random.mcap",
            (0..4000u32)
                .map(|i| (i.wrapping_mul(2654435761) >> 13) as u8)
                .collect(),
        ),
    ] {
        std::fs::write(p(name), &bytes).unwrap();
        let e = read_log(&p(name)).unwrap_err();
        assert!(matches!(e, LogError::NotMcap { .. }), "{name}: {e}");
        assert!(e.to_string().contains(name));
    }

    // MCAP magic followed by garbage.
    let mut garbage = mcap::MAGIC.to_vec();
    garbage.extend((0..500u32).map(|i| (i * 7919 % 251) as u8));
    std::fs::write(p("garbage.mcap"), &garbage).unwrap();
    let e = read_log(&p("garbage.mcap")).unwrap_err();
    assert!(e.to_string().contains("garbage.mcap"), "{e}");

    // A valid MCAP that is not a rollout log.
    {
        let f = std::fs::File::create(p("foreign.mcap")).unwrap();
        let mut w = mcap::WriteOptions::new()
            .compression_threads(0)
            .create(f)
            .unwrap();
        let s = w.add_schema("x", "jsonschema", b"{}").unwrap();
        let c = w
            .add_channel(s, "/other", "json", &Default::default())
            .unwrap();
        w.write_to_known_channel(
            &mcap::records::MessageHeader {
                channel_id: c,
                sequence: 0,
                log_time: 0,
                publish_time: 0,
            },
            b"{}",
        )
        .unwrap();
        w.finish().unwrap();
    }
    let e = read_log(&p("foreign.mcap")).unwrap_err();
    assert!(matches!(e, LogError::NotRolloutLog { .. }), "{e}");

    // A log claiming schema version 2.
    {
        let f = std::fs::File::create(p("v2.mcap")).unwrap();
        let mut w = mcap::WriteOptions::new()
            .compression_threads(0)
            .create(f)
            .unwrap();
        let s = w.add_schema("smirl.v1.Run", "jsonschema", b"{}").unwrap();
        let c = w
            .add_channel(s, "/run", "json", &Default::default())
            .unwrap();
        w.write_to_known_channel(
            &mcap::records::MessageHeader {
                channel_id: c,
                sequence: 0,
                log_time: 0,
                publish_time: 0,
            },
            br#"{"schema_version": 2}"#,
        )
        .unwrap();
        w.finish().unwrap();
    }
    let e = read_log(&p("v2.mcap")).unwrap_err();
    assert!(matches!(e, LogError::UnknownSchemaVersion { .. }), "{e}");
    assert!(
        e.to_string().contains("v2.mcap") && e.to_string().contains("version 2"),
        "{e}"
    );

    // A real log with bytes flipped inside its data: an error or a flagged recovery, never a
    // panic and never a silently complete read.
    demo(&p("good.mcap"), 2, LogOptions::default());
    let good = std::fs::read(p("good.mcap")).unwrap();
    for at in [good.len() / 4, good.len() / 2, good.len() * 3 / 4] {
        let mut bad = good.clone();
        for b in &mut bad[at..at + 16] {
            *b ^= 0x5a;
        }
        if let Ok(log) = read_log_bytes(&bad, Path::new("flipped.mcap")) {
            let same = log.episodes == read_log_bytes(&good, Path::new("g")).unwrap().episodes;
            assert!(
                !same || log.recovery.is_some(),
                "flip at {at} went unnoticed"
            );
        }
    }
}
