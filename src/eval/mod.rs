//! Evaluation of fits against synthetic ground truth (`fitstation eval`).
//!
//! A fit result (the `avatar.obj` and `report.json` of formats.md "What a fit writes")
//! is compared with the truth folder of its recording (`<recording>.truth/`, written by
//! [`crate::synth`]): per measurement the signed error (fitted - true), the surface
//! distance from the fitted vertices to the true surface, mask IoU when the result holds
//! masks, landmark errors when the report holds landmarks, and the stage timings the
//! report carries. [`evaluate`] scores one result; [`EvalTable`] aggregates rows: per
//! measurement MAE, bias and worst error, and beside them the worst single girth error
//! of the whole set ([`EvalTable::worst_girth`]), in the text table, the HTML report
//! and the JSON. The true measurements are the truth's, computed by [`crate::measure`]
//! after `shared/spec/measurements.md`; a truth folder written before the spec's
//! rules holds values measured the old way (regenerate it with `fitstation synth`).
//!
//! # Conventions
//! - Meshes in metres in the station frame; errors and distances in millimetres;
//!   girth profiles are convex hull perimeters of horizontal sections (formats.md).
//! - `report.json` landmarks, when present: `"landmarks": {"name": [x, y, z]}` in
//!   metres, station frame (objects `{"x":..,"y":..,"z":..}` are accepted too).
//! - Result masks, when present: `<result>/masks/{front,side}/NNNNNN.png` (nonzero =
//!   body), the same layout as the truth.

mod command;
pub mod distance;
pub mod html;
mod table;
#[cfg(test)]
mod tests;

pub use command::{
    parse_set, result_dir_for, run, run_with, sets_side_by_side, EvalArgs, EvalSet, FitSource,
};
pub use table::{EvalTable, MeasurementSummary, WorstGirth};

use crate::mesh::io::read_obj;
use crate::mesh::section::{hull_perimeter, slice, Plane};
use crate::mesh::TriMesh;
use crate::synth::{load_truth, Truth};
use distance::{surface_distance, SurfaceDistance};
use serde::Serialize;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// Heights sampled for the girth profiles.
pub const PROFILE_SAMPLES: usize = 80;

