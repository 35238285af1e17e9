//! The run configuration of `reacher --task`: one TOML file in which every key is required (a
//! missing, unknown or mistyped key is an error naming it, and a key of the old layout is
//! refused naming what replaced it, [`REMOVED_KEYS`]). The top level holds what every algorithm
//! shares (demonstrations, the IRL loop's sizes, evaluation, logging, threads); the tables
//! `[env]`, `[sac]`, `[smirl]`, `[lrm]`, `[firl]` and `[final]` the rest, and optional
//! `[schedule.baselines]` and `[schedule.<algorithm>]` tables give the baselines, or one
//! algorithm, its own IRL schedule ([`AlgoSchedule`], [`IrlRunConfig::for_algo`]). The one
//! optional key, `[env] episode_steps`, overrides the task's episode length
//! ([`IrlRunConfig::over_task`]).
//! What differs between `smirl` and the paper's `smirl-paper` is not a key: it follows from
//! the algorithm ([`IrlRunConfig::for_algo`]). Every key: docs/configuration.md. The sections
//! quoted as "research log" are in experiments/archive/README-research-log.md; docs/method.md
//! indexes them by mechanism.

use super::Algo;
use crate::env::reacher::{ConfigError as EnvConfigError, ReacherConfig, MAX_EPISODE_STEPS};
use crate::env::reacher_task::ReacherTask;
use crate::rl::sac::SacConfig;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::Path;

/// Where the demonstrations come from.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum DemoSource {
    /// The task's SAC expert from the expert cache (`expert_cache_dir`), trained there if
    /// missing (the paper's setting: stochastic expert policy).
    Expert,
    /// The scripted inverse-kinematics controller driven by the task's perfect machine (fast,
    /// no training; used by tests and `--quick`).
    Scripted,
}

impl DemoSource {
    pub fn name(self) -> &'static str {
        match self {
            DemoSource::Expert => "expert",
            DemoSource::Scripted => "scripted",
        }
    }
}

/// The reward machine SMIRL's jobs read.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum SmirlMachine {
    /// LRM's, learned from the demonstrations: the method.
    #[default]
    Learned,
    /// The task's own machine (`rm::perfect`) with its goal and failure states made ordinary
    /// absorbing states and its rewards zero, so that episodes run on as with a learned
    /// machine: an oracle for diagnosis, telling what the learned machine's shape costs.
    Task,
    /// One state and no transitions: the one-state control (docs/method.md), SMIRL with every other
    /// mechanism kept and no structure, telling what the learned machine itself adds.
    #[serde(rename = "one_state")]
    OneState,
}

impl SmirlMachine {
    pub fn name(self) -> &'static str {
        match self {
            SmirlMachine::Learned => "learned",
            SmirlMachine::Task => "task",
            SmirlMachine::OneState => "one_state",
        }
    }
}

/// Settings of a `reacher --task` run (see the module docs of [`super`] for what each
/// phase does). Read and written in the layout of [`RunFile`] (tables, every key required).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(into = "RunFile", from = "RunFile")]
pub struct IrlRunConfig {
    /// `"expert"` (the committed SAC experts built into the binary, or a task file's expert
    /// cache) or `"scripted"`.
    pub demo_source: DemoSource,
    /// Number of demonstrations (the paper: 16). Each is held at its final state to the
    /// episode's length (the fixed horizon T that MaxEnt IRL and f-IRL assume; without it the
    /// learned reward is pushed down wherever the agent stays after finishing the task).
    pub demo_episodes: usize,
    /// IRL iterations M (one reward update each).
    pub irl_iterations: usize,
    /// SAC environment steps per IRL iteration K (SAC continues across iterations).
    pub sac_steps_per_iteration: u64,
    /// Fresh agent trajectories per iteration for the reward update (each an episode
    /// long for the baselines, whose f-IRL covariance needs a fixed horizon).
    pub agent_trajectories: usize,
    /// Ground-truth evaluation episodes per IRL iteration (mean action, fixed seeds).
    pub eval_episodes: u64,
    /// `[firl] reward_lr`: Adam learning rate of the baselines' (64, 64) reward net.
    pub mlp_reward_lr: f32,
    /// `[firl] reward_l2`: L2 penalty (weight decay) of the reward net.
    pub mlp_reward_l2: f32,
    /// `[smirl] reward_lr`: Adam learning rate of SMIRL's linear per-RM-state weights.
    pub smirl_reward_lr: f32,
    /// `[smirl] reward_l2`: L2 penalty of SMIRL's weights.
    pub smirl_reward_l2: f32,
    /// `[smirl] machine`: `"learned"` (LRM's), `"task"` (the task's own, an oracle for
    /// diagnosis) or `"one_state"` (the control without structure; see [`SmirlMachine`]).
    pub smirl_machine: SmirlMachine,
    /// `[final] sac_steps`: the final-policy phase (`final_policy`) of every algorithm with a
    /// learned reward but `smirl-paper`: SAC environment steps on the final learned reward,
    /// held fixed, after the last IRL iteration; 0 = none.
    pub final_sac_steps: u64,
    /// `[final] checkpoints`: candidates taken along the final phase (evenly spaced, the last
    /// at its end), besides the co-trained policy of the last iteration.
    pub final_checkpoints: u64,
    /// Reward optimiser steps per IRL iteration (on the same coefficients).
    pub reward_steps_per_iteration: usize,
    /// `[smirl] smooth_sigma`: width σ (m) of `smirl-smooth`'s features exp(−d²/2σ²).
    pub smooth_sigma: f64,
    /// `[firl] kde_bandwidth`: Epanechnikov KDE bandwidth of f-IRL's fingertip densities (the
    /// paper: 0.02).
    pub kde_bandwidth: f64,
    /// `[firl] expert_trajectories`: demonstrations drawn for every f-IRL reward step and put
    /// in its covariance batch beside the agent's trajectories (f-IRL's `resample_episodes`:
    /// with replacement when more than there are demonstrations, else without); 0 = the
    /// agent's trajectories alone. Why: f-IRL's code for an expert given by samples does this,
    /// and it is what raises the reward where the expert goes and the agent does not (research log,
    /// "Positive controls").
    pub firl_expert_trajectories: usize,
    /// `[lrm] max_states`: most states of the learned machine (u_max).
    pub lrm_max_states: usize,
    /// `[lrm] tabu_len`: tabu list length.
    pub lrm_tabu_len: usize,
    /// `[lrm] steps`: search steps.
    pub lrm_steps: usize,
    /// MCAP: log every n-th agent/evaluation episode of each job (demos are all logged);
    /// 0 disables rollout logging.
    pub log_every_nth_episode: u64,
    /// Worker threads running (algorithm, seed) jobs.
    pub threads: usize,
    /// `[env] episode_steps`, optional: the episode length of every task of the run; `None`
    /// (the key absent) = each task's own (its file's `episode_steps`).
    pub episode_steps: Option<usize>,
    /// The environment: the task's (its episode length, regions and events' schedule,
    /// assets/tasks/) with `episode_steps` over it, once [`IrlRunConfig::over_task`] resolves
    /// it; before, the environment's defaults with no task.
    pub env: ReacherConfig,
    /// SAC of every job: `[sac]` sets lr, alpha, auto_alpha, warmup_steps (also the step of
    /// the first update) and replay_capacity; the rest is [`irl_run_sac`]'s.
    pub sac: SacConfig,
    /// Schedules keyed by algorithm name (`[schedule.fkl]`) or [`BASELINES`]
    /// (`[schedule.baselines]`, every baseline's): an algorithm runs with its own table's
    /// fields, then the baselines' table's (a baseline's), in place of the ones above; every
    /// field neither sets is the run's ([`IrlRunConfig::for_algo`]). Empty: one schedule for
    /// all.
    pub schedule: BTreeMap<String, AlgoSchedule>,
    /// Whether SMIRL's SAC batches move every sampled transition to a counterfactual
    /// learned-machine state (CRM, [`IrlRunConfig::counterfactual`]): not a key — true for
    /// `smirl` and `smirl-smooth`, false for `smirl-paper` ([`IrlRunConfig::for_algo`]).
    pub counterfactual_states: bool,
}

