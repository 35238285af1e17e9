//! How a scene lets the environment put a region's centre (a ball) where a layout says.
//!
//! The built-in scene (`assets/reacher_delivery.xml`) makes each ball a *mocap* body: a body
//! of the world with no degrees of freedom whose position each simulation state holds
//! (`mocap_pos`), so the physics integrates the arm's two joints only. The first built-in
//! scene (`assets/reacher_delivery_v1.xml`, the model of logs that record it) gives each ball
//! two slide joints `<body>_x`, `<body>_y` whose values in `qpos` are its position. Both
//! move the ball without touching the arm: its trajectory is the same bit for bit.

use crate::mujoco::{Data, Model, ObjectKind};

/// How one body of a scene is placed at an (x, y) position.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Placement {
    /// A mocap body: its index in `mocap_pos` and its height (z) in the model.
    Mocap { mocap: usize, z: f64 },
    /// A body with slide joints `<body>_x`, `<body>_y`: the index of the x slide in `qpos`
    /// (the y slide is the next value).
    Slides { qpos: usize },
}

impl Placement {
    /// How `body` can be placed, or `None` when it is neither a mocap body nor a body with
    /// adjacent slide joints `<body>_x`, `<body>_y` (or there is no such body).
    pub fn find(model: &Model, body: &str) -> Option<Placement> {
        if let Ok(id) = model.id(ObjectKind::Body, body) {
            if let Some(mocap) = model.body_mocap_id(id) {
                return Some(Placement::Mocap {
                    mocap,
                    z: model.body_pos(id)[2],
                });
            }
        }
        let x = model.id(ObjectKind::Joint, &format!("{body}_x")).ok()?;
        let y = model.id(ObjectKind::Joint, &format!("{body}_y")).ok()?;
        let qpos = model.joint_qpos_addr(x);
        (model.joint_qpos_addr(y) == qpos + 1).then_some(Placement::Slides { qpos })
    }

    /// Puts the body at `position` in `data`; takes effect at the next `forward`/`step`.
    pub fn place(&self, data: &mut Data, position: [f64; 2]) {
        match *self {
            Placement::Mocap { mocap, z } => {
                data.set_mocap_pos(mocap, [position[0], position[1], z])
            }
            Placement::Slides { qpos } => {
                data.qpos_mut()[qpos..qpos + 2].copy_from_slice(&position);
            }
        }
    }
}
