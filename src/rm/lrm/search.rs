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
//! compressed trace visits the same states. The split move can break that; the search's
//! result is made stutter invariant afterwards ([`stutter_invariant`]). Only the used states
//! and one fresh state are tried as targets (all fresh states are alike).
//!
//! A neighbour's cost is computed incrementally: it differs from the current machine only in
//! column `l`, so its run can diverge only where the current run reads `l` in a changed
//! state; from each such position the new run is simulated until it reaches the same state as
//! the current run at the same position (then the rest is identical) or the trace ends, and
//! only the prediction counts along these windows are updated.

use super::data::{cost_of_hist, ln_table, Data};
use rand::seq::SliceRandom;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::collections::{HashMap, HashSet, VecDeque};

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

/// The machine of `t` made to read raw traces as it reads compressed ones.
///
/// The search scores machines on compressed traces (a run of one label set is one entry),
/// but every machine is then read step by step on raw traces, where a label set is read
/// again on every step it holds. The two readings agree when the machine is *stutter
/// invariant*: a state entered on `l` stays on `l`. The reference moves keep that, the split
/// moves do not always: splitting a stay `(i, l)` of a state that another state enters on
/// `l` gives `i` a transition on `l` that a raw trace takes one step after entering `i`,
/// where the compressed trace reads the next, different label first (measured: on the
/// Sequential demonstrations of base seed 3 the state reached on leaving red left again on
/// the next empty step, and the machine no longer waited for green).
///
/// With event stutter (`stutter_of[l]` = the label id a step after `l` reads when only `l`'s
/// event is gone, see `Data::stutter_of`), a state entered on `l` must also stay on
/// `stutter_of[l]`, which the compressed traces joined to `l` and no move keeps.
///
/// For each state `i` entered on `l` that leaves on `l` or on `stutter_of[l]`, a state `f`
/// ("`i`, just entered on `l`") takes every transition into `i` on `l`; `f` stays on `l` and
/// `stutter_of[l]` and reads any other label as `i` does (a stay of `i` becomes a move to
/// `i`). A compressed trace visits `f` where it visited `i` and then continues exactly as
/// before, so the machine reads every compressed trace as `t` does and a raw trace the same
/// way. There is one `f` per (`i`, `l`), reused when a later `f` (a copy of `i`'s row, moving
/// to `i` where `i` stays) enters `i` on `l` again; an `f` is entered on its own `l` only and
/// never needs one. So the result has at most one more state per (state, label) cell of `t`
/// (and may have more states than the search's `u_max`); a stutter invariant table is
/// returned unchanged.
pub(crate) fn stutter_invariant(t: &Table, l_n: usize, stutter_of: &[Option<u16>]) -> Table {
    let mut n = t.n_used;
    let mut delta = t.delta[..n * l_n].to_vec();
    let also = |l: usize| stutter_of[l];
    let mut just_entered: HashMap<(usize, usize), usize> = HashMap::new();
    loop {
        let violation = (0..n * l_n).find(|&cell| {
            let (k, l) = (cell / l_n, cell % l_n);
            let i = delta[cell] as usize;
            i != k
                && (delta[i * l_n + l] as usize != i
                    || also(l).is_some_and(|s| delta[i * l_n + s as usize] as usize != i))
        });
        let Some(cell) = violation else {
            return Table { delta, n_used: n };
        };
        let (i, l) = (delta[cell] as usize, cell % l_n);
        let f = match just_entered.get(&(i, l)) {
            Some(&f) => f,
            None => {
                let f = n;
                for x in 0..l_n {
                    let target = if x == l || also(l) == Some(x as u16) {
                        f
                    } else {
                        delta[i * l_n + x] as usize
                    };
                    delta.push(target as u16);
                }
                n += 1;
                just_entered.insert((i, l), f);
                f
            }
        };
        for k in 0..n {
            if k != i && k != f && delta[k * l_n + l] as usize == i {
                delta[k * l_n + l] = f as u16;
            }
        }
    }
}

/// A move of the neighbourhood.
#[derive(Clone, Copy, Debug)]
enum Move {
    /// The reference move: add, redirect (`remove = false`) or remove the single transition
    /// `(i, l) -> j`.
    Single {
        i: u16,
        l: u16,
        j: u16,
        remove: bool,
    },
    /// Beyond the reference: redirect `(i, l)` into a fresh copy of its target (see
    /// [`Searcher::split_into`]). Never raises the cost.
    Split { i: u16, l: u16 },
}

