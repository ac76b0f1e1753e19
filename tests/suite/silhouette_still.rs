//! The paper's case, one still image per view: keying a plain backdrop, keying against
//! an empty-scene image, and the `fitstation landmarks` command on both.

use crate::silhouette_common;

use fitstation::landmarks::phantom::SceneParams;
use fitstation::segment::key_still;
use serde_json::Value;
use silhouette_common::*;
use std::path::Path;
use std::process::Command;

/// Still images have no learned noise model, so a little less than the live target.
const MIN_STILL_IOU: f64 = 0.97;

#[test]
fn a_plain_backdrop_is_keyed_without_an_empty_image() {
    let p = render(
        &[subject()],
        SceneParams {
            plain_backdrop: true,
            shadow: false,
            seed: 61,
            ..Default::default()
        },
    );
    for (frame, truth) in [(&p.front, &p.front_truth), (&p.side, &p.side_truth)] {
        let m = key_still(frame, None).expect("key");
        let iou = m.iou(truth);
        println!("keyed plain backdrop: IoU {iou:.4}");
        assert!(iou > MIN_STILL_IOU, "IoU {iou}");
    }
}

#[test]
fn a_textured_backdrop_is_keyed_against_its_empty_image() {
    let p = render(
        &[subject()],
        SceneParams {
            seed: 62,
            ..Default::default()
        },
    );
    let e = empty_cached(0);
    for (frame, empty, truth) in [
        (&p.front, &e.front, &p.front_truth),
        (&p.side, &e.side, &p.side_truth),
    ] {
        let m = key_still(frame, Some(empty)).expect("key");
        let iou = m.iou(truth);
        println!("keyed against an empty image: IoU {iou:.4}");
        assert!(iou > MIN_STILL_IOU, "IoU {iou}");
    }
    // Mismatched sizes are an error, not a panic.
    let small = image::RgbImage::new(10, 10);
    assert!(key_still(&p.front, Some(&small)).is_err());
}

fn run_cli(dir: &Path, with_bg: bool) -> Value {
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_fitstation"));
    cmd.arg("landmarks")
        .arg("--front")
        .arg(dir.join("front.png"))
        .arg("--side")
        .arg(dir.join("side.png"))
        .arg("--calib")
        .arg(dir.join("station.yaml"))
        .arg("--json")
        .arg("--overlay")
        .arg(dir.join("overlay.png"));
    if with_bg {
        cmd.arg("--front-bg")
            .arg(dir.join("front_bg.png"))
            .arg("--side-bg")
            .arg(dir.join("side_bg.png"));
    }
    let out = cmd.output().expect("run fitstation");
    assert!(
        out.status.success(),
        "fitstation failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).expect("JSON output")
}

fn check_json(j: &Value) {
    let crotch = &j["landmarks"]["crotch"];
    let y = crotch["station"]["y"].as_f64().expect("crotch y");
    assert!((0.7..0.9).contains(&y), "crotch y {y}");
    assert!(crotch["station"]["x"].is_f64() && crotch["station"]["z"].is_f64());
    assert!(crotch["front_px"]["u"].is_f64() && crotch["side_px"]["v"].is_f64());
    for name in [
        "armpit_left",
        "armpit_right",
        "acromion_left",
        "acromion_right",
        "head_top",
    ] {
        assert!(j["landmarks"][name]["station"]["y"].is_f64(), "{name}");
    }
    for name in [
        "hip",
        "waist",
        "chest",
        "neck",
        "knee_left",
        "ankle_right",
        "elbow_left",
        "wrist_right",
        "shoulder_left",
    ] {
        assert!(j["joints"][name]["station"]["y"].is_f64(), "{name}");
    }
    assert_eq!(
        j["verdicts"].as_array().map(|v| v.len()),
        Some(0),
        "{}",
        j["verdicts"]
    );
    let stature = j["stature_m"].as_f64().expect("stature");
    assert!((stature - 1.73).abs() < 0.015, "stature {stature}");
}

#[test]
fn the_landmarks_command_writes_json_and_an_overlay() {
    let dir =
        std::env::temp_dir().join(format!("fitstation_silhouette_cli_{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("dir");
    station()
        .save(&dir.join("station.yaml"))
        .expect("calibration");
    // Plain backdrop, no empty images: the backdrop is keyed from the border.
    let p = render(
        &[subject()],
        SceneParams {
            plain_backdrop: true,
            shadow: false,
            seed: 63,
            ..Default::default()
        },
    );
    p.front.save(dir.join("front.png")).expect("save");
    p.side.save(dir.join("side.png")).expect("save");
    check_json(&run_cli(&dir, false));
    let overlay = image::open(dir.join("overlay.png"))
        .expect("overlay")
        .to_rgb8();
    assert_eq!(
        overlay.dimensions(),
        (2 * p.front.width(), p.front.height())
    );
    // Textured backdrop with empty-scene images.
    let p = render(
        &[subject()],
        SceneParams {
            seed: 64,
            ..Default::default()
        },
    );
    p.front.save(dir.join("front.png")).expect("save");
    p.side.save(dir.join("side.png")).expect("save");
    let e = empty_cached(1);
    e.front.save(dir.join("front_bg.png")).expect("save");
    e.side.save(dir.join("side_bg.png")).expect("save");
    check_json(&run_cli(&dir, true));
    // SILHOUETTE_OVERLAY_OUT=path keeps the overlay for a look.
    if let Some(keep) = std::env::var_os("SILHOUETTE_OVERLAY_OUT") {
        std::fs::copy(dir.join("overlay.png"), keep).expect("copy overlay");
    }
    // A missing file is a clear error.
    let out = Command::new(env!("CARGO_BIN_EXE_fitstation"))
        .args([
            "landmarks",
            "--front",
            "/nonexistent.png",
            "--side",
            "/nonexistent.png",
            "--calib",
        ])
        .arg(dir.join("station.yaml"))
        .output()
        .expect("run");
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("nonexistent"));
    let _ = std::fs::remove_dir_all(&dir);
}
