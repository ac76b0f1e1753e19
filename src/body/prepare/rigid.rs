//! The rigid parts of a template (method.md section 1): the head above the neck's
//! narrowest section, the hands beyond the wrists, the feet below the ankles.

use super::{component, loops_at, Joints, Side, SCAN_STEP_M};
use crate::body::BodyError;
use crate::mesh::TriMesh;
use glam::DVec3;

/// The height of the neck's smallest section (area of the outer loop on the axis; its
/// x-width would pick the chin) between the acromions and the head top.
pub(super) fn neck_cut_y(mesh: &TriMesh, crotch_x: f64, acromion_y: f64, head_top_y: f64) -> f64 {
    let section_area = |y: f64| {
        let a = loops_at(mesh, y)
            .iter()
            .filter(|l| l.xmin <= crotch_x && l.xmax >= crotch_x)
            .map(|l| l.area)
            .fold(0.0, f64::max);
        if a > 0.0 {
            a
        } else {
            f64::INFINITY
        }
    };
    let (mut neck_cut_y, mut best) = (acromion_y, f64::INFINITY);
    let mut y = acromion_y;
    while y < head_top_y {
        let w = section_area(y);
        if w < best {
            best = w;
            neck_cut_y = y;
        }
        y += SCAN_STEP_M;
    }
    neck_cut_y
}

/// Each hand: the part beyond the wrist plane normal to the forearm.
pub(super) fn hands(
    adj: &[Vec<u32>],
    mesh: &TriMesh,
    arm_joints: &[[DVec3; 4]; 2],
    arm_axes: &[Vec<DVec3>; 2],
) -> Result<[Vec<u32>; 2], BodyError> {
    let mut hands = [Vec::new(), Vec::new()];
    for k in 0..2 {
        let (elbow, wrist) = (arm_joints[k][1], arm_joints[k][2]);
        let dir = (wrist - elbow).normalize_or_zero();
        if dir == DVec3::ZERO {
            return Err(BodyError::Prepare("degenerate forearm".into()));
        }
        // Seed: the vertex nearest the arm axis' last sample (among the finger tips; the
        // farthest vertex along the forearm direction could be a toe).
        let end = arm_axes[k].last().copied().unwrap_or(wrist);
        let tip = (0..mesh.vertex_count())
            .filter(|&v| (mesh.positions[v] - wrist).dot(dir) > 0.0)
            .min_by(|&a, &b| {
                (mesh.positions[a] - end)
                    .length_squared()
                    .total_cmp(&(mesh.positions[b] - end).length_squared())
            })
            .ok_or_else(|| BodyError::Prepare("no hand beyond the wrist".into()))?;
        hands[k] = component(adj, mesh, tip, |p| (p - wrist).dot(dir) > 0.0);
    }
    Ok(hands)
}

/// Each foot: the part below its ankle joint, on its side of the body's axis.
pub(super) fn feet(
    adj: &[Vec<u32>],
    mesh: &TriMesh,
    j: &Joints,
    crotch_x: f64,
) -> Result<[Vec<u32>; 2], BodyError> {
    let mut feet = [Vec::new(), Vec::new()];
    for (k, side) in [Side::Left, Side::Right].into_iter().enumerate() {
        let s = side.sign();
        let ay = if k == 0 {
            j.ankle_left.y
        } else {
            j.ankle_right.y
        };
        let low = (0..mesh.vertex_count())
            .filter(|&v| (mesh.positions[v].x - crotch_x) * s > 0.0)
            .min_by(|&a, &b| mesh.positions[a].y.total_cmp(&mesh.positions[b].y))
            .ok_or_else(|| BodyError::Prepare(format!("no {side:?} foot")))?;
        feet[k] = component(adj, mesh, low, |p| p.y < ay && (p.x - crotch_x) * s > 0.0);
    }
    Ok(feet)
}
