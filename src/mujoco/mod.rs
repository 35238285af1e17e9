//! Safe wrapper over the `mujoco-sys` bindings. The only module with `unsafe` code.
//!
//! - [`Model`] is a compiled MJCF model, loaded from a file or from an XML string; MuJoCo's
//!   error-buffer text becomes [`MjError::Load`] naming the file.
//! - [`Data`] is the simulation state of one model; it owns its buffers and holds an `Arc` of
//!   its model, so it can step without a borrow.
//! - MuJoCo 2.2.2 reports internal errors through `mju_error`, whose default handler prints
//!   "Press Enter to exit", waits on stdin and calls `exit(1)`: a headless run would hang or
//!   die. [`install_handlers`] replaces it with a handler that unwinds into the guarded call
//!   (`"C-unwind"` + [`std::panic::resume_unwind`], which skips the panic hook), where it
//!   becomes [`MjError::Internal`]. Warnings are recorded per thread instead of being printed
//!   and appended to `MUJOCO_LOG.TXT`.

mod data;
mod model;

pub use data::Data;
pub use model::{in_memory_text_name, vfs_key, Model, ObjectKind, IN_MEMORY_DIR, TEXT_ALONE_NAME};

use std::cell::RefCell;
use std::ffi::{c_char, CStr};
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::sync::Once;

/// Errors from MuJoCo and from misuse of the wrapper.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum MjError {
    #[error("cannot load MuJoCo model {source_name}: {message}")]
    Load {
        source_name: String,
        message: String,
    },
    #[error("no {kind} named '{name}' in model {model}")]
    UnknownName {
        kind: &'static str,
        name: String,
        model: String,
    },
    #[error("MuJoCo error: {0}")]
    Internal(String),
    #[error("linked MuJoCo library reports version {found}, this build needs 2.2.x")]
    Version { found: String },
    #[error("{what} has {got} values, the model has {expected}")]
    Length {
        what: &'static str,
        expected: usize,
        got: usize,
    },
}

/// The message carried by an unwinding `mju_error`.
struct MjErrorPayload(String);

/// Most warnings kept per thread between two [`take_warnings`] calls: nothing in a long
/// training run reads them, so the list must not grow without bound; later ones are counted.
const MAX_KEPT_WARNINGS: usize = 64;

thread_local! {
    /// Warnings kept, and how many more were dropped.
    static WARNINGS: RefCell<(Vec<String>, u64)> = const { RefCell::new((Vec::new(), 0)) };
}

unsafe extern "C-unwind" fn on_error(msg: *const c_char) {
    let text = if msg.is_null() {
        String::from("(no message)")
    } else {
        CStr::from_ptr(msg).to_string_lossy().into_owned()
    };
    // resume_unwind, not panic!: no panic hook runs, so nothing is printed; the guard that
    // wraps every MuJoCo call catches this payload.
    std::panic::resume_unwind(Box::new(MjErrorPayload(text)));
}

unsafe extern "C-unwind" fn on_warning(msg: *const c_char) {
    if msg.is_null() {
        return;
    }
    WARNINGS.with(|w| {
        let (kept, dropped) = &mut *w.borrow_mut();
        if kept.len() < MAX_KEPT_WARNINGS {
            kept.push(CStr::from_ptr(msg).to_string_lossy().into_owned());
        } else {
            *dropped += 1;
        }
    });
}

static INSTALL: Once = Once::new();

/// Installs the error and warning handlers (idempotent). Called by every constructor here.
pub fn install_handlers() {
    INSTALL.call_once(|| {
        // SAFETY: the handlers are set once, before any model exists. Both have the
        // "C-unwind" ABI (the sys crate declares MuJoCo's functions and handler pointers so),
        // which makes unwinding out of `on_error` through MuJoCo's frames defined.
        unsafe {
            mujoco_sys::mju_user_error = Some(on_error);
            mujoco_sys::mju_user_warning = Some(on_warning);
        }
    });
}

