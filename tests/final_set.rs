//! The final set (docs/algorithms.md, "Final set"): the loop's final policy and every
//! final-phase candidate are judged on episodes of their own — reset seeds disjoint from the
//! per-iteration evaluation's and the selection episodes', as many per branch as
//! `final_set_episodes` says, stratified by the event schedule also on tasks with another
//! event, two events or none — and the judgement does not steer: the job's training and
//! choice are bit for bit the same without it.

mod irl_run_common;
use irl_run_common::tiny_config;
use smirl::env::reacher::{ReacherConfig, ReacherDelivery, OBS_TIP};
use smirl::env::reacher_task::ReacherTask;
use smirl::env::ContinuousEnv;
use smirl::irl::kde::Kde;
use smirl::irl::reward::RewardModel;
use smirl::pipeline::reacher_irl::evaluation::FinalSetScore;
use smirl::pipeline::reacher_irl::evaluation::{
    final_set_episodes, stratified_eval_seeds, GroundTruth, JobWatch, FINAL_SET_EPISODES,
};
use smirl::pipeline::reacher_irl::final_policy::{
    selection_episodes, selection_seeds, FinalPolicy,
};
use smirl::pipeline::reacher_irl::firl::{self as firl_job, BaselineJob, Loss, StateMap};
use smirl::pipeline::reacher_irl::records::PreparedRun;
use smirl::pipeline::reacher_irl::run::{open_run, prepare, Silent};
use smirl::pipeline::reacher_irl::smirl::{self as smirl_job, Features, SmirlJob};
use smirl::pipeline::reacher_irl::{Algo, IrlRunConfig, MetricsRow, RunRequest};
use smirl::rm::format::parse_rm;
use smirl::rm::RewardMachine;
use std::collections::HashSet;
use std::path::{Path, PathBuf};

const SEED: u64 = 3;

#[test]
fn final_set_sizes_are_as_documented() {
    let standard = IrlRunConfig::standard();
    assert_eq!(standard.eval_episodes, 20);
    assert_eq!(final_set_episodes(&standard), FINAL_SET_EPISODES);
    assert_eq!(final_set_episodes(&IrlRunConfig::quick()), 20);
    assert_eq!(final_set_episodes(&tiny_config()), 5); // ⌈50 · 2 / 20⌉
    let mut c = tiny_config();
    c.eval_episodes = 3;
    assert_eq!(final_set_episodes(&c), 8); // ⌈7.5⌉
}

/// On a conditional task (IF) the final set has `final_set_episodes` per branch, on a task
/// without branches (OR) that many in all; its seeds are none of the evaluation's or the
/// selection episodes'.
#[test]
fn final_set_seeds_are_their_own_and_counted_per_branch() {
    let settings = IrlRunConfig::standard();
    let n = final_set_episodes(&settings);
    for (name, per_task) in [("if", 2 * n), ("or", n)] {
        let task = ReacherTask::shipped(name).unwrap();
        let perfect = task.perfect_rm().unwrap();
        let mut env = task.make_env(&ReacherConfig::default()).unwrap();
        for seed in [0, 3, 17, 105] {
            let eval = GroundTruth::new(&perfect, &mut env, seed, settings.eval_episodes);
            let final_set = GroundTruth::final_set(&perfect, &mut env, seed, n);
            let fs: HashSet<u64> = final_set.reset_seeds().iter().copied().collect();
            assert_eq!(final_set.reset_seeds().len() as u64, per_task, "{name}");
            assert_eq!(fs.len() as u64, per_task, "{name}: distinct seeds");
            let ev: HashSet<u64> = eval.reset_seeds().iter().copied().collect();
            let sel: HashSet<u64> = selection_seeds(seed, selection_episodes(&settings))
                .into_iter()
                .collect();
            assert!(
                fs.is_disjoint(&ev),
                "{name} seed {seed}: final set ∩ evaluation"
            );
            assert!(
                fs.is_disjoint(&sel),
                "{name} seed {seed}: final set ∩ selection"
            );
        }
    }
}

fn new_task(file: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("assets/tasks/new")
        .join(file)
}

