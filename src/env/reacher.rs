//! ReacherDelivery: Gymnasium's Reacher arm among a task's labelled regions, with the task's
//! random exogenous events (SMIRL paper, section 4.3 and appendix C), stepped through MuJoCo.
//! The task's layout ([`super::layout::TaskLayout`]) says which regions and events there are;
//! the paper's tasks put four coloured balls in the built-in scene and declare one event, the
//! cancel.
//!
//! **Observation** (`f32`, [`TaskLayout::obs_dim`] values):
//! `[cos q0, cos q1, sin q0, sin q1, q̇0, q̇1, tip_x, tip_y, tip − region_i (x, y) …, event
//! flags …]` where `q` are the two arm joint angles, `tip` the fingertip position, and an
//! event's flag is 1 on the step it fires, 0 otherwise (so the labelling function is a
//! function of the observation, as the paper's `L: O → 2^P` requires).
//!
//! **Labels** (the task's letters, regions then events): a region's bit while the fingertip is
//! strictly within the region's radius of its centre; an event's bit on the step it fires.
//!
//! **Reward** (the environment's own, Gymnasium-style `R = R_d + R_c`): `R_d` is minus the
//! distance from the fingertip to the nearest region centre, `R_c = −Σ a²` of the clipped
//! action. The tasks' true rewards come from their reward machines, not from this.
//!
//! **Episode**: Gymnasium's reset (joint angles ~ U(−0.1, 0.1), joint velocities ~
//! U(−0.005, 0.005)); one step applies the clipped action for 2 MuJoCo steps (0.02 s);
//! truncation after `max_steps` steps (default 100 = 2 s); the environment never terminates
//! by itself.
//!
//! **Events**: at reset, for each event in label-bit order, with the event's probability it
//! is scheduled for one step drawn uniformly from its window (counted from 1); it fires on
//! that step only. Everything random comes from the reset seed, drawn in this order: the
//! region layout (when randomised), the arm, then each event's schedule.
//!
//! **Regions**: a fixed layout (the task's positions) or, with `randomize_balls`, positions
//! drawn at each reset uniformly in the annulus 0.06–0.19 m with at least 0.08 m between
//! centres. A region whose anchor is a body with slide joints `<body>_x`, `<body>_y` is moved
//! there; any other region stays where the scene puts it.

use super::layout::{probability_ok, window_ok, Anchor, Event, TaskLayout};
use super::physics_scene::{physics_model, SceneModelError};
use super::placement::Placement;
use super::{check_action, ContinuousEnv, EnvError, EnvStep};
use crate::mujoco::{Data, MjError, Model, ObjectKind};
use crate::rm::{LabelSet, Vocabulary};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

use std::sync::Arc;

pub use super::layout::OBS_TIP;
pub use super::task_file::{MAX_EPISODE_STEPS, SLIDE_RANGE};

pub const ACT_DIM: usize = 2;
/// MuJoCo steps per environment step (Gymnasium's frame skip).
pub const FRAME_SKIP: usize = 2;

/// The schedule of a one-event task's event, as an environment config's `[env.cancel]` gives
/// it (every key required: a schedule is the task's or given whole).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CancelConfig {
    /// Chance that an episode has the event at all.
    pub probability: f64,
    /// First step (1-based) the event may fire on.
    pub earliest_step: usize,
    /// Last step the event may fire on.
    pub latest_step: usize,
}

impl CancelConfig {
    /// The schedule of an event of a task.
    pub fn of(event: &Event) -> CancelConfig {
        CancelConfig {
            probability: event.probability,
            earliest_step: event.earliest_step,
            latest_step: event.latest_step,
        }
    }

    /// Give `event` this schedule (the inverse of [`CancelConfig::of`]).
    pub fn schedule(&self, event: &mut Event) {
        event.probability = self.probability;
        event.earliest_step = self.earliest_step;
        event.latest_step = self.latest_step;
    }
}

