//! Learning reward machines from label traces: the Tabu search of LRM (Toro Icarte et al.,
//! NeurIPS 2019), as used by SMIRL's first step.
//!
//! **Objective.** For a machine with transition function `delta`, run every trace from the
//! initial state; `x_t` is the state after reading the trace's label set `l_t`. The cost is
//! `Σ_traces Σ_t log |N(x_t, l_t)|`, where `N(u, l)` is the set of label sets seen right after
//! `l` while in state `u` (the state after reading `l`, as in the reference code). Traces are
//! compressed first (a run of one label set counts once). A missing transition means "stay".
//!
//! **Search.** Tabu search over machines with at most `max_states` states, starting from the
//! one-state machine: at each step every single-transition neighbour (for each used state
//! `i`, observed label set `l` and target `j != i`: add, redirect or remove `(i, l) -> j`) is
//! evaluated in parallel, the best one that is not on the tabu list (a FIFO of the last
//! `tabu_len` visited machines) becomes current, and when every neighbour is tabu the search
//! restarts from a random machine. The best machine seen in `max_steps` steps is returned.
//! Ties are broken by a seeded shuffle, so the result depends on the seed, never on the
//! thread count. See the `search` module for the incremental cost evaluation and the canonical form
//! that makes the tabu list effective.
//!
//! **Beyond the reference: search additions** (each measured on the real Office expert
//! demonstrations, 100 000 transitions per task, see `experiments/lrm/bench.txt`). First
//! finding: on those traces the reference search stops at machines *costlier* than the
//! perfect one (Office task 4: 10 909 with 3 states vs 8 238 with 4; task 3 did not refine),
//! i.e. a search problem, not an objective problem.
//! - *Split move* ([`LrmConfig::split_moves`]): redirect one observed transition `(i, l)`
//!   into a fresh copy of its target. It never raises the cost, and adds in one move the
//!   state that the single-transition neighbourhood can only add through a costly
//!   intermediate machine (a fresh state without outgoing transitions).
//! - *Independent starts* ([`LrmConfig::starts`]): start 0 is the reference's one-state
//!   machine, the others random machines of 2..=u_max states; each has its own RNG stream
//!   of the seed, they run in parallel over the threads, and the best machine is kept
//!   (deterministic for any thread count).
//! - *Patience* ([`LrmConfig::patience`]): a start ends after that many steps without
//!   improving its best; the time saved pays for the other starts (measured in
//!   `experiments/lrm/patience.md`: patience 5 finds patience 20's cost on Office tasks 1, 2
//!   and 4, 12 % above it on task 3, in a third of its time).
//!
//! With these, the learned machines cost less than the perfect ones on every benchmark task
//! (the objective also rewards predicting the expert's random steps), and refine the perfect
//! machine along the demonstrations on Office tasks 0–3 and Reacher OR/Sequential without
//! rewards (the reference: tasks 0–2, OR, Sequential).
//!
//! **Rewards.** Not searched: after the search, the machine is run along the raw traces and
//! each transition gets the mean reward observed on it (0 without rewards). Transitions are
//! guarded by exact label-set formulas ([`Formula::exactly`], or an OR of them), so the
//! machine says nothing about label sets never observed (they stay, reward 0).
//!
//! **Beyond the reference: a reward term.** When the traces carry rewards, the cost adds
//! `reward_weight · Σ_steps log |R(u, l)|`, where `R(u, l)` is the set of rewards observed on
//! the transition cell (state before the step, label set): the same "how unpredictable"
//! measure applied to the rewards, weighted high so that machines that explain the rewards
//! come first. With `reward_weight = 0` (or no rewards) the objective is the reference one.
//!
//! **Beyond the reference: guards for unseen label sets.** With [`Guards::Tree`] each
//! state's transitions are a decision tree over the propositions fitted to the cells the
//! traces define (the domain's events, [`LrmConfig::events`], are split on first where the
//! cells show they matter),
//! instead of "stay" on every label set the traces never showed in that state; see
//! `guards.rs` for the reason and the rule.
//!
//! **Beyond the reference: merging.** The objective adds states that predict the next label
//! but pay the same rewards. With [`LrmConfig::merge`] (the default) states with the same
//! reward behaviour are merged afterwards (Mealy minimisation over the observed label sets;
//! optionally also filling unobserved cells, see `merge.rs`); [`LearnedRm::raw`] keeps the
//! machine before merging.

