//! End-to-end pipelines behind the binaries (experts, demonstrations, IRL, evaluation).

pub mod commands;
pub mod expert;
pub mod foxglove_scene;
pub mod office;
pub mod offline_rm;
pub mod reacher_draw;
pub mod reacher_expert;
pub mod reacher_irl;
pub mod render;
pub mod replay;
pub mod training_log;
