//! Body-part labels of template vertices (head, torso, arms, legs), found geometrically
//! from a few landmarks of the template so that any template topology works.
//!
//! Rules (station frame, metres; the template stands in an A-pose, facing +Z):
//! - below the crotch: a leg, split by the sign of x relative to the crotch, unless the
//!   vertex belongs to a hanging hand (connected to the arm, see below);
//! - above the neck: the head;
//! - between: an arm when it lies outside the torso's side planes, which run vertically
//!   through the armpits and, above them, through the acromions' inner... i.e. the
//!   armpit x; the torso otherwise.
//!
//! Hands hanging below the crotch are recognised by connectivity: a vertex below the
//! crotch is a leg only if it is connected to the sole of its side through vertices below
//! the crotch.

use super::correspond::Part;
use crate::mesh::{OneRings, TriMesh};
use glam::DVec3;

/// How far below the armpits the arms are taken as separate from the trunk, metres.
const ARM_GAP_BELOW_ARMPIT_M: f64 = 0.03;
/// Half-width of the band around the body axis that only the trunk reaches, metres.
const AXIS_HALF_WIDTH_M: f64 = 0.05;

/// The landmarks part labelling needs (station frame, metres).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PartLandmarks {
    pub crotch: DVec3,
    pub left_armpit: DVec3,
    pub right_armpit: DVec3,
    /// Height of the neck joint (base of the head).
    pub neck_y: f64,
}

/// Labels every vertex of `mesh` with its body part.
pub fn label_parts(mesh: &TriMesh, rings: &OneRings, lm: &PartLandmarks) -> Vec<Part> {
    let n = mesh.vertex_count();
    let mut labels = vec![Part::Torso; n];
    // Legs by connectivity below the crotch from the lowest vertex of each side.
    let mut is_leg = vec![false; n];
    for side in [1.0f64, -1.0] {
        let seed = (0..n)
            .filter(|&v| (mesh.positions[v].x - lm.crotch.x) * side > 0.0)
            .min_by(|&a, &b| mesh.positions[a].y.total_cmp(&mesh.positions[b].y));
        let Some(seed) = seed else { continue };
        let mut stack = vec![seed];
        is_leg[seed] = true;
        while let Some(v) = stack.pop() {
            for &w in rings.neighbours(v) {
                let w = w as usize;
                if !is_leg[w] && mesh.positions[w].y < lm.crotch.y {
                    is_leg[w] = true;
                    stack.push(w);
                }
            }
        }
    }
    // Below the armpits (A-pose) the arms are separate from the trunk: a component of the
    // non-leg vertices there that never comes near the body axis is an arm (this catches
    // fingers that reach inside the armpits' x range, beside the hips).
    let below_y = lm.left_armpit.y.min(lm.right_armpit.y) - ARM_GAP_BELOW_ARMPIT_M;
    let in_low = |v: usize| !is_leg[v] && mesh.positions[v].y < below_y;
    let mut is_low_arm = vec![false; n];
    let mut is_low_trunk = vec![false; n];
    let mut seen = vec![false; n];
    let mut comp = Vec::new();
    for start in 0..n {
        if seen[start] || !in_low(start) {
            continue;
        }
        comp.clear();
        seen[start] = true;
        comp.push(start);
        let mut k = 0;
        while k < comp.len() {
            let v = comp[k];
            k += 1;
            for &w in rings.neighbours(v) {
                let w = w as usize;
                if !seen[w] && in_low(w) {
                    seen[w] = true;
                    comp.push(w);
                }
            }
        }
        let on_axis = comp
            .iter()
            .any(|&v| (mesh.positions[v].x - lm.crotch.x).abs() < AXIS_HALF_WIDTH_M);
        for &v in &comp {
            if on_axis {
                is_low_trunk[v] = true;
            } else {
                is_low_arm[v] = true;
            }
        }
    }
    for (v, p) in mesh.positions.iter().enumerate() {
        labels[v] = if is_leg[v] {
            if p.x >= lm.crotch.x {
                Part::LeftLeg
            } else {
                Part::RightLeg
            }
        } else if p.y > lm.neck_y && p.x.abs() < (lm.left_armpit.x - lm.right_armpit.x).abs() * 0.5
        {
            Part::Head
        } else if is_low_arm[v] {
            if p.x >= lm.crotch.x {
                Part::LeftArm
            } else {
                Part::RightArm
            }
        } else if is_low_trunk[v] {
            // Wide hips reach beyond the armpits' x: still the trunk.
            Part::Torso
        } else if p.x > lm.left_armpit.x {
            Part::LeftArm
        } else if p.x < lm.right_armpit.x {
            Part::RightArm
        } else if p.y < lm.crotch.y {
            // Below the crotch but not connected to a sole: a hand near the thigh.
            if p.x >= lm.crotch.x {
                Part::LeftArm
            } else {
                Part::RightArm
            }
        } else {
            Part::Torso
        };
    }
    labels
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::shapes;

    #[test]
    fn cylinder_legs_and_torso() {
        // Two leg cylinders joined to nothing: each is its own leg.
        let mut a = shapes::elliptic_cylinder(0.06, 0.06, 0.8, 8, 16);
        a.map_positions(|p| p + DVec3::new(0.1, 0.0, 0.0));
        let mut b = shapes::elliptic_cylinder(0.06, 0.06, 0.8, 8, 16);
        b.map_positions(|p| p + DVec3::new(-0.1, 0.0, 0.0));
        let off = a.positions.len() as u32;
        let mut m = a.clone();
        m.positions.extend(b.positions);
        m.triangles
            .extend(b.triangles.iter().map(|t| t.map(|i| i + off)));
        let lm = PartLandmarks {
            crotch: DVec3::new(0.0, 0.9, 0.0),
            left_armpit: DVec3::new(0.2, 1.3, 0.0),
            right_armpit: DVec3::new(-0.2, 1.3, 0.0),
            neck_y: 1.5,
        };
        let l = label_parts(&m, &m.one_rings(), &lm);
        assert!(l[..off as usize].iter().all(|p| *p == Part::LeftLeg));
        assert!(l[off as usize..].iter().all(|p| *p == Part::RightLeg));
    }
}
