//! The Office Gridworld experiments (paper section 4.2, figures 4 and 5): demonstrations from
//! the task's expert, then one IRL algorithm, with the learned policy evaluated under the
//! ground-truth task after every IRL step.
//!
//! - **SMIRL**: learn a reward machine from the demonstrations' label traces (LRM Tabu
//!   search), annotate the demonstrations with its states, MaxEnt IRL on (learned RM × cells)
//!   with `δ_r(u, o) = w_uᵀ L(o)`.
//! - **MaxEnt**: the same MaxEnt IRL on cells only (one-state machine), reward `wᵀ L(o)`.
//! - **Apprenticeship**: projection method on the label features (one per letter, and none).
//!
//! The policy evaluated at each step is the greedy policy of discounted value iteration on
//! the learned reward over the algorithm's own state space (for SMIRL the learned product),
//! rolled out for the evaluation horizon from the start cell without reset; its return under
//! the task's perfect machine is 1 when the task is completed, else 0 (success = return).

use crate::env::office::{OfficeTask, OfficeWorld};
use crate::irl::tabular::maxent::MaxEntError;
use crate::irl::tabular::{
    evaluate_policy, greedy_policy, trivial_rm, Apprenticeship, ApprenticeshipConfig,
    ApprenticeshipError, DemoConfig, Demonstration, MaxEntConfig, OfficeExpert, ProductIrl,
};
use crate::report::CsvTable;
use crate::rl::tabular::{finite_horizon_greedy, TabularError};
use crate::rm::lrm::LrmError;
use crate::rm::RewardMachine;
use std::time::Instant;

/// The algorithms of the comparison (`Algo::OFFICE` runs here).
pub use crate::irl::Algo;

/// Where SMIRL's reward machine comes from.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Structure {
    /// Learned from the demonstrations (the paper's algorithm).
    #[default]
    Learned,
    /// The task's perfect machine (an oracle ablation).
    Perfect,
}

/// Most demonstrations of an Office run.
pub const MAX_OFFICE_DEMOS: usize = 100_000;
/// Longest Office episode (demonstrations and evaluation).
pub const MAX_OFFICE_HORIZON: usize = 10_000;
/// Most LRM threads.
pub const MAX_OFFICE_THREADS: usize = 256;

/// Demonstration settings (the seed comes from the run).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct DemoSettings {
    pub n_demos: usize,
    pub horizon: usize,
    pub random_steps: usize,
}

impl Default for DemoSettings {
    fn default() -> Self {
        DemoSettings {
            n_demos: 50,
            horizon: 100,
            random_steps: 5,
        }
    }
}

/// LRM settings (the seed comes from the run).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct LrmSettings {
    pub max_states: usize,
    pub tabu_len: usize,
    pub max_steps: usize,
    pub threads: usize,
}

impl Default for LrmSettings {
    fn default() -> Self {
        LrmSettings {
            max_states: 10,
            tabu_len: 100,
            max_steps: 100,
            threads: 1,
        }
    }
}

/// How a MaxEnt-learned reward (SMIRL, MaxEnt baseline) becomes the evaluated policy.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum EvalPolicy {
    /// The optimal stationary policy for discount `eval.gamma` (exact policy iteration).
    /// With γ = 0.99 the effective horizon 1/(1 − γ) is the demonstration horizon.
    #[default]
    Discounted,
    /// Optimal for a finite horizon (the evaluation horizon) with the MaxEnt discount,
    /// time-indexed. An ablation: it plans to the horizon's end, and routes through weakly
    /// identified rewards of rarely visited states when that aligns a reward cycle with the
    /// end (see the report).
    FiniteHorizon,
}

/// Evaluation settings.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct EvalSettings {
    pub policy: EvalPolicy,
    /// Discount of the evaluated policy (`policy = "discounted"`).
    pub gamma: f64,
    /// Rollout length; 0 = the demonstration horizon.
    pub horizon: usize,
}

impl Default for EvalSettings {
    fn default() -> Self {
        EvalSettings {
            policy: EvalPolicy::Discounted,
            gamma: 0.99,
            horizon: 0,
        }
    }
}

#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SmirlSettings {
    pub structure: Structure,
}

/// Everything an Office run is configured by (TOML; every section and field optional).
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct OfficeConfig {
    pub demos: DemoSettings,
    pub maxent: MaxEntConfig,
    pub apprenticeship: ApprenticeshipConfig,
    pub lrm: LrmSettings,
    pub eval: EvalSettings,
    pub smirl: SmirlSettings,
}

