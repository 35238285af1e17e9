//! Demonstrations for the IRL runs: the task's SAC expert from the cache (the paper's
//! setting) or the scripted controller driven by the task's perfect machine. Both give the
//! expert helper's [`Demo`] type with the same episode rule: an episode ends when the perfect
//! machine reaches its goal or failure sink, or at the time limit.

use super::config::{DemoSource, IrlRunConfig};
use crate::env::product::ProductEnv;
use crate::env::reacher::{ConfigError, ReacherConfig, ReacherDelivery, ReacherError};
use crate::env::reacher_controller::{ControllerGains, ScriptedController};
use crate::env::reacher_task::{ReacherTask, SubgoalPotential};
use crate::env::ContinuousEnv;
use crate::env::EnvError;
use crate::log::{LogError, RolloutLogger};
use crate::pipeline::reacher_expert::ExpertError;
use crate::pipeline::reacher_expert::{
    committed_expert, default_expert_cache, expert_cache_path, generate_demos_from, record_episode,
    Demo, ExpertPolicy, RecordError,
};
use crate::rl::sac::episode_seed;
use crate::rm::format::RmFileError;
use crate::rm::LabelSet;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::path::Path;

/// Demonstrations that cannot be produced.
#[derive(Debug, thiserror::Error)]
pub enum DemoError {
    /// Bad input: a missing, foreign or stale expert cache file.
    #[error("expert cache {path}: {problem}")]
    Cache { path: String, problem: String },
    /// No expert in the cache yet (`reacher --task FILE` trains one).
    #[error("expert cache {path}: {problem}")]
    Missing { path: String, problem: String },
    /// The run's environment over the task's layout.
    #[error("demonstrations: {0}")]
    Env(ConfigError),
    /// Demonstrations from the expert policy.
    #[error("demonstrations: {0}")]
    Expert(ExpertError),
    #[error("demonstrations: demo_source is \"expert\" but no expert policy was loaded")]
    NoExpert,
    #[error("demonstrations: {0}")]
    PerfectMachine(RmFileError),
    #[error("demonstrations: {0}")]
    Arm(ReacherError),
    /// A scripted demonstration's step.
    #[error("demonstrations: episode {index}, step {step}: {source}")]
    Episode {
        index: usize,
        step: u64,
        source: EnvError,
    },
    #[error(transparent)]
    Log(#[from] LogError),
}

/// Loads the cached expert of `task` from `cache_dir`, or with `None` the committed one built
/// into the binary for a shipped task and the one in [`default_expert_cache`] for a task file
/// (never trains here: run `reacher expert --task <task>` for that). A file of another task,
/// architecture or format version is refused.
pub fn load_expert(task: ReacherTask, cache_dir: Option<&Path>) -> Result<ExpertPolicy, DemoError> {
    let hidden = crate::rl::sac::SacConfig::expert().hidden;
    let default_cache = default_expert_cache(&task);
    let Some(cache_dir) = cache_dir.or(default_cache.as_deref()) else {
        return committed_expert(task.clone(), &hidden).map_err(|e| DemoError::Cache {
            path: "experiments/experts/cache (built in)".into(),
            problem: e.to_string(),
        });
    };
    let path = expert_cache_path(cache_dir, task.clone());
    if !path.exists() {
        return Err(DemoError::Missing {
            path: path.display().to_string(),
            problem: format!(
                "no cached expert for task '{task}' (train it with `reacher expert --task \
                 {task}`, or set demo_source = \"scripted\")"
            ),
        });
    }
    ExpertPolicy::load(&path, task, &hidden).map_err(|e| DemoError::Cache {
        path: path.display().to_string(),
        problem: e.to_string(),
    })
}

/// The demonstrations of a run: `config.demo_episodes` episodes from `config.demo_source`,
/// reset as [`demo_reset_seeds`] says, seeded by `seed`, each logged to `logger` when given.
/// `expert` must be the loaded expert when the source is `expert` (load it first with
/// [`load_expert`] to fail early). The episodes run the config's environment over the task
/// ([`IrlRunConfig::over_task`]).
pub fn make_demos(
    task: ReacherTask,
    config: &IrlRunConfig,
    expert: Option<&mut ExpertPolicy>,
    seed: u64,
    logger: Option<&mut RolloutLogger>,
) -> Result<Vec<Demo>, DemoError> {
    let env = config.over_task(&task).map_err(DemoError::Env)?.env;
    let resets = demo_reset_seeds(config.demo_episodes, seed);
    match (config.demo_source, expert) {
        (DemoSource::Expert, Some(policy)) => {
            generate_demos_from(policy, task, &env, &resets, seed, logger)
                .map_err(DemoError::Expert)
        }
        (DemoSource::Expert, None) => Err(DemoError::NoExpert),
        (DemoSource::Scripted, _) => scripted_demos(task, &env, &resets, seed, logger),
    }
}

/// The reset seeds of `n` demonstrations: `episode_seed(seed, i)` for demonstration `i`, so
/// each draws its arm start, ball layout and cancel event like any episode and a logged
/// demonstration replays from its seed.
pub fn demo_reset_seeds(n: usize, seed: u64) -> Vec<u64> {
    (0..n as u64).map(|i| episode_seed(seed, i)).collect()
}

/// Scripted demonstrations, one from each of `reset_seeds`: at every step the controller aims
/// at a region that advances the task's perfect machine (for a choice such as OR's
/// red-or-green, one option drawn per episode from `seed`), holds still once the machine is
/// done.
pub fn scripted_demos(
    task: ReacherTask,
    env_config: &ReacherConfig,
    reset_seeds: &[u64],
    seed: u64,
    mut logger: Option<&mut RolloutLogger>,
) -> Result<Vec<Demo>, DemoError> {
    let rm = task.perfect_rm().map_err(DemoError::PerfectMachine)?;
    let inner = ReacherDelivery::new(env_config.clone()).map_err(DemoError::Arm)?;
    let potential = SubgoalPotential::from_rm(&rm, inner.layout());
    let (regions, obs_dim) = (inner.layout().n_regions(), inner.obs_dim());
    let mut env = ProductEnv::new(inner, rm);
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x5c41_97ed_de30_0000);
    let mut demos = Vec::with_capacity(reset_seeds.len());
    for (i, &reset_seed) in reset_seeds.iter().enumerate() {
        let pick: usize = rng.gen_range(0..regions.max(1));
        let choices: Vec<Vec<usize>> = (0..env.rm().n_states())
            .map(|u| potential.progress_balls(u).to_vec())
            .collect();
        let choose = move |_labels: LabelSet, u: Option<usize>| {
            let options = &choices[u?];
            (!options.is_empty()).then(|| options[pick % options.len()])
        };
        let mut ctl =
            ScriptedController::with_chooser(Box::new(choose), ControllerGains::default());
        let demo = record_episode(
            &mut env,
            reset_seed,
            "demo",
            logger.as_deref_mut(),
            |obs, labels, rm_state| ctl.act(&obs[..obs_dim], labels, Some(rm_state)),
        )
        .map_err(|e| match e {
            RecordError::Env { step, source } => DemoError::Episode {
                index: i,
                step,
                source,
            },
            RecordError::Log(e) => DemoError::Log(e),
        })?;
        demos.push(demo);
    }
    Ok(demos)
}
