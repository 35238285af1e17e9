//! The run configuration of `reacher --task`: one TOML file, every top-level field required
//! (a missing or mistyped field is an error naming it), the `env` and `sac` tables default
//! field-wise to the environment's values and to [`irl_run_sac`]. Optional
//! `[schedule.<algorithm>]` tables give one algorithm its own IRL schedule ([`AlgoSchedule`]).

use super::Algo;
use crate::env::reacher::ReacherConfig;
use crate::irl::firl::DensityRatio;
use crate::irl::smirl::{LabelFeatures, SmirlNormalisation};
use crate::rl::sac::SacConfig;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

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
    /// One state and no transitions: the control of issue 54 (item 4), SMIRL with every other
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

    pub fn is_learned(&self) -> bool {
        *self == SmirlMachine::Learned
    }
}

/// How demonstrations that end before the time limit (at the task's goal) are compared
/// with agent rollouts, which always run `env.max_steps` steps.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum DemoPadding {
    /// Extend every demonstration to `env.max_steps` steps by holding its final state (arm
    /// at rest where the expert finished, no cancel event): the fixed horizon T that MaxEnt
    /// IRL and f-IRL assume. Without it the learned reward is pushed down wherever the agent
    /// stays after finishing the task (see experiments/reacher/results.md).
    Hold,
    /// Use the demonstrations as recorded (shorter than the agent's rollouts).
    None,
}

impl DemoPadding {
    pub fn name(self) -> &'static str {
        match self {
            DemoPadding::Hold => "hold",
            DemoPadding::None => "none",
        }
    }
}

