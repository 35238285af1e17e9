//! What watches an IRL job without steering it ([`JobWatch`]): the ground-truth evaluation of
//! the policy after every iteration (the rows of `metrics.csv`), the final judgement on a
//! larger set of episodes of its own ([`final_set_episodes`]), how much of the agent's sample
//! lies where the expert's density is non-zero, the MCAP log of the job's episodes, and
//! progress reports. The algorithms call it at fixed points of their loops; nothing it
//! computes flows back into training (its episodes use their own random streams and reset
//! seeds).
//!
//! The final set: the loop's own final policy (after its last iteration) and every candidate
//! of the final phase are also judged on [`final_set_episodes`] episodes per branch, from a
//! reset-seed stream of their own ([`FINAL_SET_STREAM`]), disjoint from the per-iteration
//! evaluation's and from the selection episodes'. Only the watch holds those seeds: training
//! and the final phase's choice never see them, so the numbers a preregistered evaluation
//! reports are measured on episodes nothing in the job was tuned or stopped on, and on more of
//! them than the per-iteration curve needs.

use super::config::IrlRunConfig;
use super::episodes::{play_episode, AgentBatch, EpisodeSpec, GroundTruthTask, JobEnv};
use super::iteration::{JobProgress, MetricsRow, StepError};
use super::lockstep::{play_lockstep, Keep, Lockstep};
use crate::env::layout::TaskLayout;
use crate::env::reacher::{ReacherDelivery, OBS_TIP};
use crate::env::reacher_task::BranchTally;
use crate::env::ContinuousEnv;
use crate::irl::kde::Kde;
use crate::log::RolloutLogger;
use crate::rl::sac::{episode_seed, ActMode, SacAgent};
use crate::rm::RewardMachine;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use std::sync::Arc;

/// One ground-truth evaluation.
#[derive(Clone, Copy, Debug)]
pub struct Evaluation {
    /// Fraction of successful episodes; for a conditional task the lower branch rate.
    pub success_rate: f64,
    pub progress: f64,
    pub final_ball: f64,
    pub branches: Option<BranchTally>,
    pub task_return: f64,
    pub env_return: f64,
}

/// Reset seeds of a conditional task's evaluation: the first `per_branch` seeds of the
/// `eval_seed` stream whose reset schedules a cancel event and the first `per_branch` that
/// schedule none, in stream order. (The branch an episode takes is read from its trace
/// afterwards; with the default window (steps 1–8), which ends before the committed experts
/// touch blue, a scheduled cancel almost always means the cancel branch.) A schedule that
/// never (or always) cancels fills up with the next seeds of the stream, so there are always
/// `2 · per_branch` seeds.
pub fn stratified_eval_seeds(
    env: &mut ReacherDelivery,
    eval_seed: u64,
    per_branch: u64,
) -> Vec<u64> {
    let mut obs = vec![0.0f32; env.obs_dim()];
    let target = 2 * per_branch as usize;
    let mut counts = [0u64; 2];
    let mut chosen = Vec::with_capacity(target);
    let scan = 64 * per_branch;
    for i in 0..scan {
        let seed = episode_seed(eval_seed, i);
        env.reset(seed, &mut obs);
        let k = usize::from(env.event_steps().iter().any(Option::is_some));
        if counts[k] < per_branch {
            counts[k] += 1;
            chosen.push((i, seed));
        }
        if chosen.len() == target {
            break;
        }
    }
    let mut i = scan;
    while chosen.len() < target {
        chosen.push((i, episode_seed(eval_seed, i)));
        i += 1;
    }
    chosen.sort_unstable();
    chosen.into_iter().map(|(_, seed)| seed).collect()
}

/// The final set's episodes per branch at the standard `eval_episodes`
/// ([`STANDARD_EVAL_EPISODES`]); other configs scale it ([`final_set_episodes`]).
pub const FINAL_SET_EPISODES: u64 = 50;

