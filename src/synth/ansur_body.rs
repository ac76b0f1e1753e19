//! A body that follows one ANSUR II person, with a shape the shape library cannot make.
//!
//! The evaluation set drawn from the shape library flatters the fit, which picks its
//! candidate from the same library. An ANSUR subject starts from the library body
//! nearest in gender, stature and build, then leaves the library's span in five steps
//! (vertices move, the topology is kept):
//! 1. [`fit_heights`]: uniform scale to the person's stature, then a smooth vertical map
//!    that puts the crotch at the person's crotch height (leg length) and keeps the top
//!    of the head at the stature; head and arms ride along rigidly.
//! 2. [`add_local_shape`]: shape variation no macro setting makes, drawn from the seed:
//!    a belly protrusion (front only), fuller or flatter buttocks (back only) and a few
//!    smooth bumps and dents of up to 2 cm along the normal on the trunk and thighs.
//!    For women, the chest depth the body lacks is added mostly as bust
//!    ([`shape_bust`]).
//! 3. [`scale_thighs`]: each thigh scaled radially about its own axis to the person's
//!    thigh circumference (fading out towards the knee and above the crotch).
//! 4. [`warp_sections`]: at the chest, waist and buttock levels the trunk's breadth (x)
//!    and depth (z) are scaled about the trunk's centre to the person's values (at the
//!    chest, depth and circumference: its breadth follows, [`CHEST_BREADTH_FROM_GIRTH`];
//!    at the waist, its circumference too, by a corner push: [`WAIST_FULLNESS_FROM_GIRTH`]),
//!    independently per level (the chest's depth about a point nearer the back, so that
//!    it grows mostly in front), the scales blended smoothly in height between levels
//!    (zero slope at each level, so the level's section is scaled exactly). The arms are
//!    moved rigidly by the trunk's widening at the armpits, so they are not warped into
//!    the trunk.
//! 5. The feet are put back on the mark (soles on y = 0).
//!
//! # Conventions
//! Canonical body frame: metres, soles on y = 0, facing +Z, +X the subject's left,
//! centred between the feet. Breadth: x extent of the trunk's section (the loop that
//! straddles the body axis x = 0); depth: its z extent. ANSUR values are millimetres.

use super::ansur::{AnsurRecord, Sex};
use super::rng::SplitMix64;
use super::subject::{part_labels, SubjectError};
use crate::body::{ShapeLibrary, ShapeParams, Template};
use crate::fit::correspond::Part;
use crate::fit::pose::JointAnchor;
use crate::mesh::section::{hull_perimeter, slice, Plane, SectionLoop};
use crate::mesh::TriMesh;
use glam::{DVec2, DVec3};

/// Passes of thigh scaling and section warps (see [`build`]).
const PASSES: usize = 2;
/// Half-width of the blend between leg and trunk scaling about the crotch, metres.
const LEG_BLEND_HALF_M: f64 = 0.05;
/// Along the arm from the shoulder joint, where the arm starts to move rigidly and
/// the length over which it takes over from the trunk's own motion, metres.
const ARM_RIGID_FROM_M: f64 = 0.04;
const ARM_RIGID_SPAN_M: f64 = 0.10;
/// The section warps fade to none this far below the crotch, metres.
const WARP_FADE_BELOW_CROTCH_M: f64 = 0.08;
/// Half-width of the band about the body axis a trunk section must straddle, metres.
const TRUNK_STRADDLE_M: f64 = 0.03;
/// Thigh girth is searched from 1 to 8 cm below the crotch (measurements.md).
const THIGH_BAND_M: (f64, f64) = (0.01, 0.08);
/// Above the crotch, the thigh scaling fades out over this height, metres.
const THIGH_FADE_ABOVE_M: f64 = 0.06;
/// Where the chest's depth is scaled about, as a fraction of its depth from the back
/// (women, men): a woman's deeper chest is mostly bust, a man's rib cage.
const CHEST_DEPTH_PIVOT: (f64, f64) = (0.25, 0.45);
/// The chest level takes the person's chest depth and circumference, and its breadth
/// follows from them. ANSUR II's chest breadth is a caliper's, against the chest wall
/// under the hanging arms, not the trunk's whole width: over ANSUR II the chest
/// circumference is a median 1.22 times the perimeter of the ellipse of the chest
/// breadth and depth (a rounded box is about 1.1), where the waist's is 1.06 and the
/// buttocks' 1.09 (`python3 tools/ansur_priors.py`). A body's trunk section with the
/// person's chest breadth as its width fell up to 193 mm short of the person's chest
/// circumference (the `ansur` sets made before 2026-11-28: dev seeds 20300-20323,
/// chest girth minus the person's -193 to +40 mm, men -43 to -193). Waist and buttocks
/// keep breadth and depth (the waist takes its girth too: [`WAIST_FULLNESS_FROM_GIRTH`]).
const CHEST_BREADTH_FROM_GIRTH: bool = true;
/// The waist level takes the person's waist circumference as well as breadth and depth:
/// its section is made fuller or rounder between its four rims (a superellipse corner
/// push, fading to none at the buttock and chest levels). The library's waists are
/// rounder than people's: on the development people (seeds 20300-20311) the bodies'
/// girth at the navel height was 8-52 mm (mean 28) short of the person's waist
/// circumference, at 1.006-1.046 times the ellipse of its extents against ANSUR II's
/// median 1.056 (`python3 tools/ansur_priors.py`).
const WAIST_FULLNESS_FROM_GIRTH: bool = true;
/// Rounds of the waist's joint fit of breadth, depth and fullness.
const WAIST_ROUNDS: usize = 4;
/// Bounds of the waist's superellipse exponent (2: the section's own shape): from rounder
/// than the section to a rounded box.
const EXPONENT_RANGE: (f64, f64) = (1.6, 4.0);
/// Height spread of the bust lobes, metres.
const BUST_SIGMA_M: f64 = 0.055;
/// Bounds of the per-level and thigh scales (a guard against a body the library
/// makes very differently from the person; ANSUR II's own spread stays well inside).
const SCALE_RANGE: (f64, f64) = (0.6, 1.6);

/// Local shape variation of an ANSUR subject, drawn from the seed.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct LocalShape {
    /// Belly protrusion along +Z below the navel, metres (negative: flatter).
    pub belly_m: f64,
    /// Buttock fullness along -Z, metres (negative: flatter).
    pub buttocks_m: f64,
    /// Bumps and dents along the surface normal on the trunk and thighs.
    pub bumps: Vec<Bump>,
}

/// A Gaussian bump (positive) or dent (negative) along the normal.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Bump {
    /// Height of the centre, fraction of stature.
    pub height_of_stature: f64,
    /// Direction of the centre about the body axis, degrees (0 = front, 90 = left).
    pub azimuth_deg: f64,
    pub amplitude_m: f64,
    pub sigma_m: f64,
}

