//! The IRL training loop shared by every algorithm (one (algorithm, seed) job), as chained in
//! `irl/mod.rs`: per iteration, continue the same SAC agent on the current learned reward,
//! roll out fresh trajectories, compute the algorithm's per-state loss coefficients, update
//! the reward model, evaluate on the ground-truth task. Only [`irl_coefficients`] and the
//! choice of environment/reward model differ between algorithms.

use super::config::IrlRunConfig;
use super::Algo;
use crate::env::product::ProductEnv;
use crate::env::reacher::{ReacherConfig, ReacherDelivery, OBS_DIM, OBS_TIP};
use crate::env::reacher_task::{Branch, BranchTally, CancelBranch, TaskProgress};
use crate::env::{ContinuousEnv, EnvError, EnvStep};
use crate::irl::discriminator::{Discriminator, DiscriminatorConfig};
use crate::irl::firl::{DensityRatio, FirlSurrogate, MaxEntCoefficients, DEFAULT_DENSITY_EPS};
use crate::irl::kde::Kde;
use crate::irl::reward::{MlpReward, MlpRewardConfig, RewardError, RewardModel, RewardOptimConfig};
use crate::irl::smirl::{
    maxent_coefficients, maxent_coefficients_by_visits, AnnotatedTrajectories, FeatureMap,
    LearnedSubgoalPotential, LinearRmReward, SmirlNormalisation,
};
use crate::log::RolloutLogger;
use crate::nn::codec::{ByteReader, ByteWriter, CodecError};
use crate::pipeline::training_log::{ReacherView, TrainingLog};
use crate::rl::crm::{hot_index, CounterfactualRm};
use crate::rl::replay::ReplayBatch;
use crate::rl::sac::{episode_seed, ActMode, RewardFn, SacAgent, SacTrainer, TrainingObserver};
use crate::rm::RewardMachine;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use std::path::Path;
use std::time::Instant;

/// What every job of a task shares: the demonstrations as the IRL algorithms see them.
#[derive(Clone, Debug)]
pub struct ExpertData {
    /// Observations o_1..o_T of every demonstration step (row-major, `OBS_DIM` wide): the
    /// states visited, as the agent's rollouts record them.
    pub obs: Vec<f32>,
    /// Demonstration lengths, in order.
    pub lengths: Vec<usize>,
    /// The learned machine's state each observation's labels are read in (u_{t−1}); empty
    /// when no machine was learned.
    pub learned_states: Vec<u32>,
}

impl ExpertData {
    pub fn n_states(&self) -> usize {
        self.lengths.iter().sum()
    }

    fn annotated(&self) -> AnnotatedTrajectories<'_> {
        AnnotatedTrajectories {
            obs: &self.obs,
            rm_state: &self.learned_states,
            lengths: &self.lengths,
        }
    }

    /// The binary file `reacher prepare` writes for the jobs (`expert_data.bin`): exact
    /// values, so a job that reads it computes what the one-process run computes.
    pub fn to_bytes(&self) -> Vec<u8> {
        let mut w = ByteWriter::new();
        w.raw(EXPERT_DATA_MAGIC);
        w.u32(EXPERT_DATA_VERSION);
        w.f32s(&self.obs);
        w.usize(self.lengths.len());
        for &len in &self.lengths {
            w.usize(len);
        }
        w.u32s(&self.learned_states);
        w.bytes
    }

    /// Reads [`ExpertData::to_bytes`]; every count is checked against the bytes present and
    /// the arrays against each other.
    pub fn from_bytes(bytes: &[u8]) -> Result<ExpertData, CodecError> {
        let mut r = ByteReader::new(bytes);
        r.header(EXPERT_DATA_MAGIC, "smirl expert data", EXPERT_DATA_VERSION)?;
        let obs = r.f32s("observations")?;
        let n = r.usize("demonstration count")?;
        if n > bytes.len() / 8 {
            return Err(CodecError::Invalid {
                what: "demonstration count",
                problem: format!("{n} is more than the file can hold"),
            });
        }
        let lengths = (0..n)
            .map(|_| r.usize("demonstration length"))
            .collect::<Result<Vec<_>, _>>()?;
        let learned_states = r.u32s("learned machine states")?;
        r.finish()?;
        let steps = lengths
            .iter()
            .try_fold(0usize, |a, &l| a.checked_add(l))
            .filter(|&t| t.checked_mul(OBS_DIM) == Some(obs.len()))
            .ok_or_else(|| CodecError::Invalid {
                what: "observations",
                problem: format!(
                    "{} values do not fill the demonstrations' {n} lengths × {OBS_DIM}",
                    obs.len()
                ),
            })?;
        if !learned_states.is_empty() && learned_states.len() != steps {
            return Err(CodecError::Invalid {
                what: "learned machine states",
                problem: format!("{} states for {steps} steps", learned_states.len()),
            });
        }
        Ok(ExpertData {
            obs,
            lengths,
            learned_states,
        })
    }
}

