//! The hand-written ("perfect") reward machines of the paper's tasks, shipped as text files
//! under `assets/rm/` (see each file's comments for its reading of the task).

use super::format::{read_rm, RmFileError};
use super::machine::RewardMachine;
use std::path::PathBuf;

/// Names of every shipped machine (`assets/rm/<name>.txt`).
pub const NAMES: [&str; 9] = [
    "office_t0",
    "office_t1",
    "office_t2",
    "office_t3",
    "office_t4",
    "reacher_or",
    "reacher_sequential",
    "reacher_if",
    "reacher_composite",
];

/// Path of a shipped machine.
pub fn path(name: &str) -> PathBuf {
    PathBuf::from(crate::ASSETS_DIR)
        .join("rm")
        .join(format!("{name}.txt"))
}

/// Loads `assets/rm/<name>.txt`.
pub fn load(name: &str) -> Result<RewardMachine, RmFileError> {
    read_rm(&path(name))
}

/// The machine of Office task `task` (0–4).
pub fn office(task: usize) -> Result<RewardMachine, RmFileError> {
    load(&format!("office_t{task}"))
}

/// The machine of a ReacherDelivery task: `or`, `sequential`, `if` or `composite`.
pub fn reacher(task: &str) -> Result<RewardMachine, RmFileError> {
    load(&format!("reacher_{task}"))
}
