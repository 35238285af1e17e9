//! Replay of a rollout log: re-simulate every logged episode from its recorded initial state
//! with the recorded actions, on the model XML stored in the file, and compare the state,
//! labels, reward (and observation when logged) with the log bit for bit.
//!
//! Where the run tracked a reward machine (the task's machine, stored as text in the `/run`
//! record; for a log that stores none, the shipped `assets/rm/reacher_<task>.txt`), replay
//! re-tracks it along the re-simulated labels and compares the machine state and reward of
//! every step, and the final state and success of every finished episode, with the log.
//!
//! Differences in the setting are reported as such before any step is compared: a log from
//! another MuJoCo version (bit-exact agreement is then not expected), a stored XML whose hash
//! is not the one recorded (a damaged file), or an XML that differs from the shipped model
//! (replay still uses the stored one, which is what the run used; the first shipped model,
//! `assets/reacher_delivery_v1.xml`, is named as such).

use crate::env::reacher::{ReacherConfig, ReacherDelivery, ACT_DIM};
use crate::env::reacher_task::{Branch, EventBranch};
use crate::env::{ContinuousEnv, EnvError, EnvStep};
use crate::log::schema::{sha256_hex, EpisodeEndMsg, EpisodeStartMsg, StepMsg, NO_RM};
use crate::log::{LoggedEpisode, RolloutLog};
use crate::rm::format::{parse_rm, write_rm, RmFileError};
use crate::rm::{perfect, LabelSet, RewardMachine};
use std::fmt;
use std::sync::Arc;

/// Errors that stop a replay before it compares anything.
#[derive(Debug, thiserror::Error)]
pub enum ReplayError {
    #[error("{path}: cannot replay: {problem}")]
    Cannot { path: String, problem: String },
}

/// A reward machine stored in the run record that does not parse (a damaged file).
#[derive(Debug, thiserror::Error)]
#[error("the stored reward machine does not parse: {0}")]
pub struct StoredMachineError(#[source] pub RmFileError);

/// An episode that cannot be replayed: its logged start does not fit the environment.
#[derive(Debug, thiserror::Error)]
pub enum EpisodeReplayError {
    #[error("{got} region coordinates, expected {expected}")]
    Regions { got: usize, expected: usize },
    #[error("{got} event steps, expected {expected}")]
    EventSteps { got: usize, expected: usize },
    #[error(transparent)]
    Env(#[from] EnvError),
}

/// The first difference found in an episode.
#[derive(Clone, Debug, PartialEq)]
pub struct Mismatch {
    /// 1-based step (0 = the initial state).
    pub step: usize,
    /// What differs, e.g. `qpos[1]`.
    pub what: String,
    pub logged: String,
    pub replayed: String,
}

impl fmt::Display for Mismatch {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "step {}: {} logged {} but replayed {}",
            self.step, self.what, self.logged, self.replayed
        )
    }
}

/// The outcome of one episode's replay.
#[derive(Clone, Debug, PartialEq)]
pub struct EpisodeReplay {
    pub episode: u64,
    pub seed: u64,
    pub phase: String,
    pub steps: usize,
    /// The log has the episode's end record.
    pub complete: bool,
    pub env_return: f64,
    /// Labels seen along the episode, as runs of one label set (steps from 1; e.g.
    /// `c@3 r@9–11 y@23–100`, empty sets left out); see [`label_runs`].
    pub label_events: String,
    pub mismatch: Option<Mismatch>,
    /// `reset(seed)` reproduces the logged initial state (when false, the state was still
    /// restored from the log; this only flags a seed/env-code change).
    pub seed_reproduces_start: bool,
    /// The logged reward-machine states and rewards were re-tracked and compared.
    pub rm_checked: bool,
    /// For a conditional task (IF, Composite): the branch the replayed labels took.
    pub branch: Option<Branch>,
}

/// The outcome of a whole replay.
#[derive(Clone, Debug, PartialEq)]
pub struct ReplayReport {
    /// Notes about the setting (MuJoCo version, XML hash) that explain mismatches.
    pub setting_notes: Vec<String>,
    /// The MuJoCo versions differ, so bit-exact agreement is not expected.
    pub version_differs: bool,
    /// The reward machine re-tracked along the labels: its size and where it came from
    /// (`None`: the log has no machine states, or no machine is known for its task).
    pub reward_machine: Option<String>,
    pub episodes: Vec<EpisodeReplay>,
    pub steps: usize,
    pub elapsed_secs: f64,
}

