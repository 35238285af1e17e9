//! Label traces turned into compact integer arrays for the LRM cost.
//!
//! Traces are compressed (runs of one label set become one entry, since the objective is
//! about which *different* label comes next; with event stutter, see [`Data::new`], a step
//! that only drops an event from the previous entry's label set joins that entry), identical
//! compressed traces are stored once with a multiplicity, label sets are renumbered `0..L` in the order of their bit masks, and
//! everything is concatenated into flat arrays so that running a machine is a tight loop over
//! `u16`s.

use super::{LabelTrace, LrmError};
use crate::rm::labels::{LabelSet, Vocabulary};
use std::collections::BTreeMap;

/// Most distinct label sets the learner accepts (the count tables are states × L × L).
pub const MAX_OBSERVED_LABEL_SETS: usize = 256;

pub(crate) struct Data {
    /// Compact label id -> label set, sorted by bit mask.
    pub labels: Vec<LabelSet>,
    /// Label set index (`LabelSet::index`) -> compact id, `u16::MAX` when never observed.
    pub id_of: Vec<u16>,
    /// Concatenated compressed traces.
    pub lab: Vec<u16>,
    /// Reward id (index into `reward_values`) of the step that starts each position.
    pub rid: Vec<u8>,
    /// Multiplicity of the trace of each position.
    pub mult: Vec<u32>,
    /// Distinct rewards observed (sorted); empty when the traces carry none.
    pub reward_values: Vec<f64>,
    /// Weight of the prediction made at each position: the multiplicity of its trace, or 0 at
    /// the last position of a trace (nothing comes next).
    pub w: Vec<u32>,
    /// First position of each distinct compressed trace, plus the total length at the end.
    pub starts: Vec<usize>,
    /// Index of the trace each position belongs to.
    pub trace_of: Vec<u32>,
    /// Transitions in the raw traces.
    pub raw_len: usize,
    /// Compact label id -> id of the label set without the stutter events, when that is a
    /// different, nonempty, observed label set (a step reading it joins the entry); `None`
    /// otherwise (always, without event stutter).
    pub stutter_of: Vec<Option<u16>>,
    /// What the prediction made at each position counts as the next label: `lab[t + 1]`, or,
    /// with unpredicted events, the next entry whose label set differs from this one's once
    /// both leave the events out, as the first label id of that set (the position's own when
    /// no such entry follows; unused at a trace's last position, which predicts nothing).
    pub next: Vec<u16>,
}

/// How the learner reads the traces (both empty: LRM's reading).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct TraceReading {
    /// Propositions whose dropping is a stutter ([`LrmConfig::event_stutter`]).
    ///
    /// [`LrmConfig::event_stutter`]: super::LrmConfig::event_stutter
    pub stutter_events: LabelSet,
    /// Propositions the objective does not ask a machine to predict
    /// ([`LrmConfig::predict_events`]): the next label set is compared without them.
    ///
    /// [`LrmConfig::predict_events`]: super::LrmConfig::predict_events
    pub unpredicted_events: LabelSet,
}

