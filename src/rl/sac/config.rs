//! SAC hyper-parameters, TOML-loadable, with the paper's values as defaults.

use serde::{Deserialize, Serialize};

/// Hyper-parameters of [`super::SacAgent`] and [`super::SacTrainer`].
///
/// Defaults are the paper's values for the SAC inside IRL runs: (64, 64) ReLU MLPs, Adam lr
/// 3e-3 for actor, critics and temperature, batch 256, replay 10 000; γ = 0.99, τ = 0.005.
/// The paper gives no temperature for IRL runs: the default tunes α automatically toward the
/// target entropy −|A|, starting from 0.2. [`SacConfig::expert`] is the expert preset
/// (batch 100, replay 10⁶, fixed α = 0.2).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SacConfig {
    /// Hidden layer widths of the actor and of each critic.
    pub hidden: Vec<usize>,
    /// Adam learning rate of actor, critics and log α.
    #[serde(serialize_with = "crate::short_float::f32")]
    pub lr: f32,
    pub batch_size: usize,
    pub replay_capacity: usize,
    /// Discount factor.
    #[serde(serialize_with = "crate::short_float::f32")]
    pub gamma: f32,
    /// Polyak coefficient of the target critics.
    #[serde(serialize_with = "crate::short_float::f32")]
    pub tau: f32,
    /// Entropy temperature: fixed value, or the starting value when `auto_alpha`.
    #[serde(serialize_with = "crate::short_float::f32")]
    pub alpha: f32,
    /// Tune α toward `target_entropy` (else keep it fixed).
    pub auto_alpha: bool,
    /// Target policy entropy; −act_dim when absent.
    #[serde(
        skip_serializing_if = "Option::is_none",
        serialize_with = "crate::short_float::option_f32"
    )]
    pub target_entropy: Option<f32>,
    /// Environment steps with uniformly random actions before the policy acts.
    pub warmup_steps: u64,
    /// Environment steps before the first gradient update.
    pub update_after: u64,
    /// Gradient updates per environment step once updating.
    pub updates_per_step: u32,
}

impl Default for SacConfig {
    fn default() -> Self {
        Self {
            hidden: vec![64, 64],
            lr: 3e-3,
            batch_size: 256,
            replay_capacity: 10_000,
            gamma: 0.99,
            tau: 0.005,
            alpha: 0.2,
            auto_alpha: true,
            target_entropy: None,
            warmup_steps: 1_000,
            update_after: 1_000,
            updates_per_step: 1,
        }
    }
}

// Limits of the sizes a config may ask for, checked by `SacConfig::validate` before any
// allocation (a typo such as `hidden = [1000000]` must be an error, not an abort).

/// Most hidden layers of each network.
pub const MAX_HIDDEN_LAYERS: usize = 8;
/// Widest hidden layer (a 4096² weight matrix is 64 MiB).
pub const MAX_LAYER_WIDTH: usize = 4096;
/// Largest minibatch.
pub const MAX_BATCH_SIZE: usize = 65_536;
/// Largest replay buffer, in transitions (a few hundred bytes each on Reacher's product).
pub const MAX_REPLAY_CAPACITY: usize = 4_000_000;
/// Most gradient updates per environment step.
pub const MAX_UPDATES_PER_STEP: u32 = 64;
/// Most weights between the hidden layers of a network (Σ wᵢ·wᵢ₊₁ of `hidden`): 2²⁵, 128 MiB
/// of `f32`, of which SAC keeps ~14 copies (five networks, their gradients, Adam's moments).
/// Each width within its own limit, eight layers of 4096 would need ~6 GiB.
pub const MAX_HIDDEN_WEIGHTS: usize = 1 << 25;
/// Most hidden units of a minibatch (`batch_size` × Σ `hidden`): 2²⁶ activations, 256 MiB,
/// of which SAC's updates hold ~10 arrays (activations and their gradients per network).
/// Each within its own limit, a batch of 65 536 through eight layers of 4096 would need
/// ~80 GiB.
pub const MAX_BATCH_HIDDEN_UNITS: usize = 1 << 26;

