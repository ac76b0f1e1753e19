//! Template landmarks, pose synchronisation and rigid parts.
//!
//! - Landmarks of a template are found on its own orthographic front silhouette with the
//!   paper's zones (method.md section 1): crotch = apex of the gap between the legs,
//!   armpits = apexes of the gaps between arms and torso, h = stature / 7.
//! - Pose synchronisation (the paper defers to skeleton-based synchronisation; Kazmi et al.
//!   use linear blend skinning): each arm is rotated about its shoulder and each leg about
//!   its hip, in the front (XY) plane, so that its axis takes the angle seen in the
//!   silhouettes. Skinning weights fall off smoothly across the joint so the shoulder and
//!   groin bend instead of tearing.
//! - Head, hands and feet are kept rigid: after each deformation they are replaced by the
//!   best rigid motion (Kabsch) of their shape on the posed candidate.
//!
//! Units: metres, station frame (+Y up, +Z front, +X the subject's left).

use super::correspond::Part;
use super::parts::PartLandmarks;
use super::Observation;
use crate::body::Template;
use crate::mesh::TriMesh;
use glam::{DMat3, DVec2, DVec3};

/// Cell size of the orthographic silhouette used to find template landmarks, metres.
const ORTHO_CELL_M: f64 = 0.004;
/// Half-width of the blend zone of the skinning weights across a joint, metres.
const BLEND_HALF_M: f64 = 0.06;
/// Stature fraction below which leg vertices belong to the rigid feet.
const FEET_FRACTION: f64 = 0.045;
/// Fraction of an arm's length (from the shoulder) beyond which it is the rigid hand.
const HAND_FRACTION: f64 = 0.78;

/// Orthographic front silhouette of a mesh (looking along -Z), one byte per cell.
struct OrthoMask {
    x0: f64,
    y0: f64,
    w: usize,
    h: usize,
    cells: Vec<bool>,
}

impl OrthoMask {
    fn new(mesh: &TriMesh) -> Option<Self> {
        let bb = mesh.bounds()?;
        let x0 = bb.min.x - 2.0 * ORTHO_CELL_M;
        let y0 = bb.min.y - 2.0 * ORTHO_CELL_M;
        let w = ((bb.size().x / ORTHO_CELL_M) as usize) + 5;
        let h = ((bb.size().y / ORTHO_CELL_M) as usize) + 5;
        if w * h > 50_000_000 {
            return None;
        }
        let mut cells = vec![false; w * h];
        let to = |p: DVec3| DVec2::new((p.x - x0) / ORTHO_CELL_M, (p.y - y0) / ORTHO_CELL_M);
        for t in &mesh.triangles {
            let [a, b, c] = t.map(|i| to(mesh.positions[i as usize]));
            let area = (b - a).perp_dot(c - a);
            if area.abs() < 1e-12 {
                continue;
            }
            let minx = a.x.min(b.x).min(c.x).floor().max(0.0) as usize;
            let maxx = (a.x.max(b.x).max(c.x).ceil() as usize).min(w - 1);
            let miny = a.y.min(b.y).min(c.y).floor().max(0.0) as usize;
            let maxy = (a.y.max(b.y).max(c.y).ceil() as usize).min(h - 1);
            for y in miny..=maxy {
                for x in minx..=maxx {
                    let q = DVec2::new(x as f64 + 0.5, y as f64 + 0.5);
                    let w0 = (b - q).perp_dot(c - q) / area;
                    let w1 = (c - q).perp_dot(a - q) / area;
                    if w0 >= 0.0 && w1 >= 0.0 && w0 + w1 <= 1.0 {
                        cells[y * w + x] = true;
                    }
                }
            }
        }
        Some(OrthoMask { x0, y0, w, h, cells })
    }
    fn at(&self, x: usize, y: usize) -> bool {
        x < self.w && y < self.h && self.cells[y * self.w + x]
    }
    fn col(&self, x_m: f64) -> usize {
        (((x_m - self.x0) / ORTHO_CELL_M).max(0.0) as usize).min(self.w - 1)
    }
    fn row(&self, y_m: f64) -> usize {
        (((y_m - self.y0) / ORTHO_CELL_M).max(0.0) as usize).min(self.h - 1)
    }
    fn y_of(&self, row: usize) -> f64 {
        self.y0 + (row as f64 + 0.5) * ORTHO_CELL_M
    }
    fn x_of(&self, col: usize) -> f64 {
        self.x0 + (col as f64 + 0.5) * ORTHO_CELL_M
    }
}