/// Errors of the evaluation.
#[derive(Debug, thiserror::Error)]
pub enum EvalError {
    #[error("{path}: {source}")]
    Io {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("{0}")]
    Mesh(#[from] crate::mesh::io::MeshIoError),
    #[error("{0}")]
    Truth(#[from] crate::synth::SynthError),
    #[error("{path}: {msg}")]
    Invalid { path: PathBuf, msg: String },
}

/// A fit to be scored: the avatar and its report (formats.md "What a fit writes").
#[derive(Debug, Clone)]
pub struct FitResult {
    pub avatar: TriMesh,
    pub report_json: serde_json::Value,
    /// Folder holding `masks/{front,side}/NNNNNN.png`, if the fit wrote masks.
    pub masks_dir: Option<PathBuf>,
}

impl FitResult {
    /// A fit held in memory (e.g. from `replay`), without masks.
    pub fn new(avatar: TriMesh, report_json: serde_json::Value) -> FitResult {
        FitResult {
            avatar,
            report_json,
            masks_dir: None,
        }
    }

    /// Loads `dir/avatar.obj` and `dir/report.json`.
    pub fn load(dir: &Path) -> Result<FitResult, EvalError> {
        let avatar = read_obj(&dir.join("avatar.obj"), None)?;
        let p = dir.join("report.json");
        let text = std::fs::read_to_string(&p).map_err(|source| EvalError::Io {
            path: p.clone(),
            source,
        })?;
        let report_json = serde_json::from_str(&text).map_err(|e| EvalError::Invalid {
            path: p,
            msg: e.to_string(),
        })?;
        let masks = dir.join("masks");
        Ok(FitResult {
            avatar,
            report_json,
            masks_dir: masks.is_dir().then_some(masks),
        })
    }
}

/// One measurement compared.
#[derive(Debug, Clone, Serialize)]
pub struct MeasurementCompare {
    pub name: String,
    pub true_mm: f64,
    /// None when the report lacks it.
    pub fitted_mm: Option<f64>,
    /// fitted - true.
    pub error_mm: Option<f64>,
    /// The report's `uncertainty_mm` of this measurement (its `±`), when given.
    pub pm_mm: Option<f64>,
}

/// Median and 95th percentile of a stage's time, milliseconds.
#[derive(Debug, Clone, Copy, Serialize)]
pub struct StageTiming {
    pub median: f64,
    pub p95: f64,
}

/// A girth profile sample: height and the largest section's hull perimeter of the
/// true and fitted bodies (None where a body has no section).
#[derive(Debug, Clone, Copy, Serialize)]
pub struct ProfileSample {
    pub height_m: f64,
    pub true_mm: Option<f64>,
    pub fitted_mm: Option<f64>,
}

/// The score of one fit against its truth.
#[derive(Debug, Clone, Serialize)]
pub struct EvalRow {
    pub subject: String,
    pub measurements: Vec<MeasurementCompare>,
    pub surface: Option<SurfaceDistance>,
    /// Mean mask IoU per view over the frames both hold.
    pub mask_iou: BTreeMap<String, f64>,
    /// The report's `landmarks` (the silhouettes', smoothed over the fitted frames) against the
    /// truth's.
    pub landmarks: LandmarkErrors,
    /// The report's `body_landmarks` (the fitted avatar's own) against the truth's.
    pub body_landmarks: LandmarkErrors,
    pub timings_ms: BTreeMap<String, StageTiming>,
    pub profile: Vec<ProfileSample>,
    /// Largest frame-to-frame change of each shown measurement after settling, mm
    /// (report.json `settled_step_mm`, when present).
    pub settled_step_mm: BTreeMap<String, f64>,
    /// The report's frame counts (`frames`), when present: frame pairs with a subject
    /// and those fitted; the others were refused (a verdict, no landmarks, a failed fit).
    pub frames: Option<FrameTally>,
    /// The turn on the mark the fit read (report.json `fit.turn_deg`) against the truth's.
    pub turn: TurnCompare,
}

/// The shopper's turn on the mark, degrees (positive: the front toward +X, the side
/// camera): the truth's (its placement's and its stance's) and the fit's reading.
#[derive(Debug, Clone, Copy, Serialize, PartialEq)]
pub struct TurnCompare {
    pub true_deg: f64,
    /// None when the fit read no turn (or the report does not say).
    pub read_deg: Option<f64>,
}

/// Frame pairs with a subject and fitted, from a report's `frames`.
#[derive(Debug, Clone, Copy, Serialize, PartialEq, Eq)]
pub struct FrameTally {
    pub with_subject: u64,
    pub fitted: u64,
}

impl FrameTally {
    /// From report.json's `frames` object (None when it lacks the counts).
    fn from_report(report: &serde_json::Value) -> Option<FrameTally> {
        let f = report.get("frames")?;
        Some(FrameTally {
            with_subject: f.get("with_subject")?.as_u64()?,
            fitted: f.get("fitted")?.as_u64()?,
        })
    }

    /// Frame pairs with a subject that were not fitted.
    pub fn refused(&self) -> u64 {
        self.with_subject.saturating_sub(self.fitted)
    }
}

/// Scores `result` against the truth in `truth_dir`.
///
/// # Errors
/// Unreadable truth (truth.json, mesh.obj) or result masks.
pub fn evaluate(truth_dir: &Path, result: &FitResult) -> Result<EvalRow, EvalError> {
    let truth = load_truth(truth_dir)?;
    let true_mesh = read_obj(&truth_dir.join("mesh.obj"), None)?;
    let subject = truth_dir
        .file_name()
        .map(|n| {
            n.to_string_lossy()
                .trim_end_matches(crate::synth::TRUTH_SUFFIX)
                .to_string()
        })
        .unwrap_or_default();
    let reported_key = |key: &str, name: &str| {
        result
            .report_json
            .get(key)
            .and_then(|m| m.get(name))
            .and_then(|v| v.as_f64())
    };
    let measurements = truth
        .measurements_mm
        .iter()
        .map(|(name, &t)| {
            let f = reported_key("measurements_mm", name);
            MeasurementCompare {
                name: name.clone(),
                true_mm: t,
                fitted_mm: f,
                error_mm: f.map(|f| f - t),
                pm_mm: reported_key("uncertainty_mm", name),
            }
        })
        .collect();
    let surface = surface_distance(&result.avatar.positions, &true_mesh);
    let mask_iou = match &result.masks_dir {
        Some(d) => mask_iou(&truth, truth_dir, d)?,
        None => BTreeMap::new(),
    };
    let landmarks = landmark_errors(&truth, &result.report_json, "landmarks");
    let body_landmarks = landmark_errors(&truth, &result.report_json, "body_landmarks");
    let timings_ms = timings(&result.report_json);
    let profile = girth_profile(&true_mesh, &result.avatar);
    let settled_step_mm = result
        .report_json
        .get("settled_step_mm")
        .and_then(|m| m.as_object())
        .map(|m| {
            m.iter()
                .filter_map(|(k, v)| v.as_f64().map(|v| (k.clone(), v)))
                .collect()
        })
        .unwrap_or_default();
    let turn = TurnCompare {
        true_deg: truth.placement.yaw_deg + truth.stance.as_ref().map_or(0.0, |s| s.yaw_deg),
        read_deg: result
            .report_json
            .get("fit")
            .and_then(|f| f.get("turn_deg"))
            .and_then(|v| v.as_f64()),
    };
    Ok(EvalRow {
        turn,
        frames: FrameTally::from_report(&result.report_json),
        settled_step_mm,
        subject,
        measurements,
        surface,
        mask_iou,
        landmarks,
        body_landmarks,
        timings_ms,
        profile,
    })
}

fn mask_iou(
    truth: &Truth,
    truth_dir: &Path,
    result_masks: &Path,
) -> Result<BTreeMap<String, f64>, EvalError> {
    let mut out = BTreeMap::new();
    for view in ["front", "side"] {
        let (mut sum, mut n) = (0.0, 0usize);
        for f in truth.per_frame.iter().filter(|f| f.subject) {
            let name = format!("{:06}.png", f.index);
            let rp = result_masks.join(view).join(&name);
            if !rp.is_file() {
                continue;
            }
            let tp = truth_dir.join("masks").join(view).join(&name);
            let load = |p: &Path| {
                image::open(p)
                    .map(|i| i.to_luma8())
                    .map_err(|e| EvalError::Invalid {
                        path: p.to_path_buf(),
                        msg: e.to_string(),
                    })
            };
            let (t, r) = (load(&tp)?, load(&rp)?);
            if t.dimensions() != r.dimensions() {
                return Err(EvalError::Invalid {
                    path: rp,
                    msg: "mask size differs from the frame size".into(),
                });
            }
            let (mut inter, mut uni) = (0usize, 0usize);
            for (a, b) in t.as_raw().iter().zip(r.as_raw()) {
                let (a, b) = (*a > 127, *b > 127);
                inter += (a && b) as usize;
                uni += (a || b) as usize;
            }
            if uni > 0 {
                sum += inter as f64 / uni as f64;
                n += 1;
            }
        }
        if n > 0 {
            out.insert(view.to_string(), sum / n as f64);
        }
    }
    Ok(out)
}

fn json_point(v: &serde_json::Value) -> Option<[f64; 3]> {
    if let Some(a) = v.as_array() {
        if a.len() == 3 {
            return Some([a[0].as_f64()?, a[1].as_f64()?, a[2].as_f64()?]);
        }
        return None;
    }
    let o = v.as_object()?;
    Some([
        o.get("x")?.as_f64()?,
        o.get("y")?.as_f64()?,
        o.get("z")?.as_f64()?,
    ])
}

/// The station's name of a truth landmark: the truth says `left_armpit`, the station
/// `armpit_left` (`LandmarkName`'s order: what, then side).
fn station_landmark_name(truth_name: &str) -> String {
    match truth_name.split_once('_') {
        Some((side @ ("left" | "right"), what)) => format!("{what}_{side}"),
        _ => truth_name.to_string(),
    }
}

/// Which landmarks of a report: the silhouettes' (`landmarks`) or the fitted body's own
/// (`body_landmarks`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LandmarkSource {
    Silhouettes,
    FittedBody,
}

impl LandmarkSource {
    pub const ALL: [LandmarkSource; 2] = [LandmarkSource::Silhouettes, LandmarkSource::FittedBody];

