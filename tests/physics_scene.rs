//! The physics model of a scene: the scene's text without its movable mocap region bodies.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use smirl::assets::REACHER_XML;
use smirl::env::layout::Scene;
use smirl::env::physics_scene::{
    scene_model, without_mocap_bodies, without_world_geoms, SceneCutError,
};
use smirl::env::reacher::{ReacherConfig, ReacherDelivery};
use smirl::env::reacher_task::ReacherTask;
use smirl::env::scene_xml::XmlSyntaxError;
use smirl::env::ContinuousEnv;
use smirl::mujoco::{Data, Model, ObjectKind};
use std::path::Path;
use std::sync::Arc;

const BALLS: [&str; 4] = ["red", "green", "blue", "yellow"];

/// Joint angles and velocities after each of `steps` environment steps (two `mj_step` each)
/// under torques drawn from `seed`, and how many steps end beyond 2.95 rad on joint1 (its
/// limit is 3).
fn rollout(xml: &str, steps: usize, seed: u64) -> (Vec<[f64; 4]>, usize) {
    let model = Arc::new(Model::from_xml_str(xml, "test.xml").unwrap());
    let mut data = Data::new(model).unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut states = Vec::with_capacity(steps);
    let mut near_limit = 0;
    for _ in 0..steps {
        let ctrl = [rng.gen_range(-1.0..=1.0), rng.gen_range(-1.0..=1.0)];
        data.set_ctrl(&ctrl).unwrap();
        data.step().unwrap();
        data.step().unwrap();
        let (q, v) = (data.qpos(), data.qvel());
        states.push([q[0], q[1], v[0], v[1]]);
        near_limit += usize::from(q[1].abs() > 2.95);
    }
    (states, near_limit)
}

#[test]
fn the_arm_moves_bit_for_bit_as_in_the_scene_without_the_balls() {
    let physics = without_mocap_bodies(REACHER_XML, &BALLS).unwrap();
    let model = Model::from_xml_str(&physics, "physics.xml").unwrap();
    assert_eq!(model.nbody(), 4, "world, two links and the fingertip");
    let (scene, near_limit) = rollout(REACHER_XML, 20_000, 7);
    let (cut, _) = rollout(&physics, 20_000, 7);
    assert!(
        near_limit > 100,
        "the rollout presses joint1 against its limit ({near_limit} steps)"
    );
    assert!(
        scene == cut,
        "the arm's trajectory differs without the balls"
    );
    let arm_only = without_world_geoms(&physics).unwrap();
    let model = Model::from_xml_str(&arm_only, "arm_only.xml").unwrap();
    assert_eq!(model.ngeom(), 3, "the two links and the fingertip");
    assert!(
        rollout(&arm_only, 20_000, 7).0 == scene,
        "the arm's trajectory differs without the floor and the walls"
    );
}

#[test]
fn only_the_world_bodys_own_geoms_are_cut() {
    let xml = "<mujoco><default><geom size=\"1\"/></default><!-- <geom/> --><worldbody>\n\
               <geom name=\"floor\" type=\"plane\"/>\n\
               <geom name=\"wall\" size=\".02\"></geom>\n\
               <site name=\"s\"/>\n\
               <body name=\"arm\"><geom name=\"link\"/><joint/></body>\n\
               <body name=\"red\" mocap=\"true\"><geom name=\"ball\"/></body>\n\
               </worldbody></mujoco>";
    assert_eq!(
        without_world_geoms(xml).unwrap(),
        "<mujoco><default><geom size=\"1\"/></default><!-- <geom/> --><worldbody>\n\
         \n\
         \n\
         <site name=\"s\"/>\n\
         <body name=\"arm\"><geom name=\"link\"/><joint/></body>\n\
         <body name=\"red\" mocap=\"true\"><geom name=\"ball\"/></body>\n\
         </worldbody></mujoco>"
    );
    assert!(matches!(
        without_world_geoms("<mujoco><worldbody><geom></worldbody></mujoco>"),
        Err(SceneCutError::Syntax(XmlSyntaxError::Mismatched {
            at: 25,
            ..
        }))
    ));
}

#[test]
fn everything_but_the_cut_bodies_stays_byte_for_byte() {
    assert_eq!(without_mocap_bodies(REACHER_XML, &[]).unwrap(), REACHER_XML);
    let xml = "<mujoco><!-- <body name=\"red\"> --><worldbody>\n\
               <geom name=\"g\" size=\"1\"/>\n\
               <body name='red' mocap=\"true\" pos=\"0 0 0\"><geom user=\"a>b\" size=\".02\"/></body>\n\
               <body mocap=\"true\" name=\"blue\"/>\n\
               </worldbody></mujoco>";
    assert_eq!(
        without_mocap_bodies(xml, &["red", "blue"]).unwrap(),
        "<mujoco><!-- <body name=\"red\"> --><worldbody>\n\
         <geom name=\"g\" size=\"1\"/>\n\
         \n\
         \n\
         </worldbody></mujoco>"
    );
}

