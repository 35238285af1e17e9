//! What every IRL algorithm of the Reacher comparison does with the environment, in one place:
//! the environment SAC acts in ([`JobEnv`]), one episode with the ground truth tracked
//! alongside ([`play_episode`]), the SAC phase of an iteration ([`train_sac`]) and the
//! stochastic rollouts a reward update reads ([`RolloutStream`]). The algorithms
//! (`super::smirl`, `super::firl`) differ in the reward they hand to SAC and in what they do
//! with the rollouts, not in any of this.

use super::evaluation::JobWatch;
use crate::env::product::ProductEnv;
use crate::env::reacher::{ReacherDelivery, OBS_DIM};
use crate::env::reacher_task::{Branch, CancelBranch, TaskProgress};
use crate::env::{ContinuousEnv, EnvError, EnvStep};
use crate::irl::smirl::FeatureMap;
use crate::log::RolloutLogger;
use crate::pipeline::training_log::{ReacherView, TrainingLog};
use crate::rl::sac::{episode_seed, ActMode, RewardFn, SacAgent, SacTrainer, TrainingObserver};
use crate::rm::{LabelSet, RewardMachine};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

/// The environment an IRL job's SAC acts in: ReacherDelivery itself (the baselines) or its
/// product with the learned machine (SMIRL: observation ⊕ one-hot learned state).
pub trait JobEnv: ContinuousEnv + ReacherView {
    /// The learned machine's current state (SMIRL's product), `None` for the plain
    /// environment.
    fn learned_state(&self) -> Option<usize>;

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
    pub branches: Option<CancelBranch>,
}

