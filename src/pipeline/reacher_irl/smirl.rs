//! Continuous SMIRL on ReacherDelivery (paper section 3, Algorithm 1), the algorithm in one
//! place:
//!
//! 1. **Learn the machine** ([`learn_machine`]): LRM's Tabu search on the demonstrations' label
//!    traces, without rewards (rewards are what IRL learns). (`[smirl] machine = "task"`:
//!    the task's own machine instead, [`task_machine`], an oracle for diagnosis.)
//! 2. **Annotate** ([`annotate`]): every expert observation o_t gets the learned state
//!    u_{t−1} its labels are read in (demonstrations held at their final state to the
//!    horizon, so expert and agent are compared over one T).
//! 3. **IRL on U × O** ([`train`], the loop of [`super::irl_loop`]), per iteration:
//!    1. SAC on the product ReacherDelivery × learned machine (observation ⊕ one-hot u) with
//!       the current reward δ_r(u, o) = w_uᵀ φ(o), a share of every batch moved to
//!       counterfactual machine states (CRM);
//!    2. fresh rollouts of the stochastic policy, each observation with its learned state;
//!    3. feature expectations: the loss coefficients whose gradient is μ_π − μ_D per (u, o)
//!       ([`coefficients`]);
//!    4. reward step(s) on w (Adam, L2).
//! 4. **Final policy** (`final_sac_steps` > 0): the final phase every algorithm with a
//!    learned reward shares ([`super::final_policy`]), on δ_r held fixed.
//!
//! Steps 1–2 run once per task in `reacher prepare` (every SMIRL job of a run shares the
//! machine); `train` is one (variant, seed) job. Ground-truth evaluation, logging and progress
//! watch the loop from outside ([`JobWatch`]).

use super::config::IrlRunConfig;
use super::episodes::AgentBatch;
use super::evaluation::{JobWatch, UpdateFacts};
use super::expert_data::ExpertData;
use super::final_policy::{FinalPhase, FinalPolicy};
use super::irl_loop;
use super::iteration::{Coefficients, RewardTraceRow, StepError};
use crate::env::layout::{TaskLayout, OBS_JOINT_VEL};
use crate::env::product::ProductEnv;
use crate::env::reacher::{ConfigError, ReacherDelivery};
use crate::env::ContinuousEnv;
use crate::irl::reward::{RewardError, RewardModel, RewardOptimConfig};
use crate::irl::smirl::{maxent_coefficients, AnnotatedTrajectories, FeatureMap, LinearRmReward};
use crate::irl::Algo;
use crate::pipeline::reacher_expert::Demo;
use crate::rl::crm::{hot_index, CounterfactualRm, CrmError};
use crate::rl::replay::ReplayBatch;
use crate::rl::sac::{RewardFn, RewardFnError, SacTrainer};
use crate::rm::lrm::{learn_rm, Guards, LabelTrace, LrmConfig, LrmError};
use crate::rm::{LabelSet, RewardMachine, RmError, Transition, Vocabulary};

