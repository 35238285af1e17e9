//! Mutation fuzzers for every file the program reads, run under a supervisor that sees
//! aborts (issues 16, 57). A custom test harness (`harness = false`): run plainly, it is the
//! **supervisor**; with `FUZZ_CHILD=<target> <start> <end>` in its environment, a **child**
//! that runs one target on inputs `start..end`.
//!
//! - Inputs are deterministic: input `i` of a target is a seeded mutation of a corpus file,
//!   so the supervisor rebuilds any input from its number.
//! - A child prints each input's number before running it, and `finding <i> <why>` when an
//!   oracle fails. It runs with a 4 GiB address-space limit, so an unbounded allocation
//!   aborts it. When a child dies (panic, abort, stack overflow, signal), the supervisor saves
//!   the input it was on and starts a new child at the next input; an input that runs longer
//!   than [`INPUT_TIME_LIMIT`] is a finding too (the child is killed and restarted).
//! - Findings are saved to `target/fuzz-findings/<target>/` and fail the run.
//!
//! Targets and oracles:
//! - `rm`: reward-machine files; an accepted machine writes back to text that reads back to
//!   the same machine (read → write → read).
//! - `config`: the TOML configs (IRL run, expert, SAC, Office, ReacherDraw).
//! - `task_file`, `office_task`: ReacherDelivery and Office task files, read beside copies of
//!   the shipped machines and map.
//! - `office_map`: Office map files; an accepted map builds a world and writes back to
//!   itself (read → write → read).
//! - `mcap`, `mcap_nocrc`: rollout logs of a real `--quick` run (demonstration and training
//!   logs, several chunks), with and without CRCs, under record-aware mutations (a record's
//!   length, opcode or CRC, a cut at a record boundary or anywhere, byte damage). A cut
//!   log reads to a prefix of the original's episodes (or is refused); a damaged log with
//!   CRCs is refused, read identical, or read as cut short with a prefix. Every accepted log
//!   goes through replay, render, the offline-RM traces and (one in eight) the Foxglove
//!   export, whose copy must read back to the same episodes.
//! - `mcap_fields`: the same logs as read, with well-formed but wrong values in their fields
//!   (the run record's JSON config and task layout, its vocabulary, task, machine and sizes;
//!   an episode's state vectors, event steps, labels and machine states), which CRCs cannot
//!   keep out of a log written by anyone; replay, render and the offline-RM traces run on each.
//! - `expert_data`, `policy`, `reward_net`, `reward_linear`, `job`, `prepare`: the run
//!   directory's `expert_data.bin`, `*.policy`, `rewards/*.bin`, `rewards/*.json`,
//!   `jobs/*.json` and `prepare.json`; `expert_data` also round-trips.
//!
//! CI runs the short pass (default counts, well under 60 s). The long pass is
//! `experiments/fuzz/long_pass.sh` (counts from `FUZZ_TEXT_ITERS`, `FUZZ_MCAP_ITERS`,
//! `FUZZ_BIN_ITERS`). The corpus in `tests/fuzz_corpus/` comes from
//! `experiments/fuzz/make_corpus.sh`.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use smirl::env::office::{parse_map, write_map, OfficeTask, OfficeWorld};
use smirl::env::reacher_task::ReacherTask;
use smirl::env::task_file::Task;
use smirl::irl::reward::RewardOptimConfig;
use smirl::irl::smirl::LinearRmReward;
use smirl::log::{read_log, read_log_bytes, RolloutLog};
use smirl::nn::{Mlp, MlpArch};
use smirl::pipeline::office::OfficeConfig;
use smirl::pipeline::reacher_draw::DrawConfig;
use smirl::pipeline::reacher_expert::{ExpertConfig, ExpertPolicy};
use smirl::pipeline::reacher_irl::records::{JobRecord, Prepared};
use smirl::pipeline::reacher_irl::{ExpertData, IrlRunConfig};
use smirl::pipeline::render::{render_episode, RenderOptions};
use smirl::rl::sac::SacConfig;
use smirl::rm::format::{parse_rm, write_rm};
use std::io::{BufRead, BufReader, Write};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::sync::mpsc;
use std::time::{Duration, Instant};

/// Longest an input may take before it is a finding.
const INPUT_TIME_LIMIT: Duration = Duration::from_secs(1);
/// Address space of a child: an allocation past it aborts the child (and is found).
const CHILD_ADDRESS_SPACE: u64 = 4 << 30;

