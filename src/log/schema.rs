//! The rollout log schema, version [`SCHEMA_VERSION`].
//!
//! | topic            | encoding                | schema name                  | when            |
//! |------------------|-------------------------|------------------------------|-----------------|
//! | `/run`           | `json` (JSON Schema)    | `smirl.v1.Run`               | once, first     |
//! | `/episode/start` | `protobuf`              | `smirl.v1.EpisodeStart`      | episode start   |
//! | `/step`          | `protobuf`              | `smirl.v1.Step`              | every step      |
//! | `/episode/end`   | `protobuf`              | `smirl.v1.EpisodeEnd`        | episode end     |
//!
//! The file also carries the model XML and the run config as MCAP attachments (`model.xml`,
//! `config.json`), every file the scene reads besides its own text (`include/<name>`,
//! `asset/<name>`; see [`ATTACHMENT_INCLUDE_PREFIX`]) and a metadata record `smirl.run` (the
//! run's identity as strings).
//!
//! **Why protobuf for steps.** A step is mostly floats; their low mantissa bits do not
//! compress, so on-disk size is about the raw binary size: protobuf stores a `double` in 8
//! bytes where JSON needs ~20 characters (measured: ~65 B/step protobuf vs ~240 B/step JSON,
//! both zstd). `qpos`/`qvel` are stored as exact `double`s (replay checks them bit for bit),
//! actions as the `float`s the policy produced.
//!
//! **Why the observation is optional.** ReacherDelivery's observation is a function of
//! `qpos`, `qvel`, the ball layout and the cancel label, all of which are logged; storing it
//! too costs ~64 B/step (17 incompressible `float`s), which alone would break the 100 B/step
//! budget. It is logged when [`super::LogOptions::observations`] is set, and replay checks it
//! bit for bit when present.
//!
//! **Time.** `log_time` is simulated time: each logged step advances it by the run's
//! `step_duration_ns` (20 ms for ReacherDelivery), so Foxglove plays episodes back at real
//! speed; it never depends on the wall clock, so the same seed gives the same file.

use super::proto::{
    file_descriptor_set, DecodeError, Decoder, Encoder, FieldSpec, FieldType, MessageSpec,
};
use crate::env::scene_files::{SceneFile, SceneFileKind};

/// Largest uncompressed chunk a log may have: the reader refuses a larger one, and the
/// writer's chunk size stays below half of it (its chunks are ~1 MiB; see
/// [`super::LogOptions::chunk_size`]).
pub const MAX_CHUNK_BYTES: u64 = 256 << 20;

/// Key of the run config (`RunInfo::config`) that records the task's layout (scene, regions,
/// events; `env::layout::TaskLayout` as JSON); logs without it were made on the shipped
/// four-ball layout.
pub const CONFIG_TASK_LAYOUT: &str = "task_layout";
/// Key of the run config that records the task file's text.
pub const CONFIG_TASK_FILE: &str = "task_file";
use serde::{Deserialize, Serialize};

/// Version of this schema; readers refuse files with another one.
pub const SCHEMA_VERSION: u32 = 1;
/// Protobuf package (and schema-name prefix) of this version.
pub const PACKAGE: &str = "smirl.v1";

pub const TOPIC_RUN: &str = "/run";
pub const TOPIC_EPISODE_START: &str = "/episode/start";
pub const TOPIC_STEP: &str = "/step";
pub const TOPIC_EPISODE_END: &str = "/episode/end";

pub const RUN_SCHEMA_NAME: &str = "smirl.v1.Run";
pub const STEP_SCHEMA_NAME: &str = "smirl.v1.Step";
pub const EPISODE_START_SCHEMA_NAME: &str = "smirl.v1.EpisodeStart";
pub const EPISODE_END_SCHEMA_NAME: &str = "smirl.v1.EpisodeEnd";

pub const ATTACHMENT_MODEL_XML: &str = "model.xml";
pub const ATTACHMENT_CONFIG: &str = "config.json";
/// Prefix of the attachments that carry the files the scene includes, each named by the
/// prefix and the name the scene gives it (`include/parts/motors.xml`), in the order MuJoCo
/// reads them. A log of a scene that includes nothing has none.
pub const ATTACHMENT_INCLUDE_PREFIX: &str = "include/";
/// Prefix of the attachments that carry the mesh, skin, height-field and texture files the
/// scene names, each named by the prefix and the file's name relative to the scene file's
/// directory, or its absolute path (`asset/meshes/link.stl`). A log of a scene that names none
/// has none.
pub const ATTACHMENT_ASSET_PREFIX: &str = "asset/";

