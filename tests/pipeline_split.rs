//! A run in three steps a scheduler can spread over machines — `reacher prepare`, one
//! `reacher job` per (algorithm, seed), `reacher aggregate` — gives exactly what the
//! one-process `reacher --task` gives; finished jobs are not rerun, killed ones start over;
//! bad input names the item; the binary runs away from the checkout; configs print as a
//! person would write them.

mod irl_run_common;
use irl_run_common::tiny_config;
use smirl::pipeline::reacher_irl::{DemoSource, IrlRunConfig};
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn run(bin: &Path, dir: &Path, args: &[&str]) -> Output {
    Command::new(bin)
        .current_dir(dir)
        .args(args)
        .output()
        .unwrap()
}

fn ok(o: &Output) -> String {
    assert!(
        o.status.success(),
        "{}\n{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    );
    String::from_utf8_lossy(&o.stdout).into_owned()
}

fn usage_error(o: &Output, needle: &str) {
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains(needle), "expected '{needle}' in: {err}");
}

fn bin() -> PathBuf {
    PathBuf::from(env!("CARGO_BIN_EXE_reacher"))
}

fn read(p: &Path) -> Vec<u8> {
    std::fs::read(p).unwrap_or_else(|e| panic!("{}: {e}", p.display()))
}

const PLAN: [&str; 8] = [
    "--task",
    "if",
    "--algo",
    "smirl,maxent",
    "--seeds",
    "2",
    "--seed",
    "5",
];

#[test]
fn prepare_job_aggregate_equals_one_process_run_and_reruns_are_safe() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    // The `--quick` profile, as a user would run it.
    let with = |extra: &[&'static str]| -> Vec<&'static str> {
        let mut v: Vec<&str> = PLAN.to_vec();
        v.extend_from_slice(&["--quick", "--quiet"]);
        v.extend_from_slice(extra);
        v
    };
    ok(&run(&bin(), dir, &with(&["--out", "whole"])));

    let mut prepare: Vec<&str> = vec!["prepare"];
    prepare.extend(with(&["--out", "split"]));
    prepare.retain(|a| *a != "--quiet");
    let out = ok(&run(&bin(), dir, &prepare));
    assert!(out.contains("jobs: 4"), "{out}");
    // Preparing the same plan again leaves the directory as it is.
    let out = ok(&run(&bin(), dir, &prepare));
    assert!(
        out.contains("already prepared") && out.contains("jobs: 4"),
        "{out}"
    );

    // A run directory as git checks it out: `logs/` is ignored, so it is not there.
    // Regression: jobs failed on the missing `logs/<job>.mcap.part`.
    std::fs::remove_dir_all(dir.join("split/logs")).unwrap();

    // Jobs in another order than the one-process run, by index and by name.
    for args in [
        vec!["job", "--run", "split", "--index", "3", "--quiet"],
        vec![
            "job", "--run", "split", "--algo", "smirl", "--seed", "6", "--quiet",
        ],
        vec!["job", "--run", "split", "--index", "0", "--quiet"],
    ] {
        ok(&run(&bin(), dir, &args));
    }
    // Aggregating with a job missing lists it, unless --partial.
    usage_error(&run(&bin(), dir, &["aggregate", "split"]), "maxent_seed5");
    ok(&run(&bin(), dir, &["aggregate", "split", "--partial"]));
    ok(&run(
        &bin(),
        dir,
        &["job", "--run", "split", "--index", "2", "--quiet"],
    ));
    ok(&run(&bin(), dir, &["aggregate", "split"]));
    for f in ["metrics.csv", "summary.csv", "summary.md"] {
        if f == "summary.md" {
            continue; // holds job wall times
        }
        assert_eq!(
            read(&dir.join("whole").join(f)),
            read(&dir.join("split").join(f)),
            "{f}"
        );
    }
    for f in [
        "rewards/smirl_seed6.json",
        "rewards/smirl_seed6.trace.csv",
        "rewards/maxent_seed5.bin",
        "rm/learned.txt",
        "success_branches.svg",
    ] {
        assert_eq!(
            read(&dir.join("whole").join(f)),
            read(&dir.join("split").join(f)),
            "{f}"
        );
    }

    // A finished job is not run again.
    let record = dir.join("split/jobs/smirl_seed5.json");
    let before = read(&record);
    let out = ok(&run(
        &bin(),
        dir,
        &["job", "--run", "split", "--algo", "smirl", "--seed", "5"],
    ));
    assert!(out.contains("already done"), "{out}");
    assert_eq!(read(&record), before);
    // A job killed halfway (no record, an unfinished log left behind) starts over and the
    // aggregate comes out the same.
    std::fs::remove_file(&record).unwrap();
    std::fs::write(dir.join("split/logs/smirl_seed5.mcap.part"), b"half a log").unwrap();
    std::fs::write(dir.join("split/rewards/smirl_seed5.json"), b"{\"half\":").unwrap();
    ok(&run(
        &bin(),
        dir,
        &["job", "--run", "split", "--index", "0", "--quiet"],
    ));
    let rows =
        |bytes: &[u8]| serde_json::from_slice::<serde_json::Value>(bytes).unwrap()["rows"].clone();
    assert_eq!(rows(&read(&record)), rows(&before));
    ok(&run(&bin(), dir, &["aggregate", "split"]));
    assert_eq!(
        read(&dir.join("whole/metrics.csv")),
        read(&dir.join("split/metrics.csv"))
    );
    assert!(!dir.join("split/logs/smirl_seed5.mcap.part").exists());
    smirl::log::read_log(&dir.join("split/logs/smirl_seed5.mcap")).unwrap();
}

