//! The "unless cancel" branch of IF and Composite: the default cancel schedule makes it happen
//! in a sizeable share of episodes, the committed experts solve both branches, the branch of
//! an episode is read off the perfect machine's trace, the IRL pipeline reports each branch
//! (headline = the lower branch rate), replay names the branch, and bad cancel windows are
//! refused with exit status 2.

use smirl::env::reacher::{CancelConfig, ReacherConfig, ReacherDelivery};
use smirl::env::reacher_task::{Branch, BranchTally, EventBranch, ReacherTask};
use smirl::env::ContinuousEnv;
use smirl::pipeline::reacher_expert::{
    committed_expert, evaluate_expert, ExpertConfig, ExpertPolicy,
};
use smirl::pipeline::reacher_irl::evaluation::stratified_eval_seeds;
use smirl::pipeline::reacher_irl::IrlRunConfig;
use smirl::rl::sac::{episode_seed, ActMode};
use smirl::rm::LabelSet;
use std::process::Command;

#[allow(unused_imports)]
use shipped_layout::{layout, obs_dim, shipped_config};
mod shipped_layout;

/// Label sets from letters of `rgbyc`, one string per step (`""` = no label).
fn trace(steps: &[&str]) -> Vec<LabelSet> {
    steps
        .iter()
        .map(|s| {
            s.chars().fold(LabelSet::EMPTY, |l, c| {
                l.with("rgbyc".find(c).expect("a proposition of rgbyc"))
            })
        })
        .collect()
}

/// (branch, success) of a label trace on the task's perfect machine.
fn outcome(task: ReacherTask, steps: &[&str]) -> (Option<Branch>, bool) {
    let rm = task.perfect_rm().unwrap();
    let labels = trace(steps);
    let end = rm.run(&labels).last().map_or(rm.initial(), |&(u, _)| u);
    let success = rm.is_terminal(end) && !rm.is_failure(end);
    (
        EventBranch::of(&rm, layout().events()).map(|b| b.of_labels(&rm, labels)),
        success,
    )
}

#[test]
fn branch_is_read_off_the_perfect_machines_trace() {
    use Branch::{Event, Normal};
    // OR and Sequential have no branch.
    assert_eq!(
        outcome(ReacherTask::shipped("or").unwrap(), &["r", "c", "b"]),
        (None, true)
    );
    assert_eq!(
        outcome(
            ReacherTask::shipped("sequential").unwrap(),
            &["c", "r", "g", "b", "y"]
        ),
        (None, true)
    );
    // IF: blue then red; a cancel before blue removes blue, and blue after it fails.
    let cases: [(&[&str], Branch, bool); 7] = [
        (&["", "b", "", "r"], Normal, true),
        (&["b", "c", "r"], Normal, true),
        (&["", "", "r"], Normal, false),
        (&["c", "", "r"], Event, true),
        (&["c", "b", "r"], Event, false),
        (&["bc", "", "r"], Event, true),
        (&["c", ""], Event, false),
    ];
    for (steps, branch, success) in cases {
        assert_eq!(
            outcome(ReacherTask::shipped("if").unwrap(), steps),
            (Some(branch), success),
            "IF {steps:?}"
        );
    }
    // Composite: red or green, blue unless cancel, yellow; the cancel may come before or
    // after red/green.
    let cases: [(&[&str], Branch, bool); 7] = [
        (&["g", "b", "y"], Normal, true),
        (&["r", "b", "c", "y"], Normal, true),
        (&["r", "y"], Normal, false),
        (&["c", "r", "y"], Event, true),
        (&["r", "c", "y"], Event, true),
        (&["g", "c", "b", "y"], Event, false),
        (&["c", "y"], Event, false),
    ];
    for (steps, branch, success) in cases {
        assert_eq!(
            outcome(ReacherTask::shipped("composite").unwrap(), steps),
            (Some(branch), success),
            "Composite {steps:?}"
        );
    }
}