impl<'a> GroundTruthTask<'a> {
    pub fn of(perfect: &'a RewardMachine) -> GroundTruthTask<'a> {
        GroundTruthTask {
            perfect,
            progress: TaskProgress::of(perfect),
            branches: CancelBranch::of(perfect),
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

/// Plays one episode. The perfect machine is tracked on the labels for the ground truth;
/// `on_step(inner o_t, inner o_{t+1}, learned u_t)` sees every step.
pub fn play_episode<E: JobEnv>(
    agent: &mut SacAgent,
    env: &mut E,
    task: &GroundTruthTask<'_>,
    spec: EpisodeSpec<'_>,
    rng: &mut ChaCha8Rng,
    mut logger: Option<&mut RolloutLogger>,
    mut on_step: impl FnMut(&[f32], &[f32], Option<usize>),
) -> Result<EpisodeOutcome, String> {
    let perfect = task.perfect;
    let branches = task.branches.as_ref().filter(|_| spec.with_branch);
    let mut obs = vec![0.0f32; env.obs_dim()];
    let mut next = vec![0.0f32; env.obs_dim()];
    let mut action = vec![0.0f32; env.act_dim()];
    env.reset(spec.reset_seed, &mut obs);
    let mut up = perfect.initial();
    let mut out = EpisodeOutcome::default();
    let mut tracker = task.progress.start(up);
    let mut cancelled = branches.is_some_and(|b| b.is_cancelled(up));
    if let Some(l) = logger.as_mut() {
        l.begin_reacher_episode(
            env.reacher(),
            spec.reset_seed,
            spec.phase,
            Some(up),
            &obs[..OBS_DIM],
        )
        .map_err(|e| e.to_string())?;
    }
    let max_steps = env.reacher().config().max_steps;
    for _ in 0..max_steps {
        agent.act(&obs, spec.mode, rng, &mut action);
        let u_before = env.learned_state();
        let (step, env_reward) = env
            .step_with_env_reward(&action, &mut next)
            .map_err(|e| e.to_string())?;
        let (u_next, r) = perfect.step(up, step.labels);
        task.progress.track(&mut tracker, up, u_next, step.labels);
        up = u_next;
        cancelled |= branches.is_some_and(|b| b.is_cancelled(up));
        out.task_return += r;
        out.env_return += env_reward;
        out.success |= perfect.is_terminal(up) && !perfect.is_failure(up);
        if let Some(l) = logger.as_mut() {
            let inner = env.inner_step(&step);
            l.reacher_step(
                env.reacher(),
                &action,
                &inner,
                Some((up, r)),
                &next[..OBS_DIM],
            )
            .map_err(|e| e.to_string())?;
        }
        on_step(&obs[..OBS_DIM], &next[..OBS_DIM], u_before);
        std::mem::swap(&mut obs, &mut next);
        let decided = perfect.is_terminal(up) || perfect.is_failure(up);
        if step.terminated || step.truncated || (spec.stop_when_decided && decided) {
            break;
        }
    }
    if let Some(l) = logger.as_mut() {
        l.end_episode(out.success).map_err(|e| e.to_string())?;
    }
    out.progress = tracker.fraction();
    out.final_ball = tracker.touched_final_ball();
    out.branch = branches.map(|_| {
        if cancelled {
            Branch::Cancelled
        } else {
            Branch::Normal
        }
    });
    Ok(out)
}

/// Phase 1 of an IRL iteration: `steps` more SAC environment steps on `reward` (the reward the
/// algorithm is learning), SAC's own episodes logged under "train"; then the episode in
/// progress is played to its end. (Rollouts and evaluation reset the same environment, and
/// SAC must not resume an episode from the state the last evaluation left it in; with
/// 100-step episodes and a budget that is a multiple of 100, as in the shipped profiles,
/// there is nothing to finish.)
pub fn train_sac<E: JobEnv, R: RewardFn>(
    sac: &mut SacTrainer,
    env: &mut E,
    reward: &mut R,
    steps: u64,
    iteration: usize,
    watch: &mut JobWatch<'_, '_>,
) -> Result<(), String> {
    let before = sac.env_steps();
    let chunk = 1_000u64;
    let mut done = 0;
    let perfect = watch.perfect();
    let (logger, report_progress) = watch.sac_phase(iteration);
    // One observer for the whole phase: it holds the logged episode in progress across chunks.
    let mut train_log = logger.map(|l| TrainingLog::new(l, perfect, "train"));
    while done < steps || !sac.at_episode_boundary() {
        let n = if done < steps {
            chunk.min(steps - done)
        } else {
            1
        };
        let observer = train_log
            .as_mut()
            .map(|t| t as &mut dyn TrainingObserver<E>);
        sac.train_observed(env, reward, n, observer, |_| {})
            .map_err(|e| format!("SAC: {e}"))?;
        done += n;
        report_progress(before + done);
    }
    Ok(())
}

/// Agent trajectories as a reward update reads them.
#[derive(Clone, Debug, Default)]
pub struct AgentBatch {
    /// o_1..o_T of every trajectory, row-major, `OBS_DIM` wide.
    pub obs: Vec<f32>,
    /// The labels of o_0..o_{T−1}, the observation before each step, by the labelling rule
    /// on the observation (`FeatureMap::labels_of`), for rewards of the step rather than of
    /// the state (SMIRL's label entries).
    pub labels_before: Vec<LabelSet>,
    /// The learned machine's state paired with each observation (SMIRL; else empty).
    pub states: Vec<u32>,
    pub lengths: Vec<usize>,
}

impl AgentBatch {
    /// Number of observation rows.
    pub fn n_states(&self) -> usize {
        self.obs.len() / OBS_DIM
    }

    /// Appends one step: the observations before and after it, and the learned state;
    /// `labelling` reads the labels before the step.
    pub fn push_step(
        &mut self,
        labelling: &FeatureMap,
        before: &[f32],
        after: &[f32],
        learned_state: Option<usize>,
    ) {
        self.obs.extend_from_slice(after);
        self.labels_before.push(labelling.labels_of(before));
        if let Some(u) = learned_state {
            self.states.push(u as u32);
        }
    }
}

/// Fresh trajectories of the current stochastic policy, the sample each reward update reads.
/// Reset seeds come from their own stream (counted across iterations) and actions draw from
/// their own generator, so rollouts never perturb SAC's random stream.
pub struct RolloutStream {
    seed: u64,
    next: u64,
    rng: ChaCha8Rng,
}

impl RolloutStream {
    pub fn new(seed: u64) -> RolloutStream {
        RolloutStream {
            seed: seed ^ 0x7261_6e64,
            next: 0,
            rng: ChaCha8Rng::seed_from_u64(episode_seed(seed, 0x0a11_0a11)),
        }
    }

    /// Phase 2 of an IRL iteration: `n` episodes to the time limit, each observation with the
    /// learned state its labels are read in (SMIRL), logged under "agent" and shown to the
    /// watch.
    pub fn collect<E: JobEnv>(
        &mut self,
        agent: &mut SacAgent,
        env: &mut E,
        n: usize,
        watch: &mut JobWatch<'_, '_>,
    ) -> Result<AgentBatch, String> {
        let mut batch = AgentBatch::default();
        let task = GroundTruthTask::of(watch.perfect());
        let labelling = FeatureMap::reacher_labels();
        for _ in 0..n {
            let reset_seed = episode_seed(self.seed, self.next);
            self.next += 1;
            let spec = EpisodeSpec {
                mode: ActMode::Sample,
                reset_seed,
                stop_when_decided: false,
                with_branch: false,
                phase: "agent",
            };
            let mut len = 0;
            play_episode(
                agent,
                env,
                &task,
                spec,
                &mut self.rng,
                watch.logger(),
                |before, after, u| {
                    batch.push_step(&labelling, before, after, u);
                    len += 1;
                },
            )?;
            batch.lengths.push(len);
        }
        watch.rollouts(&batch)?;
        Ok(batch)
    }
}
