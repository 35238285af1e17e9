//! The SAC training loop and its checkpoints.

use super::agent::{ActMode, SacAgent, UpdateStats};
use super::episode::EpisodeSummary;
use super::{SacConfig, SacError};
use crate::env::{ContinuousEnv, EnvStep};
use crate::nn::codec::{read_file, save_file, ByteReader, ByteWriter, CodecError, FileError};
use crate::rl::replay::{ReplayBatch, ReplayBuffer};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::path::Path;

const CHECKPOINT_MAGIC: &[u8; 8] = b"SMIRLSAC";
const CHECKPOINT_VERSION: u32 = 1;

/// Supplies the rewards of a sampled batch (see the module notes on sample-time rewards).
pub trait RewardFn {
    /// Writes one reward per transition of `batch` into `out` (`out.len() == batch.len()`).
    /// An error (e.g. a learned reward that cannot read the batch) stops training.
    fn fill_rewards(&mut self, batch: &ReplayBatch, out: &mut [f32]) -> Result<(), RewardFnError>;

    /// Rewrites sampled transitions before their rewards are filled (e.g. counterfactual
    /// reward-machine states, `rl::crm`), drawing from SAC's own stream. Default: none, and no
    /// draw, so a run without relabelling is unchanged.
    fn relabel(&mut self, _batch: &mut ReplayBatch, _rng: &mut dyn rand::RngCore) {}
}

/// The environment's own reward, as stored in the replay buffer.
#[derive(Clone, Copy, Debug, Default)]
pub struct EnvReward;

impl RewardFn for EnvReward {
    fn fill_rewards(&mut self, batch: &ReplayBatch, out: &mut [f32]) -> Result<(), RewardFnError> {
        out.copy_from_slice(&batch.env_rewards);
        Ok(())
    }
}

/// A closure that cannot fail.
impl<F: FnMut(&ReplayBatch, &mut [f32])> RewardFn for F {
    fn fill_rewards(&mut self, batch: &ReplayBatch, out: &mut [f32]) -> Result<(), RewardFnError> {
        self(batch, out);
        Ok(())
    }
}

/// What a [`RewardFn`] reports when it cannot compute a batch's rewards.
pub type RewardFnError = Box<dyn std::error::Error + Send + Sync>;

/// Sees the episodes the trainer plays, step by step, with the environment's state after
/// each event (e.g. to log them for replay). Training does not depend on it: the trainer
/// calls it after the environment step and before any update, and takes nothing back but
/// errors, which stop training.
pub trait TrainingObserver<E: ?Sized> {
    /// `env` was just reset with `reset_seed` for a new training episode; `obs` is its first
    /// observation.
    fn episode_started(
        &mut self,
        env: &E,
        reset_seed: u64,
        obs: &[f32],
    ) -> Result<(), ObserverError>;
    /// `env` took `action` and reported `step`; `obs` is the observation after it.
    fn stepped(
        &mut self,
        env: &E,
        action: &[f32],
        step: &EnvStep,
        obs: &[f32],
    ) -> Result<(), ObserverError>;
    /// The episode ended with that step (terminated or truncated).
    fn episode_ended(&mut self, env: &E, episode: &EpisodeSummary) -> Result<(), ObserverError>;
}

/// What a [`TrainingObserver`] reports when it cannot go on (e.g. a log write failed).
pub type ObserverError = Box<dyn std::error::Error + Send + Sync>;

/// What one call of [`SacTrainer::step`] did.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StepOutcome {
    pub env_step: EnvStep,
    /// Stats of the last gradient update of this step, if any.
    pub update: Option<UpdateStats>,
    /// Set when this step ended an episode.
    pub episode: Option<EpisodeSummary>,
}

/// Seed of episode `index`'s reset: a SplitMix64 mix of the run seed and the index, so resets
/// are reproducible and independent of how many random numbers the agent drew.
pub fn episode_seed(seed: u64, index: u64) -> u64 {
    fn mix(mut z: u64) -> u64 {
        z = z.wrapping_add(0x9e37_79b9_7f4a_7c15);
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }
    mix(seed ^ mix(index))
}