/// Ranges of the local variation.
const BELLY_RANGE_M: (f64, f64) = (-0.012, 0.03);
const BUTTOCKS_RANGE_M: (f64, f64) = (-0.015, 0.025);
const BUMP_COUNT: (u64, u64) = (4, 6);
const BUMP_AMPLITUDE_M: (f64, f64) = (0.005, 0.02);
const BUMP_SIGMA_M: (f64, f64) = (0.03, 0.07);
const BUMP_HEIGHT_OF_STATURE: (f64, f64) = (0.36, 0.72);
/// Stream label of the local variation.
const LOCAL_STREAM: u64 = 0x10CA1;

impl LocalShape {
    /// The local variation of `seed` (deterministic).
    pub fn sample(seed: u64) -> LocalShape {
        let mut rng = SplitMix64::stream(seed, LOCAL_STREAM);
        let belly_m = rng.range(BELLY_RANGE_M.0, BELLY_RANGE_M.1);
        let buttocks_m = rng.range(BUTTOCKS_RANGE_M.0, BUTTOCKS_RANGE_M.1);
        let n = BUMP_COUNT.0 + rng.next_u64() % (BUMP_COUNT.1 - BUMP_COUNT.0 + 1);
        let bumps = (0..n)
            .map(|_| {
                let sign = if rng.chance(0.5) { 1.0 } else { -1.0 };
                Bump {
                    height_of_stature: rng
                        .range(BUMP_HEIGHT_OF_STATURE.0, BUMP_HEIGHT_OF_STATURE.1),
                    azimuth_deg: rng.range(0.0, 360.0),
                    amplitude_m: sign * rng.range(BUMP_AMPLITUDE_M.0, BUMP_AMPLITUDE_M.1),
                    sigma_m: rng.range(BUMP_SIGMA_M.0, BUMP_SIGMA_M.1),
                }
            })
            .collect();
        LocalShape {
            belly_m,
            buttocks_m,
            bumps,
        }
    }
}

/// Everything an ANSUR subject's body is made from (deterministic from the seed).
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct AnsurSubject {
    /// The person's values used (no personal field).
    pub record: AnsurRecord,
    pub local: LocalShape,
}

/// One trunk level of the section warps: where, the targets, and what was reached.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct LevelFit {
    pub name: String,
    pub height_m: f64,
    pub target_breadth_m: f64,
    pub target_depth_m: f64,
    /// The person's girth the level's breadth was chosen for (the chest's), metres.
    pub target_girth_m: Option<f64>,
    /// Scales applied (breadth, depth).
    pub scale: [f64; 2],
    /// Breadth, depth and convex-hull girth of the finished body at the level.
    pub breadth_m: f64,
    pub depth_m: f64,
    pub girth_m: f64,
}

/// The built body and how its targets were met.
#[derive(Debug, Clone)]
pub struct AnsurBody {
    pub mesh: TriMesh,
    /// The library parameters it started from.
    pub start: ShapeParams,
    /// Chest, waist and buttock levels.
    pub levels: Vec<LevelFit>,
    /// Thigh scales (left, right).
    pub thigh_scale: [f64; 2],
}

/// Library macro parameters of the body an ANSUR person starts from: gender from sex,
/// the weight slider from the body mass index, the height slider from the stature's
/// standard score within the sex (the stature itself is set by scaling).
pub fn macro_params(r: &AnsurRecord) -> ShapeParams {
    // Means and deviations of ANSUR II stature, mm (women, men).
    let (mean, sd) = match r.sex {
        Sex::Female => (1628.0, 64.0),
        Sex::Male => (1756.0, 69.0),
    };
    let z = ((r.stature - mean) / sd).clamp(-2.5, 2.5);
    ShapeParams {
        gender: if r.sex == Sex::Male { 1.0 } else { 0.0 },
        age_years: 30.0,
        muscle: 0.5,
        // MakeHuman's weight slider: about BMI 17 at 0, 23.5 at 0.5, 35 at 1.
        weight: (0.5 + (r.bmi() - 23.5) / 22.0).clamp(0.05, 0.95),
        height: (0.5 + 0.05 * z).clamp(0.3, 0.7),
        proportions: 0.5,
        // The bust is the generator's own ([`shape_bust`]), not the library's cup size.
        cup: 0.5,
    }
}

/// Builds the body of `subject` (see the module docs for the steps).
///
/// # Errors
/// The library body cannot be labelled or a level has no trunk section.
pub fn build(lib: &ShapeLibrary, subject: &AnsurSubject) -> Result<AnsurBody, SubjectError> {
    let r = &subject.record;
    let template = lib.template();
    let start = macro_params(r);
    let mut mesh = lib.body(&start);
    let labels = part_labels(&mesh, template, "the ANSUR body")?;
    let anchors = Anchors::new(template);
    fit_heights(
        &mut mesh,
        &labels,
        &anchors,
        r.stature * 1e-3,
        r.crotchheight * 1e-3,
    )?;
    let levels = Levels::new(&mesh, &anchors, r)?;
    add_local_shape(&mut mesh, &labels, &subject.local, &levels)?;
    // Thighs and sections touch near the crotch (each fades into the other's zone), so
    // a second, small pass corrects what the other one moved.
    if r.sex == Sex::Female {
        shape_bust(&mut mesh, &labels, &levels, r.chestdepth * 1e-3)?;
    }
    let mut thigh_scale = [1.0; 2];
    let mut fits: Vec<LevelFit> = Vec::new();
    for _ in 0..PASSES {
        let k = scale_thighs(
            &mut mesh,
            &labels,
            &anchors,
            levels.crotch,
            r.thighcircumference * 1e-3,
        )?;
        thigh_scale = [thigh_scale[0] * k[0], thigh_scale[1] * k[1]];
        let pass = warp_sections(&mut mesh, &labels, &anchors, &levels, r)?;
        if fits.is_empty() {
            fits = pass;
        } else {
            for (f, p) in fits.iter_mut().zip(&pass) {
                f.scale = [f.scale[0] * p.scale[0], f.scale[1] * p.scale[1]];
            }
        }
    }
    recentre(&mut mesh, template)?;
    for f in fits.iter_mut() {
        let e = trunk_extent(&mesh, f.height_m).ok_or_else(|| {
            SubjectError::Invalid(format!("no trunk at the {} level after warping", f.name))
        })?;
        f.breadth_m = e.breadth();
        f.depth_m = e.depth();
        f.girth_m = trunk_loop(&mesh, f.height_m).map_or(f64::NAN, |l| hull_perimeter(&l.points));
    }
    mesh.validate().map_err(SubjectError::Invalid)?;
    Ok(AnsurBody {
        mesh,
        start,
        levels: fits,
        thigh_scale,
    })
}

