//! Continuous SMIRL: MaxEnt IRL on the product U × O with a linear reward per RM state.
//!
//! The reward is `δ_r(u, o) = w_uᵀ φ(o)`, one weight vector per reward-machine state u
//! (paper section 3, eq. 5). Two feature maps, chosen explicitly and never swapped silently:
//!
//! - [`FeatureKind::Labels`] — the paper's choice, φ(o) = L(o) ∈ {0, 1}^{|P|}: bit k is 1 when
//!   ball k is touched (fingertip strictly within the touch radius), the last bit is the
//!   cancel flag. In a continuous space these bits are almost always 0 (a ball's touch disc,
//!   radius 0.02 m, is 0.9 % of the reachable disc of radius 0.21 m), so the reward is flat nearly everywhere and gives
//!   SAC almost no signal on how to reach a ball.
//! - [`FeatureKind::Smooth`] — a documented variant: φ_k(o) = exp(−d_k² / (2σ²)) for the
//!   fingertip–ball distance d_k, plus the same cancel flag. It keeps the paper's structure
//!   (linear in per-ball features, one weight vector per RM state) but has a gradient
//!   everywhere.
//!
//! Both are computed from the observation (the labelling function is a function of o, see
//! `env::reacher`), so a replay buffer only needs (o, u).
//!
//! # MaxEnt gradient
//!
//! With P_w(τ) ∝ exp(Σ_t δ_r(u_t, o_t)), the average log-likelihood of N_D expert
//! trajectories has gradient (Ziebart 2008; paper eq. 4)
//!
//! ```text
//! ∂ℓ/∂w_u = μ_D(u) − μ_π(u),   μ_X(u) = 1/N_X Σ_{τ∈X} Σ_t 1[u_t = u] φ(o_t),
//! ```
//!
//! feature counts summed along each trajectory and averaged over trajectories (*per-trajectory
//! normalisation*, so trajectories of different lengths weigh by what they visit), with μ_π
//! estimated from fresh agent rollouts of the policy that is soft-optimal for the current
//! reward. The sample surrogate whose gradient this is:
//!
//! ```text
//! ℓ̂(w) = 1/N_D Σ_{τ∈D} R_w(τ) − 1/N_A Σ_{τ∈A} R_w(τ) − λ/2 ‖w‖²,   R_w(τ) = Σ_t w_{u_t}ᵀ φ(o_t)
//! ```
//!
//! (the agent term stands in for log Z, whose gradient is the agent's feature expectation).
//! As a loss to minimise, L = −ℓ̂ has per-state coefficients c = +1/N_A at agent states and
//! −1/N_D at expert states ([`maxent_coefficients`]), the same form as the continuous MaxEnt
//! baseline (see [`super::firl::MaxEntCoefficients`]).
//!
//! **Which RM state goes with an observation.** Pair each observation o_t with the RM state
//! u the labels L(o_t) are *read in* (the state before the transition), i.e. the reward of a
//! step is δ_r(u_{t−1}, o_t), as `RewardMachine::step(u, labels)` pays rewards. The functions
//! here take whatever pairing the caller passes; expert and agent batches must use the same.

use super::reward::{
    check_batch, check_coefficients, check_len, save_bytes, RewardError, RewardModel,
    RewardOptimConfig, TensorOptimizer,
};
use crate::env::layout::TaskLayout;
use crate::input_file::{read_text, MAX_DATA_FILE_BYTES};
use crate::rm::LabelSet;
use std::path::Path;

/// Which features φ the linear reward reads.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum FeatureKind {
    /// φ = L(o), the label bits (the paper's choice).
    Labels,
    /// φ_k = exp(−d_k²/(2σ²)) per region, plus the event flags (documented variant).
    Smooth { sigma: f64 },
}

/// Where a feature map finds things in an observation row: the task's regions and events
/// ([`TaskLayout`]). Label bit k is region k, then one bit per event.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(into = "ObsLayoutFile", try_from = "ObsLayoutFile")]
pub struct ObsLayout {
    pub obs_dim: usize,
    /// Columns of (fingertip − region) x and y, one pair per region, in label-bit order.
    pub ball_deltas: Vec<[usize; 2]>,
    /// Column of each event's flag (1 on the step the event fires), in label-bit order.
    pub events: Vec<usize>,
    /// A region's label is true when the fingertip is strictly closer than its radius.
    pub radii: Vec<f64>,
}

/// [`ObsLayout`] as reward files write it: a task with one event names its column `cancel`,
/// and regions of one radius write it once as `touch_radius`, so the files of the paper's
/// tasks keep their form.
#[derive(serde::Serialize, serde::Deserialize)]
struct ObsLayoutFile {
    obs_dim: usize,
    ball_deltas: Vec<[usize; 2]>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    cancel: Option<usize>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    events: Option<Vec<usize>>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    touch_radius: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    radii: Option<Vec<f64>>,
}

