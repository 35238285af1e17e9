//! A log carries every file its scene reads — the files it includes, however deep, and its
//! mesh and texture files — as attachments, and `replay`, `render` and `foxglove` compile the
//! scene from the log alone: with the scene's directory gone, the episodes replay bit for bit.
//! What a log carries is bounded as a task's scene is; a log of a scene without such files
//! carries none; the official MCAP reader sees the attachments.

use smirl::assets::REACHER_XML;
use smirl::env::scene_files::{
    SceneFile, SceneFileKind, MAX_ASSET_BYTES, MAX_ASSET_FILES, MAX_INCLUDED_BYTES,
    MAX_INCLUDED_FILES,
};
use smirl::env::scene_xml::MAX_SCENE_BYTES;
use smirl::log::reader::MAX_LOGGED_SCENE_BYTES;
use smirl::log::{read_log, LogError, LogOptions, RolloutLogger, RunHeader};
use smirl::pipeline::replay::replay;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::sync::Arc;

/// A tetrahedron as Wavefront OBJ.
const TETRAHEDRON: &str =
    "v 0 0 0\nv 0.01 0 0\nv 0 0.01 0\nv 0 0 0.01\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n";

/// A 4×4 grey PNG.
fn png() -> Vec<u8> {
    let mut out = Vec::new();
    let mut encoder = png::Encoder::new(&mut out, 4, 4);
    encoder.set_color(png::ColorType::Rgb);
    encoder.set_depth(png::BitDepth::Eight);
    let mut writer = encoder.write_header().unwrap();
    writer.write_image_data(&[128; 48]).unwrap();
    writer.finish().unwrap();
    out
}

const MACHINE: &str = "vocabulary: ab\nstates: 3\ninitial: 0\nterminal: 2\n\
                       (0, 1, 'a', 0)\n(1, 2, 'b', 1)\n";
const TASK: &str = "scene = \"scene.xml\"\nmachine = \"m.txt\"\nepisode_steps = 60\n\
                    randomize_layout = true\n\
                    [[region]]\nletter = \"a\"\nbody = \"red\"\nradius = 0.02\n\
                    [[region]]\nletter = \"b\"\nbody = \"blue\"\nradius = 0.02\n";

/// The built-in scene in `dir` with its motors two includes deep (`scene.xml` includes
/// `parts/outer.xml`, which includes `parts/motors.xml`), a mesh drawn in the world and a
/// texture; the task over it, and the scene's files as a log must carry them.
fn scene_of_ones_own(dir: &Path) -> (PathBuf, Vec<(String, Vec<u8>)>) {
    let (start, end) = (
        REACHER_XML.find("<actuator>").unwrap(),
        REACHER_XML.find("</actuator>").unwrap() + "</actuator>".len(),
    );
    let compiler = "<compiler angle=\"radian\" inertiafromgeom=\"true\"/>";
    let worldbody = "<worldbody>";
    assert!(REACHER_XML.contains(compiler) && REACHER_XML.contains(worldbody));
    let scene = format!(
        "{}<include file=\"parts/outer.xml\"/>{}",
        &REACHER_XML[..start],
        &REACHER_XML[end..]
    )
    .replacen(
        compiler,
        "<compiler angle=\"radian\" inertiafromgeom=\"true\" meshdir=\"meshes\" \
         texturedir=\"textures\"/>\n<asset><mesh name=\"tet\" file=\"tet.obj\"/>\
         <texture name=\"grey\" type=\"2d\" file=\"grey.png\"/></asset>",
        1,
    )
    .replacen(
        worldbody,
        "<worldbody><geom type=\"mesh\" mesh=\"tet\" contype=\"0\" conaffinity=\"0\" \
         pos=\"0.25 0.25 0\"/>",
        1,
    );
    let files = [
        (
            "include/parts/outer.xml",
            b"<mujoco><include file=\"parts/motors.xml\"/></mujoco>".to_vec(),
        ),
        (
            "include/parts/motors.xml",
            format!("<mujoco>{}</mujoco>", &REACHER_XML[start..end]).into_bytes(),
        ),
        ("asset/meshes/tet.obj", TETRAHEDRON.as_bytes().to_vec()),
        ("asset/textures/grey.png", png()),
    ]
    .map(|(name, bytes)| (name.to_string(), bytes));
    for (name, bytes) in &files {
        let path = dir.join(name.split_once('/').unwrap().1);
        std::fs::create_dir_all(path.parent().unwrap()).unwrap();
        std::fs::write(path, bytes).unwrap();
    }
    std::fs::write(dir.join("scene.xml"), scene).unwrap();
    std::fs::write(dir.join("m.txt"), MACHINE).unwrap();
    std::fs::write(dir.join("task.toml"), TASK).unwrap();
    (dir.join("task.toml"), files.to_vec())
}

