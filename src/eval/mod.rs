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

pub mod distance;
pub mod html;

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
    Ok(EvalRow {
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

/// Per-measurement aggregate over subjects, millimetres.
#[derive(Debug, Clone, Serialize)]
pub struct MeasurementSummary {
    pub name: String,
    pub subjects: usize,
    pub mean_abs_error_mm: f64,
    pub mean_bias_mm: f64,
    /// The error of largest magnitude (signed).
    pub worst_error_mm: f64,
    pub worst_subject: String,
    /// Of the subjects whose report gives this measurement's `±` (`uncertainty_mm`):
    /// how many, how many errors lie within it, and its median (mm).
    pub with_pm: usize,
    pub within_pm: usize,
    pub median_pm_mm: Option<f64>,
}

/// The single tape-girth error of largest magnitude in a set of fits: which girth
/// ([`crate::measure::GIRTH_KEYS`]; stature and the informational `hip_girth_max` are
/// not girths a tape reports), whose, and by how much.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct WorstGirth {
    pub name: String,
    pub subject: String,
    /// fitted - true, millimetres.
    pub error_mm: f64,
    pub true_mm: f64,
    pub fitted_mm: f64,
}

impl WorstGirth {
    /// One line for the text table and the HTML report.
    pub fn describe(&self) -> String {
        format!(
            "worst single girth error of the set: {:+.1} mm ({}, subject {}: fitted {:.1} mm, true {:.1} mm)",
            self.error_mm, self.name, self.subject, self.fitted_mm, self.true_mm
        )
    }
}

/// Rows and their summary.
#[derive(Debug, Clone, Serialize, Default)]
pub struct EvalTable {
    pub rows: Vec<EvalRow>,
    pub failures: Vec<String>,
}

impl EvalTable {
    /// Per-measurement MAE, bias and worst error (subjects whose report has it).
    pub fn summary(&self) -> Vec<MeasurementSummary> {
        let mut by: BTreeMap<String, Vec<(f64, &str, Option<f64>)>> = BTreeMap::new();
        for r in &self.rows {
            for m in &r.measurements {
                if let Some(e) = m.error_mm {
                    by.entry(m.name.clone())
                        .or_default()
                        .push((e, &r.subject, m.pm_mm));
                }
            }
        }
        by.into_iter()
            .map(|(name, es)| {
                let mut pms: Vec<f64> = es.iter().filter_map(|e| e.2).collect();
                pms.sort_by(|a, b| a.total_cmp(b));
                let within_pm = es
                    .iter()
                    .filter(|e| e.2.is_some_and(|pm| e.0.abs() <= pm))
                    .count();
                let n = es.len() as f64;
                let worst = es
                    .iter()
                    .max_by(|a, b| a.0.abs().total_cmp(&b.0.abs()))
                    .map(|e| (e.0, e.1))
                    .unwrap_or((0.0, ""));
                MeasurementSummary {
                    name,
                    subjects: es.len(),
                    mean_abs_error_mm: es.iter().map(|e| e.0.abs()).sum::<f64>() / n,
                    mean_bias_mm: es.iter().map(|e| e.0).sum::<f64>() / n,
                    worst_error_mm: worst.0,
                    worst_subject: worst.1.to_string(),
                    with_pm: pms.len(),
                    within_pm,
                    median_pm_mm: (!pms.is_empty()).then(|| pms[pms.len() / 2]),
                }
            })
            .collect()
    }

    /// The worst single girth error over every subject and tape girth of the set
    /// (`None` when no row reports a girth).
    pub fn worst_girth(&self) -> Option<WorstGirth> {
        self.rows
            .iter()
            .flat_map(|r| r.measurements.iter().map(move |m| (r, m)))
            .filter(|(_, m)| crate::measure::GIRTH_KEYS.contains(&m.name.as_str()))
            .filter_map(|(r, m)| {
                Some(WorstGirth {
                    name: m.name.clone(),
                    subject: r.subject.clone(),
                    error_mm: m.error_mm?,
                    true_mm: m.true_mm,
                    fitted_mm: m.fitted_mm?,
                })
            })
            .max_by(|a, b| a.error_mm.abs().total_cmp(&b.error_mm.abs()))
    }

    /// Per landmark of one source, over the rows that report it: mean 3-D distance,
    /// mean and worst |height error|, millimetres (truth's names, sorted).
    pub fn landmark_summary(&self, source: LandmarkSource) -> Vec<LandmarkSummary> {
        let mut by: BTreeMap<&String, (Vec<f64>, Vec<f64>)> = BTreeMap::new();
        for r in &self.rows {
            let l = match source {
                LandmarkSource::Silhouettes => &r.landmarks,
                LandmarkSource::FittedBody => &r.body_landmarks,
            };
            for (k, d) in &l.distance_mm {
                let e = by.entry(k).or_default();
                e.0.push(*d);
                e.1.extend(l.height_mm.get(k).map(|h| h.abs()));
            }
        }
        let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len().max(1) as f64;
        by.into_iter()
            .map(|(k, (d, h))| LandmarkSummary {
                name: k.clone(),
                subjects: d.len(),
                mean_distance_mm: mean(&d),
                mean_abs_height_mm: mean(&h),
                worst_abs_height_mm: h.iter().copied().fold(0.0, f64::max),
            })
            .collect()
    }

    /// Stage timings over subjects: median of the medians and the largest p95.
    pub fn timing_summary(&self) -> BTreeMap<String, StageTiming> {
        let mut by: BTreeMap<String, Vec<StageTiming>> = BTreeMap::new();
        for r in &self.rows {
            for (s, t) in &r.timings_ms {
                by.entry(s.clone()).or_default().push(*t);
            }
        }
        by.into_iter()
            .map(|(s, mut ts)| {
                ts.sort_by(|a, b| a.median.total_cmp(&b.median));
                let median = ts[ts.len() / 2].median;
                let p95 = ts.iter().map(|t| t.p95).fold(f64::NEG_INFINITY, f64::max);
                (s, StageTiming { median, p95 })
            })
            .collect()
    }

    /// The rows, their summary, stage timings and failures as JSON (`eval --json`).
    pub fn to_json(&self) -> serde_json::Value {
        serde_json::json!({ "rows": self.rows, "summary": self.summary(),
            "worst_girth": self.worst_girth(),
            "timings_ms": self.timing_summary(), "failures": self.failures })
    }

    /// Frame pairs refused of those with a subject, and the mean mask IoU per view
    /// (over the subjects that have it).
    pub fn refusals_line(&self) -> (Option<(u64, u64)>, Option<f64>, Option<f64>) {
        let tallies: Vec<FrameTally> = self.rows.iter().filter_map(|r| r.frames).collect();
        let refused = (!tallies.is_empty()).then(|| {
            (
                tallies.iter().map(|t| t.refused()).sum(),
                tallies.iter().map(|t| t.with_subject).sum(),
            )
        });
        let iou = |v: &str| {
            let x: Vec<f64> = self
                .rows
                .iter()
                .filter_map(|r| r.mask_iou.get(v).copied())
                .collect();
            (!x.is_empty()).then(|| x.iter().sum::<f64>() / x.len() as f64)
        };
        (refused, iou("front"), iou("side"))
    }

    /// The refusals and mean mask IoU as text lines (empty when the rows lack both).
    fn refusals_and_iou(&self) -> String {
        let (refused, f, s) = self.refusals_line();
        let mut out = String::new();
        if let Some((r, n)) = refused {
            out.push_str(&format!(
                "\nframes refused (subject in view, not fitted): {r} of {n}\n"
            ));
        }
        if let (Some(f), Some(s)) = (f, s) {
            out.push_str(&format!("mean mask IoU: front {f:.3}, side {s:.3}\n"));
        }
        out
    }

    /// The plain-text table.
    pub fn to_text(&self) -> String {
        let mut s = String::new();
        let names: Vec<String> = {
            let mut v: Vec<String> = self
                .rows
                .iter()
                .flat_map(|r| r.measurements.iter().map(|m| m.name.clone()))
                .collect();
            v.sort();
            v.dedup();
            v
        };
        s.push_str(&format!("{:<16}", "error (mm)"));
        for n in &names {
            s.push_str(&format!(" {:>12}", short(n)));
        }
        s.push_str(&format!(
            " {:>9} {:>9} {:>7} {:>7}\n",
            "surf mean", "surf p95", "IoU f", "IoU s"
        ));
        for r in &self.rows {
            s.push_str(&format!("{:<16}", clip(&r.subject, 16)));
            for n in &names {
                let e = r
                    .measurements
                    .iter()
                    .find(|m| &m.name == n)
                    .and_then(|m| m.error_mm);
                s.push_str(&format!(
                    " {:>12}",
                    e.map_or("-".into(), |e| format!("{e:+.1}"))
                ));
            }
            let sd = r.surface.map_or(("-".into(), "-".into()), |d| {
                (format!("{:.1}", d.mean_mm), format!("{:.1}", d.p95_mm))
            });
            let iou = |v: &str| r.mask_iou.get(v).map_or("-".into(), |x| format!("{x:.3}"));
            s.push_str(&format!(
                " {:>9} {:>9} {:>7} {:>7}\n",
                sd.0,
                sd.1,
                iou("front"),
                iou("side")
            ));
        }
        s.push_str("\nper measurement        subjects   MAE mm  bias mm  worst mm  median ± mm  within ±  (worst subject)\n");
        for m in self.summary() {
            let (pm, within) = match m.median_pm_mm {
                Some(pm) => (format!("{pm:.1}"), format!("{}/{}", m.within_pm, m.with_pm)),
                None => ("-".into(), "-".into()),
            };
            s.push_str(&format!(
                "{:<22} {:>8} {:>8.1} {:>8.1} {:>9.1} {pm:>12} {within:>9}  ({})\n",
                m.name,
                m.subjects,
                m.mean_abs_error_mm,
                m.mean_bias_mm,
                m.worst_error_mm,
                m.worst_subject
            ));
        }
        if let Some(w) = self.worst_girth() {
            s.push_str(&w.describe());
            s.push('\n');
        }
        for source in LandmarkSource::ALL {
            let rows = self.landmark_summary(source);
            if rows.is_empty() {
                continue;
            }
            s.push_str(&format!(
                "\n{:<48} mean 3-D mm  height: mean |err| mm  worst |err| mm\n",
                format!("landmark, {}", source.title())
            ));
            for l in rows {
                s.push_str(&format!(
                    "{:<48} {:>11.1} {:>22.1} {:>15.1}\n",
                    l.name, l.mean_distance_mm, l.mean_abs_height_mm, l.worst_abs_height_mm
                ));
            }
        }
        let mut steps: BTreeMap<&String, (f64, f64, usize)> = BTreeMap::new();
        for r in &self.rows {
            for (k, v) in &r.settled_step_mm {
                let e = steps.entry(k).or_insert((0.0, 0.0, 0));
                e.0 = e.0.max(*v);
                e.1 += v;
                e.2 += 1;
            }
        }
        if !steps.is_empty() {
            s.push_str(
                "\nshown value, frame-to-frame change after settling   mean mm   worst mm\n",
            );
            for (k, (worst, sum, n)) in steps {
                s.push_str(&format!(
                    "{k:<50} {:>8.1} {worst:>9.1}\n",
                    sum / n.max(1) as f64
                ));
            }
        }
        s.push_str(&self.refusals_and_iou());
        let t = self.timing_summary();
        if !t.is_empty() {
            s.push_str("\nstage                  median ms   worst p95 ms\n");
            for (k, v) in t {
                s.push_str(&format!("{k:<22} {:>9.2} {:>8.2}\n", v.median, v.p95));
            }
        }
        for f in &self.failures {
            s.push_str(&format!("FAILED: {f}\n"));
        }
        s
    }
}

fn short(name: &str) -> String {
    clip(
        &name
            .replace("_girth", "")
            .replace("thigh_left", "thigh_l")
            .replace("thigh_right", "thigh_r"),
        12,
    )
}

fn clip(s: &str, n: usize) -> String {
    s.chars().take(n).collect()
}

/// `fitstation eval`: score fits of recordings against their ground truth.
#[derive(Debug, Clone, clap::Args)]
pub struct EvalArgs {
    /// Recording folders (each with its `<recording>.truth/` beside it).
    #[arg(required_unless_present = "sets")]
    pub recordings: Vec<PathBuf>,
    /// A whole evaluation set, `NAME=DIR`: every recording in DIR that has its truth
    /// folder beside it. Repeat for several sets: each set gets its own table, then one
    /// table puts the sets side by side (MAE, bias and worst single error per girth).
    #[arg(long = "set", value_name = "NAME=DIR")]
    pub sets: Vec<String>,
    /// Print JSON instead of the table.
    #[arg(long)]
    pub json: bool,
    /// Fit results to score: a folder with avatar.obj + report.json (one recording), or
    /// a folder holding one such folder per recording name.
    #[arg(long)]
    pub result: Option<PathBuf>,
    /// Also write an HTML report (index.html) into this folder.
    #[arg(long)]
    pub report: Option<PathBuf>,
}

/// A way to obtain a fit for a recording (the lead plugs `replay` in here).
pub type FitSource<'a> = dyn FnMut(&Path) -> anyhow::Result<FitResult> + 'a;

/// The result folder of `recording` under `--result DIR`.
pub fn result_dir_for(result: &Path, recording: &Path) -> PathBuf {
    if result.join("avatar.obj").is_file() {
        return result.to_path_buf();
    }
    result.join(recording.file_name().unwrap_or_default())
}

/// Runs `fitstation eval` with results from `--result`.
pub fn run(args: EvalArgs) -> anyhow::Result<()> {
    let Some(result) = args.result.clone() else {
        anyhow::bail!("no fit to score: pass --result DIR (a folder with avatar.obj and report.json); replaying recordings through the fit is not wired in yet");
    };
    let mut source = |rec: &Path| -> anyhow::Result<FitResult> {
        Ok(FitResult::load(&result_dir_for(&result, rec))?)
    };
    run_with(&args, &mut source)
}

/// One named evaluation set of `--set NAME=DIR`.
#[derive(Debug, Clone, PartialEq)]
pub struct EvalSet {
    pub name: String,
    pub recordings: Vec<PathBuf>,
}

/// Parses `NAME=DIR` and lists DIR's recordings: its sub-folders (sorted by name) that
/// have a truth folder beside them.
pub fn parse_set(spec: &str) -> anyhow::Result<EvalSet> {
    let (name, dir) = spec
        .split_once('=')
        .filter(|(n, d)| !n.is_empty() && !d.is_empty())
        .ok_or_else(|| anyhow::anyhow!("--set takes NAME=DIR, got '{spec}'"))?;
    let dir = Path::new(dir);
    let entries = std::fs::read_dir(dir)
        .map_err(|e| anyhow::anyhow!("--set {name}: cannot read {}: {e}", dir.display()))?;
    let mut recordings: Vec<PathBuf> = entries
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.is_dir() && crate::synth::truth_dir(p).is_dir())
        .collect();
    recordings.sort();
    anyhow::ensure!(
        !recordings.is_empty(),
        "--set {name}: {} holds no recording with a truth folder beside it",
        dir.display()
    );
    Ok(EvalSet {
        name: name.to_string(),
        recordings,
    })
}