const EXPERT_DATA_MAGIC: &[u8] = b"SMIRLXD\0";
const EXPERT_DATA_VERSION: u32 = 1;

/// One row of the metrics table: the ground-truth evaluation after `iteration` IRL
/// iterations (0 = the untrained policy).
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct MetricsRow {
    pub iteration: usize,
    pub env_steps: u64,
    /// Fraction of evaluation episodes in which the task's perfect machine reached its goal;
    /// for a conditional task (IF, Composite) the lower of the two branches' rates.
    pub success_rate: f64,
    /// Conditional tasks: evaluation episodes and successes per branch.
    pub branches: Option<BranchTally>,
    /// Mean sum of the perfect machine's rewards.
    pub task_return: f64,
    /// Mean sum of the environment's own (distance) rewards.
    pub env_return: f64,
    /// Mean learned reward per step of the agent's rollouts this iteration.
    pub learned_reward: f64,
    /// The algorithm's surrogate loss Σ c_i r(o_i) before this iteration's update.
    pub surrogate_loss: f64,
    /// Mean fraction of the task's sub-goals completed along the perfect machine
    /// (`env::reacher_task::TaskProgress`); `None` in jobs run before the metric existed.
    #[serde(default)]
    pub progress: Option<f64>,
    /// Fraction of evaluation episodes that touched a ball which can end the task (the
    /// paper's "end location"); `None` in jobs run before the metric existed.
    #[serde(default)]
    pub final_ball: Option<f64>,
    /// Fraction of this iteration's agent fingertip states inside the support of the expert's
    /// Epanechnikov KDE (within `kde_bandwidth` of some demonstration state): where f-IRL's
    /// density ratio can be anything but 0. `None` before the first rollouts and in jobs run
    /// before the measurement existed.
    #[serde(default)]
    pub expert_support: Option<f64>,
}

/// What a finished job hands back.
#[derive(Clone, Debug)]
pub struct JobResult {
    pub algo: Algo,
    pub seed: u64,
    pub rows: Vec<MetricsRow>,
    /// SMIRL: the learned weights (`n_states × n_features` row-major) and the data gradient
    /// μ_π − μ_D of each iteration's reward update, one entry per IRL iteration; empty for the
    /// MLP rewards (too many parameters to trace).
    pub reward_trace: Vec<RewardTraceRow>,
    pub wall_secs: f64,
}

/// One iteration of a SMIRL job's reward trace: how the weights moved and why.
#[derive(Clone, Debug, PartialEq)]
pub struct RewardTraceRow {
    pub iteration: usize,
    /// The loss gradient without L2 (μ_π − μ_D under the configured normalisation) before
    /// this iteration's update.
    pub data_gradient: Vec<f32>,
    /// The weights after this iteration's update.
    pub weights: Vec<f32>,
}

/// Progress of a job, for progress bars.
#[derive(Clone, Copy, Debug)]
pub struct JobProgress {
    pub iteration: usize,
    pub iterations: usize,
    pub env_steps: u64,
    pub total_env_steps: u64,
    /// Success rate of the last evaluation.
    pub success_rate: f64,
}

/// A job that failed.
#[derive(Debug, thiserror::Error)]
pub enum JobError {
    #[error("{algo} seed {seed}: {problem}")]
    Run {
        algo: Algo,
        seed: u64,
        problem: String,
    },
}

/// The environment SAC acts in: the plain ReacherDelivery (baselines) or its product with
/// the learned machine (SMIRL).
pub enum JobEnv {
    Plain(Box<ReacherDelivery>),
    Product(Box<ProductEnv<ReacherDelivery>>),
}

impl JobEnv {
    pub fn new(config: &ReacherConfig, learned: Option<&RewardMachine>) -> Result<JobEnv, String> {
        let inner = ReacherDelivery::new(config.clone()).map_err(|e| e.to_string())?;
        Ok(match learned {
            None => JobEnv::Plain(Box::new(inner)),
            Some(rm) => JobEnv::Product(Box::new(ProductEnv::new(inner, rm.clone()))),
        })
    }

    pub fn reacher(&self) -> &ReacherDelivery {
        match self {
            JobEnv::Plain(e) => e,
            JobEnv::Product(p) => p.inner(),
        }
    }

    /// The learned machine's current state (SMIRL).
    pub fn learned_state(&self) -> Option<usize> {
        match self {
            JobEnv::Plain(_) => None,
            JobEnv::Product(p) => Some(p.rm_state()),
        }
    }

    /// One step; also returns the environment's own reward (the product's step reward is
    /// the learned machine's).
    fn step_full(&mut self, action: &[f32], obs: &mut [f32]) -> Result<(EnvStep, f64), EnvError> {
        match self {
            JobEnv::Plain(e) => e.step(action, obs).map(|s| (s, s.reward)),
            JobEnv::Product(p) => p.step_product(action, obs).map(|s| (s.step, s.env_reward)),
        }
    }
}

