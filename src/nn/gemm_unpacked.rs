//! Matrix products with exactly the bits of matrixmultiply 0.3.11's `sgemm`, without copying
//! `B` (nor `A`, when it is not transposed) into packed panels on every call.
//!
//! Every float the networks produce feeds committed figures and hashes, so a faster product
//! must round exactly as `sgemm` does. On x86-64 with FMA, `sgemm` selects either its AVX-512
//! 16×16 kernel or its FMA/AVX2 8×8 kernel, and both compute each element the same way:
//! - the `k` terms are cut into blocks of [`KC`] (256) in increasing order; within a block one
//!   accumulator starts at +0.0 and takes `acc = fma(a_ip, b_pj, acc)` for p in increasing
//!   order (no split accumulators, no reassociation);
//! - the first block ends with `c = β·c + α·acc` (`β·c` rounded, then one rounding for the
//!   sum; `c` is not read when β == 0), every later block with `c = 1·c + α·acc`.
//!
//! With α == 1 the full and the masked (edge) tiles of `sgemm` round identically, so the
//! result does not depend on where the tile edges fall; with other α they do not (the masked
//! tile rounds `α·acc` before adding), so only α == 1 is reproduced here. Vector width and tile
//! shape do not change any element's arithmetic, which is why this module can use tiles of
//! its own, read `A`'s columns and `B`'s elements in place, and still match bit for bit.
//! Other CPUs (no FMA: `sgemm` multiplies and adds separately; no AVX-512: this module's
//! tiles), compilers without AVX-512 intrinsics (before Rust 1.89) and α ≠ 1 are left to
//! `sgemm`.
//!
//! A dense layer's `W x + b` ([`gemm_bias`]) takes the bias as the first block's C instead of a
//! copy of it in every column: `b + acc` has the bits of `1·b + acc` (`1·b` is exact), and the
//! hidden layers' ReLU is applied as the last block's values are stored.

use std::cell::RefCell;

/// Depth of matrixmultiply's k blocks (`S_KC`): its kernels restart the accumulators for
/// every block of this many terms and add each block's sum into C.
pub const KC: usize = 256;

/// A read-only strided matrix: element (i, j) at `data[i * rs + j * cs]`.
#[derive(Clone, Copy, Debug)]
pub struct StridedRef<'a> {
    pub data: &'a [f32],
    pub rs: usize,
    pub cs: usize,
}

thread_local! {
    /// `op(A)` copied column-major when it arrives transposed (the weights of a backward
    /// pass, out × in: small next to the batch operand). Grows once, then is reused, so the
    /// training loop does not allocate.
    static A_COPY: RefCell<Vec<f32>> = const { RefCell::new(Vec::new()) };
}

/// Whether this CPU's `sgemm` kernel is one this module reproduces and it can run here.
pub fn supported() -> bool {
    imp::available()
}

/// `c = op(a) · op(b) + β c` with `op(a)` m × k, `op(b)` k × n and `c` m × n column-major
/// (leading dimension m), rounded exactly as `matrixmultiply::sgemm` with α = 1 rounds it.
/// Returns false, leaving `c` untouched, when [`supported`] is false or a dimension is 0
/// (the caller then uses `sgemm`).
///
/// # Panics
/// When a slice is shorter than its dimensions and strides require.
pub fn gemm(
    m: usize,
    k: usize,
    n: usize,
    a: StridedRef<'_>,
    b: StridedRef<'_>,
    beta: f32,
    c: &mut [f32],
) -> bool {
    product(m, k, n, a, b, Start::Beta(beta), false, c)
}

/// `c[:, j] = op(a) · op(b)[:, j] + bias` for every column j, then `c = max(0, c)` element by
/// element when `relu`: the bits of copying `bias` into every column of `c`, [`gemm`] with
/// β = 1, then `v.max(0.0)` on every element (a NaN becomes +0.0, and so does −0.0). `c` is
/// not read. Returns false, leaving `c` untouched, when [`supported`] is false or a dimension
/// is 0.
///
/// # Panics
/// When a slice is shorter than its dimensions and strides require (`bias`: m).
#[allow(clippy::too_many_arguments)]
pub fn gemm_bias(
    m: usize,
    k: usize,
    n: usize,
    a: StridedRef<'_>,
    b: StridedRef<'_>,
    bias: &[f32],
    relu: bool,
    c: &mut [f32],
) -> bool {
    assert!(bias.len() >= m, "gemm_unpacked: bias too short");
    product(m, k, n, a, b, Start::Bias(bias), relu, c)
}

/// What the first k block adds its sums to.
#[derive(Clone, Copy)]
enum Start<'a> {
    /// `β·c` (c not read when β == 0).
    Beta(f32),
    /// The same column of m values for every column of C.
    Bias(&'a [f32]),
}

