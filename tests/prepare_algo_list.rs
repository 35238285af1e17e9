//! `reacher prepare`'s outputs for an algorithm do not depend on which other algorithms the
//! run prepares (the evaluation referee's A5): SMIRL's learned machine, its report, the
//! annotated demonstrations and prepare.json's facts of the machine are the same bytes with
//! `--algo smirl` as with `--algo smirl,smirl-paper,maxent-product,fkl-product`, and
//! smirl-paper's with `--algo smirl-paper` as in that list. So an arm of the evaluation that
//! runs `smirl` alone and one that runs it beside the controls learn from the same machine and
//! the same demonstrations.

mod irl_run_common;
use irl_run_common::tiny_config;
use std::path::Path;
use std::process::Command;

/// `reacher prepare` of IF (seed 3, the tiny config) for `algos` into `dir/out`.
fn prepare(dir: &Path, algos: &str, out: &str) {
    let o = Command::new(env!("CARGO_BIN_EXE_reacher"))
        .current_dir(dir)
        .args([
            "prepare",
            "--task",
            "if",
            "--algo",
            algos,
            "--seeds",
            "1",
            "--seed",
            "3",
            "--config",
            "tiny.toml",
            "--out",
            out,
            "--quiet",
        ])
        .output()
        .unwrap();
    assert!(
        o.status.success(),
        "prepare --algo {algos}: {}",
        String::from_utf8_lossy(&o.stderr)
    );
}

/// The file `name` of run `out`, its wall times blanked: the report's LRM line ends in the
/// search's seconds.
fn read(dir: &Path, out: &str, name: &str) -> Vec<u8> {
    let bytes = std::fs::read(dir.join(out).join(name)).unwrap();
    if !name.ends_with("report.txt") && !name.ends_with("report_paper.txt") {
        return bytes;
    }
    let text = String::from_utf8(bytes).unwrap();
    let lines: Vec<String> = (text.lines())
        .map(|l| match (l.starts_with("LRM cost"), l.rsplit_once(", ")) {
            (true, Some((head, secs))) => {
                assert!(secs.ends_with(" s"), "{name}: {l}");
                format!("{head}, <secs>")
            }
            _ => l.to_string(),
        })
        .collect();
    assert!(
        lines.iter().any(|l| l.ends_with("<secs>")),
        "{name}: {text}"
    );
    lines.join("\n").into_bytes()
}

/// prepare.json's field `key`, a machine's `lrm_secs` (wall time) removed.
fn prepared_field(dir: &Path, out: &str, key: &str) -> serde_json::Value {
    let text = std::fs::read_to_string(dir.join(out).join("prepare.json")).unwrap();
    let mut json: serde_json::Value = serde_json::from_str(&text).unwrap();
    let mut value = json[key].take();
    if let (true, Some(facts)) = (key.starts_with("rm"), value.as_object_mut()) {
        assert!(facts.remove("lrm_secs").is_some(), "{key}: {text}");
    }
    value
}

/// SMIRL's outputs with `--algo smirl` and with the evaluation's list; smirl-paper's with
/// `--algo smirl-paper` and with that list.
///
/// Mutation tried: SMIRL's machine learned with smirl-paper's settings whenever smirl-paper is
/// in the list (`config.for_algo(…)` in `run::prepare` given `Algo::SmirlPaper` then): fails
/// at "rm/report.txt differs".
#[test]
fn prepares_machine_and_demonstrations_do_not_depend_on_the_algorithm_list() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    std::fs::write(dir.join("tiny.toml"), tiny_config().to_toml()).unwrap();
    prepare(dir, "smirl", "alone");
    prepare(dir, "smirl,smirl-paper,maxent-product,fkl-product", "all");
    prepare(dir, "smirl-paper", "paper");

    // SMIRL's (shared by the product controls).
    for name in [
        "config.toml",
        "rm/perfect.txt",
        "rm/learned.txt",
        "rm/learned.dot",
        "rm/report.txt",
        "expert_data.bin",
        "logs/demos.mcap",
    ] {
        assert!(
            read(dir, "alone", name) == read(dir, "all", name),
            "{name} differs"
        );
    }
    for key in [
        "rm",
        "demos_kept",
        "demos_generated",
        "demo_branches",
        "seeds",
    ] {
        let alone = prepared_field(dir, "alone", key);
        assert!(!alone.is_null(), "prepare.json has {key}");
        assert_eq!(
            alone,
            prepared_field(dir, "all", key),
            "prepare.json: {key}"
        );
    }
    assert!(prepared_field(dir, "alone", "rm_paper").is_null());

    // smirl-paper's.
    for name in [
        "rm/learned_paper.txt",
        "rm/learned_paper.dot",
        "rm/report_paper.txt",
        "expert_data_paper.bin",
        "logs/demos.mcap",
    ] {
        assert!(
            read(dir, "paper", name) == read(dir, "all", name),
            "{name} differs"
        );
    }
    let paper = prepared_field(dir, "paper", "rm_paper");
    assert!(!paper.is_null());
    assert_eq!(paper, prepared_field(dir, "all", "rm_paper"));
    // Without smirl, the demonstrations carry no learned states: a file of its own.
    assert!(!dir.join("paper/rm/learned.txt").exists());
}
