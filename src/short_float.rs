//! Serde helpers that write an `f32` as its shortest decimal (`0.001`, not the
//! `0.0010000000474974513` of its exact binary value widened to `f64`), so configuration files
//! read like a person wrote them. Reading the decimal back into an `f32` gives the same bits.

use serde::Serializer;

/// The `f64` nearest to the shortest decimal that reads back as `x`.
fn shortest(x: f32) -> f64 {
    if x.is_finite() {
        format!("{x}").parse().unwrap_or(f64::from(x))
    } else {
        f64::from(x)
    }
}

/// `#[serde(serialize_with = "crate::short_float::f32")]`.
pub fn f32<S: Serializer>(x: &f32, s: S) -> Result<S::Ok, S::Error> {
    s.serialize_f64(shortest(*x))
}

/// `#[serde(serialize_with = "crate::short_float::option_f32")]`.
pub fn option_f32<S: Serializer>(x: &Option<f32>, s: S) -> Result<S::Ok, S::Error> {
    match x {
        Some(x) => s.serialize_some(&shortest(*x)),
        None => s.serialize_none(),
    }
}
