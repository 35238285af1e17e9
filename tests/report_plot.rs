//! SVG plots of long curves stay small and keep their extremes (`report::plot::downsample`,
//! used by `LinePlot::to_svg` for series longer than `MAX_DRAWN_POINTS`).

use smirl::report::curves::{CurveTable, FigureLabels, HEADER, MAX_PANELS};
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
    plot.series.push(Series::new(
        "noisy",
        noisy(n)
            .into_iter()
            .map(|(x, y)| BandPoint {
                x,
                mean: y,
                std: 0.1 + 0.05 * (x * 0.003).cos(),
            })
            .collect(),
    ));
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

// Small multiples and curve tables (`reacher figure`).

fn labels() -> FigureLabels {
    FigureLabels {
        title: "Figure".into(),
        x_label: "env steps".into(),
        y_label: "success".into(),
    }
}

/// Two panels; smirl in both, with two branch curves in the second.
fn table_text() -> String {
    let mut t = format!("{HEADER}\n");
    for seed in 0..2 {
        for x in 0..3 {
            t += &format!("OR,smirl,,{seed},{x},0.5\n");
            t += &format!("OR,fkl,,{seed},{x},0.25\n");
            t += &format!("IF,smirl,normal,{seed},{x},1\n");
            t += &format!("IF,smirl,cancel,{seed},{x},0\n");
        }
    }
    t
}

