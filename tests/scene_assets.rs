//! A scene's mesh, texture, height-field and skin files are part of its task's expert key, as
//! its included files are: editing one makes another key, the same files the same key; a
//! missing one, or more of them than the limits allow, stops the task before any work with a
//! message naming the file; and a scene that reads no other file keeps the key its committed
//! expert is named by.

use smirl::env::reacher_task::ReacherTask;
use smirl::env::scene_files::{read_scene_files, SceneFileKind, MAX_ASSET_BYTES, MAX_ASSET_FILES};
use smirl::env::task_file::{Task, TaskProblem};
use smirl::pipeline::reacher_expert::{default_expert_cache, expert_cache_path};
use std::path::{Path, PathBuf};
use std::process::Command;

/// A tetrahedron as Wavefront OBJ, a mesh MuJoCo 2.2.2 compiles.
const TETRAHEDRON: &str =
    "v 0 0 0\nv 0.01 0 0\nv 0 0.01 0\nv 0 0 0.01\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n";

/// A `side`×`side` grey PNG of brightness `value`.
fn png(side: u32, value: u8) -> Vec<u8> {
    let mut out = Vec::new();
    let mut encoder = png::Encoder::new(&mut out, side, side);
    encoder.set_color(png::ColorType::Rgb);
    encoder.set_depth(png::BitDepth::Eight);
    let mut writer = encoder.write_header().unwrap();
    writer
        .write_image_data(&vec![value; (3 * side * side) as usize])
        .unwrap();
    writer.finish().unwrap();
    out
}

/// A height field in MuJoCo's own binary format: rows, columns, then the heights.
fn hfield(heights: [f32; 4]) -> Vec<u8> {
    let mut out = Vec::new();
    out.extend_from_slice(&2i32.to_le_bytes());
    out.extend_from_slice(&2i32.to_le_bytes());
    for h in heights {
        out.extend_from_slice(&h.to_le_bytes());
    }
    out
}

const MACHINE: &str = "vocabulary: ab\nstates: 3\ninitial: 0\nterminal: 2\n\
                       (0, 1, 'a', 0)\n(1, 2, 'b', 1)\n";
const TASK: &str = "scene = \"scene.xml\"\nmachine = \"m.txt\"\nepisode_steps = 50\n\
                    randomize_layout = false\n\
                    [[region]]\nletter = \"a\"\nbody = \"red\"\nradius = 0.02\n\
                    [[region]]\nletter = \"b\"\nbody = \"blue\"\nradius = 0.02\n";

/// The built-in scene with `compiler` as its compiler's further attributes and `assets` in an
/// `<asset>` element; the task file over it in `dir`, and the task's path.
fn scene_with(dir: &Path, compiler: &str, assets: &str) -> PathBuf {
    let xml = smirl::assets::REACHER_XML;
    let compiler_tag = "<compiler angle=\"radian\" inertiafromgeom=\"true\"/>";
    assert!(xml.contains(compiler_tag));
    let scene = xml.replacen(
        compiler_tag,
        &format!(
            "<compiler angle=\"radian\" inertiafromgeom=\"true\" {compiler}/>\n\
             <asset>{assets}</asset>"
        ),
        1,
    );
    std::fs::write(dir.join("scene.xml"), scene).unwrap();
    std::fs::write(dir.join("m.txt"), MACHINE).unwrap();
    std::fs::write(dir.join("task.toml"), TASK).unwrap();
    dir.join("task.toml")
}

/// A mesh, a 2D texture, the six faces of a cube texture, a height field and a built-in
/// texture whose `file` is never read, in `meshes/` and `textures/`.
const ASSETS: &str = "<mesh name=\"tet\" file=\"tet.obj\"/>\
                      <texture name=\"grey\" type=\"2d\" file=\"grey.png\"/>\
                      <texture name=\"box\" type=\"cube\" fileright=\"f.png\" fileleft=\"f.png\" \
                      fileup=\"f.png\" filedown=\"f.png\" filefront=\"f.png\" fileback=\"back.png\"/>\
                      <texture name=\"made\" type=\"2d\" builtin=\"checker\" width=\"8\" height=\"8\" \
                      file=\"absent.png\"/>\
                      <hfield name=\"ground\" file=\"ground.bin\" size=\"1 1 0.1 0.1\"/>";