const TARGETS: &[(&str, &str, u64)] = &[
    // (name, iteration variable, short-pass count)
    ("rm", "FUZZ_TEXT_ITERS", 20_000),
    ("config", "FUZZ_TEXT_ITERS", 4_000),
    ("office_map", "FUZZ_TEXT_ITERS", 20_000),
    ("task_file", "FUZZ_BIN_ITERS", 1_000),
    ("office_task", "FUZZ_BIN_ITERS", 4_000),
    ("mcap", "FUZZ_MCAP_ITERS", 2_000),
    ("mcap_nocrc", "FUZZ_MCAP_ITERS", 1_000),
    ("mcap_fields", "FUZZ_MCAP_ITERS", 1_000),
    ("expert_data", "FUZZ_BIN_ITERS", 4_000),
    ("policy", "FUZZ_BIN_ITERS", 3_000),
    ("reward_net", "FUZZ_BIN_ITERS", 500),
    ("reward_linear", "FUZZ_BIN_ITERS", 1_000),
    ("job", "FUZZ_BIN_ITERS", 4_000),
    ("prepare", "FUZZ_BIN_ITERS", 4_000),
];

fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

fn read(path: &str) -> Vec<u8> {
    std::fs::read(root().join(path)).unwrap_or_else(|e| panic!("{path}: {e}"))
}

// ---------------------------------------------------------------------------------------
// Mutations

/// Bytes that tend to matter to the text formats: delimiters, quotes, brackets, digits.
const INTERESTING_BYTES: &[u8] = b"\0\xff()[]{}!&|'\",:=#.\n\r 0123456789-+eE";
/// Numbers that tend to find size bugs.
const INTERESTING_NUMBERS: &[&str] = &[
    "0",
    "-1",
    "1e308",
    "18446744073709551615",
    "4294967296",
    "1000000000000",
    "nan",
    "inf",
    "99999999999999999999999",
];

/// Byte-level mutations (text and binary formats).
fn mutate_bytes(rng: &mut ChaCha8Rng, out: &mut Vec<u8>) {
    for _ in 0..rng.gen_range(1..=4) {
        let len = out.len();
        match rng.gen_range(0..8) {
            0 if len > 0 => {
                let i = rng.gen_range(0..len);
                out[i] ^= 1 << rng.gen_range(0..8);
            }
            1 if len > 0 => {
                let i = rng.gen_range(0..len);
                out[i] = INTERESTING_BYTES[rng.gen_range(0..INTERESTING_BYTES.len())];
            }
            2 if len > 0 => {
                let i = rng.gen_range(0..len);
                let n = rng.gen_range(1..=16.min(len - i));
                out.drain(i..i + n);
            }
            3 if len > 0 => {
                let i = rng.gen_range(0..len);
                let n = rng.gen_range(1..=64.min(len - i));
                let piece = out[i..i + n].to_vec();
                out.splice(i..i, piece);
            }
            4 if len > 0 => {
                // Repeat a short slice many times (deep nesting, long lines).
                let i = rng.gen_range(0..len);
                let n = rng.gen_range(1..=3.min(len - i));
                let piece = out[i..i + n].to_vec();
                let times = [10, 100, 1_000, 20_000][rng.gen_range(0..4)];
                let repeated: Vec<u8> = piece.iter().copied().cycle().take(n * times).collect();
                out.splice(i..i, repeated);
            }
            5 if len > 0 => {
                let i = rng.gen_range(0..len);
                if let Some(start) = (i..len).find(|&k| out[k].is_ascii_digit()) {
                    let end = (start..len)
                        .find(|&k| !out[k].is_ascii_digit())
                        .unwrap_or(len);
                    let number = INTERESTING_NUMBERS[rng.gen_range(0..INTERESTING_NUMBERS.len())];
                    out.splice(start..end, number.bytes());
                }
            }
            6 if len > 8 => {
                // An extreme little-endian integer (binary length and count fields).
                let width = if rng.gen_bool(0.5) { 4 } else { 8 };
                let i = rng.gen_range(0..len - width);
                let value: u64 =
                    [0, u64::MAX, u32::MAX as u64, 1 << 31, 1 << 40][rng.gen_range(0..5)];
                out[i..i + width].copy_from_slice(&value.to_le_bytes()[..width]);
            }
            7 if len > 0 => out.truncate(rng.gen_range(0..len)),
            _ => {}
        }
    }
}

/// One top-level MCAP record: offset, opcode, body length.
#[derive(Clone, Copy)]
struct McapRecord {
    at: usize,
    opcode: u8,
    len: usize,
}

fn mcap_records(bytes: &[u8]) -> Vec<McapRecord> {
    let mut at = mcap::MAGIC.len();
    let mut found = Vec::new();
    while at + 9 <= bytes.len() - mcap::MAGIC.len() {
        let len = u64::from_le_bytes(bytes[at + 1..at + 9].try_into().unwrap()) as usize;
        found.push(McapRecord {
            at,
            opcode: bytes[at],
            len,
        });
        at += 9 + len;
    }
    found
}

/// Where a record keeps its CRC (offset in the file, 4 bytes), when it has one.
fn crc_field(r: &McapRecord) -> Option<usize> {
    use mcap::records::op;
    let body = r.at + 9;
    match r.opcode {
        op::CHUNK => Some(body + 24),
        op::ATTACHMENT => Some(body + r.len - 4),
        op::DATA_END => Some(body),
        op::FOOTER => Some(body + 16),
        _ => None,
    }
}

