//! A ReacherDelivery task (a checked task file, `env::task_file`; the paper's four and `blue`
//! ship in `assets/tasks/`) and what the product with its reward machine needs: the perfect
//! machine, a sub-goal potential for shaping, and the product environment.

use super::layout::TaskLayout;
use super::product::{Potential, ProductEnv};
use super::reacher::{CancelConfig, ConfigError, ReacherConfig, ReacherDelivery, ReacherError};
use super::task_file::{Task, TaskFileError, SHIPPED};
use crate::rm::{LabelSet, RewardMachine};
use std::collections::VecDeque;
use std::fmt;
use std::str::FromStr;
use std::sync::Arc;

/// A ReacherDelivery task: a checked task file ([`Task`]), shared. Two tasks are the same
/// when their name and content (task file, scene, machine) are. It is written to run records
/// as its shipped name or its file's path and read back by loading that again.
#[derive(Clone, Debug)]
pub struct ReacherTask(Arc<Task>);

impl ReacherTask {
    /// The shipped tasks, `assets/tasks/<name>.toml`: the paper's four, then the positive
    /// control `blue` (touch blue, a task a reward over the fingertip's position alone can
    /// express).
    pub fn all_shipped() -> Result<Vec<ReacherTask>, TaskFileError> {
        SHIPPED.iter().map(|n| ReacherTask::shipped(n)).collect()
    }

    /// A shipped task by name.
    pub fn shipped(name: &str) -> Result<ReacherTask, TaskFileError> {
        Ok(ReacherTask(Arc::new(Task::shipped(name)?)))
    }

    /// A shipped name (`composite`) or the path of a task file (`my/task.toml`).
    pub fn resolve(name_or_path: &str) -> Result<ReacherTask, TaskFileError> {
        if SHIPPED.contains(&name_or_path) {
            return ReacherTask::shipped(name_or_path);
        }
        // Records name the file by an absolute path, so a run resumes from any directory.
        let path = std::path::Path::new(name_or_path);
        let path = std::fs::canonicalize(path).unwrap_or_else(|_| path.to_path_buf());
        Ok(ReacherTask(Arc::new(Task::resolve(
            &path.to_string_lossy(),
        )?)))
    }

    /// The shipped name, or the task file's stem.
    pub fn name(&self) -> &str {
        &self.0.name
    }

    /// How records name the task: the shipped name, or the task file's path.
    pub fn id(&self) -> &str {
        if self.is_shipped() {
            &self.0.name
        } else {
            &self.0.source
        }
    }

    /// The task is one of `assets/tasks/`.
    pub fn is_shipped(&self) -> bool {
        self.0.source == format!("assets/tasks/{}.toml", self.0.name)
    }

    pub fn task(&self) -> &Task {
        &self.0
    }

    /// The task's perfect reward machine.
    pub fn perfect_rm(&self) -> Result<RewardMachine, crate::rm::format::RmFileError> {
        Ok((*self.0.machine).clone())
    }

    /// The environment of a run of this task ([`ReacherTask::env_config`] of `configured`).
    pub fn make_env(&self, configured: &ReacherConfig) -> Result<ReacherDelivery, ReacherError> {
        ReacherDelivery::new(self.env_config(configured)?)
    }

    /// The task's scene, regions and events.
    pub fn layout(&self) -> Arc<TaskLayout> {
        Arc::new(self.0.layout())
    }

    /// The environment of a run of this task: the task's own, except what `configured` (an
    /// environment config's `[env]`) gives in its place (an experiment on the environment,
    /// such as another event schedule or shorter episodes, over the task's machine): the
    /// event schedule and the region positions when set (`Some`; a schedule only for a task
    /// with one event, positions only for as many regions), the episode length and the
    /// layout's randomisation when they differ from the environment's default (an expert
    /// config's `[env]` cannot say "the task's" otherwise). The result sets the schedule and
    /// the positions, so resolving it again keeps them. A run config's `[env] episode_steps`
    /// sets the length whatever its value (`IrlRunConfig::over_task`).
    pub fn env_config(&self, configured: &ReacherConfig) -> Result<ReacherConfig, ConfigError> {
        fn pick<T: PartialEq + Clone>(own: T, configured: &T, default: &T) -> T {
            if configured == default {
                own
            } else {
                configured.clone()
            }
        }
        let task = &self.0;
        let d = ReacherConfig::default();
        let c = configured;
        let cancel = match (task.events.as_slice(), &c.cancel) {
            (_, Some(given)) => Some(given.clone()),
            ([only], None) => Some(CancelConfig::of(only)),
            (_, None) => None,
        };
        let resolved = ReacherConfig {
            max_steps: pick(task.episode_steps, &c.max_steps, &d.max_steps),
            ball_layout: Some(
                c.ball_layout
                    .clone()
                    .unwrap_or_else(|| self.0.layout().positions()),
            ),
            randomize_balls: pick(
                task.randomize_layout,
                &c.randomize_balls,
                &d.randomize_balls,
            ),
            cancel,
            arm_start: c.arm_start,
            layout: Some(self.layout()),
        };
        resolved.validate()?;
        Ok(resolved)
    }
}