/// `per_branch` seeds with some declared event scheduled and `per_branch` with none, for a
/// task whose events are not IF's cancel: Switch (its event `s`), Switch with a second event,
/// and (filled from the stream) a task without events.
#[test]
fn stratified_seeds_hold_for_other_events_two_events_and_none() {
    let tmp = tempfile::tempdir().unwrap();
    let switch = std::fs::read_to_string(new_task("switch.toml")).unwrap();
    let machine = std::fs::read_to_string(new_task("switch.txt")).unwrap();
    // Switch with a second event `t` (label bit after `s`), which its machine ignores.
    std::fs::write(
        tmp.path().join("two.toml"),
        switch.replace("switch.txt", "two.txt")
            + "\n[[event]]\nletter = \"t\"\nprobability = 0.5\nearliest_step = 1\nlatest_step = 8\n",
    )
    .unwrap();
    std::fs::write(
        tmp.path().join("two.txt"),
        machine.replace("vocabulary: rgbys", "vocabulary: rgbyst"),
    )
    .unwrap();
    // No event: touch green, then red.
    let head = switch.split("[[event]]").next().unwrap();
    std::fs::write(
        tmp.path().join("none.toml"),
        head.replace("switch.txt", "none.txt"),
    )
    .unwrap();
    std::fs::write(
        tmp.path().join("none.txt"),
        "vocabulary: rgby\nstates: 4\ninitial: 0\nterminal: 2\nfailure: 3\n\
         (0, 1, 'g', 0)\n(1, 2, 'r', 1)\n",
    )
    .unwrap();
    let per_branch = 20;
    for (path, events, branches) in [
        (new_task("switch.toml"), 1, true),
        (tmp.path().join("two.toml"), 2, true),
        (tmp.path().join("none.toml"), 0, false),
    ] {
        let task = ReacherTask::resolve(path.to_str().unwrap()).unwrap();
        let mut env = task.make_env(&ReacherConfig::default()).unwrap();
        let mut obs = vec![0.0f32; env.obs_dim()];
        env.reset(1, &mut obs);
        assert_eq!(env.event_steps().len(), events, "{}", path.display());
        let seeds = stratified_eval_seeds(&mut env, 42, per_branch);
        assert_eq!(seeds.len() as u64, 2 * per_branch, "{}", path.display());
        assert_eq!(seeds.iter().collect::<HashSet<_>>().len(), seeds.len());
        let scheduled = seeds
            .iter()
            .filter(|&&s| {
                env.reset(s, &mut obs);
                env.event_steps().iter().any(Option::is_some)
            })
            .count() as u64;
        let expected = if events > 0 { per_branch } else { 0 };
        assert_eq!(scheduled, expected, "{}", path.display());
        // The final set: per branch where the perfect machine has an event branch, else in all.
        let perfect = task.perfect_rm().unwrap();
        let final_set = GroundTruth::final_set(&perfect, &mut env, SEED, per_branch);
        assert_eq!(final_set.task().branches.is_some(), branches);
        let total = if branches { 2 * per_branch } else { per_branch };
        assert_eq!(
            final_set.reset_seeds().len() as u64,
            total,
            "{}",
            path.display()
        );
    }
}