/// The file layout of [`IrlRunConfig`]: every key required, unknown keys refused.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RunFile {
    pub demo_source: DemoSource,
    pub demo_episodes: usize,
    pub irl_iterations: usize,
    pub sac_steps_per_iteration: u64,
    pub agent_trajectories: usize,
    pub reward_steps_per_iteration: usize,
    pub eval_episodes: u64,
    pub log_every_nth_episode: u64,
    pub threads: usize,
    #[serde(default, skip_serializing_if = "EnvKeys::is_empty")]
    pub env: EnvKeys,
    pub sac: SacKeys,
    pub smirl: SmirlKeys,
    pub lrm: LrmKeys,
    pub firl: FirlKeys,
    #[serde(rename = "final")]
    pub final_phase: FinalKeys,
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub schedule: BTreeMap<String, AlgoSchedule>,
}

/// `[env]`: its one key is optional (absent, each task's own episode length), so a config
/// without it reads the task rather than a length written for another task.
#[derive(Clone, Debug, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct EnvKeys {
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub episode_steps: Option<usize>,
}

impl EnvKeys {
    fn is_empty(&self) -> bool {
        self.episode_steps.is_none()
    }
}

/// `[sac]`: what the runs vary of SAC; the rest is [`irl_run_sac`]'s.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SacKeys {
    #[serde(serialize_with = "crate::short_float::f32")]
    pub lr: f32,
    #[serde(serialize_with = "crate::short_float::f32")]
    pub alpha: f32,
    pub auto_alpha: bool,
    pub warmup_steps: u64,
    pub replay_capacity: usize,
}

/// `[smirl]`: SMIRL's reward and SAC (smirl, smirl-smooth, smirl-paper).
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SmirlKeys {
    pub machine: SmirlMachine,
    #[serde(serialize_with = "crate::short_float::f32")]
    pub reward_lr: f32,
    #[serde(serialize_with = "crate::short_float::f32")]
    pub reward_l2: f32,
    pub smooth_sigma: f64,
}

/// `[lrm]`: LRM's size and search budget (its mechanisms are not settings).
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LrmKeys {
    pub max_states: usize,
    pub tabu_len: usize,
    pub steps: usize,
}

/// `[firl]`: the baselines' reward net (maxent, fkl, rkl, js) and f-IRL's densities.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FirlKeys {
    #[serde(serialize_with = "crate::short_float::f32")]
    pub reward_lr: f32,
    #[serde(serialize_with = "crate::short_float::f32")]
    pub reward_l2: f32,
    pub kde_bandwidth: f64,
    pub expert_trajectories: usize,
}

/// `[final]`: the final phase of every algorithm with a learned reward but `smirl-paper`.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FinalKeys {
    pub sac_steps: u64,
    pub checkpoints: u64,
}

impl From<IrlRunConfig> for RunFile {
    fn from(c: IrlRunConfig) -> RunFile {
        RunFile {
            demo_source: c.demo_source,
            demo_episodes: c.demo_episodes,
            irl_iterations: c.irl_iterations,
            sac_steps_per_iteration: c.sac_steps_per_iteration,
            agent_trajectories: c.agent_trajectories,
            reward_steps_per_iteration: c.reward_steps_per_iteration,
            eval_episodes: c.eval_episodes,
            log_every_nth_episode: c.log_every_nth_episode,
            threads: c.threads,
            env: EnvKeys {
                episode_steps: c.episode_steps,
            },
            sac: SacKeys {
                lr: c.sac.lr,
                alpha: c.sac.alpha,
                auto_alpha: c.sac.auto_alpha,
                warmup_steps: c.sac.warmup_steps,
                replay_capacity: c.sac.replay_capacity,
            },
            smirl: SmirlKeys {
                machine: c.smirl_machine,
                reward_lr: c.smirl_reward_lr,
                reward_l2: c.smirl_reward_l2,
                smooth_sigma: c.smooth_sigma,
            },
            lrm: LrmKeys {
                max_states: c.lrm_max_states,
                tabu_len: c.lrm_tabu_len,
                steps: c.lrm_steps,
            },
            firl: FirlKeys {
                reward_lr: c.mlp_reward_lr,
                reward_l2: c.mlp_reward_l2,
                kde_bandwidth: c.kde_bandwidth,
                expert_trajectories: c.firl_expert_trajectories,
            },
            final_phase: FinalKeys {
                sac_steps: c.final_sac_steps,
                checkpoints: c.final_checkpoints,
            },
            schedule: c.schedule,
        }
    }
}

