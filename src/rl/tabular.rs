//! Tabular solvers on finite deterministic MDPs: value iteration, soft (log-sum-exp) value
//! iteration, finite-horizon soft backward passes, expected visitation frequencies, and
//! Q-learning.
//!
//! Layout conventions, shared by every function here: states `0..S`, actions `0..A`; tables
//! indexed by `(s, a)` are flat `s * A + a`; rewards are per state-action pair (`r(s, a)`,
//! paid on taking `a` in `s`, e.g. for the label of the cell it lands on); time-indexed tables
//! are `t`-major (`t * S * A + s * A + a`). Every function allocates its buffers once per call
//! and none inside a sweep.
//!
//! Reward-machine products are built here too ([`DetMdp::product`]): state `u * n_cells +
//! cell`, and the machine is advanced by the label of the cell landed on.

use crate::rm::{LabelSet, RewardMachine};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// A call with tables of the wrong shape or a bad parameter.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum TabularError {
    #[error("{what} has length {got}, expected {expected}")]
    Shape {
        what: &'static str,
        expected: usize,
        got: usize,
    },
    #[error("transition ({state}, {action}) leads to state {target}, out of range (the MDP has {n_states} states)")]
    TargetOutOfRange {
        state: usize,
        action: usize,
        target: usize,
        n_states: usize,
    },
    #[error("{0}")]
    Parameter(String),
}

fn check_len(what: &'static str, got: usize, expected: usize) -> Result<(), TabularError> {
    if got == expected {
        Ok(())
    } else {
        Err(TabularError::Shape {
            what,
            expected,
            got,
        })
    }
}

/// A finite MDP with deterministic transitions `next[s * A + a]`.
#[derive(Clone, Debug, PartialEq)]
pub struct DetMdp {
    n_states: usize,
    n_actions: usize,
    next: Vec<u32>,
}

impl DetMdp {
    pub fn new(n_states: usize, n_actions: usize, next: Vec<u32>) -> Result<DetMdp, TabularError> {
        if n_states == 0 || n_actions == 0 {
            return Err(TabularError::Parameter(
                "an MDP needs at least one state and one action".into(),
            ));
        }
        check_len("transition table", next.len(), n_states * n_actions)?;
        if let Some(k) = next.iter().position(|&t| t as usize >= n_states) {
            return Err(TabularError::TargetOutOfRange {
                state: k / n_actions,
                action: k % n_actions,
                target: next[k] as usize,
                n_states,
            });
        }
        Ok(DetMdp {
            n_states,
            n_actions,
            next,
        })
    }

    /// The product of a deterministic labelled world (`world_next[cell * A + a]`, labels per
    /// cell) with a reward machine: state `u * n_cells + cell`; taking `a` in `(u, cell)`
    /// moves to `cell' = world_next(cell, a)` and `u' = δ(u, L(cell'))`.
    pub fn product(
        world_next: &[u32],
        n_actions: usize,
        cell_labels: &[LabelSet],
        rm: &RewardMachine,
    ) -> Result<DetMdp, TabularError> {
        let n_cells = cell_labels.len();
        let world = DetMdp::new(n_cells, n_actions, world_next.to_vec())?;
        let n_u = rm.n_states();
        let mut next = Vec::with_capacity(n_u * n_cells * n_actions);
        for u in 0..n_u {
            for c in 0..n_cells {
                for a in 0..n_actions {
                    let c2 = world.next(c, a);
                    let u2 = rm.next_state(u, cell_labels[c2]);
                    next.push((u2 * n_cells + c2) as u32);
                }
            }
        }
        DetMdp::new(n_u * n_cells, n_actions, next)
    }

    pub fn n_states(&self) -> usize {
        self.n_states
    }

    pub fn n_actions(&self) -> usize {
        self.n_actions
    }

    /// Number of state-action pairs.
    pub fn n_pairs(&self) -> usize {
        self.n_states * self.n_actions
    }

    #[inline]
    pub fn next(&self, s: usize, a: usize) -> usize {
        self.next[s * self.n_actions + a] as usize
    }

    pub fn table(&self) -> &[u32] {
        &self.next
    }
}

/// State values and action values of a solved MDP.
#[derive(Clone, Debug, PartialEq)]
pub struct Values {
    /// `v[s]`.
    pub v: Vec<f64>,
    /// `q[s * A + a]`.
    pub q: Vec<f64>,
    pub sweeps: usize,
    /// The last sweep changed no value by more than the tolerance.
    pub converged: bool,
}

