//! f-IRL's own Reacher experiment, "ReacherDraw" (Ni et al., CoRL 2020; the settings of its
//! official code are in `../shared/notes/firl.md`): the arm alone, every episode from both
//! joints at 0 rad and at rest, T = 30 steps, never done, and an expert given not by
//! demonstrations but as a density over the fingertip's (x, y) — a Gaussian at (−0.21, 0) or
//! an equal mixture of two at (−0.1485, ±0.1485), std 0.05. The IRL baselines' positive
//! control: a state-marginal task that f-IRL was built for and solves in its paper, so a
//! baseline that cannot match these densities is broken, and one that can fails the paper's
//! tasks for another reason.
//!
//! The arm is ReacherDelivery's (Gymnasium's reacher, whose balls are non-colliding and never
//! read here) with `arm_start = "zero"`. Every algorithm reads only the fingertip: the reward
//! is the baselines' (64, 64) MLP on it, f-IRL's agent density is the Epanechnikov KDE of the
//! iteration's fingertip states, the expert density is the analytic target (as in f-IRL's
//! code), MaxEnt IRL's expert states are `expert_samples` draws from it. Quality is the
//! forward and reverse KL between those draws and the agent's fingertip states, by the kNN
//! estimator ([`crate::irl::knn_divergence`], k = 3), as f-IRL reports it.
//!
//! One IRL iteration ([`run_draw`]'s loop, each phase a method of `DrawJob`), the four phases
//! of the Reacher jobs' loop: SAC continues on the current reward for
//! `sac_steps_per_iteration` steps; `agent_trajectories` fresh episodes of the stochastic
//! policy; the algorithm's per-state loss coefficients and `reward_steps_per_iteration` Adam
//! steps of the reward; every `eval_every` iterations the two KLs.

use super::reacher_irl::config::{load_toml_config, parse_toml_config};
use super::reacher_irl::{Algo, IrlConfigError};
use crate::env::reacher::ReacherError;
use crate::env::reacher::{
    ArmStart, CancelConfig, ConfigError, ReacherConfig, ReacherDelivery, OBS_TIP,
};
use crate::env::task_file::TaskFileError;
use crate::env::{ContinuousEnv, EnvError};
use crate::irl::firl::SurrogateError;
use crate::irl::firl::{density_ratio, FirlSurrogate, MaxEntCoefficients, DEFAULT_DENSITY_EPS};
use crate::irl::kde::Kde;
use crate::irl::kde::KdeError;
use crate::irl::knn_divergence::knn_kl;
use crate::irl::knn_divergence::KnnError;
use crate::irl::reward::RewardError;
use crate::irl::reward::{MlpReward, MlpRewardConfig, RewardModel};
use crate::report::raster::{Canvas, Rgb};
use crate::rl::replay::ReplayBatch;
use crate::rl::sac::{episode_seed, ActMode, ActWorkspace, SacConfig, SacTrainer};
use crate::rl::sac::{ConfigError as SacConfigError, SacError};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use serde::{Deserialize, Serialize};
use std::f64::consts::PI;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// The expert's fingertip density.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum DrawTarget {
    /// One Gaussian at (−0.21, 0), std 0.05: the point opposite the start, at full reach.
    Gaussian,
    /// An equal mixture of Gaussians at (−0.1485, ±0.1485), std 0.05.
    Mixture,
}

/// Standard deviation of every target component (m).
pub const TARGET_STD: f64 = 0.05;

impl DrawTarget {
    pub fn name(self) -> &'static str {
        match self {
            DrawTarget::Gaussian => "gaussian",
            DrawTarget::Mixture => "mixture",
        }
    }

    fn means(self) -> &'static [[f64; 2]] {
        match self {
            DrawTarget::Gaussian => &[[-0.21, 0.0]],
            DrawTarget::Mixture => &[[-0.1485, 0.1485], [-0.1485, -0.1485]],
        }
    }

    /// The density at fingertip position (x, y).
    pub fn density(self, x: f64, y: f64) -> f64 {
        let means = self.means();
        let var = TARGET_STD * TARGET_STD;
        means
            .iter()
            .map(|m| {
                let d2 = (x - m[0]).powi(2) + (y - m[1]).powi(2);
                (-d2 / (2.0 * var)).exp() / (2.0 * PI * var)
            })
            .sum::<f64>()
            / means.len() as f64
    }

    /// `n` draws, row-major (x, y).
    pub fn sample(self, n: usize, rng: &mut impl Rng) -> Vec<f64> {
        let normal = Normal::new(0.0, TARGET_STD).expect("positive std");
        let means = self.means();
        let mut out = Vec::with_capacity(2 * n);
        for _ in 0..n {
            let m = means[rng.gen_range(0..means.len())];
            out.push(m[0] + normal.sample(rng));
            out.push(m[1] + normal.sample(rng));
        }
        out
    }
}