mod data;
mod guards;
mod merge;
mod search;
pub mod synthetic;

pub use data::{TraceReading, MAX_OBSERVED_LABEL_SETS};
pub use guards::Guards;

use crate::rm::formula::Formula;
use crate::rm::labels::{LabelSet, Vocabulary};
use crate::rm::machine::{RewardMachine, Transition};
use data::Data;
use merge::{merge_states, Cell};
use std::time::Instant;

/// One demonstration's labels (one label set per environment step) and, optionally, the
/// task reward of each step.
#[derive(Clone, Debug, PartialEq)]
pub struct LabelTrace {
    pub labels: Vec<LabelSet>,
    pub rewards: Option<Vec<f64>>,
}

/// Default weight of the reward term: large, so that explaining the observed rewards comes
/// first and predicting the next label second.
pub const DEFAULT_REWARD_WEIGHT: f64 = 100.0;

/// Most states a configured search may use (the count tables grow with states × label
/// sets²); configs are checked against it before any work.
pub const MAX_STATES: usize = 100;
/// Most search steps (and tabu-list entries) a config may ask for.
pub const MAX_SEARCH_STEPS: usize = 1_000_000;

/// Default number of independent starts of the search.
pub const DEFAULT_STARTS: usize = 4;
/// Default number of steps without improvement after which a start ends.
pub const DEFAULT_PATIENCE: usize = 5;

/// Parameters of the search.
#[derive(Clone, Debug, PartialEq)]
pub struct LrmConfig {
    /// `u_max`: most states the search may use (the initial-state split, [`LrmConfig::split_initial`], may add one; merging may remove some).
    pub max_states: usize,
    /// Length of the FIFO tabu list of visited machines.
    pub tabu_len: usize,
    /// Search steps (one move each).
    pub max_steps: usize,
    pub seed: u64,
    /// Threads evaluating neighbours (does not change the result).
    pub threads: usize,
    /// Merge reward-indistinguishable states after the search.
    pub merge: bool,
    /// When merging, let an unobserved cell take the behaviour of the state it merges with
    /// (more merging, may over-generalise; see the `merge` module).
    pub fill_unobserved: bool,
    /// Weight of the reward term of the cost (see the module docs); 0 gives the reference
    /// objective. Ignored when the traces carry no rewards.
    pub reward_weight: f64,
    /// Independent Tabu searches (start 0 from the one-state machine like the reference,
    /// the others from seeded random machines); the best result is kept. 1 = the reference.
    pub starts: usize,
    /// A start ends after this many steps without improving its best cost (0 = run all
    /// `max_steps`, as the reference does).
    pub patience: usize,
    /// Add the split move to the neighbourhood (see `search.rs`); off = the reference's
    /// single-transition neighbourhood.
    pub split_moves: bool,
    /// After the search, give the machine a fresh initial state when transitions re-enter
    /// state 0 and the objective could not tell "before the first label" from it (see
    /// `search.rs`); the learned machine may then have `max_states + 1` states.
    pub split_initial: bool,
    /// How the machine reads label sets never observed in a state (see `guards.rs`):
    /// [`Guards::Exact`] = LRM's (stay).
    pub guards: Guards,
    /// Propositions the task declares exogenous events (true on one step by construction),
    /// which [`Guards::Tree`] reads first where they matter and the event rules below read;
    /// empty = none.
    pub events: LabelSet,
    /// Make the learned machine read raw traces as the search read the compressed ones
    /// (`search::stutter_invariant`): for domains whose label sets hold over several steps
    /// and whose machine is read on every step (ReacherDelivery: the fingertip stays inside a
    /// ball, and between balls the label set is empty for many steps). Off by default:
    /// Office's restart-on-goal targets pay on every step the goal is read, which no stutter
    /// invariant machine expresses.
    pub stutter_invariant: bool,
    /// Read a step that only drops an event as a stutter (`Data::new`): after a label set
    /// holding an event (`events`), the same label set without it, when not empty, continues
    /// that entry of the compressed trace, and the learned machine stays on it (the repair of
    /// `stutter_invariant`, which this needs). Assumes an event is instantaneous and can
    /// overlap a lasting proposition: the cancel fires on one step while the fingertip is on
    /// a ball (`{r, c}`), and the next steps read `{r}`, the same touch. Read as a new label,
    /// "red, then red" is free for the objective to send anywhere. Off by default.
    pub event_stutter: bool,
    /// Ask the machine to predict the events (`events`) among the next label sets, as LRM's
    /// eq. 1 does (true, the default). False: the objective compares next label sets without
    /// them, so a state pays for itself only by predicting the *other* propositions. Assumes
    /// the events are exogenous, so that the expert's next step never needs them predicted:
    /// an event that fires at most once per episode is predicted better by a machine that
    /// remembers it fired, whatever the expert does, and LRM then splits states by it in
    /// tasks that never condition on it. Transitions still read the events; the cost changes,
    /// the traces do not.
    pub predict_events: bool,
    /// After the search, read an event (a proposition of `events`) that the traces never show
    /// in a state as if it had come just before the touch that entered the state
    /// (`merge::commute_events`: "red, then cancel" ends where "cancel, then red" does, when
    /// every way into the state agrees). An event that fires at most once is seen only at
    /// some stages of the task, and where the demonstrations never show it the machine would
    /// otherwise ignore it. Assumes order independence: an event's effect does not depend on
    /// whether it comes just before or just after a touch (true of "unless" events, false of
    /// one whose meaning changes once a touch has happened), and only where the traces show
    /// the event to have an effect: a way in counts when the state the event leads to is left
    /// otherwise than the state without it (`merge::observed_equivalence`), so a cancel that
    /// a task ignores is not carried over; and a candidate comes only from a cell the traces
    /// show, never from a stay that stutter invariance implies. Traces' paths and the cost
    /// are unchanged. Off by default.
    pub commute_events: bool,
    /// After the search, read an event that the traces never show in the initial state, when
    /// no other state enters it, as coming on the first step with the label that leaves it
    /// (`merge::initial_events`). The initial-state split makes such a state ("before the
    /// first label"), and only demonstrations whose event fired on their first step show one
    /// there; without any, the guards would read a first-step event as none. Assumes an event
    /// means the same on the first step as on the second. Traces' paths and the cost are
    /// unchanged. Off by default.
    pub initial_events: bool,
}

