//! Soft value iteration and the MaxEnt gradient against brute force on a tiny MDP: every
//! action sequence of the horizon is enumerated.

use smirl::irl::tabular::{MaxEntConfig, MaxEntIrl, Optimizer, StateActionFeatures, NO_FEATURE};
use smirl::rl::tabular::{
    expected_visitation, finite_horizon_greedy, soft_backward, DetMdp, FiniteSoftPolicy,
};

const S: usize = 4;
const A: usize = 3;
const T: usize = 5;

fn tiny() -> (DetMdp, StateActionFeatures) {
    // Arbitrary deterministic transitions, with self-loops and a state reached two ways.
    let next = vec![1, 2, 0, 2, 3, 1, 3, 0, 2, 3, 3, 1];
    let mdp = DetMdp::new(S, A, next).unwrap();
    // Three one-hot features, some pairs featureless.
    let feature = vec![
        0, 1, NO_FEATURE, 1, 2, 0, 2, NO_FEATURE, 1, 0, 2, NO_FEATURE,
    ];
    (
        mdp,
        StateActionFeatures {
            n_features: 3,
            feature,
        },
    )
}

/// Discounted soft value iteration to its fixed point, written from the definition
/// (`V(s) = logsumexp_a [r(s, a) + γ V(next(s, a))]`, Jacobi sweeps): the reference the
/// finite-horizon soft backward pass must approach as its horizon grows.
fn soft_value_iteration(mdp: &DetMdp, r: &[f64], gamma: f64) -> Vec<f64> {
    let mut v = vec![0.0; S];
    for _ in 0..100_000 {
        let next: Vec<f64> = (0..S)
            .map(|s| {
                let q: Vec<f64> = (0..A)
                    .map(|a| r[s * A + a] + gamma * v[mdp.next(s, a)])
                    .collect();
                log_sum_exp(q.iter().copied())
            })
            .collect();
        let delta = next
            .iter()
            .zip(&v)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        v = next;
        if delta < 1e-14 {
            break;
        }
    }
    v
}

#[test]
fn soft_value_iteration_is_a_log_sum_exp_fixed_point() {
    let (mdp, f) = tiny();
    let r = f.reward(&[0.5, -0.2, 0.9]);
    let v = soft_value_iteration(&mdp, &r, 0.8);
    for s in 0..S {
        let q: Vec<f64> = (0..A)
            .map(|a| r[s * A + a] + 0.8 * v[mdp.next(s, a)])
            .collect();
        assert!((log_sum_exp(q.iter().copied()) - v[s]).abs() < 1e-10);
        // The soft-optimal policy exp(Q − V) is a distribution.
        let total: f64 = q.iter().map(|q| (q - v[s]).exp()).sum();
        assert!((total - 1.0).abs() < 1e-12);
    }
}

/// One enumerated trajectory: states, actions, return, feature counts.
type Traj = (Vec<usize>, Vec<usize>, f64, Vec<f64>);

/// All action sequences of length `horizon` from `s0`.
fn enumerate(
    mdp: &DetMdp,
    f: &StateActionFeatures,
    r: &[f64],
    s0: usize,
    horizon: usize,
) -> Vec<Traj> {
    let mut out = Vec::new();
    for code in 0..A.pow(horizon as u32) {
        let mut c = code;
        let mut s = s0;
        let (mut states, mut actions) = (Vec::new(), Vec::new());
        let mut ret = 0.0;
        let mut counts = vec![0.0; f.n_features];
        for _ in 0..horizon {
            let a = c % A;
            c /= A;
            states.push(s);
            actions.push(a);
            ret += r[s * A + a];
            let feat = f.feature[s * A + a];
            if feat != NO_FEATURE {
                counts[feat as usize] += 1.0;
            }
            s = mdp.next(s, a);
        }
        out.push((states, actions, ret, counts));
    }
    out
}

fn log_sum_exp(xs: impl Iterator<Item = f64>) -> f64 {
    let v: Vec<f64> = xs.collect();
    let m = v.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    m + v.iter().map(|x| (x - m).exp()).sum::<f64>().ln()
}