/// A target name that is neither `gaussian` nor `mixture`.
#[derive(Debug, thiserror::Error)]
#[error("unknown target '{0}' (expected gaussian or mixture)")]
pub struct UnknownTarget(pub String);

impl std::str::FromStr for DrawTarget {
    type Err = UnknownTarget;
    fn from_str(s: &str) -> Result<Self, UnknownTarget> {
        match s {
            "gaussian" => Ok(DrawTarget::Gaussian),
            "mixture" => Ok(DrawTarget::Mixture),
            _ => Err(UnknownTarget(s.into())),
        }
    }
}

/// The arm's environment that cannot be made: the shipped scene or its config.
#[derive(Debug, thiserror::Error)]
pub enum ArmEnvError {
    #[error(transparent)]
    Task(#[from] TaskFileError),
    #[error(transparent)]
    Config(#[from] ConfigError),
}

/// A finished run that cannot be written.
#[derive(Debug, thiserror::Error)]
pub enum WriteRunError {
    #[error("the run made no KL estimate")]
    NoEstimate,
    #[error("{}: {source}", path.display())]
    Write {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error(transparent)]
    Json(#[from] serde_json::Error),
    #[error(transparent)]
    Png(#[from] png::EncodingError),
}

/// A ReacherDraw run's settings; defaults are f-IRL's (`../shared/notes/firl.md`) except
/// SAC's network widths (see `DrawConfig::default`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct DrawConfig {
    pub target: DrawTarget,
    pub iterations: usize,
    pub sac_steps_per_iteration: u64,
    /// Steps per episode (never done before).
    pub horizon: usize,
    /// Fresh episodes of the stochastic policy per iteration (the KDE's sample).
    pub agent_trajectories: usize,
    /// Draws from the target: MaxEnt IRL's expert states and the KL estimates' sample.
    pub expert_samples: usize,
    pub kde_bandwidth: f64,
    #[serde(serialize_with = "crate::short_float::f32")]
    pub reward_lr: f32,
    pub reward_steps_per_iteration: usize,
    /// Iterations between KL estimates (also the first and the last iteration).
    pub eval_every: usize,
    pub sac: SacConfig,
}

impl Default for DrawConfig {
    /// f-IRL's ReacherDraw: 800 iterations × 300 SAC steps, T = 30, 1 000 trajectories,
    /// 10 000 target samples, bandwidth 0.02, reward Adam lr 1e-3 × 2 steps, SAC lr 3e-3 with
    /// fixed α = 1, replay 12 000, 5 random episodes first. SAC's networks are (64, 64)
    /// instead of f-IRL's (256, 256): every SAC of this crate uses them, and the wider ones
    /// cost about 16× the update time on the 2-core machine (a 2-dimensional state needs no
    /// more capacity).
    fn default() -> Self {
        DrawConfig {
            target: DrawTarget::Gaussian,
            iterations: 800,
            sac_steps_per_iteration: 300,
            horizon: 30,
            agent_trajectories: 1000,
            expert_samples: 10_000,
            kde_bandwidth: 0.02,
            reward_lr: 1e-3,
            reward_steps_per_iteration: 2,
            eval_every: 10,
            sac: SacConfig {
                hidden: vec![64, 64],
                lr: 3e-3,
                batch_size: 256,
                replay_capacity: 12_000,
                gamma: 0.99,
                tau: 0.005,
                alpha: 1.0,
                auto_alpha: false,
                target_entropy: None,
                warmup_steps: 150,
                update_after: 150,
                updates_per_step: 1,
            },
        }
    }
}

/// Most IRL iterations of a ReacherDraw run.
pub const MAX_DRAW_ITERATIONS: usize = 100_000;
/// Most SAC steps per iteration.
pub const MAX_DRAW_SAC_STEPS: u64 = 10_000_000;
/// Most fingertip states collected per iteration (trajectories × horizon).
pub const MAX_DRAW_AGENT_STATES: usize = 1_000_000;
/// Most target samples.
pub const MAX_DRAW_EXPERT_SAMPLES: usize = 1_000_000;
/// Most reward steps per iteration.
pub const MAX_DRAW_REWARD_STEPS: usize = 1_000;

/// A run that cannot work (a bad config is an [`IrlConfigError`], as for `reacher --task`).
#[derive(Debug, thiserror::Error)]
pub enum DrawError {
    #[error(transparent)]
    Config(#[from] IrlConfigError),
    #[error(
        "{algo} is not a ReacherDraw algorithm (maxent, fkl, rkl, js: SMIRL needs labelled events)"
    )]
    Algo { algo: Algo },
    #[error("environment: {0}")]
    ArmConfig(ArmEnvError),
    #[error("environment: {0}")]
    Arm(ReacherError),
    #[error("SAC: {0}")]
    SacConfig(SacConfigError),
    #[error("SAC: {0}")]
    Sac(SacError),
    /// Building the reward net.
    #[error("reward: {0}")]
    RewardNet(RewardError),
    /// The learned reward's values (for SAC's transitions or the loss's states).
    #[error("learned reward: {0}")]
    LearnedReward(RewardError),
    #[error("rollout: {0}")]
    Rollout(EnvError),
    /// A rollout episode that ended at `step` (from 0), before the horizon.
    #[error("an episode ended before the horizon (ReacherDraw's episodes are never done)")]
    EarlyEnd { step: usize, horizon: usize },
    #[error("agent KDE: {0}")]
    AgentKde(KdeError),
    #[error("density ratio: {0}")]
    DensityRatio(SurrogateError),
    #[error("f-IRL surrogate: {0}")]
    Surrogate(SurrogateError),
    #[error("MaxEnt: {0}")]
    MaxEnt(SurrogateError),
    #[error("reward update: {0}")]
    RewardUpdate(RewardError),
    #[error("forward KL: {0}")]
    ForwardKl(KnnError),
    #[error("reverse KL: {0}")]
    ReverseKl(KnnError),
}

impl DrawConfig {
    /// The smoke profile of `--quick`: 6 iterations of 300 SAC steps, 50 trajectories,
    /// 2 000 target samples, a KL estimate every 2.
    pub fn quick() -> DrawConfig {
        DrawConfig {
            iterations: 6,
            agent_trajectories: 50,
            expert_samples: 2_000,
            eval_every: 2,
            ..DrawConfig::default()
        }
    }

    pub fn from_toml(text: &str, source_name: &str) -> Result<DrawConfig, IrlConfigError> {
        parse_toml_config(text, source_name, DrawConfig::validate)
    }

    pub fn load(path: &Path) -> Result<DrawConfig, IrlConfigError> {
        load_toml_config(path, DrawConfig::validate)
    }

    pub fn to_toml(&self) -> String {
        toml::to_string(self).expect("DrawConfig always serialises")
    }

    /// Checks every size and rate against its limit (named by field) before any work.
    pub fn validate(&self, source_name: &str) -> Result<(), IrlConfigError> {
        let bad = |field: &str, problem: String| {
            Err(IrlConfigError::Invalid {
                source_name: source_name.to_string(),
                field: field.to_string(),
                problem,
                line: None,
            })
        };
        let range = |field: &str, value: u64, min: u64, max: u64| {
            if value < min || value > max {
                bad(field, format!("is {value}, it must be in {min}..={max}"))
            } else {
                Ok(())
            }
        };
        range(
            "iterations",
            self.iterations as u64,
            1,
            MAX_DRAW_ITERATIONS as u64,
        )?;
        range(
            "sac_steps_per_iteration",
            self.sac_steps_per_iteration,
            1,
            MAX_DRAW_SAC_STEPS,
        )?;
        range(
            "horizon",
            self.horizon as u64,
            1,
            crate::env::reacher::MAX_EPISODE_STEPS as u64,
        )?;
        range(
            "agent_trajectories",
            self.agent_trajectories as u64,
            2,
            MAX_DRAW_AGENT_STATES as u64,
        )?;
        let states = self.agent_trajectories.saturating_mul(self.horizon);
        if states > MAX_DRAW_AGENT_STATES {
            return bad(
                "agent_trajectories",
                format!(
                    "× horizon = {states} fingertip states per iteration, more than the limit of {MAX_DRAW_AGENT_STATES}"
                ),
            );
        }
        // The kNN estimate needs k + 1 = 4 samples of each side.
        range(
            "expert_samples",
            self.expert_samples as u64,
            4,
            MAX_DRAW_EXPERT_SAMPLES as u64,
        )?;
        range(
            "reward_steps_per_iteration",
            self.reward_steps_per_iteration as u64,
            1,
            MAX_DRAW_REWARD_STEPS as u64,
        )?;
        range(
            "eval_every",
            self.eval_every as u64,
            1,
            MAX_DRAW_ITERATIONS as u64,
        )?;
        if !(self.kde_bandwidth.is_finite() && self.kde_bandwidth > 0.0) {
            return bad("kde_bandwidth", "must be a positive number".into());
        }
        if !(self.reward_lr.is_finite() && self.reward_lr > 0.0) {
            return bad("reward_lr", "must be a positive number".into());
        }
        match self.sac.validate() {
            Err(crate::rl::sac::ConfigError::Invalid { field, problem }) => {
                bad(&format!("sac.{field}"), problem)
            }
            Err(e) => bad("sac", e.to_string()),
            Ok(()) => Ok(()),
        }
    }

    /// The arm alone: T-step episodes from rest at 0 rad, no event, in the scene of the
    /// paper's tasks (`composite`'s layout; the reward reads the fingertip alone).
    pub fn env_config(&self) -> Result<ReacherConfig, ArmEnvError> {
        let task = crate::env::reacher_task::ReacherTask::shipped("composite")?;
        let config = ReacherConfig {
            max_steps: self.horizon,
            arm_start: ArmStart::Zero,
            cancel: Some(CancelConfig {
                probability: 0.0,
                earliest_step: 1,
                latest_step: 1,
            }),
            ..ReacherConfig::default()
        };
        Ok(task.env_config(&config)?)
    }
}

/// One KL estimate of a run.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct DrawRow {
    pub iteration: usize,
    pub env_steps: u64,
    /// KL(target ‖ agent), kNN estimate between the target samples and the iteration's agent
    /// fingertip states.
    pub forward_kl: f64,
    /// KL(agent ‖ target).
    pub reverse_kl: f64,
    /// Mean learned reward over the iteration's agent states.
    pub learned_reward: f64,
    /// Σ c r before the iteration's reward update.
    pub surrogate_loss: f64,
    pub wall_secs: f64,
}

/// A finished run: its KL estimates and the last iteration's agent fingertip states.
#[derive(Clone, Debug)]
pub struct DrawResult {
    pub rows: Vec<DrawRow>,
    /// The last batch of agent fingertip states, row-major (x, y).
    pub final_tips: Vec<f64>,
    /// The target samples the KLs were measured against.
    pub target_samples: Vec<f64>,
}

/// Runs one ReacherDraw job: `algo` (maxent, fkl, rkl, js) on `config`, seeded by `seed`
/// (SAC, rollouts and target samples have their own streams). `on_row` sees each KL
/// estimate as it is made.
pub fn run_draw(
    algo: Algo,
    config: &DrawConfig,
    seed: u64,
    on_row: impl FnMut(&DrawRow),
) -> Result<DrawResult, DrawError> {
    if !matches!(algo, Algo::MaxEnt | Algo::Fkl | Algo::Rkl | Algo::Js) {
        return Err(DrawError::Algo { algo });
    }
    config.validate("ReacherDraw config")?;
    let started = Instant::now();
    let env_config = config.env_config().map_err(DrawError::ArmConfig)?;
    let env = ReacherDelivery::new(env_config.clone()).map_err(DrawError::Arm)?;
    let obs_dim = env.obs_dim();
    let trainer =
        SacTrainer::new(&config.sac, obs_dim, env.act_dim(), seed).map_err(DrawError::SacConfig)?;
    let model: Box<dyn RewardModel + Send> = Box::new(
        MlpReward::new(
            MlpRewardConfig::paper(OBS_TIP.to_vec(), config.reward_lr, seed),
            obs_dim,
        )
        .map_err(DrawError::RewardNet)?,
    );
    let target_samples = config.target.sample(
        config.expert_samples,
        &mut ChaCha8Rng::seed_from_u64(episode_seed(seed, 0xd2a3)),
    );
    // MaxEnt's expert states: the target samples as observations (the reward reads only the
    // fingertip columns).
    let expert_obs: Vec<f32> = target_samples
        .chunks_exact(2)
        .flat_map(|p| {
            let mut o = vec![0.0f32; obs_dim];
            o[OBS_TIP[0]] = p[0] as f32;
            o[OBS_TIP[1]] = p[1] as f32;
            o
        })
        .collect();
    let rollout_rng = ChaCha8Rng::seed_from_u64(episode_seed(seed, 0x0a11_0a11));
    let lockstep = (0..config.agent_trajectories.min(ROLLOUT_LOCKSTEP))
        .map(|_| ReacherDelivery::new(env_config.clone()))
        .collect::<Result<Vec<_>, _>>()
        .map_err(DrawError::Arm)?;
    let act_ws = ActWorkspace::with_batch(&trainer.agent.actor, lockstep.len());
    let mut draw = DrawJob {
        algo,
        config,
        seed,
        started,
        round_obs: vec![0.0; lockstep.len() * obs_dim],
        round_actions: vec![0.0; lockstep.len() * env.act_dim()],
        env,
        trainer,
        model,
        target_samples,
        expert_obs,
        lockstep,
        act_ws,
        rollout_rng,
        rollout_index: 0,
        tips: Vec::new(),
        rows: Vec::new(),
        on_row,
    };
    for iteration in 1..=config.iterations {
        draw.sac_phase()?;
        let agent_obs = draw.rollouts()?;
        let facts = draw.reward_update(agent_obs)?;
        draw.record(iteration, facts)?;
    }
    Ok(DrawResult {
        rows: draw.rows,
        final_tips: draw.tips,
        target_samples: draw.target_samples,
    })
}

/// A ReacherDraw job as [`run_draw`] sets it up; its methods are the four phases of an IRL
/// iteration.
struct DrawJob<'c, F> {
    algo: Algo,
    config: &'c DrawConfig,
    seed: u64,
    started: Instant,
    /// SAC's environment.
    env: ReacherDelivery,
    trainer: SacTrainer,
    model: Box<dyn RewardModel + Send>,
    target_samples: Vec<f64>,
    expert_obs: Vec<f32>,
    /// Rollout environments stepped in lockstep, and the actor's buffers for them.
    lockstep: Vec<ReacherDelivery>,
    act_ws: ActWorkspace,
    round_obs: Vec<f32>,
    round_actions: Vec<f32>,
    /// The rollouts' action noise, and how many rollout episodes have been reset (their reset
    /// seeds' stream), both counted across iterations.
    rollout_rng: ChaCha8Rng,
    rollout_index: u64,
    /// The last rollouts' fingertip states, row-major (x, y).
    tips: Vec<f64>,
    rows: Vec<DrawRow>,
    on_row: F,
}

