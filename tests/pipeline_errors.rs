//! A `reacher --task` run that cannot start or go on fails with a variant a caller can match,
//! carrying the facts (paths, counts, seeds) as fields, with the message the binary prints
//! and the class (bad input or failure while running) that picks its exit code.

mod irl_run_common;
use irl_run_common::tiny_config;
use smirl::env::reacher_task::ReacherTask;
use smirl::pipeline::reacher_irl::demos::{make_demos, DemoError};
use smirl::pipeline::reacher_irl::run::{aggregate, open_run, prepare, Silent, MAX_SEEDS};
use smirl::pipeline::reacher_irl::{Algo, DemoSource, PipelineError, RunRequest};
use std::path::Path;

fn request(out: &Path) -> RunRequest {
    RunRequest {
        task: ReacherTask::shipped("or").unwrap(),
        algos: vec![Algo::MaxEnt],
        seeds: 2,
        seed: 0,
        config: tiny_config(),
        out: out.to_path_buf(),
        force: false,
    }
}

#[test]
fn a_request_out_of_range_is_bad_input_found_before_anything_is_written() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("run");
    let too_many = RunRequest {
        seeds: MAX_SEEDS + 1,
        ..request(&dir)
    };
    let e = prepare(&too_many, &dir, &Silent).unwrap_err();
    assert!(
        matches!(e, PipelineError::TooManySeeds { seeds, limit }
            if seeds == MAX_SEEDS + 1 && limit == MAX_SEEDS),
        "{e:?}"
    );
    assert_eq!(
        e.to_string(),
        "--seeds 1001 is more than the limit of 1000 seeds per run"
    );
    assert!(e.is_usage());

    let overflow = RunRequest {
        seed: u64::MAX,
        ..request(&dir)
    };
    let e = prepare(&overflow, &dir, &Silent).unwrap_err();
    assert!(
        matches!(
            e,
            PipelineError::SeedOverflow {
                seed: u64::MAX,
                seeds: 2
            }
        ),
        "{e:?}"
    );
    assert_eq!(
        e.to_string(),
        "--seed 18446744073709551615 + --seeds 2 overflows"
    );
    assert!(e.is_usage());
    assert!(!dir.exists());
}

#[test]
fn a_directory_prepare_did_not_finish_is_not_prepared() {
    let tmp = tempfile::tempdir().unwrap();
    let Err(e) = open_run(tmp.path()) else {
        panic!("an empty directory opens as a run")
    };
    assert!(
        matches!(&e, PipelineError::NotPrepared { dir, file: "prepare.json" } if dir == tmp.path()),
        "{e:?}"
    );
    let d = tmp.path().display();
    assert_eq!(
        e.to_string(),
        format!(
            "{d}: not a prepared run directory (no prepare.json: run `reacher prepare --out {d}` \
             first, or let it finish)"
        )
    );
    assert!(e.is_usage());
}

#[test]
fn a_job_or_aggregate_outside_the_plan_names_what_is_missing() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("run");
    prepare(&request(&dir), &dir, &Silent).unwrap();
    let run = open_run(&dir).unwrap();
    let d = dir.display();

    let e = run.job_at(2).unwrap_err();
    assert!(
        matches!(&e, PipelineError::JobIndexNotInRun { dir: p, index: 2, jobs: 2 } if *p == dir),
        "{e:?}"
    );
    assert_eq!(
        e.to_string(),
        format!("{d}: job index 2 is outside 0..2 (the run has 2 jobs)")
    );
    assert!(e.is_usage());

    let e = run.job(Algo::Fkl, 0).unwrap_err();
    assert!(
        matches!(&e, PipelineError::AlgoNotInRun { algo: Algo::Fkl, prepared, .. }
            if prepared == &["maxent"]),
        "{e:?}"
    );
    assert_eq!(
        e.to_string(),
        format!("{d}: algorithm 'fkl' is not in this run (prepared: maxent)")
    );

    let e = run.job(Algo::MaxEnt, 7).unwrap_err();
    assert!(
        matches!(
            e,
            PipelineError::SeedNotInRun {
                seed: 7,
                first: 0,
                last: 1,
                ..
            }
        ),
        "{e:?}"
    );
    assert_eq!(
        e.to_string(),
        format!("{d}: seed 7 is outside this run's seeds 0..=1")
    );

    let e = aggregate(&run, false, None).unwrap_err();
    assert!(
        matches!(&e, PipelineError::JobsUnfinished { missing, jobs: 2, .. }
            if missing == &["maxent_seed0", "maxent_seed1"]),
        "{e:?}"
    );
    assert_eq!(
        e.to_string(),
        format!(
            "{d}: 2 of 2 jobs have not finished: maxent_seed0, maxent_seed1 (run them with \
             `reacher job`, or pass --partial)"
        )
    );
    assert!(e.is_usage());
}

#[test]
fn expert_demonstrations_without_an_expert_fail_while_running() {
    let mut config = tiny_config();
    config.demo_source = DemoSource::Expert;
    let task = ReacherTask::shipped("or").unwrap();
    let e = make_demos(task, &config, None, 0, None).unwrap_err();
    assert!(matches!(e, DemoError::NoExpert), "{e:?}");
    assert_eq!(
        e.to_string(),
        "demonstrations: demo_source is \"expert\" but no expert policy was loaded"
    );
    // In a run, a missing expert cache is bad input; a failure to produce demonstrations is not.
    assert!(!PipelineError::Demos(e).is_usage());
    let missing = DemoError::Missing {
        path: "cache".into(),
        problem: "no cached expert".into(),
    };
    assert!(PipelineError::Demos(missing).is_usage());
}
