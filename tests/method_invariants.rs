//! Tests that protect SMIRL's method (issue 54, item 6): each fails on a build that breaks the
//! mechanism it names (the mutation tried is in each test's doc comment).
//!
//! - shaping: along a recorded episode, the shaped minus the unshaped reward telescopes to
//!   γ^T Φ_T − Φ_0 (Φ_T = 0 after a terminating step), step by step it is γ Φ' − Φ, and moving
//!   towards the ball a state's reward values raises it;
//! - the final choice: on hand-built selection episodes whose learned returns are known, it
//!   takes the first candidate of highest learned return;
//! - the event-gated normalisation: its coefficients on a hand-worked case;
//! - no leak: perturbing the perfect machine and its rewards (the ground truth a job is judged
//!   by) leaves the learned reward, the learned returns and the final choice bit-identical,
//!   while the evaluation changes.

use smirl::env::product::ProductEnv;
use smirl::env::reacher::{ReacherConfig, ReacherDelivery};
use smirl::env::reacher_controller::{ControllerGains, ScriptedController};
use smirl::env::ContinuousEnv;
use smirl::irl::reward::{RewardModel, RewardOptimConfig};
use smirl::irl::smirl::{FeatureMap, LearnedSubgoalPotential, LinearRmReward, SmirlNormalisation};
use smirl::pipeline::reacher_irl::final_policy::{choose, mean_return, FinalCandidate};
use smirl::pipeline::reacher_irl::smirl::{coefficients, ProductReward};
use smirl::pipeline::reacher_irl::{AgentBatch, ExpertData, IrlRunConfig};
use smirl::rl::replay::ReplayBatch;
use smirl::rl::sac::RewardFn;
use smirl::rm::format::parse_rm;
use smirl::rm::{LabelSet, RewardMachine};

#[allow(unused_imports)]
use shipped_layout::{layout, obs_dim, shipped_config};
mod shipped_layout;

const RED: usize = 0;
const GREEN: usize = 1;
const BLUE: usize = 2;
const YELLOW: usize = 3;
const CANCEL: usize = 4;
/// Features per RM state: four balls and the cancel flag.
const K: usize = 5;

fn machine(text: &str) -> RewardMachine {
    parse_rm(text, "test machine").unwrap()
}

fn labels(props: &[usize]) -> LabelSet {
    props.iter().fold(LabelSet::EMPTY, |l, &p| l.with(p))
}

/// An observation row whose labels are `l`: the fingertip 7 mm from every ball of `l` and
/// 0.5 m from the others, the cancel flag as `l` says.
fn row_of(l: LabelSet) -> Vec<f32> {
    let mut r = vec![0.5f32; obs_dim()];
    r[layout().event_column(0)] = if l.contains(CANCEL) { 1.0 } else { 0.0 };
    for b in 0..4 {
        if l.contains(b) {
            r[8 + 2 * b] = 0.005;
            r[9 + 2 * b] = -0.005;
        }
    }
    r
}

/// The state each step's labels are read in (u_{t−1}), as `annotate` pairs them.
fn states_along(m: &RewardMachine, trace: &[LabelSet]) -> Vec<u32> {
    let mut u = m.initial();
    trace
        .iter()
        .map(|&l| {
            let before = u;
            u = m.next_state(u, l);
            before as u32
        })
        .collect()
}

// ---------------------------------------------------------------------------------------------
// Shaping
// ---------------------------------------------------------------------------------------------

/// A learned-like machine: blue, then red; no goal, so episodes run to the time limit.
const BLUE_THEN_RED: &str = "vocabulary: rgbyc\nstates: 3\ninitial: 0\n\
                             (0, 1, 'b', 0)\n(1, 2, 'r', 0)\n";
/// The same with a goal after red: the product terminates there.
const BLUE_THEN_RED_GOAL: &str = "vocabulary: rgbyc\nstates: 3\ninitial: 0\nterminal: 2\n\
                                  (0, 1, 'b', 0)\n(1, 2, 'r', 0)\n";

