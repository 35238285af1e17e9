//! Reward-machine files: round trips, error messages, the perfect machines' behaviour on
//! hand-written traces, the product tracker and the equivalence check.

use smirl::rm::dot::to_dot;
use smirl::rm::equiv::{counterexample, equivalent, refines, state_counts};
use smirl::rm::format::{parse_rm, read_rm, save_rm, write_rm, RmFileError};
use smirl::rm::product::RmTracker;
use smirl::rm::transform::restart_on_goal;
use smirl::rm::{perfect, Formula, LabelSet, RewardMachine, Transition};

#[test]
fn every_asset_round_trips() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/rm");
    let mut n = 0;
    for entry in std::fs::read_dir(&dir).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().and_then(|e| e.to_str()) != Some("txt") {
            continue;
        }
        let rm = read_rm(&path).unwrap_or_else(|e| panic!("{e}"));
        let text = write_rm(&rm);
        let again = parse_rm(&text, "written").unwrap();
        assert_eq!(again, rm, "{}", path.display());
        assert_eq!(write_rm(&again), text);
        n += 1;
    }
    assert_eq!(n, perfect::NAMES.len());
    // The machines built into the binaries are the shipped files.
    for name in perfect::NAMES {
        let file = dir.join(format!("{name}.txt"));
        assert_eq!(
            perfect::load(name).unwrap(),
            read_rm(&file).unwrap(),
            "{name}"
        );
        assert_eq!(
            perfect::text(name).unwrap(),
            std::fs::read_to_string(&file).unwrap()
        );
    }
    assert!(perfect::load("office_t9").is_err());
}

#[test]
fn state_counts_match_the_paper() {
    for (name, states) in [
        ("reacher_or", 3),
        ("reacher_sequential", 5),
        ("reacher_if", 5),
        ("reacher_composite", 7),
    ] {
        let rm = perfect::load(name).unwrap();
        let c = state_counts(&rm, None).unwrap();
        assert_eq!((c.total, c.reachable), (states, states), "{name}");
    }
    // Goal and failure sink behave alike (reward 0 forever): one class when minimised.
    let c = state_counts(&perfect::load("reacher_composite").unwrap(), None).unwrap();
    assert_eq!(c.minimal, 6);
    // Office task 3: the paper's 4 states once the goal restarts and plants never occur.
    let t3 = restart_on_goal(&perfect::office(3).unwrap());
    let v = t3.vocab().clone();
    let no_plants: Vec<LabelSet> = v.all_label_sets().filter(|l| !l.contains(7)).collect();
    let c = state_counts(&t3, Some(&no_plants)).unwrap();
    assert_eq!((c.reachable, c.minimal), (4, 4));
}

/// The states reachable without the cancel: Composite's normal branch (start, red/green,
/// blue, goal), not its cancelled states or the failure sink they lead to; with no event
/// excluded, every state.
#[test]
fn states_reachable_without_an_event() {
    let rm = perfect::load("reacher_composite").unwrap();
    let cancel = rm.vocab().parse_labels("c").unwrap();
    let free = rm.reachable_without(cancel);
    let states: Vec<usize> = (0..rm.n_states()).filter(|&u| free[u]).collect();
    assert_eq!(states, vec![0, 1, 2, 5]);
    assert!(rm.reachable_without(LabelSet::EMPTY).iter().all(|&r| r));
    let if_rm = perfect::load("reacher_if").unwrap();
    let free = if_rm.reachable_without(cancel);
    assert_eq!(free.iter().filter(|&&r| r).count(), 3, "{free:?}");
}

fn labels(rm: &RewardMachine, trace: &str) -> Vec<LabelSet> {
    trace
        .split(',')
        .map(|s| rm.vocab().parse_labels(s.trim()).unwrap())
        .collect()
}