impl ReplayReport {
    pub fn mismatches(&self) -> usize {
        self.episodes
            .iter()
            .filter(|e| e.mismatch.is_some())
            .count()
    }

    pub fn all_match(&self) -> bool {
        self.mismatches() == 0
    }
}

/// Floats compared bit for bit (so -0.0 differs from 0.0 and NaNs compare by payload).
trait ExactFloat: Copy + std::fmt::LowerExp {
    fn bits(self) -> u64;
}

impl ExactFloat for f64 {
    fn bits(self) -> u64 {
        self.to_bits()
    }
}

impl ExactFloat for f32 {
    fn bits(self) -> u64 {
        u64::from(self.to_bits())
    }
}

/// What differs first at a step: what, its logged value, its replayed value.
type Diff = (String, String, String);

/// The first element where the logged and replayed values differ in their bits, as
/// `(where, logged, replayed)`.
fn first_diff<T: ExactFloat>(what: &str, logged: &[T], replayed: &[T]) -> Option<Diff> {
    if logged.len() != replayed.len() {
        return Some((
            format!("{what} length"),
            logged.len().to_string(),
            replayed.len().to_string(),
        ));
    }
    logged
        .iter()
        .zip(replayed)
        .position(|(a, b)| a.bits() != b.bits())
        .map(|i| {
            (
                format!("{what}[{i}]"),
                format!("{:e}", logged[i]),
                format!("{:e}", replayed[i]),
            )
        })
}

/// Replays every episode of `log` (ReacherDelivery logs only).
pub fn replay(log: &RolloutLog) -> Result<ReplayReport, ReplayError> {
    let path = log.path.display().to_string();
    let cannot = |problem: String| ReplayError::Cannot {
        path: path.clone(),
        problem,
    };
    let xml = log.reacher_model_xml().map_err(cannot)?;
    let stored_hash = sha256_hex(xml);
    if stored_hash != log.run.model_xml_sha256 {
        return Err(cannot(format!(
            "the attached model XML hashes to {stored_hash}, the run record says {} (damaged file)",
            log.run.model_xml_sha256
        )));
    }
    let mut notes = Vec::new();
    let here = crate::mujoco::version_string();
    let version_differs = log.run.mujoco_version != here;
    if version_differs {
        notes.push(format!(
            "logged with MuJoCo {}, replaying with MuJoCo {here}: bit-exact agreement is not \
             expected, mismatches below may come from the version change",
            log.run.mujoco_version
        ));
    }
    let shipped = sha256_hex(crate::assets::REACHER_XML);
    if sha256_hex(crate::assets::REACHER_V1_XML) == stored_hash {
        notes.push(format!(
            "the run used the first shipped model (assets/{}, balls on slide joints); \
             replaying with it",
            crate::assets::REACHER_V1_XML_NAME
        ));
    } else if shipped != stored_hash {
        notes.push(format!(
            "the run used a model XML ({}, sha256 {}) that differs from the shipped assets/{} \
             (sha256 {}); replaying with the XML stored in the log",
            log.run.model_xml_name,
            &stored_hash[..12],
            crate::assets::REACHER_XML_NAME,
            &shipped[..12]
        ));
    }
    if !log.scene_files.is_empty() {
        notes.push(format!(
            "the scene reads {} more files ({}); replaying with the copies stored in the log",
            log.scene_files.len(),
            scene_file_names(log)
        ));
    }
    let model = log.reacher_model().map_err(|e| cannot(e.to_string()))?;
    // The config matters for the time limit (`truncated`) and for reset(seed) (ball
    // randomisation, cancel schedule); the replayed episodes restore their logged start state.
    let layout = log.run.task_layout().map_err(|e| cannot(e.to_string()))?;
    let mut config: ReacherConfig = match log.run.config.get("env") {
        Some(v) => serde_json::from_value(v.clone()).map_err(|e| {
            cannot(format!(
                "the run config's `env` section does not parse: {e}"
            ))
        })?,
        None => {
            notes.push(
                "the run config has no `env` section: replaying with the default environment \
                 config (a different time limit would show as a `truncated` mismatch)"
                    .into(),
            );
            ReacherConfig::default()
        }
    };
    config.layout = Some(Arc::new(layout));
    let mut env =
        ReacherDelivery::with_model(Arc::new(model), config).map_err(|e| cannot(e.to_string()))?;
    let reward_machine = run_reward_machine(log, &mut notes).map_err(|e| cannot(e.to_string()))?;
    let rm = reward_machine.as_ref().map(|(rm, _)| rm);
    let started = std::time::Instant::now();
    let mut episodes = Vec::with_capacity(log.episodes.len());
    let mut steps = 0;
    for ep in &log.episodes {
        let r = replay_episode(&mut env, ep, rm)
            .map_err(|problem| cannot(format!("episode {}: {problem}", ep.start.episode)))?;
        steps += r.steps;
        episodes.push(r);
    }
    Ok(ReplayReport {
        setting_notes: notes,
        version_differs,
        reward_machine: reward_machine
            .as_ref()
            .map(|(rm, source)| format!("{} states, {source}", rm.n_states())),
        episodes,
        steps,
        elapsed_secs: started.elapsed().as_secs_f64(),
    })
}

