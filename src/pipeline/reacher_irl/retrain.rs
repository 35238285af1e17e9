//! Re-optimising a learned reward (`reacher retrain`): a fresh SAC agent trained on a finished
//! job's final learned reward, held fixed, and judged on the ground truth as the jobs are.
//!
//! Why: an IRL job's metrics judge the policy that learned *along with* a moving reward. When
//! that policy fails, the reward may be wrong, or right with the policy lagging behind it. A
//! policy trained from scratch on the final reward, which no longer moves, tells the two
//! apart — it is what "the learned reward solves the task" means. The SAC settings, the
//! environment (the product with the learned machine for SMIRL, with counterfactual states as
//! configured) and the evaluation episodes are the job's own; only SAC's seed is new.

use super::config::{IrlConfigError, IrlRunConfig};
use super::episodes::JobEnv;
use super::evaluation::{Evaluation, GroundTruth};
use super::final_policy::{learned_return, ScoredReward};
use super::firl::{self, StateReward};
use super::iteration::StepError;
use super::run::{MissingMachine, PreparedRun};
use super::smirl::{counterfactual_states, product_env, Features, ProductReward};
use super::Algo;
use crate::env::reacher::ReacherDelivery;
use crate::irl::reward::RewardOptimConfig;
use crate::irl::reward::{MlpReward, RewardError};
use crate::irl::smirl::LinearRmReward;
use crate::rl::sac::{
    ConfigError as SacConfigError, SacConfig, SacTrainer, StepOutcome, UpdateStats,
};
use std::path::{Path, PathBuf};

/// Most SAC steps of one retraining.
pub const MAX_RETRAIN_STEPS: u64 = 100_000_000;

/// One retraining: which job's reward, how long, with which SAC seed.
#[derive(Clone, Debug)]
pub struct Retraining {
    pub algo: Algo,
    /// The job's seed (its reward file is `rewards/<algo>_seed<seed>.*`).
    pub seed: u64,
    /// SAC environment steps; `None`: the job's own (IRL iterations × SAC steps per iteration).
    pub steps: Option<u64>,
    /// Seed of the fresh SAC agent.
    pub sac_seed: u64,
    /// Ground-truth evaluations during training (the last at the end).
    pub evaluations: u64,
    /// Learned-machine states whose weights are set to zero before training (`smirl` and
    /// `smirl-smooth` only): whether those states' rewards are what misleads the agent.
    pub zero_states: Vec<usize>,
    /// Settings of the agent other than the job's (`--agent FILE`): whether the reward is
    /// optimised better another way.
    pub agent: Option<AgentSettings>,
}

/// How a retraining's agent optimises, in place of the job's (`reacher retrain --agent FILE`):
/// a `[sac]` table (any of its keys). Nothing that defines the reward,
/// the machine or the environment the agent is judged in can be changed, so the table still
/// answers "does this reward solve the task" — with another optimiser.
#[derive(Clone, Debug)]
pub struct AgentSettings {
    /// The file's stem, which names the retraining's table (`..._sac<K>_<name>.csv`).
    pub name: String,
    source: String,
    text: String,
    keys: AgentKeys,
}

#[derive(Clone, Debug, serde::Deserialize)]
#[serde(deny_unknown_fields)]
struct AgentKeys {
    sac: Option<toml::Table>,
}

/// Longest name of an agent settings file (its stem).
pub const MAX_AGENT_NAME: usize = 64;

impl AgentSettings {
    /// Reads and parses an agent settings file: an unknown key or a wrong type is an error
    /// naming its line, and the stem must be a plain name (letters, digits, `-`, `_`).
    pub fn load(path: &Path) -> Result<AgentSettings, RetrainError> {
        let source = path.display().to_string();
        let name = path
            .file_stem()
            .and_then(|s| s.to_str())
            .unwrap_or_default()
            .to_string();
        let plain = |c: char| c.is_ascii_alphanumeric() || c == '-' || c == '_';
        if name.is_empty() || name.len() > MAX_AGENT_NAME || !name.chars().all(plain) {
            return Err(RetrainError::AgentName { path: path.into() });
        }
        let text =
            crate::config_text::read_text_file(path).map_err(|source| RetrainError::ReadAgent {
                path: path.into(),
                source,
            })?;
        let keys: AgentKeys = toml::from_str(&text).map_err(|e| RetrainError::ParseAgent {
            path: path.into(),
            message: crate::config_text::toml_error_message(&text, &e),
        })?;
        Ok(AgentSettings {
            name,
            source,
            text,
            keys,
        })
    }

