//! The baselines on ReacherDelivery, as f-IRL's code runs them (Ni et al. 2020; the SMIRL
//! paper used that code for both): f-IRL with forward KL, reverse KL or Jensen–Shannon, and
//! continuous MaxEnt IRL, which shares f-IRL's loop and differs only in its loss.
//!
//! The reward is a (64, 64) MLP of the fingertip position, clamped to ±10. Per iteration
//! ([`train`], the loop of [`super::irl_loop`]):
//! 1. SAC on the plain ReacherDelivery with the current reward r(o_{t+1}), recomputed when a
//!    batch is sampled (the same agent and replay buffer throughout);
//! 2. fresh rollouts of the stochastic policy (N trajectories of the fixed length T);
//! 3. the density ratios of the batch ([`density_ratios`]) and the loss coefficients
//!    ([`coefficients`]): for f-IRL the covariance surrogate
//!    Cov_i(Σ_t h_f(ρ_E/ρ_θ), Σ_t r)/T, the density ratio from an Epanechnikov KDE of the
//!    agent's fingertip states against the expert's; for MaxEnt T·(mean r over agent states
//!    − mean r over expert states);
//! 4. reward steps (Adam). After the loop, the final phase every algorithm with a learned
//!    reward shares (`super::final_policy`). With `[firl] expert_trajectories = N`, each f-IRL step first draws N
//!    demonstrations and appends them to the covariance batch, as f-IRL's code for an expert
//!    given by samples does (`irl_samples.py`): descent raises the reward along them, also
//!    where the agent has never been.
//!
//! The controls `maxent-product` and `fkl-product` run this loop with one change, the state
//! map ([`StateMap::Product`]): the agent acts on the product with SMIRL's learned machine
//! (observation ⊕ one-hot u, SMIRL's own environment), and the reward and the
//! densities read (one-hot u, fingertip) in place of the fingertip, u the machine's state
//! before the step as SMIRL's δ_r(u_t, o_{t+1}) reads it.
//!
//! Ground-truth evaluation, logging and progress watch the loop from outside ([`JobWatch`]).

use super::config::IrlRunConfig;
use super::episodes::{AgentBatch, JobEnv};
use super::evaluation::{JobWatch, UpdateFacts};
use super::expert_data::ExpertData;
use super::final_policy::{FinalPhase, FinalPolicy};
use super::irl_loop;
use super::iteration::{Coefficients, StepError};
use crate::env::layout::OBS_ARM;
use crate::env::reacher::{ReacherDelivery, OBS_TIP};
use crate::irl::firl::{self, Divergence, FirlSurrogate, MaxEntCoefficients, DEFAULT_DENSITY_EPS};
use crate::irl::kde::Kde;
use crate::irl::reward::{MlpReward, MlpRewardConfig, RewardError, RewardModel};
use crate::rl::crm::hot_index;
use crate::rl::replay::ReplayBatch;
use crate::rl::sac::{episode_seed, RewardFn, RewardFnError, SacTrainer};
use crate::rm::product::one_hot;
use crate::rm::RewardMachine;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::borrow::Cow;
use std::path::Path;

/// What a baseline's reward and densities read of a step, and the environment its agent acts
/// in.
#[derive(Clone, Copy, Debug)]
pub enum StateMap<'a> {
    /// The baselines: the fingertip of the task observation, the agent on the task's
    /// observation.
    Fingertip,
    /// The product controls: (one-hot u, fingertip x, y), u this machine's state before the
    /// step (the state the step's labels are read in); the agent on the product with it.
    Product(&'a RewardMachine),
}

