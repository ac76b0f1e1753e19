//! Reference check: the synthetic renderer projects station points exactly as
//! `cv2.projectPoints` does on the same calibration (< 0.05 px), and
//! `cv2.FileStorage` reads every station.yaml `synth` writes. Runs
//! `tests/opencv/synth_projection.py`; without cv2 it prints SKIPPED (fails under CI).

use fitstation::synth::rng::SplitMix64;
use fitstation::synth::{project_points, sample_station, CameraOptions, Orientation};
use glam::DVec3;
use std::process::Command;

fn cv2_available() -> bool {
    Command::new("python3")
        .args(["-c", "import cv2"])
        .output()
        .is_ok_and(|o| o.status.success())
}

#[test]
fn renderer_projection_matches_cv2_project_points() {
    if !cv2_available() {
        println!(
            "SKIPPED: python3 with cv2 is not available; the OpenCV projection check did not run"
        );
        assert!(
            std::env::var_os("CI").is_none(),
            "cv2 is required when CI is set"
        );
        return;
    }
    let dir = std::env::temp_dir().join(format!("fitstation-synth-proj-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let mut cases = Vec::new();
    for seed in 0..24u64 {
        let mut opts = CameraOptions::default();
        if seed % 3 == 1 {
            opts.orientation = Some(Orientation::Portrait);
        }
        if seed % 5 == 4 {
            opts.no_distortion = true;
        }
        let stature = 1.5 + 0.02 * seed as f64;
        let calib = sample_station(seed, &opts, stature);
        let yaml = dir.join(format!("station_{seed}.yaml"));
        calib.save(&yaml).unwrap();
        let mut rng = SplitMix64::new(seed + 100);
        let points: Vec<DVec3> = (0..200)
            .map(|_| {
                DVec3::new(
                    rng.range(-0.6, 0.6),
                    rng.range(0.0, stature + 0.05),
                    rng.range(-0.5, 0.5),
                )
            })
            .collect();
        let front: Vec<[f64; 2]> = project_points(&calib.front, &points)
            .iter()
            .map(|p| p.unwrap().to_array())
            .collect();
        let side: Vec<[f64; 2]> = project_points(&calib.side, &points)
            .iter()
            .map(|p| p.unwrap().to_array())
            .collect();
        cases.push(serde_json::json!({
            "yaml": yaml.to_string_lossy(),
            "points": points.iter().map(|p| p.to_array()).collect::<Vec<_>>(),
            "front": front,
            "side": side,
        }));
    }
    let json = dir.join("cases.json");
    std::fs::write(&json, serde_json::to_string(&cases).unwrap()).unwrap();
    let script = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/tests/opencv/synth_projection.py"
    );
    let out = Command::new("python3")
        .arg(script)
        .arg(&json)
        .output()
        .unwrap();
    println!("{}", String::from_utf8_lossy(&out.stdout));
    assert!(
        out.status.success(),
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    let _ = std::fs::remove_dir_all(&dir);
}
