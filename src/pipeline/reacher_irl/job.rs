//! One (algorithm, seed) job of a `reacher --task` run: [`run_job`] hands the job to its
//! algorithm's loop — continuous SMIRL in [`super::smirl`], f-IRL and continuous MaxEnt IRL in
//! [`super::firl`] — with a [`JobWatch`] that evaluates every iteration on the ground truth,
//! logs the episodes and reports progress. Also the types every job shares: the expert data,
//! the metrics rows, the result.

use super::config::IrlRunConfig;
use super::evaluation::{final_set_episodes, FinalSetScore, GroundTruth, JobWatch};
use super::final_policy::FinalPolicy;
use super::firl::{self, BaselineJob, BaselineOutcome, Loss, StateMap};
use super::lockstep::Lockstep;
use super::smirl::{self, Features, SmirlJob};
use super::Algo;
use crate::env::reacher::{ReacherDelivery, OBS_TIP};
use crate::env::reacher_task::BranchTally;
use crate::irl::kde::Kde;
use crate::irl::reward::RewardModel;
use crate::log::RolloutLogger;
use crate::nn::codec::{ByteReader, ByteWriter, CodecError};
use crate::rm::{LabelSet, RewardMachine};
use std::path::Path;
use std::time::Instant;

pub use super::firl::baseline_reward_at;

/// What every job of a task shares: the demonstrations as the IRL algorithms see them.
#[derive(Clone, Debug)]
pub struct ExpertData {
    /// Observations o_1..o_T of every demonstration step (row-major, one task observation
    /// wide): the
    /// states visited, as the agent's rollouts record them.
    pub obs: Vec<f32>,
    /// The labels of the observation before each step (the reset observation's for a
    /// demonstration's first step), by the labelling rule on the observation.
    pub labels_before: Vec<LabelSet>,
    /// Demonstration lengths, in order.
    pub lengths: Vec<usize>,
    /// The learned machine's state each observation's labels are read in (u_{t−1}); empty
    /// when no machine was learned.
    pub learned_states: Vec<u32>,
}

impl ExpertData {
    pub fn n_states(&self) -> usize {
        self.lengths.iter().sum()
    }

    /// Width of an observation row (0 without any).
    pub fn obs_dim(&self) -> usize {
        self.obs.len() / self.n_states().max(1)
    }

    /// The binary file `reacher prepare` writes for the jobs (`expert_data.bin`): exact
    /// values, so a job that reads it computes what the one-process run computes.
    pub fn to_bytes(&self) -> Vec<u8> {
        let mut w = ByteWriter::new();
        w.raw(EXPERT_DATA_MAGIC);
        w.u32(EXPERT_DATA_VERSION);
        w.f32s(&self.obs);
        w.u32s(&self.labels_before.iter().map(|l| l.0).collect::<Vec<_>>());
        w.usize(self.lengths.len());
        for &len in &self.lengths {
            w.usize(len);
        }
        w.u32s(&self.learned_states);
        w.bytes
    }

    /// Reads [`ExpertData::to_bytes`] of a task whose observations are `obs_dim` wide; every
    /// count is checked against the bytes present and the arrays against each other.
    pub fn from_bytes(bytes: &[u8], obs_dim: usize) -> Result<ExpertData, CodecError> {
        let mut r = ByteReader::new(bytes);
        r.header(EXPERT_DATA_MAGIC, "smirl expert data", EXPERT_DATA_VERSION)?;
        let obs = r.f32s("observations")?;
        let labels_before: Vec<LabelSet> = (r.u32s("labels before each step")?)
            .into_iter()
            .map(LabelSet)
            .collect();
        let n = r.usize("demonstration count")?;
        if n > bytes.len() / 8 {
            return Err(CodecError::Invalid {
                what: "demonstration count",
                problem: format!("{n} is more than the file can hold"),
            });
        }
        let lengths = (0..n)
            .map(|_| r.usize("demonstration length"))
            .collect::<Result<Vec<_>, _>>()?;
        let learned_states = r.u32s("learned machine states")?;
        r.finish()?;
        let steps = lengths
            .iter()
            .try_fold(0usize, |a, &l| a.checked_add(l))
            .filter(|&t| t.checked_mul(obs_dim) == Some(obs.len()))
            .ok_or_else(|| CodecError::Invalid {
                what: "observations",
                problem: format!(
                    "{} values do not fill the demonstrations' {n} lengths × {obs_dim}",
                    obs.len()
                ),
            })?;
        if labels_before.len() != steps {
            return Err(CodecError::Invalid {
                what: "labels before each step",
                problem: format!("{} label sets for {steps} steps", labels_before.len()),
            });
        }
        if !learned_states.is_empty() && learned_states.len() != steps {
            return Err(CodecError::Invalid {
                what: "learned machine states",
                problem: format!("{} states for {steps} steps", learned_states.len()),
            });
        }
        Ok(ExpertData {
            obs,
            labels_before,
            lengths,
            learned_states,
        })
    }

