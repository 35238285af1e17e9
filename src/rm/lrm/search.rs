//! The Tabu search over machines on compact label ids.
//!
//! A machine is a table `delta[u * L + l]` over `u_max` states and the `L` observed label
//! sets (a cell equal to its own state is "stay"). Machines are kept *canonical*: cells never
//! used by the traces (except on a trace's last step, where they cannot change the cost) are
//! reset to stay, and states are renumbered in breadth-first order from state 0, so the used
//! states are `0..n_used` and two machines that behave the same on the traces have the same
//! table. The tabu list holds canonical tables.
//!
//! A neighbour changes one cell `(i, l)`: it removes the transition (if `delta(i,l) = j`) or
//! makes it go to `j`; like the reference implementation, adding `(i,l) -> j` also removes
//! every `(k,l) -> i` and makes `j` stay on `l`, which keeps every machine *stutter
//! invariant* (`delta(delta(u,l),l) = delta(u,l)`): running it on a raw trace and on the
//! compressed trace visits the same states. Only the used states and one fresh state are
//! tried as targets (all fresh states are alike).
//!
//! A neighbour's cost is computed incrementally: it differs from the current machine only in
//! column `l`, so its run can diverge only where the current run reads `l` in a changed
//! state; from each such position the new run is simulated until it reaches the same state as
//! the current run at the same position (then the rest is identical) or the trace ends, and
//! only the prediction counts along these windows are updated.

use super::data::{cost_of_hist, ln_table, Data};
use rand::seq::SliceRandom;
use rand::Rng;
use rand_chacha::ChaCha8Rng;
use std::collections::{HashSet, VecDeque};

/// A canonical machine on compact labels.
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
pub(crate) struct Table {
    pub delta: Vec<u16>,
    pub n_used: usize,
}

/// The current machine with everything needed to evaluate its neighbours.
struct Current {
    table: Table,
    /// State after reading each position.
    after: Vec<u16>,
    /// Prediction counts `cnt[(u * L + l) * L + l']`.
    cnt: Vec<u64>,
    cell_c: Vec<i64>,
    cell_k: Vec<u32>,
    hist: Vec<i64>,
    /// Reward counts per transition cell `rcnt[(u * L + l) * R + r]` (`u` = state before
    /// the step), their per-cell totals, distinct counts and histogram, as for labels.
    rcnt: Vec<u64>,
    rcell_c: Vec<i64>,
    rcell_k: Vec<u32>,
    rhist: Vec<i64>,
    cost: f64,
    /// Positions read in state `u` (before the step) with label `l`, per cell `u * L + l`.
    pos: Vec<Vec<u32>>,
}

#[derive(Clone, Copy, Debug)]
struct Move {
    i: u16,
    l: u16,
    j: u16,
    remove: bool,
}

pub(crate) struct SearchOutcome {
    pub best: Table,
    pub best_cost: f64,
    pub steps: usize,
    pub restarts: usize,
    pub neighbours_evaluated: u64,
}

pub(crate) struct Searcher<'a> {
    data: &'a Data,
    u_max: usize,
    l_n: usize,
    r_n: usize,
    reward_weight: f64,
    ln: Vec<f64>,
}

