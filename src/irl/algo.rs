//! The IRL algorithms of the paper's comparison: one list for both domains, each domain
//! running its subset ([`Algo::REACHER`], [`Algo::OFFICE`]).

use super::firl::Divergence;
use std::fmt;

/// An IRL algorithm.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Algo {
    /// SMIRL with the paper's label features and the mechanisms of `docs/method.md`.
    Smirl,
    /// The paper's algorithm: SMIRL with every mechanism of `docs/method.md` at the paper's
    /// value (LRM's objective, μ_D − μ_π, the policy on U × O, the loop's own final policy).
    SmirlPaper,
    /// SMIRL with smooth distance features (a documented variant, ReacherDelivery).
    SmirlSmooth,
    /// MaxEnt IRL (tabular on Office, continuous on ReacherDelivery).
    MaxEnt,
    /// f-IRL, forward KL.
    Fkl,
    /// f-IRL, reverse KL.
    Rkl,
    /// f-IRL, Jensen–Shannon.
    Js,
    /// Apprenticeship learning (projection method, Office).
    Apprenticeship,
    /// Control (ReacherDelivery): continuous MaxEnt IRL on the product with SMIRL's learned
    /// machine, the reward an MLP of (one-hot u, fingertip).
    MaxEntProduct,
    /// Control (ReacherDelivery): f-IRL (fkl) on the product with SMIRL's learned machine,
    /// the reward and the densities over (one-hot u, fingertip).
    FklProduct,
}

impl Algo {
    /// The ReacherDelivery comparison (paper figure 7), what `--algo all` runs.
    pub const REACHER: [Algo; 7] = [
        Algo::Smirl,
        Algo::SmirlPaper,
        Algo::SmirlSmooth,
        Algo::MaxEnt,
        Algo::Fkl,
        Algo::Rkl,
        Algo::Js,
    ];

    /// The controls of the comparison on ReacherDelivery (docs/algorithms.md): run when named,
    /// never by `all`, which stays the paper's comparison.
    pub const REACHER_CONTROLS: [Algo; 2] = [Algo::MaxEntProduct, Algo::FklProduct];

    /// Every ReacherDelivery algorithm: the comparison, then the controls.
    pub const REACHER_NAMED: [Algo; 9] = [
        Algo::Smirl,
        Algo::SmirlPaper,
        Algo::SmirlSmooth,
        Algo::MaxEnt,
        Algo::Fkl,
        Algo::Rkl,
        Algo::Js,
        Algo::MaxEntProduct,
        Algo::FklProduct,
    ];

    /// The default set of `reacher --task` (README.md, "Run it").
    /// `smirl-paper` is in it so that every run shows the paper's algorithm beside the
    /// improved one.
    pub const REACHER_DEFAULT: [Algo; 5] = [
        Algo::Smirl,
        Algo::SmirlPaper,
        Algo::SmirlSmooth,
        Algo::MaxEnt,
        Algo::Fkl,
    ];

    /// The Office Gridworld comparison (paper figures 4 and 5).
    pub const OFFICE: [Algo; 3] = [Algo::Smirl, Algo::MaxEnt, Algo::Apprenticeship];