impl Default for LrmConfig {
    /// The reference implementation's values: at most 10 states, a tabu list of 10 000
    /// (its code; the paper says 100), 100 steps; threads = available cores.
    fn default() -> LrmConfig {
        LrmConfig {
            max_states: 10,
            tabu_len: 10_000,
            max_steps: 100,
            seed: 0,
            threads: std::thread::available_parallelism().map_or(1, |n| n.get()),
            merge: true,
            fill_unobserved: false,
            reward_weight: DEFAULT_REWARD_WEIGHT,
            starts: DEFAULT_STARTS,
            patience: DEFAULT_PATIENCE,
            split_moves: true,
            split_initial: true,
            guards: Guards::Exact,
            events: LabelSet::EMPTY,
            stutter_invariant: false,
            event_stutter: false,
            predict_events: true,
            commute_events: false,
            initial_events: false,
        }
    }
}

/// What the search did.
#[derive(Clone, Debug, PartialEq)]
pub struct LrmStats {
    /// Transitions in the input traces.
    pub raw_transitions: usize,
    /// Positions after compression and deduplication.
    pub compressed_positions: usize,
    pub distinct_traces: usize,
    /// Label sets observed in the traces (the learned machine's alphabet).
    pub observed_label_sets: Vec<LabelSet>,
    pub steps: usize,
    pub restarts: usize,
    pub neighbours_evaluated: u64,
    /// The start whose machine was kept, and the best cost each start reached.
    pub best_start: usize,
    pub start_costs: Vec<f64>,
    /// States of the machine the search found (before merging).
    pub search_states: usize,
    /// Cost of the final (merged) machine.
    pub final_cost: f64,
    /// Wall time of the whole call (not part of the deterministic result).
    pub elapsed_secs: f64,
}