fn write_assets(dir: &Path) {
    std::fs::create_dir_all(dir.join("meshes")).unwrap();
    std::fs::create_dir_all(dir.join("textures")).unwrap();
    std::fs::write(dir.join("meshes/tet.obj"), TETRAHEDRON).unwrap();
    std::fs::write(dir.join("meshes/ground.bin"), hfield([0.0, 0.1, 0.2, 0.3])).unwrap();
    std::fs::write(dir.join("textures/grey.png"), png(4, 128)).unwrap();
    std::fs::write(dir.join("textures/f.png"), png(2, 10)).unwrap();
    std::fs::write(dir.join("textures/back.png"), png(2, 20)).unwrap();
}

fn key(task: &Path) -> String {
    Task::load(task).unwrap().content_hash
}

#[test]
fn every_file_the_scene_reads_is_part_of_the_expert_key() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    write_assets(dir);
    let task = scene_with(dir, "meshdir=\"meshes\" texturedir=\"textures\"", ASSETS);
    let loaded = Task::load(&task).unwrap();
    let names: Vec<(&str, SceneFileKind)> = (loaded.scene_files.iter())
        .map(|f| (f.name.as_str(), f.kind))
        .collect();
    assert_eq!(
        names,
        [
            "meshes/tet.obj",
            "textures/grey.png",
            "textures/f.png",
            "textures/back.png",
            "meshes/ground.bin",
        ]
        .map(|n| (n, SceneFileKind::Asset)),
        "each file once, in the document's order; the built-in texture reads none"
    );
    let first = loaded.content_hash;
    assert_eq!(key(&task), first, "the same files, the same key");

    let edits: [(&str, Vec<u8>); 4] = [
        (
            "meshes/tet.obj",
            TETRAHEDRON.replace("0.01 0 0", "0.02 0 0").into(),
        ),
        ("textures/grey.png", png(4, 129)),
        ("textures/back.png", png(2, 21)),
        ("meshes/ground.bin", hfield([0.0, 0.1, 0.2, 0.4])),
    ];
    let mut keys = vec![first.clone()];
    for (file, edited) in edits {
        let original = std::fs::read(dir.join(file)).unwrap();
        std::fs::write(dir.join(file), &edited).unwrap();
        let changed = key(&task);
        assert!(!keys.contains(&changed), "an edited {file} makes a new key");
        keys.push(changed);
        std::fs::write(dir.join(file), original).unwrap();
        assert_eq!(key(&task), first, "{file} restored, the first key again");
    }

    // The last compiler to set a directory holds, an absolute directory is taken as it
    // stands, and `strippath` drops the names' own directories.
    let moved = tempfile::tempdir().unwrap();
    std::fs::create_dir(moved.path().join("m")).unwrap();
    std::fs::write(moved.path().join("m/tet.obj"), TETRAHEDRON).unwrap();
    let absolute = format!("{}/m", moved.path().display());
    let task = scene_with(
        dir,
        &format!("meshdir=\"elsewhere\"/><compiler meshdir=\"{absolute}\" strippath=\"true\""),
        "<mesh name=\"tet\" file=\"some/where/tet.obj\"/>",
    );
    let loaded = Task::load(&task).unwrap();
    assert_eq!(
        (loaded.scene_files.iter())
            .map(|f| f.name.as_str())
            .collect::<Vec<_>>(),
        [format!("{absolute}/tet.obj")]
    );
    let before = loaded.content_hash;
    std::fs::write(
        moved.path().join("m/tet.obj"),
        TETRAHEDRON.replace("0.01", "0.03"),
    )
    .unwrap();
    assert_ne!(key(&task), before);
}

#[test]
fn a_scene_that_reads_no_other_file_keeps_its_key() {
    // The committed experts of task files are found by the key of their task, scene and
    // machine alone.
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    for file in [
        "assets/tasks/new/pair.toml",
        "assets/tasks/new/avoid.toml",
        "assets/tasks/new/loop.toml",
        "assets/tasks/new/switch.toml",
        "assets/scenes/six_targets_ring.toml",
        "assets/scenes/six_targets_detour.toml",
    ] {
        let task = ReacherTask::resolve(root.join(file).to_str().unwrap()).unwrap();
        assert!(task.task().scene_files.is_empty(), "{file}");
        let cache = default_expert_cache(&task).unwrap();
        let policy = expert_cache_path(&cache, task);
        assert!(policy.is_file(), "{file}: no {}", policy.display());
    }
}

