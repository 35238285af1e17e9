//! `reacher render`: a logged episode drawn as PNG (decodes, right size, the balls where the
//! log puts them, touches and cancel found); bad input is an error and leaves no file; a
//! closed output pipe ends `replay` quietly.

use smirl::env::reacher::ReacherConfig;
use smirl::log::demo::{log_scripted_demos, DemoSpec};
use smirl::log::{read_log, LogOptions, RolloutLog};
use smirl::pipeline::render::{render_episode, write_png, RenderOptions};
use smirl::rm::perfect;
use std::path::{Path, PathBuf};
use std::process::Command;

fn demos(path: &Path) {
    log_scripted_demos(
        path,
        &DemoSpec {
            task: "sequential".into(),
            sequence: "rgby".into(),
            episodes: 3,
            seed: 11,
            stop_when_done: true,
            // The task's event schedule, with the event in every episode.
            env: ReacherConfig::default(),
            event_probability: Some(1.0),
            reward_machine: Some(perfect::reacher("sequential").unwrap()),
        },
        LogOptions::default(),
    )
    .unwrap();
}

/// A temporary directory holding `seq.mcap` (three scripted Sequential demos), its path and
/// the log as read back.
fn logged_demos() -> (tempfile::TempDir, PathBuf, RolloutLog) {
    let dir = tempfile::tempdir().unwrap();
    let log_path = dir.path().join("seq.mcap");
    demos(&log_path);
    let log = read_log(&log_path).unwrap();
    (dir, log_path, log)
}

fn decode(path: &Path) -> (u32, u32, Vec<u8>) {
    let decoder = png::Decoder::new(std::fs::File::open(path).unwrap());
    let mut reader = decoder.read_info().unwrap();
    let mut buf = vec![0; reader.output_buffer_size()];
    let info = reader.next_frame(&mut buf).unwrap();
    assert_eq!(info.color_type, png::ColorType::Rgb);
    (info.width, info.height, buf)
}

#[test]
fn logged_episode_renders_to_a_png_with_its_balls_touches_and_cancel() {
    let (dir, _, log) = logged_demos();
    let options = RenderOptions {
        size: 320,
        poses: 4,
    };
    let pic = render_episode(&log, Some(1), &options).unwrap();
    assert_eq!((pic.episode, pic.steps), (1, log.episodes[1].steps.len()));
    // The scripted controller touches the balls in order; every episode has a cancel event.
    let order: String = pic.touches.iter().map(|t| t.1).collect();
    assert!(order.starts_with('r'), "{order}");
    let cancel = log.episodes[1].start.cancel_step as usize;
    if cancel <= pic.steps {
        assert_eq!(pic.event_step, Some(cancel));
    }

    let out = dir.path().join("ep1.png");
    write_png(&out, &pic).unwrap();
    let (w, h, pixels) = decode(&out);
    assert_eq!((w, h), (320, 320 + 28));
    let at = |(x, y): (f64, f64)| {
        let i = 3 * (y as usize * w as usize + x as usize);
        [pixels[i], pixels[i + 1], pixels[i + 2]]
    };
    // The red ball's centre carries the model's red (the arm or a touch marker could cover
    // other balls' centres; for this seed none covers the red one).
    let red = at(pic.ball_pixels[0]);
    assert!(
        red[0] > 150 && red[1] < 120 && red[2] < 120,
        "red ball {red:?}"
    );
    let background = at((3.0, 3.0));
    assert_eq!(background, [255, 255, 255]);
    let non_white = pixels.chunks(3).filter(|p| p != &[255, 255, 255]).count();
    assert!(non_white > (w * w / 2) as usize, "{non_white} drawn pixels");
    // No temporary file is left next to the picture (atomic writes use hidden `.NAME.tmp*`).
    for entry in std::fs::read_dir(dir.path()).unwrap() {
        let name = entry.unwrap().file_name().to_string_lossy().into_owned();
        assert!(
            !name.starts_with('.') && !name.ends_with(".part"),
            "left over: {name}"
        );
    }
}

#[test]
fn bad_input_is_an_error_and_writes_nothing() {
    let (dir, log_path, log) = logged_demos();
    let e = render_episode(&log, Some(9), &RenderOptions::default())
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("seq.mcap")
            && e.contains("episode 9 is not in the log")
            && e.contains("0, 1, 2"),
        "{e}"
    );

    let out = dir.path().join("pic.png");
    // `reacher render ARGS --out pic.png`
    let render = |args: &[&str]| {
        Command::new(env!("CARGO_BIN_EXE_reacher"))
            .arg("render")
            .args(args)
            .arg("--out")
            .arg(&out)
            .output()
            .unwrap()
    };
    let log = log_path.to_str().unwrap();
    let run = render(&[log, "--episode", "5"]);
    assert!(!run.status.success());
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(stderr.contains("episode 5 is not in the log"), "{stderr}");
    assert!(!out.exists());

    let junk = dir.path().join("junk.mcap");
    std::fs::write(&junk, b"this is not an MCAP file at all").unwrap();
    let run = render(&[junk.to_str().unwrap()]);
    assert!(!run.status.success());
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(
        stderr.contains("junk.mcap") && stderr.contains("not an MCAP file"),
        "{stderr}"
    );
    assert!(!out.exists());

    // The good case through the CLI writes the file.
    let run = render(&[log, "--episode", "2"]);
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    assert_eq!(decode(&out).0, 480);
}

/// `reacher replay LOG | head -0`: a reader that closes the pipe first ends the command the way
/// it ends `cat` (SIGPIPE), not with a panic in `println!` (regression: exit status 101 and
/// "failed printing to stdout" on stderr).
#[test]
fn replay_into_a_closed_pipe_ends_quietly() {
    use std::process::Stdio;
    let (_dir, log_path, _log) = logged_demos();
    let mut child = Command::new(env!("CARGO_BIN_EXE_reacher"))
        .arg("replay")
        .arg(&log_path)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    drop(child.stdout.take());
    let out = child.wait_with_output().unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!stderr.contains("panicked"), "{stderr}");
    assert_ne!(out.status.code(), Some(101), "{stderr}");
}
