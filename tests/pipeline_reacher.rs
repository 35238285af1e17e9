//! The `reacher --task` IRL pipeline: SMIRL's update direction at pipeline level, a tiny
//! end-to-end run through the library and through the CLI (every artefact written, nothing
//! half-written), bad input exiting 2 without output, and bit-identical metrics per seed.

mod irl_run_common;
use irl_run_common::tiny_config;
use smirl::env::reacher_task::ReacherTask;
use smirl::irl::reward::{RewardModel, RewardOptimConfig};
use smirl::irl::smirl::{AnnotatedTrajectories, FeatureMap, LinearRmReward};
mod smirl_reference;
use smirl::pipeline::reacher_irl::run::Silent;
use smirl::pipeline::reacher_irl::{
    run_pipeline, AgentBatch, Algo, ExpertData, IrlRunConfig, RunRequest,
};
use smirl_reference::maxent_gradient;
use std::path::{Path, PathBuf};
use std::process::Command;

#[allow(unused_imports)]
use shipped_layout::{layout, obs_dim, shipped_config};
mod shipped_layout;

/// An observation row whose fingertip touches ball `ball` (or none), cancel flag off.
fn row(ball: Option<usize>) -> Vec<f32> {
    let mut r = vec![0.5f32; obs_dim()];
    r[16] = 0.0;
    if let Some(b) = ball {
        r[8 + 2 * b] = 0.005;
        r[9 + 2 * b] = -0.005;
    }
    r
}

#[test]
fn smirl_update_direction_is_expert_minus_agent_feature_expectation() {
    // Expert: 2 trajectories touching red in u0 then blue in u1; agent: touches green in u0
    // and red in u1, one trajectory.
    let mut expert = ExpertData {
        obs: Vec::new(),
        lengths: vec![3, 2],
        learned_states: vec![0, 0, 1, 0, 1],
    };
    for b in [Some(0), None, Some(2), Some(0), Some(2)] {
        expert.obs.extend(row(b));
    }
    let mut agent = AgentBatch {
        lengths: vec![3],
        states: vec![0, 1, 1],
        ..AgentBatch::default()
    };
    for b in [Some(1), Some(0), None] {
        agent.obs.extend(row(b));
    }
    let c = smirl::pipeline::reacher_irl::smirl::coefficients(&expert, &agent);
    let mut model = LinearRmReward::new(
        FeatureMap::reacher_labels(&layout()),
        2,
        RewardOptimConfig::adam(0.1),
    )
    .unwrap();
    model.backward(&c.obs, &c.states, &c.coeffs).unwrap();
    let features = FeatureMap::reacher_labels(&layout());
    let ascent = maxent_gradient(
        &features,
        2,
        &AnnotatedTrajectories {
            obs: &expert.obs,
            rm_state: &expert.learned_states,
            lengths: &expert.lengths,
        },
        &AnnotatedTrajectories {
            obs: &agent.obs,
            rm_state: &agent.states,
            lengths: &agent.lengths,
        },
    )
    .unwrap();
    let grad = model.grad();
    for (g, a) in grad.iter().zip(&ascent) {
        assert!(
            (f64::from(*g) + a).abs() < 1e-6,
            "loss gradient {grad:?} vs ascent {ascent:?}"
        );
    }
    // Known answer: μ_D(u0, red) = 2 touches / 2 trajectories = 1, μ_π(u0, red) = 0;
    // μ_D(u1, red) = 0, μ_π(u1, red) = 1; μ_D(u0, green) = 0, μ_π(u0, green) = 1.
    let k = features.len();
    assert_eq!(ascent[0], 1.0);
    assert_eq!(ascent[k], -1.0);
    assert_eq!(ascent[1], -1.0);
    assert_eq!(ascent[k + 2], 1.0);
    // One optimiser step moves the reward toward the expert: w_u0[red] up, w_u1[red] down.
    model.step();
    assert!(model.weights(0)[0] > 0.0 && model.weights(1)[0] < 0.0);
}

fn artefacts(dir: &Path, algos: &[&str], seed: u64) {
    for f in [
        "config.toml",
        "run.json",
        "metrics.csv",
        "summary.csv",
        "summary.md",
        "success.svg",
        "task_return.svg",
        "rm/perfect.txt",
        "rm/perfect.dot",
        "rm/learned.txt",
        "rm/learned.dot",
        "rm/report.txt",
        "logs/demos.mcap",
    ] {
        assert!(dir.join(f).is_file(), "missing {f}");
    }
    // The report sets the learned machine's LRM cost beside the perfect machine's.
    let report = std::fs::read_to_string(dir.join("rm/report.txt")).unwrap();
    let line = report
        .lines()
        .find(|l| l.starts_with("LRM cost "))
        .expect("LRM cost line");
    let perfect_cost: f64 = line
        .split("same traces: ")
        .nth(1)
        .and_then(|rest| rest.split(')').next())
        .and_then(|v| v.parse().ok())
        .unwrap_or_else(|| panic!("no perfect machine's cost in {line:?}"));
    // Zero when every next label is determined (scripted demonstrations of one route).
    assert!(perfect_cost.is_finite() && perfect_cost >= 0.0, "{line}");
    for a in algos {
        assert!(
            dir.join(format!("logs/{a}_seed{seed}.mcap")).is_file(),
            "{a} log"
        );
        let ext = if a.starts_with("smirl") {
            "json"
        } else {
            "bin"
        };
        assert!(
            dir.join(format!("rewards/{a}_seed{seed}.{ext}")).is_file(),
            "{a} reward"
        );
        if a.starts_with("smirl") {
            check_reward_trace(dir, a, seed);
        }
    }
    check_final_policy(dir, algos, seed);
    let metrics = std::fs::read_to_string(dir.join("metrics.csv")).unwrap();
    // Header + (iterations + 1) rows per job.
    assert_eq!(metrics.lines().count(), 1 + algos.len() * 3, "{metrics}");
    let svg = std::fs::read_to_string(dir.join("success.svg")).unwrap();
    assert!(svg.starts_with("<svg") || svg.starts_with("<?xml"));
    // The demos log opens with the project's reader.
    let log = smirl::log::read_log(&dir.join("logs/demos.mcap")).unwrap();
    assert!(!log.episodes.is_empty());
    // Each job's log holds SAC's training episodes as well as its rollouts and evaluations,
    // every second one (log_every_nth_episode = 2), and all of them replay bit for bit with
    // the task machine re-tracked.
    for a in algos {
        let log = smirl::log::read_log(&dir.join(format!("logs/{a}_seed{seed}.mcap"))).unwrap();
        for phase in ["train", "agent", "eval"] {
            assert!(
                log.episodes.iter().any(|e| e.start.phase == phase),
                "{a}: no {phase} episode"
            );
        }
        // The final phase (every algorithm's here) logs its selection and ground-truth
        // episodes too.
        for phase in ["select", "final"] {
            assert!(
                log.episodes.iter().any(|e| e.start.phase == phase),
                "{a}: {phase} episodes"
            );
        }
        assert!(log.episodes.iter().all(|e| e.start.episode % 2 == 0));
        // No training episode is cut off by an iteration boundary: each runs its 70 steps
        // (ReacherDelivery never terminates early, nor does the learned OR machine, which has
        // no terminal state) and ends in the log.
        for e in log.episodes.iter().filter(|e| e.start.phase == "train") {
            assert!(
                e.is_complete(),
                "{a}: training episode {} cut off",
                e.start.episode
            );
            assert_eq!(
                e.steps.len(),
                70,
                "{a}: training episode {}",
                e.start.episode
            );
        }
        let report = smirl::pipeline::replay::replay(&log).unwrap();
        assert!(report.all_match(), "{a}: {report}");
        assert!(report.episodes.iter().all(|e| e.rm_checked), "{a}");
    }
}

