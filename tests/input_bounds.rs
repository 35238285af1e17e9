//! Every size read from a config, the command line or a file is bounded (issue 16).
//! Regression tests: on the previous main each of these aborted on an allocation, ran out of
//! memory, overflowed the stack or failed only at run time; each must now be refused at
//! validation with the file, the key's line and the limit.

use smirl::config_text::MAX_TEXT_FILE_BYTES;
use smirl::pipeline::reacher_expert::ExpertConfig;
use smirl::pipeline::reacher_irl::IrlRunConfig;
use smirl::rm::format::{parse_rm, read_rm};
use std::process::Command;

const CONFIG: &str = include_str!("../experiments/reacher/config.toml");

/// The committed config with the line `key = …` (first match) replaced by `replacement`.
fn with_line(key: &str, replacement: &str) -> String {
    let mut done = false;
    let lines: Vec<String> = CONFIG
        .lines()
        .map(|l| {
            if !done && l.split('=').next().unwrap().trim() == key {
                done = true;
                replacement.to_string()
            } else {
                l.to_string()
            }
        })
        .collect();
    assert!(done, "no line for {key}");
    lines.join("\n") + "\n"
}

fn line_of(text: &str, needle: &str) -> usize {
    text.lines().position(|l| l.starts_with(needle)).unwrap() + 1
}

#[test]
fn oversized_irl_configs_name_the_key_its_line_and_the_limit() {
    let cases = [
        ("max_states", "max_states = 1000", "lrm.max_states", "100"),
        (
            "replay_capacity",
            "replay_capacity = 1000000000000000",
            "sac.replay_capacity",
            "4000000",
        ),
        (
            "sac_steps",
            "sac_steps = 1000000000",
            "final.sac_steps",
            "100000000",
        ),
        (
            "tabu_len",
            "tabu_len = 1000000000",
            "lrm.tabu_len",
            "1000000",
        ),
        (
            "demo_episodes",
            "demo_episodes = 1000000",
            "demo_episodes",
            "10000",
        ),
        (
            "agent_trajectories",
            "agent_trajectories = 1000000",
            "agent_trajectories",
            "10000000",
        ),
        ("threads", "threads = 100000", "threads", "256"),
    ];
    for (key, line, field, limit) in cases {
        let text = with_line(key, line);
        let e = IrlRunConfig::from_toml(&text, "bad.toml")
            .unwrap_err()
            .to_string();
        let at = format!("line {}", line_of(&text, line));
        for needle in ["bad.toml", &at, &format!("`{field}`"), limit] {
            assert!(e.contains(needle), "{line}: expected {needle:?} in: {e}");
        }
    }
    // The optional episode length (absent from the committed config) is bounded too.
    let line = "episode_steps = 1000000000000";
    let text = with_line("[env]", &format!("[env]\n{line}"));
    let e = IrlRunConfig::from_toml(&text, "bad.toml")
        .unwrap_err()
        .to_string();
    let at = format!("line {}", line_of(&text, line));
    for needle in ["bad.toml", &at, "`env.episode_steps`", "10000"] {
        assert!(e.contains(needle), "{line}: expected {needle:?} in: {e}");
    }
    // A key of a table is required like any other.
    let text = with_line("warmup_steps", "");
    let e = IrlRunConfig::from_toml(&text, "bad.toml")
        .unwrap_err()
        .to_string();
    assert!(e.contains("missing field `warmup_steps`"), "{e}");
    // A missing top-level key is not blamed on line 1.
    let text = with_line("threads", "");
    let e = IrlRunConfig::from_toml(&text, "bad.toml")
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("missing field `threads`") && !e.contains("line 1"),
        "{e}"
    );
}

#[test]
fn oversized_expert_configs_name_the_key_and_line() {
    let text = "total_steps = 1000\n[sac]\nbatch_size = 64\nhidden = [1000000]\n";
    let e = ExpertConfig::from_toml(text, "expert.toml")
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("line 4") && e.contains("sac.hidden") && e.contains("4096"),
        "{e}"
    );
    let text = "total_steps = 1000\n[env]\nmax_steps = 1000000000000\n";
    let e = ExpertConfig::from_toml(text, "expert.toml")
        .unwrap_err()
        .to_string();
    assert!(e.contains("line 3") && e.contains("env.max_steps"), "{e}");
}

