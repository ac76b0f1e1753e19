//! Geometric analysis of a template mesh: skeleton joints (method.md section 1 tables),
//! landmark heights (crotch, armpits, acromions) and rigid parts (head, hands, feet) as
//! vertex index sets, found on the surface without any knowledge of the mesh's topology.
//!
//! # Conventions
//! The mesh is a watertight (or nearly) body in an A-pose in the station frame: metres,
//! +Y up, facing +Z, +X the subject's left. It need not stand on y = 0 or be centred.
//! `h` is the head length, stature / 7 (Zhong, section 1 conventions).
//!
//! # Method
//! The paper finds its landmarks on the front and side contours; on a mesh the same
//! points come from horizontal cross-sections ([`crate::mesh::section::slice`]):
//! - crotch (step 2): the lowest height at which one section loop spans the body axis
//!   (above it the torso, below it two separate legs);
//! - armpits (step 3): scanning down from the neck, the first height at which an arm's
//!   section separates from the torso's;
//! - acromions (step 4): the point of the front upper envelope (top of the body per x)
//!   closest to g = (+-0.8h, crotch + 2.45h) (the paper's g is given about mid-height;
//!   crotch-relative here);
//! - axis joints (step 7 table): x of the crotch, y = crotch + k h, z = the side axis, i.e.
//!   the middle of the torso section's z extent at that height (step 1);
//! - legs: centroids of the leg sections at the table's knee and ankle heights. Area
//!   centroids of horizontal sections lie on a limb's axis even when the limb is tilted,
//!   so this also answers the "horizontal cuts fail on angled limbs" remark;
//! - arms: the arm's axis is traced by section centroids from the armpit to the finger
//!   tips; elbow, wrist and hand follow along the axis at the table's distances (1.0h,
//!   1.8h, 1.9h from the shoulder: the table's heights for a hanging arm), so an A-pose
//!   arm at any angle gets the same joints. The table's shoulder height (crotch + 2.4h)
//!   belongs to the paper's arms-down pose; in an A-pose it lies at the acromion, above
//!   the joint, so the shoulder is placed on the upper-arm axis (extrapolated above the
//!   armpit) midway between the armpit and acromion heights (MakeHuman's own shoulder
//!   helper lies within ~4 cm of it).
//! - rigid parts: the head is what lies above the neck's smallest section; a hand is
//!   what lies beyond the plane through the wrist normal to the forearm; a foot is what
//!   lies below the ankle on its side; each as the connected part holding its extreme
//!   vertex.

mod rigid;
pub(super) mod surface;

use super::BodyError;
use crate::mesh::section::{slice, Plane};
use crate::mesh::TriMesh;
use glam::{DVec2, DVec3};
use std::path::Path;
use surface::{surface_landmarks, SurfaceLandmarks};

/// Head lengths per stature (Zhong: h = stature / 7).
pub const HEADS_PER_STATURE: f64 = 7.0;
/// Axis joint heights above the crotch, in h (method.md section 1, step 7).
pub const HIP_H: f64 = 0.2;
pub const ABDOMEN_H: f64 = 0.5;
pub const WAIST_H: f64 = 1.0;
pub const CHEST_H: f64 = 1.5;
pub const NECK_H: f64 = 2.4;
pub const HEAD_H: f64 = 2.6;
pub const HEAD_TOP_H: f64 = 3.0;
/// Thigh roots: half distance in x, in h.
pub const THIGH_ROOT_X_H: f64 = 0.33;
/// Knee and ankle heights below the crotch, in h.
pub const KNEE_H: f64 = 1.5;
pub const ANKLE_H: f64 = 3.0;
/// Arm joint distances from the shoulder along the arm axis, in h (the table's heights
/// 2.4, 1.4, 0.6, 0.5 of a hanging arm).
pub const ELBOW_ALONG_H: f64 = 1.0;
pub const WRIST_ALONG_H: f64 = 1.8;
pub const HAND_ALONG_H: f64 = 1.9;
/// Acromion search target g (method.md step 4), in h from the crotch.
pub const ACROMION_G_X_H: f64 = 0.8;
pub const ACROMION_G_Y_H: f64 = 2.45;
/// A loop "spans the axis" when it reaches this far on both sides of it, metres.
const SPAN_MARGIN_M: f64 = 0.02;
/// Section loops smaller than this are noise (square metres).
const MIN_LOOP_AREA_M2: f64 = 1e-5;
/// Coarse scan step, metres; transitions are then bisected to [`BISECT_TOL_M`].
const SCAN_STEP_M: f64 = 0.005;
const BISECT_TOL_M: f64 = 0.0005;
/// Arm tracing step along y, metres, and the largest centroid jump between two steps.
const ARM_STEP_M: f64 = 0.01;
const ARM_JUMP_M: f64 = 0.08;
/// Upper-arm samples used to extrapolate the axis to the shoulder, in h below the armpit.
const UPPER_ARM_FIT_H: f64 = 0.6;
/// Bin width of the front upper envelope, metres.
const ENVELOPE_BIN_M: f64 = 0.005;

