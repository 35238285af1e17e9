//! ReacherDelivery and the MuJoCo wrapper against known values.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use smirl::env::layout::TaskLayout;
use smirl::env::reacher::*;
use smirl::env::reacher_task::ReacherTask;
use smirl::env::{ContinuousEnv, EnvError};
use smirl::mujoco::{Data, MjError, Model, ObjectKind};
use std::sync::Arc;

const L1: f64 = 0.1;
const L2: f64 = 0.11;

/// Joint angles that put the fingertip at (x, y) (elbow-down solution of the 2-link arm).
fn inverse_kinematics(x: f64, y: f64) -> [f64; 2] {
    let c = (x * x + y * y - L1 * L1 - L2 * L2) / (2.0 * L1 * L2);
    let q1 = c.clamp(-1.0, 1.0).acos();
    let q0 = y.atan2(x) - (L2 * q1.sin()).atan2(L1 + L2 * q1.cos());
    [q0, q1]
}

/// The paper's tasks' layout: four balls, one event.
fn composite() -> ReacherTask {
    ReacherTask::shipped("composite").unwrap()
}

fn layout() -> std::sync::Arc<TaskLayout> {
    composite().layout()
}

fn obs_dim() -> usize {
    layout().obs_dim()
}

fn env(config: ReacherConfig) -> ReacherDelivery {
    composite().make_env(&config).unwrap()
}

fn rollout(seed: u64, steps: usize) -> Vec<(Vec<f32>, u32, f64, Vec<f64>)> {
    let mut e = env(ReacherConfig::default());
    let mut obs = vec![0.0; obs_dim()];
    e.reset(seed, &mut obs);
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0xabc);
    (0..steps)
        .map(|_| {
            let a = [rng.gen_range(-1.0..1.0), rng.gen_range(-1.0..1.0)];
            let s = e.step(&a, &mut obs).unwrap();
            (obs.clone(), s.labels.0, s.reward, e.qpos().to_vec())
        })
        .collect()
}

#[test]
fn same_seed_gives_identical_trajectories() {
    let a = rollout(7, 100);
    let b = rollout(7, 100);
    assert_eq!(a.len(), 100);
    for (x, y) in a.iter().zip(&b) {
        assert_eq!(
            x.0.iter().map(|v| v.to_bits()).collect::<Vec<_>>(),
            y.0.iter().map(|v| v.to_bits()).collect::<Vec<_>>()
        );
        assert_eq!(x.1, y.1);
        assert_eq!(x.2.to_bits(), y.2.to_bits());
        assert_eq!(
            x.3.iter().map(|v| v.to_bits()).collect::<Vec<_>>(),
            y.3.iter().map(|v| v.to_bits()).collect::<Vec<_>>()
        );
    }
    assert_ne!(
        rollout(8, 5)[4].3,
        a[4].3,
        "another seed gives another trajectory"
    );
}

#[test]
fn fingertip_follows_the_arm_geometry() {
    let mut e = env(ReacherConfig::default());
    let mut obs = vec![0.0; obs_dim()];
    e.reset(0, &mut obs);
    for &(q0, q1) in &[(0.0, 0.0), (0.5, -1.0), (-2.0, 2.5), (3.0, 0.3)] {
        e.set_arm([q0, q1], [0.0, 0.0]).unwrap();
        let tip = e.fingertip();
        let expect = [
            L1 * q0.cos() + L2 * (q0 + q1).cos(),
            L1 * q0.sin() + L2 * (q0 + q1).sin(),
        ];
        assert!(
            (tip[0] - expect[0]).abs() < 1e-12 && (tip[1] - expect[1]).abs() < 1e-12,
            "{tip:?} vs {expect:?}"
        );
    }
}

#[test]
fn each_ball_label_fires_exactly_within_touch_radius() {
    let mut e = env(ReacherConfig {
        cancel: Some(CancelConfig {
            probability: 0.0,
            earliest_step: 1,
            latest_step: 8,
        }),
        ..Default::default()
    });
    let mut obs = vec![0.0; obs_dim()];
    e.reset(1, &mut obs);
    for (bit, ball) in e.positions().to_vec().iter().enumerate() {
        for &(d, inside) in &[(0.0, true), (0.0199, true), (0.0201, false), (0.05, false)] {
            for k in 0..4 {
                let phi = k as f64 * std::f64::consts::FRAC_PI_2 + 0.3;
                let target = [ball[0] + d * phi.cos(), ball[1] + d * phi.sin()];
                let reach = target[0].hypot(target[1]);
                if !(0.02..=0.205).contains(&reach) {
                    continue; // outside the arm's annulus (joint1 is limited to ±3 rad)
                }
                e.set_arm(inverse_kinematics(target[0], target[1]), [0.0, 0.0])
                    .unwrap();
                let tip = e.fingertip();
                assert!((tip[0] - target[0]).hypot(tip[1] - target[1]) < 1e-9);
                assert_eq!(
                    e.labels().contains(bit),
                    inside,
                    "ball {} at distance {d}",
                    layout().regions[bit].anchor.name()
                );
                // Only that ball: the default layout keeps balls far apart.
                assert_eq!(e.labels().0 & !(1 << bit), 0);
            }
        }
    }
}

