//! Matrix products through matrixmultiply's `sgemm` with explicit strides.
//!
//! nalgebra's own `gemm` on strided views reads out of bounds when a dimension is ≤ 5
//! (dimforge/nalgebra#1616); calling the kernel directly on column-major storage avoids it and
//! lets us express transposes as stride swaps instead of copies.
//!
//! A per-thread trace can record the shapes of every product (see [`trace`]); benchmarks use it
//! to time exactly the products one SAC update performs.

use nalgebra::DMatrix;
use std::cell::{Cell, RefCell};

/// One matrix product `C (m×n) = α op(A) (m×k) · op(B) (k×n) + β C`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct GemmShape {
    pub m: usize,
    pub k: usize,
    pub n: usize,
    pub trans_a: bool,
    pub trans_b: bool,
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
/// When `beta == 0` the old contents of `c` are ignored (even NaN).
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
    let (m, k, rsa, csa) = op_layout(a, trans_a);
    let (kb, n, rsb, csb) = op_layout(b, trans_b);
    assert_eq!(k, kb, "gemm: inner dimensions differ");
    assert_eq!(c.shape(), (m, n), "gemm: output shape");
    if TRACING.with(Cell::get) {
        TRACE.with(|t| {
            t.borrow_mut().push(GemmShape {
                m,
                k,
                n,
                trans_a,
                trans_b,
            })
        });
    }
    if m == 0 || n == 0 {
        return;
    }
    let rsc = 1;
    let csc = m as isize;
    // SAFETY: the shapes were checked above; every pointer stays inside its matrix's storage
    // because the strides describe exactly the column-major layout of that matrix.
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