    /// `s` with these settings in place of its own, checked as a run's config is.
    fn apply(&self, mut s: IrlRunConfig) -> Result<IrlRunConfig, RetrainError> {
        if let Some(table) = &self.keys.sac {
            s.sac = SacConfig::from_table(table.clone(), s.sac.clone(), &self.source)
                .map_err(RetrainError::AgentSac)?;
        }
        s.validate(&self.source)
            .map_err(|e| RetrainError::Config(e.at_key_line(&self.text)))?;
        Ok(s)
    }
}

/// One evaluation of the retrained policy.
#[derive(Clone, Copy, Debug)]
pub struct RetrainPoint {
    pub env_steps: u64,
    /// On the ground truth, as the jobs are judged.
    pub evaluation: Evaluation,
    /// The mean learned return of the mean-action policy over the evaluation's reset seeds,
    /// each episode played to the time limit: how well the agent optimises the reward it was
    /// given, known without the ground truth (so a choice among agents may use it).
    pub learned_return: f64,
    /// SAC's own state over the segment before this evaluation: whether a collapse shows in
    /// the critics, the temperature or the policy's entropy before it shows in the task.
    pub agent: SegmentStats,
}

/// Means over one training segment's gradient updates (zeros when it had none).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SegmentStats {
    /// The temperature α at the segment's last update.
    pub alpha: f64,
    /// The policy's entropy estimate, −mean log π of the batches' fresh actions.
    pub entropy: f64,
    /// The first critic's loss, ½ mean (Q − y)².
    pub critic_loss: f64,
    /// The critics' value of the policy's actions, min(Q1, Q2) averaged over the batches
    /// (read off the actor's loss, α log π − min Q).
    pub policy_value: f64,
}

/// Running sums of a segment's updates (a segment may be millions of steps long).
#[derive(Default)]
struct SegmentSums {
    updates: u64,
    last_alpha: f32,
    entropy: f64,
    critic_loss: f64,
    policy_value: f64,
}

impl SegmentSums {
    fn add(&mut self, u: &UpdateStats) {
        self.updates += 1;
        self.last_alpha = u.alpha;
        self.entropy -= f64::from(u.mean_log_prob);
        self.critic_loss += f64::from(u.q1_loss);
        self.policy_value += f64::from(u.alpha * u.mean_log_prob - u.actor_loss);
    }

    fn means(&self) -> SegmentStats {
        if self.updates == 0 {
            return SegmentStats::default();
        }
        let n = self.updates as f64;
        SegmentStats {
            alpha: f64::from(self.last_alpha),
            entropy: self.entropy / n,
            critic_loss: self.critic_loss / n,
            policy_value: self.policy_value / n,
        }
    }
}

/// The reward file of a job.
pub fn reward_path(dir: &Path, algo: Algo, seed: u64) -> PathBuf {
    let ext = if algo.uses_rm() { "json" } else { "bin" };
    dir.join("rewards")
        .join(format!("{}_seed{seed}.{ext}", algo.name()))
}

