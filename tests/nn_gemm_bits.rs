//! The unpacked product kernel (`nn::gemm_unpacked`) gives exactly the bits of matrixmultiply's
//! `sgemm` on every product shape smirl performs (traced from SAC updates and batched network
//! forwards) and on edge sizes around its vector width and its k blocks, with operands whose
//! mixed magnitudes make any change of rounding order visible. A dense layer's `W x + b` (and
//! the hidden layers' ReLU) through `gemm_bias` gives exactly the bits of the bias copied into
//! every column, the product added with β = 1, then `v.max(0.0)`, special values included.

use nalgebra::DMatrix;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use smirl::env::{check_action, ContinuousEnv, EnvError, EnvStep};
use smirl::nn::gemm::{self, Epilogue, GemmShape};
use smirl::nn::{gemm_unpacked, Mlp, MlpArch};
use smirl::rl::sac::{EnvReward, SacConfig, SacTrainer};
use smirl::rm::LabelSet;
use std::collections::BTreeSet;

/// Observations of uniform noise, `obs_dim` wide: SAC's products depend only on the sizes.
struct Noise {
    obs_dim: usize,
    act_dim: usize,
    rng: ChaCha8Rng,
    t: usize,
}

impl Noise {
    fn fill(&mut self, obs: &mut [f32]) {
        for o in obs {
            *o = self.rng.gen_range(-1.0..1.0);
        }
    }
}

impl ContinuousEnv for Noise {
    fn obs_dim(&self) -> usize {
        self.obs_dim
    }
    fn act_dim(&self) -> usize {
        self.act_dim
    }
    fn reset(&mut self, seed: u64, obs: &mut [f32]) {
        self.rng = ChaCha8Rng::seed_from_u64(seed);
        self.t = 0;
        self.fill(obs);
    }
    fn step(&mut self, action: &[f32], obs: &mut [f32]) -> Result<EnvStep, EnvError> {
        check_action(action, self.act_dim)?;
        self.t += 1;
        self.fill(obs);
        Ok(EnvStep {
            reward: f64::from(obs[0]),
            labels: LabelSet::EMPTY,
            terminated: false,
            truncated: self.t >= 50,
        })
    }
}

/// The products of one SAC step + update with the paper's networks ((64, 64), batch 256) on
/// observations of `obs_dim` (17: Reacher; 24: Reacher with the reward machine's one-hot).
fn sac_update_shapes(obs_dim: usize, act_dim: usize) -> Vec<GemmShape> {
    let config = SacConfig {
        warmup_steps: 300,
        update_after: 300,
        ..SacConfig::default()
    };
    let mut env = Noise {
        obs_dim,
        act_dim,
        rng: ChaCha8Rng::seed_from_u64(0),
        t: 0,
    };
    let mut trainer = SacTrainer::new(&config, obs_dim, act_dim, 0).unwrap();
    trainer
        .train(&mut env, &mut EnvReward, 301, |_| {})
        .unwrap();
    let (outcome, shapes) = gemm::trace(|| trainer.step(&mut env, &mut EnvReward).unwrap());
    assert!(outcome.update.is_some(), "the traced step did no update");
    shapes
}

/// The products of a batched forward of a (64, 64) network: the policy on up to 300
/// observations at once, the reward network on chunks of states.
fn forward_shapes(inputs: usize, outputs: usize, batch: usize) -> Vec<GemmShape> {
    let net = Mlp::new(
        &MlpArch::new(inputs, &[64, 64], outputs),
        &mut ChaCha8Rng::seed_from_u64(1),
    );
    let mut ws = net.workspace(batch);
    let x = DMatrix::from_element(inputs, batch, 0.5f32);
    gemm::trace(|| {
        net.forward(&x, &mut ws);
    })
    .1
}

/// A value whose magnitude is spread over 2^±12, with some exact zeros of either sign, so that
/// sums of products lose different low bits depending on the order they are added in.
fn mixed(rng: &mut ChaCha8Rng) -> f32 {
    match rng.gen_range(0..40) {
        0 => 0.0,
        1 => -0.0,
        _ => {
            let mantissa: f32 = rng.gen_range(-1.0..1.0);
            mantissa * (rng.gen_range(-12..=12) as f32).exp2()
        }
    }
}

fn random(rows: usize, cols: usize, rng: &mut ChaCha8Rng) -> DMatrix<f32> {
    DMatrix::from_fn(rows, cols, |_, _| mixed(rng))
}

