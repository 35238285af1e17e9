//! Learning a reward machine offline from the label traces of rollout logs.
