//! Mutation fuzzers for every text and binary input format (issue 16): reward-machine files,
//! Office map files, the TOML configs (IRL run, expert, SAC, Office) and MCAP rollout logs.
//! Each starts from a seed corpus of shipped files, applies seeded random mutations (bit
//! flips, interesting bytes and numbers, deletions, duplications, long repeats of a slice —
//! the deep nesting that once overflowed the stack — and truncation), and feeds every mutant
//! to the reader.
//! A panic fails the test and writes the input to `target/fuzz-crashes/`; an abort or a
//! stack overflow kills the process, which fails the test too.
//!
//! CI runs a short pass (the default iteration counts, a few seconds). The long pass, with
//! an address-space limit so that any unbounded allocation aborts:
//!
//! ```sh
//! cargo test --release --test fuzz --no-run
//! (ulimit -v 4194304; FUZZ_TEXT_ITERS=1000000 FUZZ_MCAP_ITERS=100000 \
//!    cargo test --release --test fuzz -- --nocapture --test-threads 1)
//! ```

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use smirl::env::office::{parse_map, write_map, OfficeWorld};
use smirl::env::reacher::ReacherConfig;
use smirl::log::demo::{log_scripted_demos, DemoSpec};
use smirl::log::{read_log_bytes, LogOptions};
use smirl::pipeline::office::OfficeConfig;
use smirl::pipeline::reacher_expert::ExpertConfig;
use smirl::pipeline::reacher_irl::IrlRunConfig;
use smirl::rl::sac::SacConfig;
use smirl::rm::format::parse_rm;
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::Path;
use std::time::Instant;

fn iterations(var: &str, default: u64) -> u64 {
    std::env::var(var)
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(default)
}

/// Bytes that tend to matter to the formats: delimiters, quotes, brackets, digits, `!`.
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

fn mutate(rng: &mut ChaCha8Rng, input: &[u8]) -> Vec<u8> {
    let mut out = input.to_vec();
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
                // Duplicate a slice in place.
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
                // Replace a run of digits by an interesting number.
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
                // Overwrite 4 or 8 bytes with an extreme little-endian integer (binary
                // length fields).
                let width = if rng.gen_bool(0.5) { 4 } else { 8 };
                let i = rng.gen_range(0..len.saturating_sub(width));
                let value: u64 =
                    [0, u64::MAX, u32::MAX as u64, 1 << 31, 1 << 40][rng.gen_range(0..5)];
                out[i..i + width].copy_from_slice(&value.to_le_bytes()[..width]);
            }
            7 if len > 0 => {
                out.truncate(rng.gen_range(0..len));
            }
            _ => {}
        }
    }
    out
}

/// Runs `target` on `iters` mutants of the corpus; panics are collected and reported.
fn fuzz(name: &str, corpus: &[Vec<u8>], iters: u64, seed: u64, target: impl Fn(&[u8])) {
    assert!(!corpus.is_empty(), "{name}: empty corpus");
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let started = Instant::now();
    let mut crashes = Vec::new();
    // Silence the default panic message for each caught panic; the report below has them.
    let hook = std::panic::take_hook();
    std::panic::set_hook(Box::new(|_| {}));
    for i in 0..iters {
        let base = &corpus[rng.gen_range(0..corpus.len())];
        let input = mutate(&mut rng, base);
        if catch_unwind(AssertUnwindSafe(|| target(&input))).is_err() {
            crashes.push((i, input));
        }
    }
    std::panic::set_hook(hook);
    let secs = started.elapsed().as_secs_f64();
    println!(
        "{name}: {iters} inputs in {secs:.1} s ({:.0}/s), {} panics",
        iters as f64 / secs.max(1e-9),
        crashes.len()
    );
    if !crashes.is_empty() {
        let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("fuzz-crashes");
        std::fs::create_dir_all(&dir).unwrap();
        for (i, input) in crashes.iter().take(20) {
            std::fs::write(dir.join(format!("{name}-{i}")), input).unwrap();
        }
        panic!(
            "{name}: {} inputs panicked; the first are in {}",
            crashes.len(),
            dir.display()
        );
    }
}

