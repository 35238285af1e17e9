//! Gradients of every layer against central finite differences, Adam against a hand-computed
//! step, the squashed Gaussian's log-density against numerical integration, and the gemm
//! wrapper against a naive product.

use nalgebra::DMatrix;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use smirl::nn::gemm::gemm;
use smirl::nn::{
    gaussian, Adam, AdamConfig, BackwardMode, ByteReader, ByteWriter, Dense, Mlp, MlpArch,
};

fn random_matrix(r: usize, c: usize, rng: &mut ChaCha8Rng) -> DMatrix<f32> {
    DMatrix::from_fn(r, c, |_, _| rng.gen_range(-1.0..1.0))
}

/// Smooth test loss L = Σ c⊙y + ½ Σ y², accumulated in f64; ∂L/∂y = c + y.
fn loss(y: &DMatrix<f32>, c: &DMatrix<f32>) -> f64 {
    y.iter()
        .zip(c.iter())
        .map(|(&y, &c)| f64::from(c) * f64::from(y) + 0.5 * f64::from(y) * f64::from(y))
        .sum()
}

fn d_loss(y: &DMatrix<f32>, c: &DMatrix<f32>) -> DMatrix<f32> {
    c + y
}

fn assert_close(analytic: f32, numeric: f64, what: &str) {
    let tol = 5e-3 + 1e-2 * numeric.abs();
    assert!(
        (f64::from(analytic) - numeric).abs() <= tol,
        "{what}: analytic {analytic}, numeric {numeric}"
    );
}

const H: f32 = 1e-3;

#[test]
fn dense_gradients_match_finite_differences() {
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    let mut layer = Dense::new(5, 3, &mut rng);
    let mut x = random_matrix(5, 4, &mut rng);
    let c = random_matrix(3, 4, &mut rng);
    let mut y = DMatrix::zeros(3, 4);
    layer.forward(&x, &mut y);
    let dy = d_loss(&y, &c);
    let mut dx = DMatrix::zeros(5, 4);
    layer.backward(&x, &dy, Some(&mut dx), true);

    let eval = |layer: &Dense, x: &DMatrix<f32>| {
        let mut y = DMatrix::zeros(3, 4);
        layer.forward(x, &mut y);
        loss(&y, &c)
    };
    for i in 0..layer.w.len() {
        let mut p = layer.clone();
        p.w.as_mut_slice()[i] += H;
        let mut m = layer.clone();
        m.w.as_mut_slice()[i] -= H;
        let num = (eval(&p, &x) - eval(&m, &x)) / (2.0 * f64::from(H));
        assert_close(layer.grad_w.as_slice()[i], num, &format!("dW[{i}]"));
    }
    for i in 0..layer.b.len() {
        let mut p = layer.clone();
        p.b.as_mut_slice()[i] += H;
        let mut m = layer.clone();
        m.b.as_mut_slice()[i] -= H;
        let num = (eval(&p, &x) - eval(&m, &x)) / (2.0 * f64::from(H));
        assert_close(layer.grad_b.as_slice()[i], num, &format!("db[{i}]"));
    }
    for i in 0..x.len() {
        let orig = x.as_slice()[i];
        x.as_mut_slice()[i] = orig + H;
        let lp = eval(&layer, &x);
        x.as_mut_slice()[i] = orig - H;
        let lm = eval(&layer, &x);
        x.as_mut_slice()[i] = orig;
        assert_close(dx.as_slice()[i], (lp - lm) / (2.0 * f64::from(H)), "dx");
    }
}