/// A configuration that cannot run.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum OfficeError {
    #[error("invalid configuration: {0}")]
    Config(String),
    #[error("learning the reward machine: {0}")]
    Lrm(LrmError),
    /// The product MDP, its planning and policy evaluation.
    #[error(transparent)]
    Tabular(TabularError),
    #[error(transparent)]
    MaxEnt(MaxEntError),
    #[error(transparent)]
    Apprenticeship(ApprenticeshipError),
}

/// The key a nested config's error is about: `table`, then the setting its message names
/// before ` = ` (`"bad setting: lr = 0 must be > 0"` under `maxent` → `maxent.lr`); the
/// table alone when the message names none.
fn nested_key(table: &str, message: &str) -> String {
    match message
        .split(" = ")
        .next()
        .and_then(|m| m.split_whitespace().last())
    {
        Some(key) if message.contains(" = ") => format!("{table}.{key}"),
        _ => table.to_string(),
    }
}

impl OfficeConfig {
    /// Parses TOML text (unknown fields are errors); an error names the line of the key it
    /// is about.
    pub fn from_toml(text: &str) -> Result<OfficeConfig, OfficeError> {
        let cfg: OfficeConfig = toml::from_str(text)
            .map_err(|e| OfficeError::Config(crate::config_text::toml_error_message(text, &e)))?;
        if let Some((key, message)) = cfg.invalid_setting() {
            return Err(OfficeError::Config(
                match crate::config_text::key_line(text, &key) {
                    Some(line) => format!("line {line}: {message}"),
                    None => message,
                },
            ));
        }
        Ok(cfg)
    }

    pub fn validate(&self) -> Result<(), OfficeError> {
        match self.invalid_setting() {
            Some((_, message)) => Err(OfficeError::Config(message)),
            None => Ok(()),
        }
    }

    /// The first setting out of its range: its dotted key and the message.
    fn invalid_setting(&self) -> Option<(String, String)> {
        let bad = |key: &str, message: String| Some((key.to_string(), message));
        if self.demos.n_demos == 0 {
            return bad("demos.n_demos", "demos.n_demos must be ≥ 1".into());
        }
        if self.demos.horizon == 0 {
            return bad("demos.horizon", "demos.horizon must be ≥ 1".into());
        }
        if let Err(e) = self.maxent.validate() {
            let message = e.to_string();
            return Some((nested_key("maxent", &message), format!("maxent: {message}")));
        }
        if let Err(e) = self.apprenticeship.validate() {
            let message = e.to_string();
            return Some((
                nested_key("apprenticeship", &message),
                format!("apprenticeship: {message}"),
            ));
        }
        if !(self.eval.gamma > 0.0 && self.eval.gamma < 1.0) {
            return bad(
                "eval.gamma",
                format!("eval.gamma = {} must be in (0, 1)", self.eval.gamma),
            );
        }
        if self.lrm.max_states < 1 {
            return bad("lrm.max_states", "lrm.max_states must be ≥ 1".into());
        }
        if self.lrm.threads < 1 {
            return bad("lrm.threads", "lrm.threads must be ≥ 1".into());
        }
        for (field, value, limit) in [
            ("demos.n_demos", self.demos.n_demos, MAX_OFFICE_DEMOS),
            ("demos.horizon", self.demos.horizon, MAX_OFFICE_HORIZON),
            ("eval.horizon", self.eval.horizon, MAX_OFFICE_HORIZON),
            (
                "lrm.max_states",
                self.lrm.max_states,
                crate::rm::lrm::MAX_STATES,
            ),
            ("lrm.threads", self.lrm.threads, MAX_OFFICE_THREADS),
        ] {
            if value > limit {
                return bad(
                    field,
                    format!("{field} = {value} is more than the limit of {limit}"),
                );
            }
        }
        None
    }

    pub fn eval_horizon(&self) -> usize {
        if self.eval.horizon == 0 {
            self.demos.horizon
        } else {
            self.eval.horizon
        }
    }
}

/// One IRL step's ground-truth evaluation.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StepMetrics {
    /// 0 = before any update (initial parameters).
    pub step: usize,
    /// Environment steps the algorithm has sampled so far (0 for the exact, model-based
    /// MaxEnt forward passes).
    pub env_interactions: usize,
    pub gt_return: f64,
    pub success: bool,
    /// MaxEnt: mean demonstration log-likelihood; apprenticeship: the margin ‖μ_E − μ̄‖.
    pub objective: f64,
    /// Apprenticeship: the expected ground-truth return of the projection method's mixture
    /// policy (whose feature expectation is μ̄); NaN for the other algorithms.
    pub mixture_return: f64,
    /// Seconds since the start of the run.
    pub elapsed_s: f64,
}

