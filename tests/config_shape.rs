//! The run config's shape (issue 54, item 1): one `[schedule.baselines]` table that the four
//! baselines share, with an algorithm's own table over it; the optional `[env] episode_steps`
//! in place of `[env] max_steps`, which is refused naming it; the environment's event schedule
//! and region positions as explicit overrides (`None`: the task's), not values compared with
//! a default; a config without a key refused with exit status 2, naming it.

use smirl::env::reacher::{CancelConfig, ReacherConfig};
use smirl::env::reacher_task::ReacherTask;
use smirl::env::task_file::SHIPPED;
use smirl::pipeline::reacher_irl::config::{AlgoSchedule, FirlSchedule, BASELINES};
use smirl::pipeline::reacher_irl::{Algo, IrlRunConfig};
use std::path::Path;

/// The baselines' schedule as the standard config wrote it before `[schedule.baselines]`: four
/// identical copies, rkl's with its demonstrations drawn into each batch.
fn per_algorithm_tables() -> String {
    let mut text = String::new();
    for algo in ["fkl", "js", "maxent", "rkl"] {
        let drawn = if algo == "rkl" {
            "expert_trajectories = 300\n"
        } else {
            ""
        };
        text += &format!(
            "\n[schedule.{algo}]\nirl_iterations = 800\nsac_steps_per_iteration = 300\n\
             agent_trajectories = 300\nreward_steps_per_iteration = 2\n\
             log_every_nth_episode = 100\n\
             \n[schedule.{algo}.firl]\nreward_l2 = 0.0\n{drawn}\
             \n[schedule.{algo}.sac]\nlr = 0.003\nalpha = 1.0\nauto_alpha = false\n\
             warmup_steps = 150\n"
        );
    }
    text
}

fn without_schedules() -> IrlRunConfig {
    IrlRunConfig {
        schedule: Default::default(),
        ..IrlRunConfig::standard()
    }
}

/// Every algorithm on every shipped task runs with the settings the four per-algorithm tables
/// gave it: the standard config (and its file) resolves as before.
#[test]
fn the_baselines_table_resolves_to_the_per_algorithm_tables() {
    let old = IrlRunConfig::from_toml(
        &(without_schedules().to_toml() + &per_algorithm_tables()),
        "old.toml",
    )
    .unwrap();
    let standard = IrlRunConfig::standard();
    let shipped = IrlRunConfig::load(
        &Path::new(env!("CARGO_MANIFEST_DIR")).join("experiments/reacher/config.toml"),
    )
    .unwrap();
    assert_eq!(shipped, standard);
    assert_eq!(
        standard.schedule.keys().collect::<Vec<_>>(),
        [BASELINES, "rkl"]
    );
    for name in SHIPPED {
        let task = ReacherTask::shipped(name).unwrap();
        for &algo in &Algo::REACHER_NAMED {
            let want = old.for_algo(algo).unwrap().over_task(&task).unwrap();
            let got = standard.for_algo(algo).unwrap().over_task(&task).unwrap();
            assert_eq!(got, want, "{name} {algo}");
            assert_eq!(got.env.max_steps, 100, "{name} {algo}");
        }
    }
    // The values themselves: rkl's own key over the baselines' table.
    for algo in [Algo::MaxEnt, Algo::Fkl, Algo::Rkl, Algo::Js] {
        let c = standard.for_algo(algo).unwrap();
        assert_eq!(
            (c.irl_iterations, c.sac_steps_per_iteration, c.mlp_reward_l2),
            (800, 300, 0.0),
            "{algo}"
        );
        let drawn = if algo == Algo::Rkl { 300 } else { 0 };
        assert_eq!(c.firl_expert_trajectories, drawn, "{algo}");
    }
}

