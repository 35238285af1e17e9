//! SAC solves a small continuous control task within a test-sized budget.

mod sac_common;

use sac_common::PointReach;
use smirl::rl::sac::{ActMode, EnvReward, SacConfig, SacTrainer};

#[test]
fn sac_learns_to_reach_a_target_point() {
    let config = SacConfig {
        hidden: vec![32, 32],
        batch_size: 64,
        warmup_steps: 500,
        update_after: 500,
        ..SacConfig::default()
    };
    let mut env = PointReach::new(40);
    let mut trainer = SacTrainer::new(&config, 2, 1, 11).unwrap();
    let before = trainer
        .evaluate(&mut env, 20, ActMode::Mean, 999, 40)
        .unwrap();
    trainer
        .train(&mut env, &mut EnvReward, 4_000, |_| {})
        .unwrap();
    let after = trainer
        .evaluate(&mut env, 20, ActMode::Mean, 999, 40)
        .unwrap();
    let mean = |v: &[smirl::rl::sac::EpisodeSummary]| {
        v.iter().map(|e| e.env_return).sum::<f64>() / v.len() as f64
    };
    let (b, a) = (mean(&before), mean(&after));
    eprintln!(
        "mean return before {b:.2}, after {a:.2}, alpha {}",
        trainer.agent.alpha()
    );
    // Moving straight to the target from x ~ U(−1, 1) at 0.1 per step costs about −2 to −3;
    // staying put costs about −25 over 40 steps.
    assert!(a > -4.0, "return after training {a:.2} (before {b:.2})");
    // The final position is at the target.
    assert!(
        (env.x - env.target).abs() < 0.1,
        "final x {} target {}",
        env.x,
        env.target
    );
}
