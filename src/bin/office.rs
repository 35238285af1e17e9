//! `office`: the Office Gridworld experiments (filled in by the Office work).
fn main() {}
