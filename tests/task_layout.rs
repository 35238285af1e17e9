//! A task of another shape than the paper's four balls and one event: three regions and two
//! events, written here with its own machine. The environment, the labelling function, the
//! learners' features and the logs all take their layout from the task file: the observation
//! is as long and the label bits are where the layout says, the pipeline runs end to end, and
//! its logs replay, render, export and teach LRM without being told the task — on the built-in
//! scene and on the second scene shipped as an example (its detour task: an event, a region to
//! avoid).

mod irl_run_common;

use irl_run_common::tiny_config;
use smirl::env::layout::TaskLayout;
use smirl::env::reacher::ReacherConfig;
use smirl::env::reacher_controller::inverse_kinematics;
use smirl::env::reacher_task::ReacherTask;
use smirl::env::ContinuousEnv;
use smirl::irl::smirl::FeatureMap;
use smirl::pipeline::reacher_irl::run::Silent;
use smirl::pipeline::reacher_irl::{run_pipeline, Algo, RunRequest};
use smirl::rm::LabelSet;
use std::path::{Path, PathBuf};
use std::process::Command;

/// a, then b; after the event x (before a), d instead. The event z means nothing to the task.
const MACHINE: &str = "vocabulary: abdxz\nstates: 4\ninitial: 0\nterminal: 3\n\
                       (0, 1, 'a&!x', 0)\n(0, 2, 'x', 0)\n(1, 3, 'b', 1)\n(2, 3, 'd&!x', 1)\n";

/// Three of the built-in scene's balls in new places with their own radii, two events.
const TASK: &str = r#"scene = "builtin"
machine = "three.txt"
episode_steps = 60
randomize_layout = false

[[region]]
letter = "a"
body = "yellow"
radius = 0.025
position = [0.12, 0.1]

[[region]]
letter = "b"
body = "red"
radius = 0.02
position = [-0.1, 0.12]

[[region]]
letter = "d"
body = "green"
radius = 0.03
position = [0.02, -0.15]

[[event]]
letter = "x"
probability = 0.5
earliest_step = 1
latest_step = 10

[[event]]
letter = "z"
probability = 0.6
earliest_step = 5
latest_step = 40
"#;

fn write_task(dir: &Path) -> PathBuf {
    std::fs::write(dir.join("three.txt"), MACHINE).unwrap();
    let path = dir.join("three.toml");
    std::fs::write(&path, TASK).unwrap();
    path
}

fn task(dir: &Path) -> ReacherTask {
    ReacherTask::resolve(write_task(dir).to_str().unwrap()).unwrap()
}

#[test]
fn the_layout_follows_the_task_file() {
    let tmp = tempfile::tempdir().unwrap();
    let layout: std::sync::Arc<TaskLayout> = task(tmp.path()).layout();
    assert_eq!(layout.letters(), "abdxz");
    assert_eq!(layout.obs_dim(), 8 + 2 * 3 + 2);
    assert_eq!(layout.region_columns(2), [12, 13]);
    assert_eq!((layout.event_column(0), layout.event_column(1)), (14, 15));
    assert_eq!(layout.touches(), LabelSet(0b00111));
    assert_eq!(layout.events(), LabelSet(0b11000));
    let features = FeatureMap::reacher_labels(&layout);
    assert_eq!((features.len(), features.obs_dim()), (5, 16));
    assert_eq!(features.event_labels(), layout.events());
}