#[test]
fn bodies_that_are_part_of_the_physics_are_refused() {
    let scene = |inner: &str| format!("<mujoco><worldbody>{inner}</worldbody></mujoco>");
    assert_eq!(
        without_mocap_bodies(
            &scene("<body name=\"red\"><geom size=\"1\"/></body>"),
            &["red"]
        ),
        Err(SceneCutError::NotAWorldMocapBody("red".into()))
    );
    assert_eq!(
        without_mocap_bodies(
            &scene("<body name=\"arm\"><body name=\"red\" mocap=\"true\"/></body>"),
            &["red"]
        ),
        Err(SceneCutError::NotAWorldMocapBody("red".into()))
    );
    assert_eq!(
        without_mocap_bodies(
            &scene("<body name=\"red\" mocap=\"true\"><body name=\"x\"><joint/></body></body>"),
            &["red"]
        ),
        Err(SceneCutError::HoldsPhysics("red".into()))
    );
    assert_eq!(
        without_mocap_bodies(&scene("<body name=\"blue\" mocap=\"true\"/>"), &["red"]),
        Err(SceneCutError::Missing("red".into()))
    );
}

#[test]
fn malformed_text_is_refused_with_its_byte_offset() {
    assert!(matches!(
        without_mocap_bodies("<mujoco><worldbody></mujoco>", &[]),
        Err(SceneCutError::Syntax(XmlSyntaxError::Mismatched {
            at: 19,
            ..
        }))
    ));
    assert!(matches!(
        without_mocap_bodies("<mujoco><!-- open", &[]),
        Err(SceneCutError::Syntax(XmlSyntaxError::Unclosed {
            at: 8,
            what: "comment"
        }))
    ));
    assert!(matches!(
        without_mocap_bodies("<mujoco><worldbody>", &[]),
        Err(SceneCutError::Syntax(XmlSyntaxError::Unclosed {
            at: 8,
            ..
        }))
    ));
    assert!(matches!(
        without_mocap_bodies("</mujoco>", &[]),
        Err(SceneCutError::Syntax(XmlSyntaxError::Unopened {
            at: 0,
            ..
        }))
    ));
    assert!(matches!(
        without_mocap_bodies("<mujoco a=\">", &[]),
        Err(SceneCutError::Syntax(XmlSyntaxError::Unclosed {
            at: 0,
            what: "tag"
        }))
    ));
}

/// Everything an agent and a log see of `episodes` episodes under seeded random actions:
/// observations, rewards, labels, ends and the arm's state, as bits.
fn episodes(env: &mut ReacherDelivery, episodes: u64) -> Vec<u64> {
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let mut obs = vec![0.0f32; env.obs_dim()];
    let mut seen = Vec::new();
    for seed in 0..episodes {
        env.reset(seed, &mut obs);
        seen.extend(obs.iter().map(|x| u64::from(x.to_bits())));
        loop {
            let action = [rng.gen_range(-1.0..=1.0), rng.gen_range(-1.0..=1.0)];
            let step = env.step(&action, &mut obs).unwrap();
            seen.extend(obs.iter().map(|x| u64::from(x.to_bits())));
            seen.extend(env.qpos().iter().chain(env.qvel()).map(|x| x.to_bits()));
            seen.extend([
                step.reward.to_bits(),
                u64::from(step.labels.0),
                u64::from(step.terminated),
            ]);
            if step.truncated {
                break;
            }
        }
    }
    seen
}

/// The environment on `task` as it steps it, and on the task's whole scene.
fn envs(task: &ReacherTask) -> (ReacherDelivery, ReacherDelivery) {
    let config = task.env_config(&ReacherConfig::default()).unwrap();
    let physics = ReacherDelivery::new(config.clone()).unwrap();
    let scene = scene_model(&task.layout()).unwrap();
    let whole = ReacherDelivery::with_model(Arc::new(scene), config).unwrap();
    (physics, whole)
}

#[test]
fn the_environment_steps_the_built_in_scene_without_its_balls_and_nothing_changes() {
    let task = ReacherTask::shipped("composite").unwrap();
    let (mut physics, mut whole) = envs(&task);
    assert_eq!((physics.model().nmocap(), whole.model().nmocap()), (0, 4));
    assert_eq!(physics.model().ngeom(), 3, "the arm's geoms alone");
    let mut twin = physics.twin().unwrap();
    assert_eq!(twin.model().nmocap(), 0);
    // Balls at random places every episode, cancel events, 50 episodes of 100 steps.
    let expected = episodes(&mut whole, 50);
    assert!(episodes(&mut physics, 50) == expected);
    assert!(episodes(&mut twin, 50) == expected);
}

