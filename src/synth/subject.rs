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
//! The body source is one function, [`subject_body`] (the shape library; the raw
//! MakeHuman base mesh is the alternative), so switching is one line.

use super::rng::SplitMix64;
use crate::body::{ShapeLibrary, ShapeParams};
use crate::mesh::io::read_obj;
use crate::mesh::section::{slice, Plane, SectionLoop};
use crate::mesh::TriMesh;
use glam::{DMat3, DVec3};
use std::collections::BTreeMap;

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

/// Who to render: the shape library's macro parameters (see
/// [`crate::body::ShapeParams`]: gender 0 = female .. 1 = male, age in years, sliders
/// 0..1 with 0.5 average; `height` is MakeHuman's height slider), and optionally a
/// stature the body is uniformly rescaled to.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct SubjectParams {
    #[serde(flatten)]
    pub shape: ShapeParams,
    /// Uniform rescale of the body to this stature, metres (None: as the library makes it).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub stature_m: Option<f64>,
    /// Arms and legs away from the library's rest A-pose (none by default).
    #[serde(default, skip_serializing_if = "LimbPose::is_rest")]
    pub pose: LimbPose,
    /// A body outside the library's span: trunk and legs widened or deepened about a
    /// height (none by default).
    #[serde(default, skip_serializing_if = "BodyWarp::is_none")]
    pub warp: BodyWarp,
    /// A body following an ANSUR II person instead of the library's (`synth-set
    /// --population ansur`; `shape` then holds the library body it starts from). Written
    /// to truth.json as its own `ansur` object, not here.
    #[serde(skip)]
    pub ansur: Option<super::ansur_body::AnsurSubject>,
    /// A varied stance (`synth-set --stance varied`), applied last; in truth.json as
    /// `stance`.
    #[serde(skip)]
    pub stance: Option<super::stance::Stance>,
}

/// A smooth change of a body's proportions that no macro parameter makes: at heights
/// near `at` (fraction of stature), the trunk and legs are scaled about the body's axis
/// by `1 + width` sideways and `1 + depth` front to back, the scale fading as a Gaussian
/// of height (sigma `SIGMA_OF_STATURE` of the stature). The arms are left alone.
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize, serde::Deserialize)]
pub struct BodyWarp {
    pub width: f64,
    pub depth: f64,
    pub at: f64,
}

impl BodyWarp {
    /// Height spread of the warp, as a fraction of stature.
    pub const SIGMA_OF_STATURE: f64 = 0.06;

    pub fn is_none(&self) -> bool {
        self.width == 0.0 && self.depth == 0.0
    }
}

/// The template's part of every vertex of `mesh`, which must be in the template's vertex
/// order (`what` names the caller in the error).
pub(crate) fn part_labels(
    mesh: &TriMesh,
    template: &crate::body::Template,
    what: &str,
) -> Result<Vec<crate::fit::correspond::Part>, SubjectError> {
    use crate::fit::{parts, pose as fpose};
    if mesh.vertex_count() != template.mesh.vertex_count() {
        return Err(SubjectError::Invalid(format!(
            "{what} needs the template's vertex order"
        )));
    }
    let lm = fpose::template_part_landmarks(template).map_err(SubjectError::Invalid)?;
    Ok(parts::label_parts(
        &template.mesh,
        &template.mesh.one_rings(),
        &lm,
    ))
}

