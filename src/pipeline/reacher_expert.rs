//! ReacherDelivery experts: SAC policies trained on a task's product environment
//! (observation ⊕ one-hot state of the task's *perfect* reward machine, sub-goal shaping),
//! stored as small actor-only policy files, and the demonstrations they produce.
//!
//! - [`ExpertPolicy`]: the actor network and its observation layout; [`ExpertPolicy::save`] /
//!   [`ExpertPolicy::load`] read and write a versioned file holding only the actor (no
//!   critics, no replay buffer), refusing another task, architecture or format version.
//! - [`ExpertConfig`] (`config.rs`): the config file of an expert run.
//! - [`train_task_expert`]: [`train_expert`] on `task_env(task, …)` with checkpoints and
//!   resume, success judged by the perfect machine reaching its goal.
//! - [`evaluate_expert`]: success rate and task return of an expert policy over episodes on
//!   its task, stochastic or mean action.
//! - [`committed_expert`]: the committed expert of a task, built into the binary.
//! - [`generate_demos`]: trajectories of the expert's stochastic policy (paper appendix C:
//!   "16 trajectories collected from the expert stochastic policy"), optionally logged to
//!   MCAP.
//!
//! Demonstrations carry the perfect machine's state for *evaluation only*: SMIRL must learn its
//! own machine from the label traces and must not read [`DemoStep::rm_state`].

mod config;

pub use config::{expert_sac, ExpertConfig, MAX_EVAL_EPISODES, MAX_TOTAL_STEPS};

use super::expert::{train_expert, CurvePoint, ExpertOutcome, ExpertProgress, TrainingError};
use crate::atomic_file::write_atomic;
use crate::env::product::{Potential, ProductEnv};
use crate::env::reacher::{ReacherConfig, ReacherDelivery, ACT_DIM};
use crate::env::reacher_task::{
    task_env, Branch, BranchTally, EventBranch, ReacherTask, SubgoalPotential,
};
use crate::env::{episode, ContinuousEnv, EnvError, EnvStep};
use crate::log::{LogError, RolloutLogger, RunHeader};
use crate::nn::codec::{read_file, save_file, ByteReader, ByteWriter, CodecError, FileError};
use crate::nn::{Mlp, MlpArch};
use crate::pipeline::training_log::{ReacherView, TrainingLog};
use crate::rl::sac::{
    episode_seed, ActMode, ActWorkspace, EpisodeSummary, SacError, TrainingObserver,
};
use crate::rm::LabelSet;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};
use std::cell::Cell;
use std::path::{Path, PathBuf};
use std::rc::Rc;

/// Demonstrations per task in the paper (appendix C).
pub const PAPER_DEMOS: usize = 16;

const POLICY_MAGIC: &[u8; 8] = b"SMIRLPOL";
/// Format version of policy files; a file of another version is refused.
pub const POLICY_VERSION: u32 = 1;

/// A policy file that cannot be written or used.
#[derive(Debug, thiserror::Error)]
pub enum PolicyFileError {
    #[error(transparent)]
    File(#[from] FileError),
    #[error("{path}: expert policy is for task '{found}', not '{expected}'")]
    WrongTask {
        path: String,
        found: String,
        expected: String,
    },
    #[error("{path}: expert policy has a different architecture: {what} is {found} in the file, {expected} here")]
    Architecture {
        path: String,
        what: &'static str,
        found: String,
        expected: String,
    },
    #[error("task '{task}': {problem}")]
    Task { task: String, problem: String },
}

/// Where an expert came from (stored in the policy file as JSON).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PolicyInfo {
    /// Seed of the training run.
    pub seed: u64,
    /// Environment steps it was trained for.
    pub env_steps: u64,
    /// Shaping scale of the training environment.
    pub shaping_scale: f64,
    /// The environment it was trained on.
    pub env: ReacherConfig,
    /// Commit of the code that trained it.
    pub git_commit: String,
}

