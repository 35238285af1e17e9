//! Expert training loop: learns, checkpoints, resumes exactly, keeps the last good
//! checkpoint on NaN, refuses to overwrite.

mod sac_common;

use sac_common::PointReach;
use smirl::env::{ContinuousEnv, EnvError, EnvStep};
use smirl::pipeline::expert::{curve_path, read_curve, train_expert, TrainingError, TrainingPlan};
use smirl::rl::sac::{EpisodeSummary, SacConfig, SacTrainer};

fn config(total_steps: u64) -> TrainingPlan {
    TrainingPlan {
        sac: SacConfig {
            hidden: vec![32, 32],
            batch_size: 64,
            warmup_steps: 500,
            update_after: 500,
            ..SacConfig::default()
        },
        total_steps,
        checkpoint_every: 400,
        eval_episodes: 20,
        eval_max_steps: 100,
        progress_window: 20,
    }
}

/// The point ends the episode at the target.
fn reached(e: &EpisodeSummary) -> bool {
    e.final_reward > -0.05
}

fn params(t: &SacTrainer) -> Vec<u32> {
    let a = &t.agent;
    [&a.actor, &a.q1, &a.q2, &a.q1_target, &a.q2_target]
        .iter()
        .flat_map(|n| {
            n.params()
                .flat_map(|p| p.iter().map(|x| x.to_bits()))
                .collect::<Vec<_>>()
        })
        .collect()
}

#[test]
fn expert_training_succeeds_and_writes_checkpoint_and_curve() {
    let dir = tempfile::tempdir().unwrap();
    let ckpt = dir.path().join("expert.ckpt");
    let mut env = PointReach::new(40);
    let mut reports = 0;
    let mut checkpoints = 0;
    let out = train_expert(
        &mut env,
        &config(4_000),
        1,
        &ckpt,
        false,
        reached,
        |p| {
            reports += 1;
            checkpoints += usize::from(p.checkpointed);
        },
        None,
    )
    .unwrap();
    assert!(out.success_rate >= 0.9, "success rate {}", out.success_rate);
    assert_eq!(out.curve.len(), 100);
    assert_eq!(reports, 100);
    assert_eq!(checkpoints, 10);
    assert!(out.resumed_at.is_none());
    assert!(ckpt.exists());
    assert_eq!(read_curve(&curve_path(&ckpt), u64::MAX).unwrap(), out.curve);
    // The learning shows in the curve: late episodes succeed, the random warm-up did not.
    assert!(out.curve[..10].iter().filter(|p| p.success).count() <= 2);
    assert!(out.curve[90..].iter().filter(|p| p.success).count() >= 9);
    // Without --resume an existing checkpoint is not overwritten.
    let err = train_expert(
        &mut env,
        &config(4_000),
        1,
        &ckpt,
        false,
        reached,
        |_| {},
        None,
    )
    .unwrap_err();
    assert!(matches!(err, TrainingError::CheckpointExists(_)), "{err}");
    assert!(err.to_string().contains("--resume"));
}

#[test]
fn resumed_expert_run_equals_uninterrupted_run() {
    let dir = tempfile::tempdir().unwrap();
    let (full_ckpt, split_ckpt) = (dir.path().join("full"), dir.path().join("split"));
    let mut env = PointReach::new(40);
    let full = train_expert(
        &mut env,
        &config(1_600),
        2,
        &full_ckpt,
        false,
        reached,
        |_| {},
        None,
    )
    .unwrap();
    let first = train_expert(
        &mut env,
        &config(800),
        2,
        &split_ckpt,
        true,
        reached,
        |_| {},
        None,
    )
    .unwrap();
    assert_eq!(first.trainer.env_steps(), 800);
    let second = train_expert(
        &mut env,
        &config(1_600),
        2,
        &split_ckpt,
        true,
        reached,
        |_| {},
        None,
    )
    .unwrap();
    assert_eq!(second.resumed_at, Some(800));
    assert_eq!(params(&second.trainer), params(&full.trainer));
    assert_eq!(second.curve, full.curve);
    assert_eq!(second.success_rate, full.success_rate);
}

/// PointReach whose reward turns NaN at a given global step.
struct NanAfter {
    inner: PointReach,
    steps: u64,
    nan_at: u64,
}

impl ContinuousEnv for NanAfter {
    fn obs_dim(&self) -> usize {
        2
    }
    fn act_dim(&self) -> usize {
        1
    }
    fn reset(&mut self, seed: u64, obs: &mut [f32]) {
        self.inner.reset(seed, obs)
    }
    fn step(&mut self, action: &[f32], obs: &mut [f32]) -> Result<EnvStep, EnvError> {
        self.steps += 1;
        let mut s = self.inner.step(action, obs)?;
        if self.steps >= self.nan_at {
            s.reward = f64::NAN;
        }
        Ok(s)
    }
}

#[test]
fn nan_stops_the_run_and_keeps_the_last_good_checkpoint() {
    let dir = tempfile::tempdir().unwrap();
    let ckpt = dir.path().join("expert.ckpt");
    let mut env = NanAfter {
        inner: PointReach::new(40),
        steps: 0,
        nan_at: 1_000,
    };
    let cfg = config(4_000);
    let err = train_expert(&mut env, &cfg, 3, &ckpt, false, reached, |_| {}, None).unwrap_err();
    let msg = err.to_string();
    assert!(
        msg.contains("non-finite") && msg.contains("critic"),
        "{msg}"
    );
    let resumed = SacTrainer::resume(&ckpt, &cfg.sac, 2, 1).unwrap();
    assert_eq!(resumed.env_steps(), 800);
    assert!(resumed.agent.actor.params_finite() && resumed.agent.q1.params_finite());
}
