//! Inverse RL: apprenticeship learning, MaxEnt IRL, f-IRL, kernel density estimation and SMIRL.
//!
//! # Tabular IRL (Office Gridworld)
//!
//! - [`tabular`]: experts and demonstrations, MaxEnt IRL, SMIRL on the product, apprenticeship
//!   learning and ground-truth evaluation.
//!
//! # Continuous IRL (ReacherDelivery)
//!
//! - [`kde`]: exact Epanechnikov KDE on a bandwidth-sized cell grid (state marginals).
//! - [`knn_divergence`]: the k-nearest-neighbour KL estimate between two sample sets, f-IRL's
//!   measure of how well an agent's state marginal matches a target density.
//! - [`discriminator`]: a logistic classifier of expert vs agent states whose logit estimates
//!   log(ρ_E/ρ_θ), f-IRL's density ratio for an expert given by demonstrations.
//! - [`firl`]: f-IRL (fkl, rkl, js) and continuous MaxEnt IRL as per-state loss coefficients.
//! - [`smirl`]: SMIRL's linear reward δ_r(u, o) = w_uᵀ φ(o) on U × O and its MaxEnt gradient.
//! - [`reward`]: the [`reward::RewardModel`] trait SAC reads rewards from, and the (64, 64)
//!   MLP reward clamped to ±10 of the baselines.
//!
//! Every objective is a loss L to **minimise** whose parameter gradient is
//! `Σ_s c_s ∇θ r_θ(s)`; the algorithms produce the coefficients `c_s`, the reward model does
//! the weighted backward pass (`RewardModel::backward`) and the optimiser step (`step`).
//!
//! ## One IRL iteration, as the pipeline should chain it
//!
//! Before the loop: the expert demonstrations (16 trajectories in the paper) give the expert
//! observations `obs_E`. For f-IRL, fit `kde_E = Kde::fit_columns(obs_E, OBS_DIM, &OBS_TIP,
//! 0.02)` once. For SMIRL, learn the RM from the demos' label traces, annotate each expert
//! observation o_t with the RM state its labels are read in (u_{t−1}, see [`smirl`]), and
//! build a [`smirl::LinearRmReward`] with one weight vector per RM state (features
//! [`smirl::FeatureMap::reacher_labels`] — the paper's — or the documented smooth variant).
//! The SAC agent is created once and **kept across iterations** (not re-initialised).
//!
//! Per iteration m = 1..M:
//! 1. **Policy.** Continue training SAC for K environment steps on the *current* learned
//!    reward: the transition reward is `reward_batch(o_{t+1}, u_t)` (f-IRL/MaxEnt ignore u;
//!    SMIRL's SAC sees the product state (o, one-hot u)). Recompute rewards from the replay
//!    batch's stored observations at sampling time, so old transitions follow the reward
//!    the agent is now optimising (the reward changes every iteration).
//! 2. **Rollouts.** Collect fresh agent trajectories with the current (stochastic) policy:
//!    N trajectories of fixed length T (the paper: 1000 × 30 = 30 000 states; Reacher's
//!    episodes are cut at `max_steps`, which gives the fixed T the covariance needs). Record
//!    observations and, for SMIRL, the RM state paired with each observation. Evaluate the
//!    policy on the ground-truth task here too (success rate, return) for the metrics CSV.
//! 3. **Densities (f-IRL only).** `kde_A = Kde::fit_columns(obs_A, …, 0.02)` on this
//!    iteration's agent states.
//! 4. **Coefficients.**
//!    - f-IRL: `FirlSurrogate::from_kde(div, &kde_E, &kde_A, obs_A, OBS_DIM, &OBS_TIP, N, T,
//!      DEFAULT_DENSITY_EPS)?.coefficients` — one coefficient per agent state.
//!    - MaxEnt: `MaxEntCoefficients::new(n_A, n_E, T)` — `agent` at every agent state,
//!      `expert` at every expert state; concatenate `obs_A ++ obs_E` and the coefficients.
//!    - SMIRL: [`smirl::maxent_coefficients`] on the annotated expert and agent batches
//!      (the tests check it against the expert-minus-agent feature expectations).
//! 5. **Reward update.** `reward.update(obs, rm_state, &coeffs)` — one or a few optimiser
//!    steps (the f-IRL code takes a few reward gradient steps per iteration on the same
//!    batch; recompute nothing in between, the coefficients do not depend on θ).
//!
//! Costs per iteration at the paper's sizes: the KDE fit+evaluate of 30 000 × 30 000 runs in
//! milliseconds (see `kde_bench`), the MLP backward over 30 000 states is a few tens of ms;
//! SAC's K steps dominate.

pub mod discriminator;
pub mod firl;
pub mod kde;
pub mod knn_divergence;
pub mod reward;
pub mod smirl;
pub mod tabular;