/// `reacher ARGS` run in `dir`.
fn reacher(dir: &Path, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_reacher"))
        .current_dir(dir)
        .args(args)
        .output()
        .unwrap()
}

fn text(o: &Output) -> String {
    String::from_utf8_lossy(&o.stdout).into_owned() + &String::from_utf8_lossy(&o.stderr)
}

/// Every file under `dir`, relative to it.
fn listing(dir: &Path) -> Vec<PathBuf> {
    let mut out = Vec::new();
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        let name = PathBuf::from(path.file_name().unwrap());
        if path.is_dir() {
            out.extend(listing(&path).into_iter().map(|p| name.join(p)));
        } else {
            out.push(name);
        }
    }
    out.sort();
    out
}

#[test]
fn a_log_of_a_scene_with_nested_includes_replays_without_its_files() {
    let tmp = tempfile::tempdir().unwrap();
    let scene_dir = tmp.path().join("scene");
    let logs = tmp.path().join("logs");
    let elsewhere = tmp.path().join("elsewhere");
    for d in [&scene_dir, &logs, &elsewhere] {
        std::fs::create_dir(d).unwrap();
    }
    let (task, files) = scene_of_ones_own(&scene_dir);
    let o = reacher(
        &logs,
        &[
            "demo",
            "--task",
            task.to_str().unwrap(),
            "--episodes",
            "3",
            "--out",
            "demo.mcap",
        ],
    );
    assert!(o.status.success(), "{}", text(&o));
    let log_path = logs.join("demo.mcap");
    let log = read_log(&log_path).unwrap();
    let carried: Vec<(String, Vec<u8>)> = (log.scene_files.iter())
        .map(|f| {
            let prefix = match f.kind {
                SceneFileKind::Include => "include/",
                SceneFileKind::Asset => "asset/",
            };
            (format!("{prefix}{}", f.name), f.bytes.clone())
        })
        .collect();
    assert_eq!(
        carried, files,
        "the includes in reading order, then the assets"
    );
    let before = replay(&log).unwrap();
    assert!(before.all_match(), "{before}");

    // The scene's directory gone, and the commands run where no file of it could be found.
    std::fs::remove_dir_all(&scene_dir).unwrap();
    let log = read_log(&log_path).unwrap();
    let report = replay(&log).unwrap();
    assert!(report.all_match(), "{report}");
    assert_eq!(report.steps, log.steps());
    assert!(report.episodes.iter().all(|e| e.seed_reproduces_start));
    assert!(
        (report.setting_notes.iter()).any(|n| n.contains(
            "the scene reads 4 more files (parts/outer.xml, parts/motors.xml, meshes/tet.obj, \
             textures/grey.png); replaying with the copies stored in the log"
        )),
        "{:?}",
        report.setting_notes
    );
    let log_arg = log_path.to_str().unwrap();
    let o = reacher(&elsewhere, &["replay", "--verify", log_arg]);
    assert!(o.status.success(), "{}", text(&o));
    let picture = logs.join("ep.png");
    let o = reacher(
        &elsewhere,
        &["render", log_arg, "--out", picture.to_str().unwrap()],
    );
    assert!(o.status.success(), "{}", text(&o));
    let view = logs.join("view.mcap");
    let o = reacher(
        &elsewhere,
        &["foxglove", log_arg, "--out", view.to_str().unwrap()],
    );
    assert!(o.status.success(), "{}", text(&o));
    // The view copies the attachments: it replays too.
    let o = reacher(&elsewhere, &["replay", "--verify", view.to_str().unwrap()]);
    assert!(o.status.success(), "{}", text(&o));
    assert_eq!(
        listing(&logs),
        ["demo.mcap", "ep.png", "view.mcap"].map(PathBuf::from),
        "nothing but what was asked for is written"
    );
    assert!(listing(&elsewhere).is_empty());

    official_reader_sees(&log_path, &files);

    // A changed byte of a carried file is damage the reader finds (the attachment's CRC).
    let mut bytes = std::fs::read(&log_path).unwrap();
    let motors = &files[1].1;
    let at = (bytes.windows(motors.len()))
        .position(|w| w == motors.as_slice())
        .unwrap();
    bytes[at + motors.len() / 2] ^= 1;
    let damaged = logs.join("damaged.mcap");
    std::fs::write(&damaged, bytes).unwrap();
    let e = read_log(&damaged).unwrap_err();
    assert!(matches!(e, LogError::Corrupt { .. }), "{e}");
}