#[test]
fn headline_of_a_conditional_task_is_the_lower_branch_rate() {
    // A policy that ignores the cancel: solves the normal branch, fails the cancel branch.
    let mut ignores = BranchTally::default();
    for k in 0..20 {
        ignores.add(Branch::Normal, true);
        ignores.add(Branch::Event, k % 10 == 0);
    }
    assert_eq!(ignores.rate(Branch::Normal), Some(1.0));
    assert_eq!(ignores.rate(Branch::Event), Some(0.1));
    assert_eq!(ignores.worst_rate(), Some(0.1));
    assert_eq!(ignores.share(Branch::Event), 0.5);
    // A branch that never happened does not count as solved or failed.
    let mut one = BranchTally::default();
    one.add(Branch::Normal, true);
    assert_eq!(one.rate(Branch::Event), None);
    assert_eq!(one.worst_rate(), Some(1.0));
    assert_eq!(BranchTally::default().worst_rate(), None);
}

#[test]
fn default_schedule_cancels_half_the_episodes_early() {
    let config = ReacherConfig::default();
    // No schedule of its own: the task's.
    assert_eq!(config.cancel, None);
    assert_eq!(
        shipped_config(config.clone()).cancel,
        Some(CancelConfig {
            probability: 0.5,
            earliest_step: 1,
            latest_step: 8
        })
    );
    let mut env = ReacherDelivery::new(shipped_config(config.clone())).unwrap();
    let mut obs = vec![0.0f32; obs_dim()];
    let (mut scheduled, n) = (0, 1000u64);
    for i in 0..n {
        env.reset(episode_seed(0, i), &mut obs);
        if let Some(t) = env.event_steps()[0] {
            assert!((1..=8).contains(&t), "{t}");
            scheduled += 1;
        }
    }
    // Binomial(1000, 0.5): 500 ± 4σ (σ ≈ 16).
    assert!((436..=564).contains(&scheduled), "{scheduled}");

    // A schedule that differs from the default replaces the task's: with the window 10..=60
    // (which comes after blue in almost every IF and Composite episode) nothing fires before
    // step 10.
    let late_window = CancelConfig {
        probability: 0.5,
        earliest_step: 10,
        latest_step: 60,
    };
    let mut late = ReacherDelivery::new(shipped_config(ReacherConfig {
        cancel: Some(late_window),
        ..ReacherConfig::default()
    }))
    .unwrap();
    for i in 0..200 {
        late.reset(episode_seed(0, i), &mut obs);
        if let Some(t) = late.event_steps()[0] {
            assert!((10..=60).contains(&t), "{t}");
        }
    }
}

/// The committed expert of `task`.
fn committed(task: ReacherTask) -> ExpertPolicy {
    committed_expert(task, &ExpertConfig::default().sac.hidden)
        .unwrap_or_else(|e| panic!("committed expert: {e}"))
}

/// On a fixed seed range the committed IF and Composite experts take the cancel branch in
/// 30–60 % of the episodes and succeed on each branch.
#[test]
fn committed_conditional_experts_take_and_solve_both_branches() {
    let env = ReacherConfig::default();
    for task in [
        ReacherTask::shipped("if").unwrap(),
        ReacherTask::shipped("composite").unwrap(),
    ] {
        let mut policy = committed(task.clone());
        for mode in [ActMode::Sample, ActMode::Mean] {
            let eval = evaluate_expert(&mut policy, &env, 100, mode, 7).unwrap();
            let b = eval.branches.expect("a conditional task");
            let share = b.share(Branch::Event);
            assert!((0.3..=0.6).contains(&share), "{task} {mode:?}: {b}");
            for branch in Branch::ALL {
                assert!(
                    b.rate(branch).unwrap() >= 0.95,
                    "{task} {mode:?} {branch}: {b}"
                );
            }
        }
    }
}

