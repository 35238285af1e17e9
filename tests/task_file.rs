//! Task files (`env::task_file`): the shipped tasks describe today's ReacherDelivery exactly,
//! a user's file resolves its scene and machine relative to itself, and every bad input is
//! refused with the file, line and key before any work.

use smirl::assets::REACHER_XML;
use smirl::env::reacher::CancelConfig;
use smirl::env::reacher::ReacherConfig;
use smirl::env::reacher_task::ReacherTask;
use smirl::env::task_file::{Anchor, Task, TaskFileError, TaskProblem, SHIPPED};

/// The ball positions of the paper's tasks (red, green, blue, yellow), as measured from the
/// paper's scene.
const PAPER_LAYOUT: [[f64; 2]; 4] = [
    [0.0975, 0.1689],
    [-0.0182, -0.1034],
    [-0.0591, 0.0104],
    [0.141, -0.0513],
];
use smirl::rm::LabelSet;
use std::path::Path;

const MACHINE: &str = "vocabulary: abe\nstates: 3\ninitial: 0\nterminal: 1\nfailure: 2\n\
                       (0, 1, 'a&!b', 1)\n(0, 2, 'b', 0)\n";

/// A valid task over the built-in scene: two balls as regions `a`, `b`, one event `e`.
fn task_text() -> String {
    "scene = \"builtin\"\nmachine = \"m.txt\"\nepisode_steps = 50\nrandomize_layout = false\n\
     \n[[region]]\nletter = \"a\"\nbody = \"red\"\nradius = 0.03\nposition = [0.1, 0.1]\n\
     \n[[region]]\nletter = \"b\"\nbody = \"green\"\nradius = 0.02\nposition = [-0.1, 0.05]\n\
     \n[[event]]\nletter = \"e\"\nprobability = 0.25\nearliest_step = 3\nlatest_step = 9\n"
        .to_string()
}

fn write(dir: &Path, task: &str, machine: &str) -> std::path::PathBuf {
    std::fs::write(dir.join("m.txt"), machine).unwrap();
    let path = dir.join("t.toml");
    std::fs::write(&path, task).unwrap();
    path
}

/// Loads `task` (with [`MACHINE`] beside it) and returns the error.
fn refused(task: &str) -> TaskFileError {
    refused_with(task, MACHINE)
}

fn refused_with(task: &str, machine: &str) -> TaskFileError {
    let dir = tempfile::tempdir().unwrap();
    let path = write(dir.path(), task, machine);
    match Task::load(&path) {
        Ok(_) => panic!("task accepted:\n{task}"),
        Err(e) => e,
    }
}

/// The error is about `key` on `line`, and its message names the file, line and key.
fn assert_at(e: &TaskFileError, line: usize, key: &str) {
    let message = e.to_string();
    match e {
        TaskFileError::Invalid {
            line: l, key: k, ..
        } => {
            assert_eq!((*l, k.as_str()), (Some(line), key), "{message}");
        }
        other => panic!("not a rule error: {other}"),
    }
    assert!(
        message.contains(&format!("t.toml:{line}: `{key}`")),
        "{message}"
    );
}

#[test]
fn shipped_tasks_describe_todays_environment() {
    for name in SHIPPED {
        let task = Task::resolve(name).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_eq!(task.name, name);
        assert_eq!(task.layout().letters(), "rgbyc");
        assert_eq!(task.layout().events(), LabelSet(1 << 4));
        assert_eq!(task.region_labels(), LabelSet(0b1111));
        // The paper's layout: four balls at their distances from the base, one event.
        let env = ReacherTask::shipped(name)
            .unwrap()
            .env_config(&ReacherConfig::default())
            .unwrap();
        assert_eq!(env.ball_layout, Some(PAPER_LAYOUT.to_vec()), "{name}");
        let shipped_schedule = CancelConfig {
            probability: 0.5,
            earliest_step: 1,
            latest_step: 8,
        };
        assert_eq!(
            (env.max_steps, env.randomize_balls, &env.cancel),
            (100, false, &Some(shipped_schedule)),
            "{name}"
        );
        assert_eq!(task.layout().obs_dim(), 17);
        let shipped = smirl::rm::perfect::reacher(name).unwrap();
        assert_eq!(
            smirl::rm::format::write_rm(&task.machine),
            smirl::rm::format::write_rm(&shipped)
        );
        assert_eq!(task.machine_source, format!("assets/rm/reacher_{name}.txt"));
    }
    let hashes: std::collections::HashSet<String> = SHIPPED
        .iter()
        .map(|n| Task::shipped(n).unwrap().content_hash)
        .collect();
    assert_eq!(
        hashes.len(),
        SHIPPED.len(),
        "each task has its own content hash"
    );
}