/// The official `mcap` Python reader lists the log's attachments: `model.xml`, the scene's
/// files with their bytes, `config.json`. Skipped where Python or its `mcap` package is
/// missing; the workplace's shared checker runs too where it exists.
fn official_reader_sees(log: &Path, files: &[(String, Vec<u8>)]) {
    let script = "import hashlib, sys\n\
                  from mcap.reader import make_reader\n\
                  with open(sys.argv[1], 'rb') as f:\n\
                  \x20   for a in make_reader(f).iter_attachments():\n\
                  \x20       print(a.name, a.media_type, hashlib.sha256(a.data).hexdigest())\n";
    let Ok(o) = Command::new("python3")
        .args(["-c", script])
        .arg(log)
        .output()
    else {
        eprintln!("SKIPPED: python3 is not available");
        return;
    };
    if String::from_utf8_lossy(&o.stderr).contains("No module named 'mcap'") {
        eprintln!("SKIPPED: python3 has no mcap package");
        return;
    }
    assert!(o.status.success(), "{}", text(&o));
    let sha = |bytes: &[u8]| {
        use sha2::Digest;
        (sha2::Sha256::digest(bytes).iter())
            .map(|b| format!("{b:02x}"))
            .collect::<String>()
    };
    let lines: Vec<String> = String::from_utf8_lossy(&o.stdout)
        .lines()
        .map(str::to_string)
        .collect();
    assert_eq!(lines.len(), files.len() + 2, "{lines:?}");
    assert!(
        lines[0].starts_with("model.xml application/xml "),
        "{lines:?}"
    );
    for ((name, bytes), line) in files.iter().zip(&lines[1..]) {
        let media = if name.starts_with("include/") {
            "application/xml"
        } else {
            "application/octet-stream"
        };
        assert_eq!(line, &format!("{name} {media} {}", sha(bytes)));
    }
    assert!(
        lines[files.len() + 1].starts_with("config.json "),
        "{lines:?}"
    );
    let checker = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/tools/check_mcap.py");
    if checker.exists() {
        let o = Command::new("python3")
            .arg(&checker)
            .arg(log)
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", text(&o));
    }
}

#[test]
fn a_log_of_a_scene_that_reads_no_other_file_carries_none() {
    let tmp = tempfile::tempdir().unwrap();
    let ring = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/scenes/six_targets_ring.toml");
    for task in ["composite", ring.to_str().unwrap()] {
        let out = tmp.path().join("demo.mcap");
        let o = reacher(
            tmp.path(),
            &[
                "demo",
                "--task",
                task,
                "--episodes",
                "1",
                "--out",
                "demo.mcap",
            ],
        );
        assert!(o.status.success(), "{}", text(&o));
        let log = read_log(&out).unwrap();
        assert!(log.scene_files.is_empty(), "{task}");
        let report = replay(&log).unwrap();
        assert!(report.all_match(), "{report}");
        assert!(
            !(report.setting_notes.iter()).any(|n| n.contains("copies stored in the log")),
            "{:?}",
            report.setting_notes
        );
        std::fs::remove_file(out).unwrap();
    }
}

