//! Reading rollout logs, including files cut short by a crash.

use super::schema::{self, EpisodeEndMsg, EpisodeStartMsg, RunInfo, StepMsg, SCHEMA_VERSION};
use super::LogError;
use crate::env::scene_files::{
    compile_alone, compile_in_memory, SceneCompileError, SceneFile, SceneFileKind, MAX_ASSET_BYTES,
    MAX_ASSET_FILES, MAX_INCLUDED_BYTES, MAX_INCLUDED_FILES,
};
use crate::env::scene_xml::MAX_SCENE_BYTES;
use crate::mujoco::Model;
use mcap::records::{op, Record};
use mcap::sans_io::{LinearReadEvent, LinearReader as SansReader, LinearReaderOptions};
use mcap::McapError;
use std::collections::HashMap;
use std::fmt;
use std::path::{Path, PathBuf};

pub use super::schema::MAX_CHUNK_BYTES;

/// Largest memory the decoded episodes of one log may take (estimated per message): 1 GiB,
/// ~4 million steps, above the ~3 million (~80 bytes each) a log of [`MAX_LOG_FILE_BYTES`]
/// holds. A compressed chunk can
/// expand a thousandfold, so the file's size alone does not bound what it decodes to.
pub const MAX_DECODED_BYTES: u64 = 1 << 30;

/// One logged episode.
#[derive(Clone, Debug, PartialEq)]
pub struct LoggedEpisode {
    pub start: EpisodeStartMsg,
    pub steps: Vec<StepMsg>,
    /// `None` when the file ends before the episode did.
    pub end: Option<EpisodeEndMsg>,
}

impl LoggedEpisode {
    pub fn is_complete(&self) -> bool {
        self.end.is_some()
    }
}

/// How much of a file cut short was read.
#[derive(Clone, Debug, PartialEq)]
pub struct Recovery {
    pub file_bytes: u64,
    /// Complete chunks read.
    pub chunks: usize,
    pub messages: u64,
    pub complete_episodes: usize,
    /// Steps of a last, unfinished episode (0 if none).
    pub partial_steps: usize,
    /// Why reading stopped.
    pub stopped_by: String,
}

impl fmt::Display for Recovery {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "file is incomplete ({}); recovered {} messages from {} complete chunks of {} bytes: \
             {} complete episodes",
            self.stopped_by, self.messages, self.chunks, self.file_bytes, self.complete_episodes
        )?;
        if self.partial_steps > 0 {
            write!(f, " and {} steps of an unfinished one", self.partial_steps)?;
        }
        Ok(())
    }
}

/// A rollout log read into memory.
#[derive(Clone, Debug)]
pub struct RolloutLog {
    pub path: PathBuf,
    pub run: RunInfo,
    /// The attached model XML (`None` if the attachment is missing).
    pub model_xml: Option<String>,
    /// The attached files the scene reads besides its own text, in file order (none in a log
    /// of a scene that reads no other file, and in logs written before logs carried them).
    pub scene_files: Vec<SceneFile>,
    /// The attached run config text.
    pub config_json: Option<String>,
    /// The `smirl.run` metadata record.
    pub metadata: HashMap<String, String>,
    pub episodes: Vec<LoggedEpisode>,
    pub chunks: usize,
    pub messages: u64,
    /// Set when the file was cut short (no footer): what was recovered.
    pub recovery: Option<Recovery>,
}

impl RolloutLog {
    pub fn steps(&self) -> usize {
        self.episodes.iter().map(|e| e.steps.len()).sum()
    }

    /// The model XML of a ReacherDelivery log (what replay, render and the Foxglove view
    /// simulate): the one attached to the file, else the shipped model
    /// ([`crate::assets::REACHER_MODELS`]) whose hash the run record names; the message says
    /// why there is none.
    pub fn reacher_model_xml(&self) -> Result<&str, String> {
        if self.run.env != "ReacherDelivery" {
            return Err(format!(
                "environment {} is not ReacherDelivery",
                self.run.env
            ));
        }
        if let Some(xml) = &self.model_xml {
            return Ok(xml);
        }
        crate::assets::REACHER_MODELS
            .iter()
            .find(|(_, xml)| schema::sha256_hex(xml) == self.run.model_xml_sha256)
            .map(|(_, xml)| *xml)
            .ok_or_else(|| {
                "the file has no model.xml attachment and its run record names no shipped model"
                    .to_string()
            })
    }