/// `reacher --task TASK --quick` in a fresh run directory: its exit status and message.
fn run(task: &Path) -> (Option<i32>, String) {
    let out = tempfile::tempdir().unwrap();
    let output = Command::new(env!("CARGO_BIN_EXE_reacher"))
        .args(["--task", task.to_str().unwrap(), "--quick", "--out"])
        .arg(out.path().join("run"))
        .output()
        .unwrap();
    assert!(
        !out.path().join("run").exists(),
        "nothing is written for a refused task"
    );
    (
        output.status.code(),
        String::from_utf8_lossy(&output.stderr).into_owned(),
    )
}

#[test]
fn a_missing_asset_file_is_named_before_any_work() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    write_assets(dir);
    let task = scene_with(dir, "meshdir=\"meshes\" texturedir=\"textures\"", ASSETS);
    Task::load(&task).unwrap();
    for (file, what) in [
        ("textures/back.png", "texture file"),
        ("meshes/ground.bin", "height-field file"),
        ("meshes/tet.obj", "mesh file"),
    ] {
        let original = std::fs::read(dir.join(file)).unwrap();
        std::fs::remove_file(dir.join(file)).unwrap();
        let e = Task::load(&task).unwrap_err();
        assert!(matches!(e.problem(), Some(TaskProblem::Scene(_))), "{e}");
        let full = dir.join(file).display().to_string();
        let message = e.to_string();
        assert!(
            message.contains(&format!("{what} {full}: cannot read")),
            "{message}"
        );
        let (status, stderr) = run(&task);
        assert_eq!(status, Some(2), "{stderr}");
        assert!(stderr.contains(&full), "{stderr}");
        std::fs::write(dir.join(file), original).unwrap();
    }
}

#[test]
fn more_asset_files_or_bytes_than_the_limits_are_refused_naming_the_file() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    // One file more than the limit: the files are counted before MuJoCo compiles anything,
    // so they need not be meshes.
    std::fs::create_dir(dir.join("many")).unwrap();
    let mut assets = String::new();
    for k in 0..=MAX_ASSET_FILES {
        std::fs::write(dir.join(format!("many/{k}.stl")), "x").unwrap();
        assets.push_str(&format!("<mesh name=\"m{k}\" file=\"many/{k}.stl\"/>"));
    }
    let task = scene_with(dir, "", &assets);
    let e = Task::load(&task).unwrap_err();
    assert!(
        e.to_string().contains(&format!(
            "names more than {MAX_ASSET_FILES} mesh, skin, height-field and texture files"
        )),
        "{e}"
    );
    let (status, stderr) = run(&task);
    assert_eq!(status, Some(2), "{stderr}");

    // A file that alone holds more than the bytes allowed (sparse: nothing is written).
    let big = std::fs::File::create(dir.join("big.stl")).unwrap();
    big.set_len(MAX_ASSET_BYTES + 1).unwrap();
    let task = scene_with(dir, "", "<mesh name=\"big\" file=\"big.stl\"/>");
    let e = Task::load(&task).unwrap_err();
    let full = dir.join("big.stl").display().to_string();
    assert!(
        e.to_string().contains(&format!(
            "mesh file {full}: the scene's mesh, skin, height-field and texture files hold \
             more than {MAX_ASSET_BYTES} bytes together"
        )),
        "{e}"
    );
    let (status, stderr) = run(&task);
    assert_eq!(status, Some(2), "{stderr}");
    assert!(stderr.contains(&full), "{stderr}");
}

#[test]
fn included_files_and_their_assets_are_read_in_the_assembled_document() {
    // An asset element in an included file, and a compiler directory set in another.
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    write_assets(dir);
    std::fs::create_dir(dir.join("parts")).unwrap();
    std::fs::write(
        dir.join("parts/assets.xml"),
        "<mujoco><mesh name=\"tet\" file=\"tet.obj\"/></mujoco>",
    )
    .unwrap();
    std::fs::write(
        dir.join("parts/compiler.xml"),
        "<mujoco><compiler meshdir=\"meshes\"/></mujoco>",
    )
    .unwrap();
    scene_with(dir, "", "<include file=\"parts/assets.xml\"/>");
    let text = std::fs::read_to_string(dir.join("scene.xml")).unwrap();
    std::fs::write(
        dir.join("scene.xml"),
        text.replacen(
            "<asset>",
            "<include file=\"parts/compiler.xml\"/><asset>",
            1,
        ),
    )
    .unwrap();
    let files = read_scene_files(&dir.join("scene.xml")).unwrap();
    let names: Vec<(&str, SceneFileKind)> = (files.files.iter())
        .map(|f| (f.name.as_str(), f.kind))
        .collect();
    assert_eq!(
        names,
        [
            ("parts/compiler.xml", SceneFileKind::Include),
            ("parts/assets.xml", SceneFileKind::Include),
            ("meshes/tet.obj", SceneFileKind::Asset),
        ]
    );
    // And MuJoCo reads the same files: the task loads.
    Task::load(&dir.join("task.toml")).unwrap();
}

