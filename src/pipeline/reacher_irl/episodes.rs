//! What every IRL algorithm of the Reacher comparison does with the environment, in one place:
//! the environment SAC acts in ([`JobEnv`]), one episode with the ground truth tracked
//! alongside ([`play_episode`]) and the agent's steps as a reward update reads them
//! ([`AgentBatch`]). The algorithms (`super::smirl`, `super::firl`) differ in the reward they
//! hand to SAC and in what they do with the rollouts, not in any of this.

use crate::env::layout::TaskLayout;
use crate::env::product::ProductEnv;
use crate::env::reacher::ReacherDelivery;
use crate::env::reacher_task::{Branch, EventBranch, ProgressTracker, TaskProgress};
use crate::env::{episode, ContinuousEnv, EnvError, EnvStep};
use crate::log::writer::EpisodeStartRecord;
use crate::log::{LogError, RolloutLogger, StepRecord};
use crate::pipeline::training_log::ReacherView;
use crate::rl::sac::{ActMode, SacAgent};
use crate::rm::{LabelSet, RewardMachine};
use rand_chacha::ChaCha8Rng;

/// An episode that cannot be played or logged: the environment's step or the log writer
/// failed (the message is theirs).
#[derive(Debug, thiserror::Error)]
pub enum EpisodeError {
    #[error(transparent)]
    Env(#[from] EnvError),
    #[error(transparent)]
    Log(#[from] LogError),
}

/// The environment an IRL job's SAC acts in: ReacherDelivery itself (the baselines), or its
/// product with the learned machine (SMIRL: observation ⊕ one-hot learned state).
pub trait JobEnv: ContinuousEnv + ReacherView + Send {
    /// The learned machine's current state (SMIRL's product), `None` for the plain
    /// environment.
    fn learned_state(&self) -> Option<usize>;

    /// A new environment of the same model and configuration, for playing episodes side by
    /// side (`super::lockstep`); `None` when it cannot be made.
    fn fresh(&self) -> Option<Self>
    where
        Self: Sized;

    /// Every episode runs to the time limit (nothing in the environment ends one earlier).
    fn ends_only_at_time_limit(&self) -> bool;

    /// One step, with ReacherDelivery's own (distance) reward beside the step the agent sees
    /// (the product's step reward is its machine's).
    fn step_with_env_reward(
        &mut self,
        action: &[f32],
        obs: &mut [f32],
    ) -> Result<(EnvStep, f64), EnvError>;
}

impl JobEnv for ReacherDelivery {
    fn learned_state(&self) -> Option<usize> {
        None
    }

    fn fresh(&self) -> Option<Self> {
        self.twin().ok()
    }

    fn ends_only_at_time_limit(&self) -> bool {
        // ReacherDelivery's step never sets `terminated`.
        true
    }

    fn step_with_env_reward(
        &mut self,
        action: &[f32],
        obs: &mut [f32],
    ) -> Result<(EnvStep, f64), EnvError> {
        self.step(action, obs).map(|s| (s, s.reward))
    }
}

impl JobEnv for ProductEnv<ReacherDelivery> {
    fn learned_state(&self) -> Option<usize> {
        Some(self.rm_state())
    }

    fn fresh(&self) -> Option<Self> {
        self.inner().fresh().map(|inner| self.around(inner))
    }

    fn ends_only_at_time_limit(&self) -> bool {
        // The product ends an episode when its machine enters a terminal or failure state; the
        // machines SMIRL and the product controls learn in have neither (LRM's,
        // `smirl::task_machine`, `smirl::one_state_machine`).
        let rm = self.rm();
        let ends = (0..rm.n_states()).any(|u| rm.is_absorbing(u));
        !ends && self.inner().ends_only_at_time_limit()
    }

    fn step_with_env_reward(
        &mut self,
        action: &[f32],
        obs: &mut [f32],
    ) -> Result<(EnvStep, f64), EnvError> {
        self.step_product(action, obs)
            .map(|s| (s.step, s.env_reward))
    }
}

/// Ground-truth outcome of one episode.
#[derive(Clone, Copy, Debug, Default)]
pub struct EpisodeOutcome {
    pub success: bool,
    /// Fraction of the sub-goals completed (see `TaskProgress`).
    pub progress: f64,
    /// A ball that can end the task was touched.
    pub final_ball: bool,
    /// The branch taken, for a conditional task.
    pub branch: Option<Branch>,
    pub task_return: f64,
    pub env_return: f64,
}

/// The task's ground truth, tracked along an episode's labels: the perfect machine, the
/// sub-goal progress along it and, for a conditional task, which branch the trace takes.
pub struct GroundTruthTask<'a> {
    pub perfect: &'a RewardMachine,
    pub progress: TaskProgress,
    pub branches: Option<EventBranch>,
}

impl<'a> GroundTruthTask<'a> {
    pub fn of(perfect: &'a RewardMachine, layout: &TaskLayout) -> GroundTruthTask<'a> {
        GroundTruthTask {
            perfect,
            progress: TaskProgress::of(perfect, layout),
            branches: EventBranch::of(perfect, layout.events()),
        }
    }
}

/// How [`play_episode`] plays.
#[derive(Clone, Copy, Debug)]
pub struct EpisodeSpec<'p> {
    pub mode: ActMode,
    pub reset_seed: u64,
    /// End the episode once the perfect machine reaches its goal or failure sink
    /// (evaluation); rollouts run to the time limit.
    pub stop_when_decided: bool,
    /// Also report the branch of a conditional task.
    pub with_branch: bool,
    /// Log the episode under this phase ("agent", "eval").
    pub phase: &'p str,
}

/// Where an episode's log records go: straight into the job's logger (one episode at a time),
/// into a [`RecordedEpisode`] (episodes played in lockstep, written in order afterwards), or
/// nowhere.
pub trait EpisodeLog {
    /// The episode starts in `env`, just reset with `seed`.
    fn begin(
        &mut self,
        env: &ReacherDelivery,
        seed: u64,
        phase: &str,
        rm_state: Option<usize>,
        obs: &[f32],
    ) -> Result<(), EpisodeError>;
    /// A step of `env` (state read after it).
    fn step(
        &mut self,
        env: &ReacherDelivery,
        action: &[f32],
        step: &EnvStep,
        rm: Option<(usize, f64)>,
        obs: &[f32],
    ) -> Result<(), EpisodeError>;
    fn end(&mut self, success: bool) -> Result<(), EpisodeError>;
}

/// No log.
pub struct NoLog;

impl EpisodeLog for NoLog {
    fn begin(
        &mut self,
        _: &ReacherDelivery,
        _: u64,
        _: &str,
        _: Option<usize>,
        _: &[f32],
    ) -> Result<(), EpisodeError> {
        Ok(())
    }
    fn step(
        &mut self,
        _: &ReacherDelivery,
        _: &[f32],
        _: &EnvStep,
        _: Option<(usize, f64)>,
        _: &[f32],
    ) -> Result<(), EpisodeError> {
        Ok(())
    }
    fn end(&mut self, _: bool) -> Result<(), EpisodeError> {
        Ok(())
    }
}

impl EpisodeLog for Option<&mut RolloutLogger> {
    fn begin(
        &mut self,
        env: &ReacherDelivery,
        seed: u64,
        phase: &str,
        rm_state: Option<usize>,
        obs: &[f32],
    ) -> Result<(), EpisodeError> {
        match self {
            Some(l) => l
                .begin_reacher_episode(env, seed, phase, rm_state, obs)
                .map(|_| ())
                .map_err(EpisodeError::from),
            None => Ok(()),
        }
    }