/// Configuration of the environment: a run's settings (a run config's `[env]`) over the
/// task's layout.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ReacherConfig {
    /// Steps per episode before truncation.
    pub max_steps: usize,
    /// Region centres (x, y) in label-bit order when not randomised; `None`: the task's.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub ball_layout: Option<Vec<[f64; 2]>>,
    /// Draw a new region layout at every reset.
    pub randomize_balls: bool,
    /// The schedule of a one-event task's event in place of the task's; `None`: the task's
    /// own (every task's events keep theirs). A task with another number of events refuses
    /// one.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub cancel: Option<CancelConfig>,
    /// How the arm starts an episode (absent from written configs when `random`, the
    /// default, so a config that does not name it reads and writes unchanged).
    #[serde(skip_serializing_if = "ArmStart::is_random")]
    pub arm_start: ArmStart,
    /// The task's scene, regions and events, set from the task
    /// (`env::reacher_task::ReacherTask::env_config`); a config file does not name them.
    #[serde(skip)]
    pub layout: Option<Arc<TaskLayout>>,
}

/// Configurations are equal when their settings are (the layout is the task's, compared as
/// the task).
impl PartialEq for ReacherConfig {
    fn eq(&self, other: &Self) -> bool {
        self.max_steps == other.max_steps
            && self.ball_layout == other.ball_layout
            && self.randomize_balls == other.randomize_balls
            && self.cancel == other.cancel
            && self.arm_start == other.arm_start
    }
}

/// The arm's state at reset.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ArmStart {
    /// Gymnasium's Reacher: joint angles uniform in ±0.1 rad, velocities in ±0.005.
    #[default]
    Random,
    /// Both joints at 0 rad and at rest (fingertip at (0.21, 0)): f-IRL's ReacherDraw.
    Zero,
}

impl ArmStart {
    pub fn is_random(&self) -> bool {
        *self == ArmStart::Random
    }
}

impl Default for ReacherConfig {
    fn default() -> Self {
        ReacherConfig {
            max_steps: 100,
            ball_layout: None,
            randomize_balls: false,
            cancel: None,
            arm_start: ArmStart::Random,
            layout: None,
        }
    }
}

/// A configuration that cannot work.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum ConfigError {
    #[error("max_steps must be at least 1")]
    NoSteps,
    #[error("max_steps ({0}) is more than the limit of {MAX_EPISODE_STEPS} steps per episode")]
    TooManySteps(usize),
    #[error("cancel.probability is {}, it must be in [0, 1]", crate::quoted::number(*.0))]
    CancelProbability(f64),
    #[error(
        "cancel.earliest_step ({earliest}) must be between 1 and cancel.latest_step ({latest})"
    )]
    CancelWindow { earliest: usize, latest: usize },
    #[error(
        "cancel.latest_step ({latest}) is after the episode's last step (max_steps = {max_steps}): \
         the cancel window must lie inside the episode"
    )]
    CancelAfterEpisode { latest: usize, max_steps: usize },
    #[error("region {region} at ({}, {}) is outside the layout range ±{SLIDE_RANGE}", crate::quoted::number(*.x), crate::quoted::number(*.y))]
    BallOutOfRange { region: usize, x: f64, y: f64 },
    #[error("ball_layout has {given} positions, the task has {regions} regions")]
    LayoutCount { given: usize, regions: usize },
    #[error("[env.cancel] sets one event's schedule, the task declares {0} events")]
    CancelWithoutOneEvent(usize),
    #[error("no task layout: the environment runs a task's regions and events (ReacherTask::env_config sets them)")]
    NoLayout,
}

impl ConfigError {
    /// The config key the error is about, as a path below `[env]`.
    pub fn field(&self) -> &'static str {
        match self {
            ConfigError::NoSteps | ConfigError::TooManySteps(_) => "max_steps",
            ConfigError::CancelProbability(_) | ConfigError::CancelWithoutOneEvent(_) => {
                "cancel.probability"
            }
            ConfigError::CancelWindow { .. } => "cancel.earliest_step",
            ConfigError::CancelAfterEpisode { .. } => "cancel.latest_step",
            ConfigError::BallOutOfRange { .. } | ConfigError::LayoutCount { .. } => "ball_layout",
            ConfigError::NoLayout => "layout",
        }
    }
}

