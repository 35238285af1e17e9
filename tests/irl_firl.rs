//! f-IRL surrogate coefficients and continuous MaxEnt IRL coefficients against their formulas.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use smirl::irl::firl::*;
use smirl::irl::kde::Kde;

#[test]
fn h_is_f_minus_f_prime_u_up_to_a_constant() {
    // f' against a central difference of f, then h_exact = f − f'u and the constants the
    // surrogate drops: 0 (fkl), 1 (rkl), log 2 (js).
    let constants = [
        (Divergence::Fkl, 0.0),
        (Divergence::Rkl, 1.0),
        (Divergence::Js, std::f64::consts::LN_2),
    ];
    for (div, constant) in constants {
        for u in [0.01, 0.3, 1.0, 2.5, 40.0] {
            let e = 1e-6 * u;
            let numeric = (div.f(u + e) - div.f(u - e)) / (2.0 * e);
            assert!(
                (numeric - div.f_prime(u)).abs() < 1e-6 * div.f_prime(u).abs().max(1.0),
                "{div} f'({u})"
            );
            let h_exact = div.f(u) - div.f_prime(u) * u;
            assert!(
                (h_exact - div.h(u) - constant).abs() < 1e-9,
                "{div}: f({u}) − f'({u})·{u} − h({u}) = {}",
                h_exact - div.h(u)
            );
        }
        // f(1) = 0: every divergence is zero for identical marginals.
        assert!(div.f(1.0).abs() < 1e-15);
    }
    assert_eq!(Divergence::Fkl.h(3.0), -3.0);
    assert_eq!(Divergence::Rkl.h(std::f64::consts::E), -1.0);
    assert!((Divergence::Js.h(1.0) + std::f64::consts::LN_2).abs() < 1e-15);
}

fn synthetic_batch(seed: u64, n: usize, t: usize) -> (Vec<f64>, Vec<f64>) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let ratios = (0..n * t).map(|_| rng.gen_range(0.05..5.0)).collect();
    let rewards = (0..n * t).map(|_| rng.gen_range(-2.0..2.0)).collect();
    (ratios, rewards)
}

#[test]
fn firl_coefficients_match_the_covariance_formula() {
    let (n, t) = (5, 4);
    let (u, rewards) = synthetic_batch(11, n, t);
    for div in Divergence::ALL {
        let s = FirlSurrogate::new(div, &u, n, t).unwrap();
        // A_i by hand, with the h of the paper's table.
        let h = |x: f64| match div {
            Divergence::Fkl => -x,
            Divergence::Rkl => -x.ln(),
            Divergence::Js => -(1.0 + x).ln(),
        };
        let a: Vec<f64> = (0..n)
            .map(|i| (0..t).map(|k| h(u[i * t + k])).sum())
            .collect();
        for (x, y) in a.iter().zip(&s.advantages) {
            assert!((x - y).abs() < 1e-12);
        }
        let a_mean = a.iter().sum::<f64>() / n as f64;
        for (i, a_i) in a.iter().enumerate() {
            let c = (a_i - a_mean) / (n * t) as f64;
            for k in 0..t {
                assert!((s.coefficients[i * t + k] - c).abs() < 1e-14);
            }
        }
        // The loss is the population covariance of (A_i, B_i) over T.
        let b: Vec<f64> = (0..n)
            .map(|i| rewards[i * t..(i + 1) * t].iter().sum())
            .collect();
        let mean_ab = a.iter().zip(&b).map(|(x, y)| x * y).sum::<f64>() / n as f64;
        let mean_b = b.iter().sum::<f64>() / n as f64;
        let cov = mean_ab - a_mean * mean_b;
        let loss = s.loss(&rewards).unwrap();
        assert!((loss - cov / t as f64).abs() < 1e-12, "{div}");
        // Finite differences of the loss with respect to each reward give the coefficients.
        for j in 0..n * t {
            let e = 1e-5;
            let (mut up, mut down) = (rewards.clone(), rewards.clone());
            up[j] += e;
            down[j] -= e;
            let fd = (s.loss(&up).unwrap() - s.loss(&down).unwrap()) / (2.0 * e);
            assert!(
                (fd - s.coefficients[j]).abs() < 1e-8,
                "{div} state {j}: fd {fd} vs {}",
                s.coefficients[j]
            );
        }
        // Coefficients sum to zero: adding a constant to the reward changes nothing.
        assert!(s.coefficients.iter().sum::<f64>().abs() < 1e-12);
    }
}

