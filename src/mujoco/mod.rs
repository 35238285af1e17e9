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
pub use model::{Model, ObjectKind};

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

thread_local! {
    static WARNINGS: RefCell<Vec<String>> = const { RefCell::new(Vec::new()) };
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
    let text = CStr::from_ptr(msg).to_string_lossy().into_owned();
    WARNINGS.with(|w| w.borrow_mut().push(text));
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

/// Takes the MuJoCo warnings recorded on this thread since the last call.
pub fn take_warnings() -> Vec<String> {
    WARNINGS.with(|w| std::mem::take(&mut *w.borrow_mut()))
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