/// What a ReacherDraw reward update reports to its KL row.
struct DrawFacts {
    /// Mean learned reward over the iteration's agent states, before the update.
    learned_reward: f64,
    /// Σ c r before the update.
    surrogate_loss: f64,
}

impl<F: FnMut(&DrawRow)> DrawJob<'_, F> {
    /// Phase 1: SAC on the current reward r(o_{t+1}) of each replayed transition.
    fn sac_phase(&mut self) -> Result<(), DrawError> {
        let mut reward_error = None;
        // The plain environment's observations are the reward's input rows as stored.
        let mut reward_fn = |batch: &ReplayBatch, out: &mut [f32]| {
            if let Err(e) = self.model.reward_batch(batch.next_obs.as_slice(), &[], out) {
                out.fill(0.0);
                reward_error.get_or_insert(e);
            }
        };
        let steps = self.config.sac_steps_per_iteration;
        (self.trainer)
            .train(&mut self.env, &mut reward_fn, steps, |_| {})
            .map_err(DrawError::Sac)?;
        // Play the episode in progress to its end: the rollouts below reset the same
        // environment, and SAC must not resume from the state they leave.
        (self.trainer)
            .finish_episode_observed(&mut self.env, &mut reward_fn, None, |_| {})
            .map_err(DrawError::Sac)?;
        match reward_error {
            Some(e) => Err(DrawError::LearnedReward(e)),
            None => Ok(()),
        }
    }

    /// Phase 2: fresh episodes of the stochastic policy, fingertip states s_1..s_T, played
    /// `lockstep.len()` at a time so that the actor acts on all of them in one product; their
    /// observations, trajectory after trajectory, `horizon` each.
    fn rollouts(&mut self) -> Result<Vec<f32>, DrawError> {
        let (n_traj, horizon) = (self.config.agent_trajectories, self.config.horizon);
        let (obs_dim, act_dim) = (self.env.obs_dim(), self.env.act_dim());
        let width = self.lockstep.len();
        let mut agent_obs = vec![0.0f32; n_traj * horizon * obs_dim];
        for first in (0..n_traj).step_by(width) {
            let round = width.min(n_traj - first);
            for (k, env) in self.lockstep.iter_mut().take(round).enumerate() {
                let reset_seed =
                    episode_seed(self.seed ^ 0x7261_6e64, self.rollout_index + k as u64);
                env.reset(
                    reset_seed,
                    &mut self.round_obs[k * obs_dim..(k + 1) * obs_dim],
                );
            }
            self.rollout_index += round as u64;
            for t in 0..horizon {
                self.act_ws.act(
                    &self.trainer.agent.actor,
                    &self.round_obs,
                    ActMode::Sample,
                    &mut self.rollout_rng,
                    &mut self.round_actions,
                );
                for (k, env) in self.lockstep.iter_mut().take(round).enumerate() {
                    let o = &mut self.round_obs[k * obs_dim..(k + 1) * obs_dim];
                    let step = env
                        .step(&self.round_actions[k * act_dim..(k + 1) * act_dim], o)
                        .map_err(DrawError::Rollout)?;
                    if step.terminated || (step.truncated && t + 1 < horizon) {
                        return Err(DrawError::EarlyEnd { step: t, horizon });
                    }
                    let at = ((first + k) * horizon + t) * obs_dim;
                    agent_obs[at..at + obs_dim].copy_from_slice(o);
                }
            }
        }
        self.tips = agent_obs
            .chunks_exact(obs_dim)
            .flat_map(|o| [f64::from(o[OBS_TIP[0]]), f64::from(o[OBS_TIP[1]])])
            .collect();
        Ok(agent_obs)
    }

    /// Phase 3: the algorithm's loss coefficients at the agent (and, MaxEnt, expert) states,
    /// then the reward steps on them.
    fn reward_update(&mut self, agent_obs: Vec<f32>) -> Result<DrawFacts, DrawError> {
        let (config, tips) = (self.config, &self.tips);
        let n_agent = tips.len() / 2;
        let (obs, coeffs) = match self.algo.divergence() {
            Some(divergence) => {
                let kde_agent =
                    Kde::fit(tips, 2, config.kde_bandwidth).map_err(DrawError::AgentKde)?;
                let mut rho_agent = vec![0.0; n_agent];
                kde_agent.density_batch(tips, &mut rho_agent);
                let rho_target: Vec<f64> = tips
                    .chunks_exact(2)
                    .map(|p| config.target.density(p[0], p[1]))
                    .collect();
                let ratios = density_ratio(&rho_target, &rho_agent, DEFAULT_DENSITY_EPS)
                    .map_err(DrawError::DensityRatio)?;
                let s = FirlSurrogate::new(
                    divergence,
                    &ratios,
                    config.agent_trajectories,
                    config.horizon,
                )
                .map_err(DrawError::Surrogate)?;
                (agent_obs, s.coefficients)
            }
            None => {
                let c = MaxEntCoefficients::new(n_agent, config.expert_samples, config.horizon)
                    .map_err(DrawError::MaxEnt)?;
                let mut coeffs = vec![c.agent; n_agent];
                coeffs.extend(std::iter::repeat_n(c.expert, config.expert_samples));
                ([agent_obs.as_slice(), &self.expert_obs].concat(), coeffs)
            }
        };
        let mut r = vec![0.0f32; coeffs.len()];
        (self.model)
            .reward_batch(&obs, &[], &mut r)
            .map_err(DrawError::LearnedReward)?;
        let facts = DrawFacts {
            surrogate_loss: r.iter().zip(&coeffs).map(|(&r, c)| f64::from(r) * c).sum(),
            learned_reward: r[..n_agent].iter().map(|&x| f64::from(x)).sum::<f64>()
                / n_agent as f64,
        };
        for _ in 0..config.reward_steps_per_iteration {
            (self.model)
                .update(&obs, &[], &coeffs)
                .map_err(DrawError::RewardUpdate)?;
        }
        Ok(facts)
    }

    /// Phase 4: every `eval_every` iterations (and the first and last), the KLs to the target
    /// on this iteration's states.
    fn record(&mut self, iteration: usize, facts: DrawFacts) -> Result<(), DrawError> {
        let config = self.config;
        if iteration == 1
            || iteration.is_multiple_of(config.eval_every)
            || iteration == config.iterations
        {
            let (target, tips) = (&self.target_samples, &self.tips);
            let forward_kl = knn_kl(target, tips, 2, 3).map_err(DrawError::ForwardKl)?;
            let reverse_kl = knn_kl(tips, target, 2, 3).map_err(DrawError::ReverseKl)?;
            let row = DrawRow {
                iteration,
                env_steps: self.trainer.env_steps(),
                forward_kl,
                reverse_kl,
                learned_reward: facts.learned_reward,
                surrogate_loss: facts.surrogate_loss,
                wall_secs: self.started.elapsed().as_secs_f64(),
            };
            (self.on_row)(&row);
            self.rows.push(row);
        }
        Ok(())
    }
}