/// The sets side by side: one row per measurement, per set `MAE / bias / worst` (mm),
/// then how many subjects of each set were scored.
pub fn sets_side_by_side(sets: &[(String, EvalTable)]) -> String {
    let summaries: Vec<Vec<MeasurementSummary>> = sets.iter().map(|(_, t)| t.summary()).collect();
    let mut names: Vec<&String> = summaries.iter().flatten().map(|m| &m.name).collect();
    names.sort();
    names.dedup();
    const COL: usize = 24;
    let mut s = format!("{:<20}", "MAE / bias / worst mm");
    for (n, _) in sets {
        s.push_str(&format!(" {:>COL$}", clip(n, COL)));
    }
    s.push('\n');
    for name in &names {
        s.push_str(&format!("{:<20}", clip(name, 20)));
        for sum in &summaries {
            let cell = sum
                .iter()
                .find(|m| &m.name == *name)
                .map_or("-".into(), |m| {
                    format!(
                        "{:.1} / {:+.1} / {:+.1}",
                        m.mean_abs_error_mm, m.mean_bias_mm, m.worst_error_mm
                    )
                });
            s.push_str(&format!(" {cell:>COL$}"));
        }
        s.push('\n');
    }
    s.push_str(&format!("\n{:<20}", "within ± / median ±"));
    for (n, _) in sets {
        s.push_str(&format!(" {:>COL$}", clip(n, COL)));
    }
    s.push('\n');
    for name in names.iter().filter(|n| n.as_str() != "stature") {
        s.push_str(&format!("{:<20}", clip(name, 20)));
        for sum in &summaries {
            let cell = sum
                .iter()
                .find(|m| &m.name == *name)
                .and_then(|m| {
                    m.median_pm_mm
                        .map(|pm| format!("{}/{} / {pm:.1}", m.within_pm, m.with_pm))
                })
                .unwrap_or_else(|| "-".into());
            s.push_str(&format!(" {cell:>COL$}"));
        }
        s.push('\n');
    }
    s.push_str(&format!("{:<20}", "subjects fitted"));
    for (_, t) in sets {
        let cell = format!("{} of {}", t.rows.len(), t.rows.len() + t.failures.len());
        s.push_str(&format!(" {cell:>COL$}"));
    }
    s.push('\n');
    s.push_str(&format!("{:<20}", "frames refused"));
    for (_, t) in sets {
        let cell = match t.refusals_line().0 {
            Some((r, n)) => format!("{r} of {n}"),
            None => "-".into(),
        };
        s.push_str(&format!(" {cell:>COL$}"));
    }
    s.push('\n');
    s.push_str(&format!("{:<20}", "mask IoU front/side"));
    for (_, t) in sets {
        let cell = match t.refusals_line() {
            (_, Some(f), Some(si)) => format!("{f:.3} / {si:.3}"),
            _ => "-".into(),
        };
        s.push_str(&format!(" {cell:>COL$}"));
    }
    s.push('\n');
    s
}