    /// What the tables call it (after "landmark, " / "Landmarks: ").
    pub fn title(self) -> &'static str {
        match self {
            LandmarkSource::Silhouettes => "silhouettes, smoothed over frames",
            LandmarkSource::FittedBody => "the fitted body's own",
        }
    }
}

/// One landmark's errors over a set (see [`EvalTable::landmark_summary`]).
#[derive(Debug, Clone, Serialize)]
pub struct LandmarkSummary {
    pub name: String,
    pub subjects: usize,
    pub mean_distance_mm: f64,
    pub mean_abs_height_mm: f64,
    pub worst_abs_height_mm: f64,
}

/// Landmark errors of one source of a report against the truth, millimetres, keyed by
/// the truth's names.
#[derive(Debug, Clone, Default, Serialize)]
pub struct LandmarkErrors {
    /// 3-D distance.
    pub distance_mm: BTreeMap<String, f64>,
    /// Signed height error (reported - true).
    pub height_mm: BTreeMap<String, f64>,
}

fn landmark_errors(truth: &Truth, report: &serde_json::Value, key: &str) -> LandmarkErrors {
    let mut out = LandmarkErrors::default();
    let Some(lm) = report.get(key).and_then(|l| l.as_object()) else {
        return out;
    };
    for (name, t) in &truth.landmarks {
        let found = lm
            .get(name)
            .or_else(|| lm.get(&station_landmark_name(name)));
        if let Some(p) = found.and_then(json_point) {
            let d = ((p[0] - t[0]).powi(2) + (p[1] - t[1]).powi(2) + (p[2] - t[2]).powi(2)).sqrt();
            out.distance_mm.insert(name.clone(), d * 1000.0);
            out.height_mm.insert(name.clone(), (p[1] - t[1]) * 1000.0);
        }
    }
    out
}