    fn step(
        &mut self,
        env: &ReacherDelivery,
        action: &[f32],
        step: &EnvStep,
        rm: Option<(usize, f64)>,
        obs: &[f32],
    ) -> Result<(), EpisodeError> {
        match self {
            Some(l) => l
                .reacher_step(env, action, step, rm, obs)
                .map_err(EpisodeError::from),
            None => Ok(()),
        }
    }

    fn end(&mut self, success: bool) -> Result<(), EpisodeError> {
        match self {
            Some(l) => l.end_episode(success).map_err(EpisodeError::from),
            None => Ok(()),
        }
    }
}

/// An episode's log records kept in memory, as [`RolloutLogger::begin_reacher_episode`],
/// [`RolloutLogger::reacher_step`] and [`RolloutLogger::end_episode`] would have received
/// them; [`RecordedEpisode::write_to`] hands them to a logger.
#[derive(Clone, Debug, Default)]
pub struct RecordedEpisode {
    seed: u64,
    phase: String,
    balls: Vec<f64>,
    event_steps: Vec<Option<usize>>,
    start_labels: LabelSet,
    start_rm: Option<usize>,
    nq: usize,
    nv: usize,
    /// The start's state and observation, then every step's, one after the other.
    qpos: Vec<f64>,
    qvel: Vec<f64>,
    obs: Vec<f32>,
    actions: Vec<f32>,
    steps: Vec<(EnvStep, Option<(usize, f64)>)>,
    success: Option<bool>,
}

impl RecordedEpisode {
    /// Writes the episode into `logger`, as if it had been logged while played.
    pub fn write_to(&self, logger: &mut RolloutLogger) -> Result<(), EpisodeError> {
        let (nq, nv) = (self.nq, self.nv);
        let obs_dim = self.obs.len() / (self.steps.len() + 1);
        let act_dim = self.actions.len() / self.steps.len().max(1);
        logger.begin_episode(&EpisodeStartRecord {
            seed: self.seed,
            phase: &self.phase,
            qpos: &self.qpos[..nq],
            qvel: &self.qvel[..nv],
            balls: &self.balls,
            event_steps: &self.event_steps,
            labels: self.start_labels,
            rm_state: self.start_rm,
            obs: &self.obs[..obs_dim],
        })?;
        for (t, (step, rm)) in self.steps.iter().enumerate() {
            let k = t + 1;
            logger.step(&StepRecord {
                action: &self.actions[t * act_dim..k * act_dim],
                reward: step.reward,
                labels: step.labels,
                rm: *rm,
                qpos: &self.qpos[k * nq..(k + 1) * nq],
                qvel: &self.qvel[k * nv..(k + 1) * nv],
                obs: &self.obs[k * obs_dim..(k + 1) * obs_dim],
                terminated: step.terminated,
                truncated: step.truncated,
            })?;
        }
        match self.success {
            Some(success) => logger.end_episode(success).map_err(EpisodeError::from),
            None => Ok(()),
        }
    }
}

impl EpisodeLog for RecordedEpisode {
    fn begin(
        &mut self,
        env: &ReacherDelivery,
        seed: u64,
        phase: &str,
        rm_state: Option<usize>,
        obs: &[f32],
    ) -> Result<(), EpisodeError> {
        *self = RecordedEpisode {
            seed,
            phase: phase.into(),
            balls: env.positions().iter().flatten().copied().collect(),
            event_steps: env.event_steps().to_vec(),
            start_labels: env.labels(),
            start_rm: rm_state,
            nq: env.qpos().len(),
            nv: env.qvel().len(),
            qpos: env.qpos().to_vec(),
            qvel: env.qvel().to_vec(),
            obs: obs.to_vec(),
            ..RecordedEpisode::default()
        };
        Ok(())
    }

