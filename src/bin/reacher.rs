//! `reacher`: the ReacherDelivery command line (filled in by the foundation work).
fn main() {}