impl PartialEq for ReacherTask {
    fn eq(&self, other: &Self) -> bool {
        self.0.name == other.0.name && self.0.content_hash == other.0.content_hash
    }
}

impl Eq for ReacherTask {}

impl std::hash::Hash for ReacherTask {
    fn hash<H: std::hash::Hasher>(&self, state: &mut H) {
        self.0.name.hash(state);
        self.0.content_hash.hash(state);
    }
}

impl fmt::Display for ReacherTask {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for ReacherTask {
    type Err = TaskFileError;
    fn from_str(s: &str) -> Result<Self, TaskFileError> {
        ReacherTask::resolve(s)
    }
}

impl serde::Serialize for ReacherTask {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(self.id())
    }
}

impl<'de> serde::Deserialize<'de> for ReacherTask {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let id = String::deserialize(d)?;
        ReacherTask::resolve(&id).map_err(serde::de::Error::custom)
    }
}

/// Potential `Φ(o, u) = −(dist(u) · spacing + distance from the fingertip to the nearest
/// region that makes progress in u)`, where `dist(u)` is the number of region touches from `u`
/// to the goal along the machine (shortest path over single-region label sets, never through
/// a failure sink). With `spacing` larger than any fingertip–region distance, reaching a
/// sub-goal never lowers the potential. Derived from the machine and the task's layout.
#[derive(Clone, Debug)]
pub struct SubgoalPotential {
    /// Regions that move `u` closer to the goal, per machine state.
    progress: Vec<Vec<usize>>,
    /// Observation columns of fingertip − region, per region.
    columns: Vec<[usize; 2]>,
    /// Touches left to the goal per state (`None`: goal unreachable).
    distance: Vec<Option<usize>>,
    spacing: f64,
}

/// Larger than the largest fingertip–ball distance in the arena (2 × 0.3·√2 < 0.85).
pub const DEFAULT_SPACING: f64 = 1.0;

impl SubgoalPotential {
    pub fn from_rm(rm: &RewardMachine, layout: &TaskLayout) -> SubgoalPotential {
        let n = rm.n_states();
        let regions = layout.n_regions();
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
                .filter(|&u| distance[u].is_none() && (0..regions).any(|b| touch(u, b) == Some(v)))
                .collect();
            for u in reached {
                distance[u] = Some(d + 1);
                queue.push_back(u);
            }
        }
        let progress = (0..n)
            .map(|u| {
                (0..regions)
                    .filter(|&b| match (touch(u, b), distance[u]) {
                        (Some(v), Some(du)) => distance[v].is_some_and(|dv| dv < du),
                        _ => false,
                    })
                    .collect()
            })
            .collect();
        SubgoalPotential {
            progress,
            columns: (0..regions).map(|k| layout.region_columns(k)).collect(),
            distance,
            spacing: DEFAULT_SPACING,
        }
    }

    /// Regions that make progress in state `u`.
    pub fn progress_balls(&self, u: usize) -> &[usize] {
        &self.progress[u]
    }

    /// Ball touches from `u` to the goal.
    pub fn touches_to_goal(&self, u: usize) -> Option<usize> {
        self.distance[u]
    }
}