impl ReacherConfig {
    /// The settings on their own (without a layout, what a run config can check).
    pub fn validate(&self) -> Result<(), ConfigError> {
        if self.max_steps == 0 {
            return Err(ConfigError::NoSteps);
        }
        if self.max_steps > MAX_EPISODE_STEPS {
            return Err(ConfigError::TooManySteps(self.max_steps));
        }
        if let Some(cancel) = &self.cancel {
            let p = cancel.probability;
            if !probability_ok(p) {
                return Err(ConfigError::CancelProbability(p));
            }
            let (earliest, latest) = (cancel.earliest_step, cancel.latest_step);
            if !window_ok(earliest, latest) {
                return Err(ConfigError::CancelWindow { earliest, latest });
            }
            if latest > self.max_steps {
                return Err(ConfigError::CancelAfterEpisode {
                    latest,
                    max_steps: self.max_steps,
                });
            }
        }
        for (region, &[x, y]) in self.ball_layout.iter().flatten().enumerate() {
            if !(x.abs() <= SLIDE_RANGE && y.abs() <= SLIDE_RANGE) {
                return Err(ConfigError::BallOutOfRange { region, x, y });
            }
        }
        if let Some(layout) = &self.layout {
            self.plan(layout)?;
        }
        Ok(())
    }

    /// The task's layout this config runs (an error without one).
    pub fn task_layout(&self) -> Result<&Arc<TaskLayout>, ConfigError> {
        self.layout.as_ref().ok_or(ConfigError::NoLayout)
    }

    /// Region positions and event schedules of `layout` under these settings.
    fn plan(&self, layout: &TaskLayout) -> Result<(Vec<[f64; 2]>, Vec<CancelConfig>), ConfigError> {
        let positions = match &self.ball_layout {
            None => layout.positions(),
            Some(given) if given.len() == layout.n_regions() => given.clone(),
            Some(given) => {
                return Err(ConfigError::LayoutCount {
                    given: given.len(),
                    regions: layout.n_regions(),
                })
            }
        };
        let mut schedules: Vec<CancelConfig> = layout.events.iter().map(CancelConfig::of).collect();
        if let Some(cancel) = &self.cancel {
            match schedules.as_mut_slice() {
                [only] => *only = cancel.clone(),
                _ => return Err(ConfigError::CancelWithoutOneEvent(schedules.len())),
            }
        }
        for s in &schedules {
            if s.latest_step > self.max_steps {
                return Err(ConfigError::CancelAfterEpisode {
                    latest: s.latest_step,
                    max_steps: self.max_steps,
                });
            }
        }
        Ok((positions, schedules))
    }
}

