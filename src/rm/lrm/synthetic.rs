//! Expert-like label traces for tests, benchmarks and experiments, generated from a task's
//! machine without an environment.
//!
//! An expert completes the task in *trips* (paper appendix B): from the machine's current
//! state it aims at a shortest sequence of single sub-goal letters that reaches a terminal
//! state (ties broken at random), walks to each with some empty-label steps in between, may
//! cross an *incidental* letter on the way, and lands on the sub-goal for one or a few steps.
//! Incidental letters mimic the map: each leg (previous sub-goal → next sub-goal) has a fixed
//! letter its shortest path crosses, or none, chosen by a fixed hash among the letters that no
//! transition of the task uses. After a completed trip the expert takes up to `detour` random
//! steps (landing on random letters now and then) and starts the next trip, until the
//! episode's horizon; or, with `one_trip`, the episode ends after the trip. Uncontrolled
//! propositions (a ReacherDelivery task's events) can fire on empty steps.
//!
//! Rewards are those of the task's machine restarted after each completed trip
//! ([`RmTracker::restarting`]). Traces from random label sequences carry no structure for the
//! LRM objective; these do, like real demonstrations.

use super::LabelTrace;
use crate::rm::format::RmFileError;
use crate::rm::labels::{LabelSet, Vocabulary};
use crate::rm::machine::RewardMachine;
use crate::rm::perfect;
use crate::rm::product::RmTracker;
use rand::seq::SliceRandom;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// How the synthetic expert behaves.
#[derive(Clone, Debug, PartialEq)]
pub struct ExpertStyle {
    /// Propositions the expert can walk to, one at a time.
    pub goal_props: String,
    /// Raw steps per episode at most.
    pub horizon: usize,
    /// End the episode once the task is completed (else: detour, then another trip).
    pub one_trip: bool,
    /// Range of empty steps before each letter.
    pub gap: (usize, usize),
    /// Range of steps a reached letter stays true.
    pub hold: (usize, usize),
    /// Probability that a leg with an incidental letter crosses it.
    pub incidental: f64,
    /// Most random steps after a completed trip.
    pub detour: usize,
    /// Probability that a random step lands on a (random) letter.
    pub detour_letter: f64,
    /// Uncontrolled propositions, each with its probability on each empty step.
    pub noise: Vec<(char, f64)>,
}

impl ExpertStyle {
    /// Office Gridworld: paths of a few to a dozen cells between objects, trips repeated
    /// until the horizon with up to 10 random steps in between.
    pub fn office() -> ExpertStyle {
        ExpertStyle {
            goal_props: "ABCDcmo".into(),
            horizon: 1000,
            one_trip: false,
            gap: (2, 12),
            hold: (1, 2),
            incidental: 0.8,
            detour: 10,
            detour_letter: 0.15,
            noise: Vec::new(),
        }
    }

    /// ReacherDelivery: one trip per episode, the fingertip stays on a region for a few steps,
    /// and each event fires now and then. `regions` and `events` are the task's letters (its
    /// layout's regions' and events', in label-bit order: `"rgby"` and `"c"` for the paper's
    /// tasks).
    pub fn reacher(regions: &str, events: &str) -> ExpertStyle {
        ExpertStyle {
            goal_props: regions.into(),
            horizon: 300,
            one_trip: true,
            gap: (5, 30),
            hold: (2, 8),
            incidental: 0.3,
            detour: 0,
            detour_letter: 0.0,
            noise: events.chars().map(|e| (e, 0.01)).collect(),
        }
    }
}

/// Expert-like traces of Office task `task` totalling `total_steps` transitions.
pub fn office_traces(
    task: usize,
    total_steps: usize,
    seed: u64,
) -> Result<Vec<LabelTrace>, RmFileError> {
    let rm = perfect::office(task)?;
    Ok(expert_like_traces(
        &rm,
        &ExpertStyle::office(),
        total_steps,
        seed,
    ))
}

