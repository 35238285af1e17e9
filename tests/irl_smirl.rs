//! Continuous SMIRL: features, the MaxEnt gradient as expert-minus-agent feature
//! expectations, the log-likelihood surrogate, and the linear reward model.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use smirl::env::reacher::*;
use smirl::env::ContinuousEnv;
use smirl::irl::reward::{RewardError, RewardModel, RewardOptimConfig};
use smirl::irl::smirl::*;

mod smirl_reference;
use smirl_reference::{
    feature_expectations, log_likelihood_surrogate, maxent_gradient, maxent_step,
};

#[allow(unused_imports)]
use shipped_layout::{layout, obs_dim, shipped_config};
mod shipped_layout;

/// A Reacher observation with the fingertip at the given offsets (dx, dy) from each ball
/// and the cancel flag.
fn obs_with(deltas: [[f32; 2]; 4], cancel: bool) -> Vec<f32> {
    let mut o = vec![0.0f32; obs_dim()];
    for (k, d) in deltas.iter().enumerate() {
        o[8 + 2 * k] = d[0];
        o[9 + 2 * k] = d[1];
    }
    o[layout().event_column(0)] = if cancel { 1.0 } else { 0.0 };
    o
}

const FAR: [f32; 2] = [0.1, 0.1];

/// Touching ball `k` (offset 0.005 < 0.02), every other ball far.
fn touching(k: usize, cancel: bool) -> Vec<f32> {
    let mut d = [FAR; 4];
    d[k] = [0.005, -0.005];
    obs_with(d, cancel)
}

fn nothing() -> Vec<f32> {
    obs_with([FAR; 4], false)
}

#[test]
fn label_features_are_the_label_bits() {
    let f = FeatureMap::reacher_labels(&layout());
    assert_eq!(f.len(), 5);
    let mut phi = vec![0.0; 5];
    f.features(&touching(2, true), &mut phi);
    assert_eq!(phi, vec![0.0, 0.0, 1.0, 0.0, 1.0]);
    f.features(&nothing(), &mut phi);
    assert_eq!(phi, vec![0.0; 5]);
    // Either side of the touch radius (strict inequality, as the env).
    f.features(&obs_with([[0.0201, 0.0], FAR, FAR, FAR], false), &mut phi);
    assert_eq!(phi[0], 0.0);
    f.features(&obs_with([[0.0, -0.0199], FAR, FAR, FAR], false), &mut phi);
    assert_eq!(phi[0], 1.0);
    let labels = f.labels_of(&touching(1, true));
    assert!(labels.contains(1) && labels.contains(layout().event_bit(0)) && !labels.contains(0));
}

/// The lingering trap (issue 13): with the labels of the state reached, a policy that stays on
/// a ball collects its weight on every step it stays, so a reward that pays a ball touched
/// along the way can be worth more to sit on than the task.
#[test]
fn staying_on_a_ball_pays_every_step_with_state_labels() {
    let features = FeatureMap::reacher_labels(&layout());
    let mut model = LinearRmReward::new(features, 1, RewardOptimConfig::sgd(0.1)).unwrap();
    model.set_params(&[2.0, 0.0, 1.0, 0.0, 0.0]).unwrap();
    for k in [1, 2, 10] {
        let mut obs = nothing();
        for _ in 0..k {
            obs.extend(touching(0, false));
        }
        let mut r = vec![0.0f32; k + 1];
        model.reward_batch(&obs, &vec![0; k + 1], &mut r).unwrap();
        assert_eq!(r.iter().sum::<f32>(), 2.0 * k as f32);
    }
}

/// A label reward saves and loads with its layout; a reward file whose feature kind this build
/// does not have (`label_entries`, the features of a past experiment) is refused naming the
/// kind and the file.
#[test]
fn label_reward_saves_and_loads_and_an_unknown_feature_kind_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("labels.json");
    let mut model = LinearRmReward::new(
        FeatureMap::reacher_labels(&layout()),
        2,
        RewardOptimConfig::sgd(0.1),
    )
    .unwrap();
    let w: Vec<f32> = (0..10).map(|i| i as f32 - 4.5).collect();
    model.set_params(&w).unwrap();
    model.save(&path).unwrap();
    let back = LinearRmReward::load(&path, RewardOptimConfig::sgd(0.1)).unwrap();
    assert_eq!(back.features(), &FeatureMap::reacher_labels(&layout()));
    assert_eq!(back.params(), w);

    let file = |kind: &str| {
        format!(
            r#"{{"format": "smirl-linear-rm-reward/1", "features": {{"kind": {{"kind": "{kind}"}},
            "layout": {{"obs_dim": 17, "ball_deltas": [[8, 9], [10, 11], [12, 13], [14, 15]],
            "cancel": 16, "touch_radius": 0.02}}}}, "n_states": 1,
            "weights": [[1.0, 0.0, 0.0, 0.0, 0.0]]}}"#
        )
    };
    let written = dir.path().join("written.json");
    std::fs::write(&written, file("labels")).unwrap();
    let back = LinearRmReward::load(&written, RewardOptimConfig::sgd(0.1)).unwrap();
    assert_eq!(back.features(), &FeatureMap::reacher_labels(&layout()));
    let bad = dir.path().join("bad.json");
    std::fs::write(&bad, file("label_entries")).unwrap();
    let err = LinearRmReward::load(&bad, RewardOptimConfig::sgd(0.1))
        .err()
        .unwrap()
        .to_string();
    assert!(
        err.contains("bad.json") && err.contains("unknown variant `label_entries`"),
        "{err}"
    );
}