impl StateMap<'_> {
    /// The columns of [`StateMap::rows`] the reward and the densities read.
    pub fn columns(&self) -> Vec<usize> {
        match self {
            StateMap::Fingertip => OBS_TIP.to_vec(),
            StateMap::Product(m) => (0..m.n_states() + OBS_TIP.len()).collect(),
        }
    }

    /// Width of a row of [`StateMap::rows`] for task observations `obs_dim` wide.
    pub fn width(&self, obs_dim: usize) -> usize {
        match self {
            StateMap::Fingertip => obs_dim,
            StateMap::Product(m) => m.n_states() + OBS_TIP.len(),
        }
    }

    /// The rows the reward reads of task observations `obs` (`obs_dim` wide) paired with the
    /// machine's states before each step: the observations themselves (fingertip), or
    /// (one-hot u, fingertip) (product; one state per row, each a state of the machine).
    pub fn rows<'o>(
        &self,
        obs: &'o [f32],
        obs_dim: usize,
        states: &[u32],
    ) -> Result<Cow<'o, [f32]>, StepError> {
        let StateMap::Product(m) = self else {
            return Ok(Cow::Borrowed(obs));
        };
        let n = m.n_states();
        let rows = obs.len() / obs_dim.max(1);
        if states.len() != rows {
            return Err(StepError::StateCount {
                states: states.len(),
                rows,
            });
        }
        let width = self.width(obs_dim);
        let mut out = vec![0.0f32; rows * width];
        for ((row, o), &u) in out
            .chunks_exact_mut(width)
            .zip(obs.chunks_exact(obs_dim))
            .zip(states)
        {
            if u as usize >= n {
                return Err(StepError::UnknownState { state: u, n });
            }
            one_hot(u as usize, &mut row[..n]);
            row[n] = o[OBS_TIP[0]];
            row[n + 1] = o[OBS_TIP[1]];
        }
        Ok(Cow::Owned(out))
    }

    /// The demonstrations as the reward reads them (their learned states kept).
    pub fn expert<'e>(&self, expert: &'e ExpertData) -> Result<Cow<'e, ExpertData>, StepError> {
        match self.rows(&expert.obs, expert.obs_dim(), &expert.learned_states)? {
            Cow::Borrowed(_) => Ok(Cow::Borrowed(expert)),
            Cow::Owned(obs) => Ok(Cow::Owned(ExpertData {
                obs,
                ..expert.clone()
            })),
        }
    }

    /// An agent batch as the reward reads it (task observations `obs_dim` wide).
    pub fn agent(&self, batch: AgentBatch, obs_dim: usize) -> Result<AgentBatch, StepError> {
        Ok(match self.rows(&batch.obs, obs_dim, &batch.states)? {
            Cow::Borrowed(_) => batch,
            Cow::Owned(obs) => AgentBatch { obs, ..batch },
        })
    }

    /// The reward's rows of a SAC batch of the agent's environment (`obs_dim`: the task
    /// observation's width): the next observation (fingertip), or the state before the step
    /// read from the previous observation's one-hot block with the next fingertip (product).
    pub fn sac_rows(&self, batch: &ReplayBatch, obs_dim: usize, out: &mut Vec<f32>) {
        let d = batch.obs.nrows();
        out.clear();
        let next = batch.next_obs.as_slice().chunks_exact(d);
        match self {
            StateMap::Fingertip => {
                for next in next {
                    out.extend_from_slice(&next[..obs_dim]);
                }
            }
            StateMap::Product(m) => {
                let n = m.n_states();
                for (next, prev) in next.zip(batch.obs.as_slice().chunks_exact(d)) {
                    let u = hot_index(&prev[obs_dim..obs_dim + n]);
                    out.extend((0..n).map(|i| if i == u { 1.0 } else { 0.0 }));
                    out.extend(OBS_TIP.iter().map(|&c| next[c]));
                }
            }
        }
    }
}

/// Which baseline.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Loss {
    /// f-IRL with this f-divergence.
    FDivergence(Divergence),
    /// Continuous MaxEnt IRL.
    MaxEnt,
}

/// Where f-IRL's density ratio comes from, kept across iterations.
pub enum Ratio<'a> {
    /// The expert's KDE (fitted once) against a KDE of each iteration's agent states.
    Kde { expert: &'a Kde, bandwidth: f64 },
}