#[test]
fn split_steps_refuse_bad_input_naming_the_item() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    std::fs::write(dir.join("tiny.toml"), tiny_config().to_toml()).unwrap();
    // A directory `prepare` did not finish (or never touched).
    std::fs::create_dir(dir.join("mine")).unwrap();
    std::fs::write(dir.join("mine/notes.txt"), b"user data").unwrap();
    usage_error(
        &run(&bin(), dir, &["job", "--run", "mine", "--index", "0"]),
        "not a prepared run directory",
    );
    usage_error(&run(&bin(), dir, &["aggregate", "mine"]), "prepare.json");
    // `prepare` never writes into a directory it did not prepare.
    usage_error(
        &run(
            &bin(),
            dir,
            &[
                "prepare",
                "--task",
                "or",
                "--config",
                "tiny.toml",
                "--out",
                "mine",
            ],
        ),
        "not touching it",
    );
    assert_eq!(read(&dir.join("mine/notes.txt")), b"user data");
    assert_eq!(std::fs::read_dir(dir.join("mine")).unwrap().count(), 1);

    ok(&run(
        &bin(),
        dir,
        &[
            "prepare",
            "--task",
            "or",
            "--algo",
            "maxent",
            "--seeds",
            "2",
            "--config",
            "tiny.toml",
            "--out",
            "run",
        ],
    ));
    usage_error(
        &run(
            &bin(),
            dir,
            &["job", "--run", "run", "--algo", "fkl", "--seed", "0"],
        ),
        "algorithm 'fkl' is not in this run",
    );
    usage_error(
        &run(
            &bin(),
            dir,
            &["job", "--run", "run", "--algo", "maxent", "--seed", "7"],
        ),
        "seed 7 is outside this run's seeds 0..=1",
    );
    usage_error(
        &run(&bin(), dir, &["job", "--run", "run", "--index", "2"]),
        "job index 2 is outside 0..2",
    );
    usage_error(
        &run(
            &bin(),
            dir,
            &["job", "--run", "run", "--algo", "gail", "--seed", "0"],
        ),
        "gail",
    );
    usage_error(
        &run(&bin(), dir, &["aggregate", "run"]),
        "maxent_seed0, maxent_seed1",
    );
    usage_error(
        &run(&bin(), dir, &["aggregate", "run", "--partial"]),
        "no job has finished",
    );
    // Another plan into the prepared directory is refused.
    usage_error(
        &run(
            &bin(),
            dir,
            &[
                "prepare",
                "--task",
                "or",
                "--algo",
                "fkl",
                "--config",
                "tiny.toml",
                "--out",
                "run",
            ],
        ),
        "another task, plan or config",
    );
}

