//! The product of ReacherDelivery with the tasks' reward machines, and sub-goal shaping.

use smirl::env::product::{Potential, ProductEnv};
use smirl::env::reacher::{CancelConfig, ReacherConfig, ReacherDelivery};
use smirl::env::reacher_task::{task_env, ReacherTask, SubgoalPotential};
use smirl::env::ContinuousEnv;

#[allow(unused_imports)]
use shipped_layout::{layout, obs_dim, shipped_config};
mod shipped_layout;

fn ik(x: f64, y: f64) -> [f64; 2] {
    let (l1, l2) = (0.1, 0.11);
    let c = (x * x + y * y - l1 * l1 - l2 * l2) / (2.0 * l1 * l2);
    let q1 = c.clamp(-1.0, 1.0).acos();
    [y.atan2(x) - (l2 * q1.sin()).atan2(l1 + l2 * q1.cos()), q1]
}

fn no_cancel() -> ReacherConfig {
    ReacherConfig {
        cancel: Some(CancelConfig {
            probability: 0.0,
            earliest_step: 1,
            latest_step: 8,
        }),
        ..Default::default()
    }
}

/// Puts the fingertip on a ball and takes one zero-torque step.
fn touch<P: Potential>(
    env: &mut ProductEnv<ReacherDelivery, P>,
    ball: usize,
    obs: &mut [f32],
) -> smirl::env::product::ProductStep {
    let b = env.inner().positions()[ball];
    env.inner_mut().set_arm(ik(b[0], b[1]), [0.0, 0.0]).unwrap();
    env.step_product(&[0.0, 0.0], obs).unwrap()
}

#[test]
fn subgoals_follow_the_machines() {
    /// (task, progress balls per state, touches to goal per state)
    type Case = (
        ReacherTask,
        &'static [&'static [usize]],
        &'static [Option<usize>],
    );
    let cases: &[Case] = &[
        (
            ReacherTask::shipped("or").unwrap(),
            &[&[0, 1], &[2], &[]],
            &[Some(2), Some(1), Some(0)],
        ),
        (
            ReacherTask::shipped("sequential").unwrap(),
            &[&[0], &[1], &[2], &[3], &[]],
            &[Some(4), Some(3), Some(2), Some(1), Some(0)],
        ),
        (
            ReacherTask::shipped("if").unwrap(),
            &[&[2], &[0], &[0], &[], &[]],
            &[Some(2), Some(1), Some(1), Some(0), None],
        ),
        (
            ReacherTask::shipped("composite").unwrap(),
            &[&[0, 1], &[2], &[3], &[3], &[0, 1], &[], &[]],
            &[Some(3), Some(2), Some(1), Some(1), Some(2), Some(0), None],
        ),
    ];
    for (task, progress, distance) in cases {
        let rm = task.perfect_rm().unwrap();
        let p = SubgoalPotential::from_rm(&rm, &layout());
        for u in 0..rm.n_states() {
            assert_eq!(p.progress_balls(u), progress[u], "{task} state {u}");
            assert_eq!(p.touches_to_goal(u), distance[u], "{task} state {u}");
        }
    }
}

#[test]
fn sequential_task_runs_through_the_machine() {
    let mut env = task_env(
        ReacherTask::shipped("sequential").unwrap(),
        no_cancel(),
        0.0,
        0.99,
    )
    .unwrap();
    let n_states = env.rm().n_states();
    assert_eq!(env.obs_dim(), obs_dim() + n_states);
    let mut obs = vec![0.0; env.obs_dim()];
    env.reset(0, &mut obs);
    assert_eq!(&obs[obs_dim()..], &[1.0, 0.0, 0.0, 0.0, 0.0]);
    // Out of order: green first changes nothing.
    let s = touch(&mut env, 1, &mut obs);
    assert_eq!(
        (s.rm_state, s.task_reward, s.step.terminated),
        (0, 0.0, false)
    );
    for (k, ball) in [0usize, 1, 2].into_iter().enumerate() {
        let s = touch(&mut env, ball, &mut obs);
        assert_eq!(s.rm_state, k + 1);
        assert_eq!(obs[obs_dim() + k + 1], 1.0);
        assert!(!s.step.terminated && !s.success);
    }
    let s = touch(&mut env, 3, &mut obs);
    assert!(s.success && s.step.terminated && !s.step.truncated);
    assert_eq!(s.task_reward, 1.0);
    assert_eq!(s.step.reward, 1.0, "no shaping at scale 0");
}

#[test]
fn if_task_fails_on_blue_after_cancel() {
    let config = ReacherConfig {
        cancel: Some(CancelConfig {
            probability: 1.0,
            earliest_step: 1,
            latest_step: 1,
        }),
        ..Default::default()
    };
    let mut env = task_env(ReacherTask::shipped("if").unwrap(), config, 0.0, 0.99).unwrap();
    let mut obs = vec![0.0; env.obs_dim()];
    env.reset(3, &mut obs);
    let s = env.step_product(&[0.0, 0.0], &mut obs).unwrap();
    assert!(s.step.labels.contains(4), "cancel fires on step 1");
    assert_eq!(s.rm_state, 2);
    let s = touch(&mut env, 2, &mut obs);
    assert!(s.failure && s.step.terminated && !s.success);
    assert_eq!(s.task_reward, 0.0);
}

#[test]
fn shaping_telescopes_and_rewards_progress() {
    // With gamma = 1 the shaping terms of an episode sum to Φ(last) − Φ(first).
    let mut env = task_env(ReacherTask::shipped("or").unwrap(), no_cancel(), 1.0, 1.0).unwrap();
    let potential = SubgoalPotential::from_rm(env.rm(), &layout());
    let mut obs = vec![0.0; env.obs_dim()];
    env.reset(1, &mut obs);
    let phi0 = potential.potential(env.inner_obs(), 0);
    let mut shaping_sum = 0.0;
    let mut task_sum = 0.0;
    for a in [[0.5f32, 0.2], [0.1, -0.3], [-0.4, 0.9]] {
        let s = env.step_product(&a, &mut obs).unwrap();
        shaping_sum += s.step.reward - s.task_reward;
        task_sum += s.task_reward;
    }
    let phi_now = potential.potential(env.inner_obs(), env.rm_state());
    assert!((shaping_sum - (phi_now - phi0)).abs() < 1e-9);
    assert_eq!(task_sum, 0.0);
    // Reaching a sub-goal is never penalised by the shaping.
    let before = potential.potential(env.inner_obs(), env.rm_state());
    let s = touch(&mut env, 0, &mut obs);
    assert_eq!(s.rm_state, 1);
    assert!(s.step.reward > 0.0, "progress pays: {}", s.step.reward);
    let after = potential.potential(env.inner_obs(), 1);
    assert!(after > before);
    // Completing the task: Φ = 0 in the goal, the shaped reward is 1 + (0 − Φ(before)).
    let s = touch(&mut env, 2, &mut obs);
    assert!(s.success);
    assert!(
        (s.step.reward - (1.0 - after)).abs() < 1e-6,
        "{}",
        s.step.reward
    );
}

#[test]
fn tasks_parse_and_reject_unknown_names() {
    for t in ReacherTask::all_shipped().unwrap() {
        assert_eq!(t.name().parse::<ReacherTask>().unwrap(), t);
    }
    assert!("composit"
        .parse::<ReacherTask>()
        .unwrap_err()
        .to_string()
        .contains("no shipped task named 'composit'"));
}
