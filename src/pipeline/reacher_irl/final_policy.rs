//! The final phase of every algorithm with a learned reward (`final_sac_steps` > 0;
//! `smirl`, `smirl-smooth`, `maxent`, `fkl`, `rkl`, `js` — not `smirl-paper`, which reports its
//! loop's own last policy): after the last reward update, SAC goes on training on the job's
//! final learned reward, now held fixed, and the policy the job reports is the one of highest
//! learned return among the co-trained policy and the checkpoints of that phase. One routine (`train`) for every algorithm: they differ only in the reward they
//! hand it (`ScoredReward`: SMIRL's δ_r(u, o) on its product, a baseline's MLP of the
//! fingertip).
//!
//! Why: the IRL loop's policy learns along with a moving reward; the one evaluated after the
//! last iteration trained on the weights before the last update and can sit in a dip of the
//! loop's oscillation while the reward it leaves behind is right. The policy a user takes away
//! should optimise the reward the job returns. The choice reads only that reward — the mean
//! learned return of each candidate's mean action over selection episodes with reset seeds of
//! their own — never the ground truth; every candidate is also judged on the ground truth, so
//! the choice can be checked against the co-trained policy and against a candidate drawn at
//! random ([`FinalPolicy::random`], drawn from the job's own seed stream), which tells how
//! much the choice itself adds over having more candidates.

use super::agent_phases::train_sac;
use super::config::IrlRunConfig;
use super::episodes::{play_episode, AgentBatch, EpisodeSpec, GroundTruthTask, JobEnv};
use super::evaluation::{Evaluation, FinalSetScore, JobWatch};
use super::iteration::StepError;
use crate::env::reacher_task::BranchTally;
use crate::log::RolloutLogger;
use crate::rl::sac::{episode_seed, ActMode, RewardFn, SacAgent, SacTrainer};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// A SAC reward that can also score recorded steps.
pub(super) trait ScoredReward: RewardFn {
    /// The learned reward of every step of `steps`.
    fn score(&mut self, steps: &AgentBatch) -> Result<Vec<f32>, StepError>;
}

/// One candidate for the final policy, after `env_steps` SAC steps of the co-trained agent.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct FinalCandidate {
    pub env_steps: u64,
    /// Mean learned return (the final reward, unshaped) of the mean action over the selection
    /// episodes, each played to the time limit: what the choice reads.
    pub learned_return: f64,
    /// On the ground truth, as the iterations are judged (for a conditional task the lower
    /// branch rate).
    pub success_rate: f64,
    pub branches: Option<BranchTally>,
    pub progress: f64,
    pub final_ball: f64,
    /// On the final set ([`super::evaluation::final_set_episodes`]): what a preregistered
    /// evaluation reports; `None` in records written before it existed.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub final_set: Option<FinalSetScore>,
}

/// The final-policy phase of a job: its candidates — the co-trained policy first, then its
/// checkpoints — and which one the job reports.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct FinalPolicy {
    pub candidates: Vec<FinalCandidate>,
    /// Index into `candidates`: the first of highest learned return.
    pub chosen: usize,
    /// Index into `candidates`: one drawn uniformly from the job's own seed stream
    /// ([`random_pick`]), the yardstick of the choice; `None` in records written before it
    /// was drawn.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub random: Option<usize>,
}

impl FinalPolicy {
    /// The reported policy.
    pub fn chosen(&self) -> &FinalCandidate {
        &self.candidates[self.chosen]
    }

    /// The candidate drawn at random, if the record has one.
    pub fn random(&self) -> Option<&FinalCandidate> {
        self.random.and_then(|i| self.candidates.get(i))
    }
}

/// The length of the phase and what its choice reads.
#[derive(Clone, Copy, Debug)]
pub struct FinalPhase {
    /// SAC environment steps on the fixed final reward.
    pub steps: u64,
    /// Candidates taken along them (evenly spaced, the last at the end), besides the co-trained
    /// policy.
    pub checkpoints: u64,
    /// The job's seed (selection episodes draw their reset seeds from it).
    pub seed: u64,
    /// Selection episodes per candidate ([`selection_episodes`]).
    pub selection_episodes: u64,
}

impl FinalPhase {
    /// The phase of a job of `settings` with seed `seed`, the same for every algorithm; `None`
    /// when the settings have no final phase (`final_sac_steps` = 0, as `smirl-paper`'s).
    pub fn of(settings: &IrlRunConfig, seed: u64) -> Option<FinalPhase> {
        (settings.final_sac_steps > 0).then(|| FinalPhase {
            steps: settings.final_sac_steps,
            checkpoints: settings.final_checkpoints,
            seed,
            selection_episodes: selection_episodes(settings),
        })
    }
}

/// Selection episodes per candidate: twice `eval_episodes` on every task — as many as the
/// evaluation of a task with a cancel branch plays (`eval_episodes` per branch). Why not the
/// evaluation's own count: that count says whether the task's perfect machine has a cancel
/// branch, and the choice reads no ground truth.
pub fn selection_episodes(settings: &IrlRunConfig) -> u64 {
    2 * settings.eval_episodes
}