/// The binary carries its model, reward machines and committed experts: a copy in a
/// directory outside the checkout, run from there, runs a `--quick` pipeline and prepares a
/// run from the committed expert.
#[test]
fn relocated_binary_runs_outside_the_checkout() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    let copy = dir.join("reacher");
    std::fs::copy(bin(), &copy).unwrap();
    let out = ok(&run(
        &copy,
        dir,
        &[
            "--task", "or", "--quick", "--algo", "maxent", "--quiet", "--out", "q",
        ],
    ));
    assert!(out.contains("maxent"), "{out}");
    assert!(dir.join("q/metrics.csv").is_file());
    let mut expert = tiny_config();
    expert.demo_source = DemoSource::Expert;
    std::fs::write(dir.join("expert.toml"), expert.to_toml()).unwrap();
    let out = ok(&run(
        &copy,
        dir,
        &[
            "prepare",
            "--task",
            "composite",
            "--algo",
            "smirl",
            "--config",
            "expert.toml",
            "--out",
            "p",
        ],
    ));
    assert!(out.contains("4 of 4 demonstrations kept"), "{out}");
    // The logs carry the built-in model, which is the shipped file.
    let log = smirl::log::read_log(&dir.join("p/logs/demos.mcap")).unwrap();
    let shipped = std::fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/reacher_delivery.xml"),
    )
    .unwrap();
    assert_eq!(log.model_xml.as_deref(), Some(shipped.as_str()));
    let report = ok(&run(
        &copy,
        dir,
        &["replay", "p/logs/demos.mcap", "--verify"],
    ));
    assert!(!report.contains("differs from the shipped"), "{report}");
}

/// A number with more than 8 digits after its decimal point (`0.0010000000474974513`).
fn long_decimal(text: &str) -> bool {
    text.split(|c: char| !(c.is_ascii_digit() || c == '.'))
        .filter_map(|t| t.split_once('.'))
        .any(|(_, fraction)| fraction.len() > 8)
}

#[test]
fn configs_print_shortest_decimals_and_read_back_the_same() {
    let o = Command::new(bin())
        .args(["--task", "or", "--print-config"])
        .output()
        .unwrap();
    let text = ok(&o);
    assert!(text.contains("\nlr = 0.001\n"), "{text}");
    assert!(text.contains("\nreward_lr = 0.001\n"), "{text}");
    assert!(text.contains("\nreward_l2 = 0.05\n"), "{text}");
    assert!(text.contains("\nkde_bandwidth = 0.02\n"), "{text}");
    assert!(!long_decimal(&text), "{text}");
    assert_eq!(
        IrlRunConfig::from_toml(&text, "printed").unwrap(),
        IrlRunConfig::standard()
    );
    // Awkward values survive the round trip bit for bit.
    let mut c = IrlRunConfig::quick();
    c.mlp_reward_lr = 3.3e-7;
    c.smirl_reward_l2 = 0.123_456_79;
    c.sac.alpha = 0.123_456_79;
    let back = IrlRunConfig::from_toml(&c.to_toml(), "written").unwrap();
    assert_eq!(back, c);
    assert_eq!(back.mlp_reward_lr.to_bits(), c.mlp_reward_lr.to_bits());
    assert!(
        c.to_toml().contains("alpha = 0.12345679"),
        "{}",
        c.to_toml()
    );
    // The shipped configs are written that way too.
    let shipped = std::fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("experiments/reacher/config.toml"),
    )
    .unwrap();
    assert!(!long_decimal(&shipped), "{shipped}");
}

