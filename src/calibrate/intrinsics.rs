//! Intrinsic calibration of one camera from several board views: detection over a
//! folder, view screening (not found, blurred, duplicate), Zhang's closed-form start,
//! Levenberg-Marquardt refinement, and outlier views flagged and dropped.
//!
//! Units: pixels; board in metres. The RMS reprojection error is OpenCV's:
//! `sqrt(sum |projected - detected|² / number of corners)`.

use super::board::{BoardSpec, Target};
use super::bundle::{refine, BundleResult, IntrinsicsMode, ViewObservations, N_INTRINSIC};
use super::corners::{median, CornerDetector, DetectError, Detection};
use super::zhang::{closed_form, homography, pose_from_homography, ClosedForm, StartMethod};
use super::{CalibError, Progress, MAX_BLUR_SIGMA_PX};
use crate::camera::{Intrinsics, Rigid};
use glam::{DVec2, DVec3};
use std::path::{Path, PathBuf};

/// Fewest usable views for a calibration.
pub const MIN_VIEWS: usize = 4;
/// Views recommended to operators.
pub const RECOMMENDED_VIEWS: usize = 10;
/// Board orientations must span at least this angle (largest angle between two views'
/// board normals), degrees.
pub const MIN_ORIENTATION_SPREAD_DEG: f64 = 10.0;
/// A view is an outlier when its RMS exceeds this multiple of the median view RMS...
pub const OUTLIER_FACTOR: f64 = 3.0;
/// ...and this absolute floor, pixels.
pub const OUTLIER_FLOOR_PX: f64 = 0.5;
/// Rounds of outlier removal.
pub const OUTLIER_ROUNDS: usize = 3;
/// A calibration worse than this overall RMS is refused, pixels.
pub const MAX_ACCEPTED_RMS_PX: f64 = 2.0;
/// Above this RMS the result is kept with a warning, pixels.
pub const WARN_RMS_PX: f64 = 0.5;
/// Two views whose corners differ by less than this on average are duplicates, pixels.
pub const DUPLICATE_MEAN_PX: f64 = 1.5;
/// Coverage grid (cells per side) and the fraction of cells the corners should reach.
pub const COVERAGE_CELLS: usize = 4;
pub const MIN_COVERAGE: f64 = 0.5;

/// One input image and its detection.
#[derive(Debug, Clone, PartialEq)]
pub struct ViewInput {
    pub name: String,
    pub detection: Result<Detection, DetectError>,
}

/// Images of one camera with their detections.
#[derive(Debug, Clone, PartialEq)]
pub struct CameraViews {
    pub camera: String,
    pub width: u32,
    pub height: u32,
    pub views: Vec<ViewInput>,
}

/// What became of a view.
#[derive(Debug, Clone, PartialEq)]
pub enum ViewOutcome {
    Used { rms_px: f64 },
    NotFound(String),
    Blurred { sigma_px: f64 },
    Duplicate { of: String },
    Outlier { rms_px: f64 },
}

/// A view's line in the calibration report.
#[derive(Debug, Clone, PartialEq)]
pub struct ViewReport {
    pub name: String,
    pub outcome: ViewOutcome,
}

/// Result of an intrinsic calibration.
#[derive(Debug, Clone, PartialEq)]
pub struct IntrinsicsCalibration {
    pub camera: String,
    pub intrinsics: Intrinsics,
    pub rms_px: f64,
    /// One standard deviation of fx fy cx cy k1 k2 p1 p2 k3.
    pub std_dev: [f64; N_INTRINSIC],
    pub views: Vec<ViewReport>,
    pub used_views: usize,
    /// `camera_from_board` of the used views, in the order of `views` (used ones only).
    pub poses: Vec<Rigid>,
    pub start: StartMethod,
    pub orientation_spread_deg: f64,
    /// Fraction of the image (in a 4x4 grid) that the corners reached.
    pub coverage: f64,
    pub warnings: Vec<String>,
}

