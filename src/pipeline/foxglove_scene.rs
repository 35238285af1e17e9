//! Foxglove 3D view of a rollout log (`reacher foxglove LOG --out VIEW.mcap`): a copy of the
//! log with two more channels in Foxglove's standard schemas, so that opening it in Foxglove
//! shows the arm moving among the task's labelled regions in a 3D panel.
//!
//! - `/scene` (`foxglove.SceneUpdate`): entity `arena` (floor and walls, at each episode
//!   start), `balls` (each region's geom at the episode's layout, translucent as in the
//!   model), `arm` (both links as cylinders and the fingertip as a sphere, at every logged
//!   state), `events` (a lit touch zone around each region the fingertip is in, and the
//!   event's letter as text on the step an event fires; empty otherwise).
//! - `/tf` (`foxglove.FrameTransforms`): frames `link0`, `link1` and `fingertip` in `world`.
//!
//! Geometry, colours and sizes come from the log's own model XML; poses from forward
//! kinematics on the logged `qpos` (exact doubles) with the balls at the episode's logged
//! layout, at the `log_time` of the state's
//! `/episode/start` or `/step` message. Every original record the reader accepts (messages,
//! attachments, metadata) is copied unchanged, in file order; of a log cut short, that is its
//! complete chunks and nothing of the chunk it was cut in. The log itself keeps its size (the
//! view is a separate file). Schemas are the official ones of the `foxglove` crate.

use crate::env::layout::{Anchor, TaskLayout};
use crate::env::placement::Placement;
use crate::log::schema::{EpisodeStartMsg, StepMsg, TOPIC_EPISODE_START, TOPIC_STEP};
use crate::log::{read_log_bytes, read_log_file, read_log_records, LogError, LogModelError};
use crate::mujoco::{Data, MjError, Model, ObjectKind};
use foxglove::schemas::{
    Color, CubePrimitive, CylinderPrimitive, FrameTransform, FrameTransforms, Pose, Quaternion,
    SceneEntity, SceneUpdate, SpherePrimitive, TextPrimitive, Timestamp, Vector3,
};
use foxglove::Encode;
use mcap::records::Record;
use std::collections::{BTreeMap, HashMap};
use std::path::{Path, PathBuf};
use std::sync::Arc;

pub const TOPIC_SCENE: &str = "/scene";
pub const TOPIC_TF: &str = "/tf";
/// The frame every scene entity is expressed in.
pub const FRAME_WORLD: &str = "world";
/// Arena walls of the model (capsules of the world body).
const WALLS: [&str; 4] = ["sideS", "sideE", "sideN", "sideW"];

#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    #[error(transparent)]
    Log(#[from] LogError),
    #[error("{path}: {problem}")]
    Input { path: PathBuf, problem: String },
    #[error("{path}: {problem}")]
    Output { path: PathBuf, problem: String },
}