impl From<RunFile> for IrlRunConfig {
    fn from(f: RunFile) -> IrlRunConfig {
        IrlRunConfig {
            demo_source: f.demo_source,
            demo_episodes: f.demo_episodes,
            irl_iterations: f.irl_iterations,
            sac_steps_per_iteration: f.sac_steps_per_iteration,
            agent_trajectories: f.agent_trajectories,
            eval_episodes: f.eval_episodes,
            mlp_reward_lr: f.firl.reward_lr,
            mlp_reward_l2: f.firl.reward_l2,
            smirl_reward_lr: f.smirl.reward_lr,
            smirl_reward_l2: f.smirl.reward_l2,
            smirl_machine: f.smirl.machine,
            final_sac_steps: f.final_phase.sac_steps,
            final_checkpoints: f.final_phase.checkpoints,
            reward_steps_per_iteration: f.reward_steps_per_iteration,
            smooth_sigma: f.smirl.smooth_sigma,
            kde_bandwidth: f.firl.kde_bandwidth,
            firl_expert_trajectories: f.firl.expert_trajectories,
            lrm_max_states: f.lrm.max_states,
            lrm_tabu_len: f.lrm.tabu_len,
            lrm_steps: f.lrm.steps,
            log_every_nth_episode: f.log_every_nth_episode,
            threads: f.threads,
            episode_steps: f.env.episode_steps,
            env: ReacherConfig::default(),
            sac: run_sac(&f.sac),
            schedule: f.schedule,
            counterfactual_states: true,
        }
    }
}

/// The SAC of a `[sac]` table: [`irl_run_sac`] with the table's keys; updates begin when the
/// warm-up's random steps end.
fn run_sac(k: &SacKeys) -> SacConfig {
    SacConfig {
        lr: k.lr,
        alpha: k.alpha,
        auto_alpha: k.auto_alpha,
        warmup_steps: k.warmup_steps,
        update_after: k.warmup_steps,
        replay_capacity: k.replay_capacity,
        ..irl_run_sac()
    }
}

/// The name of the schedule every baseline shares: `[schedule.baselines]`.
pub const BASELINES: &str = "baselines";

/// The algorithms `[schedule.baselines]` applies to, each also through its controls
/// ([`Algo::base`]): the learned-reward baselines, which share f-IRL's schedule.
pub const BASELINE_ALGOS: [Algo; 4] = [Algo::MaxEnt, Algo::Fkl, Algo::Rkl, Algo::Js];

/// The fields one algorithm may run with its own values of (`[schedule.<algorithm>]`): the
/// IRL schedule, rollout logging, the baselines' reward net and KDE (`[schedule.<a>.firl]`)
/// and SAC (`[schedule.<a>.sac]`, all but the shared replay size). What the algorithms must
/// share to be compared stays run-wide: the demonstrations, the environment, the
/// ground-truth evaluation, the replay size and the final phase.
///
/// Why: f-IRL's own code runs many short IRL iterations (800 × 300 SAC steps, 2 reward steps,
/// SAC with fixed α = 1) and fails even a one-ball control task under a 20 × 5 000 schedule
/// (research log, "Positive controls"); each algorithm gets the schedule its positive control
/// needs.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AlgoSchedule {
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub irl_iterations: Option<usize>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sac_steps_per_iteration: Option<u64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub agent_trajectories: Option<usize>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub reward_steps_per_iteration: Option<usize>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub log_every_nth_episode: Option<u64>,
    /// `[firl]` keys that differ from the run's.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub firl: Option<FirlSchedule>,
    /// `[sac]` keys that differ from the run's (which supplies the rest).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sac: Option<SacSchedule>,
}

/// `[schedule.<name>.firl]`.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FirlSchedule {
    #[serde(
        default,
        skip_serializing_if = "Option::is_none",
        serialize_with = "crate::short_float::option_f32"
    )]
    pub reward_lr: Option<f32>,
    #[serde(
        default,
        skip_serializing_if = "Option::is_none",
        serialize_with = "crate::short_float::option_f32"
    )]
    pub reward_l2: Option<f32>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub kde_bandwidth: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub expert_trajectories: Option<usize>,
}

/// `[schedule.<name>.sac]`: `replay_capacity` is read only to be refused, naming why
/// ([`SHARED_SAC_KEYS`]).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SacSchedule {
    #[serde(
        default,
        skip_serializing_if = "Option::is_none",
        serialize_with = "crate::short_float::option_f32"
    )]
    pub lr: Option<f32>,
    #[serde(
        default,
        skip_serializing_if = "Option::is_none",
        serialize_with = "crate::short_float::option_f32"
    )]
    pub alpha: Option<f32>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub auto_alpha: Option<bool>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub warmup_steps: Option<u64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub replay_capacity: Option<usize>,
}

/// The baselines' schedule in the standard profile (`[schedule.baselines]`): f-IRL's own
/// ReacherDraw settings at the tasks' 100-step horizon — 800 IRL iterations of 300 SAC steps,
/// 300 fresh trajectories (30 000 states) per reward update, 2 reward steps per iteration, no
/// weight decay on the reward, SAC lr 3e-3 with a fixed temperature of 1, 150 random steps
/// first; every 100th episode logged. The replay size is not the schedule's: it is the run's
/// `[sac]` one, shared by every algorithm ([`SHARED_SAC_KEYS`]). Chosen on the Markovian
/// positive control "blue" (seeds 0–2), never on the paper's tasks: with it fkl, js and MaxEnt
/// solve "blue" in 3 of 3 seeds, with a 20 × 5 000 schedule the f-IRL variants in
/// none (research log, "Positive controls of the baselines"). rkl's own table adds to it
/// ([`rkl_schedule`]).
pub fn baselines_schedule() -> AlgoSchedule {
    AlgoSchedule {
        irl_iterations: Some(800),
        sac_steps_per_iteration: Some(300),
        agent_trajectories: Some(300),
        reward_steps_per_iteration: Some(2),
        log_every_nth_episode: Some(100),
        firl: Some(FirlSchedule {
            reward_l2: Some(0.0),
            ..FirlSchedule::default()
        }),
        sac: Some(SacSchedule {
            lr: Some(0.003),
            alpha: Some(1.0),
            auto_alpha: Some(false),
            warmup_steps: Some(150),
            replay_capacity: None,
        }),
    }
}

