//! Epanechnikov kernel density estimation with a uniform cell grid.
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
//! distance h. Points are bucketed in a grid of cells of side h over k of the d dimensions;
//! the points that can touch a query lie in the 3^k cells around the query's cell. Points are
//! stored sorted by cell (row-major, last gridded dimension fastest), so the three
//! neighbouring cells along the last gridded dimension are one contiguous slice: a query
//! scans 3^{k−1} slices, and the kernel of each point in them is evaluated in all d
//! dimensions. The result is exact (the same sum as the brute-force double loop, up to
//! floating-point summation order).
//!
//! The grid keys on at most [`GRID_MAX_DIMS`] dimensions, those in which the points occupy
//! the most cells. (Data of many dimensions, such as a machine state's one-hot beside the
//! fingertip, would otherwise need 3^{d−1} slices per query and a cell key wider than 64 bits.)
//! A dimension is left out of the grid when all points share one cell in it or when its span
//! is too many bandwidths for a cell coordinate; with no dimension left, every query scans
//! every point. Data of at most three dimensions that all qualify is gridded on all of them,
//! in index order.
//!
//! The cell directory is a dense offset table when the bounding box of the gridded
//! dimensions has at most [`DENSE_CELL_LIMIT`] cells, otherwise a sorted list of occupied cell
//! keys searched by bisection (memory stays O(n) for sparse data).

/// Largest number of grid cells for which the dense offset table is used.
pub const DENSE_CELL_LIMIT: u64 = 1 << 22;

/// Most dimensions the grid keys on (a query scans 3^{k−1} slices for k gridded dimensions).
pub const GRID_MAX_DIMS: usize = 3;

/// Largest number of cells along one gridded dimension (cell coordinates stay exact in f64).
const MAX_CELLS_PER_DIM: f64 = (1u64 << 52) as f64;

/// Largest product of cells over the gridded dimensions (keys of queries one cell beyond
/// the grid stay within u64).
const MAX_TOTAL_CELLS: u64 = u64::MAX / 4;

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
    let (mut v, start) = if d % 2 == 0 { (1.0, 2) } else { (2.0, 3) };
    let mut k = start;
    while k <= d {
        v *= 2.0 * std::f64::consts::PI / k as f64;
        k += 2;
    }
    v
}

/// How the grid finds the points of one cell.
#[derive(Clone, Debug)]
enum CellDirectory {
    /// `offsets[key]..offsets[key + 1]` are the (sorted) points of cell `key`.
    Dense(Vec<u32>),
    /// Cell key of every sorted point (non-decreasing).
    Sparse(Vec<u64>),
}

/// A fitted Epanechnikov KDE.
#[derive(Clone, Debug)]
pub struct Kde {
    dim: usize,
    bandwidth: f64,
    n: usize,
    /// Points sorted by cell, row-major `n × dim`.
    points: Vec<f64>,
    /// The dimensions the grid keys on, in increasing order (see the module docs).
    grid: Vec<usize>,
    /// Lower corner of the grid, per gridded dimension.
    origin: Vec<f64>,
    /// Cells per gridded dimension.
    cells: Vec<u64>,
    /// Row-major strides of the cell key, per gridded dimension.
    strides: Vec<u64>,
    directory: CellDirectory,
    /// c_d / (n h^d): the density contributed by one point at its own location.
    scale: f64,
}

