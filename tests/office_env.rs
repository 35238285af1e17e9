//! Office world: moves through walls and doors, labels, and the expert's optimality.

use smirl::env::office::{OfficeEpisode, OfficeTask, OfficeWorld};
use smirl::irl::tabular::{DemoConfig, OfficeExpert};
use std::collections::VecDeque;

const UP: usize = 0;
const RIGHT: usize = 1;
const DOWN: usize = 2;
const LEFT: usize = 3;

const N_CELLS: usize = 12 * 9;

fn cell(x: usize, y: usize) -> usize {
    y * 12 + x
}

fn mv(w: &OfficeWorld, from: (usize, usize), a: usize) -> (usize, usize) {
    let c = w.step(cell(from.0, from.1), a);
    (c % 12, c / 12)
}

/// The paper's five tasks, as shipped.
fn paper_tasks() -> Vec<OfficeTask> {
    (0..5)
        .map(|k| OfficeTask::shipped(&k.to_string()).unwrap())
        .collect()
}

#[test]
fn walls_and_doors_on_hand_picked_cells() {
    let w = OfficeWorld::paper();
    assert_eq!(w.start(), cell(2, 1));
    // Inside a room.
    assert_eq!(mv(&w, (2, 1), UP), (2, 2));
    assert_eq!(mv(&w, (2, 1), LEFT), (1, 1));
    // Doors, both ways.
    assert_eq!(mv(&w, (2, 1), RIGHT), (3, 1));
    assert_eq!(mv(&w, (3, 1), LEFT), (2, 1));
    assert_eq!(mv(&w, (1, 2), UP), (1, 3));
    assert_eq!(mv(&w, (1, 3), DOWN), (1, 2));
    assert_eq!(mv(&w, (4, 5), UP), (4, 6));
    assert_eq!(mv(&w, (8, 1), RIGHT), (9, 1));
    assert_eq!(mv(&w, (10, 5), UP), (10, 6));
    assert_eq!(mv(&w, (8, 7), RIGHT), (9, 7));
    // Room borders without a door.
    assert_eq!(mv(&w, (2, 2), UP), (2, 2));
    assert_eq!(mv(&w, (0, 2), UP), (0, 2));
    assert_eq!(mv(&w, (2, 2), RIGHT), (2, 2));
    assert_eq!(mv(&w, (5, 4), RIGHT), (5, 4));
    assert_eq!(mv(&w, (6, 4), LEFT), (6, 4));
    assert_eq!(mv(&w, (4, 2), UP), (4, 2));
    assert_eq!(mv(&w, (8, 2), RIGHT), (8, 2));
    // Outer border.
    assert_eq!(mv(&w, (0, 0), DOWN), (0, 0));
    assert_eq!(mv(&w, (0, 0), LEFT), (0, 0));
    assert_eq!(mv(&w, (11, 8), UP), (11, 8));
    assert_eq!(mv(&w, (11, 8), RIGHT), (11, 8));
    // Exactly 12 doors: count cross-room passages (each counted once).
    let mut passages = 0;
    for c in 0..N_CELLS {
        for a in [UP, RIGHT] {
            let d = w.step(c, a);
            let (x, y) = (c % 12, c / 12);
            let (x2, y2) = (d % 12, d / 12);
            if d != c && (x / 3 != x2 / 3 || y / 3 != y2 / 3) {
                passages += 1;
            }
        }
    }
    assert_eq!(passages, 12);
}

#[test]
fn labels_on_hand_picked_cells() {
    let w = OfficeWorld::paper();
    let v = w.vocab().clone();
    let lab = |x, y| v.format_labels(w.label(cell(x, y)));
    assert_eq!(lab(1, 1), "A");
    assert_eq!(lab(1, 7), "B");
    assert_eq!(lab(10, 7), "C");
    assert_eq!(lab(10, 1), "D");
    assert_eq!(lab(8, 2), "c");
    assert_eq!(lab(3, 6), "c");
    assert_eq!(lab(7, 4), "m");
    assert_eq!(lab(4, 4), "o");
    for (x, y) in [(4, 1), (7, 1), (4, 7), (7, 7), (1, 4), (10, 4)] {
        assert_eq!(lab(x, y), "*");
    }
    assert_eq!(lab(2, 1), "");
    assert_eq!(lab(0, 0), "");
    let labelled = (0..N_CELLS).filter(|&c| !w.label(c).is_empty()).count();
    assert_eq!(labelled, 4 + 2 + 1 + 1 + 6);
}

