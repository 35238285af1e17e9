//! Office map and task files: the shipped map is the paper's, maps round-trip through the
//! text format, bad maps and task files are refused with their file, line, column and limit,
//! and a task written here (its own map and machine) runs end to end.

use smirl::env::office::map::{MAX_COLUMNS, MAX_ROWS};
use smirl::env::office::task::{MAX_TASK_STATES, MAX_TRIP_STEPS};
use smirl::env::office::{
    parse_map, write_map, OfficeMap, OfficeTask, OfficeTaskError, OfficeWorld, N_ACTIONS,
};
use smirl::pipeline::commands::office::{run, OfficeRequest};
use std::path::Path;

/// The Office map as the paper's code defines it: 12 × 9 cells in rooms of 3 × 3, these
/// doors between rooms, these objects, start (2, 1).
const WIDTH: usize = 12;
const HEIGHT: usize = 9;
const DOORS: [((usize, usize), (usize, usize)); 12] = [
    ((1, 2), (1, 3)),
    ((1, 5), (1, 6)),
    ((2, 1), (3, 1)),
    ((2, 7), (3, 7)),
    ((4, 5), (4, 6)),
    ((5, 1), (6, 1)),
    ((5, 7), (6, 7)),
    ((7, 5), (7, 6)),
    ((8, 1), (9, 1)),
    ((8, 7), (9, 7)),
    ((10, 2), (10, 3)),
    ((10, 5), (10, 6)),
];
const OBJECTS: [(char, &[(usize, usize)]); 8] = [
    ('A', &[(1, 1)]),
    ('B', &[(1, 7)]),
    ('C', &[(10, 7)]),
    ('D', &[(10, 1)]),
    ('c', &[(8, 2), (3, 6)]),
    ('m', &[(7, 4)]),
    ('o', &[(4, 4)]),
    ('*', &[(4, 1), (7, 1), (4, 7), (7, 7), (1, 4), (10, 4)]),
];

/// The paper's transition table (`next[cell * 4 + action]`) and label bit masks, computed
/// from the constants above as the code before map files did.
fn paper_tables() -> (Vec<u32>, Vec<u32>) {
    let same_room = |a: (usize, usize), b: (usize, usize)| a.0 / 3 == b.0 / 3 && a.1 / 3 == b.1 / 3;
    let is_door = |a, b| {
        DOORS
            .iter()
            .any(|&(p, q)| (p, q) == (a, b) || (q, p) == (a, b))
    };
    let mut next = vec![0u32; WIDTH * HEIGHT * 4];
    for c in 0..WIDTH * HEIGHT {
        let (x, y) = (c % WIDTH, c / WIDTH);
        for a in 0..4 {
            let target = match a {
                0 if y + 1 < HEIGHT => Some((x, y + 1)),
                1 if x + 1 < WIDTH => Some((x + 1, y)),
                2 if y > 0 => Some((x, y - 1)),
                3 if x > 0 => Some((x - 1, y)),
                _ => None,
            };
            next[c * 4 + a] = match target {
                Some(t) if same_room((x, y), t) || is_door((x, y), t) => (t.1 * WIDTH + t.0) as u32,
                _ => c as u32,
            };
        }
    }
    let mut labels = vec![0u32; WIDTH * HEIGHT];
    for (bit, (_, cells)) in OBJECTS.iter().enumerate() {
        for &(x, y) in cells.iter() {
            labels[y * WIDTH + x] |= 1 << bit;
        }
    }
    (next, labels)
}

#[test]
fn the_shipped_map_is_the_papers() {
    let w = OfficeWorld::paper();
    let (next, labels) = paper_tables();
    assert_eq!((w.width(), w.height()), (WIDTH, HEIGHT));
    assert_eq!(w.vocab().to_string(), "ABCDcmo*");
    assert_eq!(w.start(), WIDTH + 2);
    assert_eq!(w.transition_table(), &next[..]);
    assert_eq!(w.labels().iter().map(|l| l.0).collect::<Vec<_>>(), labels);
    // Every shipped task is on this world, with the machine of assets/rm/.
    for k in 0..5 {
        let t = OfficeTask::shipped(&k.to_string()).unwrap();
        assert_eq!(t.world(), &w);
        assert_eq!(t.name(), k.to_string());
        assert_eq!(t.rm(), &smirl::rm::perfect::office(k).unwrap());
    }
}

