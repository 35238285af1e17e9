//! Epanechnikov KDE: brute-force agreement, normalisation, compact support, bad input.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use smirl::irl::kde::*;

fn random_points(rng: &mut ChaCha8Rng, n: usize, dim: usize, spread: f64) -> Vec<f64> {
    // Half in a tight cluster (many points per cell), half spread out.
    (0..n * dim)
        .map(|i| {
            if (i / dim).is_multiple_of(2) {
                rng.gen_range(-0.03..0.03)
            } else {
                rng.gen_range(-spread..spread)
            }
        })
        .collect()
}

fn assert_matches_brute_force(points: &[f64], dim: usize, h: f64, queries: &[f64]) -> usize {
    let kde = Kde::fit(points, dim, h).unwrap();
    let mut fast = vec![0.0; queries.len() / dim];
    kde.density_batch(queries, &mut fast);
    let mut nonzero = 0;
    for (q, f) in queries.chunks_exact(dim).zip(&fast) {
        let b = brute_force_density(points, dim, h, q);
        assert!(
            (f - b).abs() <= 1e-12 * b.abs().max(1.0),
            "query {q:?}: grid {f}, brute force {b}"
        );
        if b > 0.0 {
            nonzero += 1;
        }
    }
    nonzero
}

#[test]
fn grid_matches_brute_force_in_1_2_3_dimensions() {
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    for (dim, h) in [(1, 0.01), (2, 0.02), (3, 0.05)] {
        let points = random_points(&mut rng, 600, dim, 0.2);
        // Queries inside, at the edges and outside the data's bounding box.
        let queries: Vec<f64> = (0..400 * dim).map(|_| rng.gen_range(-0.3..0.3)).collect();
        let nonzero = assert_matches_brute_force(&points, dim, h, &queries);
        // Queries on the fitted points themselves are all positive.
        let on_points = assert_matches_brute_force(&points, dim, h, &points);
        assert_eq!(on_points, 600, "dim {dim}");
        assert!(nonzero > 20, "dim {dim}: only {nonzero} positive queries");
    }
}

#[test]
fn sparse_cell_directory_matches_brute_force() {
    // A 3-D spread of 2000 bandwidths per axis is 8e9 cells: the sorted-key directory.
    let mut rng = ChaCha8Rng::seed_from_u64(2);
    let h = 0.01;
    let mut points = random_points(&mut rng, 300, 3, 10.0);
    points.extend([10.0, 10.0, 10.0, -10.0, -10.0, -10.0]);
    let kde = Kde::fit(&points, 3, h).unwrap();
    assert!(!kde.uses_dense_grid());
    // Each perturbed point is within 0.005·√3 < h of its point: all 302 are positive.
    let mut queries: Vec<f64> = points
        .iter()
        .map(|p| p + rng.gen_range(-0.005..0.005))
        .collect();
    queries.extend((0..300).map(|_| rng.gen_range(-0.05..0.05)));
    let nonzero = assert_matches_brute_force(&points, 3, h, &queries);
    assert!(nonzero >= 302, "{nonzero}");
    // And the dense table is used for a compact data set.
    assert!(Kde::fit(&random_points(&mut rng, 100, 2, 0.2), 2, 0.02)
        .unwrap()
        .uses_dense_grid());
}

#[test]
fn normalising_constants_are_the_known_ones() {
    assert!((epanechnikov_constant(1) - 0.75).abs() < 1e-15);
    assert!((epanechnikov_constant(2) - 2.0 / std::f64::consts::PI).abs() < 1e-15);
    assert!((unit_ball_volume(3) - 4.0 / 3.0 * std::f64::consts::PI).abs() < 1e-14);
    assert!((unit_ball_volume(4) - std::f64::consts::PI.powi(2) / 2.0).abs() < 1e-14);
}

#[test]
fn density_integrates_to_one_in_1d() {
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let h = 0.05;
    let points: Vec<f64> = (0..50).map(|_| rng.gen_range(-0.5..0.5)).collect();
    let kde = Kde::fit(&points, 1, h).unwrap();
    // Midpoint rule on [-0.6, 0.6], which contains the support.
    let n = 200_000;
    let (lo, hi) = (-0.6, 0.6);
    let dx = (hi - lo) / n as f64;
    let integral: f64 = (0..n)
        .map(|i| kde.density(&[lo + (i as f64 + 0.5) * dx]) * dx)
        .sum();
    assert!((integral - 1.0).abs() < 1e-4, "∫p = {integral}");
}

#[test]
fn density_integrates_to_one_in_2d() {
    let mut rng = ChaCha8Rng::seed_from_u64(4);
    let h = 0.02;
    // Fingertip-like data: points inside the reachable disc of Reacher.
    let points: Vec<f64> = (0..200)
        .flat_map(|_| {
            let (r, a): (f64, f64) = (rng.gen_range(0.0..0.2), rng.gen_range(0.0..6.3));
            [r * a.cos(), r * a.sin()]
        })
        .collect();
    let kde = Kde::fit(&points, 2, h).unwrap();
    let n = 1200;
    let (lo, hi) = (-0.23, 0.23);
    let dx = (hi - lo) / n as f64;
    let mut integral = 0.0;
    for i in 0..n {
        for j in 0..n {
            let q = [lo + (i as f64 + 0.5) * dx, lo + (j as f64 + 0.5) * dx];
            integral += kde.density(&q) * dx * dx;
        }
    }
    assert!((integral - 1.0).abs() < 2e-3, "∫p = {integral}");
}