/// The log with every CRC field zeroed (a CRC of 0 means "not computed").
fn without_crcs(bytes: &[u8]) -> Vec<u8> {
    let mut out = bytes.to_vec();
    for r in mcap_records(bytes) {
        if let Some(at) = crc_field(&r) {
            out[at..at + 4].fill(0);
        }
    }
    out
}

/// A mutated log, and whether it is only cut (a prefix of the original).
fn mutate_mcap(rng: &mut ChaCha8Rng, original: &[u8]) -> (Vec<u8>, bool) {
    let records = mcap_records(original);
    let mut out = original.to_vec();
    let r = records[rng.gen_range(0..records.len())];
    match rng.gen_range(0..7) {
        0 => {
            out.truncate(r.at);
            return (out, true);
        }
        1 => {
            out.truncate(rng.gen_range(0..original.len()));
            return (out, true);
        }
        2 => {
            // A length field: a bit flip, or an extreme value.
            let field = r.at + 1;
            if rng.gen_bool(0.5) {
                out[field + rng.gen_range(0..8)] ^= 1 << rng.gen_range(0..8);
            } else {
                let v: u64 = [0, u64::MAX, 1 << 32, r.len as u64 + 1][rng.gen_range(0..4)];
                out[field..field + 8].copy_from_slice(&v.to_le_bytes());
            }
        }
        3 => out[r.at] = rng.gen_range(0..=0x12),
        4 => {
            let with_crc: Vec<usize> = records.iter().filter_map(crc_field).collect();
            let at = with_crc[rng.gen_range(0..with_crc.len())];
            out[at + rng.gen_range(0..4)] ^= 1 << rng.gen_range(0..8);
        }
        5 => {
            // Damage inside one record's body.
            if r.len > 0 {
                let at = r.at + 9 + rng.gen_range(0..r.len);
                out[at] ^= 1 << rng.gen_range(0..8);
            }
        }
        _ => mutate_bytes(rng, &mut out),
    }
    if rng.gen_bool(0.2) {
        out.truncate(rng.gen_range(0..out.len().max(1)));
    }
    let cut_only = out.len() <= original.len() && out[..] == original[..out.len()];
    (out, cut_only)
}

// ---------------------------------------------------------------------------------------
// Targets

struct Corpus {
    files: Vec<Vec<u8>>,
    /// Per file: its episodes as read (MCAP targets).
    episodes: Vec<Vec<smirl::log::LoggedEpisode>>,
    /// Architecture of the reward network files.
    reward_arch: Option<MlpArch>,
    /// The logs as read, each cut to its first two episodes and its last (`mcap_fields`).
    logs: Vec<RolloutLog>,
}