/// A log of the built-in composite task whose header carries `files` (as no task gives them:
/// the writer records what it is given).
fn log_with(path: &Path, files: Vec<SceneFile>) {
    let task = smirl::env::reacher_task::ReacherTask::shipped("composite").unwrap();
    let mut header = RunHeader::of_task("composite", task.task(), 0, serde_json::json!({}));
    header.scene_files = Arc::from(files);
    RolloutLogger::create(path, header, LogOptions::default())
        .unwrap()
        .finish()
        .unwrap();
}

fn file(kind: SceneFileKind, name: String, bytes: Vec<u8>) -> SceneFile {
    SceneFile { kind, name, bytes }
}

#[test]
fn what_a_log_carries_is_bounded_as_a_scene_is() {
    let tmp = tempfile::tempdir().unwrap();
    let path = tmp.path().join("big.mcap");
    let include = |k: usize| file(SceneFileKind::Include, format!("p/{k}.xml"), b"<m/>".into());
    let asset = |k: usize, n: usize| file(SceneFileKind::Asset, format!("m/{k}.stl"), vec![1; n]);
    let each = 15 << 20;
    assert!(4 * each < MAX_INCLUDED_BYTES as usize && 5 * each > MAX_INCLUDED_BYTES as usize);
    let part = |k: usize| {
        file(
            SceneFileKind::Include,
            format!("p/{k}.xml"),
            vec![b' '; each],
        )
    };
    let cases: [(Vec<SceneFile>, String); 5] = [
        (
            (0..=MAX_INCLUDED_FILES).map(include).collect(),
            format!(
                "attachment include/p/{MAX_INCLUDED_FILES}.xml: the scene's included files \
                 number more than the limit of {MAX_INCLUDED_FILES}"
            ),
        ),
        (
            vec![file(
                SceneFileKind::Include,
                "huge.xml".into(),
                vec![b' '; 16 << 20 | 1],
            )],
            "attachment include/huge.xml: 16777217 bytes, more than the limit of 16777216".into(),
        ),
        (
            (0..5).map(part).collect(),
            format!(
                "attachment include/p/4.xml: the scene's included files hold more than the \
                 limit of {MAX_INCLUDED_BYTES} bytes together"
            ),
        ),
        (
            (0..=MAX_ASSET_FILES).map(|k| asset(k, 1)).collect(),
            format!(
                "attachment asset/m/{MAX_ASSET_FILES}.stl: the scene's mesh, skin, height-field \
                 and texture files number more than the limit of {MAX_ASSET_FILES}"
            ),
        ),
        (
            vec![
                asset(0, MAX_ASSET_BYTES as usize / 2),
                asset(1, MAX_ASSET_BYTES as usize / 2 + 1),
            ],
            format!(
                "attachment asset/m/1.stl: the scene's mesh, skin, height-field and texture \
                 files hold more than the limit of {MAX_ASSET_BYTES} bytes together"
            ),
        ),
    ];
    for (files, expected) in cases {
        log_with(&path, files);
        let e = read_log(&path).unwrap_err();
        assert!(matches!(e, LogError::TooLarge { .. }), "{e}");
        assert!(
            e.to_string().contains(&expected),
            "{e}\nexpected: {expected}"
        );
        let o = reacher(tmp.path(), &["replay", "big.mcap"]);
        assert_eq!(o.status.code(), Some(1), "{}", text(&o));
        assert!(text(&o).contains(&expected), "{}", text(&o));
    }
    // A model.xml longer than a task's scene file may be.
    let task = smirl::env::reacher_task::ReacherTask::shipped("composite").unwrap();
    let mut header = RunHeader::of_task("composite", task.task(), 0, serde_json::json!({}));
    header.model_xml = " ".repeat(MAX_SCENE_BYTES as usize + 1);
    RolloutLogger::create(&path, header, LogOptions::default())
        .unwrap()
        .finish()
        .unwrap();
    let e = read_log(&path).unwrap_err();
    assert!(matches!(e, LogError::TooLarge { .. }), "{e}");
    let expected = format!(
        "attachment model.xml: {} bytes, more than the limit of {MAX_SCENE_BYTES} for a scene \
         file",
        MAX_SCENE_BYTES + 1
    );
    assert!(e.to_string().contains(&expected), "{e}");

    // Within the limits, the same files are read back.
    let within: Vec<SceneFile> = (0..MAX_INCLUDED_FILES)
        .map(include)
        .chain((0..MAX_ASSET_FILES).map(|k| asset(k, 3)))
        .collect();
    log_with(&path, within.clone());
    assert_eq!(read_log(&path).unwrap().scene_files, within);
}