#[test]
fn density_is_zero_outside_the_support_and_positive_inside() {
    let h = 0.02;
    let points = [0.0, 0.0, 0.1, 0.0];
    let kde = Kde::fit(&points, 2, h).unwrap();
    // Exactly one bandwidth away: the kernel is (1 − 1) = 0.
    assert_eq!(kde.density(&[0.0, h]), 0.0);
    assert_eq!(kde.density(&[0.05, 0.0]), 0.0);
    assert_eq!(kde.density(&[0.1 + 1.5 * h, 0.0]), 0.0);
    assert_eq!(kde.density(&[5.0, -7.0]), 0.0);
    assert_eq!(kde.density(&[-1e300, 1e300]), 0.0);
    assert!(kde.density(&[0.0, 0.99 * h]) > 0.0);
    // At a point alone in its support: c_2 / (n h²).
    let at_point = kde.density(&[0.0, 0.0]);
    let expected = 2.0 / std::f64::consts::PI / (2.0 * h * h);
    assert!((at_point - expected).abs() < 1e-9 * expected);
    assert!(kde.density(&[f64::NAN, 0.0]).is_nan());
}

#[test]
fn fitting_observation_columns_selects_those_columns() {
    // Rows of width 4; the KDE reads columns 2 and 0.
    let obs: Vec<f32> = vec![9.0, 1.0, 0.5, 9.0, 0.25, 2.0, -0.5, 7.0];
    let kde = Kde::fit_columns(&obs, 4, &[2, 0], 0.1).unwrap();
    assert_eq!((kde.len(), kde.dim()), (2, 2));
    let pts = select_columns(&obs, 4, &[2, 0]).unwrap();
    assert_eq!(pts, vec![0.5, 9.0, -0.5, 0.25]);
    let d = kde.density_columns(&obs, 4, &[2, 0]).unwrap();
    for (q, d) in pts.chunks(2).zip(&d) {
        assert_eq!(*d, brute_force_density(&pts, 2, 0.1, q));
    }
}

#[test]
fn bad_input_is_refused_with_the_reason() {
    assert_eq!(
        Kde::fit(&[1.0], 0, 0.1).unwrap_err(),
        KdeError::ZeroDimension
    );
    assert_eq!(Kde::fit(&[], 2, 0.1).unwrap_err(), KdeError::NoPoints);
    assert_eq!(
        Kde::fit(&[1.0, 2.0, 3.0], 2, 0.1).unwrap_err(),
        KdeError::RaggedPoints { len: 3, dim: 2 }
    );
    for h in [0.0, -1.0, f64::NAN, f64::INFINITY] {
        assert!(matches!(
            Kde::fit(&[1.0], 1, h).unwrap_err(),
            KdeError::BadBandwidth(_)
        ));
    }
    assert_eq!(
        Kde::fit(&[0.0, 0.0, 1.0, f64::NAN], 2, 0.1).unwrap_err(),
        KdeError::NonFinitePoint { index: 1 }
    );
    assert_eq!(
        Kde::fit_columns(&[0.0; 8], 4, &[1, 4], 0.1).unwrap_err(),
        KdeError::ColumnOutOfRange {
            column: 4,
            obs_dim: 4
        }
    );
    let msg = KdeError::BadBandwidth(-1.0).to_string();
    assert!(msg.contains("bandwidth") && msg.contains("-1"), "{msg}");
}

#[test]
fn a_span_too_wide_for_cell_coordinates_is_left_out_of_the_grid() {
    // 1e600 bandwidths: no cell coordinate for it, so every query scans every point.
    let points = [0.0, 1e300];
    let kde = Kde::fit(&points, 1, 1e-300).unwrap();
    assert!(kde.gridded_dimensions().is_empty());
    let queries = [0.0, 1e300, 5e-301, 0.5];
    let nonzero = assert_matches_brute_force(&points, 1, 1e-300, &queries);
    assert_eq!(nonzero, 3);
}

/// Rows (one-hot of `states` machine states, fingertip x, y), the product controls' density
/// state: `n` points spread over the states and a 0.4 × 0.4 square.
fn product_rows(rng: &mut ChaCha8Rng, n: usize, states: usize) -> Vec<f64> {
    let mut rows = Vec::with_capacity(n * (states + 2));
    for _ in 0..n {
        let u = rng.gen_range(0..states);
        rows.extend((0..states).map(|s| if s == u { 1.0 } else { 0.0 }));
        rows.push(rng.gen_range(-0.2..0.2));
        rows.push(rng.gen_range(-0.2..0.2));
    }
    rows
}