/// A machine for SMIRL that cannot be made (steps 1 and 2).
#[derive(Debug, thiserror::Error)]
pub enum MachineError {
    /// The run's environment config names no task layout.
    #[error(transparent)]
    TaskLayout(#[from] ConfigError),
    #[error("LRM: {0}")]
    Lrm(LrmError),
    #[error("the task's machine: {0}")]
    Task(RmError),
    #[error("the one-state machine: {0}")]
    OneState(RmError),
}

/// The task layout a run's environment config carries (`ReacherTask::env_config` sets it).
fn task_layout(config: &IrlRunConfig) -> Result<&TaskLayout, ConfigError> {
    config.env.task_layout().map(|l| &**l)
}

/// Step 1: the machine learned from the demonstrations' label traces by `algo`'s learner
/// ([`lrm_config`]), with its LRM cost and search time.
pub fn learn_machine(
    demos: &[Demo],
    config: &IrlRunConfig,
    seed: u64,
    algo: Algo,
) -> Result<(RewardMachine, f64, f64), MachineError> {
    let vocab = task_layout(config)?.vocabulary();
    let traces = label_traces(demos);
    let cfg = lrm_config(config, seed, algo)?;
    let learned = learn_rm(&vocab, &traces, &cfg).map_err(MachineError::Lrm)?;
    Ok((learned.rm, learned.cost, learned.stats.elapsed_secs))
}

/// The task's own machine as SMIRL reads it under `[smirl] machine = "task"`: the perfect
/// machine's states and guards with no goal or failure state and no rewards — what a learned
/// machine looks like — so that episodes run on past the goal as they do with LRM's machine
/// and only the machine's shape differs.
pub fn task_machine(perfect: &RewardMachine) -> Result<RewardMachine, MachineError> {
    let transitions = perfect
        .transitions()
        .iter()
        .map(|t| Transition {
            reward: 0.0,
            ..t.clone()
        })
        .collect();
    RewardMachine::new(
        perfect.vocab().clone(),
        perfect.n_states(),
        perfect.initial(),
        &[],
        &[],
        transitions,
    )
    .map_err(MachineError::Task)
}

/// The machine SMIRL reads under `[smirl] machine = "one_state"`: one state, no transitions, so
/// δ_r(u, o) = w_0ᵀ φ(o) and the agent's input carries no machine state; every other mechanism
/// runs as with LRM's machine (the control that tells what the machine adds).
pub fn one_state_machine(vocab: &Vocabulary) -> Result<RewardMachine, MachineError> {
    RewardMachine::new(vocab.clone(), 1, 0, &[], &[], Vec::new()).map_err(MachineError::OneState)
}

/// The learner of `algo` on a run (`seed`: the search's; size and budget from `config`; the
/// events are the task's, `TaskLayout::events`).
///
/// `smirl-paper`'s is LRM as the paper's eq. 1: the events predicted like any label set, no
/// cell written after the search, a label set unseen in a state read as a stay. `smirl`'s
/// adds the mechanisms of docs/method.md, each with what it assumes about the events:
/// unpredicted events and event stutter (`LrmConfig::predict_events`,
/// `LrmConfig::event_stutter`), commuted and initial events (`LrmConfig::commute_events`,
/// `LrmConfig::initial_events`) and tree guards (`Guards::Tree`).
pub fn lrm_config(config: &IrlRunConfig, seed: u64, algo: Algo) -> Result<LrmConfig, ConfigError> {
    let events = task_layout(config)?.events();
    let cfg = LrmConfig {
        max_states: config.lrm_max_states,
        tabu_len: config.lrm_tabu_len,
        max_steps: config.lrm_steps,
        seed,
        threads: config.threads,
        // Merging joins states by observed rewards; demos carry none (rewards are what IRL
        // learns), so merging would collapse the machine to one state.
        merge: false,
        fill_unobserved: false,
        reward_weight: 0.0,
        guards: Guards::Exact,
        events,
        // The product reads the machine on every step, and a label set holds for many.
        stutter_invariant: true,
        event_stutter: false,
        predict_events: true,
        commute_events: false,
        initial_events: false,
        // Starts, patience and split moves are the learner's defaults.
        ..LrmConfig::default()
    };
    Ok(if algo == Algo::SmirlPaper {
        cfg
    } else {
        with_event_rules(cfg)
    })
}

/// `cfg` with `smirl`'s ways of reading the declared events (docs/method.md): tree guards,
/// event stutter, unpredicted, commuted and initial events. `smirl-paper` learns without them.
pub fn with_event_rules(cfg: LrmConfig) -> LrmConfig {
    LrmConfig {
        guards: Guards::Tree,
        event_stutter: true,
        predict_events: false,
        commute_events: true,
        initial_events: true,
        ..cfg
    }
}

/// The demonstrations' label traces as LRM reads them (no rewards: those are what IRL learns).
pub fn label_traces(demos: &[Demo]) -> Vec<LabelTrace> {
    demos
        .iter()
        .map(|d| LabelTrace {
            labels: d.labels(),
            rewards: None,
        })
        .collect()
}

/// Step 2: the demonstrations as the IRL jobs read them, every observation annotated with the
/// learned machine's state before the step (the state its labels are read in); with no
/// machine, the plain observations the baselines read. With `hold_to` = Some(T), a
/// demonstration shorter than T is extended to T steps by holding its final state: the last
/// observation with zero joint velocities and no event, its labels recomputed by the
/// labelling rule, the learned machine stepped on them as on any other step. (The
/// demonstrator has finished the task; staying put is what it does in the goal, and MaxEnt
/// IRL and f-IRL compare expert and agent over one fixed horizon T.)
pub fn annotate(
    layout: &TaskLayout,
    demos: &[Demo],
    rm: Option<&RewardMachine>,
    hold_to: Option<usize>,
) -> ExpertData {
    let labelling = FeatureMap::reacher_labels(layout);
    let mut data = ExpertData {
        obs: Vec::new(),
        lengths: Vec::new(),
        learned_states: Vec::new(),
    };
    for d in demos {
        let mut u = rm.map(|m| m.initial());
        let mut push = |data: &mut ExpertData, obs: &[f32], labels: LabelSet| {
            data.obs.extend_from_slice(obs);
            if let (Some(m), Some(state)) = (rm, u) {
                data.learned_states.push(state as u32);
                u = Some(m.next_state(state, labels));
            }
        };
        for s in &d.steps {
            push(&mut data, &s.next_obs, s.labels);
        }
        let mut len = d.steps.len();
        if let (Some(horizon), Some(last)) = (hold_to, d.steps.last()) {
            let held = held_observation(layout, &last.next_obs);
            let labels = labelling.labels_of(&held);
            while len < horizon {
                push(&mut data, &held, labels);
                len += 1;
            }
        }
        data.lengths.push(len);
    }
    data
}

/// A demonstration's final observation as [`annotate`] holds it: joint velocities zero, no
/// event.
fn held_observation(layout: &TaskLayout, last: &[f32]) -> Vec<f32> {
    let mut held = last.to_vec();
    held[OBS_JOINT_VEL[0]] = 0.0;
    held[OBS_JOINT_VEL[1]] = 0.0;
    for e in 0..layout.n_events() {
        held[layout.event_column(e)] = 0.0;
    }
    held
}

/// Which features δ_r reads.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Features {
    /// Label bits (`smirl`, `smirl-paper`): of the state reached, L(o), as in the paper.
    Labels,
    /// exp(−d_k²/2σ²) per ball plus the cancel flag (`smirl-smooth`, a documented variant).
    Smooth,
}