/// Compares the unpacked kernel, and `gemm` as the networks call it, with `sgemm` on random
/// operands of `shape`; returns a description of the first differing element.
fn compare(shape: &GemmShape, beta: f32, rng: &mut ChaCha8Rng) -> Result<(), String> {
    let GemmShape {
        m,
        k,
        n,
        trans_a,
        trans_b,
        ..
    } = *shape;
    let a = if trans_a {
        random(k, m, rng)
    } else {
        random(m, k, rng)
    };
    let b = if trans_b {
        random(n, k, rng)
    } else {
        random(k, n, rng)
    };
    // With β == 0 the old C must be ignored: NaN there would show through.
    let c0 = if beta == 0.0 {
        DMatrix::from_element(m, n, f32::NAN)
    } else {
        random(m, n, rng)
    };
    let mut expected = c0.clone();
    gemm::gemm_matrixmultiply(1.0, &a, trans_a, &b, trans_b, beta, &mut expected);
    let mut unpacked = c0.clone();
    if !gemm::gemm_unpacked(&a, trans_a, &b, trans_b, beta, &mut unpacked) {
        return Err("the unpacked kernel declined the product".into());
    }
    let mut dispatched = c0;
    gemm::gemm(1.0, &a, trans_a, &b, trans_b, beta, &mut dispatched);
    for (name, got) in [("unpacked", &unpacked), ("gemm", &dispatched)] {
        let first = got
            .iter()
            .zip(expected.iter())
            .position(|(g, e)| g.to_bits() != e.to_bits());
        if let Some(idx) = first {
            return Err(format!(
                "{name}: element ({}, {}) is {:e}, sgemm gives {:e}",
                idx % m,
                idx / m,
                got.as_slice()[idx],
                expected.as_slice()[idx]
            ));
        }
    }
    Ok(())
}

/// Whether the unpacked kernel must run here: built with AVX-512 intrinsics (the build
/// script's `smirl_avx512`, Rust ≥ 1.89) on a CPU with the features it checks.
fn kernel_expected() -> bool {
    #[cfg(all(target_arch = "x86_64", smirl_avx512))]
    {
        is_x86_feature_detected!("avx512f")
            && is_x86_feature_detected!("fma")
            && is_x86_feature_detected!("avx2")
    }
    #[cfg(not(all(target_arch = "x86_64", smirl_avx512)))]
    {
        false
    }
}

fn check_all(shapes: &BTreeSet<(usize, usize, usize, bool, bool)>, betas: &[f32]) {
    assert_eq!(gemm_unpacked::supported(), kernel_expected());
    if !gemm_unpacked::supported() {
        eprintln!("no AVX-512 kernel in this build or CPU: every product goes to sgemm");
        return;
    }
    let mut rng = ChaCha8Rng::seed_from_u64(56);
    let mut failures = vec![];
    for &(m, k, n, trans_a, trans_b) in shapes {
        let shape = GemmShape {
            m,
            k,
            n,
            trans_a,
            trans_b,
            epilogue: Epilogue::Beta,
        };
        for &beta in betas {
            if let Err(e) = compare(&shape, beta, &mut rng) {
                failures.push(format!("{shape:?} beta {beta}: {e}"));
            }
        }
    }
    assert!(
        failures.is_empty(),
        "{} of {} products differ from sgemm:\n{}",
        failures.len(),
        shapes.len() * betas.len(),
        failures[..failures.len().min(20)].join("\n")
    );
}

fn key(s: &GemmShape) -> (usize, usize, usize, bool, bool) {
    (s.m, s.k, s.n, s.trans_a, s.trans_b)
}

#[test]
fn bits_match_sgemm_on_the_products_smirl_performs() {
    let mut shapes = BTreeSet::new();
    for (obs, act) in [(17, 2), (24, 2), (2, 1)] {
        let traced = sac_update_shapes(obs, act);
        assert!(
            traced.len() > 30,
            "{} products in a SAC update",
            traced.len()
        );
        shapes.extend(traced.iter().map(key));
    }
    // A SAC update multiplies by weights (W x), forms weight gradients (dy xᵀ) and
    // propagates back (Wᵀ dy): all three layouts must be among the traced products.
    for layout in [(false, false), (false, true), (true, false)] {
        assert!(
            shapes.iter().any(|s| (s.3, s.4) == layout),
            "no traced product with (trans_a, trans_b) = {layout:?}"
        );
    }
    for inputs in 17..=24 {
        for batch in [1, 7, 50, 255, 256, 300] {
            for outputs in [1, 4] {
                shapes.extend(forward_shapes(inputs, outputs, batch).iter().map(key));
            }
        }
    }
    check_all(&shapes, &[0.0, 1.0, 0.5]);
}

