//! The agent's two phases of an IRL iteration, each shown to the job's watch: SAC on the reward
//! being learned ([`train_sac`]) and fresh episodes of the current stochastic policy for the
//! reward update ([`RolloutStream`]), played in lockstep when every episode runs to the time
//! limit.

use super::episodes::{play_episode, AgentBatch, EpisodeSpec, GroundTruthTask, JobEnv};
use super::evaluation::JobWatch;
use super::iteration::StepError;
use super::lockstep::{play_lockstep, Keep};
use crate::pipeline::training_log::TrainingLog;
use crate::rl::sac::{
    draw_noise, episode_seed, ActMode, RewardFn, SacAgent, SacTrainer, TrainingObserver,
};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

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
) -> Result<(), StepError> {
    let before = sac.env_steps();
    let chunk = 1_000u64;
    let mut done = 0;
    let perfect = watch.perfect();
    let (logger, report_progress) = watch.sac_phase(iteration);
    // One observer for the whole phase: it holds the logged episode in progress across chunks.
    let mut train_log = logger.map(|l| TrainingLog::new(l, perfect, "train"));
    while done < steps {
        let n = chunk.min(steps - done);
        let observer = train_log
            .as_mut()
            .map(|t| t as &mut dyn TrainingObserver<E>);
        sac.train_observed(env, reward, n, observer, |_| {})
            .map_err(StepError::Sac)?;
        done += n;
        report_progress(before + done);
    }
    // The rollouts and evaluations after this phase reset the environment.
    let observer = train_log
        .as_mut()
        .map(|t| t as &mut dyn TrainingObserver<E>);
    done += sac
        .finish_episode_observed(env, reward, observer, |_| {})
        .map_err(StepError::Sac)?;
    report_progress(before + done);
    Ok(())
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
    /// watch. The episodes are played in lockstep (`super::lockstep`, the watch's plan) when
    /// every one runs to the time limit, so that the noise each draws is known before play;
    /// otherwise (a product whose machine has a goal or failure state) one after the other,
    /// since an episode's noise then starts where the previous episode's ended.
    pub fn collect<E: JobEnv>(
        &mut self,
        agent: &mut SacAgent,
        env: &mut E,
        n: usize,
        watch: &mut JobWatch<'_, '_>,
    ) -> Result<AgentBatch, StepError> {
        let mut batch = AgentBatch::default();
        let task = GroundTruthTask::of(watch.perfect(), watch.layout());
        let specs: Vec<EpisodeSpec<'_>> = (0..n)
            .map(|_| {
                let reset_seed = episode_seed(self.seed, self.next);
                self.next += 1;
                EpisodeSpec {
                    mode: ActMode::Sample,
                    reset_seed,
                    stop_when_decided: false,
                    with_branch: false,
                    phase: "agent",
                }
            })
            .collect();
        if env.ends_only_at_time_limit() {
            let per_episode = env.reacher().config().max_steps * env.act_dim();
            let mut noise = vec![0.0f32; n * per_episode];
            draw_noise(&mut self.rng, &mut noise);
            let keep = Keep {
                log: watch.logger().is_some(),
                steps: true,
            };
            let plan = watch.lockstep();
            let played = play_lockstep(&agent.actor, env, &task, &specs, Some(&noise), plan, keep)?;
            for p in played {
                if let (Some(logger), Some(log)) = (watch.logger(), &p.log) {
                    log.write_to(logger)?;
                }
                batch.append(p.steps.unwrap_or_default());
            }
        } else {
            for spec in specs {
                let mut len = 0;
                play_episode(
                    agent,
                    env,
                    &task,
                    spec,
                    &mut self.rng,
                    watch.logger(),
                    |after, u| {
                        batch.push_step(after, u);
                        len += 1;
                    },
                )?;
                batch.lengths.push(len);
            }
        }
        watch.rollouts(&batch)?;
        Ok(batch)
    }
}