/// `final_policy.csv`: per job (every algorithm with a learned reward has the final phase) the
/// co-trained policy and `final_checkpoints` candidates, the chosen one the first of
/// highest selection return (the cut return, else the learned return), one random pick; the
/// co-trained candidate is the policy of the last metrics row, judged on the same episodes, so
/// its success is that row's.
fn check_final_policy(dir: &Path, algos: &[&str], seed: u64) {
    use smirl::pipeline::reacher_irl::evaluation::final_set_episodes;
    let table = std::fs::read_to_string(dir.join("final_policy.csv")).unwrap();
    let metrics = std::fs::read_to_string(dir.join("metrics.csv")).unwrap();
    let mut lines = table.lines();
    assert_eq!(
        lines.next(),
        Some("algo,seed,candidate,env_steps,learned_return,chosen,success_rate,success_normal,success_cancel,progress,final_ball,random,final_set_episodes,final_set_success_rate,final_set_success_normal,final_set_success_cancel")
    );
    let rows: Vec<Vec<&str>> = lines.map(|l| l.split(',').collect()).collect();
    let config = tiny_config();
    let per_job = config.final_checkpoints as usize + 1;
    assert_eq!(rows.len(), algos.len() * per_job, "{table}");
    for a in algos {
        let job: Vec<&Vec<&str>> = rows
            .iter()
            .filter(|r| r[0] == *a && r[1] == seed.to_string())
            .collect();
        assert_eq!(job.len(), per_job, "{table}");
        // The number the choice reads: the learned return.
        let returns: Vec<f64> = job.iter().map(|r| r[4].parse().unwrap()).collect();
        let best = returns.iter().cloned().fold(f64::MIN, f64::max);
        let first_best = returns.iter().position(|&x| x == best).unwrap();
        let chosen: Vec<usize> = (0..per_job).filter(|&i| job[i][5] == "1").collect();
        assert_eq!(chosen, vec![first_best], "{table}");
        let picked = (0..per_job).filter(|&i| job[i][11] == "1").count();
        assert_eq!(picked, 1, "{table}");
        // Every candidate judged on the final set too: ⌈50 · eval_episodes / 20⌉ per branch.
        let per_branch = final_set_episodes(&config);
        for r in &job {
            let n: u64 = r[12].parse().unwrap();
            assert!(n == per_branch || n == 2 * per_branch, "{table}");
            assert!(
                (0.0..=1.0).contains(&r[13].parse::<f64>().unwrap()),
                "{table}"
            );
        }
        // Candidates 140 SAC steps apart (two 70-step episodes), the first at the end of the
        // IRL loop: the last metrics row's policy, with its success.
        let last_row: Vec<&str> = metrics
            .lines()
            .rfind(|l| l.starts_with(&format!("{a},{seed},")))
            .unwrap()
            .split(',')
            .collect();
        let loop_end: u64 = last_row[3].parse().unwrap();
        let steps: Vec<u64> = job.iter().map(|r| r[3].parse().unwrap()).collect();
        assert_eq!(steps, [loop_end, loop_end + 140, loop_end + 280], "{table}");
        assert_eq!(job[0][6], last_row[4], "{last_row:?}");
    }
}

/// SMIRL's reward trace: one row per (iteration, learned state, feature), and the weights of
/// the last iteration are the saved reward's.
fn check_reward_trace(dir: &Path, algo: &str, seed: u64) {
    let text =
        std::fs::read_to_string(dir.join(format!("rewards/{algo}_seed{seed}.trace.csv"))).unwrap();
    let mut lines = text.lines();
    assert_eq!(
        lines.next(),
        Some("iteration,rm_state,feature,weight,data_gradient")
    );
    let rows: Vec<Vec<&str>> = lines.map(|l| l.split(',').collect()).collect();
    let saved: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(dir.join(format!("rewards/{algo}_seed{seed}.json"))).unwrap(),
    )
    .unwrap();
    let weights = saved["weights"].as_array().unwrap();
    let n_states = weights.len();
    // tiny_config: 2 iterations; 5 features (r, g, b, y, c).
    assert_eq!(rows.len(), 2 * n_states * 5, "{text}");
    for (u, w) in weights.iter().enumerate() {
        for (k, (w, name)) in w
            .as_array()
            .unwrap()
            .iter()
            .zip("rgbyc".chars())
            .enumerate()
        {
            let row = &rows[n_states * 5 + u * 5 + k];
            assert_eq!(row[..3], ["2", &u.to_string(), &name.to_string()]);
            let traced: f64 = row[3].parse().unwrap();
            assert!(
                (traced - w.as_f64().unwrap()).abs() < 1e-5,
                "{row:?} vs {w}"
            );
            assert!(row[4].parse::<f64>().unwrap().is_finite());
        }
    }
}

#[test]
fn tiny_library_run_writes_every_artefact_and_is_reproducible() {
    let tmp = tempfile::tempdir().unwrap();
    let request = |out: &str| RunRequest {
        task: ReacherTask::shipped("or").unwrap(),
        algos: vec![Algo::Smirl, Algo::Fkl],
        seeds: 1,
        seed: 3,
        config: tiny_config(),
        out: tmp.path().join(out),
        force: false,
    };
    let a = run_pipeline(&request("a"), &Silent).unwrap();
    assert!(a.rm.as_ref().unwrap().learned_states >= 1);
    artefacts(&tmp.path().join("a"), &["smirl", "fkl"], 3);
    assert!(!tmp.path().join("a.partial").exists());
    run_pipeline(&request("b"), &Silent).unwrap();
    let read = |d: &str| std::fs::read(tmp.path().join(d).join("metrics.csv")).unwrap();
    assert_eq!(read("a"), read("b"), "same seed must give the same metrics");
}

fn reacher() -> Command {
    Command::new(env!("CARGO_BIN_EXE_reacher"))
}