pub const METADATA_RUN: &str = "smirl.run";
/// Channel metadata key holding the schema version.
pub const CHANNEL_VERSION_KEY: &str = "smirl.schema_version";

/// The attachment name of a file the scene reads.
pub fn scene_file_attachment(file: &SceneFile) -> String {
    let prefix = match file.kind {
        SceneFileKind::Include => ATTACHMENT_INCLUDE_PREFIX,
        SceneFileKind::Asset => ATTACHMENT_ASSET_PREFIX,
    };
    format!("{prefix}{}", file.name)
}

/// The kind and name of the scene file an attachment carries, when it carries one.
pub fn scene_file_of_attachment(name: &str) -> Option<(SceneFileKind, &str)> {
    (name
        .strip_prefix(ATTACHMENT_INCLUDE_PREFIX)
        .map(|n| (SceneFileKind::Include, n)))
    .or_else(|| (name.strip_prefix(ATTACHMENT_ASSET_PREFIX)).map(|n| (SceneFileKind::Asset, n)))
}

/// `rm_state` value meaning "no reward machine".
pub const NO_RM: i64 = -1;

/// Per-run record (topic `/run`, JSON): what was run and with what.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct RunInfo {
    pub schema_version: u32,
    /// Environment name, e.g. `"ReacherDelivery"`.
    pub env: String,
    /// Task name, e.g. `"sequential"`.
    pub task: String,
    pub seed: u64,
    /// Propositions of the labels, in bit order (e.g. `"rgbyc"`).
    pub vocabulary: String,
    pub obs_dim: u32,
    pub act_dim: u32,
    /// Simulated duration of one environment step (ns); drives `log_time`.
    pub step_duration_ns: u64,
    /// File name the model XML came from (informative).
    pub model_xml_name: String,
    /// Lower-case hex SHA-256 of the model XML text (also attached as `model.xml`).
    pub model_xml_sha256: String,
    pub crate_version: String,
    /// `smirl::GIT_COMMIT` of the binary that wrote the log (empty when unknown).
    pub git_commit: String,
    /// `mujoco::version_string()` of the library that simulated the run.
    pub mujoco_version: String,
    /// The run's full configuration (also attached as `config.json`).
    pub config: serde_json::Value,
    /// The task's reward machine in the text format, when the run used one.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub reward_machine: Option<String>,
    /// Every n-th episode was logged (1 = all).
    pub every_nth_episode: u64,
    /// Whether steps carry the observation.
    pub observations: bool,
}

impl RunInfo {
    /// The layout of the task the run was made on (`config.task_layout`); a log without the
    /// record was made on the shipped four-ball layout, read as the shipped task of its name
    /// (or Composite, which has the same layout, for a task file's log).
    pub fn task_layout(&self) -> Result<crate::env::layout::TaskLayout, RunLayoutError> {
        if let Some(v) = self.config.get(CONFIG_TASK_LAYOUT) {
            let layout: crate::env::layout::TaskLayout =
                serde_json::from_value(v.clone()).map_err(RunLayoutError::Parse)?;
            layout.check().map_err(RunLayoutError::Invalid)?;
            return Ok(layout);
        }
        let shipped = crate::env::task_file::SHIPPED;
        let name = if shipped.contains(&self.task.as_str()) {
            self.task.as_str()
        } else {
            "composite"
        };
        crate::env::task_file::Task::shipped(name)
            .map(|t| t.layout())
            .map_err(|e| RunLayoutError::Shipped(Box::new(e)))
    }
}

