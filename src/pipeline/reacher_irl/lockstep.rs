//! Many independent episodes played side by side ([`play_lockstep`]): each thread steps a
//! batch of environments together, choosing every environment's action with one batched
//! forward pass of the actor (one matrix product per layer instead of one per environment),
//! and the job's episodes are split over threads when some are free.
//!
//! Results do not depend on the batch width or the thread count: every episode has its own
//! environment and reset seed, an actor column's bits do not depend on the other columns of its
//! batch (`nn::gemm`), sampling noise is drawn before play in the order one-at-a-time play
//! draws it (episode after episode), and the episodes' outcomes, steps and log records are
//! handed back in episode order.

use super::episodes::{
    AgentBatch, EpisodeError, EpisodeLog, EpisodeOutcome, EpisodePlay, EpisodeSpec,
    GroundTruthTask, JobEnv, NoLog, RecordedEpisode,
};
use crate::nn::Mlp;
use crate::rl::sac::{ActMode, ActWorkspace};

/// Episodes that cannot be played in lockstep, or one of them failing.
#[derive(Debug, thiserror::Error)]
pub enum LockstepError {
    #[error(transparent)]
    Episode(#[from] EpisodeError),
    #[error("lockstep episodes must share one action mode")]
    MixedModes,
    #[error("lockstep sampling needs {per_episode} noise values for each of {episodes} episodes")]
    NoiseLength { per_episode: usize, episodes: usize },
    #[error("this environment cannot be copied for lockstep play")]
    NotCopyable,
    #[error("a rollout thread panicked")]
    ThreadPanicked,
    #[error(
        "the episode of reset seed {reset_seed} ended after {steps} steps, before the time \
         limit: sampled lockstep play needs episodes of the full length"
    )]
    EndedEarly { reset_seed: u64, steps: usize },
}

/// Environments one thread steps together by default: wide enough that the actor's weights are
/// packed once for many observations, narrow enough that the environments' MuJoCo data stay
/// in cache (`lockstep_bench`).
pub const LOCKSTEP_BATCH: usize = 32;

/// How a job plays its many independent episodes (not what they are: any plan gives the same
/// episodes).
#[derive(Clone, Copy)]
pub struct Lockstep<'a> {
    /// Environments stepped together on one thread.
    pub batch: usize,
    /// Threads the job may use now (asked before every set of episodes; at least 1 is used).
    pub threads: &'a (dyn Fn() -> usize + Sync),
}

impl Lockstep<'static> {
    /// One thread, [`LOCKSTEP_BATCH`] environments.
    pub fn single_thread() -> Lockstep<'static> {
        Lockstep {
            batch: LOCKSTEP_BATCH,
            threads: &|| 1,
        }
    }
}

/// What [`play_lockstep`] gives back for one episode.
#[derive(Clone, Debug, Default)]
pub struct PlayedEpisode {
    pub outcome: EpisodeOutcome,
    /// Its log records, when asked for.
    pub log: Option<RecordedEpisode>,
    /// Its steps as a reward update reads them (one trajectory), when asked for.
    pub steps: Option<AgentBatch>,
}

/// What to keep of each episode besides its outcome.
#[derive(Clone, Copy, Debug, Default)]
pub struct Keep {
    pub log: bool,
    pub steps: bool,
}

/// Plays the episodes `specs` (all of one [`ActMode`]) with `actor` in fresh copies of `proto`
/// ([`JobEnv::fresh`]), `plan.batch` at a time on each of up to `(plan.threads)()` threads.
///
/// `noise` is required for [`ActMode::Sample`]: ε for every step of every episode, episode
/// after episode, `max_steps × act_dim` per episode (what [`crate::rl::sac::draw_noise`] writes
/// for one-at-a-time play). Each such episode must then run to the time limit; one that ends
/// earlier is an error, since the noise of the episodes after it would not be the noise
/// one-at-a-time play gives them.
pub fn play_lockstep<'t, E: JobEnv>(
    actor: &Mlp,
    proto: &E,
    task: &'t GroundTruthTask<'t>,
    specs: &[EpisodeSpec<'_>],
    noise: Option<&[f32]>,
    plan: Lockstep<'_>,
    keep: Keep,
) -> Result<Vec<PlayedEpisode>, LockstepError> {
    let Some(first) = specs.first() else {
        return Ok(Vec::new());
    };
    let mode = first.mode;
    if specs.iter().any(|s| s.mode != mode) {
        return Err(LockstepError::MixedModes);
    }
    let max_steps = proto.reacher().config().max_steps;
    let per_episode = max_steps * proto.act_dim();
    let noise = match (mode, noise) {
        (ActMode::Mean, _) => None,
        (ActMode::Sample, Some(n)) if n.len() == specs.len() * per_episode => Some(n),
        (ActMode::Sample, _) => {
            return Err(LockstepError::NoiseLength {
                per_episode,
                episodes: specs.len(),
            })
        }
    };
    let threads = (plan.threads)().clamp(1, specs.len());
    let bounds: Vec<usize> = (0..=threads).map(|i| i * specs.len() / threads).collect();
    // Each thread's environments, made here (an environment may move to a thread but not be
    // shared by threads).
    let mut envs = Vec::with_capacity(threads);
    for i in 0..threads {
        let width = plan.batch.clamp(1, bounds[i + 1] - bounds[i]);
        envs.push(
            (0..width)
                .map(|_| proto.fresh())
                .collect::<Option<Vec<E>>>()
                .ok_or(LockstepError::NotCopyable)?,
        );
    }
    let play_chunk = |i: usize, envs: Vec<E>| {
        let (a, b) = (bounds[i], bounds[i + 1]);
        let chunk_noise = noise.map(|n| &n[a * per_episode..b * per_episode]);
        play_on_thread(actor, envs, task, &specs[a..b], chunk_noise, keep)
    };
    let mut envs = envs.into_iter();
    let own = envs.next().expect("at least one thread");
    if threads == 1 {
        return play_chunk(0, own);
    }
    let results: Vec<Result<Vec<PlayedEpisode>, LockstepError>> = std::thread::scope(|scope| {
        let handles: Vec<_> = envs
            .enumerate()
            .map(|(i, e)| scope.spawn(move || play_chunk(i + 1, e)))
            .collect();
        let mut results = vec![play_chunk(0, own)];
        for h in handles {
            results.push(
                h.join()
                    .unwrap_or_else(|_| Err(LockstepError::ThreadPanicked)),
            );
        }
        results
    });
    let mut played = Vec::with_capacity(specs.len());
    for r in results {
        played.extend(r?);
    }
    Ok(played)
}