#[test]
fn cli_tiny_run_and_bad_input() {
    let tmp = tempfile::tempdir().unwrap();
    let cfg = tmp.path().join("tiny.toml");
    std::fs::write(&cfg, tiny_config().to_toml()).unwrap();
    let out = tmp.path().join("run");
    let status = reacher()
        .args([
            "--task",
            "sequential",
            "--algo",
            "smirl-smooth,maxent",
            "--seed",
            "1",
            "--quiet",
        ])
        .arg("--config")
        .arg(&cfg)
        .arg("--out")
        .arg(&out)
        .status()
        .unwrap();
    assert!(status.success());
    artefacts(&out, &["smirl-smooth", "maxent"], 1);

    // Bad input: exit 2, nothing written.
    let full = tiny_config().to_toml();
    let missing = full.replace("irl_iterations = 2\n", "");
    let mistyped = full.replace("irl_iterations = 2", "irl_iterations = \"two\"");
    let unknown = format!("irl_iteratoins = 2\n{full}");
    /// (CLI arguments, optional config file (name, text), text the error must contain)
    type BadInput<'a> = (Vec<String>, Option<(&'a str, String)>, &'a str);
    let cases: Vec<BadInput> = vec![
        (vec!["--task".into(), "pentagon".into()], None, "pentagon"),
        (
            vec!["--task".into(), "or".into(), "--algo".into(), "gail".into()],
            None,
            "gail",
        ),
        (
            vec!["--task".into(), "or".into(), "--seeds".into(), "0".into()],
            None,
            "seeds",
        ),
        (
            vec!["--task".into(), "or".into()],
            Some(("missing.toml", missing)),
            "irl_iterations",
        ),
        (
            vec!["--task".into(), "or".into()],
            Some(("mistyped.toml", mistyped)),
            "irl_iterations",
        ),
        (
            vec!["--task".into(), "or".into()],
            Some(("unknown.toml", unknown)),
            "irl_iteratoins",
        ),
    ];
    for (args, file, needle) in cases {
        let bad_out = tmp.path().join("bad");
        let mut cmd = reacher();
        cmd.args(&args).arg("--out").arg(&bad_out);
        if let Some((name, text)) = &file {
            let p = tmp.path().join(name);
            std::fs::write(&p, text).unwrap();
            cmd.arg("--config").arg(&p);
        }
        let o = cmd.output().unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {err}");
        assert!(err.contains(needle), "{args:?}: {err}");
        assert!(!bad_out.exists() && !tmp.path().join("bad.partial").exists());
    }
}

/// Every shipped config of experiments/reacher either parses or, written for the old layout
/// (a record of the runs made with it), is refused naming an old key and what replaced it.
#[test]
fn shipped_configs_parse_or_are_refused_naming_the_replacement() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("experiments/reacher");
    let (mut parsed, mut refused) = (Vec::new(), 0);
    for dir in [dir.clone(), dir.join("ablations"), dir.join("controls")] {
        for entry in std::fs::read_dir(&dir).unwrap() {
            let path = entry.unwrap().path();
            if path.extension().is_some_and(|e| e == "toml") {
                match IrlRunConfig::load(&path) {
                    Ok(_) => parsed.push(path.file_name().unwrap().to_owned()),
                    Err(e) => {
                        let e = e.to_string();
                        assert!(
                            e.contains("is no longer a key") && e.contains("replaced by"),
                            "{}: {e}",
                            path.display()
                        );
                        refused += 1;
                    }
                }
            }
        }
    }
    parsed.sort();
    assert_eq!(
        parsed,
        [
            "config.toml",
            "config_one_state.toml",
            "quick.toml",
            "quick_one_state.toml"
        ]
    );
    assert!(refused >= 30, "{refused}");
}

/// The one-state control's configs are the standard and quick profiles with a one-state machine
/// and nothing else changed, as the evaluation's protocol says.
#[test]
fn one_state_configs_differ_from_their_profiles_in_the_machine_only() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("experiments/reacher");
    for (file, mut profile) in [
        ("config_one_state.toml", IrlRunConfig::standard()),
        ("quick_one_state.toml", IrlRunConfig::quick()),
    ] {
        profile.smirl_machine = smirl::pipeline::reacher_irl::SmirlMachine::OneState;
        assert_eq!(
            IrlRunConfig::load(&dir.join(file)).unwrap(),
            profile,
            "{file}"
        );
    }
}

/// The shipped figure-7 config is the built-in default profile, so `reacher --task t` and
/// `experiments/reacher/run.sh` run the same thing.
#[test]
fn shipped_config_is_the_default_profile() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("experiments/reacher/config.toml");
    assert_eq!(IrlRunConfig::load(&path).unwrap(), IrlRunConfig::standard());
}

/// Regression: `quick.toml` lagged the quick profile (a setting of the standard missing from
/// it), though docs/configuration.md calls it that profile.
#[test]
fn shipped_quick_config_is_the_quick_profile() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("experiments/reacher/quick.toml");
    assert_eq!(IrlRunConfig::load(&path).unwrap(), IrlRunConfig::quick());
}

/// `[smirl] machine`: required; `"learned"` in the standard profile, `"task"` read and
/// written back; a bad value names the file and the value, a config without the key the key.
#[test]
fn smirl_machine_key_is_required_and_round_trips() {
    use smirl::pipeline::reacher_irl::SmirlMachine;
    let standard = IrlRunConfig::standard();
    let text = standard.to_toml();
    let line = "machine = \"learned\"\n";
    assert!(text.contains(line), "{text}");
    assert_eq!(standard.smirl_machine, SmirlMachine::Learned);
    let c = IrlRunConfig::from_toml(&text.replace(line, "machine = \"task\"\n"), "c.toml").unwrap();
    assert_eq!(c.smirl_machine, SmirlMachine::Task);
    assert_eq!(c.smirl_machine.name(), "task");
    assert_eq!(IrlRunConfig::from_toml(&c.to_toml(), "c.toml").unwrap(), c);
    assert_config_error_names(&text.replace(line, "machine = \"perfect\"\n"), "perfect");
    assert_config_error_names(&text.replace(line, ""), "missing field `machine`");
}

/// `text`, read as the config file `c.toml`, is refused with an error naming the file and
/// `value`.
fn assert_config_error_names(text: &str, value: &str) {
    let err = IrlRunConfig::from_toml(text, "c.toml")
        .unwrap_err()
        .to_string();
    assert!(err.contains("c.toml") && err.contains(value), "{err}");
}