/// A logged model the scene cannot be drawn from.
#[derive(Debug, thiserror::Error)]
enum GeometryError {
    #[error(transparent)]
    MuJoCo(#[from] MjError),
    #[error("body {0} has neither a mocap body nor slides")]
    NotMovable(String),
    #[error("wall {0} is not a capsule of the world body")]
    NotCapsule(&'static str),
}

/// A logged state the scene cannot be drawn from, or whose messages cannot be written.
#[derive(Debug, thiserror::Error)]
enum FrameError {
    #[error(transparent)]
    MuJoCo(#[from] MjError),
    #[error("the region layout has {got} values, expected {expected}")]
    RegionLayout { got: usize, expected: usize },
    #[error(transparent)]
    Mcap(#[from] mcap::McapError),
}

/// What the export wrote.
#[derive(Clone, Debug, PartialEq)]
pub struct SceneSummary {
    pub out: PathBuf,
    /// Messages copied from the log.
    pub copied: u64,
    /// `/scene` messages written (as many `/tf` messages).
    pub scenes: u64,
    pub episodes: usize,
}

fn input_error(path: &Path) -> impl Fn(String) -> SceneError + '_ {
    move |problem| SceneError::Input {
        path: path.into(),
        problem,
    }
}

fn output_error(path: &Path) -> impl Fn(String) -> SceneError + '_ {
    move |problem| SceneError::Output {
        path: path.into(),
        problem,
    }
}

/// The model facts the scene needs.
struct Geometry {
    model: Arc<Model>,
    arm_bodies: [usize; 3],
    /// Each region's anchor: a body (`true`) or a site, by id.
    region_anchors: Vec<(bool, usize)>,
    /// How each movable region is put at its episode's logged position.
    region_placements: Vec<Option<Placement>>,
    link_radius: f64,
    tip_radius: f64,
    /// Radius of each region's geom (0 without one) and of its touch zone.
    ball_radii: Vec<f64>,
    touch_radii: Vec<f64>,
    link_colour: Color,
    tip_colour: Color,
    ball_colours: Vec<Color>,
    /// Label bit and letter of each event.
    events: Vec<(usize, char)>,
    walls: Vec<([f64; 3], [f64; 3], f64)>,
    wall_colour: Color,
}

fn colour(rgba: [f32; 4], alpha: Option<f64>) -> Color {
    Color {
        r: f64::from(rgba[0]),
        g: f64::from(rgba[1]),
        b: f64::from(rgba[2]),
        a: alpha.unwrap_or(f64::from(rgba[3])),
    }
}

impl Geometry {
    fn new(model: Model, layout: &TaskLayout) -> Result<Geometry, GeometryError> {
        let model = Arc::new(model);
        let id = |kind, name: &str| model.id(kind, name);
        let geom = |name: &str| id(ObjectKind::Geom, name);
        let arm_bodies = [
            id(ObjectKind::Body, "body0")?,
            id(ObjectKind::Body, "body1")?,
            id(ObjectKind::Body, "fingertip")?,
        ];
        let mut region_anchors = Vec::with_capacity(layout.n_regions());
        let mut region_placements = Vec::with_capacity(layout.n_regions());
        let (mut ball_colours, mut ball_radii) = (Vec::new(), Vec::new());
        for region in &layout.regions {
            region_anchors.push(match &region.anchor {
                Anchor::Body(b) => (true, id(ObjectKind::Body, b)?),
                Anchor::Site(s) => (false, id(ObjectKind::Site, s)?),
            });
            // The geom named as the anchor (the built-in scene's balls) gives the colour.
            match geom(region.anchor.name()) {
                Ok(g) => {
                    ball_colours.push(colour(model.geom_rgba(g), None));
                    ball_radii.push(model.geom_radius(g));
                }
                Err(_) => {
                    ball_colours.push(Color {
                        r: 0.55,
                        g: 0.35,
                        b: 0.75,
                        a: 0.3,
                    });
                    ball_radii.push(0.0);
                }
            }
            region_placements.push(match (&region.anchor, region.movable) {
                (Anchor::Body(b), true) => Some(
                    Placement::find(&model, b)
                        .ok_or_else(|| GeometryError::NotMovable(b.clone()))?,
                ),
                _ => None,
            });
        }
        let mut walls = Vec::new();
        for name in WALLS {
            let g = geom(name)?;
            let (a, b) = model
                .world_capsule_segment(g)
                .ok_or(GeometryError::NotCapsule(name))?;
            walls.push((a, b, model.geom_radius(g)));
        }
        Ok(Geometry {
            link_radius: model.geom_radius(geom("link0")?),
            tip_radius: model.geom_radius(geom("fingertip")?),
            ball_radii,
            touch_radii: layout.regions.iter().map(|r| r.radius).collect(),
            events: (0..layout.n_events())
                .map(|e| (layout.event_bit(e), layout.events[e].letter))
                .collect(),
            link_colour: colour(model.geom_rgba(geom("link0")?), None),
            tip_colour: colour(model.geom_rgba(geom("fingertip")?), None),
            wall_colour: colour(model.geom_rgba(geom(WALLS[0])?), None),
            ball_colours,
            walls,
            arm_bodies,
            region_anchors,
            region_placements,
            model,
        })
    }
}

fn vector(p: [f64; 3]) -> Vector3 {
    Vector3 {
        x: p[0],
        y: p[1],
        z: p[2],
    }
}

fn at(p: [f64; 3]) -> Option<Pose> {
    Some(Pose {
        position: Some(vector(p)),
        orientation: Some(Quaternion {
            x: 0.0,
            y: 0.0,
            z: 0.0,
            w: 1.0,
        }),
    })
}

/// The rotation taking +z to the unit vector `d` (a cylinder's axis is its z axis).
fn z_to(d: [f64; 3]) -> Quaternion {
    // q = (z × d, 1 + z·d), normalised; the antiparallel case turns about x.
    let (x, y, w) = (-d[1], d[0], 1.0 + d[2]);
    let n = (x * x + y * y + w * w).sqrt();
    if n < 1e-12 {
        return Quaternion {
            x: 1.0,
            y: 0.0,
            z: 0.0,
            w: 0.0,
        };
    }
    Quaternion {
        x: x / n,
        y: y / n,
        z: 0.0,
        w: w / n,
    }
}

/// A cylinder from `a` to `b` of the given radius.
fn segment(a: [f64; 3], b: [f64; 3], radius: f64, color: Color) -> CylinderPrimitive {
    let d = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
    let len = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
    let unit = if len > 0.0 {
        [d[0] / len, d[1] / len, d[2] / len]
    } else {
        [0.0, 0.0, 1.0]
    };
    CylinderPrimitive {
        pose: Some(Pose {
            position: Some(vector([
                (a[0] + b[0]) / 2.0,
                (a[1] + b[1]) / 2.0,
                (a[2] + b[2]) / 2.0,
            ])),
            orientation: Some(z_to(unit)),
        }),
        size: Some(vector([2.0 * radius, 2.0 * radius, len])),
        bottom_scale: 1.0,
        top_scale: 1.0,
        color: Some(color),
    }
}

fn sphere(p: [f64; 3], radius: f64, color: Color) -> SpherePrimitive {
    SpherePrimitive {
        pose: at(p),
        size: Some(vector([2.0 * radius; 3])),
        color: Some(color),
    }
}

fn entity(id: &str, time: Timestamp) -> SceneEntity {
    SceneEntity {
        timestamp: Some(time),
        frame_id: FRAME_WORLD.into(),
        id: id.into(),
        ..Default::default()
    }
}

fn timestamp(log_time_ns: u64) -> Timestamp {
    Timestamp::new(
        (log_time_ns / 1_000_000_000) as u32,
        (log_time_ns % 1_000_000_000) as u32,
    )
}

/// The scene and frames of one logged state.
struct Frame {
    scene: SceneUpdate,
    transforms: FrameTransforms,
}

impl Geometry {
    /// Puts the movable regions at an episode's logged layout (x, y of each region in label
    /// order); the state's forward pass in [`Geometry::frame`] moves them there.
    fn place_balls(&self, data: &mut Data, balls: &[f64]) -> Result<(), FrameError> {
        let n = self.region_placements.len();
        if balls.len() != 2 * n {
            return Err(FrameError::RegionLayout {
                got: balls.len(),
                expected: 2 * n,
            });
        }
        for (placement, xy) in self.region_placements.iter().zip(balls.chunks_exact(2)) {
            if let Some(placement) = placement {
                placement.place(data, [xy[0], xy[1]]);
            }
        }
        Ok(())
    }

    fn frame(
        &self,
        data: &mut Data,
        qpos: &[f64],
        labels: u32,
        episode_start: bool,
        log_time: u64,
    ) -> Result<Frame, MjError> {
        data.set_qpos(qpos).and_then(|()| data.forward())?;
        let time = timestamp(log_time);
        let [shoulder, elbow, tip] = self.arm_bodies.map(|b| data.body_xpos(b));
        let balls: Vec<[f64; 3]> = (self.region_anchors.iter())
            .map(|&(body, id)| {
                if body {
                    data.body_xpos(id)
                } else {
                    data.site_xpos(id)
                }
            })
            .collect();

        let mut arm = entity("arm", time);
        arm.cylinders = vec![
            segment(shoulder, elbow, self.link_radius, self.link_colour),
            segment(elbow, tip, self.link_radius, self.link_colour),
        ];
        arm.spheres = vec![sphere(tip, self.tip_radius, self.tip_colour)];

        let mut events = entity("events", time);
        for (k, p) in balls.iter().enumerate() {
            if labels >> k & 1 == 1 {
                let lit = Color {
                    a: 0.35,
                    ..self.ball_colours[k]
                };
                let zone = self.ball_radii[k] + self.touch_radii[k];
                events.spheres.push(sphere(*p, zone, lit));
            }
        }
        let fired: String = (self.events.iter())
            .filter(|&&(bit, _)| labels >> bit & 1 == 1)
            .map(|&(_, letter)| letter)
            .collect();
        if !fired.is_empty() {
            events.texts.push(TextPrimitive {
                pose: at([0.0, 0.0, 0.12]),
                billboard: true,
                font_size: 24.0,
                scale_invariant: true,
                color: Some(Color {
                    r: 0.0,
                    g: 0.0,
                    b: 0.0,
                    a: 1.0,
                }),
                text: fired,
            });
        }
        let mut entities = vec![arm, events];
        if episode_start {
            let mut ball_entity = entity("balls", time);
            ball_entity.spheres = balls
                .iter()
                .zip(&self.ball_colours)
                .zip(&self.ball_radii)
                .filter(|(_, &r)| r > 0.0)
                .map(|((p, c), &r)| sphere(*p, r, *c))
                .collect();
            let mut arena = entity("arena", time);
            arena.cubes = vec![CubePrimitive {
                pose: at([0.0, 0.0, -0.001]),
                size: Some(vector([0.6, 0.6, 0.002])),
                color: Some(Color {
                    r: 0.9,
                    g: 0.9,
                    b: 0.9,
                    a: 1.0,
                }),
            }];
            arena.cylinders = self
                .walls
                .iter()
                .map(|&(a, b, r)| segment(a, b, r, self.wall_colour))
                .collect();
            entities.push(ball_entity);
            entities.push(arena);
        }

        let transform = |child: &str, p: [f64; 3], towards: Option<[f64; 3]>| {
            let yaw = towards.map_or(0.0, |q| (q[1] - p[1]).atan2(q[0] - p[0]));
            FrameTransform {
                timestamp: Some(time),
                parent_frame_id: FRAME_WORLD.into(),
                child_frame_id: child.into(),
                translation: Some(vector(p)),
                rotation: Some(Quaternion {
                    x: 0.0,
                    y: 0.0,
                    z: (yaw / 2.0).sin(),
                    w: (yaw / 2.0).cos(),
                }),
            }
        };
        Ok(Frame {
            scene: SceneUpdate {
                deletions: Vec::new(),
                entities,
            },
            transforms: FrameTransforms {
                transforms: vec![
                    transform("link0", shoulder, Some(elbow)),
                    transform("link1", elbow, Some(tip)),
                    transform("fingertip", tip, None),
                ],
            },
        })
    }
}

/// Declares `topic` with the official schema and encoding of `T`; returns the channel id.
fn add_channel<T: Encode, W: std::io::Write + std::io::Seek>(
    writer: &mut mcap::Writer<W>,
    topic: &str,
) -> Result<u16, mcap::McapError> {
    let schema = T::get_schema().expect("foxglove's schemas are known");
    let schema_id = writer.add_schema(&schema.name, &schema.encoding, &schema.data)?;
    writer.add_channel(
        schema_id,
        topic,
        &T::get_message_encoding(),
        &BTreeMap::new(),
    )
}

fn encoded<T: Encode>(message: &T) -> Vec<u8> {
    let mut buf = Vec::new();
    message
        .encode(&mut buf)
        .expect("a Vec grows to fit any message");
    buf
}

/// Writes `out`: the log at `input` plus the `/scene` and `/tf` channels (see the module
/// docs). A log cut short is refused unless `allow_partial`; with it, the copy holds exactly
/// the records the reader recovers (complete chunks only, see
/// [`crate::log::read_log_records`]), and a log from which no episode is recovered is
/// refused. The output is written to `<out>.part` and renamed when complete.
pub fn export_scene(
    input: &Path,
    out: &Path,
    allow_partial: bool,
) -> Result<SceneSummary, SceneError> {
    let (bad_input, bad_output) = (input_error(input), output_error(out));
    let bytes = read_log_file(input)?;
    let log = read_log_bytes(&bytes, input)?;
    if let Some(rec) = &log.recovery {
        if !allow_partial {
            return Err(bad_input(format!(
                "{rec}; pass --allow-partial to export its complete chunks"
            )));
        }
        if log.episodes.is_empty() {
            return Err(bad_input(format!(
                "{rec}: no episode is recoverable, nothing to export"
            )));
        }
    }
    let model = log.reacher_model().map_err(|e| match e {
        LogModelError::Missing(problem) => bad_input(problem),
        LogModelError::Compile(e) => bad_input(format!("model.xml: {e}")),
    })?;
    let layout = log
        .run
        .task_layout()
        .map_err(|e| bad_input(e.to_string()))?;
    let geometry =
        Geometry::new(model, &layout).map_err(|e| bad_input(format!("model.xml: {e}")))?;
    let mut data = Data::new(geometry.model.clone()).map_err(|e| bad_input(e.to_string()))?;

    let mut part = out.as_os_str().to_os_string();
    part.push(".part");
    let part = PathBuf::from(part);
    crate::output::create_parent(out).map_err(|e| bad_output(e.problem))?;
    let file = std::fs::File::create(&part).map_err(|e| bad_output(e.to_string()))?;
    let written = write_view(&bytes, &geometry, &mut data, file, input, out);
    if written.is_err() {
        // Only the file this call created.
        let _ = std::fs::remove_file(&part);
    }
    let (copied, scenes) = written?;
    std::fs::rename(&part, out).map_err(|e| bad_output(e.to_string()))?;
    Ok(SceneSummary {
        out: out.into(),
        copied,
        scenes,
        episodes: log.episodes.len(),
    })
}

/// Copies the log's records into a view, adding a scene for every logged state.
struct ViewWriter<'g, W: std::io::Write + std::io::Seek> {
    writer: mcap::Writer<W>,
    geometry: &'g Geometry,
    data: &'g mut Data,
    scene_channel: u16,
    tf_channel: u16,
    /// The log's schemas and channels by their ids in the log.
    schemas: HashMap<u16, (String, String, Vec<u8>)>,
    channels: HashMap<u16, mcap::records::Channel>,
    /// Log channel id -> channel id in the view (declared at the channel's first message).
    view_channels: HashMap<u16, u16>,
    sequence: u32,
    copied: u64,
    scenes: u64,
}

impl<W: std::io::Write + std::io::Seek> ViewWriter<'_, W> {
    fn record(&mut self, record: &Record, input: &Path) -> Result<(), SceneError> {
        let bad_input = input_error(input);
        let mcap_err = |e: mcap::McapError| SceneError::Output {
            path: PathBuf::new(),
            problem: e.to_string(),
        };
        match record {
            Record::Schema { header, data } => {
                self.schemas.insert(
                    header.id,
                    (header.name.clone(), header.encoding.clone(), data.to_vec()),
                );
            }
            Record::Channel(ch) => {
                self.channels.insert(ch.id, ch.clone());
            }
            Record::Attachment { header, data, .. } => {
                self.writer
                    .attach(&mcap::Attachment {
                        log_time: header.log_time,
                        create_time: header.create_time,
                        name: header.name.clone(),
                        media_type: header.media_type.clone(),
                        data: std::borrow::Cow::Borrowed(data),
                    })
                    .map_err(mcap_err)?;
            }
            Record::Metadata(m) => self.writer.write_metadata(m).map_err(mcap_err)?,
            Record::Message { header, data } => {
                let ch = self.channels.get(&header.channel_id).ok_or_else(|| {
                    bad_input(format!("message on unknown channel {}", header.channel_id))
                })?;
                let channel_id = match self.view_channels.get(&ch.id) {
                    Some(&id) => id,
                    None => {
                        let schema_id = match self.schemas.get(&ch.schema_id) {
                            Some((name, encoding, schema)) => self
                                .writer
                                .add_schema(name, encoding, schema)
                                .map_err(mcap_err)?,
                            None => 0,
                        };
                        let id = self
                            .writer
                            .add_channel(schema_id, &ch.topic, &ch.message_encoding, &ch.metadata)
                            .map_err(mcap_err)?;
                        self.view_channels.insert(ch.id, id);
                        id
                    }
                };
                self.writer
                    .write_to_known_channel(
                        &mcap::records::MessageHeader {
                            channel_id,
                            ..*header
                        },
                        data,
                    )
                    .map_err(mcap_err)?;
                self.copied += 1;
                let state = match ch.topic.as_str() {
                    TOPIC_EPISODE_START => {
                        let m = EpisodeStartMsg::decode(data)
                            .map_err(|e| bad_input(format!("{TOPIC_EPISODE_START}: {e}")))?;
                        self.geometry
                            .place_balls(self.data, &m.balls)
                            .map_err(|e| bad_input(format!("{TOPIC_EPISODE_START}: {e}")))?;
                        Some((m.qpos, m.labels, true))
                    }
                    TOPIC_STEP => {
                        let m = StepMsg::decode(data)
                            .map_err(|e| bad_input(format!("{TOPIC_STEP}: {e}")))?;
                        Some((m.qpos, m.labels, false))
                    }
                    _ => None,
                };
                if let Some((qpos, labels, start)) = state {
                    self.scene(&qpos, labels, start, header.log_time)
                        .map_err(|e| {
                            bad_input(format!("state at log time {}: {e}", header.log_time))
                        })?;
                }
            }
            _ => {}
        }
        Ok(())
    }