/// f-IRL's density ratios u = ρ_E/ρ_θ of one iteration's agent batch: at the agent's states
/// and, when demonstrations join the covariance batch (`at_expert`), at every demonstration
/// state (row for row with `ExpertData::obs`). Computed once per iteration, like f-IRL's
/// classifier, which is trained once per iteration.
#[derive(Clone, Debug, PartialEq)]
pub struct IterationRatios {
    pub agent: Vec<f64>,
    /// Empty unless asked for.
    pub expert: Vec<f64>,
}

/// Step 3a: the density ratios (see [`IterationRatios`]). The agent's density can be zero at a
/// demonstration state it never comes near, so the ratios there carry the ε guard of
/// `irl::firl` (`(ρ_E + ε)/(ρ_θ + ε)`) whatever the source; at the agent's own states each
/// source computes them as it always has.
///
/// `columns`: what the densities read of the rows (the fingertip of a task observation, or
/// every column of a product control's rows, [`StateMap::columns`]).
pub fn density_ratios(
    ratio: &mut Ratio<'_>,
    expert: &ExpertData,
    agent: &AgentBatch,
    at_expert: bool,
    columns: &[usize],
) -> Result<IterationRatios, StepError> {
    let d = expert.obs_dim();
    let fit_agent = |bandwidth: f64| {
        Kde::fit_columns(&agent.obs, d, columns, bandwidth).map_err(StepError::Kde)
    };
    let guarded = |rho_e: &[f64], rho_a: &[f64]| {
        firl::density_ratio(rho_e, rho_a, DEFAULT_DENSITY_EPS).map_err(StepError::Surrogate)
    };
    match ratio {
        Ratio::Kde {
            expert: kde_e,
            bandwidth,
        } => {
            let kde_a = fit_agent(*bandwidth)?;
            ratios_at_both(agent, expert, at_expert, |obs| {
                let rho_e = kde_e.density_columns(obs, d, columns)?;
                let rho_a = kde_a.density_columns(obs, d, columns)?;
                guarded(&rho_e, &rho_a)
            })
        }
    }
}

/// The ratios `ratios_at` gives at the agent's states and, if `at_expert`, at the
/// demonstrations'.
fn ratios_at_both(
    agent: &AgentBatch,
    expert: &ExpertData,
    at_expert: bool,
    mut ratios_at: impl FnMut(&[f32]) -> Result<Vec<f64>, StepError>,
) -> Result<IterationRatios, StepError> {
    Ok(IterationRatios {
        agent: ratios_at(&agent.obs)?,
        expert: if at_expert {
            ratios_at(&expert.obs)?
        } else {
            Vec::new()
        },
    })
}

/// Step 3b: the rows and loss coefficients of one reward step (see the module docs). f-IRL:
/// the agent's trajectories, then the demonstrations `drawn` (indices into the expert's,
/// repeats allowed), one coefficient per row; MaxEnt: agent rows then every expert row
/// (`ratios` and `drawn` unused).
pub fn coefficients(
    loss: Loss,
    expert: &ExpertData,
    agent: &AgentBatch,
    ratios: Option<&IterationRatios>,
    drawn: &[usize],
) -> Result<Coefficients, StepError> {
    let n_agent = agent.lengths.iter().sum::<usize>();
    if agent.lengths.is_empty() || n_agent == 0 {
        return Err(StepError::NoAgentTrajectories);
    }
    let horizon = agent.lengths[0];
    match loss {
        Loss::FDivergence(div) => {
            if agent.lengths.iter().any(|&l| l != horizon) {
                return Err(StepError::UnequalAgentLengths);
            }
            let ratios = ratios.ok_or(StepError::NoRatios)?;
            let mut obs = agent.obs.clone();
            let mut u = ratios.agent.clone();
            if !drawn.is_empty() {
                let starts = demonstration_starts(&expert.lengths);
                if ratios.expert.len() != expert.n_states() {
                    return Err(StepError::NoExpertRatios);
                }
                for &k in drawn {
                    let (start, len) = match (starts.get(k), expert.lengths.get(k)) {
                        (Some(&start), Some(&len)) => (start, len),
                        _ => return Err(StepError::NoDemonstration(k)),
                    };
                    if len != horizon {
                        return Err(StepError::DemonstrationLength { k, len, horizon });
                    }
                    let d = expert.obs_dim();
                    obs.extend_from_slice(&expert.obs[start * d..(start + len) * d]);
                    u.extend_from_slice(&ratios.expert[start..start + len]);
                }
            }
            let n_traj = agent.lengths.len() + drawn.len();
            let surrogate = FirlSurrogate::new(div, &u, n_traj, horizon)?;
            Ok(Coefficients {
                obs,
                states: Vec::new(),
                coeffs: surrogate.coefficients,
            })
        }
        Loss::MaxEnt => {
            let n_expert = expert.n_states();
            let c = MaxEntCoefficients::new(n_agent, n_expert, horizon)?;
            let mut coeffs = vec![c.agent; n_agent];
            coeffs.extend(std::iter::repeat_n(c.expert, n_expert));
            Ok(Coefficients {
                obs: [agent.obs.as_slice(), &expert.obs].concat(),
                states: Vec::new(),
                coeffs,
            })
        }
    }
}

