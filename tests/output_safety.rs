//! No command deletes or replaces what it did not create (issue 16): `--out` naming `.`,
//! `..`, the home directory, a user's directory (with and without `--force`) or a file is
//! refused with exit 2 before any work, and the user's files are untouched. Regression
//! tests: on the previous main, `reacher --task or --quick --out .` emptied the working
//! directory, and `--out` naming a user's directory silently replaced it.

use smirl::output::{check_file, partial_path, OutputDir, MARKER};
use std::path::Path;
use std::process::{Command, Output};

fn run(bin: &str, cwd: &Path, home: &Path, args: &[&str]) -> Output {
    Command::new(bin)
        .args(args)
        .current_dir(cwd)
        .env("HOME", home)
        .output()
        .unwrap()
}

fn reacher(cwd: &Path, home: &Path, args: &[&str]) -> Output {
    run(env!("CARGO_BIN_EXE_reacher"), cwd, home, args)
}

fn office(cwd: &Path, home: &Path, args: &[&str]) -> Output {
    run(env!("CARGO_BIN_EXE_office"), cwd, home, args)
}

/// A user's directory with one file in it.
fn user_dir(path: &Path) {
    std::fs::create_dir_all(path).unwrap();
    std::fs::write(path.join("thesis.tex"), "mine").unwrap();
}

fn assert_untouched(path: &Path) {
    assert_eq!(
        std::fs::read_to_string(path.join("thesis.tex")).unwrap(),
        "mine",
        "{} was changed",
        path.display()
    );
    let names: Vec<_> = std::fs::read_dir(path)
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(names.len(), 1, "{}: {names:?}", path.display());
}

fn assert_refused(o: &Output, needle: &str) {
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "stderr: {err}");
    assert!(err.contains(needle), "expected {needle:?} in: {err}");
}

#[test]
fn reacher_and_office_refuse_protected_and_foreign_output_directories() {
    let tmp = tempfile::tempdir().unwrap();
    let home = tmp.path().join("home");
    let work = tmp.path().join("work");
    let results = tmp.path().join("results");
    user_dir(&work);
    user_dir(&home);
    user_dir(&results);

    let reacher_run = ["--task", "or", "--quick", "--algo", "maxent", "--quiet"];
    let office_run = ["--task", "0", "--seeds", "1"];
    let cases: [(&str, &str); 6] = [
        (".", "names no directory"),
        ("..", "names no directory"),
        ("../..", "names no directory"),
        ("../work", "working directory or one of its ancestors"),
        (home.to_str().unwrap(), "home directory"),
        ("../results", "not empty"),
    ];
    for force in [false, true] {
        for (out, needle) in cases {
            let needle = if force && needle == "not empty" {
                "not written by this program"
            } else {
                needle
            };
            let mut args: Vec<&str> = reacher_run.to_vec();
            args.extend(["--out", out]);
            if force {
                args.push("--force");
            }
            assert_refused(&reacher(&work, &home, &args), needle);
            let mut args: Vec<&str> = office_run.to_vec();
            args.extend(["--out", out]);
            if force {
                args.push("--force");
            }
            assert_refused(&office(&work, &home, &args), needle);
            assert_untouched(&work);
            assert_untouched(&home);
            assert_untouched(&results);
        }
    }

    // A file, and a place that cannot be written, are refused before any work.
    std::fs::write(tmp.path().join("file"), "mine").unwrap();
    assert_refused(
        &reacher(
            &work,
            &home,
            &[&reacher_run[..], &["--out", "../file"]].concat(),
        ),
        "not a directory",
    );
    assert_eq!(
        std::fs::read_to_string(tmp.path().join("file")).unwrap(),
        "mine"
    );
    assert_refused(
        &reacher(
            &work,
            &home,
            &[&reacher_run[..], &["--out", "../file/run"]].concat(),
        ),
        "is not a directory",
    );
    // `reacher prepare` and `reacher expert` follow the same rules.
    assert_refused(
        &reacher(
            &work,
            &home,
            &["prepare", "--task", "or", "--quick", "--out", "."],
        ),
        "names no directory",
    );
    assert_refused(
        &reacher(
            &work,
            &home,
            &["expert", "--task", "or", "--out", "../results", "--force"],
        ),
        "not written by this program",
    );
    assert_untouched(&results);
}

#[test]
fn file_outputs_are_not_replaced_without_force_and_inputs_are_read_first() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    let picture = dir.join("picture.png");
    std::fs::write(&picture, "mine").unwrap();
    // The output is checked before the (missing) log is even opened.
    let o = reacher(
        dir,
        dir,
        &["render", "missing.mcap", "--out", picture.to_str().unwrap()],
    );
    assert_refused(&o, "--force");
    let o = reacher(dir, dir, &["demo", "--out", picture.to_str().unwrap()]);
    assert_refused(&o, "--force");
    assert_eq!(std::fs::read_to_string(&picture).unwrap(), "mine");

    // learn-rm reads --compare before learning and writes nothing when it is bad.
    let log = dir.join("demos.mcap");
    let o = reacher(
        dir,
        dir,
        &["demo", "--out", log.to_str().unwrap(), "--episodes", "2"],
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let bad = dir.join("bad_rm.txt");
    std::fs::write(&bad, "states: 2\n(0, 1, 'r&', 1)\n").unwrap();
    let out = dir.join("learned");
    let o = reacher(
        dir,
        dir,
        &[
            "learn-rm",
            log.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--compare",
            bad.to_str().unwrap(),
        ],
    );
    assert_refused(&o, "bad_rm.txt");
    assert!(!out.join("learned_rm.txt").exists());
}

#[test]
fn a_marked_directory_is_replaced_only_with_force() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("run");
    let first = OutputDir::check(&out, false).unwrap();
    let partial = first.begin().unwrap();
    std::fs::write(partial.join("metrics.csv"), "first").unwrap();
    first.commit(&partial).unwrap();
    assert!(out.join(MARKER).is_file());
    assert!(!partial_path(&out).exists());

    let e = OutputDir::check(&out, false).unwrap_err();
    assert!(e.problem.contains("--force"), "{e}");
    let second = OutputDir::check(&out, true).unwrap();
    let partial = second.begin().unwrap();
    std::fs::write(partial.join("metrics.csv"), "second").unwrap();
    second.commit(&partial).unwrap();
    assert_eq!(
        std::fs::read_to_string(out.join("metrics.csv")).unwrap(),
        "second"
    );
    let leftovers: Vec<_> = std::fs::read_dir(tmp.path())
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(leftovers, vec![std::ffi::OsString::from("run")]);

    // A leftover .partial without the marker is the user's: refused, kept.
    let other = tmp.path().join("other");
    user_dir(&partial_path(&other));
    assert!(OutputDir::check(&other, true).is_err());
    assert_untouched(&partial_path(&other));

    // Files: an existing one only with force; a directory never.
    let file = tmp.path().join("f.png");
    std::fs::write(&file, "x").unwrap();
    assert!(check_file(&file, false).is_err());
    assert!(check_file(&file, true).is_ok());
    assert!(check_file(tmp.path(), true).is_err());
}
