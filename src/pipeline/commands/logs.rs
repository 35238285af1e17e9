//! The rollout-log commands of `reacher`: `replay`, `render`, `foxglove`, `demo` and
//! `learn-rm`. Every output file is checked (exists only with `--force`, never one of the
//! inputs) before any input is read, so a refused command writes nothing.

use super::{usage, UsageError};
use crate::env::reacher::ReacherConfig;
use crate::env::reacher_controller::{ControllerGains, ScriptedController};
use crate::log::demo::{check_event_probability, log_scripted_demos, DemoSpec};
use crate::log::{read_log, LogOptions, RolloutLog};
use crate::output::{check_file, check_not_input, create_parent};
use crate::pipeline::offline_rm::{compare, traces_from_files, OfflineRm, OfflineRmError};
use crate::pipeline::reacher_irl::smirl;
use crate::pipeline::render::{render_episode, write_png, RenderOptions};
use crate::rm::lrm::{LrmConfig, MAX_SEARCH_STEPS, MAX_STATES};
use crate::rm::LabelSet;
use anyhow::{bail, Context, Result};
use std::path::{Path, PathBuf};

/// A log cut short is refused (exit 1) unless `allow_partial`; with it, a warning.
fn check_partial(log: &RolloutLog, allow_partial: bool) -> Result<()> {
    if let Some(rec) = &log.recovery {
        if !allow_partial {
            bail!(
                "{}: {rec}; pass --allow-partial to use its complete episodes",
                log.path.display()
            );
        }
        eprintln!("warning: {}: {rec}", log.path.display());
    }
    Ok(())
}

/// `reacher replay FILE [--verify] [--allow-partial]`: re-simulates every logged episode and
/// prints the comparison. With `verify`, an empty log, a log cut short (unless
/// `allow_partial`) or any differing episode is a failure.
pub fn replay(file: &Path, verify: bool, allow_partial: bool) -> Result<()> {
    let log = read_log(file)?;
    // Listing a partial log is harmless; verifying one is not a pass.
    check_partial(&log, allow_partial || !verify)?;
    let report = crate::pipeline::replay::replay(&log)?;
    println!("{report}");
    if verify && report.episodes.is_empty() {
        bail!("{}: the log holds no episode to verify", file.display());
    }
    if verify && !report.all_match() {
        if report.version_differs {
            bail!(
                "{}: replay differs from the log (logged with MuJoCo {}, this is {})",
                file.display(),
                log.run.mujoco_version,
                crate::mujoco::version_string()
            );
        }
        bail!(
            "{}: {} episode(s) differ from the log",
            file.display(),
            report.mismatches()
        );
    }
    Ok(())
}

/// The arguments of `reacher render`.
#[derive(Clone, Debug)]
pub struct RenderRequest {
    /// The rollout log.
    pub file: PathBuf,
    /// Episode id as `reacher replay` lists it; `None`: the first logged episode.
    pub episode: Option<u64>,
    /// The PNG file to write.
    pub out: PathBuf,
    /// Replace an existing `out`.
    pub force: bool,
    /// Side of the arena picture in pixels.
    pub size: u32,
    /// Accept a log cut short (its complete episodes are used).
    pub allow_partial: bool,
    /// Arm poses drawn, evenly spaced over the episode.
    pub poses: usize,
}

/// `reacher render`: draws one logged episode top-down as PNG and prints what it shows.
pub fn render(args: RenderRequest) -> Result<()> {
    let options = RenderOptions {
        size: args.size,
        poses: args.poses,
    };
    options
        .validate()
        .map_err(|e| usage(format!("--size: {e}")))?;
    check_file(&args.out, args.force).map_err(usage)?;
    check_not_input(&args.out, &[&args.file]).map_err(usage)?;
    let log = read_log(&args.file)?;
    check_partial(&log, args.allow_partial)?;
    let picture = render_episode(&log, args.episode, &options)?;
    create_parent(&args.out)?;
    write_png(&args.out, &picture)?;
    let touches: Vec<String> = picture
        .touches
        .iter()
        .map(|(step, ball)| format!("{ball}@{step}"))
        .collect();
    println!(
        "wrote {}: episode {} [{}], {} steps, touches [{}], event {}{}",
        args.out.display(),
        picture.episode,
        picture.phase,
        picture.steps,
        touches.join(" "),
        picture
            .event_step
            .map_or("none".to_string(), |s| format!("at step {s}")),
        picture
            .branch
            .map_or(String::new(), |b| format!(", {b} branch"))
    );
    Ok(())
}

