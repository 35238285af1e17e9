//! A scripted controller for ReacherDelivery: drives the fingertip to a chosen ball with the
//! 2-link arm's inverse kinematics and a PD law on the joint angles, then dwells briefly so
//! the touch registers before moving on.
//!
//! It is for tests and scripted demonstrations (e.g. the Sequential task r→g→b→y logged to
//! MCAP and fed to the RM learner). The paper's experts are SAC policies trained on each
//! task's reward machine; those come from the SAC work (`rl::sac`), not from here.
//!
//! The controller reads only the observation (joint angles from their cos/sin, joint
//! velocities, fingertip and region offsets), the labels and optionally the RM state, so it
//! drives any ReacherDelivery rollout, including a replayed one. A target is a region's index,
//! which is its label bit (`env::layout`).

use crate::env::layout::{TaskLayout, OBS_ARM};
use crate::rm::LabelSet;

/// Length of the first link (joint0 to joint1), m.
pub const LINK0: f64 = 0.1;
/// Distance from joint1 to the fingertip, m.
pub const LINK1: f64 = 0.11;

/// Joint angles `[q0, q1]` that put the fingertip at `(x, y)` (clamped to the reachable
/// annulus), for the elbow sign `elbow` (+1 or −1).
pub fn inverse_kinematics(x: f64, y: f64, elbow: f64) -> [f64; 2] {
    let d2 = x * x + y * y;
    let c = ((d2 - LINK0 * LINK0 - LINK1 * LINK1) / (2.0 * LINK0 * LINK1)).clamp(-1.0, 1.0);
    let q1 = elbow.signum() * c.acos();
    let q0 = y.atan2(x) - (LINK1 * q1.sin()).atan2(LINK0 + LINK1 * q1.cos());
    [q0, q1]
}

/// Fingertip position of joint angles `q` (the forward kinematics the IK inverts).
pub fn forward_kinematics(q: [f64; 2]) -> [f64; 2] {
    [
        LINK0 * q[0].cos() + LINK1 * (q[0] + q[1]).cos(),
        LINK0 * q[0].sin() + LINK1 * (q[0] + q[1]).sin(),
    ]
}

fn wrap_angle(a: f64) -> f64 {
    let two_pi = std::f64::consts::TAU;
    let r = (a + std::f64::consts::PI).rem_euclid(two_pi) - std::f64::consts::PI;
    if r.is_finite() {
        r
    } else {
        0.0
    }
}

/// Gains and timing of the controller.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ControllerGains {
    /// Proportional gain on the joint-angle error (action units per rad).
    pub kp: f64,
    /// Derivative gain on the joint velocity (action units per rad/s).
    pub kd: f64,
    /// Steps to stay on a ball after its label first shows before moving on.
    pub dwell_steps: usize,
}

impl Default for ControllerGains {
    fn default() -> Self {
        ControllerGains {
            kp: 3.0,
            kd: 0.25,
            dwell_steps: 2,
        }
    }
}

/// Chooses the next region (its label bit) from the current labels and RM state;
/// `None` holds the arm still.
pub type Chooser = Box<dyn FnMut(LabelSet, Option<usize>) -> Option<usize> + Send>;

enum Plan {
    /// Visit these balls in order.
    Sequence { balls: Vec<usize>, next: usize },
    /// Ask a closure every step.
    Chooser(Chooser),
}

/// The scripted controller. Call [`ScriptedController::act`] once per step with the current
/// observation and labels.
pub struct ScriptedController {
    plan: Plan,
    gains: ControllerGains,
    dwell: usize,
    elbow: f64,
}

impl ScriptedController {
    /// Visits `balls` (region indices) in order, dwelling on each, then holds still.
    pub fn sequence(balls: &[usize], gains: ControllerGains) -> ScriptedController {
        ScriptedController {
            plan: Plan::Sequence {
                balls: balls.to_vec(),
                next: 0,
            },
            gains,
            dwell: 0,
            elbow: 1.0,
        }
    }

    /// The sequence named by the letters of `layout`'s regions, e.g. `"rgby"` (Sequential
    /// task).
    pub fn from_letters(
        letters: &str,
        layout: &TaskLayout,
        gains: ControllerGains,
    ) -> Result<ScriptedController, String> {
        let balls = letters
            .chars()
            .map(|c| {
                layout
                    .regions
                    .iter()
                    .position(|r| r.letter == c)
                    .ok_or_else(|| {
                        let known: String = layout.regions.iter().map(|r| r.letter).collect();
                        format!("'{c}' is not a region letter of the task ({known})")
                    })
            })
            .collect::<Result<Vec<_>, _>>()?;
        Ok(ScriptedController::sequence(&balls, gains))
    }