#[test]
fn labels_after_a_step_match_the_distances() {
    let mut e = env(ReacherConfig::default());
    let mut obs = vec![0.0; obs_dim()];
    e.reset(3, &mut obs);
    let ball = e.positions()[2];
    // Start resting on the blue ball; a zero action keeps it there for a step.
    e.set_arm(inverse_kinematics(ball[0], ball[1]), [0.0, 0.0])
        .unwrap();
    let s = e.step(&[0.0, 0.0], &mut obs).unwrap();
    assert!(s.labels.contains(2));
    let [cx, cy] = layout().region_columns(2);
    assert!((obs[cx] as f64).hypot(obs[cy] as f64) < layout().regions[2].radius);
}

#[test]
fn cancel_event_is_reproducible_and_fires_once() {
    let config = ReacherConfig::default();
    let mut e = env(config.clone());
    let mut obs = vec![0.0; obs_dim()];
    let mut with_cancel = 0;
    for seed in 0..200u64 {
        e.reset(seed, &mut obs);
        let scheduled = e.event_steps()[0];
        let mut fired = vec![];
        for t in 1..=config.max_steps {
            let s = e.step(&[0.1, -0.1], &mut obs).unwrap();
            let (bit, column) = (layout().event_bit(0), layout().event_column(0));
            if s.labels.contains(bit) {
                fired.push(t);
                assert_eq!(obs[column], 1.0);
            } else {
                assert_eq!(obs[column], 0.0);
            }
            assert_eq!(s.truncated, t == config.max_steps);
        }
        assert_eq!(fired, scheduled.into_iter().collect::<Vec<_>>());
        if let Some(t) = scheduled {
            // The task's own window (steps 1..=8).
            assert!((1..=8).contains(&t));
            with_cancel += 1;
        }
        e.reset(seed, &mut obs);
        assert_eq!(e.event_steps()[0], scheduled, "same seed, same schedule");
    }
    // Binomial(200, 0.5): 100 ± 5σ.
    assert!((65..=135).contains(&with_cancel), "{with_cancel}");
    let mut never = env(ReacherConfig {
        cancel: Some(CancelConfig {
            probability: 0.0,
            earliest_step: 1,
            latest_step: 8,
        }),
        ..Default::default()
    });
    for seed in 0..50 {
        never.reset(seed, &mut obs);
        assert_eq!(never.event_steps(), &[None]);
    }
}