/// Crotch, armpits and neck height of a body mesh standing in an A-pose.
pub fn part_landmarks(mesh: &TriMesh) -> Result<PartLandmarks, String> {
    let bb = mesh.bounds().ok_or("empty template")?;
    let stature = bb.size().y;
    let h = stature / 7.0;
    let m = OrthoMask::new(mesh).ok_or("template too large for its silhouette grid")?;
    let cx = 0.5 * (bb.min.x + bb.max.x);
    // Crotch: in the zone |x - cx| < 0.1h, the top of the gap that opens to the floor.
    let mut crotch: Option<(f64, f64)> = None;
    for col in m.col(cx - 0.1 * h)..=m.col(cx + 0.1 * h) {
        let mut row = 0;
        while row < m.h && !m.at(col, row) {
            row += 1;
        }
        // Skip the feet/legs if the column starts inside a leg (legs together at the ankle).
        if row >= m.h || row == 0 {
            continue;
        }
        let y = m.y_of(row);
        if y < 0.3 * stature || y > 0.65 * stature {
            continue;
        }
        if crotch.is_none_or(|c| y > c.1) {
            crotch = Some((m.x_of(col), y));
        }
    }
    let (crotch_x, crotch_y) = crotch.ok_or("no gap between the legs: the template must stand with its legs apart")?;
    // Armpits: in x in [0.2h, h] from the centre and y in [crotch + 0.5h, crotch + 2.5h],
    // the highest background cell of a gap that is closed above (not the open air beyond
    // the arm).
    let armpit = |sign: f64| -> Option<DVec3> {
        let (a, b) = (cx + sign * 0.2 * h, cx + sign * h);
        let (lo, hi) = (m.col(a.min(b)), m.col(a.max(b)));
        let (r0, r1) = (m.row(crotch_y + 0.5 * h), m.row(crotch_y + 2.5 * h));
        let mut best: Option<(usize, usize)> = None;
        for col in lo..=hi {
            if m.at(col, r0) {
                continue;
            }
            let mut row = r0;
            while row < r1 && !m.at(col, row) {
                row += 1;
            }
            if row >= r1 {
                continue; // open to the top of the zone: beside the arm, not under it
            }
            if best.is_none_or(|bst| row > bst.1) {
                best = Some((col, row));
            }
        }
        best.map(|(c, r)| DVec3::new(m.x_of(c), m.y_of(r), 0.0))
    };
    let left = armpit(1.0).ok_or("no gap between the left arm and the torso: the template must stand in an A-pose")?;
    let right = armpit(-1.0).ok_or("no gap between the right arm and the torso: the template must stand in an A-pose")?;
    Ok(PartLandmarks {
        crotch: DVec3::new(crotch_x, crotch_y, 0.0),
        left_armpit: left,
        right_armpit: right,
        neck_y: crotch_y + 2.4 * h,
    })
}

/// Landmarks of the library's template.
pub fn template_part_landmarks(t: &Template) -> Result<PartLandmarks, String> {
    part_landmarks(&t.mesh)
}

