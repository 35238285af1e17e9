//! Where a command may write: the rules that keep every binary from deleting or replacing
//! anything it did not create.
//!
//! - An output **directory** is created by this program and carries the marker file
//!   [`MARKER`]. An existing one is replaced only with `--force` *and* only when it carries
//!   the marker; an existing empty directory is used; anything else is refused. The
//!   working directory, its ancestors, the home directory and paths without a final name
//!   (`.`, `..`, `/`) are never output directories.
//! - Work is written to `<out>.partial` (marked when created; a leftover one is removed only
//!   if it carries the marker) and moved into place when complete: the previous output is
//!   first moved aside to `<out>.replaced`, then removed.
//! - An output **file** that exists is replaced only with `--force`; a directory in its
//!   place is refused.
//! - An output file is never one of the command's inputs ([`check_not_input`]), through
//!   another name, a symlink or a hard link.
//! - Every check runs before any work starts, including a write probe in the nearest
//!   existing ancestor, so an unwritable place fails in a second, not after an hour of
//!   training. Checks create nothing: missing parent directories are created only when the
//!   output is written ([`create_parent`]), so a refused command leaves no trace.

use std::path::{Component, Path, PathBuf};

/// File that marks a directory as written by this program.
pub const MARKER: &str = ".smirl-output";

const MARKER_TEXT: &str = "This directory was written by smirl; `--force` may replace it.\n";

/// A refused output location: the path and why.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("output {}: {problem}", path.display())]
pub struct OutputError {
    pub path: PathBuf,
    pub problem: String,
}

fn refuse(path: &Path, problem: impl Into<String>) -> OutputError {
    OutputError {
        path: path.to_path_buf(),
        problem: problem.into(),
    }
}

/// Writes the marker into `dir` (which this program created).
pub fn mark(dir: &Path) -> Result<(), OutputError> {
    std::fs::write(dir.join(MARKER), MARKER_TEXT)
        .map_err(|e| refuse(dir, format!("cannot write its marker: {e}")))
}

/// `dir` carries the marker.
pub fn is_marked(dir: &Path) -> bool {
    dir.join(MARKER).is_file()
}

/// `dir` is the `<out>.partial` working directory of an output (marked, named `*.partial`):
/// still being written, or left by a run that stopped. It is renamed to `<out>` when the run
/// ends, so a command that adds files to it loses them or recreates a stray directory.
pub fn is_work_in_progress(dir: &Path) -> bool {
    let partial_name = dir
        .file_name()
        .and_then(|n| n.to_str())
        .is_some_and(|n| n.ends_with(".partial"));
    partial_name && is_marked(dir)
}

/// The absolute form of `path` with `.` and `..` resolved through the real directories
/// where they exist (symlinks included), lexically below the deepest existing ancestor.
fn resolve(path: &Path) -> Result<PathBuf, OutputError> {
    let cwd = std::env::current_dir()
        .map_err(|e| refuse(path, format!("cannot read the working directory: {e}")))?;
    let absolute = cwd.join(path);
    let mut existing = absolute.clone();
    let mut rest = Vec::new();
    while !existing.exists() {
        match (existing.file_name(), existing.parent()) {
            (Some(name), Some(parent)) => {
                rest.push(name.to_os_string());
                existing = parent.to_path_buf();
            }
            _ => break,
        }
    }
    let mut resolved = existing.canonicalize().unwrap_or(existing);
    for name in rest.into_iter().rev() {
        match Path::new(&name).components().next() {
            Some(Component::ParentDir) => {
                resolved.pop();
            }
            Some(Component::CurDir) | None => {}
            Some(_) => resolved.push(name),
        }
    }
    Ok(resolved)
}

/// Paths that are never an output directory: no final name, the working directory or an
/// ancestor of it, the home directory or an ancestor of it. Returns the resolved path.
pub fn check_not_protected(path: &Path) -> Result<PathBuf, OutputError> {
    if !matches!(path.components().next_back(), Some(Component::Normal(_))) {
        return Err(refuse(
            path,
            "names no directory of its own (`.`, `..` or a root): choose a new directory name",
        ));
    }
    let resolved = resolve(path)?;
    if let Ok(cwd) = std::env::current_dir().and_then(|d| d.canonicalize()) {
        if cwd.starts_with(&resolved) {
            return Err(refuse(
                path,
                "is the working directory or one of its ancestors: choose a new directory name",
            ));
        }
    }
    if let Some(home) = std::env::var_os("HOME").map(PathBuf::from) {
        let home = home.canonicalize().unwrap_or(home);
        if home.starts_with(&resolved) {
            return Err(refuse(
                path,
                "is the home directory or one of its ancestors: choose a new directory name",
            ));
        }
    }
    Ok(resolved)
}