/// Runs the evaluation with fits from `fit` (one call per recording): the recordings
/// given, or each `--set` in turn and then the sets side by side.
pub fn run_with(args: &EvalArgs, fit: &mut FitSource<'_>) -> anyhow::Result<()> {
    if args.sets.is_empty() {
        return run_one(args, &args.recordings, args.report.as_deref(), fit).map(|_| ());
    }
    let sets = args
        .sets
        .iter()
        .map(|s| parse_set(s))
        .collect::<anyhow::Result<Vec<_>>>()?;
    let mut tables = Vec::new();
    for set in &sets {
        if !args.json {
            println!("== set {} ({} recordings)", set.name, set.recordings.len());
        }
        let report = args.report.as_ref().map(|r| r.join(&set.name));
        let table = run_one(args, &set.recordings, report.as_deref(), fit)?;
        tables.push((set.name.clone(), table));
    }
    if args.json {
        let v: serde_json::Map<String, serde_json::Value> = tables
            .iter()
            .map(|(n, t)| (n.clone(), t.to_json()))
            .collect();
        println!(
            "{}",
            serde_json::to_string_pretty(&serde_json::json!({ "sets": v }))?
        );
    } else {
        println!("\n== sets side by side\n{}", sets_side_by_side(&tables));
    }
    Ok(())
}