/// Wall-clock split of a run.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Timings {
    pub demos_s: f64,
    pub rm_learning_s: f64,
    pub irl_s: f64,
    pub total_s: f64,
}

/// What one algorithm produced on one seed.
#[derive(Clone, Debug)]
pub struct OfficeRun {
    /// The task's name.
    pub task: String,
    pub algo: Algo,
    pub seed: u64,
    pub steps: Vec<StepMetrics>,
    /// SMIRL's machine (learned or perfect, per the configuration).
    pub rm: Option<RewardMachine>,
    /// Learned reward weights: one row per machine state (one row for the baselines).
    pub weights: Vec<Vec<f64>>,
    /// Column names of `weights`.
    pub weight_columns: Vec<String>,
    /// The optimiser met its convergence test before its step limit.
    pub converged: bool,
    /// SMIRL: along the demonstrations, the perfect machine's state is a function of the
    /// learned machine's state.
    pub refines_perfect: Option<bool>,
    pub timings: Timings,
}

impl OfficeRun {
    pub fn final_success(&self) -> bool {
        self.steps.last().is_some_and(|s| s.success)
    }
}

/// Demonstrations of `task` for a run seed.
pub fn demonstrations(task: &OfficeTask, settings: &DemoSettings, seed: u64) -> Vec<Demonstration> {
    OfficeExpert::new(task).demonstrations(&DemoConfig {
        n_demos: settings.n_demos,
        horizon: settings.horizon,
        random_steps: settings.random_steps,
        seed,
    })
}

/// Demonstrations as a table: one row per step with the cell before and after it, the
/// labels of the cell landed on, the action, the expert's perfect-machine state after the
/// step and the task reward (step −1 rows give the start cell and its labels).
pub fn demonstrations_table(demos: &[Demonstration], world: &OfficeWorld) -> CsvTable {
    let v = world.vocab();
    let mut t = CsvTable::new([
        "demo", "step", "x", "y", "action", "next_x", "next_y", "labels", "rm_state", "reward",
    ]);
    for (i, d) in demos.iter().enumerate() {
        let (x0, y0) = world.xy(d.start_cell);
        t.push([
            i.to_string(),
            "-1".into(),
            String::new(),
            String::new(),
            String::new(),
            x0.to_string(),
            y0.to_string(),
            v.format_labels(d.start_labels),
            String::new(),
            String::new(),
        ]);
        for s in 0..d.len() {
            let (x, y) = world.xy(d.cell_before(s));
            let (nx, ny) = world.xy(d.cells[s] as usize);
            t.push([
                i.to_string(),
                s.to_string(),
                x.to_string(),
                y.to_string(),
                d.actions[s].to_string(),
                nx.to_string(),
                ny.to_string(),
                v.format_labels(d.labels[s]),
                d.rm_states[s].to_string(),
                d.rewards[s].to_string(),
            ]);
        }
    }
    t
}

/// Whether the perfect machine's state before each step is a function of `model`'s state
/// along the demonstrations (the perfect machine restarts after each completed trip, as the
/// expert's does).
pub fn refines_along(
    model: &RewardMachine,
    perfect: &RewardMachine,
    demos: &[Demonstration],
) -> bool {
    let mut seen: Vec<Option<usize>> = vec![None; model.n_states()];
    for d in demos {
        let mut u = model.next_state(model.initial(), d.start_labels);
        let mut p = perfect.initial();
        for t in 0..d.len() {
            match seen[u] {
                None => seen[u] = Some(p),
                Some(q) if q != p => return false,
                _ => {}
            }
            u = model.next_state(u, d.labels[t]);
            let p2 = d.rm_states[t] as usize;
            p = if perfect.is_terminal(p2) {
                perfect.initial()
            } else {
                p2
            };
        }
    }
    true
}