/// Precedence, field by field: an algorithm's own table over the baselines' over the run's
/// keys; the baselines' table reaches the baselines (and their controls) only; a single
/// algorithm's table works without it.
#[test]
fn an_algorithms_own_table_wins_over_the_baselines() {
    let text = without_schedules().to_toml()
        + "\n[schedule.baselines]\nirl_iterations = 7\nagent_trajectories = 9\n\
           \n[schedule.baselines.firl]\nreward_l2 = 0.0\n\
           \n[schedule.fkl]\nirl_iterations = 3\n\
           \n[schedule.fkl.firl]\nreward_l2 = 0.5\n";
    let c = IrlRunConfig::from_toml(&text, "c.toml").unwrap();
    let run = without_schedules();
    let fkl = c.for_algo(Algo::Fkl).unwrap();
    assert_eq!(
        (
            fkl.irl_iterations,
            fkl.agent_trajectories,
            fkl.mlp_reward_l2
        ),
        (3, 9, 0.5)
    );
    assert_eq!(fkl.sac_steps_per_iteration, run.sac_steps_per_iteration);
    for algo in [Algo::MaxEnt, Algo::Js, Algo::MaxEntProduct] {
        let b = c.for_algo(algo).unwrap();
        assert_eq!(
            (b.irl_iterations, b.agent_trajectories, b.mlp_reward_l2),
            (7, 9, 0.0),
            "{algo}"
        );
    }
    assert_eq!(c.for_algo(Algo::FklProduct).unwrap().irl_iterations, 3);
    for algo in [Algo::Smirl, Algo::SmirlSmooth] {
        assert_eq!(c.for_algo(algo).unwrap(), run, "{algo}");
    }
    // One algorithm's table alone.
    let mut one = run.clone();
    one.schedule.insert(
        "js".into(),
        AlgoSchedule {
            irl_iterations: Some(5),
            firl: Some(FirlSchedule {
                expert_trajectories: Some(4),
                ..FirlSchedule::default()
            }),
            ..AlgoSchedule::default()
        },
    );
    let one = IrlRunConfig::from_toml(&one.to_toml(), "one.toml").unwrap();
    let js = one.for_algo(Algo::Js).unwrap();
    assert_eq!((js.irl_iterations, js.firl_expert_trajectories), (5, 4));
    assert_eq!(one.for_algo(Algo::Fkl).unwrap(), run);
    // Printed and read back unchanged.
    assert_eq!(IrlRunConfig::from_toml(&c.to_toml(), "p").unwrap(), c);
}

/// A name under `[schedule]` that is neither an algorithm nor `baselines`, and a bad value or
/// shared key in the baselines' table: refused naming the key.
#[test]
fn bad_schedule_names_and_baselines_values_are_refused_naming_the_key() {
    let base = without_schedules().to_toml();
    for (extra, needle) in [
        (
            "[schedule.baseline]\nirl_iterations = 3\n",
            "schedule.baseline",
        ),
        (
            "[schedule.baselines]\nirl_iterations = 0\n",
            "schedule.baselines.irl_iterations",
        ),
        (
            "[schedule.baselines.sac]\nreplay_capacity = 1000\n",
            "schedule.baselines.sac.replay_capacity",
        ),
        ("[schedule.baselines]\niterations = 3\n", "iterations"),
    ] {
        let e = IrlRunConfig::from_toml(&format!("{base}\n{extra}"), "c.toml")
            .unwrap_err()
            .to_string();
        assert!(e.contains(needle) && e.contains("c.toml"), "{extra}: {e}");
    }
}

/// `[env] max_steps` is refused naming `episode_steps` (the binary's refusals, exit status 2:
/// `pipeline_reacher.rs`, `the_cli_refuses_a_missing_key_and_a_removed_switch`).
#[test]
fn max_steps_is_refused_naming_episode_steps() {
    let quick = IrlRunConfig::quick().to_toml();
    assert!(!quick.contains("[env]"), "{quick}");
    let e = IrlRunConfig::from_toml(&format!("{quick}\n[env]\nmax_steps = 100\n"), "c.toml")
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("env.max_steps") && e.contains("[env] episode_steps"),
        "{e}"
    );
}

