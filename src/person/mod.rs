//! A learned person model beside the backdrop model (issue 20): MediaPipe's selfie
//! segmentation and BlazePose GHUM (full) landmark networks, imported to ONNX by
//! `tools/import_mediapipe.py` (files under `models/`, see `models/PROVENANCE.md`) and run
//! in pure Rust with `tract-onnx` (the default feature `person-model`; a build without it,
//! such as the fuzz targets', fails to load a network with a message saying so).
//!
//! This module is the inference stage only: frame crop -> network -> person probability and
//! body keypoints in frame pixels. Fusing them with the backdrop segmentation is not done
//! here.
//!
//! # Conventions
//! - Frames are interleaved 8-bit RGB, row-major, `width * height * 3` bytes.
//! - Frame coordinates are continuous pixels: pixel `(i, j)` covers `[i, i+1) x [j, j+1)`,
//!   so its centre is `(i + 0.5, j + 0.5)`.
//! - A [`Roi`] is the axis-aligned frame rectangle fed to the network; it is resampled to
//!   the network's 256x256 input (area-averaged), parts outside the frame are black (as
//!   MediaPipe's zero border). A square ROI keeps the aspect ratio (MediaPipe's pose
//!   pipeline letterboxes its crop); [`Roi::full_frame`] stretches the frame (MediaPipe's
//!   selfie segmentation does).
//! - Network input: RGB in [0, 1], NHWC, as both MediaPipe graphs feed them.
//! - Outputs: [`PersonOutput::mask`] holds the probability at the network's resolution
//!   with its ROI, [`ProbMask::at`] samples it at a frame pixel and
//!   [`ProbMask::write_frame`] renders it at frame resolution; keypoints are in frame pixels
//!   with visibility and presence as probabilities (sigmoid of the network's logits).
//!
//! # Per frame
//! The network plan is built once ([`PoseLandmarker::load`], [`SelfieSegmenter::load`]);
//! [`PersonModel::infer`] reuses the input tensor and the output buffers. tract itself
//! allocates its intermediate tensors on each run.

#[cfg(not(feature = "person-model"))]
#[path = "no_engine.rs"]
mod engine;
#[cfg(feature = "person-model")]
#[path = "tract_backend.rs"]
mod engine;
mod networks;
mod prep;

pub use networks::{PoseLandmarker, SelfieSegmenter};
pub use prep::resample_roi;

use std::path::{Path, PathBuf};

/// Side of the square network input of both models.
pub const INPUT_SIZE: usize = 256;

/// File name of the selfie segmentation model under `models/`.
pub const SELFIE_MODEL_FILE: &str = "selfie_segmentation.onnx";
/// File name of the BlazePose GHUM (full) landmark model under `models/`.
pub const POSE_MODEL_FILE: &str = "pose_landmark_full.onnx";
/// Environment variable naming a folder that holds the model files (checked first).
pub const MODELS_DIR_ENV: &str = "FITSTATION_MODELS";

/// Number of body keypoints of BlazePose (the network outputs 39; the last 6 are its
/// auxiliary points for the next frame's crop, kept in [`PersonOutput::aux`]).
pub const POSE_KEYPOINTS: usize = 33;
/// Auxiliary points of the pose network (crop centre and scale hints).
pub const POSE_AUX_POINTS: usize = 6;

/// BlazePose keypoint indices (the person's own left and right).
pub mod kp {
    pub const NOSE: usize = 0;
    pub const LEFT_EYE: usize = 2;
    pub const RIGHT_EYE: usize = 5;
    pub const LEFT_EAR: usize = 7;
    pub const RIGHT_EAR: usize = 8;
    pub const LEFT_SHOULDER: usize = 11;
    pub const RIGHT_SHOULDER: usize = 12;
    pub const LEFT_ELBOW: usize = 13;
    pub const RIGHT_ELBOW: usize = 14;
    pub const LEFT_WRIST: usize = 15;
    pub const RIGHT_WRIST: usize = 16;
    pub const LEFT_HIP: usize = 23;
    pub const RIGHT_HIP: usize = 24;
    pub const LEFT_KNEE: usize = 25;
    pub const RIGHT_KNEE: usize = 26;
    pub const LEFT_ANKLE: usize = 27;
    pub const RIGHT_ANKLE: usize = 28;
    pub const LEFT_HEEL: usize = 29;
    pub const RIGHT_HEEL: usize = 30;
    pub const LEFT_FOOT_INDEX: usize = 31;
    pub const RIGHT_FOOT_INDEX: usize = 32;

