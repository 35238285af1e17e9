//! No ground truth reaches SMIRL's learner — nor a baseline's — its selection or its stopping (GUIDE, "Science";
//! issue 54, item 6): a job run on a prepared directory whose perfect machine — the task's
//! ground truth, read by the job from `rm/perfect.txt` and nowhere else — is replaced by
//! another, with other rewards, learns bit for bit the same reward (weights and data gradient
//! of every iteration), the same learned returns of every final-policy candidate and the same
//! choice, while its evaluation changes. The learned machine and the annotated demonstrations
//! are `reacher prepare`'s (`rm/learned.txt`, `expert_data.bin`): LRM reads the
//! demonstrations' label traces only (`smirl::learn_machine` takes no perfect machine), and
//! the job reads them from the directory.

mod irl_run_common;
use irl_run_common::tiny_config;
use smirl::env::reacher_task::ReacherTask;
use smirl::pipeline::reacher_irl::records::JobRecord;
use smirl::pipeline::reacher_irl::run::{open_run, prepare, Silent};
use smirl::pipeline::reacher_irl::{Algo, IrlRunConfig, RunRequest};
use smirl::rm::format::parse_rm;
use std::path::Path;

const SEED: u64 = 3;

/// What a SMIRL job reads or writes that no ground truth may change: the learned machine and
/// the annotated demonstrations (prepared), the learned reward and its trace (the job's).
const LEARNED_FILES: [&str; 4] = [
    "rm/learned.txt",
    "expert_data.bin",
    "rewards/smirl_seed3.json",
    "rewards/smirl_seed3.trace.csv",
];

/// The same for a baseline (maxent): the demonstrations it reads and the MLP reward it learns.
const BASELINE_FILES: [&str; 2] = ["expert_data.bin", "rewards/maxent_seed3.bin"];

/// The same for a product control (fkl-product): the learned machine it reads, the annotated
/// demonstrations and the MLP reward over (one-hot u, fingertip).
const PRODUCT_FILES: [&str; 3] = [
    "rm/learned.txt",
    "expert_data.bin",
    "rewards/fkl-product_seed3.bin",
];

/// Another task with a cancel branch (as IF's has), and other rewards: the episode succeeds,
/// with reward 7, on any first step without blue or the cancel; a cancel pays 0.5 and makes
/// blue a failure, red after it pays 3.
const PERTURBED_CONDITIONAL: &str = "\
# Not a task of the paper: IF's ground truth replaced in a no-leak test.
vocabulary: rgbyc
states: 4
initial: 0
terminal: 2
failure: 3
(0, 1, 'c', 0.5)
(0, 2, '!c&!b', 7)
(1, 3, 'b', 0)
(1, 2, 'r&!b', 3)
";

/// The standard mechanisms at test size: the event-gated normalisation, shaping, CRM, the clock,
/// a final phase with a reset agent and the selection cut (entries), a rollout log.
fn config() -> IrlRunConfig {
    let mut c = tiny_config();
    c.final_reset_steps = 140;
    let standard = IrlRunConfig::standard();
    assert_eq!(c.normalisation(), standard.normalisation());
    assert!(c.selection_cut() && c.clock());
    assert!(c.smirl_shaping > 0.0 && c.counterfactual() > 0.0);
    assert!(c.log_every_nth_episode > 0);
    c
}

/// Prepares task `task`'s SMIRL run in `dir`, replaces its perfect machine by `perfect` (when
/// given) and runs its job: the record and the files the job wrote.
fn job(task: ReacherTask, dir: &Path, perfect: Option<&str>) -> (JobRecord, Vec<Vec<u8>>) {
    job_of(Algo::Smirl, &LEARNED_FILES, task, dir, perfect)
}