/// Skeleton joints, station frame, metres.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Joints {
    pub hip: DVec3,
    pub abdomen: DVec3,
    pub waist: DVec3,
    pub chest: DVec3,
    pub neck: DVec3,
    pub head: DVec3,
    pub head_top: DVec3,
    pub thigh_root_left: DVec3,
    pub thigh_root_right: DVec3,
    pub knee_left: DVec3,
    pub knee_right: DVec3,
    pub ankle_left: DVec3,
    pub ankle_right: DVec3,
    pub shoulder_left: DVec3,
    pub shoulder_right: DVec3,
    pub elbow_left: DVec3,
    pub elbow_right: DVec3,
    pub wrist_left: DVec3,
    pub wrist_right: DVec3,
    pub hand_left: DVec3,
    pub hand_right: DVec3,
}

impl Joints {
    /// A joint by its field name (`"knee_left"`, `"head_top"`, ...).
    pub fn get(&self, name: &str) -> Option<DVec3> {
        self.named()
            .into_iter()
            .find(|(n, _)| *n == name)
            .map(|(_, p)| p)
    }

    /// All joints with their names, in a fixed order.
    pub fn named(&self) -> Vec<(&'static str, DVec3)> {
        vec![
            ("hip", self.hip),
            ("abdomen", self.abdomen),
            ("waist", self.waist),
            ("chest", self.chest),
            ("neck", self.neck),
            ("head", self.head),
            ("head_top", self.head_top),
            ("thigh_root_left", self.thigh_root_left),
            ("thigh_root_right", self.thigh_root_right),
            ("knee_left", self.knee_left),
            ("knee_right", self.knee_right),
            ("ankle_left", self.ankle_left),
            ("ankle_right", self.ankle_right),
            ("shoulder_left", self.shoulder_left),
            ("shoulder_right", self.shoulder_right),
            ("elbow_left", self.elbow_left),
            ("elbow_right", self.elbow_right),
            ("wrist_left", self.wrist_left),
            ("wrist_right", self.wrist_right),
            ("hand_left", self.hand_left),
            ("hand_right", self.hand_right),
        ]
    }
}

/// Landmarks (method.md section 1 steps 2-4), station frame, metres.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Landmarks {
    pub crotch: DVec3,
    pub armpit_left: DVec3,
    pub armpit_right: DVec3,
    pub acromion_left: DVec3,
    pub acromion_right: DVec3,
    pub crotch_y: f64,
    /// Mean of the two armpit heights.
    pub armpit_y: f64,
    /// Mean of the two acromion heights.
    pub acromion_y: f64,
    /// Height of the neck's smallest section (the head's rigid-part cut).
    pub neck_cut_y: f64,
    /// Lowest point of the mesh (the soles).
    pub sole_y: f64,
}