/// The directory that will hold `path` (`.` for a bare name).
fn parent_of(path: &Path) -> PathBuf {
    match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    }
}

/// Checks, without creating anything, that `path` can be created: its nearest existing
/// ancestor is a directory in which a file can be written (a probe file, removed at once).
fn check_parent_writable(path: &Path) -> Result<(), OutputError> {
    let mut ancestor = parent_of(path);
    while !ancestor.exists() {
        match ancestor.parent() {
            Some(p) if !p.as_os_str().is_empty() => ancestor = p.to_path_buf(),
            _ => {
                ancestor = PathBuf::from(".");
                break;
            }
        }
    }
    if !ancestor.is_dir() {
        return Err(refuse(
            path,
            format!("{} is not a directory", ancestor.display()),
        ));
    }
    let name = path
        .file_name()
        .map_or_else(|| "output".into(), |n| n.to_string_lossy().into_owned());
    let probe = ancestor.join(format!(".{name}.probe-{}", std::process::id()));
    std::fs::write(&probe, b"")
        .map_err(|e| refuse(path, format!("cannot write in {}: {e}", ancestor.display())))?;
    let _ = std::fs::remove_file(&probe);
    Ok(())
}

/// Creates the missing parent directories of the output file `path`, when the command
/// starts writing it (the checks before create nothing).
pub fn create_parent(path: &Path) -> Result<(), OutputError> {
    let parent = parent_of(path);
    std::fs::create_dir_all(&parent)
        .map_err(|e| refuse(path, format!("cannot create {}: {e}", parent.display())))
}

/// The file's identity (device and inode), the same through every name and link.
fn file_id(path: &Path) -> Option<(u64, u64)> {
    use std::os::unix::fs::MetadataExt;
    std::fs::metadata(path).ok().map(|m| (m.dev(), m.ino()))
}

/// Refuses an output file `out` that is one of `inputs`: the same path once symlinks, `.`
/// and `..` are resolved, or the same file through a hard link. `--force` does not lift this.
pub fn check_not_input(out: &Path, inputs: &[&Path]) -> Result<(), OutputError> {
    let resolved = resolve(out)?;
    let out_id = file_id(out);
    for input in inputs {
        if resolve(input)? == resolved || (out_id.is_some() && file_id(input) == out_id) {
            return Err(refuse(
                out,
                format!(
                    "is the input {}: choose another output (not even --force writes over an \
                     input)",
                    input.display()
                ),
            ));
        }
    }
    Ok(())
}

fn is_empty_dir(path: &Path) -> Result<bool, OutputError> {
    let mut entries =
        std::fs::read_dir(path).map_err(|e| refuse(path, format!("cannot list it: {e}")))?;
    Ok(entries.next().is_none())
}

/// A checked output directory (see the module docs).
#[derive(Clone, Debug)]
pub struct OutputDir {
    path: PathBuf,
}

impl OutputDir {
    /// Checks `path` as an output directory that the command fills from scratch.
    pub fn check(path: &Path, force: bool) -> Result<OutputDir, OutputError> {
        check_not_protected(path)?;
        if path.exists() {
            if !path.is_dir() {
                return Err(refuse(path, "exists and is not a directory"));
            }
            if !is_empty_dir(path)? {
                if !force {
                    return Err(refuse(
                        path,
                        "exists and is not empty: choose a new directory, or pass --force to \
                         replace an earlier output of this program",
                    ));
                }
                if !is_marked(path) {
                    return Err(refuse(
                        path,
                        format!(
                            "exists and was not written by this program (no {MARKER} in it): \
                             not replacing it, even with --force"
                        ),
                    ));
                }
            }
        }
        check_parent_writable(path)?;
        let partial = partial_path(path);
        if partial.exists() && !(partial.is_dir() && is_marked(&partial)) {
            return Err(refuse(
                &partial,
                format!("exists and was not written by this program (no {MARKER} in it): remove or rename it"),
            ));
        }
        // `commit` moves an existing output aside to `<out>.replaced`, removing an earlier
        // one there: only one this program wrote.
        let aside = replaced_path(path);
        if path.exists() && aside.exists() && !(aside.is_dir() && is_marked(&aside)) {
            return Err(refuse(
                &aside,
                format!("exists and was not written by this program (no {MARKER} in it): remove or rename it"),
            ));
        }
        Ok(OutputDir {
            path: path.to_path_buf(),
        })
    }

    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Creates the output directory in place, empty and marked, for a command that writes
    /// into it as it goes (e.g. checkpoints): a previous output (empty, or marked: checked
    /// again now) is removed first.
    pub fn create(&self) -> Result<(), OutputError> {
        let out = &self.path;
        if out.exists() {
            if !(out.is_dir() && (is_marked(out) || is_empty_dir(out)?)) {
                return Err(refuse(
                    out,
                    "appeared after the check and is not ours: not touching it",
                ));
            }
            std::fs::remove_dir_all(out)
                .map_err(|e| refuse(out, format!("cannot remove the previous output: {e}")))?;
        }
        std::fs::create_dir_all(out).map_err(|e| refuse(out, format!("cannot create it: {e}")))?;
        mark(out)
    }

