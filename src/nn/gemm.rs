//! Matrix products on column-major `DMatrix<f32>` with transposes expressed as stride swaps.
//!
//! nalgebra's own `gemm` on strided views reads out of bounds when a dimension is ≤ 5
//! (dimforge/nalgebra#1616), so products go to matrixmultiply's `sgemm` with explicit strides,
//! or, when the CPU allows, to [`super::gemm_unpacked`], which rounds every element exactly as
//! `sgemm` does but skips its per-call packing.
//!
//! A per-thread trace can record the shapes of every product (see [`trace`]); benchmarks use it
//! to time exactly the products one SAC update performs.

use super::gemm_unpacked::{self, StridedRef};
use nalgebra::DMatrix;
use std::cell::{Cell, RefCell};

/// One matrix product `C (m×n) = α op(A) (m×k) · op(B) (k×n) + β C`, or a dense layer's
/// `A B + bias` ([`gemm_bias`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct GemmShape {
    pub m: usize,
    pub k: usize,
    pub n: usize,
    pub trans_a: bool,
    pub trans_b: bool,
    pub epilogue: Epilogue,
}

/// What a traced product does besides multiplying.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Epilogue {
    /// `α op(A) op(B) + β C` ([`gemm`]).
    Beta,
    /// `A B + bias` in every column ([`gemm_bias`] without ReLU).
    Bias,
    /// `max(0, A B + bias)` ([`gemm_bias`] with ReLU).
    BiasRelu,
}

thread_local! {
    static TRACING: Cell<bool> = const { Cell::new(false) };
    static TRACE: RefCell<Vec<GemmShape>> = const { RefCell::new(Vec::new()) };
}

/// Runs `f` and returns its result together with the shapes of every [`gemm`] it called on
/// this thread, in order.
pub fn trace<R>(f: impl FnOnce() -> R) -> (R, Vec<GemmShape>) {
    TRACE.with(|t| t.borrow_mut().clear());
    TRACING.with(|t| t.set(true));
    let r = f();
    TRACING.with(|t| t.set(false));
    let shapes = TRACE.with(|t| std::mem::take(&mut *t.borrow_mut()));
    (r, shapes)
}

/// Logical (rows, cols) of `op(M)` and its (row stride, col stride) in `M`'s column-major
/// storage.
fn op_layout(mat: &DMatrix<f32>, trans: bool) -> (usize, usize, isize, isize) {
    let (r, c) = mat.shape();
    if trans {
        (c, r, r as isize, 1)
    } else {
        (r, c, 1, r as isize)
    }
}

/// `c = alpha * op(a) * op(b) + beta * c` where `op` transposes when the flag is set.
/// When `beta == 0` the old contents of `c` are ignored (even NaN). The bits are those of
/// [`gemm_matrixmultiply`] whichever kernel computes them.
///
/// # Panics
/// When the shapes do not agree — a programming error in the caller, not bad input.
pub fn gemm(
    alpha: f32,
    a: &DMatrix<f32>,
    trans_a: bool,
    b: &DMatrix<f32>,
    trans_b: bool,
    beta: f32,
    c: &mut DMatrix<f32>,
) {
    let shape = checked_shape(a, trans_a, b, trans_b, c);
    record(shape);
    // The unpacked kernel reproduces sgemm only for α = 1 (see its module); it was faster
    // than sgemm on every product of a SAC update (`sac_bench --compare-kernels`).
    if alpha == 1.0 && unpacked(a, trans_a, b, trans_b, beta, c) {
        return;
    }
    sgemm(alpha, a, trans_a, b, trans_b, beta, c);
}

/// Appends `shape` to this thread's trace while [`trace`] runs.
fn record(shape: GemmShape) {
    if TRACING.with(Cell::get) {
        TRACE.with(|t| t.borrow_mut().push(shape));
    }
}

/// `c = a · b + bias` in every column, then `max(0, ·)` element by element when `relu`: a
/// dense layer's forward pass. The bits are those of copying `bias` into every column,
/// [`gemm`] with α = β = 1, then [`relu`], which is what [`gemm_bias_matrixmultiply`] does and
/// what runs when the unpacked kernel does not; the kernel takes the bias as its first k
/// block's C and applies the ReLU as it stores, so C is written once and never read. (Where
/// two NaNs meet, which one comes out is the compiler's choice on either path.)
///
/// # Panics
/// When the shapes do not agree (`bias`: one value per row of `c`).
pub fn gemm_bias(
    a: &DMatrix<f32>,
    b: &DMatrix<f32>,
    bias: &[f32],
    relu: bool,
    c: &mut DMatrix<f32>,
) {
    let mut shape = checked_shape(a, false, b, false, c);
    assert_eq!(bias.len(), shape.m, "gemm_bias: bias length");
    shape.epilogue = if relu {
        Epilogue::BiasRelu
    } else {
        Epilogue::Bias
    };
    record(shape);
    let (m, k, n) = (shape.m, shape.k, shape.n);
    let (sa, sb) = (strided(a, false), strided(b, false));
    if !gemm_unpacked::gemm_bias(m, k, n, sa, sb, bias, relu, c.as_mut_slice()) {
        bias_sgemm(a, b, bias, relu, c);
    }
}

/// [`gemm_bias`] always as a copy of `bias` into every column, matrixmultiply's `sgemm` with
/// β = 1, then [`relu`] when asked (the reference the unpacked kernel is held to).
///
/// # Panics
/// When the shapes do not agree.
pub fn gemm_bias_matrixmultiply(
    a: &DMatrix<f32>,
    b: &DMatrix<f32>,
    bias: &[f32],
    relu: bool,
    c: &mut DMatrix<f32>,
) {
    checked_shape(a, false, b, false, c);
    assert_eq!(bias.len(), c.nrows(), "gemm_bias: bias length");
    bias_sgemm(a, b, bias, relu, c);
}

