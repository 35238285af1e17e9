//! SAC: config parsing, determinism, bootstrapping rules, NaN detection, checkpoints.

mod sac_common;

use nalgebra::DMatrix;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use sac_common::PointReach;
use smirl::rl::replay::{ReplayBatch, ReplayBuffer};
use smirl::rl::sac::{
    CheckpointError, ConfigError, EnvReward, SacAgent, SacConfig, SacError, SacTrainer,
};
use smirl::rm::LabelSet;

fn small_config() -> SacConfig {
    SacConfig {
        hidden: vec![16, 16],
        batch_size: 32,
        warmup_steps: 100,
        update_after: 100,
        ..SacConfig::default()
    }
}

fn all_params(t: &SacTrainer) -> Vec<f32> {
    let a = &t.agent;
    [&a.actor, &a.q1, &a.q2, &a.q1_target, &a.q2_target]
        .iter()
        .flat_map(|n| {
            n.params()
                .flat_map(|p| p.iter().copied())
                .collect::<Vec<_>>()
        })
        .chain([a.alpha()])
        .collect()
}

fn bits(v: &[f32]) -> Vec<u32> {
    v.iter().map(|x| x.to_bits()).collect()
}

#[test]
fn config_defaults_are_the_paper_values_and_expert_preset() {
    let c = SacConfig::default();
    assert_eq!(c.hidden, vec![64, 64]);
    assert_eq!((c.lr, c.batch_size, c.replay_capacity), (3e-3, 256, 10_000));
    assert_eq!((c.gamma, c.tau), (0.99, 0.005));
    assert_eq!(c.target_entropy_for(2), -2.0);
    let e = SacConfig::expert();
    assert_eq!(
        (e.batch_size, e.replay_capacity, e.alpha, e.auto_alpha),
        (100, 1_000_000, 0.2, false)
    );
    assert_eq!(SacConfig::from_toml("", "x.toml").unwrap(), c);
    let t = SacConfig::from_toml("preset = \"expert\"\nlr = 1e-3\n", "x.toml").unwrap();
    assert_eq!(
        t,
        SacConfig {
            lr: 1e-3,
            ..SacConfig::expert()
        }
    );
    // Round trip through TOML.
    assert_eq!(SacConfig::from_toml(&e.to_toml(), "e").unwrap(), e);
}

#[test]
fn config_errors_name_the_file_and_field() {
    let err = SacConfig::from_toml("batch_sise = 3\n", "cfg/sac.toml").unwrap_err();
    let msg = err.to_string();
    assert!(
        msg.contains("cfg/sac.toml") && msg.contains("batch_sise"),
        "{msg}"
    );
    let msg = SacConfig::from_toml("gamma = \"high\"\n", "a.toml")
        .unwrap_err()
        .to_string();
    assert!(msg.contains("a.toml") && msg.contains("gamma"), "{msg}");
    let err = SacConfig::from_toml("gamma = 1.5\n", "a.toml").unwrap_err();
    assert_eq!(
        err,
        ConfigError::Invalid {
            field: "gamma",
            problem: "must be in [0, 1)".into()
        }
    );
    let msg = SacConfig::from_toml("preset = \"fast\"\n", "a.toml")
        .unwrap_err()
        .to_string();
    assert!(msg.contains("fast"), "{msg}");
    assert!(SacConfig::from_toml("replay_capacity = 10\n", "a").is_err());
}

#[test]
fn same_seed_gives_identical_parameters_and_other_seed_differs() {
    let run = |seed| {
        let mut env = PointReach::new(25);
        let mut t = SacTrainer::new(&small_config(), 2, 1, seed).unwrap();
        t.train(&mut env, &mut EnvReward, 300, |_| {}).unwrap();
        assert_eq!(t.agent.updates(), 201);
        bits(&all_params(&t))
    };
    assert_eq!(run(5), run(5));
    assert_ne!(run(5), run(6));
}