impl Data {
    /// `reading.stutter_events`: the propositions whose dropping is a stutter
    /// ([`LrmConfig::event_stutter`] with the domain's events; empty = plain compression): a
    /// step whose label set is the
    /// previous entry's without these propositions, and not empty, joins that entry — the
    /// event is over, the lasting propositions it came with still hold (the fingertip is
    /// still on the ball it touched when the cancel fired).
    ///
    /// [`LrmConfig::event_stutter`]: super::LrmConfig::event_stutter
    pub fn new(
        vocab: &Vocabulary,
        traces: &[LabelTrace],
        reading: TraceReading,
    ) -> Result<Data, LrmError> {
        let stutter_events = reading.stutter_events;
        let n_sets = vocab.n_label_sets();
        let mut raw_len = 0;
        let mut seen = vec![false; n_sets];
        for (k, t) in traces.iter().enumerate() {
            for (step, l) in t.labels.iter().enumerate() {
                if l.index() >= n_sets {
                    return Err(LrmError::LabelOutOfRange {
                        trace: k,
                        step,
                        labels: l.0,
                        vocabulary: vocab.to_string(),
                    });
                }
                seen[l.index()] = true;
            }
            if let Some(r) = &t.rewards {
                if r.len() != t.labels.len() {
                    return Err(LrmError::RewardLength {
                        trace: k,
                        labels: t.labels.len(),
                        rewards: r.len(),
                    });
                }
                if let Some(step) = r.iter().position(|x| !x.is_finite()) {
                    return Err(LrmError::NonFiniteReward { trace: k, step });
                }
            }
            raw_len += t.labels.len();
        }
        let labels: Vec<LabelSet> = (0..n_sets as u32)
            .map(LabelSet)
            .filter(|l| seen[l.index()])
            .collect();
        if labels.len() > MAX_OBSERVED_LABEL_SETS {
            return Err(LrmError::TooManyLabelSets {
                observed: labels.len(),
                max: MAX_OBSERVED_LABEL_SETS,
            });
        }
        let mut id_of = vec![u16::MAX; n_sets];
        for (k, l) in labels.iter().enumerate() {
            id_of[l.index()] = k as u16;
        }
        let stutter_of: Vec<Option<u16>> = labels
            .iter()
            .map(|l| {
                let kept = LabelSet(l.0 & !stutter_events.0);
                (kept != *l && !kept.is_empty()).then(|| id_of[kept.index()])
            })
            .collect();
        // Distinct rewards (at most 256 ids are kept apart; more is not a reward machine's
        // output anyway, and the reward term is then dropped).
        let mut reward_values: Vec<f64> = traces
            .iter()
            .filter_map(|t| t.rewards.as_ref())
            .flatten()
            .copied()
            .collect();
        reward_values.sort_by(f64::total_cmp);
        reward_values.dedup();
        if reward_values.len() > 256 {
            reward_values.clear();
        }
        let reward_id = |r: f64| -> u8 {
            reward_values
                .binary_search_by(|x| x.total_cmp(&r))
                .map_or(0, |k| k as u8)
        };
        // Compress and deduplicate (BTreeMap: a deterministic order). A run of one label set
        // is one position, whose reward is that of the run's first step; a repeated step with
        // a nonzero reward starts a new position so that no reward is lost. With event
        // stutter, a step reading the previous entry's label set without its events joins it.
        let mut distinct: BTreeMap<(Vec<u16>, Vec<u8>), u64> = BTreeMap::new();
        for t in traces {
            let mut c: Vec<u16> = Vec::new();
            let mut r: Vec<u8> = Vec::new();
            for (k, l) in t.labels.iter().enumerate() {
                let id = id_of[l.index()];
                let reward = t.rewards.as_ref().map_or(0.0, |rs| rs[k]);
                let joins = c
                    .last()
                    .is_some_and(|&last| last == id || stutter_of[last as usize] == Some(id));
                if !joins || reward != 0.0 {
                    c.push(id);
                    r.push(reward_id(reward));
                }
            }
            if !c.is_empty() {
                *distinct.entry((c, r)).or_default() += 1;
            }
        }
        let total: usize = distinct.keys().map(|k| k.0.len()).sum();
        let mut lab = Vec::with_capacity(total);
        let mut w = Vec::with_capacity(total);
        let mut starts = Vec::with_capacity(distinct.len() + 1);
        let mut trace_of = Vec::with_capacity(total);
        let mut rid = Vec::with_capacity(total);
        let mut mults = Vec::with_capacity(total);
        for (k, ((c, r), &mult)) in distinct.iter().enumerate() {
            let mult = u32::try_from(mult).unwrap_or(u32::MAX);
            starts.push(lab.len());
            lab.extend_from_slice(c);
            rid.extend_from_slice(r);
            mults.extend(std::iter::repeat_n(mult, c.len()));
            w.extend(std::iter::repeat_n(mult, c.len() - 1));
            w.push(0);
            trace_of.extend(std::iter::repeat_n(k as u32, c.len()));
        }
        starts.push(lab.len());
        // Each label id's class: the first id whose set is the same once the unpredicted
        // events are left out (its own, without any).
        let unpredicted = reading.unpredicted_events.0;
        let class_of: Vec<u16> = labels
            .iter()
            .map(|l| {
                let kept = l.0 & !unpredicted;
                labels
                    .iter()
                    .position(|m| m.0 & !unpredicted == kept)
                    .unwrap_or(0) as u16 // `l` itself matches: never the fallback
            })
            .collect();
        // The first later entry of the trace that differs from this one once the events are
        // left out: an entry that only adds or drops an event ("{}, {c}, {}") is no news.
        // Without unpredicted events that is `lab[t + 1]` (compressed entries differ).
        let mut next = Vec::with_capacity(lab.len());
        for k in 0..starts.len() - 1 {
            let trace = &lab[starts[k]..starts[k + 1]];
            for (i, &here) in trace.iter().enumerate() {
                let own = class_of[here as usize];
                let news = trace[i + 1..]
                    .iter()
                    .map(|&l| class_of[l as usize])
                    .find(|&c| c != own);
                next.push(news.unwrap_or(own));
            }
        }
        Ok(Data {
            labels,
            id_of,
            lab,
            rid,
            mult: mults,
            reward_values,
            w,
            starts,
            trace_of,
            raw_len,
            stutter_of,
            next,
        })
    }

    pub fn n_labels(&self) -> usize {
        self.labels.len()
    }

    pub fn n_traces(&self) -> usize {
        self.starts.len() - 1
    }

    pub fn len(&self) -> usize {
        self.lab.len()
    }

    /// End (exclusive) of the trace that position `t` belongs to.
    #[inline]
    pub fn trace_end(&self, t: usize) -> usize {
        self.starts[self.trace_of[t] as usize + 1]
    }

    #[inline]
    pub fn is_start(&self, t: usize) -> bool {
        self.starts[self.trace_of[t] as usize] == t
    }
}

/// Natural logarithms of 0..=n (ln 0 is never used: empty cells have weight 0).
pub(crate) fn ln_table(n: usize) -> Vec<f64> {
    (0..=n)
        .map(|k| if k == 0 { 0.0 } else { (k as f64).ln() })
        .collect()
}

/// The objective from a histogram `hist[k]` = total weight of predictions made in cells
/// with `k` distinct successors: `Σ_k hist[k] · ln k`, summed in a fixed order so that the
/// same histogram always gives the same bits.
pub(crate) fn cost_of_hist(hist: &[i64], ln: &[f64]) -> f64 {
    hist.iter()
        .enumerate()
        .skip(2)
        .map(|(k, &h)| h as f64 * ln[k])
        .sum()
}