/// A learned machine: `rm` (merged when configured), `raw` (the search's machine with mean
/// rewards), `cost` = the objective of `raw`.
#[derive(Clone, Debug)]
pub struct LearnedRm {
    pub rm: RewardMachine,
    pub raw: RewardMachine,
    pub cost: f64,
    pub stats: LrmStats,
}

#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum LrmError {
    #[error("trace {trace}, step {step}: label set {labels:#x} is not a label set of the vocabulary \"{vocabulary}\"")]
    LabelOutOfRange {
        trace: usize,
        step: usize,
        labels: u32,
        vocabulary: String,
    },
    #[error("trace {trace} has {labels} label sets but {rewards} rewards")]
    RewardLength {
        trace: usize,
        labels: usize,
        rewards: usize,
    },
    #[error("trace {trace}, step {step}: the reward is not a finite number")]
    NonFiniteReward { trace: usize, step: usize },
    #[error(
        "the traces contain {observed} distinct label sets; the learner handles at most {max}"
    )]
    TooManyLabelSets { observed: usize, max: usize },
    #[error("invalid configuration: {0}")]
    Config(String),
}

/// Learns a reward machine from label traces with LRM's Tabu search (see the module docs).
pub fn learn_rm(
    vocab: &Vocabulary,
    traces: &[LabelTrace],
    cfg: &LrmConfig,
) -> Result<LearnedRm, LrmError> {
    let started = Instant::now();
    check_config(cfg)?;
    let data = Data::new(vocab, traces, trace_reading(cfg))?;
    let l_n = data.n_labels().max(1);
    check_sizes(cfg, l_n)?;

    // The search, then the initial-state split and the stutter-invariant repair.
    let searched = search_table(&data, cfg, l_n);
    let (table, n) = (&searched.table, searched.table.n_used);

    // Observed targets and mean rewards along the raw traces: the raw machine.
    let (count, raw_cells) = observed_cells(traces, &data, table, l_n);
    let raw = machine_from_cells(vocab, &data.labels, n, &raw_cells);

    // The cells the final machine is built from: observed ones, implied stays and the event
    // rules' fills.
    let defined = defined_cells(&data, cfg, table, &count, &raw_cells, l_n);

    // Merged (optionally) and read through guards.
    let (exact_rm, final_cells, final_n, final_cost) = if cfg.merge {
        let (blocks, merged) = merge_states(n, l_n, defined, cfg.fill_unobserved);
        let (quotient_cells, q_n) = renumber_blocks(&blocks, &merged, l_n);
        let rm = machine_from_cells(vocab, &data.labels, q_n, &quotient_cells);
        let delta: Vec<u16> = (0..searched.rows * l_n)
            .map(|cell| {
                let u = cell / l_n;
                match quotient_cells.get(cell).copied().flatten() {
                    Some(c) if u < q_n => c.target as u16,
                    _ => u as u16,
                }
            })
            .collect();
        let cost = searched.final_searcher.cost(&delta);
        (rm, quotient_cells, q_n, cost)
    } else {
        (raw.clone(), defined, n, searched.best_cost)
    };
    // A tree agrees with the table on every defined cell, so the cost is the same.
    let rm = match cfg.guards {
        Guards::Exact => exact_rm,
        Guards::Tree => {
            guards::tree_machine(vocab, &data.labels, final_n, &final_cells, cfg.events.0)
        }
    };

    let outcome = &searched.outcome;
    Ok(LearnedRm {
        rm,
        raw,
        cost: searched.best_cost,
        stats: LrmStats {
            raw_transitions: data.raw_len,
            compressed_positions: data.len(),
            distinct_traces: data.n_traces(),
            observed_label_sets: data.labels.clone(),
            steps: outcome.steps,
            restarts: outcome.restarts,
            neighbours_evaluated: outcome.neighbours_evaluated,
            best_start: outcome.best_start,
            start_costs: outcome.start_costs.clone(),
            search_states: n,
            final_cost,
            elapsed_secs: started.elapsed().as_secs_f64(),
        },
    })
}