/// rkl's own table in the standard profile (`[schedule.rkl]`, over the baselines'): 300 drawn
/// demonstrations in each covariance batch beside the 300 agent trajectories (`[firl]
/// expert_trajectories`, f-IRL's code for demonstrations): without them rkl fails "blue" under
/// every setting tried, with them (at T = 30) it passes in 3 of 3 seeds.
pub fn rkl_schedule() -> AlgoSchedule {
    AlgoSchedule {
        firl: Some(FirlSchedule {
            expert_trajectories: Some(300),
            ..FirlSchedule::default()
        }),
        ..AlgoSchedule::default()
    }
}

/// `[sac]` keys no `[schedule.<algorithm>.sac]` table may set: settings of the comparison, not
/// of an algorithm. The replay size: a buffer that drops old transitions makes SAC forget
/// sub-tasks its policy stopped reaching for, whatever learned the reward, and rewards are
/// recomputed at sampling time, so a large buffer holds no stale rewards for any algorithm.
pub const SHARED_SAC_KEYS: [&str; 1] = ["replay_capacity"];

/// The inner SAC of the IRL runs: the paper's IRL settings (`SacConfig::irl`) with Adam lr
/// 1e-3 instead of 3e-3 and a replay buffer of 200 000 instead of 10 000 transitions.
/// Why: the learned reward changes every IRL iteration and rewards are recomputed from the
/// current reward at sampling time, so old transitions never carry stale rewards — but a
/// 10 000 buffer holds only the last two iterations (5 000 steps each), and a sub-goal the
/// policy stops reaching for two iterations vanishes from SAC's data; the lower rate keeps
/// the critics from chasing every reward update. Measured on SMIRL with held-out seeds (the
/// paper's values are the `paper_sac` ablation: experiments/archive/reacher/ablations.md). 200 000
/// keeps every transition of a SMIRL job (150 000 loop steps and the final phase's 20 000) and
/// the last 200 000 of a baseline's 240 000 loop steps: with 100 000, SAC on a fixed learned
/// reward lost tasks it had solved once the buffer began dropping its oldest transitions
/// (experiments/archive/reacher/retrain_agents.sh; experiments/reacher/ablations/replay_all.toml).
/// One value for every algorithm ([`SHARED_SAC_KEYS`]).
pub fn irl_run_sac() -> SacConfig {
    SacConfig {
        lr: 1e-3,
        replay_capacity: 200_000,
        ..SacConfig::irl()
    }
}

/// A configuration file or value that cannot be used.
#[derive(Debug, thiserror::Error)]
pub enum IrlConfigError {
    #[error("{path}: {source}")]
    Io {
        path: String,
        #[source]
        source: std::io::Error,
    },
    #[error("{source_name}: {message}")]
    Parse {
        source_name: String,
        message: String,
    },
    #[error("{source_name}: {}field `{field}` {problem}", line.map_or(String::new(), |l| format!("line {l}: ")))]
    Invalid {
        source_name: String,
        /// Dotted key path (`sac.batch_size`, `env.episode_steps`, `lrm_steps`).
        field: String,
        problem: String,
        /// Line of the key (or of its table's header, when the key is left at its
        /// default); `None` when the config did not come from a file.
        line: Option<usize>,
    },
}

/// Parses a run config of type `T` from TOML `text` and checks it with `validate`: a
/// syntax or type error names its line and key, an invalid value the line of its key.
pub fn parse_toml_config<T: serde::de::DeserializeOwned>(
    text: &str,
    source_name: &str,
    validate: impl FnOnce(&T, &str) -> Result<(), IrlConfigError>,
) -> Result<T, IrlConfigError> {
    let config: T = toml::from_str(text).map_err(|e: toml::de::Error| IrlConfigError::Parse {
        source_name: source_name.to_string(),
        message: crate::config_text::toml_error_message(text, &e),
    })?;
    validate(&config, source_name).map_err(|e| e.at_key_line(text))?;
    Ok(config)
}

/// [`parse_toml_config`] of a file (at most `config_text::MAX_TEXT_FILE_BYTES`).
pub fn load_toml_config<T: serde::de::DeserializeOwned>(
    path: &Path,
    validate: impl FnOnce(&T, &str) -> Result<(), IrlConfigError>,
) -> Result<T, IrlConfigError> {
    let text = crate::config_text::read_text_file(path).map_err(|source| IrlConfigError::Io {
        path: path.display().to_string(),
        source,
    })?;
    parse_toml_config(&text, &path.display().to_string(), validate)
}

impl IrlConfigError {
    /// An invalid value's error with the line of its key in `text`, the document it was
    /// parsed from; other errors unchanged.
    pub fn at_key_line(self, text: &str) -> IrlConfigError {
        match self {
            IrlConfigError::Invalid {
                source_name,
                field,
                problem,
                ..
            } => IrlConfigError::Invalid {
                line: crate::config_text::key_line(text, &field),
                source_name,
                field,
                problem,
            },
            other => other,
        }
    }
}

