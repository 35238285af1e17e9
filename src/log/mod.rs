//! MCAP logging of rollouts: schema ([`schema`]), writer ([`RolloutLogger`]) and reader
//! ([`read_log`]).
//!
//! Every rollout (expert generation, training, evaluation) can go to one MCAP file per run
//! with enough to re-simulate it exactly: the model XML (attached, and its SHA-256 in the run
//! record), each episode's initial `qpos`/`qvel`, ball layout and cancel step, and every
//! action. Files open in Foxglove and the official MCAP readers (see the schema docs for the
//! topics and encodings).
//!
//! **Cost.** The training thread only encodes a step into a byte buffer (protobuf, no
//! allocation); a background thread does the MCAP framing and zstd compression (single
//! threaded: the `mcap` writer's default spawns one zstd worker per core) and the writes.
//!
//! **Crash safety.** The file is written as `NAME.mcap.part` and renamed to `NAME.mcap` when
//! finished ([`RolloutLogger::finish`] or drop). Chunks are built in memory and written whole,
//! so a run killed mid-write leaves a `.part` file that [`read_log`] reads up to its last
//! complete chunk, with a warning saying how much it recovered.

pub mod demo;
pub mod proto;
pub mod reader;
pub mod schema;
pub mod writer;

pub use reader::{
    read_log, read_log_bytes, read_log_file, read_log_records, LogModelError, LoggedEpisode,
    RecordSink, Recovery, RolloutLog,
};
pub use schema::{
    EpisodeEndMsg, EpisodeStartMsg, RunInfo, RunLayoutError, StepMsg, SCHEMA_VERSION,
};
pub use writer::{LogOptions, LogSummary, RolloutLogger, RunHeader, StepRecord};

use std::path::PathBuf;

/// Errors writing or reading a rollout log; each names the file.
#[derive(Debug, thiserror::Error)]
pub enum LogError {
    #[error("{path}: {source}")]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("{path}: MCAP error: {source}")]
    Mcap {
        path: PathBuf,
        #[source]
        source: mcap::McapError,
    },
    #[error("{path}: not an MCAP file ({problem})")]
    NotMcap { path: PathBuf, problem: String },
    #[error("{path}: not a smirl rollout log ({problem})")]
    NotRolloutLog { path: PathBuf, problem: String },
    #[error("{path}: log schema version {found} is not supported (this build reads version {supported})")]
    UnknownSchemaVersion {
        path: PathBuf,
        found: String,
        supported: u32,
    },
    #[error("{path}: the log is too large to read: {problem}")]
    TooLarge { path: PathBuf, problem: String },
    #[error("{path}: corrupt log: {problem}")]
    Corrupt { path: PathBuf, problem: String },
    #[error("{path}: {problem}")]
    Usage { path: PathBuf, problem: String },
    /// The environment failed while the log was being written (MuJoCo's own error).
    #[error("{path}: the simulation failed: {problem}")]
    Simulation { path: PathBuf, problem: String },
    #[error("{path}: the log writer thread stopped: {problem}")]
    WriterStopped { path: PathBuf, problem: String },
}
