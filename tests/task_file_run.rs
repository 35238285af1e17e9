//! A task nobody wrote code for: a task file written here (a new machine, a new layout) runs
//! the IRL pipeline end to end; every bad task file stops `reacher` with exit 2 before any
//! work; a task file's expert is keyed by its content (task, machine and scene) and never the
//! committed expert of a shipped task of the same name; `reacher --task FILE` trains a missing
//! expert first (with `--expert-config`, a smoke-sized one here) and reuses it once cached; a
//! copied task of four regions runs its cached expert through demonstrations, SMIRL and
//! evaluation; `reacher demo` applies the event chance it is asked for.

mod irl_run_common;

use irl_run_common::tiny_config;
use smirl::env::reacher::ReacherConfig;
use smirl::env::reacher_task::ReacherTask;
use smirl::log::RolloutLog;
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

/// `reacher --task <path> --quick --out <out>`.
fn run_quick(path: &Path, out: &Path) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_reacher"))
        .args(["--task", path.to_str().unwrap(), "--quick", "--out"])
        .arg(out)
        .output()
        .unwrap()
}

#[test]
fn a_new_task_file_runs_smirl_end_to_end() {
    let tmp = tempfile::tempdir().unwrap();
    let path = write_task(tmp.path());
    let task = ReacherTask::resolve(path.to_str().unwrap()).unwrap();
    assert_eq!(task.name(), "avoid_blue");
    assert!(!task.is_shipped());

    let config = tiny_config();
    let config = config.over_task(&task).unwrap();
    // The task's layout and schedule; the tiny config's shorter episodes.
    let positions = config.env.ball_layout.as_ref().unwrap();
    assert_eq!(positions[3], [0.0975, 0.1689]);
    assert_eq!(positions[0], [0.141, -0.0513]);
    let schedule = config.env.cancel.as_ref().unwrap();
    assert_eq!(schedule.probability, 0.3);
    assert_eq!(schedule.latest_step, 20);
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
    let o = run_quick(&path, &out);
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{stderr}");
    assert!(
        stderr.contains("avoid_blue.toml:26: `region[3].body`: no body 'purple'"),
        "{stderr}"
    );
    assert!(!out.exists());
}

