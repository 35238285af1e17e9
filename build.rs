//! Build script of the `smirl` package: records which git commit the binary was built from,
//! so run logs can name it. (The shipped assets are built into the binary by `src/assets.rs`,
//! so nothing here ties the binary to the checkout.)

use std::process::Command;

/// Minor version of the compiler building the crate (`rustc 1.95.0 (…)` → 95), 0 when unknown.
fn rustc_minor() -> u32 {
    let rustc = std::env::var("RUSTC").unwrap_or_else(|_| "rustc".into());
    Command::new(rustc)
        .arg("--version")
        .output()
        .ok()
        .and_then(|o| String::from_utf8(o.stdout).ok())
        .and_then(|v| v.split(['.', ' ']).nth(2).and_then(|m| m.parse().ok()))
        .unwrap_or(0)
}

fn git(manifest: &str, args: &[&str]) -> Option<String> {
    Command::new("git")
        .args(args)
        .current_dir(manifest)
        .output()
        .ok()
        .filter(|o| o.status.success())
        .and_then(|o| String::from_utf8(o.stdout).ok())
        .map(|s| s.trim().to_string())
}

fn main() {
    let manifest = std::env::var("CARGO_MANIFEST_DIR").expect("cargo sets CARGO_MANIFEST_DIR");
    let mut commit = git(&manifest, &["rev-parse", "HEAD"]).unwrap_or_default();
    // A build from a checkout whose sources differ from the commit is marked, so that a run
    // never names a commit it was not built from.
    let dirty = git(
        &manifest,
        &[
            "status",
            "--porcelain",
            "--untracked-files=no",
            "--",
            "src",
            "assets",
            "mujoco-sys",
            "build.rs",
            "Cargo.toml",
            "Cargo.lock",
        ],
    );
    if !commit.is_empty() && dirty.is_some_and(|d| !d.is_empty()) {
        commit.push_str("-dirty");
    }
    println!("cargo:rustc-env=SMIRL_GIT_COMMIT={commit}");
    // AVX-512 intrinsics are stable from Rust 1.89, above the crate's minimum: older compilers
    // build `nn::gemm_unpacked` without its kernel and every product goes to sgemm (same bits).
    println!("cargo:rustc-check-cfg=cfg(smirl_avx512)");
    if rustc_minor() >= 89 {
        println!("cargo:rustc-cfg=smirl_avx512");
    }
    println!("cargo:rerun-if-changed=build.rs");
    // Rerun when a source changes, so the dirty mark follows the checkout.
    for dir in ["src", "assets"] {
        println!("cargo:rerun-if-changed={dir}");
    }
    // Rebuild when HEAD moves: watch HEAD itself (a branch switch) and the branch's ref file
    // (a commit). Ask git for their paths: in a worktree `.git` is a file, not a folder.
    for path in ["HEAD", "refs/heads"] {
        if let Some(p) = git(
            &manifest,
            &["rev-parse", "--path-format=absolute", "--git-path", path],
        ) {
            println!("cargo:rerun-if-changed={p}");
        }
    }
    if let Some(branch) = git(&manifest, &["symbolic-ref", "-q", "HEAD"]) {
        if let Some(p) = git(
            &manifest,
            &["rev-parse", "--path-format=absolute", "--git-path", &branch],
        ) {
            println!("cargo:rerun-if-changed={p}");
        }
    }
}