/// Scores `recordings` and prints (and with `report`, writes) their table.
fn run_one(
    args: &EvalArgs,
    recordings: &[PathBuf],
    report: Option<&Path>,
    fit: &mut FitSource<'_>,
) -> anyhow::Result<EvalTable> {
    let mut table = EvalTable::default();
    let mut thumbs = Vec::new();
    let n = recordings.len();
    for (i, rec) in recordings.iter().enumerate() {
        progress(i, n, rec);
        let tdir = crate::synth::truth_dir(rec);
        let scored = fit(rec).and_then(|r| Ok((evaluate(&tdir, &r)?, r)));
        match scored {
            Ok((row, r)) => {
                if report.is_some() {
                    thumbs.push(
                        html::overlay_thumbnails(rec, &tdir, &r.avatar).unwrap_or_else(|e| {
                            table
                                .failures
                                .push(format!("{}: thumbnails: {e}", rec.display()));
                            Vec::new()
                        }),
                    );
                }
                table.rows.push(row);
            }
            Err(e) => table.failures.push(format!("{}: {e:#}", rec.display())),
        }
    }
    progress(n, n, Path::new(""));
    if args.json && args.sets.is_empty() {
        println!("{}", serde_json::to_string_pretty(&table.to_json())?);
    } else if !args.json {
        print!("{}", table.to_text());
    }
    if let Some(dir) = report {
        crate::io::atomic::create_dir(dir)?;
        let p = dir.join("index.html");
        crate::io::atomic::write(&p, html::report(&table, &thumbs))?;
        eprintln!("report: {}", p.display());
    }
    anyhow::ensure!(!table.rows.is_empty(), "no recording could be scored");
    Ok(table)
}

