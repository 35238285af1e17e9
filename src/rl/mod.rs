//! Reinforcement learning: SAC, replay buffer, counterfactual reward-machine relabelling
//! (CRM), tabular solvers.

pub mod crm;
pub mod replay;
pub mod sac;
pub mod tabular;
