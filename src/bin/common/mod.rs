//! What the benchmark binaries share: each reports medians of interleaved repetitions.

/// The median of `xs` (the mean of the two middle values for an even count).
///
/// # Panics
/// When `xs` is empty: every benchmark refuses zero repetitions before it measures.
pub fn median(xs: impl AsRef<[f64]>) -> f64 {
    let mut sorted = xs.as_ref().to_vec();
    sorted.sort_by(f64::total_cmp);
    let n = sorted.len();
    if n % 2 == 1 {
        sorted[n / 2]
    } else {
        0.5 * (sorted[n / 2 - 1] + sorted[n / 2])
    }
}
