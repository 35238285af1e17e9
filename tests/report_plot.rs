//! SVG plots of long curves stay small and keep their extremes (`report::plot::downsample`,
//! used by `LinePlot::to_svg` for series longer than `MAX_DRAWN_POINTS`).

use smirl::report::{downsample, BandPoint, LinePlot, Series, MAX_DRAWN_POINTS};

/// A noisy curve with one-point spikes up (index 6 007) and down (index 2 501).
fn noisy(n: usize) -> Vec<(f64, f64)> {
    let mut state = 0x2545_f491_4f6c_dd1du64;
    (0..n)
        .map(|i| {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            let noise = (state % 1000) as f64 / 1000.0;
            let y = match i {
                6007 => 25.0,
                2501 => -20.0,
                _ => (i as f64 * 0.01).sin() + noise,
            };
            (i as f64 * 15.0, y)
        })
        .collect()
}

fn extremes(points: &[(f64, f64)]) -> ((f64, f64), (f64, f64)) {
    let lo = points
        .iter()
        .copied()
        .fold((0.0, f64::INFINITY), |a, p| if p.1 < a.1 { p } else { a });
    let hi = points.iter().copied().fold(
        (0.0, f64::NEG_INFINITY),
        |a, p| if p.1 > a.1 { p } else { a },
    );
    (lo, hi)
}

#[test]
fn downsampling_keeps_the_ends_and_the_extremes() {
    let points = noisy(10_000);
    let kept = downsample(&points, MAX_DRAWN_POINTS);
    assert!(kept.len() <= MAX_DRAWN_POINTS, "{} points", kept.len());
    assert!(kept.len() > MAX_DRAWN_POINTS / 2, "{} points", kept.len());
    assert_eq!(kept.first(), points.first());
    assert_eq!(kept.last(), points.last());
    assert_eq!(extremes(&kept), extremes(&points));
    assert!(kept.contains(&(6007.0 * 15.0, 25.0)) && kept.contains(&(2501.0 * 15.0, -20.0)));
    // Points of the input, in its order.
    assert!(kept.windows(2).all(|w| w[0].0 < w[1].0));
    assert!(kept.iter().all(|p| points.contains(p)));
    // Every bucket (here 1/249 of the x range) keeps its own lowest and highest value.
    let (x0, x1) = (points[1].0, points[points.len() - 2].0);
    let buckets = (MAX_DRAWN_POINTS - 2) / 2;
    let bucket = |x: f64| (((x - x0) / (x1 - x0) * buckets as f64) as usize).min(buckets - 1);
    for b in (0..buckets).step_by(17) {
        let of = |ps: &[(f64, f64)]| -> Vec<(f64, f64)> {
            ps[1..ps.len() - 1]
                .iter()
                .copied()
                .filter(|p| bucket(p.0) == b)
                .collect()
        };
        assert_eq!(extremes(&of(&kept)), extremes(&of(&points)), "bucket {b}");
    }
    // Deterministic.
    assert_eq!(downsample(&points, MAX_DRAWN_POINTS), kept);
}

#[test]
fn short_series_and_tiny_limits_are_left_as_they_are() {
    let points = noisy(MAX_DRAWN_POINTS);
    assert_eq!(downsample(&points, MAX_DRAWN_POINTS), points);
    assert_eq!(downsample(&points[..10], 3), points[..10].to_vec());
    assert!(downsample(&[], MAX_DRAWN_POINTS).is_empty());
    // A constant series keeps its two ends and one point per bucket at most.
    let flat: Vec<(f64, f64)> = (0..5000).map(|i| (i as f64, 1.0)).collect();
    let kept = downsample(&flat, 100);
    assert!(kept.len() <= 51, "{}", kept.len());
    assert_eq!((kept[0], kept[kept.len() - 1]), (flat[0], flat[4999]));
}

#[test]
fn x_out_of_order_falls_back_to_buckets_of_equal_count() {
    let mut points = noisy(3000);
    points.swap(100, 2000);
    let kept = downsample(&points, 200);
    assert!(kept.len() <= 200, "{}", kept.len());
    assert_eq!(extremes(&kept), extremes(&points));
    assert_eq!((kept[0], kept[kept.len() - 1]), (points[0], points[2999]));
}

fn plot(n: usize) -> LinePlot {
    let mut plot = LinePlot::new("a long curve", "env steps", "value");
    plot.series.push(Series {
        name: "noisy".into(),
        points: noisy(n)
            .into_iter()
            .map(|(x, y)| BandPoint {
                x,
                mean: y,
                std: 0.1 + 0.05 * (x * 0.003).cos(),
            })
            .collect(),
    });
    plot
}

fn coordinates(svg: &str, element: &str) -> Vec<(f64, f64)> {
    let start = svg.find(&format!("<{element} points=\"")).unwrap() + element.len() + 10;
    let end = start + svg[start..].find('"').unwrap();
    svg[start..end]
        .split(' ')
        .map(|p| {
            let (x, y) = p.split_once(',').unwrap();
            (x.parse().unwrap(), y.parse().unwrap())
        })
        .collect()
}

#[test]
fn a_10000_point_series_plots_in_a_few_kilobytes_with_its_spikes() {
    let svg = plot(10_000).to_svg();
    assert!(svg.len() < 30_000, "{} bytes", svg.len());
    let line = coordinates(&svg, "polyline");
    let band = coordinates(&svg, "polygon");
    assert!(line.len() <= MAX_DRAWN_POINTS, "{}", line.len());
    assert!(band.len() <= 2 * MAX_DRAWN_POINTS, "{}", band.len());
    // The y range is fitted to mean ± std, so the up spike's band edge is the top of the plot
    // area (y = 40) and the down spike's the bottom (y = 365); the line's spikes sit 0.1-0.15
    // (of a range of about 45) inside them.
    let top = band.iter().map(|p| p.1).fold(f64::INFINITY, f64::min);
    let bottom = band.iter().map(|p| p.1).fold(f64::NEG_INFINITY, f64::max);
    assert_eq!((top, bottom), (40.0, 365.0));
    let (lo, hi) = (
        line.iter().map(|p| p.1).fold(f64::NEG_INFINITY, f64::max),
        line.iter().map(|p| p.1).fold(f64::INFINITY, f64::min),
    );
    assert!(hi < 42.0 && lo > 363.0, "line from {hi} to {lo}");
    // The whole x range is drawn: first and last point at the plot area's edges.
    assert_eq!(line[0].0, 70.0);
    assert_eq!(line[line.len() - 1].0, 620.0);
}

#[test]
fn short_series_are_drawn_point_for_point() {
    let n = MAX_DRAWN_POINTS - 20;
    let svg = plot(n).to_svg();
    assert_eq!(coordinates(&svg, "polyline").len(), n);
    assert_eq!(coordinates(&svg, "polygon").len(), 2 * n);
}
