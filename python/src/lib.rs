//! `smirl._core`: the Rust core behind the `smirl` Python package.
//!
//! Thin bindings over the `smirl` library: a task's environment (ReacherDelivery × its perfect
//! machine) one at a time or as a batch stepped without the GIL, reward machines (text, DOT,
//! stepping, equivalence), LRM, SMIRL's learned rewards, and the MCAP rollout logs. Every error of the library reaches
//! Python as an exception carrying the library's message; arguments are checked here before
//! they reach the library, so no call can panic or abort the interpreter.

mod env;
mod learned_product;
mod logs;
mod office;
mod reward;
mod rm;

use pyo3::prelude::*;

pyo3::create_exception!(_core, SmirlError, pyo3::exceptions::PyException);

#[pymodule]
fn _core(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("SmirlError", m.py().get_type::<SmirlError>())?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add("GIT_COMMIT", smirl::GIT_COMMIT)?;
    env::register(m)?;
    rm::register(m)?;
    logs::register(m)?;
    office::register(m)?;
    reward::register(m)?;
    learned_product::register(m)?;
    Ok(())
}

/// An exception from a library error, keeping its message.
pub(crate) fn error(e: impl std::fmt::Display) -> PyErr {
    SmirlError::new_err(e.to_string())
}
