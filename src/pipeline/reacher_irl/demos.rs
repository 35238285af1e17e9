//! Demonstrations for the IRL runs: the task's SAC expert from the cache (the paper's
//! setting) or the scripted controller driven by the task's perfect machine. Both give the
//! expert helper's [`Demo`] type with the same episode rule: an episode ends when the perfect
//! machine reaches its goal or failure sink, or at the time limit.

use super::config::{DemoSource, IrlRunConfig};
use crate::env::product::ProductEnv;
use crate::env::reacher::{ReacherConfig, ReacherDelivery, ACT_DIM, BALLS, OBS_DIM};
use crate::env::reacher_controller::{ControllerGains, ScriptedController};
use crate::env::reacher_task::{ReacherTask, SubgoalPotential};
use crate::env::{ContinuousEnv, EnvStep};
use crate::log::{LogError, RolloutLogger};
use crate::pipeline::reacher_expert::{
    expert_cache_path, generate_demos, Demo, DemoStep, ExpertPolicy,
};
use crate::rl::sac::episode_seed;
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
    #[error("demonstrations: {0}")]
    Run(String),
    #[error(transparent)]
    Log(#[from] LogError),
}

/// Loads the cached expert of `task` (never trains here: training takes hours; run
/// `reacher expert --task <task>` first). A file of another task, architecture or format
/// version is refused.
pub fn load_expert(task: ReacherTask, cache_dir: &Path) -> Result<ExpertPolicy, DemoError> {
    let path = expert_cache_path(cache_dir, task);
    if !path.exists() {
        return Err(DemoError::Cache {
            path: path.display().to_string(),
            problem: format!(
                "no cached expert for task '{task}' (train it with `reacher expert --task \
                 {task}`, or set demo_source = \"scripted\")"
            ),
        });
    }
    let hidden = crate::rl::sac::SacConfig::expert().hidden;
    ExpertPolicy::load(&path, task, &hidden).map_err(|e| DemoError::Cache {
        path: path.display().to_string(),
        problem: e.to_string(),
    })
}

/// The demonstrations of a run: `config.demo_episodes` episodes from `config.demo_source`,
/// seeded by `seed`, each logged to `logger` when given. `expert` must be the loaded expert
/// when the source is `expert` (load it first with [`load_expert`] to fail early).
pub fn make_demos(
    task: ReacherTask,
    config: &IrlRunConfig,
    expert: Option<&mut ExpertPolicy>,
    seed: u64,
    logger: Option<&mut RolloutLogger>,
) -> Result<Vec<Demo>, DemoError> {
    match (config.demo_source, expert) {
        (DemoSource::Expert, Some(policy)) => generate_demos(
            policy,
            task,
            &config.env,
            config.demo_episodes,
            seed,
            logger,
        )
        .map_err(|e| DemoError::Run(e.to_string())),
        (DemoSource::Expert, None) => Err(DemoError::Run(
            "demo_source is \"expert\" but no expert policy was loaded".into(),
        )),
        (DemoSource::Scripted, _) => {
            scripted_demos(task, &config.env, config.demo_episodes, seed, logger)
        }
    }
}

/// `n` scripted demonstrations: at every step the controller aims at a ball that advances
/// the task's perfect machine (for a choice such as OR's red-or-green, one option drawn per
/// episode from the seed), holds still once the machine is done. Episode `i` is reset with
/// `episode_seed(seed, i)`.
pub fn scripted_demos(
    task: ReacherTask,
    env_config: &ReacherConfig,
    n: usize,
    seed: u64,
    mut logger: Option<&mut RolloutLogger>,
) -> Result<Vec<Demo>, DemoError> {
    let run = |e: String| DemoError::Run(e);
    let rm = task.perfect_rm().map_err(|e| run(e.to_string()))?;
    let potential = SubgoalPotential::from_rm(&rm);
    let inner = ReacherDelivery::new(env_config.clone()).map_err(|e| run(e.to_string()))?;
    let mut env = ProductEnv::new(inner, rm);
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x5c41_97ed_de30_0000);
    let mut obs = vec![0.0f32; env.obs_dim()];
    let mut demos = Vec::with_capacity(n);
    for i in 0..n {
        let ep_seed = episode_seed(seed, i as u64);
        env.reset(ep_seed, &mut obs);
        let pick: usize = rng.gen_range(0..BALLS.len());
        let choices: Vec<Vec<usize>> = (0..env.rm().n_states())
            .map(|u| potential.progress_balls(u).to_vec())
            .collect();
        let choose = move |_labels: LabelSet, u: Option<usize>| {
            let options = &choices[u?];
            (!options.is_empty()).then(|| options[pick % options.len()])
        };
        let mut ctl =
            ScriptedController::with_chooser(Box::new(choose), ControllerGains::default());
        let mut demo = Demo {
            seed: ep_seed,
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
                ep_seed,
                "demo",
                Some(env.rm_state()),
                env.inner_obs(),
            )?;
        }
        let mut labels = env.inner().labels();
        loop {
            let before: [f32; OBS_DIM] = env.inner_obs().try_into().expect("inner obs is 17");
            let action: [f32; ACT_DIM] = ctl.act(&before, labels, Some(env.rm_state()));
            let s = env
                .step_product(&action, &mut obs)
                .map_err(|e| run(format!("episode {i}: {e}")))?;
            labels = s.step.labels;
            if let Some(l) = logger.as_deref_mut() {
                let inner_step = EnvStep {
                    reward: s.env_reward,
                    ..s.step
                };
                l.reacher_step(
                    env.inner(),
                    &action,
                    &inner_step,
                    Some((s.rm_state, s.task_reward)),
                    env.inner_obs(),
                )?;
            }
            demo.steps.push(DemoStep {
                obs: before,
                action,
                next_obs: env.inner_obs().try_into().expect("inner obs is 17"),
                labels,
                rm_state: s.rm_state,
                env_reward: s.env_reward,
                task_reward: s.task_reward,
            });
            demo.task_return += s.task_reward;
            demo.env_return += s.env_reward;
            demo.success |= s.success;
            if s.step.terminated || s.step.truncated {
                break;
            }
        }
        if let Some(l) = logger.as_deref_mut() {
            l.end_episode(demo.success)?;
        }
        demos.push(demo);
    }
    Ok(demos)
}