#[test]
fn the_shipped_files_on_disk_are_the_built_in_ones() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    for k in 0..5 {
        let on_disk = OfficeTask::load(&root.join(format!("assets/office/task{k}.toml"))).unwrap();
        let built_in = OfficeTask::shipped(&k.to_string()).unwrap();
        assert_eq!(on_disk.name(), built_in.name());
        assert_eq!(on_disk.title(), built_in.title());
        assert_eq!(on_disk.world(), built_in.world());
        assert_eq!(on_disk.rm(), built_in.rm());
    }
}

fn parse(text: &str) -> OfficeMap {
    parse_map(text, "test.map").unwrap_or_else(|e| panic!("{e}"))
}

#[test]
fn maps_round_trip_through_the_text_format() {
    let paper = parse(include_str!("../assets/office/paper.map"));
    let written = write_map(&paper);
    assert_eq!(parse(&written), paper);
    // Writing is canonical: the written picture is the shipped one.
    let picture = |t: &str| t[t.find("map:\n").unwrap()..].trim_end().to_string();
    assert_eq!(
        picture(&written),
        picture(include_str!("../assets/office/paper.map"))
    );
    // A map with open corners, a letter with an empty description, a one-cell-wide corridor.
    let small = parse(
        "legend:\nk = key\ng =\n# a comment\nmap:\n+-+-+-+\n|k . g|\n+ +-+ +\n|@|.|.|\n+-+-+-+\n\n# after\n",
    );
    assert_eq!((small.width(), small.height()), (3, 2));
    assert_eq!(small.start(), (0, 0));
    assert_eq!(small.letter(0, 1), Some('k'));
    assert!(small.open_up(0, 0) && !small.open_up(1, 0) && small.open_up(2, 0));
    assert!(!small.open_right(0, 0) && small.open_right(0, 1));
    assert_eq!(small.descriptions(), ["key", ""]);
    assert_eq!(parse(&write_map(&small)), small);
}

#[test]
fn moves_follow_the_picture() {
    let m = parse("legend:\nx = x\nmap:\n+---+\n|@ x|\n+-- +\n|. .|\n+---+\n");
    let w = OfficeWorld::from_map(&m);
    let (up, right, down, left) = (0, 1, 2, 3);
    let at = |x, y| w.cell(x, y);
    assert_eq!(w.start(), at(0, 1));
    assert_eq!(w.step(at(0, 1), right), at(1, 1));
    assert_eq!(w.step(at(0, 1), down), at(0, 1), "wall under the start");
    assert_eq!(w.step(at(1, 1), down), at(1, 0), "the gap in the wall");
    assert_eq!(w.step(at(1, 0), up), at(1, 1));
    assert_eq!(w.step(at(0, 0), left), at(0, 0), "outer border");
    assert_eq!(w.step(at(1, 1), up), at(1, 1), "outer border");
    assert_eq!(w.cells_with('x'), vec![at(1, 1)]);
    assert_eq!(N_ACTIONS, 4);
}

/// The error of parsing `text` as a map, as displayed.
fn map_error(text: &str) -> String {
    match parse_map(text, "bad.map") {
        Ok(_) => panic!("accepted:\n{text}"),
        Err(e) => e.to_string(),
    }
}

const GOOD_PICTURE: &str = "+---+\n|@ x|\n+---+\n";