impl From<ObsLayout> for ObsLayoutFile {
    fn from(l: ObsLayout) -> ObsLayoutFile {
        let one_radius = l
            .radii
            .first()
            .filter(|&&r| l.radii.iter().all(|&q| q == r));
        ObsLayoutFile {
            obs_dim: l.obs_dim,
            cancel: (l.events.len() == 1).then(|| l.events[0]),
            events: (l.events.len() != 1).then(|| l.events.clone()),
            touch_radius: one_radius.copied(),
            radii: one_radius.is_none().then(|| l.radii.clone()),
            ball_deltas: l.ball_deltas,
        }
    }
}

impl TryFrom<ObsLayoutFile> for ObsLayout {
    type Error = String;
    fn try_from(f: ObsLayoutFile) -> Result<ObsLayout, String> {
        let events = match (f.cancel, f.events) {
            (Some(c), None) => vec![c],
            (None, Some(e)) => e,
            _ => return Err("a layout gives exactly one of `cancel` and `events`".into()),
        };
        let radii = match (f.touch_radius, f.radii) {
            (Some(r), None) => vec![r; f.ball_deltas.len()],
            (None, Some(r)) if r.len() == f.ball_deltas.len() => r,
            _ => {
                return Err(
                    "a layout gives `touch_radius` or one radius per region in `radii`".into(),
                )
            }
        };
        Ok(ObsLayout {
            obs_dim: f.obs_dim,
            ball_deltas: f.ball_deltas,
            events,
            radii,
        })
    }
}

impl ObsLayout {
    /// The observation layout of a task (see `env::layout`).
    pub fn of(task: &TaskLayout) -> ObsLayout {
        ObsLayout {
            obs_dim: task.obs_dim(),
            ball_deltas: (0..task.n_regions())
                .map(|k| task.region_columns(k))
                .collect(),
            events: (0..task.n_events()).map(|e| task.event_column(e)).collect(),
            radii: task.regions.iter().map(|r| r.radius).collect(),
        }
    }
}

/// φ(o): one feature per region plus one per event.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct FeatureMap {
    pub kind: FeatureKind,
    pub layout: ObsLayout,
}

impl FeatureMap {
    pub fn new(kind: FeatureKind, layout: ObsLayout) -> Result<FeatureMap, RewardError> {
        if let FeatureKind::Smooth { sigma } = kind {
            if !(sigma.is_finite() && sigma > 0.0) {
                return Err(RewardError::Config(format!(
                    "smooth feature width sigma must be positive, got {sigma}"
                )));
            }
        }
        if layout.radii.len() != layout.ball_deltas.len() {
            return Err(RewardError::Config(format!(
                "{} region radii for {} regions",
                layout.radii.len(),
                layout.ball_deltas.len()
            )));
        }
        let bad = (layout.ball_deltas.iter().flatten())
            .chain(&layout.events)
            .find(|&&c| c >= layout.obs_dim)
            .copied();
        if let Some(column) = bad {
            return Err(RewardError::ColumnOutOfRange {
                column,
                obs_dim: layout.obs_dim,
            });
        }
        Ok(FeatureMap { kind, layout })
    }

    /// The paper's label features on a task's observations.
    pub fn reacher_labels(task: &TaskLayout) -> FeatureMap {
        FeatureMap {
            kind: FeatureKind::Labels,
            layout: ObsLayout::of(task),
        }
    }

    /// The smooth variant on a task's observations.
    pub fn reacher_smooth(task: &TaskLayout, sigma: f64) -> Result<FeatureMap, RewardError> {
        FeatureMap::new(FeatureKind::Smooth { sigma }, ObsLayout::of(task))
    }

    /// Number of features: regions + events; feature k is label bit k.
    pub fn len(&self) -> usize {
        self.layout.ball_deltas.len() + self.layout.events.len()
    }

    pub fn is_empty(&self) -> bool {
        false
    }

    pub fn obs_dim(&self) -> usize {
        self.layout.obs_dim
    }

    /// The label bits of the task's exogenous events.
    pub fn event_labels(&self) -> LabelSet {
        let nb = self.layout.ball_deltas.len();
        (0..self.layout.events.len()).fold(LabelSet::EMPTY, |s, e| s.with(nb + e))
    }