#[allow(clippy::too_many_arguments)]
fn product(
    m: usize,
    k: usize,
    n: usize,
    a: StridedRef<'_>,
    b: StridedRef<'_>,
    start: Start<'_>,
    relu: bool,
    c: &mut [f32],
) -> bool {
    if m == 0 || k == 0 || n == 0 || !supported() {
        return false;
    }
    let last = |s: &StridedRef<'_>, rows: usize, cols: usize| (rows - 1) * s.rs + (cols - 1) * s.cs;
    assert!(last(&a, m, k) < a.data.len(), "gemm_unpacked: A too short");
    assert!(last(&b, k, n) < b.data.len(), "gemm_unpacked: B too short");
    assert!(m * n <= c.len(), "gemm_unpacked: C too short");
    if a.rs == 1 {
        imp::run(m, k, n, a.data, a.cs, b, start, relu, c);
    } else {
        A_COPY.with(|buf| {
            let mut buf = buf.borrow_mut();
            buf.clear();
            buf.reserve(m * k);
            for p in 0..k {
                buf.extend((0..m).map(|i| a.data[i * a.rs + p * a.cs]));
            }
            imp::run(m, k, n, &buf, m, b, start, relu, c);
        });
    }
    true
}

// The build script sets `smirl_avx512` when the compiler has stable AVX-512 intrinsics
// (1.89), which is why they may be used here above the crate's minimum Rust version.
#[cfg(all(target_arch = "x86_64", smirl_avx512))]
#[allow(clippy::incompatible_msrv)]
mod imp {
    use super::{Start, StridedRef, KC};
    use std::arch::x86_64::*;

    /// Rows of C one tile covers at most: four 16-lane vectors (the networks' hidden width).
    const TILE_ROWS: usize = 64;

    pub fn available() -> bool {
        // `sgemm` uses an FMA kernel when it finds fma + avx2 (or avx512f, which implies
        // them); the tiles here are AVX-512.
        is_x86_feature_detected!("avx512f")
            && is_x86_feature_detected!("fma")
            && is_x86_feature_detected!("avx2")
    }

    /// `a` is column-major with leading dimension `lda` (unit row stride). The caller has
    /// checked [`available`] and that every slice covers its dimensions.
    #[allow(clippy::too_many_arguments)]
    pub fn run(
        m: usize,
        k: usize,
        n: usize,
        a: &[f32],
        lda: usize,
        b: StridedRef<'_>,
        start: Start<'_>,
        relu: bool,
        c: &mut [f32],
    ) {
        debug_assert!(available());
        let (beta, bias) = match start {
            Start::Beta(beta) => (beta, std::ptr::null()),
            Start::Bias(bias) => (1.0, bias.as_ptr()),
        };
        // SAFETY: `available()` was checked by the caller; the bounds asserted by the caller
        // (A: (m-1) + (k-1)·lda, B: (k-1)·rs + (n-1)·cs, C: m·n, bias: m) keep every load and
        // store in its slice: tiles read rows i0..i0+rows < m (lanes beyond are masked off),
        // columns j < n and terms p < k.
        unsafe {
            run_avx512(
                m,
                k,
                n,
                a.as_ptr(),
                lda,
                b.data.as_ptr(),
                b.rs,
                b.cs,
                beta,
                bias,
                relu,
                c.as_mut_ptr(),
            )
        }
    }

    #[allow(clippy::too_many_arguments)]
    #[target_feature(enable = "avx512f,fma,avx2")]
    unsafe fn run_avx512(
        m: usize,
        k: usize,
        n: usize,
        a: *const f32,
        lda: usize,
        b: *const f32,
        rsb: usize,
        csb: usize,
        beta: f32,
        bias: *const f32,
        relu: bool,
        c: *mut f32,
    ) {
        let mut k0 = 0;
        while k0 < k {
            let kc = KC.min(k - k0);
            // Blocks after the first add into what the earlier ones wrote (sgemm's β = 1).
            let beta = if k0 == 0 { beta } else { 1.0 };
            let bias = if k0 == 0 { bias } else { std::ptr::null() };
            // The ReLU applies to the final sums only.
            let relu = relu && k0 + kc == k;
            let mut i0 = 0;
            while i0 < m {
                let rows = TILE_ROWS.min(m - i0);
                let vectors = rows.div_ceil(16);
                let tail = rows - 16 * (vectors - 1);
                let mask: __mmask16 = if tail == 16 {
                    0xffff
                } else {
                    (1u16 << tail) - 1
                };
                let t = Tile {
                    kc,
                    a: a.add(i0 + k0 * lda),
                    lda,
                    mask,
                    b: b.add(k0 * rsb),
                    rsb,
                    csb,
                    beta,
                    bias: if bias.is_null() { bias } else { bias.add(i0) },
                    relu,
                    c: c.add(i0),
                    ldc: m,
                };
                match vectors {
                    1 => columns_1(t, n),
                    2 => columns_2(t, n),
                    3 => columns_3(t, n),
                    _ => columns_4(t, n),
                }
                i0 += TILE_ROWS;
            }
            k0 += KC;
        }
    }

