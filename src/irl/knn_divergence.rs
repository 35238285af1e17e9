//! The k-nearest-neighbour estimate of KL(P ‖ Q) from samples of P and Q (Wang, Kulkarni
//! and Verdú, 2009), with the Chebyshev (max-coordinate) distance, as f-IRL's evaluation of
//! its density tasks uses it (k = 3):
//!
//! ```text
//! KL̂(P ‖ Q) = (d / n) Σ_i log(ν_k(i) / ρ_k(i)) + log(m / (n − 1)),
//! ```
//!
//! for n samples x_i of P and m of Q in d dimensions, where ρ_k(i) is the distance from x_i
//! to its k-th nearest neighbour among the other samples of P and ν_k(i) to its k-th nearest
//! among the samples of Q. The volume constant of the norm's ball is the same in both terms
//! and cancels, so any norm gives a consistent estimator; the Chebyshev one lets the search
//! prune exactly on the first coordinate (the distance is at least the gap there), which is
//! what [`knn_kl`] does over the samples sorted by it.
//!
//! The estimate is undefined when a sample of P has k other samples of P at distance 0
//! (repeated points, e.g. a demonstration that holds still): that is an error, not a number.

use std::cmp::Ordering;

/// Why an estimate cannot be made.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum KnnError {
    #[error("dimension must be at least 1")]
    ZeroDimension,
    #[error("{what} has {len} numbers, not a whole number of {dim}-dimensional points")]
    Ragged {
        what: &'static str,
        len: usize,
        dim: usize,
    },
    #[error("k must be at least 1")]
    ZeroK,
    #[error("{what} has {got} points, the estimate needs at least {need}")]
    TooFew {
        what: &'static str,
        got: usize,
        need: usize,
    },
    #[error("{what} holds a coordinate that is not finite")]
    NotFinite { what: &'static str },
    #[error(
        "P's point {index} has {k} other points of P at distance 0 (repeated samples): \
         the estimate is undefined"
    )]
    Repeated { index: usize, k: usize },
}

/// Samples sorted by their first coordinate, for exact pruned k-NN queries.
struct SortedPoints {
    dim: usize,
    /// Row-major, sorted by coordinate 0.
    rows: Vec<f64>,
}

impl SortedPoints {
    fn new(points: &[f64], dim: usize) -> SortedPoints {
        let mut order: Vec<usize> = (0..points.len() / dim).collect();
        order.sort_by(|&a, &b| {
            points[a * dim]
                .partial_cmp(&points[b * dim])
                .unwrap_or(Ordering::Equal)
        });
        let rows = order
            .iter()
            .flat_map(|&i| points[i * dim..(i + 1) * dim].iter().copied())
            .collect();
        SortedPoints { dim, rows }
    }

    fn len(&self) -> usize {
        self.rows.len() / self.dim
    }

    fn row(&self, i: usize) -> &[f64] {
        &self.rows[i * self.dim..(i + 1) * self.dim]
    }

    /// The `k`-th smallest Chebyshev distance from `query` to these points (k ≥ 1, at most
    /// `len()`), counting a point equal to the query as distance 0.
    fn kth_distance(&self, query: &[f64], k: usize, best: &mut Vec<f64>) -> f64 {
        best.clear();
        let x0 = query[0];
        // First index whose coordinate 0 is ≥ the query's.
        let split = {
            let (mut lo, mut hi) = (0, self.len());
            while lo < hi {
                let mid = (lo + hi) / 2;
                if self.rows[mid * self.dim] < x0 {
                    lo = mid + 1;
                } else {
                    hi = mid;
                }
            }
            lo
        };
        let bound = |best: &Vec<f64>| {
            if best.len() == k {
                best[k - 1]
            } else {
                f64::INFINITY
            }
        };
        let consider = |i: usize, best: &mut Vec<f64>| -> bool {
            let r = self.row(i);
            if (r[0] - x0).abs() > bound(best) {
                return false; // every later point in this direction is farther still
            }
            let d = r
                .iter()
                .zip(query)
                .fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
            if d < bound(best) {
                let at = best.partition_point(|&v| v <= d);
                if best.len() == k {
                    best.pop();
                }
                best.insert(at, d);
            }
            true
        };
        let (mut left, mut right) = (split, split);
        let (mut go_left, mut go_right) = (true, true);
        while go_left || go_right {
            if go_right {
                go_right = right < self.len() && consider(right, best);
                right += 1;
            }
            if go_left {
                go_left = left > 0 && consider(left - 1, best);
                left = left.saturating_sub(1);
            }
        }
        best[k - 1]
    }
}

fn check(points: &[f64], dim: usize, what: &'static str, need: usize) -> Result<(), KnnError> {
    if !points.len().is_multiple_of(dim) {
        return Err(KnnError::Ragged {
            what,
            len: points.len(),
            dim,
        });
    }
    if points.len() / dim < need {
        return Err(KnnError::TooFew {
            what,
            got: points.len() / dim,
            need,
        });
    }
    if points.iter().any(|v| !v.is_finite()) {
        return Err(KnnError::NotFinite { what });
    }
    Ok(())
}

/// KL̂(P ‖ Q) from row-major `dim`-dimensional samples `p` (n ≥ k + 1 points) and `q`
/// (m ≥ k), with the k-th neighbour (see the module docs).
pub fn knn_kl(p: &[f64], q: &[f64], dim: usize, k: usize) -> Result<f64, KnnError> {
    if dim == 0 {
        return Err(KnnError::ZeroDimension);
    }
    if k == 0 {
        return Err(KnnError::ZeroK);
    }
    check(p, dim, "P's samples", k + 1)?;
    check(q, dim, "Q's samples", k)?;
    let (n, m) = (p.len() / dim, q.len() / dim);
    let own = SortedPoints::new(p, dim);
    let other = SortedPoints::new(q, dim);
    let mut best = Vec::with_capacity(k + 1);
    let mut sum = 0.0;
    for i in 0..n {
        let x = &p[i * dim..(i + 1) * dim];
        // The point itself is among its own samples at distance 0: the (k+1)-th.
        let rho = own.kth_distance(x, k + 1, &mut best);
        if rho == 0.0 {
            return Err(KnnError::Repeated { index: i, k });
        }
        let nu = other.kth_distance(x, k, &mut best);
        // ν = 0 (a sample of Q sits on x_i, k times) means Q is denser there than any
        // finite ratio says; the log of the smallest positive ratio stands in for −∞.
        sum += (nu.max(f64::MIN_POSITIVE) / rho).ln();
    }
    Ok(dim as f64 / n as f64 * sum + (m as f64 / (n as f64 - 1.0)).ln())
}
