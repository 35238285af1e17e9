//! The rollout logger: encodes on the caller's thread, writes MCAP on a background thread.

use super::schema::{
    self, encode_step, sha256_hex, EpisodeEndMsg, EpisodeStartMsg, RunInfo, StepFields,
    CONFIG_TASK_FILE, CONFIG_TASK_LAYOUT, MAX_CHUNK_BYTES, NO_RM, SCHEMA_VERSION,
};
use super::LogError;
use crate::env::layout::TaskLayout;
use crate::env::reacher::ReacherDelivery;
use crate::env::scene_files::{SceneFile, SceneFileKind};
use crate::env::EnvStep;
use crate::rm::LabelSet;
use mcap::records::{MessageHeader, Metadata};
use mcap::{Attachment, WriteOptions, Writer};
use std::borrow::Cow;
use std::collections::BTreeMap;
use std::fs::File;
use std::path::{Path, PathBuf};
use std::sync::mpsc::{self, Receiver, Sender, SyncSender};
use std::sync::Arc;
use std::thread::JoinHandle;

/// How much and how to log.
#[derive(Clone, Debug, PartialEq)]
pub struct LogOptions {
    /// Log every n-th episode (1 = all; episodes are numbered from 0, episode 0 is logged).
    pub every_nth_episode: u64,
    /// Store the observation with every step (~64 more bytes a step for ReacherDelivery).
    pub observations: bool,
    /// Uncompressed bytes per MCAP chunk: the most a crash can lose, and the compression
    /// window.
    pub chunk_size: u64,
    /// zstd level (1–19; 0 = zstd's default, 3).
    pub compression_level: u32,
    /// Encoded bytes collected before handing a batch to the writer thread.
    pub batch_bytes: usize,
    /// Batches that may wait for the writer thread before `step` blocks.
    pub queue_batches: usize,
}

impl Default for LogOptions {
    fn default() -> LogOptions {
        LogOptions {
            every_nth_episode: 1,
            observations: false,
            chunk_size: 1 << 20,
            compression_level: 0,
            batch_bytes: 64 << 10,
            queue_batches: 32,
        }
    }
}

/// What a run is: everything in the `/run` record that the caller knows (the logger adds
/// versions, git commit and the XML hash).
#[derive(Clone, Debug, PartialEq)]
pub struct RunHeader {
    pub env: String,
    pub task: String,
    pub seed: u64,
    pub vocabulary: String,
    pub obs_dim: u32,
    pub act_dim: u32,
    pub step_duration_ns: u64,
    pub model_xml_name: String,
    /// The model XML text (attached to the file; replay loads it).
    pub model_xml: String,
    /// The files the scene reads besides its own text (each attached to the file; replay
    /// compiles the scene with them).
    pub scene_files: Arc<[SceneFile]>,
    pub config: serde_json::Value,
    pub reward_machine: Option<String>,
}

impl RunHeader {
    /// The header of a ReacherDelivery run of a task: its layout, its task file's text
    /// (recorded in the config under [`CONFIG_TASK_LAYOUT`] and [`CONFIG_TASK_FILE`]), its
    /// scene's XML and the files the scene reads (attached).
    pub fn reacher(
        task: &str,
        layout: &TaskLayout,
        task_file: &str,
        scene_xml: &str,
        scene_files: Arc<[SceneFile]>,
        seed: u64,
        mut config: serde_json::Value,
    ) -> RunHeader {
        if let Some(map) = config.as_object_mut() {
            map.insert(
                CONFIG_TASK_LAYOUT.into(),
                serde_json::to_value(layout).unwrap_or_default(),
            );
            map.insert(CONFIG_TASK_FILE.into(), task_file.into());
        }
        RunHeader {
            env: "ReacherDelivery".into(),
            task: task.into(),
            seed,
            vocabulary: layout.letters(),
            obs_dim: layout.obs_dim() as u32,
            act_dim: crate::env::reacher::ACT_DIM as u32,
            step_duration_ns: 20_000_000,
            model_xml_name: layout.scene.to_string(),
            model_xml: scene_xml.into(),
            scene_files,
            config,
            reward_machine: None,
        }
    }