    /// The compiled model of a ReacherDelivery log's scene, from the log alone: its
    /// [`Self::reacher_model_xml`] with the scene files it carries, each found by the name the
    /// scene gives it, whether or not the original files still exist. Without scene files the
    /// text is compiled alone. Either way the text and the files it includes
    /// are walked first by a task's rules, so that a crafted log naming a file MuJoCo 2.2.2
    /// aborts the process on is an error naming the log and the file.
    pub fn reacher_model(&self) -> Result<Model, LogModelError> {
        let xml = self.reacher_model_xml().map_err(LogModelError::Missing)?;
        let source = format!("{}:{}", self.path.display(), schema::ATTACHMENT_MODEL_XML);
        Ok(if self.scene_files.is_empty() {
            compile_alone(xml, &source)?
        } else {
            compile_in_memory(xml, &self.scene_files, &source)?
        })
    }
}

/// Why a log's scene cannot be compiled.
#[derive(Debug, thiserror::Error)]
pub enum LogModelError {
    /// The log has no scene to compile (see [`RolloutLog::reacher_model_xml`]).
    #[error("{0}")]
    Missing(String),
    #[error(transparent)]
    Compile(#[from] SceneCompileError),
}

/// Largest log file read: 256 MiB (a job's log, ~40 000 steps, is ~3 MB).
pub const MAX_LOG_FILE_BYTES: u64 = 256 << 20;

/// Most bytes of a scene a log carries, and the most a task's scene holds: its text
/// ([`MAX_SCENE_BYTES`]), its included files ([`MAX_INCLUDED_BYTES`]) and its mesh, skin,
/// height-field and texture files ([`MAX_ASSET_BYTES`]) together, 144 MiB. The reader takes
/// each attachment within the task's limit of its kind.
pub const MAX_LOGGED_SCENE_BYTES: u64 = MAX_SCENE_BYTES + MAX_INCLUDED_BYTES + MAX_ASSET_BYTES;

/// What a log of [`MAX_LOG_FILE_BYTES`] keeps for its records and episodes beside the largest
/// scene a task accepts: 96 MiB, about 1.2 million steps (a job's log is ~3 MB, a `reacher
/// demo` of 10 000 episodes of 100 steps ~80 MB).
const MIN_LOG_ROOM_BYTES: u64 = 96 << 20;

// A task's scene fits in a log the reader reads, with room for its episodes: checked when the
// crate compiles, so that a limit raised on one side alone fails the build rather than
// leaving a task whose logs cannot be read.
const _: () = assert!(MAX_LOGGED_SCENE_BYTES + MIN_LOG_ROOM_BYTES <= MAX_LOG_FILE_BYTES);

/// Reads a rollout log of at most [`MAX_LOG_FILE_BYTES`]. A truncated file is read up to its
/// last complete chunk (see [`RolloutLog::recovery`]); a non-MCAP, corrupt or foreign file,
/// one that decodes past [`MAX_DECODED_BYTES`], or one with another schema version, is an
/// error naming the file.
pub fn read_log(path: &Path) -> Result<RolloutLog, LogError> {
    let bytes = read_log_file(path)?;
    read_log_bytes(&bytes, path)
}

/// The bytes of the log file at `path`, at most [`MAX_LOG_FILE_BYTES`].
pub fn read_log_file(path: &Path) -> Result<Vec<u8>, LogError> {
    crate::input_file::read_bytes(path, MAX_LOG_FILE_BYTES).map_err(|source| LogError::Io {
        path: path.into(),
        source,
    })
}

#[derive(Clone, Copy, PartialEq, Eq)]
enum Kind {
    Run,
    Start,
    Step,
    End,
    Other,
}

/// Errors that mean "the file stops here" rather than "the file is damaged".
fn is_truncation(e: &McapError) -> bool {
    matches!(
        e,
        McapError::UnexpectedEof
            | McapError::RecordTooLarge { .. }
            | McapError::BadChunkLength { .. }
            | McapError::BadAttachmentLength { .. }
    )
}

/// What [`read_log_records`] hands each accepted record to.
pub type RecordSink<'s> = dyn FnMut(&Record) -> Result<(), LogError> + 's;

struct Reading<'p> {
    path: &'p Path,
    /// Sees every record the reading accepts, in file order.
    accept: &'p mut RecordSink<'p>,
    schemas: HashMap<u16, (String, String)>,
    channels: HashMap<u16, Kind>,
    run: Option<RunInfo>,
    model_xml: Option<String>,
    scene_files: Vec<SceneFile>,
    config_json: Option<String>,
    metadata: HashMap<String, String>,
    episodes: Vec<LoggedEpisode>,
    messages: u64,
    /// (messages, chunks) of the summary's statistics record, when the file has one.
    statistics: Option<(u64, u32)>,
    /// Estimated memory of the decoded episodes so far (limit [`MAX_DECODED_BYTES`]).
    decoded_bytes: u64,
}

