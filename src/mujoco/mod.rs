//! Safe wrapper over the `mujoco-sys` bindings. The only module with `unsafe` code.