/// Template joints carried to the body (all library bodies share the vertex order).
struct Anchors {
    template_stature: f64,
    shoulder: [JointAnchor; 2],
    elbow: [JointAnchor; 2],
    armpit: [JointAnchor; 2],
    knee: [JointAnchor; 2],
}

impl Anchors {
    fn new(t: &Template) -> Anchors {
        let p = &t.mesh.positions;
        let (j, l) = (&t.info.joints, &t.info.landmarks);
        Anchors {
            template_stature: t.info.stature_m,
            shoulder: [
                JointAnchor::new(p, j.shoulder_left),
                JointAnchor::new(p, j.shoulder_right),
            ],
            elbow: [
                JointAnchor::new(p, j.elbow_left),
                JointAnchor::new(p, j.elbow_right),
            ],
            armpit: [
                JointAnchor::new(p, l.armpit_left),
                JointAnchor::new(p, l.armpit_right),
            ],
            knee: [
                JointAnchor::new(p, j.knee_left),
                JointAnchor::new(p, j.knee_right),
            ],
        }
    }
    /// Offset scale of the anchors on a body of this mesh's stature.
    fn scale(&self, mesh: &TriMesh) -> f64 {
        mesh.bounds()
            .map(|b| b.size().y / self.template_stature.max(1e-6))
            .unwrap_or(1.0)
    }
}

/// Index of a side in the anchors: 0 = left (+X), 1 = right.
fn side_index(part: Part) -> Option<usize> {
    match part {
        Part::LeftArm | Part::LeftLeg => Some(0),
        Part::RightArm | Part::RightLeg => Some(1),
        _ => None,
    }
}

fn smoothstep(t: f64) -> f64 {
    let t = t.clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}

/// How much of an arm vertex moves rigidly with the arm (0 at the shoulder, 1 beyond),
/// by its distance along the upper arm from the shoulder joint.
fn arm_rigidity(p: DVec3, shoulder: DVec3, elbow: DVec3) -> f64 {
    let u = (elbow - shoulder).normalize_or_zero();
    smoothstep(((p - shoulder).dot(u) - ARM_RIGID_FROM_M) / ARM_RIGID_SPAN_M)
}

/// Step 1: stature and crotch height. A uniform scale about the floor gives the
/// stature; then heights are mapped by `f`, slope `a` below the crotch and `b` above,
/// the slope blended over [`LEG_BLEND_HALF_M`] either side of the crotch (`f` is the
/// integral of a smoothstep between the slopes), `a` and `b` solved so that the crotch
/// lands on `crotch_m` and, with the head moved rigidly from the neck up, the top on
/// `stature_m`. Arms follow the shoulder's move rigidly (blended near the shoulder).
fn fit_heights(
    mesh: &mut TriMesh,
    labels: &[Part],
    anchors: &Anchors,
    stature_m: f64,
    crotch_m: f64,
) -> Result<(), SubjectError> {
    let b0 = mesh
        .bounds()
        .ok_or_else(|| SubjectError::Invalid("empty mesh".into()))?;
    let k = stature_m / b0.size().y.max(1e-6);
    let floor = b0.min.y;
    mesh.map_positions(|p| DVec3::new(p.x * k, (p.y - floor) * k, p.z * k));
    let yc = crotch_height(mesh)
        .ok_or_else(|| SubjectError::Invalid("no crotch on the library body".into()))?;
    let y_neck = mesh
        .positions
        .iter()
        .zip(labels)
        .filter(|(_, l)| **l == Part::Head)
        .map(|(p, _)| p.y)
        .fold(f64::INFINITY, f64::min);
    if !(y_neck.is_finite() && y_neck > yc + 2.0 * LEG_BLEND_HALF_M) {
        return Err(SubjectError::Invalid("no neck above the crotch".into()));
    }
    let w = LEG_BLEND_HALF_M;
    // f(y_c) = a (y_c - 3w/16) + b 3w/16 = crotch; f(y_neck) = a y_c + b (y_neck - y_c)
    // = y_neck (the head keeps its height above the neck).
    let c = 3.0 * w / 16.0;
    let (m11, m12, r1) = (yc - c, c, crotch_m);
    let (m21, m22, r2) = (yc, y_neck - yc, y_neck);
    let det = m11 * m22 - m12 * m21;
    let a = (r1 * m22 - m12 * r2) / det;
    let b = (m11 * r2 - r1 * m21) / det;
    let f = |y: f64| {
        if y <= yc - w {
            a * y
        } else if y >= yc + w {
            a * y + (b - a) * (y - yc)
        } else {
            let t = (y - yc + w) / (2.0 * w);
            a * y + (b - a) * 2.0 * w * (t * t * t - 0.5 * t * t * t * t)
        }
    };
    let s = anchors.scale(mesh);
    let sh = [0, 1].map(|i| anchors.shoulder[i].on(&mesh.positions, s));
    let el = [0, 1].map(|i| anchors.elbow[i].on(&mesh.positions, s));
    let head_dy = f(y_neck) - y_neck;
    for (p, l) in mesh.positions.iter_mut().zip(labels) {
        let own = f(p.y) - p.y;
        p.y += match *l {
            Part::Head => head_dy,
            Part::LeftArm | Part::RightArm => {
                let i = usize::from(*l == Part::RightArm);
                let rigid = f(sh[i].y) - sh[i].y;
                let w = arm_rigidity(*p, sh[i], el[i]);
                own + w * (rigid - own)
            }
            _ => own,
        };
    }
    Ok(())
}

/// Extent of a section (x and z).
#[derive(Debug, Clone, Copy)]
struct Extent {
    x0: f64,
    x1: f64,
    z0: f64,
    z1: f64,
}

impl Extent {
    fn of(l: &SectionLoop) -> Extent {
        let mut e = Extent {
            x0: f64::INFINITY,
            x1: f64::NEG_INFINITY,
            z0: f64::INFINITY,
            z1: f64::NEG_INFINITY,
        };
        for p in &l.points {
            e.x0 = e.x0.min(p.x);
            e.x1 = e.x1.max(p.x);
            e.z0 = e.z0.min(p.y);
            e.z1 = e.z1.max(p.y);
        }
        e
    }
    fn breadth(&self) -> f64 {
        self.x1 - self.x0
    }
    fn depth(&self) -> f64 {
        self.z1 - self.z0
    }
    fn centre(&self) -> DVec2 {
        DVec2::new(0.5 * (self.x0 + self.x1), 0.5 * (self.z0 + self.z1))
    }
}

/// The trunk's section at height `y`: the loop that straddles the body axis (x = 0)
/// with the largest bounding box.
fn trunk_extent(mesh: &TriMesh, y: f64) -> Option<Extent> {
    trunk_loop(mesh, y).as_ref().map(Extent::of)
}

