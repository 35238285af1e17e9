//! The cell grid a KDE's points are bucketed in: which fitted points a query can touch, and the
//! kernel sum over them (see the parent module's docs for the layout).

/// Largest number of grid cells for which the dense offset table is used.
pub const DENSE_CELL_LIMIT: u64 = 1 << 22;

/// Most dimensions the grid keys on (a query scans 3^{k−1} slices for k gridded dimensions).
pub const GRID_MAX_DIMS: usize = 3;

/// Largest number of cells along one gridded dimension (cell coordinates stay exact in f64).
const MAX_CELLS_PER_DIM: f64 = (1u64 << 52) as f64;

/// Largest product of cells over the gridded dimensions (keys of queries one cell beyond
/// the grid stay within u64).
const MAX_TOTAL_CELLS: u64 = u64::MAX / 4;

/// How the grid finds the points of one cell.
#[derive(Clone, Debug)]
enum CellDirectory {
    /// `offsets[key]..offsets[key + 1]` are the (sorted) points of cell `key`.
    Dense(Vec<u32>),
    /// Cell key of every sorted point (non-decreasing).
    Sparse(Vec<u64>),
}

/// Points bucketed in cells of side `bandwidth` over at most [`GRID_MAX_DIMS`] dimensions.
#[derive(Clone, Debug)]
pub(super) struct CellGrid {
    dim: usize,
    /// 1 / the cell side.
    inv_side: f64,
    /// Points sorted by cell, row-major `n × dim`.
    points: Vec<f64>,
    /// The dimensions the grid keys on, in increasing order.
    grid: Vec<usize>,
    /// Lower corner of the grid, per gridded dimension.
    origin: Vec<f64>,
    /// Cells per gridded dimension.
    cells: Vec<u64>,
    /// Row-major strides of the cell key, per gridded dimension.
    strides: Vec<u64>,
    directory: CellDirectory,
}

impl CellGrid {
    /// Buckets `points` (row-major, `dim` wide, finite, at most 2^32 of them) in cells of side
    /// `bandwidth` (positive, finite).
    pub(super) fn fit(points: &[f64], dim: usize, bandwidth: f64) -> CellGrid {
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
        // Same arithmetic as the queries' cell coordinates in `kernel_sum`.
        let inv_side = 1.0 / bandwidth;
        let key_of = |p: &[f64]| -> u64 {
            let mut key = 0;
            for (g, &j) in grid.iter().enumerate() {
                let c = (((p[j] - origin[g]) * inv_side).floor() as u64).min(cells[g] - 1);
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
        CellGrid {
            dim,
            inv_side,
            points: sorted,
            grid,
            origin,
            cells,
            strides,
            directory,
        }
    }

    /// The dimensions the grid keys on, in increasing order.
    pub(super) fn gridded_dimensions(&self) -> &[usize] {
        &self.grid
    }

    pub(super) fn uses_dense_grid(&self) -> bool {
        matches!(self.directory, CellDirectory::Dense(_))
    }

    /// Σ (1 − ‖(p − x) · inv_h‖²)₊ over the fitted points p, for a finite query `x` (length
    /// `dim`) and a kernel radius 1 / `inv_h` of at most the cell side (points beyond the
    /// neighbouring cells then contribute nothing).
    pub(super) fn kernel_sum(&self, x: &[f64], inv_h: f64) -> f64 {
        debug_assert_eq!(x.len(), self.dim);
        debug_assert!(inv_h >= self.inv_side);
        let k = self.grid.len();
        if k == 0 {
            return kernel_sum(&self.points, x, inv_h);
        }
        // Cell coordinate of the query in each gridded dimension (may be −1 or `cells`).
        let mut centre = [0i64; GRID_MAX_DIMS];
        for (g, &j) in self.grid.iter().enumerate() {
            let c = ((x[j] - self.origin[g]) * self.inv_side).floor();
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
        let d = self.dim;
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
        sum
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

/// The dimensions the grid keys on (see the parent module's docs), in increasing order: of those whose
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