/// Why a run record yields no task layout.
#[derive(Debug, thiserror::Error)]
pub enum RunLayoutError {
    #[error("the run's task layout does not parse: {0}")]
    Parse(#[source] serde_json::Error),
    #[error("the run's task layout is not one a task file declares: {0}")]
    Invalid(crate::env::layout::LayoutProblem),
    /// The shipped task a log without a recorded layout is read as (a broken build).
    #[error("{0}")]
    Shipped(Box<crate::env::task_file::TaskFileError>),
}

/// JSON Schema of [`RunInfo`] (draft 2020-12), stored with the `/run` channel.
pub fn run_json_schema() -> String {
    serde_json::json!({
        "$schema": "https://json-schema.org/draft/2020-12/schema",
        "title": RUN_SCHEMA_NAME,
        "description": "smirl rollout log: one record per run",
        "type": "object",
        "required": ["schema_version", "env", "task", "seed", "vocabulary", "obs_dim", "act_dim",
                     "step_duration_ns", "model_xml_name", "model_xml_sha256", "crate_version",
                     "git_commit", "mujoco_version", "config", "every_nth_episode", "observations"],
        "properties": {
            "schema_version": {"type": "integer", "const": SCHEMA_VERSION},
            "env": {"type": "string"},
            "task": {"type": "string"},
            "seed": {"type": "integer", "minimum": 0},
            "vocabulary": {"type": "string", "description": "propositions in label-bit order"},
            "obs_dim": {"type": "integer"},
            "act_dim": {"type": "integer"},
            "step_duration_ns": {"type": "integer"},
            "model_xml_name": {"type": "string"},
            "model_xml_sha256": {"type": "string", "pattern": "^[0-9a-f]{64}$"},
            "crate_version": {"type": "string"},
            "git_commit": {"type": "string"},
            "mujoco_version": {"type": "string"},
            "config": {"type": "object"},
            "reward_machine": {"type": "string"},
            "every_nth_episode": {"type": "integer", "minimum": 1},
            "observations": {"type": "boolean"}
        }
    })
    .to_string()
}

const fn field(name: &'static str, number: u32, ty: FieldType, repeated: bool) -> FieldSpec {
    FieldSpec {
        name,
        number,
        ty,
        repeated,
    }
}

use FieldType::{Bool, Double, Float, Sint32, String as Str, Uint32, Uint64};

/// `smirl.v1.Step`.
pub const STEP_SPEC: MessageSpec = MessageSpec {
    name: "Step",
    fields: &[
        field("episode", 1, Uint64, false),
        field("step", 2, Uint32, false),
        field("action", 3, Float, true),
        field("reward", 4, Double, false),
        field("labels", 5, Uint32, false),
        field("label_text", 6, Str, false),
        field("rm_state", 7, Sint32, false),
        field("rm_reward", 8, Double, false),
        field("qpos", 9, Double, true),
        field("qvel", 10, Double, true),
        field("obs", 11, Float, true),
        field("terminated", 12, Bool, false),
        field("truncated", 13, Bool, false),
    ],
};

/// `smirl.v1.EpisodeStart`.
pub const EPISODE_START_SPEC: MessageSpec = MessageSpec {
    name: "EpisodeStart",
    fields: &[
        field("episode", 1, Uint64, false),
        field("seed", 2, Uint64, false),
        field("phase", 3, Str, false),
        field("qpos", 4, Double, true),
        field("qvel", 5, Double, true),
        field("balls", 6, Double, true),
        field("cancel_step", 7, Uint32, false),
        field("labels", 8, Uint32, false),
        field("rm_state", 9, Sint32, false),
        field("obs", 10, Float, true),
        field("event_steps", 11, Uint32, true),
    ],
};

/// `smirl.v1.EpisodeEnd`.
pub const EPISODE_END_SPEC: MessageSpec = MessageSpec {
    name: "EpisodeEnd",
    fields: &[
        field("episode", 1, Uint64, false),
        field("seed", 2, Uint64, false),
        field("phase", 3, Str, false),
        field("length", 4, Uint32, false),
        field("env_return", 5, Double, false),
        field("rm_return", 6, Double, false),
        field("success", 7, Bool, false),
        field("rm_state", 8, Sint32, false),
    ],
};

/// The `FileDescriptorSet` declaring one message (what MCAP stores as the channel schema;
/// a self-contained set per schema, as Foxglove expects).
pub fn descriptor(spec: MessageSpec) -> Vec<u8> {
    file_descriptor_set(&format!("smirl/v1/{}.proto", spec.name), PACKAGE, &[spec])
}

/// One environment step (topic `/step`).
#[derive(Clone, Debug, PartialEq, Default)]
pub struct StepMsg {
    pub episode: u64,
    /// 1-based index of the step within its episode (the env's step counter after it).
    pub step: u32,
    pub action: Vec<f32>,
    /// The environment's own reward.
    pub reward: f64,
    /// Label bits after the step (bit i = proposition i of the run's vocabulary).
    pub labels: u32,
    /// The labels as text (e.g. `"rc"`), for people reading the log.
    pub label_text: String,
    /// RM state after the step, [`NO_RM`] without a machine.
    pub rm_state: i64,
    pub rm_reward: f64,
    pub qpos: Vec<f64>,
    pub qvel: Vec<f64>,
    /// Observation after the step (empty unless observations are logged).
    pub obs: Vec<f32>,
    pub terminated: bool,
    pub truncated: bool,
}

/// Start of an episode (topic `/episode/start`): enough to restore its initial state.
#[derive(Clone, Debug, PartialEq, Default)]
pub struct EpisodeStartMsg {
    pub episode: u64,
    /// The reset seed.
    pub seed: u64,
    /// `"expert"`, `"demo"`, `"train"`, `"agent"`, `"eval"`, `"select"`, `"final"`, …
    pub phase: String,
    pub qpos: Vec<f64>,
    pub qvel: Vec<f64>,
    /// Region layout `[x0, y0, x1, y1, …]` (ReacherDelivery; empty elsewhere).
    pub balls: Vec<f64>,
    /// A one-event task's 1-based event step, 0 for none.
    pub cancel_step: u32,
    /// Labels of the reset state.
    pub labels: u32,
    pub rm_state: i64,
    pub obs: Vec<f32>,
    /// Each event's 1-based step (0 for none) of a task with other than one event.
    pub event_steps: Vec<u32>,
}

impl EpisodeStartMsg {
    /// The step of each of a task's `n_events` events (`cancel_step` for a one-event task).
    pub fn event_steps(&self, n_events: usize) -> Vec<Option<usize>> {
        let step = |s: u32| (s > 0).then_some(s as usize);
        if n_events == 1 && self.event_steps.is_empty() {
            vec![step(self.cancel_step)]
        } else {
            self.event_steps.iter().map(|&s| step(s)).collect()
        }
    }

