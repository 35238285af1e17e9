//! Reports: CSV tables and SVG line plots of mean ± std bands over seeds. A leaf utility: it
//! imports nothing else from the crate.

pub mod csv;
pub mod curves;
pub mod plot;
pub mod raster;

pub use csv::CsvTable;
pub use plot::{
    aggregate_over_seeds, downsample, BandPoint, Figure, LinePlot, Series, MAX_DRAWN_POINTS,
};