/// Lists the image files of a folder (png, jpg, jpeg), sorted by name.
pub fn image_files(dir: &Path, camera: &str) -> Result<Vec<PathBuf>, CalibError> {
    let rd = std::fs::read_dir(dir).map_err(|e| CalibError::Io {
        path: dir.to_path_buf(),
        msg: format!("{e}: pass the folder of {camera} board photos"),
    })?;
    let mut files: Vec<PathBuf> = rd
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| {
            p.extension()
                .and_then(|e| e.to_str())
                .is_some_and(|e| matches!(e.to_ascii_lowercase().as_str(), "png" | "jpg" | "jpeg"))
        })
        .collect();
    files.sort();
    if files.is_empty() {
        return Err(CalibError::NoImages {
            camera: camera.to_string(),
            dir: dir.to_path_buf(),
        });
    }
    Ok(files)
}

/// Reads an image as grey levels.
pub fn read_gray(path: &Path) -> Result<image::GrayImage, CalibError> {
    image::open(path)
        .map(|i| i.to_luma8())
        .map_err(|e| CalibError::ImageRead {
            path: path.to_path_buf(),
            msg: e.to_string(),
        })
}

/// Detects the board in every image of a folder.
///
/// # Errors
/// No images, unreadable images, or images of different sizes.
pub fn detect_views(
    dir: &Path,
    camera: &str,
    board: &BoardSpec,
    target: Target,
    progress: &mut dyn FnMut(&Progress),
) -> Result<CameraViews, CalibError> {
    let files = image_files(dir, camera)?;
    let mut detector = CornerDetector::for_target(target);
    let mut size: Option<(u32, u32, PathBuf)> = None;
    let mut views = Vec::with_capacity(files.len());
    for (k, path) in files.iter().enumerate() {
        let img = read_gray(path)?;
        match &size {
            None => size = Some((img.width(), img.height(), path.clone())),
            Some((w, h, first)) if (*w, *h) != (img.width(), img.height()) => {
                return Err(CalibError::MixedSizes {
                    camera: camera.to_string(),
                    first: format!("{w}x{h} in {}", first.display()),
                    other: format!("{}x{}", img.width(), img.height()),
                    path: path.clone(),
                })
            }
            _ => {}
        }
        let name = path
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        let detection = detector.detect(&img, board);
        let outcome = match &detection {
            Ok(d) => format!("board found (blur sigma {:.2} px)", d.blur_sigma_px),
            Err(e) => e.to_string(),
        };
        progress(&Progress::ViewSearched {
            camera: camera.to_string(),
            index: k,
            total: files.len(),
            name: name.clone(),
            outcome,
        });
        views.push(ViewInput { name, detection });
    }
    let (width, height, _) = size.ok_or_else(|| CalibError::NoImages {
        camera: camera.to_string(),
        dir: dir.to_path_buf(),
    })?;
    Ok(CameraViews {
        camera: camera.to_string(),
        width,
        height,
        views,
    })
}

/// Calibrates one camera's intrinsics from its detected views: screen the views, start
/// from Zhang's closed form, refine by Levenberg-Marquardt dropping outlier views, then
/// judge the result.
///
/// # Errors
/// Too few usable views, views too similar, a failed start, or an RMS above
/// [`MAX_ACCEPTED_RMS_PX`]; every message tells the operator what to do.
pub fn calibrate_intrinsics(
    input: &CameraViews,
    board: &BoardSpec,
    progress: &mut dyn FnMut(&Progress),
) -> Result<IntrinsicsCalibration, CalibError> {
    let camera = input.camera.clone();
    let object = board.object_points();
    let (mut reports, candidates) = screen_views(input, object.len());
    if candidates.len() < MIN_VIEWS {
        return Err(too_few_views(&camera, candidates.len(), &reports));
    }
    progress(&Progress::Stage(format!(
        "{camera}: closed-form start from {} views",
        candidates.len()
    )));
    let (start, poses) = closed_form_start(input, &object, &candidates)?;
    let start_intr = Intrinsics {
        width: input.width,
        height: input.height,
        fx: start.pinhole.fx,
        fy: start.pinhole.fy,
        cx: start.pinhole.cx,
        cy: start.pinhole.cy,
        dist: [0.0; 5],
    };

    let (result, active) = refine_without_outliers(
        &camera,
        &object,
        &candidates,
        start_intr,
        poses,
        &mut reports,
        progress,
    );
    if active.len() < MIN_VIEWS {
        return Err(too_few_views(&camera, active.len(), &reports));
    }
    // A NaN RMS (a diverged fit) is refused too.
    if result.rms_px.is_nan() || result.rms_px > MAX_ACCEPTED_RMS_PX {
        return Err(CalibError::PoorFit {
            camera,
            rms_px: result.rms_px,
            max_px: MAX_ACCEPTED_RMS_PX,
        });
    }
    let used_corners: Vec<&Vec<DVec2>> = active.iter().map(|&a| candidates[a].1).collect();
    let coverage = coverage(&used_corners, input.width, input.height);
    let warnings = intrinsics_warnings(active.len(), coverage, result.rms_px);
    let spread = orientation_spread_deg(&result.poses);
    Ok(IntrinsicsCalibration {
        camera,
        intrinsics: result.intrinsics,
        rms_px: result.rms_px,
        std_dev: result.std_dev,
        views: reports,
        used_views: active.len(),
        poses: result.poses,
        start: start.method,
        orientation_spread_deg: spread,
        coverage,
        warnings,
    })
}