/// A log of the largest scene a task accepts (a text of MAX_SCENE_BYTES, included files of
/// MAX_INCLUDED_BYTES, asset files of MAX_ASSET_BYTES) is read whole, and takes less than
/// 1 MiB more than MAX_LOGGED_SCENE_BYTES (which the reader's limit on a log's size is
/// asserted to exceed by the room for its episodes). Fails when the reader's limits fall
/// below a task's.
#[test]
fn a_log_of_the_largest_scene_a_task_accepts_is_read() {
    let tmp = tempfile::tempdir().unwrap();
    let path = tmp.path().join("largest.mcap");
    let each = MAX_SCENE_BYTES as usize;
    let per = |total: u64| total as usize / each;
    let files: Vec<SceneFile> = (0..per(MAX_INCLUDED_BYTES))
        .map(|k| {
            file(
                SceneFileKind::Include,
                format!("p/{k}.xml"),
                vec![b' '; each],
            )
        })
        .chain(
            (0..per(MAX_ASSET_BYTES))
                .map(|k| file(SceneFileKind::Asset, format!("m/{k}.stl"), vec![1; each])),
        )
        .collect();
    let carried: u64 = files.iter().map(|f| f.bytes.len() as u64).sum();
    assert_eq!(carried, MAX_INCLUDED_BYTES + MAX_ASSET_BYTES);
    let task = smirl::env::reacher_task::ReacherTask::shipped("composite").unwrap();
    let mut header = RunHeader::of_task("composite", task.task(), 0, serde_json::json!({}));
    header.model_xml = REACHER_XML.to_string() + &" ".repeat(each - REACHER_XML.len());
    assert_eq!(header.model_xml.len() as u64, MAX_SCENE_BYTES);
    header.scene_files = Arc::from(files.clone());
    RolloutLogger::create(&path, header, LogOptions::default())
        .unwrap()
        .finish()
        .unwrap();
    let size = std::fs::metadata(&path).unwrap().len();
    assert!(size < MAX_LOGGED_SCENE_BYTES + (1 << 20), "{size}");
    let log = read_log(&path).unwrap();
    assert_eq!(log.scene_files, files);
    assert_eq!(log.model_xml.unwrap().len() as u64, MAX_SCENE_BYTES);
}

/// Two included files of one name in two directories: MuJoCo reads them from disk, but finds
/// a file in memory by its name alone, so a log of the scene could not be compiled. The task
/// is refused when it loads, naming both, before any work (it compiles its scene as a log
/// does); the same bytes under two such names are one file, and the task runs. A log that
/// carries such files anyway is refused when it is replayed.
#[test]
fn files_that_memory_cannot_tell_apart_are_refused_when_the_task_loads() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    let size = |n: usize| format!("<mujoco><size nuserdata=\"{n}\"/></mujoco>");
    std::fs::create_dir_all(d.join("a")).unwrap();
    std::fs::create_dir_all(d.join("b")).unwrap();
    std::fs::write(d.join("a/part.xml"), size(1)).unwrap();
    std::fs::write(d.join("b/Part.xml"), size(2)).unwrap();
    let compiler = "<compiler angle=\"radian\" inertiafromgeom=\"true\"/>";
    let scene = REACHER_XML.replacen(
        compiler,
        &format!("{compiler}<include file=\"a/part.xml\"/><include file=\"b/Part.xml\"/>"),
        1,
    );
    std::fs::write(d.join("scene.xml"), scene).unwrap();
    std::fs::write(d.join("m.txt"), MACHINE).unwrap();
    std::fs::write(d.join("task.toml"), TASK).unwrap();
    let both = "files a/part.xml and b/Part.xml differ but share the name 'part.xml', and MuJoCo \
                2.2 finds a file in memory by that name alone";
    let e = smirl::env::task_file::Task::load(&d.join("task.toml")).unwrap_err();
    assert!(e.to_string().contains(both), "{e}");
    let demo = [
        "demo",
        "--task",
        "task.toml",
        "--episodes",
        "1",
        "--out",
        "demo.mcap",
    ];
    let o = reacher(d, &demo);
    assert_eq!(o.status.code(), Some(2), "{}", text(&o));
    assert!(text(&o).contains(both), "{}", text(&o));
    assert!(!d.join("demo.mcap").exists());

    // The same bytes under both names: one file in memory, and the log replays.
    std::fs::write(d.join("b/Part.xml"), size(1)).unwrap();
    let o = reacher(d, &demo);
    assert!(o.status.success(), "{}", text(&o));
    let o = reacher(d, &["replay", "--verify", "demo.mcap"]);
    assert!(o.status.success(), "{}", text(&o));

    let path = d.join("carried.mcap");
    log_with(
        &path,
        vec![
            file(SceneFileKind::Include, "a/part.xml".into(), size(1).into()),
            file(SceneFileKind::Include, "b/Part.xml".into(), size(2).into()),
        ],
    );
    let o = reacher(d, &["replay", "--verify", "carried.mcap"]);
    assert_eq!(o.status.code(), Some(1), "{}", text(&o));
    assert!(text(&o).contains(both), "{}", text(&o));
}