/// Partial progress along a task's perfect machine, as the paper's figure 7 credits it
/// (its baselines "saturate at a partial reward level, given for reaching the end
/// location"): how many of the task's sub-goals (ball touches on the machine's shortest path
/// to the goal) an episode completed, and whether it touched a ball that can end the task.
#[derive(Clone, Debug)]
pub struct TaskProgress {
    /// Ball touches from each state to the goal (`None`: goal unreachable, e.g. the failure
    /// sink).
    distance: Vec<Option<usize>>,
    /// Label bits of the regions whose touch can move some state to a terminal one.
    final_balls: u32,
    /// Label bits of the regions.
    touches: LabelSet,
}

/// Sub-goal bookkeeping of one episode (see [`TaskProgress::track`]).
#[derive(Clone, Copy, Debug)]
pub struct ProgressTracker {
    done: usize,
    remaining: Option<usize>,
    final_ball: bool,
}

impl TaskProgress {
    pub fn of(rm: &RewardMachine, layout: &TaskLayout) -> TaskProgress {
        let potential = SubgoalPotential::from_rm(rm, layout);
        let distance = (0..rm.n_states())
            .map(|u| potential.touches_to_goal(u))
            .collect();
        let mut final_balls = 0u32;
        for u in (0..rm.n_states()).filter(|&u| !rm.is_absorbing(u)) {
            for b in 0..layout.n_regions() {
                if rm.is_terminal(rm.next_state(u, LabelSet::EMPTY.with(b))) {
                    final_balls |= 1 << b;
                }
            }
        }
        TaskProgress {
            distance,
            final_balls,
            touches: layout.touches(),
        }
    }

    /// The bookkeeping of an episode starting in `initial`.
    pub fn start(&self, initial: usize) -> ProgressTracker {
        ProgressTracker {
            done: 0,
            remaining: self.distance[initial],
            final_ball: false,
        }
    }

    /// Records a step from `u` to `v` on `labels`. A decrease of the touches left counts as
    /// sub-goals done when a ball was touched; a decrease by an event alone (the cancel
    /// removing blue) only shortens what remains. Entering a state that cannot reach the
    /// goal (the failure sink) freezes the record.
    pub fn track(&self, t: &mut ProgressTracker, u: usize, v: usize, labels: LabelSet) {
        t.final_ball |= labels.0 & self.final_balls != 0;
        if u == v || t.remaining.is_none() {
            return;
        }
        let (Some(du), Some(dv)) = (self.distance[u], self.distance[v]) else {
            // Into the failure sink: the sub-goals done so far stay, the rest is lost.
            return;
        };
        let touched_ball = labels.0 & self.touches.0 != 0;
        if dv < du && touched_ball {
            t.done += du - dv;
        }
        t.remaining = Some(dv);
    }
}

impl ProgressTracker {
    /// Fraction of the sub-goals completed: done / (done + remaining), in [0, 1].
    pub fn fraction(&self) -> f64 {
        let remaining = self.remaining.unwrap_or(0);
        let total = self.done + remaining;
        if total == 0 {
            0.0
        } else {
            self.done as f64 / total as f64
        }
    }

    /// A ball that can end the task was touched (in any machine state).
    pub fn touched_final_ball(&self) -> bool {
        self.final_ball
    }
}

impl Potential for SubgoalPotential {
    fn potential(&self, obs: &[f32], u: usize) -> f64 {
        let Some(d) = self.distance[u] else {
            return -(self.spacing * 8.0);
        };
        let nearest = self.progress[u]
            .iter()
            .map(|&b| {
                let [cx, cy] = self.columns[b];
                (obs[cx] as f64).hypot(obs[cy] as f64)
            })
            .fold(f64::INFINITY, f64::min);
        let nearest = if nearest.is_finite() { nearest } else { 0.0 };
        -(d as f64 * self.spacing + nearest)
    }
}

/// ReacherDelivery × the task's perfect machine, with sub-goal shaping of the given scale
/// (0 for none) for a learner with discount `gamma`; `config` runs over the task's layout
/// ([`ReacherTask::env_config`]).
pub fn task_env(
    task: ReacherTask,
    config: ReacherConfig,
    shaping_scale: f64,
    gamma: f64,
) -> Result<ProductEnv<ReacherDelivery, SubgoalPotential>, TaskEnvError> {
    let rm = task
        .perfect_rm()
        .map_err(|e| TaskEnvError::Rm(e.to_string()))?;
    let env = task.make_env(&config)?;
    let potential = SubgoalPotential::from_rm(&rm, env.layout());
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

/// Which way an episode of a conditional task (IF, Composite) went.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Branch {
    /// No event opened a branch of the machine (IF, Composite: no cancel before blue).
    Normal,
    /// An event opened a branch of the machine (IF, Composite: the cancel came before blue,
    /// which is off the task).
    Event,
}

