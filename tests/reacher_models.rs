//! The shipped model (`assets/reacher_delivery.xml`: balls as mocap bodies, no contact pass)
//! against the first one (`assets/reacher_delivery_v1.xml`: balls on slide joints): the arm
//! moves identically, the environment on either gives the same episodes, and a log made
//! with the first model replays bit for bit with it.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use smirl::assets::{REACHER_V1_XML, REACHER_XML};
use smirl::env::reacher::{ReacherConfig, ReacherDelivery};
use smirl::env::reacher_task::ReacherTask;
use smirl::env::ContinuousEnv;
use smirl::log::read_log;
use smirl::log::schema::sha256_hex;
use smirl::mujoco::{Data, Model};
use smirl::pipeline::replay::replay;
use std::path::Path;
use std::sync::Arc;

fn model(xml: &str, name: &str) -> Arc<Model> {
    Arc::new(Model::from_xml_str(xml, name).unwrap())
}

#[test]
fn the_arm_moves_as_in_the_first_model_through_long_random_torque_rollouts() {
    let (lean, v1) = (model(REACHER_XML, "lean"), model(REACHER_V1_XML, "v1"));
    assert_eq!((lean.nq(), lean.nv(), v1.nq(), v1.nv()), (2, 2, 10, 10));
    let (mut limit_steps, mut bit_identical) = (0, true);
    for seed in 0..3u64 {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let mut a = Data::new(Arc::clone(&lean)).unwrap();
        let mut b = Data::new(Arc::clone(&v1)).unwrap();
        // The first model's balls at a layout on their slides, as an episode has them.
        for k in 2..10 {
            b.qpos_mut()[k] = rng.gen_range(-0.2..0.2);
        }
        let mut ctrl = [0.0; 2];
        for t in 0..6000 {
            // A new torque every 40 steps; the elbow's is at least half the motor's range in
            // one direction, which drives it into its ±3 rad limit and holds it there.
            if t % 40 == 0 {
                let sign = if rng.gen_bool(0.5) { 1.0 } else { -1.0 };
                ctrl = [rng.gen_range(-1.0..1.0), sign * rng.gen_range(0.5..1.0)];
            }
            a.set_ctrl(&ctrl).unwrap();
            b.set_ctrl(&ctrl).unwrap();
            a.step().unwrap();
            b.step().unwrap();
            if b.qpos()[1].abs() > 3.0 {
                limit_steps += 1;
            }
            for k in 0..2 {
                for (x, y, what) in [
                    (a.qpos()[k], b.qpos()[k], "qpos"),
                    (a.qvel()[k], b.qvel()[k], "qvel"),
                ] {
                    assert!(
                        (x - y).abs() <= 1e-9,
                        "seed {seed} step {t}: {what}[{k}] {x} vs {y}"
                    );
                    bit_identical &= x.to_bits() == y.to_bits();
                }
            }
        }
        // The balls never moved in the first model.
        assert!(b.qvel()[2..].iter().all(|&v| v == 0.0));
    }
    // The rollouts test the joint limit: the elbow spends a good part of them beyond ±3 rad
    // (MuJoCo's limits are soft), pushed back by the limit constraint.
    assert!(limit_steps > 3000, "{limit_steps} steps at the limit");
    // Not only within 1e-9: the same bits (the removed coordinates add exact zeros).
    assert!(bit_identical);
}

#[test]
fn environments_on_both_models_give_the_same_episodes_bit_for_bit() {
    for randomize_balls in [false, true] {
        let config = ReacherConfig {
            randomize_balls,
            ..Default::default()
        };
        // The paper's layout: four balls and the cancel.
        let config = (ReacherTask::shipped("composite").unwrap())
            .env_config(&config)
            .unwrap();
        let mut lean = ReacherDelivery::new(config.clone()).unwrap();
        let mut v1 = ReacherDelivery::with_model(model(REACHER_V1_XML, "v1"), config).unwrap();
        let obs_dim = lean.layout().obs_dim();
        let (mut oa, mut ob) = (vec![0.0f32; obs_dim], vec![0.0f32; obs_dim]);
        let mut rng = ChaCha8Rng::seed_from_u64(9);
        for seed in 0..20 {
            lean.reset(seed, &mut oa);
            v1.reset(seed, &mut ob);
            assert_eq!(lean.positions(), v1.positions());
            assert_eq!(lean.event_steps(), v1.event_steps());
            assert_eq!(oa, ob);
            loop {
                let action = [rng.gen_range(-1.2f32..1.2), rng.gen_range(-1.2f32..1.2)];
                let (sa, sb) = (
                    lean.step(&action, &mut oa).unwrap(),
                    v1.step(&action, &mut ob).unwrap(),
                );
                assert_eq!(sa, sb);
                assert_eq!(oa, ob);
                assert_eq!(lean.qpos(), &v1.qpos()[..2]);
                assert_eq!(lean.qvel(), &v1.qvel()[..2]);
                if sa.truncated {
                    break;
                }
            }
        }
    }
}

