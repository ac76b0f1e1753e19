//! Helpers shared by the end-to-end tests that render a synthetic recording and replay
//! it through the station in-process.
#![allow(dead_code)]

use fitstation::cli::{run_offline, RecordingSource};
use fitstation::station::{default_library, StationOptions, StationProcessor};
use std::path::{Path, PathBuf};

/// The girths `report.json` reports.
pub const GIRTHS: [&str; 5] = [
    "chest_girth",
    "waist_girth",
    "hip_girth",
    "thigh_girth_left",
    "thigh_girth_right",
];

/// A fresh, empty temporary folder `fitstation-PREFIX-PID-NAME`.
pub fn tmp_dir(prefix: &str, name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("fitstation-{prefix}-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).expect("temp dir");
    d
}

/// The station's report.json for a recording replayed with the default options.
pub fn replay_report(rec: &Path) -> serde_json::Value {
    let mut src = RecordingSource::open(rec).expect("open the recording");
    let calib = src.recording().calibration().clone();
    let library = default_library().expect("shape library");
    let mut station =
        StationProcessor::new(calib, library, StationOptions::default()).expect("station");
    run_offline(&mut src, &mut station, None, false).report
}
