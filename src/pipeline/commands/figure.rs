//! `reacher figure`: small multiples of learning curves from a curve table
//! ([`crate::report::curves`]), each algorithm in its own colour ([`Algo::colour`]) in every
//! panel, one legend beside the panels.

use super::usage;
use crate::input_file::{read_text, MAX_DATA_FILE_BYTES};
use crate::irl::algo::Algo;
use crate::output::{check_file, check_not_input, create_parent};
use crate::report::curves::{CurveTable, FigureLabels};
use anyhow::Result;
use std::path::PathBuf;

/// The arguments of `reacher figure`.
#[derive(Clone, Debug)]
pub struct FigureRequest {
    /// The curve table (CSV, `panel,algo,curve,seed,x,y`).
    pub data: PathBuf,
    /// The SVG to write.
    pub out: PathBuf,
    pub title: String,
    pub x_label: String,
    pub y_label: String,
    /// `lo,hi`; `None` fits each panel to its data.
    pub y_range: Option<String>,
    /// Panels per row.
    pub columns: usize,
    /// Moving average over this many consecutive points of each seed (1: none).
    pub smooth: usize,
    /// Replace an existing `out`.
    pub force: bool,
}

/// `reacher figure`: reads and checks the table, then writes the SVG and prints its path.
pub fn run(args: FigureRequest) -> Result<()> {
    if args.columns == 0 || args.columns > 8 {
        return Err(usage(format!(
            "--columns {} is outside 1..=8",
            args.columns
        )));
    }
    if args.smooth == 0 || args.smooth > 1000 {
        return Err(usage(format!(
            "--smooth {} is outside 1..=1000",
            args.smooth
        )));
    }
    let y_range = args.y_range.as_deref().map(parse_range).transpose()?;
    check_file(&args.out, args.force).map_err(usage)?;
    check_not_input(&args.out, &[&args.data]).map_err(usage)?;
    let text = read_text(&args.data, MAX_DATA_FILE_BYTES)
        .map_err(|e| usage(format!("{}: {e}", args.data.display())))?;
    let table =
        CurveTable::parse(&text).map_err(|e| usage(format!("{}: {e}", args.data.display())))?;
    let labels = FigureLabels {
        title: args.title,
        x_label: args.x_label,
        y_label: args.y_label,
    };
    let figure = table.to_figure(&labels, y_range, args.columns, args.smooth, |algo| {
        Algo::from_name(algo).map(Algo::colour)
    });
    create_parent(&args.out)?;
    crate::atomic_file::write_atomic(&args.out, figure.to_svg().as_bytes())
        .map_err(|e| anyhow::anyhow!("{}: {e}", args.out.display()))?;
    println!("{}", args.out.display());
    Ok(())
}

/// `lo,hi` with finite `lo < hi`.
fn parse_range(text: &str) -> Result<(f64, f64)> {
    let parsed = text.split_once(',').and_then(|(a, b)| {
        let (a, b) = (a.trim().parse::<f64>().ok()?, b.trim().parse::<f64>().ok()?);
        (a.is_finite() && b.is_finite() && a < b).then_some((a, b))
    });
    parsed.ok_or_else(|| usage(format!("--y-range `{text}`: expected LO,HI with LO < HI")))
}
