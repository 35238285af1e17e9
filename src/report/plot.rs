//! SVG line plots: one line per named series with a shaded mean ± std band, axes with tick
//! labels, axis titles and a legend beside the plot area, never over the data. Series are
//! generic `(x, mean, std)` points, so any experiment (tabular or continuous) can plot its
//! curves over seeds. A series may name its colour (so one algorithm has one colour in every
//! plot) and be dashed (so two curves of one algorithm, e.g. the two branches of a conditional
//! task, share its colour and differ in line style).
//!
//! A series longer than [`MAX_DRAWN_POINTS`] (an expert's 10 000 training episodes, f-IRL's
//! 800 iterations) is drawn through [`downsample`]: its line and each edge of its band keep,
//! per bucket of consecutive points, the lowest and the highest point, so a plot stays a few
//! tens of kilobytes and a one-point spike is still drawn. Shorter series are drawn point for
//! point; the data (CSV, JSON) is never reduced, only its picture.

use std::fmt::Write;

/// Most points one drawn curve (a series' line, or one edge of its band) is made of; longer
/// series are reduced by [`downsample`]: 99 buckets of about 5.5 pixels of the default plot's
/// 550-pixel-wide plotting area, each drawn by its lowest and highest point. (A figure-7 plot
/// of the 800-iteration baselines, three curves per algorithm, takes 60–100 kB at 500 points.)
pub const MAX_DRAWN_POINTS: usize = 200;

/// At most `max_points` of `points` for drawing a curve through them, in their order: the
/// first and the last point, and of the points between, split into `(max_points - 2) / 2`
/// buckets of equal width in x (of equal count when x decreases somewhere or is constant), the
/// lowest and the highest of each bucket (one point when they are the same; the earlier
/// first). So the curve's vertical extent over every bucket, a few pixels wide, is drawn as it
/// is, and the global minimum and maximum are points of the result. `points` with at most
/// `max_points` entries (or `max_points < 4`, too few for a bucket) are returned as they are.
pub fn downsample(points: &[(f64, f64)], max_points: usize) -> Vec<(f64, f64)> {
    let n = points.len();
    if n <= max_points || max_points < 4 {
        return points.to_vec();
    }
    let inner = &points[1..n - 1];
    let buckets = (max_points - 2) / 2;
    let (lo, hi) = (inner[0].0, inner[inner.len() - 1].0);
    let by_x = hi > lo && inner.windows(2).all(|w| w[0].0 <= w[1].0);
    let bucket = |i: usize| {
        if by_x {
            (((inner[i].0 - lo) / (hi - lo) * buckets as f64) as usize).min(buckets - 1)
        } else {
            i * buckets / inner.len()
        }
    };
    let mut out = Vec::with_capacity(2 * buckets + 2);
    out.push(points[0]);
    let mut start = 0;
    while start < inner.len() {
        let b = bucket(start);
        let (mut imin, mut imax, mut end) = (start, start, start);
        while end < inner.len() && bucket(end) == b {
            if inner[end].1 < inner[imin].1 {
                imin = end;
            }
            if inner[end].1 > inner[imax].1 {
                imax = end;
            }
            end += 1;
        }
        out.push(inner[imin.min(imax)]);
        if imin != imax {
            out.push(inner[imin.max(imax)]);
        }
        start = end;
    }
    out.push(points[n - 1]);
    out
}

/// One point of a curve: the mean over seeds and its standard deviation.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BandPoint {
    pub x: f64,
    pub mean: f64,
    pub std: f64,
}

/// A named curve.
#[derive(Clone, Debug, PartialEq)]
pub struct Series {
    pub name: String,
    pub points: Vec<BandPoint>,
    /// An SVG colour; `None` takes the next free colour of [`PALETTE`].
    pub colour: Option<&'static str>,
    /// Drawn dashed rather than solid.
    pub dashed: bool,
}

impl Series {
    /// A solid series in the next free palette colour.
    pub fn new(name: impl Into<String>, points: Vec<BandPoint>) -> Series {
        Series {
            name: name.into(),
            points,
            colour: None,
            dashed: false,
        }
    }

    /// The same series in `colour`.
    pub fn with_colour(self, colour: &'static str) -> Series {
        Series {
            colour: Some(colour),
            ..self
        }
    }

    /// The same series, dashed when `dashed`.
    pub fn with_dashes(self, dashed: bool) -> Series {
        Series { dashed, ..self }
    }
}

