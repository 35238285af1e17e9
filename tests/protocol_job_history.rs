//! experiments/protocol/job_history.py: every start of a protocol's jobs and how it ended, read
//! from the ledger alone, with no score. A start with no end entry before the next session's
//! first entry is `cut` (the session ended under it); the last session's open start is
//! `running`; a failure without a start of its own (used up starts, failed prepare) is a row of
//! its own. Mutation tried: the `session` branch not closing the open starts (they stay
//! `running`) fails `each_start_gets_its_end_and_no_score_is_printed`.

use std::path::Path;
use std::process::{Command, Output};

const SCORE: &str = "0.123457";

fn python_has_tomllib() -> bool {
    Command::new("python3")
        .args(["-c", "import tomllib"])
        .output()
        .is_ok_and(|o| o.status.success())
}

/// A checkout holding run.py and job_history.py, and `ledger` as protocol `p`'s ledger.
fn checkout(root: &Path, ledger: Option<&str>) {
    let scripts = root.join("experiments/protocol");
    std::fs::create_dir_all(scripts.join("p")).unwrap();
    let here = Path::new(env!("CARGO_MANIFEST_DIR")).join("experiments/protocol");
    for f in ["run.py", "job_history.py"] {
        std::fs::copy(here.join(f), scripts.join(f)).unwrap();
    }
    if let Some(text) = ledger {
        std::fs::write(scripts.join("p/ledger.jsonl"), text).unwrap();
    }
}

fn history(root: &Path, args: &[&str]) -> Output {
    Command::new("python3")
        .arg(root.join("experiments/protocol/job_history.py"))
        .arg("p")
        .args(args)
        .output()
        .unwrap()
}

fn rows(o: &Output) -> Vec<Vec<String>> {
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    String::from_utf8_lossy(&o.stdout)
        .lines()
        .skip(2)
        .take_while(|l| l.starts_with("| "))
        .map(|l| {
            l.trim_matches('|')
                .split(" | ")
                .map(|c| c.trim().to_string())
                .collect()
        })
        .collect()
}

/// (directory, seed, attempt, outcome) of each row.
fn outcomes(rows: &[Vec<String>]) -> Vec<(String, String, String, String)> {
    rows.iter()
        .map(|r| (r[0].clone(), r[2].clone(), r[4].clone(), r[6].clone()))
        .collect()
}

fn ledger() -> String {
    let d = "runs/protocol/p/or-b1";
    let done = format!(
        r#"{{"event":"done","dir":"{d}","algo":"fkl","seed":2,"sha256":"ab","job":{{"loop":[{SCORE}]}},"at":"T3"}}"#
    );
    [
        r#"{"event":"session","parallel":2,"at":"S1"}"#.to_string(),
        format!(r#"{{"event":"start","dir":"{d}","algo":"fkl","seed":1,"attempt":1,"threads":1,"at":"T1"}}"#),
        format!(r#"{{"event":"start","dir":"{d}","algo":"fkl","seed":2,"attempt":1,"threads":1,"at":"T2"}}"#),
        done,
        r#"{"event":"session","parallel":2,"at":"S2"}"#.to_string(),
        format!(r#"{{"event":"start","dir":"{d}","algo":"fkl","seed":1,"attempt":2,"threads":1,"at":"T4"}}"#),
        format!(r#"{{"event":"killed","dir":"{d}","algo":"fkl","seed":1,"signal":15,"at":"T5"}}"#),
        r#"{"event":"session","parallel":2,"at":"S3"}"#.to_string(),
        format!(r#"{{"event":"start","dir":"{d}","algo":"fkl","seed":1,"attempt":3,"threads":1,"at":"T6"}}"#),
        r#"{"event":"session","parallel":2,"at":"S4"}"#.to_string(),
        format!(r#"{{"event":"failed","dir":"{d}","algo":"fkl","seed":1,"why":"started 3 times without finishing","at":"T7"}}"#),
        r#"{"event":"failed","dir":"runs/protocol/p/if-b1","algo":"maxent","seed":1,"why":"prepare","at":"T8"}"#.to_string(),
        format!(r#"{{"event":"start","dir":"{d}","algo":"fkl","seed":3,"attempt":1,"threads":1,"at":"T9"}}"#),
    ]
    .join("\n")
        + "\n"
}

fn row(dir: &str, seed: u64, attempt: &str, outcome: &str) -> (String, String, String, String) {
    (
        dir.to_string(),
        seed.to_string(),
        attempt.to_string(),
        outcome.to_string(),
    )
}

#[test]
fn each_start_gets_its_end_and_no_score_is_printed() {
    if !python_has_tomllib() {
        eprintln!("SKIPPED: python3 >= 3.11 (tomllib) is not available");
        return;
    }
    let tmp = tempfile::tempdir().unwrap();
    checkout(tmp.path(), Some(&ledger()));
    let o = history(tmp.path(), &[]);
    assert!(!String::from_utf8_lossy(&o.stdout).contains(SCORE));
    let all = rows(&o);
    let expected = vec![
        row("or-b1", 1, "1", "cut"),
        row("or-b1", 2, "1", "done"),
        row("or-b1", 1, "2", "killed"),
        row("or-b1", 1, "3", "cut"),
        row("or-b1", 1, "—", "failed"),
        row("if-b1", 1, "—", "failed"),
        row("or-b1", 3, "1", "running"),
    ];
    assert_eq!(outcomes(&all), expected);
    // A cut start names the session it ran in and the one after it; a kill its signal.
    assert!(all[0][7].contains("began at S1") && all[0][7].contains("next began at S2"));
    assert_eq!(all[2][7], "signal 15");
    assert_eq!(all[4][7], "started 3 times without finishing");
    assert_eq!((all[1][3].as_str(), all[1][5].as_str()), ("T2", "T3"));

    // --failed: every row of the jobs whose last outcome is a failure (both seed 1's).
    let failed = outcomes(&rows(&history(tmp.path(), &["--failed"])));
    let seed_1: Vec<_> = expected.into_iter().filter(|r| r.1 == "1").collect();
    assert_eq!(failed, seed_1);
    // --cut: the jobs a session's end cut, whatever their last outcome.
    let cut = outcomes(&rows(&history(tmp.path(), &["--cut"])));
    assert_eq!(cut.len(), 4);
    assert!(cut.iter().all(|r| r.1 == "1" && r.0 == "or-b1"));
}

#[test]
fn a_protocol_without_a_ledger_is_refused_naming_it() {
    if !python_has_tomllib() {
        eprintln!("SKIPPED: python3 >= 3.11 (tomllib) is not available");
        return;
    }
    let tmp = tempfile::tempdir().unwrap();
    checkout(tmp.path(), None);
    let o = history(tmp.path(), &[]);
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("experiments/protocol/p/ledger.jsonl does not exist"),
        "{err}"
    );
}