/// Rigid parts as vertex index lists (ascending) of the template mesh.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct RigidParts {
    pub head: Vec<u32>,
    pub hand_left: Vec<u32>,
    pub hand_right: Vec<u32>,
    pub foot_left: Vec<u32>,
    pub foot_right: Vec<u32>,
}

/// What the fit needs to know about a template; stored as the JSON sidecar.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct TemplateInfo {
    /// Vertex count of the mesh this describes (guards against a stale sidecar).
    pub vertex_count: usize,
    pub stature_m: f64,
    /// h = stature / 7.
    pub head_length_m: f64,
    pub joints: Joints,
    pub landmarks: Landmarks,
    pub rigid: RigidParts,
}

impl TemplateInfo {
    /// An empty record (no joints, no parts).
    pub fn empty() -> Self {
        TemplateInfo::default()
    }

    /// Parses a sidecar; `file` names the source in errors.
    ///
    /// # Errors
    /// Malformed JSON (with its line), a vertex count other than `vertex_count`, or a
    /// rigid-part index beyond it.
    pub fn from_json(text: &str, file: &Path, vertex_count: usize) -> Result<Self, BodyError> {
        let info: TemplateInfo = serde_json::from_str(text)
            .map_err(|e| BodyError::parse(file, e.line(), e.to_string()))?;
        if info.vertex_count != vertex_count {
            return Err(BodyError::format(
                file,
                format!(
                    "sidecar is for {} vertices, the mesh has {vertex_count}",
                    info.vertex_count
                ),
            ));
        }
        let r = &info.rigid;
        for part in [
            &r.head,
            &r.hand_left,
            &r.hand_right,
            &r.foot_left,
            &r.foot_right,
        ] {
            if part.iter().any(|&i| i as usize >= vertex_count) {
                return Err(BodyError::format(
                    file,
                    "a rigid part indexes a vertex beyond the mesh",
                ));
            }
        }
        Ok(info)
    }

    /// Reads a sidecar file.
    pub fn load(file: &Path, vertex_count: usize) -> Result<Self, BodyError> {
        let text = std::fs::read_to_string(file).map_err(|e| BodyError::io(file, e))?;
        Self::from_json(&text, file, vertex_count)
    }

    /// Writes the sidecar as pretty JSON.
    pub fn save(&self, file: &Path) -> Result<(), BodyError> {
        let text = serde_json::to_string_pretty(self)
            .map_err(|e| BodyError::format(file, e.to_string()))?;
        crate::io::atomic::write(file, text + "\n").map_err(|e| BodyError::io(file, e.into()))
    }
}

/// One horizontal section loop, summarised.
#[derive(Clone, Debug)]
struct LoopStat {
    xmin: f64,
    xmax: f64,
    zmin: f64,
    zmax: f64,
    /// Area centroid (x, z).
    centroid: DVec2,
    area: f64,
}

/// Joins open section chains that share an end point (a cut through a hole comes back
/// from [`slice`] as pieces of one curve) into whole open curves.
fn join_open_chains(mut chains: Vec<Vec<DVec2>>) -> Vec<Vec<DVec2>> {
    const SAME_POINT_M: f64 = 1e-9;
    let mut out: Vec<Vec<DVec2>> = Vec::new();
    while let Some(mut c) = chains.pop() {
        loop {
            let (first, last) = (c[0], c[c.len() - 1]);
            let hit = chains.iter().position(|d| {
                let (a, b) = (d[0], d[d.len() - 1]);
                [(last, a), (last, b), (first, a), (first, b)]
                    .iter()
                    .any(|(p, q)| (*p - *q).length() < SAME_POINT_M)
            });
            let Some(k) = hit else { break };
            let mut d = chains.swap_remove(k);
            if (last - d[0]).length() < SAME_POINT_M {
                c.extend(d.drain(1..));
            } else if (last - d[d.len() - 1]).length() < SAME_POINT_M {
                d.reverse();
                c.extend(d.drain(1..));
            } else if (first - d[d.len() - 1]).length() < SAME_POINT_M {
                d.extend(c.drain(1..));
                c = d;
            } else {
                d.reverse();
                d.extend(c.drain(1..));
                c = d;
            }
        }
        out.push(c);
    }
    out
}

