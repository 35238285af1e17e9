//! The MLP reward model: finite-difference gradient check of the weighted backward pass,
//! the output clamp, chunking, optimiser steps, persistence, bad input.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use smirl::irl::reward::*;

#[allow(unused_imports)]
use shipped_layout::{layout, obs_dim, shipped_config};
mod shipped_layout;

const OBS: usize = 17;

fn random_obs(rng: &mut ChaCha8Rng, n: usize) -> Vec<f32> {
    (0..n * OBS).map(|_| rng.gen_range(-1.0..1.0)).collect()
}

/// L = Σ c_i r(o_i), accumulated in f64.
fn weighted_sum(model: &mut MlpReward, obs: &[f32], c: &[f64]) -> f64 {
    let mut r = vec![0.0f32; c.len()];
    model.reward_batch(obs, &[], &mut r).unwrap();
    r.iter().zip(c).map(|(r, c)| f64::from(*r) * c).sum()
}

#[test]
fn mlp_backward_matches_finite_differences() {
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    let config = MlpRewardConfig::paper(vec![6, 7, 0, 16], 1e-3, 3);
    let mut model = MlpReward::new(config, OBS).unwrap();
    assert_eq!(model.num_params(), 4 * 64 + 64 + 64 * 64 + 64 + 64 + 1);
    let n = 40;
    let obs = random_obs(&mut rng, n);
    let c: Vec<f64> = (0..n).map(|_| rng.gen_range(-1.0..1.0)).collect();
    model.backward(&obs, &[], &c).unwrap();
    let grad = model.grad();
    let params = model.params();
    // Central differences on a spread of parameters in every layer (f32 network: eps 1e-3
    // relative to the parameter scale, checked against a tolerance that scales with |g|).
    let idx: Vec<usize> = (0..params.len())
        .step_by(97)
        .chain([params.len() - 1])
        .collect();
    let mut checked = 0;
    for &k in &idx {
        let eps = 1e-3f32;
        let mut p = params.clone();
        p[k] += eps;
        model.set_params(&p).unwrap();
        let up = weighted_sum(&mut model, &obs, &c);
        p[k] -= 2.0 * eps;
        model.set_params(&p).unwrap();
        let down = weighted_sum(&mut model, &obs, &c);
        let fd = (up - down) / (2.0 * f64::from(eps));
        let g = f64::from(grad[k]);
        assert!(
            (fd - g).abs() <= 5e-4 + 2e-2 * g.abs(),
            "parameter {k}: fd {fd} vs backward {g}"
        );
        checked += usize::from(g.abs() > 1e-3);
    }
    assert!(
        checked > idx.len() / 3,
        "too few non-trivial gradients checked"
    );
    model.set_params(&params).unwrap();
}

#[test]
fn output_is_clamped_and_clamped_states_give_no_gradient() {
    let mut rng = ChaCha8Rng::seed_from_u64(2);
    let mut config = MlpRewardConfig::paper((0..OBS).collect(), 1e-3, 4);
    config.clamp = 0.05;
    let mut model = MlpReward::new(config, OBS).unwrap();
    let n = 200;
    let obs: Vec<f32> = random_obs(&mut rng, n).iter().map(|x| x * 20.0).collect();
    let mut r = vec![0.0f32; n];
    model.reward_batch(&obs, &[], &mut r).unwrap();
    assert!(r.iter().all(|r| r.abs() <= 0.05));
    let clamped: Vec<bool> = r.iter().map(|r| r.abs() == 0.05).collect();
    let n_clamped = clamped.iter().filter(|&&c| c).count();
    assert!(n_clamped > 10 && n_clamped < n, "{n_clamped} clamped");
    // Coefficients only on clamped states: zero gradient.
    let c: Vec<f64> = clamped.iter().map(|&c| if c { 1.0 } else { 0.0 }).collect();
    model.backward(&obs, &[], &c).unwrap();
    assert!(model.grad().iter().all(|&g| g == 0.0));
    let c: Vec<f64> = clamped.iter().map(|&c| if c { 0.0 } else { 1.0 }).collect();
    model.backward(&obs, &[], &c).unwrap();
    assert!(model.grad().iter().any(|&g| g != 0.0));
}

#[test]
fn large_batches_are_chunked_without_changing_the_result() {
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    let mut model = MlpReward::new(MlpRewardConfig::paper(vec![6, 7], 1e-3, 7), OBS).unwrap();
    let n = 9000; // three chunks of at most 4096
    let obs = random_obs(&mut rng, n);
    let c: Vec<f64> = (0..n).map(|_| rng.gen_range(-1.0..1.0)).collect();
    let mut all = vec![0.0f32; n];
    model.reward_batch(&obs, &[], &mut all).unwrap();
    let mut one = [0.0f32];
    for i in [0, 4095, 4096, 8999] {
        model
            .reward_batch(&obs[i * OBS..(i + 1) * OBS], &[], &mut one)
            .unwrap();
        assert!((one[0] - all[i]).abs() < 1e-5, "row {i}");
    }
    model.backward(&obs, &[], &c).unwrap();
    let g_all = model.grad();
    let half = 4500;
    model.backward(&obs[..half * OBS], &[], &c[..half]).unwrap();
    let g1 = model.grad();
    model.backward(&obs[half * OBS..], &[], &c[half..]).unwrap();
    let g2 = model.grad();
    for k in 0..g_all.len() {
        let sum = g1[k] + g2[k];
        assert!(
            (g_all[k] - sum).abs() <= 1e-3 * (1.0 + sum.abs()),
            "parameter {k}: {} vs {}",
            g_all[k],
            sum
        );
    }
}