fn timings(report: &serde_json::Value) -> BTreeMap<String, StageTiming> {
    let mut out = BTreeMap::new();
    let Some(t) = report.get("timings_ms").and_then(|t| t.as_object()) else {
        return out;
    };
    for (stage, v) in t {
        let median = v.get("median").and_then(|x| x.as_f64());
        let p95 = v.get("p95").and_then(|x| x.as_f64());
        if let (Some(median), Some(p95)) = (median, p95) {
            out.insert(stage.clone(), StageTiming { median, p95 });
        } else if let Some(x) = v.as_f64() {
            out.insert(stage.clone(), StageTiming { median: x, p95: x });
        }
    }
    out
}

/// Area of a loop's bounding box (loops left open by small holes still count).
fn box_area(l: &crate::mesh::section::SectionLoop) -> f64 {
    crate::synth::subject::loop_box_area(l)
}

/// Largest-section hull perimeter against height for both bodies, from just above the
/// soles to just below the top of the true body.
pub fn girth_profile(truth: &TriMesh, fitted: &TriMesh) -> Vec<ProfileSample> {
    let Some(b) = truth.bounds() else {
        return Vec::new();
    };
    let girth = |m: &TriMesh, y: f64| -> Option<f64> {
        slice(m, &Plane::horizontal(y))
            .into_iter()
            .filter(|l| l.points.len() > 2)
            .max_by(|a, b| box_area(a).total_cmp(&box_area(b)))
            .map(|l| hull_perimeter(&l.points) * 1000.0)
    };
    (0..PROFILE_SAMPLES)
        .map(|i| {
            let y = b.min.y + b.size().y * (0.02 + 0.94 * i as f64 / (PROFILE_SAMPLES - 1) as f64);
            ProfileSample {
                height_m: y,
                true_mm: girth(truth, y),
                fitted_mm: girth(fitted, y),
            }
        })
        .collect()
}