#[test]
fn mlp_gradients_match_finite_differences() {
    let mut rng = ChaCha8Rng::seed_from_u64(2);
    let arch = MlpArch::new(4, &[8, 6], 3);
    let mut net = Mlp::new(&arch, &mut rng);
    let batch = 5;
    let mut x = random_matrix(4, batch, &mut rng);
    let c = random_matrix(3, batch, &mut rng);
    let mut ws = net.workspace(batch);
    let y = net.forward(&x, &mut ws).clone();
    let dy = d_loss(&y, &c);
    let mut dx = DMatrix::zeros(4, batch);
    net.backward(&x, &mut ws, &dy, Some(&mut dx), BackwardMode::Params);

    let eval = |net: &Mlp, x: &DMatrix<f32>| {
        let mut ws = net.workspace(batch);
        loss(net.forward(x, &mut ws), &c)
    };
    let mut checked = 0;
    for l in 0..net.layers.len() {
        for (is_bias, len) in [
            (false, net.layers[l].w.len()),
            (true, net.layers[l].b.len()),
        ] {
            for i in 0..len {
                let bump = |d: f32| {
                    let mut n = net.clone();
                    let t = if is_bias {
                        &mut n.layers[l].b
                    } else {
                        &mut n.layers[l].w
                    };
                    t.as_mut_slice()[i] += d;
                    eval(&n, &x)
                };
                let num = (bump(H) - bump(-H)) / (2.0 * f64::from(H));
                let ana = if is_bias {
                    net.layers[l].grad_b.as_slice()[i]
                } else {
                    net.layers[l].grad_w.as_slice()[i]
                };
                assert_close(ana, num, &format!("layer {l} bias={is_bias} [{i}]"));
                checked += 1;
            }
        }
    }
    assert_eq!(checked, net.num_params());
    for i in 0..x.len() {
        let orig = x.as_slice()[i];
        x.as_mut_slice()[i] = orig + H;
        let lp = eval(&net, &x);
        x.as_mut_slice()[i] = orig - H;
        let lm = eval(&net, &x);
        x.as_mut_slice()[i] = orig;
        assert_close(dx.as_slice()[i], (lp - lm) / (2.0 * f64::from(H)), "mlp dx");
    }

    // Input-only mode gives the same input gradient and leaves parameter gradients alone.
    let grads_before: Vec<f32> = net.layers[0].grad_w.as_slice().to_vec();
    let c2 = random_matrix(3, batch, &mut rng);
    net.forward(&x, &mut ws);
    let mut dx2 = DMatrix::zeros(4, batch);
    net.backward(&x, &mut ws, &c2, Some(&mut dx2), BackwardMode::InputOnly);
    assert_eq!(net.layers[0].grad_w.as_slice(), &grads_before[..]);
    let mut dx3 = DMatrix::zeros(4, batch);
    net.backward(&x, &mut ws, &c2, Some(&mut dx3), BackwardMode::Params);
    assert_eq!(dx2, dx3);
}

/// Loss on the squashed Gaussian's outputs: Σ c⊙a + Σ d·log π.
fn gaussian_loss(head: &DMatrix<f32>, eps: &DMatrix<f32>, c: &DMatrix<f32>, d: &[f32]) -> f64 {
    let (a_dim, b) = eps.shape();
    let mut pre = DMatrix::zeros(a_dim, b);
    let mut act = DMatrix::zeros(a_dim, b);
    let mut lp = vec![0.0; b];
    gaussian::sample(head, eps, &mut pre, &mut act, &mut lp);
    let mut l = 0.0;
    for (a, c) in act.iter().zip(c.iter()) {
        l += f64::from(*a) * f64::from(*c);
    }
    for (lp, d) in lp.iter().zip(d) {
        l += f64::from(*lp) * f64::from(*d);
    }
    l
}

