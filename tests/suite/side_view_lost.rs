//! A side view that lost part of the body to the backdrop (pale leggings on a pale
//! wall: a sliver of thigh left) is not fitted as a body without thighs: the station
//! measures those frames from the front view alone and says why. The silhouettes are the
//! synthetic subject's true ones (`StationOptions::truth_masks`), with the side view's
//! thighs cut down in a copy: the same recording with the whole side view is fitted from
//! both views.

use fitstation::camera::StationCalibration;
use fitstation::cli::{run_offline, RecordingSource};
use fitstation::recording::FrameFormat;
use fitstation::station::{default_library, StationOptions, StationProcessor};
use fitstation::synth::{load_truth, render_recording, truth_dir, SynthConfig};
use glam::DVec3;
use std::path::{Path, PathBuf};

/// Replays `rec` on the masks in `masks`; returns the report.
fn replay_on_masks(rec: &Path, masks: &Path) -> serde_json::Value {
    let mut src = RecordingSource::open(rec).expect("recording");
    let calib = src.recording().calibration().clone();
    let opts = StationOptions {
        truth_masks: Some(masks.to_path_buf()),
        person_model: false,
        ..StationOptions::default()
    };
    let mut station =
        StationProcessor::new(calib, default_library().expect("library"), opts).expect("station");
    run_offline(&mut src, &mut station, None, false).report
}

/// Copies the side masks of `from` into `to`, keeping of each row between the crotch and
/// 0.25 m below it only the 6 pixels around the row's middle.
fn cut_side_thighs(from: &Path, to: &Path, calib: &StationCalibration, crotch: DVec3) {
    let row = |y: f64| {
        calib
            .side
            .project(DVec3::new(crotch.x, y, crotch.z))
            .expect("in view")
            .y
    };
    let (top, bottom) = (row(crotch.y) as u32, row(crotch.y - 0.25) as u32);
    for view in ["front", "side"] {
        let dst = to.join(view);
        std::fs::create_dir_all(&dst).expect("mask dir");
        for e in std::fs::read_dir(from.join(view)).expect("masks") {
            let path = e.expect("entry").path();
            let mut img = image::open(&path).expect("mask").to_luma8();
            if view == "side" {
                for y in top..bottom.min(img.height()) {
                    let on: Vec<u32> = (0..img.width())
                        .filter(|&x| img.get_pixel(x, y)[0] > 127)
                        .collect();
                    let (Some(&a), Some(&b)) = (on.first(), on.last()) else {
                        continue;
                    };
                    let mid = (a + b) / 2;
                    for x in a..=b {
                        if x + 3 < mid || x > mid + 3 {
                            img.put_pixel(x, y, image::Luma([0]));
                        }
                    }
                }
            }
            img.save(dst.join(path.file_name().expect("name")))
                .expect("write mask");
        }
    }
}

fn views(report: &serde_json::Value) -> Vec<String> {
    report["views"]
        .as_array()
        .map(|a| {
            a.iter()
                .filter_map(|v| v.as_str().map(String::from))
                .collect()
        })
        .unwrap_or_default()
}

fn messages(report: &serde_json::Value) -> String {
    report["messages"].to_string()
}

#[test]
fn a_side_view_without_thighs_is_measured_from_the_front_alone() {
    let dir: PathBuf =
        std::env::temp_dir().join(format!("fitstation-side-lost-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let rec = dir.join("rec");
    let mut cfg = SynthConfig::from_seed(31);
    cfg.empty_frames = 10;
    cfg.subject_frames = 4;
    cfg.format = FrameFormat::Png;
    render_recording(&cfg, &rec).expect("render");
    let truth = load_truth(&truth_dir(&rec)).expect("truth");
    let calib = StationCalibration::load(&rec.join("station.yaml")).expect("calibration");
    let crotch = DVec3::from_array(truth.landmarks["crotch"]);
    let masks = truth_dir(&rec).join("masks");
    let cut = dir.join("cut_masks");
    cut_side_thighs(&masks, &cut, &calib, crotch);

    let whole = replay_on_masks(&rec, &masks);
    assert_eq!(views(&whole), ["front", "side"], "{}", messages(&whole));
    assert!(
        !messages(&whole).contains("side camera's picture"),
        "{}",
        messages(&whole)
    );

    let lost = replay_on_masks(&rec, &cut);
    assert_eq!(views(&lost), ["front"], "{}", messages(&lost));
    assert!(
        messages(&lost).contains("blends into the backdrop in the side camera's picture"),
        "{}",
        messages(&lost)
    );
    assert!(
        lost["frames"]["fitted"].as_u64().unwrap_or(0) >= 1,
        "{lost}"
    );
    // The thighs are the front view's, not the sliver's: within the one-view ±.
    let thigh = lost["measurements_mm"]["thigh_girth_left"]
        .as_f64()
        .expect("thigh");
    let t = truth.measurements_mm["thigh_girth_left"];
    assert!((thigh - t).abs() < 60.0, "thigh {thigh} truth {t}");
    std::fs::remove_dir_all(&dir).ok();
}