fn read_all(paths: &[&str]) -> Vec<Vec<u8>> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    paths
        .iter()
        .map(|p| std::fs::read(root.join(p)).unwrap())
        .collect()
}

#[test]
fn reward_machine_files() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/rm");
    let corpus: Vec<Vec<u8>> = std::fs::read_dir(&root)
        .unwrap()
        .map(|e| std::fs::read(e.unwrap().path()).unwrap())
        .collect();
    fuzz(
        "rm",
        &corpus,
        iterations("FUZZ_TEXT_ITERS", 20_000),
        1,
        |bytes| {
            let _ = parse_rm(&String::from_utf8_lossy(bytes), "fuzz.txt");
        },
    );
}

#[test]
fn office_map_files() {
    let mut corpus = read_all(&["assets/office/paper.map"]);
    corpus.push(
        b"legend:\nk = key\ng =\nmap:\n+-+-+-+\n|k . g|\n+ +-+ +\n|@|.|.|\n+-+-+-+\n".to_vec(),
    );
    fuzz(
        "office-map",
        &corpus,
        iterations("FUZZ_TEXT_ITERS", 20_000),
        4,
        |bytes| {
            // A map that parses builds a world and writes back to itself.
            if let Ok(map) = parse_map(&String::from_utf8_lossy(bytes), "fuzz.map") {
                let world = OfficeWorld::from_map(&map);
                assert_eq!(world.n_cells(), map.width() * map.height());
                assert_eq!(parse_map(&write_map(&map), "written.map").unwrap(), map);
            }
        },
    );
}

#[test]
fn configs() {
    let corpus = read_all(&[
        "experiments/reacher/config.toml",
        "experiments/reacher/quick.toml",
        "experiments/reacher/config_scripted.toml",
        "experiments/office/config.toml",
        "experiments/office/config_finite_horizon.toml",
    ]);
    let mut corpus = corpus;
    corpus.push(IrlRunConfig::standard().to_toml().into_bytes());
    corpus.push(SacConfig::expert().to_toml().into_bytes());
    corpus.push(
        b"total_steps = 1000\neval_episodes = 5\n[sac]\npreset = \"expert\"\nhidden = [64, 64]\n[env]\nmax_steps = 50\n"
            .to_vec(),
    );
    fuzz(
        "config",
        &corpus,
        iterations("FUZZ_TEXT_ITERS", 20_000),
        2,
        |bytes| {
            let text = String::from_utf8_lossy(bytes);
            let _ = IrlRunConfig::from_toml(&text, "fuzz.toml");
            let _ = ExpertConfig::from_toml(&text, "fuzz.toml");
            let _ = SacConfig::from_toml(&text, "fuzz.toml");
            let _ = OfficeConfig::from_toml(&text);
        },
    );
}

#[test]
fn mcap_logs() {
    let dir = tempfile::tempdir().unwrap();
    let mut corpus = Vec::new();
    for (k, (episodes, chunk)) in [(2u64, 1u64 << 20), (3, 4 << 10)].into_iter().enumerate() {
        let path = dir.path().join(format!("seed{k}.mcap"));
        log_scripted_demos(
            &path,
            &DemoSpec {
                task: "sequential".into(),
                sequence: "rgby".into(),
                episodes,
                seed: k as u64,
                stop_when_done: true,
                env: ReacherConfig::default(),
                reward_machine: Some(smirl::rm::perfect::load("reacher_sequential").unwrap()),
            },
            LogOptions {
                chunk_size: chunk,
                observations: k == 1,
                ..LogOptions::default()
            },
        )
        .unwrap();
        corpus.push(std::fs::read(&path).unwrap());
    }
    fuzz(
        "mcap",
        &corpus,
        iterations("FUZZ_MCAP_ITERS", 2_000),
        3,
        |bytes| {
            let _ = read_log_bytes(bytes, Path::new("fuzz.mcap"));
        },
    );
}
