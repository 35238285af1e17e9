//! `smirl-paper`, the paper's algorithm kept beside `smirl`: its settings are `smirl`'s with
//! every mechanism of docs/method.md at the paper's value, and a run gives it its own machine
//! (LRM as eq. 1; `tests/rm_lrm.rs` checks the machine) and reports its loop's own last policy.

mod irl_run_common;
use irl_run_common::tiny_config;
use smirl::env::reacher_task::ReacherTask;
use smirl::pipeline::reacher_irl::run::{open_run, JobRecord};
use smirl::pipeline::reacher_irl::smirl::lrm_config;
use smirl::pipeline::reacher_irl::{Algo, IrlRunConfig};
use smirl::rm::format::parse_rm;
use smirl::rm::lrm::{Guards, LrmConfig};
use std::process::Command;

/// Every mechanism by which the standard `smirl` departs from the paper resolves to the paper's
/// value for `smirl-paper`; everything else (schedule, SAC, reward optimiser, LRM's budget) is
/// `smirl`'s, so that the two differ by the mechanisms alone.
#[test]
fn smirl_paper_resolves_every_mechanism_to_the_papers_value() {
    let standard = IrlRunConfig::standard();
    let smirl = standard.for_algo(Algo::Smirl).unwrap();
    let paper = standard.for_algo(Algo::SmirlPaper).unwrap();
    // LRM: eq. 1 (events predicted), no event rule, LRM's guards; smirl's learner has each.
    let on_if = IrlRunConfig {
        env: ReacherTask::shipped("if")
            .unwrap()
            .env_config(&standard.env)
            .unwrap(),
        ..standard.clone()
    };
    let lrm = |algo| lrm_config(&on_if.for_algo(algo).unwrap(), 0, algo).unwrap();
    let (paper_lrm, smirl_lrm) = (lrm(Algo::SmirlPaper), lrm(Algo::Smirl));
    assert!(paper_lrm.predict_events && !smirl_lrm.predict_events);
    assert!(!paper_lrm.event_stutter && smirl_lrm.event_stutter);
    assert!(!paper_lrm.commute_events && smirl_lrm.commute_events);
    assert!(!paper_lrm.initial_events && smirl_lrm.initial_events);
    assert_eq!(
        (paper_lrm.guards, smirl_lrm.guards),
        (Guards::Exact, Guards::Tree)
    );
    // The same search otherwise.
    assert_eq!(
        LrmConfig {
            predict_events: true,
            event_stutter: false,
            commute_events: false,
            initial_events: false,
            guards: Guards::Exact,
            ..smirl_lrm
        },
        paper_lrm
    );
    // The policy on U × O: no counterfactual states.
    assert_eq!(paper.counterfactual(), 0.0);
    // No final phase, no choice among candidates.
    assert_eq!(paper.final_sac_steps, 0);
    assert_eq!(paper.final_checkpoints, 0);
    // The standard's smirl differs in each of these (else the test above proves nothing).
    assert!(smirl.counterfactual() > 0.0);
    assert!(smirl.final_sac_steps > 0);
    // What is not a mechanism is smirl's.
    let same = IrlRunConfig {
        counterfactual_states: true,
        final_sac_steps: smirl.final_sac_steps,
        final_checkpoints: smirl.final_checkpoints,
        ..paper.clone()
    };
    assert_eq!(same, smirl);
}

/// A tiny run of `reacher --task if --algo smirl,smirl-paper` through the CLI: smirl-paper gets
/// its own machine (`rm/learned_paper.txt`, guards that stay on unseen label sets) and
/// demonstrations annotated with it, learns a reward over that machine's states, runs no final
/// phase, and the run reports its loop's last policy; smirl keeps its machine and final phase.
#[test]
fn smirl_paper_runs_on_its_own_machine_and_reports_its_loops_last_policy() {
    let tmp = tempfile::tempdir().unwrap();
    let cfg = tmp.path().join("tiny.toml");
    let config = tiny_config();
    assert!(config.final_sac_steps > 0 && config.final_checkpoints > 0);
    std::fs::write(&cfg, config.to_toml()).unwrap();
    let out = tmp.path().join("run");
    let status = Command::new(env!("CARGO_BIN_EXE_reacher"))
        .args([
            "--task",
            "if",
            "--algo",
            "smirl,smirl-paper",
            "--seed",
            "2",
            "--quiet",
        ])
        .arg("--config")
        .arg(&cfg)
        .arg("--out")
        .arg(&out)
        .status()
        .unwrap();
    assert!(status.success());
    let read = |f: &str| std::fs::read_to_string(out.join(f)).unwrap();
    let paper_rm = parse_rm(&read("rm/learned_paper.txt"), "learned_paper.txt").unwrap();
    assert!(read("rm/report_paper.txt").contains("guards for label sets unseen in a state: exact"));
    assert!(read("rm/report.txt").contains("guards for label sets unseen in a state: tree"));

    // Each SMIRL algorithm reads its own machine and demonstrations annotated with it.
    let run = open_run(&out).unwrap();
    let (machine, expert) = run.inputs_of(Algo::SmirlPaper).unwrap();
    assert_eq!(
        parse_rm(&read("rm/learned_paper.txt"), "").unwrap(),
        paper_rm
    );
    assert_eq!(machine.unwrap(), &paper_rm);
    assert!(expert.check_machine(Some(&paper_rm)).is_ok());
    let (smirl_machine, _) = run.inputs_of(Algo::Smirl).unwrap();
    assert_eq!(
        smirl_machine.unwrap(),
        &parse_rm(&read("rm/learned.txt"), "").unwrap()
    );
    let reward: serde_json::Value = serde_json::from_str(&read("rewards/smirl-paper_seed2.json"))
        .expect("smirl-paper's reward is a linear reward per state");
    assert_eq!(reward["n_states"], paper_rm.n_states());

    // The paper's job reports its loop's own last policy; smirl's chooses after its final phase.
    let record = |algo: &str| -> JobRecord {
        serde_json::from_str(&read(&format!("jobs/{algo}_seed2.json"))).unwrap()
    };
    let paper = record("smirl-paper");
    assert!(paper.final_policy.is_none());
    let last = paper.rows.last().unwrap();
    assert_eq!(last.iteration, config.irl_iterations);
    assert_eq!(paper.reported_success(), last.success_rate);
    assert!(record("smirl").final_policy.is_some());
    let summary = read("summary.csv");
    let row = summary
        .lines()
        .find(|l| l.starts_with("if,smirl-paper,1,"))
        .expect("smirl-paper's row in summary.csv");
    let reported: f64 = row.split(',').nth(3).unwrap().parse().unwrap();
    assert!((reported - last.success_rate).abs() < 5e-4, "{row}");
    let final_policies = read("final_policy.csv");
    assert!(!final_policies.contains("smirl-paper"));
}