/// Expert-like traces for the task of `rm` (see the module docs), `total_steps` transitions
/// in all (the last episode is cut to fit). Propositions of `style` that the vocabulary does
/// not have are ignored.
pub fn expert_like_traces(
    rm: &RewardMachine,
    style: &ExpertStyle,
    total_steps: usize,
    seed: u64,
) -> Vec<LabelTrace> {
    let v = rm.vocab();
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let goals: Vec<usize> = style
        .goal_props
        .chars()
        .filter_map(|c| v.index_of(c).ok())
        .collect();
    let dist = distance_to_goal(rm, &goals);
    let neutral: Vec<usize> = goals
        .iter()
        .copied()
        .filter(|&p| {
            (0..rm.n_states())
                .filter(|&u| !rm.is_absorbing(u))
                .all(|u| rm.next_state(u, LabelSet::EMPTY.with(p)) == u)
        })
        .collect();
    let noise: Vec<(usize, f64)> = (style.noise.iter())
        .filter_map(|&(c, p)| v.index_of(c).ok().map(|i| (i, p)))
        .collect();
    let mut traces = Vec::new();
    let mut produced = 0;
    while produced < total_steps {
        let budget = style.horizon.min(total_steps - produced).max(1);
        let mut ep = Episode {
            tracker: RmTracker::restarting(rm.clone()),
            labels: Vec::new(),
            rewards: Vec::new(),
            budget,
            noise: noise.clone(),
        };
        let mut completed = 0;
        let mut last: Option<usize> = None;
        'episode: while !ep.full() {
            // One trip: from the machine's state, shortest letter sequences to a goal.
            let mut prev: Option<usize> = None;
            let start_trips = completed;
            while completed == start_trips {
                let u = ep.tracker.state();
                let Some(next) = next_letter(rm, &dist, &goals, u, &mut rng) else {
                    break 'episode; // failed or no way to the goal
                };
                let gap = rng.gen_range(style.gap.0..=style.gap.1);
                let crossing = incidental_letter(v, &neutral, prev, next)
                    .filter(|_| rng.gen_bool(style.incidental));
                let half = gap / 2;
                ep.empties(half, &mut rng);
                if let Some(c) = crossing {
                    ep.letter(c, 1);
                }
                ep.empties(gap - half, &mut rng);
                let hold = rng.gen_range(style.hold.0..=style.hold.1);
                if ep.letter(next, hold) {
                    completed += 1;
                }
                prev = Some(next);
                last = Some(next);
                if ep.full() {
                    break 'episode;
                }
            }
            if style.one_trip {
                let tail = rng.gen_range(style.gap.0..=style.gap.1);
                ep.empties(tail, &mut rng);
                break;
            }
            let k = rng.gen_range(0..=style.detour);
            let mut step = 0;
            while step < k && !ep.full() {
                if rng.gen_bool(style.detour_letter) && !goals.is_empty() {
                    // A random walk from the last letter only reaches letters close to it:
                    // the letter itself or its fixed neighbour on the map.
                    let here = last.unwrap_or(goals[0]);
                    let p = if rng.gen_bool(0.6) {
                        here
                    } else {
                        neighbour_letter(&goals, here)
                    };
                    last = Some(p);
                    if ep.letter(p, 1) {
                        completed += 1;
                    }
                    ep.empties(1, &mut rng);
                    step += 2;
                } else {
                    ep.empties(1, &mut rng);
                    step += 1;
                }
            }
        }
        // A machine with no way to a goal from its state gives no trip: the expert idles,
        // so that every episode makes progress.
        let rest = ep.budget - ep.labels.len();
        if ep.labels.is_empty() {
            ep.empties(rest, &mut rng);
        }
        produced += ep.labels.len();
        traces.push(LabelTrace {
            labels: ep.labels,
            rewards: Some(ep.rewards),
        });
    }
    traces
}

struct Episode {
    tracker: RmTracker,
    labels: Vec<LabelSet>,
    rewards: Vec<f64>,
    budget: usize,
    noise: Vec<(usize, f64)>,
}

impl Episode {
    fn full(&self) -> bool {
        self.labels.len() >= self.budget
    }

    /// Pushes one step; returns whether it completed the task.
    fn push(&mut self, l: LabelSet) -> bool {
        if self.full() {
            return false;
        }
        let step = self.tracker.step(l);
        self.labels.push(l);
        self.rewards.push(step.reward);
        step.terminal
    }

    fn empties(&mut self, n: usize, rng: &mut ChaCha8Rng) {
        for _ in 0..n {
            let mut l = LabelSet::EMPTY;
            for &(p, prob) in &self.noise {
                if rng.gen_bool(prob) {
                    l = l.with(p);
                }
            }
            self.push(l);
        }
    }

    fn letter(&mut self, p: usize, hold: usize) -> bool {
        let mut done = false;
        for _ in 0..hold.max(1) {
            done |= self.push(LabelSet::EMPTY.with(p));
        }
        done
    }
}

/// The letter next to `p` on the (imaginary) map: a fixed function of `p`.
fn neighbour_letter(goals: &[usize], p: usize) -> usize {
    let k = goals.iter().position(|&g| g == p).unwrap_or(0);
    goals[(k * 5 + 3) % goals.len()]
}

/// Fewest single-letter steps from each state to a terminal state (`usize::MAX` if none).
fn distance_to_goal(rm: &RewardMachine, goals: &[usize]) -> Vec<usize> {
    let n = rm.n_states();
    let mut dist: Vec<usize> = (0..n)
        .map(|u| if rm.is_terminal(u) { 0 } else { usize::MAX })
        .collect();
    for _ in 0..n {
        for u in 0..n {
            if rm.is_absorbing(u) {
                continue;
            }
            for &p in goals {
                let w = rm.next_state(u, LabelSet::EMPTY.with(p));
                if w != u && dist[w] != usize::MAX {
                    dist[u] = dist[u].min(dist[w] + 1);
                }
            }
        }
    }
    dist
}

fn next_letter(
    rm: &RewardMachine,
    dist: &[usize],
    goals: &[usize],
    u: usize,
    rng: &mut ChaCha8Rng,
) -> Option<usize> {
    if dist[u] == usize::MAX || dist[u] == 0 {
        return None;
    }
    let options: Vec<usize> = goals
        .iter()
        .copied()
        .filter(|&p| {
            let w = rm.next_state(u, LabelSet::EMPTY.with(p));
            w != u && dist[w] != usize::MAX && dist[w] + 1 == dist[u]
        })
        .collect();
    options.choose(rng).copied()
}

/// The letter the path of a leg crosses, if any: a fixed function of the leg (like the map),
/// not of the seed.
fn incidental_letter(
    v: &Vocabulary,
    neutral: &[usize],
    prev: Option<usize>,
    next: usize,
) -> Option<usize> {
    if neutral.is_empty() {
        return None;
    }
    let key = prev.map_or(v.len(), |p| p) * 31 + next + 7;
    let h = (key as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15) >> 32;
    if h.is_multiple_of(2) {
        None
    } else {
        Some(neutral[(h / 2) as usize % neutral.len()])
    }
}