/// `[smirl] machine = "task"`: the machine SMIRL reads is the task's own with no goal, no failure
/// sink and no rewards — every task's perfect machine's states along any trace until it ends,
/// then it stays — and a run prepared with it writes that machine, says so in its report, and
/// its SMIRL job runs on it.
#[test]
fn task_machine_is_the_perfect_machine_without_its_ends() {
    use smirl::pipeline::reacher_irl::smirl::task_machine;
    use smirl::rm::format::parse_rm;
    use smirl::rm::LabelSet;
    for task in [
        ReacherTask::shipped("or").unwrap(),
        ReacherTask::shipped("sequential").unwrap(),
        ReacherTask::shipped("if").unwrap(),
        ReacherTask::shipped("composite").unwrap(),
    ] {
        let perfect = task.perfect_rm().unwrap();
        let m = task_machine(&perfect).unwrap();
        assert_eq!(m.n_states(), perfect.n_states(), "{task}");
        assert!(m.terminal_states().is_empty() && m.failure_states().is_empty());
        // Every label-set sequence of length 3 over the vocabulary: the same states while the
        // perfect machine runs, no reward anywhere.
        let sets: Vec<LabelSet> = perfect.vocab().all_label_sets().collect();
        for &a in &sets {
            for &b in &sets {
                for &c in &sets {
                    let (mut u, mut v) = (perfect.initial(), m.initial());
                    for l in [a, b, c] {
                        if perfect.is_absorbing(u) {
                            assert_eq!(m.next_state(v, l), v, "{task}: an end state stays");
                            continue;
                        }
                        assert_eq!(m.reward(v, l), 0.0);
                        u = perfect.next_state(u, l);
                        v = m.next_state(v, l);
                        assert_eq!(u, v, "{task}");
                    }
                }
            }
        }
    }

    let mut config = tiny_config();
    config.smirl_machine = smirl::pipeline::reacher_irl::SmirlMachine::Task;
    let (_tmp, dir, summary) = tiny_smirl_run(ReacherTask::shipped("or").unwrap(), config);
    assert_eq!(summary.rm.as_ref().unwrap().learned_states, 3);
    assert!(summary.rm.as_ref().unwrap().refines_perfect);
    let text = std::fs::read_to_string(dir.join("rm/learned.txt")).unwrap();
    let written = parse_rm(&text, "learned.txt").unwrap();
    assert_eq!(
        written,
        task_machine(&ReacherTask::shipped("or").unwrap().perfect_rm().unwrap()).unwrap()
    );
    let report = std::fs::read_to_string(dir.join("rm/report.txt")).unwrap();
    assert!(report.contains("smirl_machine = \"task\""), "{report}");
    let metrics = std::fs::read_to_string(dir.join("metrics.csv")).unwrap();
    assert!(
        metrics.lines().skip(1).any(|l| l.starts_with("smirl,3,")),
        "{metrics}"
    );
}

/// One SMIRL job on `task` (base seed 3) with `config`: the temporary directory, its run
/// directory and the run's summary.
fn tiny_smirl_run(
    task: ReacherTask,
    config: IrlRunConfig,
) -> (
    tempfile::TempDir,
    PathBuf,
    smirl::pipeline::reacher_irl::RunSummary,
) {
    let tmp = tempfile::tempdir().unwrap();
    let request = RunRequest {
        task,
        algos: vec![Algo::Smirl],
        seeds: 1,
        seed: 3,
        config,
        out: tmp.path().join("run"),
        force: false,
    };
    let summary = run_pipeline(&request, &Silent).unwrap();
    let dir = tmp.path().join("run");
    (tmp, dir, summary)
}

/// A SMIRL job's final choice reads the plain learned return of each candidate: the record's
/// choice is `choose` of its candidates, and `final_policy.csv` has one learned return per
/// candidate and no other number the choice could read.
#[test]
fn a_smirl_job_chooses_by_the_learned_return() {
    use smirl::pipeline::reacher_irl::final_policy::choose;
    use smirl::pipeline::reacher_irl::records::JobRecord;
    let config = tiny_config();
    let (_tmp, dir, _) = tiny_smirl_run(ReacherTask::shipped("if").unwrap(), config);
    let table = std::fs::read_to_string(dir.join("final_policy.csv")).unwrap();
    let header: Vec<&str> = table.lines().next().unwrap().split(',').collect();
    assert!(!header.contains(&"cut_return"), "{header:?}");
    let column = header.iter().position(|&c| c == "learned_return").unwrap();
    for row in table.lines().skip(1) {
        let cell = row.split(',').nth(column).unwrap();
        assert!(cell.parse::<f64>().unwrap().is_finite(), "{row}");
    }
    let record: JobRecord =
        serde_json::from_str(&std::fs::read_to_string(dir.join("jobs/smirl_seed3.json")).unwrap())
            .unwrap();
    let f = record.final_policy.unwrap();
    assert!(f.candidates.len() > 1);
    assert_eq!(f.chosen, choose(&f.candidates));
}

/// `[sac]` gives five keys, each required; the rest of SAC is the IRL runs' (`irl_run_sac`),
/// and a config that sets one of its old keys is refused naming what replaced it.
#[test]
fn sac_table_sets_five_keys_over_the_irl_run_sac() {
    use smirl::pipeline::reacher_irl::config::irl_run_sac;
    use smirl::rl::sac::SacConfig;
    let text = IrlRunConfig::standard().to_toml();
    let c = IrlRunConfig::from_toml(
        &text.replace("warmup_steps = 1000\n", "warmup_steps = 7\n"),
        "c.toml",
    )
    .unwrap();
    assert_eq!(
        c.sac,
        SacConfig {
            warmup_steps: 7,
            update_after: 7,
            ..irl_run_sac()
        }
    );
    assert_eq!(IrlRunConfig::standard().sac, irl_run_sac());
    assert_config_error_names(&text.replace("alpha = 0.2\n", ""), "missing field `alpha`");
    for (old, replacement) in [
        ("batch_size = 128\n", "fixed at 256"),
        ("update_after = 10\n", "[sac] warmup_steps"),
        ("preset = \"irl\"\n", "the rest is fixed"),
    ] {
        let err =
            IrlRunConfig::from_toml(&text.replace("[sac]\n", &format!("[sac]\n{old}")), "c.toml")
                .unwrap_err()
                .to_string();
        let key = old.split(' ').next().unwrap();
        assert!(
            err.contains("c.toml")
                && err.contains(&format!("sac.{key}"))
                && err.contains(replacement),
            "{err}"
        );
    }
    // A config built in code cannot carry a SAC setting the file could not hold.
    let mut c = IrlRunConfig::standard();
    c.sac.batch_size = 64;
    assert!(c
        .validate("c")
        .unwrap_err()
        .to_string()
        .contains("sac.batch_size"));
}