impl Kde {
    /// Fits a KDE to `points` (row-major, `dim` coordinates per point).
    pub fn fit(points: &[f64], dim: usize, bandwidth: f64) -> Result<Kde, KdeError> {
        check_shape(points, dim, bandwidth)?;
        let n = points.len() / dim;
        let mut lower = vec![f64::INFINITY; dim];
        let mut upper = vec![f64::NEG_INFINITY; dim];
        for p in points.chunks_exact(dim) {
            for j in 0..dim {
                lower[j] = lower[j].min(p[j]);
                upper[j] = upper[j].max(p[j]);
            }
        }
        let (grid, cells): (Vec<usize>, Vec<u64>) =
            grid_dimensions(points, dim, bandwidth, &lower, &upper)
                .into_iter()
                .unzip();
        let origin: Vec<f64> = grid.iter().map(|&j| lower[j]).collect();
        let total: u64 = cells.iter().product();
        let k = grid.len();
        let mut strides = vec![1u64; k];
        for g in (0..k.saturating_sub(1)).rev() {
            strides[g] = strides[g + 1] * cells[g + 1];
        }
        // Same arithmetic as the queries' cell coordinates in `density`.
        let inv_h = 1.0 / bandwidth;
        let key_of = |p: &[f64]| -> u64 {
            let mut key = 0;
            for (g, &j) in grid.iter().enumerate() {
                let c = (((p[j] - origin[g]) * inv_h).floor() as u64).min(cells[g] - 1);
                key += c * strides[g];
            }
            key
        };
        let mut keyed: Vec<(u64, u32)> = points
            .chunks_exact(dim)
            .enumerate()
            .map(|(i, p)| (key_of(p), i as u32))
            .collect();
        // (key, original index) pairs are unique, so the order is fully determined.
        keyed.sort_unstable();
        let mut sorted = Vec::with_capacity(points.len());
        for &(_, i) in &keyed {
            let i = i as usize;
            sorted.extend_from_slice(&points[i * dim..(i + 1) * dim]);
        }
        let directory = if total <= DENSE_CELL_LIMIT {
            let mut offsets = vec![0u32; total as usize + 1];
            for &(k, _) in &keyed {
                offsets[k as usize + 1] += 1;
            }
            for k in 0..total as usize {
                offsets[k + 1] += offsets[k];
            }
            CellDirectory::Dense(offsets)
        } else {
            CellDirectory::Sparse(keyed.iter().map(|&(k, _)| k).collect())
        };
        let scale = epanechnikov_constant(dim) / (n as f64 * bandwidth.powi(dim as i32));
        Ok(Kde {
            dim,
            bandwidth,
            n,
            points: sorted,
            grid,
            origin,
            cells,
            strides,
            directory,
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

    /// The dimensions the grid keys on, in increasing order (see the module docs).
    pub fn gridded_dimensions(&self) -> &[usize] {
        &self.grid
    }

    /// True when the cell directory is the dense offset table (see the module docs).
    pub fn uses_dense_grid(&self) -> bool {
        matches!(self.directory, CellDirectory::Dense(_))
    }

    /// Density at `x` (length `dim`). A query with a non-finite coordinate gives NaN.
    pub fn density(&self, x: &[f64]) -> f64 {
        assert_eq!(x.len(), self.dim, "query dimension");
        if x.iter().any(|v| !v.is_finite()) {
            return f64::NAN;
        }
        let d = self.dim;
        let k = self.grid.len();
        if k == 0 {
            return kernel_sum(&self.points, x, 1.0 / self.bandwidth) * self.scale;
        }
        let inv_h = 1.0 / self.bandwidth;
        // Cell coordinate of the query in each gridded dimension (may be −1 or `cells`).
        let mut centre = [0i64; GRID_MAX_DIMS];
        for (g, &j) in self.grid.iter().enumerate() {
            let c = ((x[j] - self.origin[g]) * inv_h).floor();
            // Anything more than one cell outside the grid sees no point.
            if c < -1.0 || c > self.cells[g] as f64 {
                return 0.0;
            }
            centre[g] = c as i64;
        }
        let last = k - 1;
        let lo_last = (centre[last] - 1).max(0) as u64;
        let hi_last = (centre[last] + 1).min(self.cells[last] as i64 - 1);
        if hi_last < lo_last as i64 {
            return 0.0;
        }
        let hi_last = hi_last as u64;
        let mut sum = 0.0;
        // Odometer over the 3^{k−1} offsets of the leading gridded dimensions.
        let rows = 3usize.pow(last as u32);
        'rows: for r in 0..rows {
            let mut rest = r;
            let mut base = 0u64;
            for ((&cj, &nj), &sj) in centre[..last].iter().zip(&self.cells).zip(&self.strides) {
                let c = cj + (rest % 3) as i64 - 1;
                rest /= 3;
                if c < 0 || c >= nj as i64 {
                    continue 'rows;
                }
                base += c as u64 * sj;
            }
            let (start, end) = self.range(base + lo_last, base + hi_last);
            sum += kernel_sum(&self.points[start * d..end * d], x, inv_h);
        }
        sum * self.scale
    }

    /// Densities of row-major `queries` (`dim` coordinates each) into `out`.
    pub fn density_batch(&self, queries: &[f64], out: &mut [f64]) {
        assert_eq!(queries.len(), out.len() * self.dim, "queries/out lengths");
        for (q, o) in queries.chunks_exact(self.dim).zip(out.iter_mut()) {
            *o = self.density(q);
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

    /// Index range of the sorted points whose cell key lies in `lo..=hi`.
    fn range(&self, lo: u64, hi: u64) -> (usize, usize) {
        match &self.directory {
            CellDirectory::Dense(off) => (off[lo as usize] as usize, off[hi as usize + 1] as usize),
            CellDirectory::Sparse(keys) => (
                keys.partition_point(|&k| k < lo),
                keys.partition_point(|&k| k <= hi),
            ),
        }
    }
}

/// The dimensions the grid keys on (see the module docs), in increasing order: of those whose
/// span is at most [`MAX_CELLS_PER_DIM`] cells and in which the points occupy at least two
/// cells, the [`GRID_MAX_DIMS`] with the most occupied cells (ties to the lower index), each
/// taken only while the product of cells stays within [`MAX_TOTAL_CELLS`]; with the number of
/// cells of each.
fn grid_dimensions(
    points: &[f64],
    dim: usize,
    bandwidth: f64,
    lower: &[f64],
    upper: &[f64],
) -> Vec<(usize, u64)> {
    let inv_h = 1.0 / bandwidth;
    // (occupied cells, dimension, cells) of every eligible dimension.
    let mut eligible: Vec<(usize, usize, u64)> = Vec::new();
    let mut column: Vec<u64> = Vec::with_capacity(points.len() / dim);
    for j in 0..dim {
        // The span in cells is computed as the grid's cell counts are.
        let span = ((upper[j] - lower[j]) / bandwidth).floor() + 1.0;
        if span.is_nan() || span >= MAX_CELLS_PER_DIM {
            continue;
        }
        column.clear();
        column.extend(
            points
                .chunks_exact(dim)
                .map(|p| ((p[j] - lower[j]) * inv_h).floor() as u64),
        );
        column.sort_unstable();
        column.dedup();
        if column.len() >= 2 {
            eligible.push((column.len(), j, span as u64));
        }
    }
    eligible.sort_by(|a, b| b.0.cmp(&a.0).then(a.1.cmp(&b.1)));
    let mut grid = Vec::with_capacity(GRID_MAX_DIMS);
    let mut total: u64 = 1;
    for (_, j, cells) in eligible {
        if grid.len() == GRID_MAX_DIMS {
            break;
        }
        if let Some(t) = total.checked_mul(cells).filter(|t| *t <= MAX_TOTAL_CELLS) {
            total = t;
            grid.push((j, cells));
        }
    }
    grid.sort_unstable();
    grid
}

/// Σ over the row-major points of (1 − ‖(p − x)/h‖²)₊. Branch-free with independent
/// accumulators so the 2-D case (Reacher's fingertip) vectorises; the sum order differs
/// from the naive loop only by floating-point reassociation.
fn kernel_sum(points: &[f64], x: &[f64], inv_h: f64) -> f64 {
    let d = x.len();
    if d == 2 {
        let (x0, x1) = (x[0], x[1]);
        let mut acc = [0.0f64; 4];
        let mut quads = points.chunks_exact(8);
        for q in &mut quads {
            for (k, a) in acc.iter_mut().enumerate() {
                let t0 = (q[2 * k] - x0) * inv_h;
                let t1 = (q[2 * k + 1] - x1) * inv_h;
                *a += (1.0 - (t0 * t0 + t1 * t1)).max(0.0);
            }
        }
        let mut sum = (acc[0] + acc[1]) + (acc[2] + acc[3]);
        for p in quads.remainder().chunks_exact(2) {
            let t0 = (p[0] - x0) * inv_h;
            let t1 = (p[1] - x1) * inv_h;
            sum += (1.0 - (t0 * t0 + t1 * t1)).max(0.0);
        }
        return sum;
    }
    let mut sum = 0.0;
    for p in points.chunks_exact(d) {
        let mut r2 = 0.0;
        for (pj, xj) in p.iter().zip(x) {
            let t = (pj - xj) * inv_h;
            r2 += t * t;
        }
        sum += (1.0 - r2).max(0.0);
    }
    sum
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
    if points.len() % dim != 0 {
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
    if obs_dim == 0 || obs.len() % obs_dim != 0 {
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