/// Runs `trace` (comma-separated label sets) and checks states and rewards.
fn check(name: &str, trace: &str, states: &[usize], rewards: &[f64]) {
    let rm = perfect::load(name).unwrap();
    let out = rm.run(&labels(&rm, trace));
    let got_states: Vec<usize> = out.iter().map(|x| x.0).collect();
    let got_rewards: Vec<f64> = out.iter().map(|x| x.1).collect();
    assert_eq!(got_states, states, "{name} on {trace}");
    assert_eq!(got_rewards, rewards, "{name} on {trace}");
}

#[test]
fn perfect_office_machines_on_hand_written_traces() {
    check(
        "office_t0",
        ",A,,D,",
        &[0, 0, 0, 1, 1],
        &[0., 0., 0., 1., 0.],
    );
    check("office_t0", ",*,D", &[0, 2, 2], &[0., 0., 0.]);
    check(
        "office_t1",
        "o,c,,m,o,o",
        &[0, 1, 1, 1, 2, 2],
        &[0., 0., 0., 0., 1., 0.],
    );
    check("office_t1", "c,*,o", &[1, 3, 3], &[0., 0., 0.]);
    check(
        "office_t2",
        "c,o,m,,o",
        &[0, 0, 1, 1, 2],
        &[0., 0., 0., 0., 1.],
    );
    check(
        "office_t3",
        "c,o,c,m,o",
        &[1, 1, 1, 3, 4],
        &[0., 0., 0., 0., 1.],
    );
    check(
        "office_t3",
        "m,,c,,o",
        &[2, 2, 3, 3, 4],
        &[0., 0., 0., 0., 1.],
    );
    check("office_t3", "m,*", &[2, 5], &[0., 0.]);
    check(
        "office_t4",
        "B,A,C,B,D,C,A,D",
        &[0, 1, 1, 2, 2, 3, 3, 4],
        &[0., 0., 0., 0., 0., 0., 0., 1.],
    );
    check("office_t4", "A,B,*,C", &[1, 2, 5, 5], &[0.; 4]);
}

#[test]
fn perfect_reacher_machines_on_hand_written_traces() {
    check(
        "reacher_or",
        "b,g,g,,b",
        &[0, 1, 1, 1, 2],
        &[0., 0., 0., 0., 1.],
    );
    check("reacher_or", "r,c,b,r", &[1, 1, 2, 2], &[0., 0., 1., 0.]);
    check(
        "reacher_sequential",
        "r,b,g,y,b,y",
        &[1, 1, 2, 2, 3, 4],
        &[0., 0., 0., 0., 0., 1.],
    );
    // IF: blue then red; cancel before blue -> red directly, blue forbidden.
    check("reacher_if", "r,b,c,r", &[0, 1, 1, 3], &[0., 0., 0., 1.]);
    check("reacher_if", ",c,,r", &[0, 2, 2, 3], &[0., 0., 0., 1.]);
    check("reacher_if", "c,b", &[2, 4], &[0., 0.]);
    check("reacher_if", "bc,bc,r", &[2, 2, 3], &[0., 0., 1.]);
    // Composite.
    check(
        "reacher_composite",
        "b,g,b,y",
        &[0, 1, 2, 5],
        &[0., 0., 0., 1.],
    );
    check("reacher_composite", "r,c,y", &[1, 3, 5], &[0., 0., 1.]);
    check(
        "reacher_composite",
        "c,y,g,y",
        &[4, 4, 3, 5],
        &[0., 0., 0., 1.],
    );
    check("reacher_composite", "c,b", &[4, 6], &[0., 0.]);
    check("reacher_composite", "g,c,b,y", &[1, 3, 6, 6], &[0.; 4]);
    check("reacher_composite", "gc,y", &[3, 5], &[0., 1.]);
}

