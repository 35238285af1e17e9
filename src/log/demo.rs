//! Scripted ReacherDelivery demonstrations written to a rollout log: the scripted controller
//! ([`crate::env::reacher_controller`]) visits a ball sequence in every episode. Used by
//! tests, the logging benchmark and `reacher demo`; not the paper's experts (SAC policies).

use super::{LogError, LogOptions, LogSummary, RolloutLogger, RunHeader};
use crate::env::layout::TaskLayout;
use crate::env::reacher::{ReacherConfig, ReacherDelivery};
use crate::env::reacher_controller::{ControllerGains, ScriptedController};
use crate::env::reacher_task::ReacherTask;
use crate::env::ContinuousEnv;
use crate::rm::format::write_rm;
use crate::rm::RewardMachine;
use std::sync::Arc;

/// What to demonstrate.
#[derive(Clone, Debug, PartialEq)]
pub struct DemoSpec {
    /// The task (a shipped name or a task file's path) whose layout the demonstrations run
    /// in; recorded in the log.
    pub task: String,
    /// Regions to visit, as letters (`"rgby"` = Sequential).
    pub sequence: String,
    pub episodes: u64,
    /// Episode `i` is reset with seed `seed + i`.
    pub seed: u64,
    /// End an episode once the sequence is done (the task is complete) instead of running to
    /// the time limit.
    pub stop_when_done: bool,
    /// Settings over the task's own (`ReacherTask::env_config`).
    pub env: ReacherConfig,
    /// The chance that each of the task's events fires in an episode, within its own window;
    /// `None`: the task's own. The log records the layout with this chance, so it replays.
    pub event_probability: Option<f64>,
    /// The task's reward machine, tracked along the episode and logged (state, reward);
    /// with it, an episode also ends when the machine reaches a terminal state.
    pub reward_machine: Option<RewardMachine>,
}

/// Why `p` cannot be the chance of every event of `layout` (a chance, and a task that declares
/// an event), if it cannot.
pub fn check_event_probability(p: f64, layout: &TaskLayout) -> Result<(), String> {
    if layout.events.is_empty() {
        return Err("an event probability is given, but the task declares no event".into());
    }
    if !(0.0..=1.0).contains(&p) {
        return Err(format!("an event probability must be in [0, 1], got {p}"));
    }
    Ok(())
}

/// Runs the demonstrations and logs them to `path`.
pub fn log_scripted_demos(
    path: &std::path::Path,
    spec: &DemoSpec,
    options: LogOptions,
) -> Result<LogSummary, LogError> {
    let usage = |problem: String| LogError::Usage {
        path: path.into(),
        problem,
    };
    let task = ReacherTask::resolve(&spec.task).map_err(|e| usage(e.to_string()))?;
    let mut env_config = task
        .env_config(&spec.env)
        .map_err(|e| usage(e.to_string()))?;
    let mut layout = task.task().layout();
    if let Some(p) = spec.event_probability {
        check_event_probability(p, &layout).map_err(|e| usage(format!("{}: {e}", task.id())))?;
        for event in &mut layout.events {
            event.probability = p;
        }
        // A one-event task's resolved schedule is also the config's, which the environment
        // reads before the layout's.
        if let Some(cancel) = &mut env_config.cancel {
            cancel.probability = p;
        }
    }
    // The log records the schedule that runs: a one-event schedule the config sets (a
    // caller's `env.cancel`, or the task's own once resolved) replaces the layout's.
    if let ([only], Some(cancel)) = (layout.events.as_mut_slice(), &env_config.cancel) {
        cancel.schedule(only);
    }
    env_config.layout = Some(Arc::new(layout.clone()));
    let mut env = ReacherDelivery::new(env_config.clone()).map_err(|e| usage(e.to_string()))?;
    let config = serde_json::json!({
        "env": env_config,
        "demo": {"sequence": spec.sequence, "episodes": spec.episodes,
                 "stop_when_done": spec.stop_when_done},
    });
    let t = task.task();
    let mut header = RunHeader::reacher(
        task.id(),
        &layout,
        &t.text,
        &t.scene_xml,
        t.scene_files.clone(),
        spec.seed,
        config,
    );
    let rm = spec.reward_machine.as_ref();
    header.reward_machine = rm.map(write_rm);
    // A bad sequence is refused before the log file exists.
    let mut ctl =
        ScriptedController::from_letters(&spec.sequence, env.layout(), ControllerGains::default())
            .map_err(usage)?;
    let mut logger = RolloutLogger::create(path, header, options)?;
    let mut obs = vec![0.0f32; env.obs_dim()];
    for i in 0..spec.episodes {
        let seed = spec.seed.wrapping_add(i);
        env.reset(seed, &mut obs);
        ctl.restart();
        let mut u = rm.map(|m| m.initial());
        logger.begin_reacher_episode(&env, seed, "demo", u, &obs)?;
        let mut labels = env.labels();
        loop {
            let action = ctl.act(&obs, labels, u);
            let step = env
                .step(&action, &mut obs)
                .map_err(|e| LogError::Simulation {
                    path: path.into(),
                    problem: format!("episode {i}: {e}"),
                })?;
            labels = step.labels;
            let rm_step = rm.zip(u).map(|(m, state)| m.step(state, labels));
            u = rm_step.map(|(next, _)| next);
            logger.reacher_step(&env, &action, &step, rm_step, &obs)?;
            let rm_done = rm.zip(u).is_some_and(|(m, s)| m.is_terminal(s));
            if step.truncated || (spec.stop_when_done && (ctl.done() || rm_done)) {
                break;
            }
        }
        let success = match rm.zip(u) {
            Some((m, s)) => m.is_terminal(s) && !m.is_failure(s),
            None => ctl.done(),
        };
        logger.end_episode(success)?;
    }
    logger.finish()
}