/// Most rollout environments stepped together (their actor batch).
const ROLLOUT_LOCKSTEP: usize = 250;

/// Half-width of the pictured square around the arm's base (m): the arena's walls.
const VIEW_HALF_WIDTH: f64 = 0.3;

/// A PNG of two panels over the arena: the target density (left) and a histogram of the
/// agent's fingertip states (right), each shaded relative to its own maximum, with the
/// arm's reach (0.21 m) as a ring and the start (0.21, 0) as a dot.
pub fn density_picture(target: DrawTarget, tips: &[f64]) -> Result<Vec<u8>, png::EncodingError> {
    const PANEL: u32 = 300;
    const BINS: usize = 60;
    const GAP: u32 = 20;
    let mut canvas = Canvas::new(2 * PANEL + GAP, PANEL, Rgb::WHITE);
    let cell = PANEL as f64 / BINS as f64;
    let bin_centre =
        |i: usize| -VIEW_HALF_WIDTH + (i as f64 + 0.5) * 2.0 * VIEW_HALF_WIDTH / BINS as f64;
    let mut target_grid = vec![0.0; BINS * BINS];
    for (j, row) in target_grid.chunks_exact_mut(BINS).enumerate() {
        for (i, v) in row.iter_mut().enumerate() {
            *v = target.density(bin_centre(i), bin_centre(BINS - 1 - j));
        }
    }
    let mut agent_grid = vec![0.0; BINS * BINS];
    for p in tips.chunks_exact(2) {
        let to_bin =
            |v: f64| ((v + VIEW_HALF_WIDTH) / (2.0 * VIEW_HALF_WIDTH) * BINS as f64).floor();
        let (i, j) = (to_bin(p[0]), to_bin(p[1]));
        if (0.0..BINS as f64).contains(&i) && (0.0..BINS as f64).contains(&j) {
            agent_grid[(BINS - 1 - j as usize) * BINS + i as usize] += 1.0;
        }
    }
    let shade = Rgb(0.1, 0.2, 0.6);
    for (panel, grid) in [(0u32, &target_grid), (1, &agent_grid)] {
        let x0 = f64::from(panel * (PANEL + GAP));
        let max = grid.iter().cloned().fold(0.0, f64::max);
        if max > 0.0 {
            for (k, &v) in grid.iter().enumerate() {
                let (i, j) = ((k % BINS) as f64, (k / BINS) as f64);
                canvas.rect(
                    (x0 + i * cell) as i64,
                    (j * cell) as i64,
                    (x0 + (i + 1.0) * cell) as i64,
                    ((j + 1.0) * cell) as i64,
                    shade,
                    (v / max).sqrt() as f32,
                );
            }
        }
        let to_px = |x: f64, y: f64| {
            (
                x0 + (x + VIEW_HALF_WIDTH) / (2.0 * VIEW_HALF_WIDTH) * f64::from(PANEL),
                (VIEW_HALF_WIDTH - y) / (2.0 * VIEW_HALF_WIDTH) * f64::from(PANEL),
            )
        };
        let (cx, cy) = to_px(0.0, 0.0);
        let reach = REACH / (2.0 * VIEW_HALF_WIDTH) * f64::from(PANEL);
        canvas.ring(cx, cy, reach, 1.0, Rgb(0.5, 0.5, 0.5), 1.0);
        let (sx, sy) = to_px(0.21, 0.0);
        canvas.disc(sx, sy, 3.0, Rgb(0.8, 0.1, 0.1), 1.0);
    }
    canvas.to_png()
}