/// A configuration that cannot be used.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ConfigError {
    #[error("{source_name}: {message}")]
    Parse {
        source_name: String,
        message: String,
    },
    #[error("{source_name}: unknown preset {preset:?} (expected \"irl\" or \"expert\")")]
    UnknownPreset { source_name: String, preset: String },
    #[error("SAC config field `{field}` {problem}")]
    Invalid {
        field: &'static str,
        problem: String,
    },
}

impl SacConfig {
    /// The paper's IRL-run configuration (same as `default()`).
    pub fn irl() -> Self {
        Self::default()
    }

    /// The expert preset: batch 100, replay 10⁶, fixed α = 0.2.
    pub fn expert() -> Self {
        Self {
            batch_size: 100,
            replay_capacity: 1_000_000,
            alpha: 0.2,
            auto_alpha: false,
            ..Self::default()
        }
    }

    /// Parses a TOML document. An optional `preset = "irl" | "expert"` key picks the base
    /// values, which the other keys override; unknown keys and wrong types are errors naming
    /// the key. `source_name` (usually the file path) prefixes every message.
    pub fn from_toml(text: &str, source_name: &str) -> Result<Self, ConfigError> {
        let config = Self::from_table(parse_table(text, source_name)?, Self::irl(), source_name)?;
        config.validate()?;
        Ok(config)
    }

    /// [`SacConfig::from_toml`] on a parsed table, with `default_base` as the base values
    /// when the table names no `preset`.
    pub(crate) fn from_table(
        mut user: toml::Table,
        default_base: SacConfig,
        source_name: &str,
    ) -> Result<Self, ConfigError> {
        let parse = |message: String| ConfigError::Parse {
            source_name: source_name.to_string(),
            message,
        };
        let base = match user.remove("preset") {
            None => default_base,
            Some(toml::Value::String(p)) if p == "irl" => Self::irl(),
            Some(toml::Value::String(p)) if p == "expert" => Self::expert(),
            Some(other) => {
                return Err(ConfigError::UnknownPreset {
                    source_name: source_name.to_string(),
                    preset: other.to_string(),
                })
            }
        };
        let mut merged = toml::Table::try_from(&base).map_err(|e| parse(e.to_string()))?;
        for (k, v) in user {
            merged.insert(k, v);
        }
        // Ranges are checked by the caller's `validate`, which can name the key's line.
        deserialize_table(merged, source_name)
    }

    /// Reads and parses a TOML file.
    pub fn load(path: &std::path::Path) -> Result<Self, ConfigError> {
        load_toml(path, Self::from_toml)
    }

    pub fn to_toml(&self) -> String {
        toml::to_string(self).expect("SacConfig always serialises")
    }

