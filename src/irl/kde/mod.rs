//! Epanechnikov kernel density estimation, exact, on a uniform cell grid.
//!
//! **Kernel.** The *radial* (spherical) Epanechnikov kernel, the one scikit-learn's
//! `KernelDensity(kernel="epanechnikov")` uses and therefore the one the f-IRL reference
//! code fits:
//!
//! ```text
//! p(x) = 1 / (n h^d) · Σ_i K((x − x_i) / h),   K(v) = c_d · (1 − ‖v‖²)  for ‖v‖ < 1, else 0
//! c_d  = (d + 2) / (2 V_d),                    V_d = π^{d/2} / Γ(d/2 + 1)  (unit-ball volume)
//! ```
//!
//! `c_d` makes K integrate to one: ∫_{‖v‖<1} (1 − ‖v‖²) dv = V_d − d V_d / (d + 2) =
//! 2 V_d / (d + 2). (d = 1: c = 3/4; d = 2: c = 2/π.) So p integrates to one over ℝ^d.
//!
//! **Speed.** K has compact support (radius h), so a query only sees fitted points within
//! distance h. Every result is exact: the same sum as the brute-force double loop, up to
//! floating-point summation order.
//!
//! *Split columns.* A column whose points take at most [`MAX_SPLIT_VALUES`] values, each at
//! least 2h from the next (a machine state's one-hot beside the fingertip: 0 and 1), splits
//! the points into groups: a query is within h of at most one of those values, so only the
//! points of one group can touch it, and within a group the column adds the same
//! (x_j − v)²/h² to every point's ‖v‖². With r² that constant summed over the split columns,
//! (1 − r² − ‖Δ‖²/h²)₊ = (1 − r²) · (1 − ‖Δ‖²/h'²)₊ for h' = h √(1 − r²) ≤ h, a kernel sum over
//! the group's other columns alone. Columns are split on only while one column is left
//! for the grid and the group key fits 64 bits.
//!
//! *Cell grid* (within each group, over the columns not split on). Points are bucketed in a
//! grid of cells of side h over k of the dimensions; the points that can touch a query lie in
//! the 3^k cells around the query's cell. Points are stored sorted by cell (row-major, last
//! gridded dimension fastest), so the three neighbouring cells along the last gridded
//! dimension are one contiguous slice: a query scans 3^{k−1} slices, and the kernel of each
//! point in them is evaluated in all the group's dimensions.
//!
//! The grid keys on at most [`GRID_MAX_DIMS`] dimensions, those in which the points occupy
//! the most cells (a key over many dimensions would need 3^{d−1} slices per query and a cell
//! key wider than 64 bits). A dimension is left out of the grid when all points share one
//! cell in it or when its span is too many bandwidths for a cell coordinate; with no
//! dimension left, every query scans every point. Data of at most three dimensions that all
//! qualify is gridded on all of them, in index order.
//!
//! The cell directory is a dense offset table when the bounding box of the gridded
//! dimensions has at most [`DENSE_CELL_LIMIT`] cells, otherwise a sorted list of occupied cell
//! keys searched by bisection (memory stays O(n) for sparse data).

mod grid;

use grid::CellGrid;
pub use grid::{DENSE_CELL_LIMIT, GRID_MAX_DIMS};

/// Most distinct values a column may take for the points to be split on it.
pub const MAX_SPLIT_VALUES: usize = 64;

/// Bad input to the density estimator.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum KdeError {
    #[error("KDE dimension must be at least 1")]
    ZeroDimension,
    #[error("KDE bandwidth must be a positive finite number, got {0}")]
    BadBandwidth(f64),
    #[error("KDE needs at least one point")]
    NoPoints,
    #[error("{len} coordinates are not a whole number of {dim}-dimensional points")]
    RaggedPoints { len: usize, dim: usize },
    #[error("KDE point {index} has a non-finite coordinate")]
    NonFinitePoint { index: usize },
    #[error("column {column} is out of range for observations of dimension {obs_dim}")]
    ColumnOutOfRange { column: usize, obs_dim: usize },
    #[error("KDE takes at most 2^32 points, got {0}")]
    TooManyPoints(usize),
}