    /// [`RunHeader::reacher`] of a loaded task, named as records name it (`id`).
    pub fn of_task(
        id: &str,
        task: &crate::env::task_file::Task,
        seed: u64,
        config: serde_json::Value,
    ) -> RunHeader {
        RunHeader::reacher(
            id,
            &task.layout(),
            &task.text,
            &task.scene_xml,
            task.scene_files.clone(),
            seed,
            config,
        )
    }
}

/// One step as the training code has it.
#[derive(Clone, Copy, Debug)]
pub struct StepRecord<'a> {
    pub action: &'a [f32],
    /// The environment's reward.
    pub reward: f64,
    pub labels: LabelSet,
    /// RM state after the step and the RM's reward for it, when a machine is used.
    pub rm: Option<(usize, f64)>,
    pub qpos: &'a [f64],
    pub qvel: &'a [f64],
    /// The observation after the step (stored only with [`LogOptions::observations`]).
    pub obs: &'a [f32],
    pub terminated: bool,
    pub truncated: bool,
}

/// The start of an episode as the training code has it.
#[derive(Clone, Copy, Debug)]
pub struct EpisodeStartRecord<'a> {
    pub seed: u64,
    pub phase: &'a str,
    pub qpos: &'a [f64],
    pub qvel: &'a [f64],
    pub balls: &'a [f64],
    /// Each event's step this episode, in label-bit order.
    pub event_steps: &'a [Option<usize>],
    pub labels: LabelSet,
    pub rm_state: Option<usize>,
    pub obs: &'a [f32],
}

/// What was written.
#[derive(Clone, Debug, PartialEq)]
pub struct LogSummary {
    pub path: PathBuf,
    pub episodes_logged: u64,
    pub steps_logged: u64,
    pub bytes: u64,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Topic {
    EpisodeStart = 0,
    Step = 1,
    EpisodeEnd = 2,
}

/// Encoded messages travelling to the writer thread.
#[derive(Default)]
struct Batch {
    data: Vec<u8>,
    /// (topic, log time, end offset in `data`)
    items: Vec<(Topic, u64, usize)>,
}

/// State of the episode being logged.
struct Episode {
    id: u64,
    seed: u64,
    phase: String,
    steps: u32,
    env_return: f64,
    rm_return: f64,
    rm_state: i64,
}

/// Writes rollouts to an MCAP file. See the module docs of [`crate::log`].
pub struct RolloutLogger {
    path: PathBuf,
    options: LogOptions,
    vocabulary: Vec<char>,
    label_text: String,
    batch: Batch,
    to_writer: Option<SyncSender<Batch>>,
    recycled: Receiver<Batch>,
    thread: Option<JoinHandle<Result<u64, LogError>>>,
    next_episode: u64,
    current: Option<Episode>,
    time_ns: u64,
    step_ns: u64,
    episodes_logged: u64,
    steps_logged: u64,
}

fn part_path(path: &Path) -> PathBuf {
    let mut name = path.as_os_str().to_owned();
    name.push(".part");
    PathBuf::from(name)
}

impl RolloutLogger {
    /// Starts a log at `path` (written as `path.part` until finished).
    pub fn create(
        path: &Path,
        header: RunHeader,
        options: LogOptions,
    ) -> Result<RolloutLogger, LogError> {
        check_options(path, &options)?;
        let part = part_path(path);
        let mcap_err = |source| LogError::Mcap {
            path: part.clone(),
            source,
        };
        let file = File::create(&part).map_err(|source| LogError::Io {
            path: part.clone(),
            source,
        })?;
        let run = run_info(&header, &options);
        // Chunks are built in memory and written whole (disable_seeking), so the file on disk
        // always ends at a record boundary unless the process dies inside a write call.
        let mut w = WriteOptions::new()
            .compression_threads(0)
            .compression_level(options.compression_level)
            .chunk_size(Some(options.chunk_size))
            .disable_seeking(true)
            .profile("")
            .create(file)
            .map_err(mcap_err)?;
        write_attachments(&mut w, &header).map_err(mcap_err)?;
        write_run_metadata(&mut w, &run).map_err(mcap_err)?;
        let (run_channel, channels) = add_channels(&mut w).map_err(mcap_err)?;
        let run_json = serde_json::to_vec(&run).map_err(|e| LogError::Usage {
            path: path.into(),
            problem: format!("cannot serialise the run record: {e}"),
        })?;
        w.write_to_known_channel(
            &MessageHeader {
                channel_id: run_channel,
                sequence: 0,
                log_time: 0,
                publish_time: 0,
            },
            &run_json,
        )
        .map_err(mcap_err)?;
        // Put the run record on disk now: a run that dies early still names itself.
        w.flush().map_err(mcap_err)?;

        let (to_writer, from_logger) = mpsc::sync_channel::<Batch>(options.queue_batches.max(1));
        let (recycle, recycled) = mpsc::channel::<Batch>();
        let final_path = path.to_path_buf();
        let thread = std::thread::Builder::new()
            .name("mcap-writer".into())
            .spawn(move || writer_thread(w, channels, from_logger, recycle, part, final_path))
            .map_err(|source| LogError::Io {
                path: path.into(),
                source,
            })?;
        Ok(RolloutLogger {
            path: path.to_path_buf(),
            vocabulary: header.vocabulary.chars().collect(),
            label_text: String::new(),
            batch: Batch::default(),
            to_writer: Some(to_writer),
            recycled,
            thread: Some(thread),
            next_episode: 0,
            current: None,
            time_ns: 0,
            step_ns: header.step_duration_ns,
            episodes_logged: 0,
            steps_logged: 0,
            options,
        })
    }