/// A checkpoint that cannot be written or used.
#[derive(Debug, thiserror::Error)]
pub enum CheckpointError {
    #[error(transparent)]
    File(#[from] FileError),
    #[error("{path}: checkpoint is for a different architecture: {what} is {found} in the file, {expected} here")]
    Architecture {
        path: String,
        what: String,
        found: String,
        expected: String,
    },
    #[error("{path}: checkpoint was trained with a different config (fields differ: {fields})")]
    Config { path: String, fields: String },
    #[error("checkpoints are taken between episodes; an episode is in progress")]
    MidEpisode,
}

/// The single SAC training loop: environment interaction, replay, updates, checkpoints.
///
/// Everything random comes from one `ChaCha8Rng` seeded with the run seed (random warm-up
/// actions, policy noise, replay sampling) plus per-episode reset seeds from [`episode_seed`],
/// so a run is a pure function of (config, seed, environment, reward function).
///
/// Checkpoints are taken between episodes (the environment trait cannot save its own state);
/// resuming restores networks, optimisers, α, counters, replay buffer and RNG state, so a
/// resumed run continues exactly as the uninterrupted run would.
#[derive(Clone, Debug)]
pub struct SacTrainer {
    pub agent: SacAgent,
    pub replay: ReplayBuffer,
    seed: u64,
    rng: ChaCha8Rng,
    batch: ReplayBatch,
    rewards: Vec<f32>,
    obs: Vec<f32>,
    next_obs: Vec<f32>,
    action: Vec<f32>,
    in_episode: bool,
    env_steps: u64,
    episodes: u64,
    episode_return: f64,
    episode_len: u64,
}

impl SacTrainer {
    /// A new run. Fails when the config is invalid.
    pub fn new(
        config: &SacConfig,
        obs_dim: usize,
        act_dim: usize,
        seed: u64,
    ) -> Result<Self, super::ConfigError> {
        config.validate()?;
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let agent = SacAgent::new(config, obs_dim, act_dim, &mut rng);
        Ok(Self {
            agent,
            replay: ReplayBuffer::new(obs_dim, act_dim, config.replay_capacity),
            seed,
            rng,
            batch: ReplayBatch::new(obs_dim, act_dim, config.batch_size),
            rewards: vec![0.0; config.batch_size],
            obs: vec![0.0; obs_dim],
            next_obs: vec![0.0; obs_dim],
            action: vec![0.0; act_dim],
            in_episode: false,
            env_steps: 0,
            episodes: 0,
            episode_return: 0.0,
            episode_len: 0,
        })
    }

    pub fn seed(&self) -> u64 {
        self.seed
    }
    /// Environment steps taken so far.
    pub fn env_steps(&self) -> u64 {
        self.env_steps
    }
    /// Episodes finished so far.
    pub fn episodes(&self) -> u64 {
        self.episodes
    }
    /// True between episodes (where checkpoints can be taken).
    pub fn at_episode_boundary(&self) -> bool {
        !self.in_episode
    }
    pub fn config(&self) -> &SacConfig {
        self.agent.config()
    }

    fn check_env<E: ContinuousEnv + ?Sized>(&self, env: &E) -> Result<(), SacError> {
        let dims = [
            ("observation size", self.agent.obs_dim(), env.obs_dim()),
            ("action size", self.agent.act_dim(), env.act_dim()),
        ];
        for (what, expected, got) in dims {
            if expected != got {
                return Err(SacError::Dimension {
                    what,
                    expected,
                    got,
                });
            }
        }
        Ok(())
    }

    /// One environment step (resetting first when between episodes) followed by the
    /// configured number of gradient updates with rewards from `reward`.
    ///
    /// Transitions ending in `terminated` are not bootstrapped; those cut by `truncated` are.
    pub fn step<E: ContinuousEnv + ?Sized, R: RewardFn + ?Sized>(
        &mut self,
        env: &mut E,
        reward: &mut R,
    ) -> Result<StepOutcome, SacError> {
        self.step_observed(env, reward, None)
    }