/// The names of the scene files a log carries, the first few of them.
fn scene_file_names(log: &RolloutLog) -> String {
    const SHOWN: usize = 4;
    let mut names: Vec<&str> = (log.scene_files.iter().take(SHOWN))
        .map(|f| f.name.as_str())
        .collect();
    if log.scene_files.len() > SHOWN {
        names.push("…");
    }
    names.join(", ")
}

/// The machine to re-track: the one stored in the run record, else (when steps carry
/// machine states) the shipped machine of the run's task. Notes where it came from and
/// whether it differs from the shipped one; a stored machine that does not parse is an error
/// (a damaged file).
pub(crate) fn run_reward_machine(
    log: &RolloutLog,
    notes: &mut Vec<String>,
) -> Result<Option<(RewardMachine, String)>, StoredMachineError> {
    let shipped_name = format!("reacher_{}", log.run.task);
    let shipped = perfect::text(&shipped_name).and_then(|_| perfect::load(&shipped_name).ok());
    if let Some(text) = &log.run.reward_machine {
        let rm = parse_rm(
            text,
            &format!("{}: /run reward_machine", log.path.display()),
        )
        .map_err(StoredMachineError)?;
        if let Some(s) = shipped.as_ref().filter(|s| write_rm(s) != write_rm(&rm)) {
            notes.push(format!(
                "the run's reward machine ({} states) differs from the shipped {} ({} states); re-tracking the stored one",
                rm.n_states(),
                perfect::source_name(&shipped_name),
                s.n_states()
            ));
        }
        return Ok(Some((rm, "stored in the run record".into())));
    }
    let logs_states = log.episodes.iter().any(|e| e.start.rm_state != NO_RM);
    match shipped {
        Some(rm) if logs_states => Ok(Some((
            rm,
            format!(
                "{} (the log stores none)",
                perfect::source_name(&shipped_name)
            ),
        ))),
        None if logs_states => {
            notes.push(format!(
                "the log has reward-machine states but no machine, and task '{}' has no shipped one: machine states are not checked",
                log.run.task
            ));
            Ok(None)
        }
        _ => Ok(None),
    }
}

/// Re-tracks a reward machine along the replayed labels of an episode.
struct RmCheck<'a> {
    rm: &'a RewardMachine,
    state: usize,
    success: bool,
}

impl RmCheck<'_> {
    /// Advances on `labels` and compares with the logged state and reward.
    fn step(&mut self, labels: LabelSet, logged_state: i64, logged_reward: f64) -> Option<Diff> {
        let (next, reward) = self.rm.step(self.state, labels);
        self.state = next;
        self.success |= self.rm.is_terminal(next) && !self.rm.is_failure(next);
        if logged_state != next as i64 {
            return Some((
                "rm_state".into(),
                logged_state.to_string(),
                next.to_string(),
            ));
        }
        first_diff("rm_reward", &[logged_reward], &[reward])
    }
}