    /// The final path of the log.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Starts the next episode; returns whether it is logged (episodes not sampled by
    /// `every_nth_episode` are counted but not written, and their steps are ignored).
    pub fn begin_episode(&mut self, start: &EpisodeStartRecord) -> Result<bool, LogError> {
        let id = self.next_episode;
        self.next_episode += 1;
        if !id.is_multiple_of(self.options.every_nth_episode) {
            self.current = None;
            return Ok(false);
        }
        let rm_state = start.rm_state.map_or(NO_RM, |u| u as i64);
        let msg = EpisodeStartMsg {
            episode: id,
            seed: start.seed,
            phase: start.phase.into(),
            qpos: start.qpos.to_vec(),
            qvel: start.qvel.to_vec(),
            balls: start.balls.to_vec(),
            cancel_step: 0,
            labels: start.labels.0,
            rm_state,
            obs: if self.options.observations {
                start.obs.to_vec()
            } else {
                vec![]
            },
            event_steps: Vec::new(),
        }
        .with_event_steps(start.event_steps);
        msg.encode(&mut self.batch.data);
        self.batch
            .items
            .push((Topic::EpisodeStart, self.time_ns, self.batch.data.len()));
        self.current = Some(Episode {
            id,
            seed: start.seed,
            phase: start.phase.into(),
            steps: 0,
            env_return: 0.0,
            rm_return: 0.0,
            rm_state,
        });
        self.episodes_logged += 1;
        Ok(true)
    }