/// Weights of the shaping tests: state 0 pays blue (1.0; red's 0.3 is under half of it, so
/// only blue attracts), state 1 pays red (2.0; green's 0.5 does not attract), state 2 pays
/// yellow (0.7), so that Φ is not 0 where episodes end.
#[rustfmt::skip]
const SHAPING_WEIGHTS: [f32; 3 * K] = [
    0.3, 0.0, 1.0, 0.0, 0.0,
    2.0, 0.5, 0.0, -1.0, 0.0,
    0.0, 0.0, 0.0, 0.7, 0.0,
];

/// Φ(u, o) by hand for [`SHAPING_WEIGHTS`] with strength β: −β · (state's largest ball weight)
/// · (distance to its attracting ball).
fn potential_by_hand(row: &[f32], beta: f64) -> f64 {
    let u = (0..3).find(|&u| row[obs_dim() + u] == 1.0).unwrap();
    let dist = |b: usize| f64::from(row[8 + 2 * b]).hypot(f64::from(row[9 + 2 * b]));
    match u {
        0 => -beta * 1.0 * dist(BLUE),
        1 => -beta * 2.0 * dist(RED),
        _ => -beta * f64::from(0.7f32) * dist(YELLOW),
    }
}

/// One episode of the product (observation ⊕ one-hot state ⊕ clock, as SMIRL's SAC stores it)
/// driven by the scripted controller to blue then red: every transition (o, o', terminated).
fn recorded_episode(machine_text: &str, reset_seed: u64) -> Vec<(Vec<f32>, Vec<f32>, bool)> {
    let config = ReacherConfig::default();
    let inner = ReacherDelivery::new(shipped_config(config.clone())).unwrap();
    let mut env = ProductEnv::new(inner, machine(machine_text)).with_clock(config.max_steps);
    let d = env.obs_dim();
    let (mut obs, mut next) = (vec![0.0f32; d], vec![0.0f32; d]);
    env.reset(reset_seed, &mut obs);
    let mut controller = ScriptedController::sequence(&[BLUE, RED], ControllerGains::default());
    let mut steps = Vec::new();
    loop {
        let action = controller.act(&obs[..obs_dim()], env.inner().labels(), None);
        let step = env.step(&action, &mut next).unwrap();
        steps.push((obs.clone(), next.clone(), step.terminated));
        std::mem::swap(&mut obs, &mut next);
        if step.terminated || step.truncated {
            return steps;
        }
    }
}

/// The transitions as a SAC batch, one column each.
fn batch_of(steps: &[(Vec<f32>, Vec<f32>, bool)]) -> ReplayBatch {
    let d = steps[0].0.len();
    let mut batch = ReplayBatch::new(d, 2, steps.len());
    for (i, (o, next, terminated)) in steps.iter().enumerate() {
        batch.obs.as_mut_slice()[i * d..(i + 1) * d].copy_from_slice(o);
        batch.next_obs.as_mut_slice()[i * d..(i + 1) * d].copy_from_slice(next);
        batch.terminated[i] = if *terminated { 1.0 } else { 0.0 };
    }
    batch
}

/// SMIRL's SAC reward of every transition, unshaped and shaped with strength β and discount γ.
fn product_rewards(batch: &ReplayBatch, beta: f64, gamma: f64) -> (Vec<f32>, Vec<f32>) {
    let features = FeatureMap::reacher_labels(&layout());
    let mut model = LinearRmReward::new(features.clone(), 3, RewardOptimConfig::adam(0.1)).unwrap();
    model.set_params(&SHAPING_WEIGHTS).unwrap();
    let potential =
        LearnedSubgoalPotential::from_weights(&features, 3, &SHAPING_WEIGHTS, beta).unwrap();
    let mut plain = vec![0.0f32; batch.len()];
    ProductReward::new(&mut model, None, None)
        .fill_rewards(batch, &mut plain)
        .unwrap();
    let mut shaped = vec![0.0f32; batch.len()];
    ProductReward::new(&mut model, None, Some((&potential, gamma)))
        .fill_rewards(batch, &mut shaped)
        .unwrap();
    (plain, shaped)
}

