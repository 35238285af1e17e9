//! The command entry points behind the binaries (`pipeline::commands`) classify bad input as a
//! `UsageError` (the binaries' exit status 2) before writing anything, and a failure while
//! running as another error (exit status 1).

use smirl::env::reacher_task::ReacherTask;
use smirl::pipeline::commands::{self, draw, expert, irl, logs, office};
use smirl::pipeline::reacher_irl::Algo;
use std::path::{Path, PathBuf};

fn assert_usage(result: anyhow::Result<()>, needle: &str) {
    let e = result.expect_err("bad input is refused");
    assert!(commands::is_usage(&e), "not a usage error: {e:#}");
    assert!(format!("{e:#}").contains(needle), "{e:#}");
}

fn assert_empty(dir: &Path) {
    let left: Vec<_> = std::fs::read_dir(dir).unwrap().collect();
    assert!(left.is_empty(), "{left:?}");
}

fn irl_request(out: PathBuf) -> irl::IrlRequest {
    irl::IrlRequest {
        task: Some(ReacherTask::shipped("or").unwrap()),
        algo: None,
        seeds: 1,
        seed: 0,
        quick: true,
        config: None,
        expert_config: None,
        out: Some(out),
        force: false,
        print_config: false,
        quiet: true,
    }
}

#[test]
fn bad_input_to_every_command_is_a_usage_error_and_writes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let missing = dir.path().join("missing.toml");

    assert_usage(
        irl::run(irl::IrlRequest {
            task: None,
            ..irl_request(dir.path().join("run"))
        }),
        "nothing to do: give --task <or|sequential|if|composite|blue|FILE.toml> or a subcommand",
    );
    assert_usage(
        irl::run(irl::IrlRequest {
            algo: Some("foo".into()),
            ..irl_request(dir.path().join("run"))
        }),
        "unknown algorithm 'foo'",
    );
    assert_usage(
        irl::prepare(irl::IrlRequest {
            config: Some(missing.clone()),
            quick: false,
            ..irl_request(dir.path().join("run"))
        }),
        "missing.toml",
    );
    assert_usage(
        irl::reward(&dir.path().join("r.bin"), &["1,x".into()]),
        "--at 1,x: expected x,y (two numbers)",
    );
    assert_usage(
        irl::job(irl::JobRequest {
            run: dir.path().join("none"),
            index: Some(0),
            algo: None,
            seed: None,
            quiet: true,
        }),
        "none",
    );
    assert_usage(
        expert::run(expert::ExpertRequest {
            task: ReacherTask::shipped("if").unwrap(),
            config: Some(missing.clone()),
            quick: false,
            seed: 0,
            resume: false,
            out: Some(dir.path().join("expert")),
            force: false,
            cache: None,
            train_log_every: 1,
            quiet: true,
        }),
        "missing.toml",
    );
    assert_usage(
        expert::run(expert::ExpertRequest {
            task: ReacherTask::shipped("if").unwrap(),
            config: Some(missing.clone()),
            quick: true,
            seed: 0,
            resume: false,
            out: Some(dir.path().join("expert")),
            force: false,
            cache: None,
            train_log_every: 1,
            quiet: true,
        }),
        "--quick and --config",
    );
    assert_usage(
        draw::run(draw::DrawRequest {
            algo: Algo::Smirl,
            target: None,
            config: None,
            quick: true,
            seed: 0,
            out: dir.path().join("draw"),
            force: false,
            quiet: true,
        }),
        "ReacherDraw runs maxent, fkl, rkl or js",
    );
    assert_usage(
        logs::learn_rm(logs::LearnRmRequest {
            files: vec![dir.path().join("log.mcap")],
            out: dir.path().to_path_buf(),
            force: false,
            compare: None,
            max_states: 0,
            steps: 10,
            seed: 0,
            allow_partial: false,
            no_merge: false,
            no_events: false,
        }),
        "--max-states must be in 1..=",
    );
    let office_request = office::OfficeRequest {
        task: "9".into(),
        algo: "all".into(),
        seeds: 1,
        seed: 0,
        out: dir.path().join("office"),
        config: None,
        force: false,
        write_demos: false,
    };
    assert_usage(office::run(office_request.clone()), "unknown Office task 9");
    assert_usage(
        office::run(office::OfficeRequest {
            task: "1".into(),
            seeds: office::MAX_SEEDS + 1,
            ..office_request
        }),
        "seeds per run",
    );
    assert_empty(dir.path());
}

#[test]
fn a_failure_while_running_is_not_a_usage_error() {
    let dir = tempfile::tempdir().unwrap();
    // A missing log is found while running (the arguments themselves are fine).
    let e = logs::replay(&dir.path().join("missing.mcap"), true, false).unwrap_err();
    assert!(!commands::is_usage(&e), "{e:#}");
    assert!(format!("{e:#}").contains("missing.mcap"), "{e:#}");
}