#[test]
fn soft_backward_pass_and_visitation_match_enumeration() {
    let (mdp, f) = tiny();
    let theta = [0.7, -1.3, 0.4];
    let r = f.reward(&theta);
    let mut pol = FiniteSoftPolicy::default();
    soft_backward(&mdp, &r, 1.0, T, &mut pol).unwrap();
    for s0 in 0..S {
        let trajs = enumerate(&mdp, &f, &r, s0, T);
        let log_z = log_sum_exp(trajs.iter().map(|t| t.2));
        assert!((pol.v0()[s0] - log_z).abs() < 1e-10, "V0({s0})");
        // The time-indexed soft policy generates exactly P(τ) = exp(R(τ) − log Z).
        for (states, actions, ret, _) in &trajs {
            let p: f64 = (0..T)
                .map(|t| pol.pi[t * S * A + states[t] * A + actions[t]])
                .product();
            assert!((p - (ret - log_z).exp()).abs() < 1e-12);
        }
        // Expected state-action visitation.
        let mut p0 = vec![0.0; S];
        p0[s0] = 1.0;
        let mut visits = vec![0.0; S * A];
        let mut work = Vec::new();
        expected_visitation(&mdp, &pol.pi, &p0, T, 1.0, &mut visits, &mut work).unwrap();
        let mut brute = [0.0; S * A];
        for (states, actions, ret, _) in &trajs {
            let p = (ret - log_z).exp();
            for t in 0..T {
                brute[states[t] * A + actions[t]] += p;
            }
        }
        for k in 0..S * A {
            assert!((visits[k] - brute[k]).abs() < 1e-10, "pair {k}");
        }
    }
}

#[test]
fn maxent_gradient_and_likelihood_match_enumeration_and_finite_differences() {
    let (mdp, f) = tiny();
    // Demonstrations: fixed action sequences from two start states, of two lengths (one
    // backward pass serves both).
    let seqs: Vec<(usize, Vec<usize>)> = vec![
        (0, vec![0, 1, 1, 2, 0]),
        (0, vec![1, 1, 0, 0, 2]),
        (2, vec![2, 0, 1, 1, 1]),
        (1, vec![2, 2, 0]),
    ];
    let demos: Vec<Vec<(u32, u8)>> = seqs
        .iter()
        .map(|(s0, acts)| {
            let mut s = *s0;
            acts.iter()
                .map(|&a| {
                    let pair = (s as u32, a as u8);
                    s = mdp.next(s, a);
                    pair
                })
                .collect()
        })
        .collect();
    let cfg = MaxEntConfig::default();
    let mut irl = MaxEntIrl::new(&mdp, &f, &demos, cfg).unwrap();
    let theta = vec![0.3, -0.8, 1.1];
    let r = f.reward(&theta);

    // Brute force: mean log-likelihood and its gradient μ_demo − E_θ[μ].
    let mut ll = 0.0;
    let mut grad = vec![0.0; 3];
    for (s0, acts) in &seqs {
        let trajs = enumerate(&mdp, &f, &r, *s0, acts.len());
        let log_z = log_sum_exp(trajs.iter().map(|t| t.2));
        let demo = trajs
            .iter()
            .find(|t| t.1.as_slice() == acts.as_slice())
            .unwrap();
        ll += demo.2 - log_z;
        for k in 0..3 {
            grad[k] += demo.3[k];
            for (_, _, ret, counts) in &trajs {
                grad[k] -= (ret - log_z).exp() * counts[k];
            }
        }
    }
    let n = seqs.len() as f64;
    ll /= n;
    grad.iter_mut().for_each(|g| *g /= n);

    let mut g = vec![0.0; 3];
    let info = irl.gradient_at(&theta, &mut g).unwrap();
    assert!((info.log_likelihood - ll).abs() < 1e-10);
    for k in 0..3 {
        assert!(
            (g[k] - grad[k]).abs() < 1e-10,
            "component {k}: {g:?} vs {grad:?}"
        );
    }
    // Central finite differences of the likelihood agree with the analytic gradient.
    for k in 0..3 {
        let h = 1e-5;
        let mut tp = theta.clone();
        tp[k] += h;
        let mut tm = theta.clone();
        tm[k] -= h;
        let mut scratch = vec![0.0; 3];
        let lp = irl.gradient_at(&tp, &mut scratch).unwrap().log_likelihood;
        let lm = irl.gradient_at(&tm, &mut scratch).unwrap().log_likelihood;
        assert!(((lp - lm) / (2.0 * h) - g[k]).abs() < 1e-6);
    }
    // Gradient ascent increases the likelihood.
    let first = irl.step().unwrap().log_likelihood;
    let mut last = first;
    for _ in 0..50 {
        last = irl.step().unwrap().log_likelihood;
    }
    assert!(last > first + 0.1, "{first} -> {last}");
}

