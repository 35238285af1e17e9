//! Tabular IRL for the Office Gridworld: experts and demonstrations, MaxEnt IRL, the
//! product with a (learned) reward machine used by SMIRL and the MaxEnt baseline,
//! Apprenticeship IRL, and ground-truth evaluation.

pub mod apprenticeship;
pub mod demos;
pub mod eval;
pub mod maxent;
pub mod product;

pub use apprenticeship::{
    Apprenticeship, ApprenticeshipConfig, ApprenticeshipError, ApprenticeshipStep, PolicySolver,
};
pub use demos::{DemoConfig, Demonstration, OfficeExpert, Trip};
pub use eval::{evaluate_policy, greedy_policy, Evaluation};
pub use maxent::{
    GradientInfo, MaxEntConfig, MaxEntError, MaxEntIrl, Optimizer, StateActionDemo,
    StateActionFeatures, NO_FEATURE,
};
pub use product::{trivial_rm, ProductIrl};