/// Colours of series that name none, in order (ten colours told apart in print and by most
/// colour-blind readers; Tableau 10).
pub const PALETTE: [&str; 10] = [
    "#4e79a7", "#f28e2b", "#e15759", "#76b7b2", "#59a14f", "#edc948", "#b07aa1", "#ff9da7",
    "#9c755f", "#bab0ac",
];

/// Width of one character of the legend's 12-pixel sans-serif text, for sizing the legend.
const LEGEND_CHAR_WIDTH: f64 = 7.0;

/// A line plot with mean ± std bands.
#[derive(Clone, Debug, PartialEq)]
pub struct LinePlot {
    pub title: String,
    pub x_label: String,
    pub y_label: String,
    pub series: Vec<Series>,
    /// Fixed y range; `None` fits the data.
    pub y_range: Option<(f64, f64)>,
    pub width: f64,
    pub height: f64,
}

impl LinePlot {
    pub fn new(title: &str, x_label: &str, y_label: &str) -> LinePlot {
        LinePlot {
            title: title.into(),
            x_label: x_label.into(),
            y_label: y_label.into(),
            series: Vec::new(),
            y_range: None,
            width: 640.0,
            height: 420.0,
        }
    }

    /// The SVG document: the plot area keeps the plot's `width` × `height` layout and the
    /// legend is drawn to its right, widening the document.
    pub fn to_svg(&self) -> String {
        let colours = series_colours(&self.series);
        let legend = legend_width(&self.series);
        let (w, h) = (self.width + legend, self.height);
        let mut s = String::new();
        let _ = writeln!(
            s,
            r#"<svg xmlns="http://www.w3.org/2000/svg" width="{w}" height="{h}" viewBox="0 0 {w} {h}" font-family="sans-serif" font-size="12">"#
        );
        let _ = writeln!(s, r#"<rect width="{w}" height="{h}" fill="white"/>"#);
        self.draw_panel(&mut s, 0.0, 0.0, &colours, 15.0);
        draw_legend(&mut s, self.width, 40.0, &self.series, &colours);
        s.push_str("</svg>\n");
        s
    }

    /// Draws the plot (title, axes, bands, lines; no legend) with its top left corner at
    /// `(ox, oy)`, series `i` in `colours[i]`.
    fn draw_panel(&self, s: &mut String, ox: f64, oy: f64, colours: &[&str], title_size: f64) {
        let (w, h) = (self.width, self.height);
        let (left, right, top, bottom) = (ox + 70.0, 20.0, oy + 40.0, 55.0);
        let (pw, ph) = (w - 70.0 - right, h - 40.0 - bottom);
        let pts = self.series.iter().flat_map(|s| s.points.iter());
        let finite = |v: f64| v.is_finite();
        let (mut x0, mut x1) = (f64::INFINITY, f64::NEG_INFINITY);
        let (mut y0, mut y1) = (f64::INFINITY, f64::NEG_INFINITY);
        for p in pts {
            if finite(p.x) {
                x0 = x0.min(p.x);
                x1 = x1.max(p.x);
            }
            if finite(p.mean) && finite(p.std) {
                y0 = y0.min(p.mean - p.std);
                y1 = y1.max(p.mean + p.std);
            }
        }
        if !x0.is_finite() {
            (x0, x1) = (0.0, 1.0);
        }
        if !y0.is_finite() {
            (y0, y1) = (0.0, 1.0);
        }
        if let Some((a, b)) = self.y_range {
            (y0, y1) = (a, b);
        }
        if x1 - x0 < 1e-12 {
            x1 = x0 + 1.0;
        }
        if y1 - y0 < 1e-12 {
            y0 -= 0.5;
            y1 += 0.5;
        }
        let x_ticks = nice_ticks(x0, x1, 6);
        let y_ticks = nice_ticks(y0, y1, 6);
        let sx = |x: f64| left + (x - x0) / (x1 - x0) * pw;
        let sy = |y: f64| top + ph - (y.clamp(y0, y1) - y0) / (y1 - y0) * ph;

        let _ = writeln!(
            s,
            r#"<text x="{:.1}" y="{:.1}" text-anchor="middle" font-size="{title_size}">{}</text>"#,
            ox + w / 2.0,
            oy + 22.0,
            esc(&self.title)
        );
        // Grid and ticks.
        for &t in &x_ticks {
            let x = sx(t);
            let _ = writeln!(
                s,
                r##"<line x1="{x:.1}" y1="{top}" x2="{x:.1}" y2="{:.1}" stroke="#e5e5e5"/><text x="{x:.1}" y="{:.1}" text-anchor="middle">{}</text>"##,
                top + ph,
                top + ph + 16.0,
                fmt_tick(t)
            );
        }
        for &t in &y_ticks {
            let y = sy(t);
            let _ = writeln!(
                s,
                r##"<line x1="{left}" y1="{y:.1}" x2="{:.1}" y2="{y:.1}" stroke="#e5e5e5"/><text x="{:.1}" y="{:.1}" text-anchor="end">{}</text>"##,
                left + pw,
                left - 6.0,
                y + 4.0,
                fmt_tick(t)
            );
        }
        let _ = writeln!(
            s,
            r#"<rect x="{left}" y="{top}" width="{pw}" height="{ph}" fill="none" stroke="black"/>"#
        );
        let _ = writeln!(
            s,
            r#"<text x="{:.1}" y="{:.1}" text-anchor="middle">{}</text>"#,
            left + pw / 2.0,
            oy + h - 12.0,
            esc(&self.x_label)
        );
        let _ = writeln!(
            s,
            r#"<text transform="translate({:.1},{:.1}) rotate(-90)" text-anchor="middle">{}</text>"#,
            ox + 18.0,
            top + ph / 2.0,
            esc(&self.y_label)
        );
        // Bands, then lines on top.
        for (series, color) in self.series.iter().zip(colours) {
            let pts: Vec<&BandPoint> = series
                .points
                .iter()
                .filter(|p| p.x.is_finite() && p.mean.is_finite() && p.std.is_finite())
                .collect();
            if pts.len() >= 2 {
                // Each edge on its own: the band's extremes are those of mean ± std.
                let edge = |sign: f64| {
                    let e: Vec<(f64, f64)> =
                        pts.iter().map(|p| (p.x, p.mean + sign * p.std)).collect();
                    downsample(&e, MAX_DRAWN_POINTS)
                };
                let mut poly = String::new();
                for (x, y) in edge(1.0) {
                    let _ = write!(poly, "{:.2},{:.2} ", sx(x), sy(y));
                }
                for (x, y) in edge(-1.0).into_iter().rev() {
                    let _ = write!(poly, "{:.2},{:.2} ", sx(x), sy(y));
                }
                let _ = writeln!(
                    s,
                    r#"<polygon points="{}" fill="{color}" fill-opacity="0.15" stroke="none"/>"#,
                    poly.trim_end()
                );
            }
        }
        for (series, color) in self.series.iter().zip(colours) {
            let pts: Vec<(f64, f64)> = series
                .points
                .iter()
                .filter(|p| p.x.is_finite() && p.mean.is_finite())
                .map(|p| (p.x, p.mean))
                .collect();
            let mut line = String::new();
            for (x, y) in downsample(&pts, MAX_DRAWN_POINTS) {
                let _ = write!(line, "{:.2},{:.2} ", sx(x), sy(y));
            }
            let _ = writeln!(
                s,
                r#"<polyline points="{}" fill="none" stroke="{color}" stroke-width="2"{}/>"#,
                line.trim_end(),
                dash_attribute(series.dashed)
            );
        }
    }
}

/// Small multiples: plots side by side in a grid of `columns`, one legend for all of them to
/// the right. A series name that appears in several panels has one colour and one legend entry.
#[derive(Clone, Debug, PartialEq)]
pub struct Figure {
    pub title: String,
    pub panels: Vec<LinePlot>,
    pub columns: usize,
    /// What a solid and a dashed line mean, shown at the foot of the legend in grey (then
    /// series differing only in style share one legend entry: their name up to ` (`).
    pub line_styles: Option<[String; 2]>,
}

impl Figure {
    /// The SVG document; each panel keeps its own `width` × `height`, and a row is as high as
    /// its highest panel.
    pub fn to_svg(&self) -> String {
        let columns = self.columns.max(1);
        let rows: Vec<&[LinePlot]> = self.panels.chunks(columns).collect();
        let panel_w = self.panels.iter().map(|p| p.width).fold(0.0, f64::max);
        let row_h: Vec<f64> = rows
            .iter()
            .map(|r| r.iter().map(|p| p.height).fold(0.0, f64::max))
            .collect();
        // Legend entries: each series name once, in the order it first appears; with line
        // styles explained, one solid entry per name up to its ` (`.
        let entry_name = |name: &str| -> String {
            match &self.line_styles {
                Some(_) => name.split(" (").next().unwrap_or(name).to_string(),
                None => name.to_string(),
            }
        };
        let mut entries: Vec<Series> = Vec::new();
        for p in &self.panels {
            for series in &p.series {
                let name = entry_name(&series.name);
                if !entries.iter().any(|e| e.name == name) {
                    entries.push(Series {
                        name,
                        points: Vec::new(),
                        dashed: series.dashed && self.line_styles.is_none(),
                        ..series.clone()
                    });
                }
            }
        }
        let entry_colours = series_colours(&entries);
        let colour_of = |name: &str| {
            let name = entry_name(name);
            entries
                .iter()
                .position(|e| e.name == name)
                .map_or(PALETTE[0], |i| entry_colours[i])
        };
        let title_h = if self.title.is_empty() { 0.0 } else { 30.0 };
        let grid_w = panel_w * rows.first().map_or(0, |r| r.len()) as f64;
        let style_labels: Vec<Series> = self
            .line_styles
            .iter()
            .flatten()
            .map(|l| Series::new(l.clone(), Vec::new()))
            .collect();
        let w = grid_w + legend_width(&entries).max(legend_width(&style_labels));
        let h = title_h + row_h.iter().sum::<f64>();
        let mut s = String::new();
        let _ = writeln!(
            s,
            r#"<svg xmlns="http://www.w3.org/2000/svg" width="{w}" height="{h}" viewBox="0 0 {w} {h}" font-family="sans-serif" font-size="12">"#
        );
        let _ = writeln!(s, r#"<rect width="{w}" height="{h}" fill="white"/>"#);
        if title_h > 0.0 {
            let _ = writeln!(
                s,
                r#"<text x="{:.1}" y="22" text-anchor="middle" font-size="16">{}</text>"#,
                grid_w / 2.0,
                esc(&self.title)
            );
        }
        let mut oy = title_h;
        for (row, &rh) in rows.iter().zip(&row_h) {
            for (c, panel) in row.iter().enumerate() {
                let colours: Vec<&str> = panel.series.iter().map(|x| colour_of(&x.name)).collect();
                panel.draw_panel(&mut s, c as f64 * panel_w, oy, &colours, 14.0);
            }
            oy += rh;
        }
        let mut legend = entries.clone();
        let mut legend_colours = entry_colours.clone();
        if let Some([solid, dashed]) = &self.line_styles {
            for (label, dashed) in [(solid, false), (dashed, true)] {
                legend.push(Series::new(label.clone(), Vec::new()).with_dashes(dashed));
                legend_colours.push("#555555");
            }
        }
        draw_legend(&mut s, grid_w, title_h + 40.0, &legend, &legend_colours);
        s.push_str("</svg>\n");
        s
    }
}

/// Each series' colour: its own, else the next palette colour that no series names.
fn series_colours(series: &[Series]) -> Vec<&'static str> {
    let named: Vec<&str> = series.iter().filter_map(|s| s.colour).collect();
    let mut free = PALETTE
        .iter()
        .copied()
        .filter(|c| !named.contains(c))
        .cycle();
    series
        .iter()
        .map(|s| {
            s.colour
                .unwrap_or_else(|| free.next().unwrap_or(PALETTE[0]))
        })
        .collect()
}

fn dash_attribute(dashed: bool) -> &'static str {
    if dashed {
        r#" stroke-dasharray="7 4""#
    } else {
        ""
    }
}