/// A task file like `or` but with `episode_steps` and its event's schedule changed.
fn or_variant(dir: &Path, episode_steps: usize, probability: f64) -> ReacherTask {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let text = std::fs::read_to_string(root.join("assets/tasks/or.toml")).unwrap();
    let machine = root.join("assets/rm/reacher_or.txt");
    let text = text
        .replace(
            "machine = \"../rm/reacher_or.txt\"",
            &format!("machine = {:?}", machine.to_str().unwrap()),
        )
        .replace(
            "episode_steps = 100",
            &format!("episode_steps = {episode_steps}"),
        )
        .replace(
            "probability = 0.5",
            &format!("probability = {probability:?}"),
        );
    let path = dir.join(format!("or_{episode_steps}.toml"));
    std::fs::write(&path, text).unwrap();
    ReacherTask::resolve(path.to_str().unwrap()).unwrap()
}

/// Absent, `[env] episode_steps` is each task's own length; present, it is the length of every
/// task, whatever its value (100 too, on a task of 50 steps).
#[test]
fn episode_steps_overrides_the_tasks_length_when_given() {
    let tmp = tempfile::tempdir().unwrap();
    let short = or_variant(tmp.path(), 50, 0.5);
    let or = ReacherTask::shipped("or").unwrap();
    let mut config = IrlRunConfig::quick();
    assert_eq!(config.episode_steps, None);
    assert_eq!(config.over_task(&short).unwrap().env.max_steps, 50);
    assert_eq!(config.over_task(&or).unwrap().env.max_steps, 100);
    for steps in [100, 70] {
        config.episode_steps = Some(steps);
        let text = config.to_toml();
        assert!(
            text.contains(&format!("[env]\nepisode_steps = {steps}\n")),
            "{text}"
        );
        let read = IrlRunConfig::from_toml(&text, "c.toml").unwrap();
        assert_eq!(read, config);
        for task in [&short, &or] {
            let resolved = read.over_task(task).unwrap();
            assert_eq!(resolved.env.max_steps, steps, "{task}");
            // Resolving again changes nothing.
            assert_eq!(resolved.over_task(task).unwrap(), resolved, "{task}");
        }
    }
    // Out of range: refused naming the key.
    config.episode_steps = Some(0);
    let e = IrlRunConfig::from_toml(&config.to_toml(), "c.toml")
        .unwrap_err()
        .to_string();
    assert!(e.contains("env.episode_steps"), "{e}");
    // Shorter than the task's event window: refused when resolved over the task.
    config.episode_steps = Some(5);
    assert!(config.over_task(&or).is_err());
}

/// The event schedule and the region positions: `None` is the task's; a value is used as
/// given, also one equal to the shipped schedule (a value never stands for "not set").
#[test]
fn the_event_schedule_override_is_explicit() {
    let tmp = tempfile::tempdir().unwrap();
    let task = or_variant(tmp.path(), 100, 0.3);
    let shipped = CancelConfig {
        probability: 0.5,
        earliest_step: 1,
        latest_step: 8,
    };
    let unset = ReacherConfig::default();
    assert_eq!((&unset.cancel, &unset.ball_layout), (&None, &None));
    let own = task.env_config(&unset).unwrap();
    assert_eq!(
        own.cancel,
        Some(CancelConfig {
            probability: 0.3,
            ..shipped.clone()
        })
    );
    assert_eq!(own.ball_layout, Some(task.layout().positions()));
    // Resolving again changes nothing.
    assert_eq!(task.env_config(&own).unwrap(), own);
    let given = task
        .env_config(&ReacherConfig {
            cancel: Some(shipped.clone()),
            ..ReacherConfig::default()
        })
        .unwrap();
    assert_eq!(given.cancel, Some(shipped));
    let env = task.make_env(&given).unwrap();
    assert_eq!(env.config().cancel, given.cancel);
    // Positions given for as many regions as the task has; for another count, refused.
    let moved: Vec<[f64; 2]> = own
        .ball_layout
        .clone()
        .unwrap()
        .iter()
        .map(|&[x, y]| [x * 0.5, y * 0.5])
        .collect();
    let placed = task
        .env_config(&ReacherConfig {
            ball_layout: Some(moved.clone()),
            ..ReacherConfig::default()
        })
        .unwrap();
    assert_eq!(placed.ball_layout, Some(moved));
    assert!(task
        .env_config(&ReacherConfig {
            ball_layout: Some(vec![]),
            ..ReacherConfig::default()
        })
        .is_err());
}