/// The standard config's `eval_episodes`, at which the final set has [`FINAL_SET_EPISODES`]
/// per branch.
pub const STANDARD_EVAL_EPISODES: u64 = 20;

/// The final set's reset-seed stream within the job's seed (the per-iteration evaluation's is
/// `0xe7a1`, the selection episodes' `0x5e1e_c7ed`).
pub const FINAL_SET_STREAM: u64 = 0xf1a1_5e75;

/// Episodes per branch of the final set (a task without branches: in all):
/// [`FINAL_SET_EPISODES`] · `eval_episodes` / [`STANDARD_EVAL_EPISODES`], rounded up — 50 at
/// the standard 20, 20 at `--quick`'s 8 — so that a quick run's final judgement costs in
/// proportion to its evaluation. Why scaled rather than fixed: a fixed 50 would make the small
/// configs' final phase several times slower than their loop's evaluation.
pub fn final_set_episodes(settings: &IrlRunConfig) -> u64 {
    (FINAL_SET_EPISODES * settings.eval_episodes).div_ceil(STANDARD_EVAL_EPISODES)
}

/// A policy's ground-truth evaluation on the final set, as a job record stores it.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct FinalSetScore {
    /// Episodes played (per branch: `branches`).
    pub episodes: u64,
    /// Fraction of successful episodes; for a conditional task the lower branch rate.
    pub success_rate: f64,
    pub branches: Option<BranchTally>,
    pub progress: f64,
    pub final_ball: f64,
}

/// The ground-truth judge of a job: fixed evaluation episodes (the mean action, from the same
/// reset seeds every time, each ended once the task is decided) scored by the perfect machine.
pub struct GroundTruth<'r> {
    task: GroundTruthTask<'r>,
    layout: Arc<TaskLayout>,
    eval_seed: u64,
    eval_seeds: Vec<u64>,
}