/// A copy of the built-in scene in `dir` whose motors come from an included file in a
/// subdirectory, with `edit` applied to the scene's text; and a task on it.
fn scene_of_ones_own(dir: &Path, edit: impl Fn(&str) -> String) -> ReacherTask {
    let start = REACHER_XML.find("<actuator>").unwrap();
    let end = REACHER_XML.find("</actuator>").unwrap() + "</actuator>".len();
    let motors = format!("<mujoco>{}</mujoco>", &REACHER_XML[start..end]);
    let scene = format!(
        "{}<include file=\"parts/motors.xml\"/>{}",
        &REACHER_XML[..start],
        &REACHER_XML[end..]
    );
    std::fs::create_dir_all(dir.join("parts")).unwrap();
    std::fs::write(dir.join("parts/motors.xml"), motors).unwrap();
    std::fs::write(dir.join("scene.xml"), edit(&scene)).unwrap();
    let machine = "vocabulary: ab\nstates: 3\ninitial: 0\nterminal: 2\n\
                   (0, 1, 'a', 0)\n(1, 2, 'b', 1)\n";
    std::fs::write(dir.join("m.txt"), machine).unwrap();
    let task = "scene = \"scene.xml\"\nmachine = \"m.txt\"\nepisode_steps = 50\n\
                randomize_layout = true\n\
                [[region]]\nletter = \"a\"\nbody = \"red\"\nradius = 0.02\n\
                [[region]]\nletter = \"b\"\nbody = \"blue\"\nradius = 0.02\n";
    std::fs::write(dir.join("task.toml"), task).unwrap();
    ReacherTask::resolve(dir.join("task.toml").to_str().unwrap()).unwrap()
}

/// Every file under `dir` with its bytes.
fn files(dir: &Path) -> Vec<(std::path::PathBuf, Vec<u8>)> {
    let mut out = Vec::new();
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        if path.is_dir() {
            out.extend(files(&path));
        } else {
            out.push((path.clone(), std::fs::read(&path).unwrap()));
        }
    }
    out.sort();
    out
}

#[test]
fn a_scene_file_of_ones_own_is_cut_with_its_includes_resolved_beside_it() {
    let tmp = tempfile::tempdir().unwrap();
    let task = scene_of_ones_own(tmp.path(), str::to_string);
    let before = files(tmp.path());
    let (mut physics, mut whole) = envs(&task);
    // The task's two balls are cut; green and yellow are no region of it and stay.
    assert_eq!((physics.model().nmocap(), whole.model().nmocap()), (2, 4));
    assert_eq!(physics.model().nu(), 2, "the included motors are there");
    assert!(episodes(&mut physics, 20) == episodes(&mut whole, 20));
    assert_eq!(
        files(tmp.path()),
        before,
        "nothing is written beside the scene"
    );
}

#[test]
fn a_ball_that_can_touch_or_is_referenced_stays_in_the_physics() {
    for (what, edit) in [
        (
            "a ball that can collide",
            r#"contype="0" name="red""#,
            r#"contype="1" name="red""#,
        ),
        (
            "a ball a sensor reads",
            r#"name="red" pos="0 0 0" rgba="0.9 0. 0. 0.3" size=".02" type="sphere"/>"#,
            r#"name="red" pos="0 0 0" rgba="0.9 0. 0. 0.3" size=".02" type="sphere"/><site name="s"/>"#,
        ),
    ]
    .map(|(what, from, to)| (what, (from, to)))
    {
        let tmp = tempfile::tempdir().unwrap();
        let task = scene_of_ones_own(tmp.path(), |xml| {
            assert!(xml.contains(edit.0));
            let xml = xml.replace(edit.0, edit.1);
            if what.contains("sensor") {
                xml.replace("</mujoco>", "<sensor><framepos objtype=\"site\" objname=\"s\"/></sensor></mujoco>")
            } else {
                xml
            }
        });
        let (mut physics, mut whole) = envs(&task);
        // A ball that can collide stays and the task's other ball (blue) goes; a text whose
        // cut does not compile is not cut at all.
        let model = physics.model();
        assert!(model.id(ObjectKind::Body, "red").is_ok(), "{what}");
        let blue_cut = what.contains("collide");
        assert_eq!(model.id(ObjectKind::Body, "blue").is_err(), blue_cut, "{what}");
        assert_eq!(model.nmocap(), if blue_cut { 3 } else { 4 }, "{what}");
        assert!(episodes(&mut physics, 5) == episodes(&mut whole, 5), "{what}");
    }
}