impl ContinuousEnv for JobEnv {
    fn obs_dim(&self) -> usize {
        match self {
            JobEnv::Plain(e) => e.obs_dim(),
            JobEnv::Product(p) => p.obs_dim(),
        }
    }
    fn act_dim(&self) -> usize {
        match self {
            JobEnv::Plain(e) => e.act_dim(),
            JobEnv::Product(p) => p.act_dim(),
        }
    }
    fn reset(&mut self, seed: u64, obs: &mut [f32]) {
        match self {
            JobEnv::Plain(e) => e.reset(seed, obs),
            JobEnv::Product(p) => p.reset(seed, obs),
        }
    }
    fn step(&mut self, action: &[f32], obs: &mut [f32]) -> Result<EnvStep, EnvError> {
        self.step_full(action, obs).map(|(s, _)| s)
    }
}

impl ReacherView for JobEnv {
    fn reacher(&self) -> &ReacherDelivery {
        JobEnv::reacher(self)
    }
    fn inner_step(&self, seen: &EnvStep) -> EnvStep {
        match self {
            JobEnv::Plain(e) => e.inner_step(seen),
            JobEnv::Product(p) => p.inner_step(seen),
        }
    }
}

/// Sample-time rewards for SAC: the learned reward of each replayed transition,
/// r(o_{t+1}) for the baselines, δ_r(u_t, o_{t+1}) for SMIRL with u_t read from the stored
/// observation's one-hot part — so old transitions follow the reward being optimised now.
/// With `shaping` (SMIRL), SAC's reward is δ_r(u_t, o_{t+1}) + γ Φ(u_{t+1}, o_{t+1}) −
/// Φ(u_t, o_t) (see [`LearnedSubgoalPotential`]), Φ = 0 after a terminating step.
/// With `counterfactual` (SMIRL), a share of each batch is first moved to other learned-machine
/// states (CRM, [`CounterfactualRm`]), so SAC learns every state's values from every step.
struct LearnedReward<'a> {
    model: &'a mut dyn RewardModel,
    product: bool,
    shaping: Option<(&'a LearnedSubgoalPotential, f64)>,
    /// SMIRL: counterfactual learned-machine states for a share of each batch.
    counterfactual: Option<&'a CounterfactualRm>,
    obs: Vec<f32>,
    states: Vec<u32>,
    error: Option<RewardError>,
}

impl RewardFn for LearnedReward<'_> {
    fn relabel(&mut self, batch: &mut ReplayBatch, rng: &mut dyn rand::RngCore) {
        if let Some(crm) = self.counterfactual {
            crm.relabel(batch, rng);
        }
    }

    fn fill_rewards(&mut self, batch: &ReplayBatch, out: &mut [f32]) {
        let d = batch.obs.nrows();
        self.obs.clear();
        self.states.clear();
        for (next, prev) in batch
            .next_obs
            .as_slice()
            .chunks_exact(d)
            .zip(batch.obs.as_slice().chunks_exact(d))
        {
            self.obs.extend_from_slice(&next[..OBS_DIM]);
            if self.product {
                self.states.push(hot_index(&prev[OBS_DIM..]) as u32);
            }
        }
        if let Err(e) = self.model.reward_batch(&self.obs, &self.states, out) {
            out.fill(0.0);
            self.error.get_or_insert(e);
            return;
        }
        if let Some((potential, gamma)) = self.shaping {
            let rows = batch.next_obs.as_slice().chunks_exact(d);
            let prev_rows = batch.obs.as_slice().chunks_exact(d);
            for (((next, prev), &terminated), r) in rows
                .zip(prev_rows)
                .zip(&batch.terminated)
                .zip(out.iter_mut())
            {
                let u = hot_index(&prev[OBS_DIM..]);
                let u_next = hot_index(&next[OBS_DIM..]);
                let after = if terminated > 0.5 {
                    0.0
                } else {
                    gamma * potential.potential(next, u_next)
                };
                *r += (after - potential.potential(prev, u)) as f32;
            }
        }
    }
}

/// Agent trajectories as the reward update reads them.
#[derive(Clone, Debug, Default)]
pub struct AgentBatch {
    /// o_1..o_T of every trajectory, row-major, `OBS_DIM` wide.
    pub obs: Vec<f32>,
    /// The learned machine's state paired with each observation (SMIRL; else empty).
    pub states: Vec<u32>,
    pub lengths: Vec<usize>,
}

/// The batch of one reward update: rows, their RM states (SMIRL) and loss coefficients.
#[derive(Clone, Debug, PartialEq)]
pub struct Coefficients {
    /// Row-major observations, `OBS_DIM` wide.
    pub obs: Vec<f32>,
    /// RM state of each row (empty for the baselines).
    pub states: Vec<u32>,
    pub coeffs: Vec<f64>,
}