pub(crate) struct SearchOutcome {
    pub best: Table,
    pub best_cost: f64,
    pub steps: usize,
    pub restarts: usize,
    pub neighbours_evaluated: u64,
    /// The start whose machine was returned, and the best cost of every start.
    pub best_start: usize,
    pub start_costs: Vec<f64>,
}

pub(crate) struct Searcher<'a> {
    data: &'a Data,
    u_max: usize,
    l_n: usize,
    r_n: usize,
    reward_weight: f64,
    ln: Vec<f64>,
    split_moves: bool,
}

/// Parameters of [`Searcher::search`].
#[derive(Clone, Debug)]
pub(crate) struct SearchParams {
    pub tabu_len: usize,
    /// Steps of each start at most.
    pub max_steps: usize,
    /// A start ends after this many steps without improving its best cost (0 = never).
    pub patience: usize,
    /// Independent starts (at least 1).
    pub starts: usize,
    pub threads: usize,
    pub seed: u64,
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
            split_moves: true,
        }
    }

    /// `t` (a canonical table of a search with fewer states) as a table of this search: the
    /// extra states are unused (stay everywhere), so it stays canonical.
    pub fn widen(&self, t: &Table) -> Table {
        let mut delta = self.identity();
        let n = (t.delta.len() / self.l_n).min(self.u_max);
        delta[..n * self.l_n].copy_from_slice(&t.delta[..n * self.l_n]);
        Table {
            delta,
            n_used: t.n_used.min(self.u_max),
        }
    }

    /// The initial-state split of `t` (a table of a search with fewer states than this
    /// searcher's `u_max`), or `None` when no transition re-enters the initial state.
    ///
    /// The objective never sees the initial state as such: a prediction is made in the state
    /// *after* each label, so when the traces start with the label that also leads back to
    /// state 0 (Office task 4: every demonstration starts on A, and A after D re-enters the
    /// state "seeking B"), the search has no reason to keep "before the first label" apart
    /// from that state, and the learned machine refines the perfect one everywhere except at
    /// the first position of each trace. The split adds a fresh initial state `f` that does
    /// what state 0 does, except where state 0 stays on `l` only because some `(k, l)`
    /// enters it (a stutter stay): there `f` goes to 0. Genuine stays of 0 stay in `f`. Runs
    /// are unchanged except that the prefix before leaving `f` is read in `f`: prediction
    /// cells are only partitioned, so the cost cannot rise.
    pub fn split_initial(&self, t: &Table) -> Option<Table> {
        let (l_n, n) = (self.l_n, t.n_used);
        if n + 1 > self.u_max {
            return None;
        }
        let delta = self.widen(t).delta;
        let reentered: Vec<bool> = (0..l_n)
            .map(|l| (1..n).any(|k| delta[k * l_n + l] == 0))
            .collect();
        if !reentered.iter().any(|&r| r) {
            return None;
        }
        let f = n;
        let mut split = delta.clone();
        for l in 0..l_n {
            let d0 = delta[l] as usize;
            split[f * l_n + l] = if d0 != 0 || reentered[l] {
                d0 as u16
            } else {
                f as u16
            };
        }
        // Make `f` the initial state (state 0) by swapping it with 0.
        let swap = |u: usize| -> usize {
            if u == 0 {
                f
            } else if u == f {
                0
            } else {
                u
            }
        };
        let mut swapped = self.identity();
        for u in 0..=n {
            for l in 0..l_n {
                swapped[swap(u) * l_n + l] = swap(split[u * l_n + l] as usize) as u16;
            }
        }
        Some(self.canonical(&swapped))
    }

    /// Whether the neighbourhood includes the split move (default: yes).
    pub fn with_split_moves(mut self, on: bool) -> Searcher<'a> {
        self.split_moves = on;
        self
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
                    cnt[(s as usize * l_n + l) * l_n + d.next[t] as usize] += d.w[t] as u64;
                }
            }
        }
        let (cell_c, cell_k, hist) = summarise_cells(&cnt, l_n, l_n + 1);
        let (rcell_c, rcell_k, rhist) = summarise_cells(&rcnt, r_n, r_n.max(l_n) + 1);
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

    /// Writes the machine after the move into `out` (`n_used` = used states of `delta`).
    fn apply_into(&self, delta: &[u16], n_used: usize, mv: Move, out: &mut Vec<u16>) {
        out.clear();
        out.extend_from_slice(delta);
        let l_n = self.l_n;
        match mv {
            Move::Single { i, l, j, remove } => {
                let (i, l) = (i as usize, l as usize);
                if remove {
                    out[i * l_n + l] = i as u16;
                } else {
                    // As in the reference: `j` stays on `l` and nothing else enters `i` on
                    // `l`, which keeps the machine stutter invariant.
                    for k in 0..self.u_max {
                        if out[k * l_n + l] as usize == i && k != i {
                            out[k * l_n + l] = k as u16;
                        }
                    }
                    out[i * l_n + l] = j;
                    out[j as usize * l_n + l] = j;
                }
            }
            Move::Split { i, l } => Self::split_into(out, l_n, i as usize, l as usize, n_used),
        }
    }

    /// The split move: the fresh state `f` gets a copy of the row of `v = delta(i, l)` (its
    /// stays become stays in `f`) and `(i, l)` now goes to `f`. `f` behaves like `v`, so every
    /// run visits the same states except that some visits of `v` become visits of `f`: the
    /// prediction cells of `v` are partitioned, which can only lower `Σ log |N|` (and the
    /// reward term). It is the one move that adds a state "for free"; the reference
    /// neighbourhood needs two moves, the first of which usually costs a lot (a fresh state
    /// with no way out), so Tabu search rarely takes it: measured on Office task 4, where the
    /// search stopped at 3 states (cost 10 909) and one split of the perfect machine's
    /// missing state gives the perfect machine (cost 8 238).
    fn split_into(delta: &mut [u16], l_n: usize, i: usize, l: usize, f: usize) {
        let v = delta[i * l_n + l] as usize;
        for x in 0..l_n {
            let t = delta[v * l_n + x] as usize;
            delta[f * l_n + x] = if t == v { f as u16 } else { t as u16 };
        }
        delta[i * l_n + l] = f as u16;
    }

    fn apply(&self, delta: &[u16], n_used: usize, mv: Move) -> Vec<u16> {
        let mut out = Vec::new();
        self.apply_into(delta, n_used, mv, &mut out);
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
                    out.push(Move::Single {
                        i: i as u16,
                        l: l as u16,
                        j: j as u16,
                        remove,
                    });
                }
            }
        }
        if self.split_moves && n < self.u_max {
            for i in 0..n {
                for l in 0..self.l_n {
                    if !cur.pos[i * self.l_n + l].is_empty() {
                        out.push(Move::Split {
                            i: i as u16,
                            l: l as u16,
                        });
                    }
                }
            }
        }
        out
    }

    /// Cost of the neighbour, or `None` when the move cannot change the run.
    fn neighbour_cost(&self, cur: &Current, mv: Move, sc: &mut Scratch) -> Option<f64> {
        let delta = &cur.table.delta;
        let mut nd = std::mem::take(&mut sc.delta);
        self.apply_into(delta, cur.table.n_used, mv, &mut nd);
        // The runs diverge only where the current run reads a changed cell.
        sc.positions.clear();
        let mut lists = 0;
        for (cell, (&a, &b)) in delta.iter().zip(nd.iter()).enumerate() {
            if a != b {
                let p = &cur.pos[cell];
                if !p.is_empty() {
                    sc.positions.extend_from_slice(p);
                    lists += 1;
                }
            }
        }
        let out = if lists == 0 {
            None
        } else {
            if lists > 1 {
                sc.positions.sort_unstable();
            }
            Some(self.windows_cost(cur, &nd, sc))
        };
        sc.delta = nd;
        out
    }

    /// The neighbour's cost from the windows where its run (table `nd`) differs from the
    /// current one, starting at `sc.positions` (sorted).
    fn windows_cost(&self, cur: &Current, nd: &[u16], sc: &mut Scratch) -> f64 {
        let (d, l_n) = (self.data, self.l_n);
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
                        sc.rewards.moved(ob * l_n + lt, s * l_n + lt, r, m);
                    }
                }
                let sn = nd[s * l_n + lt] as usize;
                let so = cur.after[t] as usize;
                if sn == so {
                    cur_end = t + 1;
                    break;
                }
                let wt = d.w[t] as i64;
                if wt > 0 {
                    let nl = d.next[t] as usize;
                    sc.labels.moved(so * l_n + lt, sn * l_n + lt, nl, wt);
                }
                s = sn;
                t += 1;
            }
        }
        sc.hist.clear();
        sc.hist.extend_from_slice(&cur.hist);
        sc.labels
            .apply(&cur.cnt, &cur.cell_k, &cur.cell_c, &mut sc.hist);
        sc.rhist.clear();
        sc.rhist.extend_from_slice(&cur.rhist);
        sc.rewards
            .apply(&cur.rcnt, &cur.rcell_k, &cur.rcell_c, &mut sc.rhist);
        self.total_cost(&sc.hist, &sc.rhist)
    }

    fn scratch(&self) -> Scratch {
        Scratch {
            labels: CellDelta::new(self.u_max * self.l_n, self.l_n),
            rewards: CellDelta::new(self.u_max * self.l_n, self.r_n),
            rhist: Vec::new(),
            positions: Vec::new(),
            delta: Vec::new(),
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

    /// A random machine over `n` states (`2 <= n <= u_max`): each cell gets a random
    /// transition with probability 1/2, applied as reference moves (so it is stutter
    /// invariant), then made canonical.
    fn random_table(&self, n: usize, rng: &mut ChaCha8Rng) -> Table {
        let n = n.clamp(2, self.u_max.max(2)).min(self.u_max);
        let mut delta = self.identity();
        for i in 0..n {
            for l in 0..self.l_n {
                if n > 1 && rng.gen_bool(0.5) {
                    let mut j = rng.gen_range(0..n - 1);
                    if j >= i {
                        j += 1;
                    }
                    let mv = Move::Single {
                        i: i as u16,
                        l: l as u16,
                        j: j as u16,
                        remove: false,
                    };
                    delta = self.apply(&delta, self.u_max, mv);
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

    /// Multi-start Tabu search (an addition to the reference, which runs one search from the
    /// one-state machine): start 0 is the reference's start, start `k >= 1` is a random
    /// machine over `2 + (k - 1) % (u_max - 1)` states drawn with its own random stream. Each
    /// start is an independent Tabu search ([`Searcher::search_from`]) with its own RNG
    /// (stream `k` of the seed), so its result does not depend on which thread runs it; the
    /// best machine over all starts (lowest cost, then fewest states, then lowest start
    /// index) is returned. Starts run in parallel (`min(threads, starts)`
    /// workers; the rest of the threads evaluate neighbours within a start).
    pub fn search(&self, p: &SearchParams) -> SearchOutcome {
        let total = p.starts.max(1);
        let run_start = |k: usize, threads: usize| -> SearchOutcome {
            let mut rng = ChaCha8Rng::seed_from_u64(p.seed);
            rng.set_stream(k as u64);
            let table = if k == 0 || self.u_max < 2 {
                self.canonical(&self.identity())
            } else {
                self.random_table(2 + (k - 1) % (self.u_max - 1), &mut rng)
            };
            self.search_from(table, p, threads, &mut rng)
        };
        let workers = p.threads.clamp(1, total);
        let inner = (p.threads / workers).max(1);
        let outcomes: Vec<SearchOutcome> = if workers == 1 {
            (0..total).map(|k| run_start(k, inner)).collect()
        } else {
            let next = std::sync::atomic::AtomicUsize::new(0);
            let mut slots: Vec<Option<SearchOutcome>> = (0..total).map(|_| None).collect();
            let parts: Vec<Vec<(usize, SearchOutcome)>> = std::thread::scope(|scope| {
                let handles: Vec<_> = (0..workers)
                    .map(|_| {
                        scope.spawn(|| {
                            let mut done = Vec::new();
                            loop {
                                let k = next.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                                if k >= total {
                                    break done;
                                }
                                done.push((k, run_start(k, inner)));
                            }
                        })
                    })
                    .collect();
                handles
                    .into_iter()
                    .map(|h| h.join().expect("a start does not panic"))
                    .collect()
            });
            for (k, o) in parts.into_iter().flatten() {
                slots[k] = Some(o);
            }
            slots
                .into_iter()
                .map(|o| o.expect("every start ran"))
                .collect()
        };
        // Lowest cost, then fewest states, then lowest start index.
        let best_of = |range: std::ops::Range<usize>| -> usize {
            let mut best_k = range.start;
            for k in range {
                let (o, b) = (&outcomes[k], &outcomes[best_k]);
                if o.best_cost < b.best_cost
                    || (o.best_cost == b.best_cost && o.best.n_used < b.best.n_used)
                {
                    best_k = k;
                }
            }
            best_k
        };
        let best_k = best_of(0..total);
        let mut total = SearchOutcome {
            best: outcomes[best_k].best.clone(),
            best_cost: outcomes[best_k].best_cost,
            steps: 0,
            restarts: 0,
            neighbours_evaluated: 0,
            best_start: best_k,
            start_costs: outcomes.iter().map(|o| o.best_cost).collect(),
        };
        for o in &outcomes {
            total.steps += o.steps;
            total.restarts += o.restarts;
            total.neighbours_evaluated += o.neighbours_evaluated;
        }
        total
    }

    /// One Tabu search from `start` (the reference's loop): move to the best non-tabu
    /// neighbour, restart from a random machine when every neighbour is tabu; stops after
    /// `max_steps` steps or `patience` steps without improving the best machine found.
    pub fn search_from(
        &self,
        start: Table,
        p: &SearchParams,
        threads: usize,
        rng: &mut ChaCha8Rng,
    ) -> SearchOutcome {
        let tabu_len = p.tabu_len;
        let mut cur = self.load(start);
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
        let mut since_best = 0;
        if self.u_max >= 2 && self.data.len() > 0 {
            while steps < p.max_steps && (p.patience == 0 || since_best < p.patience) {
                steps += 1;
                since_best += 1;
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
                    let delta = self.apply(&cur.table.delta, cur.table.n_used, moves[m]);
                    let t = self.canonical(&delta);
                    if !tabu_set.contains(&t.delta) {
                        next = Some(t);
                        break;
                    }
                }
                let next = match next {
                    Some(t) => t,
                    None => {
                        restarts += 1;
                        let mut t = self.random_table(self.u_max, rng);
                        for _ in 0..100 {
                            if !tabu_set.contains(&t.delta) {
                                break;
                            }
                            t = self.random_table(self.u_max, rng);
                        }
                        t
                    }
                };
                cur = self.load(next);
                push_tabu(&cur.table, &mut tabu_set);
                if cur.cost < best.0 || (cur.cost == best.0 && cur.table.n_used < best.1.n_used) {
                    if cur.cost < best.0 {
                        since_best = 0;
                    }
                    best = (cur.cost, cur.table.clone());
                }
            }
        }
        SearchOutcome {
            best: best.1,
            best_cost: best.0,
            steps,
            restarts,
            neighbours_evaluated: evaluated,
            best_start: 0,
            start_costs: vec![best.0],
        }
    }
}

/// Per-cell totals `cell_c`, distinct-outcome counts `cell_k` and the histogram `hist[k]` (total
/// weight of cells with `k` distinct outcomes, `hist_len` bins) of outcome counts `cnt`,
/// `width` outcomes per cell — the summary [`CellDelta::apply`] updates incrementally.
fn summarise_cells(cnt: &[u64], width: usize, hist_len: usize) -> (Vec<i64>, Vec<u32>, Vec<i64>) {
    let mut hist = vec![0i64; hist_len];
    let (cell_c, cell_k): (Vec<i64>, Vec<u32>) = cnt
        .chunks(width)
        .map(|row| {
            let c = row.iter().sum::<u64>() as i64;
            let k = row.iter().filter(|&&v| v > 0).count() as u32;
            hist[k as usize] += c;
            (c, k)
        })
        .unzip();
    (cell_c, cell_k, hist)
}

/// Changes a neighbour makes to per-cell outcome counts (successor labels or rewards,
/// `width` outcomes per transition cell), and the cells it touched.
struct CellDelta {
    width: usize,
    diff: Vec<i64>,
    mark: Vec<bool>,
    touched: Vec<u32>,
}

impl CellDelta {
    fn new(cells: usize, width: usize) -> CellDelta {
        CellDelta {
            width,
            diff: vec![0; cells * width],
            mark: vec![false; cells],
            touched: Vec::new(),
        }
    }

    /// Weight `w` of outcome `outcome` moves from cell `from` to cell `to`.
    fn moved(&mut self, from: usize, to: usize, outcome: usize, w: i64) {
        self.diff[from * self.width + outcome] -= w;
        self.diff[to * self.width + outcome] += w;
        for c in [from, to] {
            if !self.mark[c] {
                self.mark[c] = true;
                self.touched.push(c as u32);
            }
        }
    }

    /// Moves every touched cell of `hist` (a copy of the current machine's histogram, whose
    /// cells have totals `cell_c` over `cell_k` distinct outcomes of counts `cnt`) to its
    /// bin after the changes, and clears the changes for the next neighbour.
    fn apply(&mut self, cnt: &[u64], cell_k: &[u32], cell_c: &[i64], hist: &mut [i64]) {
        let width = self.width;
        for &c in &self.touched {
            let c = c as usize;
            let (mut total, mut k) = (0i64, 0usize);
            let cell = c * width..(c + 1) * width;
            for (&n, d) in cnt[cell.clone()].iter().zip(&mut self.diff[cell]) {
                let v = n as i64 + *d;
                *d = 0;
                if v > 0 {
                    total += v;
                    k += 1;
                }
            }
            hist[cell_k[c] as usize] -= cell_c[c];
            hist[k] += total;
            self.mark[c] = false;
        }
        self.touched.clear();
    }
}

struct Scratch {
    labels: CellDelta,
    rewards: CellDelta,
    rhist: Vec<i64>,
    positions: Vec<u32>,
    /// The neighbour's table.
    delta: Vec<u16>,
    hist: Vec<i64>,
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rm::lrm::data::TraceReading;
    use crate::rm::lrm::synthetic::office_traces;
    use crate::rm::Vocabulary;
    use rand::SeedableRng;

    /// The incremental neighbour cost equals a full run of the neighbour, for every move
    /// from a sequence of machines visited by the search, with LRM's reading of the traces
    /// and with one proposition (here coffee, `c`) left out of the prediction.
    #[test]
    fn incremental_cost_matches_full_run() {
        let traces = office_traces(3, 3000, 5).unwrap();
        let vocab = Vocabulary::new("ABCDcmo*");
        let unpredicted = TraceReading {
            unpredicted_events: vocab.parse_labels("c").unwrap(),
            ..TraceReading::default()
        };
        for reading in [TraceReading::default(), unpredicted] {
            incremental_cost_matches_full_run_on(&Data::new(&vocab, &traces, reading).unwrap());
        }
    }

    fn incremental_cost_matches_full_run_on(data: &Data) {
        for weight in [0.0, 100.0] {
            let s = Searcher::new(data, 5, weight);
            let mut rng = ChaCha8Rng::seed_from_u64(3);
            let mut table = s.canonical(&s.identity());
            for round in 0..6 {
                let cur = s.load(table.clone());
                let moves = s.moves(&cur);
                let costs = s.evaluate_all(&cur, &moves, 2);
                for (m, c) in moves.iter().zip(&costs) {
                    let full = s.cost(&s.apply(&cur.table.delta, cur.table.n_used, *m));
                    match c {
                        Some(c) => assert!(
                            (c - full).abs() < 1e-6 * full.max(1.0),
                            "round {round} move {m:?}: incremental {c} vs full {full}"
                        ),
                        None => assert!((full - cur.cost).abs() < 1e-6 * full.max(1.0)),
                    }
                }
                table = s.random_table(2 + round % 3, &mut rng);
            }
        }
    }

    /// The repair ends on any table and stutter map, within its bound of one state per
    /// (state, label) cell, with every state entered on `l` staying on `l` and on
    /// `stutter_of[l]`. Random tables include ones where two event labels enter the same
    /// state and each "just entered" copy enters it on the other (the case the per-(state,
    /// label) reuse ends).
    #[test]
    fn stutter_repair_ends_within_its_bound_and_is_invariant() {
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        for _ in 0..2000 {
            let (n, l_n) = (rng.gen_range(1..6usize), rng.gen_range(1..6usize));
            let delta: Vec<u16> = (0..n * l_n).map(|_| rng.gen_range(0..n) as u16).collect();
            let stutter_of: Vec<Option<u16>> = (0..l_n)
                .map(|l| {
                    (l_n > 1 && rng.gen_range(0..3) > 0)
                        .then(|| ((l + rng.gen_range(1..l_n)) % l_n) as u16)
                })
                .collect();
            let fixed = stutter_invariant(&Table { delta, n_used: n }, l_n, &stutter_of);
            assert!(
                fixed.n_used <= n + n * l_n,
                "{} states from {n} x {l_n}",
                fixed.n_used
            );
            let d = &fixed.delta;
            for cell in 0..fixed.n_used * l_n {
                let (k, l, i) = (cell / l_n, cell % l_n, d[cell] as usize);
                if i == k {
                    continue;
                }
                assert_eq!(d[i * l_n + l] as usize, i);
                if let Some(s) = stutter_of[l] {
                    assert_eq!(d[i * l_n + s as usize] as usize, i);
                }
            }
        }
    }
}