    /// Writes the `/scene` and `/tf` messages of one logged state.
    fn scene(
        &mut self,
        qpos: &[f64],
        labels: u32,
        start: bool,
        log_time: u64,
    ) -> Result<(), FrameError> {
        let frame = self
            .geometry
            .frame(self.data, qpos, labels, start, log_time)?;
        for (channel_id, payload) in [
            (self.scene_channel, encoded(&frame.scene)),
            (self.tf_channel, encoded(&frame.transforms)),
        ] {
            self.writer.write_to_known_channel(
                &mcap::records::MessageHeader {
                    channel_id,
                    sequence: self.sequence,
                    log_time,
                    publish_time: log_time,
                },
                &payload,
            )?;
        }
        self.sequence = self.sequence.wrapping_add(1);
        self.scenes += 1;
        Ok(())
    }
}

/// Writes the view into `file` from the records the reader accepts; returns (messages
/// copied, scene states written).
fn write_view(
    bytes: &[u8],
    geometry: &Geometry,
    data: &mut Data,
    file: std::fs::File,
    input: &Path,
    out: &Path,
) -> Result<(u64, u64), SceneError> {
    let bad_output = output_error(out);
    let mcap_err = |e: mcap::McapError| bad_output(e.to_string());
    let mut writer = mcap::WriteOptions::new()
        .compression_threads(0)
        .create(std::io::BufWriter::new(file))
        .map_err(mcap_err)?;
    let scene_channel =
        add_channel::<SceneUpdate, _>(&mut writer, TOPIC_SCENE).map_err(mcap_err)?;
    let tf_channel = add_channel::<FrameTransforms, _>(&mut writer, TOPIC_TF).map_err(mcap_err)?;
    let mut view = ViewWriter {
        writer,
        geometry,
        data,
        scene_channel,
        tf_channel,
        schemas: HashMap::new(),
        channels: HashMap::new(),
        view_channels: HashMap::new(),
        sequence: 0,
        copied: 0,
        scenes: 0,
    };
    // The view's own failure, kept while the reader is told to stop.
    let mut failure = None;
    let read = read_log_records(bytes, input, &mut |record| {
        view.record(record, input).map_err(|e| {
            let problem = e.to_string();
            failure = Some(e);
            LogError::Usage {
                path: out.into(),
                problem,
            }
        })
    });
    if let Some(e) = failure {
        return Err(match e {
            SceneError::Output { problem, .. } => bad_output(problem),
            other => other,
        });
    }
    read?;
    view.writer.finish().map_err(mcap_err)?;
    Ok((view.copied, view.scenes))
}