#[test]
fn a_log_without_the_files_compiles_its_text_alone_as_before() {
    // Logs written before logs carried a scene's files attach the scene's text only; it is
    // compiled alone, so its includes resolve where the command runs.
    let tmp = tempfile::tempdir().unwrap();
    let scene_dir = tmp.path().join("scene");
    std::fs::create_dir(&scene_dir).unwrap();
    let (task, _) = scene_of_ones_own(&scene_dir);
    let task = smirl::env::reacher_task::ReacherTask::resolve(task.to_str().unwrap()).unwrap();
    let mut header = RunHeader::of_task("task", task.task(), 0, serde_json::json!({}));
    header.scene_files = Arc::from(Vec::new());
    let old = tmp.path().join("old.mcap");
    RolloutLogger::create(&old, header, LogOptions::default())
        .unwrap()
        .finish()
        .unwrap();
    assert!(read_log(&old).unwrap().scene_files.is_empty());
    let old = old.to_str().unwrap();
    let o = reacher(&scene_dir, &["replay", old]);
    assert!(o.status.success(), "{}", text(&o));
    let o = reacher(tmp.path(), &["replay", old]);
    assert_eq!(o.status.code(), Some(1), "{}", text(&o));
    assert!(text(&o).contains("parts/outer.xml"), "{}", text(&o));
}

/// The text compiled from memory has a directory of its own (`smirl-log/`), and files are
/// still found in memory by their last component: a height field and a texture named in three
/// bytes compile. With no directory, MuJoCo 2.2.2 reads the last four bytes of each name
/// unchecked and aborts this test process.
#[test]
fn names_of_three_bytes_compile_from_memory() {
    let mut height_field = Vec::new();
    for v in [2i32, 2] {
        height_field.extend_from_slice(&v.to_le_bytes());
    }
    for h in [0.0f32, 0.1, 0.2, 0.3] {
        height_field.extend_from_slice(&h.to_le_bytes());
    }
    let mut texture = Vec::new();
    for v in [2i32, 2] {
        texture.extend_from_slice(&v.to_le_bytes());
    }
    texture.extend_from_slice(&[99; 12]);
    let xml = "<mujoco><asset><hfield name=\"h\" file=\"a.b\" size=\"1 1 0.1 0.1\"/>\
               <texture name=\"t\" type=\"2d\" file=\"x.p\"/></asset>\
               <worldbody><geom type=\"hfield\" hfield=\"h\"/></worldbody></mujoco>";
    let model = smirl::mujoco::Model::from_xml_with_files(
        xml,
        &[("a.b", &height_field), ("x.p", &texture)],
        "three bytes",
    )
    .unwrap();
    assert_eq!(model.ngeom(), 1);
}