#[test]
fn a_curve_table_becomes_one_panel_per_task_with_one_colour_per_algorithm() {
    let table = CurveTable::parse(&table_text()).unwrap();
    let colour = |algo: &str| (algo == "smirl").then_some("#59a14f");
    let figure = table.to_figure(&labels(), Some((0.0, 1.0)), 2, 1, colour);
    assert_eq!(figure.panels.len(), 2);
    let (or, branches) = (&figure.panels[0], &figure.panels[1]);
    assert_eq!((or.title.as_str(), branches.title.as_str()), ("OR", "IF"));
    let names: Vec<&str> = branches.series.iter().map(|s| s.name.as_str()).collect();
    assert_eq!(names, ["smirl (normal)", "smirl (cancel)"]);
    // The first curve name is solid, the other dashed, both in the algorithm's colour.
    assert_eq!(
        branches.series.iter().map(|s| s.dashed).collect::<Vec<_>>(),
        [false, true]
    );
    assert!(branches.series.iter().all(|s| s.colour == Some("#59a14f")));
    // Mean over the two seeds at each x.
    assert_eq!(or.series[1].points.len(), 3);
    assert!(or.series[1]
        .points
        .iter()
        .all(|p| p.mean == 0.25 && p.std == 0.0));

    let svg = figure.to_svg();
    // One legend entry per algorithm (smirl once, though three of its lines are drawn) and
    // one per line style.
    assert_eq!(svg.matches(">smirl<").count(), 1);
    assert_eq!(svg.matches(">fkl<").count(), 1);
    assert!(svg.contains(">normal<") && svg.contains(">cancel<"));
    // smirl's colour wherever it is drawn, fkl's a palette colour no named series takes.
    assert_eq!(
        svg.matches(r##"stroke="#59a14f" stroke-width="2""##)
            .count(),
        3
    );
    assert_eq!(
        svg.matches("stroke-dasharray").count(),
        2,
        "the cancel line and its key"
    );
}

#[test]
fn the_legend_is_beside_the_plot_area_not_over_it() {
    let svg = plot(50).to_svg();
    // The plot area ends at x = 620 (70 + 550); every legend sample line starts right of it.
    let legend_x: Vec<f64> = svg
        .match_indices(r#"<line x1=""#)
        .map(|(i, m)| {
            let rest = &svg[i + m.len()..];
            rest[..rest.find('"').unwrap()].parse().unwrap()
        })
        .filter(|&x: &f64| x > 620.0)
        .collect();
    assert_eq!(legend_x.len(), 1, "one legend entry");
    let width: f64 = {
        let i = svg.find("width=\"").unwrap() + 7;
        svg[i..i + svg[i..].find('"').unwrap()].parse().unwrap()
    };
    assert!(width > 640.0, "the document widens for the legend: {width}");
}

#[test]
fn moving_average_smooths_each_seed() {
    let text = format!("{HEADER}\nA,maxent,,0,0,0\nA,maxent,,0,1,1\nA,maxent,,0,2,0\n");
    let figure = CurveTable::parse(&text)
        .unwrap()
        .to_figure(&labels(), None, 1, 2, |_| None);
    let means: Vec<f64> = figure.panels[0].series[0]
        .points
        .iter()
        .map(|p| p.mean)
        .collect();
    assert_eq!(means, [0.0, 0.5, 0.5]);
}

#[test]
fn bad_curve_tables_name_their_line() {
    let cases = [
        (
            "panel,algo,seed,x,y\n".to_string(),
            "line 1: expected the header",
        ),
        (String::new(), "line 1: empty"),
        (format!("{HEADER}\n"), "no rows"),
        (
            format!("{HEADER}\nA,smirl,,0,1\n"),
            "line 2: 5 fields, expected 6",
        ),
        (
            format!("{HEADER}\nA,smirl,,0,1,2\nA,smirl,,x,1,2\n"),
            "line 3: seed `x`",
        ),
        (
            format!("{HEADER}\nA,smirl,,0,NaN,2\n"),
            "line 2: x `NaN` is not a finite",
        ),
        (
            format!("{HEADER}\nA,smirl,,0,1,inf\n"),
            "line 2: y `inf` is not a finite",
        ),
        (
            format!("{HEADER}\n,smirl,,0,1,2\n"),
            "line 2: empty panel or algo",
        ),
    ];
    for (text, expected) in cases {
        let error = CurveTable::parse(&text).unwrap_err().to_string();
        assert!(error.contains(expected), "{text:?}: {error}");
    }
    let many: String = (0..=MAX_PANELS)
        .map(|k| format!("P{k},smirl,,0,0,0\n"))
        .collect();
    let error = CurveTable::parse(&format!("{HEADER}\n{many}"))
        .unwrap_err()
        .to_string();
    assert!(
        error.contains(&format!(
            "line {}: more than {MAX_PANELS} panels",
            MAX_PANELS + 2
        )),
        "{error}"
    );
}

#[test]
fn reacher_figure_writes_the_svg_and_refuses_bad_input_with_status_2() {
    let dir = tempfile::tempdir().unwrap();
    let data = dir.path().join("curves.csv");
    std::fs::write(&data, table_text()).unwrap();
    let out = dir.path().join("figure.svg");
    let run = |extra: &[&str]| {
        std::process::Command::new(env!("CARGO_BIN_EXE_reacher"))
            .arg("figure")
            .arg("--data")
            .arg(&data)
            .arg("--out")
            .arg(&out)
            .args(extra)
            .output()
            .unwrap()
    };
    let ok = run(&["--y-range", "0,1"]);
    assert!(
        ok.status.success(),
        "{}",
        String::from_utf8_lossy(&ok.stderr)
    );
    let svg = std::fs::read_to_string(&out).unwrap();
    assert!(svg.starts_with("<svg") && svg.contains(">OR<") && svg.contains(">IF<"));
    // An existing figure is kept without --force.
    let again = run(&[]);
    assert_eq!(again.status.code(), Some(2));
    assert_eq!(std::fs::read_to_string(&out).unwrap(), svg);
    for bad in [
        &["--y-range", "1,0"][..],
        &["--columns", "0"],
        &["--smooth", "0"],
    ] {
        let o = run(&[bad, &["--force"]].concat());
        assert_eq!(o.status.code(), Some(2), "{bad:?}");
    }
    std::fs::write(&data, format!("{HEADER}\nA,smirl,,0,1\n")).unwrap();
    let o = run(&["--force"]);
    assert_eq!(o.status.code(), Some(2));
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(stderr.contains("curves.csv: line 2: 5 fields"), "{stderr}");
}