    /// The fields of a task's event steps: `cancel_step` for one event, `event_steps` else.
    pub fn with_event_steps(mut self, steps: &[Option<usize>]) -> EpisodeStartMsg {
        let code = |s: &Option<usize>| s.map_or(0, |s| s as u32);
        match steps {
            [only] => self.cancel_step = code(only),
            _ => self.event_steps = steps.iter().map(code).collect(),
        }
        self
    }
}

/// End of an episode (topic `/episode/end`).
#[derive(Clone, Debug, PartialEq, Default)]
pub struct EpisodeEndMsg {
    pub episode: u64,
    pub seed: u64,
    pub phase: String,
    pub length: u32,
    pub env_return: f64,
    pub rm_return: f64,
    /// The task was completed (the RM reached a terminal, non-failure state).
    pub success: bool,
    pub rm_state: i64,
}

impl StepMsg {
    pub fn encode(&self, buf: &mut Vec<u8>) {
        encode_step(
            buf,
            &StepFields {
                episode: self.episode,
                step: self.step,
                action: &self.action,
                reward: self.reward,
                labels: self.labels,
                label_text: &self.label_text,
                rm_state: self.rm_state,
                rm_reward: self.rm_reward,
                qpos: &self.qpos,
                qvel: &self.qvel,
                obs: &self.obs,
                terminated: self.terminated,
                truncated: self.truncated,
            },
        );
    }

    pub fn decode(data: &[u8]) -> Result<StepMsg, DecodeError> {
        let mut m = StepMsg {
            rm_state: 0,
            ..Default::default()
        };
        let mut d = Decoder::new(data);
        while let Some((f, v)) = d.next()? {
            match f {
                1 => m.episode = v.as_u64(f)?,
                2 => m.step = v.as_u32(f)?,
                3 => v.push_floats(f, &mut m.action)?,
                4 => m.reward = v.as_f64(f)?,
                5 => m.labels = v.as_u32(f)?,
                6 => m.label_text = v.as_str(f)?.to_owned(),
                7 => m.rm_state = v.as_sint(f)?,
                8 => m.rm_reward = v.as_f64(f)?,
                9 => v.push_doubles(f, &mut m.qpos)?,
                10 => v.push_doubles(f, &mut m.qvel)?,
                11 => v.push_floats(f, &mut m.obs)?,
                12 => m.terminated = v.as_bool(f)?,
                13 => m.truncated = v.as_bool(f)?,
                _ => {} // unknown fields are skipped, as protobuf prescribes
            }
        }
        Ok(m)
    }
}

/// A step's fields by reference: what the logger encodes on the caller's thread without
/// allocating.
#[derive(Clone, Copy, Debug)]
pub struct StepFields<'a> {
    pub episode: u64,
    pub step: u32,
    pub action: &'a [f32],
    pub reward: f64,
    pub labels: u32,
    pub label_text: &'a str,
    pub rm_state: i64,
    pub rm_reward: f64,
    pub qpos: &'a [f64],
    pub qvel: &'a [f64],
    pub obs: &'a [f32],
    pub terminated: bool,
    pub truncated: bool,
}