#[test]
fn the_cli_refuses_oversized_configs_and_seed_counts_with_exit_2() {
    let tmp = tempfile::tempdir().unwrap();
    let bad = tmp.path().join("bad.toml");
    std::fs::write(
        &bad,
        with_line("replay_capacity", "replay_capacity = 1000000000000000"),
    )
    .unwrap();
    let out = tmp.path().join("run");
    let o = Command::new(env!("CARGO_BIN_EXE_reacher"))
        .args(["--task", "or", "--config", bad.to_str().unwrap()])
        .args(["--out", out.to_str().unwrap(), "--quiet"])
        .output()
        .unwrap();
    assert_eq!(
        o.status.code(),
        Some(2),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    assert!(String::from_utf8_lossy(&o.stderr).contains("sac.replay_capacity"));
    assert!(!out.exists());

    let o = Command::new(env!("CARGO_BIN_EXE_office"))
        .args(["--task", "3", "--seeds", "99999999999"])
        .args(["--out", out.to_str().unwrap()])
        .output()
        .unwrap();
    assert_eq!(
        o.status.code(),
        Some(2),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    assert!(!out.exists());

    // A config larger than the text-file limit is refused before it is read.
    let big = tmp.path().join("big.toml");
    std::fs::write(&big, "#".repeat(MAX_TEXT_FILE_BYTES as usize + 1)).unwrap();
    let o = Command::new(env!("CARGO_BIN_EXE_reacher"))
        .args(["--task", "or", "--config", big.to_str().unwrap()])
        .args(["--out", out.to_str().unwrap(), "--quiet"])
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("limit"));
}

#[test]
fn reward_machine_files_cannot_exhaust_the_stack_or_memory() {
    let head = "vocabulary: rgbyc\nstates: 2\ninitial: 0\n";
    let deep = format!(
        "{head}(0, 1, '{}r{}', 1)\n",
        "(".repeat(20_000),
        ")".repeat(20_000)
    );
    let bangs = format!("{head}(0, 1, '{}r', 1)\n", "!".repeat(50_000));
    let nested = format!(
        "{head}(0, 1, '{}r{}', 1)\n",
        "(".repeat(100),
        ")".repeat(100)
    );
    let huge = "vocabulary: rgbyc\nstates: 18446744073709551615\ninitial: 0\n";
    let large = "vocabulary: rgbyc\nstates: 100000000\ninitial: 0\n";
    let many = format!("{head}{}", "(0, 0, 'r', 0)\n".repeat(10_001));
    for (text, needle) in [
        (deep.as_str(), "limit of 4096 characters"),
        (bangs.as_str(), "limit of 4096 characters"),
        (nested.as_str(), "nested more than 64"),
        (huge, "limit of 1000"),
        (large, "limit of 1000"),
        (many.as_str(), "limit of 10000 transitions"),
    ] {
        let e = parse_rm(text, "bad_rm.txt").unwrap_err().to_string();
        assert!(e.contains("bad_rm.txt") && e.contains(needle), "{e}");
    }
    // Depth 64 is still read.
    let ok = format!("{head}(0, 1, '{}r{}', 1)\n", "(".repeat(60), ")".repeat(60));
    assert!(parse_rm(&ok, "ok.txt").is_ok());

    let tmp = tempfile::tempdir().unwrap();
    let big = tmp.path().join("big_rm.txt");
    std::fs::write(&big, "#".repeat(MAX_TEXT_FILE_BYTES as usize + 1)).unwrap();
    let e = read_rm(&big).unwrap_err().to_string();
    assert!(e.contains("big_rm.txt") && e.contains("limit"), "{e}");
}

/// Regression (issue 57, found by the supervised fuzzer): a linear RM reward file declaring
/// 10^12 states aborted on allocating its weights before the weight count was checked.
#[test]
fn a_linear_reward_file_with_a_huge_state_count_is_refused_without_allocating() {
    let text = std::fs::read_to_string(
        std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("tests/fuzz_corpus/reward_smirl_seed0.json"),
    )
    .unwrap();
    let start = text.find("\"n_states\": ").unwrap() + "\"n_states\": ".len();
    let end = start + text[start..].find(',').unwrap();
    let huge = format!("{}1000000000000{}", &text[..start], &text[end..]);
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("reward.json");
    std::fs::write(&path, huge).unwrap();
    let e = smirl::irl::smirl::LinearRmReward::load(
        &path,
        smirl::irl::reward::RewardOptimConfig::adam(1e-3),
    )
    .err()
    .expect("refused");
    assert!(e.to_string().contains("weight vectors"), "{e}");
    // The unchanged file still loads.
    std::fs::write(&path, &text).unwrap();
    assert!(smirl::irl::smirl::LinearRmReward::load(
        &path,
        smirl::irl::reward::RewardOptimConfig::adam(1e-3)
    )
    .is_ok());
}
