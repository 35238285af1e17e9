//! Tabular solvers on finite MDPs: value iteration, soft value iteration, visitation frequencies, Q-learning.