#[test]
fn formulas_in_files_follow_their_truth_tables() {
    // Each guard holds exactly on the label sets its truth table says (8 label sets of r,g,c).
    type Truth = fn(bool, bool, bool) -> bool;
    let cases: &[(&str, Truth)] = &[
        ("r|g", |r, g, _| r || g),
        ("(r|g)&!c", |r, g, c| (r || g) && !c),
        ("c&!r&!g", |r, g, c| c && !r && !g),
        ("!(r&g)|c", |r, g, c| !(r && g) || c),
        ("r&g&c", |r, g, c| r && g && c),
    ];
    for (f, truth) in cases {
        let text = format!("vocabulary: rgbyc\nstates: 2\ninitial: 0\n(0, 1, '{f}', 1)\n");
        let rm = parse_rm(&text, "table.txt").unwrap();
        let v = rm.vocab().clone();
        for bits in 0..8u32 {
            let (r, g, c) = (bits & 1 == 1, bits & 2 == 2, bits & 4 == 4);
            let mut l = LabelSet::EMPTY;
            for (on, p) in [(r, 'r'), (g, 'g'), (c, 'c')] {
                if on {
                    l = l.with(v.index_of(p).unwrap());
                }
            }
            let fired = rm.step(0, l) == (1, 1.0);
            assert_eq!(fired, truth(r, g, c), "{f} on r={r} g={g} c={c}");
        }
    }
}

#[test]
fn malformed_files_name_file_line_and_expectation() {
    let head = "vocabulary: rgbyc\nstates: 3\ninitial: 0\nterminal: 2\n";
    let cases: Vec<(String, usize, &str)> = vec![
        (
            format!("{head}(0, 1, 'r|x', 0)\n"),
            5,
            "unknown proposition 'x'",
        ),
        (format!("{head}(0, 1, 'r', 0\n"), 5, "missing ')'"),
        (format!("{head}(0, 1, r, 0)\n"), 5, "single quotes"),
        (format!("{head}(0, 'r', 0)\n"), 5, "'from, to,'"),
        (format!("{head}(0, 1, 'r', zero)\n"), 5, "finite reward"),
        (format!("{head}(0, 7, 'r', 0)\n"), 5, "out of range"),
        (format!("{head}(a, 1, 'r', 0)\n"), 5, "state number"),
        (
            format!("{head}(0, 1, 'r', 0)\n(0, 2, 'r&g', 1)\n"),
            6,
            "nondeterministic",
        ),
        (format!("{head}(2, 1, 'r', 0)\n"), 5, "terminal (absorbing)"),
        (format!("{head}(0, 1, 'r&', 0)\n"), 5, "found the end"),
        (
            format!("{head}states: 4\n"),
            5,
            "appears twice (first on line 2)",
        ),
        (
            "vocabulary: rgbyc\nstates: 3\n".to_string(),
            2,
            "missing the 'initial:'",
        ),
        (
            "vocabulary: rgbyc\nstates: 3\ninitial: 3\n".to_string(),
            3,
            "out of range",
        ),
        (
            "vocabulary: rr\nstates: 1\ninitial: 0\n".to_string(),
            1,
            "appears twice",
        ),
        (
            "states: 2\ninitial: 0\nhello\n".to_string(),
            3,
            "expected a header",
        ),
        (
            "states: 2\ninitial: 0\ncolour: red\n".to_string(),
            3,
            "unknown header 'colour:'",
        ),
        (
            format!("{head}failure: 2\n"),
            5,
            "both terminal and failure",
        ),
    ];
    for (text, line, needle) in &cases {
        let e = parse_rm(text, "bad.txt").unwrap_err();
        assert_eq!(e.line(), Some(*line), "{e} for\n{text}");
        let msg = e.to_string();
        assert!(msg.starts_with(&format!("bad.txt:{line}: ")), "{msg}");
        assert!(msg.contains(needle), "{msg} does not mention {needle:?}");
    }
}

#[test]
fn missing_file_names_the_path() {
    let e = read_rm(std::path::Path::new("/nonexistent/rm.txt")).unwrap_err();
    assert!(matches!(e, RmFileError::Io { .. }));
    assert!(e.to_string().contains("/nonexistent/rm.txt"));
}

#[test]
fn save_is_atomic_and_readable() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("t3.txt");
    let rm = perfect::office(3).unwrap();
    save_rm(&path, &rm).unwrap();
    assert_eq!(read_rm(&path).unwrap(), rm);
    let leftovers: Vec<_> = std::fs::read_dir(dir.path()).unwrap().collect();
    assert_eq!(leftovers.len(), 1, "no temporary file left behind");
    assert!(to_dot(&rm).contains("u4 [shape=doublecircle"));
}