/// The rows, RM states and loss coefficients of one reward update (see `irl/mod.rs`):
/// f-IRL's covariance surrogate (density ratio of fingertip positions from the two KDEs, or
/// from `discriminator` when given, which first trains on this batch), continuous MaxEnt's
/// T·(mean agent reward − mean expert reward), or SMIRL's MaxEnt on U × O, whose parameter
/// gradient is μ_π − μ_D (the negated expert-minus-agent feature expectation), normalised per
/// trajectory or per trajectory visiting each RM state (`smirl_normalisation`).
pub fn irl_coefficients(
    algo: Algo,
    expert: &ExpertData,
    expert_kde: Option<&Kde>,
    agent: &AgentBatch,
    kde_bandwidth: f64,
    smirl_normalisation: SmirlNormalisation,
    discriminator: Option<&mut Discriminator>,
) -> Result<Coefficients, String> {
    let n_agent = agent.lengths.iter().sum::<usize>();
    if agent.lengths.is_empty() || n_agent == 0 {
        return Err("no agent trajectories".into());
    }
    let horizon = agent.lengths[0];
    let concat = |a: &[f32], b: &[f32]| [a, b].concat();
    match algo {
        Algo::Fkl | Algo::Rkl | Algo::Js => {
            if agent.lengths.iter().any(|&l| l != horizon) {
                return Err("f-IRL needs agent trajectories of one fixed length".into());
            }
            let div = algo.divergence().expect("f-IRL algorithm");
            let n_traj = agent.lengths.len();
            let s = match discriminator {
                Some(d) => {
                    d.train(&expert.obs, &agent.obs, OBS_DIM)
                        .map_err(|e| format!("discriminator: {e}"))?;
                    let ratios: Vec<f64> = d
                        .log_ratio(&agent.obs, OBS_DIM)
                        .map_err(|e| format!("discriminator: {e}"))?
                        .into_iter()
                        .map(f64::exp)
                        .collect();
                    FirlSurrogate::new(div, &ratios, n_traj, horizon)
                }
                None => {
                    let kde_e = expert_kde.ok_or("f-IRL needs the expert KDE")?;
                    let kde_a = Kde::fit_columns(&agent.obs, OBS_DIM, &OBS_TIP, kde_bandwidth)
                        .map_err(|e| e.to_string())?;
                    FirlSurrogate::from_kde(
                        div,
                        kde_e,
                        &kde_a,
                        &agent.obs,
                        OBS_DIM,
                        &OBS_TIP,
                        n_traj,
                        horizon,
                        DEFAULT_DENSITY_EPS,
                    )
                }
            }
            .map_err(|e| e.to_string())?;
            Ok(Coefficients {
                obs: agent.obs.clone(),
                states: Vec::new(),
                coeffs: s.coefficients,
            })
        }
        Algo::MaxEnt => {
            let n_expert = expert.n_states();
            let c =
                MaxEntCoefficients::new(n_agent, n_expert, horizon).map_err(|e| e.to_string())?;
            let mut coeffs = vec![c.agent; n_agent];
            coeffs.extend(std::iter::repeat(c.expert).take(n_expert));
            Ok(Coefficients {
                obs: concat(&agent.obs, &expert.obs),
                states: Vec::new(),
                coeffs,
            })
        }
        Algo::Smirl | Algo::SmirlSmooth => {
            let agent_t = AnnotatedTrajectories {
                obs: &agent.obs,
                rm_state: &agent.states,
                lengths: &agent.lengths,
            };
            let (mut coeffs, expert_c) = match smirl_normalisation {
                SmirlNormalisation::Trajectories => {
                    maxent_coefficients(&expert.annotated(), &agent_t)
                }
                SmirlNormalisation::Visits => {
                    maxent_coefficients_by_visits(&expert.annotated(), &agent_t)
                }
            };
            coeffs.extend(expert_c);
            let states = [agent.states.as_slice(), &expert.learned_states].concat();
            Ok(Coefficients {
                obs: concat(&agent.obs, &expert.obs),
                states,
                coeffs,
            })
        }
    }
}

/// The reward learning rate of IRL iteration `iteration` (1-based): the algorithm's base rate
/// times iteration^(−`reward_lr_decay`). Why a schedule: the reward update is a stochastic
/// gradient step on sampled agent trajectories, and Adam takes steps of about lr whatever the
/// size of the mismatch, so with a constant rate the reward keeps moving by sampling noise after
/// the feature expectations match; a decaying rate lets it settle.
pub fn reward_lr(algo: Algo, settings: &IrlRunConfig, iteration: usize) -> f32 {
    let base = if algo.uses_rm() {
        settings.smirl_reward_lr
    } else {
        settings.mlp_reward_lr
    };
    base * (iteration.max(1) as f32).powf(-(settings.reward_lr_decay as f32))
}

/// SMIRL's feature map φ (`None` for the baselines).
pub fn smirl_features(
    algo: Algo,
    settings: &IrlRunConfig,
) -> Result<Option<FeatureMap>, RewardError> {
    Ok(match algo {
        Algo::Smirl => Some(FeatureMap::reacher_labels()),
        Algo::SmirlSmooth => Some(FeatureMap::reacher_smooth(settings.smooth_sigma)?),
        Algo::MaxEnt | Algo::Fkl | Algo::Rkl | Algo::Js => None,
    })
}