/// Width of the legend column: its sample lines and its longest name.
fn legend_width(series: &[Series]) -> f64 {
    let longest = series.iter().map(|s| s.name.chars().count()).max();
    longest.map_or(0.0, |n| 50.0 + LEGEND_CHAR_WIDTH * n as f64)
}

/// The legend as a column starting at `(x, y)`: a sample line in each series' colour and
/// style, then its name.
fn draw_legend(s: &mut String, x: f64, y: f64, series: &[Series], colours: &[&str]) {
    let lx = x + 10.0;
    for (i, (entry, color)) in series.iter().zip(colours).enumerate() {
        let ly = y + 10.0 + 18.0 * i as f64;
        let _ = writeln!(
            s,
            r#"<line x1="{lx}" y1="{ly}" x2="{:.1}" y2="{ly}" stroke="{color}" stroke-width="3"{}/><text x="{:.1}" y="{:.1}">{}</text>"#,
            lx + 28.0,
            dash_attribute(entry.dashed),
            lx + 34.0,
            ly + 4.0,
            esc(&entry.name)
        );
    }
}

/// Mean and (population) standard deviation over seeds, per x. Each run is a list of
/// `(x, y)` with increasing x; x values are the union over runs. A run without a point at
/// some x contributes its last earlier value (a run that stopped early has converged: its
/// result no longer changes); before its first point it contributes nothing.
pub fn aggregate_over_seeds(runs: &[Vec<(f64, f64)>]) -> Vec<BandPoint> {
    let mut xs: Vec<f64> = runs.iter().flatten().map(|p| p.0).collect();
    xs.sort_by(f64::total_cmp);
    xs.dedup();
    let mut cursor = vec![0usize; runs.len()];
    xs.into_iter()
        .map(|x| {
            let mut vals = Vec::with_capacity(runs.len());
            for (r, run) in runs.iter().enumerate() {
                while cursor[r] < run.len() && run[cursor[r]].0 <= x {
                    cursor[r] += 1;
                }
                if cursor[r] > 0 {
                    vals.push(run[cursor[r] - 1].1);
                }
            }
            let n = vals.len() as f64;
            let mean = vals.iter().sum::<f64>() / n;
            let var = vals.iter().map(|v| (v - mean) * (v - mean)).sum::<f64>() / n;
            BandPoint {
                x,
                mean,
                std: var.sqrt(),
            }
        })
        .collect()
}

