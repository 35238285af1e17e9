//! f-IRL with demonstrations in its covariance batch (`firl_expert_trajectories`, f-IRL's
//! `resample_episodes`): the rows and coefficients of a reward step on a case worked by hand,
//! f-IRL's draw rule, the config key's round trip and refusals, and a tiny pipeline run.

mod irl_run_common;
use irl_run_common::{metrics_column, tiny_config, tiny_rkl_blue_run};
use smirl::irl::firl::{Divergence, FirlSurrogate};
use smirl::pipeline::reacher_irl::firl::{coefficients, DemonstrationDraw, IterationRatios, Loss};
use smirl::pipeline::reacher_irl::iteration::StepError;
use smirl::pipeline::reacher_irl::{AgentBatch, Algo, ExpertData, IrlRunConfig};

#[allow(unused_imports)]
use shipped_layout::{layout, obs_dim, shipped_config};
mod shipped_layout;

const T: usize = 3;

/// `n` trajectories of length T whose rows are filled with `first`, `first + 1`, … (one
/// value per trajectory), so a row says where it came from.
fn rows(n: usize, first: f32) -> Vec<f32> {
    (0..n)
        .flat_map(|i| std::iter::repeat_n(first + i as f32, T * obs_dim()))
        .collect()
}

fn expert() -> ExpertData {
    ExpertData {
        obs: rows(2, 100.0),
        lengths: vec![T, T],
        learned_states: Vec::new(),
    }
}

fn agent() -> AgentBatch {
    AgentBatch {
        obs: rows(2, 0.0),
        lengths: vec![T, T],
        ..AgentBatch::default()
    }
}

/// The agent's states where the expert's density is low (u = 0.5, 0.25), the demonstrations'
/// where it is high (u = 8, 4; an agent that never goes there).
fn ratios() -> IterationRatios {
    IterationRatios {
        agent: [[0.5; T], [0.25; T]].concat(),
        expert: [[8.0; T], [4.0; T]].concat(),
    }
}

#[test]
fn drawn_demonstrations_join_the_covariance_batch() {
    let loss = Loss::FDivergence(Divergence::Rkl);
    let c = coefficients(loss, &expert(), &agent(), Some(&ratios()), &[1, 1, 0]).unwrap();
    // Rows: the agent's two trajectories, then demonstrations 1, 1 and 0.
    let firsts: Vec<f32> = c.obs.chunks_exact(T * obs_dim()).map(|t| t[0]).collect();
    assert_eq!(firsts, [0.0, 1.0, 101.0, 101.0, 100.0]);
    let u = [[0.5; T], [0.25; T], [4.0; T], [4.0; T], [8.0; T]].concat();
    let expected = FirlSurrogate::new(Divergence::Rkl, &u, 5, T).unwrap();
    assert_eq!(c.coeffs, expected.coefficients);
    // By hand: rkl's A_i = Σ_t (1 − ln u) = T (1 − ln u_i); c_i = (A_i − Ā)/(5T).
    let a: Vec<f64> = [0.5f64, 0.25, 4.0, 4.0, 8.0]
        .iter()
        .map(|u| T as f64 * (1.0 - u.ln()))
        .collect();
    let mean = a.iter().sum::<f64>() / 5.0;
    for (i, ai) in a.iter().enumerate() {
        let want = (ai - mean) / (5 * T) as f64;
        assert!((c.coeffs[i * T] - want).abs() < 1e-12, "{i}: {c:?}");
    }
    // Descent raises the reward along the demonstrations (negative coefficients) and lowers
    // it along the agent's trajectories, where the expert's density is lower than its own.
    assert!(c.coeffs[..2 * T].iter().all(|&x| x > 0.0), "{c:?}");
    assert!(c.coeffs[2 * T..].iter().all(|&x| x < 0.0), "{c:?}");

    // None drawn: the agent's batch alone, as before the key existed.
    let alone = coefficients(loss, &expert(), &agent(), Some(&ratios()), &[]).unwrap();
    assert_eq!(alone.obs, agent().obs);
    let expected = FirlSurrogate::new(Divergence::Rkl, &ratios().agent, 2, T).unwrap();
    assert_eq!(alone.coeffs, expected.coefficients);
}

