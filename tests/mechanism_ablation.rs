//! The development-range ablation of SMIRL's mechanisms outside LRM (`src/bin/smirl_ablation.rs`,
//! `experiments/reacher/mechanisms/`): each mechanism it turns off changes the job, and a run
//! without the final phase, the reset agent or the selection cut reports what the table reads
//! for it from the job with every mechanism on.

mod irl_run_common;

use irl_run_common::tiny_config;
use smirl::pipeline::reacher_irl::final_policy::{FinalAgent, FinalPolicy};
use smirl::pipeline::reacher_irl::records::JobRecord;
use std::path::Path;
use std::process::Command;

const SEED: &str = "2";

fn record(path: &Path) -> JobRecord {
    serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

/// The first candidate of highest `value`, as the final phase chooses.
fn first_best(final_policy: &FinalPolicy, value: impl Fn(usize) -> f64) -> usize {
    (0..final_policy.candidates.len())
        .fold(0, |best, i| if value(i) > value(best) { i } else { best })
}

fn ablate(run: &Path, mechanism: &str) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_smirl_ablation"))
        .arg("--run")
        .arg(run)
        .args(["--seed", SEED, "--without", mechanism])
        .output()
        .unwrap()
}

/// Mutations tried: `without` leaving the config as it is for `event_gated_visits` (fails at
/// "event_gated_visits changes the job"); `IrlRunConfig::selection_cut` true whatever
/// `Mechanisms::selection_cut` says (fails: the ablated candidates still have a cut return).
#[test]
fn each_mechanism_off_changes_the_job_and_the_ones_read_match_the_standard_job() {
    let tmp = tempfile::tempdir().unwrap();
    let cfg = tmp.path().join("tiny.toml");
    let mut config = tiny_config();
    // A reset agent, so that reading its ablation from the standard job is tested.
    config.final_reset_steps = 140;
    std::fs::write(&cfg, config.to_toml()).unwrap();
    let run = tmp.path().join("run");
    let reacher = |args: &[&str]| {
        let status = Command::new(env!("CARGO_BIN_EXE_reacher"))
            .args(args)
            .status()
            .unwrap();
        assert!(status.success(), "reacher {args:?}");
    };
    let (cfg_s, run_s) = (cfg.to_str().unwrap(), run.to_str().unwrap());
    reacher(&[
        "prepare",
        "--task",
        "composite",
        "--algo",
        "smirl",
        "--seed",
        SEED,
        "--config",
        cfg_s,
        "--out",
        run_s,
        "--quiet",
    ]);
    reacher(&[
        "job", "--run", run_s, "--algo", "smirl", "--seed", SEED, "--quiet",
    ]);
    let standard = record(&run.join("jobs/smirl_seed2.json"));
    let standard_reward = std::fs::read(run.join("rewards/smirl_seed2.json")).unwrap();

    for mechanism in [
        "clock",
        "counterfactual_states",
        "event_gated_visits",
        "shaping",
    ] {
        let out = ablate(&run, mechanism);
        assert!(out.status.success(), "{mechanism}: {out:?}");
        let dir = run.join("ablation").join(mechanism);
        let ablated = record(&dir.join("jobs/smirl_seed2.json"));
        let reward = std::fs::read(dir.join("rewards/smirl_seed2.json")).unwrap();
        assert!(
            reward != standard_reward
                || serde_json::to_string(&ablated.rows).unwrap()
                    != serde_json::to_string(&standard.rows).unwrap(),
            "{mechanism} changes the job"
        );
    }
    // The standard job is untouched by its ablations.
    assert_eq!(
        std::fs::read(run.join("rewards/smirl_seed2.json")).unwrap(),
        standard_reward
    );

    let out = ablate(&run, "selection_cut");
    assert!(out.status.success(), "{out:?}");
    let uncut = record(&run.join("ablation/selection_cut/jobs/smirl_seed2.json"));
    let (with, without) = (
        standard.final_policy.as_ref().unwrap(),
        uncut.final_policy.as_ref().unwrap(),
    );
    // The same loop and the same candidates; only what the choice reads differs.
    assert_eq!(
        serde_json::to_string(&uncut.rows).unwrap(),
        serde_json::to_string(&standard.rows).unwrap()
    );
    assert_eq!(with.candidates.len(), without.candidates.len());
    for (a, b) in with.candidates.iter().zip(&without.candidates) {
        assert_eq!(a.learned_return, b.learned_return);
        assert_eq!(a.final_set, b.final_set);
        assert!(a.cut_return.is_some() && b.cut_return.is_none());
    }
    assert_eq!(
        with.chosen,
        first_best(with, |i| with.candidates[i].selection_return())
    );
    assert_eq!(
        without.chosen,
        first_best(with, |i| with.candidates[i].learned_return),
        "without the cut the choice reads the learned return"
    );

    // Without the reset agent: the same loop and the co-trained candidates, chosen among
    // as the table reads them from the standard job.
    assert!(ablate(&run, "reset_agent").status.success());
    let no_reset = record(&run.join("ablation/reset_agent/jobs/smirl_seed2.json"));
    let no_reset_final = no_reset.final_policy.as_ref().unwrap();
    let co_trained: Vec<_> = with
        .candidates
        .iter()
        .filter(|c| c.agent == FinalAgent::CoTrained)
        .collect();
    assert!(
        co_trained.len() < with.candidates.len(),
        "the standard job has a reset agent"
    );
    assert_eq!(
        serde_json::to_string(&no_reset.rows).unwrap(),
        serde_json::to_string(&standard.rows).unwrap()
    );
    assert_eq!(no_reset_final.candidates.len(), co_trained.len());
    for (a, b) in co_trained.iter().zip(&no_reset_final.candidates) {
        assert_eq!(
            (a.learned_return, a.cut_return),
            (b.learned_return, b.cut_return)
        );
        assert_eq!(a.final_set, b.final_set);
    }
    assert_eq!(
        no_reset_final.chosen,
        first_best(no_reset_final, |i| co_trained[i].selection_return())
    );

    // Without the final phase: the same loop, and the loop's own policy is the report.
    assert!(ablate(&run, "final_phase").status.success());
    let no_final = record(&run.join("ablation/final_phase/jobs/smirl_seed2.json"));
    assert_eq!(
        serde_json::to_string(&no_final.rows).unwrap(),
        serde_json::to_string(&standard.rows).unwrap()
    );
    assert!(no_final.final_policy.is_none());
    assert_eq!(no_final.loop_final_set, standard.loop_final_set);

    // Several at once, in one directory named by them in a fixed order.
    assert!(ablate(&run, "selection_cut,shaping").status.success());
    assert!(run
        .join("ablation/shaping+selection_cut/jobs/smirl_seed2.json")
        .is_file());

    // A name that is not a mechanism, or one named twice, is refused before any work.
    for bad in ["random_pick", "clock,clock"] {
        let out = ablate(&run, bad);
        assert!(!out.status.success(), "{bad}");
        assert!(String::from_utf8_lossy(&out.stderr).contains(bad), "{bad}");
    }
    assert!(!run.join("ablation/random_pick").exists());
}