/// Every demonstration is held at its final state: a demonstration that ends at the goal is extended to the time
/// limit by holding its final state (zero joint velocities, no cancel event, the labels of
/// that state), the learned machine stepping on the held labels; `None` leaves it as is.
#[test]
fn annotate_holds_the_final_state_to_the_horizon() {
    use smirl::pipeline::reacher_expert::{Demo, DemoStep};
    use smirl::pipeline::reacher_irl::smirl::annotate;
    use smirl::rm::{Formula, RewardMachine, Transition, Vocabulary};
    let vocab = Vocabulary::new("rgbyc");
    let tr = |from, to, f: &str| Transition {
        from,
        to,
        formula: Formula::parse(f, &vocab).unwrap(),
        reward: 0.0,
    };
    // u0 --r--> u1 --b--> u2 (no terminal state: learned machines have none).
    let rm = RewardMachine::new(
        vocab.clone(),
        3,
        0,
        &[],
        &[],
        vec![tr(0, 1, "r"), tr(1, 2, "b")],
    )
    .unwrap();
    let step = |ball: Option<usize>, cancel: bool| {
        let mut next = row(ball);
        next[4] = 0.3;
        next[5] = -0.2;
        next[16] = f32::from(u8::from(cancel));
        let mut labels = FeatureMap::reacher_labels(&layout()).labels_of(&next);
        if cancel {
            labels = labels.with(4);
        }
        DemoStep {
            obs: vec![0.0; obs_dim()],
            action: [0.0; 2],
            next_obs: next,
            labels,
            rm_state: 0,
            env_reward: 0.0,
            task_reward: 0.0,
        }
    };
    let steps = vec![step(None, false), step(Some(0), false), step(Some(2), true)];
    let demo = Demo {
        seed: 0,
        initial_rm_state: 0,
        initial_labels: smirl::rm::LabelSet::EMPTY,
        steps,
        success: true,
        task_return: 1.0,
        env_return: 0.0,
    };
    let plain = annotate(&layout(), std::slice::from_ref(&demo), Some(&rm), None);
    assert_eq!(plain.lengths, vec![3]);
    assert_eq!(plain.learned_states, vec![0, 0, 1]);

    let held = annotate(&layout(), std::slice::from_ref(&demo), Some(&rm), Some(6));
    assert_eq!(held.lengths, vec![6]);
    // After the final (blue) step the machine is in u2, where the held blue touch is read.
    assert_eq!(held.learned_states, vec![0, 0, 1, 2, 2, 2]);
    assert_eq!(&held.obs[..3 * obs_dim()], &plain.obs[..]);
    let last = &plain.obs[2 * obs_dim()..];
    for t in 3..6 {
        let r = &held.obs[t * obs_dim()..(t + 1) * obs_dim()];
        assert_eq!((r[4], r[5], r[16]), (0.0, 0.0, 0.0), "held step {t}");
        assert_eq!(&r[..4], &last[..4]);
        assert_eq!(&r[6..16], &last[6..16]);
        assert_eq!(
            FeatureMap::reacher_labels(&layout()).labels_of(r),
            vocab.parse_labels("b").unwrap()
        );
    }
    // A demonstration already at the horizon is not extended.
    let full = annotate(&layout(), std::slice::from_ref(&demo), Some(&rm), Some(2));
    assert_eq!(full.lengths, vec![3]);
}

/// `expert_data.bin`: what `reacher prepare` hands the jobs reads back exactly; a file whose
/// arrays disagree, a cut one and one of another format version are refused.
#[test]
fn expert_data_round_trips_and_checks_its_arrays() {
    let mut data = ExpertData {
        obs: (0..3 * obs_dim()).map(|i| i as f32 * 0.01).collect(),
        lengths: vec![2, 1],
        learned_states: vec![0, 1, 0],
    };
    let bytes = data.to_bytes();
    let back = ExpertData::from_bytes(&bytes, obs_dim()).unwrap();
    assert_eq!(back.obs, data.obs);
    assert_eq!(back.lengths, data.lengths);
    assert_eq!(back.learned_states, data.learned_states);
    assert!(ExpertData::from_bytes(&bytes[..bytes.len() - 3], obs_dim()).is_err());
    // The version follows the 8 magic bytes; 2 is the layout with the labels before each step.
    let mut old = bytes.clone();
    old[8..12].copy_from_slice(&2u32.to_le_bytes());
    let err = ExpertData::from_bytes(&old, obs_dim())
        .unwrap_err()
        .to_string();
    assert!(err.contains("version 2 is not supported"), "{err}");
    data.obs.truncate(2 * obs_dim());
    let err = ExpertData::from_bytes(&data.to_bytes(), obs_dim())
        .unwrap_err()
        .to_string();
    assert!(err.contains("do not fill"), "{err}");
    data.lengths = vec![1, 1];
    data.learned_states.pop();
    data.learned_states.pop();
    let err = ExpertData::from_bytes(&data.to_bytes(), obs_dim())
        .unwrap_err()
        .to_string();
    assert!(err.contains("1 states for 2 steps"), "{err}");
}

/// The final phase's keys are checked together (a message names `[final]`'s key), and a
/// config without them is refused naming the missing key.
#[test]
fn final_policy_settings_are_checked() {
    let mut c = IrlRunConfig::standard();
    for (steps, checkpoints, ok) in [
        (0, 0, true),
        (20_000, 4, true),
        (5, 5, true),
        (0, 4, false),
        (20_000, 0, false),
        (3, 4, false),
        (20_000, 1_001, false),
        (100_000_001, 4, false),
    ] {
        c.final_sac_steps = steps;
        c.final_checkpoints = checkpoints;
        match c.validate("test") {
            Ok(()) => assert!(ok, "{steps} steps, {checkpoints} checkpoints accepted"),
            Err(e) => {
                assert!(!ok, "{steps}, {checkpoints}: {e}");
                assert!(e.to_string().contains("final."), "{e}");
            }
        }
    }
    let standard = IrlRunConfig::standard();
    let text = standard.to_toml();
    assert!(text.contains("[final]\nsac_steps = 20000\ncheckpoints = 4\n"));
    assert_config_error_names(
        &text.replace("checkpoints = 4\n", "checkpoints = 4\nfresh_steps = 280\n"),
        "fresh_steps",
    );
    // A config without a key of the phase is refused (never read as "no final phase").
    assert_config_error_names(
        &text.replace("checkpoints = 4\n", ""),
        "missing field `checkpoints`",
    );
    // A removed key is refused naming what replaced it.
    assert_config_error_names(
        &text.replace(
            "checkpoints = 4\n",
            "checkpoints = 4\nreset_steps = 20000\n",
        ),
        "the final phase has no reset agent",
    );
    // The old layout's keys are refused naming their new place.
    let old = format!("smirl_final_sac_steps = 20000\n{text}");
    assert_config_error_names(&old, "[final] sac_steps");
}

/// LRM's mechanisms are not settings: a config that still sets one of their old keys is
/// refused with the file, the line and the key named (and the ablation keys removed before
/// them); a config without them reads as the standard.
#[test]
fn lrm_search_settings_are_checked() {
    use smirl::pipeline::reacher_irl::config::REMOVED_KEYS;
    let text = IrlRunConfig::standard().to_toml();
    assert!(!text.contains("lrm_guards") && !text.contains("lrm_predict_events"));
    for removed in [
        "lrm_starts = 32\n",
        "lrm_patience = 0\n",
        "lrm_remember_events = true\n",
        "lrm_borrow_events = true\n",
        "lrm_fallback_starts = 28\n",
        "lrm_initial_events = true\n",
        "lrm_guards = \"tree\"\n",
        "lrm_commute_events = true\n",
        "lrm_event_stutter = true\n",
        "lrm_predict_events = false\n",
    ] {
        let key = removed.split(' ').next().unwrap();
        assert_config_error_names(&format!("{removed}{text}"), key);
    }
    for (key, replacement) in REMOVED_KEYS.iter().filter(|(k, _)| !k.contains('.')) {
        let err = IrlRunConfig::from_toml(&format!("# a\n{key} = false\n{text}"), "c.toml")
            .unwrap_err()
            .to_string();
        assert!(
            err.starts_with("c.toml: line 2: field `")
                && err.contains(key)
                && err.contains(replacement),
            "{err}"
        );
    }
    assert_eq!(
        IrlRunConfig::from_toml(&text, "c.toml").unwrap(),
        IrlRunConfig::standard()
    );
}