    /// Logs one step of the current episode (a no-op for an episode not sampled).
    #[inline]
    pub fn step(&mut self, s: &StepRecord) -> Result<(), LogError> {
        let Some(ep) = self.current.as_mut() else {
            return Ok(());
        };
        ep.steps += 1;
        ep.env_return += s.reward;
        let (rm_state, rm_reward) = match s.rm {
            Some((u, r)) => (u as i64, r),
            None => (NO_RM, 0.0),
        };
        ep.rm_return += rm_reward;
        ep.rm_state = rm_state;
        self.label_text.clear();
        for (i, &c) in self.vocabulary.iter().enumerate() {
            if s.labels.contains(i) {
                self.label_text.push(c);
            }
        }
        self.time_ns += self.step_ns;
        encode_step(
            &mut self.batch.data,
            &StepFields {
                episode: ep.id,
                step: ep.steps,
                action: s.action,
                reward: s.reward,
                labels: s.labels.0,
                label_text: &self.label_text,
                rm_state,
                rm_reward,
                qpos: s.qpos,
                qvel: s.qvel,
                obs: if self.options.observations {
                    s.obs
                } else {
                    &[]
                },
                terminated: s.terminated,
                truncated: s.truncated,
            },
        );
        self.batch
            .items
            .push((Topic::Step, self.time_ns, self.batch.data.len()));
        self.steps_logged += 1;
        if self.batch.data.len() >= self.options.batch_bytes {
            self.send_batch()?;
        }
        Ok(())
    }

    /// Ends the current episode; `success` says whether the task was completed.
    pub fn end_episode(&mut self, success: bool) -> Result<(), LogError> {
        let Some(ep) = self.current.take() else {
            return Ok(());
        };
        EpisodeEndMsg {
            episode: ep.id,
            seed: ep.seed,
            phase: ep.phase,
            length: ep.steps,
            env_return: ep.env_return,
            rm_return: ep.rm_return,
            success,
            rm_state: ep.rm_state,
        }
        .encode(&mut self.batch.data);
        self.batch
            .items
            .push((Topic::EpisodeEnd, self.time_ns, self.batch.data.len()));
        // The next episode starts one step later on the log's clock.
        self.time_ns += self.step_ns;
        Ok(())
    }

    /// Starts an episode of a ReacherDelivery environment that was just reset with `seed`.
    pub fn begin_reacher_episode(
        &mut self,
        env: &ReacherDelivery,
        seed: u64,
        phase: &str,
        rm_state: Option<usize>,
        obs: &[f32],
    ) -> Result<bool, LogError> {
        let flat: Vec<f64> = env.positions().iter().flatten().copied().collect();
        self.begin_episode(&EpisodeStartRecord {
            seed,
            phase,
            qpos: env.qpos(),
            qvel: env.qvel(),
            balls: &flat,
            event_steps: env.event_steps(),
            labels: env.labels(),
            rm_state,
            obs,
        })
    }

    /// Logs a ReacherDelivery step (state read from `env` after the step).
    #[inline]
    pub fn reacher_step(
        &mut self,
        env: &ReacherDelivery,
        action: &[f32],
        step: &EnvStep,
        rm: Option<(usize, f64)>,
        obs: &[f32],
    ) -> Result<(), LogError> {
        self.step(&StepRecord {
            action,
            reward: step.reward,
            labels: step.labels,
            rm,
            qpos: env.qpos(),
            qvel: env.qvel(),
            obs,
            terminated: step.terminated,
            truncated: step.truncated,
        })
    }

    fn send_batch(&mut self) -> Result<(), LogError> {
        if self.batch.items.is_empty() {
            return Ok(());
        }
        let fresh = self.recycled.try_recv().unwrap_or_default();
        let full = std::mem::replace(&mut self.batch, fresh);
        let sent = match &self.to_writer {
            Some(tx) => tx.send(full).is_ok(),
            None => false,
        };
        if sent {
            Ok(())
        } else {
            // The writer thread stopped: its result says why.
            Err(self
                .join()
                .err()
                .unwrap_or_else(|| LogError::WriterStopped {
                    path: self.path.clone(),
                    problem: "it exited early".into(),
                }))
        }
    }

    fn join(&mut self) -> Result<u64, LogError> {
        self.to_writer = None;
        match self.thread.take() {
            Some(t) => t.join().unwrap_or_else(|_| {
                Err(LogError::WriterStopped {
                    path: self.path.clone(),
                    problem: "it panicked".into(),
                })
            }),
            None => Err(LogError::WriterStopped {
                path: self.path.clone(),
                problem: "already stopped".into(),
            }),
        }
    }

