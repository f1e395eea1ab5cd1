//! `mimicgen prepare` recomputes what the reference's `prepare_src_dataset.py` stored.
#![allow(clippy::unwrap_used)] // tests fail loudly by design

use std::process::Command;

use mimicgen_io::tree::Node;
use mimicgen_io::{RobomimicDataset, read_source_dataset, write_tree};

fn repo(path: &str) -> std::path::PathBuf {
    std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../..").join(path)
}

#[test]
fn prepare_rebuilds_the_reference_datagen_info_from_states() {
    let fixture = repo("core/io/tests/data/source_D0_prepared.hdf5");
    let dir = tempfile::tempdir().unwrap();
    // A plain robomimic file: the reference source file without datagen_info.
    let mut plain = RobomimicDataset::open(&fixture).unwrap();
    let Some(Node::Group(data)) = plain.root.members.get_mut("data") else { panic!("no data group") };
    for node in data.members.values_mut() {
        if let Node::Group(demo) = node {
            assert!(demo.members.remove("datagen_info").is_some());
        }
    }
    let plain_path = dir.path().join("plain.hdf5");
    write_tree(&plain_path, &plain.root).unwrap();
    assert!(read_source_dataset(&plain_path, &Default::default()).is_err(), "a plain file is not a source dataset");

    let out = dir.path().join("prepared.hdf5");
    let status = Command::new(env!("CARGO_BIN_EXE_mimicgen")).arg("prepare").arg(&plain_path).arg("--out").arg(&out).output().unwrap();
    assert!(status.status.success(), "{}", String::from_utf8_lossy(&status.stderr));

    let ours = read_source_dataset(&out, &Default::default()).unwrap();
    let reference = read_source_dataset(&fixture, &Default::default()).unwrap();
    assert_eq!(ours.demos.len(), reference.demos.len());
    let err = |x: &mimicgen_engine::Pose, y: &mimicgen_engine::Pose| {
        (x.translation.vector - y.translation.vector).norm().max(x.rotation.angle_to(&y.rotation))
    };
    let (mut worst_pose, mut worst_target, mut signal_steps, mut signal_agree) = (0.0f64, 0.0f64, 0usize, 0usize);
    for (a, b) in ours.demos.iter().zip(&reference.demos) {
        assert_eq!(a.len(), b.len());
        let objects = a.object_poses.iter().flat_map(|(k, v)| v.iter().zip(&b.object_poses[k]));
        for (x, y) in a.eef_poses.iter().zip(&b.eef_poses).chain(objects) {
            worst_pose = worst_pose.max(err(x, y));
        }
        for (x, y) in a.target_poses.iter().zip(&b.target_poses) {
            worst_target = worst_target.max(err(x, y));
        }
        assert_eq!(a.gripper_actions, b.gripper_actions);
        for (x, y) in a.subtask_term_signals["grasp"].iter().zip(&b.subtask_term_signals["grasp"]) {
            signal_steps += 1;
            signal_agree += usize::from(x == y);
        }
    }
    println!(
        "prepare: worst eef/object pose difference {worst_pose:.2e}, target pose {worst_target:.2e}; grasp signal agrees on {signal_agree} of {signal_steps} steps"
    );
    assert!(worst_pose < 1e-9, "{worst_pose}");
    // The reference goes through numpy's axis-angle -> quaternion -> matrix in a different order.
    assert!(worst_target < 1e-6, "{worst_target}");
    assert!(signal_agree * 100 >= signal_steps * 99, "{signal_agree} of {signal_steps}");
}

#[test]
fn coverage_bins_the_initial_scenes_over_the_reset_region() {
    let out = Command::new(env!("CARGO_BIN_EXE_mimicgen"))
        .args(["coverage", "--json"])
        .arg(repo("core/sim/data/stack_D0_source.hdf5"))
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let c: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    // Two cubes x (x, y, yaw) in 3 bins: 3^6 joint bins; 10 demos hit at most 10 of them.
    assert_eq!(c["joint_bins_total"], 729);
    assert_eq!(c["scenes"], 10);
    let hit = c["joint_bins_hit"].as_u64().unwrap();
    assert!((2..=10).contains(&hit), "{hit}");
    let per_dimension: Vec<u64> =
        c["histograms"].as_array().unwrap().iter().map(|h| h.as_array().unwrap().iter().map(|n| n.as_u64().unwrap()).sum()).collect();
    assert_eq!(per_dimension, vec![10; 6]);
}
