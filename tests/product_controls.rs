//! The product controls `maxent-product` and `fkl-product` (issue 54, item 4; docs/algorithms.md):
//! MaxEnt IRL and f-IRL (fkl) on the product with SMIRL's learned machine, the reward an MLP of
//! (one-hot u, fingertip). What they read of a step follows the learned machine, the reward has
//! |U| + 2 inputs, the machine is the one SMIRL's job reads, and each job runs end to end and
//! reproducibly. (That no ground truth reaches them: tests/no_ground_truth_leak.rs.)

mod irl_run_common;
use irl_run_common::{job_bytes, tiny_config};
use smirl::env::product::ProductEnv;
use smirl::env::reacher::{ReacherDelivery, OBS_TIP};
use smirl::env::reacher_task::ReacherTask;
use smirl::irl::reward::{MlpReward, MlpRewardConfig, RewardModel};
use smirl::pipeline::reacher_expert::{Demo, DemoStep};
use smirl::pipeline::reacher_irl::episodes::JobEnv;
use smirl::pipeline::reacher_irl::firl::{baseline_reward_at, reward_model, StateMap};
use smirl::pipeline::reacher_irl::iteration::StepError;
use smirl::pipeline::reacher_irl::lockstep::Lockstep;
use smirl::pipeline::reacher_irl::run::{open_run, prepare, Silent};
use smirl::pipeline::reacher_irl::smirl::annotate;
use smirl::pipeline::reacher_irl::{run_pipeline, Algo, RunRequest};
use smirl::rl::replay::ReplayBatch;
use smirl::rm::format::parse_rm;
use smirl::rm::{LabelSet, RewardMachine};
use std::path::Path;

/// 0 —r→ 1 —b→ 2 over the ReacherDelivery vocabulary: a learned machine's shape (no goal).
const MACHINE: &str = "\
vocabulary: rgbyc
states: 3
initial: 0
(0, 1, 'r', 0)
(1, 2, 'b', 0)
";

fn machine() -> RewardMachine {
    parse_rm(MACHINE, "test machine").unwrap()
}

fn labels(text: &str) -> LabelSet {
    machine().vocab().parse_labels(text).unwrap()
}

/// A task observation of `obs_dim` with fingertip (x, y).
fn obs_at(obs_dim: usize, x: f32, y: f32) -> Vec<f32> {
    let mut o = vec![0.5f32; obs_dim];
    o[OBS_TIP[0]] = x;
    o[OBS_TIP[1]] = y;
    o
}

/// A demonstration whose steps carry the recorded `labels` and reach fingertip (k, −k) on step
/// k.
fn demo(obs_dim: usize, label_trace: &[&str]) -> Demo {
    let steps = label_trace
        .iter()
        .enumerate()
        .map(|(k, l)| DemoStep {
            obs: obs_at(obs_dim, k as f32 - 1.0, 1.0 - k as f32),
            action: [0.0; 2],
            next_obs: obs_at(obs_dim, k as f32, -(k as f32)),
            labels: labels(l),
            rm_state: 0,
            env_reward: 0.0,
            task_reward: 0.0,
        })
        .collect();
    Demo {
        seed: 0,
        initial_rm_state: 0,
        initial_labels: LabelSet::default(),
        steps,
        success: true,
        task_return: 0.0,
        env_return: 0.0,
    }
}