/// [`job`] of `algo`, returning `files`.
fn job_of(
    algo: Algo,
    files: &[&str],
    task: ReacherTask,
    dir: &Path,
    perfect: Option<&str>,
) -> (JobRecord, Vec<Vec<u8>>) {
    let request = RunRequest {
        task,
        algos: vec![algo],
        seeds: 1,
        seed: SEED,
        config: config(),
        out: dir.with_extension("unused"),
        force: false,
    };
    prepare(&request, dir, &Silent).unwrap();
    if let Some(text) = perfect {
        std::fs::write(dir.join("rm/perfect.txt"), text).unwrap();
    }
    let run = open_run(dir).unwrap();
    if let Some(text) = perfect {
        assert_eq!(run.perfect, parse_rm(text, "perturbed").unwrap());
    }
    let (record, ran) = run.run_job(algo, SEED, &|| 1, &|_| {}).unwrap();
    assert!(ran);
    let files = files
        .iter()
        .map(|f| std::fs::read(dir.join(f)).unwrap())
        .collect();
    (record, files)
}

/// What the learner and its choice produce must be the same bit for bit; what the ground truth
/// says of it must differ.
fn assert_same_learning_other_evaluation(a: &JobRecord, b: &JobRecord) {
    assert_eq!(a.rows.len(), b.rows.len());
    for (ra, rb) in a.rows.iter().zip(&b.rows) {
        let learner = |r: &smirl::pipeline::reacher_irl::MetricsRow| {
            (
                r.env_steps,
                r.learned_reward.to_bits(),
                r.surrogate_loss.to_bits(),
                r.expert_support.map(f64::to_bits),
            )
        };
        assert_eq!(learner(ra), learner(rb), "iteration {}", ra.iteration);
    }
    let (fa, fb) = (
        a.final_policy.as_ref().unwrap(),
        b.final_policy.as_ref().unwrap(),
    );
    assert!(
        fa.candidates.len() >= 5,
        "co-trained, 2 checkpoints, 2 of the reset agent"
    );
    assert_eq!(fa.candidates.len(), fb.candidates.len());
    for (k, (ca, cb)) in fa.candidates.iter().zip(&fb.candidates).enumerate() {
        let scored = |c: &smirl::pipeline::reacher_irl::final_policy::FinalCandidate| {
            (
                c.agent,
                c.env_steps,
                c.learned_return.to_bits(),
                c.cut_return.map(f64::to_bits),
            )
        };
        assert_eq!(scored(ca), scored(cb), "candidate {k}");
    }
    assert_eq!(fa.chosen, fb.chosen, "the final choice");
    assert_eq!(fa.random, fb.random, "the random pick");
    // The perturbation took effect: the ground truth judged the same policies differently.
    let judged = |r: &JobRecord| {
        let rows: Vec<(u64, u64)> = (r.rows.iter())
            .map(|x| (x.success_rate.to_bits(), x.task_return.to_bits()))
            .collect();
        let finals: Vec<String> = (r.final_policy.as_ref().unwrap().candidates.iter())
            .map(|c| {
                let judged = (c.success_rate, c.progress, c.final_ball, &c.branches);
                format!("{judged:?}")
            })
            .collect();
        (rows, finals)
    };
    let (ja, jb) = (judged(a), judged(b));
    assert_ne!(ja.0, jb.0, "the evaluation rows did not change");
    assert_ne!(
        ja.1, jb.1,
        "the candidates' ground-truth evaluation did not change"
    );
}

/// IF's job against the same job judged by [`PERTURBED_CONDITIONAL`]: bit-identical learned
/// machine, expert data, reward file, reward trace (weights and data gradient per iteration),
/// per-iteration learned reward and surrogate loss, candidates' learned and cut returns and
/// choice; different success rates and task returns.
///
/// Mutations tried (each a leak): the selection's cut return reading the candidate's
/// ground-truth success (`cut_return + success_rate` in `final_policy::candidate`): fails at
/// "candidate 0"; the reward update's rollouts ending when the perfect machine decides
/// (`stop_when_decided: true` in `RolloutStream::collect`): fails at "rewards/smirl_seed3.json
/// differs".
#[test]
fn perturbing_the_perfect_machine_changes_the_evaluation_and_nothing_learned() {
    let tmp = tempfile::tempdir().unwrap();
    let (a, files_a) = job(
        ReacherTask::shipped("if").unwrap(),
        &tmp.path().join("true"),
        None,
    );
    let (b, files_b) = job(
        ReacherTask::shipped("if").unwrap(),
        &tmp.path().join("perturbed"),
        Some(PERTURBED_CONDITIONAL),
    );
    for (k, (fa, fb)) in files_a.iter().zip(&files_b).enumerate() {
        assert!(fa == fb, "{} differs", LEARNED_FILES[k]);
    }
    assert_same_learning_other_evaluation(&a, &b);
}