/// Normalising constant c_d of the radial Epanechnikov kernel in dimension `d`.
pub fn epanechnikov_constant(d: usize) -> f64 {
    (d as f64 + 2.0) / (2.0 * unit_ball_volume(d))
}

/// Volume of the unit ball in ℝ^d, by the recursion V_d = V_{d−2} · 2π / d.
pub fn unit_ball_volume(d: usize) -> f64 {
    let (mut v, start) = if d.is_multiple_of(2) {
        (1.0, 2)
    } else {
        (2.0, 3)
    };
    let mut k = start;
    while k <= d {
        v *= 2.0 * std::f64::consts::PI / k as f64;
        k += 2;
    }
    v
}

/// A column the fitted points are split on (see the module docs).
#[derive(Clone, Debug)]
struct Split {
    column: usize,
    /// Its distinct values, increasing, each at least 2h from the next.
    values: Vec<f64>,
    /// Weight of a value's index in a group's key.
    stride: u64,
}

/// A fitted Epanechnikov KDE.
#[derive(Clone, Debug)]
pub struct Kde {
    dim: usize,
    bandwidth: f64,
    n: usize,
    splits: Vec<Split>,
    /// The columns not split on, increasing: the columns of every group's grid.
    free: Vec<usize>,
    /// The groups of points that share every split column's value, by key (increasing);
    /// one group of every column when nothing is split on.
    groups: Vec<(u64, CellGrid)>,
    /// c_d / (n h^d): the density contributed by one point at its own location.
    scale: f64,
}

impl Kde {
    /// Fits a KDE to `points` (row-major, `dim` coordinates per point).
    pub fn fit(points: &[f64], dim: usize, bandwidth: f64) -> Result<Kde, KdeError> {
        check_shape(points, dim, bandwidth)?;
        let n = points.len() / dim;
        let splits = split_columns(points, dim, bandwidth);
        let free: Vec<usize> = (0..dim)
            .filter(|&j| splits.iter().all(|s| s.column != j))
            .collect();
        let groups = if splits.is_empty() {
            vec![(0, CellGrid::fit(points, dim, bandwidth))]
        } else {
            // (group key, index) pairs are unique: each group keeps its points' order.
            let mut keyed: Vec<(u64, u32)> = points
                .chunks_exact(dim)
                .enumerate()
                .map(|(i, p)| (fitted_key(&splits, p), i as u32))
                .collect();
            keyed.sort_unstable();
            let mut groups = Vec::new();
            let mut rows = Vec::new();
            for (at, &(key, i)) in keyed.iter().enumerate() {
                let p = &points[i as usize * dim..][..dim];
                rows.extend(free.iter().map(|&j| p[j]));
                if keyed.get(at + 1).is_none_or(|&(next, _)| next != key) {
                    groups.push((key, CellGrid::fit(&rows, free.len(), bandwidth)));
                    rows.clear();
                }
            }
            groups
        };
        let scale = epanechnikov_constant(dim) / (n as f64 * bandwidth.powi(dim as i32));
        Ok(Kde {
            dim,
            bandwidth,
            n,
            splits,
            free,
            groups,
            scale,
        })
    }

    /// Fits a KDE to chosen `columns` of row-major `f32` observations of width `obs_dim`
    /// (e.g. the fingertip columns `env::reacher::OBS_TIP` of Reacher observations).
    pub fn fit_columns(
        obs: &[f32],
        obs_dim: usize,
        columns: &[usize],
        bandwidth: f64,
    ) -> Result<Kde, KdeError> {
        let pts = select_columns(obs, obs_dim, columns)?;
        Kde::fit(&pts, columns.len(), bandwidth)
    }

    pub fn dim(&self) -> usize {
        self.dim
    }

    pub fn bandwidth(&self) -> f64 {
        self.bandwidth
    }

    /// Number of fitted points.
    pub fn len(&self) -> usize {
        self.n
    }