impl Features {
    pub fn map(self, settings: &IrlRunConfig) -> Result<FeatureMap, RewardError> {
        let layout = task_layout(settings).map_err(|e| RewardError::Config(e.to_string()))?;
        match self {
            Features::Labels => Ok(FeatureMap::reacher_labels(layout)),
            Features::Smooth => FeatureMap::reacher_smooth(layout, settings.smooth_sigma),
        }
    }
}

/// Step 3.3: the rows, learned states and loss coefficients of one reward update — MaxEnt on
/// U × O, whose parameter gradient is μ_π − μ_D (the negated expert-minus-agent feature
/// expectation), each averaged over its trajectories ([`maxent_coefficients`]). Agent rows
/// first, then expert rows: the observations after each step.
pub fn coefficients(expert: &ExpertData, agent: &AgentBatch) -> Coefficients {
    let agent_t = AnnotatedTrajectories {
        obs: &agent.obs,
        rm_state: &agent.states,
        lengths: &agent.lengths,
    };
    let expert_t = AnnotatedTrajectories {
        obs: &expert.obs,
        rm_state: &expert.learned_states,
        lengths: &expert.lengths,
    };
    let (mut coeffs, expert_c) = maxent_coefficients(&expert_t, &agent_t);
    coeffs.extend(expert_c);
    Coefficients {
        obs: [agent.obs.as_slice(), &expert.obs].concat(),
        states: [agent.states.as_slice(), &expert.learned_states].concat(),
        coeffs,
    }
}