#[test]
fn bad_maps_are_refused_naming_the_line_column_and_limit() {
    let with = |legend: &str, picture: &str| format!("legend:\n{legend}map:\n{picture}");
    let cases: Vec<(String, &str)> = vec![
        (
            with("x = x\n", "+---+\n|@ y|\n+---+\n"),
            "bad.map:5:4: 'y' is not a cell",
        ),
        (
            with("x = x\n", "+---+\n|@ x|\n+-- +\n"),
            "bad.map:6:4: the outer border must be a wall ('-')",
        ),
        (
            with("x = x\n", "+---+\n @ x|\n+---+\n"),
            "bad.map:5:1: the outer border must be a wall ('|')",
        ),
        (
            with("x = x\n", "+---+\n|@-x|\n+---+\n"),
            "bad.map:5:3: '-' between two cells",
        ),
        (
            with("x = x\n", "+--|+\n|@ x|\n+---+\n"),
            "bad.map:4:4: '|' between two rows",
        ),
        (
            with("x = x\n", "+-x-+\n|@ x|\n+---+\n"),
            "bad.map:4:3: 'x' at a corner",
        ),
        (
            with("x = x\n", "+---+\n|@ x|\n+----+\n"),
            "bad.map:6:6: this picture line has 6 characters, the first one (line 4) 5",
        ),
        (
            with("x = x\n", "+----+\n|@ x |\n+----+\n"),
            "bad.map:4: a picture line has 2·columns + 1 characters",
        ),
        (
            with("x = x\n", "+---+\n|@ x|\n+---+\n|. .|\n"),
            "bad.map:7: the picture has 4 lines",
        ),
        (
            with("x = x\n", "+---+\n|@ @|\n+---+\n"),
            "bad.map:5:4: a second start cell '@' (the first is at line 5, column 2)",
        ),
        (
            with("x = x\n", "+---+\n|. x|\n+---+\n"),
            "bad.map: no start cell ('@')",
        ),
        (
            with("x = x\ny = y\n", GOOD_PICTURE),
            "bad.map:3: letter 'y' is in the legend but on no cell",
        ),
        (
            with("x = x\nx = again\n", GOOD_PICTURE),
            "bad.map:3: letter 'x' is already in the legend (line 2)",
        ),
        (
            with(". = dot\n", GOOD_PICTURE),
            "bad.map:2:1: '.' cannot be a letter",
        ),
        (
            with("& = and\n", GOOD_PICTURE),
            "bad.map:2:1: '&' cannot be a letter",
        ),
        (
            with("x x\n", GOOD_PICTURE),
            "bad.map:2:1: expected a legend line 'letter = description'",
        ),
        (
            with("", GOOD_PICTURE),
            "bad.map: the legend names no letter",
        ),
        (
            format!("map:\n{GOOD_PICTURE}"),
            "bad.map:1: 'map:' before 'legend:'",
        ),
        ("legend:\nx = x\n".into(), "bad.map: no 'map:' line"),
        (
            "legend:\nx = x\nmap:\n\n".into(),
            "bad.map: the picture after 'map:' is empty",
        ),
        ("size: 3\n".into(), "bad.map:1: expected 'legend:'"),
        (
            "legend:\nlegend:\n".into(),
            "bad.map:2: a second 'legend:' section",
        ),
        (
            with("x = x\n", "+---+\n|@ x|\n+---+\n\n+---+\n"),
            "bad.map:8: the picture ended at line 7",
        ),
        (
            with(&format!("x = {}\n", "d".repeat(201)), GOOD_PICTURE),
            "bad.map:2:1: the description of 'x' is longer than the limit of 200 characters",
        ),
        (
            with(
                &"abcdefghijklm"
                    .chars()
                    .map(|c| format!("{c} = {c}\n"))
                    .collect::<String>(),
                GOOD_PICTURE,
            ),
            "bad.map:14: more than the limit of 12 letters",
        ),
        (
            with(
                "x = x\n",
                &format!(
                    "+{}+\n|@ x{}|\n+{}+\n",
                    "-".repeat(2 * MAX_COLUMNS + 1),
                    " .".repeat(MAX_COLUMNS - 1),
                    "-".repeat(2 * MAX_COLUMNS + 1)
                ),
            ),
            "more than the limit of 64 columns",
        ),
        (
            with(
                "x = x\n",
                &format!("+---+\n{}", "|@ x|\n+---+\n".repeat(MAX_ROWS + 1)),
            ),
            "bad.map:133: the picture has more than 129 lines: more than the limit of 64 rows",
        ),
        (
            format!("# {}\n", "#".repeat(1100)),
            "bad.map:1: the line is longer than the limit of 1024 characters",
        ),
    ];
    for (text, expected) in cases {
        let message = map_error(&text);
        assert!(
            message.starts_with(expected) || message.contains(expected),
            "{message:?} lacks {expected:?} for:\n{text}"
        );
    }
    // Column and line are typed, too.
    let e = parse_map(&with("x = x\n", "+---+\n|@ y|\n+---+\n"), "bad.map").unwrap_err();
    assert_eq!((e.line(), e.column()), (Some(5), Some(4)));
}