/// Summaries of the loops of the section at `y` (tiny loops dropped; open chains, as a
/// scan's small holes leave them, joined and closed across the gap).
fn loops_at(mesh: &TriMesh, y: f64) -> Vec<LoopStat> {
    let mut out = Vec::new();
    let (closed, open): (Vec<_>, Vec<_>) = slice(mesh, &Plane::horizontal(y))
        .into_iter()
        .partition(|l| l.closed);
    let open: Vec<Vec<DVec2>> = open
        .into_iter()
        .map(|l| l.points)
        .filter(|p| !p.is_empty())
        .collect();
    let polys = closed
        .into_iter()
        .map(|l| l.points)
        .chain(join_open_chains(open));
    for p in polys {
        if p.len() < 3 {
            continue;
        }
        let p = &p;
        let (mut a2, mut cx, mut cz) = (0.0, 0.0, 0.0);
        let (mut xmin, mut xmax, mut zmin, mut zmax) = (
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::INFINITY,
            f64::NEG_INFINITY,
        );
        for i in 0..p.len() {
            let (a, b) = (p[i], p[(i + 1) % p.len()]);
            let c = a.perp_dot(b);
            a2 += c;
            cx += (a.x + b.x) * c;
            cz += (a.y + b.y) * c;
            xmin = xmin.min(a.x);
            xmax = xmax.max(a.x);
            zmin = zmin.min(a.y);
            zmax = zmax.max(a.y);
        }
        let area = 0.5 * a2.abs();
        if area < MIN_LOOP_AREA_M2 {
            continue;
        }
        let centroid = DVec2::new(cx / (3.0 * a2), cz / (3.0 * a2));
        out.push(LoopStat {
            xmin,
            xmax,
            zmin,
            zmax,
            centroid,
            area,
        });
    }
    out
}

fn spans(l: &LoopStat, x: f64) -> bool {
    l.xmin < x - SPAN_MARGIN_M && l.xmax > x + SPAN_MARGIN_M
}

/// Side of the body: +1 left (+X), -1 right.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Side {
    Left,
    Right,
}
impl Side {
    fn sign(self) -> f64 {
        match self {
            Side::Left => 1.0,
            Side::Right => -1.0,
        }
    }
}

/// Whether the section at `y` holds a loop entirely on `side` of `x` (an arm apart from
/// the torso).
fn has_side_loop(mesh: &TriMesh, y: f64, x: f64, side: Side) -> bool {
    loops_at(mesh, y).iter().any(|l| match side {
        Side::Left => l.xmin > x + SPAN_MARGIN_M * 0.5 && !spans(l, x),
        Side::Right => l.xmax < x - SPAN_MARGIN_M * 0.5 && !spans(l, x),
    })
}

