//! Inverse RL: apprenticeship learning, MaxEnt IRL, f-IRL, kernel density estimation and SMIRL.

pub mod tabular;