#[test]
fn a_file_on_disk_loads_with_its_machine_beside_it() {
    let dir = tempfile::tempdir().unwrap();
    let path = write(dir.path(), &task_text(), MACHINE);
    let task = Task::resolve(path.to_str().unwrap()).unwrap();
    assert_eq!(task.name, "t");
    assert_eq!(task.layout().letters(), "abe");
    assert_eq!(task.regions[0].anchor, Anchor::Body("red".into()));
    assert_eq!(task.regions[0].radius, 0.03);
    assert_eq!(task.regions[1].position, [-0.1, 0.05]);
    assert_eq!(task.events[0].latest_step, 9);
    assert_eq!(task.layout().events(), LabelSet(0b100));
    assert_eq!(task.episode_steps, 50);
    // Two regions and one event: an observation of 8 + 2·2 + 1 values.
    assert_eq!(task.layout().obs_dim(), 13);
    assert_eq!(task.layout().event_column(0), 12);

    // The expert key follows the content: the same files give the same hash, a changed
    // machine another.
    let again = Task::load(&path).unwrap();
    assert_eq!(again.content_hash, task.content_hash);
    std::fs::write(dir.path().join("m.txt"), MACHINE.replace("1)", "2)")).unwrap();
    assert_ne!(Task::load(&path).unwrap().content_hash, task.content_hash);
}

#[test]
fn a_copy_of_a_shipped_task_reproduces_it() {
    let dir = tempfile::tempdir().unwrap();
    let text = smirl::assets::task_file("composite")
        .unwrap()
        .replace("../rm/reacher_composite.txt", "composite.txt");
    std::fs::write(
        dir.path().join("composite.txt"),
        smirl::rm::perfect::text("reacher_composite").unwrap(),
    )
    .unwrap();
    let path = dir.path().join("composite.toml");
    std::fs::write(&path, text).unwrap();
    let task = Task::load(&path).unwrap();
    assert_eq!(task.layout(), Task::shipped("composite").unwrap().layout());
    assert_eq!(task.name, "composite");
}

#[test]
fn regions_on_sites_of_a_users_scene() {
    let dir = tempfile::tempdir().unwrap();
    let xml = REACHER_XML.replace(
        "<!-- Arm -->",
        "<site name=\"goal\" pos=\"0.12 -0.05 0.01\" size=\"0.01\"/>\n<!-- Arm -->",
    );
    std::fs::write(dir.path().join("scene.xml"), xml).unwrap();
    let text = task_text().replace("\"builtin\"", "\"scene.xml\"").replace(
        "body = \"red\"\nradius = 0.03\nposition = [0.1, 0.1]",
        "site = \"goal\"\nradius = 0.03",
    );
    let path = write(dir.path(), &text, MACHINE);
    let task = Task::load(&path).unwrap();
    assert_eq!(task.regions[0].anchor, Anchor::Site("goal".into()));
    assert!((task.regions[0].position[0] - 0.12).abs() < 1e-12);
    assert!((task.regions[0].position[1] + 0.05).abs() < 1e-12);
    assert!(!task.regions[0].movable);
}

#[test]
fn unknown_body_or_site() {
    let e = refused(&task_text().replace("\"green\"", "\"purple\""));
    assert_at(&e, 14, "region[1].body");
    assert!(e.to_string().contains("no body 'purple'"), "{e}");
    let e = refused(&task_text().replace("body = \"green\"", "site = \"nowhere\""));
    assert_at(&e, 14, "region[1].site");
    assert!(matches!(
        e.problem(),
        Some(TaskProblem::UnknownAnchor { .. })
    ));
}

#[test]
fn a_letter_used_twice() {
    let e = refused(&task_text().replace("letter = \"e\"", "letter = \"a\""));
    assert_at(&e, 19, "event[0].letter");
    assert!(
        e.to_string()
            .contains("'a' is defined twice (first on line 7)"),
        "{e}"
    );
}

