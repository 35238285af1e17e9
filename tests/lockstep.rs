//! Lockstep play (`pipeline::reacher_irl::lockstep`) gives the episodes one-at-a-time play
//! gives: the same actions (a batched actor forward has each column's bits), trajectories,
//! outcomes and log bytes, whatever the batch width and thread count, in the plain environment
//! and in the product with a learned machine (SMIRL's and the product controls').

use nalgebra::DMatrix;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use smirl::env::product::ProductEnv;
use smirl::env::reacher::{ReacherConfig, ReacherDelivery, ACT_DIM};
use smirl::env::reacher_task::ReacherTask;
use smirl::log::{LogOptions, RolloutLogger, RunHeader};
use smirl::nn::{Mlp, MlpArch};
use smirl::pipeline::reacher_irl::episodes::{
    play_episode, AgentBatch, EpisodeOutcome, EpisodeSpec, GroundTruthTask, JobEnv,
};
use smirl::pipeline::reacher_irl::lockstep::{
    play_lockstep, Keep, Lockstep, LockstepError, PlayedEpisode,
};
use smirl::pipeline::reacher_irl::smirl::task_machine;
use smirl::rl::sac::{draw_noise, episode_seed, ActMode, SacAgent, SacConfig};
use smirl::rm::format::parse_rm;
use std::path::Path;

#[allow(unused_imports)]
use shipped_layout::{layout, obs_dim, shipped_config};
mod shipped_layout;

/// An actor column computed in a batch of 300 has the bits of the same column computed alone,
/// for the networks SAC uses ((64, 64) and (256, 256) hidden layers).
#[test]
fn batched_forward_has_each_columns_bits() {
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    for hidden in [[64, 64], [256, 256]] {
        let mlp = Mlp::new(&MlpArch::new(obs_dim(), &hidden, 2 * ACT_DIM), &mut rng);
        let n = 300;
        let x = DMatrix::from_fn(obs_dim(), n, |_, _| rng.gen_range(-2.0f32..2.0));
        let mut ws = mlp.workspace(n);
        let batched = mlp.forward(&x, &mut ws).clone();
        let mut one = mlp.workspace(1);
        for j in 0..n {
            let col = DMatrix::from_column_slice(obs_dim(), 1, x.column(j).as_slice());
            let alone = mlp.forward(&col, &mut one);
            for i in 0..2 * ACT_DIM {
                assert_eq!(
                    alone[i].to_bits(),
                    batched[(i, j)].to_bits(),
                    "hidden {hidden:?}, column {j}, output {i}"
                );
            }
        }
    }
}

/// An untrained agent for observations `obs_dim` wide.
fn agent(seed: u64, obs_dim: usize) -> SacAgent {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    SacAgent::new(&SacConfig::default(), obs_dim, ACT_DIM, &mut rng)
}

fn env() -> ReacherDelivery {
    ReacherDelivery::new(shipped_config(ReacherConfig::default())).unwrap()
}

fn logger(path: &Path) -> RolloutLogger {
    let header = RunHeader::of_task(
        "composite",
        smirl::env::reacher_task::ReacherTask::shipped("composite")
            .unwrap()
            .task(),
        0,
        serde_json::json!({"test": true}),
    );
    RolloutLogger::create(path, header, LogOptions::default()).unwrap()
}

fn specs(n: u64, mode: ActMode, decided: bool) -> Vec<EpisodeSpec<'static>> {
    (0..n)
        .map(|i| EpisodeSpec {
            mode,
            reset_seed: episode_seed(11, i),
            stop_when_decided: decided,
            with_branch: true,
            phase: "agent",
        })
        .collect()
}