impl<'r> GroundTruth<'r> {
    /// `eval_episodes` evaluation episodes, or for a conditional task (IF, Composite) that many
    /// per branch (seeds stratified by the cancel schedule).
    pub fn new(
        perfect: &'r RewardMachine,
        env: &mut ReacherDelivery,
        seed: u64,
        eval_episodes: u64,
    ) -> GroundTruth<'r> {
        Self::of_stream(perfect, env, episode_seed(seed, 0xe7a1), eval_episodes)
    }

    /// The final set of the job of seed `seed`: `per_branch` episodes per branch
    /// ([`final_set_episodes`]) from the stream [`FINAL_SET_STREAM`].
    pub fn final_set(
        perfect: &'r RewardMachine,
        env: &mut ReacherDelivery,
        seed: u64,
        per_branch: u64,
    ) -> GroundTruth<'r> {
        Self::of_stream(
            perfect,
            env,
            episode_seed(seed, FINAL_SET_STREAM),
            per_branch,
        )
    }

    /// `per_branch` episodes per branch (a task without branches: in all) from the reset seeds
    /// of `eval_seed`'s stream.
    fn of_stream(
        perfect: &'r RewardMachine,
        env: &mut ReacherDelivery,
        eval_seed: u64,
        eval_episodes: u64,
    ) -> GroundTruth<'r> {
        let layout = Arc::clone(env.layout());
        let task = GroundTruthTask::of(perfect, &layout);
        let eval_seeds = match task.branches {
            Some(_) => stratified_eval_seeds(env, eval_seed, eval_episodes),
            None => (0..eval_episodes)
                .map(|i| episode_seed(eval_seed, i))
                .collect(),
        };
        GroundTruth {
            task,
            layout,
            eval_seed,
            eval_seeds,
        }
    }

    /// The reset seeds of the evaluation episodes.
    pub fn reset_seeds(&self) -> &[u64] {
        &self.eval_seeds
    }

    /// The task's ground truth.
    pub fn task(&self) -> &GroundTruthTask<'r> {
        &self.task
    }

    /// Plays the evaluation episodes with `agent`'s mean action in `env`.
    pub fn evaluate<E: JobEnv>(
        &self,
        agent: &mut SacAgent,
        env: &mut E,
        logger: Option<&mut RolloutLogger>,
    ) -> Result<Evaluation, StepError> {
        self.evaluate_logged_as(agent, env, logger, "eval", None)
    }

    /// [`GroundTruth::evaluate`], the episodes logged under `phase`; played in lockstep by
    /// `plan` when given and `env` can be copied (the same episodes either way).
    pub fn evaluate_logged_as<E: JobEnv>(
        &self,
        agent: &mut SacAgent,
        env: &mut E,
        mut logger: Option<&mut RolloutLogger>,
        phase: &str,
        plan: Option<Lockstep<'_>>,
    ) -> Result<Evaluation, StepError> {
        let specs: Vec<EpisodeSpec<'_>> = (self.eval_seeds.iter())
            .map(|&reset_seed| EpisodeSpec {
                mode: ActMode::Mean,
                reset_seed,
                stop_when_decided: true,
                with_branch: true,
                phase,
            })
            .collect();
        let mut outcomes = Vec::with_capacity(specs.len());
        match plan.filter(|_| env.fresh().is_some()) {
            Some(plan) => {
                let keep = Keep {
                    log: logger.is_some(),
                    steps: false,
                };
                let played =
                    play_lockstep(&agent.actor, env, &self.task, &specs, None, plan, keep)?;
                for p in played {
                    if let (Some(logger), Some(log)) = (logger.as_deref_mut(), &p.log) {
                        log.write_to(logger)?;
                    }
                    outcomes.push(p.outcome);
                }
            }
            None => {
                // The mean action draws no noise.
                let mut rng = ChaCha8Rng::seed_from_u64(self.eval_seed);
                for spec in specs {
                    outcomes.push(play_episode(
                        agent,
                        env,
                        &self.task,
                        spec,
                        &mut rng,
                        logger.as_deref_mut(),
                        |_, _| {},
                    )?);
                }
            }
        }
        let (mut succ, mut ret, mut env_ret) = (0.0, 0.0, 0.0);
        let (mut progress, mut final_ball) = (0.0, 0.0);
        let mut tally = BranchTally::default();
        for o in outcomes {
            succ += f64::from(u8::from(o.success));
            progress += o.progress;
            final_ball += f64::from(u8::from(o.final_ball));
            ret += o.task_return;
            env_ret += o.env_return;
            if let Some(b) = o.branch {
                tally.add(b, o.success);
            }
        }
        let n = self.eval_seeds.len() as f64;
        let branches = self.task.branches.as_ref().map(|_| tally);
        Ok(Evaluation {
            success_rate: branches.and_then(|t| t.worst_rate()).unwrap_or(succ / n),
            progress: progress / n,
            final_ball: final_ball / n,
            branches,
            task_return: ret / n,
            env_return: env_ret / n,
        })
    }
}

/// What an iteration's reward update reports, for the metrics row.
#[derive(Clone, Copy, Debug, Default)]
pub struct UpdateFacts {
    /// Mean learned reward per step of this iteration's agent rollouts (before the update).
    pub learned_reward: f64,
    /// The algorithm's surrogate loss Σ c_i r(o_i) before the update.
    pub surrogate_loss: f64,
}

impl UpdateFacts {
    /// From the rewards `r` of the update's rows (the agent's `n_agent` rows first) and their
    /// loss coefficients.
    pub fn of(r: &[f32], coeffs: &[f64], n_agent: usize) -> UpdateFacts {
        UpdateFacts {
            learned_reward: r[..n_agent].iter().map(|&x| f64::from(x)).sum::<f64>()
                / n_agent as f64,
            surrogate_loss: r.iter().zip(coeffs).map(|(&r, c)| f64::from(r) * c).sum(),
        }
    }
}