/// The demonstrations as a product control's reward reads them: on the recorded labels
/// ∅ r r ∅ b ∅ the machine is in 0 0 1 1 1 2 before each step (the state the step's labels are
/// read in, as SMIRL pairs u_t with o_{t+1}), so the rows are one-hot(0, 0, 1, 1, 1, 2) followed
/// by each step's fingertip; the baselines' rows are the observations themselves.
///
/// Mutation tried: the one-hot of the next state in the chain (`u + 1` capped at 2 in
/// `StateMap::rows`): fails at "row 0".
#[test]
fn the_product_rows_follow_the_learned_machine_on_a_recorded_label_sequence() {
    let layout = ReacherTask::shipped("blue").unwrap().layout();
    let d = layout.obs_dim();
    let m = machine();
    let data = annotate(
        &layout,
        &[demo(d, &["", "r", "r", "", "b", ""])],
        Some(&m),
        None,
    );
    assert_eq!(data.learned_states, [0, 0, 1, 1, 1, 2]);
    let map = StateMap::Product(&m);
    assert_eq!(map.columns(), [0, 1, 2, 3, 4]);
    let expert = map.expert(&data).unwrap();
    assert_eq!(expert.obs_dim(), 5);
    let expected: [[f32; 5]; 6] = [
        [1.0, 0.0, 0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0, 1.0, -1.0],
        [0.0, 1.0, 0.0, 2.0, -2.0],
        [0.0, 1.0, 0.0, 3.0, -3.0],
        [0.0, 1.0, 0.0, 4.0, -4.0],
        [0.0, 0.0, 1.0, 5.0, -5.0],
    ];
    for (k, (row, want)) in expert.obs.chunks_exact(5).zip(&expected).enumerate() {
        assert_eq!(row, want, "row {k}");
    }
    assert_eq!(expert.learned_states, data.learned_states);
    assert_eq!(expert.lengths, data.lengths);
    // The baselines read the observations as they are.
    let plain = StateMap::Fingertip.expert(&data).unwrap();
    assert_eq!(plain.obs, data.obs);
    // A state the machine does not have is refused, not read past the one-hot block.
    let err = map.rows(&data.obs[..d], d, &[3]).unwrap_err();
    assert!(
        matches!(err, StepError::UnknownState { state: 3, n: 3 }),
        "{err:?}"
    );
    assert_eq!(
        err.to_string(),
        "state 3 is not a state of the 3-state machine"
    );
}

/// SAC's reward rows on the product (observation ⊕ one-hot u): the state before the
/// step, read from the previous observation's one-hot block, with the next fingertip.
///
/// Mutation tried: reading the next observation's block (`next` for `prev` in
/// `StateMap::sac_rows`): fails at "transition 0".
#[test]
fn sac_reads_the_state_before_the_step_with_the_next_fingertip() {
    let d = ReacherTask::shipped("blue").unwrap().layout().obs_dim();
    let m = machine();
    let width = d + 3;
    let mut batch = ReplayBatch::new(width, 2, 2);
    let mut set = |col: usize, prev_u: usize, next_u: usize, tip: [f32; 2]| {
        let mut prev = obs_at(d, 9.0, 9.0);
        let mut next = obs_at(d, tip[0], tip[1]);
        for (o, u) in [(&mut prev, prev_u), (&mut next, next_u)] {
            o.extend((0..3).map(|k| if k == u { 1.0 } else { 0.0 }));
        }
        batch.obs.column_mut(col).copy_from_slice(&prev);
        batch.next_obs.column_mut(col).copy_from_slice(&next);
    };
    set(0, 0, 1, [0.1, -0.2]);
    set(1, 2, 2, [0.3, 0.4]);
    let mut rows = Vec::new();
    StateMap::Product(&m).sac_rows(&batch, d, &mut rows);
    assert_eq!(rows[..5], [1.0, 0.0, 0.0, 0.1, -0.2], "transition 0");
    assert_eq!(rows[5..], [0.0, 0.0, 1.0, 0.3, 0.4], "transition 1");
    // The baselines read the next task observation.
    StateMap::Fingertip.sac_rows(&batch, d, &mut rows);
    assert_eq!(rows.len(), 2 * d);
    assert_eq!(rows[OBS_TIP[0]], 0.1);
}

/// The product reward is the baselines' (64, 64) MLP with |U| + 2 inputs: one-hot u then the
/// fingertip.
///
/// Mutation tried: `StateMap::columns` of the product without the fingertip (`0..n_states`):
/// fails at "|U| + 2 inputs".
#[test]
fn the_product_reward_reads_one_hot_u_and_the_fingertip() {
    let mut settings = tiny_config();
    settings.env = ReacherTask::shipped("blue")
        .unwrap()
        .env_config(&settings.env)
        .unwrap();
    let m = machine();
    let product = reward_model(&settings, 0, StateMap::Product(&m)).unwrap();
    assert_eq!(
        product.network().inputs(),
        m.n_states() + 2,
        "|U| + 2 inputs"
    );
    assert_eq!(product.obs_dim(), m.n_states() + 2);
    assert_eq!(product.config().hidden, [64, 64]);
    let plain = reward_model(&settings, 0, StateMap::Fingertip).unwrap();
    assert_eq!(plain.network().inputs(), 2);
    assert_eq!(plain.config().optim, product.config().optim);
    assert_eq!(plain.config().clamp, product.config().clamp);
}

