//! Simulation state (`mjData`) of one model.

use super::{guard, MjError, Model};
use mujoco_sys as sys;
use std::ptr::NonNull;
use std::sync::Arc;

/// The mutable state of a simulation, tied to its model. Freed on drop.
pub struct Data {
    ptr: NonNull<sys::mjData>,
    model: Arc<Model>,
}

// SAFETY: mjData is plain heap memory owned by this handle, only reached through &mut self
// for writes; moving it to another thread is fine (it is not Sync).
unsafe impl Send for Data {}

impl Data {
    /// Allocates state for `model`, at the model's reference configuration.
    pub fn new(model: Arc<Model>) -> Result<Data, MjError> {
        // SAFETY: valid model pointer.
        let raw = guard(|| unsafe { sys::mj_makeData(model.as_ptr()) })?;
        let ptr = NonNull::new(raw)
            .ok_or_else(|| MjError::Internal("mj_makeData returned null".into()))?;
        Ok(Data { ptr, model })
    }

    pub fn model(&self) -> &Arc<Model> {
        &self.model
    }

    pub(crate) fn raw_parts(&mut self) -> (*const sys::mjModel, *mut sys::mjData) {
        (self.model.as_ptr(), self.ptr.as_ptr())
    }

    fn raw(&self) -> &sys::mjData {
        // SAFETY: valid for the lifetime of self.
        unsafe { self.ptr.as_ref() }
    }

    fn slice(&self, ptr: *const f64, len: usize) -> &[f64] {
        // SAFETY: MuJoCo allocates these arrays with the model's sizes for the life of data.
        unsafe { std::slice::from_raw_parts(ptr, len) }
    }

    fn slice_mut(&mut self, ptr: *mut f64, len: usize) -> &mut [f64] {
        // SAFETY: as above, and &mut self guarantees exclusive access.
        unsafe { std::slice::from_raw_parts_mut(ptr, len) }
    }

    /// Advances the simulation by one time step.
    pub fn step(&mut self) -> Result<(), MjError> {
        let (m, d) = self.raw_parts();
        // SAFETY: m and d are valid and belong together.
        let r = guard(|| unsafe { sys::mj_step(m, d) });
        if r.is_err() {
            // The state after an aborted step is unspecified; leave it well defined.
            self.reset();
        }
        r
    }

    /// Computes derived quantities (positions, velocities of bodies…) without integrating.
    pub fn forward(&mut self) -> Result<(), MjError> {
        let (m, d) = self.raw_parts();
        // SAFETY: as in step.
        let r = guard(|| unsafe { sys::mj_forward(m, d) });
        if r.is_err() {
            self.reset();
        }
        r
    }

    /// Resets to the model's reference configuration (qpos0, zero velocity, time 0).
    pub fn reset(&mut self) {
        let (m, d) = self.raw_parts();
        // SAFETY: as in step; mj_resetData only writes into d.
        unsafe { sys::mj_resetData(m, d) };
    }

    /// Simulation time in seconds.
    pub fn time(&self) -> f64 {
        self.raw().time
    }

    pub fn qpos(&self) -> &[f64] {
        self.slice(self.raw().qpos, self.model.nq())
    }

    pub fn qpos_mut(&mut self) -> &mut [f64] {
        let (p, n) = (self.raw().qpos, self.model.nq());
        self.slice_mut(p, n)
    }

    pub fn qvel(&self) -> &[f64] {
        self.slice(self.raw().qvel, self.model.nv())
    }

    pub fn qvel_mut(&mut self) -> &mut [f64] {
        let (p, n) = (self.raw().qvel, self.model.nv());
        self.slice_mut(p, n)
    }

    pub fn ctrl(&self) -> &[f64] {
        self.slice(self.raw().ctrl, self.model.nu())
    }

    pub fn ctrl_mut(&mut self) -> &mut [f64] {
        let (p, n) = (self.raw().ctrl, self.model.nu());
        self.slice_mut(p, n)
    }

    /// Sets every control input; the length must be the model's `nu`.
    pub fn set_ctrl(&mut self, ctrl: &[f64]) -> Result<(), MjError> {
        copy_checked("ctrl", ctrl, self.ctrl_mut())
    }

    /// Sets every generalised position; the length must be the model's `nq`.
    pub fn set_qpos(&mut self, qpos: &[f64]) -> Result<(), MjError> {
        copy_checked("qpos", qpos, self.qpos_mut())
    }

    /// Sets every generalised velocity; the length must be the model's `nv`.
    pub fn set_qvel(&mut self, qvel: &[f64]) -> Result<(), MjError> {
        copy_checked("qvel", qvel, self.qvel_mut())
    }

    /// Places a mocap body (index from [`Model::body_mocap_id`]); takes effect at the next
    /// `step`/`forward`, and [`Data::reset`] puts it back at its model position.
    pub fn set_mocap_pos(&mut self, mocap: usize, pos: [f64; 3]) {
        let (p, n) = (self.raw().mocap_pos, 3 * self.model.nmocap());
        self.slice_mut(p, n)[3 * mocap..3 * mocap + 3].copy_from_slice(&pos);
    }

    /// World position of a body's frame, as of the last `step`/`forward`.
    pub fn body_xpos(&self, body: usize) -> [f64; 3] {
        let all = self.slice(self.raw().xpos, 3 * self.model.nbody());
        [all[3 * body], all[3 * body + 1], all[3 * body + 2]]
    }

    /// World position of a site, as of the last `step`/`forward`.
    pub fn site_xpos(&self, site: usize) -> [f64; 3] {
        let all = self.slice(self.raw().site_xpos, 3 * self.model.nsite());
        [all[3 * site], all[3 * site + 1], all[3 * site + 2]]
    }

    /// Number of times MuJoCo flagged an unstable simulation (bad acceleration) since the
    /// last reset; MuJoCo resets the state itself when that happens.
    pub fn instability_count(&self) -> i32 {
        self.raw().warning[sys::mjtWarning::mjWARN_BADQACC as usize].number
    }
}

fn copy_checked(what: &'static str, src: &[f64], dst: &mut [f64]) -> Result<(), MjError> {
    if src.len() != dst.len() {
        return Err(MjError::Length {
            what,
            expected: dst.len(),
            got: src.len(),
        });
    }
    dst.copy_from_slice(src);
    Ok(())
}

impl Drop for Data {
    fn drop(&mut self) {
        // SAFETY: allocated by mj_makeData, freed once.
        unsafe { sys::mj_deleteData(self.ptr.as_ptr()) };
    }
}

impl std::fmt::Debug for Data {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Data")
            .field("time", &self.time())
            .field("model", &self.model.source_name())
            .finish()
    }
}