#[test]
fn a_machine_one_hot_beside_the_fingertip_fits_and_matches_brute_force() {
    // Regression: 12 states at bandwidth 0.02 are 51^12 · 21^2 cells, which a key over every
    // dimension cannot hold (from 10 states on); the product controls failed with it.
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    let (states, h) = (12, 0.02);
    let dim = states + 2;
    let points = product_rows(&mut rng, 3000, states);
    let kde = Kde::fit(&points, dim, h).unwrap();
    // The one-hot splits the points by state; each state's grid keys on the fingertip.
    assert_eq!(kde.split_columns(), (0..states).collect::<Vec<_>>());
    assert_eq!(kde.gridded_dimensions(), [states, states + 1]);
    let mut queries: Vec<f64> = points
        .iter()
        .enumerate()
        .map(|(i, p)| {
            if i % dim >= states {
                p + rng.gen_range(-0.01..0.01)
            } else {
                *p
            }
        })
        .collect();
    queries.extend(product_rows(&mut rng, 500, states));
    let nonzero = assert_matches_brute_force(&points, dim, h, &queries);
    assert!(nonzero >= 3000, "{nonzero}");
}

#[test]
fn up_to_three_dimensions_are_all_gridded_in_order() {
    let mut rng = ChaCha8Rng::seed_from_u64(6);
    for dim in 1..=3 {
        let kde = Kde::fit(&random_points(&mut rng, 200, dim, 0.2), dim, 0.02).unwrap();
        assert_eq!(kde.gridded_dimensions(), (0..dim).collect::<Vec<_>>());
    }
    // A dimension every point shares one cell of narrows nothing and is left out.
    let flat: Vec<f64> = random_points(&mut rng, 200, 2, 0.2)
        .chunks_exact(2)
        .flat_map(|p| [p[0], 0.5])
        .collect();
    assert_eq!(Kde::fit(&flat, 2, 0.02).unwrap().gridded_dimensions(), [0]);
}

#[test]
fn split_columns_match_brute_force_at_queries_off_their_values() {
    // Two columns of three values 0.1 apart (≥ 2h at h = 0.04) beside a 2-D cloud: split on
    // both. Queries on the values, within h of one (r² > 0: the narrowed kernel), between
    // two (no value within h) and beyond the ends.
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let h = 0.04;
    let levels = [-0.1, 0.0, 0.1];
    let mut points = Vec::new();
    for _ in 0..2000 {
        points.push(levels[rng.gen_range(0..3)]);
        points.push(rng.gen_range(-0.1..0.1));
        points.push(levels[rng.gen_range(0..3)]);
        points.push(rng.gen_range(-0.1..0.1));
    }
    let kde = Kde::fit(&points, 4, h).unwrap();
    assert_eq!(kde.split_columns(), [0, 2]);
    assert_eq!(kde.gridded_dimensions(), [1, 3]);
    let offsets = [0.0, 0.01, -0.025, 0.039, 0.05, 0.2];
    let mut queries = Vec::new();
    for _ in 0..600 {
        let off = |rng: &mut ChaCha8Rng| offsets[rng.gen_range(0..offsets.len())];
        queries.push(levels[rng.gen_range(0..3)] + off(&mut rng));
        queries.push(rng.gen_range(-0.12..0.12));
        queries.push(levels[rng.gen_range(0..3)] + off(&mut rng));
        queries.push(rng.gen_range(-0.12..0.12));
    }
    let nonzero = assert_matches_brute_force(&points, 4, h, &queries);
    assert!(nonzero > 100, "{nonzero}");
}

#[test]
fn columns_too_close_or_too_varied_are_not_split_on() {
    let mut rng = ChaCha8Rng::seed_from_u64(8);
    let h = 0.05;
    let rows = |rng: &mut ChaCha8Rng, gap: f64, values: usize| -> Vec<f64> {
        (0..500)
            .flat_map(|_| {
                [
                    gap * rng.gen_range(0..values) as f64,
                    rng.gen_range(-0.2..0.2),
                ]
            })
            .collect()
    };
    // Values more than 2h apart split; closer ones do not (a query could be within h of two).
    assert_eq!(
        Kde::fit(&rows(&mut rng, 2.5 * h, 5), 2, h)
            .unwrap()
            .split_columns(),
        [0]
    );
    let close = rows(&mut rng, 1.99 * h, 5);
    assert!(Kde::fit(&close, 2, h).unwrap().split_columns().is_empty());
    assert_matches_brute_force(&close, 2, h, &close);
    // More values than MAX_SPLIT_VALUES: not split on.
    let varied = rows(&mut rng, 1.0, MAX_SPLIT_VALUES + 1);
    assert!(Kde::fit(&varied, 2, h).unwrap().split_columns().is_empty());
    // Every column discrete: one is kept for the grid, so none is split on.
    assert!(Kde::fit(&[0.0, 0.0, 1.0, 1.0], 2, h)
        .unwrap()
        .split_columns()
        .is_empty());
}