/// Settings of an infinite-horizon (discounted) iteration.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Iteration {
    pub gamma: f64,
    /// Stop when no value changes by more than this in a sweep.
    pub tol: f64,
    pub max_sweeps: usize,
}

impl Iteration {
    fn check(&self) -> Result<(), TabularError> {
        if !(self.gamma >= 0.0 && self.gamma < 1.0) {
            return Err(TabularError::Parameter(format!(
                "discount {} must be in [0, 1) for an infinite horizon",
                self.gamma
            )));
        }
        if self.tol.is_nan() || self.tol <= 0.0 {
            return Err(TabularError::Parameter(format!(
                "tolerance {} must be positive",
                self.tol
            )));
        }
        Ok(())
    }
}

/// Discounted value iteration: `Q = r + γ V(s')`, `V = max_a Q`. `v_init` warm-starts it.
pub fn value_iteration(
    mdp: &DetMdp,
    reward: &[f64],
    it: Iteration,
    v_init: Option<&[f64]>,
) -> Result<Values, TabularError> {
    it.check()?;
    let (n_s, n_a) = (mdp.n_states, mdp.n_actions);
    check_len("reward table", reward.len(), n_s * n_a)?;
    let mut v = match v_init {
        Some(v0) => {
            check_len("initial values", v0.len(), n_s)?;
            v0.to_vec()
        }
        None => vec![0.0; n_s],
    };
    let mut q_s = vec![0.0; n_a];
    let mut sweeps = 0;
    let mut converged = false;
    while sweeps < it.max_sweeps {
        sweeps += 1;
        let mut delta: f64 = 0.0;
        for s in 0..n_s {
            let row = s * n_a;
            for a in 0..n_a {
                q_s[a] = reward[row + a] + it.gamma * v[mdp.next[row + a] as usize];
            }
            let x = q_s.iter().copied().fold(f64::NEG_INFINITY, f64::max);
            delta = delta.max((x - v[s]).abs());
            // In place (Gauss–Seidel): later states of the sweep already see the new value,
            // which converges to the same fixed point in fewer sweeps.
            v[s] = x;
        }
        if delta <= it.tol {
            converged = true;
            break;
        }
    }
    let mut q = vec![0.0; n_s * n_a];
    for (k, qk) in q.iter_mut().enumerate() {
        *qk = reward[k] + it.gamma * v[mdp.next[k] as usize];
    }
    Ok(Values {
        v,
        q,
        sweeps,
        converged,
    })
}

/// Greedy policy: the first action of maximal value in each state.
pub fn greedy_actions(q: &[f64], n_actions: usize) -> Vec<u8> {
    q.chunks_exact(n_actions)
        .map(|row| {
            let mut best = 0;
            for a in 1..n_actions {
                if row[a] > row[best] {
                    best = a;
                }
            }
            best as u8
        })
        .collect()
}

/// Exact discounted value of a deterministic stationary policy on a deterministic MDP:
/// every state's path ends in a cycle, whose value is closed-form
/// (`Σ_k γ^k r_k / (1 − γ^L)`); the states leading into it follow by `V = r + γ V(next)`.
/// O(S); `v` and `status` are reused buffers.
fn evaluate_deterministic(
    mdp: &DetMdp,
    reward: &[f64],
    gamma: f64,
    policy: &[u8],
    v: &mut [f64],
    status: &mut [u8],
    path: &mut Vec<usize>,
) {
    const NEW: u8 = 0;
    const ON_PATH: u8 = 1;
    const DONE: u8 = 2;
    let n_a = mdp.n_actions;
    let step = |s: usize| {
        let k = s * n_a + policy[s] as usize;
        (mdp.next[k] as usize, reward[k])
    };
    status.fill(NEW);
    for s0 in 0..mdp.n_states {
        if status[s0] != NEW {
            continue;
        }
        path.clear();
        let mut x = s0;
        while status[x] == NEW {
            status[x] = ON_PATH;
            path.push(x);
            x = step(x).0;
        }
        if status[x] == ON_PATH {
            // The walk closed a cycle at x: value it in closed form.
            let start = path.iter().position(|&p| p == x).expect("x is on the path");
            let cycle = &path[start..];
            let (mut g, mut disc) = (0.0, 1.0);
            for &c in cycle {
                g += disc * step(c).1;
                disc *= gamma;
            }
            v[x] = g / (1.0 - disc);
            status[x] = DONE;
            for &c in cycle[1..].iter().rev() {
                let (n, r) = step(c);
                v[c] = r + gamma * v[n];
                status[c] = DONE;
            }
            path.truncate(start);
        }
        for &p in path.iter().rev() {
            let (n, r) = step(p);
            v[p] = r + gamma * v[n];
            status[p] = DONE;
        }
    }
}