/// Errors building the environment.
#[derive(Debug, thiserror::Error)]
pub enum ReacherError {
    #[error(transparent)]
    MuJoCo(#[from] MjError),
    #[error(transparent)]
    Scene(#[from] SceneModelError),
    #[error("invalid ReacherDelivery config: {0}")]
    Config(#[from] ConfigError),
    #[error("model {model} is not a ReacherDelivery model: {problem}")]
    WrongModel { model: String, problem: String },
}

/// Where things live in `qpos`/`qvel`/`xpos`, looked up by name once.
#[derive(Clone, Debug)]
struct Places {
    arm_qpos: [usize; 2],
    arm_dof: [usize; 2],
    /// How each movable region's body is put at its layout position, in label-bit order.
    regions: Vec<Option<Placement>>,
    fingertip_body: usize,
}

impl Places {
    /// Where things are in `model`; a region whose body is `left_out` of the model has no
    /// placement (its position lives in the environment only).
    fn find(model: &Model, layout: &TaskLayout, left_out: &[bool]) -> Result<Places, ReacherError> {
        let joint = |name: &str| model.id(ObjectKind::Joint, name);
        let j0 = joint("joint0")?;
        let j1 = joint("joint1")?;
        let mut regions = Vec::with_capacity(layout.n_regions());
        for (k, region) in layout.regions.iter().enumerate() {
            let placement = match (&region.anchor, region.movable) {
                _ if left_out.get(k) == Some(&true) => None,
                (Anchor::Body(body), true) => Some(Placement::find(model, body).ok_or_else(
                    || ReacherError::WrongModel {
                        model: model.source_name().into(),
                        problem: format!(
                            "body {body} is neither a mocap body nor a body with adjacent \
                             slide joints {body}_x, {body}_y"
                        ),
                    },
                )?),
                _ => None,
            };
            regions.push(placement);
        }
        if model.nu() != ACT_DIM {
            return Err(ReacherError::WrongModel {
                model: model.source_name().into(),
                problem: format!("{} actuators, expected {ACT_DIM}", model.nu()),
            });
        }
        Ok(Places {
            arm_qpos: [model.joint_qpos_addr(j0), model.joint_qpos_addr(j1)],
            arm_dof: [model.joint_dof_addr(j0), model.joint_dof_addr(j1)],
            regions,
            fingertip_body: model.id(ObjectKind::Body, "fingertip")?,
        })
    }
}

/// The ReacherDelivery environment.
pub struct ReacherDelivery {
    config: ReacherConfig,
    layout: Arc<TaskLayout>,
    data: Data,
    places: Places,
    vocab: Vocabulary,
    radii: Vec<f64>,
    schedules: Vec<CancelConfig>,
    /// Region centres of a layout that is not randomised.
    fixed_positions: Vec<[f64; 2]>,
    positions: Vec<[f64; 2]>,
    steps: usize,
    event_steps: Vec<Option<usize>>,
    last_labels: LabelSet,
    ready: bool,
}

impl ReacherDelivery {
    /// The environment on the task's scene (`config.layout`), stepping its physics model:
    /// the scene without the bodies that only mark movable regions
    /// ([`physics_model`]), so the arm moves exactly as in the scene at a lower cost.
    pub fn new(config: ReacherConfig) -> Result<ReacherDelivery, ReacherError> {
        let layout = config.task_layout()?;
        let physics = physics_model(layout)?;
        ReacherDelivery::build(Arc::new(physics.model), config, &physics.left_out)
    }

    /// The environment on a given model (which must have the arm and the task's anchors),
    /// stepped as it is: replay steps the scene a log recorded.
    pub fn with_model(
        model: Arc<Model>,
        config: ReacherConfig,
    ) -> Result<ReacherDelivery, ReacherError> {
        ReacherDelivery::build(model, config, &[])
    }

    /// A new environment on the same model, configuration and region placements, not yet
    /// reset (for playing episodes side by side).
    pub fn twin(&self) -> Result<ReacherDelivery, ReacherError> {
        let left_out: Vec<bool> = self.places.regions.iter().map(Option::is_none).collect();
        ReacherDelivery::build(Arc::clone(self.model()), self.config.clone(), &left_out)
    }

    fn build(
        model: Arc<Model>,
        config: ReacherConfig,
        left_out: &[bool],
    ) -> Result<ReacherDelivery, ReacherError> {
        config.validate()?;
        let layout = Arc::clone(config.task_layout()?);
        let (positions, schedules) = config.plan(&layout)?;
        let places = Places::find(&model, &layout, left_out)?;
        let data = Data::new(model)?;
        Ok(ReacherDelivery {
            vocab: layout.vocabulary(),
            radii: layout.regions.iter().map(|r| r.radius).collect(),
            event_steps: vec![None; layout.n_events()],
            layout,
            fixed_positions: positions.clone(),
            positions,
            schedules,
            config,
            data,
            places,
            steps: 0,
            last_labels: LabelSet::EMPTY,
            ready: false,
        })
    }

    pub fn config(&self) -> &ReacherConfig {
        &self.config
    }

    /// The task's scene, regions and events.
    pub fn layout(&self) -> &Arc<TaskLayout> {
        &self.layout
    }

    pub fn vocabulary(&self) -> &Vocabulary {
        &self.vocab
    }

    /// The model this environment steps (see [`ReacherDelivery::new`]).
    pub fn model(&self) -> &Arc<Model> {
        self.data.model()
    }

    /// Full MuJoCo state, for logging and replay checks.
    pub fn qpos(&self) -> &[f64] {
        self.data.qpos()
    }

    pub fn qvel(&self) -> &[f64] {
        self.data.qvel()
    }

    /// World position of a body of the model (e.g. a ball), as of the last reset or step.
    pub fn body_position(&self, body: usize) -> [f64; 3] {
        self.data.body_xpos(body)
    }

    /// Region centres of the current episode, in label-bit order.
    pub fn positions(&self) -> &[[f64; 2]] {
        &self.positions
    }

    /// Steps taken in the current episode.
    pub fn steps(&self) -> usize {
        self.steps
    }

    /// The (1-based) step on which each event fires this episode, if it does, in label-bit
    /// order.
    pub fn event_steps(&self) -> &[Option<usize>] {
        &self.event_steps
    }

    /// Labels of the last step (or of the reset state).
    pub fn labels(&self) -> LabelSet {
        self.last_labels
    }

    /// Fingertip position (x, y).
    pub fn fingertip(&self) -> [f64; 2] {
        let p = self.data.body_xpos(self.places.fingertip_body);
        [p[0], p[1]]
    }

    /// Places the arm (joint angles and velocities) without stepping, for a scripted state;
    /// recomputes positions and labels. Region layout and event schedule stay.
    pub fn set_arm(&mut self, angles: [f64; 2], velocities: [f64; 2]) -> Result<(), EnvError> {
        for k in 0..2 {
            self.data.qpos_mut()[self.places.arm_qpos[k]] = angles[k];
            self.data.qvel_mut()[self.places.arm_dof[k]] = velocities[k];
        }
        self.data
            .forward()
            .map_err(|e| EnvError::Simulation(e.to_string()))?;
        self.last_labels = self.region_labels();
        Ok(())
    }

    /// Restores the start of a logged episode instead of drawing one from a seed: the full
    /// `qpos`/`qvel`, the region layout and the event steps, through the same sequence as
    /// [`ContinuousEnv::reset`] (MuJoCo data reset, state written, forward), so stepping the
    /// same actions afterwards reproduces the logged run bit for bit. Writes the observation.
    pub fn restore_start(
        &mut self,
        qpos: &[f64],
        qvel: &[f64],
        positions: &[[f64; 2]],
        event_steps: &[Option<usize>],
        obs: &mut [f32],
    ) -> Result<(), EnvError> {
        if positions.len() != self.positions.len() || event_steps.len() != self.event_steps.len() {
            return Err(EnvError::Simulation(format!(
                "a start with {} regions and {} events, the task has {} and {}",
                positions.len(),
                event_steps.len(),
                self.positions.len(),
                self.event_steps.len()
            )));
        }
        self.data.reset();
        self.positions.copy_from_slice(positions);
        // Before the logged qpos, which holds the regions itself on a model with slides.
        self.place_regions();
        self.data
            .set_qpos(qpos)
            .and_then(|()| self.data.set_qvel(qvel))
            .map_err(|e| EnvError::Simulation(e.to_string()))?;
        self.event_steps.copy_from_slice(event_steps);
        self.steps = 0;
        self.data
            .forward()
            .map_err(|e| EnvError::Simulation(e.to_string()))?;
        self.last_labels = self.region_labels();
        self.ready = true;
        self.write_obs(obs);
        Ok(())
    }

    /// Puts the model's movable regions at this episode's layout (positions take effect at
    /// the next forward pass).
    fn place_regions(&mut self) {
        for (placement, &b) in self.places.regions.iter().zip(&self.positions) {
            if let Some(placement) = placement {
                placement.place(&mut self.data, b);
            }
        }
    }

    /// Labels of the regions the fingertip is in now (no events).
    fn region_labels(&self) -> LabelSet {
        let tip = self.fingertip();
        let mut labels = LabelSet::EMPTY;
        for (i, (b, r)) in self.positions.iter().zip(&self.radii).enumerate() {
            let (dx, dy) = (tip[0] - b[0], tip[1] - b[1]);
            if dx * dx + dy * dy < r * r {
                labels = labels.with(i);
            }
        }
        labels
    }

    fn draw_layout(&mut self, rng: &mut ChaCha8Rng) {
        if !self.config.randomize_balls {
            self.positions.copy_from_slice(&self.fixed_positions);
            return;
        }
        let n = self.positions.len();
        let mut placed = 0;
        while placed < n {
            let r = rng.gen_range(0.06..0.19);
            let theta = rng.gen_range(-std::f64::consts::PI..std::f64::consts::PI);
            let candidate = [r * theta.cos(), r * theta.sin()];
            let clear = self.positions[..placed]
                .iter()
                .all(|b| (b[0] - candidate[0]).hypot(b[1] - candidate[1]) >= 0.08);
            if clear {
                self.positions[placed] = candidate;
                placed += 1;
            }
        }
    }

    fn write_obs(&self, obs: &mut [f32]) {
        let q = self.data.qpos();
        let v = self.data.qvel();
        let [a0, a1] = self.places.arm_qpos;
        let [d0, d1] = self.places.arm_dof;
        let tip = self.fingertip();
        obs[0] = q[a0].cos() as f32;
        obs[1] = q[a1].cos() as f32;
        obs[2] = q[a0].sin() as f32;
        obs[3] = q[a1].sin() as f32;
        obs[4] = v[d0] as f32;
        obs[5] = v[d1] as f32;
        obs[6] = tip[0] as f32;
        obs[7] = tip[1] as f32;
        for (i, b) in self.positions.iter().enumerate() {
            let [cx, cy] = self.layout.region_columns(i);
            obs[cx] = (tip[0] - b[0]) as f32;
            obs[cy] = (tip[1] - b[1]) as f32;
        }
        for e in 0..self.event_steps.len() {
            let fired = self.last_labels.contains(self.layout.event_bit(e));
            obs[self.layout.event_column(e)] = if fired { 1.0 } else { 0.0 };
        }
    }

    /// Gymnasium's reward: minus the distance to the nearest region centre, minus Σ a².
    fn reward(&self, action: &[f64; 2]) -> f64 {
        let tip = self.fingertip();
        let nearest = self
            .positions
            .iter()
            .map(|b| (tip[0] - b[0]).hypot(tip[1] - b[1]))
            .fold(f64::INFINITY, f64::min);
        let nearest = if nearest.is_finite() { nearest } else { 0.0 };
        -nearest - (action[0] * action[0] + action[1] * action[1])
    }
}

impl ContinuousEnv for ReacherDelivery {
    fn obs_dim(&self) -> usize {
        self.layout.obs_dim()
    }

    fn act_dim(&self) -> usize {
        ACT_DIM
    }

    fn reset(&mut self, seed: u64, obs: &mut [f32]) {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        self.data.reset();
        self.draw_layout(&mut rng);
        // ArmStart::Zero: the state data.reset() left (qpos0 = 0, at rest), no draw.
        if self.config.arm_start == ArmStart::Random {
            let q = self.data.qpos_mut();
            for &a in &self.places.arm_qpos {
                q[a] = rng.gen_range(-0.1..0.1);
            }
            for k in 0..2 {
                let d = self.places.arm_dof[k];
                self.data.qvel_mut()[d] = rng.gen_range(-0.005..0.005);
            }
        }
        self.place_regions();
        for (step, schedule) in self.event_steps.iter_mut().zip(&self.schedules) {
            *step = rng
                .gen_bool(schedule.probability)
                .then(|| rng.gen_range(schedule.earliest_step..=schedule.latest_step));
        }
        self.steps = 0;
        // forward only computes positions from a state just written by hand, which cannot
        // trip MuJoCo's error paths on a valid model; if it ever did, step() reports it.
        let _ = self.data.forward();
        self.last_labels = self.region_labels();
        self.ready = true;
        self.write_obs(obs);
    }

    fn step(&mut self, action: &[f32], obs: &mut [f32]) -> Result<EnvStep, EnvError> {
        if !self.ready {
            return Err(EnvError::NotReset);
        }
        check_action(action, ACT_DIM)?;
        let clipped = [
            action[0].clamp(-1.0, 1.0) as f64,
            action[1].clamp(-1.0, 1.0) as f64,
        ];
        self.data.ctrl_mut().copy_from_slice(&clipped);
        for _ in 0..FRAME_SKIP {
            self.data
                .step()
                .map_err(|e| EnvError::Simulation(e.to_string()))?;
        }
        if self.data.instability_count() > 0 {
            self.ready = false;
            return Err(EnvError::Simulation(format!(
                "MuJoCo flagged an unstable simulation at step {} (the state was reset)",
                self.steps + 1
            )));
        }
        self.steps += 1;
        let mut labels = self.region_labels();
        for (e, step) in self.event_steps.iter().enumerate() {
            if *step == Some(self.steps) {
                labels = labels.with(self.layout.event_bit(e));
            }
        }
        self.last_labels = labels;
        self.write_obs(obs);
        Ok(EnvStep {
            reward: self.reward(&clipped),
            labels,
            terminated: false,
            truncated: self.steps >= self.config.max_steps,
        })
    }
}
