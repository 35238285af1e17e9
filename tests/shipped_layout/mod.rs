//! The paper's tasks' layout (four balls, one event), from the shipped Composite task, for
//! tests that build observations or environments by hand.

use smirl::env::layout::TaskLayout;
use smirl::env::reacher::ReacherConfig;
use smirl::env::reacher_task::ReacherTask;
use std::sync::{Arc, OnceLock};

/// The layout, loaded once per test binary: loading a task reads its files and builds its
/// scene.
#[allow(dead_code)]
pub fn layout() -> Arc<TaskLayout> {
    static LAYOUT: OnceLock<Arc<TaskLayout>> = OnceLock::new();
    LAYOUT
        .get_or_init(|| ReacherTask::shipped("composite").unwrap().layout())
        .clone()
}

/// The observation width of the paper's tasks.
#[allow(dead_code)]
pub fn obs_dim() -> usize {
    layout().obs_dim()
}

/// `config` over the paper's tasks' layout (Composite's).
#[allow(dead_code)]
pub fn shipped_config(config: ReacherConfig) -> ReacherConfig {
    ReacherTask::shipped("composite")
        .unwrap()
        .env_config(&config)
        .unwrap()
}