/// Policy iteration with exact evaluation of deterministic policies (see
/// `evaluate_deterministic`) for a discounted deterministic MDP. `policy` is the starting
/// policy (warm start; any valid actions) and receives the optimal one; returns the optimal
/// values and the number of improvement rounds. An action replaces the current one only when
/// it is better by more than a relative 1e-12, so ties keep the current action and the
/// iteration terminates.
pub fn policy_iteration(
    mdp: &DetMdp,
    reward: &[f64],
    gamma: f64,
    policy: &mut [u8],
    max_rounds: usize,
) -> Result<(Vec<f64>, usize), TabularError> {
    let (n_s, n_a) = (mdp.n_states, mdp.n_actions);
    check_len("reward table", reward.len(), n_s * n_a)?;
    check_len("policy", policy.len(), n_s)?;
    if !(0.0..1.0).contains(&gamma) {
        return Err(TabularError::Parameter(format!(
            "discount {gamma} must be in [0, 1)"
        )));
    }
    if let Some(s) = policy.iter().position(|&a| a as usize >= n_a) {
        return Err(TabularError::Parameter(format!(
            "policy action {} in state {s} out of range",
            policy[s]
        )));
    }
    let scale = reward.iter().fold(0.0f64, |m, r| m.max(r.abs())) / (1.0 - gamma);
    let eps = 1e-12 * scale.max(1e-300);
    let mut v = vec![0.0; n_s];
    let mut status = vec![0u8; n_s];
    let mut path = Vec::new();
    let mut rounds = 0;
    while rounds < max_rounds {
        rounds += 1;
        evaluate_deterministic(mdp, reward, gamma, policy, &mut v, &mut status, &mut path);
        let mut changed = false;
        for (s, slot) in policy.iter_mut().enumerate() {
            let row = s * n_a;
            let q = |a: usize| reward[row + a] + gamma * v[mdp.next[row + a] as usize];
            let cur = *slot as usize;
            let mut best = cur;
            let mut best_q = q(cur) + eps;
            for a in 0..n_a {
                let qa = q(a);
                if qa > best_q {
                    best = a;
                    best_q = qa;
                }
            }
            if best != cur {
                *slot = best as u8;
                changed = true;
            }
        }
        if !changed {
            break;
        }
    }
    Ok((v, rounds))
}

/// Optimal time-indexed policy for a finite horizon: `V_T = 0`, `Q_t = r + γ V_{t+1}(s')`,
/// `V_t = max_a Q_t`; writes the first best action of each `(t, s)` into `actions`
/// (`t * S + s`) and returns `V_0`.
pub fn finite_horizon_greedy(
    mdp: &DetMdp,
    reward: &[f64],
    gamma: f64,
    horizon: usize,
    actions: &mut Vec<u8>,
) -> Result<Vec<f64>, TabularError> {
    let (n_s, n_a) = (mdp.n_states, mdp.n_actions);
    check_len("reward table", reward.len(), n_s * n_a)?;
    if n_a > u8::MAX as usize + 1 {
        return Err(TabularError::Parameter(format!(
            "{n_a} actions do not fit a u8 policy"
        )));
    }
    actions.clear();
    actions.resize(horizon * n_s, 0);
    let mut v_next = vec![0.0; n_s];
    let mut v = vec![0.0; n_s];
    for t in (0..horizon).rev() {
        let act_t = &mut actions[t * n_s..(t + 1) * n_s];
        for s in 0..n_s {
            let row = s * n_a;
            let mut best = 0;
            let mut best_q = f64::NEG_INFINITY;
            for a in 0..n_a {
                let q = reward[row + a] + gamma * v_next[mdp.next[row + a] as usize];
                if q > best_q {
                    best_q = q;
                    best = a;
                }
            }
            v[s] = best_q;
            act_t[s] = best as u8;
        }
        std::mem::swap(&mut v, &mut v_next);
    }
    Ok(v_next)
}