/// A SMIRL job on IF, its watch with and without the final set: the same
/// metrics rows, reward, trace, candidates (but their final-set scores) and choice bit for
/// bit; with it, the loop's final policy and every candidate are judged on
/// 2 · `final_set_episodes` episodes, and candidate 0 (the same policy as the loop's last)
/// scores what the loop's does. The job file of `reacher job` records the same.
#[test]
fn the_final_judgement_does_not_steer_the_job() {
    let config = tiny_config();
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("run");
    let request = RunRequest {
        task: ReacherTask::shipped("if").unwrap(),
        algos: vec![Algo::Smirl],
        seeds: 1,
        seed: SEED,
        config,
        out: tmp.path().join("unused"),
        force: false,
    };
    prepare(&request, &dir, &Silent).unwrap();
    let run = open_run(&dir).unwrap();
    let s = &run.config;
    let (learned, expert) = run.inputs_of(Algo::Smirl).unwrap();
    let job = SmirlJob {
        features: Features::Labels,
        seed: SEED,
        settings: s,
        machine: learned.unwrap(),
        expert,
    };
    let n = final_set_episodes(s);
    let progress = |_| {};
    let go = |with_final_set: bool| {
        let kde =
            Kde::fit_columns(&expert.obs, expert.obs_dim(), &OBS_TIP, s.kde_bandwidth).unwrap();
        let mut schedule = ReacherDelivery::new(s.env.clone()).unwrap();
        let ground_truth = GroundTruth::new(&run.perfect, &mut schedule, SEED, s.eval_episodes);
        let mut watch = JobWatch::new(
            s,
            s.final_sac_steps,
            ground_truth,
            &run.perfect,
            kde,
            None,
            &progress,
        );
        if with_final_set {
            let final_set = GroundTruth::final_set(&run.perfect, &mut schedule, SEED, n);
            watch = watch.with_final_set(final_set);
        }
        let out = smirl_job::train(&job, &mut watch).unwrap();
        let loop_final_set = watch.loop_final_set();
        (
            out.reward.params(),
            out.trace,
            out.final_policy.unwrap(),
            loop_final_set,
            watch.into_rows(),
        )
    };
    let (params_a, trace_a, final_a, loop_a, rows_a) = go(false);
    let (params_b, trace_b, final_b, loop_b, rows_b) = go(true);
    assert_eq!(params_a, params_b, "reward");
    assert_eq!(trace_a, trace_b, "reward trace");
    assert_eq!(rows_a, rows_b, "metrics rows");
    assert_eq!(final_a.chosen, final_b.chosen, "choice");
    assert_eq!(final_a.random, final_b.random);
    assert!(loop_a.is_none() && final_a.candidates.iter().all(|c| c.final_set.is_none()));
    let mut stripped = final_b.clone();
    for c in &mut stripped.candidates {
        c.final_set = None;
    }
    assert_eq!(
        final_a, stripped,
        "candidates: steps, learned returns, evaluation"
    );
    let loop_b = loop_b.expect("the loop's final policy on the final set");
    assert_eq!(loop_b.episodes, 2 * n);
    let branches = loop_b.branches.expect("IF has branches");
    assert_eq!(branches.episodes.iter().sum::<u64>(), 2 * n);
    for c in &final_b.candidates {
        assert_eq!(c.final_set.unwrap().episodes, 2 * n);
    }
    assert_eq!(final_b.candidates[0].final_set, Some(loop_b));

    // `reacher job`'s record and final_policy.csv carry them.
    let (record, _) = run.run_job(Algo::Smirl, SEED, &|| 1, &|_| {}).unwrap();
    assert_eq!(record.loop_final_set, Some(loop_b));
    assert_eq!(record.final_policy.as_ref(), Some(&final_b));
    assert_eq!(record.rows, rows_b);
    let json = std::fs::read_to_string(dir.join(format!("jobs/smirl_seed{SEED}.json"))).unwrap();
    assert!(json.contains("\"loop_final_set\""));
}

/// What a job trains and chooses, and what its final set says.
struct Watched {
    reward: Vec<f32>,
    /// SMIRL's reward trace: per iteration, (iteration, data gradient, weights).
    trace: Vec<(usize, Vec<f32>, Vec<f32>)>,
    rows: Vec<MetricsRow>,
    final_policy: FinalPolicy,
    loop_final_set: Option<FinalSetScore>,
}

/// `algo`'s job (smirl or maxent) of the prepared `run`, its watch judging the final set by
/// `perfect` on `per_branch` episodes per branch (the job's own watch: the run's perfect machine
/// and `final_set_episodes`).
fn watched(run: &PreparedRun, algo: Algo, perfect: &RewardMachine, per_branch: u64) -> Watched {
    let s = &run.config.for_algo(algo).unwrap();
    let (learned, expert) = run.inputs_of(algo).unwrap();
    let kde = Kde::fit_columns(&expert.obs, expert.obs_dim(), &OBS_TIP, s.kde_bandwidth).unwrap();
    let mut schedule = ReacherDelivery::new(s.env.clone()).unwrap();
    let ground_truth = GroundTruth::new(&run.perfect, &mut schedule, SEED, s.eval_episodes);
    let final_set = GroundTruth::final_set(perfect, &mut schedule, SEED, per_branch);
    let progress = |_| {};
    let mut watch = JobWatch::new(
        s,
        s.final_sac_steps,
        ground_truth,
        &run.perfect,
        kde,
        None,
        &progress,
    )
    .with_final_set(final_set);
    let (reward, trace, final_policy) = match algo {
        Algo::Smirl => {
            let job = SmirlJob {
                features: Features::Labels,
                seed: SEED,
                settings: s,
                machine: learned.unwrap(),
                expert,
            };
            let out = smirl_job::train(&job, &mut watch).unwrap();
            let trace = (out.trace.iter())
                .map(|r| (r.iteration, r.data_gradient.clone(), r.weights.clone()))
                .collect();
            (out.reward.params(), trace, out.final_policy)
        }
        Algo::MaxEnt => {
            let job = BaselineJob {
                loss: Loss::MaxEnt,
                seed: SEED,
                settings: s,
                expert,
                map: StateMap::Fingertip,
            };
            let out = firl_job::train(&job, &mut watch).unwrap();
            (out.reward.params(), Vec::new(), out.final_policy)
        }
        other => panic!("{other}: not a case of this test"),
    };
    Watched {
        reward,
        trace,
        loop_final_set: watch.loop_final_set(),
        rows: watch.into_rows(),
        final_policy: final_policy.expect("a final phase"),
    }
}