/// What `summary.json` of a run records: the first and last KL estimates and their ratios.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct DrawSummary {
    pub algo: String,
    pub target: DrawTarget,
    pub seed: u64,
    pub iterations: usize,
    pub first_forward_kl: f64,
    pub first_reverse_kl: f64,
    pub last_forward_kl: f64,
    pub last_reverse_kl: f64,
    /// Last / first forward KL (the ReacherDraw target: at most 0.2).
    pub forward_ratio: f64,
    pub reverse_ratio: f64,
    /// The KLs the best the arm can do would measure: the same estimates against the target
    /// conditioned on the arm's reach ([`reachable_floor`]); both targets sit at full reach,
    /// so about half their mass is out of it and no policy gets below these.
    #[serde(default)]
    pub reachable_forward_kl: Option<f64>,
    #[serde(default)]
    pub reachable_reverse_kl: Option<f64>,
    pub wall_secs: f64,
    pub git_commit: String,
}

impl DrawSummary {
    pub fn of(
        algo: Algo,
        seed: u64,
        config: &DrawConfig,
        result: &DrawResult,
    ) -> Option<DrawSummary> {
        let (first, last) = (result.rows.first()?, result.rows.last()?);
        let floor = reachable_floor(config.target, &result.target_samples, seed).ok();
        Some(DrawSummary {
            algo: algo.name().to_string(),
            target: config.target,
            seed,
            iterations: config.iterations,
            first_forward_kl: first.forward_kl,
            first_reverse_kl: first.reverse_kl,
            last_forward_kl: last.forward_kl,
            last_reverse_kl: last.reverse_kl,
            forward_ratio: last.forward_kl / first.forward_kl,
            reverse_ratio: last.reverse_kl / first.reverse_kl,
            reachable_forward_kl: floor.map(|f| f.0),
            reachable_reverse_kl: floor.map(|f| f.1),
            wall_secs: last.wall_secs,
            git_commit: crate::GIT_COMMIT.to_string(),
        })
    }
}