    /// Checks value ranges.
    pub fn validate(&self) -> Result<(), ConfigError> {
        let bad = |field, problem: &str| {
            Err(ConfigError::Invalid {
                field,
                problem: problem.to_string(),
            })
        };
        if self.hidden.is_empty() || self.hidden.contains(&0) {
            return bad("hidden", "must list at least one positive layer width");
        }
        if self.hidden.len() > MAX_HIDDEN_LAYERS {
            return bad(
                "hidden",
                &format!("lists more than {MAX_HIDDEN_LAYERS} layers"),
            );
        }
        if let Some(w) = self.hidden.iter().find(|&&w| w > MAX_LAYER_WIDTH) {
            return bad(
                "hidden",
                &format!("has a layer of width {w}, more than the limit of {MAX_LAYER_WIDTH}"),
            );
        }
        let weights: usize = self.hidden.windows(2).map(|w| w[0] * w[1]).sum();
        if weights > MAX_HIDDEN_WEIGHTS {
            return bad(
                "hidden",
                &format!(
                    "has {weights} weights between its layers, more than the limit of \
                     {MAX_HIDDEN_WEIGHTS}"
                ),
            );
        }
        if self.batch_size > MAX_BATCH_SIZE {
            return bad(
                "batch_size",
                &format!("is more than the limit of {MAX_BATCH_SIZE}"),
            );
        }
        let units = self.batch_size * self.hidden.iter().sum::<usize>();
        if units > MAX_BATCH_HIDDEN_UNITS {
            return bad(
                "batch_size",
                &format!(
                    "times the sum of the hidden widths is {units} activations, more than the \
                     limit of {MAX_BATCH_HIDDEN_UNITS} (use a smaller batch or narrower layers)"
                ),
            );
        }
        if self.replay_capacity > MAX_REPLAY_CAPACITY {
            return bad(
                "replay_capacity",
                &format!("is more than the limit of {MAX_REPLAY_CAPACITY} transitions"),
            );
        }
        if self.updates_per_step > MAX_UPDATES_PER_STEP {
            return bad(
                "updates_per_step",
                &format!("is more than the limit of {MAX_UPDATES_PER_STEP}"),
            );
        }
        if !(self.lr.is_finite() && self.lr > 0.0) {
            return bad("lr", "must be a positive number");
        }
        if self.batch_size == 0 {
            return bad("batch_size", "must be positive");
        }
        if self.replay_capacity < self.batch_size {
            return bad("replay_capacity", "must be at least batch_size");
        }
        if !(0.0..1.0).contains(&self.gamma) {
            return bad("gamma", "must be in [0, 1)");
        }
        if !(self.tau > 0.0 && self.tau <= 1.0) {
            return bad("tau", "must be in (0, 1]");
        }
        if !(self.alpha.is_finite() && self.alpha > 0.0) {
            return bad("alpha", "must be a positive number");
        }
        if let Some(t) = self.target_entropy {
            if !t.is_finite() {
                return bad("target_entropy", "must be a finite number");
            }
        }
        if self.updates_per_step == 0 {
            return bad("updates_per_step", "must be positive");
        }
        Ok(())
    }

    /// The target entropy for an action space of `act_dim` dimensions.
    pub fn target_entropy_for(&self, act_dim: usize) -> f32 {
        self.target_entropy.unwrap_or(-(act_dim as f32))
    }
}

/// The key of the `key = value` line containing byte `offset` of a flat TOML document.
fn key_at(text: &str, offset: usize) -> Option<String> {
    let start = text[..offset.min(text.len())]
        .rfind('\n')
        .map_or(0, |i| i + 1);
    let line = text[start..].lines().next()?;
    let (key, _) = line.split_once('=')?;
    Some(key.trim().trim_matches('"').to_string())
}

/// Reads the TOML file at `path` and parses it with `from_toml`, which gets the path as the
/// source name; a file that cannot be read is an error naming it.
pub(crate) fn load_toml<T>(
    path: &std::path::Path,
    from_toml: impl FnOnce(&str, &str) -> Result<T, ConfigError>,
) -> Result<T, ConfigError> {
    let name = path.display().to_string();
    let text = crate::config_text::read_text_file(path).map_err(|e| ConfigError::Parse {
        source_name: name.clone(),
        message: e.to_string(),
    })?;
    from_toml(&text, &name)
}

/// Parses a TOML document into a table, with errors naming `source_name`.
pub(crate) fn parse_table(text: &str, source_name: &str) -> Result<toml::Table, ConfigError> {
    text.parse()
        .map_err(|e: toml::de::Error| ConfigError::Parse {
            source_name: source_name.to_string(),
            message: e.to_string(),
        })
}

/// Deserialises a TOML table into `T`, with errors naming the offending key. Going through
/// text (not `Table::try_into`) keeps spans, so a type error can name its key.
pub(crate) fn deserialize_table<T: serde::de::DeserializeOwned>(
    table: toml::Table,
    source_name: &str,
) -> Result<T, ConfigError> {
    let parse = |message: String| ConfigError::Parse {
        source_name: source_name.to_string(),
        message,
    };
    let text = toml::to_string(&table).map_err(|e| parse(e.to_string()))?;
    toml::from_str(&text).map_err(|e: toml::de::Error| {
        let message = e.message().trim().to_string();
        match e.span().and_then(|s| key_at(&text, s.start)) {
            Some(key) if !message.contains(&key) => parse(format!("field `{key}`: {message}")),
            _ => parse(message),
        }
    })
}