/// Learns SMIRL's reward machine from the demonstrations' label traces.
pub fn learn_structure(
    world: &OfficeWorld,
    demos: &[Demonstration],
    settings: &LrmSettings,
    seed: u64,
) -> Result<RewardMachine, OfficeError> {
    use crate::rm::lrm::{learn_rm, LabelTrace, LrmConfig};
    let traces: Vec<LabelTrace> = demos
        .iter()
        .filter(|d| !d.is_empty())
        .map(|d| LabelTrace {
            // L(o_0) first: the paper's objective sums over o_0 … o_T, and without it the
            // initial state is never asked to predict the first label, so nothing keeps it
            // apart from states reached later.
            labels: d.label_trace(),
            rewards: None,
        })
        .collect();
    let cfg = LrmConfig {
        max_states: settings.max_states,
        tabu_len: settings.tabu_len,
        max_steps: settings.max_steps,
        seed,
        threads: settings.threads,
        // Merging joins states the observed rewards cannot tell apart; SMIRL has no rewards
        // (they are what IRL learns), so it would collapse the machine to one state.
        merge: false,
        // The reward term and the other options stay at the learner's defaults (without
        // rewards the reward term is ignored).
        ..LrmConfig::default()
    };
    learn_rm(world.vocab(), &traces, &cfg)
        .map(|learned| learned.rm)
        .map_err(OfficeError::Lrm)
}

/// Runs one algorithm on one task and seed. `progress` receives a line per IRL step.
pub fn run(
    task: &OfficeTask,
    algo: Algo,
    seed: u64,
    cfg: &OfficeConfig,
    progress: &mut dyn FnMut(&str),
) -> Result<OfficeRun, OfficeError> {
    cfg.validate()?;
    let t0 = Instant::now();
    let demos = demonstrations(task, &cfg.demos, seed);
    let mut run = OfficeRun {
        task: task.name().to_string(),
        algo,
        seed,
        steps: Vec::new(),
        rm: None,
        weights: Vec::new(),
        weight_columns: Vec::new(),
        converged: false,
        refines_perfect: None,
        timings: Timings {
            demos_s: t0.elapsed().as_secs_f64(),
            ..Timings::default()
        },
    };
    match algo {
        Algo::Smirl | Algo::MaxEnt => {
            maxent_on_product(task, &demos, cfg, t0, &mut run, progress)?;
        }
        Algo::Apprenticeship => apprenticeship(task, &demos, cfg, t0, &mut run, progress)?,
        Algo::SmirlPaper
        | Algo::SmirlSmooth
        | Algo::Fkl
        | Algo::Rkl
        | Algo::Js
        | Algo::MaxEntProduct
        | Algo::FklProduct => {
            return Err(OfficeError::Config(format!(
                "{algo} is not an Office algorithm (smirl, maxent, apprenticeship)"
            )));
        }
    }
    run.timings.total_s = t0.elapsed().as_secs_f64();
    Ok(run)
}