/// The first row of each demonstration in `ExpertData::obs`.
fn demonstration_starts(lengths: &[usize]) -> Vec<usize> {
    lengths
        .iter()
        .scan(0, |row, &len| {
            let start = *row;
            *row += len;
            Some(start)
        })
        .collect()
}

/// f-IRL's draw of demonstrations for one reward step (its `resample_episodes`): `m` indices
/// out of `n`, with replacement when `m > n`, else without; none when `m` is 0. Its own random
/// stream, so that a job that draws none consumes nothing of the other streams.
pub struct DemonstrationDraw {
    rng: ChaCha8Rng,
}

impl DemonstrationDraw {
    pub fn new(seed: u64) -> DemonstrationDraw {
        DemonstrationDraw {
            rng: ChaCha8Rng::seed_from_u64(episode_seed(seed, 0xde70)),
        }
    }

    pub fn draw(&mut self, n: usize, m: usize) -> Vec<usize> {
        if m == 0 || n == 0 {
            Vec::new()
        } else if m > n {
            (0..m).map(|_| self.rng.gen_range(0..n)).collect()
        } else {
            rand::seq::index::sample(&mut self.rng, n, m).into_vec()
        }
    }
}

/// The baselines' reward model: the paper's (64, 64) MLP on what `map` reads (the fingertip,
/// or (one-hot u, fingertip) for a product control), clamped to ±10.
pub fn reward_model(
    settings: &IrlRunConfig,
    seed: u64,
    map: StateMap<'_>,
) -> Result<MlpReward, RewardError> {
    let mut cfg = MlpRewardConfig::paper(map.columns(), settings.mlp_reward_lr, seed);
    cfg.optim.l2 = settings.mlp_reward_l2;
    let layout = (settings.env.task_layout()).map_err(|e| RewardError::Config(e.to_string()))?;
    MlpReward::new(cfg, map.width(layout.obs_dim()))
}

/// The saved reward of a baseline job (`rewards/<algo>_seed<k>.bin`) at fingertip positions
/// (x, y). The reward reads the fingertip alone, so rows of the arm's columns suffice.
pub fn baseline_reward_at(path: &Path, points: &[[f64; 2]]) -> Result<Vec<f32>, RewardError> {
    let mut model = MlpReward::new(MlpRewardConfig::paper(OBS_TIP.to_vec(), 1e-3, 0), OBS_ARM)?;
    model.load(path)?;
    let mut obs = vec![0.0f32; points.len() * OBS_ARM];
    for (row, p) in obs.chunks_exact_mut(OBS_ARM).zip(points) {
        row[OBS_TIP[0]] = p[0] as f32;
        row[OBS_TIP[1]] = p[1] as f32;
    }
    let mut r = vec![0.0f32; points.len()];
    model.reward_batch(&obs, &[], &mut r)?;
    Ok(r)
}