/// Reach of the fingertip from the arm's base (m): links of 0.1 and 0.11.
pub const REACH: f64 = 0.21;

/// The (forward, reverse) KL estimates between `target_samples` and as many draws of the
/// target conditioned on the disc the fingertip can reach: what a policy that matched the
/// target wherever the arm can go would measure.
pub fn reachable_floor(
    target: DrawTarget,
    target_samples: &[f64],
    seed: u64,
) -> Result<(f64, f64), crate::irl::knn_divergence::KnnError> {
    let n = target_samples.len() / 2;
    let mut rng = ChaCha8Rng::seed_from_u64(episode_seed(seed, 0x4eac));
    let mut reachable = Vec::with_capacity(2 * n);
    while reachable.len() < 2 * n {
        for p in target.sample(n, &mut rng).chunks_exact(2) {
            if p[0].hypot(p[1]) <= REACH && reachable.len() < 2 * n {
                reachable.extend_from_slice(p);
            }
        }
    }
    Ok((
        knn_kl(target_samples, &reachable, 2, 3)?,
        knn_kl(&reachable, target_samples, 2, 3)?,
    ))
}

/// `metrics.csv` of a run: one row per KL estimate.
pub fn metrics_csv(algo: Algo, seed: u64, rows: &[DrawRow]) -> String {
    let mut out = String::from(
        "algo,seed,iteration,env_steps,forward_kl,reverse_kl,learned_reward,surrogate_loss,wall_secs\n",
    );
    for r in rows {
        out.push_str(&format!(
            "{},{seed},{},{},{},{},{},{},{:.1}\n",
            algo.name(),
            r.iteration,
            r.env_steps,
            r.forward_kl,
            r.reverse_kl,
            r.learned_reward,
            r.surrogate_loss,
            r.wall_secs
        ));
    }
    out
}

/// Writes a finished run into `dir` (an existing, writable directory): `config.toml`,
/// `metrics.csv`, `summary.json` and `density.png` (target vs the last iteration's agent).
pub fn write_run(
    dir: &Path,
    algo: Algo,
    seed: u64,
    config: &DrawConfig,
    result: &DrawResult,
) -> Result<DrawSummary, WriteRunError> {
    let summary = DrawSummary::of(algo, seed, config, result).ok_or(WriteRunError::NoEstimate)?;
    let write = |name: &str, bytes: &[u8]| {
        let path = dir.join(name);
        crate::atomic_file::write_atomic(&path, bytes)
            .map_err(|source| WriteRunError::Write { path, source })
    };
    write("config.toml", config.to_toml().as_bytes())?;
    write(
        "metrics.csv",
        metrics_csv(algo, seed, &result.rows).as_bytes(),
    )?;
    let json = serde_json::to_string_pretty(&summary)?;
    write("summary.json", json.as_bytes())?;
    write(
        "density.png",
        &density_picture(config.target, &result.final_tips)?,
    )?;
    Ok(summary)
}