#[test]
fn descent_steps_lower_the_loss() {
    let mut rng = ChaCha8Rng::seed_from_u64(6);
    let n = 256;
    let obs = random_obs(&mut rng, n);
    let c: Vec<f64> = (0..n).map(|_| rng.gen_range(-1.0..1.0)).collect();
    for optim in [RewardOptimConfig::sgd(1e-2), RewardOptimConfig::adam(1e-3)] {
        let mut config = MlpRewardConfig::paper((0..OBS).collect(), 1e-3, 8);
        config.optim = optim;
        let mut model = MlpReward::new(config, OBS).unwrap();
        let before = weighted_sum(&mut model, &obs, &c);
        for _ in 0..5 {
            model.update(&obs, &[], &c).unwrap();
        }
        let after = weighted_sum(&mut model, &obs, &c);
        assert!(after < before - 1e-3, "{optim:?}: {before} -> {after}");
    }
    // L2 alone (zero coefficients) shrinks the parameters under plain gradient descent.
    let mut config = MlpRewardConfig::paper(vec![0, 1], 1e-3, 9);
    config.optim = RewardOptimConfig {
        adam: false,
        lr: 0.1,
        l2: 1.0,
    };
    let mut model = MlpReward::new(config, OBS).unwrap();
    let before: f32 = model.params().iter().map(|p| p * p).sum();
    model.update(&obs, &[], &vec![0.0; n]).unwrap();
    let after: f32 = model.params().iter().map(|p| p * p).sum();
    assert!(
        (after - 0.81 * before).abs() < 1e-3 * before,
        "{before} -> {after}"
    );
}

#[test]
fn same_seed_same_network_and_rewards() {
    let mut rng = ChaCha8Rng::seed_from_u64(10);
    let obs = random_obs(&mut rng, 50);
    let make = |seed| MlpReward::new(MlpRewardConfig::paper(vec![6, 7], 1e-3, seed), OBS).unwrap();
    let (mut a, mut b, mut c) = (make(1), make(1), make(2));
    let (mut ra, mut rb, mut rc) = (vec![0.0f32; 50], vec![0.0f32; 50], vec![0.0f32; 50]);
    a.reward_batch(&obs, &[], &mut ra).unwrap();
    b.reward_batch(&obs, &[], &mut rb).unwrap();
    c.reward_batch(&obs, &[], &mut rc).unwrap();
    assert_eq!(ra, rb);
    assert_ne!(ra, rc);
}

#[test]
fn mlp_reward_saves_loads_and_refuses_bad_input() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("reward.bin");
    let mut a = MlpReward::new(MlpRewardConfig::paper(vec![6, 7], 1e-3, 1), OBS).unwrap();
    a.save(&path).unwrap();
    let mut b = MlpReward::new(MlpRewardConfig::paper(vec![6, 7], 1e-3, 2), OBS).unwrap();
    b.load(&path).unwrap();
    assert_eq!(a.params(), b.params());
    // Another architecture is refused, naming the file.
    let mut c = MlpReward::new(MlpRewardConfig::paper(vec![6, 7, 8], 1e-3, 2), OBS).unwrap();
    let err = c.load(&path).unwrap_err().to_string();
    assert!(err.contains("reward.bin"), "{err}");

    assert!(matches!(
        MlpReward::new(MlpRewardConfig::paper(vec![17], 1e-3, 1), OBS).err(),
        Some(RewardError::ColumnOutOfRange { column: 17, .. })
    ));
    assert!(MlpReward::new(MlpRewardConfig::paper(vec![], 1e-3, 1), OBS).is_err());
    assert!(MlpReward::new(MlpRewardConfig::paper(vec![0], 0.0, 1), OBS).is_err());
    let mut r = vec![0.0f32; 2];
    assert!(matches!(
        a.reward_batch(&[0.0; 20], &[], &mut r).unwrap_err(),
        RewardError::ObsShape { .. }
    ));
    assert!(matches!(
        a.reward_batch(&[0.0; 34], &[0, 0, 0], &mut r).unwrap_err(),
        RewardError::Length {
            what: "rm_state",
            ..
        }
    ));
    assert!(a.set_params(&[0.0; 3]).is_err());
}

/// `set_lr` changes the step size of the following optimiser steps: a zero rate freezes the
/// parameters, restoring the rate moves them again.
#[test]
fn set_lr_changes_the_following_steps() {
    use smirl::irl::smirl::{FeatureMap, LinearRmReward};
    let mut model = LinearRmReward::new(
        FeatureMap::reacher_labels(&layout()),
        1,
        RewardOptimConfig::adam(0.1),
    )
    .unwrap();
    let obs = vec![0.0f32; model.obs_dim()];
    // Fingertip on ball 0 (zero offset): feature 0 is 1, so the gradient of w_0 is the coefficient.
    model.update(&obs, &[0], &[-1.0]).unwrap();
    let after_first = model.params();
    assert!(after_first[0] > 0.0);
    model.set_lr(0.0);
    model.update(&obs, &[0], &[-1.0]).unwrap();
    assert_eq!(model.params(), after_first);
    model.set_lr(0.1);
    model.update(&obs, &[0], &[-1.0]).unwrap();
    assert!(model.params()[0] > after_first[0]);
}