/// Everything that watches one job: see the module docs.
pub struct JobWatch<'r, 'l> {
    ground_truth: GroundTruth<'r>,
    perfect: &'r RewardMachine,
    /// The expert's fingertip KDE, to measure how much of the agent's sample it covers.
    expert_kde: Kde,
    logger: Option<&'l mut RolloutLogger>,
    progress: &'l (dyn Fn(JobProgress) + Sync),
    iterations: usize,
    total_env_steps: u64,
    /// `expert_support` of the last rollouts, for the next row.
    expert_support: Option<f64>,
    rows: Vec<MetricsRow>,
    /// How the job plays its many independent episodes (rollouts, evaluations).
    lockstep: Lockstep<'l>,
    /// The final judgement's own episodes (see the module docs); `None`: no final judgement.
    final_set: Option<GroundTruth<'r>>,
    /// The loop's own final policy (after its last iteration) on the final set.
    loop_final_set: Option<FinalSetScore>,
}

impl<'r, 'l> JobWatch<'r, 'l> {
    /// Watches a job of `settings`' length plus `final_steps` SAC steps of a final-policy
    /// phase, judged by `ground_truth` on the task's `perfect` machine.
    pub fn new(
        settings: &IrlRunConfig,
        final_steps: u64,
        ground_truth: GroundTruth<'r>,
        perfect: &'r RewardMachine,
        expert_kde: Kde,
        logger: Option<&'l mut RolloutLogger>,
        progress: &'l (dyn Fn(JobProgress) + Sync),
    ) -> JobWatch<'r, 'l> {
        let iterations = settings.irl_iterations;
        JobWatch {
            ground_truth,
            perfect,
            expert_kde,
            logger,
            progress,
            iterations,
            total_env_steps: settings.sac_steps_per_iteration * iterations as u64 + final_steps,
            expert_support: None,
            rows: Vec::with_capacity(iterations + 1),
            lockstep: Lockstep::single_thread(),
            final_set: None,
            loop_final_set: None,
        }
    }

    /// The watch with a final judgement on `final_set` ([`GroundTruth::final_set`]): the
    /// loop's final policy and every final-phase candidate are also judged there.
    pub fn with_final_set(self, final_set: GroundTruth<'r>) -> JobWatch<'r, 'l> {
        JobWatch {
            final_set: Some(final_set),
            ..self
        }
    }

    /// The watch with episodes played by `plan` (one thread unless given).
    pub fn with_lockstep(self, plan: Lockstep<'l>) -> JobWatch<'r, 'l> {
        JobWatch {
            lockstep: plan,
            ..self
        }
    }