/// The built-in scene with `<include file="NAME"/>` in place of its compiler tag (so the
/// included file's elements join the document there), and its task file, in `dir`.
fn scene_including(dir: &Path, name: &str) -> PathBuf {
    let xml = smirl::assets::REACHER_XML;
    let compiler_tag = "<compiler angle=\"radian\" inertiafromgeom=\"true\"/>";
    let scene = xml.replacen(
        compiler_tag,
        &format!("{compiler_tag}\n<include file=\"{name}\"/>"),
        1,
    );
    std::fs::write(dir.join("scene.xml"), scene).unwrap();
    std::fs::write(dir.join("m.txt"), MACHINE).unwrap();
    std::fs::write(dir.join("task.toml"), TASK).unwrap();
    dir.join("task.toml")
}

/// A scene that includes itself, two files that include each other, or one file included
/// twice (no cycle, the second time in another case), is refused at the second reading of a
/// file, as MuJoCo refuses it, naming the file — not read 64 levels deep. Fails without the
/// check of the files already read (the error is then the count of included files).
#[test]
fn a_file_included_twice_is_refused_naming_it() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    let task = scene_including(dir, "SCENE.xml");
    let e = Task::load(&task).unwrap_err().to_string();
    assert!(
        e.contains("already included") && e.contains("SCENE.xml"),
        "{e}"
    );

    let task = scene_including(dir, "a.xml");
    std::fs::write(
        dir.join("a.xml"),
        "<mujoco><include file=\"b.xml\"/></mujoco>",
    )
    .unwrap();
    std::fs::write(
        dir.join("b.xml"),
        "<mujoco><include file=\"a.xml\"/></mujoco>",
    )
    .unwrap();
    let e = Task::load(&task).unwrap_err().to_string();
    assert!(e.contains("already included") && e.contains("a.xml"), "{e}");
    let (code, out) = run(&task);
    assert_eq!(code, Some(2), "{out}");
    assert!(out.contains("already included"), "{out}");

    // No cycle: one file included twice, the second time in another case.
    let task = scene_including(dir, "c.xml\"/><include file=\"C.xml");
    std::fs::write(
        dir.join("c.xml"),
        "<mujoco><size nuserdata=\"1\"/></mujoco>",
    )
    .unwrap();
    let e = Task::load(&task).unwrap_err().to_string();
    let second = dir.join("C.xml").display().to_string();
    assert!(
        e.contains(&format!("included file {second}: already included")),
        "{e}"
    );
}

/// Included files beyond MAX_INCLUDED_BYTES together are refused naming the file that passes
/// the limit and the limit: five valid files of 15 MiB each (each within the limit of one
/// file), the fifth passing 64 MiB. Fails when included files have no limit together.
#[test]
fn included_files_beyond_their_byte_limit_are_refused_naming_the_file() {
    use smirl::env::scene_files::MAX_INCLUDED_BYTES;
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    let task = scene_including(dir, "parts.xml");
    let each = 15 << 20;
    assert!(4 * each < MAX_INCLUDED_BYTES && 5 * each > MAX_INCLUDED_BYTES);
    let part = format!("<mujoco>{}</mujoco>", " ".repeat(each as usize - 17));
    let mut parts = String::from("<mujoco>");
    for k in 1..=5 {
        std::fs::write(dir.join(format!("f{k}.xml")), &part).unwrap();
        parts += &format!("<include file=\"f{k}.xml\"/>");
    }
    std::fs::write(dir.join("parts.xml"), parts + "</mujoco>").unwrap();
    let e = Task::load(&task).unwrap_err().to_string();
    let expected = format!(
        "included file {}: the files the scene includes hold more than {MAX_INCLUDED_BYTES} \
         bytes together",
        dir.join("f5.xml").display()
    );
    assert!(e.contains(&expected), "{e}\nexpected: {expected}");
}

