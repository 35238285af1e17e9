//! The commands behind the binaries `reacher` and `office`: one entry point per command,
//! taking the parsed arguments as a plain struct, checking them, running the pipeline and
//! printing what the command prints. The binaries only parse arguments, call one entry point
//! and turn its result into an exit status, so everything a command decides (defaults of
//! output directories, which inputs are refused, what is printed) lives here, where tests and
//! other programs can reach it.
//!
//! - [`logs`]: `reacher replay`, `render`, `foxglove`, `demo`, `learn-rm` (rollout logs).
//! - [`expert`]: `reacher expert` (train, evaluate and save a task's SAC expert).
//! - [`irl`]: `reacher --task`, `prepare`, `job`, `aggregate`, `reward` (the IRL pipeline).
//! - [`draw`]: `reacher draw` (f-IRL's ReacherDraw).
//! - [`figure`]: `reacher figure` (small multiples of learning curves from a curve table).
//! - [`office`]: `office` (the Office Gridworld experiments).
//!
//! Errors: a command fails with a [`UsageError`] for bad input (an argument, a config, an
//! output path it may not write), found before anything is written where it can be, and with
//! any other error for a failure while running. Commands never print their error: the binary
//! prints it once and maps a [`UsageError`] to exit status 2, anything else to 1.

pub mod draw;
pub mod expert;
pub mod figure;
pub mod irl;
pub mod logs;
pub mod office;

/// Bad input to a command: an argument, a config or an output path it may not write (exit
/// status 2). Its message is printed as it is.
#[derive(Debug)]
pub struct UsageError(pub String);

impl std::fmt::Display for UsageError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for UsageError {}

/// Lets a closed standard output end the process quietly, as it ends `cat` or `grep`: Rust
/// ignores SIGPIPE, so `reacher replay LOG | head` would otherwise panic in `println!` once
/// `head` exits. Called first thing by the binaries.
#[allow(unsafe_code)]
pub fn exit_quietly_on_closed_pipe() {
    // SAFETY: restores the default action of one signal before any thread is started.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
}

/// Whether `error` (or an error it wraps) is a [`UsageError`].
pub fn is_usage(error: &anyhow::Error) -> bool {
    error.downcast_ref::<UsageError>().is_some()
}

/// The message of `error` and of the errors it wraps, joined by `: ` — each cause once: many
/// errors name their cause in their own message already (`{path}: {source}`), and anyhow's
/// `{:#}` would print it again.
pub fn error_message(error: &anyhow::Error) -> String {
    let mut text = String::new();
    for cause in error.chain() {
        let part = cause.to_string();
        if text.is_empty() {
            text = part;
        } else if !text.ends_with(&part) {
            text.push_str(": ");
            text.push_str(&part);
        }
    }
    text
}

/// A [`UsageError`] with `message`, as the commands return it.
fn usage(message: impl std::fmt::Display) -> anyhow::Error {
    anyhow::Error::new(UsageError(message.to_string()))
}