/// For each state, the bit mask of actions whose value is within `tol` of the best.
pub fn optimal_action_masks(q: &[f64], n_actions: usize, tol: f64) -> Vec<u32> {
    assert!(n_actions <= 32, "action masks hold at most 32 actions");
    q.chunks_exact(n_actions)
        .map(|row| {
            let best = row.iter().copied().fold(f64::NEG_INFINITY, f64::max);
            (0..n_actions)
                .filter(|&a| row[a] >= best - tol)
                .fold(0u32, |m, a| m | 1 << a)
        })
        .collect()
}

/// A finite-horizon soft-optimal (MaxEnt) policy: `π_t(a|s)` for `t = 0..T`.
///
/// Backward pass: `V_T = 0`, `Q_t(s, a) = r(s, a) + γ V_{t+1}(s')`, `V_t = logsumexp_a Q_t`,
/// `π_t = exp(Q_t − V_t)`. With γ = 1 this is exactly Ziebart's MaxEnt distribution over
/// action sequences of length T: `P(a_0..a_{T−1} | s_0) = exp(Σ_t r(s_t, a_t) − V_0(s_0))`.
///
/// The recursion only depends on the time to go, so the pass for horizon T also holds every
/// shorter horizon T' ≤ T: its policy and values are those from `t = T − T'` on
/// ([`FiniteSoftPolicy::suffix_policy`], [`FiniteSoftPolicy::values_at`]).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct FiniteSoftPolicy {
    pub horizon: usize,
    pub n_states: usize,
    pub n_actions: usize,
    /// `π_t(a|s)` at `t * S * A + s * A + a`.
    pub pi: Vec<f64>,
    /// `V_t(s)` at `t * S + s`, for `t = 0..=T` (`V_T = 0`).
    pub v: Vec<f64>,
}

impl FiniteSoftPolicy {
    /// `V_0`: the log partition function of trajectories of the full horizon from each state.
    pub fn v0(&self) -> &[f64] {
        &self.v[..self.n_states]
    }

    /// `V_0` of the horizon-`h` problem (`h ≤ horizon`).
    pub fn values_at(&self, h: usize) -> &[f64] {
        let t = self.horizon - h;
        &self.v[t * self.n_states..(t + 1) * self.n_states]
    }

    /// The time-indexed policy of the horizon-`h` problem (`h ≤ horizon`).
    pub fn suffix_policy(&self, h: usize) -> &[f64] {
        let n_sa = self.n_states * self.n_actions;
        &self.pi[(self.horizon - h) * n_sa..]
    }
}

/// Finite-horizon soft backward pass into `out` (its buffers are reused across calls).
pub fn soft_backward(
    mdp: &DetMdp,
    reward: &[f64],
    gamma: f64,
    horizon: usize,
    out: &mut FiniteSoftPolicy,
) -> Result<(), TabularError> {
    let (n_s, n_a) = (mdp.n_states, mdp.n_actions);
    check_len("reward table", reward.len(), n_s * n_a)?;
    if !(0.0..=1.0).contains(&gamma) {
        return Err(TabularError::Parameter(format!(
            "discount {gamma} must be in [0, 1]"
        )));
    }
    let n_sa = n_s * n_a;
    out.horizon = horizon;
    out.n_states = n_s;
    out.n_actions = n_a;
    out.pi.resize(horizon * n_sa, 0.0);
    out.v.resize((horizon + 1) * n_s, 0.0);
    out.v[horizon * n_s..].fill(0.0);
    for t in (0..horizon).rev() {
        let (v_t, v_next) = out.v[t * n_s..(t + 2) * n_s].split_at_mut(n_s);
        let pi_t = &mut out.pi[t * n_sa..(t + 1) * n_sa];
        for s in 0..n_s {
            let pi_s = &mut pi_t[s * n_a..(s + 1) * n_a];
            // Q into π's slot; one exp per action: π = e / Σe with e = exp(Q − max Q),
            // V = max + ln Σe.
            let mut m = f64::NEG_INFINITY;
            for (a, slot) in pi_s.iter_mut().enumerate() {
                let k = s * n_a + a;
                let q = reward[k] + gamma * v_next[mdp.next[k] as usize];
                *slot = q;
                m = m.max(q);
            }
            let mut z = 0.0;
            for p in pi_s.iter_mut() {
                let e = (*p - m).exp();
                *p = e;
                z += e;
            }
            let inv = 1.0 / z;
            pi_s.iter_mut().for_each(|p| *p *= inv);
            v_t[s] = m + z.ln();
        }
    }
    Ok(())
}

