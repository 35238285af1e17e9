//! Reports: CSV metrics, SVG plots, result tables.
