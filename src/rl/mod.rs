//! Reinforcement learning: SAC, replay buffer, tabular solvers.
