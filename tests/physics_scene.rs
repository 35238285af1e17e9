//! The physics model of a scene: the scene's text without its movable mocap region bodies.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use smirl::assets::REACHER_XML;
use smirl::env::physics_scene::{without_mocap_bodies, SceneCutError};
use smirl::mujoco::{Data, Model};
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
        Err(SceneCutError::Mismatched { at: 19, .. })
    ));
    assert!(matches!(
        without_mocap_bodies("<mujoco><!-- open", &[]),
        Err(SceneCutError::Unclosed {
            at: 8,
            what: "comment"
        })
    ));
    assert!(matches!(
        without_mocap_bodies("<mujoco><worldbody>", &[]),
        Err(SceneCutError::Unclosed { at: 8, .. })
    ));
    assert!(matches!(
        without_mocap_bodies("</mujoco>", &[]),
        Err(SceneCutError::Unopened { at: 0, .. })
    ));
    assert!(matches!(
        without_mocap_bodies("<mujoco a=\">", &[]),
        Err(SceneCutError::Unclosed { at: 0, what: "tag" })
    ));
}