/// A final-set score whose lower branch is `lower` (the other branch solved).
fn final_set(lower: f64) -> serde_json::Value {
    let k = (lower * 50.0).round() as u64;
    serde_json::json!({
        "episodes": 100, "success_rate": (50 + k) as f64 / 100.0, "progress": 0.0,
        "final_ball": 0.0, "branches": {"episodes": [50, 50], "successes": [50, k]}
    })
}

/// Writes `events` as the ablation's ledger: gzip-compressed JSON lines (compressed by
/// Python's gzip, as `ablation.py` reads and writes it).
fn write_ledger(path: &Path, events: &[serde_json::Value]) {
    let plain = path.with_extension("plain");
    let text: String = events.iter().map(|e| format!("{e}\n")).collect();
    std::fs::write(&plain, text).unwrap();
    let out = Command::new("python3")
        .args([
            "-c",
            "import gzip, shutil, sys; shutil.copyfileobj(open(sys.argv[1], 'rb'), gzip.open(sys.argv[2], 'wb'))",
        ])
        .arg(&plain)
        .arg(path)
        .output()
        .unwrap();
    assert!(out.status.success(), "{out:?}");
}

/// A job record with three candidates, whose choice the table reads again: (agent, learned
/// return, cut return, score) each; the job chose the highest cut return.
fn fake_record(seed: u64, loop_score: f64, chosen_score: Option<f64>) -> serde_json::Value {
    let mut candidates: Vec<serde_json::Value> = [
        ("co-trained", 1.0, 0.5, 0.0),
        ("co-trained", 0.8, 0.8, 1.0),
        ("reset", 0.9, 0.9, 1.0),
    ]
    .iter()
    .map(|&(agent, learned, cut, score)| {
        serde_json::json!({
            "agent": agent, "env_steps": 0, "learned_return": learned, "cut_return": cut,
            "success_rate": score, "branches": null, "progress": 0.0, "final_ball": 0.0,
            "final_set": final_set(score)
        })
    })
    .collect();
    if let Some(score) = chosen_score {
        candidates[2]["final_set"] = final_set(score);
    }
    serde_json::json!({
        "algo": "smirl", "seed": seed, "rows": [], "wall_secs": 1.0,
        "loop_final_set": final_set(loop_score),
        "final_policy": {"candidates": candidates, "chosen": 2}
    })
}

