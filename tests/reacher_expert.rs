//! ReacherDelivery experts: the actor-only policy file (round trip, refusals), demonstrations
//! (deterministic per seed, perfect-machine states consistent with their labels), the
//! committed experts, the expert config file, and `reacher expert`'s argument errors.

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use smirl::env::reacher::ReacherConfig;
use smirl::env::reacher_task::ReacherTask;
use smirl::nn::{FileError, Mlp, MlpArch};
use smirl::pipeline::reacher_expert::{
    committed_expert, evaluate_expert, expert_sac, generate_demos, ExpertConfig, ExpertError,
    ExpertPolicy, PolicyFileError, PolicyInfo,
};
use smirl::rl::sac::{ActMode, SacConfig};
use std::process::Command;

#[allow(unused_imports)]
use shipped_layout::{layout, obs_dim, shipped_config};
mod shipped_layout;

fn info() -> PolicyInfo {
    PolicyInfo {
        seed: 7,
        env_steps: 1234,
        shaping_scale: 1.0,
        env: ReacherConfig::default(),
        git_commit: "test".into(),
    }
}

/// An untrained policy for `task` with (64, 64) hidden layers.
fn random_policy(task: ReacherTask, seed: u64) -> ExpertPolicy {
    let states = task.perfect_rm().unwrap().n_states();
    let arch = MlpArch::new(obs_dim() + states, &[64, 64], 4);
    let actor = Mlp::new(&arch, &mut ChaCha8Rng::seed_from_u64(seed));
    ExpertPolicy::new(task, actor, info()).unwrap()
}

fn mean_action(policy: &mut ExpertPolicy, obs: &[f32]) -> [f32; 2] {
    let mut a = [0.0; 2];
    let mut rng = ChaCha8Rng::seed_from_u64(0);
    policy.act(obs, ActMode::Mean, &mut rng, &mut a);
    a
}

#[test]
fn policy_file_round_trip() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("p.policy");
    let mut policy = random_policy(ReacherTask::shipped("if").unwrap(), 3);
    policy.save(&path).unwrap();
    let mut loaded =
        ExpertPolicy::load(&path, ReacherTask::shipped("if").unwrap(), &[64, 64]).unwrap();
    assert_eq!(loaded.task(), ReacherTask::shipped("if").unwrap());
    assert_eq!(loaded.obs_dim(), obs_dim() + 5);
    assert_eq!(loaded.info(), &info());
    let bits = |p: &ExpertPolicy| -> Vec<u32> {
        p.actor()
            .params()
            .flat_map(|t| t.iter().map(|x| x.to_bits()).collect::<Vec<_>>())
            .collect()
    };
    assert_eq!(bits(&policy), bits(&loaded));
    let obs: Vec<f32> = (0..policy.obs_dim())
        .map(|i| (i as f32 * 0.37).sin())
        .collect();
    assert_eq!(
        mean_action(&mut policy, &obs),
        mean_action(&mut loaded, &obs)
    );
    // Only the actor is stored: a (64, 64) actor on 22 inputs is about 6 000 floats.
    let size = std::fs::metadata(&path).unwrap().len();
    assert!(size < 40_000, "policy file is {size} bytes");
}