/// A directory with a task file, its map and its machine, written by the test.
struct TaskDir {
    dir: tempfile::TempDir,
}

/// A new world: a 5 × 4 floor with an inner wall, a key `k`, a goal `g`, lava `x` and a
/// letter `s` that no task names.
const NEW_MAP: &str = "\
# A test world.
legend:
g = goal
x = lava
k = key
s = sofa
map:
+---------+
|. x . . g|
|         |
|. . . . .|
|   +-- --|
|. .|s . .|
|   |     |
|@ .|k . .|
+---------+
";

/// Key, then goal; lava fails. Its vocabulary is in another order than the map's and lacks
/// `s`.
const NEW_MACHINE: &str = "\
vocabulary: kgx
states: 4
initial: 0
terminal: 2
failure: 3
(0, 1, 'k&!x', 0)
(0, 3, 'x', 0)
(1, 2, 'g&!x', 1)
(1, 3, 'x', 0)
";

impl TaskDir {
    fn new(task: &str, map: &str, machine: &str) -> TaskDir {
        let dir = tempfile::tempdir().unwrap();
        std::fs::create_dir(dir.path().join("maps")).unwrap();
        std::fs::write(dir.path().join("maps/new.map"), map).unwrap();
        std::fs::write(dir.path().join("key_then_goal.txt"), machine).unwrap();
        std::fs::write(dir.path().join("key_goal.toml"), task).unwrap();
        TaskDir { dir }
    }

    fn task_path(&self) -> std::path::PathBuf {
        self.dir.path().join("key_goal.toml")
    }

    fn error(&self) -> String {
        match OfficeTask::load(&self.task_path()) {
            Ok(_) => panic!("accepted"),
            Err(e) => e.to_string(),
        }
    }
}

const NEW_TASK: &str =
    "map = \"maps/new.map\"\nmachine = \"key_then_goal.txt\"\ndescription = \"key, then goal\"\n";

#[test]
fn a_task_is_read_over_its_maps_letters() {
    let d = TaskDir::new(NEW_TASK, NEW_MAP, NEW_MACHINE);
    let t = OfficeTask::load(&d.task_path()).unwrap();
    assert_eq!(t.name(), "key_goal", "the file stem");
    assert_eq!(t.title(), "Office task key_goal: key, then goal");
    assert_eq!(t.rm().vocab().to_string(), "gxks", "the map's order");
    let w = t.world();
    let rm = t.rm();
    // Key then goal completes; the sofa is ignored; lava fails.
    let [k, g, x, s] = [(2, 0), (4, 3), (1, 3), (2, 1)].map(|(cx, cy)| w.label(w.cell(cx, cy)));
    assert_eq!(rm.run(&[s, k, s, g]).last().unwrap(), &(2, 1.0));
    assert_eq!(rm.run(&[g, k]).last().unwrap().0, 1);
    assert_eq!(rm.run(&[k, x]).last().unwrap().0, 3);
}

