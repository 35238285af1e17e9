//! SAC's own training episodes go to the rollout log (phase "train") and replay bit for bit,
//! sampled every n-th episode; replay re-tracks the task's reward machine and catches a
//! tampered machine state or reward.

use smirl::env::reacher::CancelConfig;
use smirl::env::reacher_task::ReacherTask;
use smirl::log::{read_log, LogOptions, RolloutLogger};
use smirl::pipeline::reacher_expert::{train_log_header, train_task_expert, ExpertConfig};
use smirl::pipeline::replay::replay;

fn tiny_expert_config() -> ExpertConfig {
    let mut c = ExpertConfig {
        total_steps: 400,
        checkpoint_every: 1_000,
        eval_episodes: 1,
        ..ExpertConfig::default()
    };
    c.sac.hidden = vec![16, 16];
    c.sac.batch_size = 32;
    c.sac.replay_capacity = 1_000;
    c.sac.warmup_steps = 100;
    c.sac.update_after = 100;
    c.env.max_steps = 40;
    c.env.cancel = Some(CancelConfig {
        probability: 0.5,
        earliest_step: 1,
        latest_step: 8,
    });
    c
}

#[test]
fn expert_training_episodes_are_logged_every_nth_and_replay_bit_exactly() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("train.mcap");
    let task = ReacherTask::shipped("sequential").unwrap();
    let config = tiny_expert_config();
    let header = train_log_header(task.clone(), &config, 5).unwrap();
    let mut logger = RolloutLogger::create(
        &path,
        header,
        LogOptions {
            every_nth_episode: 3,
            ..LogOptions::default()
        },
    )
    .unwrap();
    let (_, outcome) = train_task_expert(
        task,
        &config,
        5,
        &dir.path().join("expert.ckpt"),
        false,
        |_| {},
        Some(&mut logger),
    )
    .unwrap();
    let summary = logger.finish().unwrap();
    let episodes = outcome.trainer.episodes();
    assert!(episodes >= 10, "{episodes} episodes");

    let log = read_log(&path).unwrap();
    let ids: Vec<u64> = log.episodes.iter().map(|e| e.start.episode).collect();
    let expected: Vec<u64> = (0..episodes).filter(|i| i % 3 == 0).collect();
    assert_eq!(ids, expected);
    assert_eq!(summary.episodes_logged, expected.len() as u64);
    assert!(log.run.every_nth_episode == 3 && log.run.task == "sequential");
    for e in &log.episodes {
        assert_eq!(e.start.phase, "train");
        assert!(e.is_complete());
        assert!(e.steps.iter().all(|s| s.rm_state >= 0));
    }
    // The logged steps are the trainer's: their lengths add up to the curve's.
    let curve_len: u64 = outcome
        .curve
        .iter()
        .filter(|p| p.episode % 3 == 0)
        .map(|p| p.length)
        .sum();
    assert_eq!(log.steps() as u64, curve_len);

    let report = replay(&log).unwrap();
    assert!(report.all_match(), "{report}");
    assert!(report.episodes.iter().all(|e| e.rm_checked), "{report}");
    assert!(report.episodes.iter().all(|e| e.seed_reproduces_start));
    assert!(report
        .reward_machine
        .as_deref()
        .is_some_and(|s| s.contains("stored in the run record")));

    // A tampered machine state is caught at its step, and so is a tampered machine reward.
    let mut tampered = log.clone();
    tampered.episodes[1].steps[7].rm_state += 1;
    let m = replay(&tampered).unwrap().episodes[1]
        .mismatch
        .clone()
        .unwrap();
    assert_eq!((m.step, m.what.as_str()), (8, "rm_state"), "{m}");
    let mut tampered = log.clone();
    tampered.episodes[2].steps[3].rm_reward += 0.5;
    let m = replay(&tampered).unwrap().episodes[2]
        .mismatch
        .clone()
        .unwrap();
    assert_eq!((m.step, m.what.as_str()), (4, "rm_reward[0]"), "{m}");
    // So is a wrong initial state or final state.
    let mut tampered = log.clone();
    tampered.episodes[0].start.rm_state = 3;
    let m = replay(&tampered).unwrap().episodes[0]
        .mismatch
        .clone()
        .unwrap();
    assert_eq!((m.step, m.what.as_str()), (0, "rm_state"), "{m}");
    let mut tampered = log.clone();
    tampered.episodes[0].end.as_mut().unwrap().rm_state += 1;
    let m = replay(&tampered).unwrap().episodes[0]
        .mismatch
        .clone()
        .unwrap();
    assert_eq!(m.what, "final rm_state", "{m}");
}