/// Every bad-input case of a task file stops `reacher` with exit 2, its message naming the
/// file, the line and the key (or the limit), and nothing written: the checks run when the
/// `--task` argument is read, before any work.
#[test]
fn every_bad_task_file_case_exits_2_naming_its_place() {
    let tmp = tempfile::tempdir().unwrap();
    let path = write_task(tmp.path());
    let text = task_text();
    let extra_events: String = ["d", "e", "f", "h"]
        .iter()
        .map(|l| format!("\n[[event]]\nletter = \"{l}\"\nprobability = 0.1\nearliest_step = 2\nlatest_step = 9\n"))
        .collect();
    let extra_regions: String = ["k", "m", "n"]
        .iter()
        .map(|l| format!("\n[[region]]\nletter = \"{l}\"\nbody = \"blue\"\nradius = 0.02\n"))
        .collect();
    let xml = smirl::assets::REACHER_XML.replace(
        "name=\"fingertip\" pos=\"0.11 0 0\"",
        "name=\"tip\" pos=\"0.11 0 0\"",
    );
    std::fs::write(tmp.path().join("tipless.xml"), xml).unwrap();
    std::fs::write(tmp.path().join("not.xml"), "this is not MJCF").unwrap();
    let padded = format!("{text}#{}\n", "x".repeat(1 << 20));
    let cases: Vec<(&str, String, &str, &str)> = vec![
        (
            "a letter used twice",
            text.replace("letter = \"c\"", "letter = \"r\""),
            MACHINE,
            "avoid_blue.toml:31: `event[0].letter`: letter 'r' is defined twice (first on line 7)",
        ),
        (
            "a machine proposition no label or event defines",
            text.clone(),
            "vocabulary: rgbycz\nstates: 1\ninitial: 0\nterminal: \nfailure: \n",
            "avoid_blue.toml:2: `machine`",
        ),
        (
            "a radius of 0",
            text.replacen("radius = 0.02", "radius = 0.0", 1),
            MACHINE,
            "avoid_blue.toml:9: `region[0].radius`",
        ),
        (
            "a radius beyond the arena",
            text.replacen("radius = 0.02", "radius = 0.5", 1),
            MACHINE,
            "avoid_blue.toml:9: `region[0].radius`",
        ),
        (
            "an event window outside the episode",
            text.replace("latest_step = 20", "latest_step = 101"),
            MACHINE,
            "avoid_blue.toml:34: `event[0].latest_step`",
        ),
        (
            "an unreadable scene",
            text.replace("\"builtin\"", "\"absent.xml\""),
            MACHINE,
            "avoid_blue.toml:1: `scene`",
        ),
        (
            "a scene MuJoCo cannot load",
            text.replace("\"builtin\"", "\"not.xml\""),
            MACHINE,
            "avoid_blue.toml:1: `scene`: cannot load the scene",
        ),
        (
            "a scene without the fingertip body",
            text.replace("\"builtin\"", "\"tipless.xml\""),
            MACHINE,
            "avoid_blue.toml:1: `scene`",
        ),
        (
            "more events than the limit",
            format!("{text}{extra_events}"),
            MACHINE,
            "5 events, more than the limit of 4",
        ),
        (
            "more randomised regions than the limit",
            format!("{text}{extra_regions}")
                .replace("randomize_layout = false", "randomize_layout = true"),
            MACHINE,
            "7 regions in a randomised layout, more than the limit of 6",
        ),
        (
            "an unknown site",
            text.replacen("body = \"red\"", "site = \"nosuch\"", 1),
            MACHINE,
            "avoid_blue.toml:8: `region[0].site`: no site 'nosuch'",
        ),
        (
            "a position beyond the layout range",
            text.replace("[0.141, -0.0513]", "[0.29, -0.0513]"),
            MACHINE,
            "avoid_blue.toml:10: `region[0].position`",
        ),
        (
            "an event window starting before the first step",
            text.replace("earliest_step = 2", "earliest_step = 0"),
            MACHINE,
            "avoid_blue.toml:33: `event[0].earliest_step`",
        ),
        (
            "more regions than the limit",
            format!(
                "{text}{extra_regions}{}",
                extra_regions
                    .replace("\"k\"", "\"p\"")
                    .replace("\"m\"", "\"q\"")
                    .replace("\"n\"", "\"s\"")
            ),
            MACHINE,
            "avoid_blue.toml:6: `region`: 10 regions, more than the limit of 8",
        ),
        (
            "more steps than the limit",
            text.replace("episode_steps = 100", "episode_steps = 10001"),
            MACHINE,
            "avoid_blue.toml:3: `episode_steps`: episode_steps 10001 must be between 1 and 10000",
        ),
        (
            "a task file over 1 MiB",
            padded,
            MACHINE,
            "larger than the limit of 1048576 bytes",
        ),
    ];
    for (what, task, machine, expected) in cases {
        std::fs::write(&path, &task).unwrap();
        std::fs::write(tmp.path().join("avoid_blue.txt"), machine).unwrap();
        let out = tmp.path().join("run");
        let o = run_quick(&path, &out);
        let stderr = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{what}: {stderr}");
        assert!(stderr.contains(expected), "{what}: {stderr}");
        assert!(
            stderr.contains("avoid_blue.toml"),
            "{what}: the file is not named: {stderr}"
        );
        assert!(!out.exists(), "{what}: {} was written", out.display());
    }
    // A machine file over 1 MiB: its own name and the limit.
    std::fs::write(&path, task_text()).unwrap();
    let big = format!("{MACHINE}#{}\n", "x".repeat(1 << 20));
    std::fs::write(tmp.path().join("avoid_blue.txt"), big).unwrap();
    let o = run_quick(&path, &tmp.path().join("run"));
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{stderr}");
    assert!(
        stderr.contains("avoid_blue.txt") && stderr.contains("limit of 1048576 bytes"),
        "{stderr}"
    );
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
    // A user's scene: the same task text over an edited scene file, another key.
    std::fs::write(tmp.path().join("avoid_blue.txt"), MACHINE).unwrap();
    let scene = tmp.path().join("scene.xml");
    std::fs::write(&scene, smirl::assets::REACHER_XML).unwrap();
    std::fs::write(&path, task_text().replace("\"builtin\"", "\"scene.xml\"")).unwrap();
    let own_scene = ReacherTask::resolve(path.to_str().unwrap()).unwrap();
    let before = expert_cache_path(cache, own_scene);
    assert_ne!(before, first);
    let edited =
        smirl::assets::REACHER_XML.replacen("<worldbody>", "<worldbody>\n    <!-- edited -->", 1);
    assert_ne!(edited, smirl::assets::REACHER_XML);
    std::fs::write(&scene, edited).unwrap();
    let edited_scene = ReacherTask::resolve(path.to_str().unwrap()).unwrap();
    assert_ne!(expert_cache_path(cache, edited_scene), before);
    // A scene that includes a file which includes another: editing either makes another key.
    let xml = smirl::assets::REACHER_XML;
    let (start, end) = (
        xml.find("<actuator>").unwrap(),
        xml.find("</actuator>").unwrap() + "</actuator>".len(),
    );
    std::fs::create_dir_all(tmp.path().join("parts")).unwrap();
    let parts = |outer: &str, inner: &str| {
        std::fs::write(
            tmp.path().join("parts/outer.xml"),
            format!("<mujoco>{outer}<include file=\"parts/motors.xml\"/></mujoco>"),
        )
        .unwrap();
        std::fs::write(
            tmp.path().join("parts/motors.xml"),
            format!("<mujoco>{inner}{}</mujoco>", &xml[start..end]),
        )
        .unwrap();
        let task = ReacherTask::resolve(path.to_str().unwrap()).unwrap();
        expert_cache_path(cache, task)
    };
    let including = format!(
        "{}<include file=\"parts/outer.xml\"/>{}",
        &xml[..start],
        &xml[end..]
    );
    std::fs::write(&scene, including).unwrap();
    let keys = [
        parts("", ""),
        parts("", ""),
        parts("<!-- edited -->", ""),
        parts("", "<!-- edited -->"),
    ];
    assert_eq!(keys[0], keys[1], "the same files, the same key");
    assert_ne!(keys[2], keys[0], "an edited included file");
    assert_ne!(
        keys[3], keys[0],
        "an edited file the included file includes"
    );
    assert_ne!(keys[3], keys[2]);
    std::fs::write(&path, task_text()).unwrap();
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

/// A one-region task that any policy solves: the region covers the fingertip's start, so a
/// smoke-sized expert completes every demonstration.
const START_MACHINE: &str = "vocabulary: g\nstates: 2\ninitial: 0\nterminal: 1\n(0, 1, 'g', 1)\n";
const START_TASK: &str = "scene = \"builtin\"\nmachine = \"start.txt\"\nepisode_steps = 20\n\
                          randomize_layout = false\nregion = [{ letter = \"g\", body = \"green\", \
                          radius = 0.05, position = [0.2, 0.0] }]\n";

/// Writes into `d` the quick run config of `task` with the expert as the demonstrations'
/// source (`run.toml`) and a smoke-sized expert config (`expert.toml`).
fn write_expert_configs(d: &Path, task: &str) {
    let quick = Command::new(env!("CARGO_BIN_EXE_reacher"))
        .current_dir(d)
        .args(["--task", task, "--quick", "--print-config"])
        .output()
        .unwrap();
    assert!(quick.status.success());
    let config = String::from_utf8(quick.stdout).unwrap();
    assert!(config.contains("demo_source = \"scripted\""), "{config}");
    std::fs::write(
        d.join("run.toml"),
        config.replace("demo_source = \"scripted\"", "demo_source = \"expert\""),
    )
    .unwrap();
    std::fs::write(
        d.join("expert.toml"),
        "total_steps = 300\ncheckpoint_every = 300\neval_episodes = 4\nprogress_window = 4\n",
    )
    .unwrap();
}

/// `reacher --task FILE --config RUN --expert-config EXPERT --algo smirl --quiet --out OUT`.
fn run_with_expert(dir: &Path, expert: &str, out: &str) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_reacher"))
        .current_dir(dir)
        .args([
            "--task",
            "start.toml",
            "--config",
            "run.toml",
            "--expert-config",
            expert,
            "--algo",
            "smirl",
            "--quiet",
            "--out",
            out,
        ])
        .output()
        .unwrap()
}