#[test]
fn the_environment_steps_and_labels_by_the_layout() {
    let tmp = tempfile::tempdir().unwrap();
    let task = task(tmp.path());
    let layout = task.layout();
    let mut env = task.make_env(&ReacherConfig::default()).unwrap();
    assert_eq!(env.obs_dim(), 16);
    assert_eq!(env.config().max_steps, 60);
    let labelling = FeatureMap::reacher_labels(&layout);
    let mut obs = vec![0.0f32; env.obs_dim()];
    let mut fired = [0usize; 2];
    for seed in 0..200u64 {
        env.reset(seed, &mut obs);
        let steps = env.event_steps().to_vec();
        assert_eq!(steps.len(), 2);
        let mut seen = [Vec::new(), Vec::new()];
        for t in 1..=60 {
            let s = env.step(&[0.4, -0.3], &mut obs).unwrap();
            // The labelling rule on the observation is the environment's.
            assert_eq!(labelling.labels_of(&obs), s.labels, "seed {seed} step {t}");
            for e in 0..2 {
                let on = s.labels.contains(layout.event_bit(e));
                assert_eq!(obs[layout.event_column(e)], f32::from(u8::from(on)));
                if on {
                    seen[e].push(t);
                }
            }
            assert_eq!(s.truncated, t == 60);
        }
        for e in 0..2 {
            assert_eq!(seen[e], steps[e].into_iter().collect::<Vec<_>>());
            if let Some(t) = steps[e] {
                let ev = &layout.events[e];
                assert!((ev.earliest_step..=ev.latest_step).contains(&t));
                fired[e] += 1;
            }
        }
    }
    // Binomial(200, 0.5) and (200, 0.6), ± 5σ.
    assert!((65..=135).contains(&fired[0]), "{fired:?}");
    assert!((85..=155).contains(&fired[1]), "{fired:?}");

    // Each region's label holds strictly within its own radius of its own centre, and the
    // observation carries tip − centre in the region's columns.
    for (k, region) in layout.regions.iter().enumerate() {
        let [x, y] = region.position;
        assert_eq!(env.positions()[k], [x, y]);
        for (d, inside) in [
            (0.0, true),
            (region.radius - 1e-4, true),
            (region.radius + 1e-4, false),
        ] {
            env.set_arm(inverse_kinematics(x + d, y, 1.0), [0.0, 0.0])
                .unwrap();
            assert_eq!(env.labels(), LabelSet(u32::from(inside) << k), "{k} at {d}");
        }
        env.set_arm(inverse_kinematics(x, y, 1.0), [0.0, 0.0])
            .unwrap();
        env.step(&[0.0, 0.0], &mut obs).unwrap();
        let [cx, cy] = layout.region_columns(k);
        assert!(f64::from(obs[cx]).hypot(f64::from(obs[cy])) < region.radius);
        assert!(env.labels().contains(k));
    }
}

#[test]
fn a_task_of_another_shape_runs_the_pipeline_and_its_logs_read_back() {
    let tmp = tempfile::tempdir().unwrap();
    let task = task(tmp.path());
    let mut config = tiny_config();
    config.env = task.env_config(&config.env).unwrap();
    let out = tmp.path().join("run");
    let request = RunRequest {
        task: task.clone(),
        algos: vec![Algo::Smirl, Algo::Fkl],
        seeds: 1,
        seed: 0,
        config,
        out: out.clone(),
        force: false,
    };
    let summary = run_pipeline(&request, &Silent).unwrap();
    assert_eq!(summary.algos.len(), 2);
    let metrics = std::fs::read_to_string(out.join("metrics.csv")).unwrap();
    for algo in ["smirl", "fkl"] {
        assert!(
            metrics
                .lines()
                .any(|l| l.starts_with(&format!("{algo},0,"))),
            "{metrics}"
        );
    }
    // SMIRL's reward reads the task's columns: five features, both event flags.
    let reward: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(out.join("rewards/smirl_seed0.json")).unwrap(),
    )
    .unwrap();
    let layout = &reward["features"]["layout"];
    assert_eq!(layout["obs_dim"], 16);
    assert_eq!(layout["events"], serde_json::json!([14, 15]));
    assert_eq!(layout["radii"], serde_json::json!([0.025, 0.02, 0.03]));
    assert_eq!(reward["weights"][0].as_array().unwrap().len(), 5);
    let learned = std::fs::read_to_string(out.join("rm/learned.txt")).unwrap();
    assert!(learned.contains("vocabulary: abdxz"), "{learned}");

    logs_read_back(tmp.path(), &out, "vocabulary: abdxz");
}

/// `reacher ARGS`, which must exit 0; its stdout and stderr.
fn reacher_ok(args: &[&str]) -> String {
    let o = Command::new(env!("CARGO_BIN_EXE_reacher"))
        .args(args)
        .output()
        .unwrap();
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    );
    assert_eq!(o.status.code(), Some(0), "{args:?}: {text}");
    text
}