fn corpus(target: &str) -> Corpus {
    let mut c = Corpus {
        files: Vec::new(),
        episodes: Vec::new(),
        reward_arch: None,
        logs: Vec::new(),
    };
    let dir_files = |dir: &str| -> Vec<Vec<u8>> {
        // The directory's files (`assets/tasks/new/` holds more tasks, not a seed input).
        let mut paths: Vec<PathBuf> = std::fs::read_dir(root().join(dir))
            .unwrap()
            .map(|e| e.unwrap().path())
            .filter(|p| p.is_file())
            .collect();
        paths.sort();
        paths.iter().map(|p| std::fs::read(p).unwrap()).collect()
    };
    match target {
        "rm" => c.files = dir_files("assets/rm"),
        "task_file" => c.files = dir_files("assets/tasks"),
        "office_task" => {
            for k in 0..5 {
                c.files.push(read(&format!("assets/office/task{k}.toml")));
            }
        }
        "office_map" => {
            c.files.push(read("assets/office/paper.map"));
            c.files.push(
                b"legend:\nk = key\ng =\nmap:\n+-+-+-+\n|k . g|\n+ +-+ +\n|@|.|.|\n+-+-+-+\n"
                    .to_vec(),
            );
        }
        "config" => {
            for p in [
                "experiments/reacher/config.toml",
                "experiments/reacher/quick.toml",
                "experiments/reacher/config_scripted.toml",
                "experiments/office/config.toml",
                "experiments/office/config_finite_horizon.toml",
                "tests/fuzz_corpus/config.toml",
            ] {
                c.files.push(read(p));
            }
            c.files
                .push(IrlRunConfig::standard().to_toml().into_bytes());
            c.files.push(SacConfig::expert().to_toml().into_bytes());
        }
        "mcap" | "mcap_nocrc" => {
            for p in [
                "tests/fuzz_corpus/demos.mcap",
                "tests/fuzz_corpus/fkl_seed0.mcap",
            ] {
                let bytes = read(p);
                let bytes = if target == "mcap" {
                    bytes
                } else {
                    without_crcs(&bytes)
                };
                let log = read_log_bytes(&bytes, Path::new(p)).unwrap();
                assert!(log.recovery.is_none() && log.chunks > 1, "{p}");
                c.episodes.push(log.episodes);
                c.files.push(bytes);
            }
        }
        "mcap_fields" => {
            for p in [
                "tests/fuzz_corpus/demos.mcap",
                "tests/fuzz_corpus/fkl_seed0.mcap",
            ] {
                let bytes = read(p);
                let mut log = read_log_bytes(&bytes, Path::new(p)).unwrap();
                // The corpus predates logs that record their task's layout; a log written
                // now carries it, and what reads it is fuzzed here.
                let layout = ReacherTask::shipped(&log.run.task).unwrap().task().layout();
                log.run.config[smirl::log::schema::CONFIG_TASK_LAYOUT] =
                    serde_json::to_value(layout).unwrap();
                if log.episodes.len() > 3 {
                    let last = log.episodes.pop().unwrap();
                    log.episodes.truncate(2);
                    log.episodes.push(last);
                }
                c.logs.push(log);
                c.files.push(bytes);
            }
        }
        "expert_data" => c.files.push(read("tests/fuzz_corpus/expert_data.bin")),
        "policy" => {
            c.files
                .push(read("experiments/experts/cache/expert_or.policy"));
            c.files
                .push(read("experiments/experts/cache/expert_composite.policy"));
        }
        "reward_net" => {
            let bytes = read("tests/fuzz_corpus/reward_maxent_seed0.bin");
            let path = scratch_file(&bytes);
            c.reward_arch = (1..=17).find_map(|d| {
                let arch = MlpArch::new(d, &[64, 64], 1);
                let mut net = Mlp::new(&arch, &mut ChaCha8Rng::seed_from_u64(0));
                net.load(&path).ok().map(|()| arch)
            });
            assert!(c.reward_arch.is_some(), "no architecture reads the corpus");
            c.files.push(bytes);
        }
        "reward_linear" => c
            .files
            .push(read("tests/fuzz_corpus/reward_smirl_seed0.json")),
        "job" => {
            c.files.push(read("tests/fuzz_corpus/job_smirl_seed0.json"));
            c.files.push(read("tests/fuzz_corpus/job_fkl_seed0.json"));
        }
        "prepare" => c.files.push(read("tests/fuzz_corpus/prepare.json")),
        "selftest" => c.files.push(b"x".to_vec()),
        other => panic!("unknown fuzz target {other}"),
    }
    assert!(!c.files.is_empty(), "{target}: empty corpus");
    c
}

/// Input `i` of `target`: (bytes, corpus file it came from, cut only).
fn input(target: &str, c: &Corpus, i: u64) -> (Vec<u8>, usize, bool) {
    let salt = TARGETS.iter().position(|t| t.0 == target).unwrap_or(99) as u64;
    let mut rng = ChaCha8Rng::seed_from_u64(i.wrapping_mul(0x9e37_79b9_7f4a_7c15) ^ salt);
    let k = rng.gen_range(0..c.files.len());
    if target == "mcap_fields" {
        // What was changed, for the saved finding.
        return (field_mutation(c, i).1.into_bytes(), k, false);
    }
    if target.starts_with("mcap") {
        let (bytes, cut) = mutate_mcap(&mut rng, &c.files[k]);
        return (bytes, k, cut);
    }
    let mut bytes = c.files[k].clone();
    mutate_bytes(&mut rng, &mut bytes);
    (bytes, k, false)
}

/// Values that tend to break what reads a field: signs, zero, huge and non-integral numbers.
const FIELD_NUMBERS: &[f64] = &[0.0, -1.0, 0.5, 2.0, 1e300, -1e300, 4294967296.0, 1.8e19];
/// Strings for text fields: empty, a letter twice, reserved characters, a path, unknown names.
const FIELD_TEXTS: &[&str] = &["", "r", "rr", "rgbyc", "&|", "builtin", "../x", "nosuch"];

