//! Redraws the committed expert training curves (`experiments/experts/curve_<task>.svg` and
//! `curve_return_<task>.svg`) from the training-curve CSVs `experiments/experts/train_all.sh`
//! copies next to them (`curve_<task>.csv`, one row per training episode), with the same
//! function `reacher expert` draws them with (`reacher_expert::write_curve_svg`, window of 100
//! episodes: the default expert config's `progress_window`, which train_all.sh uses). The
//! CSVs are not tracked (experiments/README.md); retraining writes them again.
//!
//! Usage: cargo run --release --example expert_curves -- DIR TASK...
//! e.g.   cargo run --release --example expert_curves -- experiments/experts or sequential if composite

use std::path::Path;

use smirl::env::reacher_task::ReacherTask;
use smirl::pipeline::expert::read_curve;
use smirl::pipeline::reacher_expert::write_curve_svg;

/// `ExpertConfig::default().progress_window`.
const WINDOW: usize = 100;

fn main() -> Result<(), String> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let Some((dir, tasks)) = args.split_first().filter(|(_, t)| !t.is_empty()) else {
        return Err("usage: expert_curves DIR TASK...".into());
    };
    let dir = Path::new(dir);
    for name in tasks {
        let task: ReacherTask = name.parse()?;
        let csv = dir.join(format!("curve_{name}.csv"));
        let curve = read_curve(&csv, u64::MAX).map_err(|e| e.to_string())?;
        // write_curve_svg names the return plot `<stem>_return.svg`; train_all.sh's names are
        // curve_<task>.svg and curve_return_<task>.svg.
        let tmp = tempdir(dir, name)?;
        write_curve_svg(&tmp.join("curve.svg"), task, &curve, WINDOW).map_err(|e| e.to_string())?;
        for (from, to) in [("curve.svg", "curve"), ("curve_return.svg", "curve_return")] {
            let target = dir.join(format!("{to}_{name}.svg"));
            std::fs::rename(tmp.join(from), &target).map_err(|e| e.to_string())?;
            println!("{} ({} episodes)", target.display(), curve.len());
        }
        std::fs::remove_dir(&tmp).map_err(|e| e.to_string())?;
    }
    Ok(())
}

fn tempdir(dir: &Path, name: &str) -> Result<std::path::PathBuf, String> {
    let tmp = dir.join(format!(".expert_curves_{name}.tmp"));
    std::fs::create_dir_all(&tmp).map_err(|e| e.to_string())?;
    Ok(tmp)
}
