//! ReacherDelivery: Gymnasium's Reacher arm with four coloured balls and a random *cancel*
//! event (SMIRL paper, section 4.3 and appendix C), stepped through MuJoCo.
//!
//! **Observation** (17 values, `f32`):
//! `[cos q0, cos q1, sin q0, sin q1, q̇0, q̇1, tip_x, tip_y,
//!   tip−red (x, y), tip−green (x, y), tip−blue (x, y), tip−yellow (x, y), cancel]`
//! where `q` are the two arm joint angles, `tip` the fingertip position, and `cancel` is 1
//! on the step the cancel event fires, 0 otherwise (so the labelling function is a function
//! of the observation, as the paper's `L: O → 2^P` requires).
//!
//! **Labels** (vocabulary `"rgbyc"`): `r`/`g`/`b`/`y` when the fingertip is strictly within
//! [`TOUCH_RADIUS`] (0.02 m) of that ball's centre; `c` on the step the cancel event fires.
//!
//! **Reward** (the environment's own, Gymnasium-style `R = R_d + R_c`): `R_d` is minus the
//! distance from the fingertip to the nearest ball, `R_c = −Σ a²` of the clipped action. The
//! tasks' true rewards come from their reward machines, not from this.
//!
//! **Episode**: Gymnasium's reset (joint angles ~ U(−0.1, 0.1), joint velocities ~
//! U(−0.005, 0.005)); one step applies the clipped action for 2 MuJoCo steps (0.02 s);
//! truncation after `max_steps` steps (default 100 = 2 s); the environment never terminates
//! by itself.
//!
//! **Cancel rule**: at reset, with probability `cancel.probability` (default 0.5) the event is
//! scheduled for one step drawn uniformly from `earliest_step..=latest_step` (default 1..=8,
//! counted from 1); it fires on that step only. Everything random comes from the reset seed.
//! The window is early on purpose: a competent arm touches blue after about 9 steps (IF) or
//! 11–13 (Composite), so with the first schedule (10..=60, [`CancelConfig::LATE`]) the cancel
//! almost never came before blue and the "unless cancel" branch of IF and Composite never
//! happened. With 1..=8 about half of all episodes take it.
//!
//! **Balls**: a fixed default layout inside the reachable disc (reach 0.21 m). Each ball is at
//! its own distance from the base — red 0.195 m at 60°, blue 0.06 m at 170°, green 0.105 m at
//! 260°, yellow 0.15 m at 340° — 0.045 m apart in radius (more than the two touch radii), so
//! an arm that sweeps at a fixed elbow angle touches at most one ball, and counter-clockwise
//! the balls come red, blue, green, yellow, not the Sequential order. (A first layout with all
//! balls at one radius in the order red, green, blue, yellow let a policy that merely spins the
//! arm complete OR and Sequential.) With `randomize_balls`, each reset draws positions uniformly in the annulus
//! 0.06–0.19 m with at least 0.08 m between balls.

use super::placement::Placement;
use super::{check_action, ContinuousEnv, EnvError, EnvStep};
use crate::mujoco::{Data, MjError, Model, ObjectKind};
use crate::rm::{LabelSet, Vocabulary};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

use std::sync::Arc;

/// Propositions of the domain, in label-bit order: red, green, blue, yellow, cancel.
pub const VOCABULARY: &str = "rgbyc";
/// Ball names, in label-bit order (also the body and joint name prefixes in the XML).
pub const BALLS: [&str; 4] = ["red", "green", "blue", "yellow"];
/// Label bit of the cancel proposition.
pub const CANCEL_BIT: usize = 4;
/// The domain's *events*: propositions true on a single step by construction (the cancel);
/// the ball propositions hold as long as the fingertip touches the ball. Learned machines
/// read an event first in a label set they never saw (`rm::lrm::Guards`).
pub const EVENTS: LabelSet = LabelSet(1 << CANCEL_BIT);
/// A ball's proposition is true when the fingertip is closer than this to its centre (m).
pub const TOUCH_RADIUS: f64 = 0.02;
pub const OBS_DIM: usize = 17;
pub const ACT_DIM: usize = 2;
/// MuJoCo steps per environment step (Gymnasium's frame skip).
pub const FRAME_SKIP: usize = 2;
/// Index of the cancel flag in the observation.
pub const OBS_CANCEL: usize = 16;
/// Indices of the fingertip position in the observation.
pub const OBS_TIP: [usize; 2] = [6, 7];

/// The default ball layout (x, y) in metres, in [`BALLS`] order.
pub const DEFAULT_LAYOUT: [[f64; 2]; 4] = [
    [0.0975, 0.1689],
    [-0.0182, -0.1034],
    [-0.0591, 0.0104],
    [0.141, -0.0513],
];