/// Bisects a transition: `pred(lo) != pred(hi)`; returns the height of the change.
fn bisect(mut lo: f64, mut hi: f64, pred: impl Fn(f64) -> bool) -> f64 {
    let at_lo = pred(lo);
    while (hi - lo).abs() > BISECT_TOL_M {
        let mid = 0.5 * (lo + hi);
        if pred(mid) == at_lo {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    0.5 * (lo + hi)
}

struct Analysis<'a> {
    mesh: &'a TriMesh,
    h: f64,
    crotch: DVec3,
    top: DVec3,
}

impl Analysis<'_> {
    /// The side axis z at height `y` (method.md step 1): middle of the z extent of the
    /// torso loops (those spanning the body axis), else of the loop nearest the axis.
    fn axis_z(&self, y: f64) -> f64 {
        let loops = loops_at(self.mesh, y);
        let x = self.crotch.x;
        let torso: Vec<&LoopStat> = loops
            .iter()
            .filter(|l| l.xmin <= x && l.xmax >= x)
            .collect();
        let pick: Vec<&LoopStat> = if torso.is_empty() {
            loops
                .iter()
                .min_by(|a, b| {
                    (a.centroid.x - x)
                        .abs()
                        .total_cmp(&(b.centroid.x - x).abs())
                })
                .into_iter()
                .collect()
        } else {
            torso
        };
        if pick.is_empty() {
            return self.top.z;
        }
        let lo = pick.iter().map(|l| l.zmin).fold(f64::INFINITY, f64::min);
        let hi = pick
            .iter()
            .map(|l| l.zmax)
            .fold(f64::NEG_INFINITY, f64::max);
        0.5 * (lo + hi)
    }

    fn axis_joint(&self, k_h: f64) -> DVec3 {
        let y = (self.crotch.y + k_h * self.h).min(self.top.y - BISECT_TOL_M);
        DVec3::new(self.crotch.x, y, self.axis_z(y))
    }

    /// Leg joint: centroid of the largest section loop on `side` at height `y`.
    fn leg_joint(&self, y: f64, side: Side) -> Result<DVec3, BodyError> {
        let s = side.sign();
        loops_at(self.mesh, y)
            .into_iter()
            .filter(|l| (l.centroid.x - self.crotch.x) * s > 0.0 && !spans(l, self.crotch.x))
            .max_by(|a, b| a.area.total_cmp(&b.area))
            .map(|l| DVec3::new(l.centroid.x, y, l.centroid.y))
            .ok_or_else(|| BodyError::Prepare(format!("no {side:?} leg section at y = {y:.3} m")))
    }
}

/// Arm axis samples from the armpit down to the finger tips (section centroids).
fn trace_arm(mesh: &TriMesh, armpit_y: f64, axis_x: f64, side: Side, floor_y: f64) -> Vec<DVec3> {
    let s = side.sign();
    let mut pts: Vec<DVec3> = Vec::new();
    let mut y = armpit_y - ARM_STEP_M * 0.5;
    let mut prev: Option<DVec2> = None;
    while y > floor_y {
        let loops = loops_at(mesh, y);
        let cand: Vec<&LoopStat> = match prev {
            // The first arm section: the loop on this side farthest out and apart from
            // the torso.
            None => loops
                .iter()
                .filter(|l| !spans(l, axis_x) && (l.centroid.x - axis_x) * s > 0.0)
                .max_by(|a, b| {
                    ((a.centroid.x - axis_x) * s).total_cmp(&((b.centroid.x - axis_x) * s))
                })
                .into_iter()
                .collect(),
            // Further down: every loop close to the previous centroid (fingers count together).
            Some(c) => loops
                .iter()
                .filter(|l| (l.centroid - c).length() < ARM_JUMP_M && !spans(l, axis_x))
                .collect(),
        };
        if cand.is_empty() {
            break;
        }
        let a: f64 = cand.iter().map(|l| l.area).sum();
        let c = cand.iter().map(|l| l.centroid * l.area).sum::<DVec2>() / a;
        pts.push(DVec3::new(c.x, y, c.y));
        prev = Some(c);
        y -= ARM_STEP_M;
    }
    pts
}

/// Point at arc length `dist` along the polyline (clamped to its end).
fn along(poly: &[DVec3], dist: f64) -> DVec3 {
    let mut left = dist;
    for w in poly.windows(2) {
        let l = (w[1] - w[0]).length();
        if l >= left && l > 0.0 {
            return w[0] + (w[1] - w[0]) * (left / l);
        }
        left -= l;
    }
    poly.last().copied().unwrap_or(DVec3::ZERO)
}