/// The reward model of `algo`: the (64, 64) MLP on the fingertip position clamped to ±10
/// (baselines), or δ_r(u, o) = w_uᵀ φ(o) with label or smooth features (SMIRL).
pub fn reward_model(
    algo: Algo,
    settings: &IrlRunConfig,
    learned_states: usize,
    seed: u64,
) -> Result<Box<dyn RewardModel + Send>, RewardError> {
    let smirl_optim = RewardOptimConfig {
        adam: true,
        lr: settings.smirl_reward_lr,
        l2: settings.smirl_reward_l2,
    };
    Ok(match smirl_features(algo, settings)? {
        Some(features) => Box::new(LinearRmReward::new(features, learned_states, smirl_optim)?),
        None => {
            let mut cfg = MlpRewardConfig::paper(OBS_TIP.to_vec(), settings.mlp_reward_lr, seed);
            cfg.optim.l2 = settings.mlp_reward_l2;
            Box::new(MlpReward::new(cfg, OBS_DIM)?)
        }
    })
}

/// The saved reward of a baseline job (`rewards/<algo>_seed<k>.bin` of maxent, fkl, rkl, js:
/// the (64, 64) MLP on the fingertip, clamped to ±10) at fingertip positions (x, y).
pub fn baseline_reward_at(path: &Path, points: &[[f64; 2]]) -> Result<Vec<f32>, RewardError> {
    let mut model = MlpReward::new(MlpRewardConfig::paper(OBS_TIP.to_vec(), 1e-3, 0), OBS_DIM)?;
    model.load(path)?;
    let mut obs = vec![0.0f32; points.len() * OBS_DIM];
    for (row, p) in obs.chunks_exact_mut(OBS_DIM).zip(points) {
        row[OBS_TIP[0]] = p[0] as f32;
        row[OBS_TIP[1]] = p[1] as f32;
    }
    let mut r = vec![0.0f32; points.len()];
    model.reward_batch(&obs, &[], &mut r)?;
    Ok(r)
}

/// Ground-truth outcome of one episode.
#[derive(Clone, Copy, Debug, Default)]
struct EpisodeOutcome {
    success: bool,
    /// Fraction of the sub-goals completed (see `TaskProgress`).
    progress: f64,
    /// A ball that can end the task was touched.
    final_ball: bool,
    /// The branch taken, for a conditional task.
    branch: Option<Branch>,
    task_return: f64,
    env_return: f64,
}

/// Plays one episode. The perfect machine is tracked on the labels for the ground truth;
/// `stop_when_decided` ends the episode once it reaches its goal or failure sink (evaluation).
/// `on_step(inner o_{t+1}, learned u_t)` sees every step. With `branches`, the outcome says
/// which branch of the conditional task the perfect machine's trace took.
#[allow(clippy::too_many_arguments)]
fn play_episode(
    agent: &mut SacAgent,
    env: &mut JobEnv,
    perfect: &RewardMachine,
    task_progress: &TaskProgress,
    branches: Option<&CancelBranch>,
    mode: ActMode,
    reset_seed: u64,
    stop_when_decided: bool,
    rng: &mut ChaCha8Rng,
    mut logger: Option<(&mut RolloutLogger, &str)>,
    mut on_step: impl FnMut(&[f32], Option<usize>),
) -> Result<EpisodeOutcome, String> {
    let mut obs = vec![0.0f32; env.obs_dim()];
    let mut next = vec![0.0f32; env.obs_dim()];
    let mut action = vec![0.0f32; env.act_dim()];
    env.reset(reset_seed, &mut obs);
    let mut up = perfect.initial();
    let mut out = EpisodeOutcome::default();
    let mut tracker = task_progress.start(up);
    let mut cancelled = branches.is_some_and(|b| b.is_cancelled(up));
    if let Some((l, phase)) = logger.as_mut() {
        l.begin_reacher_episode(env.reacher(), reset_seed, phase, Some(up), &obs[..OBS_DIM])
            .map_err(|e| e.to_string())?;
    }
    let max_steps = env.reacher().config().max_steps;
    for _ in 0..max_steps {
        agent.act(&obs, mode, rng, &mut action);
        let u_before = env.learned_state();
        let (step, env_reward) = env
            .step_full(&action, &mut next)
            .map_err(|e| e.to_string())?;
        let (u_next, r) = perfect.step(up, step.labels);
        task_progress.track(&mut tracker, up, u_next, step.labels);
        up = u_next;
        cancelled |= branches.is_some_and(|b| b.is_cancelled(up));
        out.task_return += r;
        out.env_return += env_reward;
        out.success |= perfect.is_terminal(up) && !perfect.is_failure(up);
        if let Some((l, _)) = logger.as_mut() {
            let inner = env.inner_step(&step);
            l.reacher_step(
                env.reacher(),
                &action,
                &inner,
                Some((up, r)),
                &next[..OBS_DIM],
            )
            .map_err(|e| e.to_string())?;
        }
        on_step(&next[..OBS_DIM], u_before);
        std::mem::swap(&mut obs, &mut next);
        let decided = perfect.is_terminal(up) || perfect.is_failure(up);
        if step.terminated || step.truncated || (stop_when_decided && decided) {
            break;
        }
    }
    if let Some((l, _)) = logger.as_mut() {
        l.end_episode(out.success).map_err(|e| e.to_string())?;
    }
    out.progress = tracker.fraction();
    out.final_ball = tracker.touched_final_ball();
    out.branch = branches.map(|_| {
        if cancelled {
            Branch::Cancelled
        } else {
            Branch::Normal
        }
    });
    Ok(out)
}