    /// One strip of rows of C for one k block; `b` and `c` point at column 0.
    #[derive(Clone, Copy)]
    struct Tile {
        kc: usize,
        a: *const f32,
        lda: usize,
        /// Lanes of the strip's last vector that are rows of C.
        mask: __mmask16,
        b: *const f32,
        rsb: usize,
        csb: usize,
        beta: f32,
        /// The strip's rows of the bias that replaces `β·c` (null: `β·c` as in sgemm).
        bias: *const f32,
        /// Whether stored values go through `max(·, 0)`.
        relu: bool,
        c: *mut f32,
        ldc: usize,
    }

    /// Walks the columns of C in tiles of `NR` (as many as the registers hold for `RV`
    /// vectors of rows), then the remaining columns in one narrower tile.
    macro_rules! columns {
        ($name:ident, $rv:literal, $nr:literal, [$($tail:literal)*]) => {
            #[target_feature(enable = "avx512f,fma,avx2")]
            unsafe fn $name(t: Tile, n: usize) {
                let mut j0 = 0;
                while j0 + $nr <= n {
                    tile::<$rv, $nr>(t, j0);
                    j0 += $nr;
                }
                match n - j0 {
                    0 => {}
                    $($tail => tile::<$rv, $tail>(t, j0),)*
                    _ => unreachable!(),
                }
            }
        };
    }
    columns!(columns_1, 1, 16, [1 2 3 4 5 6 7 8 9 10 11 12 13 14 15]);
    columns!(columns_2, 2, 12, [1 2 3 4 5 6 7 8 9 10 11]);
    columns!(columns_3, 3, 8, [1 2 3 4 5 6 7]);
    columns!(columns_4, 4, 6, [1 2 3 4 5]);

    /// C[strip, j0..j0+NR] for one k block: `RV·NR` accumulators, each one FMA chain over p
    /// from +0.0, then sgemm's epilogue `c = β·c + acc` (c not read when β == 0), or
    /// `c = bias + acc` when there is a bias, then `max(c, 0)` when `relu`.
    #[inline]
    #[target_feature(enable = "avx512f,fma,avx2")]
    unsafe fn tile<const RV: usize, const NR: usize>(t: Tile, j0: usize) {
        let mut acc = [[_mm512_setzero_ps(); RV]; NR];
        let mut ap = t.a;
        let mut bp = t.b.add(j0 * t.csb);
        for _ in 0..t.kc {
            let mut av = [_mm512_setzero_ps(); RV];
            for (r, v) in av.iter_mut().enumerate() {
                *v = if r + 1 == RV {
                    _mm512_maskz_loadu_ps(t.mask, ap.add(16 * r))
                } else {
                    _mm512_loadu_ps(ap.add(16 * r))
                };
            }
            for (j, accj) in acc.iter_mut().enumerate() {
                let bv = _mm512_set1_ps(*bp.add(j * t.csb));
                for (s, v) in accj.iter_mut().zip(&av) {
                    *s = _mm512_fmadd_ps(*v, bv, *s);
                }
            }
            ap = ap.add(t.lda);
            bp = bp.add(t.rsb);
        }
        let betav = _mm512_set1_ps(t.beta);
        let mut biasv = [_mm512_setzero_ps(); RV];
        if !t.bias.is_null() {
            for (r, v) in biasv.iter_mut().enumerate() {
                let mask = if r + 1 == RV { t.mask } else { 0xffff };
                *v = _mm512_maskz_loadu_ps(mask, t.bias.add(16 * r));
            }
        }
        for (j, accj) in acc.iter().enumerate() {
            let col = t.c.add((j0 + j) * t.ldc);
            for (r, s) in accj.iter().enumerate() {
                let mask = if r + 1 == RV { t.mask } else { 0xffff };
                let p = col.add(16 * r);
                // The first operand of each add is the one whose NaN sgemm's path returns when
                // both are NaN (`β·c` there, the copied bias).
                let v = if !t.bias.is_null() {
                    _mm512_add_ps(biasv[r], *s)
                } else if t.beta != 0.0 {
                    let old = _mm512_maskz_loadu_ps(mask, p);
                    _mm512_add_ps(_mm512_mul_ps(old, betav), *s)
                } else {
                    *s
                };
                // `vmaxps` returns its second operand when either is NaN or both are zero,
                // which is what `f32::max(v, 0.0)` returns: +0.0 for NaN and for −0.0.
                let v = if t.relu {
                    _mm512_max_ps(v, _mm512_setzero_ps())
                } else {
                    v
                };
                _mm512_mask_storeu_ps(p, mask, v);
            }
        }
    }
}

#[cfg(not(all(target_arch = "x86_64", smirl_avx512)))]
mod imp {
    use super::{Start, StridedRef};

    pub fn available() -> bool {
        false
    }

    #[allow(clippy::too_many_arguments)]
    pub fn run(
        _m: usize,
        _k: usize,
        _n: usize,
        _a: &[f32],
        _lda: usize,
        _b: StridedRef<'_>,
        _start: Start<'_>,
        _relu: bool,
        _c: &mut [f32],
    ) {
        unreachable!("gemm_unpacked: no kernel in this build")
    }
}
