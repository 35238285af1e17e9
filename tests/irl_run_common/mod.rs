//! The tiny IRL run configuration the pipeline tests share.

use smirl::env::reacher_task::ReacherTask;
use smirl::log::{LogOptions, RolloutLogger, RunHeader};
use smirl::pipeline::reacher_irl::job::{run_job, JobInputs};
use smirl::pipeline::reacher_irl::lockstep::Lockstep;
use smirl::pipeline::reacher_irl::records::{JobRecord, PreparedRun};
use smirl::pipeline::reacher_irl::run::Silent;
use smirl::pipeline::reacher_irl::{run_pipeline, Algo, DemoSource, IrlRunConfig, RunRequest};
use std::path::Path;

/// A tiny but complete configuration: scripted demos, 2 IRL iterations of 300 SAC steps
/// (seconds per job).
pub fn tiny_config() -> IrlRunConfig {
    let mut c = IrlRunConfig::quick();
    c.demo_source = DemoSource::Scripted;
    c.demo_episodes = 4;
    c.irl_iterations = 2;
    c.sac_steps_per_iteration = 300;
    c.agent_trajectories = 3;
    c.eval_episodes = 2;
    c.lrm_steps = 20;
    c.lrm_tabu_len = 100;
    c.log_every_nth_episode = 2;
    // SMIRL's final policy: two candidates after the co-trained one, 140 steps apart.
    c.final_sac_steps = 280;
    c.final_checkpoints = 2;
    // 300 SAC steps are not a whole number of 70-step episodes: each iteration has to finish
    // SAC's episode in progress before the rollouts reset the environment.
    c.episode_steps = Some(70);
    c.sac.warmup_steps = 100;
    c.sac.update_after = 100;
    c
}

/// One rkl job on task "blue" (seed 4) with `config`: its metrics.csv and written config.toml.
#[allow(dead_code)] // each test crate that includes this module uses only some of it
pub fn tiny_rkl_blue_run(config: IrlRunConfig) -> (String, String) {
    let tmp = tempfile::tempdir().unwrap();
    let request = RunRequest {
        task: ReacherTask::shipped("blue").unwrap(),
        algos: vec![Algo::Rkl],
        seeds: 1,
        seed: 4,
        config,
        out: tmp.path().join("run"),
        force: false,
    };
    run_pipeline(&request, &Silent).unwrap();
    let read = |f: &str| std::fs::read_to_string(tmp.path().join("run").join(f)).unwrap();
    (read("metrics.csv"), read("config.toml"))
}

/// The column `name` of a metrics.csv, row by row.
#[allow(dead_code)]
pub fn metrics_column(metrics: &str, name: &str) -> Vec<String> {
    let mut lines = metrics.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let col = header.iter().position(|h| *h == name).unwrap();
    lines
        .map(|l| l.split(',').nth(col).unwrap().to_string())
        .collect()
}

/// What one job of a prepared run gives, in bytes: its record as JSON (wall time zeroed), its
/// saved reward and its rollout log.
#[allow(dead_code)]
pub struct JobBytes {
    pub record: String,
    pub reward: Vec<u8>,
    pub log: Vec<u8>,
}

/// Runs job (`algo`, `seed`) of the prepared run `run` with `settings` (the run's for `algo`,
/// or changed), its independent episodes played by `plan`, its files in `dir`.
#[allow(dead_code)]
pub fn job_bytes(
    run: &PreparedRun,
    algo: Algo,
    seed: u64,
    settings: &IrlRunConfig,
    plan: Lockstep<'_>,
    dir: &Path,
) -> JobBytes {
    std::fs::create_dir_all(dir).unwrap();
    let (learned, expert) = run.inputs_of(algo).unwrap();
    let reward_path = dir.join("reward");
    let log_path = dir.join("log.mcap");
    let task = &run.prepared.task;
    let header = RunHeader::of_task(task.id(), task.task(), seed, serde_json::json!({}));
    let options = LogOptions {
        every_nth_episode: settings.log_every_nth_episode.max(1),
        ..LogOptions::default()
    };
    let mut logger = RolloutLogger::create(&log_path, header, options).unwrap();
    let inputs = JobInputs {
        algo,
        seed,
        settings,
        perfect_rm: &run.perfect,
        learned_rm: learned,
        expert,
        reward_path: Some(&reward_path),
        lockstep: plan,
    };
    let result = run_job(&inputs, Some(&mut logger), &|_| {}).unwrap();
    logger.finish().unwrap();
    let record = JobRecord {
        wall_secs: 0.0,
        ..JobRecord::from(result)
    };
    JobBytes {
        record: serde_json::to_string(&record).unwrap(),
        reward: std::fs::read(&reward_path).unwrap(),
        log: std::fs::read(&log_path).unwrap(),
    }
}