/// A view kept for the calibration: its index in the input and its corners (pixels).
type Candidate<'a> = (usize, &'a Vec<DVec2>);

/// Screens the views: refuses those whose board was not found (or not whole, of
/// `corners` corners), blurred or duplicating an earlier view; returns a report per view
/// (the kept ones provisionally used) and the kept views.
fn screen_views(input: &CameraViews, corners: usize) -> (Vec<ViewReport>, Vec<Candidate<'_>>) {
    let mut reports: Vec<ViewReport> = Vec::with_capacity(input.views.len());
    let mut candidates: Vec<Candidate<'_>> = Vec::new();
    for (k, v) in input.views.iter().enumerate() {
        let outcome = match &v.detection {
            Err(e) => Some(match e.blurred() {
                Some(sigma_px) => ViewOutcome::Blurred { sigma_px },
                None => ViewOutcome::NotFound(e.to_string()),
            }),
            Ok(d) if d.corners.len() != corners => {
                Some(ViewOutcome::NotFound("wrong number of corners".into()))
            }
            Ok(d) if d.blur_sigma_px > MAX_BLUR_SIGMA_PX => Some(ViewOutcome::Blurred {
                sigma_px: d.blur_sigma_px,
            }),
            Ok(d) => {
                let dup = candidates
                    .iter()
                    .find(|(_, c)| mean_distance(c, &d.corners) < DUPLICATE_MEAN_PX);
                match dup {
                    Some((j, _)) => Some(ViewOutcome::Duplicate {
                        of: input.views[*j].name.clone(),
                    }),
                    None => {
                        candidates.push((k, &d.corners));
                        None
                    }
                }
            }
        };
        reports.push(ViewReport {
            name: v.name.clone(),
            outcome: outcome.unwrap_or(ViewOutcome::Used { rms_px: f64::NAN }),
        });
    }
    (reports, candidates)
}

/// The refusal for too few usable views, counting why the others were refused.
fn too_few_views(camera: &str, usable: usize, reports: &[ViewReport]) -> CalibError {
    let count = |f: &dyn Fn(&ViewOutcome) -> bool| reports.iter().filter(|r| f(&r.outcome)).count();
    let detail = format!(
        "{} images: board not found in {}, blurred {}, duplicates {}, outliers {}.",
        reports.len(),
        count(&|o| matches!(o, ViewOutcome::NotFound(_))),
        count(&|o| matches!(o, ViewOutcome::Blurred { .. })),
        count(&|o| matches!(o, ViewOutcome::Duplicate { .. })),
        count(&|o| matches!(o, ViewOutcome::Outlier { .. })),
    );
    CalibError::TooFewViews {
        camera: camera.to_string(),
        usable,
        needed: MIN_VIEWS,
        detail,
    }
}