/// `reacher retrain`: a fresh SAC agent on a finished job's final reward, judged on the ground
/// truth; the table is written once (again only with --force), the same seed gives the same
/// table, and bad input — a job that has not run, zero steps, more evaluations than steps, an
/// Office algorithm, a learned state the machine lacks, a reward file of a feature kind this
/// build does not have, a run's `.partial` working directory, a bad agent settings file — exits
/// 2 before any training, writing nothing; zeroed states and
/// other agent settings write tables of their own.
#[test]
fn retrain_judges_a_fresh_policy_on_the_final_reward() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    let mut prepare: Vec<&str> = vec!["prepare"];
    prepare.extend_from_slice(&PLAN);
    prepare.extend_from_slice(&["--quick", "--out", "run"]);
    ok(&run(&bin(), dir, &prepare));
    let (algo, seed) = ("smirl", "5");
    let retrain = |extra: &[&str]| {
        let mut v = vec!["retrain", "--run", "run", "--algo", algo, "--seed", seed];
        v.extend_from_slice(extra);
        run(&bin(), dir, &v)
    };
    usage_error(&retrain(&["--steps", "400"]), "no learned reward");
    ok(&run(
        &bin(),
        dir,
        &[
            "job", "--run", "run", "--algo", algo, "--seed", seed, "--quiet",
        ],
    ));
    usage_error(&retrain(&["--steps", "0"]), "--steps must be in 1..=");
    usage_error(
        &retrain(&["--steps", "300", "--evaluations", "301"]),
        "--evaluations must be in 1..=300",
    );
    let office = run(
        &bin(),
        dir,
        &[
            "retrain",
            "--run",
            "run",
            "--algo",
            "apprenticeship",
            "--seed",
            seed,
        ],
    );
    assert_eq!(office.status.code(), Some(2));
    assert!(!dir.join("run/retrain").exists());
    // A run's `.partial` working directory is renamed when its run ends: job, aggregate and
    // retrain refuse to add to it (a retrain started in one recreated it after the rename).
    std::fs::rename(dir.join("run"), dir.join("run.partial")).unwrap();
    for args in [
        vec![
            "retrain",
            "--run",
            "run.partial",
            "--algo",
            algo,
            "--seed",
            seed,
            "--steps",
            "400",
        ],
        vec!["job", "--run", "run.partial", "--index", "0", "--quiet"],
        vec!["aggregate", "run.partial"],
    ] {
        usage_error(
            &run(&bin(), dir, &args),
            "still being written (or one that stopped): use run once",
        );
    }
    assert!(!dir.join("run.partial/retrain").exists());
    std::fs::rename(dir.join("run.partial"), dir.join("run")).unwrap();

    let table = dir.join("run/retrain/smirl_seed5_sac1000.csv");
    let out = ok(&retrain(&["--steps", "400", "--evaluations", "2"]));
    let written = std::fs::read_to_string(&table).unwrap();
    assert_eq!(out, written);
    let lines: Vec<&str> = written.lines().collect();
    assert_eq!(lines.len(), 3, "{written}");
    assert!(lines[0].starts_with("env_steps,success_rate"));
    usage_error(
        &retrain(&["--steps", "400", "--evaluations", "2"]),
        "--force",
    );
    ok(&retrain(&[
        "--steps",
        "400",
        "--evaluations",
        "2",
        "--force",
    ]));
    assert_eq!(std::fs::read_to_string(&table).unwrap(), written);
    // With a learned state's weights zeroed: a table of its own, the job's left as it was; a
    // state the machine does not have is refused before any training.
    usage_error(
        &retrain(&["--steps", "400", "--zero-state", "999"]),
        "--zero-state 999",
    );
    // Regression: a state past u32 was cast down and wrapped onto state 1.
    usage_error(
        &retrain(&["--steps", "400", "--zero-state", "4294967297"]),
        "--zero-state 4294967297",
    );
    // A reward file of a feature kind this build does not have (`label_entries`, a past
    // experiment's) is refused naming the kind and the file, before any training.
    let reward = dir.join("run/rewards/smirl_seed5.json");
    let saved = std::fs::read_to_string(&reward).unwrap();
    let entries = saved.replace(r#""kind": "labels""#, r#""kind": "label_entries""#);
    assert_ne!(entries, saved);
    std::fs::write(&reward, entries).unwrap();
    let o = retrain(&["--steps", "400"]);
    usage_error(&o, "unknown variant `label_entries`");
    usage_error(&o, "smirl_seed5.json");
    std::fs::write(&reward, saved).unwrap();
    ok(&retrain(&[
        "--steps",
        "400",
        "--evaluations",
        "2",
        "--zero-state",
        "0",
        "--zero-state",
        "1",
    ]));
    let zeroed = dir.join("run/retrain/smirl_seed5_sac1000_zero0-1.csv");
    assert_eq!(std::fs::read_to_string(&zeroed).unwrap().lines().count(), 3);
    assert_eq!(std::fs::read_to_string(&table).unwrap(), written);

    // Other agent settings (--agent FILE): a table named after the file, the job's left as it
    // was; a file that asks for the same settings as the job's gives the job's table; an
    // unknown key, a bad value (named with its line) or a stem that cannot name a table is
    // refused before any training.
    let agent = |name: &str, text: &str| {
        let path = dir.join(name);
        std::fs::write(&path, text).unwrap();
        path.to_str().unwrap().to_string()
    };
    let same = agent("same.toml", "# the job's own settings\n");
    ok(&retrain(&[
        "--steps",
        "400",
        "--evaluations",
        "2",
        "--agent",
        &same,
    ]));
    let same_table = dir.join("run/retrain/smirl_seed5_sac1000_same.csv");
    assert_eq!(std::fs::read_to_string(&same_table).unwrap(), written);
    let slower = agent(
        "slower.toml",
        "[sac]\nlr = 0.0003\nwarmup_steps = 100\nupdate_after = 100\n",
    );
    ok(&retrain(&[
        "--steps",
        "400",
        "--evaluations",
        "2",
        "--agent",
        &slower,
    ]));
    let slower_table = dir.join("run/retrain/smirl_seed5_sac1000_slower.csv");
    let slower_text = std::fs::read_to_string(&slower_table).unwrap();
    assert_eq!(slower_text.lines().count(), 3);
    // SAC's own state per segment, the last four columns: none before the first update (the
    // job's 400 steps are all warm-up), a positive temperature and critic loss once updating
    // (the second segment: the first update waits for a batch of 256 transitions too).
    let agent_columns = |line: &str| -> Vec<f64> {
        let cells: Vec<&str> = line.split(',').collect();
        assert_eq!(cells.len(), 12, "{line}");
        cells[8..].iter().map(|c| c.parse().unwrap()).collect()
    };
    assert_eq!(agent_columns(lines[2]), vec![0.0; 4]);
    let last = slower_text.lines().last().unwrap();
    let [alpha, entropy, critic_loss, value] = agent_columns(last)[..] else {
        unreachable!()
    };
    assert!(alpha > 0.0 && critic_loss > 0.0, "{last}");
    assert!(
        entropy.is_finite() && value.is_finite() && value != 0.0,
        "{last}"
    );
    assert_eq!(std::fs::read_to_string(&table).unwrap(), written);
    let refused = [
        ("unknown.toml", "smirl_reward_lr = 0.5\n", "smirl_reward_lr"),
        (
            "negative.toml",
            "# a typo\n[sac]\nlr = -0.001\n",
            "line 3: field `sac.lr`",
        ),
        (
            "oversized.toml",
            "[sac]\nreplay_capacity = 999999999999\n",
            "replay_capacity",
        ),
        ("two words.toml", "", "the file's stem names the table"),
    ];
    for (name, text, needle) in refused {
        let path = agent(name, text);
        usage_error(&retrain(&["--steps", "400", "--agent", &path]), needle);
    }
    let missing = dir.join("missing.toml");
    usage_error(
        &retrain(&["--steps", "400", "--agent", missing.to_str().unwrap()]),
        "missing.toml",
    );
    for name in ["unknown", "negative", "oversized"] {
        let refused = format!("run/retrain/smirl_seed5_sac1000_{name}.csv");
        assert!(!dir.join(refused).exists());
    }
}