/// Encodes a step (appending to `buf`).
#[inline]
pub fn encode_step(buf: &mut Vec<u8>, s: &StepFields) {
    let mut e = Encoder::new(buf);
    e.uint(1, s.episode);
    e.uint(2, u64::from(s.step));
    e.floats(3, s.action);
    e.double(4, s.reward);
    e.uint(5, u64::from(s.labels));
    e.bytes(6, s.label_text.as_bytes());
    e.sint(7, s.rm_state);
    if s.rm_state != NO_RM {
        e.double(8, s.rm_reward);
    }
    e.doubles(9, s.qpos);
    e.doubles(10, s.qvel);
    e.floats(11, s.obs);
    e.uint(12, u64::from(s.terminated));
    e.uint(13, u64::from(s.truncated));
}

impl EpisodeStartMsg {
    pub fn encode(&self, buf: &mut Vec<u8>) {
        let mut e = Encoder::new(buf);
        e.uint(1, self.episode);
        e.uint(2, self.seed);
        e.bytes(3, self.phase.as_bytes());
        e.doubles(4, &self.qpos);
        e.doubles(5, &self.qvel);
        e.doubles(6, &self.balls);
        e.uint(7, u64::from(self.cancel_step));
        e.uint(8, u64::from(self.labels));
        e.sint(9, self.rm_state);
        e.floats(10, &self.obs);
        e.uints(11, self.event_steps.iter().map(|&s| u64::from(s)));
    }

    pub fn decode(data: &[u8]) -> Result<EpisodeStartMsg, DecodeError> {
        let mut m = EpisodeStartMsg::default();
        let mut d = Decoder::new(data);
        while let Some((f, v)) = d.next()? {
            match f {
                1 => m.episode = v.as_u64(f)?,
                2 => m.seed = v.as_u64(f)?,
                3 => m.phase = v.as_str(f)?.to_owned(),
                4 => v.push_doubles(f, &mut m.qpos)?,
                5 => v.push_doubles(f, &mut m.qvel)?,
                6 => v.push_doubles(f, &mut m.balls)?,
                7 => m.cancel_step = v.as_u32(f)?,
                8 => m.labels = v.as_u32(f)?,
                9 => m.rm_state = v.as_sint(f)?,
                10 => v.push_floats(f, &mut m.obs)?,
                11 => m.event_steps.push(v.as_u32(f)?),
                _ => {}
            }
        }
        Ok(m)
    }
}

impl EpisodeEndMsg {
    pub fn encode(&self, buf: &mut Vec<u8>) {
        let mut e = Encoder::new(buf);
        e.uint(1, self.episode);
        e.uint(2, self.seed);
        e.bytes(3, self.phase.as_bytes());
        e.uint(4, u64::from(self.length));
        e.double(5, self.env_return);
        e.double(6, self.rm_return);
        e.uint(7, u64::from(self.success));
        e.sint(8, self.rm_state);
    }

    pub fn decode(data: &[u8]) -> Result<EpisodeEndMsg, DecodeError> {
        let mut m = EpisodeEndMsg::default();
        let mut d = Decoder::new(data);
        while let Some((f, v)) = d.next()? {
            match f {
                1 => m.episode = v.as_u64(f)?,
                2 => m.seed = v.as_u64(f)?,
                3 => m.phase = v.as_str(f)?.to_owned(),
                4 => m.length = v.as_u32(f)?,
                5 => m.env_return = v.as_f64(f)?,
                6 => m.rm_return = v.as_f64(f)?,
                7 => m.success = v.as_bool(f)?,
                8 => m.rm_state = v.as_sint(f)?,
                _ => {}
            }
        }
        Ok(m)
    }
}

/// Lower-case hex SHA-256 of a text.
pub fn sha256_hex(text: &str) -> String {
    use sha2::{Digest, Sha256};
    let digest = Sha256::digest(text.as_bytes());
    digest.iter().map(|b| format!("{b:02x}")).collect()
}
