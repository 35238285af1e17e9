//! The hand-written ("perfect") reward machines of the paper's tasks, shipped as text files
//! under `assets/rm/` (see each file's comments for its reading of the task) and built into
//! the binaries ([`crate::assets`]).

use super::format::{parse_rm, RmFileError};
use super::machine::RewardMachine;

/// Names of every shipped machine (`assets/rm/<name>.txt`).
pub const NAMES: [&str; 10] = [
    "office_t0",
    "office_t1",
    "office_t2",
    "office_t3",
    "office_t4",
    "reacher_or",
    "reacher_sequential",
    "reacher_if",
    "reacher_composite",
    "reacher_blue",
];

/// The text of a shipped machine (`None`: no machine of that name).
pub fn text(name: &str) -> Option<&'static str> {
    crate::assets::reward_machine(name)
}

/// How messages name a shipped machine: `assets/rm/<name>.txt`.
pub fn source_name(name: &str) -> String {
    format!("assets/rm/{name}.txt")
}

/// Parses the built-in `assets/rm/<name>.txt`.
pub fn load(name: &str) -> Result<RewardMachine, RmFileError> {
    let text = text(name).ok_or_else(|| RmFileError::Io {
        file: source_name(name),
        error: std::io::Error::new(
            std::io::ErrorKind::NotFound,
            format!("no shipped reward machine named '{name}'"),
        ),
    })?;
    parse_rm(text, &source_name(name))
}

/// The machine of Office task `task` (0–4).
pub fn office(task: usize) -> Result<RewardMachine, RmFileError> {
    load(&format!("office_t{task}"))
}

/// The machine of a ReacherDelivery task: `or`, `sequential`, `if`, `composite` or `blue`.
pub fn reacher(task: &str) -> Result<RewardMachine, RmFileError> {
    load(&format!("reacher_{task}"))
}