/// Input `i` of `mcap_fields`: a corpus log with one to three fields set to well-formed but
/// wrong values, and what was changed.
fn field_mutation(c: &Corpus, i: u64) -> (RolloutLog, String) {
    let salt = TARGETS.iter().position(|t| t.0 == "mcap_fields").unwrap() as u64;
    let mut rng = ChaCha8Rng::seed_from_u64(i.wrapping_mul(0x9e37_79b9_7f4a_7c15) ^ salt);
    let k = rng.gen_range(0..c.files.len());
    let mut log = c.logs[k].clone();
    let mut what = Vec::new();
    let number = |rng: &mut ChaCha8Rng| FIELD_NUMBERS[rng.gen_range(0..FIELD_NUMBERS.len())];
    let text = |rng: &mut ChaCha8Rng| FIELD_TEXTS[rng.gen_range(0..FIELD_TEXTS.len())].to_string();
    // A vector made shorter, longer, or given a non-finite or huge entry.
    let vector = |rng: &mut ChaCha8Rng, v: &mut Vec<f64>| match rng.gen_range(0..3) {
        0 => v.truncate(rng.gen_range(0..=v.len())),
        1 => v.extend(std::iter::repeat_n(0.1, rng.gen_range(1..40))),
        _ if !v.is_empty() => {
            let at = rng.gen_range(0..v.len());
            v[at] = [f64::NAN, f64::INFINITY, 1e300][rng.gen_range(0..3)];
        }
        _ => {}
    };
    for _ in 0..rng.gen_range(1..=3) {
        let e = rng.gen_range(0..log.episodes.len());
        let episode = &mut log.episodes[e];
        match rng.gen_range(0..10) {
            0..=2 => {
                // A node of the run config's JSON (the task layout and env settings in it).
                let mut paths = Vec::new();
                json_paths(&log.run.config, String::new(), &mut paths);
                // Half the time within the task layout, which most readers build from.
                let layout = format!("/{}/", smirl::log::schema::CONFIG_TASK_LAYOUT);
                if rng.gen_bool(0.5) && paths.iter().any(|p| p.starts_with(&layout)) {
                    paths.retain(|p| p.starts_with(&layout));
                }
                let path = &paths[rng.gen_range(0..paths.len())];
                let node = log.run.config.pointer_mut(path).unwrap();
                *node = match (rng.gen_range(0..6), &*node) {
                    (0, serde_json::Value::Array(a)) if !a.is_empty() => {
                        let mut a = a.clone();
                        a.push(a[0].clone());
                        serde_json::Value::Array(a)
                    }
                    (1, serde_json::Value::Array(a)) if !a.is_empty() => {
                        serde_json::Value::Array(a[1..].to_vec())
                    }
                    (2, _) => serde_json::json!(text(&mut rng)),
                    (3, _) => serde_json::Value::Null,
                    (4, _) => serde_json::json!(rng.gen::<u64>()),
                    _ => serde_json::json!(number(&mut rng)),
                };
                what.push(format!("config {path} = {node}"));
            }
            3 => {
                log.run.vocabulary = text(&mut rng);
                what.push(format!("vocabulary {:?}", log.run.vocabulary));
            }
            4 => {
                log.run.task = text(&mut rng);
                let machine = (rng.gen_bool(0.5)).then(|| "vocabulary: rr\nstates: 1\n".into());
                log.run.reward_machine = machine;
                what.push(format!(
                    "task {:?}, machine {:?}",
                    log.run.task, log.run.reward_machine
                ));
            }
            5 => {
                log.run.obs_dim = rng.gen_range(0..40);
                log.run.act_dim = rng.gen_range(0..4);
                what.push(format!("dims {} {}", log.run.obs_dim, log.run.act_dim));
            }
            6 => {
                let start = &mut episode.start;
                match rng.gen_range(0..3) {
                    0 => vector(&mut rng, &mut start.qpos),
                    1 => vector(&mut rng, &mut start.qvel),
                    _ => vector(&mut rng, &mut start.balls),
                }
                what.push(format!("episode {e} start state"));
            }
            7 => {
                let start = &mut episode.start;
                start.cancel_step = rng.gen();
                start.event_steps = (0..rng.gen_range(0..6))
                    .map(|_| rng.gen_range(0..200))
                    .collect();
                start.labels = rng.gen();
                start.rm_state = rng.gen_range(-2..20);
                what.push(format!("episode {e} events {:?}", start.event_steps));
            }
            _ if !episode.steps.is_empty() => {
                let t = rng.gen_range(0..episode.steps.len());
                let step = &mut episode.steps[t];
                match rng.gen_range(0..4) {
                    0 => step.action.truncate(rng.gen_range(0..2)),
                    1 => step.labels = rng.gen(),
                    2 => step.rm_state = rng.gen_range(-2..20),
                    _ => vector(&mut rng, &mut step.qpos),
                }
                what.push(format!("episode {e} step {t}"));
            }
            _ => {}
        }
    }
    (log, format!("corpus log {k}: {}\n", what.join("; ")))
}

/// JSON pointers of every node under `value` (`prefix` its own).
fn json_paths(value: &serde_json::Value, prefix: String, out: &mut Vec<String>) {
    match value {
        serde_json::Value::Object(m) => {
            for (k, v) in m {
                json_paths(
                    v,
                    format!("{prefix}/{}", k.replace('~', "~0").replace('/', "~1")),
                    out,
                );
            }
        }
        serde_json::Value::Array(a) => {
            for (k, v) in a.iter().enumerate() {
                json_paths(v, format!("{prefix}/{k}"), out);
            }
        }
        _ => {}
    }
    out.push(prefix);
}