/// One episode in a slot of a thread's batch.
struct Slot<'t, 'p, E> {
    env: E,
    /// Index of the episode within the thread's chunk, and its play.
    episode: Option<(usize, EpisodePlay<'t, 'p>)>,
    log: RecordedEpisode,
    steps: AgentBatch,
}

/// Starts the next episode not yet started in `slot` (or empties the slot when none is left).
fn start_next<'t, 'p, E: JobEnv>(
    slot: &mut Slot<'t, 'p, E>,
    task: &'t GroundTruthTask<'t>,
    specs: &[EpisodeSpec<'p>],
    obs: &mut [f32],
    started: &mut usize,
    keep: Keep,
) -> Result<(), LockstepError> {
    slot.episode = None;
    if *started < specs.len() {
        let j = *started;
        *started += 1;
        slot.steps = AgentBatch::default();
        let log: &mut dyn EpisodeLog = if keep.log { &mut slot.log } else { &mut NoLog };
        slot.env.reset(specs[j].reset_seed, obs);
        let play = EpisodePlay::begin(&slot.env, task, specs[j], obs, log)?;
        slot.episode = Some((j, play));
    }
    Ok(())
}

/// [`play_lockstep`]'s work on one thread: `specs` in slots of `batch` environments; a slot
/// whose episode ends takes the next episode not yet started.
fn play_on_thread<'t, E: JobEnv>(
    actor: &Mlp,
    envs: Vec<E>,
    task: &'t GroundTruthTask<'t>,
    specs: &[EpisodeSpec<'_>],
    noise: Option<&[f32]>,
    keep: Keep,
) -> Result<Vec<PlayedEpisode>, LockstepError> {
    let width = envs.len();
    let Some(proto) = envs.first() else {
        return Ok(Vec::new());
    };
    let (obs_dim, act_dim) = (proto.obs_dim(), proto.act_dim());
    let per_episode = proto.reacher().config().max_steps * act_dim;
    let mut slots: Vec<Slot<'t, '_, E>> = envs
        .into_iter()
        .map(|env| Slot {
            env,
            episode: None,
            log: RecordedEpisode::default(),
            steps: AgentBatch::default(),
        })
        .collect();
    let mut ws = ActWorkspace::with_batch(actor, width);
    let mut obs = vec![0.0f32; width * obs_dim];
    let mut next = vec![0.0f32; obs_dim];
    let mut actions = vec![0.0f32; width * act_dim];
    let mut eps = vec![0.0f32; width * act_dim];
    let mut played: Vec<PlayedEpisode> = vec![PlayedEpisode::default(); specs.len()];
    let mut started = 0;

    for (k, slot) in slots.iter_mut().enumerate() {
        start_next(
            slot,
            task,
            specs,
            &mut obs[k * obs_dim..(k + 1) * obs_dim],
            &mut started,
            keep,
        )?;
    }
    while slots.iter().any(|s| s.episode.is_some()) {
        if let Some(noise) = noise {
            for (slot, e) in slots.iter().zip(eps.chunks_exact_mut(act_dim)) {
                if let Some((j, play)) = &slot.episode {
                    let at = j * per_episode + play.steps() * act_dim;
                    e.copy_from_slice(&noise[at..at + act_dim]);
                }
            }
        }
        ws.act_with_noise(actor, &obs, noise.map(|_| &eps[..]), &mut actions);
        for (k, slot) in slots.iter_mut().enumerate() {
            let Some((j, play)) = slot.episode.as_mut() else {
                continue;
            };
            let o = &mut obs[k * obs_dim..(k + 1) * obs_dim];
            let a = &actions[k * act_dim..(k + 1) * act_dim];
            let steps = &mut slot.steps;
            let on_step = |after: &[f32], u: Option<usize>| {
                if keep.steps {
                    steps.push_step(after, u);
                }
            };
            let log: &mut dyn EpisodeLog = if keep.log { &mut slot.log } else { &mut NoLog };
            play.step(&mut slot.env, a, &mut next, log, on_step)?;
            o.copy_from_slice(&next);
            if play.ended() {
                let j = *j;
                let (_, play) = slot.episode.take().expect("the slot plays an episode");
                if noise.is_some() && play.steps() * act_dim != per_episode {
                    return Err(LockstepError::EndedEarly {
                        reset_seed: specs[j].reset_seed,
                        steps: play.steps(),
                    });
                }
                let length = play.steps();
                let log: &mut dyn EpisodeLog = if keep.log { &mut slot.log } else { &mut NoLog };
                let outcome = play.finish(log)?;
                let mut steps = std::mem::take(&mut slot.steps);
                steps.lengths.push(length);
                played[j] = PlayedEpisode {
                    outcome,
                    log: keep.log.then(|| std::mem::take(&mut slot.log)),
                    steps: keep.steps.then_some(steps),
                };
                start_next(slot, task, specs, o, &mut started, keep)?;
            }
        }
    }
    Ok(played)
}