/// Least-squares line x(y), z(y) through samples, evaluated at `y`.
fn extrapolate(samples: &[DVec3], y: f64) -> Option<DVec3> {
    let n = samples.len() as f64;
    if samples.len() < 2 {
        return None;
    }
    let my = samples.iter().map(|p| p.y).sum::<f64>() / n;
    let mx = samples.iter().map(|p| p.x).sum::<f64>() / n;
    let mz = samples.iter().map(|p| p.z).sum::<f64>() / n;
    let syy: f64 = samples.iter().map(|p| (p.y - my).powi(2)).sum();
    if syy < 1e-12 {
        return None;
    }
    let sxy: f64 = samples.iter().map(|p| (p.y - my) * (p.x - mx)).sum();
    let szy: f64 = samples.iter().map(|p| (p.y - my) * (p.z - mz)).sum();
    Some(DVec3::new(
        mx + sxy / syy * (y - my),
        y,
        mz + szy / syy * (y - my),
    ))
}

/// Vertex adjacency lists from the triangles.
fn adjacency(mesh: &TriMesh) -> Vec<Vec<u32>> {
    let mut adj = vec![Vec::new(); mesh.vertex_count()];
    for t in &mesh.triangles {
        for k in 0..3 {
            let (a, b) = (t[k] as usize, t[(k + 1) % 3]);
            if !adj[a].contains(&b) {
                adj[a].push(b);
                adj[b as usize].push(t[k]);
            }
        }
    }
    adj
}

/// The connected set of vertices satisfying `inside` that holds `seed` (ascending).
fn component(
    adj: &[Vec<u32>],
    mesh: &TriMesh,
    seed: usize,
    inside: impl Fn(DVec3) -> bool,
) -> Vec<u32> {
    let mut seen = vec![false; mesh.vertex_count()];
    let mut stack = vec![seed];
    seen[seed] = true;
    let mut out = Vec::new();
    while let Some(v) = stack.pop() {
        out.push(v as u32);
        for &w in &adj[v] {
            let w = w as usize;
            if !seen[w] && inside(mesh.positions[w]) {
                seen[w] = true;
                stack.push(w);
            }
        }
    }
    out.sort_unstable();
    out
}

/// Analyses a template mesh (see the module docs): the surface landmarks, the arms'
/// axes, the joints along the body's axis, legs and arms, then the rigid parts.
///
/// # Errors
/// [`BodyError::Prepare`] when the mesh is empty, implausibly sized (stature outside
/// 0.5 .. 3 m), or a landmark cannot be found (no two legs, no arm apart from the torso).
pub fn prepare(mesh: &TriMesh) -> Result<TemplateInfo, BodyError> {
    let SurfaceLandmarks {
        stature,
        floor_y,
        top_index: top_i,
        top,
        crotch,
        armpits,
        acromions,
    } = surface_landmarks(mesh)?;
    let h = stature / HEADS_PER_STATURE;
    let (crotch_x, crotch_y) = (crotch.x, crotch.y);
    let an = Analysis {
        mesh,
        h,
        crotch,
        top,
    };
    let arm_axes = trace_arms(mesh, &armpits, crotch_x, floor_y)?;
    let mut j = axis_and_leg_joints(&an, floor_y)?;
    let arm_joints = arm_joints(&arm_axes, &armpits, &acromions, h);
    [j.shoulder_left, j.elbow_left, j.wrist_left, j.hand_left] = arm_joints[0];
    [j.shoulder_right, j.elbow_right, j.wrist_right, j.hand_right] = arm_joints[1];

    // Rigid parts.
    let adj = adjacency(mesh);
    let acromion_y = 0.5 * (acromions[0].y + acromions[1].y);
    let neck_cut_y = rigid::neck_cut_y(mesh, crotch_x, acromion_y, j.head_top.y);
    let head = component(&adj, mesh, top_i, |p| p.y > neck_cut_y);
    let [hand_left, hand_right] = rigid::hands(&adj, mesh, &arm_joints, &arm_axes)?;
    let [foot_left, foot_right] = rigid::feet(&adj, mesh, &j, crotch_x)?;

    Ok(TemplateInfo {
        vertex_count: mesh.vertex_count(),
        stature_m: stature,
        head_length_m: h,
        joints: j,
        landmarks: Landmarks {
            crotch: an.crotch,
            armpit_left: armpits[0],
            armpit_right: armpits[1],
            acromion_left: acromions[0],
            acromion_right: acromions[1],
            crotch_y,
            armpit_y: 0.5 * (armpits[0].y + armpits[1].y),
            acromion_y,
            neck_cut_y,
            sole_y: floor_y,
        },
        rigid: RigidParts {
            head,
            hand_left,
            hand_right,
            foot_left,
            foot_right,
        },
    })
}

