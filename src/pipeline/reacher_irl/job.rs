//! One (algorithm, seed) job of a `reacher --task` run: [`run_job`] hands the job to its
//! algorithm's loop — continuous SMIRL in [`super::smirl`], f-IRL and continuous MaxEnt IRL in
//! [`super::firl`] — with a [`JobWatch`] that evaluates every iteration on the ground truth,
//! logs the episodes and reports progress, and what a finished job hands back ([`JobResult`]).

use super::config::IrlRunConfig;
use super::evaluation::{final_set_episodes, FinalSetScore, GroundTruth, JobWatch};
use super::expert_data::ExpertData;
use super::final_policy::FinalPolicy;
use super::firl::{self, BaselineJob, BaselineOutcome, Loss, StateMap};
use super::iteration::{JobProgress, MetricsRow, RewardTraceRow, StepError};
use super::lockstep::Lockstep;
use super::smirl::{self, Features, SmirlJob};
use super::Algo;
use crate::env::reacher::{ReacherDelivery, OBS_TIP};
use crate::irl::kde::Kde;
use crate::irl::reward::RewardModel;
use crate::log::RolloutLogger;
use crate::rm::RewardMachine;
use std::path::Path;
use std::time::Instant;

pub use super::firl::baseline_reward_at;

/// What a finished job hands back.
#[derive(Clone, Debug)]
pub struct JobResult {
    pub algo: Algo,
    pub seed: u64,
    pub rows: Vec<MetricsRow>,
    /// SMIRL: the learned weights (`n_states × n_features` row-major) and the data gradient
    /// μ_π − μ_D of each iteration's reward update, one entry per IRL iteration; empty for the
    /// MLP rewards (too many parameters to trace).
    pub reward_trace: Vec<RewardTraceRow>,
    /// Jobs with a final phase: its candidates, the reported one and the random pick.
    pub final_policy: Option<FinalPolicy>,
    /// The loop's own final policy (after its last iteration) on the final set.
    pub loop_final_set: Option<FinalSetScore>,
    pub wall_secs: f64,
}

/// A job that failed.
#[derive(Debug, thiserror::Error)]
pub enum JobError {
    #[error("{algo} seed {seed}: {problem}")]
    Run {
        algo: Algo,
        seed: u64,
        problem: String,
    },
    /// A step of the algorithm's loop failed.
    #[error("{algo} seed {seed}: {problem}")]
    Step {
        algo: Algo,
        seed: u64,
        #[source]
        problem: StepError,
    },
}

/// Everything one job reads.
pub struct JobInputs<'a> {
    pub algo: Algo,
    pub seed: u64,
    pub settings: &'a IrlRunConfig,
    pub perfect_rm: &'a RewardMachine,
    /// The learned machine (required for SMIRL and the product controls, ignored by the
    /// baselines).
    pub learned_rm: Option<&'a RewardMachine>,
    pub expert: &'a ExpertData,
    /// Where the learned reward's parameters are saved at the end (`None`: not saved).
    pub reward_path: Option<&'a Path>,
    /// How the job plays its many independent episodes (no effect on its results).
    pub lockstep: Lockstep<'a>,
}

/// Runs one (algorithm, seed) job: a pure function of its inputs (own seeded RNGs), so the
/// result does not depend on which thread runs it or when.
pub fn run_job(
    inputs: &JobInputs<'_>,
    logger: Option<&mut RolloutLogger>,
    progress: &(dyn Fn(JobProgress) + Sync),
) -> Result<JobResult, JobError> {
    let started = Instant::now();
    let JobInputs {
        algo,
        seed,
        settings: s,
        perfect_rm,
        expert,
        reward_path,
        ..
    } = *inputs;
    let fail = |problem: String| JobError::Run {
        algo,
        seed,
        problem,
    };
    // The expert's fingertip density, to measure how much of each iteration's sample it covers
    // (`expert_support`, every algorithm).
    let expert_kde = Kde::fit_columns(&expert.obs, expert.obs_dim(), &OBS_TIP, s.kde_bandwidth)
        .map_err(|e| fail(format!("expert KDE: {e}")))?;
    let mut schedule = ReacherDelivery::new(s.env.clone()).map_err(|e| fail(e.to_string()))?;
    let ground_truth = GroundTruth::new(perfect_rm, &mut schedule, seed, s.eval_episodes);
    let final_set = GroundTruth::final_set(perfect_rm, &mut schedule, seed, final_set_episodes(s));
    let final_steps = s.final_sac_steps;
    let mut watch = JobWatch::new(
        s,
        final_steps,
        ground_truth,
        perfect_rm,
        expert_kde,
        logger,
        progress,
    )
    .with_lockstep(inputs.lockstep)
    .with_final_set(final_set);
    let baseline = |loss| BaselineJob {
        loss,
        seed,
        settings: s,
        expert,
        map: StateMap::Fingertip,
    };
    let boxed = |o: BaselineOutcome| {
        let reward = Box::new(o.reward) as Box<dyn RewardModel>;
        (reward, Vec::new(), o.final_policy)
    };
    let (reward, reward_trace, final_policy) = match algo {
        Algo::Smirl | Algo::SmirlPaper | Algo::SmirlSmooth => {
            let machine = inputs
                .learned_rm
                .ok_or_else(|| fail("SMIRL needs a learned reward machine".into()))?;
            let features = if algo == Algo::SmirlSmooth {
                Features::Smooth
            } else {
                Features::Labels
            };
            let job = SmirlJob {
                features,
                seed,
                settings: s,
                machine,
                expert,
            };
            smirl::train(&job, &mut watch).map(|o| {
                let reward = Box::new(o.reward) as Box<dyn RewardModel>;
                (reward, o.trace, o.final_policy)
            })
        }
        Algo::MaxEnt => firl::train(&baseline(Loss::MaxEnt), &mut watch).map(boxed),
        Algo::Fkl | Algo::Rkl | Algo::Js => {
            let div = algo.divergence().expect("f-IRL algorithm");
            firl::train(&baseline(Loss::FDivergence(div)), &mut watch).map(boxed)
        }
        Algo::MaxEntProduct | Algo::FklProduct => {
            let machine = inputs
                .learned_rm
                .ok_or_else(|| fail(format!("{algo} needs a learned reward machine")))?;
            let loss = match algo.divergence() {
                Some(div) => Loss::FDivergence(div),
                None => Loss::MaxEnt,
            };
            let job = BaselineJob {
                map: StateMap::Product(machine),
                ..baseline(loss)
            };
            firl::train(&job, &mut watch).map(boxed)
        }
        Algo::Apprenticeship => {
            return Err(fail(
                "apprenticeship learning is an Office algorithm".into(),
            ))
        }
    }
    .map_err(|problem| JobError::Step {
        algo,
        seed,
        problem,
    })?;
    if let Some(path) = reward_path {
        reward
            .save(path)
            .map_err(|e| fail(format!("saving the reward: {e}")))?;
    }
    let loop_final_set = watch.loop_final_set();
    Ok(JobResult {
        algo,
        seed,
        loop_final_set,
        rows: watch.into_rows(),
        reward_trace,
        final_policy,
        wall_secs: started.elapsed().as_secs_f64(),
    })
}
