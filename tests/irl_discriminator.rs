//! The f-IRL density-ratio discriminator: its logit against the closed-form log ratio of two
//! Gaussians, determinism, and bad input.

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use smirl::irl::discriminator::{
    Discriminator, DiscriminatorConfig, DiscriminatorError, LOGIT_CLAMP,
};

/// Rows of width 3 whose columns 0 and 2 are N(mean, σ²) and column 1 is noise the
/// discriminator must not read.
fn gaussian_rows(mean: [f32; 2], sigma: f32, n: usize, seed: u64) -> Vec<f32> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let normal = Normal::new(0.0f32, sigma).unwrap();
    let mut rows = Vec::with_capacity(3 * n);
    for _ in 0..n {
        rows.push(mean[0] + normal.sample(&mut rng));
        rows.push(1e3 * normal.sample(&mut rng));
        rows.push(mean[1] + normal.sample(&mut rng));
    }
    rows
}

fn config(steps: usize) -> DiscriminatorConfig {
    DiscriminatorConfig {
        steps,
        lr: 3e-3,
        ..DiscriminatorConfig::firl()
    }
}

/// Expert N((0.1, 0), σ²I), agent N((−0.1, 0), σ²I): log ρ_E/ρ_θ = (|x − μ_A|² − |x − μ_E|²)/2σ²
/// = 0.2 x / σ² (linear in x, 0 on the y axis).
#[test]
fn logit_approaches_the_gaussian_log_ratio() {
    let sigma = 0.1f32;
    let expert = gaussian_rows([0.1, 0.0], sigma, 4000, 1);
    let agent = gaussian_rows([-0.1, 0.0], sigma, 4000, 2);
    let mut d = Discriminator::new(config(1500), &[0, 2], 7).unwrap();
    let loss = d.train(&expert, &agent, 3).unwrap();
    // The optimum's cross-entropy: E over both classes of −log σ(±z), here about 0.50.
    assert!(loss < 0.56, "final BCE {loss}");
    let points = [-0.1f32, -0.05, 0.0, 0.05, 0.1];
    let mut rows = Vec::new();
    for &x in &points {
        rows.extend([x, 0.0, 0.03]);
    }
    let z = d.log_ratio(&rows, 3).unwrap();
    for (&x, &z) in points.iter().zip(&z) {
        let exact = f64::from(0.2 * x / (sigma * sigma));
        assert!(
            (z - exact).abs() < 0.35,
            "at x = {x}: logit {z:.3}, exact log ratio {exact:.3}"
        );
    }
    // Far from both samples the logit is clamped, not unbounded.
    let far = d.log_ratio(&[5.0, 0.0, 0.0, -5.0, 0.0, 0.0], 3).unwrap();
    assert!(far[0] > 5.0 && far[0] <= f64::from(LOGIT_CLAMP), "{far:?}");
    assert!(
        far[1] < -5.0 && far[1] >= -f64::from(LOGIT_CLAMP),
        "{far:?}"
    );
}

#[test]
fn same_seed_same_logits() {
    let expert = gaussian_rows([0.05, 0.0], 0.05, 500, 3);
    let agent = gaussian_rows([-0.05, 0.0], 0.05, 500, 4);
    let run = |seed| {
        let mut d = Discriminator::new(config(20), &[0, 2], seed).unwrap();
        d.train(&expert, &agent, 3).unwrap();
        d.log_ratio(&agent, 3).unwrap()
    };
    assert_eq!(run(5), run(5));
    assert_ne!(run(5), run(6));
}

#[test]
fn bad_input_is_an_error() {
    assert!(matches!(
        Discriminator::new(config(1), &[], 0),
        Err(DiscriminatorError::Config(_))
    ));
    assert!(matches!(
        Discriminator::new(
            DiscriminatorConfig {
                lr: f32::NAN,
                ..config(1)
            },
            &[0],
            0
        ),
        Err(DiscriminatorError::Config(_))
    ));
    let mut d = Discriminator::new(config(1), &[0, 2], 0).unwrap();
    let rows = gaussian_rows([0.0, 0.0], 0.1, 10, 0);
    assert!(matches!(
        d.train(&rows[..4], &rows, 3),
        Err(DiscriminatorError::Shape { .. })
    ));
    assert!(matches!(
        d.train(&[], &rows, 3),
        Err(DiscriminatorError::Empty { .. })
    ));
    assert!(matches!(
        d.train(&rows, &rows, 2),
        Err(DiscriminatorError::Column { column: 2, .. })
    ));
    assert!(matches!(
        d.log_ratio(&rows[..5], 3),
        Err(DiscriminatorError::Shape { .. })
    ));
}