/// Settings of a `reacher --task` run (see the module docs of [`super`] for what each
/// phase does).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct IrlRunConfig {
    /// `"expert"` or `"scripted"`.
    pub demo_source: DemoSource,
    /// Directory of cached expert policies (`expert_<task>.policy`); relative paths are
    /// relative to the working directory. Empty: the committed experts
    /// (`experiments/experts/cache`, built into the binary).
    pub expert_cache_dir: PathBuf,
    /// Number of demonstrations (the paper: 16).
    pub demo_episodes: usize,
    /// `"hold"` (pad demonstrations to the time limit by holding the final state) or
    /// `"none"`.
    pub demo_padding: DemoPadding,
    /// IRL iterations M (one reward update each).
    pub irl_iterations: usize,
    /// SAC environment steps per IRL iteration K (SAC continues across iterations).
    pub sac_steps_per_iteration: u64,
    /// Fresh agent trajectories per iteration for the reward update (each `env.max_steps`
    /// long for the baselines, whose f-IRL covariance needs a fixed horizon).
    pub agent_trajectories: usize,
    /// Ground-truth evaluation episodes per IRL iteration (mean action, fixed seeds).
    pub eval_episodes: u64,
    /// Adam learning rate of the baselines' (64, 64) reward net.
    #[serde(serialize_with = "crate::short_float::f32")]
    pub mlp_reward_lr: f32,
    /// L2 penalty (weight decay) of the reward net.
    #[serde(serialize_with = "crate::short_float::f32")]
    pub mlp_reward_l2: f32,
    /// Adam learning rate of SMIRL's linear per-RM-state weights.
    #[serde(serialize_with = "crate::short_float::f32")]
    pub smirl_reward_lr: f32,
    /// L2 penalty of SMIRL's weights.
    #[serde(serialize_with = "crate::short_float::f32")]
    pub smirl_reward_l2: f32,
    /// `"visits"` (feature counts of each RM state averaged over the trajectories that visit
    /// it), `"trajectories"` (the plain MaxEnt average over all trajectories), or
    /// `"shared_visits"` / `"event_gated_visits"` (as `"visits"`, without the expert's pull on
    /// a state the agent's batch does not visit: every such state / only those that need the
    /// cancel to enter; see `irl::smirl::maxent_coefficients_by_shared_visits`).
    pub smirl_normalisation: SmirlNormalisation,
    /// The machine SMIRL reads: `"learned"` (LRM's) or `"task"` (the task's own, an oracle
    /// for diagnosis; see [`SmirlMachine`]). A config without the key is read as
    /// `"learned"`. Omitted from written configs when `"learned"`.
    #[serde(default, skip_serializing_if = "SmirlMachine::is_learned")]
    pub smirl_machine: SmirlMachine,
    /// `smirl`'s label features: `"state"` (L(o) of the state reached, paid on every step a
    /// label holds: the paper's eq. 5) or `"entries"` (the labels that became true on the
    /// step, paid once per entry into a ball). A config without the key is read as
    /// `"state"`, what every run before the key existed used.
    #[serde(default)]
    pub smirl_label_features: LabelFeatures,
    /// Strength β of SMIRL's potential-based shaping of SAC's reward (per metre, relative to
    /// the RM state's largest ball weight; see `irl::smirl::LearnedSubgoalPotential`); 0 = the
    /// learned reward alone.
    pub smirl_shaping: f64,
    /// SMIRL's final-policy phase (`final_policy`): SAC environment steps on the final learned
    /// reward, held fixed, after the last IRL iteration; 0 = none (every run before the key
    /// existed). Omitted from written configs when 0.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub smirl_final_sac_steps: u64,
    /// Candidates taken along the final-policy phase (evenly spaced, the last at its end),
    /// besides the co-trained policy.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub smirl_final_checkpoints: u64,
    /// Gradient updates, then as many SAC environment steps, of a reset agent after the
    /// co-trained (and fresh) agent's final phase: new networks, optimisers, temperature and
    /// seed on a copy of the co-trained agent's replay buffer, which it first learns from alone;
    /// `smirl_final_checkpoints` candidates along its steps; 0 = none (every run before the key
    /// existed). Why: a co-trained agent can stay stuck on the final reward while a fresh agent
    /// solves it (README, "Composite's five misses"); a reset keeps the loop's data and drops
    /// the networks' habit (README, "A reset agent", for what it did held out). Omitted from
    /// written configs when 0.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub smirl_final_reset_steps: u64,
    /// The final phase's choice reads each candidate's learned return only up to its first
    /// ball touch, after the cancel, that no demonstration makes after a cancel in the same
    /// learned state (`irl::seen_after_events`); training is unchanged. Why: a learned machine
    /// without a failure state lets a policy that touches blue after the cancel earn about
    /// what one that avoids it earns (README, "A choice that reads what the expert does after
    /// the cancel"). Without the phase (and for the baselines, which have none) it does
    /// nothing. False for every run before the key existed; omitted when false.
    #[serde(default, skip_serializing_if = "is_false")]
    pub smirl_selection_cut: bool,
    /// With `smirl_selection_cut`: a ball counts as touched on the step its touch begins, not
    /// on the steps the fingertip stays on it (an agent lingers on a ball the expert brushes,
    /// README "A choice that reads what the expert does after the cancel"). Refused without
    /// the cut; false for every run before the key existed; omitted when false.
    #[serde(default, skip_serializing_if = "is_false")]
    pub smirl_selection_cut_entries: bool,
    /// SMIRL's agent sees a clock: the product's observation gets one more entry, the share of
    /// the episode still to come (`ProductEnv::with_clock`), in the loop, the final phase and
    /// `reacher retrain`; the reward does not read it. Why: the cancel comes only early in an
    /// episode, and an agent without a clock cannot tell that it no longer will (README, "A
    /// clock for the agent": Composite 30 seed 30 and 39 seed 40 waited without a cancel).
    /// False for every run before the key existed; omitted when false.
    #[serde(default, skip_serializing_if = "is_false")]
    pub smirl_clock: bool,
    /// With `smirl_clock`: the clock entry stays at 1 (`ProductEnv::with_frozen_clock`), the
    /// clock's control — the same observation width and network initialisation, no time (README,
    /// "A frozen clock"). Refused without the clock; omitted when false.
    #[serde(default, skip_serializing_if = "is_false")]
    pub smirl_clock_frozen: bool,
    /// Share of each SAC batch of SMIRL that is relabelled to a counterfactual learned-machine
    /// state (CRM, see `rl::crm`): 0 = only the states the agent was in, 1 = every sampled
    /// transition from a uniformly drawn state.
    pub smirl_counterfactual: f64,
    /// Exponent p of the reward learning-rate schedule lr_k = lr · k^(−p) over IRL iterations
    /// k = 1, 2, … (every algorithm); 0 = constant.
    pub reward_lr_decay: f64,
    /// Reward optimiser steps per IRL iteration (on the same coefficients).
    pub reward_steps_per_iteration: usize,
    /// Width σ (m) of `smirl-smooth`'s features exp(−d²/2σ²).
    pub smooth_sigma: f64,
    /// Epanechnikov KDE bandwidth of f-IRL's fingertip densities (the paper: 0.02).
    pub kde_bandwidth: f64,
    /// f-IRL's density ratio: `"kde"` (KDEs of both state sets, the SMIRL paper's baselines)
    /// or `"discriminator"` (a classifier, f-IRL's code for an expert given by samples;
    /// `irl::discriminator`), or `"gaussian_expert"` (the expert's density a Gaussian KDE of
    /// bandwidth `kde_bandwidth`, no zeros; `irl::gaussian_kde`). Omitted from written configs when `"kde"`, so configs from
    /// before the key existed read and write unchanged.
    #[serde(default, skip_serializing_if = "DensityRatio::is_kde")]
    pub firl_density_ratio: DensityRatio,
    /// Demonstrations drawn for every f-IRL reward step and put in its covariance batch beside
    /// the agent's trajectories (f-IRL's `resample_episodes`: with replacement when more than
    /// there are demonstrations, else without); 0 = the agent's trajectories alone, the
    /// covariance of f-IRL's code for an expert given as a density and of every run before
    /// the key existed. Why: f-IRL's code for an expert given by samples does this (as many
    /// demonstrations as agent trajectories in its configs), and it is what raises the reward
    /// where the expert goes and the agent does not (README, "Positive controls"). Needs
    /// `demo_padding = "hold"` (the covariance wants trajectories of one length). Omitted from
    /// written configs when 0.
    #[serde(default, skip_serializing_if = "is_zero_usize")]
    pub firl_expert_trajectories: usize,
    /// LRM: most states of the learned machine (u_max).
    pub lrm_max_states: usize,
    /// LRM: tabu list length.
    pub lrm_tabu_len: usize,
    /// LRM: search steps.
    pub lrm_steps: usize,
    /// MCAP: log every n-th agent/evaluation episode of each job (demos are all logged);
    /// 0 disables rollout logging.
    pub log_every_nth_episode: u64,
    /// Worker threads running (algorithm, seed) jobs.
    pub threads: usize,
    #[serde(default)]
    pub env: ReacherConfig,
    /// SAC of every job; keys missing from the `[sac]` table come from [`irl_run_sac`]
    /// (or from the table's `preset`, as in [`SacConfig::from_toml`]).
    #[serde(default = "irl_run_sac", deserialize_with = "deserialize_irl_run_sac")]
    pub sac: SacConfig,
    /// Per-algorithm schedules, keyed by algorithm name (`[schedule.fkl]`): an algorithm
    /// with a table runs with those fields in place of the ones above; the others (and
    /// every field the table leaves out) use the run's. Empty: one schedule for all.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub schedule: BTreeMap<String, AlgoSchedule>,
}