impl Reading<'_> {
    fn corrupt(&self, problem: String) -> LogError {
        LogError::Corrupt {
            path: self.path.into(),
            problem,
        }
    }

    fn record(&mut self, record: Record) -> Result<(), LogError> {
        (self.accept)(&record)?;
        match record {
            Record::Schema { header, data } => {
                if header.name.starts_with("smirl.") && !header.name.starts_with("smirl.v1.") {
                    let found = header.name.split('.').nth(1).unwrap_or("?").to_string();
                    return Err(LogError::UnknownSchemaVersion {
                        path: self.path.into(),
                        found: format!("{found} (schema {})", header.name),
                        supported: SCHEMA_VERSION,
                    });
                }
                let _ = data;
                self.schemas
                    .insert(header.id, (header.name, header.encoding));
            }
            Record::Channel(ch) => {
                if let Some(v) = ch.metadata.get(schema::CHANNEL_VERSION_KEY) {
                    if v != &SCHEMA_VERSION.to_string() {
                        return Err(LogError::UnknownSchemaVersion {
                            path: self.path.into(),
                            found: v.clone(),
                            supported: SCHEMA_VERSION,
                        });
                    }
                }
                let schema_name = self.schemas.get(&ch.schema_id).map(|s| s.0.as_str());
                let kind = match (ch.topic.as_str(), schema_name) {
                    (schema::TOPIC_RUN, Some(schema::RUN_SCHEMA_NAME)) => Kind::Run,
                    (schema::TOPIC_EPISODE_START, Some(schema::EPISODE_START_SCHEMA_NAME)) => {
                        Kind::Start
                    }
                    (schema::TOPIC_STEP, Some(schema::STEP_SCHEMA_NAME)) => Kind::Step,
                    (schema::TOPIC_EPISODE_END, Some(schema::EPISODE_END_SCHEMA_NAME)) => Kind::End,
                    _ => Kind::Other,
                };
                self.channels.insert(ch.id, kind);
            }
            Record::Message { header, data } => {
                self.messages += 1;
                let kind = *self.channels.get(&header.channel_id).ok_or_else(|| {
                    self.corrupt(format!(
                        "message on channel {} before its channel record",
                        header.channel_id
                    ))
                })?;
                self.message(kind, &data)?;
            }
            Record::Attachment { header, data, .. } => {
                let text = || String::from_utf8_lossy(&data).into_owned();
                match header.name.as_str() {
                    schema::ATTACHMENT_MODEL_XML => {
                        // model.xml is a task's scene text, which a task reads up to this limit.
                        if data.len() as u64 > MAX_SCENE_BYTES {
                            return Err(LogError::TooLarge {
                                path: self.path.into(),
                                problem: format!(
                                    "attachment {}: {} bytes, more than the limit of \
                                     {MAX_SCENE_BYTES} for a scene file",
                                    header.name,
                                    data.len()
                                ),
                            });
                        }
                        self.model_xml = Some(text())
                    }
                    schema::ATTACHMENT_CONFIG => self.config_json = Some(text()),
                    name => {
                        if let Some((kind, file)) = schema::scene_file_of_attachment(name) {
                            self.scene_file(name, kind, file, &data)?;
                        }
                    }
                }
            }
            Record::Statistics(st) => {
                self.statistics = Some((st.message_count, st.chunk_count));
            }
            Record::Metadata(m) if m.name == schema::METADATA_RUN => {
                if let Some(v) = m.metadata.get("schema_version") {
                    if v != &SCHEMA_VERSION.to_string() {
                        return Err(LogError::UnknownSchemaVersion {
                            path: self.path.into(),
                            found: v.clone(),
                            supported: SCHEMA_VERSION,
                        });
                    }
                }
                self.metadata = m.metadata.into_iter().collect();
            }
            _ => {}
        }
        Ok(())
    }

    fn message(&mut self, kind: Kind, data: &[u8]) -> Result<(), LogError> {
        match kind {
            Kind::Run => {
                let value: serde_json::Value = serde_json::from_slice(data)
                    .map_err(|e| self.corrupt(format!("/run record is not JSON: {e}")))?;
                let version = value.get("schema_version").cloned();
                if version != Some(serde_json::json!(SCHEMA_VERSION)) {
                    return Err(LogError::UnknownSchemaVersion {
                        path: self.path.into(),
                        found: version.map_or("none".into(), |v| v.to_string()),
                        supported: SCHEMA_VERSION,
                    });
                }
                let run: RunInfo = serde_json::from_value(value)
                    .map_err(|e| self.corrupt(format!("/run record: {e}")))?;
                self.run = Some(run);
            }
            Kind::Start => {
                let m = EpisodeStartMsg::decode(data)
                    .map_err(|e| self.corrupt(format!("/episode/start message: {e}")))?;
                self.charge(
                    std::mem::size_of::<LoggedEpisode>()
                        + m.phase.len()
                        + 8 * (m.qpos.len() + m.qvel.len() + m.balls.len())
                        + 4 * m.obs.len(),
                )?;
                self.episodes.push(LoggedEpisode {
                    start: m,
                    steps: Vec::new(),
                    end: None,
                });
            }
            Kind::Step => {
                let m = StepMsg::decode(data)
                    .map_err(|e| self.corrupt(format!("/step message: {e}")))?;
                self.charge(
                    std::mem::size_of::<StepMsg>()
                        + 4 * (m.action.len() + m.obs.len())
                        + 8 * (m.qpos.len() + m.qvel.len())
                        + m.label_text.len(),
                )?;
                let ep = self.open_episode(m.episode, "/step")?;
                ep.steps.push(m);
            }
            Kind::End => {
                let m = EpisodeEndMsg::decode(data)
                    .map_err(|e| self.corrupt(format!("/episode/end message: {e}")))?;
                let ep = self.open_episode(m.episode, "/episode/end")?;
                ep.end = Some(m);
            }
            Kind::Other => {}
        }
        Ok(())
    }

    /// Takes a scene file the log carries (in `attachment`), within what a task accepts: at
    /// most [`MAX_INCLUDED_FILES`] included files of [`MAX_SCENE_BYTES`] each and
    /// [`MAX_INCLUDED_BYTES`] together, and [`MAX_ASSET_FILES`] asset files of
    /// [`MAX_ASSET_BYTES`] together.
    fn scene_file(
        &mut self,
        attachment: &str,
        kind: SceneFileKind,
        name: &str,
        data: &[u8],
    ) -> Result<(), LogError> {
        let of_kind = || self.scene_files.iter().filter(|f| f.kind == kind);
        let count = of_kind().count();
        let bytes: u64 = of_kind().map(|f| f.bytes.len() as u64).sum();
        let (what, count_limit, byte_limit) = match kind {
            SceneFileKind::Include => ("included files", MAX_INCLUDED_FILES, MAX_INCLUDED_BYTES),
            SceneFileKind::Asset => (
                "mesh, skin, height-field and texture files",
                MAX_ASSET_FILES,
                MAX_ASSET_BYTES,
            ),
        };
        let too_large = |problem: String| LogError::TooLarge {
            path: self.path.into(),
            problem: format!("attachment {attachment}: {problem}"),
        };
        if count == count_limit {
            return Err(too_large(format!(
                "the scene's {what} number more than the limit of {count_limit}"
            )));
        }
        if kind == SceneFileKind::Include && data.len() as u64 > MAX_SCENE_BYTES {
            return Err(too_large(format!(
                "{} bytes, more than the limit of {MAX_SCENE_BYTES} for a scene file",
                data.len()
            )));
        }
        if bytes + data.len() as u64 > byte_limit {
            return Err(too_large(format!(
                "the scene's {what} hold more than the limit of {byte_limit} bytes together"
            )));
        }
        self.scene_files.push(SceneFile {
            kind,
            name: name.into(),
            bytes: data.to_vec(),
        });
        Ok(())
    }

    /// Counts `bytes` more of decoded episodes against [`MAX_DECODED_BYTES`].
    fn charge(&mut self, bytes: usize) -> Result<(), LogError> {
        self.decoded_bytes += bytes as u64;
        if self.decoded_bytes > MAX_DECODED_BYTES {
            return Err(LogError::TooLarge {
                path: self.path.into(),
                problem: format!(
                    "its episodes decode to more than the limit of {MAX_DECODED_BYTES} bytes \
                     (after {} messages)",
                    self.messages
                ),
            });
        }
        Ok(())
    }

    fn open_episode(&mut self, id: u64, topic: &str) -> Result<&mut LoggedEpisode, LogError> {
        let path = self.path;
        match self.episodes.last_mut() {
            Some(ep) if ep.start.episode == id && ep.end.is_none() => Ok(ep),
            _ => Err(LogError::Corrupt {
                path: path.into(),
                problem: format!("{topic} message of episode {id} outside that episode"),
            }),
        }
    }
}