fn replay_episode(
    env: &mut ReacherDelivery,
    ep: &LoggedEpisode,
    rm: Option<&RewardMachine>,
) -> Result<EpisodeReplay, EpisodeReplayError> {
    let start = &ep.start;
    let (mut obs, seed_reproduces_start) = restore_start(env, start)?;
    let mut result = EpisodeReplay {
        episode: start.episode,
        seed: start.seed,
        phase: start.phase.clone(),
        steps: ep.steps.len(),
        complete: ep.is_complete(),
        env_return: 0.0,
        label_events: String::new(),
        mismatch: None,
        seed_reproduces_start,
        rm_checked: false,
        branch: None,
    };
    let mismatch = |step: usize, (what, logged, replayed): Diff| Mismatch {
        step,
        what,
        logged,
        replayed,
    };
    // Episodes logged without a machine state are not checked against one.
    let mut rm_check = rm.filter(|_| start.rm_state != NO_RM).map(|rm| RmCheck {
        rm,
        state: rm.initial(),
        success: false,
    });
    if let Some(d) = start_diff(env, start, &obs, rm_check.as_ref()) {
        result.mismatch = Some(mismatch(0, d));
        return Ok(result);
    }
    result.rm_checked = rm_check.is_some();

    let mut replayed_labels = Vec::with_capacity(ep.steps.len());
    for (k, s) in ep.steps.iter().enumerate() {
        let n = k + 1;
        let out = match step_as_logged(env, s, n, &mut obs) {
            Ok(out) => out,
            Err(d) => {
                result.mismatch = Some(mismatch(n, d));
                break;
            }
        };
        result.env_return += out.reward;
        replayed_labels.push(out.labels);
        if let Some(d) = step_diff(env, s, &out, &obs, rm_check.as_mut()) {
            result.mismatch = Some(mismatch(n, d));
            break;
        }
    }

    result.label_events = label_runs(env.vocabulary(), &replayed_labels);
    let layout = Arc::clone(env.layout());
    let branches = rm.and_then(|rm| EventBranch::of(rm, layout.events()).map(|b| (rm, b)));
    result.branch = branches.map(|(rm, b)| b.of_labels(rm, replayed_labels));
    if let (Some(c), Some(end), None) = (&rm_check, &ep.end, &result.mismatch) {
        result.mismatch = end_diff(c, end).map(|d| mismatch(ep.steps.len(), d));
    }
    Ok(result)
}

/// Puts `env` in the logged start state (balls, event steps, joints) and returns its first
/// observation, and whether the episode's seed still produces that start (informative only).
fn restore_start(
    env: &mut ReacherDelivery,
    start: &EpisodeStartMsg,
) -> Result<(Vec<f32>, bool), EpisodeReplayError> {
    let layout = Arc::clone(env.layout());
    if start.balls.len() != 2 * layout.n_regions() {
        return Err(EpisodeReplayError::Regions {
            got: start.balls.len(),
            expected: 2 * layout.n_regions(),
        });
    }
    let positions: Vec<[f64; 2]> = start.balls.chunks_exact(2).map(|b| [b[0], b[1]]).collect();
    let event_steps = start.event_steps(layout.n_events());
    if event_steps.len() != layout.n_events() {
        return Err(EpisodeReplayError::EventSteps {
            got: event_steps.len(),
            expected: layout.n_events(),
        });
    }
    let mut obs = vec![0.0f32; layout.obs_dim()];
    env.reset(start.seed, &mut obs);
    let seed_reproduces_start = env.qpos() == start.qpos.as_slice()
        && env.qvel() == start.qvel.as_slice()
        && env.positions() == positions.as_slice()
        && env.event_steps() == event_steps.as_slice();
    env.restore_start(&start.qpos, &start.qvel, &positions, &event_steps, &mut obs)?;
    Ok((obs, seed_reproduces_start))
}

/// The first difference of the restored start from the logged one: labels, observation,
/// machine state.
fn start_diff(
    env: &ReacherDelivery,
    start: &EpisodeStartMsg,
    obs: &[f32],
    rm_check: Option<&RmCheck>,
) -> Option<Diff> {
    if env.labels().0 != start.labels {
        return Some((
            "labels".into(),
            format!("{:#x}", start.labels),
            format!("{:#x}", env.labels().0),
        ));
    }
    if let Some(d) = (!start.obs.is_empty())
        .then(|| first_diff("obs", &start.obs, obs))
        .flatten()
    {
        return Some(d);
    }
    rm_check
        .filter(|c| start.rm_state != c.state as i64)
        .map(|c| {
            (
                "rm_state".into(),
                start.rm_state.to_string(),
                c.state.to_string(),
            )
        })
}

/// Steps `env` with the logged action of step `n`, or says why that step cannot be taken
/// (its index, its action's length, a simulation error).
fn step_as_logged(
    env: &mut ReacherDelivery,
    s: &StepMsg,
    n: usize,
    obs: &mut [f32],
) -> Result<EnvStep, Diff> {
    if s.step as usize != n {
        return Err(("step index".into(), s.step.to_string(), n.to_string()));
    }
    if s.action.len() != ACT_DIM {
        return Err((
            "action length".into(),
            s.action.len().to_string(),
            ACT_DIM.to_string(),
        ));
    }
    env.step(&s.action, obs)
        .map_err(|e| ("simulation".into(), "a step".into(), format!("error: {e}")))
}