/// The fields one algorithm may run with its own values of (`[schedule.<algorithm>]`): the
/// IRL schedule, the baselines' reward optimiser and KDE, rollout logging and SAC. What the
/// algorithms must share to be compared stays run-wide: the demonstrations, the environment
/// (episode length, cancel schedule) and the ground-truth evaluation.
///
/// Why: f-IRL's own code runs many short IRL iterations (800 × 300 SAC steps, 2 reward steps,
/// SAC with fixed α = 1) and fails even a one-ball control task under SMIRL's earlier 20 × 5 000
/// (README, "Positive controls"); each algorithm gets the schedule its positive control needs.
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
    #[serde(
        default,
        skip_serializing_if = "Option::is_none",
        serialize_with = "crate::short_float::option_f32"
    )]
    pub mlp_reward_lr: Option<f32>,
    #[serde(
        default,
        skip_serializing_if = "Option::is_none",
        serialize_with = "crate::short_float::option_f32"
    )]
    pub mlp_reward_l2: Option<f32>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub kde_bandwidth: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub firl_density_ratio: Option<DensityRatio>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub firl_expert_trajectories: Option<usize>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub log_every_nth_episode: Option<u64>,
    /// SAC keys that differ from the run's `[sac]` (which supplies the rest).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sac: Option<toml::Table>,
}