#[test]
fn squashed_gaussian_gradients_match_finite_differences() {
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let (a_dim, b) = (2, 4);
    let mut head = random_matrix(2 * a_dim, b, &mut rng);
    // One log-std beyond the upper clamp: its gradient must be zero.
    head[(a_dim, 3)] = 2.5;
    let eps = random_matrix(a_dim, b, &mut rng);
    let c = random_matrix(a_dim, b, &mut rng);
    let d: Vec<f32> = (0..b).map(|_| rng.gen_range(-1.0..1.0)).collect();
    let mut pre = DMatrix::zeros(a_dim, b);
    let mut act = DMatrix::zeros(a_dim, b);
    let mut lp = vec![0.0; b];
    gaussian::sample(&head, &eps, &mut pre, &mut act, &mut lp);
    let mut d_head = DMatrix::zeros(2 * a_dim, b);
    gaussian::backward(&head, &eps, &act, &c, &d, &mut d_head);
    for i in 0..head.len() {
        let mut hp = head.clone();
        hp.as_mut_slice()[i] += H;
        let mut hm = head.clone();
        hm.as_mut_slice()[i] -= H;
        let num = (gaussian_loss(&hp, &eps, &c, &d) - gaussian_loss(&hm, &eps, &c, &d))
            / (2.0 * f64::from(H));
        assert_close(d_head.as_slice()[i], num, &format!("d_head[{i}]"));
    }
    assert_eq!(d_head[(a_dim, 3)], 0.0);
}

/// log π(a) of a squashed action `a ∈ (−1, 1)` under one mean and log-std (clamped as the
/// policy clamps it), in `f64`, by the change of variables a = tanh(u).
fn log_prob_of_action(mean: f32, log_std: f32, a: f64) -> f64 {
    let ls = f64::from(log_std.clamp(gaussian::LOG_STD_MIN, gaussian::LOG_STD_MAX));
    let z = (a.atanh() - f64::from(mean)) / ls.exp();
    -0.5 * z * z - ls - 0.5 * (2.0 * std::f64::consts::PI).ln() - (1.0 - a * a).ln()
}

#[test]
fn squashed_gaussian_density_integrates_to_one_and_matches_samples() {
    for &(mean, log_std) in &[(0.3f32, -0.5f32), (-1.0, 0.5), (0.0, -3.0)] {
        // Midpoint rule over (−1, 1).
        let n = 400_000;
        let h = 2.0 / n as f64;
        let total: f64 = (0..n)
            .map(|i| -1.0 + (i as f64 + 0.5) * h)
            .map(|a| log_prob_of_action(mean, log_std, a).exp() * h)
            .sum();
        assert!(
            (total - 1.0).abs() < 1e-3,
            "mean {mean} log-std {log_std}: density integrates to {total}"
        );
        // The sampler's log-prob equals the change-of-variables density at its own sample.
        let mut rng = ChaCha8Rng::seed_from_u64(4);
        for _ in 0..100 {
            let e: f32 = rng.sample(rand_distr::StandardNormal);
            let head = DMatrix::from_column_slice(2, 1, &[mean, log_std]);
            let eps = DMatrix::from_element(1, 1, e);
            let mut pre = DMatrix::zeros(1, 1);
            let mut act = DMatrix::zeros(1, 1);
            let mut lp = [0.0f32];
            gaussian::sample(&head, &eps, &mut pre, &mut act, &mut lp);
            let a = f64::from(act[(0, 0)]);
            if a.abs() > 0.999 {
                continue; // atanh of a rounded f32 action is too inexact there
            }
            let want = log_prob_of_action(mean, log_std, a);
            assert!(
                (f64::from(lp[0]) - want).abs() < 2e-3 * want.abs().max(1.0),
                "log-prob {} vs density {want}",
                lp[0]
            );
        }
    }
}

