//! Graphviz export of reward machines.
//!
//! Terminal (goal) states are double circles, failure sinks are filled red boxes labelled
//! "fail", the initial state has an incoming arrow from a point. Edges read
//! `formula / reward`.

use super::machine::RewardMachine;
use std::fmt::Write as _;

/// The machine as a Graphviz `digraph`; render with `dot -Tsvg`.
pub fn to_dot(rm: &RewardMachine) -> String {
    let v = rm.vocab();
    let mut out = String::new();
    let _ = writeln!(out, "digraph reward_machine {{");
    let _ = writeln!(out, "  rankdir=LR;");
    let _ = writeln!(out, "  node [shape=circle, fontname=\"Helvetica\"];");
    let _ = writeln!(out, "  edge [fontname=\"Helvetica\", fontsize=10];");
    let _ = writeln!(out, "  start [shape=point, width=0.08];");
    for u in 0..rm.n_states() {
        let attrs = if rm.is_terminal(u) {
            format!("shape=doublecircle, label=\"u{u}\"")
        } else if rm.is_failure(u) {
            format!("shape=box, style=filled, fillcolor=\"#f4a6a6\", label=\"u{u}\\nfail\"")
        } else {
            format!("label=\"u{u}\"")
        };
        let _ = writeln!(out, "  u{u} [{attrs}];");
    }
    let _ = writeln!(out, "  start -> u{};", rm.initial());
    for t in rm.transitions() {
        let label = format!("{} / {}", t.formula.display(v), t.reward);
        let _ = writeln!(
            out,
            "  u{} -> u{} [label=\"{}\"];",
            t.from,
            t.to,
            escape(&label)
        );
    }
    let _ = writeln!(out, "}}");
    out
}

fn escape(s: &str) -> String {
    s.replace('\\', "\\\\").replace('"', "\\\"")
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rm::format::parse_rm;

    #[test]
    fn marks_terminal_and_failure_states() {
        let rm = parse_rm(
            "vocabulary: rgbyc\nstates: 3\ninitial: 0\nterminal: 1\nfailure: 2\n(0, 1, 'b&!c', 1)\n(0, 2, 'c', 0)\n",
            "t",
        )
        .unwrap();
        let dot = to_dot(&rm);
        assert!(dot.starts_with("digraph"));
        assert!(dot.contains("u1 [shape=doublecircle"));
        assert!(dot.contains("u2 [shape=box") && dot.contains("fail"));
        assert!(dot.contains("u0 -> u1 [label=\"b&!c / 1\"]"), "{dot}");
        assert!(dot.contains("start -> u0"));
        assert!(dot.trim_end().ends_with('}'));
    }
}