#[test]
fn arm_matches_gymnasium_reacher() {
    let m = Model::from_xml_path(&shipped_xml()).unwrap();
    assert_eq!(m.timestep(), 0.01);
    assert!(m.uses_rk4());
    let j0 = m.id(ObjectKind::Joint, "joint0").unwrap();
    let j1 = m.id(ObjectKind::Joint, "joint1").unwrap();
    assert_eq!(m.joint_range(j0), None, "joint0 is unlimited");
    assert_eq!(m.joint_range(j1), Some((-3.0, 3.0)));
    for j in [j0, j1] {
        let dof = m.joint_dof_addr(j);
        assert_eq!(m.dof_armature(dof), 1.0);
        assert_eq!(m.dof_damping(dof), 1.0);
    }
    assert_eq!(m.nu(), 2);
    for (a, j) in [(0, j0), (1, j1)] {
        assert_eq!(m.actuator_ctrl_range(a), Some((-1.0, 1.0)));
        assert_eq!(m.actuator_gear(a), 200.0);
        assert_eq!(m.actuator_joint(a), j);
    }
    for g in 0..m.ngeom() {
        assert_eq!(m.geom_collision_masks(g).0, 0, "geom {g} must not collide");
    }
    for region in &layout().regions {
        let g = m.id(ObjectKind::Geom, region.anchor.name()).unwrap();
        assert_eq!(m.geom_radius(g), 0.02);
    }
    // The arena walls, from their `fromto` attributes: capsules along the square's sides.
    let close = |a: [f64; 3], b: [f64; 3]| a.iter().zip(&b).all(|(x, y)| (x - y).abs() < 1e-9);
    for (name, from, to) in [
        ("sideS", [-0.3, -0.3, 0.01], [0.3, -0.3, 0.01]),
        ("sideE", [0.3, -0.3, 0.01], [0.3, 0.3, 0.01]),
        ("sideN", [-0.3, 0.3, 0.01], [0.3, 0.3, 0.01]),
        ("sideW", [-0.3, -0.3, 0.01], [-0.3, 0.3, 0.01]),
    ] {
        let g = m.id(ObjectKind::Geom, name).unwrap();
        let (a, b) = m.world_capsule_segment(g).unwrap();
        assert!(
            (close(a, from) && close(b, to)) || (close(a, to) && close(b, from)),
            "{name}: {a:?} - {b:?}"
        );
        assert_eq!(m.geom_radius(g), 0.02);
    }
    let ball = m
        .id(ObjectKind::Geom, layout().regions[0].anchor.name())
        .unwrap();
    assert_eq!(
        m.world_capsule_segment(ball),
        None,
        "a sphere has no segment"
    );
    // One env step is 0.02 s.
    let mut e = env(ReacherConfig::default());
    let mut obs = vec![0.0; obs_dim()];
    e.reset(0, &mut obs);
    for _ in 0..10 {
        e.step(&[0.0, 0.0], &mut obs).unwrap();
    }
    let data_time = {
        let mut d = Data::new(Arc::clone(e.model())).unwrap();
        for _ in 0..20 {
            d.step().unwrap();
        }
        d.time()
    };
    assert!((data_time - 0.2).abs() < 1e-12);
}

#[test]
fn actions_are_clipped_and_bad_actions_rejected() {
    let mut a = env(ReacherConfig::default());
    let mut b = env(ReacherConfig::default());
    let (mut oa, mut ob) = (vec![0.0; obs_dim()], vec![0.0; obs_dim()]);
    a.reset(5, &mut oa);
    b.reset(5, &mut ob);
    let sa = a.step(&[5.0, -7.0], &mut oa).unwrap();
    let sb = b.step(&[1.0, -1.0], &mut ob).unwrap();
    assert_eq!(oa, ob);
    assert_eq!(sa.reward, sb.reward);
    assert_eq!(
        a.step(&[0.0], &mut oa),
        Err(EnvError::ActionLength {
            expected: 2,
            got: 1
        })
    );
    assert!(matches!(
        a.step(&[0.0, f32::NAN], &mut oa),
        Err(EnvError::ActionNotFinite { index: 1, .. })
    ));
    let mut fresh = env(ReacherConfig::default());
    assert_eq!(fresh.step(&[0.0, 0.0], &mut oa), Err(EnvError::NotReset));
}

#[test]
fn randomised_layouts_are_reachable_and_seeded() {
    let config = ReacherConfig {
        randomize_balls: true,
        ..Default::default()
    };
    let mut e = env(config.clone());
    // The whole shipped scene (the environment steps it without the balls) and the first
    // scene, whose balls sit on slide joints, place the same layouts.
    let scene_config = composite().env_config(&config).unwrap();
    let scene = Arc::new(Model::from_xml_path(&shipped_xml()).unwrap());
    let mut whole = ReacherDelivery::with_model(scene, scene_config.clone()).unwrap();
    let mut v1 = ReacherDelivery::with_model(v1_model(), scene_config).unwrap();
    let ball_ids: Vec<usize> = (layout().regions.iter())
        .map(|r| whole.model().id(ObjectKind::Body, r.anchor.name()).unwrap())
        .collect();
    let mut obs = vec![0.0; obs_dim()];
    e.reset(11, &mut obs);
    let first = e.positions().to_vec();
    e.reset(12, &mut obs);
    assert_ne!(first, e.positions());
    e.reset(11, &mut obs);
    assert_eq!(first, e.positions());
    for seed in 0..100 {
        e.reset(seed, &mut obs);
        let balls = e.positions().to_vec();
        for (i, b) in balls.iter().enumerate() {
            let r = b[0].hypot(b[1]);
            assert!((0.06..0.19).contains(&r));
            // The model's ball bodies are where the layout says, in both scenes.
            whole.reset(seed, &mut obs);
            assert_eq!(whole.positions(), balls);
            let p = whole.body_position(ball_ids[i]);
            assert_eq!([p[0], p[1]], *b);
            v1.reset(seed, &mut obs);
            assert_eq!(v1.positions(), balls);
            assert_eq!([v1.qpos()[2 + 2 * i], v1.qpos()[3 + 2 * i]], *b);
            let p = v1.body_position(ball_ids[i]);
            assert_eq!([p[0], p[1]], *b);
            for c in &balls[..i] {
                assert!((b[0] - c[0]).hypot(b[1] - c[1]) >= 0.08);
            }
        }
    }
}