/// [`read_log`] on bytes already in memory; `path` names them in messages.
pub fn read_log_bytes(bytes: &[u8], path: &Path) -> Result<RolloutLog, LogError> {
    read_log_records(bytes, path, &mut |_| Ok(()))
}

/// [`read_log_bytes`], handing every record it accepts to `accept` in file order: the records
/// of each chunk once the whole chunk has decoded and passed its CRC, never one of a chunk
/// cut short or damaged. A copy made of these records holds exactly what the reader reads
/// (the same episodes, attachments and metadata); an error from `accept` stops the reading.
pub fn read_log_records(
    bytes: &[u8],
    path: &Path,
    accept: &mut RecordSink,
) -> Result<RolloutLog, LogError> {
    if bytes.len() < mcap::MAGIC.len() || &bytes[..mcap::MAGIC.len()] != mcap::MAGIC {
        return Err(LogError::NotMcap {
            path: path.into(),
            problem: "it does not start with the MCAP magic bytes".into(),
        });
    }
    let mut r = Reading {
        path,
        accept,
        schemas: HashMap::new(),
        channels: HashMap::new(),
        run: None,
        model_xml: None,
        scene_files: Vec::new(),
        config_json: None,
        metadata: HashMap::new(),
        episodes: Vec::new(),
        messages: 0,
        statistics: None,
        decoded_bytes: 0,
    };
    let mut chunks = 0;
    let mut footer = false;
    let mut stopped_by = None;
    // Top level: whole records, chunks undecoded (their bodies are decoded below, all or
    // nothing). The length limit keeps a damaged length field from becoming an allocation.
    let mut top = SansReader::new_with_options(
        LinearReaderOptions::default()
            .with_skip_end_magic(true)
            .with_emit_chunks(true)
            .with_validate_data_section_crc(true)
            .with_validate_summary_section_crc(true)
            .with_record_length_limit(MAX_CHUNK_BYTES as usize),
    );
    let mut input = bytes;
    let outcome = drive(&mut top, &mut input, |opcode, data| {
        check_lengths(opcode, data).map_err(|problem| LogError::Corrupt {
            path: path.into(),
            problem: format!("record (opcode {opcode:#04x}): {problem}"),
        })?;
        if opcode == op::CHUNK {
            read_chunk(&mut r, opcode, data, chunks + 1)?;
            chunks += 1;
            return Ok(());
        }
        if opcode == op::FOOTER {
            footer = true;
        }
        let record = mcap::parse_record(opcode, data).map_err(|e| LogError::Corrupt {
            path: path.into(),
            problem: format!("record (opcode {opcode:#04x}) cannot be parsed: {e}"),
        })?;
        r.record(record)
    })?;
    match outcome {
        None => {}
        // A file that ends with a valid footer was written to the end: a record running past
        // it is damage, not truncation.
        Some(e) if is_truncation(&e) && ends_with_footer(bytes) => {
            return Err(LogError::Corrupt {
                path: path.into(),
                problem: format!(
                    "the file ends with its footer (it was finished), but a record's length runs \
                     past the data: {e}"
                ),
            })
        }
        Some(e) if is_truncation(&e) => stopped_by = Some(format!("it ends inside a record: {e}")),
        Some(McapError::BadMagic) => {
            return Err(LogError::NotMcap {
                path: path.into(),
                problem: "bad magic bytes".into(),
            })
        }
        Some(source) => {
            return Err(LogError::Mcap {
                path: path.into(),
                source,
            })
        }
    }
    if r.messages == 0 && r.run.is_none() && r.schemas.is_empty() && stopped_by.is_some() {
        return Err(LogError::NotRolloutLog {
            path: path.into(),
            problem: "nothing readable before the file ends".into(),
        });
    }
    let Some(run) = r.run.take() else {
        return Err(LogError::NotRolloutLog {
            path: path.into(),
            problem: "no /run record".into(),
        });
    };
    if footer {
        if let Some((messages, chunk_count)) = r.statistics {
            if messages != r.messages || chunk_count as usize != chunks {
                return Err(LogError::Corrupt {
                    path: path.into(),
                    problem: format!(
                        "the summary counts {messages} messages in {chunk_count} chunks, the data \
                         holds {} in {chunks}",
                        r.messages
                    ),
                });
            }
        }
    } else if ends_with_footer(bytes) {
        return Err(LogError::Corrupt {
            path: path.into(),
            problem: "the file ends with a footer that the records before it do not reach".into(),
        });
    }
    // One end-of-file rule: a log is complete only when the footer the records reach is
    // followed by the closing magic bytes and nothing else; part of the magic (or none) is a
    // file cut short, anything else (more records: a damaged opcode made a footer of one)
    // is damage.
    if footer && stopped_by.is_none() {
        let magic = mcap::MAGIC.len();
        if input.len() > magic || input != &mcap::MAGIC[..input.len()] {
            return Err(LogError::Corrupt {
                path: path.into(),
                problem: format!(
                    "a footer record ends the data {} bytes before the end of the file",
                    input.len()
                ),
            });
        }
        if input.len() < magic {
            stopped_by = Some("it ends before its closing magic bytes".into());
        }
    }
    let recovery = if footer && stopped_by.is_none() {
        None
    } else {
        let partial_steps = r
            .episodes
            .last()
            .filter(|e| !e.is_complete())
            .map_or(0, |e| e.steps.len());
        Some(Recovery {
            file_bytes: bytes.len() as u64,
            chunks,
            messages: r.messages,
            complete_episodes: r.episodes.iter().filter(|e| e.is_complete()).count(),
            partial_steps,
            stopped_by: stopped_by.unwrap_or_else(|| "no footer".into()),
        })
    };
    Ok(RolloutLog {
        path: path.into(),
        run,
        model_xml: r.model_xml,
        scene_files: r.scene_files,
        config_json: r.config_json,
        metadata: r.metadata,
        episodes: r.episodes,
        chunks,
        messages: r.messages,
        recovery,
    })
}