    pub fn is_empty(&self) -> bool {
        self.n == 0
    }

    /// The columns the points are split on, in increasing order (see the module docs).
    pub fn split_columns(&self) -> Vec<usize> {
        self.splits.iter().map(|s| s.column).collect()
    }

    /// The dimensions any group's grid keys on, in increasing order (see the module docs).
    pub fn gridded_dimensions(&self) -> Vec<usize> {
        let mut dims: Vec<usize> = self
            .groups
            .iter()
            .flat_map(|(_, g)| g.gridded_dimensions().iter().map(|&j| self.free[j]))
            .collect();
        dims.sort_unstable();
        dims.dedup();
        dims
    }

    /// True when every group's cell directory is the dense offset table (see the module docs).
    pub fn uses_dense_grid(&self) -> bool {
        self.groups.iter().all(|(_, g)| g.uses_dense_grid())
    }

    /// Density at `x` (length `dim`). A query with a non-finite coordinate gives NaN.
    pub fn density(&self, x: &[f64]) -> f64 {
        assert_eq!(x.len(), self.dim, "query dimension");
        self.density_at(x, &mut Vec::new())
    }

    /// Densities of row-major `queries` (`dim` coordinates each) into `out`.
    pub fn density_batch(&self, queries: &[f64], out: &mut [f64]) {
        assert_eq!(queries.len(), out.len() * self.dim, "queries/out lengths");
        let mut free = Vec::with_capacity(self.free.len());
        for (q, o) in queries.chunks_exact(self.dim).zip(out.iter_mut()) {
            *o = self.density_at(q, &mut free);
        }
    }

    /// Densities at chosen `columns` of row-major `f32` observations of width `obs_dim`.
    pub fn density_columns(
        &self,
        obs: &[f32],
        obs_dim: usize,
        columns: &[usize],
    ) -> Result<Vec<f64>, KdeError> {
        let q = query_columns(obs, obs_dim, columns, self.dim)?;
        let mut out = vec![0.0; q.len() / self.dim];
        self.density_batch(&q, &mut out);
        Ok(out)
    }

    /// [`Kde::density`] with a buffer for the query's columns not split on.
    fn density_at(&self, x: &[f64], free: &mut Vec<f64>) -> f64 {
        if x.iter().any(|v| !v.is_finite()) {
            return f64::NAN;
        }
        let inv_h = 1.0 / self.bandwidth;
        if self.splits.is_empty() {
            return self.groups[0].1.kernel_sum(x, inv_h) * self.scale;
        }
        let mut key = 0;
        let mut r2 = 0.0;
        for s in &self.splits {
            let v = x[s.column];
            // The nearest value is the only one that can be within h.
            let above = s.values.partition_point(|&a| a < v);
            let nearest = match (above.checked_sub(1), s.values.get(above)) {
                (Some(below), Some(&a)) if a - v < v - s.values[below] => above,
                (Some(below), _) => below,
                (None, _) => above,
            };
            let t = (s.values[nearest] - v) * inv_h;
            r2 += t * t;
            if r2 >= 1.0 {
                return 0.0;
            }
            key += nearest as u64 * s.stride;
        }
        let Ok(g) = self.groups.binary_search_by_key(&key, |&(k, _)| k) else {
            return 0.0;
        };
        free.clear();
        free.extend(self.free.iter().map(|&j| x[j]));
        // At r² = 0 (a one-hot query) the factor and the divisor are exactly 1.
        let shrink = 1.0 - r2;
        shrink * self.groups[g].1.kernel_sum(free, inv_h / shrink.sqrt()) * self.scale
    }
}