impl<'a> Searcher<'a> {
    /// `reward_weight` scales the reward term of the cost (0 = the reference objective).
    pub fn new(data: &'a Data, u_max: usize, reward_weight: f64) -> Searcher<'a> {
        let l_n = data.n_labels().max(1);
        let r_n = data.reward_values.len().max(1);
        Searcher {
            data,
            u_max,
            l_n,
            r_n,
            reward_weight,
            ln: ln_table(l_n.max(r_n)),
        }
    }

    fn total_cost(&self, hist: &[i64], rhist: &[i64]) -> f64 {
        let c = cost_of_hist(hist, &self.ln);
        if self.reward_weight > 0.0 {
            c + self.reward_weight * cost_of_hist(rhist, &self.ln)
        } else {
            c
        }
    }

    pub fn identity(&self) -> Vec<u16> {
        (0..self.u_max * self.l_n)
            .map(|c| (c / self.l_n) as u16)
            .collect()
    }

    /// Cost of any table (not necessarily canonical).
    pub fn cost(&self, delta: &[u16]) -> f64 {
        self.run(delta).cost
    }

    fn run(&self, delta: &[u16]) -> Current {
        let (d, l_n, u_max) = (self.data, self.l_n, self.u_max);
        let mut after = vec![0u16; d.len()];
        let mut cnt = vec![0u64; u_max * l_n * l_n];
        let mut pos = vec![Vec::new(); u_max * l_n];
        let r_n = self.r_n;
        let mut rcnt = vec![0u64; u_max * l_n * r_n];
        for k in 0..d.n_traces() {
            let mut s = 0u16;
            for t in d.starts[k]..d.starts[k + 1] {
                let l = d.lab[t] as usize;
                pos[s as usize * l_n + l].push(t as u32);
                rcnt[(s as usize * l_n + l) * r_n + d.rid[t] as usize] += d.mult[t] as u64;
                s = delta[s as usize * l_n + l];
                after[t] = s;
                if d.w[t] > 0 {
                    cnt[(s as usize * l_n + l) * l_n + d.lab[t + 1] as usize] += d.w[t] as u64;
                }
            }
        }
        let mut cell_c = vec![0i64; u_max * l_n];
        let mut cell_k = vec![0u32; u_max * l_n];
        let mut hist = vec![0i64; l_n + 1];
        for cell in 0..u_max * l_n {
            let row = &cnt[cell * l_n..(cell + 1) * l_n];
            cell_c[cell] = row.iter().sum::<u64>() as i64;
            cell_k[cell] = row.iter().filter(|&&v| v > 0).count() as u32;
            hist[cell_k[cell] as usize] += cell_c[cell];
        }
        let mut rcell_c = vec![0i64; u_max * l_n];
        let mut rcell_k = vec![0u32; u_max * l_n];
        let mut rhist = vec![0i64; r_n.max(l_n) + 1];
        for cell in 0..u_max * l_n {
            let row = &rcnt[cell * r_n..(cell + 1) * r_n];
            rcell_c[cell] = row.iter().sum::<u64>() as i64;
            rcell_k[cell] = row.iter().filter(|&&v| v > 0).count() as u32;
            rhist[rcell_k[cell] as usize] += rcell_c[cell];
        }
        let cost = self.total_cost(&hist, &rhist);
        Current {
            table: Table {
                delta: delta.to_vec(),
                n_used: 0,
            },
            after,
            cnt,
            cell_c,
            cell_k,
            hist,
            rcnt,
            rcell_c,
            rcell_k,
            rhist,
            cost,
            pos,
        }
    }

    /// Prunes cells the traces do not use and renumbers states breadth-first.
    pub fn canonical(&self, delta: &[u16]) -> Table {
        let (d, l_n, u_max) = (self.data, self.l_n, self.u_max);
        let mut used = vec![false; u_max * l_n];
        for k in 0..d.n_traces() {
            let mut s = 0usize;
            for t in d.starts[k]..d.starts[k + 1] {
                let cell = s * l_n + d.lab[t] as usize;
                let v = delta[cell] as usize;
                if v != s && d.w[t] > 0 {
                    used[cell] = true;
                }
                s = v;
            }
        }
        let pruned = |cell: usize| {
            if used[cell] {
                delta[cell] as usize
            } else {
                cell / l_n
            }
        };
        let mut id = vec![usize::MAX; u_max];
        let mut order = vec![0usize];
        id[0] = 0;
        let mut head = 0;
        while head < order.len() {
            let u = order[head];
            head += 1;
            for l in 0..l_n {
                let v = pruned(u * l_n + l);
                if id[v] == usize::MAX {
                    id[v] = order.len();
                    order.push(v);
                }
            }
        }
        let mut out = self.identity();
        for (new_u, &u) in order.iter().enumerate() {
            for l in 0..l_n {
                out[new_u * l_n + l] = id[pruned(u * l_n + l)] as u16;
            }
        }
        Table {
            delta: out,
            n_used: order.len(),
        }
    }

    /// Column `l` of `delta` after the move.
    fn column(&self, delta: &[u16], mv: Move, col: &mut Vec<u16>) {
        let (l_n, l) = (self.l_n, mv.l as usize);
        col.clear();
        col.extend((0..self.u_max).map(|s| delta[s * l_n + l]));
        let (i, j) = (mv.i as usize, mv.j);
        if mv.remove {
            col[i] = i as u16;
        } else {
            for (k, c) in col.iter_mut().enumerate() {
                if *c as usize == i && k != i {
                    *c = k as u16;
                }
            }
            col[i] = j;
            col[j as usize] = j;
        }
    }

    fn apply(&self, delta: &[u16], mv: Move) -> Vec<u16> {
        let mut col = Vec::new();
        self.column(delta, mv, &mut col);
        let mut out = delta.to_vec();
        for (s, &c) in col.iter().enumerate() {
            out[s * self.l_n + mv.l as usize] = c;
        }
        out
    }

    fn moves(&self, cur: &Current) -> Vec<Move> {
        let n = cur.table.n_used;
        let targets = (n + 1).min(self.u_max);
        let mut out = Vec::new();
        for i in 0..n {
            for l in 0..self.l_n {
                for j in 0..targets {
                    if i == j {
                        continue;
                    }
                    let remove = cur.table.delta[i * self.l_n + l] as usize == j;
                    out.push(Move {
                        i: i as u16,
                        l: l as u16,
                        j: j as u16,
                        remove,
                    });
                }
            }
        }
        out
    }

    /// Cost of the neighbour, or `None` when the move cannot change the run.
    fn neighbour_cost(&self, cur: &Current, mv: Move, sc: &mut Scratch) -> Option<f64> {
        let (d, l_n) = (self.data, self.l_n);
        let l = mv.l as usize;
        let delta = &cur.table.delta;
        self.column(delta, mv, &mut sc.col);
        sc.positions.clear();
        let mut lists = 0;
        for s in 0..self.u_max {
            if sc.col[s] != delta[s * l_n + l] {
                let p = &cur.pos[s * l_n + l];
                if !p.is_empty() {
                    sc.positions.extend_from_slice(p);
                    lists += 1;
                }
            }
        }
        if lists == 0 {
            return None;
        }
        if lists > 1 {
            sc.positions.sort_unstable();
        }
        let mut cur_end = 0usize;
        for k in 0..sc.positions.len() {
            let p = sc.positions[k] as usize;
            if p < cur_end {
                continue;
            }
            let end = d.trace_end(p);
            let mut s = if d.is_start(p) {
                0
            } else {
                cur.after[p - 1] as usize
            };
            let mut t = p;
            cur_end = end;
            while t < end {
                let lt = d.lab[t] as usize;
                // The reward of step t is counted in the cell of the state before it: from
                // the second position of a window on, that state differs.
                if t > p {
                    let ob = cur.after[t - 1] as usize;
                    if ob != s {
                        let m = d.mult[t] as i64;
                        let r = d.rid[t] as usize;
                        let (co, cn) = (ob * l_n + lt, s * l_n + lt);
                        sc.rdiff[co * self.r_n + r] -= m;
                        sc.rdiff[cn * self.r_n + r] += m;
                        for c in [co, cn] {
                            if !sc.rmark[c] {
                                sc.rmark[c] = true;
                                sc.rtouched.push(c as u32);
                            }
                        }
                    }
                }
                let sn = if lt == l {
                    sc.col[s] as usize
                } else {
                    delta[s * l_n + lt] as usize
                };
                let so = cur.after[t] as usize;
                if sn == so {
                    cur_end = t + 1;
                    break;
                }
                let wt = d.w[t] as i64;
                if wt > 0 {
                    let nl = d.lab[t + 1] as usize;
                    let (co, cn) = (so * l_n + lt, sn * l_n + lt);
                    sc.diff[co * l_n + nl] -= wt;
                    sc.diff[cn * l_n + nl] += wt;
                    for c in [co, cn] {
                        if !sc.mark[c] {
                            sc.mark[c] = true;
                            sc.touched.push(c as u32);
                        }
                    }
                }
                s = sn;
                t += 1;
            }
        }
        sc.hist.clear();
        sc.hist.extend_from_slice(&cur.hist);
        for &c in &sc.touched {
            let c = c as usize;
            let (mut total, mut k) = (0i64, 0usize);
            for nl in 0..l_n {
                let idx = c * l_n + nl;
                let v = cur.cnt[idx] as i64 + sc.diff[idx];
                sc.diff[idx] = 0;
                if v > 0 {
                    total += v;
                    k += 1;
                }
            }
            sc.hist[cur.cell_k[c] as usize] -= cur.cell_c[c];
            sc.hist[k] += total;
            sc.mark[c] = false;
        }
        sc.touched.clear();
        sc.rhist.clear();
        sc.rhist.extend_from_slice(&cur.rhist);
        let r_n = self.r_n;
        for &c in &sc.rtouched {
            let c = c as usize;
            let (mut total, mut k) = (0i64, 0usize);
            for r in 0..r_n {
                let idx = c * r_n + r;
                let v = cur.rcnt[idx] as i64 + sc.rdiff[idx];
                sc.rdiff[idx] = 0;
                if v > 0 {
                    total += v;
                    k += 1;
                }
            }
            sc.rhist[cur.rcell_k[c] as usize] -= cur.rcell_c[c];
            sc.rhist[k] += total;
            sc.rmark[c] = false;
        }
        sc.rtouched.clear();
        Some(self.total_cost(&sc.hist, &sc.rhist))
    }

    fn scratch(&self) -> Scratch {
        Scratch {
            diff: vec![0; self.u_max * self.l_n * self.l_n],
            mark: vec![false; self.u_max * self.l_n],
            touched: Vec::new(),
            rdiff: vec![0; self.u_max * self.l_n * self.r_n],
            rmark: vec![false; self.u_max * self.l_n],
            rtouched: Vec::new(),
            rhist: Vec::new(),
            positions: Vec::new(),
            col: Vec::new(),
            hist: Vec::new(),
        }
    }

    /// Costs of all moves, evaluated on `threads` threads (moves interleaved); the result
    /// does not depend on the thread count.
    fn evaluate_all(&self, cur: &Current, moves: &[Move], threads: usize) -> Vec<Option<f64>> {
        let threads = threads.clamp(1, moves.len().max(1));
        if threads == 1 {
            let mut sc = self.scratch();
            return moves
                .iter()
                .map(|&m| self.neighbour_cost(cur, m, &mut sc))
                .collect();
        }
        let mut out = vec![None; moves.len()];
        let parts: Vec<Vec<(usize, Option<f64>)>> = std::thread::scope(|scope| {
            let handles: Vec<_> = (0..threads)
                .map(|k| {
                    scope.spawn(move || {
                        let mut sc = self.scratch();
                        (k..moves.len())
                            .step_by(threads)
                            .map(|m| (m, self.neighbour_cost(cur, moves[m], &mut sc)))
                            .collect::<Vec<_>>()
                    })
                })
                .collect();
            handles
                .into_iter()
                .map(|h| h.join().expect("neighbour evaluation does not panic"))
                .collect()
        });
        for part in parts {
            for (m, c) in part {
                out[m] = c;
            }
        }
        out
    }

    fn random_table(&self, rng: &mut ChaCha8Rng) -> Table {
        let mut delta = self.identity();
        for i in 0..self.u_max {
            for l in 0..self.l_n {
                if rng.gen_bool(0.5) {
                    let mut j = rng.gen_range(0..self.u_max - 1);
                    if j >= i {
                        j += 1;
                    }
                    delta = self.apply(
                        &delta,
                        Move {
                            i: i as u16,
                            l: l as u16,
                            j: j as u16,
                            remove: false,
                        },
                    );
                }
            }
        }
        self.canonical(&delta)
    }

    fn load(&self, table: Table) -> Current {
        let mut cur = self.run(&table.delta);
        cur.table = table;
        cur
    }

    /// The Tabu search from the one-state machine.
    pub fn search(
        &self,
        tabu_len: usize,
        max_steps: usize,
        threads: usize,
        rng: &mut ChaCha8Rng,
    ) -> SearchOutcome {
        let mut cur = self.load(self.canonical(&self.identity()));
        let mut best = (cur.cost, cur.table.clone());
        let mut tabu_set: HashSet<Vec<u16>> = HashSet::new();
        let mut tabu_fifo: VecDeque<Vec<u16>> = VecDeque::new();
        let mut push_tabu = |t: &Table, set: &mut HashSet<Vec<u16>>| {
            if tabu_len == 0 {
                return;
            }
            if set.insert(t.delta.clone()) {
                tabu_fifo.push_back(t.delta.clone());
                if tabu_fifo.len() > tabu_len {
                    if let Some(old) = tabu_fifo.pop_front() {
                        set.remove(&old);
                    }
                }
            }
        };
        push_tabu(&cur.table, &mut tabu_set);
        let (mut steps, mut restarts, mut evaluated) = (0, 0, 0u64);
        if self.u_max < 2 || self.data.len() == 0 {
            return SearchOutcome {
                best: best.1,
                best_cost: best.0,
                steps,
                restarts,
                neighbours_evaluated: evaluated,
            };
        }
        while steps < max_steps {
            steps += 1;
            let moves = self.moves(&cur);
            let costs = self.evaluate_all(&cur, &moves, threads);
            evaluated += moves.len() as u64;
            // Ties are broken by a seeded shuffle, not by move order.
            let mut cands: Vec<(f64, usize)> = costs
                .iter()
                .enumerate()
                .filter_map(|(m, c)| c.map(|c| (c, m)))
                .collect();
            cands.shuffle(rng);
            cands.sort_by(|a, b| a.0.total_cmp(&b.0));
            let mut next = None;
            for &(_, m) in &cands {
                let t = self.canonical(&self.apply(&cur.table.delta, moves[m]));
                if !tabu_set.contains(&t.delta) {
                    next = Some(t);
                    break;
                }
            }
            let next = match next {
                Some(t) => t,
                None => {
                    restarts += 1;
                    let mut t = self.random_table(rng);
                    for _ in 0..100 {
                        if !tabu_set.contains(&t.delta) {
                            break;
                        }
                        t = self.random_table(rng);
                    }
                    t
                }
            };
            cur = self.load(next);
            push_tabu(&cur.table, &mut tabu_set);
            if cur.cost < best.0 || (cur.cost == best.0 && cur.table.n_used < best.1.n_used) {
                best = (cur.cost, cur.table.clone());
            }
        }
        SearchOutcome {
            best: best.1,
            best_cost: best.0,
            steps,
            restarts,
            neighbours_evaluated: evaluated,
        }
    }
}

struct Scratch {
    diff: Vec<i64>,
    mark: Vec<bool>,
    touched: Vec<u32>,
    rdiff: Vec<i64>,
    rmark: Vec<bool>,
    rtouched: Vec<u32>,
    rhist: Vec<i64>,
    positions: Vec<u32>,
    col: Vec<u16>,
    hist: Vec<i64>,
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rm::lrm::synthetic::office_traces;
    use crate::rm::Vocabulary;
    use rand::SeedableRng;

    /// The incremental neighbour cost equals a full run of the neighbour, for every move
    /// from a sequence of machines visited by the search.
    #[test]
    fn incremental_cost_matches_full_run() {
        let traces = office_traces(3, 3000, 5).unwrap();
        let data = Data::new(&Vocabulary::new("ABCDcmo*"), &traces).unwrap();
        for weight in [0.0, 100.0] {
            let s = Searcher::new(&data, 5, weight);
            let mut rng = ChaCha8Rng::seed_from_u64(3);
            let mut table = s.canonical(&s.identity());
            for round in 0..6 {
                let cur = s.load(table.clone());
                let moves = s.moves(&cur);
                let costs = s.evaluate_all(&cur, &moves, 2);
                for (m, c) in moves.iter().zip(&costs) {
                    let full = s.cost(&s.apply(&cur.table.delta, *m));
                    match c {
                        Some(c) => assert!(
                            (c - full).abs() < 1e-6 * full.max(1.0),
                            "round {round} move {m:?}: incremental {c} vs full {full}"
                        ),
                        None => assert!((full - cur.cost).abs() < 1e-6 * full.max(1.0)),
                    }
                }
                table = s.random_table(&mut rng);
            }
        }
    }
}