/// Why a retraining cannot run: bad input, found before any training.
#[derive(Debug, thiserror::Error)]
pub enum RetrainError {
    #[error(
        "{}: the file's stem names the table: it must be 1 to {MAX_AGENT_NAME} letters, digits, '-' or '_'",
        path.display()
    )]
    AgentName { path: PathBuf },
    #[error("{}: {source}", path.display())]
    ReadAgent {
        path: PathBuf,
        source: std::io::Error,
    },
    /// An agent settings file that is not TOML of its keys: the message names the line.
    #[error("{}: {message}", path.display())]
    ParseAgent { path: PathBuf, message: String },
    /// An agent settings file's `[sac]` table.
    #[error(transparent)]
    AgentSac(SacConfigError),
    /// The settings retrained with (the job's algorithm's, under an agent settings file).
    #[error(transparent)]
    Config(IrlConfigError),
    #[error(
        "{algo}: retrain reads a SMIRL or baseline reward; a product control's agent acts on \
         the product, which retrain does not build"
    )]
    ProductControl { algo: Algo },
    #[error("{algo} is not a ReacherDelivery algorithm")]
    NotReacher { algo: Algo },
    #[error("--steps must be in 1..={max}, got {steps}")]
    Steps { steps: u64, max: u64 },
    #[error("--evaluations must be in 1..={steps} (the steps), got {evaluations}")]
    Evaluations { evaluations: u64, steps: u64 },
    #[error("{}: no learned reward (has job {algo} seed {seed} finished?)", path.display())]
    NoReward {
        path: PathBuf,
        algo: Algo,
        seed: u64,
    },
    /// The job's reward file or the reward it is read into.
    #[error(transparent)]
    Reward(RewardError),
    #[error(
        "{}: not a {algo} reward of this run's {states}-state machine",
        path.display()
    )]
    ForeignReward {
        path: PathBuf,
        algo: Algo,
        states: usize,
    },
    #[error("--zero-state {state}: {source}")]
    ZeroState { state: usize, source: RewardError },
    #[error(
        "--zero-state needs a reward per learned-machine state (smirl, smirl-paper, smirl-smooth), not {algo}"
    )]
    ZeroStateNeedsMachine { algo: Algo },
    /// The run's files lack what the retraining reads.
    #[error(transparent)]
    Input(#[from] MissingMachine),
    #[error("the run has no learned machine")]
    NoMachine,
    #[error(transparent)]
    Step(#[from] StepError),
}

/// A job's final reward, loaded and checked against its run: everything a retraining needs
/// before it trains.
pub struct LoadedReward<'a> {
    run: &'a PreparedRun,
    settings: IrlRunConfig,
    request: Retraining,
    steps: u64,
    reward: Reward,
}

enum Reward {
    /// SMIRL's δ_r(u, o) = w_uᵀ φ(o) on the run's learned machine.
    Linear(LinearRmReward),
    /// A baseline's reward net on the fingertip.
    Mlp(MlpReward),
}

/// Step 1 (no training, nothing written): checks the request and loads the job's reward. Every
/// error here is bad input.
pub fn load<'a>(run: &'a PreparedRun, r: &Retraining) -> Result<LoadedReward<'a>, RetrainError> {
    if r.algo.is_product_control() {
        return Err(RetrainError::ProductControl { algo: r.algo });
    }
    if !Algo::REACHER.contains(&r.algo) {
        return Err(RetrainError::NotReacher { algo: r.algo });
    }
    let mut s = run.config.for_algo(r.algo).map_err(RetrainError::Config)?;
    if let Some(agent) = &r.agent {
        s = agent.apply(s)?;
    }
    let steps = r
        .steps
        .unwrap_or(s.sac_steps_per_iteration * s.irl_iterations as u64);
    if steps == 0 || steps > MAX_RETRAIN_STEPS {
        return Err(RetrainError::Steps {
            steps,
            max: MAX_RETRAIN_STEPS,
        });
    }
    if r.evaluations == 0 || r.evaluations > steps {
        return Err(RetrainError::Evaluations {
            evaluations: r.evaluations,
            steps,
        });
    }
    let path = reward_path(&run.dir, r.algo, r.seed);
    if !path.is_file() {
        return Err(RetrainError::NoReward {
            path,
            algo: r.algo,
            seed: r.seed,
        });
    }
    let reward = if r.algo.uses_rm() {
        let (machine, _) = run.inputs_of(r.algo)?;
        let machine = machine.ok_or(RetrainError::NoMachine)?;
        let features = if r.algo == Algo::SmirlSmooth {
            Features::Smooth
        } else {
            Features::Labels
        };
        let optim = RewardOptimConfig {
            adam: true,
            lr: s.smirl_reward_lr,
            l2: s.smirl_reward_l2,
        };
        let mut reward = LinearRmReward::load(&path, optim).map_err(RetrainError::Reward)?;
        let expected = features.map(&s).map_err(RetrainError::Reward)?;
        if reward.features() != &expected || reward.n_states() != machine.n_states() {
            return Err(RetrainError::ForeignReward {
                path,
                algo: r.algo,
                states: machine.n_states(),
            });
        }
        for &u in &r.zero_states {
            reward
                .zero_state(u)
                .map_err(|source| RetrainError::ZeroState { state: u, source })?;
        }
        Reward::Linear(reward)
    } else {
        if !r.zero_states.is_empty() {
            return Err(RetrainError::ZeroStateNeedsMachine { algo: r.algo });
        }
        let mut reward =
            firl::reward_model(&s, 0, firl::StateMap::Fingertip).map_err(RetrainError::Reward)?;
        reward.load(&path).map_err(RetrainError::Reward)?;
        Reward::Mlp(reward)
    };
    Ok(LoadedReward {
        run,
        settings: s,
        request: r.clone(),
        steps,
        reward,
    })
}