/// A stderr progress bar: redrawn in place on a terminal, one plain line per step
/// otherwise ([`crate::io::progress`]).
fn progress(i: usize, n: usize, current: &Path) {
    const WIDTH: usize = 30;
    if n < 2 {
        return;
    }
    let filled = WIDTH * i / n;
    let text = format!(
        "[{}{}] {i}/{n} {:<40}",
        "#".repeat(filled),
        " ".repeat(WIDTH - filled),
        current
            .file_name()
            .map(|f| f.to_string_lossy().into_owned())
            .unwrap_or_default()
    );
    crate::io::progress::show(
        crate::io::progress::ProgressStyle::for_stderr(),
        &text,
        i == n,
    );
}

#[cfg(test)]
mod tests {
    use super::*;

    fn row(subject: &str, errors: &[(&str, Option<f64>)]) -> EvalRow {
        EvalRow {
            subject: subject.into(),
            measurements: errors
                .iter()
                .map(|&(name, e)| MeasurementCompare {
                    name: name.into(),
                    true_mm: 800.0,
                    fitted_mm: e.map(|e| 800.0 + e),
                    error_mm: e,
                    pm_mm: Some(8.0),
                })
                .collect(),
            surface: None,
            mask_iou: BTreeMap::new(),
            landmarks: LandmarkErrors::default(),
            body_landmarks: LandmarkErrors::default(),
            timings_ms: BTreeMap::new(),
            profile: Vec::new(),
            settled_step_mm: BTreeMap::new(),
            frames: None,
        }
    }

