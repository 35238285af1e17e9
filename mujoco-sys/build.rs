//! Generates bindings to MuJoCo's simulation API from the installed headers and links
//! `libmujoco.so`. Debian's `libmujoco-dev` ships no pkg-config file, so the default
//! locations are Debian's and two environment variables override them.

use std::env;
use std::path::PathBuf;

const INSTALL_HINT: &str = "install Debian's MuJoCo 2.2.2 with \
`apt-get install libmujoco-dev libclang-dev`, or point MUJOCO_INCLUDE_DIR (the folder that \
holds mujoco/mujoco.h) and MUJOCO_LIB_DIR (the folder that holds libmujoco.so) at another copy";

fn main() {
    println!("cargo:rerun-if-env-changed=MUJOCO_INCLUDE_DIR");
    println!("cargo:rerun-if-env-changed=MUJOCO_LIB_DIR");
    println!("cargo:rerun-if-changed=wrapper.h");

    let include_dir =
        PathBuf::from(env::var("MUJOCO_INCLUDE_DIR").unwrap_or_else(|_| "/usr/include".into()));
    let lib_dir = PathBuf::from(env::var("MUJOCO_LIB_DIR").unwrap_or_else(|_| debian_lib_dir()));

    let header = include_dir.join("mujoco").join("mujoco.h");
    if !header.is_file() {
        fail(&format!("MuJoCo header not found at {}", header.display()));
    }
    let has_lib = std::fs::read_dir(&lib_dir)
        .map(|entries| {
            entries.flatten().any(|e| {
                let name = e.file_name();
                let name = name.to_string_lossy();
                name == "libmujoco.so" || name.starts_with("libmujoco.so.")
            })
        })
        .unwrap_or(false);
    if !has_lib {
        fail(&format!("libmujoco.so not found in {}", lib_dir.display()));
    }

    println!("cargo:rustc-link-search=native={}", lib_dir.display());
    println!("cargo:rustc-link-lib=dylib=mujoco");
    println!("cargo:include={}", include_dir.display());

    let bindings = bindgen::Builder::default()
        .header("wrapper.h")
        .clang_arg(format!("-I{}", include_dir.display()))
        // The simulation API only: no rendering (mjr_), visualisation (mjv_) or UI (mjui_).
        .allowlist_function("mj_.*")
        .allowlist_function("mju_.*")
        .allowlist_var("mju_user_.*")
        .allowlist_var("mj(NREF|NEQDATA|NDYN|NGAIN|NBIAS|NIMP|NSOLVER|MINVAL|MINIMP|MAXIMP|MAXCONPAIR|MAXVFS|MAXVFSNAME)")
        .allowlist_type("mjModel|mjData|mjOption|mjContact|mjWarningStat|mjTimerStat|mjSolverStat|mjVFS|mjLROpt|mjStatistic|mjtObj|mjtWarning|mjtJoint|mjtGeom|mjtIntegrator|mjtState|mjtNum")
        .blocklist_function("mjr_.*|mjv_.*|mjui_.*")
        // Any of these may reach mju_error, whose handler (installed by the safe wrapper)
        // unwinds. With the plain "C" ABI Rust assumes no unwinding and drops the landing
        // pads that would catch it, so the calls must be declared "C-unwind".
        .override_abi(bindgen::Abi::CUnwind, "mj_.*|mju_.*")
        .default_enum_style(bindgen::EnumVariation::Rust { non_exhaustive: false })
        .derive_default(true)
        .layout_tests(false)
        .generate()
        .unwrap_or_else(|e| fail(&format!("bindgen could not process {}: {e}", header.display())));

    let out = PathBuf::from(env::var("OUT_DIR").expect("cargo sets OUT_DIR"));
    bindings
        .write_to_file(out.join("bindings.rs"))
        .unwrap_or_else(|e| fail(&format!("cannot write bindings: {e}")));
}

/// Debian's library folder for the target, `/usr/lib/<arch>-linux-gnu`: its multiarch name is
/// the target's arch on x86_64, aarch64 and riscv64 (elsewhere MUJOCO_LIB_DIR names the folder).
fn debian_lib_dir() -> String {
    let arch = env::var("CARGO_CFG_TARGET_ARCH").expect("cargo sets CARGO_CFG_TARGET_ARCH");
    format!("/usr/lib/{arch}-linux-gnu")
}

fn fail(problem: &str) -> ! {
    panic!("\n\nmujoco-sys: {problem}.\nTo fix: {INSTALL_HINT}.\n\n");
}