/// One-at-a-time play as the pipeline did it before lockstep: every episode in turn in `env`,
/// the noise drawn as it goes from one generator shared by all episodes, logged as it goes.
fn one_at_a_time<E: JobEnv>(
    mut env: E,
    task: &GroundTruthTask<'_>,
    specs: &[EpisodeSpec<'_>],
    log_path: &Path,
) -> (Vec<EpisodeOutcome>, AgentBatch) {
    let mut agent = agent(3, env.obs_dim());
    let mut rng = ChaCha8Rng::seed_from_u64(99);
    let mut log = logger(log_path);
    let mut batch = AgentBatch::default();
    let mut outcomes = Vec::new();
    for &spec in specs {
        let mut len = 0;
        let o = play_episode(
            &mut agent,
            &mut env,
            task,
            spec,
            &mut rng,
            Some(&mut log),
            |after, u| {
                batch.push_step(after, u);
                len += 1;
            },
        )
        .unwrap();
        batch.lengths.push(len);
        outcomes.push(o);
    }
    log.finish().unwrap();
    (outcomes, batch)
}

/// The same episodes in lockstep in copies of `env`, `batch` environments per thread on
/// `threads` threads, the noise drawn beforehand from the same generator; log records written
/// in episode order.
fn in_lockstep<E: JobEnv>(
    env: &E,
    task: &GroundTruthTask<'_>,
    specs: &[EpisodeSpec<'_>],
    batch: usize,
    threads: usize,
    log_path: &Path,
) -> (Vec<EpisodeOutcome>, AgentBatch) {
    let agent = agent(3, env.obs_dim());
    let noise = (specs[0].mode == ActMode::Sample).then(|| {
        let mut rng = ChaCha8Rng::seed_from_u64(99);
        let mut noise = vec![0.0f32; specs.len() * env.reacher().config().max_steps * ACT_DIM];
        draw_noise(&mut rng, &mut noise);
        noise
    });
    let threads_now = move || threads;
    let plan = Lockstep {
        batch,
        threads: &threads_now,
    };
    let keep = Keep {
        log: true,
        steps: true,
    };
    let played: Vec<PlayedEpisode> =
        play_lockstep(&agent.actor, env, task, specs, noise.as_deref(), plan, keep).unwrap();
    let mut log = logger(log_path);
    let mut steps = AgentBatch::default();
    let mut outcomes = Vec::new();
    for p in played {
        p.log.unwrap().write_to(&mut log).unwrap();
        steps.append(p.steps.unwrap());
        outcomes.push(p.outcome);
    }
    log.finish().unwrap();
    (outcomes, steps)
}

fn same_outcomes(a: &[EpisodeOutcome], b: &[EpisodeOutcome], what: &str) {
    assert_eq!(a.len(), b.len(), "{what}");
    for (k, (x, y)) in a.iter().zip(b).enumerate() {
        let key = |o: &EpisodeOutcome| {
            (
                o.success,
                o.progress.to_bits(),
                o.final_ball,
                o.branch,
                o.task_return.to_bits(),
                o.env_return.to_bits(),
            )
        };
        assert_eq!(key(x), key(y), "{what}: episode {k}");
    }
}

fn same_steps(a: &AgentBatch, b: &AgentBatch, what: &str) {
    let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    assert_eq!(a.lengths, b.lengths, "{what}: lengths");
    assert_eq!(bits(&a.obs), bits(&b.obs), "{what}: observations");
    assert_eq!(a.states, b.states, "{what}: learned states");
}

/// Sampled rollouts to the time limit (f-IRL's agent trajectories) and mean-action episodes
/// ended once the task is decided (evaluation) in copies of `env`: batch 1, 32 and 300, threads
/// 1 and 2 give the trajectories, outcomes and log file bytes of one-at-a-time play. Returns
/// the sampled rollouts.
fn assert_lockstep_is_one_at_a_time<E: JobEnv>(
    env: impl Fn() -> E,
    task: &GroundTruthTask<'_>,
    dir: &Path,
) -> AgentBatch {
    assert!(env().ends_only_at_time_limit());
    let mut sampled = AgentBatch::default();
    for (mode, decided, n) in [(ActMode::Sample, false, 300), (ActMode::Mean, true, 40)] {
        let specs = specs(n, mode, decided);
        let reference_log = dir.join(format!("{mode:?}-reference.mcap"));
        let (outcomes, steps) = one_at_a_time(env(), task, &specs, &reference_log);
        let reference_bytes = std::fs::read(&reference_log).unwrap();
        if decided {
            assert!(
                steps.lengths.iter().any(|&l| l < 100),
                "the test needs episodes that end before the time limit"
            );
        }
        for (batch, threads) in [(1, 1), (300, 1), (1, 2), (32, 2)] {
            let what = format!("{mode:?}, batch {batch}, threads {threads}");
            let log = dir.join(format!("{mode:?}-{batch}-{threads}.mcap"));
            let (o, s) = in_lockstep(&env(), task, &specs, batch, threads, &log);
            same_outcomes(&outcomes, &o, &what);
            same_steps(&steps, &s, &what);
            assert!(
                std::fs::read(&log).unwrap() == reference_bytes,
                "{what}: log bytes differ"
            );
        }
        if !decided {
            sampled = steps;
        }
    }
    sampled
}

/// In the plain environment (the baselines').
#[test]
fn lockstep_play_is_one_at_a_time_play() {
    let dir = tempfile::tempdir().unwrap();
    let rm = ReacherTask::shipped("composite")
        .unwrap()
        .perfect_rm()
        .unwrap();
    let task = GroundTruthTask::of(&rm, &layout());
    assert_lockstep_is_one_at_a_time(env, &task, dir.path());
}

/// In the product with a machine shaped as a learned one (no goal or failure state: the
/// Composite task's states and guards), as SMIRL and the product controls act:
/// every environment of a batch reads its own machine state, and each sampled observation is
/// paired with the learned state one-at-a-time play pairs it with. The ground truth is decided
/// by the first label of an episode, so that evaluation episodes end before the time limit
/// (ActMode::Mean). A machine with a goal or failure state can end an episode before the time
/// limit: such a product is not played in lockstep with sampled actions.
///
/// Mutations tried: the product's `JobEnv::fresh` returning `None` (as before lockstep reached
/// the product): fails with "this environment cannot be copied for lockstep play";
/// `ends_only_at_time_limit` ignoring the machine: fails at the last assertion.
#[test]
fn lockstep_play_in_the_product_is_one_at_a_time_play() {
    let dir = tempfile::tempdir().unwrap();
    let first_label =
        "vocabulary: rgbyc\nstates: 2\ninitial: 0\nterminal: 1\n(0, 1, 'r|g|b|y|c', 1)\n";
    let perfect = parse_rm(first_label, "first label").unwrap();
    let task = GroundTruthTask::of(&perfect, &layout());
    let composite = ReacherTask::shipped("composite")
        .unwrap()
        .perfect_rm()
        .unwrap();
    let learned = task_machine(&composite).unwrap();
    let product = || ProductEnv::new(env(), learned.clone());
    let sampled = assert_lockstep_is_one_at_a_time(product, &task, dir.path());
    let initial = learned.initial() as u32;
    assert!(
        sampled.states.iter().any(|&u| u != initial),
        "the test needs rollouts that leave the machine's initial state"
    );
    assert!(!ProductEnv::new(env(), perfect.clone()).ends_only_at_time_limit());
}

/// Sampled lockstep play refuses noise of the wrong size instead of playing other episodes.
#[test]
fn lockstep_sampling_needs_the_whole_noise() {
    let rm = ReacherTask::shipped("or").unwrap().perfect_rm().unwrap();
    let task = GroundTruthTask::of(&rm, &layout());
    let specs = specs(3, ActMode::Sample, false);
    let agent = agent(1, obs_dim());
    let noise = vec![0.0f32; 3 * 100 * ACT_DIM - 1];
    let err = play_lockstep(
        &agent.actor,
        &env(),
        &task,
        &specs,
        Some(&noise),
        Lockstep::single_thread(),
        Keep::default(),
    )
    .unwrap_err();
    assert!(
        matches!(
            err,
            LockstepError::NoiseLength {
                per_episode: 200,
                episodes: 3
            }
        ),
        "{err:?}"
    );
    assert_eq!(
        err.to_string(),
        "lockstep sampling needs 200 noise values for each of 3 episodes"
    );
}