#[test]
fn smooth_features_are_gaussian_bumps_in_distance() {
    let sigma = 0.05;
    let f = FeatureMap::reacher_smooth(&layout(), sigma).unwrap();
    let mut phi = vec![0.0; 5];
    f.features(
        &obs_with([[0.03, 0.04], [0.0, 0.0], FAR, FAR], true),
        &mut phi,
    );
    let expect = |d2: f64| (-d2 / (2.0 * sigma * sigma)).exp();
    let d0 = f64::from(0.03f32).powi(2) + f64::from(0.04f32).powi(2);
    assert!((phi[0] - expect(d0)).abs() < 1e-12);
    assert_eq!(phi[1], 1.0);
    let far = 2.0 * f64::from(0.1f32).powi(2);
    assert!((phi[2] - expect(far)).abs() < 1e-12);
    assert_eq!(phi[4], 1.0);
    assert!(FeatureMap::reacher_smooth(&layout(), 0.0).is_err());
    assert!(FeatureMap::reacher_smooth(&layout(), f64::NAN).is_err());
}

#[test]
fn label_features_agree_with_the_environment_labelling_function() {
    // Scripted fingertip placements around every ball (inside, near and outside the touch
    // radius) with a cancel event early in the episode.
    let config = ReacherConfig {
        cancel: Some(CancelConfig {
            probability: 1.0,
            earliest_step: 1,
            latest_step: 3,
        }),
        ..ReacherConfig::default()
    };
    let mut env = ReacherDelivery::new(shipped_config(config)).unwrap();
    let f = FeatureMap::reacher_labels(&layout());
    let mut obs = vec![0.0f32; obs_dim()];
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let (mut touches, mut cancels, mut steps) = (0, 0, 0);
    for episode in 0..40u64 {
        env.reset(episode, &mut obs);
        let ball = layout().positions()[episode as usize % 4];
        for _ in 0..6 {
            let (r, a) = (rng.gen_range(0.0..0.03), rng.gen_range(0.0..6.3f64));
            let angles = inverse_kinematics(ball[0] + r * a.cos(), ball[1] + r * a.sin());
            env.set_arm(angles, [0.0, 0.0]).unwrap();
            let step = env.step(&[0.0, 0.0], &mut obs).unwrap();
            assert_eq!(f.labels_of(&obs), step.labels, "episode {episode}");
            touches += usize::from(step.labels.0 & 0xf != 0);
            cancels += usize::from(step.labels.contains(layout().event_bit(0)));
            steps += 1;
        }
    }
    assert!(
        touches > 20 && touches < steps,
        "{touches} touches in {steps}"
    );
    assert_eq!(cancels, 40, "one cancel step per episode");
}

/// Elbow-down inverse kinematics of the 0.1 + 0.11 m arm.
fn inverse_kinematics(x: f64, y: f64) -> [f64; 2] {
    let (l1, l2) = (0.1, 0.11);
    let c = (x * x + y * y - l1 * l1 - l2 * l2) / (2.0 * l1 * l2);
    let q1 = c.clamp(-1.0, 1.0).acos();
    let q0 = y.atan2(x) - (l2 * q1.sin()).atan2(l1 + l2 * q1.cos());
    [q0, q1]
}

/// A hand-built batch over 2 RM states with known feature counts.
struct Batch {
    obs: Vec<f32>,
    rm: Vec<u32>,
    lengths: Vec<usize>,
}

impl Batch {
    fn new(trajs: Vec<Vec<(Vec<f32>, u32)>>) -> Batch {
        let lengths = trajs.iter().map(|t| t.len()).collect();
        let mut obs = Vec::new();
        let mut rm = Vec::new();
        for (o, u) in trajs.into_iter().flatten() {
            obs.extend(o);
            rm.push(u);
        }
        Batch { obs, rm, lengths }
    }