#[test]
fn tracker_steps_restarts_and_encodes() {
    let rm = perfect::office(1).unwrap();
    let v = rm.vocab().clone();
    let l = |s: &str| v.parse_labels(s).unwrap();
    let mut t = RmTracker::new(rm.clone());
    assert_eq!(t.step(l("c")).state, 1);
    let s = t.step(l("o"));
    assert_eq!(
        (s.state, s.reward, s.terminal, s.failure),
        (2, 1.0, true, false)
    );
    assert_eq!(t.step(l("c")).state, 2, "terminal is absorbing");
    let mut buf = [9.0f32; 4];
    t.encode_state(&mut buf);
    assert_eq!(buf, [0.0, 0.0, 1.0, 0.0]);
    t.reset();
    assert_eq!(t.state(), 0);
    assert!(t.step(l("*")).failure);

    let mut r = RmTracker::restarting(rm);
    r.step(l("c"));
    let s = r.step(l("o"));
    assert_eq!((s.state, s.reward, s.terminal), (0, 1.0, true));
    assert_eq!(r.step(l("c")).state, 1, "a new trip starts");
}

#[test]
fn equivalence_rejects_a_one_transition_change() {
    let rm = perfect::office(3).unwrap();
    assert!(equivalent(&rm, &rm, None).unwrap());
    // Same machine with one transition redirected: mail first, then coffee goes to "coffee
    // only" instead of "both".
    let mut ts: Vec<Transition> = rm.transitions().to_vec();
    let k = ts.iter().position(|t| t.from == 2 && t.to == 3).unwrap();
    ts[k].to = 1;
    let changed = RewardMachine::new(rm.vocab().clone(), 6, 0, &[4], &[5], ts).unwrap();
    let cx = counterexample(&rm, &changed, None).unwrap().unwrap();
    let v = rm.vocab();
    let shown: Vec<String> = cx.iter().map(|&l| v.format_labels(l)).collect();
    assert_eq!(shown, ["m", "c", "o"], "shortest counter-example");
    // A reward-only change is caught too.
    let mut ts: Vec<Transition> = rm.transitions().to_vec();
    let k = ts.iter().position(|t| t.to == 4).unwrap();
    ts[k].reward = 0.5;
    let changed = RewardMachine::new(rm.vocab().clone(), 6, 0, &[4], &[5], ts).unwrap();
    assert!(!equivalent(&rm, &changed, None).unwrap());
    // Renumbered states and rewritten formulas are still equivalent.
    let v = rm.vocab().clone();
    let f = |s: &str| Formula::parse(s, &v).unwrap();
    let t0 = RewardMachine::new(
        v.clone(),
        3,
        2,
        &[0],
        &[1],
        vec![
            Transition {
                from: 2,
                to: 0,
                formula: f("D&!(*)"),
                reward: 1.0,
            },
            Transition {
                from: 2,
                to: 1,
                formula: f("!!*"),
                reward: 0.0,
            },
        ],
    )
    .unwrap();
    assert!(equivalent(&t0, &perfect::office(0).unwrap(), None).unwrap());
}

#[test]
fn refinement_along_traces() {
    let coarse = restart_on_goal(&perfect::office(1).unwrap());
    let v = coarse.vocab().clone();
    let trace: Vec<LabelSet> = ["", "c", "", "o", "", "m", "c", "o"]
        .iter()
        .map(|s| v.parse_labels(s).unwrap())
        .collect();
    // A machine refines itself; the one-state machine does not refine it.
    assert!(refines(&coarse, &coarse, [trace.as_slice()]).refines);
    let one = RewardMachine::new(v.clone(), 1, 0, &[], &[], vec![]).unwrap();
    let r = refines(&one, &coarse, [trace.as_slice()]);
    assert!(!r.refines);
    assert_eq!(r.seen_with[0], vec![0, 1]);
}