/// The columns to split `points` on (see the module docs), in increasing order.
fn split_columns(points: &[f64], dim: usize, bandwidth: f64) -> Vec<Split> {
    let mut candidates = Vec::new();
    'columns: for j in 0..dim {
        let mut values: Vec<f64> = Vec::new();
        for p in points.chunks_exact(dim) {
            if let Err(at) = values.binary_search_by(|a| a.total_cmp(&p[j])) {
                if values.len() == MAX_SPLIT_VALUES {
                    continue 'columns;
                }
                values.insert(at, p[j]);
            }
        }
        if values.windows(2).all(|w| w[1] - w[0] >= 2.0 * bandwidth) {
            candidates.push((j, values));
        }
    }
    if candidates.len() == dim {
        return Vec::new();
    }
    let mut splits = Vec::new();
    let mut stride = 1u64;
    for (column, values) in candidates {
        let Some(next) = stride.checked_mul(values.len() as u64) else {
            break;
        };
        splits.push(Split {
            column,
            values,
            stride,
        });
        stride = next;
    }
    splits
}

/// The group key of a fitted point: each split column's value is one of its values.
fn fitted_key(splits: &[Split], p: &[f64]) -> u64 {
    splits
        .iter()
        .map(|s| {
            s.values
                .partition_point(|a| a.total_cmp(&p[s.column]).is_lt()) as u64
                * s.stride
        })
        .sum()
}

/// Checks fitted points (row-major, `dim` wide, finite) and a bandwidth (positive, finite).
pub(crate) fn check_shape(points: &[f64], dim: usize, bandwidth: f64) -> Result<(), KdeError> {
    if dim == 0 {
        return Err(KdeError::ZeroDimension);
    }
    if !(bandwidth.is_finite() && bandwidth > 0.0) {
        return Err(KdeError::BadBandwidth(bandwidth));
    }
    if points.is_empty() {
        return Err(KdeError::NoPoints);
    }
    if !points.len().is_multiple_of(dim) {
        return Err(KdeError::RaggedPoints {
            len: points.len(),
            dim,
        });
    }
    if points.len() / dim > u32::MAX as usize {
        return Err(KdeError::TooManyPoints(points.len() / dim));
    }
    if let Some(i) = points.iter().position(|v| !v.is_finite()) {
        return Err(KdeError::NonFinitePoint { index: i / dim });
    }
    Ok(())
}

/// [`select_columns`] for queries of a density fitted in `dim` dimensions: as many columns.
pub(crate) fn query_columns(
    obs: &[f32],
    obs_dim: usize,
    columns: &[usize],
    dim: usize,
) -> Result<Vec<f64>, KdeError> {
    if columns.len() != dim {
        return Err(KdeError::RaggedPoints {
            len: columns.len(),
            dim,
        });
    }
    select_columns(obs, obs_dim, columns)
}

/// Copies `columns` of row-major `f32` rows of width `obs_dim` into row-major `f64` points.
pub fn select_columns(
    obs: &[f32],
    obs_dim: usize,
    columns: &[usize],
) -> Result<Vec<f64>, KdeError> {
    if obs_dim == 0 || !obs.len().is_multiple_of(obs_dim) {
        return Err(KdeError::RaggedPoints {
            len: obs.len(),
            dim: obs_dim,
        });
    }
    if let Some(&column) = columns.iter().find(|&&c| c >= obs_dim) {
        return Err(KdeError::ColumnOutOfRange { column, obs_dim });
    }
    let mut out = Vec::with_capacity(obs.len() / obs_dim * columns.len());
    for row in obs.chunks_exact(obs_dim) {
        out.extend(columns.iter().map(|&c| f64::from(row[c])));
    }
    Ok(out)
}

/// Reference density by the naive double loop over all fitted points (for tests and the
/// benchmark; O(n) per query).
pub fn brute_force_density(points: &[f64], dim: usize, bandwidth: f64, x: &[f64]) -> f64 {
    let n = points.len() / dim;
    let inv_h = 1.0 / bandwidth;
    let mut sum = 0.0;
    for p in points.chunks_exact(dim) {
        let mut r2 = 0.0;
        for j in 0..dim {
            let t = (p[j] - x[j]) * inv_h;
            r2 += t * t;
        }
        if r2 < 1.0 {
            sum += 1.0 - r2;
        }
    }
    sum * epanechnikov_constant(dim) / (n as f64 * bandwidth.powi(dim as i32))
}