/// The baselines' schedule in the standard profile: f-IRL's own ReacherDraw settings at the
/// tasks' 100-step horizon — 800 IRL iterations of 300 SAC steps, 300 fresh trajectories (30 000
/// states) per reward update, 2 reward steps per iteration, no weight decay on the reward, SAC
/// lr 3e-3 with a fixed temperature of 1, 150 random steps first; every 100th episode logged.
/// The replay size is not the schedule's: it is the run's `[sac]` one, shared by every
/// algorithm ([`SHARED_SAC_KEYS`]). Chosen on the Markovian positive control "blue" (seeds
/// 0–2), never on the paper's tasks: with it fkl, js and MaxEnt solve "blue" in 3 of 3 seeds, with SMIRL's earlier 20 × 5 000
/// schedule the f-IRL variants in none (README, "Positive controls of the baselines").
/// rkl's also puts 300 drawn demonstrations in each covariance batch beside the 300 agent
/// trajectories (`firl_expert_trajectories`, f-IRL's code for demonstrations): without them rkl
/// fails "blue" under every setting tried, with them (at T = 30) it passes in 3 of 3 seeds.
pub fn firl_schedule(algo: Algo) -> AlgoSchedule {
    let mut sac = toml::Table::new();
    sac.insert("lr".into(), toml::Value::Float(0.003));
    sac.insert("alpha".into(), toml::Value::Float(1.0));
    sac.insert("auto_alpha".into(), toml::Value::Boolean(false));
    sac.insert("warmup_steps".into(), toml::Value::Integer(150));
    sac.insert("update_after".into(), toml::Value::Integer(150));
    AlgoSchedule {
        irl_iterations: Some(800),
        sac_steps_per_iteration: Some(300),
        agent_trajectories: Some(300),
        reward_steps_per_iteration: Some(2),
        mlp_reward_l2: Some(0.0),
        firl_expert_trajectories: (algo == Algo::Rkl).then_some(300),
        log_every_nth_episode: Some(100),
        sac: Some(sac),
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
/// the critics from chasing every reward update. Measured on SMIRL with held-out seeds in
/// experiments/reacher/results.md (the paper's values are the `paper_sac` ablation). 200 000
/// keeps every transition of a SMIRL job (150 000 loop steps and the final phase's 20 000) and
/// the last 200 000 of a baseline's 240 000 loop steps: with 100 000, SAC on a fixed learned
/// reward lost tasks it had solved once the buffer began dropping its oldest transitions
/// (experiments/reacher/retrain_agents.sh; experiments/reacher/ablations/replay_all.toml). One
/// value for every algorithm ([`SHARED_SAC_KEYS`]).
pub fn irl_run_sac() -> SacConfig {
    SacConfig {
        lr: 1e-3,
        replay_capacity: 200_000,
        ..SacConfig::irl()
    }
}

fn deserialize_irl_run_sac<'de, D: serde::Deserializer<'de>>(
    deserializer: D,
) -> Result<SacConfig, D::Error> {
    let table = toml::Table::deserialize(deserializer)?;
    SacConfig::from_table(table, irl_run_sac(), "[sac]").map_err(serde::de::Error::custom)
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
        /// Dotted key path (`sac.batch_size`, `env.max_steps`, `lrm_steps`).
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

/// Keys a run config no longer has, and why: a config that still sets one was written for a
/// learner that no longer exists, and is refused rather than read as something else.
pub const REMOVED_KEYS: [(&str, &str); 6] = [
    (
        "lrm_fallback_starts",
        "LRM has no fallback starts (they changed no development base towards the task's \
         machine more often than away from it: experiments/lrm/ablation.md)",
    ),
    (
        "lrm_initial_events",
        "initial events are part of smirl's LRM (docs/method.md)",
    ),
    (
        "lrm_guards",
        "smirl's LRM reads unseen label sets by its decision trees, smirl-paper's stays \
         (docs/method.md)",
    ),
    (
        "lrm_commute_events",
        "commuted events are part of smirl's LRM (docs/method.md)",
    ),
    (
        "lrm_event_stutter",
        "event stutter is part of smirl's LRM (docs/method.md)",
    ),
    (
        "lrm_predict_events",
        "smirl's LRM leaves the events out of its prediction, smirl-paper's predicts them \
         (docs/method.md)",
    ),
];

/// Refuses a top-level key of [`REMOVED_KEYS`] in `text` (a document that does not parse is
/// left to the parser's message).
fn refuse_removed_keys(text: &str, source_name: &str) -> Result<(), IrlConfigError> {
    let Ok(table) = text.parse::<toml::Table>() else {
        return Ok(());
    };
    match REMOVED_KEYS
        .iter()
        .find(|(key, _)| table.contains_key(*key))
    {
        Some((key, why)) => Err(IrlConfigError::Invalid {
            source_name: source_name.to_string(),
            field: key.to_string(),
            problem: format!("is no longer a setting: {why}; delete the line"),
            line: crate::config_text::key_line(text, key),
        }),
        None => Ok(()),
    }
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
/// evaluation episodes): trajectories × `env.max_steps`.
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
    /// The default profile: sized so that `reacher --task <t>` with the default algorithm set
    /// finishes in well under 20 minutes on 2 cores (README.md, "ReacherDelivery IRL").
    pub fn standard() -> IrlRunConfig {
        IrlRunConfig {
            demo_source: DemoSource::Expert,
            expert_cache_dir: PathBuf::new(),
            demo_episodes: 16,
            demo_padding: DemoPadding::Hold,
            // SMIRL's schedule: 30 IRL iterations (two of three Sequential tuning seeds first
            // solve the task in iterations 16-20), with potential-based shaping of its SAC
            // (Composite's normal branch: 3 of 3 tuning seeds against 1 of 3 without);
            // README, "SMIRL's settings".
            irl_iterations: 30,
            sac_steps_per_iteration: 5_000,
            agent_trajectories: 20,
            eval_episodes: 20,
            mlp_reward_lr: 1e-3,
            mlp_reward_l2: 1e-3,
            smirl_reward_lr: 0.1,
            smirl_reward_l2: 0.05,
            smirl_normalisation: SmirlNormalisation::EventGatedVisits,
            smirl_machine: SmirlMachine::Learned,
            smirl_label_features: LabelFeatures::State,
            smirl_shaping: 1.0,
            // SMIRL's final policy: four candidates 5 000 SAC steps apart on the final reward
            // (README, "SMIRL's final policy").
            smirl_final_sac_steps: 20_000,
            smirl_final_checkpoints: 4,
            // Four more from a reset agent on the co-trained agent's replay buffer (24 of 24
            // tuning jobs; README, "A reset agent").
            smirl_final_reset_steps: 20_000,
            // The choice reads no return earned after a touch, after the cancel, that no
            // demonstration makes there (24 of 24 tuning jobs; README, "A choice that reads
            // what the expert does after the cancel").
            smirl_selection_cut: true,
            // A ball counts on the step its touch begins (24 of 24 tuning jobs; an agent
            // lingers on a ball the expert brushes).
            smirl_selection_cut_entries: true,
            // The agent sees the episode's remaining time (24 of 24 tuning jobs, every miss of
            // the reset-agent standard held out solved: README, "A clock for the agent").
            smirl_clock: true,
            smirl_clock_frozen: false,
            smirl_counterfactual: 1.0,
            reward_lr_decay: 0.0,
            reward_steps_per_iteration: 5,
            smooth_sigma: 0.05,
            kde_bandwidth: 0.02,
            firl_density_ratio: DensityRatio::Kde,
            firl_expert_trajectories: 0,
            lrm_max_states: 10,
            lrm_tabu_len: 10_000,
            lrm_steps: 100,
            log_every_nth_episode: 10,
            threads: 2,
            env: ReacherConfig::default(),
            sac: irl_run_sac(),
            schedule: [Algo::MaxEnt, Algo::Fkl, Algo::Rkl, Algo::Js]
                .into_iter()
                .map(|a| (a.name().to_string(), firl_schedule(a)))
                .collect(),
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
            smirl_final_sac_steps: 2_000,
            smirl_final_checkpoints: 2,
            smirl_final_reset_steps: 2_000,
            // One short schedule for every algorithm: a smoke run, not the baselines' 800
            // iterations.
            schedule: BTreeMap::new(),
            ..IrlRunConfig::standard()
        }
    }

    /// Parses a TOML document; `source_name` (the file path) prefixes every message. A key
    /// of [`REMOVED_KEYS`] is refused, naming it and why.
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

    /// The settings `algo` runs with: the run's, with `algo`'s `[schedule.<algo>]` fields
    /// in their place (a control's: its baseline's, [`Algo::base`]). The schedules were checked by [`IrlRunConfig::validate`].
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
        let Some(s) = self.schedule.get(base.name()) else {
            return Ok(config);
        };
        let field = |name: &str| format!("schedule.{base}.{name}");
        macro_rules! take {
            ($($f:ident),*) => {$(
                if let Some(v) = s.$f {
                    config.$f = v;
                }
            )*};
        }
        take!(
            irl_iterations,
            sac_steps_per_iteration,
            agent_trajectories,
            reward_steps_per_iteration,
            mlp_reward_lr,
            mlp_reward_l2,
            kde_bandwidth,
            firl_density_ratio,
            firl_expert_trajectories,
            log_every_nth_episode
        );
        if let Some(table) = &s.sac {
            if let Some(key) = SHARED_SAC_KEYS.iter().find(|k| table.contains_key(**k)) {
                return Err(IrlConfigError::Invalid {
                    source_name: String::new(),
                    field: field(&format!("sac.{key}")),
                    problem: "is shared by every algorithm: set it in [sac], not per schedule"
                        .into(),
                    line: None,
                });
            }
            config.sac =
                SacConfig::from_table(table.clone(), self.sac.clone(), "").map_err(|e| {
                    IrlConfigError::Invalid {
                        source_name: String::new(),
                        field: field("sac"),
                        problem: e.to_string(),
                        line: None,
                    }
                })?;
        }
        Ok(config)
    }

    /// `smirl-paper`'s settings: every mechanism by which `smirl` departs from the paper
    /// (docs/method.md) at the paper's value — LRM's are not settings but the learner's
    /// (`smirl::lrm_config` of `Algo::SmirlPaper`) — MaxEnt's
    /// μ_D − μ_π averaged over trajectories, label features of the state, SAC on U × O without
    /// clock, counterfactual states or shaping, and no final phase, so the job reports its
    /// loop's own last policy. The schedule, SAC, the reward optimiser, the demonstrations, the
    /// machine's source and LRM's size and search budget stay the run's, so that the two
    /// algorithms differ by the mechanisms alone.
    fn set_paper_mechanisms(&mut self) {
        self.smirl_normalisation = SmirlNormalisation::Trajectories;
        self.smirl_label_features = LabelFeatures::State;
        self.smirl_clock = false;
        self.smirl_clock_frozen = false;
        self.smirl_counterfactual = 0.0;
        self.smirl_shaping = 0.0;
        self.smirl_final_sac_steps = 0;
        self.smirl_final_checkpoints = 0;
        self.smirl_final_reset_steps = 0;
        self.smirl_selection_cut = false;
        self.smirl_selection_cut_entries = false;
    }

    /// The expert cache directory; `None` (an empty `expert_cache_dir`) means the committed
    /// experts built into the binary.
    pub fn cache_dir(&self) -> Option<&Path> {
        (!self.expert_cache_dir.as_os_str().is_empty()).then_some(self.expert_cache_dir.as_path())
    }

    /// Checks value ranges (named by field).
    pub fn validate(&self, source_name: &str) -> Result<(), IrlConfigError> {
        let bad = |field: &str, problem: &str| {
            Err(IrlConfigError::Invalid {
                source_name: source_name.to_string(),
                field: field.to_string(),
                problem: problem.to_string(),
                line: None,
            })
        };
        // The environment first: the rollout limits below use its episode length.
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
                "lrm_max_states",
                self.lrm_max_states as u64,
                MAX_LRM_STATES as u64,
            ),
            ("lrm_steps", self.lrm_steps as u64, MAX_LRM_STEPS as u64),
            (
                "lrm_tabu_len",
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
                "firl_expert_trajectories",
                self.firl_expert_trajectories as u64,
            ),
            ("eval_episodes", self.eval_episodes),
        ] {
            let steps = episodes.saturating_mul(self.env.max_steps as u64);
            if steps > MAX_ROLLOUT_STEPS as u64 {
                return bad(
                    field,
                    &format!(
                        "× env.max_steps = {steps} steps per iteration, more than the limit of {MAX_ROLLOUT_STEPS}"
                    ),
                );
            }
        }
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
        if self.firl_expert_trajectories > 0 && self.demo_padding != DemoPadding::Hold {
            return bad(
                "firl_expert_trajectories",
                "needs demo_padding = \"hold\": the covariance batch wants demonstrations as \
                 long as the agent's trajectories",
            );
        }
        for (field, v) in [
            ("mlp_reward_lr", self.mlp_reward_lr),
            ("smirl_reward_lr", self.smirl_reward_lr),
        ] {
            if !positive(f64::from(v)) {
                return bad(field, "must be a positive number");
            }
        }
        for (field, v) in [
            ("mlp_reward_l2", self.mlp_reward_l2),
            ("smirl_reward_l2", self.smirl_reward_l2),
        ] {
            if !non_negative(f64::from(v)) {
                return bad(field, "must be a non-negative number");
            }
        }
        if self.reward_steps_per_iteration == 0 {
            return bad("reward_steps_per_iteration", "must be at least 1");
        }
        if !(self.reward_lr_decay.is_finite() && self.reward_lr_decay >= 0.0) {
            return bad("reward_lr_decay", "must be a non-negative number");
        }
        if !(self.smirl_shaping.is_finite() && self.smirl_shaping >= 0.0) {
            return bad("smirl_shaping", "must be a non-negative number");
        }
        if self.smirl_final_sac_steps > MAX_SAC_STEPS_PER_ITERATION {
            return over(
                "smirl_final_sac_steps",
                self.smirl_final_sac_steps,
                MAX_SAC_STEPS_PER_ITERATION,
            );
        }
        if self.smirl_final_checkpoints > MAX_FINAL_CHECKPOINTS {
            return over(
                "smirl_final_checkpoints",
                self.smirl_final_checkpoints,
                MAX_FINAL_CHECKPOINTS,
            );
        }
        match (self.smirl_final_sac_steps, self.smirl_final_checkpoints) {
            (0, 0) => {}
            (0, _) => {
                return bad(
                    "smirl_final_checkpoints",
                    "needs smirl_final_sac_steps > 0 (there is no final-policy phase to take them from)",
                )
            }
            (steps, k) if k == 0 || k > steps => {
                return bad(
                    "smirl_final_checkpoints",
                    &format!("must be in 1..={steps} (smirl_final_sac_steps), got {k}"),
                )
            }
            _ => {}
        }
        // The reset agent is one more agent of the final phase: it needs its checkpoints.
        let extra_agents = [("smirl_final_reset_steps", self.smirl_final_reset_steps)];
        for (field, steps) in extra_agents {
            if steps > MAX_SAC_STEPS_PER_ITERATION {
                return over(field, steps, MAX_SAC_STEPS_PER_ITERATION);
            }
            match (steps, self.smirl_final_checkpoints) {
                (0, _) => {}
                (_, 0) => {
                    return bad(
                        field,
                        "needs the final-policy phase (smirl_final_sac_steps and smirl_final_checkpoints > 0)",
                    )
                }
                (steps, k) if k > steps => {
                    return bad(
                        field,
                        &format!("must be at least smirl_final_checkpoints ({k}), got {steps}"),
                    )
                }
                _ => {}
            }
        }
        if self.smirl_selection_cut_entries && !self.smirl_selection_cut {
            return bad(
                "smirl_selection_cut_entries",
                "needs smirl_selection_cut = true (it says how the cut reads touches)",
            );
        }
        if self.smirl_clock_frozen && !self.smirl_clock {
            return bad(
                "smirl_clock_frozen",
                "needs smirl_clock = true (it freezes the clock's entry)",
            );
        }
        if !(0.0..=1.0).contains(&self.smirl_counterfactual) {
            return bad("smirl_counterfactual", "must be a number in [0, 1]");
        }
        if !positive(self.smooth_sigma) {
            return bad("smooth_sigma", "must be a positive number");
        }
        if !positive(self.kde_bandwidth) {
            return bad("kde_bandwidth", "must be a positive number");
        }
        if self.lrm_max_states == 0 || self.lrm_steps == 0 || self.lrm_tabu_len == 0 {
            return bad(
                "lrm_max_states/lrm_steps/lrm_tabu_len",
                "must be at least 1",
            );
        }
        if self.threads == 0 {
            return bad("threads", "must be at least 1");
        }
        match self.sac.validate() {
            Err(crate::rl::sac::ConfigError::Invalid { field, problem }) => {
                return bad(&format!("sac.{field}"), &problem)
            }
            Err(e) => return bad("sac", &e.to_string()),
            Ok(()) => {}
        }
        // Each schedule: a known algorithm, and the settings it resolves to pass the same
        // checks (an error names the schedule's key).
        for name in self.schedule.keys() {
            let algo = match Algo::parse_in(name, &Algo::REACHER) {
                Ok(a) => a,
                Err(e) => return bad(&format!("schedule.{name}"), &e),
            };
            let resolved = self.for_algo(algo).map_err(|e| match e {
                IrlConfigError::Invalid { field, problem, .. } => IrlConfigError::Invalid {
                    source_name: source_name.to_string(),
                    field,
                    problem,
                    line: None,
                },
                other => other,
            })?;
            if let Err(IrlConfigError::Invalid { field, problem, .. }) =
                resolved.validate(source_name)
            {
                return bad(&format!("schedule.{name}.{field}"), &problem);
            }
        }
        Ok(())
    }
}

fn is_zero(x: &u64) -> bool {
    *x == 0
}

fn is_zero_usize(x: &usize) -> bool {
    *x == 0
}

fn is_false(x: &bool) -> bool {
    !*x
}