/// Keys a run config no longer has, each with what replaced it (dotted for a table's key): a
/// config that still sets one was written for the old layout or for a mechanism that is now
/// the method's (or gone), and is refused rather than read as something else. Configs of runs
/// made with these keys are read by the binary of their commit (their `run.json` names it).
pub const REMOVED_KEYS: [(&str, &str); 53] = [
    (
        "lrm_fallback_starts",
        "nothing: LRM has no fallback starts (they changed no development base towards the \
         task's machine more often than away from it: experiments/lrm/ablation.md)",
    ),
    (
        "lrm_initial_events",
        "nothing: initial events are part of smirl's LRM (docs/method.md)",
    ),
    (
        "lrm_guards",
        "nothing: smirl's LRM reads unseen label sets by its decision trees, smirl-paper's \
         stays (docs/method.md)",
    ),
    (
        "lrm_commute_events",
        "nothing: commuted events are part of smirl's LRM (docs/method.md)",
    ),
    (
        "lrm_event_stutter",
        "nothing: event stutter is part of smirl's LRM (docs/method.md)",
    ),
    (
        "lrm_predict_events",
        "nothing: smirl's LRM leaves the events out of its prediction, smirl-paper's predicts \
         them (docs/method.md)",
    ),
    ("lrm_max_states", "[lrm] max_states"),
    ("lrm_tabu_len", "[lrm] tabu_len"),
    ("lrm_steps", "[lrm] steps"),
    (
        "expert_cache_dir",
        "nothing: demonstrations come from the experts built into the binary (a task file's: \
         its expert cache, `reacher expert`)",
    ),
    (
        "demo_padding",
        "nothing: demonstrations are always held at their final state to the episode's \
         length (the old \"hold\")",
    ),
    ("mlp_reward_lr", "[firl] reward_lr"),
    ("mlp_reward_l2", "[firl] reward_l2"),
    ("kde_bandwidth", "[firl] kde_bandwidth"),
    ("firl_expert_trajectories", "[firl] expert_trajectories"),
    (
        "firl_density_ratio",
        "nothing: f-IRL's density ratio is always that of two KDEs (the old \"kde\")",
    ),
    ("smirl_reward_lr", "[smirl] reward_lr"),
    ("smirl_reward_l2", "[smirl] reward_l2"),
    ("smirl_machine", "[smirl] machine"),
    (
        "smirl_shaping",
        "nothing: SMIRL's SAC reads the learned reward unshaped (shaping did not show it pays: \
         experiments/reacher/mechanisms/ablation.md)",
    ),
    (
        "smirl.shaping",
        "nothing: SMIRL's SAC reads the learned reward unshaped (shaping did not show it pays: \
         experiments/reacher/mechanisms/ablation.md)",
    ),
    ("smooth_sigma", "[smirl] smooth_sigma"),
    (
        "smirl_normalisation",
        "nothing: every SMIRL variant averages mu_D - mu_pi over trajectories (event-gated \
         visits did not show they pay: experiments/reacher/mechanisms/ablation.md)",
    ),
    (
        "smirl_label_features",
        "nothing: SMIRL's label features are those of the state reached (the old \"state\")",
    ),
    (
        "smirl_counterfactual",
        "the algorithm: smirl and smirl-smooth relabel every SAC transition to a \
         counterfactual machine state (the old 1.0), smirl-paper none",
    ),
    ("smirl_final_sac_steps", "[final] sac_steps"),
    ("smirl_final_checkpoints", "[final] checkpoints"),
    (
        "smirl_final_reset_steps",
        "nothing: the final phase has no reset agent (it did not show it pays: \
         experiments/reacher/mechanisms/ablation.md)",
    ),
    (
        "final.reset_steps",
        "nothing: the final phase has no reset agent (it did not show it pays: \
         experiments/reacher/mechanisms/ablation.md)",
    ),
    (
        "smirl_selection_cut",
        "nothing: the final choice reads the plain learned return (the selection cut did not \
         show it pays: experiments/reacher/mechanisms/ablation.md)",
    ),
    (
        "smirl_selection_cut_entries",
        "nothing: the selection cut is gone (experiments/reacher/mechanisms/ablation.md)",
    ),
    (
        "smirl_clock",
        "nothing: no learner's observation has a clock (it did not show it pays: \
         experiments/reacher/mechanisms/ablation.md)",
    ),
    (
        "smirl_clock_frozen",
        "nothing: the clock and its control, the frozen clock, are gone",
    ),
    (
        "reward_lr_decay",
        "nothing: the reward's learning rate is constant (the old 0.0)",
    ),
    (
        "env.randomize_balls",
        "nothing: the balls are where the task file puts them (the old false)",
    ),
    (
        "env.max_steps",
        "[env] episode_steps, optional: absent, each task's own episode length (its file's \
         episode_steps); present, the length of every task of the run",
    ),
    (
        "env.ball_layout",
        "the task file's regions (assets/tasks/, docs/tasks.md)",
    ),
    (
        "env.arm_start",
        "nothing: the arm starts at a random pose (the old \"random\")",
    ),
    (
        "env.cancel",
        "the task file's [[event]] schedule (assets/tasks/, docs/tasks.md)",
    ),
    (
        "sac.preset",
        "nothing: [sac] gives its five keys, the rest is fixed (docs/configuration.md)",
    ),
    ("sac.hidden", "nothing: fixed at [64, 64]"),
    ("sac.batch_size", "nothing: fixed at 256"),
    ("sac.gamma", "nothing: fixed at 0.99"),
    ("sac.tau", "nothing: fixed at 0.005"),
    (
        "sac.target_entropy",
        "nothing: fixed at −(action dimension)",
    ),
    ("sac.updates_per_step", "nothing: fixed at 1"),
    (
        "sac.update_after",
        "[sac] warmup_steps (updates begin when the warm-up ends)",
    ),
    (
        "schedule.*.mlp_reward_lr",
        "[schedule.<algo>.firl] reward_lr",
    ),
    (
        "schedule.*.mlp_reward_l2",
        "[schedule.<algo>.firl] reward_l2",
    ),
    (
        "schedule.*.kde_bandwidth",
        "[schedule.<algo>.firl] kde_bandwidth",
    ),
    (
        "schedule.*.firl_expert_trajectories",
        "[schedule.<algo>.firl] expert_trajectories",
    ),
    (
        "schedule.*.firl_density_ratio",
        "nothing: f-IRL's density ratio is always that of two KDEs (the old \"kde\")",
    ),
    (
        "schedule.*.sac.update_after",
        "[schedule.<algo>.sac] warmup_steps (updates begin when the warm-up ends)",
    ),
];

/// Refuses the first key of [`REMOVED_KEYS`] that `text` sets (in the table order of the
/// list; `schedule.*` stands for any algorithm), naming what replaced it. A document that does
/// not parse is left to the parser's message.
fn refuse_removed_keys(text: &str, source_name: &str) -> Result<(), IrlConfigError> {
    let Ok(table) = text.parse::<toml::Table>() else {
        return Ok(());
    };
    let lookup = |path: &[&str]| -> bool {
        let mut t = &table;
        for (i, part) in path.iter().enumerate() {
            match t.get(*part) {
                Some(_) if i + 1 == path.len() => return true,
                Some(toml::Value::Table(sub)) => t = sub,
                _ => return false,
            }
        }
        false
    };
    let algos: Vec<String> = table
        .get("schedule")
        .and_then(|s| s.as_table())
        .map(|s| s.keys().cloned().collect())
        .unwrap_or_default();
    for (key, replacement) in REMOVED_KEYS {
        let paths: Vec<String> = match key.strip_prefix("schedule.*.") {
            Some(rest) => algos
                .iter()
                .map(|a| format!("schedule.{a}.{rest}"))
                .collect(),
            None => vec![key.to_string()],
        };
        for path in paths {
            let parts: Vec<&str> = path.split('.').collect();
            if lookup(&parts) {
                return Err(IrlConfigError::Invalid {
                    source_name: source_name.to_string(),
                    field: path.clone(),
                    problem: format!(
                        "is no longer a key (the run config's layout changed, \
                         docs/configuration.md; a config of an older commit is read by that \
                         commit's binary, which its run's prepare.json names); replaced by \
                         {replacement}"
                    ),
                    line: crate::config_text::key_line(text, &path),
                });
            }
        }
    }
    Ok(())
}