#[test]
fn bits_match_sgemm_on_edge_sizes() {
    // Around the 16-lane vectors and 64-row tiles of the unpacked kernel, sgemm's 16×16 tiles
    // and its 256-deep k blocks (513: three blocks).
    const EDGES: [usize; 13] = [1, 7, 8, 9, 17, 63, 64, 65, 255, 256, 257, 300, 513];
    const OTHERS: [usize; 4] = [1, 9, 64, 130];
    let mut shapes = BTreeSet::new();
    for &e in &EDGES {
        for &x in &OTHERS {
            for &y in &OTHERS {
                for trans_a in [false, true] {
                    for trans_b in [false, true] {
                        shapes.insert((e, x, y, trans_a, trans_b));
                        shapes.insert((x, e, y, trans_a, trans_b));
                        shapes.insert((x, y, e, trans_a, trans_b));
                    }
                }
            }
        }
    }
    check_all(&shapes, &[0.0, 1.0]);
}

#[test]
fn unpacked_kernel_declines_empty_products() {
    let a = DMatrix::<f32>::zeros(3, 0);
    let b = DMatrix::<f32>::zeros(0, 4);
    let mut c = DMatrix::from_element(3, 4, 2.0f32);
    assert!(!gemm::gemm_unpacked(&a, false, &b, false, 1.0, &mut c));
    gemm::gemm(1.0, &a, false, &b, false, 0.5, &mut c);
    assert!(c.iter().all(|&x| x == 1.0), "k = 0 scales C by beta");
}

/// Biases made of the values whose handling could differ between `b + acc` and `1·b + acc`
/// or between a vector max and `f32::max`: zeros of either sign, quiet and signalling NaNs of
/// either sign with payloads, infinities, subnormals, then ordinary mixed values.
fn special_bias(m: usize, rng: &mut ChaCha8Rng) -> Vec<f32> {
    const SPECIAL: [u32; 12] = [
        0x0000_0000, // +0
        0x8000_0000, // −0
        0x7fc0_0000, // quiet NaN
        0xffc1_2345, // negative quiet NaN with a payload
        0x7fa0_0001, // signalling NaN
        0x7f80_0000, // +inf
        0xff80_0000, // −inf
        0x0000_0001, // smallest subnormal
        0x8000_0001, // its negative
        0x007f_ffff, // largest subnormal
        0x807f_ffff, // its negative
        0x0080_0000, // smallest normal
    ];
    (0..m)
        .map(|i| match SPECIAL.get(i % 24) {
            Some(&bits) => f32::from_bits(bits),
            None => mixed(rng),
        })
        .collect()
}

/// `x` with, in a few columns, an infinity or a NaN with a payload of its own, so that some
/// sums are ±inf (meeting a bias of the other sign: NaN) or NaN (meeting a NaN bias).
fn special_input(k: usize, n: usize, rng: &mut ChaCha8Rng) -> DMatrix<f32> {
    let mut x = random(k, n, rng);
    for j in 0..n {
        let p = j % k;
        match j % 9 {
            3 => x[(p, j)] = f32::INFINITY,
            5 => x[(p, j)] = f32::NEG_INFINITY,
            7 => x[(p, j)] = f32::from_bits(0x7fc5_4321),
            _ => {}
        }
    }
    x
}

/// Equal bits, or both NaN. Which NaN an addition returns when both operands are NaN depends
/// on their order, which LLVM may swap (addition commutes): the same source compiled twice can
/// return either payload and sign, and the unpacked kernel and `sgemm` already differ there.
/// NaNs stop training, so their payloads reach no output.
fn same(got: f32, want: f32) -> bool {
    got.to_bits() == want.to_bits() || (got.is_nan() && want.is_nan())
}

/// `gemm`'s signature: `gemm` itself or `gemm_matrixmultiply`.
type Product = fn(f32, &DMatrix<f32>, bool, &DMatrix<f32>, bool, f32, &mut DMatrix<f32>);

/// The dense forward as it was computed before `gemm_bias`: the bias copied into every
/// column, the product added with β = 1, then the ReLU as a separate pass.
fn copy_then_beta_one(
    w: &DMatrix<f32>,
    x: &DMatrix<f32>,
    bias: &[f32],
    relu: bool,
    product: Product,
) -> DMatrix<f32> {
    let mut y = DMatrix::from_fn(w.nrows(), x.ncols(), |i, _| bias[i]);
    product(1.0, w, false, x, false, 1.0, &mut y);
    if relu {
        for v in y.as_mut_slice() {
            *v = v.max(0.0);
        }
    }
    y
}

