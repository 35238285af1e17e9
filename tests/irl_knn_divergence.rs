//! The kNN KL estimator against the closed form for Gaussians, against a brute-force search,
//! and its error paths.

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use smirl::irl::knn_divergence::{knn_kl, KnnError};

/// `n` samples of an isotropic 2-D Gaussian, row-major.
fn gaussian(n: usize, mean: [f64; 2], std: f64, seed: u64) -> Vec<f64> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let normal = Normal::new(0.0, std).unwrap();
    (0..n)
        .flat_map(|_| [mean[0], mean[1]])
        .map(|c| c + normal.sample(&mut rng))
        .collect()
}

/// KL(N(μ1, σ1² I) ‖ N(μ2, σ2² I)) in d dimensions.
fn closed_form(d: f64, mu1: [f64; 2], s1: f64, mu2: [f64; 2], s2: f64) -> f64 {
    let sq = (mu1[0] - mu2[0]).powi(2) + (mu1[1] - mu2[1]).powi(2);
    d * (s2 / s1).ln() + (d * s1 * s1 + sq) / (2.0 * s2 * s2) - d / 2.0
}

#[test]
fn matches_the_closed_form_for_two_gaussians() {
    // f-IRL's ReacherDraw sizes: 10 000 expert samples, 30 000 agent states.
    let (mu_e, s_e) = ([-0.21, 0.0], 0.05);
    let (mu_a, s_a) = ([-0.18, 0.02], 0.06);
    let expert = gaussian(10_000, mu_e, s_e, 1);
    let agent = gaussian(30_000, mu_a, s_a, 2);
    // The estimator is consistent but biased at finite n (low in the broader sample's tails): a
    // tenth of the value, while a wrong dimension factor or a missing log(m / (n − 1)) term
    // is off by more than the whole value.
    let forward = knn_kl(&expert, &agent, 2, 3).unwrap();
    let reverse = knn_kl(&agent, &expert, 2, 3).unwrap();
    let want_forward = closed_form(2.0, mu_e, s_e, mu_a, s_a);
    let want_reverse = closed_form(2.0, mu_a, s_a, mu_e, s_e);
    assert!(
        (forward - want_forward).abs() < 0.1 * want_forward,
        "forward {forward} vs {want_forward}"
    );
    assert!(
        (reverse - want_reverse).abs() < 0.1 * want_reverse,
        "reverse {reverse} vs {want_reverse}"
    );
}

#[test]
fn is_near_zero_for_two_samples_of_one_distribution() {
    let a = gaussian(5_000, [0.1, -0.1], 0.05, 3);
    let b = gaussian(5_000, [0.1, -0.1], 0.05, 4);
    let kl = knn_kl(&a, &b, 2, 3).unwrap();
    assert!(kl.abs() < 0.03, "{kl}");
}

/// The estimate computed by scanning every pair.
fn brute_force(p: &[f64], q: &[f64], k: usize) -> f64 {
    let cheb = |a: &[f64], b: &[f64]| (a[0] - b[0]).abs().max((a[1] - b[1]).abs());
    let kth = |x: &[f64], set: &[f64], skip: Option<usize>| {
        let mut d: Vec<f64> = set
            .chunks(2)
            .enumerate()
            .filter(|(j, _)| Some(*j) != skip)
            .map(|(_, y)| cheb(x, y))
            .collect();
        d.sort_by(|a, b| a.partial_cmp(b).unwrap());
        d[k - 1]
    };
    let (n, m) = (p.len() / 2, q.len() / 2);
    let sum: f64 = p
        .chunks(2)
        .enumerate()
        .map(|(i, x)| (kth(x, q, None) / kth(x, p, Some(i))).ln())
        .sum();
    2.0 / n as f64 * sum + (m as f64 / (n as f64 - 1.0)).ln()
}

#[test]
fn the_pruned_search_finds_the_same_neighbours_as_a_full_scan() {
    for (seed, k) in [(5, 1), (6, 3), (7, 5)] {
        let p = gaussian(300, [0.0, 0.0], 0.1, seed);
        let q = gaussian(200, [0.05, 0.0], 0.07, seed + 100);
        let fast = knn_kl(&p, &q, 2, k).unwrap();
        let slow = brute_force(&p, &q, k);
        assert!((fast - slow).abs() < 1e-12, "k={k}: {fast} vs {slow}");
    }
}

#[test]
fn bad_inputs_are_errors() {
    let p = gaussian(10, [0.0, 0.0], 0.1, 8);
    assert_eq!(knn_kl(&p, &p, 0, 3), Err(KnnError::ZeroDimension));
    assert_eq!(knn_kl(&p, &p, 2, 0), Err(KnnError::ZeroK));
    assert!(matches!(
        knn_kl(&p[..5], &p, 2, 3),
        Err(KnnError::Ragged { len: 5, .. })
    ));
    assert!(matches!(
        knn_kl(&p[..6], &p, 2, 3),
        Err(KnnError::TooFew {
            got: 3,
            need: 4,
            ..
        })
    ));
    let mut nan = p.clone();
    nan[3] = f64::NAN;
    assert!(matches!(
        knn_kl(&nan, &p, 2, 3),
        Err(KnnError::NotFinite { .. })
    ));
    // A demonstration that holds still: the same point five times.
    let mut held = p.clone();
    for i in 0..5 {
        held[2 * i] = 0.5;
        held[2 * i + 1] = 0.5;
    }
    let e = knn_kl(&held, &p, 2, 3).unwrap_err();
    assert!(matches!(e, KnnError::Repeated { k: 3, .. }), "{e}");
    assert!(e.to_string().contains("repeated samples"));
}