    fn view(&self) -> AnnotatedTrajectories<'_> {
        AnnotatedTrajectories {
            obs: &self.obs,
            rm_state: &self.rm,
            lengths: &self.lengths,
        }
    }
}

fn expert_batch() -> Batch {
    // Two expert trajectories: touch red in u0, then blue in u1.
    Batch::new(vec![
        vec![
            (nothing(), 0),
            (touching(0, false), 0),
            (nothing(), 1),
            (touching(2, false), 1),
        ],
        vec![
            (touching(0, false), 0),
            (touching(0, false), 1),
            (touching(2, true), 1),
        ],
    ])
}

fn agent_batch() -> Batch {
    // Three agent trajectories: blue in u0 (wrong order), red, and a cancel.
    Batch::new(vec![
        vec![(touching(2, false), 0), (touching(2, false), 0)],
        vec![(touching(0, false), 0), (nothing(), 1), (nothing(), 1)],
        vec![(nothing(), 0), (obs_with([FAR; 4], true), 0)],
    ])
}

#[test]
fn maxent_gradient_is_expert_minus_agent_feature_expectation() {
    let f = FeatureMap::reacher_labels(&layout());
    let (e, a) = (expert_batch(), agent_batch());
    let mu_d = feature_expectations(&f, 2, &e.view()).unwrap();
    // Expert, per trajectory then averaged over the 2 trajectories:
    // u0: red 1 + red 1 = 2 → 1.0; u1: red 1, blue 1 + 1, cancel 1 → (0.5, 0, 1.0, 0, 0.5).
    let expected_d = [
        1.0, 0.0, 0.0, 0.0, 0.0, //
        0.5, 0.0, 1.0, 0.0, 0.5,
    ];
    assert_eq!(mu_d, expected_d);
    let mu_pi = feature_expectations(&f, 2, &a.view()).unwrap();
    // Agent over 3 trajectories: u0: blue 2, red 1, cancel 1; u1: nothing.
    let third = 1.0 / 3.0;
    let expected_pi = [third, 0.0, 2.0 * third, 0.0, third, 0.0, 0.0, 0.0, 0.0, 0.0];
    for (x, y) in mu_pi.iter().zip(&expected_pi) {
        assert!((x - y).abs() < 1e-15);
    }
    let g = maxent_gradient(&f, 2, &e.view(), &a.view()).unwrap();
    for k in 0..10 {
        assert!(
            (g[k] - (expected_d[k] - expected_pi[k])).abs() < 1e-15,
            "{k}"
        );
    }
    // The linear model's weighted backward pass with the SMIRL coefficients is −gradient.
    let mut model = LinearRmReward::new(f, 2, RewardOptimConfig::sgd(0.1)).unwrap();
    let (ca, ce) = maxent_coefficients(&e.view(), &a.view());
    assert_eq!((ca.len(), ce.len()), (7, 7));
    let obs: Vec<f32> = a.obs.iter().chain(&e.obs).copied().collect();
    let rm: Vec<u32> = a.rm.iter().chain(&e.rm).copied().collect();
    let coeffs: Vec<f64> = ca.iter().chain(&ce).copied().collect();
    model.backward(&obs, &rm, &coeffs).unwrap();
    for (m, g) in model.grad().iter().zip(&g) {
        assert!((f64::from(*m) + g).abs() < 1e-6);
    }
    // One plain gradient step moves the weights by lr · (μ_D − μ_π).
    model.step();
    for (w, g) in model.params().iter().zip(&g) {
        assert!((f64::from(*w) - 0.1 * g).abs() < 1e-6);
    }
    // And the IRL loop's step (coefficients, backward, optimiser step) is the same step.
    let mut m2 = LinearRmReward::new(
        FeatureMap::reacher_labels(&layout()),
        2,
        RewardOptimConfig::sgd(0.1),
    )
    .unwrap();
    maxent_step(&mut m2, &e.view(), &a.view()).unwrap();
    assert_eq!(m2.params(), model.params());
}