fn run(dir: &Path, algos: &[Algo]) {
    let request = RunRequest {
        task: ReacherTask::shipped("blue").unwrap(),
        algos: algos.to_vec(),
        seeds: 1,
        seed: 5,
        config: tiny_config(),
        out: dir.to_path_buf(),
        force: false,
    };
    run_pipeline(&request, &Silent).unwrap();
}

/// A job of each control runs end to end on a tiny config (records, metrics with the final
/// phase, an MLP reward of |U| + 2 inputs that `reacher reward` refuses) and a second run of
/// the same seed writes the same bytes.
///
/// Mutation tried: the product agent's environment without the one-hot block
/// (the task's own environment for the product in `firl::train`): the run fails (SAC's batch has no block
/// to read the state from).
#[test]
fn each_control_runs_end_to_end_and_reproducibly() {
    let tmp = tempfile::tempdir().unwrap();
    let algos = Algo::REACHER_CONTROLS;
    run(&tmp.path().join("a"), &algos);
    run(&tmp.path().join("b"), &algos);
    let read = |run: &str, f: &str| std::fs::read(tmp.path().join(run).join(f)).unwrap();
    let learned = parse_rm(
        &String::from_utf8(read("a", "rm/learned.txt")).unwrap(),
        "learned",
    )
    .unwrap();
    let n = learned.n_states();
    for f in [
        "metrics.csv",
        "final_policy.csv",
        "rm/learned.txt",
        "rewards/maxent-product_seed5.bin",
        "rewards/fkl-product_seed5.bin",
    ] {
        assert!(read("a", f) == read("b", f), "{f} differs between two runs");
    }
    let metrics = String::from_utf8(read("a", "metrics.csv")).unwrap();
    for algo in algos {
        let rows = metrics
            .lines()
            .filter(|l| l.starts_with(&format!("{},", algo.name())))
            .count();
        assert_eq!(rows, 3, "{algo}: iterations 0, 1, 2");
        let path = tmp
            .path()
            .join(format!("a/rewards/{}_seed5.bin", algo.name()));
        let cfg = MlpRewardConfig::paper((0..n + 2).collect(), 1e-3, 0);
        let mut reward = MlpReward::new(cfg, n + 2).unwrap();
        reward.load(&path).unwrap();
        assert!(baseline_reward_at(&path, &[[0.0, 0.0]]).is_err());
    }
    let summary = String::from_utf8(read("a", "summary.md")).unwrap();
    assert!(summary.contains("maxent-product") && summary.contains("fkl-product"));
}

/// The controls read the machine SMIRL's job reads: `reacher prepare` of a control alone
/// writes the same learned machine and annotated demonstrations as of `smirl` alone (LRM's
/// seed is the run's base seed, not a job's SAC seed).
///
/// Mutation tried: the controls' machine learned with `smirl-paper`'s settings (`Machine::of`
/// giving `Machine::Paper`): fails at "rm/learned.txt" (no file).
#[test]
fn the_controls_read_the_machine_smirl_learns() {
    let tmp = tempfile::tempdir().unwrap();
    let prep = |name: &str, algo: Algo| {
        let request = RunRequest {
            task: ReacherTask::shipped("if").unwrap(),
            algos: vec![algo],
            seeds: 2,
            seed: 3,
            config: tiny_config(),
            out: tmp.path().join(format!("{name}.unused")),
            force: false,
        };
        prepare(&request, &tmp.path().join(name), &Silent).unwrap();
    };
    prep("smirl", Algo::Smirl);
    prep("maxent-product", Algo::MaxEntProduct);
    prep("fkl-product", Algo::FklProduct);
    for f in ["rm/learned.txt", "expert_data.bin"] {
        let smirl = std::fs::read(tmp.path().join("smirl").join(f)).unwrap();
        for control in ["maxent-product", "fkl-product"] {
            let path = tmp.path().join(control).join(f);
            let bytes = std::fs::read(&path).unwrap_or_default();
            assert!(bytes == smirl, "{f}: {control}'s differs from smirl's");
        }
    }
}

