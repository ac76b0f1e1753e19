//! Operator tools beside the kiosk: the calibration wizard hook and station checks.
//!
//! The calibration itself lives in `src/calibrate` (another module); the screen reaches
//! it only through [`CalibrationWizard`], which the lead implements there. Until then
//! [`NoCalibrationWizard`] says so on screen. Pixel coordinates are those of each
//! camera's frames; distances in metres, angles in degrees.

use crate::camera::{StationCalibration, View};
use glam::DVec2;
use image::RgbImage;

/// One calibration board found in one camera frame.
#[derive(Debug, Clone, PartialEq)]
pub struct BoardDetection {
    /// Which board ("charuco 7x5 #0", ...).
    pub board: String,
    /// Detected corners in that camera's pixels (drawn over the view).
    pub corners_px: Vec<DVec2>,
    /// A short note (corner count, sharpness, reprojection error...).
    pub note: String,
}

/// Detections in the current frame pair, per camera.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct BoardDetections {
    pub front: Vec<BoardDetection>,
    pub side: Vec<BoardDetection>,
}

/// What the operator's calibration panel calls; implemented with `src/calibrate`.
pub trait CalibrationWizard: Send {
    /// Finds boards in the current frames (called on the operator's click, UI thread).
    fn detect(&mut self, front: &RgbImage, side: &RgbImage) -> BoardDetections;
    /// Keeps the last detection as a calibration view; returns a status line.
    fn add_view(&mut self) -> String {
        "adding views is not available".into()
    }
    /// Solves the station from the kept views.
    fn solve(&mut self) -> Result<StationCalibration, String> {
        Err("solving is not available".into())
    }
    /// Extra station checks to show (beside the built-in [`station_checks`]).
    fn station_checks(&self, _calibration: Option<&StationCalibration>) -> Vec<String> {
        Vec::new()
    }
    /// One line for the panel's title.
    fn describe(&self) -> String;
}

/// Placeholder until the calibration module is connected.
#[derive(Debug, Default)]
pub struct NoCalibrationWizard;

impl CalibrationWizard for NoCalibrationWizard {
    fn detect(&mut self, _front: &RgbImage, _side: &RgbImage) -> BoardDetections {
        BoardDetections::default()
    }
    fn describe(&self) -> String {
        "calibration module not connected (board detection unavailable)".into()
    }
}

/// Angle between the optical axes that the station expects (front and side at right
/// angles) and the tolerance before a check warns.
const EXPECTED_AXIS_ANGLE_DEG: f64 = 90.0;
const AXIS_ANGLE_TOLERANCE_DEG: f64 = 10.0;

/// Plain-language checks of a calibration against the frames being received.
/// `frame_sizes` are the current (front, side) frame sizes when known.
pub fn station_checks(
    calibration: Option<&StationCalibration>,
    frame_sizes: Option<([u32; 2], [u32; 2])>,
) -> Vec<String> {
    let Some(cal) = calibration else {
        return vec!["No calibration: run the calibration wizard, then save station.yaml.".into()];
    };
    let mut out = Vec::new();
    for view in [View::Front, View::Side] {
        let cam = cal.camera(view);
        let c = cam.center_in_station();
        out.push(format!(
            "{} camera at x {:.2} y {:.2} z {:.2} m, {:.2} m from the mark, {}x{} px",
            view.name(),
            c.x,
            c.y,
            c.z,
            (c.x * c.x + c.z * c.z).sqrt(),
            cam.intrinsics.width,
            cam.intrinsics.height
        ));
        if let Some((f, s)) = frame_sizes {
            let size = if view == View::Front { f } else { s };
            match cal.check_frame_size(view, size[0], size[1]) {
                Ok(()) => out.push(format!("OK: {} frames match the calibration", view.name())),
                Err(e) => out.push(format!("PROBLEM: {e}")),
            }
        }
    }
    let a = cal.front.axis_in_station();
    let b = cal.side.axis_in_station();
    let angle = a.dot(b).clamp(-1.0, 1.0).acos().to_degrees();
    if (angle - EXPECTED_AXIS_ANGLE_DEG).abs() <= AXIS_ANGLE_TOLERANCE_DEG {
        out.push(format!("OK: camera axes {angle:.1} deg apart"));
    } else {
        out.push(format!("PROBLEM: camera axes {angle:.1} deg apart (expected about {EXPECTED_AXIS_ANGLE_DEG:.0})"));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::app::demo::demo_calibration;

    #[test]
    fn checks_report_missing_calibration_and_size_mismatch() {
        let none = station_checks(None, None);
        assert_eq!(none.len(), 1);
        assert!(none[0].contains("No calibration"));
        let cal = demo_calibration();
        let w = cal.front.intrinsics.width;
        let h = cal.front.intrinsics.height;
        let ok = station_checks(Some(&cal), Some(([w, h], [w, h])));
        assert!(ok.iter().all(|l| !l.starts_with("PROBLEM")), "{ok:?}");
        assert!(
            ok.iter().any(|l| l.starts_with("OK: camera axes")),
            "{ok:?}"
        );
        let bad = station_checks(Some(&cal), Some(([w, h], [h, w])));
        assert_eq!(
            bad.iter().filter(|l| l.starts_with("PROBLEM")).count(),
            1,
            "{bad:?}"
        );
    }

    #[test]
    fn placeholder_wizard_detects_nothing() {
        let mut w = NoCalibrationWizard;
        let img = RgbImage::new(4, 4);
        assert_eq!(w.detect(&img, &img), BoardDetections::default());
        assert!(w.solve().is_err());
        assert!(w.describe().contains("not connected"));
    }
}
