//! The four ReacherDelivery tasks of the paper (appendix C) and what the product with their
//! reward machines needs: the perfect machine, a sub-goal potential for shaping, and the
//! product environment.

use super::product::{Potential, ProductEnv};
use super::reacher::{ReacherConfig, ReacherDelivery, ReacherError, BALLS};
use crate::rm::perfect;
use crate::rm::{LabelSet, RewardMachine};
use std::collections::VecDeque;
use std::fmt;
use std::str::FromStr;

/// A ReacherDelivery task.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ReacherTask {
    /// Red or green, then blue (3 machine states).
    Or,
    /// Red, green, blue, yellow in order (5).
    Sequential,
    /// Blue unless cancel, then red (5).
    If,
    /// Red or green, then blue unless cancel, then yellow (7).
    Composite,
}

impl ReacherTask {
    pub const ALL: [ReacherTask; 4] = [
        ReacherTask::Or,
        ReacherTask::Sequential,
        ReacherTask::If,
        ReacherTask::Composite,
    ];

    pub fn name(self) -> &'static str {
        match self {
            ReacherTask::Or => "or",
            ReacherTask::Sequential => "sequential",
            ReacherTask::If => "if",
            ReacherTask::Composite => "composite",
        }
    }

    /// The task's perfect reward machine, from `assets/rm/reacher_<name>.txt`.
    pub fn perfect_rm(self) -> Result<RewardMachine, crate::rm::format::RmFileError> {
        perfect::reacher(self.name())
    }
}

impl fmt::Display for ReacherTask {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for ReacherTask {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        ReacherTask::ALL
            .into_iter()
            .find(|t| t.name() == s)
            .ok_or_else(|| {
                format!("unknown task '{s}' (expected one of: or, sequential, if, composite)")
            })
    }
}

/// Potential `Φ(o, u) = −(dist(u) · spacing + distance from the fingertip to the nearest
/// ball that makes progress in u)`, where `dist(u)` is the number of ball touches from `u` to
/// the goal along the machine (shortest path over single-ball label sets, never through a
/// failure sink). With `spacing` larger than any fingertip–ball distance, reaching a
/// sub-goal never lowers the potential. Derived from the machine alone, so it works for any
/// task over the `rgbyc` vocabulary.
#[derive(Clone, Debug)]
pub struct SubgoalPotential {
    /// Balls that move `u` closer to the goal, per machine state.
    progress: Vec<Vec<usize>>,
    /// Touches left to the goal per state (`None`: goal unreachable).
    distance: Vec<Option<usize>>,
    spacing: f64,
}

/// Larger than the largest fingertip–ball distance in the arena (2 × 0.3·√2 < 0.85).
pub const DEFAULT_SPACING: f64 = 1.0;

impl SubgoalPotential {
    pub fn from_rm(rm: &RewardMachine) -> SubgoalPotential {
        let n = rm.n_states();
        let touch = |u: usize, ball: usize| {
            let v = rm.next_state(u, LabelSet::EMPTY.with(ball));
            (v != u && !rm.is_failure(v)).then_some(v)
        };
        // Backward BFS from the terminal states over single-touch edges.
        let mut distance: Vec<Option<usize>> =
            (0..n).map(|u| rm.is_terminal(u).then_some(0)).collect();
        let mut queue: VecDeque<usize> = (0..n).filter(|&u| rm.is_terminal(u)).collect();
        while let Some(v) = queue.pop_front() {
            let d = distance[v].expect("queued states have a distance");
            let reached: Vec<usize> = (0..n)
                .filter(|&u| {
                    distance[u].is_none() && (0..BALLS.len()).any(|b| touch(u, b) == Some(v))
                })
                .collect();
            for u in reached {
                distance[u] = Some(d + 1);
                queue.push_back(u);
            }
        }
        let progress = (0..n)
            .map(|u| {
                (0..BALLS.len())
                    .filter(|&b| match (touch(u, b), distance[u]) {
                        (Some(v), Some(du)) => distance[v].is_some_and(|dv| dv < du),
                        _ => false,
                    })
                    .collect()
            })
            .collect();
        SubgoalPotential {
            progress,
            distance,
            spacing: DEFAULT_SPACING,
        }
    }

    /// Balls that make progress in state `u`.
    pub fn progress_balls(&self, u: usize) -> &[usize] {
        &self.progress[u]
    }

    /// Ball touches from `u` to the goal.
    pub fn touches_to_goal(&self, u: usize) -> Option<usize> {
        self.distance[u]
    }
}

impl Potential for SubgoalPotential {
    fn potential(&self, obs: &[f32], u: usize) -> f64 {
        let Some(d) = self.distance[u] else {
            return -(self.spacing * 8.0);
        };
        let nearest = self.progress[u]
            .iter()
            .map(|&b| (obs[8 + 2 * b] as f64).hypot(obs[9 + 2 * b] as f64))
            .fold(f64::INFINITY, f64::min);
        let nearest = if nearest.is_finite() { nearest } else { 0.0 };
        -(d as f64 * self.spacing + nearest)
    }
}

/// ReacherDelivery × the task's perfect machine, with sub-goal shaping of the given scale
/// (0 for none) for a learner with discount `gamma`.
pub fn task_env(
    task: ReacherTask,
    config: ReacherConfig,
    shaping_scale: f64,
    gamma: f64,
) -> Result<ProductEnv<ReacherDelivery, SubgoalPotential>, TaskEnvError> {
    let rm = task
        .perfect_rm()
        .map_err(|e| TaskEnvError::Rm(e.to_string()))?;
    let env = ReacherDelivery::new(config)?;
    let potential = SubgoalPotential::from_rm(&rm);
    Ok(ProductEnv::with_shaping(
        env,
        rm,
        potential,
        shaping_scale,
        gamma,
    ))
}

#[derive(Debug, thiserror::Error)]
pub enum TaskEnvError {
    #[error(transparent)]
    Env(#[from] ReacherError),
    #[error("{0}")]
    Rm(String),
}
