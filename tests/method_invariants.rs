//! Tests that protect SMIRL's method (issue 54, item 6): each fails on a build that breaks the
//! mechanism it names (the mutation tried is in each test's doc comment).
//!
//! - SAC's reward: along a recorded episode of the product it is the learned reward δ_r(u, o')
//!   itself, nothing added;
//! - the final choice: on hand-built selection episodes whose learned returns are known, it
//!   takes the first candidate of highest learned return;
//! - the normalisation: μ_D − μ_π averaged over trajectories, its coefficients on a
//!   hand-worked case;
//! - no leak: perturbing the perfect machine and its rewards (the ground truth a job is judged
//!   by) leaves the learned reward, the learned returns and the final choice bit-identical,
//!   while the evaluation changes.

use smirl::env::product::ProductEnv;
use smirl::env::reacher::{ReacherConfig, ReacherDelivery};
use smirl::env::reacher_controller::{ControllerGains, ScriptedController};
use smirl::env::ContinuousEnv;
use smirl::irl::reward::{RewardModel, RewardOptimConfig};
use smirl::irl::smirl::{FeatureMap, LinearRmReward};
use smirl::pipeline::reacher_irl::final_policy::{choose, mean_return, FinalCandidate};
use smirl::pipeline::reacher_irl::smirl::{coefficients, ProductReward};
use smirl::pipeline::reacher_irl::{AgentBatch, ExpertData};
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
// SAC's reward
// ---------------------------------------------------------------------------------------------

/// A learned-like machine: blue, then red; no goal, so episodes run to the time limit.
const BLUE_THEN_RED: &str = "vocabulary: rgbyc\nstates: 3\ninitial: 0\n\
                             (0, 1, 'b', 0)\n(1, 2, 'r', 0)\n";

/// Weights of the SAC-reward test: state 0 pays blue and a little red, state 1 red and green
/// and charges yellow, state 2 pays yellow.
#[rustfmt::skip]
const PRODUCT_WEIGHTS: [f32; 3 * K] = [
    0.3, 0.0, 1.0, 0.0, 0.0,
    2.0, 0.5, 0.0, -1.0, 0.0,
    0.0, 0.0, 0.0, 0.7, 0.0,
];