/// The reset seeds of the `n` selection episodes of the job of seed `seed`: a stream of their
/// own within the job's seed.
pub fn selection_seeds(seed: u64, n: u64) -> Vec<u64> {
    let stream = episode_seed(seed, 0x5e1e_c7ed);
    (0..n).map(|i| episode_seed(stream, i)).collect()
}

/// The stream of the random pick within the job's seed.
const RANDOM_PICK_STREAM: u64 = 0x7a4d_019c;

/// The random pick among `n` candidates (n ≥ 1) of the job of seed `seed`: uniform, from a
/// stream of its own (no other draw of the job moves), the same for the same seed and `n`.
pub fn random_pick(seed: u64, n: usize) -> usize {
    ChaCha8Rng::seed_from_u64(episode_seed(seed, RANDOM_PICK_STREAM)).gen_range(0..n.max(1))
}

/// Runs the phase: `sac`, fresh from the IRL loop, trains on `reward` (the final reward, fixed)
/// and is scored at each checkpoint. `iterations` is the loop's length (for progress reports).
pub(super) fn train<E: JobEnv, R: ScoredReward>(
    sac: &mut SacTrainer,
    env: &mut E,
    reward: &mut R,
    phase: FinalPhase,
    iterations: usize,
    watch: &mut JobWatch<'_, '_>,
) -> Result<FinalPolicy, StepError> {
    let selection_seeds = selection_seeds(phase.seed, phase.selection_episodes);
    let task = GroundTruthTask::of(watch.perfect(), watch.layout());
    let selection = selection_seeds.as_slice();
    let mut candidates = vec![candidate(sac, env, reward, &task, selection, watch)?];
    // `phase.steps` more SAC steps in `phase.checkpoints` even segments, each ending in a
    // scored candidate.
    let start = sac.env_steps();
    for k in 1..=phase.checkpoints {
        let end = start + phase.steps * k / phase.checkpoints;
        let n = end.saturating_sub(sac.env_steps());
        train_sac(sac, env, reward, n, iterations + 1, watch)?;
        candidates.push(candidate(sac, env, reward, &task, selection, watch)?);
    }
    let chosen = choose(&candidates);
    let random = Some(random_pick(phase.seed, candidates.len()));
    Ok(FinalPolicy {
        candidates,
        chosen,
        random,
    })
}

/// Scores the current policy of `sac`: its learned return on the selection episodes, then its
/// ground-truth evaluation.
fn candidate<E: JobEnv, R: ScoredReward>(
    sac: &mut SacTrainer,
    env: &mut E,
    reward: &mut R,
    task: &GroundTruthTask<'_>,
    selection: &[u64],
    watch: &mut JobWatch<'_, '_>,
) -> Result<FinalCandidate, StepError> {
    let learned_return =
        learned_return(&mut sac.agent, env, reward, task, selection, watch.logger())?;
    let ev: Evaluation = watch.judge_final(&mut sac.agent, env)?;
    let final_set = watch.judge_final_set(&mut sac.agent, env)?;
    Ok(FinalCandidate {
        env_steps: sac.env_steps(),
        learned_return,
        success_rate: ev.success_rate,
        branches: ev.branches,
        progress: ev.progress,
        final_ball: ev.final_ball,
        final_set,
    })
}

/// The first candidate of highest learned return.
pub fn choose(candidates: &[FinalCandidate]) -> usize {
    let mut best = 0;
    for (i, c) in candidates.iter().enumerate() {
        if c.learned_return > candidates[best].learned_return {
            best = i;
        }
    }
    best
}

/// The mean learned return of `agent`'s mean action over the episodes of `reset_seeds`, every
/// episode played to the time limit (logged under "select" when a logger is given).
pub(super) fn learned_return<E: JobEnv, R: ScoredReward>(
    agent: &mut SacAgent,
    env: &mut E,
    reward: &mut R,
    task: &GroundTruthTask<'_>,
    reset_seeds: &[u64],
    mut logger: Option<&mut RolloutLogger>,
) -> Result<f64, StepError> {
    let mut rng = ChaCha8Rng::seed_from_u64(0);
    let mut steps = AgentBatch::default();
    for &reset_seed in reset_seeds {
        let spec = EpisodeSpec {
            mode: ActMode::Mean,
            reset_seed,
            stop_when_decided: false,
            with_branch: false,
            phase: "select",
        };
        let mut len = 0;
        play_episode(
            agent,
            env,
            task,
            spec,
            &mut rng,
            logger.as_deref_mut(),
            |next, u| {
                steps.push_step(next, u);
                len += 1;
            },
        )?;
        steps.lengths.push(len);
    }
    let r = reward.score(&steps)?;
    mean_return(&r, &steps.lengths)
}

/// The mean over recorded selection episodes (concatenated, `lengths` steps each) of each
/// one's learned return, from `rewards`, the learned reward of every step.
pub fn mean_return(rewards: &[f32], lengths: &[usize]) -> Result<f64, StepError> {
    let steps = lengths.iter().sum::<usize>();
    if rewards.len() != steps {
        return Err(StepError::SelectionRewards {
            rewards: rewards.len(),
            steps,
        });
    }
    let episodes = lengths.len().max(1) as f64;
    Ok(rewards.iter().map(|&x| f64::from(x)).sum::<f64>() / episodes)
}