/// A scene of a million nested elements is read in time linear in its tags (the elements
/// around each tag are kept as a stack, not gathered again for every tag); MuJoCo then refuses
/// it. Gathering them again for every tag takes about 10¹² steps here and never ends in a
/// test run.
#[test]
fn a_deeply_nested_scene_is_read_in_linear_time() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    let task = scene_including(dir, "deep.xml");
    let depth = 1_000_000;
    let deep = format!(
        "<mujoco>{}{}</mujoco>",
        "<a>".repeat(depth),
        "</a>".repeat(depth)
    );
    std::fs::write(dir.join("deep.xml"), deep).unwrap();
    assert!(Task::load(&task).is_err());
}

/// The message of a task that does not load.
fn refusal(task: &Path) -> String {
    Task::load(task).unwrap_err().to_string()
}

/// Names on which MuJoCo 2.2.2 aborts the process (an uncaught `std::out_of_range`: the
/// compiler takes a mesh's or skin's last 3 bytes as its type, and reads a height field's or
/// texture's last 4 to tell a PNG file) are refused by name before MuJoCo compiles anything.
/// Without the refusal, the mesh named `ab` aborts this test process: the task's scene is
/// compiled in `Task::load`.
#[test]
fn names_mujoco_aborts_on_are_refused_before_it_compiles() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    write_assets(dir);
    std::fs::write(dir.join("ab"), TETRAHEDRON).unwrap();
    std::fs::write(dir.join("a.b"), hfield([0.0; 4])).unwrap();
    std::fs::write(dir.join("a.p"), png(2, 10)).unwrap();
    let full = |name: &str| dir.join(name).display().to_string();
    let cases = [
        (
            "",
            "<mesh name=\"m\" file=\"ab\"/>",
            format!(
                "mesh file {}: MuJoCo 2.2.2 aborts the process on this name: the file name \
                 'ab' has fewer than 3 bytes, and MuJoCo takes its last 3 as the file's type",
                full("ab")
            ),
        ),
        (
            // A name long enough until `strippath` drops its directory.
            "strippath=\"true\"",
            "<mesh name=\"m\" file=\"some/where/ab\"/>",
            format!("mesh file {}: MuJoCo 2.2.2 aborts", full("ab")),
        ),
        (
            "",
            "<skin file=\"s\"/>",
            format!("skin file {}: MuJoCo 2.2.2 aborts", full("s")),
        ),
        (
            "",
            "<hfield name=\"h\" file=\"a.b\" size=\"1 1 0.1 0.1\"/>",
            format!(
                "height-field file {}: MuJoCo 2.2.2 aborts the process on this name: the name \
                 'a.b' has fewer than 4 bytes, and MuJoCo reads its last 4 to tell a PNG file",
                full("a.b")
            ),
        ),
        (
            "",
            "<texture name=\"t\" type=\"2d\" file=\"a.p\"/>",
            format!("texture file {}: MuJoCo 2.2.2 aborts", full("a.p")),
        ),
        (
            "",
            "<texture name=\"t\" type=\"cube\" fileright=\"a.p\"/>",
            format!("texture file {}: MuJoCo 2.2.2 aborts", full("a.p")),
        ),
    ];
    for (compiler, assets, expected) in cases {
        let task = scene_with(dir, compiler, assets);
        let e = refusal(&task);
        assert!(e.contains(&expected), "{e}\nexpected: {expected}");
    }
    // The rule is on the name with its directory, as the scene gives it: the same file four
    // bytes long with `meshdir` is taken, whichever directory the task is loaded from.
    let task = scene_with(
        dir,
        "meshdir=\"./\"",
        "<hfield name=\"h\" file=\"a.b\" size=\"1 1 0.1 0.1\"/>",
    );
    let loaded = Task::load(&task).unwrap();
    assert_eq!(loaded.scene_files[0].name, "./a.b");

    // The command refuses it before any work, run from the scene's own directory too.
    let task = scene_with(
        dir,
        "",
        "<hfield name=\"h\" file=\"a.b\" size=\"1 1 0.1 0.1\"/>",
    );
    assert!(task.is_file());
    let out = tempfile::tempdir().unwrap();
    let o = Command::new(env!("CARGO_BIN_EXE_reacher"))
        .current_dir(dir)
        .args(["--task", "task.toml", "--quick", "--out"])
        .arg(out.path().join("run"))
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{stderr}");
    assert!(
        stderr.contains("a.b: MuJoCo 2.2.2 aborts the process on this name"),
        "{stderr}"
    );
    assert!(!out.path().join("run").exists());
}