/// Regression: `reacher job` printed the last IRL iteration's success as the job's "final
/// success" (0.00 for a SMIRL job whose final policy reports 0.65). The reported success is
/// the chosen final-policy candidate's; without a final phase, the last iteration's.
#[test]
fn a_job_reports_its_final_policy_success() {
    use smirl::pipeline::reacher_irl::run::JobRecord;
    let row = |iteration: usize, success: f64| {
        serde_json::json!({
            "iteration": iteration, "env_steps": iteration * 100, "success_rate": success,
            "branches": null, "task_return": 0.0, "env_return": 0.0, "learned_reward": 0.0,
            "surrogate_loss": 0.0
        })
    };
    let candidate = |success: f64, learned_return: f64| {
        serde_json::json!({
            "env_steps": 3000, "learned_return": learned_return, "success_rate": success,
            "branches": null, "progress": success, "final_ball": success
        })
    };
    let mut record = serde_json::json!({
        "algo": "smirl", "seed": 20, "rows": [row(0, 0.0), row(30, 0.0)], "wall_secs": 1.0,
        "final_policy": {"candidates": [candidate(0.0, 106.1), candidate(0.65, 431.4)], "chosen": 1}
    });
    let with_final: JobRecord = serde_json::from_value(record.clone()).unwrap();
    assert_eq!(with_final.reported_success(), 0.65);
    // Records written with a reset agent or the selection cut still read.
    let mut old = record.clone();
    old["final_policy"]["candidates"][1]["agent"] = "reset".into();
    old["final_policy"]["candidates"][1]["cut_return"] = 400.0.into();
    let old: JobRecord = serde_json::from_value(old).unwrap();
    assert_eq!(old.reported_success(), 0.65);
    record.as_object_mut().unwrap().remove("final_policy");
    record["rows"][1]["success_rate"] = 0.8.into();
    let without: JobRecord = serde_json::from_value(record).unwrap();
    assert_eq!(without.reported_success(), 0.8);
}