#[test]
fn policy_file_refusals_name_file_and_problem() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("or.policy");
    random_policy(ReacherTask::shipped("or").unwrap(), 1)
        .save(&path)
        .unwrap();
    let p = path.display().to_string();

    let e = ExpertPolicy::load(
        &path,
        ReacherTask::shipped("sequential").unwrap(),
        &[64, 64],
    )
    .unwrap_err();
    assert!(matches!(e, PolicyFileError::WrongTask { .. }), "{e}");
    let msg = e.to_string();
    assert!(
        msg.contains(&p) && msg.contains("'or'") && msg.contains("'sequential'"),
        "{msg}"
    );

    let e = ExpertPolicy::load(&path, ReacherTask::shipped("or").unwrap(), &[32, 32]).unwrap_err();
    assert!(matches!(e, PolicyFileError::Architecture { .. }), "{e}");
    let msg = e.to_string();
    assert!(
        msg.contains(&p) && msg.contains("20-64-64-4") && msg.contains("20-32-32-4"),
        "{msg}"
    );

    let good = std::fs::read(&path).unwrap();
    let mut bad_version = good.clone();
    bad_version[8..12].copy_from_slice(&99u32.to_le_bytes());
    std::fs::write(&path, &bad_version).unwrap();
    let msg = ExpertPolicy::load(&path, ReacherTask::shipped("or").unwrap(), &[64, 64])
        .unwrap_err()
        .to_string();
    assert!(msg.contains(&p) && msg.contains("version 99"), "{msg}");

    for cut in [4, 30, good.len() / 2, good.len() - 1] {
        std::fs::write(&path, &good[..cut]).unwrap();
        let msg = ExpertPolicy::load(&path, ReacherTask::shipped("or").unwrap(), &[64, 64])
            .unwrap_err()
            .to_string();
        assert!(msg.contains(&p), "{msg}");
        assert!(
            msg.contains("ends early") || msg.contains("magic"),
            "cut at {cut}: {msg}"
        );
    }

    let mut trailing = good.clone();
    trailing.push(0);
    std::fs::write(&path, &trailing).unwrap();
    let msg = ExpertPolicy::load(&path, ReacherTask::shipped("or").unwrap(), &[64, 64])
        .unwrap_err()
        .to_string();
    assert!(msg.contains("trailing"), "{msg}");

    let e = ExpertPolicy::load(
        &dir.path().join("missing.policy"),
        ReacherTask::shipped("or").unwrap(),
        &[64, 64],
    )
    .unwrap_err();
    assert!(
        matches!(e, PolicyFileError::File(FileError::Io { .. })),
        "{e}"
    );
}

/// The committed expert of `task`.
fn committed(task: ReacherTask) -> ExpertPolicy {
    committed_expert(task, &ExpertConfig::default().sac.hidden)
        .unwrap_or_else(|e| panic!("committed expert: {e}"))
}

#[test]
fn demos_are_deterministic_and_carry_the_perfect_machines_states() {
    let task = ReacherTask::shipped("if").unwrap();
    let mut policy = committed(task.clone());
    let env = ReacherConfig::default();
    let a = generate_demos(&mut policy, task.clone(), &env, 6, 11, None).unwrap();
    let b = generate_demos(&mut policy, task.clone(), &env, 6, 11, None).unwrap();
    assert_eq!(a, b, "same seed, same demonstrations");
    let c = generate_demos(&mut policy, task.clone(), &env, 6, 12, None).unwrap();
    assert_ne!(a, c, "another seed, other demonstrations");

    let rm = task.perfect_rm().unwrap();
    let mut state_changes = 0;
    for d in &a {
        assert_eq!(d.initial_rm_state, rm.initial());
        let mut u = rm.initial();
        let mut ret = 0.0;
        for (t, s) in d.steps.iter().enumerate() {
            let (next, r) = rm.step(u, s.labels);
            state_changes += usize::from(next != u);
            u = next;
            ret += r;
            assert_eq!(s.rm_state, u, "seed {} step {t}", d.seed);
            assert_eq!(s.task_reward, r);
            if t > 0 {
                assert_eq!(s.obs, d.steps[t - 1].next_obs);
            }
        }
        assert_eq!(d.success, rm.is_terminal(u) && !rm.is_failure(u));
        assert_eq!(d.task_return, ret);
        assert!(d.steps.len() <= env.max_steps);
    }
    assert!(state_changes >= a.len(), "the expert makes progress");

    let e = generate_demos(
        &mut policy,
        ReacherTask::shipped("or").unwrap(),
        &env,
        1,
        0,
        None,
    )
    .unwrap_err();
    assert!(matches!(e, ExpertError::Task { .. }), "{e}");
}

#[test]
fn committed_or_expert_succeeds() {
    let mut policy = committed(ReacherTask::shipped("or").unwrap());
    let env = ReacherConfig::default();
    let eval = evaluate_expert(&mut policy, &env, 20, ActMode::Sample, 99).unwrap();
    assert!(eval.success_rate >= 0.9, "{eval:?}");
    assert!(eval.mean_task_return >= 0.9, "{eval:?}");
}