/// SAC's reward: r(o_{t+1}) (a product control: r(u_t, o_{t+1})) of every sampled transition,
/// computed when the batch is sampled so that old transitions follow the reward being
/// optimised now.
pub(super) struct StateReward<'a> {
    model: &'a mut MlpReward,
    map: StateMap<'a>,
    /// Width of the task observation at the front of every environment observation.
    task_obs_dim: usize,
    obs: Vec<f32>,
}

impl<'a> StateReward<'a> {
    /// The reward of a baseline's model (on the fingertip).
    pub(super) fn new(model: &'a mut MlpReward) -> StateReward<'a> {
        let task_obs_dim = model.obs_dim();
        StateReward::with_map(model, StateMap::Fingertip, task_obs_dim)
    }

    /// The reward of `model` on the rows `map` makes of task observations `task_obs_dim` wide.
    pub(super) fn with_map(
        model: &'a mut MlpReward,
        map: StateMap<'a>,
        task_obs_dim: usize,
    ) -> StateReward<'a> {
        StateReward {
            model,
            map,
            task_obs_dim,
            obs: Vec::new(),
        }
    }
}

impl RewardFn for StateReward<'_> {
    fn fill_rewards(&mut self, batch: &ReplayBatch, out: &mut [f32]) -> Result<(), RewardFnError> {
        (self.map).sac_rows(batch, self.task_obs_dim, &mut self.obs);
        Ok(self.model.reward_batch(&self.obs, &[], out)?)
    }
}

impl super::final_policy::ScoredReward for StateReward<'_> {
    fn score(&mut self, steps: &AgentBatch) -> Result<Vec<f32>, StepError> {
        let rows = (self.map).rows(&steps.obs, self.task_obs_dim, &steps.states)?;
        let mut r = vec![0.0f32; steps.n_states()];
        (self.model).reward_batch(&rows, &[], &mut r)?;
        Ok(r)
    }
}

/// What a baseline job returns: the learned reward and the final phase's candidates, if any.
pub struct BaselineOutcome {
    pub reward: MlpReward,
    pub final_policy: Option<FinalPolicy>,
}

/// One baseline job.
pub struct BaselineJob<'a> {
    pub loss: Loss,
    pub seed: u64,
    pub settings: &'a IrlRunConfig,
    /// The demonstrations (a product control's annotated with its machine's states).
    pub expert: &'a ExpertData,
    /// What the reward reads and where the agent acts: the baselines' fingertip, or a product
    /// control's machine.
    pub map: StateMap<'a>,
}

/// f-IRL's loop (see the module docs) in the environment of `job.map`: the task's, or (a
/// product control) SMIRL's product with the machine.
pub fn train(
    job: &BaselineJob<'_>,
    watch: &mut JobWatch<'_, '_>,
) -> Result<BaselineOutcome, StepError> {
    let s = job.settings;
    let mut inner = ReacherDelivery::new(s.env.clone())?;
    match job.map {
        StateMap::Fingertip => train_in(job, &mut inner, watch),
        StateMap::Product(machine) => {
            train_in(job, &mut super::smirl::product_env(inner, machine), watch)
        }
    }
}