#[test]
fn stratified_evaluation_seeds_give_each_branch_its_episodes() {
    let mut env = ReacherDelivery::new(shipped_config(ReacherConfig::default())).unwrap();
    let seeds = stratified_eval_seeds(&mut env, 42, 20);
    assert_eq!(seeds.len(), 40);
    let mut obs = vec![0.0f32; obs_dim()];
    let with_cancel = seeds
        .iter()
        .filter(|&&s| {
            env.reset(s, &mut obs);
            env.event_steps()[0].is_some()
        })
        .count();
    assert_eq!(with_cancel, 20);
    let mut unique = seeds.clone();
    unique.sort_unstable();
    unique.dedup();
    assert_eq!(unique.len(), 40);
    assert_eq!(
        seeds,
        stratified_eval_seeds(&mut env, 42, 20),
        "deterministic"
    );
    // A schedule that never cancels still gives 2 · 20 seeds.
    let mut never = ReacherDelivery::new(shipped_config(ReacherConfig {
        cancel: Some(CancelConfig {
            probability: 0.0,
            earliest_step: 1,
            latest_step: 8,
        }),
        ..ReacherConfig::default()
    }))
    .unwrap();
    assert_eq!(stratified_eval_seeds(&mut never, 42, 20).len(), 40);
}

fn reacher() -> Command {
    Command::new(env!("CARGO_BIN_EXE_reacher"))
}

/// `reacher --task if --quick` writes the per-branch columns, the lower branch rate is the
/// headline, and `reacher replay` names each episode's branch.
#[test]
fn quick_if_run_reports_each_branch() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("run");
    let o = reacher()
        .args([
            "--task", "if", "--quick", "--algo", "maxent", "--quiet", "--out",
        ])
        .arg(&out)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let per_branch = IrlRunConfig::quick().eval_episodes;
    let metrics = std::fs::read_to_string(out.join("metrics.csv")).unwrap();
    let mut lines = metrics.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let col = |name: &str| header.iter().position(|&h| h == name).expect(name);
    let (rate, normal, cancel, n_normal, n_cancel) = (
        col("success_rate"),
        col("success_normal"),
        col("success_cancel"),
        col("episodes_normal"),
        col("episodes_cancel"),
    );
    let support = col("expert_support");
    let mut rows = 0;
    for line in lines {
        let f: Vec<&str> = line.split(',').collect();
        let x = |i: usize| f[i].parse::<f64>().unwrap();
        // The share of agent states in the expert density's support: none before the first
        // rollouts, a fraction after.
        if rows == 0 {
            assert_eq!(f[support], "", "{line}");
        } else {
            assert!((0.0..=1.0).contains(&x(support)), "{line}");
        }
        // The quick profile's window is the default one: every scheduled cancel comes before
        // blue, so the stratified evaluation splits evenly.
        assert_eq!(x(n_normal) + x(n_cancel), 2.0 * per_branch as f64, "{line}");
        assert_eq!(x(rate), x(normal).min(x(cancel)), "{line}");
        rows += 1;
    }
    assert_eq!(rows, IrlRunConfig::quick().irl_iterations + 1);
    let summary = std::fs::read_to_string(out.join("summary.csv")).unwrap();
    assert!(summary
        .lines()
        .next()
        .unwrap()
        .contains("final_success_cancel_mean"));
    assert!(out.join("success_branches.svg").is_file());
    let md = std::fs::read_to_string(out.join("summary.md")).unwrap();
    assert!(md.contains("| normal branch | event branch |"), "{md}");

    let o = reacher()
        .arg("replay")
        .arg(out.join("logs/maxent_seed0.mcap"))
        .output()
        .unwrap();
    assert!(o.status.success());
    let text = String::from_utf8_lossy(&o.stdout);
    let episodes = text.lines().filter(|l| l.starts_with("episode")).count();
    assert!(episodes > 0);
    let named = text
        .lines()
        .filter(|l| l.contains(" normal branch:") || l.contains(" event branch:"))
        .count();
    assert_eq!(named, episodes, "{text}");
    // And a logged cancel before blue is reported as the cancel branch.
    let log = smirl::log::read_log(&out.join("logs/demos.mcap")).unwrap();
    let report = smirl::pipeline::replay::replay(&log).unwrap();
    let rm = ReacherTask::shipped("if").unwrap().perfect_rm().unwrap();
    let branches = EventBranch::of(&rm, layout().events()).unwrap();
    for (ep, r) in log.episodes.iter().zip(&report.episodes) {
        let labels = ep.steps.iter().map(|s| LabelSet(s.labels));
        assert_eq!(r.branch, Some(branches.of_labels(&rm, labels)));
        let first = |bit: usize| ep.steps.iter().position(|s| s.labels & (1 << bit) != 0);
        let cancel_first = match (first(layout().event_bit(0)), first(2)) {
            (Some(c), Some(b)) => c <= b,
            (Some(_), None) => true,
            _ => false,
        };
        assert_eq!(r.branch == Some(Branch::Event), cancel_first);
    }
}