/// Trains the critics on one repeated transition with reward 1 and checks the value they
/// converge toward: 1 when the transition terminates, growing toward 1/(1−γ) when it does not.
fn q_after_fitting(terminated: bool) -> f32 {
    let config = SacConfig {
        hidden: vec![16],
        batch_size: 8,
        gamma: 0.9,
        lr: 1e-2,
        auto_alpha: false,
        alpha: 1e-6,
        tau: 0.05,
        ..SacConfig::default()
    };
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    let mut agent = SacAgent::new(&config, 2, 1, &mut rng);
    let mut replay = ReplayBuffer::new(2, 1, 8);
    replay.push(
        &[0.3, -0.2],
        &[0.5],
        &[0.3, -0.2],
        1.0,
        LabelSet::EMPTY,
        terminated,
    );
    let mut batch = ReplayBatch::new(2, 1, 8);
    let rewards = [1.0f32; 8];
    for _ in 0..1500 {
        replay.sample_into(&mut rng, &mut batch);
        agent.update(&batch, &rewards, &mut rng).unwrap();
    }
    let x = DMatrix::from_column_slice(3, 1, &[0.3, -0.2, 0.5]);
    let mut ws = agent.q1.workspace(1);
    agent.q1.forward(&x, &mut ws)[0]
}

#[test]
fn terminated_transitions_are_not_bootstrapped_but_others_are() {
    let q_term = q_after_fitting(true);
    assert!(
        (q_term - 1.0).abs() < 0.05,
        "Q of a terminal transition {q_term}"
    );
    let q_cont = q_after_fitting(false);
    // The fixed point is 10; after 1500 updates with τ = 0.05 the value is well on its way.
    assert!(q_cont > 5.0, "Q of a bootstrapped transition {q_cont}");
}

#[test]
fn nan_rewards_stop_training_naming_network_and_update() {
    let mut env = PointReach::new(25);
    let mut t = SacTrainer::new(&small_config(), 2, 1, 3).unwrap();
    let mut calls = 0;
    let mut nan_reward = |b: &ReplayBatch, out: &mut [f32]| {
        calls += 1;
        out.copy_from_slice(&b.env_rewards);
        if calls == 7 {
            out[3] = f32::NAN;
        }
    };
    let err = t
        .train(&mut env, &mut nan_reward, 1_000, |_| {})
        .unwrap_err();
    match &err {
        SacError::NonFinite {
            network,
            what,
            update,
        } => {
            assert_eq!((*network, *what, *update), ("critic q1", "loss", 7));
        }
        other => panic!("unexpected error {other}"),
    }
    assert!(err.to_string().contains("critic q1") && err.to_string().contains("update 7"));
    // The failed update was not counted.
    assert_eq!(t.agent.updates(), 6);
}

#[test]
fn corrupted_parameters_stop_training_at_the_next_update() {
    let mut env = PointReach::new(25);
    let mut t = SacTrainer::new(&small_config(), 2, 1, 3).unwrap();
    t.train(&mut env, &mut EnvReward, 150, |_| {}).unwrap();
    let done = t.agent.updates();
    t.agent.actor.layers[1].w[(0, 0)] = f32::INFINITY;
    let err = t.train(&mut env, &mut EnvReward, 10, |_| {}).unwrap_err();
    // The infinite actor weight makes the critic targets NaN: the first loss computed from
    // them is reported.
    match err {
        SacError::NonFinite { update, .. } => assert_eq!(update, done + 1),
        other => panic!("unexpected error {other}"),
    }
}

#[test]
fn environment_of_wrong_size_is_refused() {
    let mut env = PointReach::new(25);
    let mut t = SacTrainer::new(&small_config(), 3, 1, 3).unwrap();
    let msg = t
        .train(&mut env, &mut EnvReward, 1, |_| {})
        .unwrap_err()
        .to_string();
    assert!(msg.contains("observation size 2"), "{msg}");
}

#[test]
fn killed_and_resumed_run_matches_uninterrupted_run_bit_for_bit() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("run.ckpt");
    let config = small_config();
    // Episodes are 25 steps; 200 = 8 whole episodes, so the split falls between episodes.
    let mut env = PointReach::new(25);
    let mut full = SacTrainer::new(&config, 2, 1, 42).unwrap();
    full.train(&mut env, &mut EnvReward, 400, |_| {}).unwrap();

    let mut env = PointReach::new(25);
    let mut first = SacTrainer::new(&config, 2, 1, 42).unwrap();
    first.train(&mut env, &mut EnvReward, 200, |_| {}).unwrap();
    assert!(first.at_episode_boundary());
    first.save_checkpoint(&path).unwrap();
    let halfway = bits(&all_params(&first));
    drop(first);

    let mut resumed = SacTrainer::resume(&path, &config, 2, 1).unwrap();
    assert_eq!(bits(&all_params(&resumed)), halfway, "round trip is exact");
    assert_eq!((resumed.env_steps(), resumed.episodes()), (200, 8));
    let mut env = PointReach::new(25);
    resumed
        .train(&mut env, &mut EnvReward, 200, |_| {})
        .unwrap();
    assert_eq!(bits(&all_params(&resumed)), bits(&all_params(&full)));
    assert_eq!(resumed.agent.updates(), full.agent.updates());
}