    /// The task's perfect machine (logged episodes track it).
    pub fn perfect(&self) -> &'r RewardMachine {
        self.perfect
    }

    /// The task's layout (observation columns, labels).
    pub fn layout(&self) -> &TaskLayout {
        &self.ground_truth.layout
    }

    /// How the job plays its many independent episodes.
    pub fn lockstep(&self) -> Lockstep<'l> {
        self.lockstep
    }

    /// The job's rollout log, if it keeps one.
    pub fn logger(&mut self) -> Option<&mut RolloutLogger> {
        self.logger.as_deref_mut()
    }

    /// The job's rollout log (if it keeps one) together with a progress report for the SAC
    /// phase of `iteration`: called with SAC's environment steps in all, it reports them with
    /// the last evaluation's success rate. (One borrow of the watch, so that SAC's episodes can
    /// be logged while its progress is reported.)
    pub fn sac_phase(
        &mut self,
        iteration: usize,
    ) -> (Option<&mut RolloutLogger>, impl Fn(u64) + 'l) {
        let progress = self.progress;
        let (iterations, total_env_steps) = (self.iterations, self.total_env_steps);
        let success_rate = self.rows.last().map_or(0.0, |r| r.success_rate);
        let report = move |env_steps| {
            progress(JobProgress {
                iteration: iteration - 1,
                iterations,
                env_steps,
                total_env_steps,
                success_rate,
            })
        };
        (self.logger.as_deref_mut(), report)
    }

    /// The agent's rollouts of this iteration: the share of their fingertip states inside the
    /// support of the expert's Epanechnikov KDE (within the bandwidth of some demonstration
    /// state), where f-IRL's density ratio can be anything but 0.
    pub fn rollouts(&mut self, batch: &AgentBatch) -> Result<(), StepError> {
        let inside = self
            .expert_kde
            .density_columns(&batch.obs, self.ground_truth.layout.obs_dim(), &OBS_TIP)
            .map_err(StepError::ExpertKde)?
            .iter()
            .filter(|&&d| d > 0.0)
            .count();
        self.expert_support = Some(inside as f64 / batch.n_states().max(1) as f64);
        Ok(())
    }

    /// End of `iteration` (0: before any training): evaluates the policy on the ground truth
    /// and records the metrics row. `update` is `None` before the first reward update.
    pub fn iteration_done<E: JobEnv>(
        &mut self,
        iteration: usize,
        env_steps: u64,
        agent: &mut SacAgent,
        env: &mut E,
        update: Option<UpdateFacts>,
    ) -> Result<(), StepError> {
        // The untrained policy's evaluation is not logged.
        let logger = if iteration == 0 {
            None
        } else {
            self.logger.as_deref_mut()
        };
        let ev = self.ground_truth.evaluate_logged_as(
            agent,
            env,
            logger,
            "eval",
            Some(self.lockstep),
        )?;
        let facts = update.unwrap_or_default();
        self.rows.push(MetricsRow {
            iteration,
            env_steps,
            success_rate: ev.success_rate,
            branches: ev.branches,
            task_return: ev.task_return,
            env_return: ev.env_return,
            learned_reward: facts.learned_reward,
            surrogate_loss: facts.surrogate_loss,
            progress: Some(ev.progress),
            final_ball: Some(ev.final_ball),
            expert_support: self.expert_support.take(),
        });
        if iteration == self.iterations {
            self.loop_final_set = self.judge_final_set(agent, env)?;
        }
        (self.progress)(JobProgress {
            iteration,
            iterations: self.iterations,
            env_steps,
            total_env_steps: self.total_env_steps,
            success_rate: ev.success_rate,
        });
        Ok(())
    }

    /// Judges a candidate of the final-policy phase on the ground truth (episodes logged
    /// under "final"); no metrics row.
    pub fn judge_final<E: JobEnv>(
        &mut self,
        agent: &mut SacAgent,
        env: &mut E,
    ) -> Result<Evaluation, StepError> {
        let logger = self.logger.as_deref_mut();
        self.ground_truth
            .evaluate_logged_as(agent, env, logger, "final", Some(self.lockstep))
    }

    /// Judges a policy on the final set (`None` without one). Its episodes are not logged:
    /// the log keeps what the per-iteration evaluation and the final phase played.
    pub fn judge_final_set<E: JobEnv>(
        &mut self,
        agent: &mut SacAgent,
        env: &mut E,
    ) -> Result<Option<FinalSetScore>, StepError> {
        let Some(final_set) = &self.final_set else {
            return Ok(None);
        };
        let ev =
            final_set.evaluate_logged_as(agent, env, None, "final-set", Some(self.lockstep))?;
        Ok(Some(FinalSetScore {
            episodes: final_set.reset_seeds().len() as u64,
            success_rate: ev.success_rate,
            branches: ev.branches,
            progress: ev.progress,
            final_ball: ev.final_ball,
        }))
    }

    /// The loop's own final policy on the final set (`None` without a final set, or before
    /// the last iteration).
    pub fn loop_final_set(&self) -> Option<FinalSetScore> {
        self.loop_final_set
    }

    /// The metrics rows, iteration 0 first.
    pub fn into_rows(self) -> Vec<MetricsRow> {
        self.rows
    }
}