/// Expected state-action visitation counts `Σ_{t<T} disc^t P(s_t = s, a_t = a)` from the
/// start distribution `p0`, added into `sa_out` (length S·A). `policy` holds `π(a|s)`,
/// either stationary (length S·A) or time-indexed (length ≥ T·S·A, `t`-major). `work` is a
/// scratch buffer.
pub fn expected_visitation(
    mdp: &DetMdp,
    policy: &[f64],
    p0: &[f64],
    horizon: usize,
    discount: f64,
    sa_out: &mut [f64],
    work: &mut Vec<f64>,
) -> Result<(), TabularError> {
    let (n_s, n_a) = (mdp.n_states, mdp.n_actions);
    let n_sa = n_s * n_a;
    check_len("start distribution", p0.len(), n_s)?;
    check_len("visitation output", sa_out.len(), n_sa)?;
    let stationary = policy.len() == n_sa;
    if !stationary && policy.len() < horizon * n_sa {
        return Err(TabularError::Shape {
            what: "time-indexed policy",
            expected: horizon * n_sa,
            got: policy.len(),
        });
    }
    work.clear();
    work.resize(2 * n_s, 0.0);
    let (d, d_next) = work.split_at_mut(n_s);
    d.copy_from_slice(p0);
    let mut w = 1.0;
    for t in 0..horizon {
        let pi_t = if stationary {
            policy
        } else {
            &policy[t * n_sa..(t + 1) * n_sa]
        };
        d_next.fill(0.0);
        for (s, &ds) in d.iter().enumerate() {
            if ds == 0.0 {
                continue;
            }
            for a in 0..n_a {
                let k = s * n_a + a;
                let m = ds * pi_t[k];
                sa_out[k] += w * m;
                d_next[mdp.next[k] as usize] += m;
            }
        }
        d.copy_from_slice(d_next);
        w *= discount;
    }
    Ok(())
}

/// Settings of tabular Q-learning.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct QLearning {
    pub gamma: f64,
    /// Step size.
    pub alpha: f64,
    /// Probability of a uniformly random action (ε-greedy).
    pub epsilon: f64,
    /// Environment steps in total.
    pub steps: usize,
    /// The agent returns to `start` after this many steps (no other reset).
    pub episode_len: usize,
    pub seed: u64,
}