/// A URDF scene (`<robot>`, in any case) is refused, naming its root: MuJoCo finds the meshes
/// it names by other rules, so its key and logs would miss them. MuJoCo reads a root named
/// `mujoco` in any case as MJCF (and its schema then refuses all but the lower case): the
/// files are found as MuJoCo finds them, its `<compiler>` directories holding, and MuJoCo's
/// message is the one shown, not a missing file's.
#[test]
fn a_urdf_scene_is_refused_and_the_mjcf_root_is_read_in_any_case() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    write_assets(dir);
    let task = scene_with(dir, "", "");
    std::fs::write(
        dir.join("scene.xml"),
        "<robot name=\"arm\"><link name=\"base\"><visual><geometry>\
         <mesh filename=\"meshes/tet.obj\"/></geometry></visual></link></robot>",
    )
    .unwrap();
    let e = refusal(&task);
    let scene = dir.join("scene.xml").display().to_string();
    assert!(
        e.contains(&format!(
            "{scene}: the root element is <robot>; a task's scene is an MJCF file, whose root \
             is <mujoco>"
        )),
        "{e}"
    );
    let (status, stderr) = run(&task);
    assert_eq!(status, Some(2), "{stderr}");
    assert!(stderr.contains("the root element is <robot>"), "{stderr}");
    std::fs::write(
        dir.join("scene.xml"),
        "<?xml version=\"1.0\"?><Robot name=\"arm\"/>",
    )
    .unwrap();
    assert!(refusal(&task).contains("the root element is <Robot>"));

    let task = scene_with(
        dir,
        "meshdir=\"meshes\"",
        "<mesh name=\"tet\" file=\"tet.obj\"/>",
    );
    let text = std::fs::read_to_string(dir.join("scene.xml")).unwrap();
    std::fs::write(
        dir.join("scene.xml"),
        text.replace("<mujoco ", "<MuJoCo ")
            .replace("</mujoco>", "</MuJoCo>"),
    )
    .unwrap();
    let files = read_scene_files(&dir.join("scene.xml")).unwrap();
    assert_eq!(files.files[0].name, "meshes/tet.obj");
    let e = refusal(&task);
    assert!(e.contains("Schema violation"), "{e}");
}

/// An absolute `texturedir` is taken as it stands: the texture is named by its absolute
/// path, is part of the key, and the scene compiles from memory with it.
#[test]
fn an_absolute_texturedir_is_taken_as_it_stands() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    let elsewhere = tempfile::tempdir().unwrap();
    std::fs::create_dir(elsewhere.path().join("t")).unwrap();
    std::fs::write(elsewhere.path().join("t/grey.png"), png(4, 128)).unwrap();
    // A file of that name beside the scene is not the one read.
    std::fs::create_dir(dir.join("t")).unwrap();
    std::fs::write(dir.join("t/grey.png"), png(4, 7)).unwrap();
    let absolute = format!("{}/t", elsewhere.path().display());
    let task = scene_with(
        dir,
        &format!("texturedir=\"{absolute}\""),
        "<texture name=\"grey\" type=\"2d\" file=\"grey.png\"/>",
    );
    let loaded = Task::load(&task).unwrap();
    let files: Vec<(&str, &[u8])> = (loaded.scene_files.iter())
        .map(|f| (f.name.as_str(), f.bytes.as_slice()))
        .collect();
    assert_eq!(
        files,
        [(
            format!("{absolute}/grey.png").as_str(),
            png(4, 128).as_slice()
        )]
    );
    std::fs::write(elsewhere.path().join("t/grey.png"), png(4, 129)).unwrap();
    assert_ne!(key(&task), loaded.content_hash);
}

/// `strippath="true"` drops the directories of a cube texture's faces as it drops a file's:
/// each face is read in `texturedir`, once however many faces name it.
#[test]
fn strippath_drops_the_directories_of_cube_faces() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    write_assets(dir);
    let task = scene_with(
        dir,
        "texturedir=\"textures\" strippath=\"true\"",
        "<texture name=\"box\" type=\"cube\" fileright=\"a/f.png\" fileleft=\"b/f.png\" \
         fileup=\"f.png\" filedown=\"c\\d\\f.png\" filefront=\"/abs/f.png\" \
         fileback=\"x/y/back.png\"/>",
    );
    let loaded = Task::load(&task).unwrap();
    let names: Vec<&str> = (loaded.scene_files.iter())
        .map(|f| f.name.as_str())
        .collect();
    assert_eq!(names, ["textures/f.png", "textures/back.png"]);
    let first = loaded.content_hash;
    std::fs::write(dir.join("textures/back.png"), png(2, 21)).unwrap();
    assert_ne!(key(&task), first);
}
