//! A task nobody wrote code for: a task file written here (a new machine, a new layout) runs
//! the IRL pipeline end to end; a bad task file stops `reacher` with exit 2 before any work;
//! a task file's expert is keyed by its content and never the committed expert of a shipped
//! task of the same name.

mod irl_run_common;

use irl_run_common::tiny_config;
use smirl::env::reacher::ReacherConfig;
use smirl::env::reacher_task::ReacherTask;
use smirl::pipeline::reacher_expert::{committed_expert, expert_cache_path};
use smirl::pipeline::reacher_irl::run::Silent;
use smirl::pipeline::reacher_irl::{run_pipeline, Algo, RunRequest};
use std::path::Path;
use std::process::Command;

/// Green, then yellow, never blue: a machine none of the shipped tasks has.
const MACHINE: &str = "vocabulary: rgbyc\nstates: 4\ninitial: 0\nterminal: 2\nfailure: 3\n\
                       (0, 3, 'b', 0)\n(0, 1, 'g&!b', 0)\n(1, 3, 'b', 0)\n(1, 2, 'y&!b', 1)\n";

/// The four built-in balls in a new layout (yellow and red swapped round), a later event.
fn task_text() -> String {
    let mut s = "scene = \"builtin\"\nmachine = \"avoid_blue.txt\"\nepisode_steps = 100\n\
                 randomize_layout = false\n"
        .to_string();
    for (letter, body, [x, y]) in [
        ("r", "red", [0.141, -0.0513]),
        ("g", "green", [-0.0182, -0.1034]),
        ("b", "blue", [-0.0591, 0.0104]),
        ("y", "yellow", [0.0975, 0.1689]),
    ] {
        s.push_str(&format!(
            "\n[[region]]\nletter = \"{letter}\"\nbody = \"{body}\"\nradius = 0.02\nposition = [{x}, {y}]\n"
        ));
    }
    s.push_str(
        "\n[[event]]\nletter = \"c\"\nprobability = 0.3\nearliest_step = 2\nlatest_step = 20\n",
    );
    s
}

fn write_task(dir: &Path) -> std::path::PathBuf {
    std::fs::write(dir.join("avoid_blue.txt"), MACHINE).unwrap();
    let path = dir.join("avoid_blue.toml");
    std::fs::write(&path, task_text()).unwrap();
    path
}

#[test]
fn a_new_task_file_runs_smirl_end_to_end() {
    let tmp = tempfile::tempdir().unwrap();
    let path = write_task(tmp.path());
    let task = ReacherTask::resolve(path.to_str().unwrap()).unwrap();
    assert_eq!(task.name(), "avoid_blue");
    assert!(!task.is_shipped());

    let mut config = tiny_config();
    config.env = task.env_config(&config.env).unwrap();
    // The task's layout and schedule; the tiny config's shorter episodes.
    assert_eq!(config.env.ball_layout[3], [0.0975, 0.1689]);
    assert_eq!(config.env.ball_layout[0], [0.141, -0.0513]);
    assert_eq!(config.env.cancel.probability, 0.3);
    assert_eq!(config.env.cancel.latest_step, 20);
    assert_eq!(config.env.max_steps, 70);
    assert_ne!(config.env, ReacherConfig::default());

    let out = tmp.path().join("run");
    let request = RunRequest {
        task: task.clone(),
        algos: vec![Algo::Smirl],
        seeds: 1,
        seed: 2,
        config,
        out: out.clone(),
        force: false,
    };
    let summary = run_pipeline(&request, &Silent).unwrap();
    assert_eq!(summary.algos.len(), 1);
    // The perfect machine is the file's, the learned one exists, and the run's records name
    // the task file, so the run reads back without being told the task.
    let perfect = std::fs::read_to_string(out.join("rm/perfect.txt")).unwrap();
    assert!(perfect.contains("(1, 2, 'y&!b', 1)"), "{perfect}");
    assert!(out.join("rm/learned.txt").is_file());
    let prepared = std::fs::read_to_string(out.join("prepare.json")).unwrap();
    let canonical = std::fs::canonicalize(&path).unwrap();
    assert!(
        prepared.contains(&format!("\"task\": \"{}\"", canonical.display())),
        "{prepared}"
    );
    let metrics = std::fs::read_to_string(out.join("metrics.csv")).unwrap();
    assert!(
        metrics.lines().skip(1).any(|l| l.starts_with("smirl,2,")),
        "{metrics}"
    );
    let reread = smirl::pipeline::reacher_irl::run::open_run(&out).unwrap();
    assert_eq!(reread.prepared.task, task);
}

#[test]
fn a_bad_task_file_exits_2_before_any_work() {
    let tmp = tempfile::tempdir().unwrap();
    let path = write_task(tmp.path());
    std::fs::write(&path, task_text().replace("\"yellow\"", "\"purple\"")).unwrap();
    let out = tmp.path().join("run");
    let o = Command::new(env!("CARGO_BIN_EXE_reacher"))
        .args(["--task", path.to_str().unwrap(), "--quick", "--out"])
        .arg(&out)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{stderr}");
    assert!(
        stderr.contains("avoid_blue.toml:26: `region[3].body`: no body 'purple'"),
        "{stderr}"
    );
    assert!(!out.exists());
}

#[test]
fn a_task_files_expert_is_keyed_by_its_content() {
    let tmp = tempfile::tempdir().unwrap();
    let path = write_task(tmp.path());
    let task = ReacherTask::resolve(path.to_str().unwrap()).unwrap();
    let cache = Path::new("cache");
    let first = expert_cache_path(cache, task.clone());
    let name = first.file_name().unwrap().to_str().unwrap().to_string();
    assert!(
        name.starts_with("avoid_blue-") || name.starts_with("expert_avoid_blue-"),
        "{name}"
    );
    assert_eq!(
        name.len(),
        "expert_avoid_blue-".len() + 16 + ".policy".len(),
        "{name}"
    );
    // The same content, the same key; a changed machine, another.
    let again = ReacherTask::resolve(path.to_str().unwrap()).unwrap();
    assert_eq!(expert_cache_path(cache, again), first);
    std::fs::write(
        tmp.path().join("avoid_blue.txt"),
        MACHINE.replace("'y&!b', 1)", "'y&!b', 2)"),
    )
    .unwrap();
    let changed = ReacherTask::resolve(path.to_str().unwrap()).unwrap();
    assert_ne!(expert_cache_path(cache, changed), first);
    // Shipped tasks keep their committed experts' names.
    let composite = ReacherTask::shipped("composite").unwrap();
    assert_eq!(
        expert_cache_path(cache, composite.clone()),
        cache.join("expert_composite.policy")
    );
    assert!(committed_expert(composite, &[64, 64]).is_ok());

    // A task file named like a shipped task does not get the shipped task's expert.
    let copy = tmp.path().join("composite.toml");
    std::fs::write(&copy, task_text()).unwrap();
    let impostor = ReacherTask::resolve(copy.to_str().unwrap()).unwrap();
    assert_eq!(impostor.name(), "composite");
    assert!(committed_expert(impostor, &[64, 64]).is_err());
}
