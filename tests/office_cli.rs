//! The `office` binary: bad arguments exit with code 2 and write nothing; a small run writes
//! its complete results.

use std::path::Path;
use std::process::Command;

fn office(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_office"))
        .args(args)
        .output()
        .expect("office runs")
}

fn assert_rejected(args: &[&str], out: &Path, needle: &str) {
    let o = office(args);
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{args:?}: {stderr}");
    assert!(stderr.contains(needle), "{args:?}: {stderr}");
    assert!(!out.exists(), "{args:?} created {}", out.display());
    let parent = out.parent().unwrap();
    let leftovers: Vec<_> = std::fs::read_dir(parent)
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .filter(|n| n != "bad.toml" && n != "typo.toml" && n != "task.toml" && n != "existing")
        .collect();
    assert!(leftovers.is_empty(), "{args:?} left {leftovers:?}");
}

#[test]
fn bad_arguments_exit_2_and_write_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("run");
    let o = out.to_str().unwrap();
    assert_rejected(&["--task", "7", "--out", o], &out, "unknown Office task 7");
    assert_rejected(
        &["--task", "-1", "--out", o],
        &out,
        "unknown Office task -1",
    );
    assert_rejected(&["--task", "x", "--out", o], &out, "unknown Office task x");
    let task = dir.path().join("task.toml");
    std::fs::write(&task, "map = \"none.map\"\nmachine = \"none.txt\"\n").unwrap();
    assert_rejected(
        &["--task", task.to_str().unwrap(), "--out", o],
        &out,
        "task.toml:1: `map` = \"none.map\": cannot read",
    );
    assert_rejected(
        &["--task", "3", "--algo", "qlearn", "--out", o],
        &out,
        "unknown algorithm \"qlearn\"",
    );
    assert_rejected(
        &["--task", "3", "--seeds", "0", "--out", o],
        &out,
        "--seeds",
    );
    assert_rejected(&["--task", "3"], &out, "--out");

    let bad = dir.path().join("bad.toml");
    std::fs::write(&bad, "[maxent]\nlr = -1.0\n").unwrap();
    assert_rejected(
        &["--task", "3", "--config", bad.to_str().unwrap(), "--out", o],
        &out,
        "lr = -1",
    );
    let typo = dir.path().join("typo.toml");
    std::fs::write(&typo, "[demos]\nn_demo = 3\n").unwrap();
    assert_rejected(
        &[
            "--task",
            "3",
            "--config",
            typo.to_str().unwrap(),
            "--out",
            o,
        ],
        &out,
        "n_demo",
    );
    let missing = dir.path().join("missing.toml");
    assert_rejected(
        &[
            "--task",
            "3",
            "--config",
            missing.to_str().unwrap(),
            "--out",
            o,
        ],
        &out,
        "missing.toml",
    );

    // An existing output directory is left alone.
    let existing = dir.path().join("existing");
    std::fs::create_dir(&existing).unwrap();
    std::fs::write(existing.join("keep.txt"), "mine").unwrap();
    let r = office(&["--task", "0", "--out", existing.to_str().unwrap()]);
    assert_eq!(r.status.code(), Some(2));
    assert_eq!(
        std::fs::read_to_string(existing.join("keep.txt")).unwrap(),
        "mine"
    );
}

#[test]
fn a_small_run_writes_complete_results() {
    let dir = tempfile::tempdir().unwrap();
    let cfg = dir.path().join("small.toml");
    std::fs::write(
        &cfg,
        "[demos]\nn_demos = 8\nhorizon = 60\n[maxent]\nmax_steps = 20\n[apprenticeship]\nmax_steps = 5\n",
    )
    .unwrap();
    let out = dir.path().join("res");
    let r = office(&[
        "--task",
        "0",
        "--algo",
        "maxent",
        "--seeds",
        "2",
        "--seed",
        "5",
        "--config",
        cfg.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--write-demos",
    ]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let demos = std::fs::read_to_string(out.join("demos_seed6.csv")).unwrap();
    assert!(demos.starts_with("demo,step,x,y,action,next_x,next_y,labels,rm_state,reward\n"));
    // 8 demonstrations, each a start row and up to 60 steps.
    assert!(demos.lines().filter(|l| l.contains(",-1,")).count() == 8);
    let metrics = std::fs::read_to_string(out.join("metrics.csv")).unwrap();
    let lines: Vec<&str> = metrics.lines().collect();
    assert!(lines[0].starts_with("task,algo,seed,step,env_interactions,gt_return,success"));
    // Two seeds × (initial + up to 20 steps).
    assert!(
        lines.len() > 2 * 2 && lines.len() <= 1 + 2 * 21,
        "{}",
        lines.len()
    );
    assert!(lines.iter().any(|l| l.starts_with("0,maxent,6,")));
    let svg = std::fs::read_to_string(out.join("success.svg")).unwrap();
    assert!(svg.contains("MaxEnt IRL") && svg.contains("IRL step"));
    assert!(out.join("weights_maxent_seed5.csv").exists());
    assert!(out.join("summary.csv").exists());
    // Nothing else (no temporary directory) next to the results.
    let names: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name().into_string().unwrap())
        .collect();
    assert_eq!(names.len(), 2, "{names:?}");
}

/// One list of algorithms serves both domains; each command takes only its own: Office
/// refuses the ReacherDelivery baselines, `reacher` refuses apprenticeship learning.
#[test]
fn each_domain_accepts_only_its_algorithms() {
    use smirl::irl::Algo;
    for (name, office, reacher) in [
        ("smirl", true, true),
        ("maxent", true, true),
        ("apprenticeship", true, false),
        ("smirl-smooth", false, true),
        ("fkl", false, true),
        ("rkl", false, true),
        ("js", false, true),
    ] {
        assert_eq!(
            Algo::parse_in(name, &Algo::OFFICE).is_ok(),
            office,
            "{name}"
        );
        assert_eq!(Algo::parse_reacher(name).is_ok(), reacher, "{name}");
    }
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("run");
    assert_rejected(
        &[
            "--task",
            "1",
            "--algo",
            "fkl",
            "--out",
            out.to_str().unwrap(),
        ],
        &out,
        "unknown algorithm \"fkl\"",
    );
    let reacher = std::process::Command::new(env!("CARGO_BIN_EXE_reacher"))
        .args(["draw", "--algo", "apprenticeship", "--quick"])
        .args(["--out", out.to_str().unwrap()])
        .output()
        .unwrap();
    assert_eq!(reacher.status.code(), Some(2));
    let err = String::from_utf8_lossy(&reacher.stderr);
    assert!(err.contains("unknown algorithm 'apprenticeship'"), "{err}");
    assert!(!out.exists());
}