#[test]
fn bad_task_files_are_refused_naming_the_file_line_and_key() {
    let cases: Vec<(String, String, String, &str)> = vec![
        (
            format!("{NEW_TASK}colour = \"red\"\n"),
            NEW_MAP.into(),
            NEW_MACHINE.into(),
            "key_goal.toml: line 4: unknown field `colour`",
        ),
        (
            "map = \"maps/new.map\"\n".into(),
            NEW_MAP.into(),
            NEW_MACHINE.into(),
            "key_goal.toml: missing field `machine`",
        ),
        (
            NEW_TASK.replace("maps/new.map", "maps/none.map"),
            NEW_MAP.into(),
            NEW_MACHINE.into(),
            "key_goal.toml:1: `map` = \"maps/none.map\": cannot read",
        ),
        (
            NEW_TASK.replace("key_then_goal.txt", ""),
            NEW_MAP.into(),
            NEW_MACHINE.into(),
            "key_goal.toml:2: `machine`: an empty path",
        ),
        (
            format!("name = \"a,b\"\n{NEW_TASK}"),
            NEW_MAP.into(),
            NEW_MACHINE.into(),
            "key_goal.toml:1: `name`: \"a,b\" is not a task name",
        ),
        (
            NEW_TASK.replace("key, then goal", &"d".repeat(201)),
            NEW_MAP.into(),
            NEW_MACHINE.into(),
            "key_goal.toml:3: `description`: one line of at most 200 characters",
        ),
        (
            NEW_TASK.into(),
            NEW_MAP.into(),
            NEW_MACHINE.replace("kgx", "kgxz"),
            "key_then_goal.txt:1: proposition 'z' of the machine is not a letter of the map",
        ),
        (
            NEW_TASK.into(),
            NEW_MAP.into(),
            NEW_MACHINE.replace("initial: 0", "initial: 0\ninitial: 1"),
            "key_then_goal.txt:4:",
        ),
        (
            NEW_TASK.into(),
            NEW_MAP.replace("|@ .|k", "|@ .|x"),
            NEW_MACHINE.into(),
            "new.map:5: letter 'k' is in the legend but on no cell",
        ),
        (
            NEW_TASK.into(),
            NEW_MAP.replace("|   +-- --|", "|---+-- --|"),
            NEW_MACHINE.into(),
            "no path from the start cell (0, 0)",
        ),
        (
            NEW_TASK.into(),
            NEW_MAP.into(),
            format!(
                "vocabulary: k\nstates: {}\ninitial: 0\nterminal: 1\n(0, 1, 'k', 1)\n",
                MAX_TASK_STATES + 1
            ),
            "the machine has 257 states, more than the limit of 256",
        ),
    ];
    for (task, map, machine, expected) in cases {
        let d = TaskDir::new(&task, &map, &machine);
        let message = d.error();
        assert!(message.contains(expected), "{message:?} lacks {expected:?}");
    }
    // A snake of 40 × 4 cells: from the start the goal is 159 steps away, beyond what the
    // expert's discount tells apart.
    let n = 40;
    let wall = |gap: usize| -> String {
        (0..2 * n + 1)
            .map(|j| match j {
                0 => '|',
                _ if j == 2 * n => '|',
                _ if j % 2 == 1 && (j - 1) / 2 == gap => ' ',
                _ => '-',
            })
            .collect()
    };
    let border = format!("+{}+", "-".repeat(2 * n - 1));
    let row = |first: char| format!("|{first}{}|", " .".repeat(n - 1));
    let picture = [
        border.clone(),
        row('g'),
        wall(n - 1),
        row('.'),
        wall(0),
        row('.'),
        wall(n - 1),
        row('@'),
        border,
    ]
    .join("\n");
    let snake = format!("legend:\ng = goal\nmap:\n{picture}\n");
    let machine = "vocabulary: g\nstates: 2\ninitial: 0\nterminal: 1\n(0, 1, 'g', 1)\n";
    let message = TaskDir::new(NEW_TASK, &snake, machine).error();
    assert!(
        message.contains(&format!(
            "takes 159 steps, more than the limit of {MAX_TRIP_STEPS}"
        )),
        "{message}"
    );
    // Two rows shorter (80 steps) is accepted.
    let shorter = snake
        .replacen(&format!("{}\n{}\n", row('g'), wall(n - 1)), "", 1)
        .replacen(&row('.'), &row('g'), 1);
    assert!(OfficeTask::load(&TaskDir::new(NEW_TASK, &shorter, machine).task_path()).is_ok());
}

#[test]
fn unknown_shipped_names_and_missing_files_are_refused() {
    for name in ["9", "-1", "t3"] {
        match OfficeTask::from_argument(name) {
            Err(e @ OfficeTaskError::Unknown { .. }) => {
                assert!(e
                    .to_string()
                    .contains(&format!("unknown Office task {name}")))
            }
            other => panic!("{name}: {other:?}"),
        }
    }
    match OfficeTask::from_argument("no/such/task.toml") {
        Err(e @ OfficeTaskError::Io { .. }) => {
            assert!(
                e.to_string().starts_with("no/such/task.toml: cannot read"),
                "{e}"
            )
        }
        other => panic!("{other:?}"),
    }
}

