//! experiments/protocol/run.py and table.py on a throwaway repository with a fake `reacher` (a
//! small Python script that writes job files): a preregistered evaluation resumes on a fresh
//! checkout from its committed lock and ledger alone — the jobs the ledger records are not run
//! again, a job killed by SIGTERM is (at most twice), a failed one never is — and the tables
//! come from the ledger without any run directory; a failed job scores 0 for every policy; a
//! failed or changed prepare fails its run directory's jobs and the plan goes on; a job past its
//! timeout is killed and failed; `--partial` counts complete bases only; `check` runs once, and
//! `run` and table.py refuse once the protocol, its config or the scripts change after the lock,
//! and `run` once a file a task file names changes; `status` and table.py find a protocol's
//! run directories after its config changes on a later commit;
//! diagnose.py gives each missed job its first cause and reproduces lost run directories;
//! machine_or_reward.py asks its missed jobs again with more fresh agents and the task's machine;
//! new_tasks_table.py puts a pool's tasks branch by branch beside their experts.
//! Seeds here are the fake's, far from every real range; nothing is written inside the
//! repository's experiments/.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

const NAME: &str = "tmp_resume_test";

/// A fresh checkout of `from` at `to` (a session on another machine).
fn clone(from: &Path, to: &Path) {
    let o = run_in(
        from.parent().unwrap(),
        "git",
        &["clone", "-q", from.to_str().unwrap(), to.to_str().unwrap()],
        &[],
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}

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

/// The fake binary: `--version` names `commit`; `prepare` appends `prepare:<task>:<base>` to
/// `log`, exits 1 when `<task>:<base>` is listed in FAKE_PREPARE_FAIL, else writes config.toml
/// (threads = 2, 4 IRL iterations of 50 SAC steps, or of FAKE_SAC_STEPS when set; `[env]
/// max_steps = 100`; `machine = "task"` when the given config says so, else "learned"),
/// rm/learned.txt (its text FAKE_MACHINE), rm/report.txt and prepare.json's `rm` (refining
/// the perfect machine unless the base is listed in FAKE_NOT_REFINES and the machine is
/// learned: 3 of 9 steps ambiguous), expert_data.bin, logs/demos.mcap (a text the fake
/// `replay` prints: one episode line per demonstration, seeded by the base) and prepare.json;
/// `job` appends its (algo, seed) to `log`, kills itself with SIGTERM when listed in FAKE_TERM,
/// with SIGSEGV when listed in FAKE_SEGV, sleeps a minute when listed in FAKE_HANG, exits 1
/// when listed in FAKE_FAIL, else writes a job file (as `reacher job`, returning at once when
/// it exists). Its per-iteration success (the last row's) is 0.01, its final-set scores
/// seed-dependent: a table that reads the wrong one shows it. SMIRL's choice is the candidate
/// at 0.96 (the loop's own score with FAKE_CHOOSE_FIRST; 0.5 in its place with
/// FAKE_NO_ORACLE). In a run directory whose config says `machine = "task"` (prepared from
/// such a config), a job appends `task:<algo>:<seed>` and chooses a candidate at 0.96 when
/// listed in FAKE_TASK_SOLVES, else at 0.4. `retrain` appends
/// `retrain:<algo>:<seed>:<sac seed>`, appends a line to the file FAKE_EDIT names (if set),
/// and writes a retraining table of `--evaluations` rows (default 5) over `--steps` (default
/// the run config's iterations × steps per iteration), its last row past them to the end of
/// the episode in progress as the real one's (episodes of `[env] max_steps` steps never end
/// early here: the next multiple of max_steps), 0.95 on both branches and at the last row 1.0
/// when `<algo>:<seed>` or `<algo>:<seed>:<sac seed>` is listed in FAKE_RETRAIN_SOLVES, else
/// 0.3 on the normal one.
fn fake_reacher(path: &Path, commit: &str, log: &Path) {
    let script = format!(
        r#"#!/usr/bin/env python3
import json, os, signal, sys, time
a = sys.argv[1:]
if a == ["--version"]:
    print("smirl 0.1.0 (commit {commit})")
    sys.exit(0)
opt = {{a[i]: a[i + 1] for i in range(1, len(a) - 1) if a[i].startswith("--")}}
listed = lambda var, what: what in os.environ.get(var, "").split(",")
if a[0] == "prepare":
    base = int(opt["--seed"])
    with open("{log}", "a") as fh:
        fh.write(f"prepare:{{opt['--task']}}:{{base}}\n")
    if listed("FAKE_PREPARE_FAIL", f"{{opt['--task']}}:{{base}}"):
        sys.exit(1)
    os.makedirs(os.path.join(opt["--out"], "rm"), exist_ok=True)
    with open(opt["--config"]) as fh:
        machine = "task" if 'machine = "task"' in fh.read() else "learned"
    with open(os.path.join(opt["--out"], "config.toml"), "w") as fh:
        fh.write(f"demo_episodes = 16\nthreads = 2\nirl_iterations = 4\n"
                 f"sac_steps_per_iteration = {{os.environ.get('FAKE_SAC_STEPS', '50')}}\n\n"
                 f"[env]\nmax_steps = 100\n\n[smirl]\nmachine = \"{{machine}}\"\n")
    with open(os.path.join(opt["--out"], "rm", "learned.txt"), "w") as fh:
        fh.write(os.environ.get("FAKE_MACHINE", "u0 -> u1 on r\n"))
    refines = "false (3 of 9 steps ambiguous)" if listed("FAKE_NOT_REFINES", str(base)) and machine == "learned" else "true"
    with open(os.path.join(opt["--out"], "rm", "report.txt"), "w") as fh:
        fh.write("learned machine: 2 states (2 reachable); perfect machine: 3 states\n"
                 f"refines the perfect machine along the 16 demonstrations: {{refines}}\n")
    with open(os.path.join(opt["--out"], "expert_data.bin"), "wb") as fh:
        fh.write(b"demonstrations")
    os.makedirs(os.path.join(opt["--out"], "logs"), exist_ok=True)
    with open(os.path.join(opt["--out"], "logs", "demos.mcap"), "w") as fh:
        fh.write(f"episode 0 seed {{base}}\nepisode 1 seed {{base + 1}}\n")
    with open(os.path.join(opt["--out"], "prepare.json"), "w") as fh:
        json.dump({{"seeds": list(range(base, base + int(opt["--seeds"]))), "git_commit": "{commit}",
                   "demos_kept": 15, "demos_generated": 16,
                   "rm": {{"refines_perfect": refines == "true", "ambiguous_steps": 0 if refines == "true" else 3,
                          "total_steps": 9}}}}, fh)
    sys.exit(0)
if a[0] == "replay":
    with open(a[1]) as fh:
        print("reward machine: stored in the run record")
        print(fh.read(), end="")
    sys.exit(0)
algo, seed = opt["--algo"], int(opt["--seed"])
if a[0] == "retrain":
    with open("{log}", "a") as fh:
        fh.write(f"retrain:{{algo}}:{{seed}}:{{opt['--sac-seed']}}\n")
    solves = listed("FAKE_RETRAIN_SOLVES", f"{{algo}}:{{seed}}") or listed("FAKE_RETRAIN_SOLVES", f"{{algo}}:{{seed}}:{{opt['--sac-seed']}}")
    if os.environ.get("FAKE_EDIT"):
        with open(os.environ["FAKE_EDIT"], "a") as fh:
            fh.write("\n# edited while a run reads it\n")
    rate = 1.0 if solves else 0.3
    import tomllib
    with open(os.path.join(opt["--run"], "config.toml"), "rb") as fh:
        config = tomllib.load(fh)
    steps = int(opt.get("--steps", config["irl_iterations"] * config["sac_steps_per_iteration"]))
    n = int(opt.get("--evaluations", 5))
    # `reacher retrain` plays the episode in progress to its end before the last evaluation.
    last = -(-steps // config["env"]["max_steps"]) * config["env"]["max_steps"]
    rows = [f"{{steps * k // n}},0.95,0.95,0.95" for k in range(1, n)] + [f"{{last}},{{rate}},{{rate}},1.0"]
    out = os.path.join(opt["--run"], "retrain")
    os.makedirs(out, exist_ok=True)
    with open(os.path.join(out, f"{{algo}}_seed{{seed}}_sac{{opt['--sac-seed']}}.csv"), "w") as fh:
        fh.write("env_steps,success_rate,success_normal,success_cancel\n" + "\n".join(rows) + "\n")
    sys.exit(0)
with open(os.path.join(opt["--run"], "config.toml")) as fh:
    task_machine = 'machine = "task"' in fh.read()
with open("{log}", "a") as fh:
    fh.write(("task:" if task_machine else "") + f"{{algo}}:{{seed}}\n")
me = f"{{algo}}:{{seed}}"
if listed("FAKE_TERM", me):
    os.kill(os.getpid(), signal.SIGTERM)
if listed("FAKE_SEGV", me):
    os.kill(os.getpid(), signal.SIGSEGV)
if listed("FAKE_HANG", me):
    time.sleep(60)
if listed("FAKE_FAIL", me):
    sys.exit(1)
path = os.path.join(opt["--run"], "jobs", f"{{algo}}_seed{{seed}}.json")
if os.path.isfile(path):
    sys.exit(0)
def score(rate):
    return {{"episodes": 100, "success_rate": rate, "progress": 0.5, "final_ball": 0.1,
            "branches": {{"episodes": [50, 50], "successes": [int(50 * rate), 50]}}}}
record = {{"algo": algo, "seed": seed, "wall_secs": float(os.environ.get("FAKE_WALL", "12.0")),
          "rows": [{{"iteration": 0, "success_rate": 0.0}}, {{"iteration": 1, "success_rate": 0.01}}],
          "loop_final_set": score((seed % 10) / 10)}}
if task_machine:
    record["loop_final_set"] = score(0.3)
    record["final_policy"] = {{"chosen": 1, "random": 0, "candidates": [
        {{"success_rate": 0.01, "final_set": score(0.3)}},
        {{"success_rate": 0.01, "final_set": score(0.96 if listed("FAKE_TASK_SOLVES", me) else 0.4)}}]}}
elif algo == "smirl":
    record["final_policy"] = {{"chosen": 0 if listed("FAKE_CHOOSE_FIRST", me) else 1, "random": 0, "candidates": [
        {{"success_rate": 0.01, "final_set": score((seed % 10) / 10)}},
        {{"success_rate": 0.01, "final_set": score(0.5 if listed("FAKE_NO_ORACLE", me) else 0.96)}},
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

/// The protocol of most tests: bases `base` and `base + 10`, one arm on `or` with smirl and
/// paper, 2 seeds.
fn standard_plan(base: u64) -> String {
    format!(
        "bases = [{base}, {}]\ntimeout_secs = {{ smirl = 600, paper = 600 }}\n\n[[arm]]\n\
         name = \"a\"\ntasks = [\"or\"]\nalgos = [\"smirl\", \"paper\"]\nn_bases = 2\nseeds = 2\n",
        base + 10
    )
}

/// A repository with the scripts, a "method" (the frozen commit) and a protocol on top
/// (`plan`: its toml after `commit` and `config`). (Each test has bases of its own: `check`
/// refuses seeds found in any run directory under /tmp, such as another test's.)
fn protocol_repo(repo: &Path, plan: &str) -> String {
    protocol_repo_with(repo, plan, &[])
}

/// [`protocol_repo`] with `files` (path, text) committed with the method.
fn protocol_repo_with(repo: &Path, plan: &str, files: &[(&str, &str)]) -> String {
    let manifest = Path::new(env!("CARGO_MANIFEST_DIR"));
    std::fs::create_dir_all(repo).unwrap();
    git(repo, &["init", "-q", "-b", "main"]);
    git(repo, &["config", "user.email", "test@example.invalid"]);
    git(repo, &["config", "user.name", "test"]);
    for f in [
        "run.py",
        "table.py",
        "diagnose.py",
        "new_tasks_table.py",
        "machine_or_reward.py",
    ] {
        let text = std::fs::read_to_string(manifest.join("experiments/protocol").join(f)).unwrap();
        write(&repo.join("experiments/protocol").join(f), &text);
    }
    write(&repo.join(".gitignore"), "runs/\n__pycache__/\n");
    write(&repo.join("src/method.rs"), "// the method\n");
    write(
        &repo.join("experiments/reacher/config.toml"),
        "# a config\nthreads = 2\n",
    );
    for (path, text) in files {
        write(&repo.join(path), text);
    }
    commit_all(repo, "the method");
    let frozen = git(repo, &["rev-parse", "HEAD"]);
    write(
        &repo.join(format!("experiments/protocol/{NAME}.md")),
        "# A protocol of a test\n",
    );
    write(
        &repo.join(format!("experiments/protocol/{NAME}.toml")),
        &format!("commit = \"{frozen}\"\nconfig = \"experiments/reacher/config.toml\"\n{plan}"),
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
        self.run_with(&[], env)
    }

    fn run_with(&self, args: &[&str], env: &[(&str, &str)]) -> Output {
        let bin = self.bin.to_str().unwrap();
        let mut all = vec!["run", NAME, "--bin", bin];
        all.extend_from_slice(args);
        self.script("run.py", &all, env)
    }

    /// `check`, then the lock committed.
    fn check_and_lock(&self) {
        let bin = self.bin.to_str().unwrap();
        let o = self.script("run.py", &["check", NAME, "--bin", bin], &[]);
        assert!(o.status.success(), "check: {}", stderr(&o));
        commit_all(self.repo, "lock");
    }

    fn table(&self, args: &[&str]) -> Output {
        let mut all = vec![NAME];
        all.extend_from_slice(args);
        self.script("table.py", &all, &[])
    }

    fn state(&self, file: &str) -> String {
        let path = self
            .repo
            .join(format!("experiments/protocol/{NAME}"))
            .join(file);
        std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
    }
}

/// The row of jobs.csv for (algo, seed), split at commas.
fn csv_row(jobs: &str, algo: &str, seed: u64) -> Vec<String> {
    let line = jobs
        .lines()
        .find(|l| l.contains(&format!(",{algo},{seed},")))
        .unwrap_or_else(|| panic!("no row {algo} {seed} in\n{jobs}"));
    line.split(',').map(String::from).collect()
}

/// The line of summary.md's exploratory table for (task, arm, algo).
fn exploratory_row<'a>(summary: &'a str, task: &str, arm: &str, algo: &str) -> &'a str {
    let tail = summary
        .split("## Exploratory")
        .nth(1)
        .unwrap_or_else(|| panic!("no exploratory section in\n{summary}"));
    tail.lines()
        .find(|l| l.starts_with(&format!("| {task} | {arm} | {algo} |")))
        .unwrap_or_else(|| panic!("no row {task} {arm} {algo} in\n{summary}"))
}

/// The jobs the fake ran, in order (`algo:seed`).
fn log_lines(log: &Path) -> Vec<String> {
    std::fs::read_to_string(log)
        .unwrap_or_default()
        .lines()
        .filter(|l| !l.starts_with("prepare:"))
        .map(String::from)
        .collect()
}

/// The prepares the fake ran, in order (`prepare:task:base`).
fn prepare_lines(log: &Path) -> Vec<String> {
    std::fs::read_to_string(log)
        .unwrap_or_default()
        .lines()
        .filter(|l| l.starts_with("prepare:"))
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
    let frozen = protocol_repo(&first, &standard_plan(910_000));
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

    // Session 1: the second job is killed by SIGTERM (a session ending), the session stops there.
    let o = s1.run(&[("FAKE_TERM", "smirl:910001")]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert_eq!(log_lines(&log), ["smirl:910000", "smirl:910001"]);
    commit_all(&first, "session 1's ledger");

    // Session 2 on a fresh clone (no runs/): the done job is not run again, the killed one is;
    // one job fails.
    let second = tmp.path().join("second");
    clone(&first, &second);
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
    let frozen = protocol_repo(&repo, &standard_plan(920_000));
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

/// A protocol's run directories are named by the config its lock holds: once the config changes
/// on a later commit, `status` and table.py still find every job the ledger records.
#[test]
fn tables_find_a_protocols_jobs_after_its_config_changes() {
    if !python_has_tomllib() {
        eprintln!("SKIPPED: python3 >= 3.11 (tomllib) is not available");
        return;
    }
    let tmp = tempfile::tempdir().unwrap();
    let (repo, bin, log) = locked(tmp.path(), &standard_plan(921_000));
    let s = Session {
        repo: &repo,
        bin: &bin,
    };
    let o = s.run(&[]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(log_lines(&log).len(), 8);
    write(
        &repo.join("experiments/reacher/config.toml"),
        "# the next standard\nthreads = 1\n",
    );
    commit_all(&repo, "a later config");
    let o = s.script("run.py", &["status", NAME], &[]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        String::from_utf8_lossy(&o.stdout).contains("8 of 8 jobs done"),
        "{}",
        String::from_utf8_lossy(&o.stdout)
    );
    let o = s.table(&[]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(s.state("summary.md").contains("8 of 8 jobs"));
    // `run` still refuses the changed config.
    let o = s.run(&[]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("changed after"), "{}", stderr(&o));
}

/// What a task file makes a job read from the checkout (its machine and scene, here in sibling
/// directories, the files beside them and its experts) is locked with it. `check` refuses an
/// untracked file among them, ignored or not, a scene naming a file outside its directory, a
/// task without a committed expert and a read that differs from the frozen commit; `run`
/// refuses a change to any, committed or not, a deleted or new file, and a lock without them.
#[test]
fn the_files_a_task_file_names_are_locked_with_it() {
    if !python_has_tomllib() {
        eprintln!("SKIPPED: python3 >= 3.11 (tomllib) is not available");
        return;
    }
    let tmp = tempfile::tempdir().unwrap();
    let repo = tmp.path().join("repo");
    let plan = "bases = [922000]\ntimeout_secs = { smirl = 600 }\n\n[[arm]]\nname = \"a\"\n\
                tasks = [\"tasks/t.toml\"]\nalgos = [\"smirl\"]\nn_bases = 1\nseeds = 1\n";
    let expert = "tasks/experts/expert_t-0123456789abcdef.policy";
    let scene = "<mujoco><asset><mesh file=\"mesh.stl\"/></asset></mujoco>\n";
    let reads = ["machines/t.txt", "scenes/mesh.stl", "scenes/s.xml", expert];
    let files = [
        (
            "tasks/t.toml",
            "scene = \"../scenes/s.xml\"\nmachine = \"../machines/t.txt\"\n",
        ),
        ("machines/t.txt", "the original\n"),
        ("scenes/mesh.stl", "the original\n"),
        ("scenes/s.xml", scene),
        (expert, "the original\n"),
    ];
    let frozen = protocol_repo_with(&repo, plan, &files);
    let (bin, log) = (tmp.path().join("reacher"), tmp.path().join("jobs.log"));
    fake_reacher(&bin, &frozen, &log);
    let s = Session {
        repo: &repo,
        bin: &bin,
    };
    let refused_check = |what: &str| {
        let o = s.script(
            "run.py",
            &["check", NAME, "--bin", bin.to_str().unwrap()],
            &[],
        );
        assert_eq!(o.status.code(), Some(2), "{what}: {}", stderr(&o));
        assert!(stderr(&o).contains(what), "{what}: {}", stderr(&o));
        assert!(!repo
            .join(format!("experiments/protocol/{NAME}/lock.json"))
            .exists());
    };
    // An expert trained on this machine and not committed, even one git ignores.
    let stray = repo.join("tasks/experts/expert_t-fedcba9876543210.policy");
    write(&stray, "trained here\n");
    refused_check("expert_t-fedcba9876543210.policy");
    write(&repo.join(".git/info/exclude"), "*.policy\n");
    refused_check("expert_t-fedcba9876543210.policy");
    std::fs::remove_file(&stray).unwrap();
    write(&repo.join(".git/info/exclude"), "");
    // A scene that reads a file outside its directory.
    write(
        &repo.join("scenes/s.xml"),
        "<mujoco><include file=\"../x.xml\"/></mujoco>\n",
    );
    refused_check("scenes/s.xml names file=\"../x.xml\"");
    // Files above the limits reacher puts on them, refused before they are read whole.
    let padding = |bytes: usize| format!("<!--{}-->", "x".repeat(bytes));
    write(
        &repo.join("scenes/s.xml"),
        &format!("{scene}{}", padding(16 << 20)),
    );
    refused_check("scenes/s.xml: 16777279 bytes, above the limit of 16777216 bytes");
    write(&repo.join("scenes/s.xml"), scene);
    let task = std::fs::read_to_string(repo.join("tasks/t.toml")).unwrap();
    write(
        &repo.join("tasks/t.toml"),
        &format!("{task}# {}\n", "x".repeat(1 << 20)),
    );
    refused_check("tasks/t.toml: 1048635 bytes, above the limit of 1048576 bytes");
    write(&repo.join("tasks/t.toml"), &task);
    // No committed expert: a job would train one.
    let aside = tmp.path().join("expert.policy");
    std::fs::rename(repo.join(expert), &aside).unwrap();
    commit_all(&repo, "no expert");
    refused_check("no committed expert");
    std::fs::rename(&aside, repo.join(expert)).unwrap();
    commit_all(&repo, "the expert again");
    // A read that differs from the frozen commit.
    write(&repo.join("machines/t.txt"), "changed before the lock\n");
    commit_all(&repo, "a change before the lock");
    refused_check("machines/t.txt");
    write(&repo.join("machines/t.txt"), "the original\n");
    commit_all(&repo, "undone");
    s.check_and_lock();
    let lock: serde_json::Value = serde_json::from_str(&s.state("lock.json")).unwrap();
    let mut locked: Vec<&str> = lock["task_reads"]
        .as_object()
        .unwrap()
        .keys()
        .map(String::as_str)
        .collect();
    locked.sort_unstable();
    assert_eq!(locked, reads);
    let refused_run = |what: &str| {
        let o = s.run(&[]);
        assert_eq!(o.status.code(), Some(2), "{what}: {}", stderr(&o));
        assert!(
            stderr(&o).contains(what) && stderr(&o).contains("changed after"),
            "{what}: {}",
            stderr(&o)
        );
    };
    for (file, committed) in reads
        .iter()
        .map(|f| (*f, true))
        .chain([("scenes/mesh.stl", false)])
    {
        let path = repo.join(file);
        let before = std::fs::read_to_string(&path).unwrap();
        write(&path, "changed after the lock\n");
        if committed {
            commit_all(&repo, "a change after the lock");
        }
        refused_run(file);
        write(&path, &before);
        if committed {
            commit_all(&repo, "undone");
        }
    }
    // A deleted file, not committed.
    std::fs::remove_file(repo.join("machines/t.txt")).unwrap();
    refused_run("machines/t.txt");
    git(&repo, &["checkout", "--", "machines/t.txt"]);
    // A new file beside the task file, committed or not.
    for committed in [false, true] {
        write(&stray, "trained here\n");
        if committed {
            git(&repo, &["add", stray.to_str().unwrap()]);
            commit_all(&repo, "a new expert");
        }
        refused_run("expert_t-fedcba9876543210.policy");
    }
    git(&repo, &["rm", "-q", stray.to_str().unwrap()]);
    commit_all(&repo, "undone");
    assert_eq!(log_lines(&log), Vec::<String>::new(), "no job ran");
    let o = s.run(&[]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(log_lines(&log), ["smirl:922000"]);
    assert_eq!(prepare_lines(&log), ["prepare:tasks/t.toml:922000"]);
    // A lock written before task files' reads were locked is refused.
    let lock_file = repo.join(format!("experiments/protocol/{NAME}/lock.json"));
    let mut old = lock.clone();
    old.as_object_mut().unwrap().remove("task_reads");
    std::fs::write(&lock_file, serde_json::to_string(&old).unwrap()).unwrap();
    commit_all(&repo, "an old lock");
    let o = s.run(&[]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("no `task_reads`"), "{}", stderr(&o));
}

/// Sets up a repository with `plan`, the fake binary and the lock committed.
fn locked(tmp: &Path, plan: &str) -> (PathBuf, PathBuf, PathBuf) {
    let repo = tmp.join("repo");
    let frozen = protocol_repo(&repo, plan);
    let (bin, log) = (tmp.join("reacher"), tmp.join("jobs.log"));
    fake_reacher(&bin, &frozen, &log);
    Session {
        repo: &repo,
        bin: &bin,
    }
    .check_and_lock();
    (repo, bin, log)
}

/// A failed job scores 0 for every policy of its algorithm in jobs.csv and in every mean and
/// share of the summary; jobs side by side (`--parallel 2`) run on one thread each.
#[test]
fn a_failed_job_scores_zero_for_every_policy_in_every_mean() {
    if !python_has_tomllib() {
        eprintln!("SKIPPED: python3 >= 3.11 (tomllib) is not available");
        return;
    }
    let tmp = tempfile::tempdir().unwrap();
    let (repo, bin, log) = locked(tmp.path(), &standard_plan(940_000));
    let s = Session {
        repo: &repo,
        bin: &bin,
    };
    let o = s.run_with(&["--parallel", "2"], &[("FAKE_FAIL", "smirl:940011")]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(log_lines(&log).len(), 8);
    let config = std::fs::read_to_string(
        repo.join("runs/protocol")
            .join(NAME)
            .join(
                std::fs::read_dir(repo.join("runs/protocol").join(NAME))
                    .unwrap()
                    .next()
                    .unwrap()
                    .unwrap()
                    .file_name(),
            )
            .join("config.toml"),
    )
    .unwrap();
    assert!(config.contains("threads = 1\n"), "{config}");
    assert!(s.state("ledger.jsonl").contains("\"threads\":1,"));
    let o = s.table(&[]);
    assert!(o.status.success(), "table: {}", stderr(&o));
    let jobs = s.state("jobs.csv");
    // status, loop, chosen, random_pick, oracle
    assert_eq!(
        csv_row(&jobs, "smirl", 940011)[5..10],
        ["failed", "0.00", "0.00", "0.00", "0.00"]
    );
    // Chosen: 0.96 three times and the failed job's 0; the loop's own: 0.0, 0.1, 0.0 and 0;
    // the random pick: (0.0 + 0.96 + 0.2) / 3, (0.1 + 0.96 + 0.2) / 3, the first again, 0;
    // the oracle: 0.96 three times and 0. Left out, the failed job would make them 0.96, 0.03,
    // 0.40 and 0.96.
    let summary = s.state("summary.md");
    let row = exploratory_row(&summary, "or", "a", "smirl");
    let cols: Vec<&str> = row.split('|').map(str::trim).collect();
    // | task | arm | algo | jobs (bases) | failed | solved, chosen | chosen mean | solved, loop |
    // loop mean | random pick mean | oracle mean | chosen − loop | ...
    assert_eq!(cols[4], "4 (2)", "{row}");
    assert!(cols[6].starts_with("3/4 "), "{row}");
    assert_eq!(
        [cols[7], cols[9], cols[10], cols[11]],
        ["0.72", "0.03", "0.30", "0.72"],
        "{row}"
    );
}

/// A prepare that fails is recorded once, its run directory's jobs count as failed and the
/// plan goes on; a later session that prepares a directory again with other bytes is refused
/// the same way; the learned machines are kept in machines.txt.
#[test]
fn a_failed_or_changed_prepare_fails_its_jobs_and_the_plan_goes_on() {
    if !python_has_tomllib() {
        eprintln!("SKIPPED: python3 >= 3.11 (tomllib) is not available");
        return;
    }
    let tmp = tempfile::tempdir().unwrap();
    let plan =
        "bases = [950000, 950010]\ntimeout_secs = { smirl = 600 }\n\n[[arm]]\nname = \"a\"\n\
                tasks = [\"or\", \"if\"]\nalgos = [\"smirl\"]\nn_bases = 2\nseeds = 2\n";
    let (repo, bin, log) = locked(tmp.path(), plan);
    let s = Session {
        repo: &repo,
        bin: &bin,
    };
    let o = s.run_with(&["--max-jobs", "3"], &[("FAKE_PREPARE_FAIL", "or:950000")]);
    assert!(o.status.success(), "{}", stderr(&o));
    // or-b950000 failed to prepare: its two jobs are failed, the plan went on to if-b950000
    // and or-b950010.
    assert_eq!(
        log_lines(&log),
        ["smirl:950000", "smirl:950001", "smirl:950010"]
    );
    assert_eq!(
        prepare_lines(&log),
        [
            "prepare:or:950000",
            "prepare:if:950000",
            "prepare:or:950010"
        ]
    );
    let ledger = s.state("ledger.jsonl");
    assert_eq!(ledger.matches("\"prepare_failed\"").count(), 1, "{ledger}");
    assert_eq!(ledger.matches("\"why\":\"prepare\"").count(), 2, "{ledger}");
    assert!(s.state("machines.txt").contains("u0 -> u1 on r"));
    commit_all(&repo, "session 1");

    // A fresh checkout whose prepare gives another machine: or-b950010 (one job done) is
    // refused and its other job failed; if-b950010 is new and runs; the failed prepare of
    // or-b950000 is not tried again.
    let second = tmp.path().join("second");
    clone(&repo, &second);
    std::fs::remove_file(&log).unwrap();
    let s2 = Session {
        repo: &second,
        bin: &bin,
    };
    let o = s2.run(&[("FAKE_MACHINE", "u0 -> u2 on r\n")]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(log_lines(&log), ["smirl:950010", "smirl:950011"]);
    assert_eq!(
        prepare_lines(&log),
        ["prepare:or:950010", "prepare:if:950010"]
    );
    let ledger = s2.state("ledger.jsonl");
    assert_eq!(ledger.matches("\"prepare_failed\"").count(), 2, "{ledger}");
    assert!(
        ledger.contains("prepared again with other bytes"),
        "{ledger}"
    );
    let status = s2.script("run.py", &["status", NAME], &[]);
    assert!(
        String::from_utf8_lossy(&status.stdout).contains("5 of 8 jobs done, 3 failed"),
        "{}",
        String::from_utf8_lossy(&status.stdout)
    );
}

/// A job killed by SIGTERM is rerun at most twice (its third kill fails it); a job killed by
/// another signal fails at once.
#[test]
fn a_job_killed_by_sigterm_reruns_at_most_twice_and_other_signals_fail_it() {
    if !python_has_tomllib() {
        eprintln!("SKIPPED: python3 >= 3.11 (tomllib) is not available");
        return;
    }
    let tmp = tempfile::tempdir().unwrap();
    let (repo, bin, log) = locked(tmp.path(), &standard_plan(960_000));
    let s = Session {
        repo: &repo,
        bin: &bin,
    };
    let env = [("FAKE_TERM", "smirl:960001"), ("FAKE_SEGV", "paper:960000")];
    for session in 1..=3 {
        let o = s.run(&env);
        assert_eq!(
            o.status.code(),
            Some(2),
            "session {session}: {}",
            stderr(&o)
        );
    }
    let ran: Vec<String> = log_lines(&log);
    assert_eq!(
        ran.iter().filter(|l| *l == "smirl:960001").count(),
        3,
        "{ran:?}"
    );
    let ledger = s.state("ledger.jsonl");
    assert_eq!(
        ledger.matches("\"event\":\"killed\"").count(),
        2,
        "{ledger}"
    );
    assert!(
        ledger.contains("killed by signal 15 on its start 3 of 3"),
        "{ledger}"
    );
    // Session 4 runs the rest, the third kill's job not again; the job that dies by SIGSEGV
    // fails at once.
    std::fs::remove_file(&log).unwrap();
    let o = s.run(&env);
    assert!(o.status.success(), "session 4: {}", stderr(&o));
    let ran = log_lines(&log);
    assert!(!ran.contains(&"smirl:960001".to_string()), "{ran:?}");
    assert!(ran.contains(&"paper:960000".to_string()), "{ran:?}");
    let ledger = s.state("ledger.jsonl");
    assert!(
        ledger.contains("\"why\":\"killed by signal 11\""),
        "{ledger}"
    );
    // Session 5: nothing left.
    std::fs::remove_file(&log).unwrap();
    let o = s.run(&env);
    assert!(o.status.success(), "session 5: {}", stderr(&o));
    assert_eq!(log_lines(&log), Vec::<String>::new());
    let status = s.script("run.py", &["status", NAME], &[]);
    assert!(String::from_utf8_lossy(&status.stdout).contains("6 of 8 jobs done, 2 failed"));
}

/// A job running longer than its algorithm's `timeout_secs` is killed and recorded failed.
#[test]
fn a_job_past_its_timeout_is_killed_and_failed() {
    if !python_has_tomllib() {
        eprintln!("SKIPPED: python3 >= 3.11 (tomllib) is not available");
        return;
    }
    let tmp = tempfile::tempdir().unwrap();
    let plan = standard_plan(970_000).replace("smirl = 600", "smirl = 2");
    let (repo, bin, log) = locked(tmp.path(), &plan);
    let s = Session {
        repo: &repo,
        bin: &bin,
    };
    let started = std::time::Instant::now();
    let o = s.run(&[("FAKE_HANG", "smirl:970000")]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        started.elapsed().as_secs() < 30,
        "the hung job was not killed"
    );
    assert_eq!(log_lines(&log).len(), 8);
    let ledger = s.state("ledger.jsonl");
    assert!(
        ledger.contains("\"why\":\"timeout\",\"timeout_secs\":2"),
        "{ledger}"
    );
    let o = s.table(&[]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(csv_row(&s.state("jobs.csv"), "smirl", 970000)[5], "failed");
}

/// `table.py --partial` counts complete bases only (every job of the arm's tier and earlier
/// tiers on the base finished) and says how many bases each arm reached; without `--partial`
/// it refuses an unfinished plan.
#[test]
fn partial_tables_count_complete_bases_only() {
    if !python_has_tomllib() {
        eprintln!("SKIPPED: python3 >= 3.11 (tomllib) is not available");
        return;
    }
    let tmp = tempfile::tempdir().unwrap();
    let plan = "bases = [980000, 980010, 980020]\ntimeout_secs = { smirl = 600, paper = 600 }\n\n\
                [[arm]]\nname = \"a\"\ntasks = [\"or\"]\nalgos = [\"smirl\"]\nn_bases = 3\nseeds = 2\n\n\
                [[arm]]\nname = \"p\"\ntasks = [\"or\"]\nalgos = [\"paper\"]\nn_bases = 3\nseeds = 1\n\
                tier = 2\n";
    let (repo, bin, log) = locked(tmp.path(), plan);
    let s = Session {
        repo: &repo,
        bin: &bin,
    };
    // Tier 1 base by base, then tier 2: 5 jobs finish a's bases 980000 and 980010 and start
    // 980020; p reaches no base.
    let o = s.run_with(&["--max-jobs", "5"], &[]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(
        log_lines(&log),
        [
            "smirl:980000",
            "smirl:980001",
            "smirl:980010",
            "smirl:980011",
            "smirl:980020"
        ]
    );
    let o = s.table(&[]);
    assert!(!o.status.success());
    assert!(stderr(&o).contains("missing"), "{}", stderr(&o));
    let o = s.table(&["--partial"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let summary = s.state("summary.md");
    assert!(
        summary.contains("- a (tier 1): 3 reached, 2 counted, of 3 planned"),
        "{summary}"
    );
    assert!(
        summary.contains("- p (tier 2): 0 reached, 0 counted, of 3 planned"),
        "{summary}"
    );
    let jobs = s.state("jobs.csv");
    assert_eq!(jobs.lines().count(), 1 + 4, "{jobs}");
    assert!(!jobs.contains(",980020,"), "{jobs}");
    // One more job completes base 980020 for tier 1.
    let o = s.run_with(&["--max-jobs", "1"], &[]);
    assert!(o.status.success(), "{}", stderr(&o));
    let o = s.table(&["--partial"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(s
        .state("summary.md")
        .contains("- a (tier 1): 3 reached, 3 counted, of 3 planned"));
}

/// table.py refuses to run when table.py or run.py differ from the blobs the lock records,
/// committed or not, and so does `run`.
#[test]
fn table_and_run_refuse_scripts_changed_after_the_lock() {
    if !python_has_tomllib() {
        eprintln!("SKIPPED: python3 >= 3.11 (tomllib) is not available");
        return;
    }
    let tmp = tempfile::tempdir().unwrap();
    let (repo, bin, _log) = locked(tmp.path(), &standard_plan(990_000));
    let s = Session {
        repo: &repo,
        bin: &bin,
    };
    let o = s.run(&[]);
    assert!(o.status.success(), "{}", stderr(&o));
    let o = s.table(&[]);
    assert!(o.status.success(), "{}", stderr(&o));
    for script in ["table.py", "run.py"] {
        let path = repo.join("experiments/protocol").join(script);
        let before = std::fs::read_to_string(&path).unwrap();
        std::fs::write(&path, before.clone() + "# a change after the lock\n").unwrap();
        for committed in [false, true] {
            if committed {
                commit_all(&repo, "a change after the lock");
            }
            let o = s.table(&[]);
            assert!(
                !o.status.success(),
                "{script} changed, committed {committed}"
            );
            assert!(
                stderr(&o).contains(&format!("experiments/protocol/{script} differ")),
                "{}",
                stderr(&o)
            );
            let o = s.run(&[]);
            assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
            assert!(stderr(&o).contains("changed after"), "{}", stderr(&o));
        }
        std::fs::write(&path, before).unwrap();
        commit_all(&repo, "undone");
    }
    let o = s.table(&[]);
    assert!(o.status.success(), "{}", stderr(&o));
}

/// A development protocol (`development = true`) skips the never-used-seed check and says so;
/// any other protocol refuses a base below 10 000.
#[test]
fn only_a_development_protocol_runs_on_development_seeds() {
    if !python_has_tomllib() {
        eprintln!("SKIPPED: python3 >= 3.11 (tomllib) is not available");
        return;
    }
    let tmp = tempfile::tempdir().unwrap();
    let repo = tmp.path().join("repo");
    let frozen = protocol_repo(&repo, &standard_plan(0));
    let (bin, log) = (tmp.path().join("reacher"), tmp.path().join("jobs.log"));
    fake_reacher(&bin, &frozen, &log);
    let s = Session {
        repo: &repo,
        bin: &bin,
    };
    let check = || {
        s.script(
            "run.py",
            &["check", NAME, "--bin", bin.to_str().unwrap()],
            &[],
        )
    };
    let o = check();
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("development data"), "{}", stderr(&o));
    let toml = repo.join(format!("experiments/protocol/{NAME}.toml"));
    let text = std::fs::read_to_string(&toml).unwrap();
    std::fs::write(
        &toml,
        text.replace("\nbases =", "\ndevelopment = true\nbases ="),
    )
    .unwrap();
    commit_all(&repo, "a rehearsal");
    let o = check();
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        String::from_utf8_lossy(&o.stdout).contains("never used is skipped"),
        "{}",
        String::from_utf8_lossy(&o.stdout)
    );
}

/// The goal's reading needs 5 bases ("too few bases" below, whatever the scores), and a
/// secondary comparison with a unit `[analysis] control_failed` names is called in neither
/// direction while the same comparison with another unit is called.
#[test]
fn readings_need_five_bases_and_failed_controls_are_not_called() {
    if !python_has_tomllib() {
        eprintln!("SKIPPED: python3 >= 3.11 (tomllib) is not available");
        return;
    }
    let tmp = tempfile::tempdir().unwrap();
    let plan = "bases = [930000, 930010, 930020, 930030, 930040]\n\
                timeout_secs = { smirl = 600, paper = 600 }\n\n\
                [[arm]]\nname = \"a\"\ntasks = [\"or\"]\nalgos = [\"smirl\"]\nn_bases = 5\nseeds = 1\n\n\
                [[arm]]\nname = \"b\"\ntasks = [\"or\"]\nalgos = [\"paper\"]\nn_bases = 5\nseeds = 1\n\n\
                [[arm]]\nname = \"c\"\ntasks = [\"or\"]\nalgos = [\"paper\"]\nn_bases = 5\nseeds = 1\n\n\
                [analysis]\nprimary = \"a:smirl\"\n\
                secondary = [[\"a:smirl\", \"b:paper\"], [\"a:smirl\", \"c:paper\"]]\n\
                control_failed = [\"c:paper\"]\n";
    let (repo, bin, _log) = locked(tmp.path(), plan);
    let s = Session {
        repo: &repo,
        bin: &bin,
    };
    // Two bases (b and c plan the same paper job, so a base is two jobs): smirl's chosen
    // policy solves both (0.96), yet no reading.
    let o = s.run_with(&["--max-jobs", "4"], &[]);
    assert!(o.status.success(), "{}", stderr(&o));
    let o = s.table(&["--partial"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let summary = s.state("summary.md");
    let p1 = summary
        .lines()
        .find(|l| l.starts_with("| or | 2 (2) |"))
        .unwrap_or_else(|| panic!("no P1 row in\n{summary}"));
    assert!(p1.contains("| too few bases |"), "{p1}");
    // All five bases: met; a:smirl against b:paper is called, against c:paper not.
    let o = s.run(&[]);
    assert!(o.status.success(), "{}", stderr(&o));
    let o = s.table(&[]);
    assert!(o.status.success(), "{}", stderr(&o));
    let summary = s.state("summary.md");
    let p1 = summary
        .lines()
        .find(|l| l.starts_with("| or | 5 (5) |"))
        .unwrap_or_else(|| panic!("no P1 row in\n{summary}"));
    assert!(p1.contains("| met |"), "{p1}");
    let row = |b: &str| {
        summary
            .lines()
            .find(|l| l.starts_with(&format!("| or | a:smirl | {b} |")))
            .unwrap_or_else(|| panic!("no secondary row for {b} in\n{summary}"))
            .to_string()
    };
    assert!(
        row("b:paper").contains("5/5 vs 0/5: A called"),
        "{}",
        row("b:paper")
    );
    assert!(
        row("c:paper").contains("5/5 vs 0/5: control failed, not called"),
        "{}",
        row("c:paper")
    );
}

/// The row of diagnosis.md for SMIRL's job with `seed`, split at `|`.
fn diagnosis_row(diagnosis: &str, seed: u64) -> Vec<String> {
    let line = diagnosis
        .lines()
        .find(|l| l.starts_with("| a | or |") && l.contains(&format!(" | {seed} | ")))
        .unwrap_or_else(|| panic!("no row for seed {seed} in\n{diagnosis}"));
    line.split('|').map(|c| c.trim().to_string()).collect()
}

/// diagnose.py gives each missed job the first cause that applies — failed, the choice (a
/// candidate solved), the agent (a fresh agent on the learned reward solves, even over a
/// machine that does not refine the task's), a fresh agent failing too over a coarse or a
/// refining machine — retraining only where
/// the final set leaves the question open; it prepares a lost run directory and reruns its
/// job again, and a prepare that gives other bytes than the ledger's is "not reproduced"; it
/// refuses before table.py has run, reads an existing retraining table instead of retraining,
/// and never writes the ledger.
#[test]
fn diagnose_gives_each_missed_job_its_first_cause() {
    if !python_has_tomllib() {
        eprintln!("SKIPPED: python3 >= 3.11 (tomllib) is not available");
        return;
    }
    let tmp = tempfile::tempdir().unwrap();
    let (repo, bin, log) = locked(tmp.path(), &standard_plan(945_000));
    let s = Session {
        repo: &repo,
        bin: &bin,
    };
    let jobs = [
        (
            "FAKE_CHOOSE_FIRST",
            "smirl:945000,smirl:945001,smirl:945010",
        ),
        ("FAKE_NO_ORACLE", "smirl:945001,smirl:945010"),
        ("FAKE_FAIL", "smirl:945011"),
        ("FAKE_NOT_REFINES", "945000"),
        ("FAKE_RETRAIN_SOLVES", "smirl:945001"),
    ];
    let o = s.run(&jobs);
    assert!(o.status.success(), "{}", stderr(&o));
    let b = bin.to_str().unwrap();
    let diagnose = |env: &[(&str, &str)]| {
        s.script(
            "diagnose.py",
            &[NAME, "--bin", b, "--units", "a:smirl"],
            env,
        )
    };
    let o = diagnose(&jobs);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("jobs.csv does not exist"),
        "{}",
        stderr(&o)
    );
    let o = s.table(&[]);
    assert!(o.status.success(), "table: {}", stderr(&o));
    // A config other than the lock's would prepare another directory: refused by name.
    let config = repo.join("experiments/reacher/config.toml");
    let locked_config = std::fs::read_to_string(&config).unwrap();
    std::fs::write(&config, "# the next standard\nthreads = 1\n").unwrap();
    let o = diagnose(&jobs);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("experiments/reacher/config.toml differs from what the lock holds"),
        "{}",
        stderr(&o)
    );
    std::fs::write(&config, locked_config).unwrap();
    let ledger = s.state("ledger.jsonl");
    let lost = std::fs::read_dir(repo.join("runs/protocol").join(NAME))
        .unwrap()
        .map(|e| e.unwrap().path())
        .find(|p| {
            p.file_name()
                .unwrap()
                .to_str()
                .unwrap()
                .starts_with("or-b945010-")
        })
        .expect("the run directory of base 945010");
    std::fs::remove_dir_all(&lost).unwrap();
    let mut other_machine = jobs.to_vec();
    other_machine.push(("FAKE_MACHINE", "u0 -> u1 on g\n"));
    let o = diagnose(&other_machine);
    assert!(o.status.success(), "diagnose: {}", stderr(&o));
    let d = s.state("diagnosis.md");
    assert_eq!(diagnosis_row(&d, 945010)[8], "not reproduced", "{d}");
    assert!(
        diagnosis_row(&d, 945010)[12].contains("other bytes than the ledger"),
        "{d}"
    );
    std::fs::remove_dir_all(&lost).unwrap();
    std::fs::write(&log, "").unwrap();
    // The job run again takes another wall time than the ledger's run, as a real one does.
    let mut again = jobs.to_vec();
    again.push(("FAKE_WALL", "13.0"));
    let o = diagnose(&again);
    assert!(o.status.success(), "diagnose: {}", stderr(&o));
    let d = s.state("diagnosis.md");
    // | arm | task | base | seed | loop | chosen | oracle | cause | fresh agent | states |
    // refines | note |
    let causes: Vec<(String, String)> = [945000, 945001, 945010, 945011]
        .iter()
        .map(|&seed| {
            let row = diagnosis_row(&d, seed);
            (row[8].clone(), row[9].clone())
        })
        .collect();
    assert_eq!(
        causes,
        [
            ("choice".to_string(), String::new()),
            ("agent".to_string(), "1.00, 1.00".to_string()),
            (
                "fresh fails, refining machine".to_string(),
                "0.30, 0.95".to_string()
            ),
            ("failed".to_string(), String::new()),
        ],
        "{d}"
    );
    assert!(
        diagnosis_row(&d, 945001)[11].starts_with("no (3 of 9"),
        "{d}"
    );
    assert_eq!(diagnosis_row(&d, 945010)[11], "yes", "{d}");
    // Per task, one count per cause that occurs; the refinement test's rate over the run
    // directories on disk (base 945000's machine does not refine, 945010's does).
    assert!(d.contains("| or | 4 | 1 | 1 | 1 | 1 |"), "{d}");
    assert!(
        d.contains("1 of 2 learned machines refine the perfect one"),
        "{d}"
    );
    // The lost directory was prepared and its job run again; 945001's table from the first
    // diagnosis was read, not retrained; nothing was retrained for the choice or the failure.
    let ran = std::fs::read_to_string(&log).unwrap();
    assert_eq!(
        ran.lines().collect::<Vec<_>>(),
        [
            "prepare:or:945010",
            "smirl:945010",
            "retrain:smirl:945010:1000"
        ],
        "{d}"
    );
    assert_eq!(s.state("ledger.jsonl"), ledger);
    // The job run again keeps its file aside, so the tables still build on this machine.
    let o = s.table(&[]);
    assert!(o.status.success(), "table after diagnose: {}", stderr(&o));
}

/// The run directory of `base` under `root`.
fn run_dir(root: &Path, base: u64) -> PathBuf {
    std::fs::read_dir(root)
        .unwrap()
        .map(|e| e.unwrap().path())
        .find(|p| p.is_dir() && p.to_str().unwrap().contains(&format!("-b{base}-")))
        .unwrap_or_else(|| panic!("no run directory of base {base} in {}", root.display()))
}

/// The row of machine_or_reward.md for SMIRL's job with `seed`, split at `|`.
fn asked_row(text: &str, seed: u64) -> Vec<String> {
    text.lines()
        .filter(|l| l.starts_with("| a | or |"))
        .map(|l| {
            l.split('|')
                .map(|c| c.trim().to_string())
                .collect::<Vec<_>>()
        })
        .find(|row| row[4] == seed.to_string())
        .unwrap_or_else(|| panic!("no row for seed {seed} in\n{text}"))
}

/// machine_or_reward.py asks each missed job diagnose.py calls "agent" or "fresh fails" again:
/// fresh agents at three SAC seeds (seed 1000's table read when it exists) and SMIRL on the
/// task's machine, in a run directory of its own prepared from the job's config with
/// `machine = "task"`; the first reading that applies (a fresh agent solves: the training
/// draw; else the task's machine solves: the learned machine; else neither); a solved job per
/// task as a control; the refinement test over every run directory and over the task's own
/// machine. Run again, it runs nothing; a lost run directory is prepared again and its jobs
/// run again beside the ledger's names, with the same readings; it never writes the ledger,
/// and table.py still runs. It refuses to replace a file written with other arguments or by
/// another script blob, unless `--replace`.
#[test]
fn machine_or_reward_asks_each_unexplained_miss_again() {
    if !python_has_tomllib() {
        eprintln!("SKIPPED: python3 >= 3.11 (tomllib) is not available");
        return;
    }
    let tmp = tempfile::tempdir().unwrap();
    let (repo, bin, log) = locked(tmp.path(), &standard_plan(947_000));
    let s = Session {
        repo: &repo,
        bin: &bin,
    };
    // 947000 solved (the control); 947001, 947010 and 947011 missed, no candidate solved.
    let env = [
        (
            "FAKE_CHOOSE_FIRST",
            "smirl:947001,smirl:947010,smirl:947011",
        ),
        ("FAKE_NO_ORACLE", "smirl:947001,smirl:947010,smirl:947011"),
        ("FAKE_RETRAIN_SOLVES", "smirl:947001:1002"),
        ("FAKE_TASK_SOLVES", "smirl:947000,smirl:947010"),
        ("FAKE_NOT_REFINES", "947010"),
    ];
    let o = s.run(&env);
    assert!(o.status.success(), "{}", stderr(&o));
    let o = s.table(&[]);
    assert!(o.status.success(), "table: {}", stderr(&o));
    let ledger = s.state("ledger.jsonl");
    std::fs::write(&log, "").unwrap();
    let b = bin.to_str().unwrap();
    let ask_with = |extra: &[&str], env: &[(&str, &str)]| {
        let mut args = vec![NAME, "--bin", b, "--units", "a:smirl"];
        args.extend_from_slice(extra);
        s.script("machine_or_reward.py", &args, env)
    };
    let ask = || ask_with(&[], &env);
    let o = ask();
    assert!(o.status.success(), "machine_or_reward: {}", stderr(&o));
    let m = s.state("machine_or_reward.md");
    // | arm | task | base | seed | chosen | cause | fresh agents | solved | task's machine |
    // reading | note |
    let rows: Vec<(String, String, String, String)> = [947001, 947010, 947011, 947000]
        .iter()
        .map(|&seed| {
            let row = asked_row(&m, seed);
            (
                row[7].clone(),
                row[8].clone(),
                row[9].clone(),
                row[10].clone(),
            )
        })
        .collect();
    let row = |fresh: &str, solved: &str, task: &str, reading: &str| {
        (
            fresh.to_string(),
            solved.to_string(),
            task.to_string(),
            reading.to_string(),
        )
    };
    assert_eq!(
        rows,
        [
            row("0.30, 0.30, 1.00", "1 of 3", "0.30, 0.40", "training draw"),
            row(
                "0.30, 0.30, 0.30",
                "0 of 3",
                "0.30, 0.96",
                "learned machine"
            ),
            row("0.30, 0.30, 0.30", "0 of 3", "0.30, 0.40", "neither"),
            row("0.30, 0.30, 0.30", "0 of 3", "0.30, 0.96", ""),
        ],
        "{m}"
    );
    assert_eq!(asked_row(&m, 947000)[6], "solved (control)", "{m}");
    assert!(
        m.contains("| fresh fails, refining machine | 1 | 1 of 1 | 0 of 1 | 0 of 1 | 0 |"),
        "{m}"
    );
    assert!(
        m.contains("| fresh fails, coarse machine | 2 | 0 of 2 | 0 of 2 | 1 of 2 | 0 |"),
        "{m}"
    );
    // The machine test over both run directories (each has a miss; base 947010's machine
    // does not refine, 3 of 9 steps ambiguous) and over the task's own machine.
    assert!(m.contains("| every job solved | 0 |"), "{m}");
    assert!(
        m.contains("| a job missed | 2 | 1 | 0.00 | 0.17 | 0.33 |"),
        "{m}"
    );
    assert!(m.contains("refines the task's in 2 of 2"), "{m}");
    assert!(
        m.contains("| solved (control) | 1 | 0 of 1 | 0 of 1 | 1 of 1 | 0 |"),
        "{m}"
    );
    // | task | asked | training draw | learned machine | both | neither | not read |
    assert!(m.contains("| or | 3 | 1 | 1 | 0 | 1 | 0 |"), "{m}");
    assert!(m.contains("--fresh-seeds 1000,1001,1002"), "{m}");
    // Seed 1000 once per job (diagnose.py's question), then the other two; the task machine's
    // run directories prepared from a config that says so, once per base.
    let ran = std::fs::read_to_string(&log).unwrap();
    let expected = [
        "retrain:smirl:947001:1000",
        "retrain:smirl:947010:1000",
        "retrain:smirl:947011:1000",
        "prepare:or:947000",
        "prepare:or:947010",
        "retrain:smirl:947001:1001",
        "retrain:smirl:947001:1002",
        "task:smirl:947001",
        "retrain:smirl:947010:1001",
        "retrain:smirl:947010:1002",
        "task:smirl:947010",
        "retrain:smirl:947011:1001",
        "retrain:smirl:947011:1002",
        "task:smirl:947011",
        "retrain:smirl:947000:1000",
        "retrain:smirl:947000:1001",
        "retrain:smirl:947000:1002",
        "task:smirl:947000",
    ];
    assert_eq!(ran.lines().collect::<Vec<_>>(), expected, "{m}");
    let config = std::fs::read_dir(repo.join(format!("runs/protocol/{NAME}-task-machine")))
        .unwrap()
        .map(|e| e.unwrap().path())
        .find(|p| p.is_dir())
        .map(|d| std::fs::read_to_string(d.join("config.toml")).unwrap())
        .unwrap();
    assert!(config.contains("machine = \"task\""), "{config}");
    // Again: everything is read, nothing runs.
    std::fs::write(&log, "").unwrap();
    let o = ask();
    assert!(o.status.success(), "machine_or_reward: {}", stderr(&o));
    assert_eq!(std::fs::read_to_string(&log).unwrap(), "");
    assert_eq!(s.state("machine_or_reward.md"), m);
    // A lost run directory is prepared again, its jobs run again (another wall time, as a
    // real run takes) and kept as .diagnose.json, its fresh agents retrained: the same file.
    let lost = run_dir(&repo.join("runs/protocol").join(NAME), 947_010);
    std::fs::remove_dir_all(&lost).unwrap();
    let mut again = env.to_vec();
    again.push(("FAKE_WALL", "13.0"));
    let o = ask_with(&[], &again);
    assert!(o.status.success(), "machine_or_reward: {}", stderr(&o));
    assert_eq!(s.state("machine_or_reward.md"), m);
    let ran = std::fs::read_to_string(&log).unwrap();
    assert_eq!(
        ran.lines().collect::<Vec<_>>(),
        [
            "prepare:or:947010",
            "smirl:947010",
            "retrain:smirl:947010:1000",
            "smirl:947011",
            "retrain:smirl:947011:1000",
            "retrain:smirl:947010:1001",
            "retrain:smirl:947010:1002",
            "retrain:smirl:947011:1001",
            "retrain:smirl:947011:1002",
        ],
        "{m}"
    );
    for seed in [947_010, 947_011] {
        let jobs = lost.join("jobs");
        assert!(jobs
            .join(format!("smirl_seed{seed}.diagnose.json"))
            .is_file());
        assert!(!jobs.join(format!("smirl_seed{seed}.json")).exists());
    }
    // The ledger is untouched and the tables build.
    assert_eq!(s.state("ledger.jsonl"), ledger);
    let o = s.table(&[]);
    assert!(
        o.status.success(),
        "table after machine_or_reward: {}",
        stderr(&o)
    );
    // The task machine's run must replay the job's own demonstrations: other episodes (base
    // 947010's) or no log (base 947000's) leave those jobs unread.
    let task_dir = |base: u64| {
        std::fs::read_dir(repo.join(format!("runs/protocol/{NAME}-task-machine")))
            .unwrap()
            .map(|e| e.unwrap().path())
            .find(|p| p.is_dir() && p.to_str().unwrap().contains(&format!("-b{base}-")))
            .unwrap()
    };
    std::fs::write(
        task_dir(947_010).join("logs/demos.mcap"),
        "episode 0 seed 5\nepisode 1 seed 6\n",
    )
    .unwrap();
    std::fs::remove_file(task_dir(947_000).join("logs/demos.mcap")).unwrap();
    let o = ask();
    assert!(o.status.success(), "machine_or_reward: {}", stderr(&o));
    let m = s.state("machine_or_reward.md");
    for (seed, why) in [
        (947010, "other demonstrations"),
        (947011, "other demonstrations"),
        (947001, "demos.mcap does not exist"),
        (947000, "demos.mcap does not exist"),
    ] {
        let row = asked_row(&m, seed);
        assert_eq!(row[10], "not read", "{seed}: {m}");
        assert!(row[11].contains(why), "{seed}: {m}");
    }
    // A file written with other arguments, or by another script blob, is not replaced: the
    // run refuses before any work, unless --replace.
    std::fs::write(&log, "").unwrap();
    let o = ask_with(&["--fresh-seeds", "1000,1001"], &env);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(
        stderr(&o).contains(&format!(
            "experiments/protocol/{NAME}/machine_or_reward.md was written with other arguments"
        )),
        "{}",
        stderr(&o)
    );
    assert_eq!(s.state("machine_or_reward.md"), m);
    let header = m
        .lines()
        .find(|l| l.starts_with("Written by "))
        .unwrap()
        .to_string();
    let blob = header.split("(script blob ").nth(1).unwrap()[..12].to_string();
    let other_blob = m.replace(&blob, "000000000000");
    write(
        &repo.join(format!("experiments/protocol/{NAME}/machine_or_reward.md")),
        &other_blob,
    );
    let o = ask();
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert_eq!(s.state("machine_or_reward.md"), other_blob);
    assert_eq!(std::fs::read_to_string(&log).unwrap(), "");
    let o = ask_with(&["--fresh-seeds", "1000,1001", "--replace"], &env);
    assert!(o.status.success(), "machine_or_reward: {}", stderr(&o));
    let m = s.state("machine_or_reward.md");
    assert!(
        m.contains(&header.replace("1000,1001,1002", "1000,1001")),
        "{m}"
    );
    assert_eq!(std::fs::read_to_string(&log).unwrap(), "");
    // Seed 1000 is diagnose.py's: its causes rest on it.
    let o = s.script(
        "machine_or_reward.py",
        &[NAME, "--bin", b, "--fresh-seeds", "1001,1002"],
        &env,
    );
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("must hold diagnose.py's seed 1000"));
}

/// machine_or_reward.py reads only what is the job's own, and its readings count the "fresh
/// fails" jobs only: a job diagnose.py calls "agent" is asked and shown, not counted; a
/// retraining table whose last row ends past the run's SAC steps, in the episode in progress,
/// is the job's own (the budget here, 4 × 55, is no multiple of the 100-step episodes); a
/// retraining table of other steps (its last row before the budget, or a whole episode past
/// it) or other evaluations leaves its job unread and stays; at seed 1000 (diagnose.py's, read
/// there unchecked) such a table makes the job "not reproduced": shown, not asked. A run
/// config without one `machine = "learned"` line leaves its job unread; a task-machine
/// directory without prepare.json leaves its jobs unread and keeps its contents. The header
/// names the script's blob at start, though the file changes during the run.
#[test]
fn machine_or_reward_reads_only_the_jobs_own_tables_and_directories() {
    if !python_has_tomllib() {
        eprintln!("SKIPPED: python3 >= 3.11 (tomllib) is not available");
        return;
    }
    let tmp = tempfile::tempdir().unwrap();
    let plan = "bases = [948000, 948010]\ntimeout_secs = { smirl = 600 }\n\n[[arm]]\n\
                name = \"a\"\ntasks = [\"or\"]\nalgos = [\"smirl\"]\nn_bases = 2\nseeds = 3\n";
    let (repo, bin, log) = locked(tmp.path(), plan);
    let s = Session {
        repo: &repo,
        bin: &bin,
    };
    // Every job missed, no candidate solved; a fresh agent solves 948000's reward at every
    // SAC seed (diagnose.py: "agent"), SMIRL on the task's machine 948001's. 220 SAC steps:
    // every retraining ends its last episode at 300.
    let missed = "smirl:948000,smirl:948001,smirl:948002,smirl:948010,smirl:948011,smirl:948012";
    let env = [
        ("FAKE_CHOOSE_FIRST", missed),
        ("FAKE_NO_ORACLE", missed),
        ("FAKE_RETRAIN_SOLVES", "smirl:948000"),
        ("FAKE_TASK_SOLVES", "smirl:948001"),
        ("FAKE_SAC_STEPS", "55"),
    ];
    let o = s.run(&env);
    assert!(o.status.success(), "{}", stderr(&o));
    let o = s.table(&[]);
    assert!(o.status.success(), "table: {}", stderr(&o));
    let b = bin.to_str().unwrap();
    let d10 = run_dir(&repo.join("runs/protocol").join(NAME), 948_010);
    let rel = format!(
        "runs/protocol/{NAME}/{}",
        d10.file_name().unwrap().to_str().unwrap()
    );
    // Retrainings by hand under the names the script reads: 948010's at SAC seed 1001 with
    // other steps, 948011's at diagnose.py's seed 1000 with other evaluations.
    for (seed, sac, flag, value) in [
        ("948010", "1001", "--steps", "100"),
        ("948011", "1000", "--evaluations", "3"),
    ] {
        let args = [
            "retrain",
            "--run",
            d10.to_str().unwrap(),
            "--algo",
            "smirl",
            "--seed",
            seed,
            "--sac-seed",
            sac,
            flag,
            value,
        ];
        let o = run_in(&repo, b, &args, &[]);
        assert!(o.status.success(), "{}", stderr(&o));
    }
    let retrain_table = |dir: &Path, seed: u64, sac: u64| {
        std::fs::read_to_string(dir.join(format!("retrain/smirl_seed{seed}_sac{sac}.csv"))).unwrap()
    };
    let tables = [
        retrain_table(&d10, 948_010, 1001),
        retrain_table(&d10, 948_011, 1000),
    ];
    // 948010's run config has no `machine = "learned"` line.
    let config = d10.join("config.toml");
    let text = std::fs::read_to_string(&config).unwrap();
    write(&config, &text.replace("machine = \"learned\"\n", ""));
    std::fs::write(&log, "").unwrap();
    let script = repo.join("experiments/protocol/machine_or_reward.py");
    let mut edit = env.to_vec();
    edit.push(("FAKE_EDIT", script.to_str().unwrap()));
    let ask = |env: &[(&str, &str)]| {
        s.script(
            "machine_or_reward.py",
            &[NAME, "--bin", b, "--units", "a:smirl"],
            env,
        )
    };
    let o = ask(&edit);
    assert!(o.status.success(), "machine_or_reward: {}", stderr(&o));
    let m = s.state("machine_or_reward.md");
    // The script changed while it ran; the header names the blob that ran.
    let ran_blob = git(
        &repo,
        &[
            "rev-parse",
            "HEAD:experiments/protocol/machine_or_reward.py",
        ],
    );
    assert_ne!(
        git(
            &repo,
            &["hash-object", "experiments/protocol/machine_or_reward.py"]
        ),
        ran_blob
    );
    assert!(
        m.contains(&format!("(script blob {})", &ran_blob[..12])),
        "{m}"
    );
    git(
        &repo,
        &[
            "checkout",
            "--",
            "experiments/protocol/machine_or_reward.py",
        ],
    );
    // | arm | task | base | seed | chosen | cause | fresh agents | solved | task's machine |
    // reading | note |
    let rows: Vec<Vec<String>> = [948000, 948001, 948002]
        .iter()
        .map(|&seed| asked_row(&m, seed)[6..11].to_vec())
        .collect();
    assert_eq!(
        rows,
        [
            [
                "agent",
                "1.00, 1.00, 1.00",
                "3 of 3",
                "0.30, 0.40",
                "training draw"
            ],
            [
                "fresh fails, refining machine",
                "0.30, 0.30, 0.30",
                "0 of 3",
                "0.30, 0.96",
                "learned machine"
            ],
            [
                "fresh fails, refining machine",
                "0.30, 0.30, 0.30",
                "0 of 3",
                "0.30, 0.40",
                "neither"
            ],
        ],
        "{m}"
    );
    // 948000's tables were read, their last row 80 steps past the 220 (seed 1000's gave
    // diagnose.py's cause).
    let d00 = run_dir(&repo.join("runs/protocol").join(NAME), 948_000);
    for sac in [1000, 1001, 1002] {
        let table = retrain_table(&d00, 948_000, sac);
        assert!(table.ends_with("\n300,1.0,1.0,1.0\n"), "{table}");
    }
    // 948011's cause is not diagnose.py's reading of its foreign seed-1000 table: it is not
    // reproduced, and not asked.
    for (seed, cause, why) in [
        (
            948010,
            "fresh fails, refining machine",
            format!(
                "foreign retraining table {rel}/retrain/smirl_seed948010_sac1001.csv: \
                 last env_steps 100, not in [220, 320)"
            ),
        ),
        (
            948011,
            "not reproduced",
            format!(
                "foreign retraining table {rel}/retrain/smirl_seed948011_sac1000.csv: \
                 3 evaluations, not 5"
            ),
        ),
        (
            948012,
            "fresh fails, refining machine",
            format!("{rel}/config.toml has 0 lines `machine = \"learned\"`, not one"),
        ),
    ] {
        let row = asked_row(&m, seed);
        assert_eq!(row[6], cause, "{seed}: {m}");
        assert_eq!(row[10], "not read", "{seed}: {m}");
        assert!(row[11].starts_with(&why), "{seed}: {m}");
    }
    assert_eq!(
        [
            retrain_table(&d10, 948_010, 1001),
            retrain_table(&d10, 948_011, 1000)
        ],
        tables
    );
    let ran = std::fs::read_to_string(&log).unwrap();
    assert!(!ran.contains("retrain:smirl:948011:"), "{ran}");
    // The "agent" job is in the first table, not among the readings; nor is the job not
    // reproduced.
    assert!(
        m.contains("| agent | 1 | 1 of 1 | 1 of 1 | 0 of 1 | 0 |"),
        "{m}"
    );
    assert!(
        m.contains("| not reproduced | 1 | 0 of 0 | 0 of 0 | 0 of 0 | 1 |"),
        "{m}"
    );
    // | task | asked | training draw | learned machine | both | neither | not read |
    assert!(m.contains("| or | 4 | 0 | 1 | 0 | 1 | 2 |"), "{m}");
    assert!(m.contains("| all | 4 | 0 | 1 | 0 | 1 | 2 |"), "{m}");
    // A task-machine directory without prepare.json is not overwritten (948010's config is
    // whole again).
    write(&config, &text);
    let task = repo
        .join(format!("runs/protocol/{NAME}-task-machine"))
        .join(d10.file_name().unwrap());
    assert!(!task.exists());
    write(&task.join("notes.txt"), "mine\n");
    std::fs::write(&log, "").unwrap();
    let o = ask(&env);
    assert!(o.status.success(), "machine_or_reward: {}", stderr(&o));
    let m = s.state("machine_or_reward.md");
    let row = asked_row(&m, 948012);
    assert_eq!(row[10], "not read", "{m}");
    assert_eq!(
        row[11],
        format!(
            "runs/protocol/{NAME}-task-machine/{}",
            &rel[rel.rfind('/').unwrap() + 1..]
        ) + " exists without prepare.json: not overwritten",
        "{m}"
    );
    let kept: Vec<_> = std::fs::read_dir(&task)
        .unwrap()
        .map(|e| e.unwrap().file_name().into_string().unwrap())
        .collect();
    assert_eq!(kept, ["notes.txt"]);
    assert_eq!(
        std::fs::read_to_string(task.join("notes.txt")).unwrap(),
        "mine\n"
    );
    assert!(!PathBuf::from(format!("{}.config.toml", task.display())).exists());
    assert_eq!(prepare_lines(&log), Vec::<String>::new());
    // A last row a whole episode past the 220 steps (at 320) is of a longer retraining.
    let path = d00.join("retrain/smirl_seed948002_sac1002.csv");
    let table = retrain_table(&d00, 948_002, 1002);
    write(&path, &table.replace("\n300,", "\n320,"));
    let o = ask(&env);
    assert!(o.status.success(), "machine_or_reward: {}", stderr(&o));
    let m = s.state("machine_or_reward.md");
    let row = asked_row(&m, 948002);
    assert_eq!(row[10], "not read", "{m}");
    assert_eq!(
        row[11],
        format!(
            "foreign retraining table runs/protocol/{NAME}/{}/retrain/smirl_seed948002_sac1002.csv: \
             last env_steps 320, not in [220, 320) (sac_steps_per_iteration × irl_iterations, \
             plus less than [env] max_steps)",
            d00.file_name().unwrap().to_str().unwrap()
        ),
        "{m}"
    );
}

/// new_tasks_table.py puts a pool's tasks branch by branch: the expert's successes per branch
/// from its summary, and per arm the solved counts and the reported policy's mean per branch,
/// a failed job counting 0 on each branch (left out, the means would be 0.96 and 1.00).
#[test]
fn the_pool_table_gives_every_arm_per_branch_beside_the_expert() {
    if !python_has_tomllib() {
        eprintln!("SKIPPED: python3 >= 3.11 (tomllib) is not available");
        return;
    }
    let tmp = tempfile::tempdir().unwrap();
    let plan = format!(
        "{}\n[analysis]\npools = {{ p = [\"or\"] }}\n",
        standard_plan(946_000)
    );
    let (repo, bin, _log) = locked(tmp.path(), &plan);
    let s = Session {
        repo: &repo,
        bin: &bin,
    };
    let o = s.run(&[("FAKE_FAIL", "smirl:946011")]);
    assert!(o.status.success(), "{}", stderr(&o));
    let o = s.table(&[]);
    assert!(o.status.success(), "table: {}", stderr(&o));
    write(
        &repo.join("experts/summary_or.json"),
        r#"{"success_stochastic": 0.9, "success_mean": 0.95,
            "branches_stochastic": {"episodes": [60, 40], "successes": [57, 36]},
            "branches_mean": {"episodes": [60, 40], "successes": [60, 40]}}"#,
    );
    let o = s.script(
        "new_tasks_table.py",
        &[NAME, "--pool", "p", "--experts", "experts"],
        &[],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let t = s.state("p_tasks.md");
    assert!(
        t.contains("| or | 57/60 (0.95), 36/40 (0.90) | 60/60 (1.00), 40/40 (1.00) |"),
        "{t}"
    );
    // smirl: the choice (0.96, 1.00) in three jobs, one failed; paper: its loop's own
    // (0.0, 0.1, 0.0, 0.1 on the normal branch, 1.00 on the event's).
    assert!(
        t.contains("| or | a | smirl | 4 | 1 | 3/4 | 0/4 | normal 0.72, event 0.75 |"),
        "{t}"
    );
    assert!(
        t.contains("| or | a | paper | 4 | 0 | 0/4 | 0/4 | normal 0.05, event 1.00 |"),
        "{t}"
    );
}
