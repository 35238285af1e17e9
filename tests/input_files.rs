//! Every input file is read under a size limit, and what it decodes to is bounded too; every
//! argument is checked before a command writes anything. Regression tests of a read-and-try
//! audit: on the previous main, `reacher replay /dev/zero` read until memory ran out, a log of
//! a few hundred kilobytes whose chunks decompress a thousandfold aborted `replay` on a 2.8 GB
//! allocation, a state index 0xFFFFFFFF in `expert_data.bin` became a 32 GiB allocation, a
//! SAC config of in-range fields (8 × 4096 wide, batch 65 536) aborted after LRM had run,
//! `learn-rm --compare` refused another vocabulary only after writing its outputs, and
//! `demo --sequence zz` left an empty log behind.

mod irl_run_common;
use irl_run_common::tiny_config;
use smirl::env::reacher::ReacherConfig;
use smirl::input_file::read_bytes;
use smirl::log::demo::{log_scripted_demos, DemoSpec};
use smirl::log::reader::{MAX_DECODED_BYTES, MAX_LOG_FILE_BYTES};
use smirl::log::writer::EpisodeStartRecord;
use smirl::log::{read_log, LogError, LogOptions, RolloutLogger, RunHeader, StepRecord};
use smirl::pipeline::office::OfficeConfig;
use smirl::pipeline::reacher_expert::ExpertConfig;
use smirl::pipeline::reacher_irl::ExpertData;
use smirl::rl::sac::SacConfig;
use smirl::rm::LabelSet;
use std::path::Path;
use std::process::{Command, Output};

fn reacher(dir: &Path, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_reacher"))
        .current_dir(dir)
        .args(args)
        .output()
        .unwrap()
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

#[test]
fn files_are_read_only_up_to_their_limit() {
    let dir = tempfile::tempdir().unwrap();
    let exact = dir.path().join("exact");
    std::fs::write(&exact, [7u8; 100]).unwrap();
    assert_eq!(read_bytes(&exact, 100).unwrap(), vec![7u8; 100]);
    let e = read_bytes(&exact, 99).unwrap_err();
    assert!(e.to_string().contains("limit of 99 bytes"), "{e}");
    // A file whose size the file system does not know is cut off at the limit.
    let e = read_bytes(Path::new("/dev/zero"), 4096).unwrap_err();
    assert!(e.to_string().contains("limit of 4096 bytes"), "{e}");
}

#[test]
fn replay_refuses_a_log_over_the_file_limit_before_reading_it() {
    let dir = tempfile::tempdir().unwrap();
    let big = dir.path().join("big.mcap");
    // Sparse: the limit is checked on the size, nothing is read.
    let f = std::fs::File::create(&big).unwrap();
    f.set_len(MAX_LOG_FILE_BYTES + 1).unwrap();
    drop(f);
    for args in [
        vec!["replay", "big.mcap"],
        vec!["render", "big.mcap", "--out", "x.png"],
    ] {
        let o = reacher(dir.path(), &args);
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(1), "{args:?}: {err}");
        assert!(
            err.contains("big.mcap")
                && err.contains(&format!("limit of {MAX_LOG_FILE_BYTES} bytes")),
            "{err}"
        );
        // The cause is printed once.
        assert_eq!(err.matches("limit of").count(), 1, "{err}");
    }
    assert!(!dir.path().join("x.png").exists());
}