/// A file in the child's scratch directory holding `bytes` (for readers that take a path).
fn scratch_file(bytes: &[u8]) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("smirl-fuzz-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("input");
    std::fs::write(&path, bytes).unwrap();
    path
}

/// A task file's bytes written as `<scratch>/<dir>/input.toml`, beside copies of the shipped
/// machines (`<scratch>/rm/`) and Office map (`<scratch>/office/`), so that the relative paths
/// of the shipped task files resolve as they do in `assets/`.
fn task_scratch(bytes: &[u8], dir: &str) -> PathBuf {
    let scratch = std::env::temp_dir().join(format!("smirl-fuzz-tasks-{}", std::process::id()));
    if !scratch.join("office/paper.map").is_file() {
        for sub in ["rm", "office", "tasks"] {
            std::fs::create_dir_all(scratch.join(sub)).unwrap();
        }
        for entry in std::fs::read_dir(root().join("assets/rm")).unwrap() {
            let path = entry.unwrap().path();
            std::fs::copy(&path, scratch.join("rm").join(path.file_name().unwrap())).unwrap();
        }
        std::fs::copy(
            root().join("assets/office/paper.map"),
            scratch.join("office/paper.map"),
        )
        .unwrap();
    }
    let path = scratch.join(dir).join("input.toml");
    std::fs::write(&path, bytes).unwrap();
    path
}

/// `part` is `whole` or a prefix of it: complete episodes equal, a last unfinished one
/// holding the first steps of its original.
fn is_prefix(
    part: &[smirl::log::LoggedEpisode],
    whole: &[smirl::log::LoggedEpisode],
) -> Result<(), String> {
    if part.len() > whole.len() {
        return Err(format!(
            "{} episodes, the original has {}",
            part.len(),
            whole.len()
        ));
    }
    for (k, (p, w)) in part.iter().zip(whole).enumerate() {
        let same = if p.is_complete() {
            p == w
        } else {
            p.start == w.start
                && p.steps.len() <= w.steps.len()
                && p.steps[..] == w.steps[..p.steps.len()]
                && k + 1 == part.len()
        };
        if !same {
            return Err(format!("episode {k} differs from the original"));
        }
    }
    Ok(())
}

/// The commands' work on an accepted log; errors are fine, wrong copies are not.
fn downstream(log: &RolloutLog, bytes: &[u8], i: u64) -> Result<(), String> {
    // Replay re-simulates: its first two episodes and its last (where a cut or damage shows)
    // keep an input well inside the time limit.
    let mut few = log.clone();
    if few.episodes.len() > 3 {
        let last = few.episodes.pop().unwrap();
        few.episodes.truncate(2);
        few.episodes.push(last);
    }
    let _ = smirl::pipeline::replay::replay(&few);
    let options = RenderOptions { size: 64, poses: 2 };
    let _ = render_episode(log, None, &options);
    let _ = smirl::pipeline::offline_rm::traces_from_logs(std::slice::from_ref(log));
    if i.is_multiple_of(8) {
        let input = scratch_file(bytes);
        let view = input.with_file_name("view.mcap");
        let _ = std::fs::remove_file(&view);
        if smirl::pipeline::foxglove_scene::export_scene(&input, &view, true).is_ok() {
            let copy =
                read_log(&view).map_err(|e| format!("the Foxglove copy does not read: {e}"))?;
            if copy.episodes != log.episodes {
                return Err("the Foxglove copy holds other episodes than the log".into());
            }
        }
    }
    Ok(())
}