/// SAC's reward on U × O, computed when a batch is sampled so that old transitions follow the
/// reward being optimised now: δ_r(u_t, o_{t+1}) with u_t read from the stored observation's
/// one-hot block. With `counterfactual`, a share of each batch is first moved to other learned
/// states (CRM), so SAC learns every state's values from every step.
pub struct ProductReward<'a> {
    model: &'a mut LinearRmReward,
    counterfactual: Option<&'a CounterfactualRm>,
    next_obs: Vec<f32>,
    states: Vec<u32>,
}

impl<'a> ProductReward<'a> {
    /// The reward of `model` on SAC batches of the product (observation ⊕ one-hot learned
    /// state), relabelled by `counterfactual` when given.
    pub fn new(
        model: &'a mut LinearRmReward,
        counterfactual: Option<&'a CounterfactualRm>,
    ) -> ProductReward<'a> {
        ProductReward {
            model,
            counterfactual,
            next_obs: Vec::new(),
            states: Vec::new(),
        }
    }
}

impl RewardFn for ProductReward<'_> {
    fn relabel(&mut self, batch: &mut ReplayBatch, rng: &mut dyn rand::RngCore) {
        if let Some(crm) = self.counterfactual {
            crm.relabel(batch, rng);
        }
    }

    fn fill_rewards(&mut self, batch: &ReplayBatch, out: &mut [f32]) -> Result<(), RewardFnError> {
        let d = batch.obs.nrows();
        let width = self.model.features().obs_dim();
        // The one-hot block, the observation's last entries.
        let block = width..width + self.model.n_states();
        self.next_obs.clear();
        self.states.clear();
        let rows = batch.next_obs.as_slice().chunks_exact(d);
        for (next, prev) in rows.zip(batch.obs.as_slice().chunks_exact(d)) {
            self.next_obs.extend_from_slice(&next[..width]);
            self.states.push(hot_index(&prev[block.clone()]) as u32);
        }
        self.model.reward_batch(&self.next_obs, &self.states, out)?;
        Ok(())
    }
}

impl super::final_policy::ScoredReward for ProductReward<'_> {
    fn score(&mut self, steps: &AgentBatch) -> Result<Vec<f32>, StepError> {
        let mut r = vec![0.0f32; steps.n_states()];
        (self.model).reward_batch(&steps.obs, &steps.states, &mut r)?;
        Ok(r)
    }
}

/// The environment SMIRL's agent learns in: ReacherDelivery × the learned machine.
pub(super) fn product_env(
    inner: ReacherDelivery,
    machine: &RewardMachine,
) -> ProductEnv<ReacherDelivery> {
    ProductEnv::new(inner, machine.clone())
}

/// SMIRL's counterfactual relabelling of SAC batches ([`IrlRunConfig::counterfactual`] > 0), for the
/// observations of `env`.
pub(super) fn counterfactual_states(
    env: &ProductEnv<ReacherDelivery>,
    s: &IrlRunConfig,
) -> Result<Option<CounterfactualRm>, CrmError> {
    (s.counterfactual() > 0.0)
        .then(|| CounterfactualRm::new(env.rm().clone(), env.inner().obs_dim(), s.counterfactual()))
        .transpose()
}

/// One SMIRL job.
pub struct SmirlJob<'a> {
    pub features: Features,
    pub seed: u64,
    pub settings: &'a IrlRunConfig,
    /// The machine of step 1.
    pub machine: &'a RewardMachine,
    /// The demonstrations of step 2.
    pub expert: &'a ExpertData,
}