/// Shaping along recorded episodes of the product, as SMIRL's SAC reads its batches (standard
/// strength β = 1 and the IRL runs' discount γ):
/// - step by step, shaped − unshaped = γ Φ(u', o') − Φ(u, o), with Φ(u', o') = 0 on a
///   terminating step, Φ computed here by hand from the fingertip–ball offsets;
/// - along the episode, Σ_t γ^t (shaped_t − unshaped_t) = γ^T Φ_T − Φ_0 (truncated at the time
///   limit) and = −Φ_0 (terminated at the goal): shaping adds only a function of the ends;
/// - its sign: a step in a state that brings the fingertip closer to the ball the state's
///   reward pays (d' < d/γ) is shaped up, one that moves away is shaped down, and approaching
///   blue before touching it adds up to a positive shaping.
///
/// Mutation tried: `*r += (after − Φ(prev))` → `*r -= …` in `ProductReward::fill_rewards`
/// (`src/pipeline/reacher_irl/smirl.rs`): fails the per-step identity at "step 0". Also
/// tried: dropping the terminal case (`after` = γ Φ' on every step): fails the per-step
/// identity on the terminated episode's last step ("step 26").
#[test]
fn shaping_telescopes_along_a_recorded_episode_and_pulls_towards_the_paid_ball() {
    let beta = 1.0;
    assert_eq!(IrlRunConfig::standard().smirl_shaping, beta);
    let gamma = f64::from(IrlRunConfig::standard().sac.gamma);
    for (text, reset_seed, ends_at_goal) in
        [(BLUE_THEN_RED, 11, false), (BLUE_THEN_RED_GOAL, 11, true)]
    {
        let steps = recorded_episode(text, reset_seed);
        let last = steps.last().unwrap();
        assert_eq!(last.2, ends_at_goal, "the episode ends as the machine says");
        // The controller visits blue, then red: the episode passes through every state.
        let state_of = |row: &[f32]| (0..3).find(|&u| row[obs_dim() + u] == 1.0).unwrap();
        assert_eq!(
            state_of(&last.1),
            2,
            "the controller reaches red after blue"
        );
        let batch = batch_of(&steps);
        let (plain, shaped) = product_rewards(&batch, beta, gamma);

        let mut discounted = 0.0;
        let mut approach = 0.0;
        let mut closer_steps = 0;
        for (t, ((o, next, terminated), (&p, &s))) in
            steps.iter().zip(plain.iter().zip(&shaped)).enumerate()
        {
            let after = if *terminated {
                0.0
            } else {
                gamma * potential_by_hand(next, beta)
            };
            let expected = after - potential_by_hand(o, beta);
            let f = f64::from(s) - f64::from(p);
            assert!(
                (f - expected).abs() < 1e-5,
                "step {t}: shaped − unshaped = {f}, γ Φ' − Φ = {expected}"
            );
            discounted += gamma.powi(t as i32) * f;
            // Sign, within a state that pulls: closer (d' < d/γ) is rewarded.
            let (u, u_next) = (state_of(o), state_of(next));
            if u == u_next && !*terminated {
                let ball = [BLUE, RED, YELLOW][u];
                let dist = |r: &[f32]| f64::from(r[8 + 2 * ball]).hypot(f64::from(r[9 + 2 * ball]));
                let margin = dist(o) - gamma * dist(next);
                if margin.abs() > 1e-4 {
                    assert_eq!(
                        f > 0.0,
                        margin > 0.0,
                        "step {t}: shaping {f}, d − γ d' = {margin}"
                    );
                    closer_steps += usize::from(margin > 0.0);
                }
                if u == 0 {
                    approach += f;
                }
            }
        }
        let t_end = steps.len() as i32;
        let phi_end = if ends_at_goal {
            0.0
        } else {
            potential_by_hand(&last.1, beta)
        };
        let phi_0 = potential_by_hand(&steps[0].0, beta);
        let telescoped = gamma.powi(t_end) * phi_end - phi_0;
        assert!(
            (discounted - telescoped).abs() < 1e-4,
            "Σ γ^t (shaped − unshaped) = {discounted}, γ^T Φ_T − Φ_0 = {telescoped}"
        );
        assert!(
            phi_0 < -0.05,
            "the episode starts away from blue (Φ_0 = {phi_0})"
        );
        assert!(
            closer_steps >= 5,
            "only {closer_steps} steps approach a paid ball"
        );
        assert!(approach > 0.05, "approaching blue is shaped by {approach}");
    }
}