/// f-IRL's loop in `env` ([`irl_loop::run`] with the baselines' reward, [`BaselineReward`]),
/// then the final phase every algorithm with a learned reward shares ([`super::final_policy`]: more
/// SAC on the final MLP held fixed, the candidate of highest learned return, the MLP's reward
/// summed along each selection episode).
fn train_in<E: JobEnv>(
    job: &BaselineJob<'_>,
    env: &mut E,
    watch: &mut JobWatch<'_, '_>,
) -> Result<BaselineOutcome, StepError> {
    let s = job.settings;
    let map = job.map;
    let columns = map.columns();
    // The demonstrations as the reward reads them.
    let expert = map.expert(job.expert)?;
    let expert = expert.as_ref();
    // f-IRL's ρ_E/ρ_θ: the expert's KDE, or a classifier on its own random stream.
    let d = expert.obs_dim();
    let expert_kde = Kde::fit_columns(&expert.obs, d, &columns, s.kde_bandwidth)
        .map_err(StepError::ExpertKde)?;
    let mut learner = BaselineReward {
        reward: reward_model(s, job.seed, map)?,
        ratio: match job.loss {
            Loss::MaxEnt => None,
            Loss::FDivergence(_) => Some(Ratio::Kde {
                expert: &expert_kde,
                bandwidth: s.kde_bandwidth,
            }),
        },
        // f-IRL's demonstrations in the covariance batch (f-IRL only: MaxEnt's loss has them
        // all).
        drawn_per_step: match job.loss {
            Loss::FDivergence(_) => s.firl_expert_trajectories,
            Loss::MaxEnt => 0,
        },
        demo_draw: DemonstrationDraw::new(job.seed),
        task_obs_dim: job.expert.obs_dim(),
        columns,
        expert,
        job,
    };
    let mut sac = SacTrainer::new(&s.sac, env.obs_dim(), env.act_dim(), job.seed)?;
    // The final phase has no selection cut (it reads a learned machine, and the baselines have
    // none).
    let final_phase = FinalPhase::of(s, job.seed);
    let final_policy = irl_loop::run(&mut learner, &mut sac, env, s, job.seed, final_phase, watch)?;
    Ok(BaselineOutcome {
        reward: learner.reward,
        final_policy,
    })
}

/// The baselines' reward in the IRL loop: the MLP on what `job.map` reads and its f-IRL
/// (or MaxEnt) update.
struct BaselineReward<'a> {
    reward: MlpReward,
    /// f-IRL's density ratio (`None`: MaxEnt).
    ratio: Option<Ratio<'a>>,
    /// Demonstrations drawn into each reward step's covariance batch (0: MaxEnt).
    drawn_per_step: usize,
    demo_draw: DemonstrationDraw,
    task_obs_dim: usize,
    /// What the densities read of a row ([`StateMap::columns`]).
    columns: Vec<usize>,
    /// The demonstrations as the reward reads them.
    expert: &'a ExpertData,
    job: &'a BaselineJob<'a>,
}

impl irl_loop::RewardLearner for BaselineReward<'_> {
    type SacReward<'r>
        = StateReward<'r>
    where
        Self: 'r;

    fn sac_reward(&mut self) -> Result<StateReward<'_>, StepError> {
        let map = self.job.map;
        Ok(StateReward::with_map(
            &mut self.reward,
            map,
            self.task_obs_dim,
        ))
    }

    fn update(&mut self, _iteration: usize, batch: AgentBatch) -> Result<UpdateFacts, StepError> {
        let (s, loss, expert) = (self.job.settings, self.job.loss, self.expert);
        let batch = self.job.map.agent(batch, self.task_obs_dim)?;

        // The density ratios (f-IRL), once per iteration.
        let drawn_per_step = self.drawn_per_step;
        let ratios = match self.ratio.as_mut() {
            Some(ratio) => Some(density_ratios(
                ratio,
                expert,
                &batch,
                drawn_per_step > 0,
                &self.columns,
            )?),
            None => None,
        };

        // Reward steps, each on its own draw of demonstrations (f-IRL's samples code); with
        // none drawn, one set of coefficients.
        let reward = &mut self.reward;
        let n_demos = expert.lengths.len();
        reward.set_lr(s.mlp_reward_lr);
        let drawn = self.demo_draw.draw(n_demos, drawn_per_step);
        let mut c = coefficients(loss, expert, &batch, ratios.as_ref(), &drawn)?;
        let mut r = vec![0.0f32; c.coeffs.len()];
        reward.reward_batch(&c.obs, &c.states, &mut r)?;
        let facts = UpdateFacts::of(&r, &c.coeffs, batch.n_states());
        for step in 0..s.reward_steps_per_iteration.max(1) {
            if step > 0 && drawn_per_step > 0 {
                let drawn = self.demo_draw.draw(n_demos, drawn_per_step);
                c = coefficients(loss, expert, &batch, ratios.as_ref(), &drawn)?;
            }
            reward
                .update(&c.obs, &c.states, &c.coeffs)
                .map_err(StepError::RewardUpdate)?;
        }
        Ok(facts)
    }
}
