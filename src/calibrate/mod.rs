//! Calibration of the two orthogonal station cameras (issue 7).
//!
//! 1. Intrinsics per camera ([`intrinsics`]): chessboard corners or circle-grid centres
//!    ([`corners`]), Zhang's closed-form start ([`zhang`]), Levenberg-Marquardt over
//!    fx fy cx cy, OpenCV's k1 k2 p1 p2 k3 and every view's pose ([`bundle`]); per-view
//!    and overall RMS reprojection error in pixels; outlier, blurred and duplicate
//!    views dropped with a reason. Live frames: [`intrinsics::LensSession`].
//! 2. Extrinsics in the station frame ([`extrinsics`]) from the placement board standing
//!    on the mark (procedure in `calib/README.md`), seen by both cameras.
//! 3. Operator checks ([`checks`]): angle between the optical axes, camera heights and
//!    tilts, the standing volume in view, millimetres per pixel and the girth error of
//!    one pixel of silhouette error.
//! 4. The `fitstation calibrate` command ([`cli`]); a renderer for tests ([`render`]).
//!
//! # Conventions
//! Station frame as `../shared/spec/formats.md`: metres, origin on the floor at the
//! mark, +Y up, +Z toward the front camera, +X the subject's left. Camera frame OpenCV's
//! (x right, y down, z forward), `x_cam = R x_station + t`. Board frame: see [`board`].
//! Pixels: origin at the centre of the top-left pixel. Angles in degrees at the
//! interface, radians inside.
//!
//! The core is library functions returning result structs so that the station UI can
//! drive the same steps as a wizard, with [`Progress`] events for its progress bar.

pub mod board;
pub mod bundle;
pub mod checks;
pub mod cli;
pub mod corners;
pub mod extrinsics;
pub mod intrinsics;
pub mod linalg;
pub mod render;
pub mod zhang;

pub use board::BoardSpec;
pub use checks::{check_station, StationChecks};
pub use corners::{CornerDetector, DetectError, Detection};
pub use extrinsics::{place_camera, CameraPlacement, Placement};
pub use intrinsics::{
    calibrate_intrinsics, detect_views, FrameFeedback, FrameOutcome, IntrinsicsCalibration,
    LensSession, ViewOutcome, ViewReport,
};

use std::path::PathBuf;

/// A view whose board edges are blurred more than this (Gaussian sigma, pixels) is not
/// used: motion or focus blur biases corners.
pub const MAX_BLUR_SIGMA_PX: f64 = 2.5;

/// Progress of a calibration, for a progress bar or a log.
#[derive(Debug, Clone, PartialEq)]
pub enum Progress {
    /// One image was searched for the board.
    ViewSearched {
        camera: String,
        index: usize,
        total: usize,
        name: String,
        outcome: String,
    },
    /// A stage started (text for the operator).
    Stage(String),
}

/// Errors a calibration can end with; each message says what to do next.
#[derive(Debug, thiserror::Error)]
pub enum CalibError {
    #[error("{dir}: no images (.png, .jpg) found: point --{camera} at the folder holding that camera's board photos")]
    NoImages { camera: String, dir: PathBuf },
    #[error("{path}: cannot read the image ({msg})")]
    ImageRead { path: PathBuf, msg: String },
    #[error("{camera}: images have different sizes ({first} and {other} in {path}): use frames from one camera at one resolution")]
    MixedSizes {
        camera: String,
        first: String,
        other: String,
        path: PathBuf,
    },
    #[error("{camera} camera: only {usable} usable board views, at least {needed} needed. {detail} Take 10-15 photos of the board, tilted 20-40 degrees left/right and up/down, moved into every part of the image, held still.")]
    TooFewViews {
        camera: String,
        usable: usize,
        needed: usize,
        detail: String,
    },
    #[error("{camera} camera: the board views are too similar (their orientations span only {spread_deg:.1} degrees; {needed_deg:.0} needed). Tilt the board 20-40 degrees left, right, up and down between photos.")]
    TooSimilarViews {
        camera: String,
        spread_deg: f64,
        needed_deg: f64,
    },
    #[error("{camera} camera: the closed-form start failed (views degenerate). Tilt the board more between photos and check --board counts INNER corners.")]
    StartFailed { camera: String },
    #[error("{camera} camera: calibration error is too large ({rms_px:.2} px RMS, at most {max_px:.1} allowed). Check --board and --square-mm, that the board is flat, and that all photos come from this camera at one zoom/focus.")]
    PoorFit {
        camera: String,
        rms_px: f64,
        max_px: f64,
    },
    #[error("{camera} station image {path}: {reason}. {advice}")]
    PlacementBoardNotFound {
        camera: String,
        path: PathBuf,
        reason: String,
        advice: String,
    },
    #[error("the placement board was found by the {seen} camera only; the {missing} camera: {reason}. Turn the board 45 degrees so that its printed side faces the corner between the cameras (calib/README.md), then take both station images again.")]
    SeenByOneCamera {
        seen: String,
        missing: String,
        reason: String,
    },
    #[error("placement board: {0}")]
    Placement(String),
    #[error(transparent)]
    Camera(#[from] crate::camera::CameraError),
    #[error("{path}: {msg}")]
    Io { path: PathBuf, msg: String },
}