/// [`gemm_bias_matrixmultiply`] on shapes already checked.
fn bias_sgemm(a: &DMatrix<f32>, b: &DMatrix<f32>, bias: &[f32], relu: bool, c: &mut DMatrix<f32>) {
    for col in c.as_mut_slice().chunks_exact_mut(bias.len().max(1)) {
        col.copy_from_slice(bias);
    }
    sgemm(1.0, a, false, b, false, 1.0, c);
    if relu {
        self::relu(c.as_mut_slice());
    }
}

/// `v = max(v, 0)` on every element, as `f32::max(v, 0.0)`: NaN and −0.0 become +0.0.
pub fn relu(values: &mut [f32]) {
    // Branch-free: compiles to a vector max.
    for v in values {
        *v = v.max(0.0);
    }
}

/// [`gemm`] with α = 1 through [`super::gemm_unpacked`] whatever the shape; false (and `c`
/// untouched) when that kernel does not run on this CPU.
///
/// # Panics
/// When the shapes do not agree.
pub fn gemm_unpacked(
    a: &DMatrix<f32>,
    trans_a: bool,
    b: &DMatrix<f32>,
    trans_b: bool,
    beta: f32,
    c: &mut DMatrix<f32>,
) -> bool {
    checked_shape(a, trans_a, b, trans_b, c);
    unpacked(a, trans_a, b, trans_b, beta, c)
}

/// [`gemm`] always through matrixmultiply's `sgemm` (the reference the unpacked kernel is
/// held to, and the baseline benchmarks compare with).
///
/// # Panics
/// When the shapes do not agree.
pub fn gemm_matrixmultiply(
    alpha: f32,
    a: &DMatrix<f32>,
    trans_a: bool,
    b: &DMatrix<f32>,
    trans_b: bool,
    beta: f32,
    c: &mut DMatrix<f32>,
) {
    checked_shape(a, trans_a, b, trans_b, c);
    sgemm(alpha, a, trans_a, b, trans_b, beta, c);
}

fn checked_shape(
    a: &DMatrix<f32>,
    trans_a: bool,
    b: &DMatrix<f32>,
    trans_b: bool,
    c: &DMatrix<f32>,
) -> GemmShape {
    let (m, k, _, _) = op_layout(a, trans_a);
    let (kb, n, _, _) = op_layout(b, trans_b);
    assert_eq!(k, kb, "gemm: inner dimensions differ");
    assert_eq!(c.shape(), (m, n), "gemm: output shape");
    GemmShape {
        m,
        k,
        n,
        trans_a,
        trans_b,
        epilogue: Epilogue::Beta,
    }
}

/// The unpacked product on shapes already checked.
fn unpacked(
    a: &DMatrix<f32>,
    trans_a: bool,
    b: &DMatrix<f32>,
    trans_b: bool,
    beta: f32,
    c: &mut DMatrix<f32>,
) -> bool {
    let (m, k, _, _) = op_layout(a, trans_a);
    let (_, n, _, _) = op_layout(b, trans_b);
    let (sa, sb) = (strided(a, trans_a), strided(b, trans_b));
    gemm_unpacked::gemm(m, k, n, sa, sb, beta, c.as_mut_slice())
}

/// `op(mat)` as the unpacked kernel reads it: the matrix's data with op's strides.
fn strided(mat: &DMatrix<f32>, trans: bool) -> StridedRef<'_> {
    let (_, _, rs, cs) = op_layout(mat, trans);
    StridedRef {
        data: mat.as_slice(),
        rs: rs as usize,
        cs: cs as usize,
    }
}

/// matrixmultiply's `sgemm` on shapes already checked.
fn sgemm(
    alpha: f32,
    a: &DMatrix<f32>,
    trans_a: bool,
    b: &DMatrix<f32>,
    trans_b: bool,
    beta: f32,
    c: &mut DMatrix<f32>,
) {
    let (m, k, rsa, csa) = op_layout(a, trans_a);
    let (_, n, rsb, csb) = op_layout(b, trans_b);
    if m == 0 || n == 0 {
        return;
    }
    let rsc = 1;
    let csc = m as isize;
    // SAFETY: the shapes were checked by the caller; every pointer stays inside its matrix's
    // storage because the strides describe exactly the column-major layout of that matrix.
    unsafe {
        matrixmultiply::sgemm(
            m,
            k,
            n,
            alpha,
            a.as_ptr(),
            rsa,
            csa,
            b.as_ptr(),
            rsb,
            csb,
            beta,
            c.as_mut_ptr(),
            rsc,
            csc,
        );
    }
}

/// Allocates operands for `shape` (for benchmarks that replay a [`trace`]).
pub fn operands_for(shape: &GemmShape) -> (DMatrix<f32>, DMatrix<f32>, DMatrix<f32>) {
    let a = if shape.trans_a {
        DMatrix::from_element(shape.k, shape.m, 0.5)
    } else {
        DMatrix::from_element(shape.m, shape.k, 0.5)
    };
    let b = if shape.trans_b {
        DMatrix::from_element(shape.n, shape.k, 0.25)
    } else {
        DMatrix::from_element(shape.k, shape.n, 0.25)
    };
    (a, b, DMatrix::zeros(shape.m, shape.n))
}