#[test]
fn malformed_xml_reports_mujocos_message_and_the_file() {
    let err = Model::from_xml_str(
        "<mujoco><worldbody><body></worldbody></mujoco>",
        "broken.xml",
    )
    .unwrap_err();
    let text = err.to_string();
    assert!(matches!(err, MjError::Load { .. }));
    assert!(text.contains("broken.xml"), "{text}");
    assert!(
        text.to_lowercase().contains("xml"),
        "MuJoCo's parser message is kept: {text}"
    );
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("bad.xml");
    std::fs::write(
        &path,
        "<mujoco><worldbody><geom type='sphere'/></worldbody></mujoco>",
    )
    .unwrap();
    let text = Model::from_xml_path(&path).unwrap_err().to_string();
    assert!(text.contains("bad.xml") && text.contains("size"), "{text}");
    let text = Model::from_xml_path(&dir.path().join("missing.xml"))
        .unwrap_err()
        .to_string();
    assert!(
        text.contains("missing.xml") && text.contains("no such file"),
        "{text}"
    );
}

#[test]
fn unknown_names_and_wrong_models_are_errors() {
    let m = Arc::new(Model::from_xml_path(&shipped_xml()).unwrap());
    let e = m.id(ObjectKind::Body, "purple").unwrap_err();
    assert!(e.to_string().contains("no body named 'purple'"), "{e}");
    // The balls are mocap bodies without joints; the first scene moves them by slides.
    assert!(m.id(ObjectKind::Joint, "red_x").is_err());
    assert!(m
        .body_mocap_id(m.id(ObjectKind::Body, "red").unwrap())
        .is_some());
    assert!(v1_model().id(ObjectKind::Joint, "red_x").is_ok());
    assert!(v1_model().id(ObjectKind::Site, "red_x").is_err());
    let plain = Arc::new(Model::from_xml_str("<mujoco><worldbody><body name='b'><joint name='joint0' type='hinge'/><geom size='0.1'/></body></worldbody></mujoco>", "plain").unwrap());
    let config = composite().env_config(&ReacherConfig::default()).unwrap();
    let err = ReacherDelivery::with_model(plain, config).err().unwrap();
    assert!(err.to_string().contains("joint1"), "{err}");
    // A scene whose ball can be neither moved by mocap nor by slides is refused by name.
    let fixed = smirl::assets::REACHER_XML
        .replace(r#"<body mocap="true" name="blue""#, r#"<body name="blue""#);
    let fixed = Arc::new(Model::from_xml_str(&fixed, "fixed.xml").unwrap());
    let config = composite().env_config(&ReacherConfig::default()).unwrap();
    let err = ReacherDelivery::with_model(fixed, config)
        .err()
        .unwrap()
        .to_string();
    assert!(
        err.contains("fixed.xml") && err.contains("body blue"),
        "{err}"
    );
}

#[test]
fn invalid_configs_are_rejected() {
    let bad = ReacherConfig {
        cancel: Some(CancelConfig {
            probability: 1.5,
            earliest_step: 1,
            latest_step: 8,
        }),
        ..Default::default()
    };
    assert!(composite()
        .make_env(&bad)
        .err()
        .unwrap()
        .to_string()
        .contains("probability"));
    let bad = ReacherConfig {
        max_steps: 0,
        ..Default::default()
    };
    assert!(composite().make_env(&bad).is_err());
    let bad: Result<ReacherConfig, _> = toml::from_str("max_step = 10");
    assert!(bad.unwrap_err().to_string().contains("max_step"));
}

#[test]
fn data_state_setters_check_lengths() {
    let m = Arc::new(Model::from_xml_path(&shipped_xml()).unwrap());
    let mut d = Data::new(m).unwrap();
    // The arm's two joints are the whole state.
    assert_eq!((d.qpos().len(), d.qvel().len()), (2, 2));
    assert!(d.set_qpos(&[0.0; 3]).is_err());
    assert!(d.set_qvel(&[0.0; 10]).is_err());
    d.set_qpos(&[0.1; 2]).unwrap();
    d.forward().unwrap();
    assert_eq!(d.qpos(), &[0.1; 2]);
    let mut d = Data::new(v1_model()).unwrap();
    assert_eq!(d.qpos().len(), 10);
    d.set_qpos(&[0.1; 10]).unwrap();
    d.forward().unwrap();
    assert_eq!(d.qpos(), &[0.1; 10]);
}

#[test]
fn a_sweeping_arm_touches_at_most_one_ball_of_the_default_layout() {
    // A policy that spins the shoulder at a fixed elbow angle must not complete a task by
    // accident: at every elbow angle, a full turn of the shoulder touches at most one ball.
    let mut e = env(ReacherConfig {
        cancel: Some(CancelConfig {
            probability: 0.0,
            earliest_step: 1,
            latest_step: 8,
        }),
        ..Default::default()
    });
    let mut obs = vec![0.0; obs_dim()];
    e.reset(0, &mut obs);
    for i in 0..=600 {
        let q1 = -3.0 + 6.0 * i as f64 / 600.0;
        let mut touched = 0u32;
        for k in 0..720 {
            let q0 = k as f64 * std::f64::consts::TAU / 720.0;
            e.set_arm([q0, q1], [0.0, 0.0]).unwrap();
            touched |= e.labels().0;
        }
        assert!(
            touched.count_ones() <= 1,
            "elbow {q1:.3}: touched {touched:#b}"
        );
    }
    // ...and every ball can be touched.
    for (bit, ball) in e.positions().to_vec().iter().enumerate() {
        e.set_arm(inverse_kinematics(ball[0], ball[1]), [0.0, 0.0])
            .unwrap();
        assert!(e.labels().contains(bit));
    }
}

/// The shipped model file (the binaries use the same text, built in: `smirl::assets`).
fn shipped_xml() -> std::path::PathBuf {
    std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/reacher_delivery.xml")
}

/// The first scene, balls on slide joints (`assets/reacher_delivery_v1.xml`).
fn v1_model() -> Arc<Model> {
    let path =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/reacher_delivery_v1.xml");
    Arc::new(Model::from_xml_path(&path).unwrap())
}

#[test]
fn built_in_model_is_the_shipped_file() {
    let file = std::fs::read_to_string(shipped_xml()).unwrap();
    assert_eq!(smirl::assets::REACHER_XML, file);
}

#[test]
fn constraint_buffers_hold_every_limit_at_once() {
    // Each model sizes its constraint buffers (njmax) to what it can produce, because MuJoCo
    // zeroes them on every reset. The worst case: every limited joint at its limit and moving
    // outward: the elbow alone in the shipped model, the elbow and all eight ball slides (nine
    // limit rows) in the first scene. A full buffer is a MuJoCo warning.
    for m in [
        Arc::new(Model::from_xml_path(&shipped_xml()).unwrap()),
        v1_model(),
    ] {
        let mut d = Data::new(Arc::clone(&m)).unwrap();
        smirl::mujoco::take_warnings();
        let mut qpos = vec![0.27f64; m.nq()];
        qpos[0] = 0.0;
        qpos[1] = 3.0;
        for (i, q) in qpos.iter_mut().enumerate().skip(2) {
            if i % 2 == 1 {
                *q = -*q;
            }
        }
        let qvel: Vec<f64> = qpos.iter().map(|q: &f64| q.signum()).collect();
        d.set_qpos(&qpos).unwrap();
        d.set_qvel(&qvel).unwrap();
        d.set_ctrl(&[1.0, 1.0]).unwrap();
        for _ in 0..20 {
            d.step().unwrap();
        }
        assert_eq!(smirl::mujoco::take_warnings(), Vec::<String>::new());
        // The limits held: every limited joint is still within a few mm (or rad/100) of its
        // range.
        for (i, q) in d.qpos().iter().enumerate().skip(1) {
            let limit = if i == 1 { 3.0 } else { 0.27 };
            assert!(q.abs() < limit + 0.05, "{m:?} qpos[{i}] = {q}");
        }
    }
}

/// `CancelConfig::schedule` is the inverse of `CancelConfig::of`: an event given a schedule
/// reads it back whole, and its letter stays its own (`reacher demo` records the schedule that
/// ran this way).
#[test]
fn an_event_given_a_schedule_reads_it_back() {
    let mut event = smirl::env::layout::Event {
        letter: 's',
        probability: 0.2,
        earliest_step: 1,
        latest_step: 100,
    };
    let given = CancelConfig {
        probability: 0.75,
        earliest_step: 7,
        latest_step: 23,
    };
    given.schedule(&mut event);
    assert_eq!(CancelConfig::of(&event), given);
    assert_eq!(event.letter, 's');
}
