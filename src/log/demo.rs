//! Scripted ReacherDelivery demonstrations written to a rollout log: the scripted controller
//! ([`crate::env::reacher_controller`]) visits a ball sequence in every episode. Used by
//! tests, the logging benchmark and `reacher demo`; not the paper's experts (SAC policies).

use super::{LogError, LogOptions, LogSummary, RolloutLogger, RunHeader};
use crate::env::reacher::{ReacherConfig, ReacherDelivery, OBS_DIM};
use crate::env::reacher_controller::{ControllerGains, ScriptedController};
use crate::env::ContinuousEnv;
use crate::rm::format::write_rm;
use crate::rm::RewardMachine;

/// What to demonstrate.
#[derive(Clone, Debug, PartialEq)]
pub struct DemoSpec {
    /// Task name recorded in the log.
    pub task: String,
    /// Balls to visit, as letters (`"rgby"` = Sequential).
    pub sequence: String,
    pub episodes: u64,
    /// Episode `i` is reset with seed `seed + i`.
    pub seed: u64,
    /// End an episode once the sequence is done (the task is complete) instead of running to
    /// the time limit.
    pub stop_when_done: bool,
    pub env: ReacherConfig,
    /// The task's reward machine, tracked along the episode and logged (state, reward);
    /// with it, an episode also ends when the machine reaches a terminal state.
    pub reward_machine: Option<RewardMachine>,
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
    let mut env = ReacherDelivery::new(spec.env.clone()).map_err(|e| usage(e.to_string()))?;
    let config = serde_json::json!({
        "env": spec.env,
        "demo": {"sequence": spec.sequence, "episodes": spec.episodes,
                 "stop_when_done": spec.stop_when_done},
    });
    let mut header = RunHeader::reacher_shipped(&spec.task, spec.seed, config);
    let rm = spec.reward_machine.as_ref();
    header.reward_machine = rm.map(write_rm);
    // A bad sequence is refused before the log file exists.
    let mut ctl = ScriptedController::from_letters(&spec.sequence, ControllerGains::default())
        .map_err(usage)?;
    let mut logger = RolloutLogger::create(path, header, options)?;
    let mut obs = vec![0.0f32; OBS_DIM];
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
                .map_err(|e| usage(format!("episode {i}: {e}")))?;
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