fn reacher(args: &[&str]) -> (i32, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_reacher"))
        .args(args)
        .output()
        .unwrap();
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

#[test]
fn expert_command_rejects_bad_arguments_with_status_2() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("run");
    let out_s = out.to_str().unwrap();

    let (code, err) = reacher(&["expert", "--task", "diagonal", "--out", out_s]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("no shipped task named 'diagonal'"), "{err}");

    let (code, err) = reacher(&["expert", "--task", "or", "--seed", "x", "--out", out_s]);
    assert_eq!(code, 2, "{err}");

    let (code, err) = reacher(&["expert", "--out", out_s]);
    assert_eq!(code, 2, "{err}");

    let config = dir.path().join("bad.toml");
    std::fs::write(&config, "total_stepz = 10\n").unwrap();
    let c = config.to_str().unwrap();
    let (code, err) = reacher(&["expert", "--task", "or", "--config", c, "--out", out_s]);
    assert_eq!(code, 2, "{err}");
    assert!(
        err.contains("bad.toml") && err.contains("total_stepz"),
        "{err}"
    );

    std::fs::write(&config, "[sac]\nlr = \"fast\"\n").unwrap();
    let (code, err) = reacher(&["expert", "--task", "or", "--config", c, "--out", out_s]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("lr"), "{err}");

    std::fs::write(&config, "shaping_scale = -1.0\n").unwrap();
    let (code, err) = reacher(&["expert", "--task", "or", "--config", c, "--out", out_s]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("shaping_scale"), "{err}");

    std::fs::write(&config, "[env]\nmax_steps = 0\n").unwrap();
    let (code, err) = reacher(&["expert", "--task", "or", "--config", c, "--out", out_s]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("max_steps"), "{err}");

    let missing = dir.path().join("missing.toml");
    let (code, err) = reacher(&[
        "expert",
        "--task",
        "or",
        "--config",
        missing.to_str().unwrap(),
        "--out",
        out_s,
    ]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("missing.toml"), "{err}");

    // An existing checkpoint without --resume is refused, not overwritten.
    std::fs::create_dir_all(&out).unwrap();
    std::fs::write(out.join("expert.ckpt"), b"x").unwrap();
    let (code, err) = reacher(&["expert", "--task", "or", "--out", out_s]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("--resume"), "{err}");
    assert_eq!(std::fs::read(out.join("expert.ckpt")).unwrap(), b"x");
    assert!(!out.join("summary.json").exists());
}

/// `reacher expert --resume` continues from the last checkpoint: a run stopped after 400
/// steps and resumed to 800 ends with the same policy, bit for bit, as a run of 800 steps.
#[test]
fn expert_command_resumes_exactly() {
    let dir = tempfile::tempdir().unwrap();
    let config = |steps: u64| {
        let path = dir.path().join(format!("c{steps}.toml"));
        std::fs::write(
            &path,
            format!(
                "total_steps = {steps}\ncheckpoint_every = 200\neval_episodes = 2\n\
                 [sac]\nhidden = [16, 16]\nwarmup_steps = 100\nupdate_after = 100\n"
            ),
        )
        .unwrap();
        path.to_str().unwrap().to_string()
    };
    let run = |cfg: &str, out: &str, resume: bool| {
        let cache = dir.path().join("cache");
        let mut args = vec!["expert", "--task", "or", "--seed", "5", "--quiet"];
        args.extend([
            "--config",
            cfg,
            "--out",
            out,
            "--cache",
            cache.to_str().unwrap(),
        ]);
        if resume {
            args.push("--resume");
        }
        let (code, err) = reacher(&args);
        assert_eq!(code, 0, "{err}");
    };
    let (c400, c800) = (config(400), config(800));
    let whole = dir.path().join("whole");
    let split = dir.path().join("split");
    run(&c800, whole.to_str().unwrap(), false);
    run(&c400, split.to_str().unwrap(), false);
    run(&c800, split.to_str().unwrap(), true);
    let read = |d: &std::path::Path, f: &str| std::fs::read(d.join(f)).unwrap();
    assert_eq!(read(&whole, "expert.policy"), read(&split, "expert.policy"));
    assert_eq!(
        read(&whole, "expert.ckpt.curve.csv"),
        read(&split, "expert.ckpt.curve.csv")
    );
    assert_eq!(
        read(&whole, "demos.mcap").len(),
        read(&split, "demos.mcap").len()
    );
    for f in ["curve.svg", "curve_return.svg", "summary.json"] {
        assert!(split.join(f).exists(), "{f}");
    }
}