    /// Writes what is pending, finishes the MCAP file (summary, footer) and renames it into
    /// place. An episode still open is ended with `success = false`.
    pub fn finish(mut self) -> Result<LogSummary, LogError> {
        self.finish_inner()
    }

    fn finish_inner(&mut self) -> Result<LogSummary, LogError> {
        if self.current.is_some() {
            self.end_episode(false)?;
        }
        self.send_batch()?;
        let bytes = self.join()?;
        Ok(LogSummary {
            path: self.path.clone(),
            episodes_logged: self.episodes_logged,
            steps_logged: self.steps_logged,
            bytes,
        })
    }
}

impl Drop for RolloutLogger {
    fn drop(&mut self) {
        if self.thread.is_some() {
            if let Err(e) = self.finish_inner() {
                eprintln!("warning: finishing rollout log on drop failed: {e}");
            }
        }
    }
}

/// The options' limits, checked before the file is created.
fn check_options(path: &Path, options: &LogOptions) -> Result<(), LogError> {
    if options.every_nth_episode == 0 {
        return Err(LogError::Usage {
            path: path.into(),
            problem: "every_nth_episode must be at least 1".into(),
        });
    }
    if options.chunk_size == 0 || options.chunk_size > MAX_CHUNK_BYTES / 2 {
        return Err(LogError::Usage {
            path: path.into(),
            problem: format!(
                "chunk_size {} must be between 1 and {} bytes",
                options.chunk_size,
                MAX_CHUNK_BYTES / 2
            ),
        });
    }
    Ok(())
}

/// The run record (`/run`) of a log with `header` and `options`.
fn run_info(header: &RunHeader, options: &LogOptions) -> RunInfo {
    RunInfo {
        schema_version: SCHEMA_VERSION,
        env: header.env.clone(),
        task: header.task.clone(),
        seed: header.seed,
        vocabulary: header.vocabulary.clone(),
        obs_dim: header.obs_dim,
        act_dim: header.act_dim,
        step_duration_ns: header.step_duration_ns,
        model_xml_name: header.model_xml_name.clone(),
        model_xml_sha256: sha256_hex(&header.model_xml),
        crate_version: env!("CARGO_PKG_VERSION").into(),
        git_commit: crate::GIT_COMMIT.into(),
        mujoco_version: crate::mujoco::version_string(),
        config: header.config.clone(),
        reward_machine: header.reward_machine.clone(),
        every_nth_episode: options.every_nth_episode,
        observations: options.observations,
    }
}

/// The attachments: the scene's XML, each file it reads, the config as JSON.
fn write_attachments(w: &mut Writer<File>, header: &RunHeader) -> Result<(), mcap::McapError> {
    let config_text = serde_json::to_string_pretty(&header.config).unwrap_or_default();
    w.attach(&Attachment {
        log_time: 0,
        create_time: 0,
        name: schema::ATTACHMENT_MODEL_XML.into(),
        media_type: "application/xml".into(),
        data: Cow::Borrowed(header.model_xml.as_bytes()),
    })?;
    for file in header.scene_files.iter() {
        w.attach(&Attachment {
            log_time: 0,
            create_time: 0,
            name: schema::scene_file_attachment(file),
            media_type: match file.kind {
                SceneFileKind::Include => "application/xml",
                SceneFileKind::Asset => "application/octet-stream",
            }
            .into(),
            data: Cow::Borrowed(&file.bytes),
        })?;
    }
    w.attach(&Attachment {
        log_time: 0,
        create_time: 0,
        name: schema::ATTACHMENT_CONFIG.into(),
        media_type: "application/json".into(),
        data: Cow::Borrowed(config_text.as_bytes()),
    })
}

/// The run's metadata record, which readers show without parsing `/run`.
fn write_run_metadata(w: &mut Writer<File>, run: &RunInfo) -> Result<(), mcap::McapError> {
    let metadata: BTreeMap<String, String> = [
        ("schema_version", SCHEMA_VERSION.to_string()),
        ("env", run.env.clone()),
        ("task", run.task.clone()),
        ("seed", run.seed.to_string()),
        ("model_xml_sha256", run.model_xml_sha256.clone()),
        ("crate_version", run.crate_version.clone()),
        ("git_commit", run.git_commit.clone()),
        ("mujoco_version", run.mujoco_version.clone()),
    ]
    .into_iter()
    .map(|(k, v)| (k.to_string(), v))
    .collect();
    w.write_metadata(&Metadata {
        name: schema::METADATA_RUN.into(),
        metadata,
    })
}

/// The schemas and channels: `/run` (JSON), then episode start, step and episode end
/// (protobuf). Returns the run channel and the other three, in that order.
fn add_channels(w: &mut Writer<File>) -> Result<(u16, [u16; 3]), mcap::McapError> {
    let version_meta: BTreeMap<String, String> = [(
        schema::CHANNEL_VERSION_KEY.to_string(),
        SCHEMA_VERSION.to_string(),
    )]
    .into();
    let run_schema = w.add_schema(
        schema::RUN_SCHEMA_NAME,
        "jsonschema",
        schema::run_json_schema().as_bytes(),
    )?;
    let run_channel = w.add_channel(run_schema, schema::TOPIC_RUN, "json", &version_meta)?;
    let mut channels = [0u16; 3];
    for (slot, (name, spec, topic)) in [
        (
            schema::EPISODE_START_SCHEMA_NAME,
            schema::EPISODE_START_SPEC,
            schema::TOPIC_EPISODE_START,
        ),
        (
            schema::STEP_SCHEMA_NAME,
            schema::STEP_SPEC,
            schema::TOPIC_STEP,
        ),
        (
            schema::EPISODE_END_SCHEMA_NAME,
            schema::EPISODE_END_SPEC,
            schema::TOPIC_EPISODE_END,
        ),
    ]
    .into_iter()
    .enumerate()
    {
        let id = w.add_schema(name, "protobuf", &schema::descriptor(spec))?;
        channels[slot] = w.add_channel(id, topic, "protobuf", &version_meta)?;
    }
    Ok((run_channel, channels))
}

/// The background writer: MCAP framing, zstd, file writes; at the end the summary and the
/// rename. Returns the file size.
fn writer_thread(
    mut w: Writer<File>,
    channels: [u16; 3],
    batches: Receiver<Batch>,
    recycle: Sender<Batch>,
    part: PathBuf,
    final_path: PathBuf,
) -> Result<u64, LogError> {
    let mcap_err = |source| LogError::Mcap {
        path: part.clone(),
        source,
    };
    let mut sequence = [0u32; 3];
    for mut batch in batches {
        let mut start = 0;
        for &(topic, log_time, end) in &batch.items {
            let t = topic as usize;
            sequence[t] = sequence[t].wrapping_add(1);
            w.write_to_known_channel(
                &MessageHeader {
                    channel_id: channels[t],
                    sequence: sequence[t],
                    log_time,
                    publish_time: log_time,
                },
                &batch.data[start..end],
            )
            .map_err(mcap_err)?;
            start = end;
        }
        batch.data.clear();
        batch.items.clear();
        // The logger may have gone; then the batch is simply dropped.
        let _ = recycle.send(batch);
    }
    w.finish().map_err(mcap_err)?;
    let file = w.into_inner();
    let io_err = |source| LogError::Io {
        path: part.clone(),
        source,
    };
    file.sync_all().map_err(io_err)?;
    let bytes = file.metadata().map_err(io_err)?.len();
    drop(file);
    std::fs::rename(&part, &final_path).map_err(|source| LogError::Io {
        path: final_path.clone(),
        source,
    })?;
    Ok(bytes)
}