/// `reacher foxglove FILE --out VIEW`: writes a copy of the log with a Foxglove 3D scene.
pub fn foxglove(file: &Path, out: &Path, force: bool, allow_partial: bool) -> Result<()> {
    check_file(out, force).map_err(usage)?;
    check_not_input(out, &[file]).map_err(usage)?;
    let s = crate::pipeline::foxglove_scene::export_scene(file, out, allow_partial)?;
    println!(
        "wrote {}: {} messages of the log, {} scene states of {} episodes (/scene, /tf); open it in Foxglove and add a 3D panel",
        s.out.display(),
        s.copied,
        s.scenes,
        s.episodes
    );
    Ok(())
}

/// The arguments of `reacher learn-rm`.
#[derive(Clone, Debug)]
pub struct LearnRmRequest {
    /// Rollout logs whose label traces are learned from.
    pub files: Vec<PathBuf>,
    /// Directory of `learned_rm.txt` and `learned_rm.dot`.
    pub out: PathBuf,
    /// Replace existing `learned_rm.txt` / `learned_rm.dot` in `out`.
    pub force: bool,
    /// Reference machine to check equivalence with.
    pub compare: Option<PathBuf>,
    /// Most states of the learned machine (LRM's u_max), 1..=[`MAX_STATES`].
    pub max_states: usize,
    /// Tabu search steps, 1..=[`MAX_SEARCH_STEPS`].
    pub steps: usize,
    pub seed: u64,
    /// Accept logs cut short (their complete episodes are used).
    pub allow_partial: bool,
    /// Keep the search's machine instead of merging reward-indistinguishable states.
    pub no_merge: bool,
    /// Learn as plain LRM, with no declared events (instead of the logs' task's events read by
    /// SMIRL's learner's event rules).
    pub no_events: bool,
}

/// `reacher learn-rm`: learns a reward machine from the label traces of rollout logs, writes
/// it as text and DOT, and compares it with a reference machine if one is given.
pub fn learn_rm(args: LearnRmRequest) -> Result<()> {
    let mut cfg = LrmConfig {
        max_states: args.max_states,
        max_steps: args.steps,
        seed: args.seed,
        merge: !args.no_merge,
        // ReacherDelivery's label sets hold over several steps, and the machine is read on
        // every step (as SMIRL's learner reads it).
        stutter_invariant: true,
        ..LrmConfig::default()
    };
    // Every input and output is checked before the search runs.
    if !(1..=MAX_STATES).contains(&args.max_states) {
        return Err(usage(format!("--max-states must be in 1..={MAX_STATES}")));
    }
    if !(1..=MAX_SEARCH_STEPS).contains(&args.steps) {
        return Err(usage(format!("--steps must be in 1..={MAX_SEARCH_STEPS}")));
    }
    let txt = args.out.join("learned_rm.txt");
    let dot = args.out.join("learned_rm.dot");
    let inputs: Vec<&Path> = args
        .files
        .iter()
        .chain(&args.compare)
        .map(PathBuf::as_path)
        .collect();
    for path in [&txt, &dot] {
        check_file(path, args.force).map_err(usage)?;
        check_not_input(path, &inputs).map_err(usage)?;
    }
    let reference = match &args.compare {
        Some(path) => Some((
            path,
            crate::rm::format::read_rm(path).map_err(|e| UsageError(format!("{e:#}")))?,
        )),
        None => None,
    };
    let traces = traces_from_files(&args.files, args.allow_partial).map_err(|e| match e {
        // Logs that disagree on their task are bad input; a damaged log is not.
        OfflineRmError::Vocabulary { .. }
        | OfflineRmError::BadVocabulary { .. }
        | OfflineRmError::Events { .. }
        | OfflineRmError::TaskLayout { .. } => usage(e),
        e => e.into(),
    })?;
    if let Some((path, rm)) = &reference {
        if rm.vocab() != &traces.vocabulary {
            return Err(usage(format!(
                "{}: vocabulary \"{}\" differs from the logs' \"{}\"",
                path.display(),
                rm.vocab(),
                traces.vocabulary
            )));
        }
    }
    if !args.no_events {
        // Learned as SMIRL's learner reads the events, as the run learned its own machine.
        cfg = smirl::with_event_rules(LrmConfig {
            events: traces.events,
            ..cfg
        });
    }
    println!(
        "events: {}",
        match cfg.events {
            LabelSet::EMPTY if args.no_events => "none (--no-events)".to_string(),
            LabelSet::EMPTY => "none (the logs' task declares none)".to_string(),
            e => format!(
                "{} (declared by the logs' task)",
                traces.vocabulary.format_labels(e)
            ),
        }
    );
    let learned = crate::rm::lrm::learn_rm(&traces.vocabulary, &traces.traces, &cfg)?;
    let result = OfflineRm { learned, traces };
    for w in &result.traces.warnings {
        eprintln!("warning: {w}");
    }
    let learned = &result.learned;
    println!(
        "{} traces ({} unfinished skipped, rewards: {}), {} transitions",
        result.traces.traces.len(),
        result.traces.skipped_unfinished,
        if result.traces.traces[0].rewards.is_some() {
            "RM rewards"
        } else {
            "none"
        },
        learned.stats.raw_transitions
    );
    println!(
        "learned RM: {} states (search found {}), cost {:.4}",
        learned.rm.n_states(),
        learned.stats.search_states,
        learned.cost
    );
    create_parent(&txt)?;
    crate::rm::format::save_rm(&txt, &learned.rm)
        .with_context(|| format!("cannot write {}", txt.display()))?;
    crate::atomic_file::write_atomic(&dot, crate::rm::dot::to_dot(&learned.rm).as_bytes())
        .with_context(|| format!("cannot write {}", dot.display()))?;
    println!("wrote {} and {}", txt.display(), dot.display());
    if let Some((reference, reference_rm)) = &reference {
        let c = compare(&learned.rm, reference_rm, &result.traces.traces)?;
        match c.counterexample {
            None => println!(
                "equivalent to {} (over the observed label sets)",
                reference.display()
            ),
            Some(cex) => println!(
                "NOT equivalent to {}: rewards differ on [{cex}]",
                reference.display()
            ),
        }
        match c.counterexample_until_done {
            None => println!("equivalent until the task is done (sequences stop at the reference's terminal states)"),
            Some(cex) => println!("differs before the task is done: rewards differ on [{cex}]"),
        }
    }
    Ok(())
}