    fn step(
        &mut self,
        env: &ReacherDelivery,
        action: &[f32],
        step: &EnvStep,
        rm: Option<(usize, f64)>,
        obs: &[f32],
    ) -> Result<(), EpisodeError> {
        self.qpos.extend_from_slice(env.qpos());
        self.qvel.extend_from_slice(env.qvel());
        self.obs.extend_from_slice(obs);
        self.actions.extend_from_slice(action);
        self.steps.push((*step, rm));
        Ok(())
    }

    fn end(&mut self, success: bool) -> Result<(), EpisodeError> {
        self.success = Some(success);
        Ok(())
    }
}

/// One episode being played, step by step: the ground truth tracked on the labels, the log
/// records written as it goes. [`play_episode`] plays one to its end; lockstep rollouts
/// (`super::lockstep`) play many side by side.
pub struct EpisodePlay<'t, 'p> {
    task: &'t GroundTruthTask<'t>,
    spec: EpisodeSpec<'p>,
    branches: Option<&'t EventBranch>,
    up: usize,
    tracker: ProgressTracker,
    cancelled: bool,
    out: EpisodeOutcome,
    steps: usize,
    max_steps: usize,
    ended: bool,
}

impl<'t, 'p> EpisodePlay<'t, 'p> {
    /// Starts the episode `env` was just reset to (with the spec's seed; first observation
    /// `obs`) and its log.
    pub fn begin<E: JobEnv>(
        env: &E,
        task: &'t GroundTruthTask<'t>,
        spec: EpisodeSpec<'p>,
        obs: &[f32],
        log: &mut dyn EpisodeLog,
    ) -> Result<EpisodePlay<'t, 'p>, EpisodeError> {
        let perfect = task.perfect;
        let branches = task.branches.as_ref().filter(|_| spec.with_branch);
        let up = perfect.initial();
        log.begin(
            env.reacher(),
            spec.reset_seed,
            spec.phase,
            Some(up),
            &obs[..env.reacher().obs_dim()],
        )?;
        let max_steps = env.reacher().config().max_steps;
        Ok(EpisodePlay {
            task,
            spec,
            branches,
            up,
            tracker: task.progress.start(up),
            cancelled: branches.is_some_and(|b| b.in_event_branch(up)),
            out: EpisodeOutcome::default(),
            steps: 0,
            max_steps,
            ended: max_steps == 0,
        })
    }