#[test]
fn a_machine_proposition_nobody_defines() {
    let machine = MACHINE.replace("abe", "abez");
    let e = refused_with(&task_text(), &machine);
    assert_at(&e, 2, "machine");
    assert!(e.to_string().contains("proposition 'z'"), "{e}");
    // Defined, but listed in another order than the task's bits.
    let e = refused_with(&task_text(), &MACHINE.replace("abe", "bae"));
    assert!(
        matches!(e.problem(), Some(TaskProblem::VocabularyOrder { .. })),
        "{e}"
    );
    // A machine file that does not parse: the RM file's own line.
    let e = refused_with(&task_text(), "vocabulary: abe\nstates: x\n");
    assert!(e.to_string().contains("m.txt:2"), "{e}");
    // A machine file that is not there.
    let e = refused(&task_text().replace("m.txt", "absent.txt"));
    assert_at(&e, 2, "machine");
}

#[test]
fn radius_not_positive_or_beyond_the_arena() {
    for r in ["0.0", "-0.01", "0.5", "nan"] {
        let e = refused(&task_text().replace("radius = 0.02", &format!("radius = {r}")));
        assert_at(&e, 15, "region[1].radius");
    }
    // A region that pokes out of the arena.
    let e = refused(
        &task_text()
            .replace("[-0.1, 0.05]", "[0.26, 0.05]")
            .replace("radius = 0.02", "radius = 0.05"),
    );
    assert_at(&e, 16, "region[1].position");
    // A randomised layout's regions must fit wherever they are drawn.
    let e = refused(
        &task_text()
            .replace("randomize_layout = false", "randomize_layout = true")
            .replace("radius = 0.02", "radius = 0.2"),
    );
    assert_at(&e, 16, "region[1].position");
}

#[test]
fn event_window_outside_the_episode() {
    let e = refused(&task_text().replace("latest_step = 9", "latest_step = 51"));
    assert_at(&e, 22, "event[0].latest_step");
    assert!(e.to_string().contains("1..=50"), "{e}");
    let e = refused(&task_text().replace("earliest_step = 3", "earliest_step = 0"));
    assert_at(&e, 21, "event[0].earliest_step");
    let e = refused(&task_text().replace("earliest_step = 3", "earliest_step = 10"));
    assert_at(&e, 21, "event[0].earliest_step");
    let e = refused(&task_text().replace("probability = 0.25", "probability = 1.5"));
    assert_at(&e, 20, "event[0].probability");
}

#[test]
fn unreadable_non_mujoco_or_fingerless_scenes() {
    let e = refused(&task_text().replace("\"builtin\"", "\"absent.xml\""));
    assert_at(&e, 1, "scene");
    assert!(matches!(e.problem(), Some(TaskProblem::Scene(_))));

    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("not.xml"), "this is not MJCF").unwrap();
    let path = write(
        dir.path(),
        &task_text().replace("\"builtin\"", "\"not.xml\""),
        MACHINE,
    );
    let e = Task::load(&path).unwrap_err();
    assert_at(&e, 1, "scene");
    assert!(e.to_string().contains("cannot load the scene"), "{e}");

    let xml = REACHER_XML.replace(
        "name=\"fingertip\" pos=\"0.11 0 0\"",
        "name=\"tip\" pos=\"0.11 0 0\"",
    );
    assert_ne!(xml, REACHER_XML);
    std::fs::write(dir.path().join("tipless.xml"), xml).unwrap();
    let path = write(
        dir.path(),
        &task_text().replace("\"builtin\"", "\"tipless.xml\""),
        MACHINE,
    );
    let e = Task::load(&path).unwrap_err();
    assert_at(&e, 1, "scene");
    assert!(
        matches!(e.problem(), Some(TaskProblem::NoFingertip { .. })),
        "{e}"
    );
}

#[test]
fn sizes_are_bounded() {
    let mut text = task_text();
    for k in 0..9 {
        text.push_str(&format!(
            "\n[[region]]\nletter = \"{k}\"\nbody = \"blue\"\nradius = 0.02\n"
        ));
    }
    let e = refused(&text);
    assert!(
        e.to_string()
            .contains("11 regions, more than the limit of 8"),
        "{e}"
    );
    let e = refused(&task_text().replace("episode_steps = 50", "episode_steps = 10001"));
    assert_at(&e, 3, "episode_steps");
    let e = refused(&task_text().replace("episode_steps = 50", "episode_steps = 0"));
    assert_at(&e, 3, "episode_steps");
}

