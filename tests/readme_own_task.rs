//! README's "Your own task" is a worked example that runs as it is written: the shell block
//! between `<!-- own-task -->` and `<!-- /own-task -->` runs in an empty temporary directory
//! with the built `reacher` first on the PATH, and every step's output exists and reads back —
//! the machine and the task file it writes, the smoke expert (not cached), the SMIRL run, the
//! learned machine as DOT, and the Foxglove copy of the demonstrations' log.

use smirl::env::reacher_task::ReacherTask;
use smirl::log::read_log;
use smirl::pipeline::foxglove_scene::TOPIC_SCENE;
use smirl::pipeline::reacher_expert::ExpertPolicy;
use smirl::rm::format::read_rm;
use std::path::Path;
use std::process::Command;

/// The README's block between the markers, without its code fence.
fn readme_block() -> String {
    let readme = std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("README.md"))
        .expect("README.md reads");
    let start = readme
        .find("<!-- own-task -->")
        .expect("README marks its own-task block");
    let end = readme
        .find("<!-- /own-task -->")
        .expect("README closes its own-task block");
    let block = &readme[start..end];
    let body = block
        .split_once("```sh\n")
        .expect("the block is a sh code fence")
        .1;
    body.rsplit_once("```")
        .expect("the fence closes")
        .0
        .to_string()
}

#[test]
fn the_readme_worked_example_runs_from_an_empty_directory() {
    let script = readme_block();
    // It uses the installed command, as a reader outside the repository would.
    assert!(!script.contains("cargo "), "{script}");
    assert!(script.contains("--quick"), "{script}");

    let dir = tempfile::tempdir().unwrap();
    let bin = Path::new(env!("CARGO_BIN_EXE_reacher"));
    let path = format!(
        "{}:{}",
        bin.parent().unwrap().display(),
        std::env::var("PATH").unwrap_or_default()
    );
    let out = Command::new("sh")
        .args(["-e", "-c", &script])
        .current_dir(dir.path())
        .env("PATH", path)
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        out.status.success(),
        "README block failed ({}):\n{stdout}\n{stderr}",
        out.status
    );
    let d = dir.path();

    // Step 1 and 2: the machine and the task file it names.
    let machine = read_rm(&d.join("mine.txt")).unwrap();
    assert_eq!(machine.n_states(), 3);
    let task = ReacherTask::resolve(d.join("mine.toml").to_str().unwrap()).unwrap();
    assert_eq!(task.name(), "mine");
    assert_eq!(task.layout().letters(), "gy");

    // Step 3: the smoke expert, in its run directory only (a smoke policy is no expert).
    let expert_run = d.join("target/expert-runs/mine");
    let hidden = smirl::rl::sac::SacConfig::expert().hidden;
    ExpertPolicy::load(&expert_run.join("expert.policy"), task.clone(), &hidden).unwrap();
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(expert_run.join("summary.json")).unwrap())
            .unwrap();
    assert!(summary["env_steps"].as_u64().unwrap() <= 2_100, "{summary}");
    assert!(!d.join("experts").exists(), "--quick cached its policy");

    // Step 4: SMIRL's run, its learned machine over the task's letters.
    let run = d.join("runs/reacher-mine");
    let metrics = std::fs::read_to_string(run.join("metrics.csv")).unwrap();
    assert!(metrics.lines().count() > 1, "{metrics}");
    assert!(metrics.lines().skip(1).all(|l| l.contains("smirl")));
    let learned = read_rm(&run.join("rm/learned.txt")).unwrap();
    assert_eq!(learned.vocab().props(), ['g', 'y']);

    // Step 5: the DOT the block prints is the run's learned machine, one node per state.
    let dot = std::fs::read_to_string(run.join("rm/learned.dot")).unwrap();
    assert!(stdout.contains(&dot), "{stdout}");
    let dot = dot.trim();
    assert!(dot.starts_with("digraph") && dot.ends_with('}'), "{dot}");
    assert_eq!(dot.matches('{').count(), dot.matches('}').count(), "{dot}");
    for u in 0..learned.n_states() {
        assert!(dot.contains(&format!("u{u} [")), "state {u} in {dot}");
    }

    // Step 6: the Foxglove copy holds the log's episodes and a 3D scene per step.
    let view = d.join("demos.foxglove.mcap");
    let demos = read_log(&run.join("logs/demos.mcap")).unwrap();
    assert_eq!(read_log(&view).unwrap().episodes, demos.episodes);
    let bytes = std::fs::read(&view).unwrap();
    let mut scenes = 0;
    for m in mcap::MessageStream::new(&bytes).unwrap() {
        scenes += usize::from(m.unwrap().channel.topic == TOPIC_SCENE);
    }
    let states: usize = demos.episodes.iter().map(|e| e.steps.len() + 1).sum();
    assert_eq!(scenes, states);
}
