//! experiments/protocol/run.py and table.py on a throwaway repository with a fake `reacher` (a
//! small Python script that writes job files): a preregistered evaluation resumes on a fresh
//! checkout from its committed lock and ledger alone — the jobs the ledger records are not run
//! again, a job killed by a signal is, a failed one never is — and the tables come from the
//! ledger without any run directory; `check` runs once, and `run` refuses once the protocol or
//! its config changes after the lock. Seeds here are the fake's, far from every real range;
//! nothing is written inside the repository's experiments/.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

const NAME: &str = "tmp_resume_test";

fn run_in(dir: &Path, program: &str, args: &[&str], env: &[(&str, &str)]) -> Output {
    let mut c = Command::new(program);
    c.args(args).current_dir(dir);
    for (k, v) in env {
        c.env(k, v);
    }
    c.output().unwrap_or_else(|e| panic!("{program}: {e}"))
}

fn git(dir: &Path, args: &[&str]) -> String {
    let o = run_in(dir, "git", args, &[]);
    assert!(
        o.status.success(),
        "git {args:?}: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    String::from_utf8(o.stdout).unwrap().trim().to_string()
}

fn commit_all(dir: &Path, message: &str) {
    git(dir, &["add", "-A"]);
    git(dir, &["commit", "-q", "-m", message]);
}

fn write(path: &Path, text: &str) {
    std::fs::create_dir_all(path.parent().unwrap()).unwrap();
    std::fs::write(path, text).unwrap();
}

/// The fake binary: `--version` names `commit`; `prepare` writes prepare.json; `job` appends
/// its (algo, seed) to `log`, dies by SIGKILL when listed in FAKE_KILL, exits 1 when listed in
/// FAKE_FAIL, else writes a job file (as `reacher job`, returning at once when it exists).
/// Its per-iteration success (the last row's) is 0.01, its final-set scores seed-dependent:
/// a table that reads the wrong one shows it.
fn fake_reacher(path: &Path, commit: &str, log: &Path) {
    let script = format!(
        r#"#!/usr/bin/env python3
import json, os, signal, sys
a = sys.argv[1:]
if a == ["--version"]:
    print("smirl 0.1.0 (commit {commit})")
    sys.exit(0)
opt = {{a[i]: a[i + 1] for i in range(1, len(a) - 1) if a[i].startswith("--")}}
if a[0] == "prepare":
    os.makedirs(opt["--out"], exist_ok=True)
    base = int(opt["--seed"])
    with open(os.path.join(opt["--out"], "prepare.json"), "w") as fh:
        json.dump({{"seeds": list(range(base, base + int(opt["--seeds"]))), "git_commit": "{commit}"}}, fh)
    sys.exit(0)
algo, seed = opt["--algo"], int(opt["--seed"])
with open("{log}", "a") as fh:
    fh.write(f"{{algo}}:{{seed}}\n")
if f"{{algo}}:{{seed}}" in os.environ.get("FAKE_KILL", "").split(","):
    os.kill(os.getpid(), signal.SIGKILL)
if f"{{algo}}:{{seed}}" in os.environ.get("FAKE_FAIL", "").split(","):
    sys.exit(1)
path = os.path.join(opt["--run"], "jobs", f"{{algo}}_seed{{seed}}.json")
if os.path.isfile(path):
    sys.exit(0)
def score(rate):
    return {{"episodes": 100, "success_rate": rate, "progress": 0.5, "final_ball": 0.1,
            "branches": {{"episodes": [50, 50], "successes": [int(50 * rate), 50]}}}}
record = {{"algo": algo, "seed": seed, "wall_secs": 12.0,
          "rows": [{{"iteration": 0, "success_rate": 0.0}}, {{"iteration": 1, "success_rate": 0.01}}],
          "loop_final_set": score((seed % 10) / 10)}}
if algo == "smirl":
    record["final_policy"] = {{"chosen": 1, "random": 0, "candidates": [
        {{"success_rate": 0.01, "final_set": score((seed % 10) / 10)}},
        {{"success_rate": 0.01, "final_set": score(0.96)}},
        {{"success_rate": 0.01, "final_set": score(0.2)}}]}}
os.makedirs(os.path.dirname(path), exist_ok=True)
with open(path, "w") as fh:
    json.dump(record, fh)
"#,
        log = log.display()
    );
    write(path, &script);
    let o = run_in(
        Path::new("/"),
        "chmod",
        &["+x", path.to_str().unwrap()],
        &[],
    );
    assert!(o.status.success());
}

/// A repository with the scripts, a "method" (the frozen commit) and a protocol of bases
/// `base` and `base + 10` on top. (Each test has bases of its own: `check` refuses seeds found
/// in any run directory under /tmp, such as another test's.)
fn protocol_repo(repo: &Path, base: u64) -> String {
    let manifest = Path::new(env!("CARGO_MANIFEST_DIR"));
    std::fs::create_dir_all(repo).unwrap();
    git(repo, &["init", "-q", "-b", "main"]);
    git(repo, &["config", "user.email", "test@example.invalid"]);
    git(repo, &["config", "user.name", "test"]);
    for f in ["run.py", "table.py"] {
        let text = std::fs::read_to_string(manifest.join("experiments/protocol").join(f)).unwrap();
        write(&repo.join("experiments/protocol").join(f), &text);
    }
    write(&repo.join(".gitignore"), "runs/\n__pycache__/\n");
    write(&repo.join("src/method.rs"), "// the method\n");
    write(
        &repo.join("experiments/reacher/config.toml"),
        "# a config\n",
    );
    commit_all(repo, "the method");
    let frozen = git(repo, &["rev-parse", "HEAD"]);
    write(
        &repo.join(format!("experiments/protocol/{NAME}.md")),
        "# A protocol of a test\n",
    );
    write(
        &repo.join(format!("experiments/protocol/{NAME}.toml")),
        &format!(
            "commit = \"{frozen}\"\nconfig = \"experiments/reacher/config.toml\"\n\
             bases = [{base}, {}]\n\n[[arm]]\nname = \"a\"\ntasks = [\"or\"]\n\
             algos = [\"smirl\", \"paper\"]\nn_bases = 2\nseeds = 2\n",
            base + 10
        ),
    );
    commit_all(repo, "the protocol");
    frozen
}

struct Session<'a> {
    repo: &'a Path,
    bin: &'a Path,
}