/// ε-greedy one-step Q-learning on a known deterministic MDP used as a simulator; returns
/// `Q[s * A + a]`. Every step is one environment interaction.
pub fn q_learning(
    mdp: &DetMdp,
    reward: &[f64],
    start: usize,
    cfg: &QLearning,
) -> Result<Vec<f64>, TabularError> {
    let (n_s, n_a) = (mdp.n_states, mdp.n_actions);
    check_len("reward table", reward.len(), n_s * n_a)?;
    if start >= n_s {
        return Err(TabularError::Parameter(format!(
            "start state {start} out of range ({n_s} states)"
        )));
    }
    if cfg.episode_len == 0 || !(0.0..1.0).contains(&cfg.gamma) {
        return Err(TabularError::Parameter(
            "Q-learning needs episode_len ≥ 1 and γ in [0, 1)".into(),
        ));
    }
    let mut rng = ChaCha8Rng::seed_from_u64(cfg.seed);
    let mut q = vec![0.0; n_s * n_a];
    let mut s = start;
    for step in 0..cfg.steps {
        if step % cfg.episode_len == 0 {
            s = start;
        }
        let row = s * n_a;
        let a = if rng.gen::<f64>() < cfg.epsilon {
            rng.gen_range(0..n_a)
        } else {
            // Ties broken at random so that an all-zero table still explores.
            let best = q[row..row + n_a]
                .iter()
                .copied()
                .fold(f64::NEG_INFINITY, f64::max);
            let n_best = q[row..row + n_a].iter().filter(|&&x| x == best).count();
            let mut pick = rng.gen_range(0..n_best);
            (0..n_a)
                .find(|&a| {
                    if q[row + a] == best {
                        if pick == 0 {
                            return true;
                        }
                        pick -= 1;
                    }
                    false
                })
                .expect("some action is best")
        };
        let s2 = mdp.next[row + a] as usize;
        let target = reward[row + a]
            + cfg.gamma
                * q[s2 * n_a..(s2 + 1) * n_a]
                    .iter()
                    .copied()
                    .fold(f64::NEG_INFINITY, f64::max);
        q[row + a] += cfg.alpha * (target - q[row + a]);
        s = s2;
    }
    Ok(q)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 4-state chain: action 0 left, action 1 right; reward 1 for entering state 3.
    fn chain() -> (DetMdp, Vec<f64>) {
        let next = vec![0, 1, 0, 2, 1, 3, 2, 3];
        let mdp = DetMdp::new(4, 2, next).unwrap();
        let mut r = vec![0.0; 8];
        r[2 * 2 + 1] = 1.0; // 2 -> 3
        r[3 * 2 + 1] = 1.0; // staying at 3 by pushing right
        (mdp, r)
    }

    #[test]
    fn value_iteration_matches_closed_form_on_a_chain() {
        let (mdp, r) = chain();
        let it = Iteration {
            gamma: 0.9,
            tol: 1e-12,
            max_sweeps: 10_000,
        };
        let vals = value_iteration(&mdp, &r, it, None).unwrap();
        assert!(vals.converged);
        let v3 = 1.0 / (1.0 - 0.9);
        assert!((vals.v[3] - v3).abs() < 1e-9);
        assert!((vals.v[2] - v3).abs() < 1e-9);
        assert!((vals.v[1] - 0.9 * v3).abs() < 1e-9);
        assert_eq!(greedy_actions(&vals.q, 2), vec![1, 1, 1, 1]);
    }

    #[test]
    fn q_learning_finds_the_greedy_policy_of_value_iteration() {
        let (mdp, r) = chain();
        let cfg = QLearning {
            gamma: 0.9,
            alpha: 0.5,
            epsilon: 0.3,
            steps: 20_000,
            episode_len: 20,
            seed: 3,
        };
        let q = q_learning(&mdp, &r, 0, &cfg).unwrap();
        assert_eq!(greedy_actions(&q, 2), vec![1, 1, 1, 1]);
        let it = Iteration {
            gamma: 0.9,
            tol: 1e-12,
            max_sweeps: 10_000,
        };
        let vals = value_iteration(&mdp, &r, it, None).unwrap();
        assert!((q[3 * 2 + 1] - vals.q[3 * 2 + 1]).abs() < 0.05, "{q:?}");
    }

    #[test]
    fn policy_iteration_matches_value_iteration_on_random_mdps() {
        let mut rng = ChaCha8Rng::seed_from_u64(9);
        for _ in 0..20 {
            let (n_s, n_a) = (30, 4);
            let next: Vec<u32> = (0..n_s * n_a)
                .map(|_| rng.gen_range(0..n_s as u32))
                .collect();
            let mdp = DetMdp::new(n_s, n_a, next).unwrap();
            let r: Vec<f64> = (0..n_s * n_a).map(|_| rng.gen_range(-1.0..1.0)).collect();
            let it = Iteration {
                gamma: 0.97,
                tol: 1e-13,
                max_sweeps: 100_000,
            };
            let vals = value_iteration(&mdp, &r, it, None).unwrap();
            let mut policy = vec![0u8; n_s];
            let (v, rounds) = policy_iteration(&mdp, &r, 0.97, &mut policy, 1000).unwrap();
            assert!(rounds < 1000);
            for s in 0..n_s {
                assert!((v[s] - vals.v[s]).abs() < 1e-9, "state {s}");
                // The returned policy attains the optimal Q in every state.
                let best = vals.q[s * n_a..(s + 1) * n_a]
                    .iter()
                    .copied()
                    .fold(f64::NEG_INFINITY, f64::max);
                assert!((vals.q[s * n_a + policy[s] as usize] - best).abs() < 1e-9);
            }
        }
    }

    #[test]
    fn bad_shapes_are_errors() {
        assert!(DetMdp::new(2, 2, vec![0, 1, 2, 0]).is_err());
        assert!(DetMdp::new(2, 2, vec![0, 1, 1]).is_err());
        let (mdp, _) = chain();
        let it = Iteration {
            gamma: 0.9,
            tol: 1e-6,
            max_sweeps: 10,
        };
        assert!(value_iteration(&mdp, &[0.0; 3], it, None).is_err());
        let it = Iteration { gamma: 1.0, ..it };
        assert!(value_iteration(&mdp, &[0.0; 8], it, None).is_err());
    }
}