/// About `n` round tick values covering `[lo, hi]`.
fn nice_ticks(lo: f64, hi: f64, n: usize) -> Vec<f64> {
    let raw = (hi - lo) / n.max(1) as f64;
    let mag = 10f64.powf(raw.log10().floor());
    let step = [1.0, 2.0, 2.5, 5.0, 10.0]
        .iter()
        .map(|m| m * mag)
        .find(|&s| s >= raw)
        .unwrap_or(10.0 * mag);
    let k0 = (lo / step - 1e-9).ceil() as i64;
    let k1 = (hi / step + 1e-9).floor() as i64;
    // Rounded through decimal text so that 3 × 0.2 prints and compares as 0.6.
    (k0..=k1)
        .map(|k| {
            format!("{:.10}", k as f64 * step)
                .parse::<f64>()
                .unwrap_or(0.0)
                + 0.0
        })
        .collect()
}

fn fmt_tick(t: f64) -> String {
    if t.abs() >= 1e4 {
        // Enough mantissa digits to tell neighbouring ticks apart (1.5e5, not 2e5), none
        // trailing: "1e5", "1.5e5", "1.25e5".
        let s = format!("{t:.3e}");
        let (mantissa, exponent) = s.split_once('e').unwrap_or((&s, "0"));
        let mantissa = mantissa.trim_end_matches('0').trim_end_matches('.');
        format!("{mantissa}e{exponent}")
    } else if t.fract().abs() < 1e-9 {
        format!("{t:.0}")
    } else {
        let s = format!("{t:.3}");
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    }
}