#[test]
fn a_task_file_without_an_expert_trains_one_first_then_reuses_it() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    std::fs::write(d.join("start.txt"), START_MACHINE).unwrap();
    std::fs::write(d.join("start.toml"), START_TASK).unwrap();
    write_expert_configs(d, "start.toml");
    std::fs::write(d.join("bad_expert.toml"), "total_steps = 0\n").unwrap();

    // A bad expert config is refused before any work: no cache, no run directory.
    let bad = run_with_expert(d, "bad_expert.toml", "r0");
    assert_eq!(bad.status.code(), Some(2));
    let stderr = String::from_utf8_lossy(&bad.stderr);
    assert!(
        stderr.contains("bad_expert.toml: line 1: field `total_steps`"),
        "{stderr}"
    );
    assert!(!d.join("experts").exists() && !d.join("r0").exists());

    // No expert cached: it is trained with the given config, cached by content, and used.
    let first = run_with_expert(d, "expert.toml", "r1");
    let stderr = String::from_utf8_lossy(&first.stderr);
    assert!(first.status.success(), "{stderr}");
    assert!(stderr.contains("no expert for task"), "{stderr}");
    assert!(stderr.contains("training one first"), "{stderr}");
    let task = ReacherTask::resolve(d.join("start.toml").to_str().unwrap()).unwrap();
    let cached = expert_cache_path(&d.join("experts"), task);
    let policy = std::fs::read(&cached).unwrap();
    let run_config = std::fs::read_to_string(d.join("r1/config.toml")).unwrap();
    assert!(
        run_config.contains("demo_source = \"expert\""),
        "{run_config}"
    );
    assert!(d.join("r1/metrics.csv").is_file());

    // Cached now: the second run trains nothing, says the expert config is unused, and leaves
    // the cached policy as it was.
    let second = run_with_expert(d, "expert.toml", "r2");
    let stderr = String::from_utf8_lossy(&second.stderr);
    assert!(second.status.success(), "{stderr}");
    assert!(!stderr.contains("training one first"), "{stderr}");
    assert!(stderr.contains("already cached"), "{stderr}");
    assert_eq!(std::fs::read(&cached).unwrap(), policy);
    assert_eq!(
        std::fs::read(d.join("r1/metrics.csv")).unwrap(),
        std::fs::read(d.join("r2/metrics.csv")).unwrap()
    );
}