/// Attachments a log could carry but no task writes: a name with no last component
/// (`include/`, `asset/dir/`), a NUL byte, a last component of 1000 bytes, no bytes. Each is
/// read, and compiling the log's scene fails with a message naming it; `replay` says so and
/// exits 1 (no panic, no abort). A name of 1000 bytes whose last component is short is found
/// by that component, as MuJoCo finds it.
#[test]
fn attachments_no_task_writes_are_clear_errors() {
    let tmp = tempfile::tempdir().unwrap();
    let path = tmp.path().join("odd.mcap");
    let long = "x".repeat(1000);
    let cases: [(SceneFile, String); 5] = [
        (
            file(SceneFileKind::Include, String::new(), b"<mujoco/>".into()),
            "file name '' does not end in a name of 1 to 999 bytes".into(),
        ),
        (
            file(SceneFileKind::Asset, "dir/".into(), vec![1]),
            "file name 'dir/' does not end in a name of 1 to 999 bytes".into(),
        ),
        (
            file(SceneFileKind::Asset, "m/a\0b.stl".into(), vec![1]),
            "holds a NUL byte".into(),
        ),
        (
            file(SceneFileKind::Asset, format!("m/{long}"), vec![1]),
            format!("file name 'm/{long}' does not end in a name of 1 to 999 bytes"),
        ),
        (
            file(SceneFileKind::Asset, "m/empty.stl".into(), Vec::new()),
            "file m/empty.stl is empty".into(),
        ),
    ];
    for (carried, expected) in cases {
        log_with(&path, vec![carried.clone()]);
        let log = read_log(&path).unwrap();
        assert_eq!(log.scene_files, [carried]);
        let e = log.reacher_model().unwrap_err().to_string();
        assert!(e.contains(&expected), "{e}\nexpected: {expected}");
        let o = reacher(tmp.path(), &["replay", "odd.mcap"]);
        assert_eq!(o.status.code(), Some(1), "{}", text(&o));
        assert!(text(&o).contains(&expected), "{}", text(&o));
    }
    let deep = format!("{}/m.stl", "d/".repeat(500));
    assert!(deep.len() > 1000);
    log_with(
        &path,
        vec![file(SceneFileKind::Asset, deep, TETRAHEDRON.into())],
    );
    read_log(&path).unwrap().reacher_model().unwrap();
}

/// A file the scene reads that its log lacks (a log no task writes: each carries every file)
/// is not read from where the command runs: the compile fails naming it as MuJoCo looks for it,
/// under `smirl-log/` in the working directory, the only place MuJoCo still looks.
#[test]
fn a_file_absent_from_the_log_is_not_read_from_the_working_directory() {
    let tmp = tempfile::tempdir().unwrap();
    let scene_dir = tmp.path().join("scene");
    let elsewhere = tmp.path().join("elsewhere");
    std::fs::create_dir(&scene_dir).unwrap();
    std::fs::create_dir(&elsewhere).unwrap();
    let (task, _) = scene_of_ones_own(&scene_dir);
    let task = smirl::env::reacher_task::ReacherTask::resolve(task.to_str().unwrap()).unwrap();
    let log = tmp.path().join("partial.mcap");
    for (absent, looked_for) in [
        ("meshes/tet.obj", "smirl-log/meshes/tet.obj"),
        ("parts/motors.xml", "smirl-log/parts/motors.xml"),
    ] {
        let mut header = RunHeader::of_task("task", task.task(), 0, serde_json::json!({}));
        let files: Vec<SceneFile> = (header.scene_files.iter())
            .filter(|f| f.name != absent)
            .cloned()
            .collect();
        assert_eq!(files.len(), 3);
        header.scene_files = Arc::from(files);
        RolloutLogger::create(&log, header, LogOptions::default())
            .unwrap()
            .finish()
            .unwrap();
        // The scene's own copy, where the command runs.
        let copy = elsewhere.join(absent);
        std::fs::create_dir_all(copy.parent().unwrap()).unwrap();
        std::fs::copy(scene_dir.join(absent), &copy).unwrap();
        let o = reacher(&elsewhere, &["replay", log.to_str().unwrap()]);
        assert_eq!(o.status.code(), Some(1), "{}", text(&o));
        assert!(text(&o).contains(looked_for), "{}", text(&o));

        let copy = elsewhere.join(looked_for);
        std::fs::create_dir_all(copy.parent().unwrap()).unwrap();
        std::fs::copy(scene_dir.join(absent), &copy).unwrap();
        let o = reacher(&elsewhere, &["replay", log.to_str().unwrap()]);
        assert!(o.status.success(), "{}", text(&o));
        std::fs::remove_dir_all(elsewhere.join("smirl-log")).unwrap();
    }
}