    /// Checks the learned-machine states against `machine`, the one they were read in (the
    /// run's `rm/learned.txt`): one per step and each a state of it, so that no index read
    /// from the file reaches past the machine's arrays.
    pub fn check_machine(&self, machine: Option<&RewardMachine>) -> Result<(), CodecError> {
        let Some(machine) = machine else {
            return Ok(());
        };
        let invalid = |problem: String| CodecError::Invalid {
            what: "learned machine states",
            problem,
        };
        if self.learned_states.len() != self.n_states() {
            return Err(invalid(format!(
                "{} states for {} steps of a run with a learned machine",
                self.learned_states.len(),
                self.n_states()
            )));
        }
        let n = machine.n_states();
        if let Some(&u) = self.learned_states.iter().find(|&&u| u as usize >= n) {
            return Err(invalid(format!(
                "state {u} is not a state of the learned machine ({n} states)"
            )));
        }
        Ok(())
    }
}

const EXPERT_DATA_MAGIC: &[u8] = b"SMIRLXD\0";
/// 2: the labels before each step.
const EXPERT_DATA_VERSION: u32 = 2;

/// One row of the metrics table: the ground-truth evaluation after `iteration` IRL
/// iterations (0 = the untrained policy).
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct MetricsRow {
    pub iteration: usize,
    pub env_steps: u64,
    /// Fraction of evaluation episodes in which the task's perfect machine reached its goal;
    /// for a conditional task (IF, Composite) the lower of the two branches' rates.
    pub success_rate: f64,
    /// Conditional tasks: evaluation episodes and successes per branch.
    pub branches: Option<BranchTally>,
    /// Mean sum of the perfect machine's rewards.
    pub task_return: f64,
    /// Mean sum of the environment's own (distance) rewards.
    pub env_return: f64,
    /// Mean learned reward per step of the agent's rollouts this iteration.
    pub learned_reward: f64,
    /// The algorithm's surrogate loss Σ c_i r(o_i) before this iteration's update.
    pub surrogate_loss: f64,
    /// Mean fraction of the task's sub-goals completed along the perfect machine
    /// (`env::reacher_task::TaskProgress`); `None` in jobs run before the metric existed.
    #[serde(default)]
    pub progress: Option<f64>,
    /// Fraction of evaluation episodes that touched a ball which can end the task (the
    /// paper's "end location"); `None` in jobs run before the metric existed.
    #[serde(default)]
    pub final_ball: Option<f64>,
    /// Fraction of this iteration's agent fingertip states inside the support of the expert's
    /// Epanechnikov KDE (within `kde_bandwidth` of some demonstration state): where f-IRL's
    /// density ratio can be anything but 0. `None` before the first rollouts and in jobs run
    /// before the measurement existed.
    #[serde(default)]
    pub expert_support: Option<f64>,
}

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

/// One iteration of a SMIRL job's reward trace: how the weights moved and why.
#[derive(Clone, Debug, PartialEq)]
pub struct RewardTraceRow {
    pub iteration: usize,
    /// The loss gradient without L2 (μ_π − μ_D under the configured normalisation) before
    /// this iteration's update.
    pub data_gradient: Vec<f32>,
    /// The weights after this iteration's update.
    pub weights: Vec<f32>,
}

/// Progress of a job, for progress bars.
#[derive(Clone, Copy, Debug)]
pub struct JobProgress {
    pub iteration: usize,
    pub iterations: usize,
    pub env_steps: u64,
    pub total_env_steps: u64,
    /// Success rate of the last evaluation.
    pub success_rate: f64,
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
}

/// The batch of one reward update: rows, their learned-machine states (SMIRL) and loss
/// coefficients.
#[derive(Clone, Debug, PartialEq)]
pub struct Coefficients {
    /// Row-major observations, one task observation wide.
    pub obs: Vec<f32>,
    /// Learned-machine state of each row (empty for the baselines).
    pub states: Vec<u32>,
    pub coeffs: Vec<f64>,
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
        Algo::Apprenticeship => Err("apprenticeship learning is an Office algorithm".into()),
    }
    .map_err(fail)?;
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