/// The configuration's limits that do not depend on the traces.
fn check_config(cfg: &LrmConfig) -> Result<(), LrmError> {
    if cfg.max_states == 0 || cfg.max_states > u16::MAX as usize {
        return Err(LrmError::Config(format!(
            "max_states must be in 1..={}, got {}",
            u16::MAX,
            cfg.max_states
        )));
    }
    if cfg.event_stutter && !cfg.stutter_invariant {
        return Err(LrmError::Config(
            "event_stutter needs stutter_invariant (the repair that makes the machine stay on \
             a stutter)"
                .to_string(),
        ));
    }
    Ok(())
}

/// The limits that depend on the number of distinct label sets `l_n`, and the reward weight.
fn check_sizes(cfg: &LrmConfig, l_n: usize) -> Result<(), LrmError> {
    // The stutter-invariant repair adds at most one state per (state, label set) cell, and
    // the tables store states as u16.
    if cfg.stutter_invariant && (cfg.max_states + 1) * (1 + l_n) > u16::MAX as usize {
        return Err(LrmError::Config(format!(
            "with stutter_invariant, (max_states + 1) x (1 + label sets) must be at most {}, \
             got ({} + 1) x (1 + {})",
            u16::MAX,
            cfg.max_states,
            l_n
        )));
    }
    if !(cfg.reward_weight >= 0.0 && cfg.reward_weight.is_finite()) {
        return Err(LrmError::Config(format!(
            "reward_weight must be a finite number >= 0, got {}",
            cfg.reward_weight
        )));
    }
    Ok(())
}

/// The searched machine as a table, with what scores it.
struct Searched<'a> {
    /// The search's statistics.
    outcome: search::SearchOutcome,
    /// The machine after the initial-state split and the stutter-invariant repair.
    table: search::Table,
    best_cost: f64,
    /// A searcher with rows enough for `table`, which scores the final machines.
    final_searcher: search::Searcher<'a>,
    /// The rows of `final_searcher`.
    rows: usize,
}

/// The Tabu search, then the initial-state split (see `Searcher::split_initial`) and, with
/// `stutter_invariant`, the repair that makes the machine read raw traces as the compressed
/// ones the search scored (see `search::stutter_invariant`; the cost on compressed traces can
/// only drop).
fn search_table<'a>(data: &'a Data, cfg: &LrmConfig, l_n: usize) -> Searched<'a> {
    let searcher = search::Searcher::new(data, cfg.max_states, cfg.reward_weight)
        .with_split_moves(cfg.split_moves);
    let outcome = searcher.search(&search::SearchParams {
        tabu_len: cfg.tabu_len,
        max_steps: cfg.max_steps,
        patience: cfg.patience,
        starts: cfg.starts,
        threads: cfg.threads.max(1),
        seed: cfg.seed,
    });
    // The split runs on a searcher with one more state, which also evaluates the final
    // machines.
    let final_searcher = search::Searcher::new(data, cfg.max_states + 1, cfg.reward_weight);
    let split = if cfg.split_initial {
        final_searcher.split_initial(&outcome.best)
    } else {
        None
    };
    let (table, best_cost) = match split {
        Some(t) => {
            let c = final_searcher.cost(&t.delta);
            (t, c)
        }
        None => (final_searcher.widen(&outcome.best), outcome.best_cost),
    };
    // A repaired table has new states, possibly more than the final searcher's rows; a grown
    // table is scored by a searcher with enough rows.
    let rows = |t: &search::Table| t.n_used.max(cfg.max_states + 1);
    let repaired = cfg
        .stutter_invariant
        .then(|| search::stutter_invariant(&table, l_n, &data.stutter_of))
        .filter(|t| t.n_used > table.n_used);
    let (table, best_cost, final_searcher) = match repaired {
        None => (table, best_cost, final_searcher),
        Some(t) => {
            let wide = search::Searcher::new(data, rows(&t), cfg.reward_weight);
            let cost = wide.cost(&wide.widen(&t).delta);
            (t, cost, wide)
        }
    };
    let rows = rows(&table);
    Searched {
        outcome,
        table,
        best_cost,
        final_searcher,
        rows,
    }
}