    /// Writes φ for one row into `out` (length [`FeatureMap::len`]).
    pub fn features(&self, row: &[f32], out: &mut [f64]) {
        let nb = self.layout.ball_deltas.len();
        for (k, [cx, cy]) in self.layout.ball_deltas.iter().enumerate() {
            let (dx, dy) = (f64::from(row[*cx]), f64::from(row[*cy]));
            let d2 = dx * dx + dy * dy;
            let r = self.layout.radii[k];
            out[k] = match self.kind {
                FeatureKind::Labels => f64::from(u8::from(d2 < r * r)),
                FeatureKind::Smooth { sigma } => (-d2 / (2.0 * sigma * sigma)).exp(),
            };
        }
        for (e, &c) in self.layout.events.iter().enumerate() {
            out[nb + e] = f64::from(u8::from(row[c] > 0.5));
        }
    }

    /// The label set of a row by the labelling rule: bit k for region k, then one bit per
    /// event flag — the same rule as the environment's labelling function. The environment decides on the
    /// `f64` positions and the observation carries `f32` offsets, so the two can disagree
    /// only for a fingertip within ~1e-9 m of a touch circle.
    pub fn labels_of(&self, row: &[f32]) -> LabelSet {
        let mut labels = LabelSet::EMPTY;
        for (k, [cx, cy]) in self.layout.ball_deltas.iter().enumerate() {
            let r = self.layout.radii[k];
            let (dx, dy) = (f64::from(row[*cx]), f64::from(row[*cy]));
            if dx * dx + dy * dy < r * r {
                labels = labels.with(k);
            }
        }
        let nb = self.layout.ball_deltas.len();
        for (e, &c) in self.layout.events.iter().enumerate() {
            if row[c] > 0.5 {
                labels = labels.with(nb + e);
            }
        }
        labels
    }
}

/// Trajectories of (observation, RM state) pairs, concatenated.
#[derive(Clone, Copy, Debug)]
pub struct AnnotatedTrajectories<'a> {
    /// Row-major observations of every step of every trajectory (Σ lengths rows).
    pub obs: &'a [f32],
    /// RM state paired with each observation row.
    pub rm_state: &'a [u32],
    /// Length of each trajectory, in order.
    pub lengths: &'a [usize],
}

/// Per-row coefficients of the loss −ℓ̂: +1/N_A at every agent row, −1/N_D at every expert
/// row (N_X: X's trajectories), so that the loss's gradient on w_u is μ_π(u) − μ_D(u) with
/// μ_X(u) = 1/N_X Σ_τ Σ_t 1[u_t = u] φ(o_t): the plain MaxEnt gradient, averaged over
/// trajectories.
pub fn maxent_coefficients(
    expert: &AnnotatedTrajectories<'_>,
    agent: &AnnotatedTrajectories<'_>,
) -> (Vec<f64>, Vec<f64>) {
    let per = |t: &AnnotatedTrajectories<'_>, sign: f64| {
        let total: usize = t.lengths.iter().sum();
        vec![sign / t.lengths.len() as f64; total]
    };
    (per(agent, 1.0), per(expert, -1.0))
}

fn check_state(u: u32, n_states: usize) -> Result<usize, RewardError> {
    if (u as usize) < n_states {
        Ok(u as usize)
    } else {
        Err(RewardError::RmStateOutOfRange { state: u, n_states })
    }
}

/// δ_r(u, o) = w_uᵀ φ(o): the SMIRL reward as a [`RewardModel`].
pub struct LinearRmReward {
    features: FeatureMap,
    n_states: usize,
    /// `n_states × n_features` row-major.
    weights: Vec<f32>,
    grad: Vec<f32>,
    optim: TensorOptimizer,
    phi: Vec<f64>,
}

/// The saved form of a [`LinearRmReward`].
#[derive(serde::Serialize, serde::Deserialize)]
struct LinearRmRewardFile {
    format: String,
    features: FeatureMap,
    n_states: usize,
    /// One weight vector per RM state.
    weights: Vec<Vec<f32>>,
}

const LINEAR_FORMAT: &str = "smirl-linear-rm-reward/1";

impl LinearRmReward {
    /// Zero weights (a flat reward) for `n_states` RM states.
    pub fn new(
        features: FeatureMap,
        n_states: usize,
        optim: RewardOptimConfig,
    ) -> Result<LinearRmReward, RewardError> {
        if n_states == 0 {
            return Err(RewardError::Config(
                "the reward machine has no state".into(),
            ));
        }
        let n = n_states * features.len();
        Ok(LinearRmReward {
            optim: TensorOptimizer::new(optim, &[n])?,
            phi: vec![0.0; features.len()],
            weights: vec![0.0; n],
            grad: vec![0.0; n],
            features,
            n_states,
        })
    }

    pub fn features(&self) -> &FeatureMap {
        &self.features
    }

    pub fn n_states(&self) -> usize {
        self.n_states
    }

    /// Weight vector w_u.
    pub fn weights(&self, u: usize) -> &[f32] {
        let k = self.features.len();
        &self.weights[u * k..(u + 1) * k]
    }