// Limits of the sizes a config may ask for, checked by `validate` before any work (a typo
// must be an error naming the key, not an allocation failure an hour later).

/// Most demonstrations generated.
pub const MAX_DEMO_EPISODES: usize = 10_000;
/// Most IRL iterations.
pub const MAX_IRL_ITERATIONS: usize = 100_000;
/// Most SAC environment steps per IRL iteration.
pub const MAX_SAC_STEPS_PER_ITERATION: u64 = 100_000_000;
/// Most environment steps kept in memory for one iteration's agent rollouts (or its
/// evaluation episodes): trajectories × the episode's steps.
pub const MAX_ROLLOUT_STEPS: usize = 10_000_000;
/// Most reward optimiser steps per IRL iteration.
pub const MAX_REWARD_STEPS: usize = 100_000;
/// Most states of a learned machine.
pub const MAX_LRM_STATES: usize = crate::rm::lrm::MAX_STATES;
/// Most LRM search steps and tabu-list entries.
pub const MAX_LRM_STEPS: usize = crate::rm::lrm::MAX_SEARCH_STEPS;
/// Most worker threads.
pub const MAX_THREADS: usize = 256;
/// Most candidates of SMIRL's final-policy phase (each is two evaluations).
pub const MAX_FINAL_CHECKPOINTS: u64 = 1_000;

impl IrlRunConfig {
    /// The default profile: `reacher --task <t>` runs it with the default algorithm set; the
    /// paper's schedules sized for 2 cores (docs/benchmarks.md times the main command).
    pub fn standard() -> IrlRunConfig {
        IrlRunConfig {
            demo_source: DemoSource::Expert,
            demo_episodes: 16,
            // SMIRL's schedule: 30 IRL iterations (two of three Sequential tuning seeds first
            // solve the task in iterations 16-20; research log, "SMIRL's settings").
            irl_iterations: 30,
            sac_steps_per_iteration: 5_000,
            agent_trajectories: 20,
            eval_episodes: 20,
            mlp_reward_lr: 1e-3,
            mlp_reward_l2: 1e-3,
            smirl_reward_lr: 0.1,
            smirl_reward_l2: 0.05,
            smirl_machine: SmirlMachine::Learned,
            // The final policy: four candidates 5 000 SAC steps apart on the final reward
            // (research log, "SMIRL's final policy").
            final_sac_steps: 20_000,
            final_checkpoints: 4,
            reward_steps_per_iteration: 5,
            smooth_sigma: 0.05,
            kde_bandwidth: 0.02,
            firl_expert_trajectories: 0,
            lrm_max_states: 10,
            lrm_tabu_len: 10_000,
            lrm_steps: 100,
            log_every_nth_episode: 10,
            threads: 2,
            episode_steps: None,
            env: ReacherConfig::default(),
            sac: irl_run_sac(),
            schedule: [
                (BASELINES.to_string(), baselines_schedule()),
                (Algo::Rkl.name().to_string(), rkl_schedule()),
            ]
            .into_iter()
            .collect(),
            counterfactual_states: true,
        }
    }

    /// The `--quick` smoke profile (a few minutes): scripted demos, few short iterations, the
    /// same schedule for every algorithm.
    pub fn quick() -> IrlRunConfig {
        IrlRunConfig {
            demo_source: DemoSource::Scripted,
            demo_episodes: 8,
            irl_iterations: 4,
            sac_steps_per_iteration: 2_000,
            agent_trajectories: 8,
            eval_episodes: 8,
            lrm_steps: 50,
            log_every_nth_episode: 4,
            final_sac_steps: 2_000,
            final_checkpoints: 2,
            // One short schedule for every algorithm: a smoke run, not the baselines' 800
            // iterations.
            schedule: BTreeMap::new(),
            ..IrlRunConfig::standard()
        }
    }

    /// Parses a TOML document; `source_name` (the file path) prefixes every message. A key
    /// of [`REMOVED_KEYS`] is refused, naming it and what replaced it; a missing key is
    /// refused naming it.
    pub fn from_toml(text: &str, source_name: &str) -> Result<IrlRunConfig, IrlConfigError> {
        refuse_removed_keys(text, source_name)?;
        parse_toml_config(text, source_name, IrlRunConfig::validate)
    }

    /// Reads and parses a TOML file (as [`IrlRunConfig::from_toml`]).
    pub fn load(path: &Path) -> Result<IrlRunConfig, IrlConfigError> {
        let text =
            crate::config_text::read_text_file(path).map_err(|source| IrlConfigError::Io {
                path: path.display().to_string(),
                source,
            })?;
        IrlRunConfig::from_toml(&text, &path.display().to_string())
    }

    pub fn to_toml(&self) -> String {
        toml::to_string(self).expect("IrlRunConfig always serialises")
    }

    /// The settings `algo` runs with: the run's, with the fields of `[schedule.baselines]` in
    /// their place when `algo` is a baseline ([`BASELINE_ALGOS`]), then those of `algo`'s own
    /// `[schedule.<algo>]` in theirs: the algorithm's own table over the baselines' over the
    /// run's keys, field by field (a control's: its baseline's, [`Algo::base`]). The schedules
    /// were checked by [`IrlRunConfig::validate`].
    pub fn for_algo(&self, algo: Algo) -> Result<IrlRunConfig, IrlConfigError> {
        let mut config = IrlRunConfig {
            schedule: BTreeMap::new(),
            ..self.clone()
        };
        if algo == Algo::SmirlPaper {
            config.set_paper_mechanisms();
        }
        // A control runs its baseline's schedule (no table of its own).
        let base = algo.base();
        if BASELINE_ALGOS.contains(&base) {
            if let Some(s) = self.schedule.get(BASELINES) {
                config.apply_schedule(BASELINES, s)?;
            }
        }
        if let Some(s) = self.schedule.get(base.name()) {
            config.apply_schedule(base.name(), s)?;
        }
        Ok(config)
    }