#[test]
fn episodes_pay_on_completion_and_can_continue_or_reset() {
    let w = OfficeWorld::paper();
    let rm = OfficeTask::shipped("0").unwrap().rm().clone();
    // From the start (2,1), around the plants at (4,1) and (7,1), to D (10,1).
    let path = [
        RIGHT, UP, RIGHT, RIGHT, DOWN, RIGHT, UP, RIGHT, RIGHT, DOWN, RIGHT, RIGHT,
    ];
    let mut ep = OfficeEpisode::new(&w, &rm, false);
    let mut total = 0.0;
    let mut completed_at = None;
    for (t, &a) in path.iter().enumerate() {
        let s = ep.step(a);
        total += s.reward;
        assert!(!s.failed);
        if s.completed {
            completed_at = Some(t);
        }
    }
    assert_eq!(ep.cell(), cell(10, 1));
    assert_eq!(completed_at, Some(path.len() - 1));
    assert_eq!(total, 1.0);
    // Without reset the agent moves on, and is paid no more when it comes back to D.
    let s = ep.step(DOWN);
    assert_eq!((s.reward, ep.cell()), (0.0, cell(10, 0)));
    let s = ep.step(UP);
    assert_eq!(
        (s.reward, s.completed, ep.cell()),
        (0.0, false, cell(10, 1))
    );
    // With reset, the ending step returns it to the start; a plant fails the task.
    let mut ep = OfficeEpisode::new(&w, &rm, true);
    ep.step(RIGHT);
    let s = ep.step(RIGHT); // (4,1) is a plant
    assert!(s.failed && s.reward == 0.0);
    assert_eq!((ep.cell(), ep.rm_state()), (w.start(), rm.initial()));
}

/// Shortest number of steps from `(cell, u)` to a goal state of the task's machine in the
/// product graph, never entering a failure state.
fn bfs_distance(w: &OfficeWorld, task: &OfficeTask, cell0: usize, u0: usize) -> Option<usize> {
    let rm = task.rm();
    let n = rm.n_states() * N_CELLS;
    let mut dist = vec![usize::MAX; n];
    let mut queue = VecDeque::new();
    dist[u0 * N_CELLS + cell0] = 0;
    queue.push_back((cell0, u0));
    while let Some((c, u)) = queue.pop_front() {
        let d = dist[u * N_CELLS + c];
        for a in 0..4 {
            let c2 = w.step(c, a);
            let u2 = rm.next_state(u, w.label(c2));
            if rm.is_terminal(u2) {
                return Some(d + 1);
            }
            if rm.is_failure(u2) || dist[u2 * N_CELLS + c2] != usize::MAX {
                continue;
            }
            dist[u2 * N_CELLS + c2] = d + 1;
            queue.push_back((c2, u2));
        }
    }
    None
}

#[test]
fn expert_trips_are_shortest_paths_for_every_task() {
    let w = OfficeWorld::paper();
    for (k, task) in paper_tasks().iter().enumerate() {
        let expert = OfficeExpert::new(task);
        let cfg = DemoConfig {
            n_demos: 12,
            horizon: 100,
            random_steps: 5,
            seed: 7 + k as u64,
        };
        let demos = expert.demonstrations(&cfg);
        let mut n_trips = 0;
        for d in &demos {
            assert!(
                !d.trips.is_empty(),
                "task {k}: a demo without a completed trip"
            );
            // The first trip starts at the start cell and is optimal from there.
            assert_eq!(d.trips[0].start_t, 0);
            for trip in &d.trips {
                let best = bfs_distance(&w, task, trip.start_cell, trip.start_u).unwrap();
                assert_eq!(trip.len(), best, "task {k} trip {trip:?}");
                assert_eq!(d.rewards[trip.end_t - 1], 1.0);
                n_trips += 1;
            }
            // Labels are those of the cells landed on.
            for t in 0..d.len() {
                assert_eq!(d.labels[t], w.label(d.cells[t] as usize));
                assert_eq!(
                    w.step(d.cell_before(t), d.actions[t] as usize),
                    d.cells[t] as usize
                );
            }
        }
        assert!(n_trips > demos.len(), "task {k}: {n_trips} trips");
    }
    // Known optimal first-trip lengths from the start, by BFS on the map.
    let lens: Vec<usize> = paper_tasks()
        .iter()
        .map(|t| bfs_distance(&w, t, w.start(), 0).unwrap())
        .collect();
    assert!(lens.iter().all(|&l| l > 5), "{lens:?}");
}

#[test]
fn demonstrations_are_reproducible_and_seed_dependent() {
    let expert = OfficeExpert::new(&OfficeTask::shipped("3").unwrap());
    let cfg = DemoConfig {
        n_demos: 5,
        horizon: 80,
        random_steps: 4,
        seed: 1,
    };
    let a = expert.demonstrations(&cfg);
    let b = expert.demonstrations(&cfg);
    assert_eq!(a, b);
    let c = expert.demonstrations(&DemoConfig { seed: 2, ..cfg });
    assert_ne!(a, c);
}