    /// Sets w_u to zero: the state pays nothing (a diagnostic: does this state's reward mislead
    /// the agent?).
    pub fn zero_state(&mut self, u: usize) -> Result<(), RewardError> {
        // A state beyond u32 is out of range too: no cast may wrap it onto a real one.
        let u = check_state(u32::try_from(u).unwrap_or(u32::MAX), self.n_states)?;
        let k = self.features.len();
        self.weights[u * k..(u + 1) * k].fill(0.0);
        Ok(())
    }

    /// Loads a reward saved by [`RewardModel::save`].
    pub fn load(path: &Path, optim: RewardOptimConfig) -> Result<LinearRmReward, RewardError> {
        let name = path.display().to_string();
        let text = read_text(path, MAX_DATA_FILE_BYTES).map_err(|source| RewardError::Io {
            path: name.clone(),
            source,
        })?;
        let file: LinearRmRewardFile =
            serde_json::from_str(&text).map_err(|e| RewardError::Config(format!("{name}: {e}")))?;
        if file.format != LINEAR_FORMAT {
            return Err(RewardError::Config(format!(
                "{name}: format {:?}, expected {LINEAR_FORMAT:?}",
                file.format
            )));
        }
        let features = FeatureMap::new(file.features.kind, file.features.layout)
            .map_err(|e| RewardError::Config(format!("{name}: {e}")))?;
        // The weights present bound the state count before anything is sized by it.
        let k = features.len();
        if file.weights.len() != file.n_states || file.weights.iter().any(|w| w.len() != k) {
            return Err(RewardError::Config(format!(
                "{name}: expected {} weight vectors of length {k}",
                file.n_states
            )));
        }
        let mut model = LinearRmReward::new(features, file.n_states, optim)?;
        model.weights = file.weights.concat();
        Ok(model)
    }
}

impl RewardModel for LinearRmReward {
    fn obs_dim(&self) -> usize {
        self.features.obs_dim()
    }

    fn reward_batch(
        &mut self,
        obs: &[f32],
        rm_state: &[u32],
        out: &mut [f32],
    ) -> Result<(), RewardError> {
        check_batch(obs, self.obs_dim(), rm_state, true, ("out", out.len()))?;
        let k = self.features.len();
        for ((row, &u), o) in obs.chunks_exact(self.obs_dim()).zip(rm_state).zip(out) {
            let u = check_state(u, self.n_states)?;
            self.features.features(row, &mut self.phi);
            let w = &self.weights[u * k..(u + 1) * k];
            *o = w
                .iter()
                .zip(&self.phi)
                .map(|(&w, p)| f64::from(w) * p)
                .sum::<f64>() as f32;
        }
        Ok(())
    }

    fn backward(
        &mut self,
        obs: &[f32],
        rm_state: &[u32],
        coeffs: &[f64],
    ) -> Result<(), RewardError> {
        check_batch(
            obs,
            self.obs_dim(),
            rm_state,
            true,
            ("coeffs", coeffs.len()),
        )?;
        check_coefficients(coeffs)?;
        let k = self.features.len();
        let mut grad = vec![0.0f64; self.weights.len()];
        for ((row, &u), &c) in obs.chunks_exact(self.obs_dim()).zip(rm_state).zip(coeffs) {
            let u = check_state(u, self.n_states)?;
            self.features.features(row, &mut self.phi);
            for (g, p) in grad[u * k..(u + 1) * k].iter_mut().zip(&self.phi) {
                *g += c * p;
            }
        }
        for (dst, g) in self.grad.iter_mut().zip(&grad) {
            *dst = *g as f32;
        }
        Ok(())
    }

    fn step(&mut self) {
        self.optim
            .step(&mut [(self.weights.as_mut_slice(), self.grad.as_mut_slice())]);
    }

    fn set_lr(&mut self, lr: f32) {
        self.optim.set_lr(lr);
    }

    fn num_params(&self) -> usize {
        self.weights.len()
    }

    fn params(&self) -> Vec<f32> {
        self.weights.clone()
    }

    fn set_params(&mut self, params: &[f32]) -> Result<(), RewardError> {
        check_len("params", params.len(), self.weights.len())?;
        self.weights.copy_from_slice(params);
        Ok(())
    }

    fn grad(&self) -> Vec<f32> {
        self.grad.clone()
    }

    fn save(&self, path: &Path) -> Result<(), RewardError> {
        let k = self.features.len();
        let file = LinearRmRewardFile {
            format: LINEAR_FORMAT.to_string(),
            features: self.features.clone(),
            n_states: self.n_states,
            weights: self.weights.chunks(k).map(|w| w.to_vec()).collect(),
        };
        let text = serde_json::to_string_pretty(&file)
            .map_err(|e| RewardError::Config(format!("serialising the reward: {e}")))?;
        save_bytes(path, text.as_bytes())
    }
}