// ---------------------------------------------------------------------------------------------
// The final choice
// ---------------------------------------------------------------------------------------------

/// A learned machine of IF that merges "blue touched" with "cancelled" (`0 -(b|c)-> 1`), as
/// LRM learns it: no failure state, so blue after the cancel costs nothing in it.
const IF_MERGED: &str = "vocabulary: rgbyc\nstates: 3\ninitial: 0\n\
                         (0, 1, 'b|c', 0)\n(1, 2, 'r', 0)\n";

/// The learned reward of the selection tests: blue pays in state 0, red in states 1 and 2,
/// and blue in state 1 pays half of red (the normal branch touches blue on its way into it).
#[rustfmt::skip]
const SELECTION_WEIGHTS: [f32; 3 * K] = [
    0.0, 0.0, 1.0, 0.0, 0.0,
    1.0, 0.0, 0.5, 0.0, 0.0,
    1.0, 0.0, 0.0, 0.0, 0.0,
];

/// Selection episodes (label traces) played by one candidate: their learned rewards,
/// concatenated, and their lengths.
struct Recorded {
    rewards: Vec<f32>,
    lengths: Vec<usize>,
}

fn record(m: &RewardMachine, episodes: &[Vec<LabelSet>]) -> Recorded {
    let mut model = LinearRmReward::new(
        FeatureMap::reacher_labels(&layout()),
        m.n_states(),
        RewardOptimConfig::adam(0.1),
    )
    .unwrap();
    model.set_params(&SELECTION_WEIGHTS).unwrap();
    let mut rec = Recorded {
        rewards: Vec::new(),
        lengths: Vec::new(),
    };
    for trace in episodes {
        let states = states_along(m, trace);
        let rows: Vec<f32> = trace.iter().flat_map(|&l| row_of(l)).collect();
        let mut r = vec![0.0f32; trace.len()];
        model.reward_batch(&rows, &states, &mut r).unwrap();
        rec.rewards.extend(r);
        rec.lengths.push(trace.len());
    }
    rec
}