/// `--algo all` stays the figure-7 comparison; the controls run when named; a config that
/// hands SMIRL the task's own machine is refused for them before anything runs.
#[test]
fn the_controls_are_named_not_in_all_and_never_read_the_tasks_machine() {
    let all = Algo::parse_reacher_list("all").unwrap();
    assert_eq!(all, Algo::REACHER);
    assert!(!all.iter().any(|a| a.is_product_control()));
    assert_eq!(
        Algo::parse_reacher_list("fkl,fkl-product,maxent-product").unwrap(),
        [Algo::Fkl, Algo::FklProduct, Algo::MaxEntProduct]
    );
    assert_eq!(Algo::FklProduct.base(), Algo::Fkl);
    assert_eq!(Algo::MaxEntProduct.base(), Algo::MaxEnt);
    let unknown = Algo::parse_list("maxent-product", &Algo::OFFICE).unwrap_err();
    assert_eq!(unknown.name, "maxent-product");
    assert_eq!(unknown.expected, ["smirl", "maxent", "apprenticeship"]);
    assert_eq!(
        unknown.to_string(),
        "unknown algorithm 'maxent-product' (expected one of: smirl, maxent, apprenticeship, all)"
    );

    let tmp = tempfile::tempdir().unwrap();
    let mut config = tiny_config();
    config.smirl_machine = smirl::pipeline::reacher_irl::SmirlMachine::Task;
    let request = RunRequest {
        task: ReacherTask::shipped("blue").unwrap(),
        algos: vec![Algo::FklProduct],
        seeds: 1,
        seed: 5,
        config,
        out: tmp.path().join("run"),
        force: false,
    };
    let err = run_pipeline(&request, &Silent).unwrap_err().to_string();
    assert!(err.contains("smirl_machine"), "{err}");
    assert!(!tmp.path().join("run").exists());
}

/// A control's schedule is its baseline's table (no table of its own).
#[test]
fn a_control_runs_its_baselines_schedule() {
    let c = smirl::pipeline::reacher_irl::IrlRunConfig::standard();
    for (control, base) in [
        (Algo::MaxEntProduct, Algo::MaxEnt),
        (Algo::FklProduct, Algo::Fkl),
    ] {
        let (a, b) = (c.for_algo(control).unwrap(), c.for_algo(base).unwrap());
        assert_eq!(a, b, "{control}");
        assert_ne!(a.irl_iterations, c.irl_iterations, "the table applies");
    }
}

/// A control's job plays its rollouts and evaluations in lockstep (the learned machine has no
/// goal or failure state, so the product ends episodes at the time limit only and can be
/// copied), and what it gives does not depend on how: batch 1 or 32 on one thread, or 32 on
/// two threads, give the same record, reward and log bytes.
///
/// Mutations tried: the product's `JobEnv::fresh` returning `None` (its rollouts one at a time,
/// as before): fails at the first assertion; lockstep play reading each step's noise at the
/// slot's index instead of the episode's (`play_on_thread`): fails at "maxent-product, batch
/// 32: record".
#[test]
fn a_controls_job_is_the_same_whatever_its_lockstep_plan() {
    let tmp = tempfile::tempdir().unwrap();
    let mut config = tiny_config();
    config.agent_trajectories = 5;
    let request = RunRequest {
        task: ReacherTask::shipped("blue").unwrap(),
        algos: Algo::REACHER_CONTROLS.to_vec(),
        seeds: 1,
        seed: 5,
        config,
        out: tmp.path().join("run.unused"),
        force: false,
    };
    prepare(&request, &tmp.path().join("run"), &Silent).unwrap();
    let run = open_run(&tmp.path().join("run")).unwrap();
    let learned = run.learned.clone().expect("the controls' machine");
    let inner = ReacherDelivery::new(run.config.env.clone()).unwrap();
    let product = ProductEnv::new(inner, learned);
    assert!(product.ends_only_at_time_limit() && product.fresh().is_some());

    let (one, two) = (|| 1, || 2);
    let plans = [
        (
            "batch 1",
            Lockstep {
                batch: 1,
                threads: &one,
            },
        ),
        (
            "batch 32",
            Lockstep {
                batch: 32,
                threads: &one,
            },
        ),
        (
            "batch 32, 2 threads",
            Lockstep {
                batch: 32,
                threads: &two,
            },
        ),
    ];
    for algo in Algo::REACHER_CONTROLS {
        let settings = run.config.for_algo(algo).unwrap();
        let dir = |k: usize| tmp.path().join(format!("{algo}-{k}"));
        let reference = job_bytes(&run, algo, 5, &settings, plans[0].1, &dir(0));
        for (k, (what, plan)) in plans.iter().enumerate().skip(1) {
            let other = job_bytes(&run, algo, 5, &settings, *plan, &dir(k));
            assert_eq!(reference.record, other.record, "{algo}, {what}: record");
            assert!(reference.reward == other.reward, "{algo}, {what}: reward");
            assert!(reference.log == other.log, "{algo}, {what}: log");
        }
    }
}