    /// Names of the 33 keypoints, by index.
    pub const NAMES: [&str; super::POSE_KEYPOINTS] = [
        "nose",
        "left_eye_inner",
        "left_eye",
        "left_eye_outer",
        "right_eye_inner",
        "right_eye",
        "right_eye_outer",
        "left_ear",
        "right_ear",
        "mouth_left",
        "mouth_right",
        "left_shoulder",
        "right_shoulder",
        "left_elbow",
        "right_elbow",
        "left_wrist",
        "right_wrist",
        "left_pinky",
        "right_pinky",
        "left_index",
        "right_index",
        "left_thumb",
        "right_thumb",
        "left_hip",
        "right_hip",
        "left_knee",
        "right_knee",
        "left_ankle",
        "right_ankle",
        "left_heel",
        "right_heel",
        "left_foot_index",
        "right_foot_index",
    ];
}

/// Errors of the person models.
#[derive(Debug, thiserror::Error)]
pub enum PersonError {
    #[error(
        "person model file {file} not found; looked in: {tried}. The models are committed \
         under models/ at the top of the repository (set {MODELS_DIR_ENV} to another folder)"
    )]
    ModelMissing { file: String, tried: String },
    #[error("person model {path}: {msg}")]
    Load { path: PathBuf, msg: String },
    #[error("person model: frame buffer holds {got} bytes, {width}x{height} RGB needs {need}")]
    FrameSize {
        width: usize,
        height: usize,
        got: usize,
        need: usize,
    },
    #[error("person model: empty region of interest ({0:?})")]
    EmptyRoi(Roi),
    #[error("person model inference: {0}")]
    Inference(String),
}

/// A borrowed RGB frame (interleaved, row-major, 3 bytes a pixel).
#[derive(Debug, Clone, Copy)]
pub struct FrameRef<'a> {
    pub rgb: &'a [u8],
    pub width: usize,
    pub height: usize,
}

impl<'a> FrameRef<'a> {
    /// Checks the buffer's size.
    ///
    /// # Errors
    /// [`PersonError::FrameSize`] when `rgb` is not `width * height * 3` bytes.
    pub fn new(rgb: &'a [u8], width: usize, height: usize) -> Result<Self, PersonError> {
        let need = width * height * 3;
        if rgb.len() != need || width == 0 || height == 0 {
            return Err(PersonError::FrameSize {
                width,
                height,
                got: rgb.len(),
                need,
            });
        }
        Ok(FrameRef { rgb, width, height })
    }

    /// A view of an `image` RGB frame.
    pub fn from_image(img: &'a image::RgbImage) -> Self {
        FrameRef {
            rgb: img.as_raw(),
            width: img.width() as usize,
            height: img.height() as usize,
        }
    }
}

/// The frame rectangle fed to the network (continuous pixel coordinates; may reach
/// outside the frame, where the input is black).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Roi {
    pub x0: f32,
    pub y0: f32,
    pub width: f32,
    pub height: f32,
}

impl Roi {
    /// The whole frame, stretched to the square input (MediaPipe's selfie segmentation).
    pub fn full_frame(width: usize, height: usize) -> Roi {
        Roi {
            x0: 0.0,
            y0: 0.0,
            width: width as f32,
            height: height as f32,
        }
    }

    /// The square centred on a box (`x0, y0, x1, y1`, continuous pixels) whose side is
    /// `scale` times the box's longer side: the aspect ratio is kept (MediaPipe's pose
    /// crop: the person's box enlarged by 1.25).
    pub fn square_around(x0: f32, y0: f32, x1: f32, y1: f32, scale: f32) -> Roi {
        let side = (x1 - x0).max(y1 - y0) * scale;
        let cx = 0.5 * (x0 + x1);
        let cy = 0.5 * (y0 + y1);
        Roi {
            x0: cx - 0.5 * side,
            y0: cy - 0.5 * side,
            width: side,
            height: side,
        }
    }

    /// The square around a set of points (e.g. the previous frame's keypoints), enlarged
    /// by `scale`; `None` for no point.
    pub fn square_around_points(
        points: impl IntoIterator<Item = (f32, f32)>,
        scale: f32,
    ) -> Option<Roi> {
        let mut b = [
            f32::INFINITY,
            f32::INFINITY,
            f32::NEG_INFINITY,
            f32::NEG_INFINITY,
        ];
        for (x, y) in points {
            b = [b[0].min(x), b[1].min(y), b[2].max(x), b[3].max(y)];
        }
        (b[0] <= b[2]).then(|| Roi::square_around(b[0], b[1], b[2], b[3], scale))
    }

    fn is_valid(&self) -> bool {
        self.width.is_finite()
            && self.height.is_finite()
            && self.x0.is_finite()
            && self.y0.is_finite()
            && self.width >= 1.0
            && self.height >= 1.0
    }