    pub fn name(self) -> &'static str {
        match self {
            Algo::Smirl => "smirl",
            Algo::SmirlPaper => "smirl-paper",
            Algo::SmirlSmooth => "smirl-smooth",
            Algo::MaxEnt => "maxent",
            Algo::Fkl => "fkl",
            Algo::Rkl => "rkl",
            Algo::Js => "js",
            Algo::Apprenticeship => "apprenticeship",
            Algo::MaxEntProduct => "maxent-product",
            Algo::FklProduct => "fkl-product",
        }
    }

    /// Name for plots and tables.
    pub fn label(self) -> &'static str {
        match self {
            Algo::Smirl => "SMIRL",
            Algo::SmirlPaper => "SMIRL (paper)",
            Algo::SmirlSmooth => "SMIRL (smooth features)",
            Algo::MaxEnt => "MaxEnt IRL",
            Algo::Fkl => "f-IRL (fkl)",
            Algo::Rkl => "f-IRL (rkl)",
            Algo::Js => "f-IRL (js)",
            Algo::Apprenticeship => "Apprenticeship IRL",
            Algo::MaxEntProduct => "MaxEnt IRL (product)",
            Algo::FklProduct => "f-IRL (fkl, product)",
        }
    }

    /// The algorithm's colour in every plot (one of [`crate::report::plot::PALETTE`]): SMIRL's
    /// variants in green, yellow and teal, the baselines each in their own hue, a control in
    /// its baseline's.
    pub fn colour(self) -> &'static str {
        match self {
            Algo::Smirl => "#59a14f",
            Algo::SmirlPaper => "#edc948",
            Algo::SmirlSmooth => "#76b7b2",
            Algo::MaxEnt | Algo::MaxEntProduct => "#4e79a7",
            Algo::Fkl | Algo::FklProduct => "#f28e2b",
            Algo::Rkl => "#b07aa1",
            Algo::Js => "#e15759",
            Algo::Apprenticeship => "#9c755f",
        }
    }

    /// SMIRL variants act on the product with a learned machine.
    pub fn uses_rm(self) -> bool {
        matches!(self, Algo::Smirl | Algo::SmirlPaper | Algo::SmirlSmooth)
    }

    /// The controls: a baseline on the product with SMIRL's learned machine.
    pub fn is_product_control(self) -> bool {
        matches!(self, Algo::MaxEntProduct | Algo::FklProduct)
    }

    /// The baseline a control runs (its loss and its `[schedule.<base>]` table); the
    /// algorithm itself otherwise.
    pub fn base(self) -> Algo {
        match self {
            Algo::MaxEntProduct => Algo::MaxEnt,
            Algo::FklProduct => Algo::Fkl,
            a => a,
        }
    }

    /// The f-divergence of an f-IRL algorithm (a control's, its base's).
    pub fn divergence(self) -> Option<Divergence> {
        match self.base() {
            Algo::Fkl => Some(Divergence::Fkl),
            Algo::Rkl => Some(Divergence::Rkl),
            Algo::Js => Some(Divergence::Js),
            _ => None,
        }
    }

    /// Every algorithm of either domain.
    pub const ALL: [Algo; 10] = [
        Algo::Smirl,
        Algo::SmirlPaper,
        Algo::SmirlSmooth,
        Algo::MaxEnt,
        Algo::Fkl,
        Algo::Rkl,
        Algo::Js,
        Algo::Apprenticeship,
        Algo::MaxEntProduct,
        Algo::FklProduct,
    ];

    /// The algorithm called `name` (its [`Algo::name`]), of either domain.
    pub fn from_name(name: &str) -> Option<Algo> {
        Algo::ALL.into_iter().find(|a| a.name() == name)
    }

    /// The algorithm called `name` among `domain`'s.
    pub fn parse_in(name: &str, domain: &[Algo]) -> Result<Algo, UnknownAlgorithm> {
        domain
            .iter()
            .copied()
            .find(|a| a.name() == name)
            .ok_or_else(|| UnknownAlgorithm {
                name: name.to_string(),
                expected: domain.iter().map(|a| a.name()).collect(),
            })
    }

    /// A ReacherDelivery algorithm by name, a control included (a command-line value parser).
    pub fn parse_reacher(name: &str) -> Result<Algo, UnknownAlgorithm> {
        Algo::parse_in(name, &Algo::REACHER_NAMED)
    }

    /// A comma-separated list of `domain`'s algorithms (`all` = every one of them);
    /// duplicates are dropped.
    pub fn parse_list(s: &str, domain: &[Algo]) -> Result<Vec<Algo>, UnknownAlgorithm> {
        Algo::parse_list_of(s, domain, domain)
    }

    /// A comma-separated list of ReacherDelivery algorithms: any by name, `all` = the
    /// comparison ([`Algo::REACHER`]; the controls are named).
    pub fn parse_reacher_list(s: &str) -> Result<Vec<Algo>, UnknownAlgorithm> {
        Algo::parse_list_of(s, &Algo::REACHER_NAMED, &Algo::REACHER)
    }

    /// A comma-separated list of `named`'s algorithms, `all` standing for `all`'s.
    fn parse_list_of(s: &str, named: &[Algo], all: &[Algo]) -> Result<Vec<Algo>, UnknownAlgorithm> {
        let mut out = Vec::new();
        for part in s.split(',').map(str::trim) {
            let algos: Vec<Algo> = if part == "all" {
                all.to_vec()
            } else {
                vec![Algo::parse_in(part, named)?]
            };
            for a in algos {
                if !out.contains(&a) {
                    out.push(a);
                }
            }
        }
        Ok(out)
    }
}

/// A name that is none of a domain's algorithms.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("unknown algorithm '{name}' (expected one of: {}, all)", .expected.join(", "))]
pub struct UnknownAlgorithm {
    pub name: String,
    /// The domain's algorithm names.
    pub expected: Vec<&'static str>,
}

impl fmt::Display for Algo {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}