/// The first difference of a replayed step from the logged one: joints, labels, reward,
/// observation, truncation, then the machine's state and reward (which `rm_check` advances).
fn step_diff(
    env: &ReacherDelivery,
    s: &StepMsg,
    out: &EnvStep,
    obs: &[f32],
    rm_check: Option<&mut RmCheck>,
) -> Option<Diff> {
    first_diff("qpos", &s.qpos, env.qpos())
        .or_else(|| first_diff("qvel", &s.qvel, env.qvel()))
        .or_else(|| {
            (s.labels != out.labels.0).then(|| {
                (
                    "labels".into(),
                    format!("{:#x}", s.labels),
                    format!("{:#x}", out.labels.0),
                )
            })
        })
        .or_else(|| first_diff("reward", &[s.reward], &[out.reward]))
        .or_else(|| {
            (!s.obs.is_empty())
                .then(|| first_diff("obs", &s.obs, obs))
                .flatten()
        })
        .or_else(|| {
            (s.truncated != out.truncated).then(|| {
                (
                    "truncated".into(),
                    s.truncated.to_string(),
                    out.truncated.to_string(),
                )
            })
        })
        .or_else(|| rm_check.and_then(|c| c.step(out.labels, s.rm_state, s.rm_reward)))
}

/// The first difference of the re-tracked machine at the episode's end from the logged end:
/// its final state, then success.
fn end_diff(c: &RmCheck, end: &EpisodeEndMsg) -> Option<Diff> {
    if end.rm_state != c.state as i64 {
        Some((
            "final rm_state".into(),
            end.rm_state.to_string(),
            c.state.to_string(),
        ))
    } else if end.success != c.success {
        Some((
            "success".into(),
            end.success.to_string(),
            c.success.to_string(),
        ))
    } else {
        None
    }
}

impl fmt::Display for ReplayReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for note in &self.setting_notes {
            writeln!(f, "NOTE: {note}")?;
        }
        if let Some(rm) = &self.reward_machine {
            writeln!(
                f,
                "reward machine: {rm}; re-tracked along the replayed labels"
            )?;
        }
        for e in &self.episodes {
            let status = match &e.mismatch {
                None if e.rm_checked => "ok (bit-exact, RM states and rewards match)".to_string(),
                None => "ok (bit-exact)".to_string(),
                Some(m) => format!("MISMATCH at {m}"),
            };
            writeln!(
                f,
                "episode {:>5} [{}] seed {:>6}: {:>4} steps{}, return {:>9.3}, labels [{}]{}: {status}{}",
                e.episode,
                e.phase,
                e.seed,
                e.steps,
                if e.complete { "" } else { " (unfinished)" },
                e.env_return,
                e.label_events,
                e.branch.map_or(String::new(), |b| format!(", {b} branch")),
                if e.seed_reproduces_start {
                    ""
                } else {
                    " (note: reset(seed) no longer gives the logged start state)"
                },
            )?;
        }
        let rate = self.steps as f64 / self.elapsed_secs.max(1e-9);
        write!(
            f,
            "{} episodes, {} steps replayed in {:.3} s ({:.0} steps/s): {} match bit for bit, {} mismatch",
            self.episodes.len(),
            self.steps,
            self.elapsed_secs,
            rate,
            self.episodes.len() - self.mismatches(),
            self.mismatches()
        )
    }
}

/// A label trace as runs of one non-empty label set: `r@9–11` for steps 9 to 11 (steps
/// counted from 1), `c@3` for a single step, separated by spaces.
pub fn label_runs(vocab: &crate::rm::Vocabulary, labels: &[crate::rm::LabelSet]) -> String {
    let mut parts = Vec::new();
    let mut k = 0;
    while k < labels.len() {
        let l = labels[k];
        let mut end = k;
        while end + 1 < labels.len() && labels[end + 1] == l {
            end += 1;
        }
        if !l.is_empty() {
            let text = vocab.format_labels(l);
            parts.push(if end == k {
                format!("{text}@{}", k + 1)
            } else {
                format!("{text}@{}\u{2013}{}", k + 1, end + 1)
            });
        }
        k = end + 1;
    }
    parts.join(" ")
}