#[test]
fn firl_raises_the_reward_where_the_expert_is() {
    // Expert at the origin; agent trajectories half at the origin, half far away. Descent on
    // the surrogate must raise the reward along the near trajectories (negative coefficient)
    // and lower it along the far ones, for every divergence.
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    let h = 0.02;
    let expert: Vec<f32> = (0..400).map(|_| rng.gen_range(-0.01..0.01)).collect();
    let (n, t) = (6, 10);
    let mut agent = Vec::new();
    for i in 0..n {
        let centre = if i % 2 == 0 { 0.0 } else { 0.1 };
        for _ in 0..t {
            agent.push(centre + rng.gen_range(-0.01f32..0.01));
            agent.push(centre + rng.gen_range(-0.01f32..0.01));
        }
    }
    let kde_e = Kde::fit_columns(&expert, 2, &[0, 1], h).unwrap();
    let kde_a = Kde::fit_columns(&agent, 2, &[0, 1], h).unwrap();
    for div in Divergence::ALL {
        let s = FirlSurrogate::from_kde(
            div,
            &kde_e,
            &kde_a,
            &agent,
            2,
            &[0, 1],
            n,
            t,
            DEFAULT_DENSITY_EPS,
        )
        .unwrap();
        for i in 0..n {
            let c = s.coefficients[i * t];
            assert!(c.is_finite());
            if i % 2 == 0 {
                assert!(c < 0.0, "{div}: near trajectory {i} has coefficient {c}");
            } else {
                assert!(c > 0.0, "{div}: far trajectory {i} has coefficient {c}");
            }
        }
    }
}

#[test]
fn density_ratio_guard_keeps_ratios_finite() {
    let u = density_ratio(&[0.0, 2.0, 0.0], &[4.0, 1.0, 0.0], 1e-8).unwrap();
    assert!(u[0] > 0.0 && u[0] < 1e-8);
    assert!((u[1] - 2.0).abs() < 1e-7);
    assert_eq!(u[2], 1.0, "no density on either side: ratio 1");
    // Zero expert density is still a finite −log u for rkl.
    assert!(Divergence::Rkl.h(u[0]).is_finite());
    assert_eq!(
        density_ratio(&[1.0], &[1.0], 0.0).unwrap_err(),
        SurrogateError::BadEpsilon(0.0)
    );
    assert!(matches!(
        density_ratio(&[1.0, 1.0], &[1.0], 1e-8).unwrap_err(),
        SurrogateError::Length { .. }
    ));
    assert!(matches!(
        density_ratio(&[f64::NAN], &[1.0], 1e-8).unwrap_err(),
        SurrogateError::BadRatio { index: 0, .. }
    ));
}

#[test]
fn firl_refuses_inconsistent_batches() {
    assert!(matches!(
        FirlSurrogate::new(Divergence::Fkl, &[1.0; 7], 2, 4).unwrap_err(),
        SurrogateError::Shape { len: 7, .. }
    ));
    assert_eq!(
        FirlSurrogate::new(Divergence::Fkl, &[], 0, 4).unwrap_err(),
        SurrogateError::Empty
    );
    assert!(matches!(
        FirlSurrogate::new(Divergence::Rkl, &[1.0, 0.0], 1, 2).unwrap_err(),
        SurrogateError::BadRatio { index: 1, .. }
    ));
    let s = FirlSurrogate::new(Divergence::Js, &[1.0; 4], 2, 2).unwrap();
    assert!(s.loss(&[0.0; 3]).is_err());
    assert_eq!("rkl".parse::<Divergence>().unwrap(), Divergence::Rkl);
    let err = "kl".parse::<Divergence>().unwrap_err().to_string();
    assert!(err.contains("\"kl\"") && err.contains("fkl"), "{err}");
}

#[test]
fn maxent_coefficients_are_the_loss_gradient() {
    let mut rng = ChaCha8Rng::seed_from_u64(9);
    let t = 30;
    let agent: Vec<f64> = (0..90).map(|_| rng.gen_range(-1.0..1.0)).collect();
    let expert: Vec<f64> = (0..60).map(|_| rng.gen_range(-1.0..1.0)).collect();
    let c = MaxEntCoefficients::new(agent.len(), expert.len(), t).unwrap();
    assert_eq!(c.agent, 30.0 / 90.0);
    assert_eq!(c.expert, -30.0 / 60.0);
    let loss = |a: &[f64], e: &[f64]| MaxEntCoefficients::loss(a, e, t);
    let eps = 1e-6;
    for j in [0, 17, 89] {
        let (mut up, mut down) = (agent.clone(), agent.clone());
        up[j] += eps;
        down[j] -= eps;
        let fd = (loss(&up, &expert) - loss(&down, &expert)) / (2.0 * eps);
        assert!((fd - c.agent).abs() < 1e-7);
    }
    for j in [0, 59] {
        let (mut up, mut down) = (expert.clone(), expert.clone());
        up[j] += eps;
        down[j] -= eps;
        let fd = (loss(&agent, &up) - loss(&agent, &down)) / (2.0 * eps);
        assert!((fd - c.expert).abs() < 1e-7);
    }
    // Identical agent and expert rewards: zero loss.
    assert_eq!(MaxEntCoefficients::loss(&[0.5; 4], &[0.5; 2], t), 0.0);
    assert!(MaxEntCoefficients::new(0, 5, t).is_err());
}