/// Runs input `i`; `Err` is an oracle's finding.
fn run(target: &str, c: &Corpus, i: u64) -> Result<(), String> {
    if target == "mcap_fields" {
        // Errors are fine; a panic, an abort or a hang is the finding.
        let log = field_mutation(c, i).0;
        let _ = smirl::pipeline::replay::replay(&log);
        let _ = render_episode(&log, None, &RenderOptions { size: 64, poses: 2 });
        let _ = smirl::pipeline::offline_rm::traces_from_logs(std::slice::from_ref(&log));
        return Ok(());
    }
    let (bytes, k, cut_only) = input(target, c, i);
    let text = || String::from_utf8_lossy(&bytes).into_owned();
    match target {
        "rm" => {
            let Ok(text) = std::str::from_utf8(&bytes) else {
                return Ok(());
            };
            if let Ok(rm) = parse_rm(text, "fuzz.txt") {
                let written = write_rm(&rm);
                let again = parse_rm(&written, "written.txt")
                    .map_err(|e| format!("the written machine does not read back: {e}"))?;
                if write_rm(&again) != written {
                    return Err("read → write → read changes the machine".into());
                }
            }
        }
        "task_file" => {
            let _ = Task::load(&task_scratch(&bytes, "tasks"));
        }
        "office_task" => {
            let _ = OfficeTask::load(&task_scratch(&bytes, "office"));
        }
        "office_map" => {
            // A map that parses builds a world and writes back to itself.
            if let Ok(map) = parse_map(&text(), "fuzz.map") {
                let world = OfficeWorld::from_map(&map);
                if world.n_cells() != map.width() * map.height() {
                    return Err("the world's cells are not the map's".into());
                }
                match parse_map(&write_map(&map), "written.map") {
                    Ok(again) if again == map => {}
                    _ => return Err("read → write → read changes the map".into()),
                }
            }
        }
        "config" => {
            let text = text();
            let _ = IrlRunConfig::from_toml(&text, "fuzz.toml");
            let _ = ExpertConfig::from_toml(&text, "fuzz.toml");
            let _ = SacConfig::from_toml(&text, "fuzz.toml");
            let _ = OfficeConfig::from_toml(&text);
            let _ = DrawConfig::from_toml(&text, "fuzz.toml");
        }
        "mcap" | "mcap_nocrc" => {
            let Ok(log) = read_log_bytes(&bytes, Path::new("fuzz.mcap")) else {
                return Ok(());
            };
            let original = &c.episodes[k];
            if cut_only || target == "mcap" {
                if log.recovery.is_none() && bytes != c.files[k] && log.episodes != *original {
                    return Err("a changed log reads as complete with other episodes".into());
                }
                is_prefix(&log.episodes, original)?;
            }
            downstream(&log, &bytes, i)?;
        }
        "expert_data" => {
            if let Ok(data) = ExpertData::from_bytes(&bytes, 17) {
                let written = data.to_bytes();
                let again = ExpertData::from_bytes(&written, 17)
                    .map_err(|e| format!("written expert data does not read back: {e}"))?;
                if again.to_bytes() != written {
                    return Err("expert data changes in a round trip".into());
                }
            }
        }
        "policy" => {
            let hidden = SacConfig::expert().hidden;
            for name in ["or", "composite"] {
                let task = ReacherTask::shipped(name).map_err(|e| e.to_string())?;
                let _ = ExpertPolicy::from_bytes(&bytes, "fuzz.policy", task, &hidden);
            }
        }
        "reward_net" => {
            let arch = c.reward_arch.as_ref().unwrap();
            let mut net = Mlp::new(arch, &mut ChaCha8Rng::seed_from_u64(0));
            let _ = net.load(&scratch_file(&bytes));
        }
        "reward_linear" => {
            let _ = LinearRmReward::load(&scratch_file(&bytes), RewardOptimConfig::adam(1e-3));
        }
        "job" => {
            let _ = serde_json::from_slice::<JobRecord>(&bytes);
        }
        "prepare" => {
            if let Ok(p) = serde_json::from_slice::<Prepared>(&bytes) {
                let _ = p.jobs();
            }
        }
        // The supervisor's own check: an abort, a panic and a hang at known inputs.
        "selftest" => match i {
            10 => std::process::abort(),
            20 => panic!("selftest panic"),
            30 => std::thread::sleep(INPUT_TIME_LIMIT * 2),
            _ => {}
        },
        other => panic!("unknown fuzz target {other}"),
    }
    Ok(())
}

// ---------------------------------------------------------------------------------------
// Child and supervisor

fn child(spec: &str) {
    let mut parts = spec.split_whitespace();
    let (target, start, end) = (
        parts.next().unwrap().to_string(),
        parts.next().unwrap().parse::<u64>().unwrap(),
        parts.next().unwrap().parse::<u64>().unwrap(),
    );
    let limit = libc::rlimit {
        rlim_cur: CHILD_ADDRESS_SPACE,
        rlim_max: CHILD_ADDRESS_SPACE,
    };
    // SAFETY: sets a resource limit of this process only.
    unsafe { libc::setrlimit(libc::RLIMIT_AS, &limit) };
    let c = corpus(&target);
    let mut out = std::io::stdout().lock();
    writeln!(out, "ready").unwrap();
    for i in start..end {
        writeln!(out, "{i}").unwrap();
        out.flush().unwrap();
        if let Err(why) = run(&target, &c, i) {
            writeln!(out, "finding {i} {why}").unwrap();
        }
    }
    writeln!(out, "done").unwrap();
    let _ = std::fs::remove_dir_all(
        std::env::temp_dir().join(format!("smirl-fuzz-{}", std::process::id())),
    );
}

struct Report {
    inputs: u64,
    secs: f64,
    findings: Vec<String>,
}

fn save_finding(target: &str, c: &Corpus, i: u64, kind: &str, why: &str) -> String {
    let dir = root().join("target/fuzz-findings").join(target);
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join(format!("{kind}-{i}"));
    std::fs::write(&path, input(target, c, i).0).unwrap();
    format!(
        "{target} input {i}: {kind}: {why} (saved as {})",
        path.display()
    )
}