/// `reacher` refuses a config file that sets a removed LRM key before any work: exit 2, the
/// file and the key named, nothing written.
#[test]
fn a_config_with_a_removed_lrm_key_is_refused_by_the_cli() {
    let tmp = tempfile::tempdir().unwrap();
    let cfg = tmp.path().join("old.toml");
    std::fs::write(
        &cfg,
        format!(
            "lrm_guards = \"exact\"\n{}",
            IrlRunConfig::quick().to_toml()
        ),
    )
    .unwrap();
    let out = tmp.path().join("run");
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_reacher"))
        .args(["--task", "or", "--algo", "smirl", "--quiet", "--config"])
        .arg(&cfg)
        .arg("--out")
        .arg(&out)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{stderr}");
    assert!(
        stderr.contains("old.toml") && stderr.contains("lrm_guards"),
        "{stderr}"
    );
    assert!(!out.exists() && !tmp.path().join("run.partial").exists());
}

#[test]
fn final_policy_is_the_first_candidate_of_highest_learned_return() {
    use smirl::pipeline::reacher_irl::final_policy::{choose, FinalCandidate};
    let candidate = |learned_return: f64, success_rate: f64| FinalCandidate {
        env_steps: 0,
        learned_return,
        success_rate,
        branches: None,
        progress: 0.0,
        final_ball: 0.0,
        final_set: None,
    };
    let c = [
        candidate(10.0, 1.0),
        candidate(42.0, 0.0),
        candidate(42.0, 1.0),
        candidate(-5.0, 1.0),
    ];
    assert_eq!(choose(&c), 1);
    assert_eq!(choose(&c[..1]), 0);
    assert_eq!(choose(&c[2..]), 0);
}

/// The standard profile without its per-algorithm schedules: what SMIRL runs with.
fn without_schedules() -> IrlRunConfig {
    let mut c = IrlRunConfig::standard();
    c.schedule.clear();
    c
}

/// The standard profile without schedules: one schedule for every algorithm.
fn uniform() -> IrlRunConfig {
    without_schedules()
}

/// The standard profile gives the baselines f-IRL's schedule (800 × 300 SAC steps, 300
/// trajectories, 2 reward steps, SAC lr 3e-3 with α = 1 fixed, replay 12 000) and SMIRL the
/// run's own (30 × 5 000).
#[test]
fn standard_profile_gives_each_algorithm_its_schedule() {
    let standard = IrlRunConfig::standard();
    for algo in [Algo::MaxEnt, Algo::Fkl, Algo::Rkl, Algo::Js] {
        let c = standard.for_algo(algo).unwrap();
        assert_eq!(
            (
                c.irl_iterations,
                c.sac_steps_per_iteration,
                c.agent_trajectories
            ),
            (800, 300, 300),
            "{algo}"
        );
        assert_eq!(c.reward_steps_per_iteration, 2);
        assert_eq!(c.mlp_reward_l2, 0.0);
        assert_eq!(
            (c.sac.lr, c.sac.alpha, c.sac.auto_alpha),
            (0.003, 1.0, false)
        );
        // The replay size is the run's, shared by every algorithm.
        assert_eq!(c.sac.replay_capacity, standard.sac.replay_capacity);
        // Only rkl draws demonstrations into its covariance batch (it fails "blue" without).
        let drawn = if algo == Algo::Rkl { 300 } else { 0 };
        assert_eq!(c.firl_expert_trajectories, drawn, "{algo}");
    }
    for algo in [Algo::Smirl, Algo::SmirlSmooth] {
        let c = standard.for_algo(algo).unwrap();
        assert_eq!(c, without_schedules(), "{algo}");
        assert_eq!(c.irl_iterations, 30, "{algo}");
    }
    assert!(IrlRunConfig::quick().schedule.is_empty());
}

/// `[schedule.<algo>]`: an algorithm's own IRL schedule replaces exactly the fields it names
/// (the SAC keys on top of the run's `[sac]`); the other algorithms keep the run's; the
/// config prints and parses back unchanged.
#[test]
fn per_algorithm_schedules_replace_only_their_fields() {
    use smirl::rl::sac::SacConfig;
    let text = uniform().to_toml()
        + "\n[schedule.fkl]\nirl_iterations = 800\nsac_steps_per_iteration = 300\n\
           agent_trajectories = 300\nreward_steps_per_iteration = 2\n\
           \n[schedule.fkl.firl]\nreward_l2 = 0.0\n\
           \n[schedule.fkl.sac]\nlr = 0.003\nalpha = 1.0\nauto_alpha = false\n";
    let c = IrlRunConfig::from_toml(&text, "c.toml").unwrap();
    let standard = uniform();
    let fkl = c.for_algo(Algo::Fkl).unwrap();
    assert_eq!(
        (
            fkl.irl_iterations,
            fkl.sac_steps_per_iteration,
            fkl.agent_trajectories,
            fkl.reward_steps_per_iteration,
            fkl.mlp_reward_l2
        ),
        (800, 300, 300, 2, 0.0)
    );
    assert_eq!(
        fkl.sac,
        SacConfig {
            lr: 0.003,
            alpha: 1.0,
            auto_alpha: false,
            ..standard.sac.clone()
        }
    );
    assert_eq!(fkl.mlp_reward_lr, standard.mlp_reward_lr);
    assert_eq!(fkl.env, standard.env);
    assert!(fkl.schedule.is_empty());
    for algo in [Algo::Smirl, Algo::MaxEnt, Algo::Rkl] {
        assert_eq!(c.for_algo(algo).unwrap(), standard, "{algo}");
    }
    let printed = c.to_toml();
    assert!(printed.contains("[schedule.fkl]"), "{printed}");
    assert_eq!(IrlRunConfig::from_toml(&printed, "printed").unwrap(), c);
    // Without schedules the printed config is what it always was.
    assert!(!standard.to_toml().contains("schedule"));
}