#[test]
fn a_demonstration_the_batch_cannot_take_is_an_error() {
    let loss = Loss::FDivergence(Divergence::Fkl);
    let err = coefficients(loss, &expert(), &agent(), Some(&ratios()), &[2]).unwrap_err();
    assert!(matches!(err, StepError::NoDemonstration(2)), "{err:?}");
    assert_eq!(err.to_string(), "no demonstration 2");
    let mut short = expert();
    short.lengths = vec![T + 1, T - 1];
    let err = coefficients(loss, &short, &agent(), Some(&ratios()), &[0]).unwrap_err();
    assert!(
        err.to_string().contains("demonstration 0 has 4 steps"),
        "{err}"
    );
    let no_expert_ratios = IterationRatios {
        expert: Vec::new(),
        ..ratios()
    };
    let err = coefficients(loss, &expert(), &agent(), Some(&no_expert_ratios), &[0]).unwrap_err();
    assert!(matches!(err, StepError::NoExpertRatios), "{err:?}");
    assert_eq!(
        err.to_string(),
        "f-IRL has no density ratios at the demonstrations"
    );
}

#[test]
fn demonstrations_are_drawn_as_firl_draws_them() {
    let mut draw = DemonstrationDraw::new(7);
    assert!(draw.draw(16, 0).is_empty());
    // No more than there are: without replacement.
    for m in [1, 5, 16] {
        let mut d = draw.draw(16, m);
        assert_eq!(d.len(), m);
        d.sort_unstable();
        d.dedup();
        assert_eq!(d.len(), m, "repeats in a draw of {m} of 16");
        assert!(d.iter().all(|&k| k < 16));
    }
    // More than there are: with replacement, every demonstration drawn about equally often.
    let d = draw.draw(16, 16_000);
    assert_eq!(d.len(), 16_000);
    let mut counts = [0usize; 16];
    for k in d {
        counts[k] += 1;
    }
    assert!(
        counts.iter().all(|&c| (800..1200).contains(&c)),
        "{counts:?}"
    );
    // The same seed draws the same.
    let (mut a, mut b) = (DemonstrationDraw::new(3), DemonstrationDraw::new(3));
    assert_eq!(a.draw(16, 40), b.draw(16, 40));
    assert_ne!(a.draw(16, 40), DemonstrationDraw::new(4).draw(16, 40));
}

#[test]
fn config_key_round_trips_and_is_checked() {
    // Every config writes it ([firl], required); the standard gives rkl's schedule 300.
    assert!(IrlRunConfig::quick()
        .to_toml()
        .contains("[firl]\nreward_lr = 0.001\nreward_l2 = 0.001\nkde_bandwidth = 0.02\nexpert_trajectories = 0\n"));
    let standard = IrlRunConfig::standard();
    assert_eq!(standard.to_toml().matches("expert_trajectories").count(), 2);
    assert_eq!(
        standard
            .for_algo(Algo::Rkl)
            .unwrap()
            .firl_expert_trajectories,
        300
    );
    let base = tiny_config().to_toml();
    let text = base.replace("expert_trajectories = 0\n", "expert_trajectories = 5\n");
    let c = IrlRunConfig::from_toml(
        &format!("{text}\n[schedule.js.firl]\nexpert_trajectories = 9\n"),
        "c.toml",
    )
    .unwrap();
    assert_eq!(c.firl_expert_trajectories, 5);
    assert_eq!(c.for_algo(Algo::Js).unwrap().firl_expert_trajectories, 9);
    assert_eq!(c.for_algo(Algo::Fkl).unwrap().firl_expert_trajectories, 5);
    let again = IrlRunConfig::from_toml(&c.to_toml(), "again.toml").unwrap();
    assert_eq!(again, c);

    let text = base.replace(
        "expert_trajectories = 0\n",
        "expert_trajectories = 1000000000000\n",
    );
    let err = IrlRunConfig::from_toml(&text, "c.toml")
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("firl.expert_trajectories") && err.contains("limit"),
        "{err}"
    );
}

/// A tiny rkl run with demonstrations in the batch completes, records the key, and learns a
/// different reward from the same seed without them.
#[test]
fn tiny_run_with_demonstrations_in_the_batch() {
    let run = |m: usize| {
        let mut config = tiny_config();
        config.firl_expert_trajectories = m;
        tiny_rkl_blue_run(config)
    };
    let (alone, written_alone) = run(0);
    let (with, written) = run(6);
    assert!(written_alone.contains("expert_trajectories = 0\n"));
    assert!(written.contains("expert_trajectories = 6\n"), "{written}");
    let losses = |m: &str| metrics_column(m, "surrogate_loss");
    assert_eq!(losses(&alone).len(), losses(&with).len());
    assert_ne!(losses(&alone)[1..], losses(&with)[1..], "{alone}\n{with}");
    // Same seed, same run.
    assert_eq!(run(6).0, with);
}