/// Runs `target` on inputs `0..iters` in children, restarting after every crash or timeout.
fn supervise(target: &str, iters: u64) -> Report {
    let c = corpus(target);
    let started = Instant::now();
    let mut findings = Vec::new();
    let mut next = 0;
    while next < iters {
        let mut proc = Command::new(std::env::current_exe().unwrap())
            .env("FUZZ_CHILD", format!("{target} {next} {iters}"))
            .env("RUST_BACKTRACE", "0")
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        let (tx, rx) = mpsc::channel();
        let stdout = proc.stdout.take().unwrap();
        std::thread::spawn(move || {
            for line in BufReader::new(stdout).lines() {
                if tx.send(line.unwrap_or_default()).is_err() {
                    break;
                }
            }
        });
        let stderr = proc.stderr.take().unwrap();
        let errors = std::thread::spawn(move || {
            // The first lines: the panic or abort message.
            let mut head = Vec::new();
            for line in BufReader::new(stderr).lines().map_while(Result::ok) {
                if head.len() < 3 {
                    head.push(line);
                }
            }
            head.join(" | ")
        });
        let mut current = None;
        let mut done = false;
        let mut timed_out = false;
        let mut wait = Duration::from_secs(60); // corpus loading
        loop {
            match rx.recv_timeout(wait) {
                Ok(line) if line == "ready" => wait = INPUT_TIME_LIMIT,
                Ok(line) if line == "done" => {
                    done = true;
                    break;
                }
                Ok(line) if line.starts_with("finding ") => {
                    let mut p = line.splitn(3, ' ').skip(1);
                    let i: u64 = p.next().unwrap().parse().unwrap();
                    findings.push(save_finding(
                        target,
                        &c,
                        i,
                        "oracle",
                        p.next().unwrap_or(""),
                    ));
                }
                Ok(line) => current = line.parse::<u64>().ok(),
                Err(mpsc::RecvTimeoutError::Timeout) => {
                    timed_out = true;
                    let _ = proc.kill();
                    break;
                }
                Err(mpsc::RecvTimeoutError::Disconnected) => break,
            }
        }
        let status = proc.wait().unwrap();
        let tail = errors.join().unwrap_or_default();
        if done && status.success() {
            break;
        }
        let Some(i) = current else {
            panic!("{target}: the child failed before its first input ({status}): {tail}");
        };
        let (kind, why) = if timed_out {
            ("timeout", format!("ran longer than {INPUT_TIME_LIMIT:?}"))
        } else {
            ("crash", format!("{status}: {tail}"))
        };
        findings.push(save_finding(target, &c, i, kind, &why));
        next = i + 1;
    }
    Report {
        inputs: iters,
        secs: started.elapsed().as_secs_f64(),
        findings,
    }
}

fn main() {
    if let Ok(spec) = std::env::var("FUZZ_CHILD") {
        child(&spec);
        return;
    }
    // `cargo test -- --list` and filters: this harness has one test, `fuzz`.
    let args: Vec<String> = std::env::args().skip(1).collect();
    if args.iter().any(|a| a == "--list") {
        println!("fuzz: test");
        return;
    }
    // The supervisor sees what a single-process fuzzer cannot: an abort, and a hang.
    let check = supervise("selftest", 40);
    let kinds: Vec<&str> = check
        .findings
        .iter()
        .map(|f| f.split(": ").nth(1).unwrap_or(""))
        .collect();
    assert_eq!(
        kinds,
        ["crash", "crash", "timeout"],
        "the supervisor missed a failure: {:?}",
        check.findings
    );
    for name in ["crash-10", "crash-20", "timeout-30"] {
        assert!(
            root()
                .join("target/fuzz-findings/selftest")
                .join(name)
                .is_file(),
            "{name} not saved"
        );
    }
    let _ = std::fs::remove_dir_all(root().join("target/fuzz-findings/selftest"));
    println!("selftest: an abort, a panic and a hang found and saved, every other input run");

    let only = std::env::var("FUZZ_TARGETS").ok();
    let mut findings = 0;
    for &(target, var, short) in TARGETS {
        if only
            .as_ref()
            .is_some_and(|o| !o.split(',').any(|t| t == target))
        {
            continue;
        }
        let iters = std::env::var(var)
            .ok()
            .and_then(|v| v.parse().ok())
            .unwrap_or(short);
        let r = supervise(target, iters);
        println!(
            "{target}: {} inputs in {:.1} s ({:.0}/s), {} findings",
            r.inputs,
            r.secs,
            r.inputs as f64 / r.secs.max(1e-9),
            r.findings.len()
        );
        for f in r.findings.iter().take(10) {
            println!("  {f}");
        }
        findings += r.findings.len();
    }
    if findings > 0 {
        eprintln!("fuzz: {findings} findings");
        std::process::exit(1);
    }
    println!("fuzz: 0 findings");
}
