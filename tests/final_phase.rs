//! The final phase every algorithm with a learned reward shares and its random pick (issue 54,
//! item 4: what is not specific to reward machines goes to every algorithm).

mod irl_run_common;
use irl_run_common::{metrics_column, tiny_config};
use smirl::env::reacher_task::ReacherTask;
use smirl::pipeline::reacher_irl::final_policy::random_pick;
use smirl::pipeline::reacher_irl::records::JobRecord;
use smirl::pipeline::reacher_irl::run::Silent;
use smirl::pipeline::reacher_irl::{run_pipeline, Algo, IrlRunConfig, RunRequest};
use std::path::{Path, PathBuf};

const SEED: u64 = 5;

/// One `algo` job on task "blue" (base seed [`SEED`]) with `config`: the temporary directory,
/// the run directory and the job's record.
fn tiny_run(algo: Algo, config: IrlRunConfig) -> (tempfile::TempDir, PathBuf, JobRecord) {
    let tmp = tempfile::tempdir().unwrap();
    let request = RunRequest {
        task: ReacherTask::shipped("blue").unwrap(),
        algos: vec![algo],
        seeds: 1,
        seed: SEED,
        config,
        out: tmp.path().join("run"),
        force: false,
    };
    run_pipeline(&request, &Silent).unwrap();
    let dir = tmp.path().join("run");
    let record = read_record(&dir, algo);
    (tmp, dir, record)
}

fn read_record(dir: &Path, algo: Algo) -> JobRecord {
    let path = dir.join(format!("jobs/{}_seed{SEED}.json", algo.name()));
    serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

/// A baseline (maxent) runs the final phase: the co-trained policy and two checkpoints; the
/// chosen candidate has the highest learned return, the random pick is one of
/// the candidates and is [`random_pick`] of the job's seed; metrics.csv shows the loop's own,
/// the chosen and the randomly picked policy side by side on the job's last row, and the
/// summary too.
///
/// Mutations tried: `firl::train` without its final phase (`final_policy: None`): fails at
/// "maxent has a final phase"; `choose` keeping the first candidate of *lowest* return (`<`
/// for `>`): fails at "the chosen candidate has the highest learned return".
#[test]
fn a_baseline_runs_the_final_phase_and_chooses_by_its_learned_return() {
    let config = tiny_config();
    let (_tmp, dir, record) = tiny_run(Algo::MaxEnt, config.clone());
    let f = record
        .final_policy
        .as_ref()
        .expect("maxent has a final phase");
    assert_eq!(f.candidates.len(), 1 + config.final_checkpoints as usize);
    let best = (f.candidates.iter())
        .map(|c| c.learned_return)
        .fold(f64::NEG_INFINITY, f64::max);
    assert_eq!(
        f.chosen().learned_return,
        best,
        "the chosen candidate has the highest learned return"
    );
    // The learned returns differ between candidates: they are read, not constant.
    assert!(
        f.candidates
            .iter()
            .any(|c| c.learned_return != f.candidates[0].learned_return),
        "{f:?}"
    );
    let random = f.random.expect("a random pick");
    assert!(random < f.candidates.len());
    assert_eq!(random, random_pick(SEED, f.candidates.len()));
    // The co-trained candidate is the loop's last policy.
    let last = record.rows.last().unwrap();
    assert_eq!(f.candidates[0].success_rate, last.success_rate);
    assert_eq!(f.candidates[0].env_steps, last.env_steps);

    let metrics = std::fs::read_to_string(dir.join("metrics.csv")).unwrap();
    let chosen = metrics_column(&metrics, "chosen_success_rate");
    let picked = metrics_column(&metrics, "random_success_rate");
    let n = chosen.len();
    assert!(chosen[..n - 1].iter().all(String::is_empty), "{metrics}");
    assert_eq!(chosen[n - 1], format!("{}", f.chosen().success_rate));
    assert_eq!(
        picked[n - 1],
        format!("{}", f.candidates[random].success_rate)
    );
    let summary = std::fs::read_to_string(dir.join("summary.md")).unwrap();
    assert!(
        summary.contains("| loop's own policy | chosen | random pick |"),
        "{summary}"
    );
    let table = std::fs::read_to_string(dir.join("final_policy.csv")).unwrap();
    let random_col = (table.lines().next().unwrap().split(','))
        .position(|h| h == "random")
        .expect("final_policy.csv has a random column");
    let marked: Vec<usize> = (table.lines().skip(1).enumerate())
        .filter(|(_, l)| l.split(',').nth(random_col) == Some("1"))
        .map(|(i, _)| i)
        .collect();
    assert_eq!(marked, vec![random], "{table}");
}

/// The random pick: deterministic per (seed, count), always a candidate, and not a constant
/// (over seeds it reaches every index).
///
/// Mutation tried: `random_pick` returning `n - 1`: fails at "every index is drawn".
#[test]
fn the_random_pick_is_deterministic_and_among_the_candidates() {
    for n in 1..12 {
        let mut seen = vec![false; n];
        for seed in 0..200 {
            let k = random_pick(seed, n);
            assert!(k < n);
            assert_eq!(k, random_pick(seed, n));
            seen[k] = true;
        }
        assert!(seen.iter().all(|&s| s), "every index is drawn for n = {n}");
    }
}