    /// [`SacTrainer::step`], reporting the reset (if any), the step and the episode's end to
    /// `observer`.
    pub fn step_observed<E: ContinuousEnv + ?Sized, R: RewardFn + ?Sized>(
        &mut self,
        env: &mut E,
        reward: &mut R,
        mut observer: Option<&mut (dyn TrainingObserver<E> + '_)>,
    ) -> Result<StepOutcome, SacError> {
        self.check_env(env)?;
        let observed = |step: u64, r: Result<(), ObserverError>| {
            r.map_err(|source| SacError::Observer { step, source })
        };
        if !self.in_episode {
            let reset_seed = episode_seed(self.seed, self.episodes);
            env.reset(reset_seed, &mut self.obs);
            self.in_episode = true;
            self.episode_return = 0.0;
            self.episode_len = 0;
            if let Some(o) = observer.as_deref_mut() {
                observed(
                    self.env_steps,
                    o.episode_started(env, reset_seed, &self.obs),
                )?;
            }
        }
        let cfg = self.agent.config();
        if self.env_steps < cfg.warmup_steps {
            for a in &mut self.action {
                *a = self.rng.gen_range(-1.0..=1.0);
            }
        } else {
            self.agent
                .act(&self.obs, ActMode::Sample, &mut self.rng, &mut self.action);
        }
        let env_step = env
            .step(&self.action, &mut self.next_obs)
            .map_err(|source| SacError::Env {
                step: self.env_steps,
                source,
            })?;
        self.replay.push(
            &self.obs,
            &self.action,
            &self.next_obs,
            env_step.reward as f32,
            env_step.labels,
            env_step.terminated,
        );
        if let Some(o) = observer.as_deref_mut() {
            observed(
                self.env_steps,
                o.stepped(env, &self.action, &env_step, &self.next_obs),
            )?;
        }
        std::mem::swap(&mut self.obs, &mut self.next_obs);
        self.env_steps += 1;
        self.episode_return += env_step.reward;
        self.episode_len += 1;
        let mut episode = None;
        if env_step.terminated || env_step.truncated {
            episode = Some(EpisodeSummary {
                index: self.episodes,
                env_return: self.episode_return,
                final_reward: env_step.reward,
                length: self.episode_len,
                terminated: env_step.terminated,
            });
            self.episodes += 1;
            self.in_episode = false;
            if let (Some(o), Some(e)) = (observer, episode.as_ref()) {
                observed(self.env_steps, o.episode_ended(env, e))?;
            }
        }
        let mut update = None;
        let cfg = self.agent.config();
        if self.env_steps >= cfg.update_after && self.replay.len() >= cfg.batch_size {
            for _ in 0..cfg.updates_per_step {
                update = Some(self.update_once(reward)?);
            }
        }
        Ok(StepOutcome {
            env_step,
            update,
            episode,
        })
    }

    /// One gradient update on a batch sampled from the replay buffer, rewards from `reward`.
    fn update_once<R: RewardFn + ?Sized>(
        &mut self,
        reward: &mut R,
    ) -> Result<UpdateStats, SacError> {
        self.replay.sample_into(&mut self.rng, &mut self.batch);
        reward.relabel(&mut self.batch, &mut self.rng);
        reward
            .fill_rewards(&self.batch, &mut self.rewards)
            .map_err(|source| SacError::Reward {
                step: self.env_steps,
                source,
            })?;
        self.agent.update(&self.batch, &self.rewards, &mut self.rng)
    }

    /// Runs `steps` calls of [`SacTrainer::step`], reporting each outcome to `on_step`.
    pub fn train<E: ContinuousEnv + ?Sized, R: RewardFn + ?Sized>(
        &mut self,
        env: &mut E,
        reward: &mut R,
        steps: u64,
        on_step: impl FnMut(&StepOutcome),
    ) -> Result<(), SacError> {
        self.train_observed(env, reward, steps, None, on_step)
    }

    /// [`SacTrainer::train`] with a [`TrainingObserver`] seeing every episode.
    pub fn train_observed<E: ContinuousEnv + ?Sized, R: RewardFn + ?Sized>(
        &mut self,
        env: &mut E,
        reward: &mut R,
        steps: u64,
        mut observer: Option<&mut (dyn TrainingObserver<E> + '_)>,
        mut on_step: impl FnMut(&StepOutcome),
    ) -> Result<(), SacError> {
        for _ in 0..steps {
            let outcome = self.step_observed(env, reward, observer.as_deref_mut())?;
            on_step(&outcome);
        }
        Ok(())
    }

    /// Trains on until the episode in progress ends (no step between episodes), reporting each
    /// outcome to `on_step`; returns the steps taken. A caller that resets the environment next
    /// (rollouts, evaluations) calls it first, so that SAC never resumes an episode from the
    /// state they leave.
    pub fn finish_episode_observed<E: ContinuousEnv + ?Sized, R: RewardFn + ?Sized>(
        &mut self,
        env: &mut E,
        reward: &mut R,
        mut observer: Option<&mut (dyn TrainingObserver<E> + '_)>,
        mut on_step: impl FnMut(&StepOutcome),
    ) -> Result<u64, SacError> {
        let mut steps = 0;
        while !self.at_episode_boundary() {
            let outcome = self.step_observed(env, reward, observer.as_deref_mut())?;
            on_step(&outcome);
            steps += 1;
        }
        Ok(steps)
    }

    /// Runs `episodes` evaluation episodes (at most `max_steps` steps each) with the given
    /// action mode, on resets seeded from `seed` (independent of the training episodes).
    /// Leaves the training state untouched apart from the environment, so call it between
    /// episodes.
    pub fn evaluate<E: ContinuousEnv + ?Sized>(
        &mut self,
        env: &mut E,
        episodes: u64,
        mode: ActMode,
        seed: u64,
        max_steps: u64,
    ) -> Result<Vec<EpisodeSummary>, SacError> {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        (0..episodes)
            .map(|index| {
                let mut summary = self.agent.rollout(
                    env,
                    mode,
                    episode_seed(seed, index),
                    max_steps,
                    &mut rng,
                    |_| {},
                )?;
                summary.index = index;
                Ok(summary)
            })
            .collect()
    }

    /// Saves the whole run state to `path` atomically (temp file + rename). Only between
    /// episodes.
    pub fn save_checkpoint(&self, path: &Path) -> Result<(), CheckpointError> {
        if self.in_episode {
            return Err(CheckpointError::MidEpisode);
        }
        let mut w = ByteWriter::new();
        w.raw(CHECKPOINT_MAGIC);
        w.u32(CHECKPOINT_VERSION);
        w.usize(self.agent.obs_dim());
        w.usize(self.agent.act_dim());
        w.str(&self.agent.config().to_toml());
        w.u64(self.seed);
        w.blob(&self.rng.get_seed());
        w.u64(self.rng.get_stream());
        w.u128(self.rng.get_word_pos());
        w.u64(self.env_steps);
        w.u64(self.episodes);
        self.agent.write(&mut w);
        self.replay.write(&mut w);
        Ok(save_file(path, &w.bytes)?)
    }

    /// Restores a run saved by [`SacTrainer::save_checkpoint`]. The checkpoint must come from
    /// the same format version, observation/action sizes and config; anything else is refused
    /// with a message naming what differs.
    pub fn resume(
        path: &Path,
        config: &SacConfig,
        obs_dim: usize,
        act_dim: usize,
    ) -> Result<Self, CheckpointError> {
        let p = path.display().to_string();
        let bytes = read_file(path)?;
        let codec = FileError::codec_at(&p);
        let arch = |what: &str, found: String, expected: String| CheckpointError::Architecture {
            path: p.clone(),
            what: what.to_string(),
            found,
            expected,
        };
        let mut r = ByteReader::new(&bytes);
        r.header(CHECKPOINT_MAGIC, "smirl SAC checkpoint", CHECKPOINT_VERSION)
            .map_err(codec)?;
        let file_obs = r.usize("observation size").map_err(codec)?;
        let file_act = r.usize("action size").map_err(codec)?;
        if file_obs != obs_dim {
            return Err(arch(
                "observation size",
                file_obs.to_string(),
                obs_dim.to_string(),
            ));
        }
        if file_act != act_dim {
            return Err(arch(
                "action size",
                file_act.to_string(),
                act_dim.to_string(),
            ));
        }
        let file_config_text = r.string("config").map_err(codec)?;
        let file_config = SacConfig::from_toml(&file_config_text, &p).map_err(|e| {
            codec(CodecError::Invalid {
                what: "stored config",
                problem: e.to_string(),
            })
        })?;
        if file_config.hidden != config.hidden {
            return Err(arch(
                "hidden layers",
                format!("{:?}", file_config.hidden),
                format!("{:?}", config.hidden),
            ));
        }
        let fields = config_differences(&file_config, config);
        if !fields.is_empty() {
            return Err(CheckpointError::Config {
                path: p.clone(),
                fields: fields.join(", "),
            });
        }
        let seed = r.u64("seed").map_err(codec)?;
        let mut trainer = Self::new(config, obs_dim, act_dim, seed).map_err(|e| {
            codec(CodecError::Invalid {
                what: "config",
                problem: e.to_string(),
            })
        })?;
        let rng_seed: [u8; 32] = r.blob("rng seed").map_err(codec)?.try_into().map_err(|_| {
            codec(CodecError::Invalid {
                what: "rng seed",
                problem: "not 32 bytes".into(),
            })
        })?;
        let mut rng = ChaCha8Rng::from_seed(rng_seed);
        rng.set_stream(r.u64("rng stream").map_err(codec)?);
        rng.set_word_pos(r.u128("rng position").map_err(codec)?);
        trainer.rng = rng;
        trainer.env_steps = r.u64("environment steps").map_err(codec)?;
        trainer.episodes = r.u64("episodes").map_err(codec)?;
        if let Err((name, found, expected)) = trainer.agent.read_into(&mut r).map_err(codec)? {
            return Err(arch(name, found.to_string(), expected.to_string()));
        }
        trainer.replay.read_into(&mut r).map_err(codec)?;
        r.finish().map_err(codec)?;
        Ok(trainer)
    }
}

/// Names of the config fields whose values differ.
fn config_differences(a: &SacConfig, b: &SacConfig) -> Vec<String> {
    let ta = toml::Table::try_from(a).expect("SacConfig serialises");
    let tb = toml::Table::try_from(b).expect("SacConfig serialises");
    let mut keys: Vec<&String> = ta.keys().chain(tb.keys()).collect();
    keys.sort();
    keys.dedup();
    keys.into_iter()
        .filter(|k| ta.get(*k) != tb.get(*k))
        .cloned()
        .collect()
}
