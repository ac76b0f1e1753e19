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

/// A fresh, empty temporary folder `fitstation-PREFIX-PID-NAME`, removed when dropped
/// (the renders and fits in it are tens of megabytes a test, and CI's disk is shared by
/// every run); kept, and named on stderr, when the test fails, to look at.
pub struct TempDir(PathBuf);

impl TempDir {
    pub fn new(prefix: &str, name: &str) -> TempDir {
        let d =
            std::env::temp_dir().join(format!("fitstation-{prefix}-{}-{name}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).expect("temp dir");
        TempDir(d)
    }
}

impl std::ops::Deref for TempDir {
    type Target = Path;
    fn deref(&self) -> &Path {
        &self.0
    }
}

impl AsRef<Path> for TempDir {
    fn as_ref(&self) -> &Path {
        &self.0
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        if std::thread::panicking() {
            eprintln!("kept for a look: {}", self.0.display());
        } else {
            let _ = std::fs::remove_dir_all(&self.0);
        }
    }
}

/// A fresh, empty temporary folder `fitstation-PREFIX-PID-NAME` (see [`TempDir`]).
pub fn tmp_dir(prefix: &str, name: &str) -> TempDir {
    TempDir::new(prefix, name)
}

/// The station's report.json for a recording replayed with the default options.
pub fn replay_report(rec: &Path) -> serde_json::Value {
    replay_report_with(rec, StationOptions::default())
}

/// The station's report.json for a recording replayed with `opts`.
pub fn replay_report_with(rec: &Path, opts: StationOptions) -> serde_json::Value {
    let mut src = RecordingSource::open(rec).expect("open the recording");
    let calib = src.recording().calibration().clone();
    let library = default_library().expect("shape library");
    let mut station = StationProcessor::new(calib, library, opts).expect("station");
    run_offline(&mut src, &mut station, None, false).report
}

/// ANSUR II from `../shared` beside the checkout.
pub fn ansur_table() -> fitstation::synth::ansur::AnsurTable {
    fitstation::synth::ansur::AnsurTable::load(
        &fitstation::synth::ansur::resolve_dir(None).expect("ANSUR II beside the checkout"),
    )
    .expect("ANSUR II")
}

/// Every frame's value of measurement `key` in a report's `series`.
pub fn series(report: &serde_json::Value, key: &str) -> Vec<f64> {
    report["series"]
        .as_array()
        .expect("series")
        .iter()
        .filter_map(|r| r[key].as_f64())
        .collect()
}