/// A schedule for an unknown algorithm, an unknown or out-of-range field in one: an error
/// naming the schedule's key and its line, before any work.
#[test]
fn bad_schedules_name_the_key_and_line() {
    let base = uniform().to_toml();
    let base_lines = base.lines().count();
    for (table, expected_key, expected_line) in [
        ("[schedule.fkx]\nirl_iterations = 3\n", "schedule.fkx", 2),
        (
            "[schedule.fkl]\nirl_iterations = 0\n",
            "schedule.fkl.irl_iterations",
            3,
        ),
        (
            "[schedule.js]\nagent_trajectories = 1000000\n",
            "schedule.js.agent_trajectories",
            3,
        ),
        (
            "[schedule.rkl.firl]\nkde_bandwidth = -1.0\n",
            "schedule.rkl.firl.kde_bandwidth",
            3,
        ),
        // A key of the old layout names its new place.
        (
            "[schedule.rkl]\nmlp_reward_l2 = 0.0\n",
            "[schedule.<algo>.firl] reward_l2",
            3,
        ),
        ("[schedule.fkl.sac]\nlr = -1.0\n", "schedule.fkl.sac.lr", 3),
        // The replay size is one [sac] setting for every algorithm.
        (
            "[schedule.fkl.sac]\nreplay_capacity = 12000\n",
            "schedule.fkl.sac.replay_capacity",
            3,
        ),
    ] {
        let text = format!("{base}\n{table}");
        let err = IrlRunConfig::from_toml(&text, "c.toml")
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("c.toml")
                && err.contains(expected_key)
                && err.contains(&format!("line {}", base_lines + expected_line)),
            "{table}: {err}"
        );
    }
    for (table, needle) in [
        ("[schedule.fkl]\nirl_iteration = 3\n", "irl_iteration"),
        ("[schedule.fkl]\nenv = 3\n", "env"),
        ("[schedule.fkl.sac]\nbatch = 3\n", "batch"),
    ] {
        let err = IrlRunConfig::from_toml(&format!("{base}\n{table}"), "c.toml")
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("c.toml") && err.contains(needle),
            "{table}: {err}"
        );
    }
}

/// A job runs with its algorithm's schedule: one IRL iteration for `maxent`, the run's two
/// for `smirl`, in the same run.
#[test]
fn jobs_run_with_their_algorithms_schedule() {
    let tmp = tempfile::tempdir().unwrap();
    let mut config = tiny_config();
    config.schedule.insert(
        "maxent".into(),
        smirl::pipeline::reacher_irl::config::AlgoSchedule {
            irl_iterations: Some(1),
            ..Default::default()
        },
    );
    let request = RunRequest {
        task: ReacherTask::shipped("or").unwrap(),
        algos: vec![Algo::Smirl, Algo::MaxEnt],
        seeds: 1,
        seed: 3,
        config,
        out: tmp.path().join("run"),
        force: false,
    };
    run_pipeline(&request, &Silent).unwrap();
    let metrics = std::fs::read_to_string(tmp.path().join("run/metrics.csv")).unwrap();
    let rows = |algo: &str| {
        metrics
            .lines()
            .filter(|l| l.starts_with(&format!("{algo},")))
            .count()
    };
    assert_eq!((rows("smirl"), rows("maxent")), (3, 2), "{metrics}");
    let written = std::fs::read_to_string(tmp.path().join("run/config.toml")).unwrap();
    assert!(written.contains("[schedule.maxent]"), "{written}");
}

/// Issue 14's positive control as a user runs it: `reacher --task blue --quick` with a
/// baseline of each family completes, and every row has the partial-progress columns and,
/// for f-IRL, the share of its states inside the expert's support.
#[test]
fn quick_positive_control_run_completes() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("blue");
    let o = reacher()
        .args([
            "--task",
            "blue",
            "--quick",
            "--algo",
            "maxent,fkl",
            "--quiet",
        ])
        .arg("--out")
        .arg(&out)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let metrics = std::fs::read_to_string(out.join("metrics.csv")).unwrap();
    let mut lines = metrics.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let col = |name: &str| header.iter().position(|h| *h == name).unwrap();
    let (algo, iteration, progress, support) = (
        col("algo"),
        col("iteration"),
        col("progress"),
        col("expert_support"),
    );
    let rows: Vec<Vec<&str>> = lines.map(|l| l.split(',').collect()).collect();
    // 4 quick iterations plus the untrained policy's evaluation, for each algorithm.
    assert_eq!(rows.len(), 2 * 5, "{metrics}");
    for r in &rows {
        let p: f64 = r[progress].parse().unwrap();
        assert!((0.0..=1.0).contains(&p), "{metrics}");
        if r[algo] == "fkl" && r[iteration] != "0" {
            let s: f64 = r[support].parse().unwrap();
            assert!((0.0..=1.0).contains(&s), "{metrics}");
        }
    }
    assert!(out.join("progress.svg").is_file());
}

/// SMIRL's agent acts on observation ⊕ one-hot learned state, no clock: a run trains with
/// counterfactual states on that observation (the relabeller refuses a width it was not built
/// for), replays its log and repeats itself per seed; `reacher retrain` on its reward trains in
/// the same product.
#[test]
fn smirls_product_runs_through_the_pipeline() {
    use smirl::pipeline::commands::irl::{retrain, RetrainRequest};
    let config = tiny_config();
    assert!(config.counterfactual() > 0.0);
    assert_eq!(
        config.for_algo(Algo::SmirlPaper).unwrap().counterfactual(),
        0.0
    );
    let (_with_tmp, with, _) = tiny_smirl_run(ReacherTask::shipped("or").unwrap(), config.clone());
    let (_again_tmp, again, _) = tiny_smirl_run(ReacherTask::shipped("or").unwrap(), config);
    let read = |dir: &PathBuf, file: &str| std::fs::read_to_string(dir.join(file)).unwrap();
    for file in ["metrics.csv", "final_policy.csv"] {
        assert_eq!(read(&with, file), read(&again, file), "{file}");
    }
    let log = smirl::log::read_log(&with.join("logs/smirl_seed3.mcap")).unwrap();
    let report = smirl::pipeline::replay::replay(&log).unwrap();
    assert!(report.all_match(), "{report}");

    retrain(RetrainRequest {
        run: with.clone(),
        algo: Algo::Smirl,
        seed: 3,
        steps: Some(200),
        sac_seed: 1,
        evaluations: 1,
        zero_states: Vec::new(),
        agent: None,
        force: false,
    })
    .unwrap();
    let table = read(&with, "retrain/smirl_seed3_sac1.csv");
    assert_eq!(table.lines().count(), 2, "{table}");
}

/// `[smirl] machine = "one_state"`, the control of issue 54 without structure: the run's machine
/// has one state and no transitions and its report says so, every expert step is in that
/// state, the SMIRL job learns one weight vector on it and keeps every other mechanism (its
/// final phase included).
#[test]
fn one_state_control_runs_smirl_on_a_one_state_machine() {
    use smirl::pipeline::reacher_irl::run::JobRecord;
    use smirl::pipeline::reacher_irl::SmirlMachine;
    use smirl::rm::format::parse_rm;
    let text = IrlRunConfig::standard().to_toml();
    let c = IrlRunConfig::from_toml(
        &text.replace("machine = \"learned\"", "machine = \"one_state\""),
        "c.toml",
    )
    .unwrap();
    assert_eq!(c.smirl_machine, SmirlMachine::OneState);
    assert!(c.to_toml().contains("machine = \"one_state\""));

    let mut config = tiny_config();
    config.smirl_machine = SmirlMachine::OneState;
    let (_tmp, dir, _) = tiny_smirl_run(ReacherTask::shipped("if").unwrap(), config);
    let read = |f: &str| std::fs::read_to_string(dir.join(f)).unwrap();
    let machine = parse_rm(&read("rm/learned.txt"), "learned.txt").unwrap();
    assert_eq!(machine.n_states(), 1);
    assert!(machine.transitions().is_empty());
    assert!(read("rm/report.txt").contains("smirl_machine = \"one_state\""));
    let bytes = std::fs::read(dir.join("expert_data.bin")).unwrap();
    let expert = ExpertData::from_bytes(&bytes, obs_dim()).unwrap();
    assert!(!expert.learned_states.is_empty());
    assert!(expert.learned_states.iter().all(|&u| u == 0));
    let reward: serde_json::Value =
        serde_json::from_str(&read("rewards/smirl_seed3.json")).unwrap();
    assert_eq!(reward["n_states"], 1);
    let record: JobRecord = serde_json::from_str(&read("jobs/smirl_seed3.json")).unwrap();
    assert!(record.final_policy.is_some());
}

