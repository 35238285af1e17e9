//! Learning a reward machine offline from the label traces of rollout logs: each complete
//! logged episode becomes one LRM trace (its step labels, and the RM rewards when the run
//! logged a machine), the LRM Tabu search learns a machine, and it can be compared with a
//! reference machine (e.g. the perfect one in `assets/rm/`).

use crate::log::{read_log, LogError, RolloutLog, RunLayoutError};
use crate::rm::equiv::{counterexample, EquivError};
use crate::rm::lrm::{learn_rm, observed_label_sets, LabelTrace, LearnedRm, LrmConfig, LrmError};
use crate::rm::{LabelSet, RewardMachine, Vocabulary, VocabularyError};
use std::path::PathBuf;

#[derive(Debug, thiserror::Error)]
pub enum OfflineRmError {
    #[error(transparent)]
    Log(#[from] LogError),
    #[error("{path}: {recovery}; pass --allow-partial to learn from its complete episodes")]
    Partial { path: PathBuf, recovery: String },
    #[error("{path}: vocabulary \"{found}\" differs from \"{expected}\" of the first log")]
    Vocabulary {
        path: PathBuf,
        found: String,
        expected: String,
    },
    #[error("{path}: vocabulary \"{vocabulary}\" is invalid: {problem}")]
    BadVocabulary {
        path: PathBuf,
        vocabulary: String,
        problem: VocabularyError,
    },
    #[error("{path}: its task declares the events \"{found}\", the first log's \"{expected}\"")]
    Events {
        path: PathBuf,
        found: String,
        expected: String,
    },
    #[error("{path}: {problem}")]
    TaskLayout {
        path: PathBuf,
        problem: RunLayoutError,
    },
    #[error("the logs contain no complete episode to learn from")]
    NoTraces,
    #[error("LRM: {0}")]
    Lrm(#[from] LrmError),
    #[error("comparison: {0}")]
    Equiv(#[from] EquivError),
}

/// Traces extracted from logs.
#[derive(Clone, Debug)]
pub struct LogTraces {
    pub vocabulary: Vocabulary,
    /// The exogenous events the logs' task declares (their `/run` record's task layout);
    /// none for a log whose vocabulary is not its layout's (a log written without a task).
    pub events: LabelSet,
    pub traces: Vec<LabelTrace>,
    /// Recovery notes for truncated files, naming them.
    pub warnings: Vec<String>,
    /// Episodes skipped because they were unfinished.
    pub skipped_unfinished: usize,
}

/// Turns complete episodes into traces. RM rewards are used when every log recorded a
/// machine (`rm_state >= 0` on every step), else the traces carry no rewards.
pub fn traces_from_logs(logs: &[RolloutLog]) -> Result<LogTraces, OfflineRmError> {
    let first = logs.first().ok_or(OfflineRmError::NoTraces)?;
    let vocabulary = Vocabulary::parse(&first.run.vocabulary).map_err(|problem| {
        OfflineRmError::BadVocabulary {
            path: first.path.clone(),
            vocabulary: first.run.vocabulary.clone(),
            problem,
        }
    })?;
    let events = declared_events(first)?;
    let mut traces = Vec::new();
    let mut warnings = Vec::new();
    let mut skipped_unfinished = 0;
    let with_rewards = logs.iter().all(|l| {
        l.episodes
            .iter()
            .all(|e| e.steps.iter().all(|s| s.rm_state >= 0))
    });
    for log in logs {
        if log.run.vocabulary != first.run.vocabulary {
            return Err(OfflineRmError::Vocabulary {
                path: log.path.clone(),
                found: log.run.vocabulary.clone(),
                expected: first.run.vocabulary.clone(),
            });
        }
        let found = declared_events(log)?;
        if found != events {
            return Err(OfflineRmError::Events {
                path: log.path.clone(),
                found: vocabulary.format_labels(found),
                expected: vocabulary.format_labels(events),
            });
        }
        if let Some(rec) = &log.recovery {
            warnings.push(format!("{}: {rec}", log.path.display()));
        }
        for ep in &log.episodes {
            if !ep.is_complete() {
                skipped_unfinished += 1;
                continue;
            }
            traces.push(LabelTrace {
                labels: ep.steps.iter().map(|s| LabelSet(s.labels)).collect(),
                rewards: with_rewards.then(|| ep.steps.iter().map(|s| s.rm_reward).collect()),
            });
        }
    }
    if traces.is_empty() {
        return Err(OfflineRmError::NoTraces);
    }
    Ok(LogTraces {
        vocabulary,
        events,
        traces,
        warnings,
        skipped_unfinished,
    })
}

/// The events `log`'s task declares: its recorded task layout's, when the layout's letters
/// are the log's vocabulary (a log without a record is read as the shipped task of its name);
/// none otherwise (a log written without a task, e.g. by `smirl.write_log` over letters of its
/// own).
fn declared_events(log: &RolloutLog) -> Result<LabelSet, OfflineRmError> {
    let layout = log
        .run
        .task_layout()
        .map_err(|problem| OfflineRmError::TaskLayout {
            path: log.path.clone(),
            problem,
        })?;
    Ok(if layout.letters() == log.run.vocabulary {
        layout.events()
    } else {
        LabelSet::EMPTY
    })
}

/// Reads the logs and extracts their traces. A log cut short (see
/// [`crate::log::RolloutLog::recovery`]) is an error unless `allow_partial`.
pub fn traces_from_files(
    paths: &[PathBuf],
    allow_partial: bool,
) -> Result<LogTraces, OfflineRmError> {
    let logs = paths
        .iter()
        .map(|p| read_log(p))
        .collect::<Result<Vec<_>, _>>()?;
    if !allow_partial {
        if let Some(log) = logs.iter().find(|l| l.recovery.is_some()) {
            return Err(OfflineRmError::Partial {
                path: log.path.clone(),
                recovery: log.recovery.as_ref().expect("found").to_string(),
            });
        }
    }
    traces_from_logs(&logs)
}

/// Result of learning from logs.
#[derive(Clone, Debug)]
pub struct OfflineRm {
    pub learned: LearnedRm,
    pub traces: LogTraces,
}

pub fn learn_from_files(
    paths: &[PathBuf],
    cfg: &LrmConfig,
    allow_partial: bool,
) -> Result<OfflineRm, OfflineRmError> {
    let traces = traces_from_files(paths, allow_partial)?;
    let learned = learn_rm(&traces.vocabulary, &traces.traces, cfg)?;
    Ok(OfflineRm { learned, traces })
}

/// How a learned machine compares with a reference one.
#[derive(Clone, Debug, PartialEq)]
pub struct Comparison {
    /// Same rewards on every sequence over the label sets seen in the traces.
    pub equivalent: bool,
    /// A shortest sequence on which they differ, as text (`"r g c"`), when not equivalent.
    pub counterexample: Option<String>,
    /// Same rewards on every such sequence up to the step where the reference reaches a
    /// terminal state (where episodes end, so logs never show what follows).
    pub equivalent_until_done: bool,
    pub counterexample_until_done: Option<String>,
}

/// A state of each machine.
type Pair = (usize, usize);

/// Shortest label sequence (over `alphabet`) on which `a` and `b` pay different rewards,
/// exploring only while `b` has not reached a terminal state: breadth-first search on the
/// product of the two machines.
pub fn counterexample_until_done(
    a: &RewardMachine,
    b: &RewardMachine,
    alphabet: &[LabelSet],
) -> Option<Vec<LabelSet>> {
    use std::collections::{HashMap, VecDeque};
    let start = (a.initial(), b.initial());
    let mut parent: HashMap<Pair, Option<(Pair, LabelSet)>> = HashMap::from([(start, None)]);
    let mut queue = VecDeque::from([start]);
    let path_to = |parent: &HashMap<Pair, Option<(Pair, LabelSet)>>, mut at, last| {
        let mut seq = vec![last];
        while let Some(Some((prev, l))) = parent.get(&at) {
            seq.push(*l);
            at = *prev;
        }
        seq.reverse();
        seq
    };
    while let Some((ua, ub)) = queue.pop_front() {
        if b.is_terminal(ub) {
            continue;
        }
        for &l in alphabet {
            let (na, ra) = a.step(ua, l);
            let (nb, rb) = b.step(ub, l);
            if (ra - rb).abs() > crate::rm::equiv::REWARD_TOL {
                return Some(path_to(&parent, (ua, ub), l));
            }
            if let std::collections::hash_map::Entry::Vacant(e) = parent.entry((na, nb)) {
                e.insert(Some(((ua, ub), l)));
                queue.push_back((na, nb));
            }
        }
    }
    None
}

fn sequence_text(vocab: &Vocabulary, seq: &[LabelSet]) -> String {
    seq.iter()
        .map(|&l| {
            let t = vocab.format_labels(l);
            if t.is_empty() {
                "{}".to_string()
            } else {
                t
            }
        })
        .collect::<Vec<_>>()
        .join(" ")
}

/// Compares `learned` with `reference` over the label sets observed in `traces` (the learned
/// machine says nothing about label sets it never saw).
pub fn compare(
    learned: &RewardMachine,
    reference: &RewardMachine,
    traces: &[LabelTrace],
) -> Result<Comparison, OfflineRmError> {
    let alphabet = observed_label_sets(traces);
    let cex = counterexample(learned, reference, Some(&alphabet))?;
    let cex_done = counterexample_until_done(learned, reference, &alphabet);
    let vocab = learned.vocab();
    Ok(Comparison {
        equivalent: cex.is_none(),
        counterexample: cex.map(|seq| sequence_text(vocab, &seq)),
        equivalent_until_done: cex_done.is_none(),
        counterexample_until_done: cex_done.map(|seq| sequence_text(vocab, &seq)),
    })
}
