//! `reacher reward FILE --at x,y`: a baseline's saved reward at fingertip positions.

use smirl::env::reacher::OBS_TIP;
use smirl::irl::reward::{MlpReward, MlpRewardConfig, RewardModel};
use std::process::Command;

#[allow(unused_imports)]
use shipped_layout::{layout, obs_dim, shipped_config};
mod shipped_layout;

fn reacher() -> Command {
    Command::new(env!("CARGO_BIN_EXE_reacher"))
}

#[test]
fn prints_the_saved_reward_at_each_point_and_refuses_bad_input() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("fkl_seed3.bin");
    let model =
        MlpReward::new(MlpRewardConfig::paper(OBS_TIP.to_vec(), 1e-3, 3), obs_dim()).unwrap();
    model.save(&path).unwrap();
    let points = [[0.21, 0.0], [-0.0591, 0.0104]];
    let mut obs = vec![0.0f32; 2 * obs_dim()];
    for (row, p) in obs.chunks_exact_mut(obs_dim()).zip(&points) {
        row[OBS_TIP[0]] = p[0] as f32;
        row[OBS_TIP[1]] = p[1] as f32;
    }
    let mut want = vec![0.0f32; 2];
    let mut m = model;
    m.reward_batch(&obs, &[], &mut want).unwrap();
    let o = reacher()
        .arg("reward")
        .arg(&path)
        .args(["--at", "0.21,0", "--at", "-0.0591,0.0104"])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let got: Vec<f32> = String::from_utf8_lossy(&o.stdout)
        .lines()
        .map(|l| l.split_whitespace().nth(2).unwrap().parse().unwrap())
        .collect();
    assert_eq!(got, want);
    for (args, needle) in [
        (vec!["--at", "1"], "expected x,y"),
        (vec!["--at", "nan,0"], "expected x,y"),
    ] {
        let o = reacher()
            .arg("reward")
            .arg(&path)
            .args(&args)
            .output()
            .unwrap();
        assert_eq!(o.status.code(), Some(2));
        assert!(String::from_utf8_lossy(&o.stderr).contains(needle));
    }
    // Not a reward file: named, exit 2.
    let other = dir.path().join("notes.txt");
    std::fs::write(&other, "hello").unwrap();
    let o = reacher()
        .arg("reward")
        .arg(&other)
        .args(["--at", "0,0"])
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("notes.txt"));
}