impl Session<'_> {
    fn script(&self, script: &str, args: &[&str], env: &[(&str, &str)]) -> Output {
        let path = format!("experiments/protocol/{script}");
        let mut all = vec![path.as_str()];
        all.extend_from_slice(args);
        run_in(self.repo, "python3", &all, env)
    }

    fn run(&self, env: &[(&str, &str)]) -> Output {
        let bin = self.bin.to_str().unwrap();
        self.script("run.py", &["run", NAME, "--bin", bin], env)
    }
}

fn log_lines(log: &Path) -> Vec<String> {
    std::fs::read_to_string(log)
        .unwrap_or_default()
        .lines()
        .map(String::from)
        .collect()
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

fn python_has_tomllib() -> bool {
    run_in(Path::new("/"), "python3", &["-c", "import tomllib"], &[])
        .status
        .success()
}

/// Check once, run with a kill, commit, resume on a fresh clone with a failure: what is done
/// or failed is not run again, the killed job is; the table reads the ledger alone.
#[test]
fn a_protocol_resumes_on_a_fresh_checkout_from_its_committed_ledger() {
    if !python_has_tomllib() {
        eprintln!("SKIPPED: python3 >= 3.11 (tomllib) is not available");
        return;
    }
    let tmp = tempfile::tempdir().unwrap();
    let first = tmp.path().join("first");
    let frozen = protocol_repo(&first, 910_000);
    let (bin, log) = (tmp.path().join("reacher"), tmp.path().join("jobs.log"));
    fake_reacher(&bin, &frozen, &log);
    let s1 = Session {
        repo: &first,
        bin: &bin,
    };
    let check = |s: &Session| {
        s.script(
            "run.py",
            &["check", NAME, "--bin", bin.to_str().unwrap()],
            &[],
        )
    };
    let o = check(&s1);
    assert!(o.status.success(), "check: {}", stderr(&o));
    let state = PathBuf::from(format!("experiments/protocol/{NAME}"));
    assert!(first.join(&state).join("lock.json").is_file());
    // `check` runs once.
    let o = check(&s1);
    assert_eq!(o.status.code(), Some(2), "a second check: {}", stderr(&o));
    assert!(stderr(&o).contains("lock.json exists"), "{}", stderr(&o));
    // `run` wants the lock committed.
    let o = s1.run(&[]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("not committed"), "{}", stderr(&o));
    commit_all(&first, "lock");

    // Session 1: the second job is killed, the session stops there.
    let o = s1.run(&[("FAKE_KILL", "smirl:910001")]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert_eq!(log_lines(&log), ["smirl:910000", "smirl:910001"]);
    commit_all(&first, "session 1's ledger");

    // Session 2 on a fresh clone (no runs/): the done job is not run again, the killed one is;
    // one job fails.
    let second = tmp.path().join("second");
    let o = run_in(
        tmp.path(),
        "git",
        &[
            "clone",
            "-q",
            first.to_str().unwrap(),
            second.to_str().unwrap(),
        ],
        &[],
    );
    assert!(o.status.success());
    assert!(!second.join("runs").exists());
    std::fs::remove_file(&log).unwrap();
    let s2 = Session {
        repo: &second,
        bin: &bin,
    };
    let o = s2.run(&[("FAKE_FAIL", "paper:910010")]);
    assert!(o.status.success(), "session 2: {}", stderr(&o));
    assert_eq!(
        log_lines(&log),
        [
            "smirl:910001",
            "paper:910000",
            "paper:910001",
            "smirl:910010",
            "smirl:910011",
            "paper:910010",
            "paper:910011"
        ]
    );
    // Session 3, same checkout: nothing left to run (the failed job is not retried).
    std::fs::remove_file(&log).unwrap();
    let o = s2.run(&[]);
    assert!(o.status.success(), "session 3: {}", stderr(&o));
    assert_eq!(log_lines(&log), Vec::<String>::new());
    let status = s2.script("run.py", &["status", NAME], &[]);
    assert!(String::from_utf8_lossy(&status.stdout).contains("7 of 8 jobs done, 1 failed"));

    // The tables from the ledger alone.
    std::fs::remove_dir_all(second.join("runs")).unwrap();
    let o = s2.script("table.py", &[NAME], &[]);
    assert!(o.status.success(), "table: {}", stderr(&o));
    let jobs = std::fs::read_to_string(second.join(&state).join("jobs.csv")).unwrap();
    let row = |algo: &str, seed: u64| -> Vec<String> {
        let line = jobs
            .lines()
            .find(|l| l.contains(&format!(",{algo},{seed},")))
            .unwrap_or_else(|| panic!("no row {algo} {seed} in\n{jobs}"));
        line.split(',').map(String::from).collect()
    };
    // arm, task, base, algo, seed, status, loop, chosen, random_pick, loop_branches, ...
    // The loop's own policy on the final set (lower branch: seed % 10 / 10), not its last
    // per-iteration row (0.01); chosen: candidate 1 (0.96); random pick: the mean.
    assert_eq!(row("smirl", 910001)[5..9], ["done", "0.10", "0.96", "0.42"]);
    assert_eq!(row("paper", 910011)[5..9], ["done", "0.10", "-", "-"]);
    assert_eq!(row("paper", 910010)[5..7], ["failed", "0.00"]);
    let summary = std::fs::read_to_string(second.join(&state).join("summary.md")).unwrap();
    assert!(summary.contains("8 of 8 jobs"), "{summary}");
}

/// After the lock, a changed protocol or config is refused by `run`, committed or not.
#[test]
fn run_refuses_a_protocol_or_config_changed_after_the_lock() {
    if !python_has_tomllib() {
        eprintln!("SKIPPED: python3 >= 3.11 (tomllib) is not available");
        return;
    }
    let tmp = tempfile::tempdir().unwrap();
    let repo = tmp.path().join("repo");
    let frozen = protocol_repo(&repo, 920_000);
    let (bin, log) = (tmp.path().join("reacher"), tmp.path().join("jobs.log"));
    fake_reacher(&bin, &frozen, &log);
    let s = Session {
        repo: &repo,
        bin: &bin,
    };
    let o = s.script(
        "run.py",
        &["check", NAME, "--bin", bin.to_str().unwrap()],
        &[],
    );
    assert!(o.status.success(), "check: {}", stderr(&o));
    commit_all(&repo, "lock");
    let toml = repo.join(format!("experiments/protocol/{NAME}.toml"));
    let config = repo.join("experiments/reacher/config.toml");
    let original = std::fs::read_to_string(&toml).unwrap();
    for (path, text, committed) in [
        (&toml, original.replace("seeds = 2", "seeds = 1"), true),
        (&toml, original.clone() + "# a note\n", false),
        (&config, "# another config\n".to_string(), true),
    ] {
        let before = std::fs::read_to_string(path).unwrap();
        std::fs::write(path, &text).unwrap();
        if committed {
            commit_all(&repo, "a change after the lock");
        }
        let o = s.run(&[]);
        assert_eq!(
            o.status.code(),
            Some(2),
            "{}: {}",
            path.display(),
            stderr(&o)
        );
        assert!(stderr(&o).contains("changed after"), "{}", stderr(&o));
        std::fs::write(path, before).unwrap();
        if committed {
            commit_all(&repo, "undone");
        }
    }
    assert_eq!(log_lines(&log), Vec::<String>::new(), "no job ran");
    // Undone, it runs.
    let o = s.run(&[]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(log_lines(&log).len(), 8);
}