/// The final choice on IF, on hand-built selection episodes whose learned returns are worked
/// by hand: each candidate plays one normal and one cancelled episode. Normal: blue in state 0
/// (1.0), red entering state 2 (1.0), red in it (1.0): 3.0. Cancelled: A touches blue in state
/// 1 (0.5) and red four times (4.0); B red three times (3.0); C red once (1.0); D is B again.
/// Means over the two episodes: A 3.75, B 3.0, C 2.0, D 3.0. The choice reads the plain
/// learned return, so it takes A (the highest) from every order, and of B and D, equal, the
/// first; the ground truth (A fails the cancelled branch) does not enter.
///
/// Mutations tried: `choose` taking the lowest learned return (`<` for `>`): fails "the
/// highest learned return" (3, not 0); `choose` taking the last of equals (`>=`): fails "the
/// first of equals" (3, not 1); `mean_return` dividing by steps instead of episodes: fails
/// "A's learned return".
#[test]
fn the_final_choice_takes_the_first_candidate_of_highest_learned_return() {
    let m = machine(IF_MERGED);
    let (e, c, r, b) = (
        LabelSet::EMPTY,
        labels(&[CANCEL]),
        labels(&[RED]),
        labels(&[BLUE]),
    );
    let normal = vec![e, e, b, e, r, r, e, e];
    let plays = [
        [normal.clone(), vec![c, e, b, e, r, r, r, r]],
        [normal.clone(), vec![c, e, e, e, e, r, r, r]],
        [normal.clone(), vec![c, e, e, e, e, e, e, r]],
        [normal, vec![c, e, e, e, e, r, r, r]],
    ];
    let candidate = |episodes: &[Vec<LabelSet>], success_rate: f64| {
        let rec = record(&m, episodes);
        FinalCandidate {
            env_steps: 0,
            learned_return: mean_return(&rec.rewards, &rec.lengths).unwrap(),
            success_rate,
            branches: None,
            progress: 0.0,
            final_ball: 0.0,
            final_set: None,
        }
    };
    let [a, b_, c_, d] = [
        candidate(&plays[0], 0.0),
        candidate(&plays[1], 1.0),
        candidate(&plays[2], 1.0),
        candidate(&plays[3], 1.0),
    ];
    assert_eq!(a.learned_return, (3.0 + 4.5) / 2.0, "A's learned return");
    assert_eq!(b_.learned_return, 3.0, "B's learned return");
    assert_eq!(c_.learned_return, 2.0, "C's learned return");
    assert_eq!(d.learned_return, b_.learned_return, "D's learned return");
    assert_eq!(
        choose(&[c_.clone(), b_.clone(), d.clone(), a.clone()]),
        3,
        "the highest learned return"
    );
    assert_eq!(
        choose(&[a.clone(), c_.clone(), b_.clone()]),
        0,
        "the highest learned return, first"
    );
    assert_eq!(
        choose(&[c_.clone(), b_.clone(), d.clone()]),
        1,
        "the first of equals"
    );
    assert_eq!(choose(&[c_]), 0, "one candidate");
    // Lengths that do not add up to the rewards are an error.
    let rec = record(&m, &plays[0]);
    assert!(mean_return(&rec.rewards, &[3]).is_err());
}

// ---------------------------------------------------------------------------------------------
// The event-gated normalisation
// ---------------------------------------------------------------------------------------------

/// A learned machine of IF with a state only the cancel enters: 0 -b-> 1, 0 -c-> 2, then red
/// to 3 from either.
const IF_SPLIT: &str = "vocabulary: rgbyc\nstates: 4\ninitial: 0\n\
                        (0, 1, 'b&!c', 0)\n(0, 2, 'c', 0)\n(1, 3, 'r', 0)\n(2, 3, 'r', 0)\n";

