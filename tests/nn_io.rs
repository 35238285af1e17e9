//! Parameter files: round trip, architecture check, corrupt files.

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use smirl::nn::{Mlp, MlpArch, NnError};

#[test]
fn mlp_save_load_round_trip_is_exact() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("net.bin");
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let arch = MlpArch::new(24, &[64, 64], 4);
    let a = Mlp::new(&arch, &mut rng);
    a.save(&path).unwrap();
    let mut b = Mlp::new(&arch, &mut rng);
    assert!(a.params().zip(b.params()).any(|(x, y)| x != y));
    b.load(&path).unwrap();
    assert!(a.params().zip(b.params()).all(|(x, y)| x == y));
}

#[test]
fn loading_another_architecture_is_refused_naming_both() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("net.bin");
    let mut rng = ChaCha8Rng::seed_from_u64(8);
    Mlp::new(&MlpArch::new(24, &[64, 64], 4), &mut rng)
        .save(&path)
        .unwrap();
    let mut other = Mlp::new(&MlpArch::new(24, &[32], 4), &mut rng);
    let before: Vec<Vec<f32>> = other.params().map(|p| p.to_vec()).collect();
    let err = other.load(&path).unwrap_err();
    assert!(matches!(err, NnError::ArchitectureMismatch { .. }));
    let msg = err.to_string();
    assert!(
        msg.contains("24-64-64-4") && msg.contains("24-32-4"),
        "{msg}"
    );
    assert!(msg.contains("net.bin"), "{msg}");
    let after: Vec<Vec<f32>> = other.params().map(|p| p.to_vec()).collect();
    assert_eq!(before, after, "a refused load must not modify the network");
}

#[test]
fn corrupt_and_truncated_files_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("net.bin");
    let mut rng = ChaCha8Rng::seed_from_u64(9);
    let mut net = Mlp::new(&MlpArch::new(3, &[5], 2), &mut rng);
    net.save(&path).unwrap();
    let bytes = std::fs::read(&path).unwrap();
    std::fs::write(&path, &bytes[..bytes.len() - 3]).unwrap();
    let msg = net.load(&path).unwrap_err().to_string();
    assert!(msg.contains("ends early"), "{msg}");
    std::fs::write(&path, b"not a network").unwrap();
    let msg = net.load(&path).unwrap_err().to_string();
    assert!(msg.contains("magic"), "{msg}");
    let mut wrong_version = bytes.clone();
    wrong_version[8] = 99;
    std::fs::write(&path, &wrong_version).unwrap();
    let msg = net.load(&path).unwrap_err().to_string();
    assert!(msg.contains("version 99"), "{msg}");
}

#[test]
fn finiteness_check_catches_nan_and_infinities_only() {
    use smirl::nn::mlp::all_finite;
    assert!(all_finite(&[
        0.0,
        -0.0,
        f32::MAX,
        f32::MIN,
        f32::MIN_POSITIVE,
        1e-45
    ]));
    for bad in [f32::NAN, f32::INFINITY, f32::NEG_INFINITY, -f32::NAN] {
        let mut v = vec![1.0f32; 37];
        v[29] = bad;
        assert!(!all_finite(&v), "{bad} not caught");
    }
}