/// Principal axis (in the XY plane) and centroid of a set of vertices, axis pointing down.
fn limb_axis(positions: &[DVec3], labels: &[Part], part: Part) -> Option<(DVec2, DVec2)> {
    let pts: Vec<DVec2> = positions.iter().zip(labels).filter(|(_, l)| **l == part).map(|(p, _)| DVec2::new(p.x, p.y)).collect();
    if pts.len() < 10 {
        return None;
    }
    let c = pts.iter().copied().sum::<DVec2>() / pts.len() as f64;
    let (mut sxx, mut sxy, mut syy) = (0.0, 0.0, 0.0);
    for p in &pts {
        let d = *p - c;
        sxx += d.x * d.x;
        sxy += d.x * d.y;
        syy += d.y * d.y;
    }
    let angle = 0.5 * (2.0 * sxy).atan2(sxx - syy);
    let mut axis = DVec2::new(angle.cos(), angle.sin());
    if axis.y > 0.0 {
        axis = -axis;
    }
    Some((c, axis))
}

/// Angle of a downward axis from straight down, positive away from the body on `side`
/// (+1 = the subject's left, +X).
fn abduction(axis: DVec2, side: f64) -> f64 {
    (axis.x * side).atan2(-axis.y)
}

/// Rotates arms and legs of `body` (labels from the template) to the observed angles.
pub fn synchronise(body: &mut TriMesh, labels: &[Part], _template: &Template, _scale: f64, obs: &Observation) {
    let Ok(lm) = part_landmarks(body) else { return };
    let limbs = [
        (Part::LeftArm, 1.0, obs.arm_angles.map(|a| a.0), lm.left_armpit),
        (Part::RightArm, -1.0, obs.arm_angles.map(|a| a.1), lm.right_armpit),
        (Part::LeftLeg, 1.0, obs.leg_angles.map(|a| a.0), lm.crotch),
        (Part::RightLeg, -1.0, obs.leg_angles.map(|a| a.1), lm.crotch),
    ];
    for (part, side, target, joint_ref) in limbs {
        let Some(target) = target else { continue };
        let Some((c, axis)) = limb_axis(&body.positions, labels, part) else { continue };
        let delta = (target - abduction(axis, side)) * side;
        if delta.abs() < 1e-3 {
            continue;
        }
        // Pivot: where the limb's axis reaches the joint's height (shoulder: a little
        // above the armpit; hip: the crotch height).
        let is_arm = matches!(part, Part::LeftArm | Part::RightArm);
        let pivot_y = if is_arm { joint_ref.y + 0.06 } else { joint_ref.y };
        let t = (pivot_y - c.y) / axis.y.min(-1e-6);
        let pivot = c + axis * t;
        let rot = DMat3::from_rotation_z(delta);
        for (p, l) in body.positions.iter_mut().zip(labels) {
            let along = (DVec2::new(p.x, p.y) - pivot).dot(axis);
            let own = *l == part;
            let near_joint = *l == Part::Torso && (DVec2::new(p.x, p.y) - pivot).length() < 2.0 * BLEND_HALF_M;
            if !own && !near_joint {
                continue;
            }
            let w = smoothstep((along + BLEND_HALF_M) / (2.0 * BLEND_HALF_M)) * if own { 1.0 } else { 0.5 };
            if w <= 0.0 {
                continue;
            }
            let q = DVec3::new(pivot.x, pivot.y, 0.0);
            let moved = rot * (*p - q) + q;
            let mz = p.z;
            *p = *p * (1.0 - w) + moved * w;
            p.z = mz * (1.0 - w) + moved.z * w;
        }
    }
}

fn smoothstep(x: f64) -> f64 {
    let x = x.clamp(0.0, 1.0);
    x * x * (3.0 - 2.0 * x)
}