/// When the cancel event fires.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct CancelConfig {
    /// Chance that an episode has a cancel event at all.
    pub probability: f64,
    /// First step (1-based) the event may fire on.
    pub earliest_step: usize,
    /// Last step the event may fire on.
    pub latest_step: usize,
}

impl CancelConfig {
    /// The first schedule (steps 10..=60), kept for comparison: it fires after blue in almost
    /// every IF and Composite episode, so those tasks never take their cancel branch.
    pub const LATE: CancelConfig = CancelConfig {
        probability: 0.5,
        earliest_step: 10,
        latest_step: 60,
    };
}

impl Default for CancelConfig {
    /// Steps 1..=8 with probability 0.5: before blue in about half of the IF and Composite
    /// episodes (measured by `reacher expert`, see experiments/experts/results.md).
    fn default() -> Self {
        CancelConfig {
            probability: 0.5,
            earliest_step: 1,
            latest_step: 8,
        }
    }
}

/// Configuration of the environment.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ReacherConfig {
    /// Steps per episode before truncation.
    pub max_steps: usize,
    /// Ball positions (x, y) in [`BALLS`] order when not randomised.
    pub ball_layout: [[f64; 2]; 4],
    /// Draw a new ball layout at every reset.
    pub randomize_balls: bool,
    pub cancel: CancelConfig,
    /// How the arm starts an episode (absent from written configs when `random`, the
    /// default, so configs from before the option read and write unchanged).
    #[serde(skip_serializing_if = "ArmStart::is_random")]
    pub arm_start: ArmStart,
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
            ball_layout: DEFAULT_LAYOUT,
            randomize_balls: false,
            cancel: CancelConfig::default(),
            arm_start: ArmStart::Random,
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
    #[error("ball {ball} at ({}, {}) is outside the layout range ±0.27", crate::quoted::number(*.x), crate::quoted::number(*.y))]
    BallOutOfRange { ball: &'static str, x: f64, y: f64 },
}

/// Longest episode a config may ask for (episodes are buffered whole).
pub const MAX_EPISODE_STEPS: usize = 10_000;

impl ConfigError {
    /// The config key the error is about, as a path below `[env]`.
    pub fn field(&self) -> &'static str {
        match self {
            ConfigError::NoSteps | ConfigError::TooManySteps(_) => "max_steps",
            ConfigError::CancelProbability(_) => "cancel.probability",
            ConfigError::CancelWindow { .. } => "cancel.earliest_step",
            ConfigError::CancelAfterEpisode { .. } => "cancel.latest_step",
            ConfigError::BallOutOfRange { .. } => "ball_layout",
        }
    }
}

impl ReacherConfig {
    pub fn validate(&self) -> Result<(), ConfigError> {
        if self.max_steps == 0 {
            return Err(ConfigError::NoSteps);
        }
        if self.max_steps > MAX_EPISODE_STEPS {
            return Err(ConfigError::TooManySteps(self.max_steps));
        }
        let p = self.cancel.probability;
        if !(0.0..=1.0).contains(&p) {
            return Err(ConfigError::CancelProbability(p));
        }
        let (earliest, latest) = (self.cancel.earliest_step, self.cancel.latest_step);
        if earliest == 0 || earliest > latest {
            return Err(ConfigError::CancelWindow { earliest, latest });
        }
        if latest > self.max_steps {
            return Err(ConfigError::CancelAfterEpisode {
                latest,
                max_steps: self.max_steps,
            });
        }
        for (i, &[x, y]) in self.ball_layout.iter().enumerate() {
            if !(x.abs() <= 0.27 && y.abs() <= 0.27) {
                return Err(ConfigError::BallOutOfRange {
                    ball: BALLS[i],
                    x,
                    y,
                });
            }
        }
        Ok(())
    }
}