/// `tests/fixtures/demo_v1_model.mcap`: 3 scripted Sequential demonstrations (seed 5, with
/// observations) logged by the program at main bb347e7, whose built-in model was the first.
fn v1_fixture() -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/demo_v1_model.mcap")
}

#[test]
fn a_log_made_with_the_first_model_replays_bit_for_bit_with_it() {
    let log = read_log(&v1_fixture()).unwrap();
    assert_eq!(log.model_xml.as_deref(), Some(REACHER_V1_XML));
    assert_eq!(log.episodes[0].start.qpos.len(), 10);
    let report = replay(&log).unwrap();
    assert!(report.all_match(), "{report}");
    assert_eq!(report.steps, log.steps());
    assert!(report.episodes.iter().all(|e| e.seed_reproduces_start));
    assert!(
        report.setting_notes[0].contains("reacher_delivery_v1.xml"),
        "{:?}",
        report.setting_notes
    );

    // Without its attachment, the run record's hash picks the same shipped model.
    let mut bare = log.clone();
    bare.model_xml = None;
    let report = replay(&bare).unwrap();
    assert!(report.all_match(), "{report}");

    // The choice matters: the shipped model cannot take the log's 10-value states.
    let mut other = log.clone();
    other.model_xml = Some(REACHER_XML.into());
    other.run.model_xml_sha256 = sha256_hex(REACHER_XML);
    let refused = replay(&other).map(|r| r.all_match()).unwrap_or(false);
    assert!(!refused, "a 10-value state replayed on the 2-joint model");
}

#[test]
fn a_fresh_log_records_the_shipped_model_and_replays_bit_for_bit() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("demo.mcap");
    smirl::log::demo::log_scripted_demos(
        &path,
        &smirl::log::demo::DemoSpec {
            task: "sequential".into(),
            sequence: "rgby".into(),
            episodes: 3,
            seed: 5,
            stop_when_done: true,
            env: ReacherConfig::default(),
            event_probability: None,
            reward_machine: Some(smirl::rm::perfect::reacher("sequential").unwrap()),
        },
        smirl::log::LogOptions {
            observations: true,
            ..Default::default()
        },
    )
    .unwrap();
    let log = read_log(&path).unwrap();
    assert_eq!(log.run.model_xml_sha256, sha256_hex(REACHER_XML));
    assert_eq!(log.model_xml.as_deref(), Some(REACHER_XML));
    let report = replay(&log).unwrap();
    assert!(
        report.all_match() && report.setting_notes.is_empty(),
        "{report}"
    );

    // The same demonstrations as the first model's log: the arm's states, the labels,
    // rewards and observations agree bit for bit; only the balls left the state.
    let old = read_log(&v1_fixture()).unwrap();
    assert_eq!(log.episodes.len(), old.episodes.len());
    for (new, old) in log.episodes.iter().zip(&old.episodes) {
        assert_eq!(new.start.balls, old.start.balls);
        assert_eq!(new.start.qpos[..], old.start.qpos[..2]);
        assert_eq!(new.steps.len(), old.steps.len());
        for (s, o) in new.steps.iter().zip(&old.steps) {
            assert_eq!((&s.qpos[..], &s.qvel[..]), (&o.qpos[..2], &o.qvel[..2]));
            assert_eq!(
                (s.labels, s.reward.to_bits()),
                (o.labels, o.reward.to_bits())
            );
            assert_eq!(s.obs, o.obs);
            assert_eq!(s.action, o.action);
        }
    }
}
