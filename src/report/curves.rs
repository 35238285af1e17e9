//! Curve tables: a long CSV of learning curves (`panel,algo,curve,seed,x,y`, one row per
//! point) drawn as small multiples, one panel per `panel` value, the mean ± std over seeds of
//! each (algo, curve) pair. `curve` names a second line of one algorithm (e.g. a branch of a
//! conditional task): empty for an algorithm's only line; otherwise the first curve name of
//! the table is drawn solid and every other dashed, in the algorithm's colour. Scripts in
//! `experiments/` write such tables from committed run data; `reacher figure` draws them.

use super::plot::{aggregate_over_seeds, Figure, LinePlot, Series};
use std::collections::BTreeMap;

/// The header a curve table starts with.
pub const HEADER: &str = "panel,algo,curve,seed,x,y";
/// Most panels in one figure.
pub const MAX_PANELS: usize = 16;
/// Most lines (algo, curve pairs) in one panel.
pub const MAX_LINES_PER_PANEL: usize = 24;

/// A bad curve table: the 1-based line and what is wrong with it.
#[derive(Debug, thiserror::Error, PartialEq)]
#[error("line {line}: {problem}")]
pub struct CurveTableError {
    pub line: usize,
    pub problem: String,
}

/// One panel's lines: (algo, curve) → seed → points in file order.
type Lines = Vec<((String, String), BTreeMap<u64, Vec<(f64, f64)>>)>;

/// A parsed curve table, panels and lines in the order they first appear.
#[derive(Debug, Default)]
pub struct CurveTable {
    panels: Vec<(String, Lines)>,
    /// The first non-empty `curve` value: drawn solid.
    solid_curve: Option<String>,
}

impl CurveTable {
    /// Parses `text`; every row is checked (six fields, a whole seed, finite x and y) and the
    /// panel and line counts are bounded by [`MAX_PANELS`] and [`MAX_LINES_PER_PANEL`].
    pub fn parse(text: &str) -> Result<CurveTable, CurveTableError> {
        let mut lines = text.lines().enumerate();
        let bad = |line: usize, problem: String| CurveTableError {
            line: line + 1,
            problem,
        };
        match lines.next() {
            Some((_, header)) if header.trim_end() == HEADER => {}
            Some((i, header)) => {
                return Err(bad(
                    i,
                    format!("expected the header `{HEADER}`, found `{header}`"),
                ))
            }
            None => return Err(bad(0, format!("empty; expected the header `{HEADER}`"))),
        }
        let mut table = CurveTable::default();
        for (i, line) in lines {
            if line.trim().is_empty() {
                continue;
            }
            let fields: Vec<&str> = line.trim_end().split(',').collect();
            let [panel, algo, curve, seed, x, y] = fields[..] else {
                return Err(bad(i, format!("{} fields, expected 6", fields.len())));
            };
            if panel.is_empty() || algo.is_empty() {
                return Err(bad(i, "empty panel or algo".into()));
            }
            let seed: u64 = seed
                .parse()
                .map_err(|_| bad(i, format!("seed `{seed}` is not a whole number")))?;
            let number = |name: &str, v: &str| -> Result<f64, CurveTableError> {
                v.parse::<f64>()
                    .ok()
                    .filter(|v| v.is_finite())
                    .ok_or_else(|| bad(i, format!("{name} `{v}` is not a finite number")))
            };
            let point = (number("x", x)?, number("y", y)?);
            if !curve.is_empty() && table.solid_curve.is_none() {
                table.solid_curve = Some(curve.to_string());
            }
            let panel_index = match table.panels.iter().position(|(p, _)| p == panel) {
                Some(k) => k,
                None if table.panels.len() == MAX_PANELS => {
                    return Err(bad(i, format!("more than {MAX_PANELS} panels")))
                }
                None => {
                    table.panels.push((panel.to_string(), Vec::new()));
                    table.panels.len() - 1
                }
            };
            let lines = &mut table.panels[panel_index].1;
            let key = (algo.to_string(), curve.to_string());
            let line_index = match lines.iter().position(|(k, _)| *k == key) {
                Some(k) => k,
                None if lines.len() == MAX_LINES_PER_PANEL => {
                    return Err(bad(
                        i,
                        format!("more than {MAX_LINES_PER_PANEL} lines in panel `{panel}`"),
                    ))
                }
                None => {
                    lines.push((key, BTreeMap::new()));
                    lines.len() - 1
                }
            };
            lines[line_index].1.entry(seed).or_default().push(point);
        }
        if table.panels.is_empty() {
            return Err(bad(0, "no rows".into()));
        }
        Ok(table)
    }

    /// The small multiples: one panel per table panel in `columns` columns, each line the mean
    /// ± std over its seeds (`aggregate_over_seeds`) of each seed's moving average over
    /// `smooth` consecutive points (1: as given), in `colour(algo)` when it gives one, y in
    /// `y_range`.
    pub fn to_figure(
        &self,
        labels: &FigureLabels,
        y_range: Option<(f64, f64)>,
        columns: usize,
        smooth: usize,
        colour: impl Fn(&str) -> Option<&'static str>,
    ) -> Figure {
        let FigureLabels {
            title,
            x_label,
            y_label,
        } = labels;
        let panels = self
            .panels
            .iter()
            .map(|(name, lines)| {
                let mut plot = LinePlot::new(name, x_label, y_label);
                plot.width = 420.0;
                plot.height = 300.0;
                plot.y_range = y_range;
                for ((algo, curve), seeds) in lines {
                    let runs: Vec<Vec<(f64, f64)>> =
                        seeds.values().map(|p| moving_average(p, smooth)).collect();
                    let label = if curve.is_empty() {
                        algo.clone()
                    } else {
                        format!("{algo} ({curve})")
                    };
                    let mut series = Series::new(label, aggregate_over_seeds(&runs))
                        .with_dashes(!curve.is_empty() && Some(curve) != self.solid_curve.as_ref());
                    if let Some(c) = colour(algo) {
                        series = series.with_colour(c);
                    }
                    plot.series.push(series);
                }
                plot
            })
            .collect();
        // Dashed lines explained when there are any: "<first curve> (solid)", "others (dashed)".
        let line_styles = self.solid_curve.as_ref().map(|solid| {
            let others: Vec<&str> = self
                .panels
                .iter()
                .flat_map(|(_, lines)| lines.iter().map(|((_, c), _)| c.as_str()))
                .filter(|c| !c.is_empty() && *c != solid)
                .fold(Vec::new(), |mut v, c| {
                    if !v.contains(&c) {
                        v.push(c);
                    }
                    v
                });
            [solid.clone(), others.join(", ")]
        });
        Figure {
            title: title.clone(),
            panels,
            columns,
            line_styles,
        }
    }
}

/// A figure's title and axis titles.
#[derive(Clone, Debug, Default)]
pub struct FigureLabels {
    pub title: String,
    pub x_label: String,
    pub y_label: String,
}

/// Each point's y replaced by the mean of it and the up to `window - 1` points before it.
fn moving_average(points: &[(f64, f64)], window: usize) -> Vec<(f64, f64)> {
    let window = window.max(1);
    let mut sum = 0.0;
    points
        .iter()
        .enumerate()
        .map(|(i, &(x, y))| {
            sum += y;
            if i >= window {
                sum -= points[i - window].1;
            }
            (x, sum / (i + 1).min(window) as f64)
        })
        .collect()
}