    /// Puts the fields `s` (`[schedule.<name>]`) sets in place of these.
    fn apply_schedule(&mut self, name: &str, s: &AlgoSchedule) -> Result<(), IrlConfigError> {
        macro_rules! take {
            ($from:expr, $($f:ident => $to:expr),*) => {$(
                if let Some(v) = $from.$f {
                    $to = v;
                }
            )*};
        }
        take!(s,
            irl_iterations => self.irl_iterations,
            sac_steps_per_iteration => self.sac_steps_per_iteration,
            agent_trajectories => self.agent_trajectories,
            reward_steps_per_iteration => self.reward_steps_per_iteration,
            log_every_nth_episode => self.log_every_nth_episode
        );
        if let Some(f) = &s.firl {
            take!(f,
                reward_lr => self.mlp_reward_lr,
                reward_l2 => self.mlp_reward_l2,
                kde_bandwidth => self.kde_bandwidth,
                expert_trajectories => self.firl_expert_trajectories
            );
        }
        if let Some(sac) = &s.sac {
            if sac.replay_capacity.is_some() {
                return Err(IrlConfigError::Invalid {
                    source_name: String::new(),
                    field: format!("schedule.{name}.sac.{}", SHARED_SAC_KEYS[0]),
                    problem: "is shared by every algorithm: set it in [sac], not per schedule"
                        .into(),
                    line: None,
                });
            }
            take!(sac,
                lr => self.sac.lr,
                alpha => self.sac.alpha,
                auto_alpha => self.sac.auto_alpha,
                warmup_steps => self.sac.warmup_steps,
                warmup_steps => self.sac.update_after
            );
        }
        Ok(())
    }

    /// The run's settings over `task`, as every run of a task reads them: the environment is
    /// the task's (its regions, its events' schedule and its episode length), with
    /// `[env] episode_steps` as the episode length when the config gives it. Resolving a
    /// resolved config again changes nothing.
    pub fn over_task(&self, task: &ReacherTask) -> Result<IrlRunConfig, EnvConfigError> {
        let mut env = task.env_config(&self.env)?;
        if let Some(steps) = self.episode_steps {
            env.max_steps = steps;
            env.validate()?;
        }
        Ok(IrlRunConfig {
            env,
            ..self.clone()
        })
    }

    /// The episode length the rollout limits are checked against: `[env] episode_steps`, else
    /// the environment's (a task's once [`IrlRunConfig::over_task`] resolved it).
    fn episode_len(&self) -> usize {
        self.episode_steps.unwrap_or(self.env.max_steps)
    }

    /// `smirl-paper`'s settings: every mechanism by which `smirl` departs from the paper
    /// (docs/method.md) at the paper's value — LRM's are not settings but the learner's
    /// (`smirl::lrm_config` of `Algo::SmirlPaper`) — SAC on U × O without counterfactual
    /// states, and no final phase, so the job reports its loop's own last policy. The schedule, SAC, the
    /// reward optimiser, the demonstrations, the machine's source and LRM's size and search
    /// budget stay the run's, so that the two algorithms differ by the mechanisms alone.
    fn set_paper_mechanisms(&mut self) {
        self.counterfactual_states = false;
        self.final_sac_steps = 0;
        self.final_checkpoints = 0;
    }

    /// Share of each SAC batch of SMIRL relabelled to a counterfactual learned-machine state
    /// (CRM, `rl::crm`): 1 (every sampled transition, from a uniformly drawn state) for smirl
    /// and smirl-smooth, 0 for smirl-paper.
    pub fn counterfactual(&self) -> f64 {
        if self.counterfactual_states {
            1.0
        } else {
            0.0
        }
    }

    /// Checks value ranges (named by field): sizes against their limits, then values, then
    /// the SAC settings that are not keys, then each schedule as it resolves.
    pub fn validate(&self, source_name: &str) -> Result<(), IrlConfigError> {
        self.validate_sizes(source_name)?;
        self.validate_values(source_name)?;
        self.validate_fixed_sac(source_name)?;
        self.validate_schedules(source_name)
    }

    /// The episode length, the environment, and every size against its limit (no unbounded
    /// allocation).
    fn validate_sizes(&self, source_name: &str) -> Result<(), IrlConfigError> {
        let bad = |field: &str, problem: &str| invalid(source_name, field, problem);
        // The environment first: the rollout limits below use its episode length.
        if let Some(steps) = self.episode_steps {
            if steps == 0 || steps > MAX_EPISODE_STEPS {
                return bad(
                    "env.episode_steps",
                    &format!("is {steps}, it must be in 1..={MAX_EPISODE_STEPS}"),
                );
            }
        }
        if let Err(e) = self.env.validate() {
            return bad(&format!("env.{}", e.field()), &e.to_string());
        }
        let over = |field: &str, value: u64, limit: u64| {
            bad(
                field,
                &format!("is {value}, more than the limit of {limit}"),
            )
        };
        for (field, value, limit) in [
            (
                "demo_episodes",
                self.demo_episodes as u64,
                MAX_DEMO_EPISODES as u64,
            ),
            (
                "irl_iterations",
                self.irl_iterations as u64,
                MAX_IRL_ITERATIONS as u64,
            ),
            (
                "sac_steps_per_iteration",
                self.sac_steps_per_iteration,
                MAX_SAC_STEPS_PER_ITERATION,
            ),
            (
                "reward_steps_per_iteration",
                self.reward_steps_per_iteration as u64,
                MAX_REWARD_STEPS as u64,
            ),
            (
                "lrm.max_states",
                self.lrm_max_states as u64,
                MAX_LRM_STATES as u64,
            ),
            ("lrm.steps", self.lrm_steps as u64, MAX_LRM_STEPS as u64),
            (
                "lrm.tabu_len",
                self.lrm_tabu_len as u64,
                MAX_LRM_STEPS as u64,
            ),
            ("threads", self.threads as u64, MAX_THREADS as u64),
        ] {
            if value > limit {
                return over(field, value, limit);
            }
        }
        for (field, episodes) in [
            ("agent_trajectories", self.agent_trajectories as u64),
            (
                "firl.expert_trajectories",
                self.firl_expert_trajectories as u64,
            ),
            ("eval_episodes", self.eval_episodes),
        ] {
            let steps = episodes.saturating_mul(self.episode_len() as u64);
            if steps > MAX_ROLLOUT_STEPS as u64 {
                return bad(
                    field,
                    &format!(
                        "× the episode's steps = {steps} steps per iteration, more than the limit of {MAX_ROLLOUT_STEPS}"
                    ),
                );
            }
        }
        Ok(())
    }