#[test]
fn adam_matches_hand_computed_steps() {
    let cfg = AdamConfig {
        lr: 0.1,
        beta1: 0.9,
        beta2: 0.999,
        eps: 1e-8,
    };
    let mut adam = Adam::new(cfg, &[2]);
    let mut p = [1.0f32, -2.0];
    adam.step_tensors(&mut [(&mut p[..], &[0.5f32, -0.1][..])]);
    // Step 1: m̂ = g, v̂ = g², so the step is lr·g/(|g| + ε) ≈ lr·sign(g).
    assert!(
        (p[0] - 0.9).abs() < 1e-6 && (p[1] + 1.9).abs() < 1e-6,
        "{p:?}"
    );
    adam.step_tensors(&mut [(&mut p[..], &[0.2f32, 0.3][..])]);
    // Step 2 by hand: m = 0.9·0.1·g1 + 0.1·g2, v = 0.999·0.001·g1² + 0.001·g2²,
    // p -= lr/(1−0.9²) · m / (√v/√(1−0.999²) + ε).
    for (i, (g1, g2, p1)) in [(0.5f64, 0.2f64, 0.9f64), (-0.1, 0.3, -1.9)]
        .iter()
        .enumerate()
    {
        let m = 0.9 * 0.1 * g1 + 0.1 * g2;
        let v = 0.999 * 0.001 * g1 * g1 + 0.001 * g2 * g2;
        let want = p1 - 0.1 / (1.0 - 0.81) * m / (v.sqrt() / (1.0 - 0.998001f64).sqrt() + 1e-8);
        assert!(
            (f64::from(p[i]) - want).abs() < 1e-5,
            "component {i}: {} vs {want}",
            p[i]
        );
    }
    assert_eq!(adam.t, 2);
}

#[test]
fn gemm_matches_naive_product_for_small_and_transposed_shapes() {
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    for &(m, k, n) in &[(1, 1, 1), (3, 5, 2), (2, 7, 4), (17, 5, 3), (64, 24, 9)] {
        for ta in [false, true] {
            for tb in [false, true] {
                let a = if ta {
                    random_matrix(k, m, &mut rng)
                } else {
                    random_matrix(m, k, &mut rng)
                };
                let b = if tb {
                    random_matrix(n, k, &mut rng)
                } else {
                    random_matrix(k, n, &mut rng)
                };
                let oa = if ta { a.transpose() } else { a.clone() };
                let ob = if tb { b.transpose() } else { b.clone() };
                let c0 = random_matrix(m, n, &mut rng);
                let mut c = c0.clone();
                gemm(0.5, &a, ta, &b, tb, 2.0, &mut c);
                for i in 0..m {
                    for j in 0..n {
                        let mut s = 0.0f64;
                        for l in 0..k {
                            s += f64::from(oa[(i, l)]) * f64::from(ob[(l, j)]);
                        }
                        let want = 0.5 * s + 2.0 * f64::from(c0[(i, j)]);
                        assert!((f64::from(c[(i, j)]) - want).abs() < 1e-4);
                    }
                }
            }
        }
    }
}

#[test]
fn adam_moments_of_a_parameter_without_gradient_reach_zero() {
    // A parameter whose gradient stops (a dead ReLU unit) must not keep subnormal moments:
    // they cost a microcode assist per vector instruction on x86 (the reason for the flush).
    let mut adam = Adam::new(AdamConfig::with_lr(1e-3), &[2]);
    let mut p = [0.5f32, -0.25];
    adam.step_tensors(&mut [(&mut p[..], &[0.3f32, -0.2][..])]);
    let mut ever_subnormal = false;
    for _ in 0..200_000 {
        adam.step_tensors(&mut [(&mut p[..], &[0.0f32, 0.0][..])]);
        let mut w = ByteWriter::new();
        adam.write(&mut w);
        let mut r = ByteReader::new(&w.bytes);
        r.u64("t").unwrap();
        assert_eq!(r.usize("tensors").unwrap(), 1);
        let floats = [r.f32s("m").unwrap(), r.f32s("v").unwrap()].concat();
        ever_subnormal |= floats.iter().any(|x| x.is_subnormal());
    }
    assert!(!ever_subnormal, "a moment was stored subnormal");
    let p_after = p;
    adam.step_tensors(&mut [(&mut p[..], &[0.0f32, 0.0][..])]);
    assert_eq!(p, p_after, "zero moments move nothing");
}
