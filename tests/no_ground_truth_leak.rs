//! No ground truth reaches SMIRL's learner — nor a baseline's — its selection or its stopping (GUIDE, "Science";
//! issue 54, item 6): a job run on a prepared directory whose perfect machine — the task's
//! ground truth, read by the job from `rm/perfect.txt` and nowhere else — is replaced by
//! another, with other rewards, learns bit for bit the same reward (weights and data gradient
//! of every iteration), the same learned returns of every final-policy candidate and the same
//! choice, while its evaluation changes. The learned machine and the annotated demonstrations
//! are `reacher prepare`'s (`rm/learned.txt`, `expert_data.bin`), and the job reads them from
//! the directory. Prepare's learner reads the demonstrations' label traces only: a perfect
//! machine that makes the same demonstrations (other rewards, a state no episode reaches)
//! gives the same learned machine and annotated demonstrations, bit for bit. The perfect
//! machine does make the demonstrations, as a demonstrator's task would: an expert episode
//! ends at its goal or failure and a failed one is dropped.
//!
//! Every algorithm the evaluation runs is covered: smirl, smirl-paper, the baselines maxent,
//! fkl, rkl and js, the product controls maxent-product and fkl-product, and the one-state
//! control (`smirl` with `[smirl] machine = "one_state"`). The perturbed machine changes the
//! task's structure and its rewards (the true reward a job's `task_return` sums) alike.

mod irl_run_common;
use irl_run_common::tiny_config;
use smirl::env::reacher_task::ReacherTask;
use smirl::pipeline::reacher_irl::records::JobRecord;
use smirl::pipeline::reacher_irl::run::{open_run, prepare, Silent};
use smirl::pipeline::reacher_irl::{Algo, IrlRunConfig, RunRequest, SmirlMachine};
use smirl::rm::format::parse_rm;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

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

