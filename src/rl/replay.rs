//! Uniform replay buffer for off-policy learning.