/// `ablation.py table` reads each mechanism's ablation from the right policy and applies the
/// plan's two-stage rule: on hand-made records of both stages where turning the clock off, the
/// final phase or the cut loses every pair, the reset agent and shaping none, counterfactual
/// states one, and one job failed; then the mechanisms that go, turned off together.
///
/// Mutations tried: the reset agent's ablation choosing by learned return instead of the cut
/// return (fails at the reset agent's row); the lower branch read as `success_rate` (fails at
/// the clock's row); a failed job taken for one not run yet (fails: stage 1 never completes).
#[test]
fn the_ablation_table_reads_each_mechanism_from_its_policy_and_applies_the_rule() {
    let tmp = tempfile::tempdir().unwrap();
    let ledger = tmp.path().join("ledger.jsonl.gz");
    let events = std::cell::RefCell::new(Vec::new());
    let done = |task: &str, base: u64, job: &str, record: serde_json::Value| {
        events.borrow_mut().push(serde_json::json!({
            "event": "done", "task": task, "base": base, "job": job, "record": record
        }));
    };
    let tasks = ["or", "sequential", "if", "composite"];
    let stage_1 = [10u64, 20, 30, 40, 50, 60];
    let stage_2 = [70u64, 80, 90, 100, 153, 219];
    let write_stage = |bases: &[u64]| {
        for task in tasks {
            for &base in bases {
                done(task, base, "standard", fake_record(base, 0.0, None));
                done(task, base, "second_draw", fake_record(base + 1, 0.0, None));
                let off = |mechanism: &str, score: f64| {
                    done(
                        task,
                        base,
                        &format!("without_{mechanism}"),
                        fake_record(base, 0.0, Some(score)),
                    );
                };
                off("clock", 0.0);
                off("shaping", 1.0);
                off(
                    "counterfactual_states",
                    if (task, base) == ("if", 30) { 0.5 } else { 1.0 },
                );
                if (task, base) != ("composite", 60) {
                    off("event_gated_visits", 1.0);
                }
            }
        }
    };
    let table = || {
        write_ledger(&ledger, &events.borrow());
        let out = Command::new("python3")
            .arg(concat!(
                env!("CARGO_MANIFEST_DIR"),
                "/experiments/reacher/mechanisms/ablation.py"
            ))
            .args(["table", "--ledger"])
            .arg(&ledger)
            .arg("--out")
            .arg(tmp.path())
            .output()
            .unwrap();
        assert!(out.status.success(), "{out:?}");
        std::fs::read_to_string(tmp.path().join("ablation.md")).unwrap()
    };
    let row = |md: &str, label: &str| {
        md.lines()
            .find(|l| l.starts_with(&format!("| {label} |")))
            .unwrap_or_else(|| panic!("no row {label} in\n{md}"))
            .to_string()
    };

    write_stage(&stage_1);
    events.borrow_mut().push(serde_json::json!({
        "event": "failed", "task": "composite", "base": 60,
        "job": "without_event_gated_visits", "why": "exit 1"
    }));
    let md = table();
    assert!(md.contains("Completed stages: 1 "), "{md}");
    for pays in ["clock", "final_phase", "selection_cut"] {
        let r = row(&md, pays);
        assert!(
            r.contains("| 1 | 24 | 24 | 0 | 24 | 0 | +1.000 [+1.000, +1.000] |")
                && r.ends_with("| pays |"),
            "{r}"
        );
    }
    for unresolved in ["shaping", "reset_agent"] {
        let r = row(&md, unresolved);
        assert!(
            r.contains("| 1 | 24 | 24 | 24 | 0 | 0 | +0.000 [+0.000, +0.000] |")
                && r.ends_with("| not resolved |"),
            "{r}"
        );
    }
    let r = row(&md, "counterfactual_states");
    assert!(
        r.contains("| 1 | 24 | 24 | 23 | 1 | 0 | +0.021 [+0.000,")
            && r.ends_with("| not resolved |"),
        "{r}"
    );
    // The failed job's pair is left out, not scored.
    let r = row(&md, "event_gated_visits");
    assert!(r.contains("| 1 | 23 | 23 | 23 | 0 | 0 |"), "{r}");
    assert!(md.contains("Failed (left out of the comparisons that need them): composite 60 without_event_gated_visits."), "{md}");
    assert!(
        !md.contains("Together"),
        "nothing goes before every mechanism is resolved"
    );
    let csv = std::fs::read_to_string(tmp.path().join("jobs.csv")).unwrap();
    assert_eq!(csv.lines().count(), 1 + 24 * 10);

    write_stage(&stage_2);
    let md = table();
    assert!(md.contains("Completed stages: 1, 2 "), "{md}");
    assert!(
        row(&md, "clock").contains("| 1 | 24 |"),
        "a reading of stage 1 stays"
    );
    for goes in [
        "shaping",
        "reset_agent",
        "counterfactual_states",
        "event_gated_visits",
    ] {
        let r = row(&md, goes);
        assert!(
            r.contains("| 2 | ") && r.ends_with("| does not show it pays |"),
            "{r}"
        );
    }
    let together = "counterfactual_states, event_gated_visits, shaping, reset_agent";
    assert!(
        md.contains(&format!("Together ({together} off at once): not run yet")),
        "{md}"
    );
    for task in tasks {
        for base in stage_1.iter().chain(&stage_2) {
            done(
                task,
                *base,
                "without_counterfactual_states+event_gated_visits+shaping+reset_agent",
                fake_record(*base, 0.0, Some(0.0)),
            );
        }
    }
    // Read without the reset agent, the together job reports a co-trained candidate (solved).
    let r = row(&table(), &format!("together: {together}"));
    assert!(
        r.contains("| 2 | 48 | 48 | 48 | 0 | 0 |") && r.ends_with("| they go |"),
        "{r}"
    );
}

