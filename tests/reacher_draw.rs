//! ReacherDraw (f-IRL's own Reacher experiment): the arm's zero start, the target densities,
//! a `--quick` run of each baseline through the binary, and its bad inputs.

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use smirl::env::reacher::{ArmStart, ReacherConfig, ReacherDelivery, OBS_TIP};
use smirl::env::ContinuousEnv;
use smirl::nn::mlp::Mlp;
use smirl::pipeline::reacher_draw::{DrawConfig, DrawTarget, TARGET_STD};
use smirl::pipeline::reacher_irl::IrlConfigError;
use smirl::rl::sac::{ActMode, ActWorkspace, SacAgent, SacConfig};
use std::process::Command;

#[allow(unused_imports)]
use shipped_layout::{layout, obs_dim, shipped_config};
mod shipped_layout;

#[test]
fn zero_start_puts_the_fingertip_at_full_reach_at_rest() {
    let config = ReacherConfig {
        arm_start: ArmStart::Zero,
        ..ReacherConfig::default()
    };
    let mut env = ReacherDelivery::new(shipped_config(config)).unwrap();
    let mut obs = vec![0.0; obs_dim()];
    for seed in [0, 1, 99] {
        env.reset(seed, &mut obs);
        assert!((f64::from(obs[OBS_TIP[0]]) - 0.21).abs() < 1e-6, "{obs:?}");
        assert!(f64::from(obs[OBS_TIP[1]]).abs() < 1e-6, "{obs:?}");
        assert_eq!(&env.qpos()[..2], &[0.0, 0.0]);
    }
    // The default (Gymnasium's) start is random and is not written to configs.
    let random = ReacherConfig::default();
    assert_eq!(random.arm_start, ArmStart::Random);
    assert!(!toml::to_string(&random).unwrap().contains("arm_start"));
    let zero = toml::to_string(&ReacherConfig {
        arm_start: ArmStart::Zero,
        ..ReacherConfig::default()
    })
    .unwrap();
    assert!(zero.contains("arm_start = \"zero\""), "{zero}");
}

#[test]
fn target_densities_integrate_to_one_and_samples_follow_them() {
    for target in [DrawTarget::Gaussian, DrawTarget::Mixture] {
        // Riemann sum over ±0.5 m (every component is > 6 std inside).
        let h = 0.002;
        let n = (1.0 / h) as i64;
        let mut mass = 0.0;
        for i in 0..n {
            for j in 0..n {
                let (x, y) = (-0.5 + (i as f64 + 0.5) * h, -0.5 + (j as f64 + 0.5) * h);
                mass += target.density(x, y) * h * h;
            }
        }
        assert!((mass - 1.0).abs() < 1e-3, "{target:?}: {mass}");
        let samples = target.sample(20_000, &mut ChaCha8Rng::seed_from_u64(1));
        let mean_x = samples.iter().step_by(2).sum::<f64>() / 20_000.0;
        let want_x = match target {
            DrawTarget::Gaussian => -0.21,
            DrawTarget::Mixture => -0.1485,
        };
        assert!((mean_x - want_x).abs() < 0.003, "{target:?}: {mean_x}");
        // The mixture's y is ±0.1485 ± noise: its spread is much wider than one component's.
        let var_y = samples
            .iter()
            .skip(1)
            .step_by(2)
            .map(|y| y * y)
            .sum::<f64>()
            / 20_000.0;
        let want_var_y = match target {
            DrawTarget::Gaussian => TARGET_STD * TARGET_STD,
            DrawTarget::Mixture => TARGET_STD * TARGET_STD + 0.1485 * 0.1485,
        };
        assert!(
            (var_y - want_var_y).abs() < 0.05 * want_var_y,
            "{target:?}: {var_y}"
        );
    }
}

#[test]
fn a_batch_of_observations_acts_as_one_call_per_observation() {
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let agent = SacAgent::new(&SacConfig::default(), 5, 2, &mut rng);
    let actor: &Mlp = &agent.actor;
    let obs: Vec<f32> = (0..15).map(|i| (i as f32 * 0.37).sin()).collect();
    for mode in [ActMode::Mean, ActMode::Sample] {
        let mut one = ActWorkspace::new(actor);
        let mut rng_one = ChaCha8Rng::seed_from_u64(4);
        let mut singles = vec![0.0f32; 6];
        for k in 0..3 {
            one.act(
                actor,
                &obs[5 * k..5 * (k + 1)],
                mode,
                &mut rng_one,
                &mut singles[2 * k..2 * (k + 1)],
            );
        }
        let mut three = ActWorkspace::with_batch(actor, 3);
        assert_eq!(three.batch(), 3);
        let mut batched = vec![0.0f32; 6];
        three.act(
            actor,
            &obs,
            mode,
            &mut ChaCha8Rng::seed_from_u64(4),
            &mut batched,
        );
        for (a, b) in singles.iter().zip(&batched) {
            assert!((a - b).abs() < 1e-5, "{mode:?}: {singles:?} vs {batched:?}");
        }
    }
}

