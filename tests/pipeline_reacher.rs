//! The `reacher --task` IRL pipeline: SMIRL's update direction at pipeline level, a tiny
//! end-to-end run through the library and through the CLI (every artefact written, nothing
//! half-written), bad input exiting 2 without output, and bit-identical metrics per seed.

mod irl_run_common;
use irl_run_common::{metrics_column, tiny_config, tiny_rkl_blue_run};
use smirl::env::reacher_task::ReacherTask;
use smirl::irl::reward::{RewardModel, RewardOptimConfig};
use smirl::irl::smirl::{AnnotatedTrajectories, FeatureMap, LinearRmReward, SmirlNormalisation};
mod smirl_reference;
use smirl::pipeline::reacher_irl::run::Silent;
use smirl::pipeline::reacher_irl::{
    reward_lr, run_pipeline, AgentBatch, Algo, DemoSource, ExpertData, IrlRunConfig, RunRequest,
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
        labels_before: vec![smirl::rm::LabelSet::EMPTY; 5],
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
    agent.labels_before = vec![smirl::rm::LabelSet::EMPTY; 3];
    let c = smirl::pipeline::reacher_irl::smirl::coefficients(
        &FeatureMap::reacher_labels(&layout()),
        &expert,
        &agent,
        SmirlNormalisation::Trajectories,
        &smirl::rm::format::read_rm(
            &Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/rm/reacher_blue.txt"),
        )
        .unwrap(),
    );
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
/// co-trained policy and `smirl_final_checkpoints` candidates, the chosen one the first of
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
        Some("algo,seed,candidate,env_steps,learned_return,chosen,success_rate,success_normal,success_cancel,progress,final_ball,agent,cut_return,random,final_set_episodes,final_set_success_rate,final_set_success_normal,final_set_success_cancel")
    );
    let rows: Vec<Vec<&str>> = lines.map(|l| l.split(',').collect()).collect();
    let config = tiny_config();
    let per_job = config.smirl_final_checkpoints as usize + 1;
    assert_eq!(rows.len(), algos.len() * per_job, "{table}");
    for a in algos {
        let job: Vec<&Vec<&str>> = rows
            .iter()
            .filter(|r| r[0] == *a && r[1] == seed.to_string())
            .collect();
        assert_eq!(job.len(), per_job, "{table}");
        // The number the choice reads: the cut return (last column) when the run has one.
        let returns: Vec<f64> = job
            .iter()
            .map(|r| r[12].parse().unwrap_or_else(|_| r[4].parse().unwrap()))
            .collect();
        let best = returns.iter().cloned().fold(f64::MIN, f64::max);
        let first_best = returns.iter().position(|&x| x == best).unwrap();
        let chosen: Vec<usize> = (0..per_job).filter(|&i| job[i][5] == "1").collect();
        assert_eq!(chosen, vec![first_best], "{table}");
        let picked = (0..per_job).filter(|&i| job[i][13] == "1").count();
        assert_eq!(picked, 1, "{table}");
        // Every candidate judged on the final set too: ⌈50 · eval_episodes / 20⌉ per branch.
        let per_branch = final_set_episodes(&config);
        for r in &job {
            let n: u64 = r[14].parse().unwrap();
            assert!(n == per_branch || n == 2 * per_branch, "{table}");
            assert!(
                (0.0..=1.0).contains(&r[15].parse::<f64>().unwrap()),
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
        assert!(job.iter().all(|r| r[11] == "co-trained"), "{table}");
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
    // An expert cache from another task is refused before anything is written.
    let cache = tmp.path().join("cache");
    std::fs::create_dir_all(&cache).unwrap();
    std::fs::write(cache.join("expert_or.policy"), b"SMIRLPOL not a policy").unwrap();
    let mut c = tiny_config();
    c.demo_source = DemoSource::Expert;
    c.expert_cache_dir = cache.clone();
    let p = tmp.path().join("expert.toml");
    std::fs::write(&p, c.to_toml()).unwrap();
    let o = reacher()
        .args(["--task", "or", "--config"])
        .arg(&p)
        .arg("--out")
        .arg(tmp.path().join("bad"))
        .output()
        .unwrap();
    assert_eq!(
        o.status.code(),
        Some(2),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    assert!(String::from_utf8_lossy(&o.stderr).contains("expert_or.policy"));
    assert!(!tmp.path().join("bad").exists());
    // The subcommands still work next to the top-level arguments.
    assert_eq!(
        reacher()
            .args(["replay", "--help"])
            .output()
            .unwrap()
            .status
            .code(),
        Some(0)
    );
}

#[test]
fn shipped_configs_parse() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("experiments/reacher");
    let mut parsed = 0;
    for dir in [dir.clone(), dir.join("ablations"), dir.join("controls")] {
        for entry in std::fs::read_dir(&dir).unwrap() {
            let path = entry.unwrap().path();
            if path.extension().is_some_and(|e| e == "toml") {
                IrlRunConfig::load(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
                parsed += 1;
            }
        }
    }
    assert!(
        parsed >= 20,
        "config, config_uniform, quick, config_scripted, the three ablations and the controls"
    );
}

/// The shipped figure-7 config is the built-in default profile, so `reacher --task t` and
/// `experiments/reacher/run.sh` run the same thing.
#[test]
fn shipped_config_is_the_default_profile() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("experiments/reacher/config.toml");
    assert_eq!(IrlRunConfig::load(&path).unwrap(), IrlRunConfig::standard());
}

/// Regression: `quick.toml` lagged the quick profile (a setting of the standard missing from
/// it), though the README calls it that profile.
#[test]
fn shipped_quick_config_is_the_quick_profile() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("experiments/reacher/quick.toml");
    assert_eq!(IrlRunConfig::load(&path).unwrap(), IrlRunConfig::quick());
}

/// `smirl_label_features`: a config without the key reads as the paper's state labels (what
/// every run before the key used); `"entries"` selects label entries and is written back; a
/// bad value names the key.
#[test]
fn smirl_label_features_key_reads_old_configs_as_state_labels() {
    use smirl::irl::smirl::LabelFeatures;
    use smirl::pipeline::reacher_irl::smirl::Features;
    let text = IrlRunConfig::standard().to_toml();
    let line = text
        .lines()
        .find(|l| l.starts_with("smirl_label_features"))
        .expect("the key is written")
        .to_string();
    let mut without = IrlRunConfig::from_toml(&text.replace(&line, ""), "c.toml").unwrap();
    without.env = shipped_config(without.env);
    assert_eq!(without.smirl_label_features, LabelFeatures::State);
    assert_eq!(
        Features::Labels.map(&without).unwrap(),
        FeatureMap::reacher_labels(&layout())
    );
    let entries = text.replace(&line, "smirl_label_features = \"entries\"");
    let mut c = IrlRunConfig::from_toml(&entries, "c.toml").unwrap();
    c.env = shipped_config(c.env);
    assert_eq!(c.smirl_label_features, LabelFeatures::Entries);
    assert_eq!(
        Features::Labels.map(&c).unwrap(),
        FeatureMap::reacher_label_entries(&layout())
    );
    assert_eq!(IrlRunConfig::from_toml(&c.to_toml(), "c.toml").unwrap(), c);
    // smirl-smooth reads its smooth features either way.
    assert_eq!(
        Features::Smooth.map(&c).unwrap(),
        FeatureMap::reacher_smooth(&layout(), c.smooth_sigma).unwrap()
    );
    let bad = text.replace(&line, "smirl_label_features = \"edges\"");
    assert_config_error_names(&bad, "edges");
}

/// `smirl_machine`: a config without the key reads as LRM's machine (what every run before the
/// key used) and is written without it; `"task"` is written back; a bad value names the file
/// and the value.
#[test]
fn smirl_machine_key_reads_old_configs_as_the_learned_machine() {
    use smirl::pipeline::reacher_irl::SmirlMachine;
    let standard = IrlRunConfig::standard();
    let text = standard.to_toml();
    assert!(
        !text.contains("smirl_machine"),
        "the default is not written"
    );
    assert_eq!(standard.smirl_machine, SmirlMachine::Learned);
    let task = format!("smirl_machine = \"task\"\n{text}");
    let c = IrlRunConfig::from_toml(&task, "c.toml").unwrap();
    assert_eq!(c.smirl_machine, SmirlMachine::Task);
    assert_eq!(c.smirl_machine.name(), "task");
    assert_eq!(IrlRunConfig::from_toml(&c.to_toml(), "c.toml").unwrap(), c);
    let bad = format!("smirl_machine = \"perfect\"\n{text}");
    assert_config_error_names(&bad, "perfect");
}

/// `text`, read as the config file `c.toml`, is refused with an error naming the file and
/// `value`.
fn assert_config_error_names(text: &str, value: &str) {
    let err = IrlRunConfig::from_toml(text, "c.toml")
        .unwrap_err()
        .to_string();
    assert!(err.contains("c.toml") && err.contains(value), "{err}");
}

/// `smirl_machine = "task"`: the machine SMIRL reads is the task's own with no goal, no failure
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

/// `smirl_selection_cut`: the standard, read as false from configs without the key; a run with it says in its report which balls
/// the demonstrations touch after the cancel per learned state, and every final-policy
/// candidate of its SMIRL job carries a cut return, the one the choice reads.
#[test]
fn selection_cut_scores_every_candidate_and_chooses_by_it() {
    use smirl::pipeline::reacher_irl::final_policy::choose;
    use smirl::pipeline::reacher_irl::records::JobRecord;
    // The standard since its tuning rule was met; a config without the key reads as false.
    let c = IrlRunConfig::standard();
    assert!(c.smirl_selection_cut);
    assert_eq!(IrlRunConfig::from_toml(&c.to_toml(), "c.toml").unwrap(), c);
    assert!(c.smirl_selection_cut_entries);
    let without = c
        .to_toml()
        .replace("smirl_selection_cut = true\n", "")
        .replace("smirl_selection_cut_entries = true\n", "");
    assert!(
        !IrlRunConfig::from_toml(&without, "c.toml")
            .unwrap()
            .smirl_selection_cut
    );
    // Reading touches as entries is a way of cutting: refused without the cut.
    let entries = format!("smirl_selection_cut_entries = true\n{without}");
    assert_config_error_names(&entries, "smirl_selection_cut_entries");
    let with_cut = format!("smirl_selection_cut = true\n{entries}");
    let e = IrlRunConfig::from_toml(&with_cut, "c.toml").unwrap();
    assert!(e.smirl_selection_cut_entries);
    assert_eq!(IrlRunConfig::from_toml(&e.to_toml(), "c.toml").unwrap(), e);

    let mut config = tiny_config();
    config.smirl_selection_cut = true;
    config.smirl_selection_cut_entries = true;
    let (_tmp, dir, _) = tiny_smirl_run(ReacherTask::shipped("if").unwrap(), config);
    let report = std::fs::read_to_string(dir.join("rm/report.txt")).unwrap();
    assert!(
        report.contains(
            "smirl_selection_cut: regions the demonstrations touch (touches begun) after an event"
        ),
        "{report}"
    );
    let table = std::fs::read_to_string(dir.join("final_policy.csv")).unwrap();
    let header: Vec<&str> = table.lines().next().unwrap().split(',').collect();
    let column = header.iter().position(|&c| c == "cut_return").unwrap();
    for row in table.lines().skip(1) {
        let cell = row.split(',').nth(column).unwrap();
        assert!(cell.parse::<f64>().unwrap().is_finite(), "{row}");
    }
    let record: JobRecord =
        serde_json::from_str(&std::fs::read_to_string(dir.join("jobs/smirl_seed3.json")).unwrap())
            .unwrap();
    let f = record.final_policy.unwrap();
    assert!(f.candidates.iter().all(|c| c.cut_return.is_some()));
    assert_eq!(f.chosen, choose(&f.candidates));
}

/// Keys missing from `[sac]` come from the IRL runs' SAC, not from the paper's preset; a
/// `preset` key switches the base.
#[test]
fn sac_table_defaults_to_the_irl_run_sac() {
    use smirl::pipeline::reacher_irl::config::irl_run_sac;
    use smirl::rl::sac::SacConfig;
    let mut text = IrlRunConfig::standard().to_toml();
    let cut = text.find("[sac]").unwrap();
    text.truncate(cut);
    let c = IrlRunConfig::from_toml(&format!("{text}[sac]\nbatch_size = 128\n"), "c.toml").unwrap();
    assert_eq!(
        c.sac,
        SacConfig {
            batch_size: 128,
            ..irl_run_sac()
        }
    );
    assert_eq!(c.sac.replay_capacity, 200_000);
    let c = IrlRunConfig::from_toml(&format!("{text}[sac]\npreset = \"irl\"\n"), "c.toml").unwrap();
    assert_eq!(c.sac, SacConfig::irl());
    let without = IrlRunConfig::from_toml(&text, "c.toml").unwrap();
    assert_eq!(without.sac, irl_run_sac());
    let err = IrlRunConfig::from_toml(&format!("{text}[sac]\nbatch = 3\n"), "c.toml")
        .unwrap_err()
        .to_string();
    assert!(err.contains("c.toml") && err.contains("batch"), "{err}");
}

/// `demo_padding = "hold"`: a demonstration that ends at the goal is extended to the time
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
    // Each step starts where the one before ended; the first from an untouched observation.
    let mut steps = vec![step(None, false), step(Some(0), false), step(Some(2), true)];
    let mut before: Vec<f32> = row(None);
    for s in &mut steps {
        s.obs = before;
        before = s.next_obs.clone();
    }
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
    // The labels before each step: the first step's observation (here nothing touched), then
    // each step's predecessor.
    let labels = |s: &str| vocab.parse_labels(s).unwrap();
    assert_eq!(
        plain.labels_before,
        vec![labels(""), labels(""), labels("r")]
    );

    let held = annotate(&layout(), std::slice::from_ref(&demo), Some(&rm), Some(6));
    assert_eq!(held.lengths, vec![6]);
    // The last recorded step touched blue with the cancel; the held steps stay on blue.
    let after_blue = vec![
        labels(""),
        labels(""),
        labels("r"),
        labels("bc"),
        labels("b"),
        labels("b"),
    ];
    assert_eq!(held.labels_before, after_blue);
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

/// `expert_data.bin`: what `reacher prepare` hands the jobs reads back exactly, and a file
/// whose arrays disagree is refused.
#[test]
fn expert_data_round_trips_and_checks_its_arrays() {
    use smirl::rm::LabelSet;
    let mut data = ExpertData {
        obs: (0..3 * obs_dim()).map(|i| i as f32 * 0.01).collect(),
        labels_before: vec![LabelSet::EMPTY, LabelSet(1), LabelSet(0b10001)],
        lengths: vec![2, 1],
        learned_states: vec![0, 1, 0],
    };
    let back = ExpertData::from_bytes(&data.to_bytes(), obs_dim()).unwrap();
    assert_eq!(back.obs, data.obs);
    assert_eq!(back.labels_before, data.labels_before);
    assert_eq!(back.lengths, data.lengths);
    assert_eq!(back.learned_states, data.learned_states);
    data.labels_before.pop();
    let err = ExpertData::from_bytes(&data.to_bytes(), obs_dim())
        .unwrap_err()
        .to_string();
    assert!(err.contains("labels before"), "{err}");
    let bytes = data.to_bytes();
    assert!(ExpertData::from_bytes(&bytes[..bytes.len() - 3], obs_dim()).is_err());
}

/// The reward learning-rate schedule lr · k^(−p) of a base rate (SMIRL's or the reward
/// net's), constant for p = 0.
#[test]
fn reward_learning_rate_decays_as_a_power_of_the_iteration() {
    let mut c = IrlRunConfig::standard();
    c.smirl_reward_lr = 0.1;
    c.mlp_reward_lr = 0.001;
    c.reward_lr_decay = 0.0;
    for k in [1, 2, 20] {
        assert_eq!(reward_lr(c.smirl_reward_lr, &c, k), 0.1);
        assert_eq!(reward_lr(c.mlp_reward_lr, &c, k), 0.001);
    }
    c.reward_lr_decay = 0.5;
    assert_eq!(reward_lr(c.smirl_reward_lr, &c, 1), 0.1);
    assert!((reward_lr(c.smirl_reward_lr, &c, 4) - 0.05).abs() < 1e-7);
    assert!((reward_lr(c.mlp_reward_lr, &c, 16) - 0.00025).abs() < 1e-9);
    c.reward_lr_decay = -0.5;
    assert!(c.validate("test").is_err());
}

/// The counterfactual share is a probability; the error names the field.
#[test]
fn counterfactual_share_must_be_in_the_unit_interval() {
    let mut c = IrlRunConfig::standard();
    for ok in [0.0, 0.5, 1.0] {
        c.smirl_counterfactual = ok;
        c.validate("test").unwrap();
    }
    for bad in [-0.1, 1.5, f64::NAN] {
        c.smirl_counterfactual = bad;
        let e = c.validate("test").unwrap_err().to_string();
        assert!(e.contains("smirl_counterfactual"), "{e}");
    }
}

/// The final-policy phase's keys: checkpoints need steps, lie in 1..=steps and under the
/// limit; the error names the field.
#[test]
fn final_policy_settings_are_checked() {
    let mut c = IrlRunConfig::standard();
    // The phase's own keys first, without the standard's reset agent (which needs them).
    c.smirl_final_reset_steps = 0;
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
        c.smirl_final_sac_steps = steps;
        c.smirl_final_checkpoints = checkpoints;
        match c.validate("test") {
            Ok(()) => assert!(ok, "{steps} steps, {checkpoints} checkpoints accepted"),
            Err(e) => {
                assert!(!ok, "{steps}, {checkpoints}: {e}");
                assert!(e.to_string().contains("smirl_final_"), "{e}");
            }
        }
    }
    // The reset agent needs the phase's checkpoints, at least one step per checkpoint and at
    // most the step limit.
    type Key = fn(&mut IrlRunConfig) -> &mut u64;
    let keys: [(&str, Key); 1] = [("smirl_final_reset_steps", |c| {
        &mut c.smirl_final_reset_steps
    })];
    for (field, key) in keys {
        for (extra, steps, checkpoints, ok) in [
            (150_000, 20_000, 4, true),
            (4, 20_000, 4, true),
            (3, 20_000, 4, false),
            (150_000, 0, 0, false),
            (100_000_001, 20_000, 4, false),
        ] {
            let mut c = c.clone();
            *key(&mut c) = extra;
            c.smirl_final_sac_steps = steps;
            c.smirl_final_checkpoints = checkpoints;
            match c.validate("test") {
                Ok(()) => assert!(ok, "{field} {extra} accepted"),
                Err(e) => {
                    assert!(!ok, "{field} {extra}: {e}");
                    assert!(e.to_string().contains(field), "{e}");
                }
            }
        }
    }
    let standard = IrlRunConfig::standard();
    assert_config_error_names(
        &format!("smirl_final_fresh_steps = 280\n{}", standard.to_toml()),
        "smirl_final_fresh_steps",
    );
    assert_eq!(standard.smirl_final_reset_steps, 20_000);
    assert!(standard
        .to_toml()
        .contains("smirl_final_reset_steps = 20000"));
    // A config without the keys (every run before them) has no final phase.
    let old = IrlRunConfig::standard()
        .to_toml()
        .lines()
        .filter(|l| !l.starts_with("smirl_final_"))
        .collect::<Vec<_>>()
        .join("\n");
    let c = IrlRunConfig::from_toml(&old, "old.toml").unwrap();
    assert_eq!((c.smirl_final_sac_steps, c.smirl_final_checkpoints), (0, 0));
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
    assert_eq!(REMOVED_KEYS.len(), 6);
    for (key, _) in REMOVED_KEYS {
        let err = IrlRunConfig::from_toml(&format!("# a\n{key} = false\n{text}"), "c.toml")
            .unwrap_err()
            .to_string();
        assert!(
            err.starts_with("c.toml: line 2: field `") && err.contains(key),
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

/// `smirl_normalisation`'s three values read back as written; a misspelt one is refused with
/// the file and the key named.
#[test]
fn smirl_normalisation_values_round_trip() {
    let text = IrlRunConfig::standard().to_toml();
    let current = "smirl_normalisation = \"event_gated_visits\"\n";
    assert!(text.contains(current), "the standard's value moved");
    for (value, expected) in [
        ("visits", SmirlNormalisation::Visits),
        ("trajectories", SmirlNormalisation::Trajectories),
        ("shared_visits", SmirlNormalisation::SharedVisits),
        ("event_gated_visits", SmirlNormalisation::EventGatedVisits),
    ] {
        let t = text.replace(current, &format!("smirl_normalisation = \"{value}\"\n"));
        let c = IrlRunConfig::from_toml(&t, "n.toml").unwrap();
        assert_eq!(c.smirl_normalisation, expected);
        assert_eq!(c.smirl_normalisation.name(), value);
        assert_eq!(
            IrlRunConfig::from_toml(&c.to_toml(), "again.toml").unwrap(),
            c
        );
    }
    let t = text.replace(current, "smirl_normalisation = \"shared\"\n");
    let e = IrlRunConfig::from_toml(&t, "bad.toml")
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("bad.toml") && e.contains("smirl_normalisation"),
        "{e}"
    );
}

/// The reported candidate is the first of highest learned return, whatever its ground truth;
/// with the selection cut, of highest cut return.
#[test]
fn final_policy_is_the_first_candidate_of_highest_learned_return() {
    use smirl::pipeline::reacher_irl::final_policy::{choose, FinalAgent, FinalCandidate};
    let candidate = |learned_return: f64, success_rate: f64| FinalCandidate {
        agent: FinalAgent::CoTrained,
        env_steps: 0,
        learned_return,
        cut_return: None,
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
    // IF 42 seed 44's pattern: the candidate of highest learned return touches blue after the
    // cancel, its cut return falls below one that does not.
    let cut = |learned: f64, cut: f64| FinalCandidate {
        cut_return: Some(cut),
        ..candidate(learned, 0.0)
    };
    assert_eq!(choose(&[cut(380.0, 300.0), cut(355.0, 355.0)]), 1);
    assert_eq!(choose(&[cut(380.0, 380.0), cut(355.0, 355.0)]), 0);
}

/// The standard profile without its per-algorithm schedules: what SMIRL runs with.
fn without_schedules() -> IrlRunConfig {
    let mut c = IrlRunConfig::standard();
    c.schedule.clear();
    c
}

/// `config_unshaped.toml`'s settings: the standard profile with SMIRL's settings from before
/// issue 13 (20 IRL iterations, no shaping, no selection cut or reset agent, a replay buffer
/// of 100 000; its runs' LRM settings are no longer settings), as the runs made with it.
fn unshaped() -> IrlRunConfig {
    IrlRunConfig {
        sac: smirl::rl::sac::SacConfig {
            replay_capacity: 100_000,
            ..IrlRunConfig::standard().sac
        },
        irl_iterations: 20,
        smirl_shaping: 0.0,
        smirl_final_sac_steps: 0,
        smirl_final_checkpoints: 0,
        smirl_final_reset_steps: 0,
        smirl_selection_cut: false,
        smirl_selection_cut_entries: false,
        smirl_clock: false,
        smirl_normalisation: SmirlNormalisation::Visits,
        ..IrlRunConfig::standard()
    }
}

/// `config_uniform.toml`'s settings: `unshaped()` without the per-algorithm schedules.
fn uniform() -> IrlRunConfig {
    let mut c = unshaped();
    c.schedule.clear();
    c
}

/// The standard profile gives the baselines f-IRL's schedule (800 × 300 SAC steps, 300
/// trajectories, 2 reward steps, SAC lr 3e-3 with α = 1 fixed, replay 12 000) and SMIRL the
/// run's own (30 × 5 000 with shaping); `config_unshaped.toml` is it with SMIRL's earlier
/// settings (20 × 5 000, no shaping), and `config_uniform.toml` that without the schedules.
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
        assert_eq!((c.irl_iterations, c.smirl_shaping), (30, 1.0), "{algo}");
    }
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("experiments/reacher");
    assert_eq!(
        IrlRunConfig::load(&dir.join("config_uniform.toml")).unwrap(),
        uniform()
    );
    // config_unshaped.toml, which prepared the figure-7 runs of issue 14: the standard profile
    // with SMIRL's earlier settings; the baselines' schedules are the same.
    let unshaped_file = IrlRunConfig::load(&dir.join("config_unshaped.toml")).unwrap();
    assert_eq!(unshaped_file, unshaped());
    // The baselines' resolved settings differ only in SMIRL's shaping, the final phase (and
    // SMIRL's selection cut), the clock, the normalisation
    // and the replay size, which every algorithm shares.
    for algo in [Algo::MaxEnt, Algo::Fkl, Algo::Rkl, Algo::Js] {
        let unshaped_algo = unshaped_file.for_algo(algo).unwrap();
        let before = IrlRunConfig {
            sac: smirl::rl::sac::SacConfig {
                replay_capacity: standard.sac.replay_capacity,
                ..unshaped_algo.sac.clone()
            },
            smirl_shaping: 1.0,
            smirl_final_sac_steps: standard.smirl_final_sac_steps,
            smirl_final_checkpoints: standard.smirl_final_checkpoints,
            smirl_final_reset_steps: standard.smirl_final_reset_steps,
            smirl_selection_cut: standard.smirl_selection_cut,
            smirl_selection_cut_entries: standard.smirl_selection_cut_entries,
            smirl_clock: standard.smirl_clock,
            smirl_normalisation: standard.smirl_normalisation,
            ..unshaped_algo
        };
        assert_eq!(before, standard.for_algo(algo).unwrap(), "{algo}");
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
           agent_trajectories = 300\nreward_steps_per_iteration = 2\nmlp_reward_l2 = 0.0\n\
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
            "[schedule.rkl]\nkde_bandwidth = -1.0\n",
            "schedule.rkl.kde_bandwidth",
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

/// An OR run (seed 3, tiny config) without and with one more agent of the final phase
/// (`set` puts `steps` into its key): both runs' `final_policy.csv` rows. Checks what holds for
/// every such agent: the IRL loop and the co-trained candidates are those of the run without
/// it, the choice is the first candidate of highest learned return, the rollout log with the
/// agent's episodes replays bit for bit, and the written config holds the key (`written`).
fn run_with_extra_agent(
    set: fn(&mut IrlRunConfig, u64),
    steps: u64,
    written: &str,
) -> (Vec<Vec<String>>, Vec<Vec<String>>) {
    let run = |steps: u64| {
        let mut config = tiny_config();
        set(&mut config, steps);
        tiny_smirl_run(ReacherTask::shipped("or").unwrap(), config)
    };
    let ((_without_tmp, without_dir, _), (_with_tmp, with_dir, _)) = (run(0), run(steps));
    let read = |dir: &PathBuf, file: &str| std::fs::read_to_string(dir.join(file)).unwrap();
    // The loop's metrics (the columns before the final phase's chosen and random policies).
    let loop_metrics = |dir: &PathBuf| -> Vec<String> {
        (read(dir, "metrics.csv").lines())
            .map(|l| l.split(',').take(16).collect::<Vec<_>>().join(","))
            .collect()
    };
    assert_eq!(loop_metrics(&without_dir), loop_metrics(&with_dir));
    let rows = |dir: &PathBuf| -> Vec<Vec<String>> {
        read(dir, "final_policy.csv")
            .lines()
            .skip(1)
            .map(|l| l.split(',').map(String::from).collect())
            .collect()
    };
    let (without, with) = (rows(&without_dir), rows(&with_dir));
    // The co-trained candidates are unchanged but for `chosen` and `random`.
    for (a, b) in without.iter().zip(&with) {
        assert_eq!((&a[..5], &a[6..13]), (&b[..5], &b[6..13]));
    }
    let returns: Vec<f64> = with.iter().map(|r| r[4].parse().unwrap()).collect();
    let best = returns.iter().cloned().fold(f64::MIN, f64::max);
    let chosen: Vec<usize> = (0..with.len()).filter(|&i| with[i][5] == "1").collect();
    assert_eq!(
        chosen,
        vec![returns.iter().position(|&x| x == best).unwrap()]
    );
    let log = smirl::log::read_log(&with_dir.join("logs/smirl_seed3.mcap")).unwrap();
    let report = smirl::pipeline::replay::replay(&log).unwrap();
    assert!(report.all_match(), "{report}");
    let config = read(&with_dir, "config.toml");
    assert!(config.contains(written), "{config}");
    (without, with)
}

/// `smirl_final_reset_steps`: after the co-trained agent's final phase a reset agent (new
/// networks on its replay buffer) learns from that buffer, then trains on, and its checkpoints
/// join the candidates (`agent` = reset, step counts going on from the co-trained agent's),
/// the rest as [`run_with_extra_agent`] checks.
#[test]
fn reset_agent_checkpoints_join_the_final_policy_candidates() {
    let (without, with) = run_with_extra_agent(
        |c, steps| c.smirl_final_reset_steps = steps,
        280,
        "smirl_final_reset_steps = 280",
    );
    assert_eq!(with.len(), without.len() + 2, "{with:?}");
    let agents: Vec<&str> = with.iter().map(|r| r[11].as_str()).collect();
    assert_eq!(
        agents,
        ["co-trained", "co-trained", "co-trained", "reset", "reset"]
    );
    let co_trained_end: u64 = with[2][3].parse().unwrap();
    let reset_steps: Vec<u64> = with[3..].iter().map(|r| r[3].parse().unwrap()).collect();
    assert_eq!(reset_steps, [co_trained_end + 140, co_trained_end + 280]);
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

/// `firl_density_ratio = "discriminator"` (in an algorithm's schedule here) runs f-IRL on a
/// classifier's log-ratio: the job completes, its learned reward differs from the KDE run's
/// on the same seed, and the written config keeps the key; without it the config prints as
/// before the key existed.
#[test]
fn discriminator_density_ratio_runs_and_is_recorded() {
    assert!(!IrlRunConfig::standard()
        .to_toml()
        .contains("firl_density_ratio"));
    let run = |ratio: Option<&str>| {
        let mut config = tiny_config();
        if let Some(ratio) = ratio {
            let text = format!(
                "{}\n[schedule.rkl]\nfirl_density_ratio = \"{ratio}\"\n",
                config.to_toml()
            );
            config = IrlRunConfig::from_toml(&text, "c.toml").unwrap();
        }
        tiny_rkl_blue_run(config)
    };
    let (kde, _) = run(None);
    let (disc, written) = run(Some("discriminator"));
    assert!(
        written.contains("firl_density_ratio = \"discriminator\""),
        "{written}"
    );
    let learned = |m: &str| metrics_column(m, "learned_reward");
    assert_eq!(learned(&kde).len(), learned(&disc).len());
    assert_ne!(learned(&kde)[1..], learned(&disc)[1..], "{kde}\n{disc}");
    let err = IrlRunConfig::from_toml(
        &format!(
            "firl_density_ratio = \"classifier\"\n{}",
            IrlRunConfig::standard().to_toml()
        ),
        "c.toml",
    )
    .unwrap_err()
    .to_string();
    assert!(
        err.contains("c.toml") && err.contains("line 1") && err.contains("classifier"),
        "{err}"
    );
}

/// `smirl_clock`: SMIRL's agent sees the share of the episode still to come. Read as false
/// from configs without the key and not written when false; the standard's (its ablation's
/// config, `ablations/clock.toml`, is the standard); a run with it records it
/// (config.toml, run.json), trains with counterfactual states on the wider observation (the
/// relabeller refuses a width it was not built for), replays its log, repeats itself per seed
/// and differs from the run without a clock; `reacher retrain` on its reward trains in the same
/// product.
#[test]
fn clock_widens_smirls_observation_through_the_pipeline() {
    use smirl::pipeline::commands::irl::{retrain, RetrainRequest};
    let text = unshaped().to_toml();
    assert!(!text.contains("smirl_clock"));
    assert!(
        !IrlRunConfig::from_toml(&text, "c.toml")
            .unwrap()
            .smirl_clock
    );
    let config = tiny_config();
    assert!(
        config.smirl_clock,
        "the standard's, and so the quick profile's"
    );
    assert!(config.smirl_counterfactual > 0.0);
    let written = config.to_toml();
    assert!(written.contains("smirl_clock = true"), "{written}");
    assert_eq!(IrlRunConfig::from_toml(&written, "c.toml").unwrap(), config);
    // The ablation's config is the standard, which has the clock.
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("experiments/reacher");
    assert_eq!(
        IrlRunConfig::load(&dir.join("ablations/clock.toml")).unwrap(),
        IrlRunConfig::load(&dir.join("config.toml")).unwrap()
    );

    let (_with_tmp, with, _) = tiny_smirl_run(ReacherTask::shipped("or").unwrap(), config.clone());
    let (_again_tmp, again, _) = tiny_smirl_run(ReacherTask::shipped("or").unwrap(), config);
    let no_clock = IrlRunConfig {
        smirl_clock: false,
        ..tiny_config()
    };
    let (_without_tmp, without, _) = tiny_smirl_run(ReacherTask::shipped("or").unwrap(), no_clock);
    let read = |dir: &PathBuf, file: &str| std::fs::read_to_string(dir.join(file)).unwrap();
    for file in ["metrics.csv", "final_policy.csv"] {
        assert_eq!(read(&with, file), read(&again, file), "{file}");
    }
    assert_ne!(read(&with, "metrics.csv"), read(&without, "metrics.csv"));
    assert!(read(&with, "config.toml").contains("smirl_clock = true"));
    let run_json: serde_json::Value = serde_json::from_str(&read(&with, "run.json")).unwrap();
    assert_eq!(run_json["smirl_clock"], serde_json::Value::Bool(true));
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

/// `smirl_clock_frozen`, the clock's control: refused without the clock; read as false from
/// configs without the key; a run with it records it and differs from the run with the moving
/// clock; its ablation config is the standard with only the clock frozen.
#[test]
fn frozen_clock_is_the_clock_without_the_time() {
    let standard = tiny_config();
    assert!(!standard.smirl_clock_frozen);
    assert!(!standard.to_toml().contains("smirl_clock_frozen"));
    let frozen = IrlRunConfig {
        smirl_clock_frozen: true,
        ..standard.clone()
    };
    let written = frozen.to_toml();
    assert!(written.contains("smirl_clock_frozen = true"), "{written}");
    assert_eq!(IrlRunConfig::from_toml(&written, "c.toml").unwrap(), frozen);
    assert_config_error_names(
        &written.replace("smirl_clock = true\n", ""),
        "smirl_clock_frozen",
    );
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("experiments/reacher");
    let control = IrlRunConfig::load(&dir.join("ablations/clock_frozen.toml")).unwrap();
    assert!(control.smirl_clock_frozen);
    assert_eq!(
        IrlRunConfig {
            smirl_clock_frozen: false,
            ..control
        },
        IrlRunConfig::load(&dir.join("config.toml")).unwrap()
    );

    let (_frozen_tmp, with_frozen, _) = tiny_smirl_run(ReacherTask::shipped("or").unwrap(), frozen);
    let (_clock_tmp, with_clock, _) = tiny_smirl_run(ReacherTask::shipped("or").unwrap(), standard);
    let read = |dir: &PathBuf, file: &str| std::fs::read_to_string(dir.join(file)).unwrap();
    assert_ne!(
        read(&with_frozen, "metrics.csv"),
        read(&with_clock, "metrics.csv")
    );
    let run_json: serde_json::Value =
        serde_json::from_str(&read(&with_frozen, "run.json")).unwrap();
    assert_eq!(
        run_json["smirl_clock_frozen"],
        serde_json::Value::Bool(true)
    );
}

/// `smirl_machine = "one_state"`, the control of issue 54 without structure: the run's machine
/// has one state and no transitions and its report says so, every expert step is in that
/// state, the SMIRL job learns one weight vector on it and keeps every other mechanism (its
/// final phase included).
#[test]
fn one_state_control_runs_smirl_on_a_one_state_machine() {
    use smirl::pipeline::reacher_irl::run::JobRecord;
    use smirl::pipeline::reacher_irl::SmirlMachine;
    use smirl::rm::format::parse_rm;
    let text = IrlRunConfig::standard().to_toml();
    let c = IrlRunConfig::from_toml(&format!("smirl_machine = \"one_state\"\n{text}"), "c.toml")
        .unwrap();
    assert_eq!(c.smirl_machine, SmirlMachine::OneState);
    assert!(c.to_toml().contains("smirl_machine = \"one_state\""));

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