/// Zhang's closed-form start from the views' homographies and the board's pose in each
/// view under it; refused when the views are too alike in orientation.
fn closed_form_start(
    input: &CameraViews,
    object: &[DVec3],
    candidates: &[Candidate<'_>],
) -> Result<(ClosedForm, Vec<Rigid>), CalibError> {
    let camera = input.camera.clone();
    let board_xy: Vec<DVec2> = object.iter().map(|p| p.truncate()).collect();
    let hs: Vec<_> = candidates
        .iter()
        .filter_map(|(_, c)| homography(&board_xy, c))
        .collect();
    if hs.len() != candidates.len() {
        return Err(CalibError::StartFailed { camera });
    }
    let Some(start) = closed_form(&hs, input.width, input.height) else {
        // Degenerate views: report their spread under a nominal lens.
        let f = input.width.max(input.height) as f64;
        let nominal = super::zhang::Pinhole {
            fx: f,
            fy: f,
            cx: 0.5 * input.width as f64,
            cy: 0.5 * input.height as f64,
        };
        let poses: Vec<Rigid> = hs
            .iter()
            .filter_map(|h| pose_from_homography(h, &nominal.k()))
            .collect();
        return Err(CalibError::TooSimilarViews {
            camera,
            spread_deg: orientation_spread_deg(&poses),
            needed_deg: MIN_ORIENTATION_SPREAD_DEG,
        });
    };
    let k = start.pinhole.k();
    let mut poses: Vec<Rigid> = Vec::with_capacity(hs.len());
    for h in &hs {
        poses.push(
            pose_from_homography(h, &k).ok_or_else(|| CalibError::StartFailed {
                camera: camera.clone(),
            })?,
        );
    }
    let spread = orientation_spread_deg(&poses);
    if spread < MIN_ORIENTATION_SPREAD_DEG {
        return Err(CalibError::TooSimilarViews {
            camera,
            spread_deg: spread,
            needed_deg: MIN_ORIENTATION_SPREAD_DEG,
        });
    }
    Ok((start, poses))
}

/// Levenberg-Marquardt from the start over the kept views, dropping outlier views (RMS
/// above [`OUTLIER_FACTOR`] times the median) and refining again; marks every view's
/// report used or outlier and returns the result with the views it used.
fn refine_without_outliers(
    camera: &str,
    object: &[DVec3],
    candidates: &[Candidate<'_>],
    start_intr: Intrinsics,
    poses: Vec<Rigid>,
    reports: &mut [ViewReport],
    progress: &mut dyn FnMut(&Progress),
) -> (BundleResult, Vec<usize>) {
    let mut active: Vec<usize> = (0..candidates.len()).collect();
    let mut current_start = start_intr;
    let mut current_poses = poses;
    let mut result: BundleResult;
    let mut round = 0;
    loop {
        progress(&Progress::Stage(format!(
            "{camera}: Levenberg-Marquardt over {} views",
            active.len()
        )));
        let views: Vec<ViewObservations> = active
            .iter()
            .map(|&a| ViewObservations {
                object: object.to_vec(),
                image: candidates[a].1.clone(),
            })
            .collect();
        result = refine(
            &current_start,
            &current_poses,
            &views,
            IntrinsicsMode::AllFree,
        );
        let mut per = result.per_view_rms_px.clone();
        let med = median(&mut per).unwrap_or(0.0);
        let limit = (OUTLIER_FACTOR * med).max(OUTLIER_FLOOR_PX);
        let outliers: Vec<usize> = (0..active.len())
            .filter(|&i| result.per_view_rms_px[i] > limit)
            .collect();
        round += 1;
        if outliers.is_empty()
            || round > OUTLIER_ROUNDS
            || active.len() - outliers.len() < MIN_VIEWS
        {
            break;
        }
        for &i in &outliers {
            let view_index = candidates[active[i]].0;
            reports[view_index].outcome = ViewOutcome::Outlier {
                rms_px: result.per_view_rms_px[i],
            };
        }
        let keep: Vec<usize> = (0..active.len())
            .filter(|i| !outliers.contains(i))
            .collect();
        current_start = result.intrinsics;
        current_poses = keep.iter().map(|&i| result.poses[i]).collect();
        active = keep.iter().map(|&i| active[i]).collect();
    }
    for (i, &a) in active.iter().enumerate() {
        reports[candidates[a].0].outcome = ViewOutcome::Used {
            rms_px: result.per_view_rms_px[i],
        };
    }
    (result, active)
}

/// Advice on a calibration that passed: few views, the board far from the image's
/// corners, or a high RMS.
fn intrinsics_warnings(used_views: usize, coverage: f64, rms_px: f64) -> Vec<String> {
    let mut warnings = Vec::new();
    if used_views < RECOMMENDED_VIEWS {
        warnings.push(format!(
            "only {} views used; {RECOMMENDED_VIEWS}-15 give a steadier result",
            used_views
        ));
    }
    if coverage < MIN_COVERAGE {
        warnings.push(format!("the board reached only {:.0}% of the image: add views with the board near the image corners and edges (lens distortion is measured there)", coverage * 100.0));
    }
    if rms_px > WARN_RMS_PX {
        warnings.push(format!(
            "RMS {:.2} px is high: check that the board is flat and the photos sharp",
            rms_px
        ));
    }
    warnings
}

/// A live frame must move the board's corners by this much (mean, pixels) from every
/// accepted view to count as a new view.
pub const LIVE_MIN_CHANGE_PX: f64 = 25.0;

/// What became of one live frame.
#[derive(Debug, Clone, PartialEq)]
pub enum FrameOutcome {
    Accepted,
    NotFound(DetectError),
    Blurred {
        sigma_px: f64,
    },
    /// Too close to an accepted view (named): move or tilt the board.
    TooSimilar {
        to: String,
    },
    WrongSize {
        width: u32,
        height: u32,
    },
}

/// Feedback for the station UI after each live frame.
#[derive(Debug, Clone, PartialEq)]
pub struct FrameFeedback {
    pub outcome: FrameOutcome,
    /// The board's corners in this frame (empty when not found), for an overlay.
    pub corners: Vec<DVec2>,
    pub accepted_views: usize,
    /// Fraction of the image reached by accepted views' corners (4x4 cells).
    pub coverage: f64,
    /// Enough views and coverage to calibrate well.
    pub ready: bool,
}

/// Collects live frames of one camera for the UI's calibration wizard; the same
/// screening and calibration as the folder route.
pub struct LensSession {
    camera: String,
    board: BoardSpec,
    width: u32,
    height: u32,
    detector: CornerDetector,
    views: Vec<ViewInput>,
}

impl LensSession {
    pub fn new(camera: &str, board: BoardSpec, width: u32, height: u32) -> Self {
        LensSession {
            camera: camera.to_string(),
            board,
            width,
            height,
            detector: CornerDetector::new(),
            views: Vec::new(),
        }
    }

    /// The same session for another target (circle grid).
    pub fn with_target(mut self, target: Target) -> Self {
        self.detector = CornerDetector::for_target(target);
        self
    }

    /// Searches one grey frame (convert colour frames with `image::imageops::grayscale`)
    /// and keeps it when it is a sharp, new view.
    pub fn add_frame(&mut self, name: &str, frame: &image::GrayImage) -> FrameFeedback {
        let (outcome, corners) = if (frame.width(), frame.height()) != (self.width, self.height) {
            (
                FrameOutcome::WrongSize {
                    width: frame.width(),
                    height: frame.height(),
                },
                Vec::new(),
            )
        } else {
            match self.detector.detect(frame, &self.board) {
                Err(e) => match e.blurred() {
                    Some(sigma_px) => (FrameOutcome::Blurred { sigma_px }, Vec::new()),
                    None => (FrameOutcome::NotFound(e), Vec::new()),
                },
                Ok(d) if d.blur_sigma_px > MAX_BLUR_SIGMA_PX => (
                    FrameOutcome::Blurred {
                        sigma_px: d.blur_sigma_px,
                    },
                    d.corners,
                ),
                Ok(d) => {
                    let similar = self.views.iter().find(|v| {
                        v.detection.as_ref().is_ok_and(|o| {
                            mean_distance(&o.corners, &d.corners) < LIVE_MIN_CHANGE_PX
                        })
                    });
                    match similar {
                        Some(v) => (FrameOutcome::TooSimilar { to: v.name.clone() }, d.corners),
                        None => {
                            let corners = d.corners.clone();
                            self.views.push(ViewInput {
                                name: name.to_string(),
                                detection: Ok(d),
                            });
                            (FrameOutcome::Accepted, corners)
                        }
                    }
                }
            }
        };
        let accepted: Vec<&Vec<DVec2>> = self
            .views
            .iter()
            .filter_map(|v| v.detection.as_ref().ok().map(|d| &d.corners))
            .collect();
        let coverage = coverage(&accepted, self.width, self.height);
        FrameFeedback {
            outcome,
            corners,
            accepted_views: accepted.len(),
            coverage,
            ready: accepted.len() >= RECOMMENDED_VIEWS && coverage >= MIN_COVERAGE,
        }
    }

    /// The accepted views.
    pub fn views(&self) -> CameraViews {
        CameraViews {
            camera: self.camera.clone(),
            width: self.width,
            height: self.height,
            views: self.views.clone(),
        }
    }

    /// Calibrates from the accepted views ([`calibrate_intrinsics`]).
    pub fn calibrate(
        &self,
        progress: &mut dyn FnMut(&Progress),
    ) -> Result<IntrinsicsCalibration, CalibError> {
        calibrate_intrinsics(&self.views(), &self.board, progress)
    }
}

fn mean_distance(a: &[DVec2], b: &[DVec2]) -> f64 {
    if a.len() != b.len() || a.is_empty() {
        return f64::INFINITY;
    }
    a.iter()
        .zip(b)
        .map(|(p, q)| (*p - *q).length())
        .sum::<f64>()
        / a.len() as f64
}

/// Largest angle between two views' board normals, degrees.
pub fn orientation_spread_deg(poses: &[Rigid]) -> f64 {
    let normals: Vec<DVec3> = poses.iter().map(|p| p.rotation * DVec3::Z).collect();
    let mut best = 0.0f64;
    for (i, a) in normals.iter().enumerate() {
        for b in &normals[i + 1..] {
            best = best.max(a.dot(*b).clamp(-1.0, 1.0).acos().to_degrees());
        }
    }
    best
}

fn coverage(views: &[&Vec<DVec2>], w: u32, h: u32) -> f64 {
    let mut cells = [[false; COVERAGE_CELLS]; COVERAGE_CELLS];
    for v in views {
        for p in v.iter() {
            let cx = ((p.x / w as f64) * COVERAGE_CELLS as f64).floor();
            let cy = ((p.y / h as f64) * COVERAGE_CELLS as f64).floor();
            if cx >= 0.0
                && cy >= 0.0
                && (cx as usize) < COVERAGE_CELLS
                && (cy as usize) < COVERAGE_CELLS
            {
                cells[cy as usize][cx as usize] = true;
            }
        }
    }
    cells.iter().flatten().filter(|c| **c).count() as f64 / (COVERAGE_CELLS * COVERAGE_CELLS) as f64
}

impl std::fmt::Display for IntrinsicsCalibration {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let i = &self.intrinsics;
        let s = &self.std_dev;
        writeln!(
            f,
            "{} camera: {}x{}, {} of {} views used, RMS {:.3} px",
            self.camera,
            i.width,
            i.height,
            self.used_views,
            self.views.len(),
            self.rms_px
        )?;
        writeln!(
            f,
            "  fx {:.2} ± {:.2}  fy {:.2} ± {:.2}  cx {:.2} ± {:.2}  cy {:.2} ± {:.2}",
            i.fx, s[0], i.fy, s[1], i.cx, s[2], i.cy, s[3]
        )?;
        writeln!(
            f,
            "  k1 {:.4} k2 {:.4} p1 {:.5} p2 {:.5} k3 {:.4}",
            i.dist[0], i.dist[1], i.dist[2], i.dist[3], i.dist[4]
        )?;
        writeln!(
            f,
            "  board orientations span {:.0} deg, image coverage {:.0}%",
            self.orientation_spread_deg,
            self.coverage * 100.0
        )?;
        for v in &self.views {
            let o = match &v.outcome {
                ViewOutcome::Used { rms_px } => format!("used, RMS {rms_px:.3} px"),
                ViewOutcome::NotFound(e) => format!("skipped: {e}"),
                ViewOutcome::Blurred { sigma_px } => format!("skipped: blurred (edge sigma {sigma_px:.1} px > {MAX_BLUR_SIGMA_PX}); hold the board still, add light"),
                ViewOutcome::Duplicate { of } => format!("skipped: same as {of}; move or tilt the board between photos"),
                ViewOutcome::Outlier { rms_px } => format!("dropped as outlier: RMS {rms_px:.2} px (board bent, moving, or mis-detected)"),
            };
            writeln!(f, "    {:<24} {o}", v.name)?;
        }
        for w in &self.warnings {
            writeln!(f, "  WARNING: {w}")?;
        }
        Ok(())
    }
}