/// What a SMIRL job returns: the learned reward, its trace (per iteration, the data gradient
/// μ_π − μ_D before the update and the weights after it) and the final-policy phase, if any.
pub struct SmirlOutcome {
    pub reward: LinearRmReward,
    pub trace: Vec<RewardTraceRow>,
    pub final_policy: Option<FinalPolicy>,
}

/// Step 3: MaxEnt IRL on U × O with SAC as the inner solver (the loop of [`super::irl_loop`]
/// with SMIRL's reward, `SmirlReward`), then (`final_sac_steps` > 0) the final policy on the
/// final reward ([`super::final_policy`]).
pub fn train(job: &SmirlJob<'_>, watch: &mut JobWatch<'_, '_>) -> Result<SmirlOutcome, StepError> {
    let s = job.settings;
    let n_states = job.machine.n_states();
    let inner = ReacherDelivery::new(s.env.clone())?;
    let mut env = product_env(inner, job.machine);
    let features = job.features.map(s)?;
    let optim = RewardOptimConfig {
        adam: true,
        lr: s.smirl_reward_lr,
        l2: s.smirl_reward_l2,
    };
    let mut learner = SmirlReward {
        reward: LinearRmReward::new(features, n_states, optim)?,
        counterfactual: counterfactual_states(&env, s)?,
        job,
        trace: Vec::with_capacity(s.irl_iterations),
    };
    let mut sac = SacTrainer::new(&s.sac, env.obs_dim(), env.act_dim(), job.seed)?;
    // Step 4, the final policy, after the loop's last iteration: SAC goes on with the final
    // reward, now fixed, and the candidate of highest learned return is the job's policy.
    let final_phase = FinalPhase::of(s, job.seed);
    let final_policy = irl_loop::run(
        &mut learner,
        &mut sac,
        &mut env,
        s,
        job.seed,
        final_phase,
        watch,
    )?;
    Ok(SmirlOutcome {
        reward: learner.reward,
        trace: learner.trace,
        final_policy,
    })
}

/// SMIRL's reward in the IRL loop: δ_r(u, o) = w_uᵀ φ(o) and its MaxEnt update on U × O.
struct SmirlReward<'j> {
    reward: LinearRmReward,
    /// CRM's counterfactual machine states, moved into a share of every SAC batch.
    counterfactual: Option<CounterfactualRm>,
    job: &'j SmirlJob<'j>,
    trace: Vec<RewardTraceRow>,
}

impl irl_loop::RewardLearner for SmirlReward<'_> {
    type SacReward<'a>
        = ProductReward<'a>
    where
        Self: 'a;

    /// SAC on the product with the current δ_r, counterfactual states in every batch.
    fn sac_reward(&mut self) -> Result<ProductReward<'_>, StepError> {
        Ok(ProductReward::new(
            &mut self.reward,
            self.counterfactual.as_ref(),
        ))
    }

    fn update(&mut self, iteration: usize, batch: AgentBatch) -> Result<UpdateFacts, StepError> {
        let s = self.job.settings;
        let reward = &mut self.reward;
        // Feature expectations: coefficients of μ_π − μ_D per (u, o).
        let c = coefficients(self.job.expert, &batch);

        // Reward steps; the first step's gradient (before any step) is the traced data
        // gradient.
        let mut r = vec![0.0f32; c.coeffs.len()];
        reward.reward_batch(&c.obs, &c.states, &mut r)?;
        let facts = UpdateFacts::of(&r, &c.coeffs, batch.n_states());
        reward.set_lr(s.smirl_reward_lr);
        reward
            .backward(&c.obs, &c.states, &c.coeffs)
            .map_err(StepError::RewardUpdate)?;
        let data_gradient = reward.grad();
        reward.step();
        for _ in 1..s.reward_steps_per_iteration {
            reward
                .update(&c.obs, &c.states, &c.coeffs)
                .map_err(StepError::RewardUpdate)?;
        }
        self.trace.push(RewardTraceRow {
            iteration,
            data_gradient,
            weights: reward.params(),
        });
        Ok(facts)
    }
}