#[test]
fn a_new_task_runs_end_to_end() {
    let d = TaskDir::new(NEW_TASK, NEW_MAP, NEW_MACHINE);
    let out = d.dir.path().join("out");
    let config = d.dir.path().join("small.toml");
    std::fs::write(
        &config,
        "[demos]\nn_demos = 20\n[maxent]\nmax_steps = 100\n",
    )
    .unwrap();
    run(OfficeRequest {
        task: d.task_path().display().to_string(),
        algo: "all".into(),
        seeds: 1,
        seed: 5,
        out: out.clone(),
        config: Some(config),
        force: false,
        write_demos: true,
    })
    .unwrap();
    let summary = std::fs::read_to_string(out.join("summary.csv")).unwrap();
    let rows: Vec<Vec<&str>> = summary
        .lines()
        .skip(1)
        .map(|l| l.split(',').collect())
        .collect();
    assert_eq!(rows.len(), 3, "{summary}");
    for row in &rows {
        assert_eq!(row[0], "key_goal");
    }
    // SMIRL learns key → goal on the new world.
    let smirl = rows.iter().find(|r| r[1] == "smirl").unwrap();
    assert_eq!(smirl[3], "1", "SMIRL's final success: {summary}");
    let rm = std::fs::read_to_string(out.join("rm_smirl_seed5.txt")).unwrap();
    assert!(rm.contains("vocabulary: gxks"), "{rm}");
    let weights = std::fs::read_to_string(out.join("weights_smirl_seed5.csv")).unwrap();
    assert!(weights.starts_with("rm_state,g,x,k,s\n"), "{weights}");
    let demos = std::fs::read_to_string(out.join("demos_seed5.csv")).unwrap();
    assert!(
        demos.lines().any(|l| l.contains(",k,")),
        "the expert fetches the key"
    );
    let svg = std::fs::read_to_string(out.join("success.svg")).unwrap();
    assert!(svg.contains("Office task key_goal: key, then goal"));
}

#[test]
fn a_shipped_task_by_name_and_by_path_gives_the_same_results() {
    let dir = tempfile::tempdir().unwrap();
    let config = dir.path().join("small.toml");
    std::fs::write(&config, "[demos]\nn_demos = 10\n[maxent]\nmax_steps = 30\n").unwrap();
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let outputs = |task: String, out: &str| {
        let out = dir.path().join(out);
        run(OfficeRequest {
            task,
            algo: "smirl".into(),
            seeds: 1,
            seed: 2,
            out: out.clone(),
            config: Some(config.clone()),
            force: false,
            write_demos: true,
        })
        .unwrap();
        let mut files: Vec<(String, String)> = std::fs::read_dir(&out)
            .unwrap()
            .map(|e| {
                let path = e.unwrap().path();
                let name = path.file_name().unwrap().to_string_lossy().into_owned();
                let text = std::fs::read_to_string(&path).unwrap();
                // Wall-clock columns aside (metrics: the last; summary: demos_s .. total_s).
                let text = match name.as_str() {
                    "metrics.csv" => text
                        .lines()
                        .map(|l| l.rsplit_once(',').unwrap().0.to_string() + "\n")
                        .collect(),
                    "summary.csv" => text
                        .lines()
                        .map(|l| {
                            let f: Vec<&str> = l.split(',').collect();
                            format!("{},{}\n", f[..8].join(","), f[12])
                        })
                        .collect(),
                    _ => text,
                };
                (name, text)
            })
            .collect();
        files.sort();
        files
    };
    let by_name = outputs("2".into(), "by-name");
    let by_path = outputs(
        root.join("assets/office/task2.toml").display().to_string(),
        "by-path",
    );
    let names: Vec<&str> = by_name.iter().map(|f| f.0.as_str()).collect();
    assert!(names.contains(&"demos_seed2.csv") && names.contains(&"rm_smirl_seed2.txt"));
    assert_eq!(by_name, by_path);
    let metrics = &by_name.iter().find(|f| f.0 == "metrics.csv").unwrap().1;
    assert!(metrics.contains("\n2,smirl,2,0,"), "{metrics}");
}