/// Each arm's axis, traced down from its armpit (at least three samples).
fn trace_arms(
    mesh: &TriMesh,
    armpits: &[DVec3; 2],
    crotch_x: f64,
    floor_y: f64,
) -> Result<[Vec<DVec3>; 2], BodyError> {
    let mut arm_axes: [Vec<DVec3>; 2] = [Vec::new(), Vec::new()];
    for (k, side) in [Side::Left, Side::Right].into_iter().enumerate() {
        arm_axes[k] = trace_arm(mesh, armpits[k].y, crotch_x, side, floor_y);
        if arm_axes[k].len() < 3 {
            return Err(BodyError::Prepare(format!(
                "{side:?} arm could not be traced below the armpit"
            )));
        }
    }
    Ok(arm_axes)
}

/// The joints on the body's axis (step 7), the thigh roots beside the crotch, and the
/// knees and ankles in the legs' sections.
fn axis_and_leg_joints(an: &Analysis<'_>, floor_y: f64) -> Result<Joints, BodyError> {
    let (h, crotch_x, crotch_y) = (an.h, an.crotch.x, an.crotch.y);
    let mut j = Joints {
        hip: an.axis_joint(HIP_H),
        abdomen: an.axis_joint(ABDOMEN_H),
        waist: an.axis_joint(WAIST_H),
        chest: an.axis_joint(CHEST_H),
        neck: an.axis_joint(NECK_H),
        head: an.axis_joint(HEAD_H),
        head_top: an.axis_joint(HEAD_TOP_H),
        ..Default::default()
    };
    j.thigh_root_left = DVec3::new(crotch_x + THIGH_ROOT_X_H * h, crotch_y, an.crotch.z);
    j.thigh_root_right = DVec3::new(crotch_x - THIGH_ROOT_X_H * h, crotch_y, an.crotch.z);
    j.knee_left = an.leg_joint(crotch_y - KNEE_H * h, Side::Left)?;
    j.knee_right = an.leg_joint(crotch_y - KNEE_H * h, Side::Right)?;
    let ankle_y = (crotch_y - ANKLE_H * h).max(floor_y + 2.0 * SCAN_STEP_M);
    j.ankle_left = an.leg_joint(ankle_y, Side::Left)?;
    j.ankle_right = an.leg_joint(ankle_y, Side::Right)?;
    Ok(j)
}

/// Each arm's shoulder, elbow, wrist and hand: the shoulder on the extrapolated
/// upper-arm axis, the others at distances along the axis.
fn arm_joints(
    arm_axes: &[Vec<DVec3>; 2],
    armpits: &[DVec3; 2],
    acromions: &[DVec3; 2],
    h: f64,
) -> [[DVec3; 4]; 2] {
    let mut arm_joints = [[DVec3::ZERO; 4]; 2];
    for k in 0..2 {
        let axis = &arm_axes[k];
        let upper: Vec<DVec3> = axis
            .iter()
            .copied()
            .filter(|p| p.y > armpits[k].y - UPPER_ARM_FIT_H * h)
            .collect();
        let sy = 0.5 * (armpits[k].y + acromions[k].y);
        let shoulder = extrapolate(&upper, sy).unwrap_or(axis[0]);
        let mut poly = vec![shoulder];
        poly.extend(axis.iter().copied());
        arm_joints[k] = [
            shoulder,
            along(&poly, ELBOW_ALONG_H * h),
            along(&poly, WRIST_ALONG_H * h),
            along(&poly, HAND_ALONG_H * h),
        ];
    }
    arm_joints
}