#[test]
fn syntax_errors_and_unknown_keys_name_their_line() {
    let e = refused(&task_text().replace("radius = 0.03", "radius = 0.03\ncolour = \"red\""));
    assert!(matches!(e, TaskFileError::Toml { .. }), "{e}");
    assert!(
        e.to_string().contains("line 10") && e.to_string().contains("colour"),
        "{e}"
    );
    let e = refused(&task_text().replace("letter = \"a\"", "letter = \"ab\""));
    assert_at(&e, 7, "region[0].letter");
    let e = refused(&task_text().replace("body = \"red\"\n", ""));
    assert!(matches!(e.problem(), Some(TaskProblem::AnchorCount)), "{e}");
}

/// The README's own layout: regions as an array of inline tables, one per line. A rule error
/// names the line of the key inside its element, and a repeated letter the line of the first.
#[test]
fn keys_inside_an_array_of_inline_tables_name_their_line() {
    let inline = "scene = \"builtin\"\nmachine = \"m.txt\"\nepisode_steps = 50\n\
                  randomize_layout = false\n\
                  region = [{ letter = \"a\", body = \"red\", radius = 0.03, position = [0.1, 0.1] },\n\
                  \x20         { letter = \"b\", body = \"green\", radius = 0.02, position = [-0.1, 0.05] }]\n\
                  event = [{ letter = \"e\", probability = 0.25, earliest_step = 3, latest_step = 9 }]\n";
    let dir = tempfile::tempdir().unwrap();
    Task::load(&write(dir.path(), inline, MACHINE)).unwrap();
    let e = refused(&inline.replace("\"green\"", "\"purple\""));
    assert_at(&e, 6, "region[1].body");
    let e = refused(&inline.replace("position = [-0.1, 0.05]", "position = [-0.9, 0.05]"));
    assert_at(&e, 6, "region[1].position");
    let e = refused(&inline.replace("latest_step = 9", "latest_step = 99"));
    assert_at(&e, 7, "event[0].latest_step");
    let e = refused(&inline.replace("letter = \"b\"", "letter = \"a\""));
    assert_at(&e, 6, "region[1].letter");
    assert!(e.to_string().contains("(first on line 5)"), "{e}");
}

#[test]
fn names_and_paths_resolve() {
    assert!(matches!(
        Task::resolve("compost"),
        Err(TaskFileError::UnknownName(_))
    ));
    let e = Task::resolve("/nonexistent/task.toml").unwrap_err();
    assert!(matches!(e, TaskFileError::Io { .. }), "{e}");
    assert!(
        e.to_string()
            .starts_with("/nonexistent/task.toml: cannot read"),
        "{e}"
    );
}

#[test]
fn layouts_move_mocap_bodies_and_bodies_on_slides_only() {
    let dir = tempfile::tempdir().unwrap();
    // The built-in scene's balls are mocap bodies.
    let task = Task::load(&write(dir.path(), &task_text(), MACHINE)).unwrap();
    assert!(task.regions.iter().all(|r| r.movable));
    // The first built-in scene's balls move by their slide joints.
    std::fs::write(dir.path().join("v1.xml"), smirl::assets::REACHER_V1_XML).unwrap();
    let text = task_text().replace("\"builtin\"", "\"v1.xml\"");
    let task = Task::load(&write(dir.path(), &text, MACHINE)).unwrap();
    assert!(task.regions.iter().all(|r| r.movable));
    assert_eq!(task.regions[0].position, [0.1, 0.1]);
    // A body that is neither cannot be put at a position.
    let xml = REACHER_XML.replace(r#"<body mocap="true" name="red""#, r#"<body name="red""#);
    assert_ne!(xml, REACHER_XML);
    std::fs::write(dir.path().join("fixed.xml"), xml).unwrap();
    let text = task_text().replace("\"builtin\"", "\"fixed.xml\"");
    let e = Task::load(&write(dir.path(), &text, MACHINE)).unwrap_err();
    assert_at(&e, 10, "region[0].position");
    assert!(e.to_string().contains("neither a mocap body"), "{e}");
}
