//! Reinforcement learning: SAC, replay buffer, tabular solvers.

pub mod crm;
pub mod replay;
pub mod sac;
pub mod tabular;