/// The standard mechanisms at test size: CRM, a final phase, a rollout log.
fn config() -> IrlRunConfig {
    let c = tiny_config();
    assert!(c.counterfactual() > 0.0);
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
    assert_eq!(a.final_policy.is_some(), b.final_policy.is_some());
    let (Some(fa), Some(fb)) = (a.final_policy.as_ref(), b.final_policy.as_ref()) else {
        // smirl-paper: no final phase, the loop's own last policy is the job's.
        let rows = |r: &JobRecord| -> Vec<(u64, u64)> {
            (r.rows.iter())
                .map(|x| (x.success_rate.to_bits(), x.task_return.to_bits()))
                .collect()
        };
        assert_ne!(rows(a), rows(b), "the evaluation rows did not change");
        return;
    };
    assert!(fa.candidates.len() >= 3, "co-trained, 2 checkpoints");
    assert_eq!(fa.candidates.len(), fb.candidates.len());
    for (k, (ca, cb)) in fa.candidates.iter().zip(&fb.candidates).enumerate() {
        let scored = |c: &smirl::pipeline::reacher_irl::final_policy::FinalCandidate| {
            (c.env_steps, c.learned_return.to_bits())
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
/// per-iteration learned reward and surrogate loss, candidates' learned returns and choice;
/// different success rates and task returns.
///
/// Mutations tried (each a leak): the candidates' learned return reading their ground-truth
/// success (`learned_return + ev.success_rate` in `final_policy::candidate`): fails at
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

/// Copies the tree `from` to `to`.
fn copy_dir(from: &Path, to: &Path) {
    std::fs::create_dir_all(to).unwrap();
    for entry in std::fs::read_dir(from).unwrap() {
        let entry = entry.unwrap();
        let target = to.join(entry.file_name());
        if entry.file_type().unwrap().is_dir() {
            copy_dir(&entry.path(), &target);
        } else {
            std::fs::copy(entry.path(), &target).unwrap();
        }
    }
}

/// A run prepared once on IF and its copy judged by [`PERTURBED_CONDITIONAL`]: the two
/// directories every job of `algos` runs in, side by side.
struct PreparedPair {
    truth: PathBuf,
    perturbed: PathBuf,
}

impl PreparedPair {
    /// Prepares `algos` with `config` in `<CARGO_TARGET_TMPDIR>/no_ground_truth_leak/<name>`
    /// (replacing what an earlier test run left there), then copies it and replaces the copy's
    /// perfect machine.
    fn new(name: &str, algos: Vec<Algo>, config: IrlRunConfig) -> PreparedPair {
        let root = Path::new(env!("CARGO_TARGET_TMPDIR"))
            .join("no_ground_truth_leak")
            .join(name);
        if root.exists() {
            std::fs::remove_dir_all(&root).unwrap();
        }
        let (truth, perturbed) = (root.join("true"), root.join("perturbed"));
        let request = RunRequest {
            task: ReacherTask::shipped("if").unwrap(),
            algos,
            seeds: 1,
            seed: SEED,
            config,
            out: root.join("unused"),
            force: false,
        };
        prepare(&request, &truth, &Silent).unwrap();
        copy_dir(&truth, &perturbed);
        std::fs::write(perturbed.join("rm/perfect.txt"), PERTURBED_CONDITIONAL).unwrap();
        PreparedPair { truth, perturbed }
    }
}

/// Every algorithm of the evaluation not tested above, prepared once (the standard mechanisms
/// at test size, [`config`]).
///
/// Mutation tried on the tests of every algorithm with a final phase below (fkl, rkl, js,
/// maxent-product, the one-state control): the candidates' learned return plus their
/// ground-truth success (`learned_return + ev.success_rate` in `final_policy::candidate`): each
/// fails at "candidate 0". The one-state control's test also fails with the rollouts ending
/// when the perfect machine decides (`stop_when_decided: true` in `RolloutStream::collect`),
/// at "rewards/smirl_seed3.json differs".
fn evaluated_algorithms() -> &'static PreparedPair {
    static PAIR: OnceLock<PreparedPair> = OnceLock::new();
    PAIR.get_or_init(|| {
        let algos = vec![
            Algo::SmirlPaper,
            Algo::Fkl,
            Algo::Rkl,
            Algo::Js,
            Algo::MaxEntProduct,
        ];
        PreparedPair::new("algorithms", algos, config())
    })
}

/// The one-state control: `smirl` with `[smirl] machine = "one_state"` (as
/// experiments/reacher/config_one_state.toml runs it) and every other setting [`config`]'s.
fn one_state_control() -> &'static PreparedPair {
    static PAIR: OnceLock<PreparedPair> = OnceLock::new();
    PAIR.get_or_init(|| {
        let mut c = config();
        c.smirl_machine = SmirlMachine::OneState;
        PreparedPair::new("one_state", vec![Algo::Smirl], c)
    })
}

/// What a job of `algo` reads that no ground truth may change (its learned machine and
/// demonstrations) and what it writes (its reward, and SMIRL's trace of weights and data
/// gradients).
fn files_of(algo: Algo) -> Vec<String> {
    let stem = format!("{}_seed{SEED}", algo.name());
    let mut files = vec![];
    match algo {
        Algo::SmirlPaper => files.extend([
            "rm/learned_paper.txt".to_string(),
            "expert_data_paper.bin".to_string(),
        ]),
        a if a.uses_rm() || a.is_product_control() => files.push("rm/learned.txt".into()),
        _ => {}
    }
    files.push("expert_data.bin".into());
    if algo.uses_rm() {
        files.push(format!("rewards/{stem}.json"));
        files.push(format!("rewards/{stem}.trace.csv"));
    } else {
        files.push(format!("rewards/{stem}.bin"));
    }
    files
}

/// Runs `algo`'s job in both directories of `pair`: the learned machine, the demonstrations,
/// the reward (and trace), every iteration's learned reward and surrogate loss, the
/// candidates' learned returns, the choice and the random pick bit-identical; the evaluation
/// different. Returns the true job's record.
fn assert_no_leak(pair: &PreparedPair, algo: Algo) -> JobRecord {
    let files = files_of(algo);
    let run = |dir: &Path| {
        let run = open_run(dir).unwrap();
        let (record, ran) = run.run_job(algo, SEED, &|| 1, &|_| {}).unwrap();
        assert!(ran, "{algo}: a record from an earlier run");
        let bytes: Vec<Vec<u8>> = (files.iter())
            .map(|f| std::fs::read(dir.join(f)).unwrap())
            .collect();
        (run.perfect, record, bytes)
    };
    let (perfect_a, a, files_a) = run(&pair.truth);
    let (perfect_b, b, files_b) = run(&pair.perturbed);
    assert_eq!(
        perfect_b,
        parse_rm(PERTURBED_CONDITIONAL, "perturbed").unwrap()
    );
    assert_ne!(perfect_a, perfect_b);
    for (k, (fa, fb)) in files_a.iter().zip(&files_b).enumerate() {
        assert!(fa == fb, "{algo}: {} differs", files[k]);
    }
    assert_eq!(
        a.final_policy.is_some(),
        algo != Algo::SmirlPaper,
        "{algo}: every algorithm but smirl-paper has a final phase"
    );
    assert_same_learning_other_evaluation(&a, &b);
    a
}

/// smirl-paper (its own learned machine and annotated demonstrations, no final phase: its
/// loop's last policy is the job's) on IF against the same job judged by
/// [`PERTURBED_CONDITIONAL`].
///
/// Mutation tried (a leak): the reward update's rollouts ending when the perfect machine
/// decides (`stop_when_decided: true` in `RolloutStream::collect`): fails at
/// "rewards/smirl-paper_seed3.json differs".
#[test]
fn perturbing_the_perfect_machine_leaves_smirl_papers_learning_unchanged() {
    assert_no_leak(evaluated_algorithms(), Algo::SmirlPaper);
}

/// fkl (f-IRL, forward KL) on IF against the same job judged by [`PERTURBED_CONDITIONAL`].
#[test]
fn perturbing_the_perfect_machine_leaves_fkls_learning_and_choice_unchanged() {
    assert_no_leak(evaluated_algorithms(), Algo::Fkl);
}

/// rkl (f-IRL, reverse KL) on IF against the same job judged by [`PERTURBED_CONDITIONAL`].
#[test]
fn perturbing_the_perfect_machine_leaves_rkls_learning_and_choice_unchanged() {
    assert_no_leak(evaluated_algorithms(), Algo::Rkl);
}

/// js (f-IRL, Jensen–Shannon) on IF against the same job judged by [`PERTURBED_CONDITIONAL`].
#[test]
fn perturbing_the_perfect_machine_leaves_jss_learning_and_choice_unchanged() {
    assert_no_leak(evaluated_algorithms(), Algo::Js);
}

/// The other product control, maxent-product (MaxEnt on the product with SMIRL's learned
/// machine), on IF against the same job judged by [`PERTURBED_CONDITIONAL`].
#[test]
fn perturbing_the_perfect_machine_leaves_maxent_products_learning_and_choice_unchanged() {
    assert_no_leak(evaluated_algorithms(), Algo::MaxEntProduct);
}

/// The one-state control (`smirl`, `[smirl] machine = "one_state"`) on IF against the same job
/// judged by [`PERTURBED_CONDITIONAL`]: its machine has one state (no structure from anywhere,
/// the perfect machine included), and its learning and choice are bit-identical.
#[test]
fn perturbing_the_perfect_machine_leaves_the_one_state_controls_learning_unchanged() {
    let pair = one_state_control();
    let learned = std::fs::read_to_string(pair.truth.join("rm/learned.txt")).unwrap();
    assert_eq!(parse_rm(&learned, "learned").unwrap().n_states(), 1);
    assert_no_leak(pair, Algo::Smirl);
}

/// IF's machine as it makes demonstrations (the same transitions, so the same scripted
/// episodes, ending at the same steps) but not as a learner could read it: other rewards (the
/// normal branch pays 7, the cancel branch 3.25), its states numbered otherwise (IF's 0, 1, 2,
/// 3, 4 are 2, 0, 5, 1, 3 here) and a state, 4, that no transition enters.
const PERTURBED_SAME_DEMONSTRATIONS: &str = "\
# Not a task of the paper: IF's machine with other rewards, states and a state no episode reaches.
vocabulary: rgbyc
states: 6
initial: 2
terminal: 1
failure: 3
(2, 5, 'c', 0.25)
(2, 0, 'b&!c', 2)
(0, 1, 'r', 5)
(5, 3, 'b&!c', -1)
(5, 1, 'r&!b', 3)
(4, 1, 'g', 9)
";

/// `reacher prepare` of IF and of a copy of IF's task file whose machine is
/// [`PERTURBED_SAME_DEMONSTRATIONS`], 8 scripted demonstrations over both branches: the
/// learned machines (smirl's and smirl-paper's) and the demonstrations as every learner reads
/// them (annotated with either machine) are the same, bit for bit. The demonstration logs
/// differ, as they should: a log records its task.
///
/// Mutation tried (a leak into the training data): keeping only the demonstrations of the
/// highest true return (`d.success && d.task_return >= best` in `run::prepare`): the perturbed
/// run keeps no event-branch demonstration and fails at "both branches: [4, 0]".
#[test]
fn prepares_learner_reads_the_demonstrations_and_not_the_machine_that_made_them() {
    let tmp = tempfile::tempdir().unwrap();
    let assets = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets");
    let task_text = std::fs::read_to_string(assets.join("tasks/if.toml")).unwrap();
    let machine = tmp.path().join("perturbed_if.txt");
    std::fs::write(&machine, PERTURBED_SAME_DEMONSTRATIONS).unwrap();
    let copy_dir = tmp.path().join("task");
    std::fs::create_dir(&copy_dir).unwrap();
    let copy = copy_dir.join("if.toml");
    let pointed = task_text.replace(
        "machine = \"../rm/reacher_if.txt\"",
        &format!("machine = {:?}", machine.to_str().unwrap()),
    );
    assert_ne!(pointed, task_text, "the copy names the perturbed machine");
    std::fs::write(&copy, pointed).unwrap();
    let perturbed = ReacherTask::resolve(copy.to_str().unwrap()).unwrap();
    assert_eq!(perturbed.perfect_rm().unwrap().n_states(), 6);

    let prepared = |task: ReacherTask, dir: &Path| {
        let request = RunRequest {
            task,
            algos: vec![Algo::Smirl, Algo::SmirlPaper],
            seeds: 1,
            seed: SEED,
            config: IrlRunConfig {
                demo_episodes: 8,
                ..config()
            },
            out: dir.with_extension("unused"),
            force: false,
        };
        let prepared = prepare(&request, dir, &Silent).unwrap();
        let branches = prepared
            .demo_branches
            .expect("IF has an event branch")
            .episodes;
        assert!(
            branches.iter().all(|&n| n > 0),
            "both branches: {branches:?}"
        );
        [
            "rm/learned.txt",
            "rm/learned_paper.txt",
            "expert_data.bin",
            "expert_data_paper.bin",
        ]
        .map(|f| (f, std::fs::read(dir.join(f)).unwrap()))
    };
    let truth = prepared(
        ReacherTask::shipped("if").unwrap(),
        &tmp.path().join("truth"),
    );
    let other = prepared(perturbed, &tmp.path().join("other"));
    for ((name, a), (_, b)) in truth.iter().zip(&other) {
        assert!(a == b, "{name} differs");
    }
}