/// How often each (state, label set) cell of `table` is read along the raw traces, and each
/// cell with its target and mean observed reward (0 where none is observed).
fn observed_cells(
    traces: &[LabelTrace],
    data: &Data,
    table: &search::Table,
    l_n: usize,
) -> (Vec<u64>, Vec<Option<Cell>>) {
    let n = table.n_used;
    let mut count = vec![0u64; n * l_n];
    let mut reward_sum = vec![0.0f64; n * l_n];
    for t in traces {
        let mut s = 0usize;
        for (k, l) in t.labels.iter().enumerate() {
            let cell = s * l_n + data.id_of[l.index()] as usize;
            count[cell] += 1;
            if let Some(r) = &t.rewards {
                reward_sum[cell] += r[k];
            }
            s = table.delta[cell] as usize;
        }
    }
    let mean = |cell: usize| {
        if count[cell] > 0 {
            reward_sum[cell] / count[cell] as f64
        } else {
            0.0
        }
    };
    let raw_cells = (0..n * l_n)
        .map(|cell| {
            Some(Cell {
                target: table.delta[cell] as usize,
                reward: mean(cell),
                weight: count[cell] as f64,
            })
        })
        .collect();
    (count, raw_cells)
}

/// The cells the final machine is built from: the observed ones, the stays implied by
/// stutter invariance (on the label set a state was entered on, and with event stutter on
/// that set without its event), and what commuted and initial events fill in.
fn defined_cells(
    data: &Data,
    cfg: &LrmConfig,
    table: &search::Table,
    count: &[u64],
    raw_cells: &[Option<Cell>],
    l_n: usize,
) -> Vec<Option<Cell>> {
    let n = table.n_used;
    let mut defined: Vec<Option<Cell>> = (0..n * l_n)
        .map(|cell| (count[cell] > 0).then(|| raw_cells[cell].unwrap()))
        .collect();
    for (cell, &seen) in count.iter().enumerate() {
        let (u, l) = (cell / l_n, cell % l_n);
        let v = table.delta[cell] as usize;
        if seen == 0 || v == u {
            continue;
        }
        for stay in std::iter::once(l).chain(data.stutter_of[l].map(usize::from)) {
            if defined[v * l_n + stay].is_none() {
                defined[v * l_n + stay] = Some(Cell {
                    target: v,
                    reward: 0.0,
                    weight: 0.0,
                });
            }
        }
    }

    // Label ids whose set holds an event: the cells commuting and initial events may fill.
    let event_bits: Vec<u32> = data.labels.iter().map(|l| l.0 & cfg.events.0).collect();
    let event_ids: Vec<usize> = (0..l_n)
        .filter(|&l| event_bits.get(l).is_some_and(|&b| b != 0))
        .collect();
    // Label id -> id of the same set without its events, when the traces read that set.
    let without_events: Vec<Option<usize>> = data
        .labels
        .iter()
        .map(
            |l| match data.id_of[LabelSet(l.0 & !cfg.events.0).index()] {
                u16::MAX => None,
                id => Some(usize::from(id)),
            },
        )
        .collect();
    if cfg.commute_events {
        merge::commute_events(n, l_n, &mut defined, &event_ids, &without_events);
    }
    if cfg.initial_events {
        merge::initial_events(n, l_n, &mut defined, &event_ids, &without_events);
    }
    defined
}

/// How the learner with `cfg` reads traces: the propositions whose dropping
/// [`LrmConfig::event_stutter`] reads as a stutter, and those [`LrmConfig::predict_events`]
/// leaves out of the prediction.
pub fn trace_reading(cfg: &LrmConfig) -> TraceReading {
    let events_if = |on: bool| if on { cfg.events } else { LabelSet::EMPTY };
    TraceReading {
        stutter_events: events_if(cfg.event_stutter),
        unpredicted_events: events_if(!cfg.predict_events),
    }
}