#[test]
fn long_discounted_backward_pass_reaches_the_soft_value_iteration_fixed_point() {
    let (mdp, f) = tiny();
    let r = f.reward(&[0.5, -0.2, 0.9]);
    let gamma = 0.8;
    let v = soft_value_iteration(&mdp, &r, gamma);
    let mut pol = FiniteSoftPolicy::default();
    soft_backward(&mdp, &r, gamma, 300, &mut pol).unwrap();
    for (finite, infinite) in pol.v0().iter().zip(&v) {
        assert!((finite - infinite).abs() < 1e-9);
    }
}

#[test]
fn lbfgs_and_adam_reach_the_same_maximum_likelihood() {
    let (mdp, f) = tiny();
    let demos: Vec<Vec<(u32, u8)>> = [(0usize, [0usize, 1, 1, 2, 0]), (2, [2, 0, 1, 1, 1])]
        .iter()
        .map(|(s0, acts)| {
            let mut s = *s0;
            acts.iter()
                .map(|&a| {
                    let pair = (s as u32, a as u8);
                    s = mdp.next(s, a);
                    pair
                })
                .collect()
        })
        .collect();
    // A little L2 makes the optimum unique and finite whatever the demonstrations.
    let base = MaxEntConfig {
        l2: 0.1,
        ..MaxEntConfig::default()
    };
    let mut lbfgs = MaxEntIrl::new(&mdp, &f, &demos, base).unwrap();
    let mut steps = 0;
    while lbfgs.current_info().unwrap().grad_max > 1e-9 && steps < 100 {
        lbfgs.step().unwrap();
        steps += 1;
    }
    assert!(steps < 30, "L-BFGS took {steps} steps");
    let adam_cfg = MaxEntConfig {
        optimizer: Optimizer::Adam,
        lr: 0.05,
        ..base
    };
    let mut adam = MaxEntIrl::new(&mdp, &f, &demos, adam_cfg).unwrap();
    for _ in 0..5000 {
        adam.step().unwrap();
    }
    for k in 0..3 {
        assert!(
            (lbfgs.theta[k] - adam.theta[k]).abs() < 1e-3,
            "{:?} vs {:?}",
            lbfgs.theta,
            adam.theta
        );
    }
}

#[test]
fn finite_horizon_greedy_attains_the_best_enumerated_return() {
    let (mdp, f) = tiny();
    let r = f.reward(&[0.7, -1.3, 0.4]);
    let mut actions = Vec::new();
    let v0 = finite_horizon_greedy(&mdp, &r, 1.0, T, &mut actions).unwrap();
    for (s0, &v) in v0.iter().enumerate() {
        let best = enumerate(&mdp, &f, &r, s0, T)
            .iter()
            .map(|t| t.2)
            .fold(f64::NEG_INFINITY, f64::max);
        assert!((v - best).abs() < 1e-12);
        // Following the time-indexed policy collects exactly that return.
        let (mut s, mut ret) = (s0, 0.0);
        for t in 0..T {
            let a = actions[t * S + s] as usize;
            ret += r[s * A + a];
            s = mdp.next(s, a);
        }
        assert!((ret - best).abs() < 1e-12);
    }
}
