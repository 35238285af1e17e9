//! The committed experts of the task files written after the paper's four — the new tasks of
//! `assets/tasks/new/` and the six-target scene's two — are where `reacher --task FILE` looks
//! for them (keyed by the task's content: a task edited without retraining its expert has
//! none), and each solves every branch of its task on evaluation episodes other than the ones
//! `reacher expert` reported (`experiments/experts/new_tasks.md`). Only the experts run here:
//! the IRL algorithms run on these tasks in the preregistered protocols
//! (`experiments/protocol/`).

use smirl::env::reacher_task::{Branch, ReacherTask};
use smirl::pipeline::reacher_expert::{evaluate_expert, ExpertConfig};
use smirl::pipeline::reacher_irl::demos::load_expert;
use smirl::rl::sac::ActMode;
use std::path::Path;

/// The task files with a committed expert, and whether their machine has an event's branch.
const TASKS: [(&str, bool); 6] = [
    ("assets/tasks/new/pair.toml", false),
    ("assets/tasks/new/avoid.toml", false),
    ("assets/tasks/new/loop.toml", false),
    ("assets/scenes/six_targets_ring.toml", false),
    ("assets/scenes/six_targets_detour.toml", true),
    ("assets/tasks/new/switch.toml", true),
];

fn task(file: &str) -> ReacherTask {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join(file);
    ReacherTask::resolve(path.to_str().unwrap()).unwrap()
}

#[test]
fn committed_experts_of_the_new_tasks_solve_every_branch() {
    for (file, branches) in TASKS {
        let task = task(file);
        // The default cache beside the task file, as the pipeline reads it.
        let mut policy = load_expert(task.clone(), None)
            .unwrap_or_else(|e| panic!("{file}: no committed expert the pipeline finds: {e}"));
        let env = task.env_config(&ExpertConfig::default().env).unwrap();
        for mode in [ActMode::Sample, ActMode::Mean] {
            // Seed 11: not the seeds of the reported evaluation (`reacher expert`'s) or demos.
            let eval = evaluate_expert(&mut policy, &env, 60, mode, 11).unwrap();
            match eval.branches {
                Some(b) => {
                    assert!(branches, "{file}: a branch where none was expected: {b}");
                    for branch in Branch::ALL {
                        let rate = b.rate(branch).expect("both branches are played");
                        assert!(rate >= 0.95, "{file} {mode:?} {branch}: {b}");
                    }
                }
                None => {
                    assert!(!branches, "{file}: no branch");
                    assert!(eval.success_rate >= 0.95, "{file} {mode:?}: {eval:?}");
                }
            }
        }
    }
}

#[test]
fn an_edited_task_file_has_no_committed_expert() {
    let dir = tempfile::tempdir().unwrap();
    let source = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/tasks/new");
    for file in ["pair.toml", "pair.txt"] {
        std::fs::copy(source.join(file), dir.path().join(file)).unwrap();
    }
    std::fs::create_dir(dir.path().join("experts")).unwrap();
    for entry in std::fs::read_dir(source.join("experts")).unwrap() {
        let entry = entry.unwrap();
        std::fs::copy(
            entry.path(),
            dir.path().join("experts").join(entry.file_name()),
        )
        .unwrap();
    }
    let path = dir.path().join("pair.toml");
    // The copy, unchanged, finds the committed expert beside it.
    assert!(load_expert(ReacherTask::resolve(path.to_str().unwrap()).unwrap(), None).is_ok());
    // One changed episode length later, it has none.
    let text = std::fs::read_to_string(&path).unwrap();
    std::fs::write(
        &path,
        text.replace("episode_steps = 100", "episode_steps = 90"),
    )
    .unwrap();
    let edited = ReacherTask::resolve(path.to_str().unwrap()).unwrap();
    assert!(load_expert(edited, None).is_err());
}