/// IF's job judged by Sequential's machine, a task without a cancel branch: the evaluation
/// plays half as many episodes, unstratified; the selection still plays its own
/// (`final_policy::selection_episodes`).
///
/// Regression: the selection played as many episodes as the ground-truth evaluation, so
/// whether the perfect machine has a cancel branch set the candidates' learned returns; on
/// main df9c858 (before `selection_episodes`) this test fails at "candidate 0".
#[test]
fn perturbing_the_perfect_machine_to_a_task_without_a_cancel_branch_changes_nothing_learned() {
    let tmp = tempfile::tempdir().unwrap();
    let sequential = std::fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/rm/reacher_sequential.txt"),
    )
    .unwrap();
    let (a, files_a) = job(
        ReacherTask::shipped("if").unwrap(),
        &tmp.path().join("true"),
        None,
    );
    let (b, files_b) = job(
        ReacherTask::shipped("if").unwrap(),
        &tmp.path().join("perturbed"),
        Some(&sequential),
    );
    for (k, (fa, fb)) in files_a.iter().zip(&files_b).enumerate() {
        assert!(fa == fb, "{} differs", LEARNED_FILES[k]);
    }
    assert_same_learning_other_evaluation(&a, &b);
}

/// A baseline (maxent, whose final phase runs the same routine as SMIRL's) on IF against the
/// same job judged by [`PERTURBED_CONDITIONAL`]: the demonstrations, the learned MLP reward,
/// every iteration's learned reward and surrogate loss, the candidates' learned returns, the
/// choice and the random pick bit-identical; the evaluation different.
///
/// Mutation tried (a leak): the candidates' learned return plus their ground-truth success
/// (`learned_return: learned_return + ev.success_rate` in `final_policy::candidate`): fails at
/// "candidate 3" (the first candidate the perturbed machine judges differently).
#[test]
fn perturbing_the_perfect_machine_leaves_a_baselines_learning_and_choice_unchanged() {
    let tmp = tempfile::tempdir().unwrap();
    let run = |name: &str, perfect: Option<&str>| {
        job_of(
            Algo::MaxEnt,
            &BASELINE_FILES,
            ReacherTask::shipped("if").unwrap(),
            &tmp.path().join(name),
            perfect,
        )
    };
    let (a, files_a) = run("true", None);
    let (b, files_b) = run("perturbed", Some(PERTURBED_CONDITIONAL));
    for (k, (fa, fb)) in files_a.iter().zip(&files_b).enumerate() {
        assert!(fa == fb, "{} differs", BASELINE_FILES[k]);
    }
    assert_same_learning_other_evaluation(&a, &b);
}

/// A product control (fkl-product: SMIRL's learned machine, the reward and the densities over
/// (one-hot u, fingertip)) on IF against the same job judged by [`PERTURBED_CONDITIONAL`]: the
/// learned machine, the demonstrations, the MLP reward, every iteration's learned reward and
/// surrogate loss, the candidates' learned returns and the choice bit-identical; the
/// evaluation different.
///
/// Mutation tried (a leak): the control's state map on the job's perfect machine instead of the
/// learned one (`StateMap::Product(perfect_rm)` in `job::run_job`): the job fails ("f-IRL needs
/// agent trajectories of one fixed length": the perfect machine's goal ends the product's
/// episodes).
#[test]
fn perturbing_the_perfect_machine_leaves_a_product_controls_learning_unchanged() {
    let tmp = tempfile::tempdir().unwrap();
    let run = |name: &str, perfect: Option<&str>| {
        job_of(
            Algo::FklProduct,
            &PRODUCT_FILES,
            ReacherTask::shipped("if").unwrap(),
            &tmp.path().join(name),
            perfect,
        )
    };
    let (a, files_a) = run("true", None);
    let (b, files_b) = run("perturbed", Some(PERTURBED_CONDITIONAL));
    for (k, (fa, fb)) in files_a.iter().zip(&files_b).enumerate() {
        assert!(fa == fb, "{} differs", PRODUCT_FILES[k]);
    }
    assert_same_learning_other_evaluation(&a, &b);
}