#[test]
fn bad_cancel_windows_are_refused_with_status_2() {
    let tmp = tempfile::tempdir().unwrap();
    // A run config has no cancel window (the task file's [[event]] schedule is).
    let run = format!(
        "{}\n[env.cancel]\nlatest_step = 60\n",
        IrlRunConfig::quick().to_toml()
    );
    let e = IrlRunConfig::from_toml(&run, "r.toml")
        .unwrap_err()
        .to_string();
    assert!(e.contains("env.cancel") && e.contains("[[event]]"), "{e}");
    // An expert config's window is checked.
    let full = "[env]\nmax_steps = 100\n[env.cancel]\nprobability = 0.5\nearliest_step = 1\nlatest_step = 8\n";
    let window = "earliest_step = 1\nlatest_step = 8";
    assert!(full.contains(window), "{full}");
    let cases = [
        (
            full.replace(window, "earliest_step = 1\nlatest_step = 101"),
            "cancel.latest_step",
        ),
        (
            full.replace(window, "earliest_step = 9\nlatest_step = 8"),
            "cancel.earliest_step",
        ),
        (
            full.replace(window, "earliest_step = 0\nlatest_step = 8"),
            "cancel.earliest_step",
        ),
        (
            full.replace("probability = 0.5", "probability = 1.5"),
            "cancel.probability",
        ),
        (
            full.replace("probability = 0.5", "probability = -0.1"),
            "cancel.probability",
        ),
    ];
    for (text, field) in cases {
        let cfg = tmp.path().join("bad.toml");
        std::fs::write(&cfg, &text).unwrap();
        let out = tmp.path().join("out");
        let o = reacher()
            .args(["expert", "--task", "if", "--config"])
            .arg(&cfg)
            .arg("--out")
            .arg(&out)
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{field}: {err}");
        assert!(err.contains(field), "{field}: {err}");
        assert!(!out.exists());
    }
    // The expert trainer refuses them too.
    let cfg = tmp.path().join("expert.toml");
    std::fs::write(
        &cfg,
        "[env]\nmax_steps = 50\n[env.cancel]\nprobability = 0.5\nearliest_step = 1\nlatest_step = 60\n",
    )
    .unwrap();
    let o = reacher()
        .args(["expert", "--task", "if", "--config"])
        .arg(&cfg)
        .arg("--out")
        .arg(tmp.path().join("expert"))
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains("cancel.latest_step"), "{err}");
}

/// The demonstrations are reset from the run's own seed stream (so each replays from its reset
/// seed and draws its cancel like any episode); the stratified schedule's key is gone.
#[test]
fn demonstrations_are_reset_from_the_runs_stream() {
    use smirl::pipeline::reacher_irl::demos::{demo_reset_seeds, make_demos};
    let stream: Vec<u64> = (0..16).map(|i| episode_seed(7, i)).collect();
    assert_eq!(demo_reset_seeds(16, 7), stream);
    let config = IrlRunConfig {
        demo_episodes: 6,
        ..IrlRunConfig::quick()
    };
    let demos = make_demos(ReacherTask::shipped("if").unwrap(), &config, None, 7, None).unwrap();
    let used: Vec<u64> = demos.iter().map(|d| d.seed).collect();
    assert_eq!(used, stream[..6]);
    let text = IrlRunConfig::quick().to_toml().replace(
        "demo_episodes = 8\n",
        "demo_episodes = 8\ndemo_cancel = \"stratified\"\n",
    );
    let e = IrlRunConfig::from_toml(&text, "s.toml")
        .unwrap_err()
        .to_string();
    assert!(e.contains("s.toml") && e.contains("demo_cancel"), "{e}");
}