/// The LRM objective of any machine on `traces` (e.g. of a perfect machine, to compare with
/// a learned one's cost), the traces read as the learner reads them with `reading`
/// ([`trace_reading`]; the default is LRM's plain compression and prediction).
pub fn trace_cost(
    rm: &RewardMachine,
    traces: &[LabelTrace],
    reading: TraceReading,
) -> Result<f64, LrmError> {
    let data = Data::new(rm.vocab(), traces, reading)?;
    let l_n = data.n_labels().max(1);
    let searcher = search::Searcher::new(&data, rm.n_states().min(u16::MAX as usize), 0.0);
    let delta: Vec<u16> = (0..rm.n_states() * l_n)
        .map(|cell| {
            let (u, l) = (cell / l_n, cell % l_n);
            match data.labels.get(l) {
                Some(&ls) => rm.next_state(u, ls) as u16,
                None => u as u16,
            }
        })
        .collect();
    // The searcher starts runs in state 0: renumber so that the initial state is 0.
    let init = rm.initial();
    let swap = |u: u16| -> u16 {
        if u as usize == init {
            0
        } else if u == 0 {
            init as u16
        } else {
            u
        }
    };
    let mut swapped = delta.clone();
    for u in 0..rm.n_states() {
        for l in 0..l_n {
            swapped[swap(u as u16) as usize * l_n + l] = swap(delta[u * l_n + l]);
        }
    }
    Ok(searcher.cost(&swapped))
}

/// The label sets that occur in `traces`, sorted.
pub fn observed_label_sets(traces: &[LabelTrace]) -> Vec<LabelSet> {
    let mut v: Vec<LabelSet> = traces
        .iter()
        .flat_map(|t| t.labels.iter().copied())
        .collect();
    v.sort();
    v.dedup();
    v
}

/// Renumbers merged blocks breadth-first from the block of state 0; returns the quotient's
/// cells (targets renumbered) and its state count.
fn renumber_blocks(
    blocks: &[usize],
    merged: &[Option<Cell>],
    l_n: usize,
) -> (Vec<Option<Cell>>, usize) {
    let n = blocks.len();
    let mut id = vec![usize::MAX; n];
    let mut order = vec![blocks[0]];
    id[blocks[0]] = 0;
    let mut head = 0;
    while head < order.len() {
        let b = order[head];
        head += 1;
        for l in 0..l_n {
            if let Some(c) = merged[b * l_n + l] {
                let t = blocks[c.target];
                if id[t] == usize::MAX {
                    id[t] = order.len();
                    order.push(t);
                }
            }
        }
    }
    let q_n = order.len();
    let mut cells = vec![None; q_n * l_n];
    for (new_b, &b) in order.iter().enumerate() {
        for l in 0..l_n {
            cells[new_b * l_n + l] = merged[b * l_n + l].map(|c| Cell {
                target: id[blocks[c.target]],
                ..c
            });
        }
    }
    (cells, q_n)
}

/// A machine over `n` states from per-cell targets and rewards on the observed label sets:
/// one transition per (source, target, reward), guarded by the OR of the exact label sets.
fn machine_from_cells(
    vocab: &Vocabulary,
    labels: &[LabelSet],
    n: usize,
    cells: &[Option<Cell>],
) -> RewardMachine {
    let l_n = labels.len();
    let mut groups: Vec<(usize, usize, f64, Vec<LabelSet>)> = Vec::new();
    for u in 0..n {
        let first = groups.len();
        for (l, &ls) in labels.iter().enumerate() {
            let Some(c) = cells[u * l_n + l] else {
                continue;
            };
            if c.target == u && c.reward == 0.0 {
                continue;
            }
            match groups[first..]
                .iter_mut()
                .find(|g| g.1 == c.target && g.2.to_bits() == c.reward.to_bits())
            {
                Some(g) => g.3.push(ls),
                None => groups.push((u, c.target, c.reward, vec![ls])),
            }
        }
    }
    let transitions = groups
        .into_iter()
        .map(|(from, to, reward, sets)| {
            let mut fs: Vec<Formula> = sets.iter().map(|&l| Formula::exactly(l, vocab)).collect();
            let formula = if fs.len() == 1 {
                fs.pop().unwrap()
            } else {
                Formula::Or(fs)
            };
            Transition {
                from,
                to,
                formula,
                reward,
            }
        })
        .collect();
    RewardMachine::new(vocab.clone(), n.max(1), 0, &[], &[], transitions)
        .expect("exact label-set guards from one table are deterministic and in range")
}
