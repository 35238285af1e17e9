//! The last ways to lose or silently alter data (issue 57), one regression test each; every
//! one failed on main df9c858:
//!
//! 1. `foxglove --allow-partial` copied messages of the cut-off chunk (never CRC-checked,
//!    refused by the reader) into a complete, valid-looking view;
//! 2. the view of a partial log lost `model.xml`, `config.json` and the `smirl.run` metadata;
//! 3. `render LOG --out LOG --force` replaced the log with a PNG;
//! 4. a user's `<out>.replaced` was found only after the whole run;
//! 5. refused commands left `--out` parents (`n1/n2`) and empty `--out` directories behind;
//! 6. a log without its closing magic passed `replay --verify`, `learn-rm` and `render` but
//!    not `foxglove`;
//! 7. `demo --task nope` ran; RM-file errors echoed NUL and BOM raw and quoted 4 000-character
//!    formulas and 300-digit numbers whole.

use smirl::env::reacher::ReacherConfig;
use smirl::log::demo::{log_scripted_demos, DemoSpec};
use smirl::log::{read_log, read_log_bytes, LogOptions};
use smirl::output::{OutputDir, MARKER};
use smirl::rm::format::parse_rm;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn reacher(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_reacher"))
        .args(args)
        .output()
        .unwrap()
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// A demonstration log of `episodes` episodes in chunks of 8 KiB (several chunks), with the
/// task's machine tracked.
fn demo_log(dir: &Path, episodes: u64) -> PathBuf {
    let path = dir.join("demo.mcap");
    log_scripted_demos(
        &path,
        &DemoSpec {
            task: "sequential".into(),
            sequence: "rgby".into(),
            episodes,
            seed: 3,
            stop_when_done: true,
            env: ReacherConfig::default(),
            event_probability: None,
            reward_machine: Some(smirl::rm::perfect::load("reacher_sequential").unwrap()),
        },
        LogOptions {
            chunk_size: 8 << 10,
            ..LogOptions::default()
        },
    )
    .unwrap();
    path
}

/// (offset, total length) of the top-level records with `opcode`.
fn records(bytes: &[u8], opcode: u8) -> Vec<(usize, usize)> {
    let mut at = mcap::MAGIC.len();
    let mut found = Vec::new();
    while at + 9 <= bytes.len() {
        let len = u64::from_le_bytes(bytes[at + 1..at + 9].try_into().unwrap()) as usize;
        if bytes[at] == opcode {
            found.push((at, 9 + len));
        }
        at += 9 + len;
    }
    found
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

#[test]
fn a_foxglove_view_of_a_partial_log_holds_exactly_what_the_reader_recovers() {
    let dir = tempfile::tempdir().unwrap();
    let log = demo_log(dir.path(), 20);
    let good = std::fs::read(&log).unwrap();
    let chunks = records(&good, mcap::records::op::CHUNK);
    assert!(chunks.len() >= 4, "{} chunks", chunks.len());
    // Cut inside the third chunk and damage its compressed data before the cut: the reader
    // drops that chunk whole (it never reaches its CRC); a copy must not take it either.
    let (at, len) = chunks[2];
    let cut_at = at + len / 2;
    let mut bad = good[..cut_at].to_vec();
    for k in (at + 60..cut_at).step_by(97) {
        bad[k] ^= 0x5a;
    }
    let bad_path = dir.path().join("bad.mcap");
    std::fs::write(&bad_path, &bad).unwrap();
    let recovered = read_log_bytes(&bad, &bad_path).unwrap();
    assert!(recovered.recovery.is_some() && !recovered.episodes.is_empty());

    let view = dir.path().join("view.mcap");
    let o = reacher(&[
        "foxglove",
        "--allow-partial",
        s(&bad_path),
        "--out",
        s(&view),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let copy = read_log(&view).unwrap();
    assert_eq!(
        copy.episodes, recovered.episodes,
        "the view adds or alters steps"
    );
    // Issue 57's two: the view keeps the attachments and the run metadata.
    assert_eq!(copy.model_xml, recovered.model_xml);
    assert!(copy.model_xml.is_some() && copy.config_json.is_some());
    assert_eq!(copy.config_json, recovered.config_json);
    assert_eq!(copy.metadata, recovered.metadata);
    assert!(!copy.metadata.is_empty());
    let o = reacher(&["replay", "--verify", s(&view)]);
    assert!(o.status.success(), "{}", stderr(&o));

    // Cut inside the first chunk of episode data (the first chunk holds the run record, with
    // the task file's text): the log is readable, no episode is recoverable, and the view is
    // refused.
    let first = chunks.iter().filter(|&&(_, l)| l > 2000).nth(1).unwrap();
    let none = dir.path().join("none.mcap");
    std::fs::write(&none, &good[..first.0 + first.1 / 2]).unwrap();
    let view2 = dir.path().join("view2.mcap");
    let o = reacher(&["foxglove", "--allow-partial", s(&none), "--out", s(&view2)]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(stderr(&o).contains("no episode"), "{}", stderr(&o));
    assert!(!view2.exists());
}

#[test]
fn a_command_never_writes_over_its_input_even_with_force() {
    let dir = tempfile::tempdir().unwrap();
    let log = demo_log(dir.path(), 2);
    let original = std::fs::read(&log).unwrap();
    let link = dir.path().join("link.mcap");
    std::os::unix::fs::symlink(&log, &link).unwrap();
    let hard = dir.path().join("hard.mcap");
    std::fs::hard_link(&log, &hard).unwrap();
    let dotted = dir.path().join(".").join("demo.mcap");
    for (input, out) in [
        (&log, &log),
        (&link, &log),
        (&log, &link),
        (&hard, &log),
        (&dotted, &log),
    ] {
        for command in ["render", "foxglove"] {
            let o = reacher(&[command, s(input), "--out", s(out), "--force"]);
            assert_eq!(
                o.status.code(),
                Some(2),
                "{command} {input:?} {out:?}: {}",
                stderr(&o)
            );
            assert!(stderr(&o).contains("input"), "{}", stderr(&o));
        }
    }
    // learn-rm's outputs are files in --out: one of them may be the log or the --compare file.
    std::fs::copy(&log, dir.path().join("learned_rm.txt")).unwrap();
    let o = reacher(&[
        "learn-rm",
        s(&dir.path().join("learned_rm.txt")),
        "--out",
        s(dir.path()),
        "--force",
    ]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert_eq!(std::fs::read(&log).unwrap(), original);
    assert_eq!(
        std::fs::read(dir.path().join("learned_rm.txt")).unwrap(),
        original
    );
}

#[test]
fn a_users_replaced_directory_is_refused_before_any_work() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("m");
    // An earlier output of this program, and a user's directory at `<out>.replaced`.
    std::fs::create_dir(&out).unwrap();
    std::fs::write(out.join(MARKER), "").unwrap();
    let aside = dir.path().join("m.replaced");
    std::fs::create_dir(&aside).unwrap();
    std::fs::write(aside.join("x"), "mine").unwrap();
    let e = OutputDir::check(&out, true).unwrap_err();
    assert!(e.to_string().contains("m.replaced"), "{e}");

    let o = Command::new(env!("CARGO_BIN_EXE_office"))
        .args([
            "--task",
            "0",
            "--algo",
            "smirl",
            "--seeds",
            "1",
            "--out",
            s(&out),
        ])
        .arg("--force")
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(!dir.path().join("m.partial").exists(), "work was started");
    assert_eq!(std::fs::read_to_string(aside.join("x")).unwrap(), "mine");
}

#[test]
fn a_refused_command_leaves_no_directories_behind() {
    let dir = tempfile::tempdir().unwrap();
    let empty = dir.path().join("empty.mcap");
    std::fs::write(&empty, b"").unwrap();
    let o = reacher(&[
        "render",
        s(&empty),
        "--out",
        s(&dir.path().join("n1/n2/x.png")),
    ]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(!dir.path().join("n1").exists(), "render left n1/n2");

    let log = demo_log(dir.path(), 2);
    let bad = dir.path().join("bad_rm.txt");
    std::fs::write(&bad, "states: 2\n(0, 1, 'r&', 1)\n").unwrap();
    let out = dir.path().join("learned");
    let o = reacher(&["learn-rm", s(&log), "--out", s(&out), "--compare", s(&bad)]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(!out.exists(), "learn-rm left an empty --out");

    // A command that succeeds still creates the parents it needs.
    let deep = dir.path().join("a/b/x.png");
    let o = reacher(&["render", s(&log), "--out", s(&deep)]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(deep.is_file());
}

#[test]
fn a_log_without_its_closing_magic_is_cut_short_for_every_command() {
    let dir = tempfile::tempdir().unwrap();
    let log = demo_log(dir.path(), 3);
    let good = std::fs::read(&log).unwrap();
    for cut in [1, 4, 8] {
        let path = dir.path().join(format!("cut{cut}.mcap"));
        std::fs::write(&path, &good[..good.len() - cut]).unwrap();
        let read = read_log(&path).unwrap();
        assert!(read.recovery.is_some(), "cut {cut}: read as complete");
        let p = s(&path);
        let out = dir.path().join(format!("out{cut}"));
        let png = out.join("x.png");
        let view = out.join("v.mcap");
        for args in [
            vec!["replay", "--verify", p],
            vec!["learn-rm", p, "--out", s(&out)],
            vec!["render", p, "--out", s(&png)],
            vec!["foxglove", p, "--out", s(&view)],
        ] {
            let o = reacher(&args);
            assert_eq!(o.status.code(), Some(1), "{args:?}: {}", stderr(&o));
            assert!(
                stderr(&o).contains("incomplete"),
                "{args:?}: {}",
                stderr(&o)
            );
        }
        for args in [
            vec!["replay", "--verify", "--allow-partial", p],
            vec!["render", "--allow-partial", p, "--out", s(&png)],
            vec!["foxglove", "--allow-partial", p, "--out", s(&view)],
        ] {
            let o = reacher(&args);
            assert!(o.status.success(), "{args:?}: {}", stderr(&o));
        }
        assert_eq!(read_log(&view).unwrap().episodes, read.episodes);
    }
}

#[test]
fn demo_refuses_an_unknown_task() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("d.mcap");
    let o = reacher(&[
        "demo",
        "--task",
        "nope",
        "--out",
        s(&out),
        "--episodes",
        "1",
    ]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("nope"));
    assert!(!out.exists());
}

#[test]
fn rm_file_errors_name_invisible_characters_and_stay_short() {
    const OR: &str =
        "vocabulary: rgbyc\nstates: 3\ninitial: 0\nterminal: 2\n(0, 1, 'r|g', 0)\n(1, 2, 'b', 1)\n";
    let bom = format!("\u{feff}{OR}");
    let e = parse_rm(&bom, "bom.txt").unwrap_err().to_string();
    assert!(e.contains("U+FEFF") && !e.contains('\u{feff}'), "{e}");
    for nul in [
        OR.replace("states: 3", "states: \0"),
        OR.replace("'r|g'", "'r|\0'"),
        OR.replace("rgbyc", "rgb\0c"),
        OR.replace("(1, 2, 'b', 1)", "(1, 2, 'b', 1\0)"),
    ] {
        let e = parse_rm(&nul, "nul.txt").unwrap_err().to_string();
        assert!(e.contains("NUL") && !e.contains('\0'), "{e:?}");
    }
    let long = format!(
        "{}(0, 1, '{}x', 0)\n",
        OR.replace("(0, 1, 'r|g', 0)\n", ""),
        "r|".repeat(2000)
    );
    let e = parse_rm(&long, "long.txt").unwrap_err().to_string();
    assert!(e.len() < 400, "{} characters: {e}", e.len());
    let huge = OR.replace("'b', 1)", &format!("'b', 1{})", "0".repeat(400)));
    let e = parse_rm(&huge, "huge.txt").unwrap_err().to_string();
    assert!(e.len() < 400, "{} characters: {e}", e.len());

    let config = ReacherConfig {
        ball_layout: Some(vec![[1e300, 0.0]]),
        ..Default::default()
    };
    let e = config.validate().unwrap_err().to_string();
    assert!(e.contains("1e300") && e.len() < 120, "{e}");
}