#[test]
fn log_likelihood_surrogate_has_the_maxent_gradient() {
    // Smooth features so every weight matters; random weights, L2 on.
    let f = FeatureMap::reacher_smooth(&layout(), 0.05).unwrap();
    let (e, a) = (expert_batch(), agent_batch());
    let mut rng = ChaCha8Rng::seed_from_u64(4);
    let w: Vec<f64> = (0..10).map(|_| rng.gen_range(-1.0..1.0)).collect();
    let l2 = 0.3;
    let g = maxent_gradient(&f, 2, &e.view(), &a.view()).unwrap();
    let ll = |w: &[f64]| log_likelihood_surrogate(&f, 2, w, l2, &e.view(), &a.view()).unwrap();
    for k in 0..10 {
        let eps = 1e-6;
        let (mut up, mut down) = (w.clone(), w.clone());
        up[k] += eps;
        down[k] -= eps;
        let fd = (ll(&up) - ll(&down)) / (2.0 * eps);
        let analytic = g[k] - l2 * w[k];
        assert!(
            (fd - analytic).abs() < 1e-8,
            "weight {k}: fd {fd} vs {analytic}"
        );
    }
    assert!(log_likelihood_surrogate(&f, 2, &w[..9], l2, &e.view(), &a.view()).is_err());
}

#[test]
fn linear_reward_is_w_u_dot_phi_and_its_gradient_checks() {
    let f = FeatureMap::reacher_smooth(&layout(), 0.05).unwrap();
    let mut model = LinearRmReward::new(f.clone(), 3, RewardOptimConfig::adam(0.01)).unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(8);
    let w: Vec<f32> = (0..15).map(|_| rng.gen_range(-1.0..1.0)).collect();
    model.set_params(&w).unwrap();
    let rows: Vec<Vec<f32>> = vec![touching(0, false), touching(3, true), nothing()];
    let obs: Vec<f32> = rows.concat();
    let rm = [2u32, 0, 1];
    let mut r = [0.0f32; 3];
    model.reward_batch(&obs, &rm, &mut r).unwrap();
    let mut phi = vec![0.0; 5];
    for i in 0..3 {
        f.features(&rows[i], &mut phi);
        let u = rm[i] as usize;
        let expect: f64 = (0..5).map(|k| f64::from(w[u * 5 + k]) * phi[k]).sum();
        assert!((f64::from(r[i]) - expect).abs() < 1e-6);
    }
    // Finite differences of L = Σ c_i r_i with respect to each weight.
    let c = [0.7, -1.3, 0.4];
    model.backward(&obs, &rm, &c).unwrap();
    let grad = model.grad();
    let loss = |m: &mut LinearRmReward, p: &[f32]| -> f64 {
        m.set_params(p).unwrap();
        let mut r = [0.0f32; 3];
        m.reward_batch(&obs, &rm, &mut r).unwrap();
        r.iter().zip(&c).map(|(r, c)| f64::from(*r) * c).sum()
    };
    for k in 0..15 {
        let eps = 1e-2;
        let (mut up, mut down) = (w.clone(), w.clone());
        up[k] += eps;
        down[k] -= eps;
        let fd = (loss(&mut model, &up) - loss(&mut model, &down)) / (2.0 * f64::from(eps));
        assert!((fd - f64::from(grad[k])).abs() < 1e-4, "weight {k}");
    }
    // Bad input.
    assert!(matches!(
        model.reward_batch(&obs, &[0, 1, 3], &mut r).unwrap_err(),
        RewardError::RmStateOutOfRange { state: 3, .. }
    ));
    assert!(matches!(
        model.reward_batch(&obs, &[0, 1], &mut r).unwrap_err(),
        RewardError::Length { .. }
    ));
    assert!(matches!(
        model
            .backward(&obs, &rm, &[0.0, f64::NAN, 0.0])
            .unwrap_err(),
        RewardError::NonFiniteCoefficient { index: 1, .. }
    ));
    assert!(LinearRmReward::new(f, 0, RewardOptimConfig::sgd(0.1)).is_err());
}

#[test]
fn linear_reward_saves_and_loads() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("reward.json");
    let mut model = LinearRmReward::new(
        FeatureMap::reacher_smooth(&layout(), 0.04).unwrap(),
        2,
        RewardOptimConfig::sgd(0.1),
    )
    .unwrap();
    let w: Vec<f32> = (0..10).map(|i| i as f32 * 0.25 - 1.0).collect();
    model.set_params(&w).unwrap();
    model.save(&path).unwrap();
    let back = LinearRmReward::load(&path, RewardOptimConfig::sgd(0.1)).unwrap();
    assert_eq!(back.params(), w);
    assert_eq!(back.features(), model.features());
    assert_eq!(back.weights(1), &w[5..]);
    std::fs::write(&path, "{\"format\": \"other\"}").unwrap();
    let err = LinearRmReward::load(&path, RewardOptimConfig::sgd(0.1))
        .err()
        .unwrap()
        .to_string();
    assert!(err.contains("reward.json"), "{err}");
    let missing = dir.path().join("missing.json");
    let err = LinearRmReward::load(&missing, RewardOptimConfig::sgd(0.1))
        .err()
        .unwrap()
        .to_string();
    assert!(err.contains("missing.json"), "{err}");
}