/// A small file whose steps decode past the memory limit: each step carries 100 000 joint
/// positions of zero, ~800 kB decoded and a few hundred bytes compressed.
#[test]
fn a_log_that_decodes_past_the_memory_limit_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("bomb.mcap");
    let or = smirl::env::reacher_task::ReacherTask::shipped("or").unwrap();
    let header = RunHeader::of_task(
        "or",
        or.task(),
        0,
        serde_json::json!({"env": ReacherConfig::default()}),
    );
    let mut log = RolloutLogger::create(&path, header, LogOptions::default()).unwrap();
    let zeros = vec![0.0f64; 100_000];
    log.begin_episode(&EpisodeStartRecord {
        seed: 0,
        phase: "demo",
        qpos: &zeros[..4],
        qvel: &zeros[..4],
        balls: &zeros[..8],
        event_steps: &[None],
        labels: LabelSet::EMPTY,
        rm_state: None,
        obs: &[],
    })
    .unwrap();
    let step_bytes = 8 * 2 * zeros.len() as u64;
    for _ in 0..MAX_DECODED_BYTES / step_bytes + 2 {
        log.step(&StepRecord {
            action: &[0.0, 0.0],
            reward: 0.0,
            labels: LabelSet::EMPTY,
            rm: None,
            qpos: &zeros,
            qvel: &zeros,
            obs: &[],
            terminated: false,
            truncated: false,
        })
        .unwrap();
    }
    log.end_episode(false).unwrap();
    log.finish().unwrap();
    let file_bytes = std::fs::metadata(&path).unwrap().len();
    assert!(file_bytes < 16 << 20, "{file_bytes} bytes");
    match read_log(&path) {
        Err(e @ LogError::TooLarge { .. }) => {
            let text = e.to_string();
            assert!(
                text.contains("bomb.mcap") && text.contains(&MAX_DECODED_BYTES.to_string()),
                "{text}"
            );
        }
        other => panic!("expected TooLarge, got {:?}", other.map(|l| l.steps())),
    }
}

#[test]
fn sac_configs_whose_sizes_multiply_past_memory_are_refused() {
    let cases = [
        // Each width and the layer count within their limits, the weights not.
        ("hidden = [4096, 4096, 4096, 4096]\n", "hidden", "weights"),
        // Batch and widths within their limits, the activations not.
        (
            "hidden = [4096, 4096]\nbatch_size = 65536\nreplay_capacity = 65536\n",
            "batch_size",
            "activations",
        ),
    ];
    for (text, field, needle) in cases {
        let e = SacConfig::from_toml(text, "sac.toml")
            .unwrap_err()
            .to_string();
        assert!(
            e.contains(field) && e.contains(needle) && e.contains("limit"),
            "{e}"
        );
    }
    // What the project runs and a large but sane network pass.
    SacConfig::from_toml("hidden = [1024, 1024]\nbatch_size = 4096\n", "sac.toml").unwrap();
    SacConfig::from_toml("hidden = [4096, 4096]\nbatch_size = 1024\n", "sac.toml").unwrap();
}

#[test]
fn a_prepared_run_with_damaged_files_is_refused_by_its_jobs() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    std::fs::write(dir.join("tiny.toml"), tiny_config().to_toml()).unwrap();
    let o = reacher(
        dir,
        &[
            "prepare",
            "--task",
            "or",
            "--algo",
            "smirl",
            "--seeds",
            "1",
            "--config",
            "tiny.toml",
            "--out",
            "run",
        ],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let run = dir.join("run");
    let job = |dir: &Path| reacher(dir, &["job", "--run", "run", "--index", "0"]);

    // A learned-machine state outside the machine.
    let data_path = run.join("expert_data.bin");
    let original = std::fs::read(&data_path).unwrap();
    let mut data = ExpertData::from_bytes(&original, 17).unwrap();
    assert!(!data.learned_states.is_empty());
    data.learned_states[3] = u32::MAX;
    std::fs::write(&data_path, data.to_bytes()).unwrap();
    let o = job(dir);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("expert_data.bin")
            && stderr(&o).contains("state 4294967295 is not a state of the learned machine"),
        "{}",
        stderr(&o)
    );
    // A file of the previous format version (2: with the labels before each step).
    let mut old = original.clone();
    old[8..12].copy_from_slice(&2u32.to_le_bytes());
    std::fs::write(&data_path, &old).unwrap();
    let o = job(dir);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("expert_data.bin")
            && stderr(&o).contains("format version 2 is not supported"),
        "{}",
        stderr(&o)
    );
    std::fs::write(&data_path, &original).unwrap();

    // A machine file over the text limit.
    let perfect = run.join("rm/perfect.txt");
    let text = std::fs::read(&perfect).unwrap();
    let mut big = text.clone();
    big.resize(text.len() + (2 << 20), b'#');
    std::fs::write(&perfect, &big).unwrap();
    let o = job(dir);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("perfect.txt") && stderr(&o).contains("limit"),
        "{}",
        stderr(&o)
    );
    assert!(!run.join("jobs").read_dir().unwrap().any(|e| e
        .unwrap()
        .file_name()
        .to_string_lossy()
        .ends_with(".json")));
}