/// The standard normalisation's coefficients (`event_gated_visits`, through SMIRL's
/// `coefficients`) on a case worked by hand. Expert: E1 visits states 0, 1, 3; E2 0, 1, 3; E3
/// (the cancel) 0, 2, 3 — N_D = (3, 2, 1, 3). Agent: A1 and A2 visit 0 and 1 only — N_A =
/// (2, 2, 0, 0). Agent rows get +1/N_A(u): ½ in states 0 and 1. Expert rows get −1/N_D(u)
/// where the agent comes (state 0: −⅓, state 1: −½); where it does not, state 3 keeps its
/// pull (the agent can reach it by its own moves: −⅓) and state 2, which only the cancel
/// enters, gets 0. The gradient on w follows: expert yellow touches in state 3 (one per
/// trajectory) give −1, E3's red touches in state 2 nothing, A1's green touches in state 0
/// (two) +1.
///
/// Mutations tried: `maxent_coefficients_by_shared_visits` ignoring `pull_unvisited` (every
/// unvisited state dropped): fails at state 3's −⅓; `coefficients` gating with every state
/// free (`vec![true; n]`, i.e. plain visits): fails at state 2's 0; `trajectories_visiting`
/// counting rows instead of trajectories: fails at state 0's coefficients; the expert rows'
/// coefficient −1/N_D(u) halved (`per(expert, -0.5)` in `maxent_coefficients_by_visits`):
/// fails at the coefficients.
#[test]
fn event_gated_normalisation_coefficients_on_a_hand_worked_case() {
    let m = machine(IF_SPLIT);
    let (e, c, r, g, y) = (
        LabelSet::EMPTY,
        labels(&[CANCEL]),
        labels(&[RED]),
        labels(&[GREEN]),
        labels(&[YELLOW]),
    );
    let b = labels(&[BLUE]);
    // Each step's state is given (u_{t−1}); its row's labels are the next observation's.
    let expert_steps: [&[(u32, LabelSet)]; 3] = [
        &[(0, e), (0, b), (1, e), (1, r), (3, y)],
        &[(0, b), (1, r), (3, y)],
        &[(0, c), (2, r), (2, r), (3, y)],
    ];
    let agent_steps: [&[(u32, LabelSet)]; 2] =
        [&[(0, g), (0, g), (0, b), (1, e)], &[(0, b), (1, e), (1, e)]];
    let mut expert = ExpertData {
        obs: Vec::new(),
        lengths: Vec::new(),
        learned_states: Vec::new(),
    };
    for t in expert_steps {
        for &(u, l) in t {
            expert.obs.extend(row_of(l));
            expert.learned_states.push(u);
        }
        expert.lengths.push(t.len());
    }
    let mut agent = AgentBatch::default();
    for t in agent_steps {
        for &(u, l) in t {
            agent.obs.extend(row_of(l));
            agent.states.push(u);
        }
        agent.lengths.push(t.len());
    }
    let features = FeatureMap::reacher_labels(&layout());
    let normalisation = IrlRunConfig::standard().normalisation();
    assert_eq!(normalisation, SmirlNormalisation::EventGatedVisits);
    let got = coefficients(&features, &expert, &agent, normalisation, &m);

    let (h, third) = (0.5, 1.0 / 3.0);
    #[rustfmt::skip]
    let expected = [
        // Agent A1 (states 0 0 0 1), A2 (0 1 1).
        h, h, h, h, h, h, h,
        // Expert E1 (0 0 1 1 3), E2 (0 1 3), E3 (0 2 2 3).
        -third, -third, -h, -h, -third,
        -third, -h, -third,
        -third, 0.0, 0.0, -third,
    ];
    assert_eq!(got.coeffs, expected);
    let states: Vec<u32> = [agent.states.as_slice(), &expert.learned_states].concat();
    assert_eq!(got.states, states);
    assert_eq!(got.obs, [agent.obs.as_slice(), &expert.obs].concat());

    // The gradient of the loss on w: Σ_rows c · φ(row) per (state, feature).
    let mut model = LinearRmReward::new(features, 4, RewardOptimConfig::adam(0.1)).unwrap();
    model.backward(&got.obs, &got.states, &got.coeffs).unwrap();
    let grad = model.grad();
    let at = |u: usize, f: usize| grad[u * K + f];
    assert_eq!(
        at(3, YELLOW),
        -1.0,
        "three yellow touches in state 3, −⅓ each"
    );
    assert_eq!(
        at(2, RED),
        0.0,
        "state 2 is entered only by the cancel and never by the agent"
    );
    assert_eq!(
        at(0, GREEN),
        1.0,
        "A1's two green touches in state 0, +½ each"
    );
    // Blue in state 0: agents 2 × ½, experts E1, E2 −⅓ each.
    assert!((at(0, BLUE) - (1.0 - 2.0 / 3.0) as f32).abs() < 1e-7);
    assert_eq!(at(1, RED), -1.0, "E1 and E2 touch red in state 1, −½ each");
}