/// Applies `warp` to a library body in the canonical frame (soles on y = 0, centred on
/// x = 0, the template's vertex order).
fn warp_body(
    mesh: &mut TriMesh,
    template: &crate::body::Template,
    warp: BodyWarp,
) -> Result<(), SubjectError> {
    if warp.is_none() {
        return Ok(());
    }
    let labels = part_labels(mesh, template, "warping")?;
    let b = mesh
        .bounds()
        .ok_or_else(|| SubjectError::Invalid("empty mesh".into()))?;
    let stature = b.size().y;
    let yc = b.min.y + warp.at * stature;
    let sigma = BodyWarp::SIGMA_OF_STATURE * stature;
    // The axis: the middle of the trunk's extent near the warp's height.
    let (mut lo, mut hi) = (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY));
    for (p, l) in mesh.positions.iter().zip(&labels) {
        if !l.is_arm() && (p.y - yc).abs() < sigma {
            lo = lo.min(*p);
            hi = hi.max(*p);
        }
    }
    if !lo.is_finite() {
        return Err(SubjectError::Invalid(format!(
            "no trunk at {:.2} of the stature to warp",
            warp.at
        )));
    }
    let c = 0.5 * (lo + hi);
    for (p, l) in mesh.positions.iter_mut().zip(&labels) {
        if l.is_arm() {
            continue;
        }
        let g = (-0.5 * ((p.y - yc) / sigma).powi(2)).exp();
        p.x = c.x + (p.x - c.x) * (1.0 + warp.width * g);
        p.z = c.z + (p.z - c.z) * (1.0 + warp.depth * g);
    }
    Ok(())
}

/// Limbs of a synthetic subject turned from the shape library's rest A-pose, degrees:
/// arms about the shoulders and legs about the hips, in the front plane, positive away
/// from the body, both sides alike.
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize, serde::Deserialize)]
pub struct LimbPose {
    pub arms_deg: f64,
    pub legs_deg: f64,
}

impl LimbPose {
    pub fn is_rest(&self) -> bool {
        self.arms_deg == 0.0 && self.legs_deg == 0.0
    }
}

/// Half-width of the blend across a joint when posing a subject, metres. Wider than the
/// fit's own pose synchronisation (`fit::pose`), so that the fit does not meet its own
/// skinning in the test data.
const POSE_BLEND_HALF_M: f64 = 0.09;
/// Share of a limb's rotation the trunk takes next to the joint.
const POSE_TRUNK_SHARE: f64 = 0.4;

/// Turns the limbs of a library body (the template's vertex order) by `pose`: linear
/// blend skinning with two bones per limb, the trunk fixed and the limb rotated about its
/// joint (the template's shoulder and thigh-root joints carried by nearby vertices; legs
/// sheared instead, see below), the weight rising smoothly across the joint along the
/// limb's axis.
fn pose_limbs(
    mesh: &mut TriMesh,
    template: &crate::body::Template,
    pose: LimbPose,
) -> Result<(), SubjectError> {
    use crate::fit::correspond::Part;
    use crate::fit::pose as fpose;
    if pose.is_rest() {
        return Ok(());
    }
    let labels = part_labels(mesh, template, "posing")?;
    let joints = fpose::PoseJoints::new(template);
    let limbs = [
        (
            Part::LeftArm,
            1.0,
            pose.arms_deg,
            &joints.shoulder_left,
            false,
        ),
        (
            Part::RightArm,
            -1.0,
            pose.arms_deg,
            &joints.shoulder_right,
            false,
        ),
        (Part::LeftLeg, 1.0, pose.legs_deg, &joints.hip_left, true),
        (Part::RightLeg, -1.0, pose.legs_deg, &joints.hip_right, true),
    ];
    for (part, side, deg, anchor, leg) in limbs {
        if deg == 0.0 {
            continue;
        }
        let j = anchor.on(&mesh.positions, 1.0);
        let (mut c, mut n) = (DVec3::ZERO, 0.0);
        for (p, l) in mesh.positions.iter().zip(&labels) {
            if *l == part {
                c += *p;
                n += 1.0;
            }
        }
        if n == 0.0 {
            continue;
        }
        let axis = glam::DVec2::new(c.x / n - j.x, c.y / n - j.y).normalize_or_zero();
        let rot = DMat3::from_rotation_z(side * deg.to_radians());
        let q = DVec3::new(j.x, j.y, 0.0);
        let b = POSE_BLEND_HALF_M;
        for (p, l) in mesh.positions.iter_mut().zip(&labels) {
            let rel = glam::DVec2::new(p.x - j.x, p.y - j.y);
            let own = *l == part;
            let near_joint = *l == Part::Torso && rel.length() < 2.0 * b;
            if !own && !near_joint {
                continue;
            }
            let t = ((rel.dot(axis) + b) / (2.0 * b)).clamp(0.0, 1.0);
            let w = t * t * (3.0 - 2.0 * t) * if own { 1.0 } else { POSE_TRUNK_SHARE };
            if w <= 0.0 {
                continue;
            }
            let moved = if leg {
                // Legs are sheared sideways, not turned: every height is kept, so the feet
                // stay flat on the floor.
                let shear = side * deg.to_radians().tan() * (j.y - p.y);
                DVec3::new(p.x + shear, p.y, p.z)
            } else {
                rot * (*p - q) + q
            };
            *p = *p * (1.0 - w) + moved * w;
        }
    }
    Ok(())
}