/// Errors building the environment.
#[derive(Debug, thiserror::Error)]
pub enum ReacherError {
    #[error(transparent)]
    MuJoCo(#[from] MjError),
    #[error("invalid ReacherDelivery config: {0}")]
    Config(#[from] ConfigError),
    #[error("model {model} is not a ReacherDelivery model: {problem}")]
    WrongModel { model: String, problem: String },
}

/// Where things live in `qpos`/`qvel`/`xpos`, looked up by name once.
#[derive(Clone, Debug)]
struct Layout {
    arm_qpos: [usize; 2],
    arm_dof: [usize; 2],
    /// How each ball is put at its layout position.
    balls: [Placement; 4],
    fingertip_body: usize,
}

impl Layout {
    fn find(model: &Model) -> Result<Layout, ReacherError> {
        let joint = |name: &str| model.id(ObjectKind::Joint, name);
        let j0 = joint("joint0")?;
        let j1 = joint("joint1")?;
        let mut balls = [Placement::Slides { qpos: 0 }; 4];
        for (slot, ball) in balls.iter_mut().zip(BALLS) {
            *slot = Placement::find(model, ball).ok_or_else(|| ReacherError::WrongModel {
                model: model.source_name().into(),
                problem: format!(
                    "ball {ball} is neither a mocap body nor a body with adjacent slide joints \
                     {ball}_x, {ball}_y"
                ),
            })?;
        }
        if model.nu() != ACT_DIM {
            return Err(ReacherError::WrongModel {
                model: model.source_name().into(),
                problem: format!("{} actuators, expected {ACT_DIM}", model.nu()),
            });
        }
        Ok(Layout {
            arm_qpos: [model.joint_qpos_addr(j0), model.joint_qpos_addr(j1)],
            arm_dof: [model.joint_dof_addr(j0), model.joint_dof_addr(j1)],
            balls,
            fingertip_body: model.id(ObjectKind::Body, "fingertip")?,
        })
    }
}

/// The ReacherDelivery environment.
pub struct ReacherDelivery {
    config: ReacherConfig,
    data: Data,
    layout: Layout,
    vocab: Vocabulary,
    balls: [[f64; 2]; 4],
    steps: usize,
    cancel_step: Option<usize>,
    last_labels: LabelSet,
    ready: bool,
}

impl ReacherDelivery {
    /// The environment on the shipped model.
    pub fn new(config: ReacherConfig) -> Result<ReacherDelivery, ReacherError> {
        let model =
            Model::from_xml_str(crate::assets::REACHER_XML, crate::assets::REACHER_XML_NAME)?;
        ReacherDelivery::with_model(Arc::new(model), config)
    }

    /// The environment on a given model (which must have the ReacherDelivery bodies/joints).
    pub fn with_model(
        model: Arc<Model>,
        config: ReacherConfig,
    ) -> Result<ReacherDelivery, ReacherError> {
        config.validate()?;
        let layout = Layout::find(&model)?;
        let data = Data::new(model)?;
        Ok(ReacherDelivery {
            balls: config.ball_layout,
            config,
            data,
            layout,
            vocab: Vocabulary::new(VOCABULARY),
            steps: 0,
            cancel_step: None,
            last_labels: LabelSet::EMPTY,
            ready: false,
        })
    }

    pub fn config(&self) -> &ReacherConfig {
        &self.config
    }

    pub fn vocabulary(&self) -> &Vocabulary {
        &self.vocab
    }

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

    /// Ball positions of the current episode, in [`BALLS`] order.
    pub fn balls(&self) -> [[f64; 2]; 4] {
        self.balls
    }

    /// Steps taken in the current episode.
    pub fn steps(&self) -> usize {
        self.steps
    }

    /// The (1-based) step on which this episode's cancel event fires, if any.
    pub fn cancel_step(&self) -> Option<usize> {
        self.cancel_step
    }

    /// Labels of the last step (or of the reset state).
    pub fn labels(&self) -> LabelSet {
        self.last_labels
    }

    /// Fingertip position (x, y).
    pub fn fingertip(&self) -> [f64; 2] {
        let p = self.data.body_xpos(self.layout.fingertip_body);
        [p[0], p[1]]
    }

    /// Places the arm (joint angles and velocities) without stepping, e.g. for tests and
    /// scripted states; recomputes positions and labels. Ball layout and cancel schedule stay.
    pub fn set_arm(&mut self, angles: [f64; 2], velocities: [f64; 2]) -> Result<(), EnvError> {
        for k in 0..2 {
            self.data.qpos_mut()[self.layout.arm_qpos[k]] = angles[k];
            self.data.qvel_mut()[self.layout.arm_dof[k]] = velocities[k];
        }
        self.data
            .forward()
            .map_err(|e| EnvError::Simulation(e.to_string()))?;
        self.last_labels = self.ball_labels();
        Ok(())
    }

    /// Restores the start of a logged episode instead of drawing one from a seed: the full
    /// `qpos`/`qvel`, the ball layout and the cancel step, through the same sequence as
    /// [`ContinuousEnv::reset`] (MuJoCo data reset, state written, forward), so stepping the
    /// same actions afterwards reproduces the logged run bit for bit. Writes the observation.
    pub fn restore_start(
        &mut self,
        qpos: &[f64],
        qvel: &[f64],
        balls: [[f64; 2]; 4],
        cancel_step: Option<usize>,
        obs: &mut [f32],
    ) -> Result<(), EnvError> {
        self.data.reset();
        self.balls = balls;
        // Before the logged qpos, which holds the balls itself on a model with ball slides.
        self.place_balls();
        self.data
            .set_qpos(qpos)
            .and_then(|()| self.data.set_qvel(qvel))
            .map_err(|e| EnvError::Simulation(e.to_string()))?;
        self.cancel_step = cancel_step;
        self.steps = 0;
        self.data
            .forward()
            .map_err(|e| EnvError::Simulation(e.to_string()))?;
        self.last_labels = self.ball_labels();
        self.ready = true;
        self.write_obs(obs);
        Ok(())
    }

    /// Puts the model's balls at this episode's layout (positions take effect at the next
    /// forward pass).
    fn place_balls(&mut self) {
        for (placement, &b) in self.layout.balls.iter().zip(&self.balls) {
            placement.place(&mut self.data, b);
        }
    }

    /// Labels of the balls the fingertip touches now (no cancel).
    fn ball_labels(&self) -> LabelSet {
        let tip = self.fingertip();
        let mut labels = LabelSet::EMPTY;
        for (i, b) in self.balls.iter().enumerate() {
            let (dx, dy) = (tip[0] - b[0], tip[1] - b[1]);
            if dx * dx + dy * dy < TOUCH_RADIUS * TOUCH_RADIUS {
                labels = labels.with(i);
            }
        }
        labels
    }

    fn draw_layout(&self, rng: &mut ChaCha8Rng) -> [[f64; 2]; 4] {
        if !self.config.randomize_balls {
            return self.config.ball_layout;
        }
        let mut balls = [[0.0; 2]; 4];
        let mut placed = 0;
        while placed < 4 {
            let r = rng.gen_range(0.06..0.19);
            let theta = rng.gen_range(-std::f64::consts::PI..std::f64::consts::PI);
            let candidate = [r * theta.cos(), r * theta.sin()];
            let clear = balls[..placed]
                .iter()
                .all(|b| (b[0] - candidate[0]).hypot(b[1] - candidate[1]) >= 0.08);
            if clear {
                balls[placed] = candidate;
                placed += 1;
            }
        }
        balls
    }

    fn write_obs(&self, obs: &mut [f32]) {
        let q = self.data.qpos();
        let v = self.data.qvel();
        let [a0, a1] = self.layout.arm_qpos;
        let [d0, d1] = self.layout.arm_dof;
        let tip = self.fingertip();
        obs[0] = q[a0].cos() as f32;
        obs[1] = q[a1].cos() as f32;
        obs[2] = q[a0].sin() as f32;
        obs[3] = q[a1].sin() as f32;
        obs[4] = v[d0] as f32;
        obs[5] = v[d1] as f32;
        obs[6] = tip[0] as f32;
        obs[7] = tip[1] as f32;
        for (i, b) in self.balls.iter().enumerate() {
            obs[8 + 2 * i] = (tip[0] - b[0]) as f32;
            obs[9 + 2 * i] = (tip[1] - b[1]) as f32;
        }
        obs[OBS_CANCEL] = if self.last_labels.contains(CANCEL_BIT) {
            1.0
        } else {
            0.0
        };
    }

    /// Gymnasium's reward: minus the distance to the nearest ball, minus Σ a².
    fn reward(&self, action: &[f64; 2]) -> f64 {
        let tip = self.fingertip();
        let nearest = self
            .balls
            .iter()
            .map(|b| (tip[0] - b[0]).hypot(tip[1] - b[1]))
            .fold(f64::INFINITY, f64::min);
        -nearest - (action[0] * action[0] + action[1] * action[1])
    }
}

impl ContinuousEnv for ReacherDelivery {
    fn obs_dim(&self) -> usize {
        OBS_DIM
    }

    fn act_dim(&self) -> usize {
        ACT_DIM
    }

    fn reset(&mut self, seed: u64, obs: &mut [f32]) {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        self.data.reset();
        self.balls = self.draw_layout(&mut rng);
        // ArmStart::Zero: the state data.reset() left (qpos0 = 0, at rest), no draw.
        if self.config.arm_start == ArmStart::Random {
            let q = self.data.qpos_mut();
            for &a in &self.layout.arm_qpos {
                q[a] = rng.gen_range(-0.1..0.1);
            }
            for k in 0..2 {
                let d = self.layout.arm_dof[k];
                self.data.qvel_mut()[d] = rng.gen_range(-0.005..0.005);
            }
        }
        self.place_balls();
        let cancel = &self.config.cancel;
        self.cancel_step = rng
            .gen_bool(cancel.probability)
            .then(|| rng.gen_range(cancel.earliest_step..=cancel.latest_step));
        self.steps = 0;
        // forward only computes positions from a state just written by hand, which cannot
        // trip MuJoCo's error paths on a valid model; if it ever did, step() reports it.
        let _ = self.data.forward();
        self.last_labels = self.ball_labels();
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
        let mut labels = self.ball_labels();
        if self.cancel_step == Some(self.steps) {
            labels = labels.with(CANCEL_BIT);
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