#[test]
fn expert_config_uses_the_expert_preset_and_names_bad_keys() {
    let c = ExpertConfig::from_toml("total_steps = 5000\n[sac]\nlr = 5e-4\n", "e.toml").unwrap();
    assert_eq!(c.total_steps, 5000);
    assert_eq!(
        c.sac,
        SacConfig {
            lr: 5e-4,
            ..expert_sac()
        }
    );
    // Naming a preset takes that preset's values (the paper's fixed α = 0.2, lr 3e-3).
    let c = ExpertConfig::from_toml("[sac]\npreset = \"expert\"\n", "e.toml").unwrap();
    assert_eq!(c.sac, SacConfig::expert());
    assert!(!c.sac.auto_alpha);
    assert_eq!(
        ExpertConfig::from_toml("", "e.toml").unwrap(),
        ExpertConfig::default()
    );
    let msg = ExpertConfig::from_toml("total_step = 5\n", "e.toml")
        .unwrap_err()
        .to_string();
    assert!(
        msg.contains("e.toml") && msg.contains("total_step"),
        "{msg}"
    );
    let msg = ExpertConfig::from_toml("eval_episodes = -3\n", "e.toml")
        .unwrap_err()
        .to_string();
    assert!(msg.contains("eval_episodes"), "{msg}");
    let msg = ExpertConfig::from_toml("[sac]\nbatch = 3\n", "e.toml")
        .unwrap_err()
        .to_string();
    assert!(
        msg.contains("e.toml [sac]") && msg.contains("batch"),
        "{msg}"
    );
}

/// `reacher expert-curve` draws the success and return plots from a training-curve CSV (long
/// curves stay small), refuses to replace plots without --force, and names the bad line of a
/// malformed CSV; bad input exits 2 and writes nothing.
#[test]
fn expert_curve_redraws_the_plots_from_the_csv() {
    let dir = tempfile::tempdir().unwrap();
    let csv = dir.path().join("curve.csv");
    let mut text = String::from("env_steps,episode,env_return,length,success\n");
    for k in 0..5_000u64 {
        let success = u8::from(k % 7 != 0 && k > 1_000);
        text.push_str(&format!(
            "{},{k},{},100,{success}\n",
            100 * (k + 1),
            k as f64 * 1e-3
        ));
    }
    std::fs::write(&csv, &text).unwrap();
    let (success, ret) = (dir.path().join("s.svg"), dir.path().join("r.svg"));
    let run = |csv: &std::path::Path, extra: &[&str]| {
        Command::new(env!("CARGO_BIN_EXE_reacher"))
            .args(["expert-curve", "--task", "or", "--csv"])
            .arg(csv)
            .arg("--out")
            .arg(&success)
            .arg("--out-return")
            .arg(&ret)
            .args(extra)
            .output()
            .unwrap()
    };
    let o = run(&csv, &[]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    for plot in [&success, &ret] {
        let svg = std::fs::read_to_string(plot).unwrap();
        assert!(
            svg.starts_with("<svg") || svg.starts_with("<?xml"),
            "{svg:.80}"
        );
        assert!(svg.len() < 60_000, "{} bytes", svg.len());
    }
    let before = std::fs::read(&success).unwrap();
    let o = run(&csv, &[]);
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("--force"));
    assert_eq!(std::fs::read(&success).unwrap(), before);
    assert!(run(&csv, &["--force"]).status.success());

    let bad = dir.path().join("bad.csv");
    std::fs::write(
        &bad,
        "env_steps,episode,env_return,length,success\n100,0,0.5,100,2\n",
    )
    .unwrap();
    std::fs::remove_file(&success).unwrap();
    std::fs::remove_file(&ret).unwrap();
    let o = run(&bad, &[]);
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("line 2"));
    assert!(!success.exists() && !ret.exists());
}
