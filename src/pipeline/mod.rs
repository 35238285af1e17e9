//! The experiments behind the binaries, one module per pipeline: `commands` (one entry point
//! per command line, what the binaries call), `reacher_irl` (figure 7: SMIRL and the baselines
//! on ReacherDelivery, one file per algorithm's loop), `reacher_expert` and `expert` (the SAC
//! experts and their demonstrations), `reacher_draw` (f-IRL's own ReacherDraw control),
//! `office` (figures 4–5), `offline_rm` (LRM on logged label traces), `replay`, `render`,
//! `foxglove_scene` and `training_log` (rollout logs: replay, pictures, Foxglove, SAC's own
//! episodes).

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
