//! SMIRL's MaxEnt loop on a problem with a closed-form soft-optimal agent: in each of two
//! RM states the agent places the Reacher fingertip on a grid point s with probability
//! ∝ exp(w_uᵀ φ(s)). The expert touches red in u0 and blue in u1. For both feature maps the
//! learned per-state weights must send the agent to the right ball in each RM state.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use smirl::irl::reward::{RewardModel, RewardOptimConfig};
use smirl::irl::smirl::*;

#[allow(unused_imports)]
use shipped_layout::{layout, obs_dim, shipped_config};
mod shipped_layout;

mod smirl_reference;

/// A Reacher observation row with the fingertip at `tip` (only what the features read).
fn obs_at(tip: [f32; 2]) -> Vec<f32> {
    let mut o = vec![0.0f32; obs_dim()];
    o[6] = tip[0];
    o[7] = tip[1];
    for (k, b) in layout().positions().iter().enumerate() {
        o[8 + 2 * k] = tip[0] - b[0] as f32;
        o[9 + 2 * k] = tip[1] - b[1] as f32;
    }
    o
}

fn grid_obs() -> Vec<f32> {
    let mut g = Vec::new();
    for i in 0..43 {
        for j in 0..43 {
            g.extend(obs_at([-0.21 + 0.01 * i as f32, -0.21 + 0.01 * j as f32]));
        }
    }
    g
}

/// Agent's distribution over the grid in RM state u: softmax of the reward.
fn policy(model: &mut LinearRmReward, grid: &[f32], u: u32) -> Vec<f64> {
    let n = grid.len() / obs_dim();
    let mut r = vec![0.0f32; n];
    model.reward_batch(grid, &vec![u; n], &mut r).unwrap();
    let m = r.iter().fold(f32::MIN, |a, &b| a.max(b));
    let w: Vec<f64> = r.iter().map(|&x| f64::from(x - m).exp()).collect();
    let z: f64 = w.iter().sum();
    w.into_iter().map(|x| x / z).collect()
}

fn draw(p: &[f64], rng: &mut ChaCha8Rng) -> usize {
    let mut x = rng.gen_range(0.0..1.0);
    for (i, &pi) in p.iter().enumerate() {
        if x < pi {
            return i;
        }
        x -= pi;
    }
    p.len() - 1
}

/// Mass the policy puts where ball `k` is touched.
fn touch_mass(p: &[f64], grid: &[f32], k: usize) -> f64 {
    let f = FeatureMap::reacher_labels(&layout());
    p.iter()
        .zip(grid.chunks(obs_dim()))
        .filter(|(_, o)| f.labels_of(o).contains(k))
        .map(|(p, _)| p)
        .sum()
}

fn run(features: FeatureMap) -> [f64; 2] {
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let grid = grid_obs();
    // Expert trajectories: (touch red, u0), (touch blue, u1).
    let (red, blue) = (layout().positions()[0], layout().positions()[2]);
    let mut e_obs = Vec::new();
    let mut e_rm = Vec::new();
    for _ in 0..16 {
        for (ball, u) in [(red, 0u32), (blue, 1)] {
            let (dx, dy) = (rng.gen_range(-0.01..0.01), rng.gen_range(-0.01..0.01));
            e_obs.extend(obs_at([(ball[0] + dx) as f32, (ball[1] + dy) as f32]));
            e_rm.push(u);
        }
    }
    let e_len = vec![2usize; 16];
    let mut model = LinearRmReward::new(features, 2, RewardOptimConfig::adam(0.1)).unwrap();
    let n = 200;
    for _ in 0..500 {
        let p: Vec<Vec<f64>> = (0..2).map(|u| policy(&mut model, &grid, u)).collect();
        let mut a_obs = Vec::new();
        let mut a_rm = Vec::new();
        for _ in 0..n {
            for u in 0..2u32 {
                let s = draw(&p[u as usize], &mut rng);
                a_obs.extend_from_slice(&grid[s * obs_dim()..(s + 1) * obs_dim()]);
                a_rm.push(u);
            }
        }
        let a_len = vec![2usize; n];
        let expert = AnnotatedTrajectories {
            obs: &e_obs,
            rm_state: &e_rm,
            lengths: &e_len,
        };
        let agent = AnnotatedTrajectories {
            obs: &a_obs,
            rm_state: &a_rm,
            lengths: &a_len,
        };
        smirl_reference::maxent_step(&mut model, &expert, &agent).unwrap();
    }
    [
        touch_mass(&policy(&mut model, &grid, 0), &grid, 0),
        touch_mass(&policy(&mut model, &grid, 1), &grid, 2),
    ]
}

#[test]
fn smirl_learns_which_ball_to_touch_in_each_rm_state() {
    let grid = grid_obs();
    let n = grid.len() / obs_dim();
    let uniform = vec![1.0 / n as f64; n];
    let start = touch_mass(&uniform, &grid, 0);
    assert!(start < 0.01, "{start}");
    for features in [
        FeatureMap::reacher_labels(&layout()),
        FeatureMap::reacher_smooth(&layout(), 0.05).unwrap(),
    ] {
        let kind = features.kind;
        let [red_in_u0, blue_in_u1] = run(features);
        eprintln!(
            "{kind:?}: P(touch red | u0) = {red_in_u0:.3}, P(touch blue | u1) = {blue_in_u1:.3}"
        );
        assert!(red_in_u0 > 0.5, "{kind:?}: {red_in_u0}");
        assert!(blue_in_u1 > 0.5, "{kind:?}: {blue_in_u1}");
    }
}