/// `reacher demo --task <path> --episodes N` with `extra` arguments into `dir/name`; the log
/// must replay bit for bit, each episode from the start its seed gives (the schedule the log
/// records is the one that ran).
fn demo_log(dir: &Path, path: &Path, name: &str, episodes: u32, extra: &[&str]) -> RolloutLog {
    let out = dir.join(name);
    let o = Command::new(env!("CARGO_BIN_EXE_reacher"))
        .args(["demo", "--task", path.to_str().unwrap(), "--episodes"])
        .arg(episodes.to_string())
        .args(extra)
        .arg("--out")
        .arg(&out)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let o = Command::new(env!("CARGO_BIN_EXE_reacher"))
        .args(["replay", "--verify"])
        .arg(&out)
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&o.stdout) + String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{text}");
    assert!(!text.contains("no longer gives the logged start"), "{text}");
    smirl::log::read_log(&out).unwrap()
}

/// How many of `log`'s episodes schedule each of `n` events.
fn scheduled(log: &RolloutLog, n: usize) -> Vec<usize> {
    (0..n)
        .map(|e| {
            (log.episodes.iter())
                .filter(|ep| ep.start.event_steps(n)[e].is_some())
                .count()
        })
        .collect()
}

/// 0.5, the environment's default chance, is applied as asked (not taken for "not set") on a
/// task whose own chance is 0.3, and the log records it.
#[test]
fn demo_applies_the_asked_event_probability_even_when_it_is_the_default() {
    let tmp = tempfile::tempdir().unwrap();
    let path = write_task(tmp.path());
    let own = demo_log(tmp.path(), &path, "own.mcap", 200, &[]);
    let asked = demo_log(
        tmp.path(),
        &path,
        "half.mcap",
        200,
        &["--event-probability", "0.5"],
    );
    let chance = |log: &RolloutLog| log.run.task_layout().unwrap().events[0].probability;
    assert_eq!((chance(&own), chance(&asked)), (0.3, 0.5));
    let (own, asked) = (scheduled(&own, 1)[0], scheduled(&asked, 1)[0]);
    assert!((40..=80).contains(&own), "{own} of 200 at 0.3");
    assert!((80..=120).contains(&asked), "{asked} of 200 at 0.5");
}