/// Compares `gemm_bias` (and its matrixmultiply path) with [`copy_then_beta_one`] through
/// `gemm` and through `sgemm`, for (m, k, n), both with and without ReLU, with ordinary and
/// special operands; returns the differences found.
fn compare_bias(m: usize, k: usize, n: usize, rng: &mut ChaCha8Rng) -> Vec<String> {
    let mut failures = vec![];
    for special in [false, true] {
        let w = random(m, k, rng);
        let (x, bias) = if special {
            (special_input(k, n, rng), special_bias(m, rng))
        } else {
            (random(k, n, rng), (0..m).map(|_| mixed(rng)).collect())
        };
        for relu in [false, true] {
            let expected = copy_then_beta_one(&w, &x, &bias, relu, gemm::gemm);
            let via_sgemm = copy_then_beta_one(&w, &x, &bias, relu, gemm::gemm_matrixmultiply);
            // C is written, never read: NaN there must not show through.
            let mut fused = DMatrix::from_element(m, n, f32::NAN);
            gemm::gemm_bias(&w, &x, &bias, relu, &mut fused);
            let mut fallback = DMatrix::from_element(m, n, f32::NAN);
            gemm::gemm_bias_matrixmultiply(&w, &x, &bias, relu, &mut fallback);
            // The fused entry against the old path as it ran where the kernel runs (gemm),
            // and the fallback against the old path where it does not (sgemm): the two old
            // paths themselves may return different NaNs (sgemm's α·acc step).
            for (name, got, want) in [
                ("gemm_bias", &fused, &expected),
                ("gemm_bias_matrixmultiply", &fallback, &via_sgemm),
            ] {
                let first = got.iter().zip(want.iter()).position(|(g, e)| !same(*g, *e));
                if let Some(idx) = first {
                    failures.push(format!(
                        "m {m} k {k} n {n} relu {relu} special {special}: {name} element ({}, {}) \
                         is {:#010x}, the copy and beta 1 give {:#010x}",
                        idx % m,
                        idx / m,
                        got.as_slice()[idx].to_bits(),
                        want.as_slice()[idx].to_bits()
                    ));
                }
            }
        }
    }
    failures
}

fn check_bias(shapes: &BTreeSet<(usize, usize, usize)>) {
    assert_eq!(gemm_unpacked::supported(), kernel_expected());
    if !gemm_unpacked::supported() {
        eprintln!("no AVX-512 kernel in this build or CPU: gemm_bias copies and calls sgemm");
    }
    let mut rng = ChaCha8Rng::seed_from_u64(57);
    let failures: Vec<String> = shapes
        .iter()
        .flat_map(|&(m, k, n)| compare_bias(m, k, n, &mut rng))
        .collect();
    assert!(
        failures.is_empty(),
        "{} dense forwards differ from copy + beta 1:\n{}",
        failures.len(),
        failures[..failures.len().min(20)].join("\n")
    );
}

#[test]
fn dense_forward_bits_match_copy_and_beta_one_on_the_products_smirl_performs() {
    let mut traced = vec![];
    for (obs, act) in [(17, 2), (24, 2), (2, 1)] {
        traced.extend(sac_update_shapes(obs, act));
    }
    for inputs in [17, 24] {
        for batch in [1, 7, 256, 300] {
            traced.extend(forward_shapes(inputs, 4, batch));
        }
    }
    // Hidden layers go through the fused ReLU, output layers through the bias alone, and
    // nothing else takes a bias.
    for epilogue in [Epilogue::Bias, Epilogue::BiasRelu] {
        assert!(
            traced.iter().any(|s| s.epilogue == epilogue),
            "no traced product with {epilogue:?}"
        );
    }
    for s in &traced {
        if s.epilogue == Epilogue::BiasRelu {
            assert_eq!(s.m, 64, "a ReLU on a layer of {} units: {s:?}", s.m);
        }
        if s.epilogue != Epilogue::Beta {
            assert!(!s.trans_a && !s.trans_b, "{s:?}");
        }
    }
    let shapes = traced
        .iter()
        .filter(|s| s.epilogue != Epilogue::Beta)
        .map(|s| (s.m, s.k, s.n))
        .collect();
    check_bias(&shapes);
}

#[test]
fn dense_forward_bits_match_copy_and_beta_one_on_edge_sizes() {
    // m around the 16-lane vectors and 64-row strips (not multiples of 16 included), k across
    // one, two and three 256-deep blocks (the bias goes with the first, the ReLU with the
    // last), n = 1 and around the column tiles.
    const EDGES: [usize; 11] = [1, 7, 16, 17, 63, 64, 65, 255, 256, 257, 513];
    const OTHERS: [usize; 4] = [1, 9, 64, 130];
    let mut shapes = BTreeSet::new();
    for &e in &EDGES {
        for &x in &OTHERS {
            for &y in &OTHERS {
                shapes.insert((e, x, y));
                shapes.insert((x, e, y));
                shapes.insert((x, y, e));
            }
        }
    }
    check_bias(&shapes);
}