    #[test]
    fn sets_side_by_side_shows_each_sets_mae_bias_and_worst() {
        let a = EvalTable {
            rows: vec![
                row(
                    "subject_00",
                    &[("chest_girth", Some(4.0)), ("hip_girth", Some(-2.0))],
                ),
                row(
                    "subject_01",
                    &[("chest_girth", Some(-10.0)), ("hip_girth", Some(6.0))],
                ),
            ],
            failures: vec!["subject_02: no frame".into()],
        };
        let b = EvalTable {
            rows: vec![row("subject_00", &[("chest_girth", Some(30.0))])],
            failures: Vec::new(),
        };
        let t = sets_side_by_side(&[("library".into(), a), ("ansur".into(), b)]);
        let chest = t
            .lines()
            .find(|l| l.starts_with("chest_girth"))
            .expect("chest row");
        assert!(chest.contains("7.0 / -3.0 / -10.0"), "{chest}");
        assert!(chest.contains("30.0 / +30.0 / +30.0"), "{chest}");
        let hip = t
            .lines()
            .find(|l| l.starts_with("hip_girth"))
            .expect("hip row");
        assert!(
            hip.contains("4.0 / +2.0 / +6.0") && hip.trim_end().ends_with('-'),
            "{hip}"
        );
        // Each chest row is given ±8: 4 mm is within it, -10 mm is not.
        let cover = t
            .lines()
            .filter(|l| l.starts_with("chest_girth"))
            .nth(1)
            .expect("cover row");
        assert!(
            cover.contains("1/2 / 8.0") && cover.contains("0/1 / 8.0"),
            "{cover}"
        );
        let fitted = t
            .lines()
            .find(|l| l.starts_with("subjects"))
            .expect("count row");
        assert!(
            fitted.contains("2 of 3") && fitted.contains("1 of 1"),
            "{fitted}"
        );
    }