    /// The episode has ended (time limit, termination, or decided when the spec says so).
    pub fn ended(&self) -> bool {
        self.ended
    }

    /// Steps played so far.
    pub fn steps(&self) -> usize {
        self.steps
    }

    /// Plays `action`; the next observation goes into `next`. `on_step(inner o_{t+1},
    /// learned u_t)` sees the step.
    pub fn step<E: JobEnv>(
        &mut self,
        env: &mut E,
        action: &[f32],
        next: &mut [f32],
        log: &mut dyn EpisodeLog,
        mut on_step: impl FnMut(&[f32], Option<usize>),
    ) -> Result<(), EpisodeError> {
        let perfect = self.task.perfect;
        let u_before = env.learned_state();
        let (step, env_reward) = env.step_with_env_reward(action, next)?;
        let (u_next, r) = perfect.step(self.up, step.labels);
        (self.task.progress).track(&mut self.tracker, self.up, u_next, step.labels);
        self.up = u_next;
        self.cancelled |= self.branches.is_some_and(|b| b.in_event_branch(u_next));
        self.out.task_return += r;
        self.out.env_return += env_reward;
        self.out.success |= perfect.is_terminal(u_next) && !perfect.is_failure(u_next);
        let inner = env.inner_step(&step);
        let d = env.reacher().obs_dim();
        log.step(env.reacher(), action, &inner, Some((u_next, r)), &next[..d])?;
        on_step(&next[..d], u_before);
        self.steps += 1;
        let decided = perfect.is_terminal(u_next) || perfect.is_failure(u_next);
        self.ended = step.terminated
            || step.truncated
            || (self.spec.stop_when_decided && decided)
            || self.steps >= self.max_steps;
        Ok(())
    }

    /// Ends the log and reports the outcome.
    pub fn finish(self, log: &mut dyn EpisodeLog) -> Result<EpisodeOutcome, EpisodeError> {
        log.end(self.out.success)?;
        let mut out = self.out;
        out.progress = self.tracker.fraction();
        out.final_ball = self.tracker.touched_final_ball();
        out.branch = self.branches.map(|_| {
            if self.cancelled {
                Branch::Event
            } else {
                Branch::Normal
            }
        });
        Ok(out)
    }
}

/// Plays one episode. The perfect machine is tracked on the labels for the ground truth;
/// `on_step(inner o_{t+1}, learned u_t)` sees every step.
pub fn play_episode<E: JobEnv>(
    agent: &mut SacAgent,
    env: &mut E,
    task: &GroundTruthTask<'_>,
    spec: EpisodeSpec<'_>,
    rng: &mut ChaCha8Rng,
    logger: Option<&mut RolloutLogger>,
    mut on_step: impl FnMut(&[f32], Option<usize>),
) -> Result<EpisodeOutcome, EpisodeError> {
    let max_steps = env.reacher().config().max_steps as u64;
    let (play, mut log) = episode::play(
        env,
        spec.reset_seed,
        max_steps,
        |env, obs| {
            let mut log = logger;
            EpisodePlay::begin(env, task, spec, obs, &mut log).map(|play| (play, log))
        },
        |_, obs, action| agent.act(obs, spec.mode, rng, action),
        |(play, log), env, s| {
            play.step(env, s.action, s.next_obs, log, &mut on_step)?;
            Ok(play.ended())
        },
    )?;
    play.finish(&mut log)
}

/// Agent trajectories as a reward update reads them.
#[derive(Clone, Debug, Default)]
pub struct AgentBatch {
    /// o_1..o_T of every trajectory, row-major, one task observation wide.
    pub obs: Vec<f32>,
    /// The learned machine's state paired with each observation (SMIRL; else empty).
    pub states: Vec<u32>,
    pub lengths: Vec<usize>,
}

impl AgentBatch {
    /// Number of observation rows.
    pub fn n_states(&self) -> usize {
        self.lengths.iter().sum()
    }

    /// Appends `other`'s trajectories after this batch's.
    pub fn append(&mut self, other: AgentBatch) {
        self.obs.extend_from_slice(&other.obs);
        self.states.extend_from_slice(&other.states);
        self.lengths.extend_from_slice(&other.lengths);
    }

    /// Appends one step: the observation after it, and the learned state.
    pub fn push_step(&mut self, after: &[f32], learned_state: Option<usize>) {
        self.obs.extend_from_slice(after);
        if let Some(u) = learned_state {
            self.states.push(u as u32);
        }
    }
}