    /// Frame point of a network-input point (continuous coordinates of the 256x256 input).
    pub fn to_frame(&self, u: f32, v: f32) -> (f32, f32) {
        (
            self.x0 + u * self.width / INPUT_SIZE as f32,
            self.y0 + v * self.height / INPUT_SIZE as f32,
        )
    }

    /// Network-input point of a frame point.
    pub fn to_input(&self, x: f32, y: f32) -> (f32, f32) {
        (
            (x - self.x0) * INPUT_SIZE as f32 / self.width,
            (y - self.y0) * INPUT_SIZE as f32 / self.height,
        )
    }
}

/// A person probability map at the network's resolution with the ROI it covers.
#[derive(Debug, Clone)]
pub struct ProbMask {
    /// `INPUT_SIZE * INPUT_SIZE` probabilities in [0, 1], row-major.
    pub prob: Vec<f32>,
    /// The frame rectangle the map covers.
    pub roi: Roi,
}

impl ProbMask {
    fn new() -> Self {
        ProbMask {
            prob: vec![0.0; INPUT_SIZE * INPUT_SIZE],
            roi: Roi::full_frame(1, 1),
        }
    }

    /// Probability at a frame point (bilinear between the map's cell centres); 0 outside
    /// the ROI.
    pub fn at(&self, x: f32, y: f32) -> f32 {
        let (u, v) = self.roi.to_input(x, y);
        let n = INPUT_SIZE as f32;
        if !(0.0..n).contains(&u) || !(0.0..n).contains(&v) {
            return 0.0;
        }
        let (fu, fv) = ((u - 0.5).clamp(0.0, n - 1.0), (v - 0.5).clamp(0.0, n - 1.0));
        let (iu, iv) = (fu as usize, fv as usize);
        let (iu1, iv1) = ((iu + 1).min(INPUT_SIZE - 1), (iv + 1).min(INPUT_SIZE - 1));
        let (au, av) = (fu - iu as f32, fv - iv as f32);
        let p = |i: usize, j: usize| self.prob[j * INPUT_SIZE + i];
        let top = p(iu, iv) * (1.0 - au) + p(iu1, iv) * au;
        let bot = p(iu, iv1) * (1.0 - au) + p(iu1, iv1) * au;
        top * (1.0 - av) + bot * av
    }

    /// Renders the probability at every pixel centre of a `width x height` frame into `out`
    /// (resized to `width * height`; no allocation once it has that capacity).
    pub fn write_frame(&self, width: usize, height: usize, out: &mut Vec<f32>) {
        out.clear();
        out.resize(width * height, 0.0);
        for j in 0..height {
            let row = &mut out[j * width..(j + 1) * width];
            for (i, o) in row.iter_mut().enumerate() {
                *o = self.at(i as f32 + 0.5, j as f32 + 0.5);
            }
        }
    }
}

/// One body keypoint in frame pixels.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Keypoint {
    pub x: f32,
    pub y: f32,
    /// Depth relative to the hips, in the same scale as x (network input pixels scaled to
    /// the frame), smaller = nearer the camera.
    pub z: f32,
    /// Probability that the point is visible (not occluded), sigmoid of the logit.
    pub visibility: f32,
    /// Probability that the point is inside the crop, sigmoid of the logit.
    pub presence: f32,
}

/// What a person model returns for one frame.
#[derive(Debug, Clone)]
pub struct PersonOutput {
    /// Person probability.
    pub mask: ProbMask,
    /// The 33 BlazePose keypoints (empty for a segmentation-only model).
    pub keypoints: Vec<Keypoint>,
    /// The pose network's 6 auxiliary points (empty for a segmentation-only model).
    pub aux: Vec<Keypoint>,
    /// The pose network's probability that a person is in the crop (`None` for a
    /// segmentation-only model).
    pub presence: Option<f32>,
}

impl PersonOutput {
    pub fn new() -> Self {
        PersonOutput {
            mask: ProbMask::new(),
            keypoints: Vec::with_capacity(POSE_KEYPOINTS),
            aux: Vec::with_capacity(POSE_AUX_POINTS),
            presence: None,
        }
    }
}

impl Default for PersonOutput {
    fn default() -> Self {
        Self::new()
    }
}

/// A learned person model: one frame region in, person probability (and keypoints) out.
pub trait PersonModel {
    /// A short name for logs and reports.
    fn name(&self) -> &'static str;