#[test]
fn commands_check_every_argument_before_writing() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    // A log with the vocabulary rgbyc, and a machine over another one.
    log_scripted_demos(
        &dir.join("demo.mcap"),
        &DemoSpec {
            task: "sequential".into(),
            sequence: "rg".into(),
            episodes: 2,
            seed: 1,
            stop_when_done: true,
            env: ReacherConfig::default(),
            event_probability: None,
            reward_machine: None,
        },
        LogOptions::default(),
    )
    .unwrap();
    std::fs::write(
        dir.join("other.txt"),
        "vocabulary: ab\nstates: 2\ninitial: 0\n(0, 1, 'a', 1)\n",
    )
    .unwrap();
    std::fs::create_dir(dir.join("out")).unwrap();
    let o = reacher(
        dir,
        &[
            "learn-rm",
            "demo.mcap",
            "--out",
            "out",
            "--compare",
            "other.txt",
        ],
    );
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("other.txt") && stderr(&o).contains("vocabulary"));
    assert_eq!(std::fs::read_dir(dir.join("out")).unwrap().count(), 0);

    for (args, needle) in [
        (vec!["--sequence", "zz"], "--sequence"),
        (vec!["--event-probability", "2"], "--event-probability"),
        (vec!["--cancel-probability", "nan"], "--event-probability"),
        (vec!["--episodes", "0"], "--episodes"),
        (vec!["--episodes", "10000000"], "--episodes"),
    ] {
        let mut all = vec!["demo", "--out", "new.mcap"];
        all.extend(&args);
        let o = reacher(dir, &all);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {}", stderr(&o));
        assert!(stderr(&o).contains(needle), "{}", stderr(&o));
        assert!(!dir.join("new.mcap").exists(), "{args:?}");
    }

    // A picture size out of range is the argument's fault, whatever the log.
    let o = reacher(
        dir,
        &["render", "missing.mcap", "--out", "x.png", "--size", "10"],
    );
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("--size") && !stderr(&o).contains("missing.mcap"));
}

#[test]
fn config_errors_name_the_line_of_dotted_keys_inline_tables_and_office_keys() {
    for (text, line) in [
        ("total_steps = 1000\nsac.hidden = [1000000]\n", 2),
        (
            "total_steps = 1000\nsac = { batch_size = 64, hidden = [1000000] }\n",
            2,
        ),
        (
            "total_steps = 1000\n[sac]\nbatch_size = 64\nhidden = [1000000]\n",
            4,
        ),
    ] {
        let e = ExpertConfig::from_toml(text, "expert.toml")
            .unwrap_err()
            .to_string();
        assert!(
            e.contains(&format!("line {line}")) && e.contains("sac.hidden"),
            "{text:?}: {e}"
        );
    }
    let office = include_str!("../experiments/office/config.toml");
    let line_of = |prefix: &str| office.lines().position(|l| l.starts_with(prefix)).unwrap() + 1;
    for (key, replacement) in [("n_demos =", "n_demos = 0"), ("lr =", "lr = -1")] {
        let at = line_of(key);
        let text: Vec<String> = office
            .lines()
            .enumerate()
            .map(|(i, l)| {
                if i + 1 == at {
                    replacement.into()
                } else {
                    l.into()
                }
            })
            .collect();
        let e = OfficeConfig::from_toml(&text.join("\n"))
            .unwrap_err()
            .to_string();
        assert!(e.contains(&format!("line {at}:")), "{replacement}: {e}");
    }
}