impl Branch {
    pub const ALL: [Branch; 2] = [Branch::Normal, Branch::Event];

    pub fn name(self) -> &'static str {
        match self {
            Branch::Normal => "normal",
            Branch::Event => "event",
        }
    }

    /// Position in [`Branch::ALL`] (for per-branch counters).
    pub fn index(self) -> usize {
        self as usize
    }
}

impl fmt::Display for Branch {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// The states of a task's perfect machine that an exogenous event opened: those the machine
/// cannot reach without one (IF and Composite: "unless cancel", blue off the task). Read off
/// the machine, so the branch of an episode is a function of the perfect machine's trace
/// along it; a machine whose every state is reachable without events (OR, Sequential) has no
/// branches. Assumes an event that opens states redirects the task (the "unless" reading).
#[derive(Clone, Debug)]
pub struct EventBranch {
    opened: Vec<bool>,
}

impl EventBranch {
    /// `None` when the machine has no branch opened by one of `events`.
    pub fn of(rm: &RewardMachine, events: LabelSet) -> Option<EventBranch> {
        let free = rm.reachable_without(events);
        let opened: Vec<bool> = (0..rm.n_states())
            .map(|u| !rm.is_absorbing(u) && !free[u])
            .collect();
        opened.iter().any(|&c| c).then_some(EventBranch { opened })
    }

    /// The state belongs to the event branch.
    pub fn in_event_branch(&self, u: usize) -> bool {
        self.opened.get(u).copied().unwrap_or(false)
    }

    /// The branch of an episode from the perfect machine's states along it.
    pub fn of_states(&self, states: impl IntoIterator<Item = usize>) -> Branch {
        if states.into_iter().any(|u| self.in_event_branch(u)) {
            Branch::Event
        } else {
            Branch::Normal
        }
    }

    /// The branch of an episode from its label trace, tracking `rm` (the machine this was
    /// built from) from its initial state.
    pub fn of_labels(
        &self,
        rm: &RewardMachine,
        labels: impl IntoIterator<Item = LabelSet>,
    ) -> Branch {
        let mut u = rm.initial();
        self.of_states(std::iter::once(u).chain(labels.into_iter().map(move |l| {
            u = rm.next_state(u, l);
            u
        })))
    }
}

/// Episodes and successes per [`Branch`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct BranchTally {
    /// Episodes per branch, in [`Branch::ALL`] order.
    pub episodes: [u64; 2],
    pub successes: [u64; 2],
}

impl BranchTally {
    pub fn add(&mut self, branch: Branch, success: bool) {
        self.episodes[branch.index()] += 1;
        self.successes[branch.index()] += u64::from(success);
    }

    /// Success rate on the branch's episodes (`None` without any).
    pub fn rate(&self, branch: Branch) -> Option<f64> {
        let i = branch.index();
        (self.episodes[i] > 0).then(|| self.successes[i] as f64 / self.episodes[i] as f64)
    }

    /// Share of all episodes that took the branch.
    pub fn share(&self, branch: Branch) -> f64 {
        let total: u64 = self.episodes.iter().sum();
        self.episodes[branch.index()] as f64 / total.max(1) as f64
    }

    /// The lower of the branch success rates, over the branches that occurred: the headline
    /// success of a conditional task (a policy that ignores the cancel must not score the
    /// mean of a solved and a failed branch).
    pub fn worst_rate(&self) -> Option<f64> {
        Branch::ALL
            .iter()
            .filter_map(|&b| self.rate(b))
            .reduce(f64::min)
    }
}

impl fmt::Display for BranchTally {
    /// `normal 48/50, event 47/50 successful (event branch in 50 % of episodes)`: the event
    /// branch is the one a declared event opens (the paper's tasks: the cancel).
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let [n, c] = [Branch::Normal, Branch::Event].map(|b| b.index());
        write!(
            f,
            "normal {}/{}, event {}/{} successful (event branch in {:.0} % of episodes)",
            self.successes[n],
            self.episodes[n],
            self.successes[c],
            self.episodes[c],
            100.0 * self.share(Branch::Event)
        )
    }
}