/// Runs a closure that calls into MuJoCo, turning an `mju_error` into [`MjError::Internal`].
pub(crate) fn guard<T>(f: impl FnOnce() -> T) -> Result<T, MjError> {
    install_handlers();
    catch_unwind(AssertUnwindSafe(f)).map_err(|payload| {
        match payload.downcast::<MjErrorPayload>() {
            Ok(p) => MjError::Internal(p.0),
            // A genuine Rust panic inside the closure is a bug: let it continue.
            Err(other) => std::panic::resume_unwind(other),
        }
    })
}

/// Takes the MuJoCo warnings recorded on this thread since the last call (at most
/// `MAX_KEPT_WARNINGS`, then one line saying how many more there were).
pub fn take_warnings() -> Vec<String> {
    WARNINGS.with(|w| {
        let (kept, dropped) = std::mem::take(&mut *w.borrow_mut());
        let mut out = kept;
        if dropped > 0 {
            out.push(format!("... and {dropped} more MuJoCo warnings"));
        }
        out
    })
}

/// The linked library's version as MuJoCo reports it (`222` for 2.2.2).
pub fn version() -> i32 {
    // SAFETY: no arguments, returns a constant.
    unsafe { mujoco_sys::mj_version() }
}

/// The linked library's version string, e.g. `"2.2.2"`.
pub fn version_string() -> String {
    // SAFETY: returns a pointer to a static NUL-terminated string.
    unsafe { CStr::from_ptr(mujoco_sys::mj_versionString()) }
        .to_string_lossy()
        .into_owned()
}

/// Checks that the linked library is MuJoCo 2.2.x, the version the bindings were made for.
pub fn check_version() -> Result<(), MjError> {
    if version() / 10 == mujoco_sys::EXPECTED_MAJOR_MINOR {
        Ok(())
    } else {
        Err(MjError::Version {
            found: version_string(),
        })
    }
}

/// The reference loop for benchmarks: `steps × frame_skip` bare `mj_step` calls with a fixed
/// control, no guard, no bookkeeping. Environments are measured against it.
pub fn raw_step_loop(data: &mut Data, ctrl: &[f64], steps: usize, frame_skip: usize) {
    data.set_ctrl(ctrl)
        .expect("control length checked by the caller");
    let (m, d) = data.raw_parts();
    for _ in 0..steps {
        for _ in 0..frame_skip {
            // SAFETY: m and d are valid and belong together (Data holds its model).
            unsafe { mujoco_sys::mj_step(m, d) };
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::ffi::CString;

    #[test]
    fn warnings_are_kept_up_to_a_bound_and_the_rest_counted() {
        let _ = take_warnings();
        let msg = CString::new("Nan, Inf or huge value in QACC").unwrap();
        for _ in 0..MAX_KEPT_WARNINGS + 36 {
            // SAFETY: a valid NUL-terminated string, as MuJoCo passes.
            unsafe { on_warning(msg.as_ptr()) };
        }
        let got = take_warnings();
        assert_eq!(got.len(), MAX_KEPT_WARNINGS + 1);
        assert_eq!(got[0], "Nan, Inf or huge value in QACC");
        assert_eq!(got[MAX_KEPT_WARNINGS], "... and 36 more MuJoCo warnings");
        assert!(take_warnings().is_empty());
    }

    #[test]
    fn linked_library_is_2_2() {
        check_version().unwrap();
        assert!(version_string().starts_with("2.2"));
    }

    #[test]
    fn mju_error_becomes_an_error_value() {
        let msg = std::ffi::CString::new("deliberate test error").unwrap();
        // SAFETY: mju_error only reads the message before calling the installed handler.
        let r = guard(|| unsafe { mujoco_sys::mju_error(msg.as_ptr()) });
        assert_eq!(r, Err(MjError::Internal("deliberate test error".into())));
        // The thread is still usable afterwards.
        assert_eq!(guard(|| 2 + 2), Ok(4));
    }
}