/// SMIRL (on the learned or the perfect machine, per `cfg.smirl.structure`) and MaxEnt (on the
/// one-state machine): exact MaxEnt IRL on the product U × O, evaluated on the ground truth
/// after every optimiser step. Fills `run`'s steps, machine, weights and timings.
fn maxent_on_product(
    task: &OfficeTask,
    demos: &[Demonstration],
    cfg: &OfficeConfig,
    t0: Instant,
    run: &mut OfficeRun,
    progress: &mut dyn FnMut(&str),
) -> Result<(), OfficeError> {
    let (algo, seed) = (run.algo, run.seed);
    let world = task.world();
    let gt = task.rm();
    let horizon = cfg.eval_horizon();
    let t_rm = Instant::now();
    let model = match (algo, cfg.smirl.structure) {
        (Algo::MaxEnt, _) => trivial_rm(world.vocab()),
        (_, Structure::Perfect) => gt.clone(),
        (_, Structure::Learned) => learn_structure(world, demos, &cfg.lrm, seed)?,
    };
    run.timings.rm_learning_s = t_rm.elapsed().as_secs_f64();
    if algo == Algo::Smirl {
        run.refines_perfect = Some(refines_along(&model, gt, demos));
        progress(&format!(
            "{} seed {seed}: reward machine with {} states ({:.2} s), refines the perfect one: {}",
            algo.name(),
            model.n_states(),
            run.timings.rm_learning_s,
            run.refines_perfect == Some(true)
        ));
    }
    let t_irl = Instant::now();
    let product = ProductIrl::new(world, model).map_err(OfficeError::Tabular)?;
    let annotated = product.annotate(demos);
    let mut irl = product
        .maxent(&annotated, cfg.maxent)
        .map_err(OfficeError::MaxEnt)?;
    let mut warm = Vec::new();
    let evaluate = |theta: &[f64], warm: &mut Vec<u8>| {
        let reward = product.features.reward(theta);
        let policy = match cfg.eval.policy {
            EvalPolicy::Discounted => greedy_policy(&product.mdp, &reward, cfg.eval.gamma, warm),
            EvalPolicy::FiniteHorizon => {
                let mut actions = Vec::new();
                finite_horizon_greedy(
                    &product.mdp,
                    &reward,
                    cfg.maxent.gamma,
                    horizon,
                    &mut actions,
                )
                .map(|_| actions)
            }
        }
        .map_err(OfficeError::Tabular)?;
        Ok::<_, OfficeError>(evaluate_policy(
            world,
            &product.model_rm,
            &policy,
            gt,
            horizon,
        ))
    };
    let e0 = evaluate(&irl.theta, &mut warm)?;
    run.steps.push(StepMetrics {
        step: 0,
        env_interactions: 0,
        gt_return: e0.gt_return,
        success: e0.success,
        objective: f64::NAN,
        mixture_return: f64::NAN,
        elapsed_s: t0.elapsed().as_secs_f64(),
    });
    for m in 1..=cfg.maxent.max_steps {
        irl.step().map_err(OfficeError::MaxEnt)?;
        // Likelihood and gradient at the new parameters (cached by L-BFGS).
        let info = irl.current_info().map_err(OfficeError::MaxEnt)?;
        run.converged = irl.converged(&info);
        let e = evaluate(&irl.theta, &mut warm)?;
        run.steps.push(StepMetrics {
            step: m,
            env_interactions: 0,
            gt_return: e.gt_return,
            success: e.success,
            objective: info.log_likelihood,
            mixture_return: f64::NAN,
            elapsed_s: t0.elapsed().as_secs_f64(),
        });
        if m % 25 == 0 || run.converged {
            progress(&format!(
                "{} seed {seed} step {m}: log-lik {:.4}, |grad| {:.2e}, success {}",
                algo.name(),
                info.log_likelihood,
                info.grad_max,
                e.success
            ));
        }
        if run.converged {
            break;
        }
    }
    run.timings.irl_s = t_irl.elapsed().as_secs_f64();
    run.weights = product.weight_rows(&irl.theta);
    run.weight_columns = world
        .vocab()
        .props()
        .iter()
        .map(|c| c.to_string())
        .collect();
    if algo == Algo::Smirl {
        run.rm = Some(product.model_rm.clone());
    }
    Ok(())
}

/// Apprenticeship IRL (Abbeel and Ng's projection method) on the observations alone, each
/// policy of its sequence evaluated on the ground truth. Fills `run`'s steps, weights and
/// timings.
fn apprenticeship(
    task: &OfficeTask,
    demos: &[Demonstration],
    cfg: &OfficeConfig,
    t0: Instant,
    run: &mut OfficeRun,
    progress: &mut dyn FnMut(&str),
) -> Result<(), OfficeError> {
    let (algo, seed) = (run.algo, run.seed);
    let world = task.world();
    let gt = task.rm();
    let horizon = cfg.eval_horizon();
    let t_irl = Instant::now();
    let mut app = Apprenticeship::new(world, demos, cfg.apprenticeship, seed)
        .map_err(OfficeError::Apprenticeship)?;
    let one_state = trivial_rm(world.vocab());
    let mut interactions = 0;
    let mut step = 0;
    let mut weights = Vec::new();
    let mut returns = Vec::new();
    while !app.done() {
        let s = app.step().map_err(OfficeError::Tabular)?;
        interactions += s.interactions;
        let e = evaluate_policy(world, &one_state, &s.policy, gt, horizon);
        returns.push(e.gt_return);
        let mixture_return: f64 = app
            .mixture_weights()
            .iter()
            .zip(&returns)
            .map(|(l, r)| l * r)
            .sum();
        // Step 0 is the random initial policy π₀, as in the projection method.
        run.steps.push(StepMetrics {
            step,
            env_interactions: interactions,
            gt_return: e.gt_return,
            success: e.success,
            objective: if step == 0 { f64::NAN } else { s.margin },
            mixture_return,
            elapsed_s: t0.elapsed().as_secs_f64(),
        });
        if step % 5 == 0 {
            progress(&format!(
                "{} seed {seed} step {step}: margin {:.4}, success {}",
                algo.name(),
                s.margin,
                e.success
            ));
        }
        weights = s.weights;
        step += 1;
    }
    run.converged = app.margin() <= cfg.apprenticeship.epsilon;
    run.timings.irl_s = t_irl.elapsed().as_secs_f64();
    run.weights = vec![weights];
    run.weight_columns = world
        .vocab()
        .props()
        .iter()
        .map(|c| c.to_string())
        .chain(std::iter::once("none".to_string()))
        .collect();
    Ok(())
}