/// One ground-truth evaluation.
struct Evaluation {
    success_rate: f64,
    progress: f64,
    final_ball: f64,
    branches: Option<BranchTally>,
    task_return: f64,
    env_return: f64,
}

/// Reset seeds of a conditional task's evaluation: the first `per_branch` seeds of the
/// `eval_seed` stream whose reset schedules a cancel event and the first `per_branch` that
/// schedule none, in stream order. (The branch an episode takes is read from its trace
/// afterwards; with the default window (steps 1–8), which ends before the committed experts
/// touch blue, a scheduled cancel almost always means the cancel branch.) A schedule that never (or always) cancels fills up with
/// the next seeds of the stream, so there are always `2 · per_branch` seeds.
pub fn stratified_eval_seeds(
    env: &mut ReacherDelivery,
    eval_seed: u64,
    per_branch: u64,
) -> Vec<u64> {
    let mut obs = vec![0.0f32; OBS_DIM];
    let target = 2 * per_branch as usize;
    let mut counts = [0u64; 2];
    let mut chosen = Vec::with_capacity(target);
    let scan = 64 * per_branch;
    for i in 0..scan {
        let seed = episode_seed(eval_seed, i);
        env.reset(seed, &mut obs);
        let k = usize::from(env.cancel_step().is_some());
        if counts[k] < per_branch {
            counts[k] += 1;
            chosen.push((i, seed));
        }
        if chosen.len() == target {
            break;
        }
    }
    let mut i = scan;
    while chosen.len() < target {
        chosen.push((i, episode_seed(eval_seed, i)));
        i += 1;
    }
    chosen.sort_unstable();
    chosen.into_iter().map(|(_, seed)| seed).collect()
}

/// Everything one job reads.
pub struct JobInputs<'a> {
    pub algo: Algo,
    pub seed: u64,
    pub settings: &'a IrlRunConfig,
    pub perfect_rm: &'a RewardMachine,
    /// The learned machine (required for SMIRL, ignored by the baselines).
    pub learned_rm: Option<&'a RewardMachine>,
    pub expert: &'a ExpertData,
    /// Where the learned reward's parameters are saved at the end (`None`: not saved).
    pub reward_path: Option<&'a Path>,
}