/// The loop of [`trunk_extent`].
fn trunk_loop(mesh: &TriMesh, y: f64) -> Option<SectionLoop> {
    slice(mesh, &Plane::horizontal(y))
        .into_iter()
        .filter(|l| l.points.len() > 2)
        .map(|l| (Extent::of(&l), l))
        .filter(|(e, _)| e.x0 < -TRUNK_STRADDLE_M && e.x1 > TRUNK_STRADDLE_M)
        .max_by(|a, b| (a.0.breadth() * a.0.depth()).total_cmp(&(b.0.breadth() * b.0.depth())))
        .map(|(_, l)| l)
}

/// The breadth scale (about `centre.x`) that, with the depth scaled by `sz` about
/// `centre.y`, gives the section `points` (x, z) the convex-hull girth `girth_m`, within
/// [`SCALE_RANGE`] (the girth grows with the breadth).
fn breadth_scale_for_girth(points: &[DVec2], centre: DVec2, sz: f64, girth_m: f64) -> f64 {
    girth_root(points, girth_m, SCALE_RANGE, |p, sx| {
        centre + (p - centre) * DVec2::new(sx, sz)
    })
}

/// The parameter `t` within `range` at which the convex-hull girth of `points`, each
/// moved by `map(point, t)`, is `girth_m`: bisection, for a girth that grows with `t`
/// (the range's end when the girth is out of its reach).
fn girth_root(
    points: &[DVec2],
    girth_m: f64,
    range: (f64, f64),
    map: impl Fn(DVec2, f64) -> DVec2,
) -> f64 {
    let mut mapped = Vec::with_capacity(points.len());
    let mut girth = |t: f64| {
        mapped.clear();
        mapped.extend(points.iter().map(|&p| map(p, t)));
        hull_perimeter(&mapped)
    };
    let (mut lo, mut hi) = range;
    if girth(lo) >= girth_m {
        return lo;
    }
    if girth(hi) <= girth_m {
        return hi;
    }
    for _ in 0..40 {
        let mid = 0.5 * (lo + hi);
        if girth(mid) < girth_m {
            lo = mid
        } else {
            hi = mid
        }
    }
    0.5 * (lo + hi)
}

/// Whether the section at `y` has a loop reaching `reach` to each side of x = 0.
fn joined_at(mesh: &TriMesh, y: f64, reach: f64) -> bool {
    slice(mesh, &Plane::horizontal(y))
        .iter()
        .filter(|l| l.points.len() > 2)
        .map(Extent::of)
        .any(|e| e.x0 < -reach && e.x1 > reach)
}