/// What `ablation.py run` keeps of a finished job (its run directory is gone on the next
/// checkout): a `done` entry in the ledger holding the record without its per-iteration rows,
/// every field the table reads unchanged, under the job's key; a second entry appends, and an
/// existing ledger is not rewritten otherwise.
#[test]
fn a_finished_job_is_kept_in_the_ledger_without_its_rows() {
    let tmp = tempfile::tempdir().unwrap();
    let (runs, ledger) = (tmp.path().join("runs"), tmp.path().join("ledger.jsonl.gz"));
    let mut raw = fake_record(10, 0.5, Some(1.0));
    raw["rows"] = serde_json::json!([{"iteration": 0, "success_rate": 0.25}]);
    for rel in [
        "or-b10/jobs/smirl_seed10.json",
        "or-b10/ablation/clock+shaping/jobs/smirl_seed10.json",
    ] {
        let path = runs.join(rel);
        std::fs::create_dir_all(path.parent().unwrap()).unwrap();
        std::fs::write(path, raw.to_string()).unwrap();
    }
    let version = serde_json::json!({"event": "version", "version": "smirl 0.1.0 (commit x)"});
    write_ledger(&ledger, std::slice::from_ref(&version));
    let script = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/experiments/reacher/mechanisms"
    );
    let code = "import gzip, json, sys\n\
        sys.path.insert(0, sys.argv[1]); import ablation\n\
        ablation.LEDGER = sys.argv[2]\n\
        ablation.keep_record(sys.argv[3], 'or', 10, 'standard')\n\
        ablation.keep_record(sys.argv[3], 'or', 10, ('shaping', 'clock'))\n\
        print(json.dumps(ablation.read_ledger()))\n";
    let out = Command::new("python3")
        .args(["-c", code, script])
        .arg(&ledger)
        .arg(&runs)
        .output()
        .unwrap();
    assert!(out.status.success(), "{out:?}");
    let events: Vec<serde_json::Value> = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(events.len(), 3, "{events:?}");
    assert_eq!(events[0], version);
    for (event, job) in events[1..]
        .iter()
        .zip(["standard", "without_clock+shaping"])
    {
        assert_eq!(event["event"], "done");
        assert_eq!((&event["task"], &event["base"]), (&"or".into(), &10.into()));
        assert_eq!(event["job"], job);
        let kept = &event["record"];
        assert!(kept.get("rows").is_none(), "{job}: {kept}");
        for field in ["final_policy", "loop_final_set", "wall_secs", "seed"] {
            assert_eq!(kept[field], raw[field], "{job}: {field}");
        }
    }
}