/// One episode of the product (observation ⊕ one-hot state, as SMIRL's SAC stores it) driven
/// by the scripted controller to blue then red: every transition (o, o', terminated).
fn recorded_episode(machine_text: &str, reset_seed: u64) -> Vec<(Vec<f32>, Vec<f32>, bool)> {
    let config = ReacherConfig::default();
    let inner = ReacherDelivery::new(shipped_config(config)).unwrap();
    let mut env = ProductEnv::new(inner, machine(machine_text));
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

/// SMIRL's SAC reads the learned reward itself: along a recorded episode of the product, the
/// reward of every transition (o, o') is δ_r(u, o') — the weights of the state read from o's
/// one-hot block, the features of o' — as the IRL update and the final choice read it, with
/// nothing added.
///
/// Mutation tried: `fill_rewards` adding a potential-based term (γ Φ(u', o') − Φ(u, o), the
/// removed shaping) after `reward_batch`: fails at "step 0".
#[test]
fn sacs_reward_is_the_learned_reward_itself() {
    let steps = recorded_episode(BLUE_THEN_RED, 11);
    let state_of = |row: &[f32]| (0..3).find(|&u| row[obs_dim() + u] == 1.0).unwrap();
    assert_eq!(
        state_of(&steps.last().unwrap().1),
        2,
        "the controller reaches red after blue"
    );
    let batch = batch_of(&steps);
    let features = FeatureMap::reacher_labels(&layout());
    let mut model = LinearRmReward::new(features, 3, RewardOptimConfig::adam(0.1)).unwrap();
    model.set_params(&PRODUCT_WEIGHTS).unwrap();
    let mut sac = vec![0.0f32; batch.len()];
    ProductReward::new(&mut model, None)
        .fill_rewards(&batch, &mut sac)
        .unwrap();
    let next_rows: Vec<f32> = steps
        .iter()
        .flat_map(|s| s.1[..obs_dim()].to_vec())
        .collect();
    let states: Vec<u32> = steps.iter().map(|s| state_of(&s.0) as u32).collect();
    let mut learned = vec![0.0f32; steps.len()];
    model
        .reward_batch(&next_rows, &states, &mut learned)
        .unwrap();
    for (t, (s, l)) in sac.iter().zip(&learned).enumerate() {
        assert_eq!(s.to_bits(), l.to_bits(), "step {t}: SAC's {s}, learned {l}");
    }
    assert!(
        learned.iter().any(|&r| r != 0.0),
        "the episode touches a paid ball"
    );
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
/// Mutations tried in `choose` (`src/pipeline/reacher_irl/final_policy.rs`): the lowest learned
/// return (`<` for `>`): fails "the highest learned return" (0 for 3); the last of equals (`>=`
/// for `>`): fails "the first of equals" (2 for 1).
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
// The normalisation: μ_D − μ_π averaged over trajectories
// ---------------------------------------------------------------------------------------------

/// SMIRL's coefficients (`coefficients`, as every SMIRL variant's update reads them) on a case
/// worked by hand, on a learned machine of IF with a state only the cancel enters (0 -b-> 1,
/// 0 -c-> 2, red to 3 from either; each step's state given by hand). Expert: three trajectories, E1 in states 0, 1, 3, E2 in 0, 1, 3, E3 (the
/// cancel) in 0, 2, 3. Agent: two, A1 and A2 in 0 and 1 only. Every agent row gets +1/N_A =
/// +½ and every expert row −1/N_D = −⅓, whatever its state — no state is weighted by the
/// trajectories that visit it, and an expert state the agent never reaches (2, 3) keeps its
/// pull. The gradient on w_u is then μ_π(u) − μ_D(u): expert yellow touches in state 3 (one
/// per trajectory) give −1, E3's two red touches in state 2 −⅔, A1's two green touches in
/// state 0 +1, red in state 1 (E1, E2) −⅔.
///
/// Mutation tried: the sign of μ_D − μ_π flipped (`(per(agent, -1.0), per(expert, 1.0))` in
/// `maxent_coefficients`, `src/irl/smirl.rs`): fails at the coefficients (−½ for ½). A
/// normalisation by the trajectories visiting each state (the removed event-gated visits) would
/// give state 1's expert rows −½ and state 2's −1, not −⅓.
#[test]
fn trajectory_averaged_coefficients_on_a_hand_worked_case() {
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
    let got = coefficients(&expert, &agent);

    let (h, third) = (0.5, 1.0 / 3.0);
    #[rustfmt::skip]
    let expected = [
        // Agent A1 (states 0 0 0 1), A2 (0 1 1).
        h, h, h, h, h, h, h,
        // Expert E1 (0 0 1 1 3), E2 (0 1 3), E3 (0 2 2 3).
        -third, -third, -third, -third, -third,
        -third, -third, -third,
        -third, -third, -third, -third,
    ];
    assert_eq!(got.coeffs, expected);
    let states: Vec<u32> = [agent.states.as_slice(), &expert.learned_states].concat();
    assert_eq!(got.states, states);
    assert_eq!(got.obs, [agent.obs.as_slice(), &expert.obs].concat());

    // The gradient of the loss on w: Σ_rows c · φ(row) per (state, feature) = μ_π − μ_D.
    let features = FeatureMap::reacher_labels(&layout());
    let mut model = LinearRmReward::new(features, 4, RewardOptimConfig::adam(0.1)).unwrap();
    model.backward(&got.obs, &got.states, &got.coeffs).unwrap();
    let grad = model.grad();
    let at = |u: usize, f: usize| grad[u * K + f];
    let close = |x: f32, want: f64| (f64::from(x) - want).abs() < 1e-6;
    assert!(
        close(at(3, YELLOW), -1.0),
        "three yellow touches in state 3, −⅓ each: {}",
        at(3, YELLOW)
    );
    assert!(
        close(at(2, RED), -2.0 / 3.0),
        "E3's two red touches in state 2, which the agent never enters: {}",
        at(2, RED)
    );
    assert!(
        close(at(0, GREEN), 1.0),
        "A1's two green touches in state 0, +½ each: {}",
        at(0, GREEN)
    );
    // Blue in state 0: agents 2 × ½, experts E1, E2 −⅓ each.
    assert!(close(at(0, BLUE), 1.0 - 2.0 / 3.0), "{}", at(0, BLUE));
    assert!(
        close(at(1, RED), -2.0 / 3.0),
        "E1 and E2 touch red in state 1, −⅓ each: {}",
        at(1, RED)
    );
}