#[test]
fn mismatched_or_damaged_checkpoints_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("run.ckpt");
    let config = small_config();
    let mut env = PointReach::new(25);
    let mut t = SacTrainer::new(&config, 2, 1, 1).unwrap();
    t.train(&mut env, &mut EnvReward, 110, |_| {}).unwrap();
    // Mid-episode: refused, nothing written.
    assert!(matches!(
        t.save_checkpoint(&path),
        Err(CheckpointError::MidEpisode)
    ));
    assert!(!path.exists());
    t.train(&mut env, &mut EnvReward, 15, |_| {}).unwrap();
    t.save_checkpoint(&path).unwrap();

    let other_arch = SacConfig {
        hidden: vec![16, 8],
        ..config.clone()
    };
    let err = SacTrainer::resume(&path, &other_arch, 2, 1).unwrap_err();
    assert!(matches!(err, CheckpointError::Architecture { .. }), "{err}");
    let msg = err.to_string();
    assert!(
        msg.contains("run.ckpt") && msg.contains("[16, 16]") && msg.contains("[16, 8]"),
        "{msg}"
    );

    let err = SacTrainer::resume(&path, &config, 3, 1).unwrap_err();
    assert!(
        err.to_string()
            .contains("observation size is 2 in the file, 3 here"),
        "{err}"
    );

    let other_lr = SacConfig {
        lr: 1e-4,
        ..config.clone()
    };
    let msg = SacTrainer::resume(&path, &other_lr, 2, 1)
        .unwrap_err()
        .to_string();
    assert!(msg.contains("fields differ: lr"), "{msg}");

    let bytes = std::fs::read(&path).unwrap();
    let mut v2 = bytes.clone();
    v2[8] = 2;
    std::fs::write(&path, &v2).unwrap();
    let msg = SacTrainer::resume(&path, &config, 2, 1)
        .unwrap_err()
        .to_string();
    assert!(msg.contains("version 2"), "{msg}");
    std::fs::write(&path, &bytes[..bytes.len() / 2]).unwrap();
    let msg = SacTrainer::resume(&path, &config, 2, 1)
        .unwrap_err()
        .to_string();
    assert!(msg.contains("ends early"), "{msg}");
    let msg = SacTrainer::resume(&dir.path().join("missing"), &config, 2, 1)
        .unwrap_err()
        .to_string();
    assert!(msg.contains("missing"), "{msg}");
}

#[test]
fn finishing_the_episode_trains_to_the_next_boundary_exactly_as_single_steps_do() {
    let config = small_config();
    let mut env = PointReach::new(25);
    let mut t = SacTrainer::new(&config, 2, 1, 9).unwrap();
    t.train(&mut env, &mut EnvReward, 130, |_| {}).unwrap();
    assert!(!t.at_episode_boundary(), "130 steps end inside an episode");
    let episodes = t.episodes();
    let mut seen = 0;
    let steps = t
        .finish_episode_observed(&mut env, &mut EnvReward, None, |_| seen += 1)
        .unwrap();
    assert!(t.at_episode_boundary());
    assert_eq!((t.env_steps(), t.episodes()), (130 + steps, episodes + 1));
    assert_eq!(seen, steps, "every step is reported");
    let again = t
        .finish_episode_observed(&mut env, &mut EnvReward, None, |_| {})
        .unwrap();
    assert_eq!(again, 0, "no step between episodes");

    let mut env = PointReach::new(25);
    let mut single = SacTrainer::new(&config, 2, 1, 9).unwrap();
    single.train(&mut env, &mut EnvReward, 130, |_| {}).unwrap();
    while !single.at_episode_boundary() {
        single.train(&mut env, &mut EnvReward, 1, |_| {}).unwrap();
    }
    assert_eq!(single.env_steps(), t.env_steps());
    assert_eq!(bits(&all_params(&single)), bits(&all_params(&t)));
}