fn esc(text: &str) -> String {
    text.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn large_ticks_keep_the_digits_that_tell_them_apart() {
        assert_eq!(fmt_tick(100_000.0), "1e5");
        assert_eq!(fmt_tick(150_000.0), "1.5e5");
        assert_eq!(fmt_tick(125_000.0), "1.25e5");
        assert_eq!(fmt_tick(20_000.0), "2e4");
        assert_eq!(fmt_tick(2500.0), "2500");
        assert_eq!(fmt_tick(0.25), "0.25");
    }

    #[test]
    fn aggregates_with_carry_forward() {
        let runs = vec![
            vec![(0.0, 0.0), (1.0, 1.0), (2.0, 1.0)],
            vec![(0.0, 0.0), (1.0, 0.0)],
        ];
        let band = aggregate_over_seeds(&runs);
        assert_eq!(band.len(), 3);
        assert_eq!(band[1].mean, 0.5);
        assert_eq!(band[1].std, 0.5);
        // The second run stopped at x = 1: its last value 0 counts at x = 2.
        assert_eq!(band[2].mean, 0.5);
    }

    #[test]
    fn svg_has_legend_labels_and_bands() {
        let mut p = LinePlot::new("Task <3>", "IRL step", "success");
        p.series.push(Series::new(
            "SMIRL",
            aggregate_over_seeds(&[vec![(0.0, 0.0), (1.0, 1.0)], vec![(0.0, 1.0), (1.0, 1.0)]]),
        ));
        let svg = p.to_svg();
        assert!(svg.starts_with("<svg") && svg.ends_with("</svg>\n"));
        assert!(svg.contains(">SMIRL<") && svg.contains(">IRL step<") && svg.contains(">success<"));
        assert!(svg.contains("Task &lt;3&gt;"));
        assert_eq!(svg.matches("<polygon").count(), 1);
        assert_eq!(nice_ticks(0.0, 1.0, 5), vec![0.0, 0.2, 0.4, 0.6, 0.8, 1.0]);
    }
}