/// Feeds `input` to a sans-io reader, handing each record to `f`. Returns the reader's error
/// (the caller decides whether it means truncation or damage), `None` at a clean end.
fn drive(
    reader: &mut SansReader,
    input: &mut &[u8],
    mut f: impl FnMut(u8, &[u8]) -> Result<(), LogError>,
) -> Result<Option<McapError>, LogError> {
    while let Some(event) = reader.next_event() {
        match event {
            Ok(LinearReadEvent::ReadRequest(need)) => {
                let n = need.min(input.len());
                reader.insert(n).copy_from_slice(&input[..n]);
                reader.notify_read(n);
                *input = &input[n..];
            }
            Ok(LinearReadEvent::Record { data, opcode }) => f(opcode, data)?,
            Err(e) => return Ok(Some(e)),
        }
    }
    Ok(None)
}

/// Decodes one chunk record (its body `data`) completely, checking its CRC before any of its
/// records is used, so a chunk is taken entirely or not at all.
fn read_chunk(r: &mut Reading, opcode: u8, data: &[u8], number: usize) -> Result<(), LogError> {
    let path = r.path;
    let corrupt = |problem: String| LogError::Corrupt {
        path: path.into(),
        problem: format!("chunk {number}: {problem}"),
    };
    if let Ok(Record::Chunk { header, .. }) = mcap::parse_record(opcode, data) {
        // The mcap crate allocates the declared uncompressed size up front: a damaged header
        // must not turn into a huge allocation.
        if header.uncompressed_size > MAX_CHUNK_BYTES {
            return Err(corrupt(format!(
                "declares {} uncompressed bytes (limit {MAX_CHUNK_BYTES})",
                header.uncompressed_size
            )));
        }
    }
    let mut framed = Vec::with_capacity(9 + data.len());
    framed.push(opcode);
    framed.extend_from_slice(&(data.len() as u64).to_le_bytes());
    framed.extend_from_slice(data);
    let mut inner = SansReader::new_with_options(
        LinearReaderOptions::default()
            .with_skip_start_magic(true)
            .with_skip_end_magic(true)
            .with_emit_chunks(false)
            .with_prevalidate_chunk_crcs(true)
            .with_record_length_limit(MAX_CHUNK_BYTES as usize),
    );
    let mut records = Vec::new();
    let mut input = &framed[..];
    let outcome = drive(&mut inner, &mut input, |op, body| {
        check_lengths(op, body).map_err(|p| corrupt(format!("record (opcode {op:#04x}): {p}")))?;
        let rec = mcap::parse_record(op, body)
            .map_err(|e| corrupt(format!("record cannot be parsed: {e}")))?;
        records.push(rec.into_owned());
        Ok(())
    })?;
    if let Some(e) = outcome {
        return Err(corrupt(e.to_string()));
    }
    for rec in records {
        r.record(rec)?;
    }
    Ok(())
}