    /// Counts that must be at least 1, rates and weights, the final phase's shape.
    fn validate_values(&self, source_name: &str) -> Result<(), IrlConfigError> {
        let bad = |field: &str, problem: &str| invalid(source_name, field, problem);
        let over = |field: &str, value: u64, limit: u64| {
            bad(
                field,
                &format!("is {value}, more than the limit of {limit}"),
            )
        };
        let positive = |x: f64| x.is_finite() && x > 0.0;
        let non_negative = |x: f64| x.is_finite() && x >= 0.0;
        if self.demo_episodes == 0 {
            return bad("demo_episodes", "must be at least 1");
        }
        if self.irl_iterations == 0 {
            return bad("irl_iterations", "must be at least 1");
        }
        if self.sac_steps_per_iteration == 0 {
            return bad("sac_steps_per_iteration", "must be at least 1");
        }
        if self.agent_trajectories < 2 {
            return bad(
                "agent_trajectories",
                "must be at least 2 (f-IRL's covariance)",
            );
        }
        if self.eval_episodes == 0 {
            return bad("eval_episodes", "must be at least 1");
        }
        for (field, v) in [
            ("firl.reward_lr", self.mlp_reward_lr),
            ("smirl.reward_lr", self.smirl_reward_lr),
        ] {
            if !positive(f64::from(v)) {
                return bad(field, "must be a positive number");
            }
        }
        for (field, v) in [
            ("firl.reward_l2", self.mlp_reward_l2),
            ("smirl.reward_l2", self.smirl_reward_l2),
        ] {
            if !non_negative(f64::from(v)) {
                return bad(field, "must be a non-negative number");
            }
        }
        if self.reward_steps_per_iteration == 0 {
            return bad("reward_steps_per_iteration", "must be at least 1");
        }
        if self.final_sac_steps > MAX_SAC_STEPS_PER_ITERATION {
            return over(
                "final.sac_steps",
                self.final_sac_steps,
                MAX_SAC_STEPS_PER_ITERATION,
            );
        }
        if self.final_checkpoints > MAX_FINAL_CHECKPOINTS {
            return over(
                "final.checkpoints",
                self.final_checkpoints,
                MAX_FINAL_CHECKPOINTS,
            );
        }
        match (self.final_sac_steps, self.final_checkpoints) {
            (0, 0) => {}
            (0, _) => return bad(
                "final.checkpoints",
                "needs [final] sac_steps > 0 (there is no final-policy phase to take them from)",
            ),
            (steps, k) if k == 0 || k > steps => {
                return bad(
                    "final.checkpoints",
                    &format!("must be in 1..={steps} ([final] sac_steps), got {k}"),
                )
            }
            _ => {}
        }
        if !positive(self.smooth_sigma) {
            return bad("smirl.smooth_sigma", "must be a positive number");
        }
        if !positive(self.kde_bandwidth) {
            return bad("firl.kde_bandwidth", "must be a positive number");
        }
        if self.lrm_max_states == 0 || self.lrm_steps == 0 || self.lrm_tabu_len == 0 {
            return bad(
                "lrm.max_states/lrm.steps/lrm.tabu_len",
                "must be at least 1",
            );
        }
        if self.threads == 0 {
            return bad("threads", "must be at least 1");
        }
        Ok(())
    }

    /// The SAC settings that are not keys stay the IRL runs' (a config built in code that
    /// changes one could not be written to its run directory and read back).
    fn validate_fixed_sac(&self, source_name: &str) -> Result<(), IrlConfigError> {
        let bad = |field: &str, problem: &str| invalid(source_name, field, problem);
        let fixed = irl_run_sac();
        for (field, same) in [
            ("hidden", self.sac.hidden == fixed.hidden),
            ("batch_size", self.sac.batch_size == fixed.batch_size),
            ("gamma", self.sac.gamma == fixed.gamma),
            ("tau", self.sac.tau == fixed.tau),
            (
                "target_entropy",
                self.sac.target_entropy == fixed.target_entropy,
            ),
            (
                "updates_per_step",
                self.sac.updates_per_step == fixed.updates_per_step,
            ),
            (
                "update_after",
                self.sac.update_after == self.sac.warmup_steps,
            ),
        ] {
            if !same {
                return bad(
                    &format!("sac.{field}"),
                    "is not a setting of a run: it is irl_run_sac()'s (update_after: warmup_steps)",
                );
            }
        }
        match self.sac.validate() {
            Err(crate::rl::sac::ConfigError::Invalid { field, problem }) => {
                return bad(&format!("sac.{field}"), &problem)
            }
            Err(e) => return bad("sac", &e.to_string()),
            Ok(()) => {}
        }
        Ok(())
    }

    /// Each schedule: the baselines' or a known algorithm's, and the settings it resolves to
    /// pass the same checks (an error names the schedule's key).
    fn validate_schedules(&self, source_name: &str) -> Result<(), IrlConfigError> {
        let bad = |field: &str, problem: &str| invalid(source_name, field, problem);
        // The baselines' table is checked over the run's keys alone, each algorithm's with the
        // baselines' beneath.
        for (name, schedule) in &self.schedule {
            let named = |e: IrlConfigError| match e {
                IrlConfigError::Invalid { field, problem, .. } => IrlConfigError::Invalid {
                    source_name: source_name.to_string(),
                    field,
                    problem,
                    line: None,
                },
                other => other,
            };
            let resolved = if name == BASELINES {
                let mut resolved = IrlRunConfig {
                    schedule: BTreeMap::new(),
                    ..self.clone()
                };
                resolved.apply_schedule(name, schedule).map_err(named)?;
                resolved
            } else {
                let algo = match Algo::parse_in(name, &Algo::REACHER) {
                    Ok(a) => a,
                    Err(e) => {
                        return bad(
                            &format!("schedule.{name}"),
                            &format!("{e} (or `{BASELINES}`, every baseline's)"),
                        )
                    }
                };
                self.for_algo(algo).map_err(named)?
            };
            if let Err(IrlConfigError::Invalid { field, problem, .. }) =
                resolved.validate(source_name)
            {
                return bad(&format!("schedule.{name}.{field}"), &problem);
            }
        }
        Ok(())
    }
}

/// A value of `source_name` out of its range, named by its key.
fn invalid<T>(source_name: &str, field: &str, problem: &str) -> Result<T, IrlConfigError> {
    Err(IrlConfigError::Invalid {
        source_name: source_name.to_string(),
        field: field.to_string(),
        problem: problem.to_string(),
        line: None,
    })
}
