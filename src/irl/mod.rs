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
//! - [`firl`]: f-IRL (fkl, rkl, js) and continuous MaxEnt IRL as per-state loss coefficients.
//! - [`smirl`]: SMIRL's linear reward δ_r(u, o) = w_uᵀ φ(o) on U × O and its MaxEnt gradient.
//! - [`reward`]: the [`reward::RewardModel`] trait SAC reads rewards from, and the (64, 64)
//!   MLP reward clamped to ±10 of the baselines.
//!
//! Every objective is a loss L to **minimise** whose parameter gradient is
//! `Σ_s c_s ∇θ r_θ(s)`; the algorithms produce the coefficients `c_s`, the reward model does
//! the weighted backward pass (`RewardModel::backward`) and the optimiser step (`step`).
//!
//! ## Where the loops are
//!
//! This module holds the pieces each IRL iteration is made of; the loops that chain them on
//! ReacherDelivery — SAC on the current reward, fresh rollouts, the algorithm's coefficients,
//! reward steps, ground-truth evaluation watching from outside — are one file per algorithm:
//! `pipeline::reacher_irl::smirl` (continuous SMIRL: learn the machine, annotate, MaxEnt on
//! U × O with SAC on the product and counterfactual machine states) and
//! `pipeline::reacher_irl::firl` (f-IRL fkl/rkl/js and continuous MaxEnt, as f-IRL's code runs
//! them). The Office loops are `pipeline::office` over [`tabular`].
//!
//! Costs per iteration at the paper's sizes: the KDE fit+evaluate of 30 000 × 30 000 runs in
//! tens of milliseconds (see `kde_bench`), the MLP backward over 30 000 states is a few tens of ms;
//! SAC's steps and the rollouts' physics dominate.

pub mod algo;
pub mod firl;
pub mod kde;
pub mod knn_divergence;
pub mod reward;
pub mod smirl;
pub mod tabular;

pub use algo::{Algo, UnknownAlgorithm};