/// Every declared event takes the asked chance (two events here, in their own windows); a
/// task without events refuses one; the default sequence is the task's regions in file order.
#[test]
fn demo_sets_every_events_chance_and_visits_the_regions_in_file_order() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    std::fs::write(d.join("avoid_blue.txt"), MACHINE.replace("rgbyc", "rgbycd")).unwrap();
    let two = task_text()
        + "\n[[event]]\nletter = \"d\"\nprobability = 0.2\nearliest_step = 30\nlatest_step = 40\n";
    std::fs::write(d.join("two.toml"), two).unwrap();
    let log = demo_log(
        d,
        &d.join("two.toml"),
        "two.mcap",
        20,
        &["--event-probability", "1"],
    );
    let layout = log.run.task_layout().unwrap();
    assert_eq!(
        layout
            .events
            .iter()
            .map(|e| e.probability)
            .collect::<Vec<_>>(),
        [1.0, 1.0]
    );
    assert_eq!(scheduled(&log, 2), [20, 20]);
    assert_eq!(log.run.config["demo"]["sequence"], "rgby");

    let ring = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/scenes/six_targets_ring.toml");
    let log = demo_log(d, &ring, "ring.mcap", 2, &[]);
    assert_eq!(log.run.config["demo"]["sequence"], "abcdef");
    let o = Command::new(env!("CARGO_BIN_EXE_reacher"))
        .args([
            "demo",
            "--task",
            ring.to_str().unwrap(),
            "--event-probability",
            "0.3",
        ])
        .arg("--out")
        .arg(d.join("none.mcap"))
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("declares no event"));
    assert!(!d.join("none.mcap").exists());
}

/// The chain a user runs on a task of several regions, none at the arm's start: a task file
/// copied with its machine and its cached expert (found by content, beside the file) gives
/// expert demonstrations that complete the task, a learned machine, SMIRL's quick run and its
/// evaluation; both logs replay bit for bit. (`pair`: red and green in either order, then
/// blue; a smoke-sized expert trained in a test could not complete it.)
#[test]
fn a_copied_task_runs_its_cached_expert_through_demonstrations_smirl_and_evaluation() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    let shipped = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/tasks/new");
    for name in ["pair.toml", "pair.txt"] {
        std::fs::copy(shipped.join(name), d.join(name)).unwrap();
    }
    let task = ReacherTask::resolve(d.join("pair.toml").to_str().unwrap()).unwrap();
    assert_eq!(task.layout().n_regions(), 4);
    let expert = expert_cache_path(&shipped.join("experts"), task.clone());
    std::fs::create_dir(d.join("experts")).unwrap();
    std::fs::copy(&expert, expert_cache_path(&d.join("experts"), task)).unwrap();
    let reacher = |args: &[&str]| {
        Command::new(env!("CARGO_BIN_EXE_reacher"))
            .current_dir(d)
            .args(args)
            .output()
            .unwrap()
    };
    // Were the cached expert missed, a smoke-sized one would be trained (and the test fail).
    write_expert_configs(d, "pair.toml");
    let o = reacher(&[
        "--task",
        "pair.toml",
        "--config",
        "run.toml",
        "--expert-config",
        "expert.toml",
        "--algo",
        "smirl",
        "--quiet",
        "--out",
        "r",
    ]);
    let text = String::from_utf8_lossy(&o.stdout) + String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{text}");
    assert!(!text.contains("training one first"), "{text}");
    assert!(
        text.contains("8 of 8 complete the task (expert source)"),
        "{text}"
    );
    let prepared: serde_json::Value =
        serde_json::from_slice(&std::fs::read(d.join("r/prepare.json")).unwrap()).unwrap();
    assert!(prepared["rm"]["learned_states"].as_u64().unwrap() >= 2);
    let metrics = std::fs::read_to_string(d.join("r/metrics.csv")).unwrap();
    assert_eq!(
        metrics
            .lines()
            .filter(|l| l.starts_with("smirl,0,"))
            .count(),
        5
    );
    assert!(d.join("r/final_policy.csv").is_file());
    for log in ["r/logs/demos.mcap", "r/logs/smirl_seed0.mcap"] {
        let o = reacher(&["replay", "--verify", log]);
        assert!(
            o.status.success(),
            "{log}: {}",
            String::from_utf8_lossy(&o.stderr)
        );
    }
}
