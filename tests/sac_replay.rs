//! Replay buffer: ring overwrite, consistent sampled columns, uniform sampling, persistence;
//! agent rollouts.

mod sac_common;

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use sac_common::PointReach;
use smirl::env::ContinuousEnv;
use smirl::nn::{ByteReader, ByteWriter};
use smirl::rl::replay::{ReplayBatch, ReplayBuffer};
use smirl::rl::sac::{ActMode, SacAgent, SacConfig};
use smirl::rm::LabelSet;

/// Transition `i` carries `i` in every field, so a sample shows where each column came from.
fn push_numbered(buf: &mut ReplayBuffer, i: usize) {
    let v = i as f32;
    buf.push(
        &[v, v + 0.5],
        &[-v],
        &[v + 1.0, v + 1.5],
        10.0 * v,
        LabelSet(i as u32),
        i % 2 == 1,
    );
}

#[test]
fn full_buffer_overwrites_oldest_and_samples_whole_transitions() {
    let mut buf = ReplayBuffer::new(2, 1, 3);
    for i in 0..5 {
        push_numbered(&mut buf, i);
    }
    assert_eq!(buf.len(), 3);
    let mut batch = ReplayBatch::new(2, 1, 50);
    let mut rng = ChaCha8Rng::seed_from_u64(0);
    buf.sample_into(&mut rng, &mut batch);
    let mut seen = std::collections::BTreeSet::new();
    for j in 0..50 {
        let v = batch.obs[(0, j)];
        let i = v as usize;
        seen.insert(i);
        assert_eq!(batch.obs[(1, j)], v + 0.5);
        assert_eq!(batch.actions[(0, j)], -v);
        assert_eq!(batch.next_obs[(0, j)], v + 1.0);
        assert_eq!(batch.next_obs[(1, j)], v + 1.5);
        assert_eq!(batch.env_rewards[j], 10.0 * v);
        assert_eq!(batch.labels[j], LabelSet(i as u32));
        assert_eq!(batch.terminated[j], (i % 2) as f32);
    }
    assert_eq!(seen.into_iter().collect::<Vec<_>>(), vec![2, 3, 4]);
}

#[test]
fn sampling_is_uniform() {
    let mut buf = ReplayBuffer::new(2, 1, 10);
    for i in 0..10 {
        push_numbered(&mut buf, i);
    }
    let mut batch = ReplayBatch::new(2, 1, 1000);
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    let mut counts = [0usize; 10];
    for _ in 0..40 {
        buf.sample_into(&mut rng, &mut batch);
        for j in 0..1000 {
            counts[batch.obs[(0, j)] as usize] += 1;
        }
    }
    for c in counts {
        // Expected 4000 each; 5 standard deviations is about ±300.
        assert!((3700..=4300).contains(&c), "{counts:?}");
    }
}

#[test]
fn buffer_round_trips_and_refuses_other_sizes() {
    let mut buf = ReplayBuffer::new(2, 1, 4);
    for i in 0..6 {
        push_numbered(&mut buf, i);
    }
    let mut w = ByteWriter::new();
    buf.write(&mut w);
    let mut copy = ReplayBuffer::new(2, 1, 4);
    copy.read_into(&mut ByteReader::new(&w.bytes)).unwrap();
    let (mut b1, mut b2) = (ReplayBatch::new(2, 1, 64), ReplayBatch::new(2, 1, 64));
    buf.sample_into(&mut ChaCha8Rng::seed_from_u64(2), &mut b1);
    copy.sample_into(&mut ChaCha8Rng::seed_from_u64(2), &mut b2);
    assert_eq!(b1.obs, b2.obs);
    assert_eq!(b1.labels, b2.labels);
    // The ring position survives too: the next push overwrites the same slot in both.
    push_numbered(&mut buf, 9);
    push_numbered(&mut copy, 9);
    assert_eq!(buf.obs(2), copy.obs(2));
    let mut other = ReplayBuffer::new(2, 1, 5);
    let err = other.read_into(&mut ByteReader::new(&w.bytes)).unwrap_err();
    assert!(err.to_string().contains("replay capacity"), "{err}");
}

#[test]
fn rollout_reports_chained_steps_and_is_seeded() {
    let config = SacConfig {
        hidden: vec![8],
        batch_size: 4,
        ..SacConfig::default()
    };
    let mut agent = SacAgent::new(&config, 2, 1, &mut ChaCha8Rng::seed_from_u64(3));
    let mut env = PointReach::new(15);
    let record = |agent: &mut SacAgent, env: &mut PointReach| {
        let mut steps = Vec::new();
        let mut rng = ChaCha8Rng::seed_from_u64(4);
        let summary = agent
            .rollout(env, ActMode::Sample, 77, 100, &mut rng, |s| {
                steps.push((s.t, s.obs.to_vec(), s.action.to_vec(), s.next_obs.to_vec()));
            })
            .unwrap();
        (summary, steps)
    };
    let (summary, steps) = record(&mut agent, &mut env);
    assert_eq!(summary.length, 15);
    assert!(!summary.terminated);
    assert_eq!(steps.len(), 15);
    for w in steps.windows(2) {
        assert_eq!(w[0].3, w[1].1, "next_obs of one step is obs of the next");
        assert_eq!(w[0].0 + 1, w[1].0);
    }
    assert!(steps.iter().all(|s| s.2[0].abs() <= 1.0));
    assert_eq!(record(&mut agent, &mut env).1, steps);

    // The same episode by hand: reset, then one action drawn from the stream and one step at a
    // time. The episode loop neither draws nor steps more than that, nor in another order.
    let mut rng = ChaCha8Rng::seed_from_u64(4);
    let mut obs = vec![0.0f32; 2];
    env.reset(77, &mut obs);
    let mut action = vec![0.0f32; 1];
    let mut env_return = 0.0;
    for (t, o, a, next) in &steps {
        assert_eq!(&obs, o, "step {t}");
        agent.act(&obs, ActMode::Sample, &mut rng, &mut action);
        assert_eq!(&action, a, "step {t}");
        env_return += env.step(&action, &mut obs).unwrap().reward;
        assert_eq!(&obs, next, "step {t}");
    }
    assert_eq!(summary.env_return, env_return);

    // A step budget cuts the episode; a budget of 0 plays nothing.
    let mut rng = ChaCha8Rng::seed_from_u64(4);
    let cut = agent
        .rollout(&mut env, ActMode::Sample, 77, 6, &mut rng, |_| {})
        .unwrap();
    assert_eq!((cut.length, cut.terminated), (6, false));
    let none = agent
        .rollout(&mut env, ActMode::Sample, 77, 0, &mut rng, |_| {})
        .unwrap();
    assert_eq!((none.length, none.env_return), (0, 0.0));
}