/// Why training, evaluating or saving a task expert, or recording its demonstrations, failed.
#[derive(Debug, thiserror::Error)]
pub enum ExpertError {
    #[error(transparent)]
    Training(#[from] TrainingError),
    #[error(transparent)]
    Sac(#[from] SacError),
    #[error(transparent)]
    Policy(#[from] PolicyFileError),
    #[error("task '{task}': {problem}")]
    Task { task: String, problem: String },
    #[error(transparent)]
    Log(Box<LogError>),
    /// A summary or plot that cannot be written.
    #[error("{path}: {problem}")]
    Write { path: String, problem: String },
}

/// Observation size of `task`'s product environment: the task's observation + number of
/// machine states.
fn product_obs_dim(task: ReacherTask) -> Result<usize, PolicyFileError> {
    task.perfect_rm()
        .map(|rm| task.layout().obs_dim() + rm.n_states())
        .map_err(|e| PolicyFileError::Task {
            task: task.name().into(),
            problem: e.to_string(),
        })
}

/// A trained expert: the SAC actor acting on the product observation of the task's
/// perfect-machine environment, `[inner observation | one-hot machine state]`.
#[derive(Clone, Debug)]
pub struct ExpertPolicy {
    task: ReacherTask,
    actor: Mlp,
    info: PolicyInfo,
    act_ws: ActWorkspace,
}

impl ExpertPolicy {
    /// Wraps a trained actor (head: mean and log-std per action) for `task`; the actor's input
    /// must be the task's product observation.
    pub fn new(task: ReacherTask, actor: Mlp, info: PolicyInfo) -> Result<Self, PolicyFileError> {
        let obs_dim = product_obs_dim(task.clone())?;
        let arch = actor.arch();
        let expected = MlpArch::new(obs_dim, &hidden_of(&arch), 2 * ACT_DIM);
        if arch != expected {
            return Err(PolicyFileError::Architecture {
                path: "(in memory)".into(),
                what: "actor",
                found: arch.to_string(),
                expected: expected.to_string(),
            });
        }
        let act_ws = ActWorkspace::new(&actor);
        Ok(Self {
            task,
            actor,
            info,
            act_ws,
        })
    }

    pub fn task(&self) -> ReacherTask {
        self.task.clone()
    }
    /// Product observation size (17 + machine states).
    pub fn obs_dim(&self) -> usize {
        self.actor.inputs()
    }
    pub fn act_dim(&self) -> usize {
        ACT_DIM
    }
    /// Hidden layer widths of the actor.
    pub fn hidden(&self) -> Vec<usize> {
        hidden_of(&self.actor.arch())
    }
    pub fn info(&self) -> &PolicyInfo {
        &self.info
    }
    pub fn actor(&self) -> &Mlp {
        &self.actor
    }

    /// Chooses an action for one product observation, exactly as the SAC agent that trained
    /// it would (same noise draws from `rng` in [`ActMode::Sample`]).
    pub fn act(&mut self, obs: &[f32], mode: ActMode, rng: &mut impl Rng, action: &mut [f32]) {
        self.act_ws.act(&self.actor, obs, mode, rng, action);
    }

    /// Writes the policy file (magic, version, task, info, actor) atomically.
    pub fn save(&self, path: &Path) -> Result<(), PolicyFileError> {
        let mut w = ByteWriter::new();
        w.raw(POLICY_MAGIC);
        w.u32(POLICY_VERSION);
        w.str(self.task.name());
        w.str(&serde_json::to_string(&self.info).expect("PolicyInfo serialises"));
        self.actor.write(&mut w);
        Ok(save_file(path, &w.bytes)?)
    }

    /// Reads a policy file for `task` whose actor has the hidden layers `hidden`. A file of
    /// another task, architecture or format version, or a truncated one, is refused with a
    /// message naming the file and the difference.
    pub fn load(
        path: &Path,
        task: ReacherTask,
        hidden: &[usize],
    ) -> Result<ExpertPolicy, PolicyFileError> {
        let bytes = read_file(path)?;
        ExpertPolicy::from_bytes(&bytes, &path.display().to_string(), task, hidden)
    }

    /// Reads the bytes of a policy file; `source_name` names it in errors.
    pub fn from_bytes(
        bytes: &[u8],
        source_name: &str,
        task: ReacherTask,
        hidden: &[usize],
    ) -> Result<ExpertPolicy, PolicyFileError> {
        let p = source_name.to_string();
        let codec = FileError::codec_at(&p);
        let mut r = ByteReader::new(bytes);
        r.header(POLICY_MAGIC, "smirl expert policy", POLICY_VERSION)
            .map_err(codec)?;
        let file_task = r.string("task").map_err(codec)?;
        if file_task != task.name() {
            return Err(PolicyFileError::WrongTask {
                path: p,
                found: file_task,
                expected: task.name().into(),
            });
        }
        let info_text = r.string("policy info").map_err(codec)?;
        let info: PolicyInfo = serde_json::from_str(&info_text).map_err(|e| {
            codec(CodecError::Invalid {
                what: "policy info",
                problem: e.to_string(),
            })
        })?;
        let expected = MlpArch::new(product_obs_dim(task.clone())?, hidden, 2 * ACT_DIM);
        let mut actor = Mlp::new(&expected, &mut ChaCha8Rng::seed_from_u64(0));
        if let Err(found) = actor.read_into(&mut r).map_err(codec)? {
            return Err(PolicyFileError::Architecture {
                path: p,
                what: "actor",
                found: found.to_string(),
                expected: expected.to_string(),
            });
        }
        r.finish().map_err(codec)?;
        if !actor.params_finite() {
            return Err(codec(CodecError::Invalid {
                what: "actor parameters",
                problem: "contain NaN or infinity".into(),
            })
            .into());
        }
        ExpertPolicy::new(task, actor, info)
    }
}

/// Hidden widths of an architecture (all layer widths but input and output).
fn hidden_of(arch: &MlpArch) -> Vec<usize> {
    arch.sizes[1..arch.sizes.len() - 1].to_vec()
}

/// The committed expert of a shipped task, built into the binary
/// (`experiments/experts/cache`); a task file has none (it is never given the expert of a
/// shipped task of the same name).
pub fn committed_expert(
    task: ReacherTask,
    hidden: &[usize],
) -> Result<ExpertPolicy, PolicyFileError> {
    let name = format!("experiments/experts/cache/expert_{task}.policy (built in)");
    let bytes = if task.is_shipped() {
        crate::assets::expert_policy(task.name()).unwrap_or_default()
    } else {
        &[]
    };
    ExpertPolicy::from_bytes(bytes, &name, task, hidden)
}

/// The cached policy file of `task`'s expert in `cache_dir`: `expert_<name>.policy` for a
/// shipped task, `expert_<name>-<content hash>.policy` for a task file, so that a changed
/// task file, scene or machine never finds the expert of its former content.
pub fn expert_cache_path(cache_dir: &Path, task: ReacherTask) -> PathBuf {
    if task.is_shipped() {
        cache_dir.join(format!("expert_{}.policy", task.name()))
    } else {
        let hash = &task.task().content_hash[..16];
        cache_dir.join(format!("expert_{}-{hash}.policy", task.name()))
    }
}

/// Where the experts of a task file are cached by default: `experts/` beside the task file
/// (`None` for a shipped task, whose experts are committed).
pub fn default_expert_cache(task: &ReacherTask) -> Option<PathBuf> {
    (!task.is_shipped()).then(|| {
        Path::new(&task.task().source)
            .parent()
            .unwrap_or(Path::new(""))
            .join("experts")
    })
}

/// The product environment with a shared flag telling whether its last episode reached the
/// machine's goal (the training loop only sees [`EpisodeSummary`]s, whose shaped rewards
/// cannot tell success from failure).
struct SuccessFlag {
    env: ProductEnv<ReacherDelivery, SubgoalPotential>,
    success: Rc<Cell<bool>>,
}

impl ReacherView for SuccessFlag {
    fn reacher(&self) -> &ReacherDelivery {
        self.env.inner()
    }
    fn inner_step(&self, seen: &EnvStep) -> EnvStep {
        self.env.inner_step(seen)
    }
}

impl ContinuousEnv for SuccessFlag {
    fn obs_dim(&self) -> usize {
        self.env.obs_dim()
    }
    fn act_dim(&self) -> usize {
        self.env.act_dim()
    }
    fn reset(&mut self, seed: u64, obs: &mut [f32]) {
        self.success.set(false);
        self.env.reset(seed, obs);
    }
    fn step(&mut self, action: &[f32], obs: &mut [f32]) -> Result<EnvStep, EnvError> {
        let s = self.env.step_product(action, obs)?;
        self.success.set(s.success);
        Ok(s.step)
    }
}

fn product_env(
    task: ReacherTask,
    env: &ReacherConfig,
    shaping_scale: f64,
    gamma: f64,
) -> Result<ProductEnv<ReacherDelivery, SubgoalPotential>, ExpertError> {
    task_env(task.clone(), env.clone(), shaping_scale, gamma).map_err(|e| ExpertError::Task {
        task: task.name().into(),
        problem: e.to_string(),
    })
}

/// Trains (or with `resume`, continues from `checkpoint`) the SAC expert of `task` on its
/// product environment with `config.shaping_scale` sub-goal shaping, and returns the trained
/// actor as a policy with the run's outcome (curve, mean-action evaluation). With a `logger`
/// (see [`train_log_header`]), every training episode is logged (phase `"train"`, with the
/// task machine's state and reward).
pub fn train_task_expert(
    task: ReacherTask,
    config: &ExpertConfig,
    seed: u64,
    checkpoint: &Path,
    resume: bool,
    progress: impl FnMut(&ExpertProgress),
    logger: Option<&mut RolloutLogger>,
) -> Result<(ExpertPolicy, ExpertOutcome), ExpertError> {
    let success = Rc::new(Cell::new(false));
    let mut env = SuccessFlag {
        env: product_env(
            task.clone(),
            &config.env,
            config.shaping_scale,
            config.sac.gamma as f64,
        )?,
        success: success.clone(),
    };
    let task_rm = env.env.rm().clone();
    let mut train_log = logger.map(|l| TrainingLog::new(l, &task_rm, "train"));
    let outcome = train_expert(
        &mut env,
        &config.training_plan(),
        seed,
        checkpoint,
        resume,
        |_: &EpisodeSummary| success.get(),
        progress,
        train_log
            .as_mut()
            .map(|t| t as &mut dyn TrainingObserver<SuccessFlag>),
    )?;
    let info = PolicyInfo {
        seed,
        env_steps: outcome.trainer.env_steps(),
        shaping_scale: config.shaping_scale,
        env: config.env.clone(),
        git_commit: crate::GIT_COMMIT.to_string(),
    };
    let policy = ExpertPolicy::new(task.clone(), outcome.trainer.agent.actor.clone(), info)?;
    Ok((policy, outcome))
}

/// Success rate and returns of a policy over evaluation episodes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EvalSummary {
    pub episodes: u64,
    pub successes: u64,
    pub success_rate: f64,
    /// Mean return of the task's (unshaped) machine reward.
    pub mean_task_return: f64,
    /// Mean return of the environment's own reward.
    pub mean_env_return: f64,
    pub mean_length: f64,
    /// Episodes in which the cancel event fired, and how many of them succeeded.
    pub cancel_episodes: u64,
    pub cancel_successes: u64,
    /// Conditional tasks (IF, Composite): episodes and successes per branch.
    pub branches: Option<BranchTally>,
}

/// Episodes and successes per branch of `demos` (`None` for a task without branches).
pub fn branch_tally(task: ReacherTask, demos: &[Demo]) -> Result<Option<BranchTally>, ExpertError> {
    let rm = task.perfect_rm().map_err(|e| ExpertError::Task {
        task: task.name().into(),
        problem: e.to_string(),
    })?;
    Ok(
        EventBranch::of(&rm, task.layout().events()).map(|branches| {
            let mut tally = BranchTally::default();
            for d in demos {
                tally.add(d.branch(&branches), d.success);
            }
            tally
        }),
    )
}

/// Plays `episodes` episodes of `policy` on its task (no shaping), resets seeded by
/// [`episode_seed`]`(seed, i)` and action noise from `seed`; success = the perfect machine
/// reached its goal.
pub fn evaluate_expert(
    policy: &mut ExpertPolicy,
    env_config: &ReacherConfig,
    episodes: u64,
    mode: ActMode,
    seed: u64,
) -> Result<EvalSummary, ExpertError> {
    let resets: Vec<u64> = (0..episodes).map(|i| episode_seed(seed, i)).collect();
    let demos = run_episodes(policy, env_config, &resets, mode, seed, None)?;
    let n = demos.len().max(1) as f64;
    let events = policy.task().layout().events();
    let successes = demos.iter().filter(|d| d.success).count() as u64;
    Ok(EvalSummary {
        episodes,
        successes,
        success_rate: successes as f64 / n,
        mean_task_return: demos.iter().map(|d| d.task_return).sum::<f64>() / n,
        mean_env_return: demos.iter().map(|d| d.env_return).sum::<f64>() / n,
        mean_length: demos.iter().map(|d| d.steps.len() as f64).sum::<f64>() / n,
        cancel_episodes: demos.iter().filter(|d| d.has_event(events)).count() as u64,
        cancel_successes: (demos.iter())
            .filter(|d| d.has_event(events) && d.success)
            .count() as u64,
        branches: branch_tally(policy.task(), &demos)?,
    })
}

/// One step of a demonstration.
#[derive(Clone, Debug, PartialEq)]
pub struct DemoStep {
    /// Inner (ReacherDelivery) observation the action was taken in.
    pub obs: Vec<f32>,
    pub action: [f32; ACT_DIM],
    /// Inner observation after the step.
    pub next_obs: Vec<f32>,
    /// Labels after the step, `L(next_obs)`.
    pub labels: LabelSet,
    /// State of the task's *perfect* machine after the step. For evaluation only: SMIRL must
    /// not use it.
    pub rm_state: usize,
    /// The environment's own reward.
    pub env_reward: f64,
    /// The perfect machine's reward for the step.
    pub task_reward: f64,
}

/// One demonstration episode.
#[derive(Clone, Debug, PartialEq)]
pub struct Demo {
    /// Reset seed of the episode.
    pub seed: u64,
    /// Perfect machine state before the first step (its initial state).
    pub initial_rm_state: usize,
    /// Labels of the initial observation.
    pub initial_labels: LabelSet,
    pub steps: Vec<DemoStep>,
    /// The perfect machine reached its goal.
    pub success: bool,
    /// Sum of the machine's rewards.
    pub task_return: f64,
    /// Sum of the environment's rewards.
    pub env_return: f64,
}

impl Demo {
    /// The label trace (one label set per step).
    pub fn labels(&self) -> Vec<LabelSet> {
        self.steps.iter().map(|s| s.labels).collect()
    }

    /// One of `events` (the task's event labels) fired during the episode.
    pub fn has_event(&self, events: LabelSet) -> bool {
        self.steps.iter().any(|s| s.labels.0 & events.0 != 0)
    }

    /// The branch the episode took, from the perfect machine's states along it.
    pub fn branch(&self, branches: &EventBranch) -> Branch {
        branches.of_states(
            std::iter::once(self.initial_rm_state).chain(self.steps.iter().map(|s| s.rm_state)),
        )
    }
}

/// Seed of the action noise of a demonstration/evaluation run, apart from its reset seeds.
fn noise_seed(seed: u64) -> u64 {
    seed ^ 0xac71_0e5e_ed00_0000
}

/// Why recording an episode stopped.
#[derive(Debug, thiserror::Error)]
pub enum RecordError {
    #[error("environment step {step}: {source}")]
    Env { step: u64, source: EnvError },
    #[error(transparent)]
    Log(#[from] LogError),
}

/// Plays one episode of `policy` on the product of ReacherDelivery with the task's perfect
/// machine and records it as a [`Demo`] (and, with a `logger`, logs it under `phase`). The
/// policy sees the product observation (inner observation ⊕ one-hot machine state), the labels
/// of the last step (of the reset state at first) and the machine state. Ends when the machine
/// reaches its goal or failure sink, or at the time limit. The one episode recorder behind
/// expert demonstrations, expert evaluation and scripted demonstrations.
pub fn record_episode<P: Potential>(
    env: &mut ProductEnv<ReacherDelivery, P>,
    reset_seed: u64,
    phase: &str,
    mut logger: Option<&mut RolloutLogger>,
    mut policy: impl FnMut(&[f32], LabelSet, usize) -> [f32; ACT_DIM],
) -> Result<Demo, RecordError> {
    let (demo, logger) = episode::play(
        env,
        reset_seed,
        // The time limit (`truncated`) ends the episode.
        u64::MAX,
        |env, _| {
            let demo = Demo {
                seed: reset_seed,
                initial_rm_state: env.rm_state(),
                initial_labels: env.inner().labels(),
                steps: Vec::new(),
                success: false,
                task_return: 0.0,
                env_return: 0.0,
            };
            if let Some(l) = logger.as_deref_mut() {
                l.begin_reacher_episode(
                    env.inner(),
                    reset_seed,
                    phase,
                    Some(env.rm_state()),
                    env.inner_obs(),
                )?;
            }
            Ok::<_, RecordError>((demo, logger))
        },
        // The inner environment's labels are those of its last step (of the reset state at
        // first).
        |env, obs, action| {
            action.copy_from_slice(&policy(obs, env.inner().labels(), env.rm_state()))
        },
        |(demo, logger), env, step| {
            let before = env.inner_obs().to_vec();
            let s = env
                .step_product(step.action, step.next_obs)
                .map_err(|source| RecordError::Env {
                    step: step.t,
                    source,
                })?;
            if let Some(l) = logger.as_deref_mut() {
                let inner_step = EnvStep {
                    reward: s.env_reward,
                    ..s.step
                };
                l.reacher_step(
                    env.inner(),
                    step.action,
                    &inner_step,
                    Some((s.rm_state, s.task_reward)),
                    env.inner_obs(),
                )?;
            }
            let mut action = [0.0f32; ACT_DIM];
            action.copy_from_slice(step.action);
            demo.steps.push(DemoStep {
                obs: before,
                action,
                next_obs: env.inner_obs().to_vec(),
                labels: s.step.labels,
                rm_state: s.rm_state,
                env_reward: s.env_reward,
                task_reward: s.task_reward,
            });
            demo.task_return += s.task_reward;
            demo.env_return += s.env_reward;
            demo.success |= s.success;
            Ok(s.step.terminated || s.step.truncated)
        },
    )?;
    if let Some(l) = logger {
        l.end_episode(demo.success)?;
    }
    Ok(demo)
}

fn run_episodes(
    policy: &mut ExpertPolicy,
    env_config: &ReacherConfig,
    reset_seeds: &[u64],
    mode: ActMode,
    seed: u64,
    mut logger: Option<&mut RolloutLogger>,
) -> Result<Vec<Demo>, ExpertError> {
    let task = policy.task();
    // No shaping: the demonstrations and evaluation see the task's own reward only.
    let mut env = product_env(task, env_config, 0.0, 0.99)?;
    if env.obs_dim() != policy.obs_dim() {
        return Err(SacError::Dimension {
            what: "observation size",
            expected: policy.obs_dim(),
            got: env.obs_dim(),
        }
        .into());
    }
    let mut rng = ChaCha8Rng::seed_from_u64(noise_seed(seed));
    let mut action = [0.0f32; ACT_DIM];
    let mut demos = Vec::with_capacity(reset_seeds.len());
    for &reset_seed in reset_seeds {
        let demo = record_episode(
            &mut env,
            reset_seed,
            "expert",
            logger.as_deref_mut(),
            |obs, _labels, _rm_state| {
                policy.act(obs, mode, &mut rng, &mut action);
                action
            },
        )
        .map_err(|e| match e {
            RecordError::Env { step, source } => SacError::Env { step, source }.into(),
            RecordError::Log(e) => ExpertError::Log(Box::new(e)),
        })?;
        demos.push(demo);
    }
    Ok(demos)
}

/// `n` demonstrations of `policy`'s stochastic policy on `task` (episode `i` reset with
/// [`episode_seed`]`(seed, i)`, action noise seeded from `seed`: the same seed gives the same
/// demonstrations bit for bit). Episodes end when the perfect machine reaches its goal or
/// failure sink, or at the time limit. With a `logger`, every episode is also logged (phase
/// `"expert"`, with the perfect machine's state and reward).
pub fn generate_demos(
    policy: &mut ExpertPolicy,
    task: ReacherTask,
    env_config: &ReacherConfig,
    n: usize,
    seed: u64,
    logger: Option<&mut RolloutLogger>,
) -> Result<Vec<Demo>, ExpertError> {
    let resets: Vec<u64> = (0..n as u64).map(|i| episode_seed(seed, i)).collect();
    generate_demos_from(policy, task, env_config, &resets, seed, logger)
}

/// [`generate_demos`] from given reset seeds (one demonstration each, in order); action noise
/// seeded from `seed`.
pub fn generate_demos_from(
    policy: &mut ExpertPolicy,
    task: ReacherTask,
    env_config: &ReacherConfig,
    reset_seeds: &[u64],
    seed: u64,
    logger: Option<&mut RolloutLogger>,
) -> Result<Vec<Demo>, ExpertError> {
    if task != policy.task() {
        return Err(ExpertError::Task {
            task: task.name().into(),
            problem: format!("the expert policy is for task '{}'", policy.task()),
        });
    }
    run_episodes(
        policy,
        env_config,
        reset_seeds,
        ActMode::Sample,
        seed,
        logger,
    )
}

/// The `/run` header of a demonstration log of `policy` (model XML, task, perfect machine).
pub fn demo_log_header(
    policy: &ExpertPolicy,
    env_config: &ReacherConfig,
    seed: u64,
) -> Result<RunHeader, ExpertError> {
    let config = serde_json::json!({
        "env": env_config,
        "expert": policy.info(),
        "policy": "SAC expert, stochastic actions",
    });
    let task = policy.task();
    let mut header = RunHeader::of_task(task.id(), task.task(), seed, config);
    let rm = policy.task().perfect_rm().map_err(|e| ExpertError::Task {
        task: policy.task().name().into(),
        problem: e.to_string(),
    })?;
    header.reward_machine = Some(crate::rm::format::write_rm(&rm));
    Ok(header)
}

/// The `/run` header of the training log of `task`'s expert (model XML, task, perfect
/// machine, the expert config).
pub fn train_log_header(
    task: ReacherTask,
    config: &ExpertConfig,
    seed: u64,
) -> Result<RunHeader, ExpertError> {
    let json = serde_json::json!({
        "run": "SAC expert training",
        // Replay reads the environment config from `env` (time limit, cancel schedule).
        "env": config.env,
        "expert_config": config,
    });
    let mut header = RunHeader::of_task(task.id(), task.task(), seed, json);
    let rm = task.perfect_rm().map_err(|e| ExpertError::Task {
        task: task.name().into(),
        problem: e.to_string(),
    })?;
    header.reward_machine = Some(crate::rm::format::write_rm(&rm));
    Ok(header)
}

/// What `reacher expert` measured, written as `summary.json` in its run directory.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ExpertRunSummary {
    pub task: String,
    pub seed: u64,
    pub env_steps: u64,
    pub episodes: u64,
    /// Wall time of the training in the last session (a resumed run counts only its own).
    pub train_seconds: f64,
    pub resumed_at: Option<u64>,
    pub eval_episodes: u64,
    pub success_stochastic: f64,
    pub success_mean: f64,
    pub task_return_stochastic: f64,
    pub task_return_mean: f64,
    pub length_stochastic: f64,
    pub length_mean: f64,
    /// Stochastic-policy evaluation episodes with a cancel event, and their successes.
    pub cancel_episodes_stochastic: u64,
    pub cancel_successes_stochastic: u64,
    pub cancel_episodes_mean: u64,
    pub cancel_successes_mean: u64,
    /// Conditional tasks: evaluation episodes and successes per branch (normal, cancel).
    pub branches_stochastic: Option<BranchTally>,
    pub branches_mean: Option<BranchTally>,
    /// Conditional tasks: the demonstrations per branch.
    pub demo_branches: Option<BranchTally>,
    pub demos: usize,
    pub demo_successes: usize,
    pub git_commit: String,
}

/// Writes `summary` as pretty JSON, atomically.
pub fn write_run_summary(path: &Path, summary: &ExpertRunSummary) -> Result<(), ExpertError> {
    let text = serde_json::to_string_pretty(summary).expect("summary serialises") + "\n";
    write_atomic(path, text.as_bytes()).map_err(|e| ExpertError::Write {
        path: path.display().to_string(),
        problem: e.to_string(),
    })
}

/// Writes the training curve of a task expert as SVG: the success rate and the mean
/// (shaped) training return over the last `window` episodes, against environment steps, to
/// `path` and `return_path`.
pub fn write_curve_svg(
    path: &Path,
    return_path: &Path,
    task: ReacherTask,
    curve: &[CurvePoint],
    window: usize,
) -> Result<(), ExpertError> {
    use crate::report::{BandPoint, LinePlot, Series};
    let window = window.max(1);
    let moving = |value: &dyn Fn(&CurvePoint) -> f64| -> Vec<BandPoint> {
        let mut sum = 0.0;
        curve
            .iter()
            .enumerate()
            .map(|(i, p)| {
                sum += value(p);
                if i >= window {
                    sum -= value(&curve[i - window]);
                }
                BandPoint {
                    x: p.env_steps as f64,
                    mean: sum / (i + 1).min(window) as f64,
                    std: 0.0,
                }
            })
            .collect()
    };
    let mut success = LinePlot::new(
        &format!("SAC expert, task {task}: training success rate"),
        "environment steps",
        &format!("success rate (last {window} episodes)"),
    );
    success.y_range = Some((0.0, 1.0));
    success.series.push(Series::new(
        task.name(),
        moving(&|p| f64::from(u8::from(p.success))),
    ));
    let mut ret = LinePlot::new(
        &format!("SAC expert, task {task}: training return (shaped)"),
        "environment steps",
        &format!("mean return (last {window} episodes)"),
    );
    ret.series
        .push(Series::new(task.name(), moving(&|p| p.env_return)));
    for (p, plot) in [(path, &success), (return_path, &ret)] {
        write_atomic(p, plot.to_svg().as_bytes()).map_err(|e| ExpertError::Write {
            path: p.display().to_string(),
            problem: e.to_string(),
        })?;
    }
    Ok(())
}