/// Runs one (algorithm, seed) job: a pure function of its inputs (own seeded RNGs), so the
/// result does not depend on which thread runs it or when.
pub fn run_job(
    inputs: &JobInputs<'_>,
    mut logger: Option<&mut RolloutLogger>,
    progress: &(dyn Fn(JobProgress) + Sync),
) -> Result<JobResult, JobError> {
    let started = Instant::now();
    let JobInputs {
        algo,
        seed,
        settings: s,
        perfect_rm,
        expert,
        ..
    } = *inputs;
    let fail = |problem: String| JobError::Run {
        algo,
        seed,
        problem,
    };
    let learned = if algo.uses_rm() {
        Some(
            inputs
                .learned_rm
                .ok_or_else(|| fail("SMIRL needs a learned reward machine".into()))?,
        )
    } else {
        None
    };
    let n_learned = learned.map_or(0, |rm| rm.n_states());
    let mut env = JobEnv::new(&s.env, learned).map_err(fail)?;
    let mut model =
        reward_model(algo, s, n_learned.max(1), seed).map_err(|e| fail(e.to_string()))?;
    // SMIRL's feature map when its SAC is shaped (`smirl_shaping` > 0), else `None`.
    let shaping_features = match learned {
        Some(_) if s.smirl_shaping > 0.0 => {
            smirl_features(algo, s).map_err(|e| fail(e.to_string()))?
        }
        _ => None,
    };
    // SMIRL's counterfactual relabelling of SAC batches (`smirl_counterfactual` > 0).
    let counterfactual = match learned {
        Some(rm) if s.smirl_counterfactual > 0.0 => Some(
            CounterfactualRm::new(rm.clone(), OBS_DIM, s.smirl_counterfactual)
                .map_err(|e| fail(e.to_string()))?,
        ),
        _ => None,
    };
    // The expert's fingertip density: f-IRL's ρ_E, and for every algorithm the measure of
    // how much of the agent's sample it covers (`expert_support`).
    let expert_kde = Kde::fit_columns(&expert.obs, OBS_DIM, &OBS_TIP, s.kde_bandwidth)
        .map_err(|e| fail(format!("expert KDE: {e}")))?;
    // f-IRL's density ratio from a classifier instead (`firl_density_ratio`), kept across
    // iterations, on its own random stream.
    let mut discriminator = match (algo.divergence(), s.firl_density_ratio) {
        (Some(_), DensityRatio::Discriminator) => Some(
            Discriminator::new(
                DiscriminatorConfig::firl(),
                &OBS_TIP,
                episode_seed(seed, 0xd15c),
            )
            .map_err(|e| fail(e.to_string()))?,
        ),
        _ => None,
    };
    let mut trainer = SacTrainer::new(&s.sac, env.obs_dim(), env.act_dim(), seed)
        .map_err(|e| fail(e.to_string()))?;
    // Separate streams: rollouts and evaluation never perturb SAC's own RNG.
    let mut rollout_rng = ChaCha8Rng::seed_from_u64(episode_seed(seed, 0x0a11_0a11));
    let eval_seed = episode_seed(seed, 0xe7a1);
    // Conditional tasks: evaluation episodes stratified by the cancel schedule, so that each
    // branch gets about `eval_episodes` of them.
    let branches = CancelBranch::of(perfect_rm);
    let task_progress = TaskProgress::of(perfect_rm);
    let eval_seeds = match branches {
        Some(_) => {
            let mut schedule =
                ReacherDelivery::new(s.env.clone()).map_err(|e| fail(e.to_string()))?;
            stratified_eval_seeds(&mut schedule, eval_seed, s.eval_episodes)
        }
        None => (0..s.eval_episodes)
            .map(|i| episode_seed(eval_seed, i))
            .collect(),
    };
    let total_env_steps = s.sac_steps_per_iteration * s.irl_iterations as u64;
    let mut rows = Vec::with_capacity(s.irl_iterations + 1);
    let mut rollout_index = 0u64;
    let mut reward_trace = Vec::new();

    let evaluate = |agent: &mut SacAgent,
                    env: &mut JobEnv,
                    logger: Option<&mut RolloutLogger>|
     -> Result<Evaluation, String> {
        let mut rng = ChaCha8Rng::seed_from_u64(eval_seed);
        let mut logger = logger;
        let (mut succ, mut ret, mut env_ret) = (0.0, 0.0, 0.0);
        let (mut progress, mut final_ball) = (0.0, 0.0);
        let mut tally = BranchTally::default();
        for &reset_seed in &eval_seeds {
            let o = play_episode(
                agent,
                env,
                perfect_rm,
                &task_progress,
                branches.as_ref(),
                ActMode::Mean,
                reset_seed,
                true,
                &mut rng,
                logger.as_deref_mut().map(|l| (l, "eval")),
                |_, _| {},
            )?;
            succ += f64::from(u8::from(o.success));
            progress += o.progress;
            final_ball += f64::from(u8::from(o.final_ball));
            ret += o.task_return;
            env_ret += o.env_return;
            if let Some(b) = o.branch {
                tally.add(b, o.success);
            }
        }
        let n = eval_seeds.len() as f64;
        let branches = branches.as_ref().map(|_| tally);
        Ok(Evaluation {
            success_rate: branches.and_then(|t| t.worst_rate()).unwrap_or(succ / n),
            progress: progress / n,
            final_ball: final_ball / n,
            branches,
            task_return: ret / n,
            env_return: env_ret / n,
        })
    };

    let ev = evaluate(&mut trainer.agent, &mut env, None).map_err(fail)?;
    let sr = ev.success_rate;
    rows.push(MetricsRow {
        iteration: 0,
        env_steps: 0,
        success_rate: sr,
        branches: ev.branches,
        task_return: ev.task_return,
        env_return: ev.env_return,
        learned_reward: 0.0,
        surrogate_loss: 0.0,
        progress: Some(ev.progress),
        final_ball: Some(ev.final_ball),
        expert_support: None,
    });
    progress(JobProgress {
        iteration: 0,
        iterations: s.irl_iterations,
        env_steps: 0,
        total_env_steps,
        success_rate: sr,
    });

    for iteration in 1..=s.irl_iterations {
        // 1. Policy: continue SAC on the current learned reward (SMIRL: shaped by the
        // potential of the current weights).
        {
            let potential = match &shaping_features {
                Some(f) => Some(
                    LearnedSubgoalPotential::from_weights(
                        f,
                        n_learned,
                        &model.params(),
                        s.smirl_shaping,
                    )
                    .map_err(|e| fail(e.to_string()))?,
                ),
                None => None,
            };
            let mut reward_fn = LearnedReward {
                counterfactual: counterfactual.as_ref(),
                model: model.as_mut(),
                product: learned.is_some(),
                shaping: potential.as_ref().map(|p| (p, f64::from(s.sac.gamma))),
                obs: Vec::new(),
                states: Vec::new(),
                error: None,
            };
            let before = trainer.env_steps();
            let chunk = 1_000u64;
            let mut done = 0;
            // SAC's own episodes go to the log too (phase "train").
            let mut train_log = logger
                .as_deref_mut()
                .map(|l| TrainingLog::new(l, perfect_rm, "train"));
            // Train the step budget, then play the episode in progress to its end: rollouts
            // and evaluation reset the same environment, and SAC must not resume an episode
            // from the state the last evaluation left it in (with 100-step episodes and a
            // budget that is a multiple of 100, as in the shipped profiles, there is nothing
            // to finish).
            while done < s.sac_steps_per_iteration || !trainer.at_episode_boundary() {
                let n = if done < s.sac_steps_per_iteration {
                    chunk.min(s.sac_steps_per_iteration - done)
                } else {
                    1
                };
                let observer = train_log
                    .as_mut()
                    .map(|t| t as &mut dyn TrainingObserver<JobEnv>);
                trainer
                    .train_observed(&mut env, &mut reward_fn, n, observer, |_| {})
                    .map_err(|e| fail(format!("SAC: {e}")))?;
                done += n;
                progress(JobProgress {
                    iteration: iteration - 1,
                    iterations: s.irl_iterations,
                    env_steps: before + done,
                    total_env_steps,
                    success_rate: rows.last().map_or(0.0, |r| r.success_rate),
                });
            }
            if let Some(e) = reward_fn.error {
                return Err(fail(format!("learned reward: {e}")));
            }
        }
        // 2. Rollouts: fresh trajectories of the current stochastic policy.
        let mut batch = AgentBatch::default();
        for _ in 0..s.agent_trajectories {
            let reset_seed = episode_seed(seed ^ 0x7261_6e64, rollout_index);
            rollout_index += 1;
            let mut len = 0;
            play_episode(
                &mut trainer.agent,
                &mut env,
                perfect_rm,
                &task_progress,
                None,
                ActMode::Sample,
                reset_seed,
                false,
                &mut rollout_rng,
                logger.as_deref_mut().map(|l| (l, "agent")),
                |o, u| {
                    batch.obs.extend_from_slice(o);
                    if let Some(u) = u {
                        batch.states.push(u as u32);
                    }
                    len += 1;
                },
            )
            .map_err(fail)?;
            batch.lengths.push(len);
        }
        let expert_support = expert_kde
            .density_columns(&batch.obs, OBS_DIM, &OBS_TIP)
            .map_err(|e| fail(format!("expert KDE: {e}")))?
            .iter()
            .filter(|&&d| d > 0.0)
            .count() as f64
            / (batch.obs.len() / OBS_DIM).max(1) as f64;
        // 3–4. Coefficients of the algorithm's loss.
        let Coefficients {
            obs,
            states,
            coeffs,
        } = irl_coefficients(
            algo,
            expert,
            Some(&expert_kde),
            &batch,
            s.kde_bandwidth,
            s.smirl_normalisation,
            discriminator.as_mut(),
        )
        .map_err(fail)?;
        let mut r = vec![0.0f32; coeffs.len()];
        model
            .reward_batch(&obs, &states, &mut r)
            .map_err(|e| fail(e.to_string()))?;
        let surrogate_loss: f64 = r.iter().zip(&coeffs).map(|(&r, c)| f64::from(r) * c).sum();
        let n_agent = batch.obs.len() / OBS_DIM;
        let learned_reward =
            r[..n_agent].iter().map(|&x| f64::from(x)).sum::<f64>() / n_agent as f64;
        // 5. Reward update, with learning rate lr · k^(−reward_lr_decay) at iteration k: the
        // first step's gradient (before any step) is SMIRL's traced data gradient.
        model.set_lr(reward_lr(algo, s, iteration));
        model
            .backward(&obs, &states, &coeffs)
            .map_err(|e| fail(format!("reward update: {e}")))?;
        let data_gradient = algo.uses_rm().then(|| model.grad());
        model.step();
        for _ in 1..s.reward_steps_per_iteration {
            model
                .update(&obs, &states, &coeffs)
                .map_err(|e| fail(format!("reward update: {e}")))?;
        }
        if let Some(data_gradient) = data_gradient {
            reward_trace.push(RewardTraceRow {
                iteration,
                data_gradient,
                weights: model.params(),
            });
        }
        // Ground-truth evaluation.
        let ev = evaluate(&mut trainer.agent, &mut env, logger.as_deref_mut()).map_err(fail)?;
        let sr = ev.success_rate;
        rows.push(MetricsRow {
            iteration,
            env_steps: trainer.env_steps(),
            success_rate: sr,
            branches: ev.branches,
            task_return: ev.task_return,
            env_return: ev.env_return,
            learned_reward,
            surrogate_loss,
            progress: Some(ev.progress),
            final_ball: Some(ev.final_ball),
            expert_support: Some(expert_support),
        });
        progress(JobProgress {
            iteration,
            iterations: s.irl_iterations,
            env_steps: trainer.env_steps(),
            total_env_steps,
            success_rate: sr,
        });
    }
    if let Some(path) = inputs.reward_path {
        model
            .save(path)
            .map_err(|e| fail(format!("saving the reward: {e}")))?;
    }
    Ok(JobResult {
        algo,
        seed,
        rows,
        reward_trace,
        wall_secs: started.elapsed().as_secs_f64(),
    })
}