/// The arguments of `reacher demo`.
#[derive(Clone, Debug)]
pub struct DemoRequest {
    /// The MCAP file to write.
    pub out: PathBuf,
    /// Replace an existing `out`.
    pub force: bool,
    /// Regions to visit, in order, as letters; `None`: every region of the task in file order.
    pub sequence: Option<String>,
    /// A shipped task's name or a task file's path; its machine is tracked and logged.
    pub task: String,
    pub episodes: u64,
    pub seed: u64,
    /// Chance of each of the task's events per episode; `None`: the task's own.
    pub event_probability: Option<f64>,
    /// Also store observations.
    pub observations: bool,
}

/// Most episodes `reacher demo` writes: 10 000 episodes of at most the default 100 steps,
/// ~80 MB, stay below what a log may hold (`log::reader::MAX_LOG_FILE_BYTES`).
pub const MAX_DEMO_EPISODES: u64 = 10_000;

/// `reacher demo`: logs scripted demonstrations (a sequence of regions) to an MCAP file.
pub fn demo(args: DemoRequest) -> Result<()> {
    // Every argument is checked before the log file is created.
    let task = args
        .task
        .parse::<crate::env::reacher_task::ReacherTask>()
        .map_err(|e| usage(format!("--task: {e}")))?;
    if !(1..=MAX_DEMO_EPISODES).contains(&args.episodes) {
        return Err(usage(format!(
            "--episodes must be in 1..={MAX_DEMO_EPISODES}"
        )));
    }
    let layout = task.layout();
    let sequence = (args.sequence.clone())
        .unwrap_or_else(|| layout.regions.iter().map(|r| r.letter).collect());
    ScriptedController::from_letters(&sequence, &layout, ControllerGains::default())
        .map_err(|e| usage(format!("--sequence: {e}")))?;
    if let Some(p) = args.event_probability {
        check_event_probability(p, &layout)
            .map_err(|e| usage(format!("--event-probability: {e}")))?;
    }
    check_file(&args.out, args.force).map_err(usage)?;
    let reward_machine = Some((*task.task().machine).clone());
    let spec = DemoSpec {
        task: args.task,
        sequence,
        episodes: args.episodes,
        seed: args.seed,
        stop_when_done: true,
        env: ReacherConfig::default(),
        event_probability: args.event_probability,
        reward_machine,
    };
    let options = LogOptions {
        observations: args.observations,
        ..LogOptions::default()
    };
    create_parent(&args.out)?;
    let s = log_scripted_demos(&args.out, &spec, options)?;
    println!(
        "wrote {}: {} episodes, {} steps, {} bytes ({:.1} B/step)",
        s.path.display(),
        s.episodes_logged,
        s.steps_logged,
        s.bytes,
        s.bytes as f64 / s.steps_logged.max(1) as f64
    );
    Ok(())
}