/// The run config's keys: at most 30, each listed on its own line of docs/configuration.md
/// (the docs and the layout name the same set), each required. Mutations tried: a field added
/// to a table of `RunFile` without its line in the docs fails at the set comparison; one with
/// `#[serde(default)]` fails at "read without".
#[test]
fn the_config_has_at_most_30_keys_each_documented_and_required() {
    // The standard profile's keys, a table's dotted (`smirl.reward_lr`), the
    // `[schedule.<algo>]` overrides not counted.
    let layout: toml::Value = toml::from_str(&IrlRunConfig::standard().to_toml()).unwrap();
    let mut keys = Vec::new();
    for (k, v) in layout.as_table().unwrap() {
        match v {
            toml::Value::Table(t) if k != "schedule" => {
                keys.extend(t.keys().map(|sub| format!("{k}.{sub}")))
            }
            toml::Value::Table(_) => {}
            _ => keys.push(k.clone()),
        }
    }
    let doc = std::fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("docs/configuration.md"),
    )
    .unwrap();
    let section = doc.split("\n## Keys\n").nth(1).unwrap();
    let section = section.split("\n## ").next().unwrap();
    let mut documented: Vec<String> = section
        .lines()
        .filter_map(|l| l.strip_prefix("| `"))
        .map(|l| l.split('`').next().unwrap().to_string())
        .collect();
    documented.sort();
    keys.sort();
    assert_eq!(documented, keys);
    assert!(keys.len() <= 30, "{} keys", keys.len());
    // Print, load, print: the same text.
    let text = IrlRunConfig::standard().to_toml();
    let loaded = IrlRunConfig::from_toml(&text, "printed").unwrap();
    assert_eq!(loaded, IrlRunConfig::standard());
    assert_eq!(loaded.to_toml(), text);
    // Each key left out: refused naming it.
    for key in &keys {
        let (table, name) = match key.split_once('.') {
            Some((t, k)) => (Some(t), k),
            None => (None, key.as_str()),
        };
        let mut current: Option<&str> = None;
        let mut removed = 0;
        let without: String = text
            .lines()
            .filter(|l| {
                if let Some(h) = l.strip_prefix('[') {
                    current = Some(h.trim_end_matches(']'));
                }
                let hit = current == table && l.split(" = ").next() == Some(name);
                removed += usize::from(hit);
                !hit
            })
            .map(|l| format!("{l}\n"))
            .collect();
        assert_eq!(removed, 1, "{key}");
        let err = IrlRunConfig::from_toml(&without, "c.toml")
            .expect_err(&format!("read without {key}"))
            .to_string();
        assert!(
            err.contains("c.toml") && err.contains(&format!("missing field `{name}`")),
            "{key}: {err}"
        );
    }
}

/// The CLI refuses a config without a key (naming it) and one with a removed switch (naming
/// what replaced it) with exit status 2, before anything is written.
#[test]
fn the_cli_refuses_a_missing_key_and_a_removed_switch() {
    let tmp = tempfile::tempdir().unwrap();
    let quick = IrlRunConfig::quick().to_toml();
    for (name, text, needles) in [
        (
            "missing.toml",
            quick.replace("checkpoints = 2\n", ""),
            ["missing field `checkpoints`", "missing.toml"],
        ),
        (
            "missing_lrm.toml",
            quick.replace("steps = 50\n", ""),
            ["missing field `steps`", "missing_lrm.toml"],
        ),
        (
            "missing_top.toml",
            quick.replace("eval_episodes = 8\n", ""),
            ["missing field `eval_episodes`", "missing_top.toml"],
        ),
        (
            "old_env.toml",
            format!("{quick}\n[env]\nmax_steps = 100\n"),
            ["env.max_steps", "[env] episode_steps"],
        ),
        (
            "old.toml",
            format!("smirl_clock = false\n{quick}"),
            ["smirl_clock", "no learner's observation has a clock"],
        ),
    ] {
        let cfg = tmp.path().join(name);
        std::fs::write(&cfg, text).unwrap();
        let out = tmp.path().join("run");
        let o = reacher()
            .args(["--task", "or", "--algo", "smirl", "--quiet", "--config"])
            .arg(&cfg)
            .arg("--out")
            .arg(&out)
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{stderr}");
        for needle in needles {
            assert!(stderr.contains(needle), "{needle}: {stderr}");
        }
        assert!(!out.exists());
    }
}

/// Records the order in which a run's jobs end.
#[derive(Default)]
struct EndOrder {
    labels: std::sync::Mutex<Vec<String>>,
    ended: std::sync::Mutex<Vec<String>>,
}

impl smirl::pipeline::reacher_irl::run::RunObserver for EndOrder {
    fn jobs(&self, labels: &[String], _total_env_steps: u64) {
        *self.labels.lock().unwrap() = labels.to_vec();
    }
    fn job_done(&self, job: usize, _record: &smirl::pipeline::reacher_irl::records::JobRecord) {
        let label = self.labels.lock().unwrap()[job].clone();
        self.ended.lock().unwrap().push(label);
    }
}

/// The pool starts the job of most planned environment steps first: on one worker, smirl
/// (2 iterations and a final phase) ends before smirl-paper (the same iterations, no final
/// phase), though the run lists smirl-paper first; the run's tables keep the listed order.
/// Fails when the pool takes the jobs as listed.
#[test]
fn the_pool_starts_the_longest_planned_job_first() {
    let tmp = tempfile::tempdir().unwrap();
    let request = RunRequest {
        task: ReacherTask::shipped("or").unwrap(),
        algos: vec![Algo::SmirlPaper, Algo::Smirl],
        seeds: 1,
        seed: 3,
        config: IrlRunConfig {
            threads: 1,
            ..tiny_config()
        },
        out: tmp.path().join("run"),
        force: false,
    };
    let observer = EndOrder::default();
    run_pipeline(&request, &observer).unwrap();
    assert_eq!(
        *observer.ended.lock().unwrap(),
        ["smirl seed 3", "smirl-paper seed 3"]
    );
    let summary = std::fs::read_to_string(tmp.path().join("run/summary.csv")).unwrap();
    let rows: Vec<&str> = summary
        .lines()
        .skip(1)
        .map(|l| l.split(',').nth(1).unwrap())
        .collect();
    assert_eq!(rows, ["smirl-paper", "smirl"]);
}