    /// Asks `choose(labels, rm_state)` for the target every step (e.g. a map from RM state to
    /// the ball that advances the machine).
    pub fn with_chooser(choose: Chooser, gains: ControllerGains) -> ScriptedController {
        ScriptedController {
            plan: Plan::Chooser(choose),
            gains,
            dwell: 0,
            elbow: 1.0,
        }
    }

    /// For a sequence: every ball has been visited.
    pub fn done(&self) -> bool {
        match &self.plan {
            Plan::Sequence { balls, next } => *next >= balls.len(),
            Plan::Chooser(_) => false,
        }
    }

    /// Restarts a sequence from its first ball (for a new episode).
    pub fn restart(&mut self) {
        if let Plan::Sequence { next, .. } = &mut self.plan {
            *next = 0;
        }
        self.dwell = 0;
    }

    /// The action for the current observation `obs` (a ReacherDelivery observation), the
    /// labels that hold now and the RM state (if any). Components are in [-1, 1].
    pub fn act(&mut self, obs: &[f32], labels: LabelSet, rm_state: Option<usize>) -> [f32; 2] {
        let target = match &mut self.plan {
            Plan::Sequence { balls, next } => {
                if let Some(&b) = balls.get(*next) {
                    if labels.contains(b) {
                        self.dwell += 1;
                        if self.dwell > self.gains.dwell_steps {
                            *next += 1;
                            self.dwell = 0;
                        }
                    }
                }
                balls.get(*next).copied()
            }
            Plan::Chooser(choose) => choose(labels, rm_state),
        };
        let f = |i: usize| f64::from(obs[i]);
        let q = [f(2).atan2(f(0)), f(3).atan2(f(1))];
        let qd = [f(4), f(5)];
        let goal = match target {
            Some(b) => {
                let (tip_x, tip_y) = (f(6), f(7));
                let (bx, by) = (tip_x - f(OBS_ARM + 2 * b), tip_y - f(OBS_ARM + 2 * b + 1));
                // Keep the elbow on the side it is on, so the arm does not flip through the
                // joint1 limit between targets.
                if q[1].abs() > 0.2 {
                    self.elbow = q[1].signum();
                }
                inverse_kinematics(bx, by, self.elbow)
            }
            None => q,
        };
        let mut action = [0.0f32; 2];
        for k in 0..2 {
            let err = wrap_angle(goal[k] - q[k]);
            let a = self.gains.kp * err - self.gains.kd * qd[k];
            action[k] = a.clamp(-1.0, 1.0) as f32;
        }
        action
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::env::reacher::{ReacherConfig, ReacherDelivery};
    use crate::env::reacher_task::ReacherTask;
    use crate::env::ContinuousEnv;

    fn sequential() -> ReacherTask {
        ReacherTask::shipped("sequential").unwrap()
    }

    #[test]
    fn ik_inverts_fk() {
        for [x, y] in sequential().layout().positions() {
            for elbow in [1.0, -1.0] {
                let tip = forward_kinematics(inverse_kinematics(x, y, elbow));
                assert!((tip[0] - x).abs() < 1e-12 && (tip[1] - y).abs() < 1e-12);
            }
        }
    }

    #[test]
    fn sequence_touches_every_ball_in_order() {
        let task = sequential();
        let config = task.env_config(&ReacherConfig::default()).unwrap();
        let mut env = ReacherDelivery::new(config).unwrap();
        for seed in 0..5 {
            let mut obs = vec![0.0; env.obs_dim()];
            env.reset(seed, &mut obs);
            let mut ctl = ScriptedController::from_letters(
                "rgby",
                &task.layout(),
                ControllerGains::default(),
            )
            .unwrap();
            let mut first_touch = vec![];
            let mut labels = env.labels();
            for t in 1..=100 {
                let a = ctl.act(&obs, labels, None);
                let s = env.step(&a, &mut obs).unwrap();
                labels = s.labels;
                for b in 0..4 {
                    if labels.contains(b) && !first_touch.iter().any(|&(x, _)| x == b) {
                        first_touch.push((b, t));
                    }
                }
            }
            assert!(ctl.done(), "seed {seed}: touched {first_touch:?}");
            let order: Vec<usize> = first_touch.iter().map(|&(b, _)| b).collect();
            assert_eq!(order, vec![0, 1, 2, 3], "seed {seed}: {first_touch:?}");
        }
    }
}