    /// Runs the network on `roi` of `frame` and writes `out` (mask, keypoints in frame
    /// pixels). The plan is built at load time; `out`'s buffers are reused.
    ///
    /// # Errors
    /// [`PersonError::EmptyRoi`] for a degenerate ROI, [`PersonError::Inference`] when the
    /// network fails.
    fn infer(
        &mut self,
        frame: FrameRef<'_>,
        roi: Roi,
        out: &mut PersonOutput,
    ) -> Result<(), PersonError>;
}

/// Folders searched for a model file, in order: `$FITSTATION_MODELS`, `models/` under the
/// current directory, `models/` beside the executable and up to three of its parents
/// (`target/release/` of a checkout), and the crate's own `models/` at build time.
pub fn model_search_dirs() -> Vec<PathBuf> {
    let mut dirs = Vec::new();
    if let Some(d) = std::env::var_os(MODELS_DIR_ENV) {
        dirs.push(PathBuf::from(d));
    }
    if let Ok(cwd) = std::env::current_dir() {
        dirs.push(cwd.join("models"));
    }
    if let Ok(exe) = std::env::current_exe() {
        let mut dir = exe.parent().map(Path::to_path_buf);
        for _ in 0..4 {
            let Some(d) = dir else { break };
            dirs.push(d.join("models"));
            dir = d.parent().map(Path::to_path_buf);
        }
    }
    dirs.push(Path::new(env!("CARGO_MANIFEST_DIR")).join("models"));
    dirs
}

/// The path of a model file (`SELFIE_MODEL_FILE`, `POSE_MODEL_FILE`) in the first folder of
/// [`model_search_dirs`] that holds it.
///
/// # Errors
/// [`PersonError::ModelMissing`] listing the folders tried.
pub fn find_model(file: &str) -> Result<PathBuf, PersonError> {
    let dirs = model_search_dirs();
    for d in &dirs {
        let p = d.join(file);
        if p.is_file() {
            return Ok(p);
        }
    }
    Err(PersonError::ModelMissing {
        file: file.to_string(),
        tried: dirs
            .iter()
            .map(|d| d.display().to_string())
            .collect::<Vec<_>>()
            .join(", "),
    })
}

pub(crate) fn sigmoid(x: f32) -> f32 {
    1.0 / (1.0 + (-x).exp())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn roi_round_trip_and_square() {
        let r = Roi::square_around(100.0, 50.0, 200.0, 450.0, 1.25);
        assert_eq!(r.width, 500.0);
        assert_eq!(r.height, 500.0);
        assert_eq!(r.x0, 150.0 - 250.0);
        let (u, v) = r.to_input(123.0, 321.0);
        let (x, y) = r.to_frame(u, v);
        assert!((x - 123.0).abs() < 1e-3 && (y - 321.0).abs() < 1e-3);
        assert!(Roi::square_around_points(std::iter::empty(), 1.0).is_none());
    }

    #[test]
    fn prob_mask_sampling_follows_the_roi() {
        let mut m = ProbMask::new();
        // right half of the map is person
        for j in 0..INPUT_SIZE {
            for i in INPUT_SIZE / 2..INPUT_SIZE {
                m.prob[j * INPUT_SIZE + i] = 1.0;
            }
        }
        m.roi = Roi {
            x0: 100.0,
            y0: 0.0,
            width: 512.0,
            height: 256.0,
        };
        assert_eq!(m.at(50.0, 10.0), 0.0); // left of the ROI
        assert_eq!(m.at(150.0, 10.0), 0.0); // left half
        assert_eq!(m.at(500.0, 10.0), 1.0); // right half
        assert_eq!(m.at(700.0, 10.0), 0.0); // right of the ROI
        let mut out = Vec::new();
        m.write_frame(640, 8, &mut out);
        assert_eq!(out.len(), 640 * 8);
        assert_eq!(out[3 * 640 + 600], 1.0);
        assert_eq!(out[3 * 640 + 200], 0.0);
    }

    #[test]
    fn a_missing_model_names_the_folders_tried() {
        let e = find_model("no_such_model.onnx").expect_err("no such file");
        let msg = e.to_string();
        assert!(
            msg.contains("no_such_model.onnx") && msg.contains(MODELS_DIR_ENV),
            "{msg}"
        );
        assert!(msg.contains(env!("CARGO_MANIFEST_DIR")), "{msg}");
        assert!(find_model(POSE_MODEL_FILE).is_ok() && find_model(SELFIE_MODEL_FILE).is_ok());
    }

    #[test]
    fn frame_ref_checks_size() {
        assert!(FrameRef::new(&[0; 12], 2, 2).is_ok());
        assert!(matches!(
            FrameRef::new(&[0; 11], 2, 2),
            Err(PersonError::FrameSize { need: 12, .. })
        ));
    }
}
