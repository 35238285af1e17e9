//! The whole per-iteration chain (agent samples → KDE → coefficients → reward update) on a
//! one-step problem whose soft-optimal policy is known in closed form: the agent picks a
//! position s on a grid with probability ∝ exp(r_θ(s)) (the soft-optimal policy of a
//! one-step MDP, α = 1), so ρ_θ is exact and the f-IRL theorem applies with T = 1. The
//! learned reward must move the agent's state marginal onto the expert's.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use smirl::irl::firl::{Divergence, FirlSurrogate, MaxEntCoefficients, DEFAULT_DENSITY_EPS};
use smirl::irl::kde::Kde;
use smirl::irl::reward::{MlpReward, MlpRewardConfig, RewardModel};

const EXPERT_CENTRE: [f32; 2] = [0.1, 0.1];

fn grid() -> Vec<f32> {
    let mut g = Vec::new();
    for i in 0..21 {
        for j in 0..21 {
            g.push(-0.2 + 0.02 * i as f32);
            g.push(-0.2 + 0.02 * j as f32);
        }
    }
    g
}

/// Agent state marginal over the grid: softmax of the reward.
fn policy(model: &mut MlpReward, grid: &[f32]) -> Vec<f64> {
    let mut r = vec![0.0f32; grid.len() / 2];
    model.reward_batch(grid, &[], &mut r).unwrap();
    let m = r.iter().fold(f32::MIN, |a, &b| a.max(b));
    let w: Vec<f64> = r.iter().map(|&x| f64::from(x - m).exp()).collect();
    let z: f64 = w.iter().sum();
    w.into_iter().map(|x| x / z).collect()
}

fn sample(p: &[f64], grid: &[f32], n: usize, rng: &mut ChaCha8Rng) -> Vec<f32> {
    let mut out = Vec::with_capacity(2 * n);
    for _ in 0..n {
        let mut x = rng.gen_range(0.0..1.0);
        let mut k = p.len() - 1;
        for (i, &pi) in p.iter().enumerate() {
            if x < pi {
                k = i;
                break;
            }
            x -= pi;
        }
        out.extend_from_slice(&grid[2 * k..2 * k + 2]);
    }
    out
}

/// Probability mass the agent puts within 0.05 of the expert's centre.
fn mass_near_expert(p: &[f64], grid: &[f32]) -> f64 {
    p.iter()
        .zip(grid.chunks(2))
        .filter(|(_, s)| {
            let (dx, dy) = (s[0] - EXPERT_CENTRE[0], s[1] - EXPERT_CENTRE[1]);
            dx * dx + dy * dy < 0.05 * 0.05
        })
        .map(|(p, _)| p)
        .sum()
}

enum Algo {
    Firl(Divergence),
    MaxEnt,
}

fn run(algo: Algo) -> (f64, f64) {
    let mut rng = ChaCha8Rng::seed_from_u64(42);
    let grid = grid();
    let expert: Vec<f32> = (0..800)
        .flat_map(|_| {
            [
                EXPERT_CENTRE[0] + rng.gen_range(-0.03f32..0.03),
                EXPERT_CENTRE[1] + rng.gen_range(-0.03f32..0.03),
            ]
        })
        .collect();
    let h = 0.05;
    let kde_e = Kde::fit_columns(&expert, 2, &[0, 1], h).unwrap();
    let mut model = MlpReward::new(MlpRewardConfig::paper(vec![0, 1], 1e-2, 1), 2).unwrap();
    let before = mass_near_expert(&policy(&mut model, &grid), &grid);
    let n = 1000;
    for _ in 0..200 {
        let p = policy(&mut model, &grid);
        let agent = sample(&p, &grid, n, &mut rng);
        match algo {
            Algo::Firl(div) => {
                let kde_a = Kde::fit_columns(&agent, 2, &[0, 1], h).unwrap();
                let s = FirlSurrogate::from_kde(
                    div,
                    &kde_e,
                    &kde_a,
                    &agent,
                    2,
                    &[0, 1],
                    n,
                    1,
                    DEFAULT_DENSITY_EPS,
                )
                .unwrap();
                model.update(&agent, &[], &s.coefficients).unwrap();
            }
            Algo::MaxEnt => {
                let c = MaxEntCoefficients::new(n, 800, 1).unwrap();
                let obs: Vec<f32> = agent.iter().chain(&expert).copied().collect();
                let coeffs: Vec<f64> = std::iter::repeat_n(c.agent, n)
                    .chain(std::iter::repeat_n(c.expert, 800))
                    .collect();
                model.update(&obs, &[], &coeffs).unwrap();
            }
        }
    }
    let after = mass_near_expert(&policy(&mut model, &grid), &grid);
    eprintln!("mass within 0.05 of the expert centre: {before:.3} -> {after:.3}");
    (before, after)
}

#[test]
fn firl_moves_the_agent_marginal_onto_the_expert() {
    for div in Divergence::ALL {
        let (before, after) = run(Algo::Firl(div));
        assert!(before < 0.1, "{div}: {before}");
        assert!(
            after > 0.9,
            "{div}: mass near the expert {before:.3} -> {after:.3}"
        );
    }
}

#[test]
fn maxent_moves_the_agent_marginal_onto_the_expert() {
    let (before, after) = run(Algo::MaxEnt);
    assert!(before < 0.1, "{before}");
    assert!(
        after > 0.9,
        "mass near the expert {before:.3} -> {after:.3}"
    );
}