/// Logs no task writes whose scene names a file on which MuJoCo 2.2.2 aborts the process (an
/// uncaught C++ exception, which no Rust code can catch): a mesh named in 2 bytes, in the
/// log's text and in an included file the log carries; a height field and a texture named in
/// 3 bytes in a log that carries no file (its text is compiled alone, with no directory); a
/// mesh named in 2 bytes by a file such a log includes from disk. Each log reads, compiling its
/// scene is an error naming the log and the file, and `replay` and `foxglove` exit 1 saying
/// so, writing nothing. Without the walk before the compile, this test process aborts.
#[test]
fn a_log_naming_a_file_mujoco_aborts_on_is_refused_before_it_compiles() {
    let tmp = tempfile::tempdir().unwrap();
    let path = tmp.path().join("crafted.mcap");
    let before_world =
        |what: &str| REACHER_XML.replacen("<worldbody>", &format!("{what}<worldbody>"), 1);
    let mesh = "<asset><mesh name=\"m\" file=\"ab\"/></asset>";
    let on_disk = tmp.path().join("parts/more.xml");
    std::fs::create_dir_all(on_disk.parent().unwrap()).unwrap();
    std::fs::write(&on_disk, format!("<mujoco>{mesh}</mujoco>")).unwrap();
    let cases: [(String, Vec<SceneFile>, &str); 5] = [
        (
            before_world(mesh),
            vec![file(SceneFileKind::Asset, "ab".into(), TETRAHEDRON.into())],
            "mesh file smirl-log/ab: MuJoCo 2.2.2 aborts the process on this name: the file \
             name 'ab' has fewer than 3 bytes",
        ),
        (
            before_world("<include file=\"parts/more.xml\"/>"),
            vec![file(
                SceneFileKind::Include,
                "parts/more.xml".into(),
                format!("<mujoco>{mesh}</mujoco>").into(),
            )],
            "mesh file smirl-log/ab: MuJoCo 2.2.2 aborts",
        ),
        (
            before_world("<asset><hfield name=\"h\" file=\"a.b\" size=\"1 1 0.1 0.1\"/></asset>"),
            Vec::new(),
            "height-field file a.b: MuJoCo 2.2.2 aborts the process on this name: the name \
             'a.b' has fewer than 4 bytes",
        ),
        (
            before_world("<asset><texture name=\"t\" type=\"2d\" file=\"x.p\"/></asset>"),
            Vec::new(),
            "texture file x.p: MuJoCo 2.2.2 aborts",
        ),
        (
            before_world(&format!("<include file=\"{}\"/>", on_disk.display())),
            Vec::new(),
            "mesh file ab: MuJoCo 2.2.2 aborts",
        ),
    ];
    let task = smirl::env::reacher_task::ReacherTask::shipped("composite").unwrap();
    for (xml, files, expected) in cases {
        let mut header = RunHeader::of_task("composite", task.task(), 0, serde_json::json!({}));
        header.model_xml = xml;
        header.scene_files = Arc::from(files);
        RolloutLogger::create(&path, header, LogOptions::default())
            .unwrap()
            .finish()
            .unwrap();
        let e = read_log(&path)
            .unwrap()
            .reacher_model()
            .unwrap_err()
            .to_string();
        let named = format!("{}:model.xml: {expected}", path.display());
        assert!(e.contains(&named), "{e}\nexpected: {named}");
        let expected = format!("crafted.mcap:model.xml: {expected}");
        for args in [
            &["replay", "crafted.mcap"][..],
            &["foxglove", "crafted.mcap", "--out", "view.mcap"],
        ] {
            let o = reacher(tmp.path(), args);
            assert_eq!(o.status.code(), Some(1), "{args:?}: {}", text(&o));
            assert!(text(&o).contains(&expected), "{args:?}: {}", text(&o));
        }
        assert!(!tmp.path().join("view.mcap").exists());
    }
}
