//! The Gaussian expert density (f-IRL's reverse KL on demonstrations): its log-density against
//! the closed form, exact far from the data (where a plain sum of exponentials underflows),
//! and bad input.

use smirl::irl::gaussian_kde::GaussianKde;
use smirl::irl::kde::KdeError;

fn log_normal_2d(x: [f64; 2], mu: [f64; 2], sigma: f64) -> f64 {
    let d2 = (x[0] - mu[0]).powi(2) + (x[1] - mu[1]).powi(2);
    -d2 / (2.0 * sigma * sigma) - (2.0 * std::f64::consts::PI * sigma * sigma).ln()
}

#[test]
fn log_density_is_the_mixture_of_normals() {
    let pts = [0.1, 0.0, -0.05, 0.02, 0.0, 0.15];
    let sigma = 0.02;
    let kde = GaussianKde::fit(&pts, 2, sigma).unwrap();
    for x in [[0.1, 0.0], [0.03, 0.03], [-0.2, 0.1], [0.0, 0.14]] {
        let direct: f64 = pts
            .chunks_exact(2)
            .map(|p| log_normal_2d(x, [p[0], p[1]], sigma).exp())
            .sum::<f64>()
            / 3.0;
        let got = kde.log_density(&x);
        assert!(
            (got - direct.ln()).abs() < 1e-9,
            "{x:?}: {got} vs {}",
            direct.ln()
        );
    }
    // One point: exactly the normal's log-density, even 1 m away (exp would underflow there).
    let one = GaussianKde::fit(&[0.2, -0.1], 2, sigma).unwrap();
    for x in [[0.2, -0.1], [0.25, -0.1], [1.2, 0.9]] {
        let want = log_normal_2d(x, [0.2, -0.1], sigma);
        assert!((one.log_density(&x) - want).abs() < 1e-9 * want.abs().max(1.0));
    }
    assert!(one.log_density(&[1.2, 0.9]) < -2_000.0);
    assert!(one.log_density(&[1.2, 0.9]).is_finite());
}

#[test]
fn columns_of_observations_and_bad_input() {
    let obs: Vec<f32> = vec![9.0, 0.1, 0.0, 9.0, -0.05, 0.02];
    let kde = GaussianKde::fit_columns(&obs, 3, &[1, 2], 0.02).unwrap();
    let direct = GaussianKde::fit(
        &[0.1f32 as f64, 0.0, -0.05f32 as f64, 0.02f32 as f64],
        2,
        0.02,
    )
    .unwrap();
    let at = kde.log_density_columns(&obs, 3, &[1, 2]).unwrap();
    assert_eq!(at[0], direct.log_density(&[0.1f32 as f64, 0.0]));
    assert_eq!(
        GaussianKde::fit(&[0.0, 0.0], 2, 0.0),
        Err(KdeError::BadBandwidth(0.0))
    );
    assert_eq!(GaussianKde::fit(&[], 2, 0.1), Err(KdeError::NoPoints));
    assert_eq!(
        GaussianKde::fit(&[0.0, f64::NAN], 2, 0.1),
        Err(KdeError::NonFinitePoint { index: 0 })
    );
    assert!(kde.log_density_columns(&obs, 3, &[1, 5]).is_err());
    assert!(kde.log_density_columns(&obs, 3, &[1]).is_err());
}