impl SubjectParams {
    /// An adult drawn from `seed` by the shape library (both genders, a spread of builds
    /// and statures).
    pub fn sample(seed: u64) -> SubjectParams {
        SubjectParams {
            shape: ShapeLibrary::sample_adult(seed),
            stature_m: None,
            pose: LimbPose::default(),
            warp: BodyWarp::default(),
            ansur: None,
            stance: None,
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

/// Builds the subject's body. THE switch between body sources: the shape library, or
/// an ANSUR II person (`params.ansur`); then the varied stance if any.
pub fn subject_body(params: &SubjectParams) -> Result<SubjectBody, SubjectError> {
    let mut body = match &params.ansur {
        None => library_body(params)?,
        Some(a) => {
            let lib = shape_library()?;
            let built = super::ansur_body::build(lib, a)?;
            SubjectBody {
                mesh: built.mesh,
                source: format!(
                    "ANSUR II subject {} ({:?}): shape library body warped section-wise to the person's measurements, with local shape variation",
                    a.record.subjectid, a.record.sex
                ),
            }
        }
    };
    if let Some(stance) = &params.stance {
        let lib = shape_library()?;
        super::stance::apply(&mut body.mesh, lib.template(), stance)?;
        body.source.push_str("; varied stance");
    }
    Ok(body)
}

/// The embedded shape library, loaded once per process (a synth-set renders many
/// bodies; loading takes a few hundred milliseconds).
fn shape_library() -> Result<&'static ShapeLibrary, SubjectError> {
    static LIBRARY: std::sync::OnceLock<Result<ShapeLibrary, String>> = std::sync::OnceLock::new();
    LIBRARY
        .get_or_init(|| ShapeLibrary::load_default().map_err(|e| e.to_string()))
        .as_ref()
        .map_err(|e| SubjectError::Invalid(format!("shape library: {e}")))
}

/// The shape library's body for the parameters (soles on y = 0, centred between the
/// feet, facing +Z), optionally rescaled to a stature.
pub fn library_body(params: &SubjectParams) -> Result<SubjectBody, SubjectError> {
    let lib = shape_library()?;
    let mut mesh = lib.body(&params.shape.clamp());
    pose_limbs(&mut mesh, lib.template(), params.pose)?;
    warp_body(&mut mesh, lib.template(), params.warp)?;
    mesh.validate().map_err(SubjectError::Invalid)?;
    let b = mesh
        .bounds()
        .ok_or_else(|| SubjectError::Invalid("empty mesh".into()))?;
    mesh.map_positions(|p| p - DVec3::new(0.0, b.min.y, 0.0));
    if let Some(s) = params.stature_m {
        let k = s / b.size().y.max(1e-6);
        mesh.map_positions(|p| p * k);
    }
    Ok(SubjectBody {
        mesh,
        source: "shape library (MakeHuman adult macro model)".into(),
    })
}

/// Alternative source: the raw MakeHuman base mesh (no shape variation), scaled to
/// `params.stature_m` when given.
pub fn makehuman_body(params: &SubjectParams) -> Result<SubjectBody, SubjectError> {
    // The MakeHuman base mesh (CC0) in the cache directory (crate::io::cache).
    let mut mesh = read_obj(&crate::io::cache::makehuman_base_obj(), Some("body"))?;
    mesh.map_positions(|p| p * MAKEHUMAN_TO_M);
    canonicalise(&mut mesh)?;
    if let (Some(s), Some(b)) = (params.stature_m, mesh.bounds()) {
        let k = s / b.size().y.max(1e-6);
        mesh.map_positions(|p| p * k);
    }
    Ok(SubjectBody {
        mesh,
        source: "makehuman-base".into(),
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

/// Area of a section loop's bounding box (robust to loops left open by small holes in
/// the mesh), square metres.
pub fn loop_box_area(l: &SectionLoop) -> f64 {
    let (x0, x1, z0, z1) = loop_extent(l);
    (x1 - x0).max(0.0) * (z1 - z0).max(0.0)
}

/// The torso's section: the loop with the largest bounding box (arms and hands are
/// smaller at every torso height).
fn torso_loop(loops: &[SectionLoop]) -> Option<&SectionLoop> {
    loops
        .iter()
        .filter(|l| l.points.len() > 2)
        .max_by(|a, b| loop_box_area(a).total_cmp(&loop_box_area(b)))
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

/// True landmarks of a prepared body (`crate::body::prepare`, method.md section 1
/// steps 2-4): `crotch`, `left_armpit`, `right_armpit`, `left_acromion`,
/// `right_acromion` (same frame as the mesh it analysed).
pub fn template_landmarks(info: &crate::body::TemplateInfo) -> Landmarks {
    let l = &info.landmarks;
    [
        ("crotch", l.crotch),
        ("left_armpit", l.armpit_left),
        ("right_armpit", l.armpit_right),
        ("left_acromion", l.acromion_left),
        ("right_acromion", l.acromion_right),
    ]
    .into_iter()
    .map(|(k, p)| (k.to_string(), p.to_array()))
    .collect()
}

/// The crotch found on the mesh alone: the lowest vertex near the midline between 0.3
/// and 0.65 of the height (method.md step 1.2).
pub(crate) fn crotch_point(mesh: &TriMesh) -> Option<DVec3> {
    let b = mesh.bounds()?;
    let h = b.size().y;
    let mid_x = 0.5 * (b.min.x + b.max.x);
    mesh.positions
        .iter()
        .filter(|p| {
            (p.x - mid_x).abs() < 0.015 && p.y > b.min.y + 0.3 * h && p.y < b.min.y + 0.65 * h
        })
        .min_by(|a, b| a.y.total_cmp(&b.y))
        .copied()
}

/// Landmarks found on the mesh geometry alone (no skeleton): `head_top` (highest vertex), `crotch`
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
    if let Some(c) = crotch_point(mesh) {
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
                // The arm: another loop beyond the torso on this side.
                let arm = loops
                    .iter()
                    .filter(|l| !std::ptr::eq(*l, torso) && l.points.len() > 2)
                    .filter(|l| {
                        side * (l.centroid().x - torso_edge) > 0.0 && loop_box_area(l) > 1e-4
                    })
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

/// True measurements in millimetres, keyed as report.json's `measurements_mm`, from
/// the measurement module.
pub fn measurements_mm(
    mesh: &TriMesh,
) -> Result<BTreeMap<String, f64>, crate::measure::MeasureError> {
    let m = crate::measure::measure(mesh)?;
    Ok(m.to_report_map()
        .into_iter()
        .filter_map(|(k, v)| v.as_f64().map(|v| (k, v)))
        .collect())
}