/// Crotch height of a body standing on y = 0, centred on x = 0, as measurements.md
/// defines the crotch level: the lowest height, searched upwards from 0.30 of the
/// stature, at which a loop reaches 0.04 of the stature to each side of the body axis
/// (2 mm grid, then bisection to 0.25 mm).
pub fn crotch_height(mesh: &TriMesh) -> Option<f64> {
    let h = mesh.bounds()?.size().y;
    let reach = 0.04 * h;
    let mut lo = 0.30 * h;
    if joined_at(mesh, lo, reach) {
        return None;
    }
    let mut hi = lo;
    while !joined_at(mesh, hi, reach) {
        lo = hi;
        hi += 0.002;
        if hi > 0.65 * h {
            return None;
        }
    }
    while hi - lo > 0.00025 {
        let mid = 0.5 * (lo + hi);
        if joined_at(mesh, mid, reach) {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    Some(hi)
}

/// Breadth and depth of the trunk of `mesh` at height `y` (metres), as the builder
/// measures them (for checks).
pub fn trunk_breadth_depth(mesh: &TriMesh, y: f64) -> Option<(f64, f64)> {
    trunk_extent(mesh, y).map(|e| (e.breadth(), e.depth()))
}

/// Step of the scans for the chest and buttock levels, metres.
const LEVEL_SCAN_STEP_M: f64 = 0.005;
/// The chest level is searched this far under the armpits (from, to), metres.
const CHEST_SEARCH_M: (f64, f64) = (0.16, 0.03);

/// Heights of the levels on the body after step 1, metres: the person's navel height
/// for the waist, the body's own chest prominence and buttock protrusion (the person's
/// nipple and buttock heights are where their own extremes are; the library body's
/// extremes are elsewhere, and warping the person's depth onto a height where the body
/// has no prominence would draw a ledge).
struct Levels {
    crotch: f64,
    buttock: f64,
    waist: f64,
    chest: f64,
    /// Where the section warps have faded out above the chest (the shoulder joints).
    top: f64,
    /// The armpits' height.
    armpit: f64,
    stature: f64,
}

impl Levels {
    /// The ANSUR heights, kept in order and under the body's own armpits (the chest
    /// section must be the trunk's alone).
    fn new(mesh: &TriMesh, anchors: &Anchors, r: &AnsurRecord) -> Result<Levels, SubjectError> {
        let crotch = crotch_height(mesh)
            .ok_or_else(|| SubjectError::Invalid("no crotch after scaling".into()))?;
        let s = anchors.scale(mesh);
        let armpit = 0.5
            * (anchors.armpit[0].on(&mesh.positions, s).y
                + anchors.armpit[1].on(&mesh.positions, s).y);
        let top = 0.5
            * (anchors.shoulder[0].on(&mesh.positions, s).y
                + anchors.shoulder[1].on(&mesh.positions, s).y);
        // The body's own extremes: its chest (bust) prominence, the section reaching
        // furthest forward under the armpits, and its buttock protrusion, the section reaching furthest
        // back above the crotch; the navel (waist) at the person's height.
        let scan = |lo: f64, hi: f64, key: &dyn Fn(&Extent) -> f64| {
            let mut best: Option<(f64, f64)> = None;
            let mut y = lo;
            while y <= hi {
                if let Some(e) = trunk_extent(mesh, y) {
                    let k = key(&e);
                    if best.is_none_or(|(_, b)| k > b) {
                        best = Some((y, k));
                    }
                }
                y += LEVEL_SCAN_STEP_M;
            }
            best.map(|(y, _)| y)
        };
        let chest = scan(armpit - CHEST_SEARCH_M.0, armpit - CHEST_SEARCH_M.1, &|e| {
            e.z1
        })
        .unwrap_or(r.chestheight * 1e-3);
        let buttock = scan(
            crotch + 0.02,
            (r.waistheightomphalion * 1e-3 - 0.06).max(crotch + 0.03),
            &|e| -e.z0,
        )
        .unwrap_or(r.buttockheight * 1e-3)
        .max(crotch + 0.03);
        let waist = (r.waistheightomphalion * 1e-3)
            .max(buttock + 0.06)
            .min(chest - 0.06);
        if !(chest < top - 0.03 && waist > buttock) {
            return Err(SubjectError::Invalid(format!(
                "the levels do not fit the body (chest {chest:.3} m, shoulders {top:.3} m)"
            )));
        }
        Ok(Levels {
            crotch,
            buttock,
            waist,
            chest,
            top,
            armpit,
            stature: mesh.bounds().map(|b| b.size().y).unwrap_or(0.0),
        })
    }
}

/// Step 2: belly, buttocks, bumps and dents (displacements from the positions before
/// the step, so they do not compound).
fn add_local_shape(
    mesh: &mut TriMesh,
    labels: &[Part],
    local: &LocalShape,
    lv: &Levels,
) -> Result<(), SubjectError> {
    let at = |y: f64, what: &str| {
        trunk_extent(mesh, y)
            .ok_or_else(|| SubjectError::Invalid(format!("no trunk at the {what}")))
    };
    let (ew, eb) = (at(lv.waist, "waist")?, at(lv.buttock, "buttocks")?);
    let normals = mesh.vertex_normals();
    let rest = mesh.positions.clone();
    let trunk_or_leg = |l: Part| matches!(l, Part::Torso | Part::LeftLeg | Part::RightLeg);
    let gauss = |d: f64, s: f64| (-0.5 * (d / s).powi(2)).exp();
    // Belly: below the navel, front half of the trunk only.
    let (cw, half_depth_w) = (ew.centre(), 0.5 * ew.depth());
    let belly_y = lv.waist - 0.04;
    // Buttocks: two lobes at the buttock level, back half only.
    let (cb, half_b, half_depth_b) = (eb.centre(), 0.5 * eb.breadth(), 0.5 * eb.depth());
    // Bump centres: the outermost trunk or thigh vertex at the bump's height in its
    // direction about the body axis.
    let centres: Vec<Option<usize>> = local
        .bumps
        .iter()
        .map(|b| {
            let h = b.height_of_stature * lv.stature;
            let dir = DVec2::new(
                b.azimuth_deg.to_radians().sin(),
                b.azimuth_deg.to_radians().cos(),
            );
            rest.iter()
                .enumerate()
                .filter(|(i, p)| trunk_or_leg(labels[*i]) && (p.y - h).abs() < 0.015)
                .max_by(|(_, p), (_, q)| {
                    DVec2::new(p.x, p.z)
                        .dot(dir)
                        .total_cmp(&DVec2::new(q.x, q.z).dot(dir))
                })
                .map(|(i, _)| i)
        })
        .collect();
    for (i, p) in mesh.positions.iter_mut().enumerate() {
        let l = labels[i];
        if !trunk_or_leg(l) {
            continue;
        }
        let q = rest[i];
        let mut d = DVec3::ZERO;
        if l == Part::Torso {
            let front = smoothstep((q.z - cw.y) / (0.5 * half_depth_w));
            d.z += local.belly_m * gauss(q.y - belly_y, 0.08) * gauss(q.x - cw.x, 0.10) * front;
        }
        let back = smoothstep((cb.y - q.z) / (0.5 * half_depth_b));
        let lobes = gauss(q.x - cb.x - 0.45 * half_b, 0.3 * half_b)
            + gauss(q.x - cb.x + 0.45 * half_b, 0.3 * half_b);
        d.z -= local.buttocks_m * gauss(q.y - lv.buttock, 0.07) * lobes.min(1.0) * back;
        for (b, c) in local.bumps.iter().zip(&centres) {
            let Some(c) = *c else { continue };
            let facing = normals[i].dot(normals[c]).max(0.0);
            d += normals[i] * b.amplitude_m * gauss((q - rest[c]).length(), b.sigma_m) * facing;
        }
        *p = q + d;
    }
    Ok(())
}

/// A woman's chest depth beyond the body's is mostly bust: before the section warps,
/// the front of the chest is pushed forward in two breast-shaped Gaussian lobes (at
/// 0.3 of the chest breadth either side of the centre, spread 0.18 of it sideways and
/// [`BUST_SIGMA_M`] in height; half as much between them) by the front share
/// (`1 - CHEST_DEPTH_PIVOT.0`) of the missing depth. The section warp then meets the
/// target exactly.
fn shape_bust(
    mesh: &mut TriMesh,
    labels: &[Part],
    lv: &Levels,
    target_depth_m: f64,
) -> Result<(), SubjectError> {
    let e = trunk_extent(mesh, lv.chest)
        .ok_or_else(|| SubjectError::Invalid("no trunk at the chest".into()))?;
    let missing = target_depth_m - e.depth();
    if missing <= 0.0 {
        return Ok(());
    }
    let lift = missing * (1.0 - CHEST_DEPTH_PIVOT.0);
    let (c, b, half_depth) = (e.centre(), e.breadth(), 0.5 * e.depth());
    let gauss = |d: f64, s: f64| (-0.5 * (d / s).powi(2)).exp();
    for (p, l) in mesh.positions.iter_mut().zip(labels) {
        if *l != Part::Torso {
            continue;
        }
        let front = smoothstep((p.z - c.y) / (0.5 * half_depth));
        let lobes = gauss(p.x - c.x - 0.3 * b, 0.18 * b) + gauss(p.x - c.x + 0.3 * b, 0.18 * b);
        p.z += lift * lobes.min(1.0) * gauss(p.y - lv.chest, BUST_SIGMA_M) * front;
    }
    Ok(())
}

/// The largest loop on one side (`side` +1 left, -1 right) at height `y`: its hull
/// perimeter and, as (x, z), its inner edge's x and its middle z.
fn side_loop(mesh: &TriMesh, y: f64, side: f64) -> Option<(f64, DVec2)> {
    slice(mesh, &Plane::horizontal(y))
        .into_iter()
        .filter(|l| l.points.len() > 2 && l.centroid().x * side > 0.0)
        .max_by(|a, b| {
            let e = |l: &SectionLoop| Extent::of(l).breadth() * Extent::of(l).depth();
            e(a).total_cmp(&e(b))
        })
        .map(|l| {
            let e = Extent::of(&l);
            let inner = if side > 0.0 { e.x0 } else { e.x1 };
            (hull_perimeter(&l.points), DVec2::new(inner, e.centre().y))
        })
}

/// Step 3: each thigh's sections scaled uniformly (x about the thigh's inner edge, so
/// the thighs do not grow into each other and the crotch keeps its height; z about its
/// middle) so that its largest girth 1 to 8 cm below the crotch becomes `target_m`;
/// the scaling is full down to 12 cm below the crotch, fades out towards the knee, and
/// above the crotch fades out in height and towards the midline. The reference line
/// runs from the thigh's section 5 cm below the crotch to the knee's.
/// Returns the scales (left, right).
fn scale_thighs(
    mesh: &mut TriMesh,
    labels: &[Part],
    anchors: &Anchors,
    crotch: f64,
    target_m: f64,
) -> Result<[f64; 2], SubjectError> {
    let s = anchors.scale(mesh);
    let mut scales = [1.0; 2];
    let mut plans = Vec::with_capacity(2);
    for (i, side) in [(0usize, 1.0f64), (1, -1.0)] {
        let mut girth = 0.0f64;
        let mut dy = THIGH_BAND_M.0;
        while dy <= THIGH_BAND_M.1 + 1e-9 {
            if let Some((g, _)) = side_loop(mesh, crotch - dy, side) {
                girth = girth.max(g);
            }
            dy += 0.005;
        }
        let (_, top) = side_loop(mesh, crotch - 0.05, side)
            .ok_or_else(|| SubjectError::Invalid("no thigh below the crotch".into()))?;
        let knee_y = anchors.knee[i].on(&mesh.positions, s).y;
        let (_, knee) = side_loop(mesh, knee_y, side)
            .ok_or_else(|| SubjectError::Invalid("no knee section".into()))?;
        if girth <= 0.0 {
            return Err(SubjectError::Invalid("no thigh girth".into()));
        }
        let k = (target_m / girth).clamp(SCALE_RANGE.0, SCALE_RANGE.1);
        scales[i] = k;
        plans.push((side, k, top, knee, knee_y));
    }
    let top_y = crotch - 0.05;
    let full_from = crotch - 0.12;
    for (p, l) in mesh.positions.iter_mut().zip(labels) {
        for &(side, k, top, knee, knee_y) in &plans {
            let own_leg =
                (side > 0.0 && *l == Part::LeftLeg) || (side < 0.0 && *l == Part::RightLeg);
            let lateral = smoothstep(p.x * side / (top.x.abs() + 0.05));
            let w = if own_leg {
                let down = smoothstep((p.y - (knee_y + 0.05)) / (full_from - knee_y - 0.05));
                let near_crotch = smoothstep((crotch - p.y) / 0.04);
                down * (lateral + near_crotch * (1.0 - lateral))
            } else if *l == Part::Torso && p.x * side > 0.0 && p.y >= crotch {
                (1.0 - smoothstep((p.y - crotch) / THIGH_FADE_ABOVE_M)) * lateral
            } else {
                0.0
            };
            if w <= 0.0 {
                continue;
            }
            let t = ((p.y - knee_y) / (top_y - knee_y)).clamp(0.0, 1.0);
            let c = knee + (top - knee) * t;
            let f = 1.0 + (k - 1.0) * w;
            // Vertices inside the inner edge's line (towards the other thigh) keep x.
            let dx = p.x - c.x;
            if dx * side > 0.0 {
                p.x = c.x + dx * f;
            }
            p.z = c.y + (p.z - c.y) * f;
        }
    }
    Ok(scales)
}

/// One knot of the section warp field: height, scales (x, z) and centre (x, z).
#[derive(Debug, Clone, Copy)]
struct Knot {
    y: f64,
    scale: DVec2,
    centre: DVec2,
    /// Superellipse exponent of the section's corner push ([`corner_factor`]; 2: none)
    /// and the scaled section's half extents it is taken in.
    exponent: f64,
    half: DVec2,
}

/// The warp field at height `y`: knots interpolated by a smoothstep (zero slope at
/// every knot), constant beyond the ends.
fn field(knots: &[Knot], y: f64) -> (DVec2, DVec2) {
    let k = knot_at(knots, y);
    (k.scale, k.centre)
}

/// The knots interpolated at height `y` (see [`field`]).
fn knot_at(knots: &[Knot], y: f64) -> Knot {
    let (first, last) = (knots[0], knots[knots.len() - 1]);
    if y <= first.y {
        return first;
    }
    if y >= last.y {
        return last;
    }
    for w in knots.windows(2) {
        if y <= w[1].y {
            let t = smoothstep((y - w[0].y) / (w[1].y - w[0].y));
            return Knot {
                y,
                scale: w[0].scale.lerp(w[1].scale, t),
                centre: w[0].centre.lerp(w[1].centre, t),
                exponent: w[0].exponent + (w[1].exponent - w[0].exponent) * t,
                half: w[0].half.lerp(w[1].half, t),
            };
        }
    }
    last
}

/// How far the corner push of superellipse exponent `n` moves a point at `q` from the
/// section's centre (in the section's half extents): the radius of the superellipse
/// `|u|^n + |v|^n = 1` over the circle's at the point's angle. One at the four rims (the
/// breadth and depth stay), above one between them for `n > 2` (a fuller, boxier
/// section), below for `n < 2`.
fn corner_factor(q: DVec2, n: f64) -> f64 {
    let r = q.length();
    if r < 1e-12 || (n - 2.0).abs() < 1e-12 {
        return 1.0;
    }
    let (c, s) = (q.x.abs() / r, q.y.abs() / r);
    (c.powf(n) + s.powf(n)).powf(-1.0 / n)
}

/// `p` moved by the corner push of exponent `n` about `centre`, in half extents `half`
/// ([`corner_factor`]).
fn corner_pushed(p: DVec2, centre: DVec2, half: DVec2, n: f64) -> DVec2 {
    let d = p - centre;
    centre + d * corner_factor(d / half, n)
}

/// The superellipse exponent whose corner push gives the section `points` (x, z, about
/// `centre`, in half extents `half`) the convex-hull girth `girth_m`, within
/// [`EXPONENT_RANGE`] (the girth grows with the exponent).
fn exponent_for_girth(points: &[DVec2], centre: DVec2, half: DVec2, girth_m: f64) -> f64 {
    girth_root(points, girth_m, EXPONENT_RANGE, |p, n| {
        corner_pushed(p, centre, half, n)
    })
}

/// Step 4: the section warps (see the module docs). Returns the levels' fits (the
/// reached breadth and depth are filled in by the caller on the finished body).
fn warp_sections(
    mesh: &mut TriMesh,
    labels: &[Part],
    anchors: &Anchors,
    lv: &Levels,
    r: &AnsurRecord,
) -> Result<Vec<LevelFit>, SubjectError> {
    // The chest's breadth follows from its girth (see [`CHEST_BREADTH_FROM_GIRTH`]).
    let targets = [
        ("buttock", lv.buttock, r.hipbreadth, r.buttockdepth, None),
        ("waist", lv.waist, r.waistbreadth, r.waistdepth, None),
        (
            "chest",
            lv.chest,
            r.chestbreadth,
            r.chestdepth,
            CHEST_BREADTH_FROM_GIRTH.then_some(r.chestcircumference),
        ),
    ];
    let mut knots = Vec::with_capacity(5);
    let mut fits = Vec::with_capacity(3);
    for (name, y, breadth_mm, depth_mm, girth_mm) in targets {
        let l = trunk_loop(mesh, y)
            .ok_or_else(|| SubjectError::Invalid(format!("no trunk at the {name} level")))?;
        let e = Extent::of(&l);
        let td = depth_mm * 1e-3;
        let sz = (td / e.depth()).clamp(SCALE_RANGE.0, SCALE_RANGE.1);
        // The chest deepens mostly in front (the bust) for women, about evenly for men.
        let pivot = if name == "chest" {
            match r.sex {
                Sex::Female => CHEST_DEPTH_PIVOT.0,
                Sex::Male => CHEST_DEPTH_PIVOT.1,
            }
        } else {
            0.5
        };
        let centre = DVec2::new(e.centre().x, e.z0 + pivot * e.depth());
        let sx = match girth_mm {
            Some(g) => breadth_scale_for_girth(&l.points, centre, sz, g * 1e-3),
            None => (breadth_mm * 1e-3 / e.breadth()).clamp(SCALE_RANGE.0, SCALE_RANGE.1),
        };
        let mut scale = DVec2::new(sx, sz);
        let mut half = 0.5 * DVec2::new(e.breadth() * sx, e.depth() * sz);
        let mut exponent = 2.0;
        // The waist's fullness: its girth the person's ([`WAIST_FULLNESS_FROM_GIRTH`]).
        // The push moves the extremes a little where they are off the rims: breadth,
        // depth and exponent are found together by a few rounds of each in turn.
        if name == "waist" && WAIST_FULLNESS_FROM_GIRTH {
            let want = DVec2::new(breadth_mm, depth_mm) * 1e-3;
            let girth = r.waistcircumference * 1e-3;
            half = 0.5 * want;
            let mut scaled = Vec::with_capacity(l.points.len());
            for round in 0..=WAIST_ROUNDS {
                scaled.clear();
                scaled.extend(l.points.iter().map(|p| centre + (*p - centre) * scale));
                exponent = exponent_for_girth(&scaled, centre, half, girth);
                if round == WAIST_ROUNDS {
                    break;
                }
                let (lo, hi) = scaled
                    .iter()
                    .map(|&p| corner_pushed(p, centre, half, exponent))
                    .fold(
                        (DVec2::splat(f64::INFINITY), DVec2::splat(f64::NEG_INFINITY)),
                        |(lo, hi), q| (lo.min(q), hi.max(q)),
                    );
                scale = (scale * want / (hi - lo))
                    .clamp(DVec2::splat(SCALE_RANGE.0), DVec2::splat(SCALE_RANGE.1));
            }
        }
        knots.push(Knot {
            y,
            scale,
            centre,
            exponent,
            half,
        });
        fits.push(LevelFit {
            name: name.into(),
            height_m: y,
            target_breadth_m: if name == "chest" {
                e.breadth() * sx
            } else {
                breadth_mm * 1e-3
            },
            target_depth_m: td,
            target_girth_m: girth_mm
                .map(|g| g * 1e-3)
                .or((name == "waist" && WAIST_FULLNESS_FROM_GIRTH)
                    .then_some(r.waistcircumference * 1e-3)),
            scale: scale.to_array(),
            breadth_m: e.breadth(),
            depth_m: e.depth(),
            girth_m: hull_perimeter(&l.points),
        });
    }
    let bottom = Knot {
        y: lv.crotch - WARP_FADE_BELOW_CROTCH_M,
        scale: DVec2::ONE,
        centre: knots[0].centre,
        exponent: 2.0,
        half: knots[0].half,
    };
    let top = Knot {
        y: lv.top,
        scale: DVec2::ONE,
        centre: knots[2].centre,
        exponent: 2.0,
        half: knots[2].half,
    };
    knots.insert(0, bottom);
    knots.push(top);
    // The arms move rigidly by the trunk's widening on their side between the chest
    // and the armpits (the most of it, so the arm keeps its gap to the trunk), and by
    // its deepening at the armpits.
    let s = anchors.scale(mesh);
    let sh = [0, 1].map(|i| anchors.shoulder[i].on(&mesh.positions, s));
    let el = [0, 1].map(|i| anchors.elbow[i].on(&mesh.positions, s));
    let mut arm_shift = [DVec3::ZERO; 2];
    for (i, side) in [(0usize, 1.0f64), (1, -1.0)] {
        let mut dx = f64::NEG_INFINITY;
        for k in 0..=4 {
            let y = lv.chest + (lv.armpit - lv.chest) * k as f64 / 4.0;
            let Some(e) = trunk_extent(mesh, y) else {
                continue;
            };
            let (sc, c) = field(&knots, y);
            let edge = if side > 0.0 { e.x1 } else { e.x0 };
            dx = dx.max(side * (sc.x - 1.0) * (edge - c.x));
        }
        let (sc, c) = field(&knots, lv.armpit);
        arm_shift[i] = DVec3::new(
            if dx.is_finite() { side * dx } else { 0.0 },
            0.0,
            (sc.y - 1.0) * (sh[i].z - c.y),
        );
    }
    for (p, l) in mesh.positions.iter_mut().zip(labels) {
        if *l == Part::Head {
            continue;
        }
        let k = knot_at(&knots, p.y);
        let (sc, c) = (k.scale, k.centre);
        let own = DVec3::new((sc.x - 1.0) * (p.x - c.x), 0.0, (sc.y - 1.0) * (p.z - c.y));
        let d = match side_index(*l).filter(|_| l.is_arm()) {
            Some(i) => {
                let w = arm_rigidity(*p, sh[i], el[i]);
                own + w * (arm_shift[i] - own)
            }
            None => own,
        };
        *p += d;
        // The trunk's (and the legs' tops') corner push about the waist.
        if !l.is_arm() && (k.exponent - 2.0).abs() > 1e-9 {
            let q = corner_pushed(DVec2::new(p.x, p.z), c, k.half, k.exponent);
            p.x = q.x;
            p.z = q.y;
        }
    }
    Ok(fits)
}

/// Step 5: soles on y = 0, the feet's midpoint on x = z = 0 (as the library places
/// its bodies).
fn recentre(mesh: &mut TriMesh, template: &Template) -> Result<(), SubjectError> {
    let b = mesh
        .bounds()
        .ok_or_else(|| SubjectError::Invalid("empty mesh".into()))?;
    let centroid = |set: &[u32]| {
        set.iter()
            .filter_map(|&i| mesh.positions.get(i as usize))
            .copied()
            .sum::<DVec3>()
            / set.len().max(1) as f64
    };
    let rigid = &template.info.rigid;
    let mark = 0.5 * (centroid(&rigid.foot_left) + centroid(&rigid.foot_right));
    let shift = DVec3::new(mark.x, b.min.y, mark.z);
    mesh.map_positions(|p| p - shift);
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::super::ansur::{resolve_dir, AnsurTable};
    use super::*;

    fn setup() -> Option<(&'static ShapeLibrary, AnsurTable)> {
        let lib = ShapeLibrary::shared().ok()?;
        let dir = resolve_dir(None).ok()?;
        Some((lib, AnsurTable::load(&dir).ok()?))
    }

    /// The produced body meets the person's stature, crotch height and the breadths
    /// and depths of the three levels within a few millimetres, for both sexes and
    /// builds far from the average.
    #[test]
    fn targets_are_met() {
        let Some((lib, table)) = setup() else {
            eprintln!("library or ANSUR II data missing: skipped");
            return;
        };
        for seed in [20001u64, 20002, 20003, 20004] {
            let sex = if seed % 2 == 0 {
                Sex::Female
            } else {
                Sex::Male
            };
            let subject = AnsurSubject {
                record: table.pick(seed, sex).clone(),
                local: LocalShape::sample(seed),
            };
            let body = build(lib, &subject).expect("builds");
            let r = &subject.record;
            let b = body.mesh.bounds().expect("bounds");
            assert!(b.min.y.abs() < 1e-9);
            assert!(
                (b.size().y - r.stature * 1e-3).abs() < 0.003,
                "{}",
                b.size().y
            );
            let crotch = crotch_height(&body.mesh).expect("crotch");
            assert!(
                (crotch - r.crotchheight * 1e-3).abs() < 0.004,
                "crotch {crotch} vs {}; thigh scales {:?}",
                r.crotchheight * 1e-3,
                body.thigh_scale
            );
            for f in &body.levels {
                let (bw, dp) = trunk_breadth_depth(&body.mesh, f.height_m).expect("level");
                eprintln!(
                    "seed {seed} {}: breadth {:.1}/{:.1} depth {:.1}/{:.1} mm, scales {:?}",
                    f.name,
                    bw * 1e3,
                    f.target_breadth_m * 1e3,
                    dp * 1e3,
                    f.target_depth_m * 1e3,
                    f.scale
                );
                assert!((bw - f.target_breadth_m).abs() < 0.004, "{f:?}");
                assert!((dp - f.target_depth_m).abs() < 0.004, "{f:?}");
                if let Some(g) = f.target_girth_m {
                    eprintln!("  girth {:.1}/{:.1} mm", f.girth_m * 1e3, g * 1e3);
                    assert!((f.girth_m - g).abs() < 0.005, "{f:?}");
                }
            }
            for side in [1.0, -1.0] {
                let g = (0..=28)
                    .filter_map(|k| side_loop(&body.mesh, crotch - 0.01 - 0.0025 * k as f64, side))
                    .map(|(g, _)| g)
                    .fold(0.0, f64::max);
                eprintln!(
                    "seed {seed} thigh {side}: {:.1}/{:.1} mm",
                    g * 1e3,
                    r.thighcircumference
                );
                assert!((g * 1e3 - r.thighcircumference).abs() < 10.0);
            }
            // Same topology as the library.
            assert_eq!(body.mesh.triangles, lib.template().mesh.triangles);
        }
    }

    /// The per-level warps are independent: the breadth/depth ratios of the three
    /// levels move by different amounts from the start body's, by more than the
    /// library's own spread of the waist's ratio over its weight slider moves them.
    #[test]
    fn the_body_leaves_the_library() {
        let Some((lib, table)) = setup() else { return };
        let seed = 20005;
        let subject = AnsurSubject {
            record: table.pick(seed, Sex::Male).clone(),
            local: LocalShape::sample(seed),
        };
        let body = build(lib, &subject).expect("builds");
        let ratio_change: Vec<f64> = body
            .levels
            .iter()
            .map(|f| f.scale[0] / f.scale[1])
            .collect();
        let spread = ratio_change
            .iter()
            .fold(f64::NEG_INFINITY, |m, &x| m.max(x))
            - ratio_change.iter().fold(f64::INFINITY, |m, &x| m.min(x));
        assert!(spread > 0.03, "ratio changes {ratio_change:?}");
        // Deterministic.
        let again = build(lib, &subject).expect("builds");
        assert_eq!(again.mesh.positions, body.mesh.positions);
        // Another seed's local shape moves the trunk by centimetres somewhere.
        let other = AnsurSubject {
            local: LocalShape::sample(seed + 100),
            ..subject.clone()
        };
        let b2 = build(lib, &other).expect("builds");
        let max_move = body
            .mesh
            .positions
            .iter()
            .zip(&b2.mesh.positions)
            .map(|(a, b)| (*a - *b).length())
            .fold(0.0, f64::max);
        assert!(max_move > 0.008, "{max_move}");
    }

    /// The arms keep their shape (rigid beyond the shoulder) and their gap to the trunk.
    #[test]
    fn arms_stay_rigid_and_apart() {
        let Some((lib, table)) = setup() else { return };
        for seed in 20006..20012u64 {
            arms_of(lib, &table, seed);
        }
    }

    fn arms_of(lib: &ShapeLibrary, table: &AnsurTable, seed: u64) {
        let sex = if seed.is_multiple_of(2) {
            Sex::Female
        } else {
            Sex::Male
        };
        let subject = AnsurSubject {
            record: table.pick(seed, sex).clone(),
            local: LocalShape::sample(seed),
        };
        let body = build(lib, &subject).expect("builds");
        let start = lib.body(&body.start);
        let template = lib.template();
        let labels = part_labels(&start, template, "test").expect("labels");
        let k = body.mesh.bounds().expect("b").size().y / start.bounds().expect("b").size().y;
        // Hand vertices: pairwise distances scale uniformly with the stature.
        let hand = &template.info.rigid.hand_left;
        for w in hand.windows(2).step_by(97) {
            let (a, b) = (w[0] as usize, w[1] as usize);
            let d0 = (start.positions[a] - start.positions[b]).length() * k;
            let d1 = (body.mesh.positions[a] - body.mesh.positions[b]).length();
            assert!((d0 - d1).abs() < 1e-6, "{d0} {d1}");
        }
        // Apart from the trunk in the front view, from the crotch to well under the
        // armpits (0.70 of the stature; the armpits are at about 0.75).
        let m = &body.mesh;
        let h = m.bounds().expect("b").size().y;
        let mut y = crotch_height(m).expect("crotch");
        let mut smallest_gap = f64::INFINITY;
        while y < 0.70 * h {
            for (side, arm) in [(1.0, Part::LeftArm), (-1.0, Part::RightArm)] {
                let near = |want: Part| {
                    m.positions
                        .iter()
                        .zip(&labels)
                        .filter(move |(p, l)| **l == want && (p.y - y).abs() < 0.01)
                        .map(move |(p, _)| p.x * side)
                };
                let trunk_out = near(Part::Torso).fold(f64::NEG_INFINITY, f64::max);
                let arm_in = near(arm).fold(f64::INFINITY, f64::min);
                if trunk_out.is_finite() && arm_in.is_finite() {
                    smallest_gap = smallest_gap.min(arm_in - trunk_out);
                }
            }
            y += 0.02;
        }
        eprintln!("seed {seed}: smallest front-view gap {smallest_gap:.3} m");
        assert!(smallest_gap > 0.01, "seed {seed}: {smallest_gap}");
    }
}