#[test]
fn config_errors_name_the_field_and_line() {
    let e = DrawConfig::from_toml("target = \"gaussian\"\nhorizon = 0\n", "draw.toml").unwrap_err();
    let msg = e.to_string();
    assert!(
        matches!(e, IrlConfigError::Invalid { line: Some(2), .. }),
        "{msg}"
    );
    assert!(
        msg.contains("draw.toml") && msg.contains("horizon"),
        "{msg}"
    );
    let msg = DrawConfig::from_toml("agent_trajectories = 100000\n", "draw.toml")
        .unwrap_err()
        .to_string();
    assert!(msg.contains("more than the limit"), "{msg}");
    let msg = DrawConfig::from_toml("target = \"square\"\n", "draw.toml")
        .unwrap_err()
        .to_string();
    assert!(msg.contains("line 1") && msg.contains("square"), "{msg}");
    let msg = DrawConfig::from_toml("[sac]\nhidden = [100000]\n", "draw.toml")
        .unwrap_err()
        .to_string();
    assert!(msg.contains("sac.hidden"), "{msg}");
    // f-IRL's settings are the defaults and round-trip.
    let d = DrawConfig::default();
    assert_eq!(
        (d.iterations, d.horizon, d.agent_trajectories),
        (800, 30, 1000)
    );
    assert_eq!(DrawConfig::from_toml(&d.to_toml(), "x").unwrap(), d);
}

fn reacher() -> Command {
    Command::new(env!("CARGO_BIN_EXE_reacher"))
}

#[test]
fn quick_runs_write_their_files_and_repeat_bit_for_bit() {
    let dir = tempfile::tempdir().unwrap();
    for algo in ["fkl", "maxent"] {
        let mut metrics = Vec::new();
        for run in ["a", "b"] {
            let out = dir.path().join(format!("{algo}-{run}"));
            let o = reacher()
                .args([
                    "draw", "--algo", algo, "--quick", "--quiet", "--seed", "5", "--out",
                ])
                .arg(&out)
                .output()
                .unwrap();
            assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
            let stdout = String::from_utf8_lossy(&o.stdout);
            assert!(stdout.contains("forward KL"), "{stdout}");
            for file in ["config.toml", "metrics.csv", "summary.json", "density.png"] {
                assert!(out.join(file).is_file(), "{algo}: no {file}");
            }
            let csv = std::fs::read_to_string(out.join("metrics.csv")).unwrap();
            // Iterations 1, 2, 4, 6 of the quick profile; KLs finite and positive.
            assert_eq!(csv.lines().count(), 5, "{csv}");
            for line in csv.lines().skip(1) {
                let f: Vec<&str> = line.split(',').collect();
                let (fwd, rev): (f64, f64) = (f[4].parse().unwrap(), f[5].parse().unwrap());
                assert!(
                    fwd.is_finite() && rev.is_finite() && fwd > 0.0 && rev > 0.0,
                    "{line}"
                );
            }
            // Everything but the wall-time column.
            metrics.push(
                csv.lines()
                    .map(|l| l.rsplit_once(',').unwrap().0.to_string())
                    .collect::<Vec<_>>(),
            );
        }
        assert_eq!(metrics[0], metrics[1], "{algo}: same seed, different KLs");
    }
}

#[test]
fn bad_arguments_exit_2_before_any_work() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("run");
    let o = reacher()
        .args(["draw", "--algo", "smirl", "--quick", "--out"])
        .arg(&out)
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("maxent, fkl, rkl or js"));
    assert!(!out.exists(), "nothing may be written");
    let bad = dir.path().join("bad.toml");
    std::fs::write(&bad, "kde_bandwidth = -1\n").unwrap();
    let o = reacher()
        .args(["draw", "--algo", "fkl", "--config"])
        .arg(&bad)
        .arg("--out")
        .arg(&out)
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("bad.toml") && err.contains("line 1") && err.contains("kde_bandwidth"),
        "{err}"
    );
    // A user's non-empty directory is refused.
    std::fs::create_dir(&out).unwrap();
    std::fs::write(out.join("mine.txt"), "keep").unwrap();
    let o = reacher()
        .args(["draw", "--algo", "fkl", "--quick", "--force", "--out"])
        .arg(&out)
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2));
    assert_eq!(
        std::fs::read_to_string(out.join("mine.txt")).unwrap(),
        "keep"
    );
}

#[test]
fn the_reachable_floor_of_the_reverse_kl_is_minus_log_the_reachable_mass() {
    use smirl::pipeline::reacher_draw::{reachable_floor, REACH};
    for target in [DrawTarget::Gaussian, DrawTarget::Mixture] {
        let samples = target.sample(10_000, &mut ChaCha8Rng::seed_from_u64(7));
        // KL(p restricted to the disc ‖ p) = −log P(disc), exactly.
        let check = target.sample(200_000, &mut ChaCha8Rng::seed_from_u64(8));
        let inside = check
            .chunks_exact(2)
            .filter(|p| p[0].hypot(p[1]) <= REACH)
            .count() as f64
            / 200_000.0;
        let (forward, reverse) = reachable_floor(target, &samples, 0).unwrap();
        assert!(
            (reverse + inside.ln()).abs() < 0.08,
            "{target:?}: {reverse} vs {}",
            -inside.ln()
        );
        // Half the target is out of reach: the forward KL cannot come near 0.
        assert!(forward > 1.0, "{target:?}: {forward}");
    }
}