    /// Creates `<out>.partial`, empty and marked (removing a leftover marked one).
    pub fn begin(&self) -> Result<PathBuf, OutputError> {
        let partial = partial_path(&self.path);
        if partial.exists() {
            if !is_marked(&partial) {
                return Err(refuse(
                    &partial,
                    format!("exists without {MARKER}: not removing it"),
                ));
            }
            std::fs::remove_dir_all(&partial)
                .map_err(|e| refuse(&partial, format!("cannot remove it: {e}")))?;
        }
        std::fs::create_dir_all(&partial)
            .map_err(|e| refuse(&partial, format!("cannot create it: {e}")))?;
        mark(&partial)?;
        Ok(partial)
    }

    /// Moves the finished `partial` into place. A previous output (empty, or marked: checked
    /// again now) is moved aside first and removed after the move.
    pub fn commit(&self, partial: &Path) -> Result<(), OutputError> {
        let out = &self.path;
        let aside = replaced_path(out);
        let previous = if out.exists() {
            if !(out.is_dir() && (is_marked(out) || is_empty_dir(out)?)) {
                return Err(refuse(out, "appeared during the run and is not ours: leaving the result in the .partial directory"));
            }
            if aside.exists() {
                if !(aside.is_dir() && is_marked(&aside)) {
                    return Err(refuse(
                        &aside,
                        format!("exists without {MARKER}: not removing it"),
                    ));
                }
                std::fs::remove_dir_all(&aside)
                    .map_err(|e| refuse(&aside, format!("cannot remove it: {e}")))?;
            }
            std::fs::rename(out, &aside)
                .map_err(|e| refuse(out, format!("cannot move it aside: {e}")))?;
            true
        } else {
            false
        };
        std::fs::rename(partial, out).map_err(|e| {
            refuse(
                out,
                format!("cannot move {} into place: {e}", partial.display()),
            )
        })?;
        if previous {
            std::fs::remove_dir_all(&aside)
                .map_err(|e| refuse(&aside, format!("cannot remove the previous output: {e}")))?;
        }
        Ok(())
    }
}

/// `<out>.partial`.
pub fn partial_path(out: &Path) -> PathBuf {
    let mut name = out
        .file_name()
        .map_or_else(Default::default, |n| n.to_os_string());
    name.push(".partial");
    out.with_file_name(name)
}

/// `<out>.replaced`, where [`OutputDir::commit`] moves a previous output aside.
pub fn replaced_path(out: &Path) -> PathBuf {
    let mut name = out
        .file_name()
        .map_or_else(Default::default, |n| n.to_os_string());
    name.push(".replaced");
    out.with_file_name(name)
}

/// Checks `path` as an output file: a directory there is refused, an existing file is
/// replaced only with `force`, and the nearest existing ancestor must be writable. Nothing
/// is created: the writer calls [`create_parent`].
pub fn check_file(path: &Path, force: bool) -> Result<(), OutputError> {
    if !matches!(path.components().next_back(), Some(Component::Normal(_))) {
        return Err(refuse(path, "names no file"));
    }
    if path.is_dir() {
        return Err(refuse(path, "is a directory: name a file"));
    }
    if path.exists() && !force {
        return Err(refuse(
            path,
            "exists: choose another name, or pass --force to replace it",
        ));
    }
    check_parent_writable(path)
}