#[test]
fn the_worlds_geoms_stay_when_one_can_touch_or_is_named() {
    for (what, edit, extra) in [
        (
            "a wall that can collide",
            (
                r#"conaffinity="0" fromto="-.3 -.3"#,
                r#"conaffinity="1" contype="1" fromto="-.3 -.3"#,
            ),
            "",
        ),
        (
            "a floor a contact pair names",
            ("", ""),
            "<contact><pair geom1=\"ground\" geom2=\"link0\"/></contact>",
        ),
    ] {
        let tmp = tempfile::tempdir().unwrap();
        let task = scene_of_ones_own(tmp.path(), |xml| {
            assert!(xml.contains(edit.0));
            xml.replacen(edit.0, edit.1, 1)
                .replace("</mujoco>", &format!("{extra}</mujoco>"))
        });
        let (mut physics, mut whole) = envs(&task);
        // Every geom of the world stays (nine in the scene), the task's two balls still go.
        let model = physics.model();
        assert!(model.id(ObjectKind::Geom, "ground").is_ok(), "{what}");
        assert_eq!(
            (model.ngeom(), model.nmocap(), whole.model().ngeom()),
            (11, 2, 13),
            "{what}"
        );
        assert!(
            episodes(&mut physics, 5) == episodes(&mut whole, 5),
            "{what}"
        );
    }
}

/// The environment steps the scene as its task loaded it: after the task loads, an edit of
/// the scene file (a shorter time step) and of the file it includes (weaker motors), then the
/// removal of both, change nothing the environment does, and its model has the loaded time
/// step and gear. The expert's key and the logs record the loaded bytes, so a run trains on
/// the model they describe; compiling from disk again, the edits would drive the arm
/// otherwise, and the removal would stop it.
#[test]
fn the_environment_steps_the_scene_its_task_loaded() {
    let tmp = tempfile::tempdir().unwrap();
    let task = scene_of_ones_own(tmp.path(), str::to_string);
    let config = task.env_config(&ReacherConfig::default()).unwrap();
    let mut before = ReacherDelivery::new(config.clone()).unwrap();
    let expected = episodes(&mut before, 5);
    let key = task.task().content_hash.clone();

    let edit = |file: &str, from: &str, to: &str| {
        let path = tmp.path().join(file);
        let text = std::fs::read_to_string(&path).unwrap();
        assert!(text.contains(from), "{file}");
        std::fs::write(&path, text.replace(from, to)).unwrap();
    };
    edit("scene.xml", "timestep=\"0.01\"", "timestep=\"0.005\"");
    edit("parts/motors.xml", "gear=\"200.0\"", "gear=\"50.0\"");
    let edited = ReacherTask::resolve(tmp.path().join("task.toml").to_str().unwrap()).unwrap();
    assert_ne!(
        edited.task().content_hash,
        key,
        "a new load reads the edits"
    );
    let mut reloaded = edited.make_env(&ReacherConfig::default()).unwrap();
    assert_eq!(reloaded.model().timestep(), 0.005);
    assert!(
        episodes(&mut reloaded, 5) != expected,
        "the edits change what the arm does"
    );
    let mut after = task.make_env(&ReacherConfig::default()).unwrap();
    assert_eq!(after.model().timestep(), 0.01);
    assert_eq!(after.model().actuator_gear(0), 200.0);
    assert!(episodes(&mut after, 5) == expected);
    let scene = scene_model(&task.layout()).unwrap();
    let mut whole = ReacherDelivery::with_model(Arc::new(scene), config.clone()).unwrap();
    assert_eq!(whole.model().actuator_gear(1), 200.0);
    assert!(episodes(&mut whole, 5) == expected);

    std::fs::remove_file(tmp.path().join("scene.xml")).unwrap();
    std::fs::remove_dir_all(tmp.path().join("parts")).unwrap();
    let mut gone = ReacherDelivery::new(config).unwrap();
    assert!(episodes(&mut gone, 5) == expected);
    assert_eq!(task.task().content_hash, key);
}

/// The shipped file scenes (`assets/scenes/`), whose committed experts were trained on the
/// scene compiled from disk, step bit for bit as that scene: compiling the environment's model
/// from the bytes the task loaded changes no result.
#[test]
fn the_shipped_file_scenes_step_as_compiled_from_disk() {
    let scenes = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/scenes");
    let disk = Arc::new(Model::from_xml_path(&scenes.join("six_targets.xml")).unwrap());
    for name in ["six_targets_ring", "six_targets_detour"] {
        let file = scenes.join(format!("{name}.toml"));
        let task = ReacherTask::resolve(file.to_str().unwrap()).unwrap();
        assert!(matches!(task.layout().scene, Scene::File(_)), "{name}");
        let config = task.env_config(&ReacherConfig::default()).unwrap();
        let mut physics = ReacherDelivery::new(config.clone()).unwrap();
        let mut whole = ReacherDelivery::with_model(Arc::clone(&disk), config).unwrap();
        assert!(
            episodes(&mut physics, 20) == episodes(&mut whole, 20),
            "{name}"
        );
    }
}