/// The file ends with a footer record and the closing magic (as every finished log does):
/// opcode, length 20, two offsets and a CRC, then the 8 magic bytes.
fn ends_with_footer(bytes: &[u8]) -> bool {
    const FOOTER_RECORD: usize = 1 + 8 + 20;
    let magic = mcap::MAGIC.len();
    if bytes.len() < mcap::MAGIC.len() + FOOTER_RECORD + magic {
        return false;
    }
    let tail = &bytes[bytes.len() - magic - FOOTER_RECORD..];
    tail[0] == op::FOOTER
        && tail[1..9] == 20u64.to_le_bytes()
        && &tail[FOOTER_RECORD..] == mcap::MAGIC
}

/// Checks that every length prefix inside a record's body (strings, byte arrays, maps,
/// arrays) fits in the body, before the mcap crate parses it: the crate allocates what a
/// prefix declares, so a damaged one (e.g. 0xFFFFFFFF) would otherwise ask for gigabytes.
/// Layouts from the MCAP specification; records this reader does not know pass.
fn check_lengths(opcode: u8, body: &[u8]) -> Result<(), String> {
    struct Cursor<'a> {
        rest: &'a [u8],
    }
    impl Cursor<'_> {
        fn skip(&mut self, n: u64, what: &str) -> Result<(), String> {
            if n > self.rest.len() as u64 {
                return Err(format!(
                    "{what} declares {n} bytes but only {} remain in the record",
                    self.rest.len()
                ));
            }
            self.rest = &self.rest[n as usize..];
            Ok(())
        }
        fn int(&mut self, bytes: usize, what: &str) -> Result<u64, String> {
            if self.rest.len() < bytes {
                return Err(format!("{what}: the record ends early"));
            }
            let mut v = [0u8; 8];
            v[..bytes].copy_from_slice(&self.rest[..bytes]);
            self.rest = &self.rest[bytes..];
            Ok(u64::from_le_bytes(v))
        }
        /// A u32-prefixed string or byte array.
        fn string(&mut self, what: &str) -> Result<(), String> {
            let n = self.int(4, what)?;
            self.skip(n, what)
        }
        /// A map of strings to strings (u32 byte length, then the entries).
        fn string_map(&mut self, what: &str) -> Result<(), String> {
            let n = self.int(4, what)?;
            if n > self.rest.len() as u64 {
                return self.skip(n, what);
            }
            let mut inner = Cursor {
                rest: &self.rest[..n as usize],
            };
            while !inner.rest.is_empty() {
                inner.string(what)?;
                inner.string(what)?;
            }
            self.skip(n, what)
        }
    }
    let mut c = Cursor { rest: body };
    match opcode {
        op::HEADER => {
            c.string("profile")?;
            c.string("library")?;
        }
        op::SCHEMA => {
            c.int(2, "schema id")?;
            c.string("schema name")?;
            c.string("schema encoding")?;
            c.string("schema data")?;
        }
        op::CHANNEL => {
            c.int(2, "channel id")?;
            c.int(2, "schema id")?;
            c.string("topic")?;
            c.string("message encoding")?;
            c.string_map("channel metadata")?;
        }
        op::CHUNK => {
            c.int(8, "start time")?;
            c.int(8, "end time")?;
            c.int(8, "uncompressed size")?;
            c.int(4, "uncompressed crc")?;
            c.string("compression")?;
            let n = c.int(8, "chunk records")?;
            c.skip(n, "chunk records")?;
        }
        op::MESSAGE_INDEX => {
            c.int(2, "channel id")?;
            c.string("message index entries")?;
        }
        op::CHUNK_INDEX => {
            for what in ["start time", "end time", "chunk offset", "chunk length"] {
                c.int(8, what)?;
            }
            c.string("message index offsets")?;
            c.int(8, "message index length")?;
            c.string("compression")?;
        }
        op::ATTACHMENT => {
            c.int(8, "log time")?;
            c.int(8, "create time")?;
            c.string("attachment name")?;
            c.string("media type")?;
            let n = c.int(8, "attachment data")?;
            c.skip(n, "attachment data")?;
        }
        op::ATTACHMENT_INDEX => {
            for what in ["offset", "length", "log time", "create time", "data size"] {
                c.int(8, what)?;
            }
            c.string("attachment name")?;
            c.string("media type")?;
        }
        op::STATISTICS => {
            c.int(8, "message count")?;
            c.int(2, "schema count")?;
            for what in [
                "channel count",
                "attachment count",
                "metadata count",
                "chunk count",
            ] {
                c.int(4, what)?;
            }
            c.int(8, "start time")?;
            c.int(8, "end time")?;
            c.string("channel message counts")?;
        }
        op::METADATA => {
            c.string("metadata name")?;
            c.string_map("metadata")?;
        }
        op::METADATA_INDEX => {
            c.int(8, "offset")?;
            c.int(8, "length")?;
            c.string("metadata name")?;
        }
        _ => {}
    }
    Ok(())
}