/// Vertex groups moved rigidly: head, hands (far end of each arm), feet (low leg part).
pub fn rigid_groups(rest: &[DVec3], labels: &[Part]) -> Vec<Vec<u32>> {
    let miny = rest.iter().map(|p| p.y).fold(f64::MAX, f64::min);
    let maxy = rest.iter().map(|p| p.y).fold(f64::MIN, f64::max);
    let stature = maxy - miny;
    let mut groups = Vec::new();
    groups.push(labels.iter().enumerate().filter(|(_, l)| **l == Part::Head).map(|(i, _)| i as u32).collect::<Vec<_>>());
    for arm in [Part::LeftArm, Part::RightArm] {
        if let Some((c, axis)) = limb_axis(rest, labels, arm) {
            let along: Vec<(u32, f64)> = rest
                .iter()
                .zip(labels)
                .enumerate()
                .filter(|(_, (_, l))| **l == arm)
                .map(|(i, (p, _))| (i as u32, (DVec2::new(p.x, p.y) - c).dot(axis)))
                .collect();
            let lo = along.iter().map(|a| a.1).fold(f64::MAX, f64::min);
            let hi = along.iter().map(|a| a.1).fold(f64::MIN, f64::max);
            let cut = lo + HAND_FRACTION * (hi - lo);
            groups.push(along.iter().filter(|a| a.1 > cut).map(|a| a.0).collect());
        }
    }
    for leg in [Part::LeftLeg, Part::RightLeg] {
        groups.push(
            rest.iter()
                .zip(labels)
                .enumerate()
                .filter(|(_, (p, l))| **l == leg && p.y < miny + FEET_FRACTION * stature)
                .map(|(i, _)| i as u32)
                .collect(),
        );
    }
    groups.retain(|g| g.len() >= 3);
    groups
}

/// Replaces each rigid group of `positions` by the best rigid motion of its `rest` shape.
pub fn restore_rigid_parts(rest: &[DVec3], groups: &[Vec<u32>], positions: &mut [DVec3]) {
    for g in groups {
        let n = g.len() as f64;
        let cr = g.iter().map(|&i| rest[i as usize]).sum::<DVec3>() / n;
        let cp = g.iter().map(|&i| positions[i as usize]).sum::<DVec3>() / n;
        let mut cov = DMat3::ZERO;
        for &i in g {
            let a = rest[i as usize] - cr;
            let b = positions[i as usize] - cp;
            cov += DMat3::from_cols(b * a.x, b * a.y, b * a.z);
        }
        let r = nearest_rotation(cov);
        for &i in g {
            positions[i as usize] = r * (rest[i as usize] - cr) + cp;
        }
    }
}

/// The rotation nearest to `m` (polar decomposition by Newton iterations; falls back to
/// the identity for a degenerate matrix).
pub fn nearest_rotation(m: DMat3) -> DMat3 {
    if m.determinant().abs() < 1e-18 {
        return DMat3::IDENTITY;
    }
    let mut r = m;
    for _ in 0..30 {
        let inv_t = r.inverse().transpose();
        let next = (r + inv_t) * 0.5;
        if (next - r).to_cols_array().iter().map(|x| x.abs()).sum::<f64>() < 1e-13 {
            r = next;
            break;
        }
        r = next;
    }
    if r.determinant() < 0.0 {
        // A reflection: flip the weakest axis (rare, for near-planar groups).
        return DMat3::IDENTITY;
    }
    r
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nearest_rotation_recovers_a_rotation() {
        let r = DMat3::from_rotation_y(0.4) * DMat3::from_rotation_x(-0.2);
        let got = nearest_rotation(r * DMat3::from_diagonal(DVec3::new(2.0, 2.0, 2.0)));
        assert!((got - r).to_cols_array().iter().all(|x| x.abs() < 1e-9));
    }

    #[test]
    fn rigid_restore_is_exact_for_a_rigid_motion() {
        let rest: Vec<DVec3> = (0..20).map(|i| DVec3::new((i as f64).sin(), (i as f64 * 0.7).cos(), i as f64 * 0.05)).collect();
        let r = DMat3::from_rotation_z(0.3);
        let mut moved: Vec<DVec3> = rest.iter().map(|p| r * *p + DVec3::new(0.1, 0.2, 0.3)).collect();
        let truth = moved.clone();
        // Disturb, then restore.
        moved[3] += DVec3::splat(0.01);
        moved[7] -= DVec3::splat(0.01);
        restore_rigid_parts(&rest, &[(0..20).collect()], &mut moved);
        for (a, b) in moved.iter().zip(&truth) {
            assert!((*a - *b).length() < 2e-3);
        }
    }
}