    #[test]
    fn a_set_lists_the_recordings_with_truth_and_bad_specs_are_said() {
        let dir = std::env::temp_dir().join(format!("fitstation_evalset_{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        for d in [
            "subject_01",
            "subject_01.truth",
            "subject_00",
            "subject_00.truth",
            "notes",
        ] {
            std::fs::create_dir_all(dir.join(d)).expect("mkdir");
        }
        let set = parse_set(&format!("lib={}", dir.display())).expect("set");
        assert_eq!(set.name, "lib");
        assert_eq!(
            set.recordings,
            vec![dir.join("subject_00"), dir.join("subject_01")]
        );
        assert!(parse_set("nodir").is_err());
        assert!(parse_set(&format!("empty={}", dir.join("notes").display())).is_err());
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn worst_girth_is_the_largest_girth_error_of_the_set() {
        let table = EvalTable {
            rows: vec![
                row(
                    "a",
                    &[
                        ("chest_girth", Some(4.0)),
                        ("waist_girth", Some(-9.5)),
                        // Not tape girths: never the worst girth.
                        ("stature", Some(40.0)),
                        ("hip_girth_max", Some(-30.0)),
                    ],
                ),
                row(
                    "b",
                    &[
                        ("thigh_girth_left", Some(9.0)),
                        ("hip_girth", None),
                        ("thigh_girth_right", Some(-12.25)),
                    ],
                ),
            ],
            failures: Vec::new(),
        };
        let w = table.worst_girth().expect("a worst girth");
        assert_eq!(
            (w.name.as_str(), w.subject.as_str(), w.error_mm),
            ("thigh_girth_right", "b", -12.25)
        );
        assert_eq!(w.fitted_mm, 800.0 - 12.25);
        let text = table.to_text();
        assert!(
            text.contains(
                "worst single girth error of the set: -12.2 mm (thigh_girth_right, subject b"
            ),
            "{text}"
        );
        let html = super::html::report(&table, &[]);
        assert!(
            html.contains("thigh_girth_right, subject b"),
            "no worst girth in the HTML"
        );
        assert!(EvalTable::default().worst_girth().is_none());
    }

    #[test]
    fn truth_landmark_names_map_to_the_stations() {
        assert_eq!(station_landmark_name("left_armpit"), "armpit_left");
        assert_eq!(station_landmark_name("right_acromion"), "acromion_right");
        assert_eq!(station_landmark_name("crotch"), "crotch");
        assert_eq!(station_landmark_name("head_top"), "head_top");
        // Every such name is one the station writes.
        use crate::landmarks::LandmarkName::*;
        for (n, l) in [
            ("left_armpit", ArmpitLeft),
            ("right_armpit", ArmpitRight),
            ("left_acromion", AcromionLeft),
            ("right_acromion", AcromionRight),
        ] {
            assert_eq!(station_landmark_name(n), l.as_str());
        }
    }
}