/// Step 2: trains a fresh SAC agent on the loaded reward; `on_point` sees every evaluation.
pub fn retrain(
    loaded: LoadedReward<'_>,
    mut on_point: impl FnMut(&RetrainPoint),
) -> Result<Vec<RetrainPoint>, RetrainError> {
    let LoadedReward {
        run,
        settings: s,
        request: r,
        steps,
        reward,
    } = loaded;
    let mut schedule = ReacherDelivery::new(s.env.clone()).map_err(StepError::from)?;
    let judge = GroundTruth::new(&run.perfect, &mut schedule, r.seed, s.eval_episodes);
    let inner = ReacherDelivery::new(s.env.clone()).map_err(StepError::from)?;
    let training = Training {
        sac: &s.sac,
        sac_seed: r.sac_seed,
        segments: Segments::new(steps, r.evaluations),
        judge: &judge,
    };
    match reward {
        Reward::Linear(mut reward) => {
            let machine = run
                .inputs_of(r.algo)
                .map_err(RetrainError::Input)?
                .0
                .ok_or(RetrainError::NoMachine)?;
            let mut env = product_env(inner, machine);
            let counterfactual = counterfactual_states(&env, &s).map_err(StepError::from)?;
            let mut sac_reward = ProductReward::new(&mut reward, counterfactual.as_ref());
            training.run(&mut env, &mut sac_reward, &mut on_point)
        }
        Reward::Mlp(mut reward) => {
            let mut env = inner;
            let mut sac_reward = StateReward::new(&mut reward);
            training.run(&mut env, &mut sac_reward, &mut on_point)
        }
    }
}

/// `steps` split into `evaluations` nearly equal training segments.
struct Segments {
    steps: u64,
    evaluations: u64,
}

impl Segments {
    fn new(steps: u64, evaluations: u64) -> Segments {
        Segments { steps, evaluations }
    }

    /// Environment steps at the end of segment `k` (1-based).
    fn end(&self, k: u64) -> u64 {
        self.steps * k / self.evaluations
    }
}

/// A fresh agent's training and its judging, whatever the environment and reward.
struct Training<'a> {
    sac: &'a SacConfig,
    sac_seed: u64,
    segments: Segments,
    judge: &'a GroundTruth<'a>,
}

impl Training<'_> {
    fn run<E: JobEnv, R: ScoredReward>(
        &self,
        env: &mut E,
        reward: &mut R,
        on_point: &mut impl FnMut(&RetrainPoint),
    ) -> Result<Vec<RetrainPoint>, RetrainError> {
        let mut sac = SacTrainer::new(self.sac, env.obs_dim(), env.act_dim(), self.sac_seed)
            .map_err(StepError::from)?;
        let mut points = Vec::new();
        for k in 1..=self.segments.evaluations {
            let mut sums = SegmentSums::default();
            let mut keep = |o: &StepOutcome| {
                if let Some(u) = &o.update {
                    sums.add(u);
                }
            };
            let n = self.segments.end(k).saturating_sub(sac.env_steps());
            sac.train_observed(env, reward, n, None, &mut keep)
                .map_err(StepError::Sac)?;
            // Evaluation resets the environment: finish SAC's episode first.
            sac.finish_episode_observed(env, reward, None, &mut keep)
                .map_err(StepError::Sac)?;
            let point = RetrainPoint {
                env_steps: sac.env_steps(),
                evaluation: self.judge.evaluate(&mut sac.agent, env, None)?,
                learned_return: learned_return(
                    &mut sac.agent,
                    env,
                    reward,
                    self.judge.task(),
                    self.judge.reset_seeds(),
                    None,
                )?,
                agent: sums.means(),
            };
            on_point(&point);
            points.push(point);
        }
        Ok(points)
    }
}