/// `a` and `b` trained, were evaluated per iteration and chose bit for bit alike: they differ
/// at most in what the final set says (the loop's final policy's and each candidate's
/// `final_set`, the `final_set_*` columns of final_policy.csv).
fn assert_same_but_final_set(what: &str, a: &Watched, b: &Watched) {
    assert_eq!(a.reward, b.reward, "{what}: reward");
    assert_eq!(a.trace, b.trace, "{what}: reward trace");
    assert_eq!(a.rows, b.rows, "{what}: metrics rows");
    let strip = |f: &FinalPolicy| {
        let mut f = f.clone();
        for c in &mut f.candidates {
            assert!(c.final_set.is_some(), "{what}: every candidate is judged");
            c.final_set = None;
        }
        f
    };
    assert_eq!(
        strip(&a.final_policy),
        strip(&b.final_policy),
        "{what}: candidates (steps, learned and cut returns, evaluation), choice, random pick"
    );
}

/// The final set does not reach training or selection, whatever it holds: a SMIRL job and a
/// baseline's (maxent) on IF with the job's own final set (the perfect machine,
/// `final_set_episodes` = 5 per branch), with three times as many episodes and one more per
/// branch (a superset: the same stratified stream read further), and with the final set judged
/// by another machine (Sequential's, no cancel branch: 5 episodes unstratified, other seeds).
/// Reward, trace, metrics rows, candidates' learned and cut returns, ground-truth
/// evaluation, choice and random pick are bit-identical; only the final-set scores differ (in
/// their episode counts at least).
///
/// No config setting changes the final set alone: its size is `final_set_episodes`, a function
/// of `eval_episodes`, which also sets the per-iteration evaluation and the selection
/// episodes (`selection_episodes` = 2 · `eval_episodes`); so the watch is given the final set
/// directly, as `job::run_job` gives it.
///
/// Mutation tried (a leak): the candidates' learned return plus their final-set progress
/// (`learned_return + final_set.map_or(0.0, |f| f.progress)` in `final_policy::candidate`):
/// fails at "smirl, a larger final set: candidates …" (candidate 2's learned return).
#[test]
fn the_final_sets_size_and_machine_reach_neither_training_nor_the_choice() {
    let config = tiny_config();
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("run");
    let request = RunRequest {
        task: ReacherTask::shipped("if").unwrap(),
        algos: vec![Algo::Smirl, Algo::MaxEnt],
        seeds: 1,
        seed: SEED,
        config,
        out: tmp.path().join("unused"),
        force: false,
    };
    prepare(&request, &dir, &Silent).unwrap();
    let run = open_run(&dir).unwrap();
    let n = final_set_episodes(&run.config);
    assert_eq!(n, 5);
    let sequential = parse_rm(
        &std::fs::read_to_string(
            Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/rm/reacher_sequential.txt"),
        )
        .unwrap(),
        "sequential",
    )
    .unwrap();
    for algo in [Algo::Smirl, Algo::MaxEnt] {
        let own = watched(&run, algo, &run.perfect, n);
        let larger = watched(&run, algo, &run.perfect, 3 * n + 1);
        let other = watched(&run, algo, &sequential, n);
        assert_same_but_final_set(&format!("{algo}, a larger final set"), &own, &larger);
        assert_same_but_final_set(&format!("{algo}, another machine's"), &own, &other);
        let episodes = |w: &Watched| {
            let mut e = vec![w.loop_final_set.unwrap().episodes];
            (w.final_policy.candidates.iter()).for_each(|c| e.push(c.final_set.unwrap().episodes));
            e
        };
        let k = own.final_policy.candidates.len() + 1;
        assert_eq!(episodes(&own), vec![2 * n; k], "{algo}");
        assert_eq!(episodes(&larger), vec![2 * (3 * n + 1); k], "{algo}");
        assert_eq!(episodes(&other), vec![n; k], "{algo}");
        assert!(other.loop_final_set.unwrap().branches.is_none(), "{algo}");
        // The job's own watch is this one: `reacher job` records what `own` found.
        if algo == Algo::MaxEnt {
            let (record, _) = run.run_job(algo, SEED, &|| 1, &|_| {}).unwrap();
            assert_eq!(record.rows, own.rows, "{algo}: the job's rows");
            assert_eq!(record.loop_final_set, own.loop_final_set, "{algo}");
            assert_eq!(
                record.final_policy.as_ref(),
                Some(&own.final_policy),
                "{algo}"
            );
        }
    }
}