/// The run's demonstration log records its task and scene: replay, render, the Foxglove
/// export and LRM read them from there, without being told the task (written under `tmp`).
fn logs_read_back(tmp: &Path, out: &Path, vocabulary: &str) {
    let demos = out.join("logs/demos.mcap");
    let demos = demos.to_str().unwrap();
    let text = reacher_ok(&["replay", demos, "--verify"]);
    assert!(text.contains("match bit for bit, 0 mismatch"), "{text}");
    let png = tmp.join("episode.png");
    reacher_ok(&["render", demos, "--out", png.to_str().unwrap()]);
    assert!(png.is_file());
    let view = tmp.join("view.mcap");
    reacher_ok(&["foxglove", demos, "--out", view.to_str().unwrap()]);
    assert!(view.is_file());
    let learned = tmp.join("learned");
    std::fs::create_dir(&learned).unwrap();
    reacher_ok(&["learn-rm", demos, "--out", learned.to_str().unwrap()]);
    let text = std::fs::read_to_string(learned.join("learned_rm.txt")).unwrap();
    assert!(text.contains(vocabulary), "{text}");
}

/// The second scene shipped as an example (`assets/scenes/six_targets.xml`): the same arm
/// among six fixed targets, with two task files over it.
fn six_targets(task: &str) -> ReacherTask {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("assets/scenes")
        .join(format!("six_targets_{task}.toml"));
    ReacherTask::resolve(path.to_str().unwrap()).unwrap()
}

#[test]
fn the_six_target_scene_loads_with_its_tasks() {
    let ring = six_targets("ring");
    let detour = six_targets("detour");
    assert_eq!(ring.layout().letters(), "abcdef");
    assert_eq!(ring.layout().obs_dim(), 8 + 12);
    assert_eq!(detour.layout().letters(), "abcdefx");
    assert_eq!(detour.layout().obs_dim(), 8 + 12 + 1);
    // The targets stay where the scene puts them: t4 0.07 m straight below the base.
    let t4 = &ring.layout().regions[3];
    assert!(!t4.movable);
    assert!(t4.position[0].abs() < 1e-9 && (t4.position[1] + 0.07).abs() < 1e-9);
    for task in [&ring, &detour] {
        let mut env = task.make_env(&ReacherConfig::default()).unwrap();
        let mut obs = vec![0.0f32; env.obs_dim()];
        env.reset(3, &mut obs);
        assert_eq!(env.positions(), task.layout().positions().as_slice());
        // Each target's label holds at its centre, alone.
        for (k, [x, y]) in task.layout().positions().into_iter().enumerate() {
            env.set_arm(inverse_kinematics(x, y, 1.0), [0.0, 0.0])
                .unwrap();
            assert_eq!(env.labels(), LabelSet(1 << k), "target {k}");
        }
    }
}

/// The detour task (an event, a region to avoid) over the second scene runs SMIRL, and its
/// logs read back like the built-in scene's.
#[test]
fn a_task_over_the_six_target_scene_runs_the_pipeline_and_its_logs_read_back() {
    let tmp = tempfile::tempdir().unwrap();
    let task = six_targets("detour");
    let mut config = tiny_config();
    config.env = task.env_config(&config.env).unwrap();
    let out = tmp.path().join("run");
    let request = RunRequest {
        task,
        algos: vec![Algo::Smirl],
        seeds: 1,
        seed: 1,
        config,
        out: out.clone(),
        force: false,
    };
    run_pipeline(&request, &Silent).unwrap();
    let metrics = std::fs::read_to_string(out.join("metrics.csv")).unwrap();
    assert!(
        metrics.lines().any(|l| l.starts_with("smirl,1,")),
        "{metrics}"
    );
    let learned = std::fs::read_to_string(out.join("rm/learned.txt")).unwrap();
    assert!(learned.contains("vocabulary: abcdefx"), "{learned}");
    logs_read_back(tmp.path(), &out, "vocabulary: abcdefx");
}
