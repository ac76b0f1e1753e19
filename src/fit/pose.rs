//! Template landmarks, pose synchronisation and rigid parts.
//!
//! - Landmarks of a template are found on its own orthographic front silhouette with the
//!   paper's zones (method.md section 1): crotch = apex of the gap between the legs,
//!   armpits = apexes of the gaps between arms and torso, h = stature / 7.
//! - Pose synchronisation (the paper defers to skeleton-based synchronisation; Kazmi et al.
//!   use linear blend skinning): each arm is rotated about its shoulder, in the front (XY)
//!   plane, so that its axis takes the angle seen in the silhouettes; each leg is sheared
//!   sideways about its hip to the same effect, which keeps the feet flat on the floor. Skinning weights fall off smoothly across the joint so the shoulder and
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

/// Half-width of the blend zone of the skinning weights across a joint, metres.
const BLEND_HALF_M: f64 = 0.06;
/// Template vertices averaged to carry a joint from the template to a library body.
const JOINT_ANCHORS: usize = 12;

/// Part landmarks of the library's template, from its sidecar (`fitstation templates
/// prepare`).
pub fn template_part_landmarks(t: &Template) -> Result<PartLandmarks, String> {
    let lm = &t.info.landmarks;
    if !(lm.crotch_y > 0.0 && lm.armpit_y > lm.crotch_y && lm.neck_cut_y > lm.armpit_y) {
        return Err("the template's sidecar has no usable crotch/armpit/neck landmarks: run `fitstation templates prepare`".into());
    }
    Ok(PartLandmarks {
        crotch: lm.crotch,
        left_armpit: lm.armpit_left,
        right_armpit: lm.armpit_right,
        neck_y: lm.neck_cut_y,
    })
}

/// A joint carried by the template's vertices: the centroid of its nearest vertices plus
/// the offset, so it follows the body through shape changes (all library bodies share
/// the template's vertex order).
#[derive(Debug, Clone)]
pub struct JointAnchor {
    vertices: Vec<u32>,
    offset: DVec3,
}

impl JointAnchor {
    pub fn new(template: &[DVec3], joint: DVec3) -> Self {
        let mut idx: Vec<u32> = (0..template.len() as u32).collect();
        idx.sort_by(|&a, &b| {
            (template[a as usize] - joint)
                .length_squared()
                .total_cmp(&(template[b as usize] - joint).length_squared())
        });
        idx.truncate(JOINT_ANCHORS);
        let c = idx.iter().map(|&i| template[i as usize]).sum::<DVec3>() / idx.len().max(1) as f64;
        JointAnchor {
            vertices: idx,
            offset: joint - c,
        }
    }
    /// The joint on a body with the template's vertex order, scaled by `scale`.
    pub fn on(&self, positions: &[DVec3], scale: f64) -> DVec3 {
        let c = self
            .vertices
            .iter()
            .map(|&i| positions[i as usize])
            .sum::<DVec3>()
            / self.vertices.len().max(1) as f64;
        c + self.offset * scale
    }
}

/// Shoulder and hip joints of the template, carried to any library body.
#[derive(Debug, Clone)]
pub struct PoseJoints {
    pub shoulder_left: JointAnchor,
    pub shoulder_right: JointAnchor,
    pub hip_left: JointAnchor,
    pub hip_right: JointAnchor,
}

impl PoseJoints {
    pub fn new(t: &Template) -> Self {
        let j = &t.info.joints;
        let p = &t.mesh.positions;
        PoseJoints {
            shoulder_left: JointAnchor::new(p, j.shoulder_left),
            shoulder_right: JointAnchor::new(p, j.shoulder_right),
            hip_left: JointAnchor::new(p, j.thigh_root_left),
            hip_right: JointAnchor::new(p, j.thigh_root_right),
        }
    }
}

/// Principal axis (in the XY plane) and centroid of a set of vertices, axis pointing down.
fn limb_axis(positions: &[DVec3], labels: &[Part], part: Part) -> Option<(DVec2, DVec2)> {
    let pts: Vec<DVec2> = positions
        .iter()
        .zip(labels)
        .filter(|(_, l)| **l == part)
        .map(|(p, _)| DVec2::new(p.x, p.y))
        .collect();
    if pts.len() < 10 {
        return None;
    }
    let (c, mut axis) = crate::landmarks::zones::principal_axis(&pts)?;
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

/// Rotates arms and legs of `body` (labels from the template) about the shoulder and
/// hip joints to the observed abduction angles (linear blend skinning with two bones per
/// limb: the trunk with the identity, the limb with the rotation; weights blend across
/// the joint).
pub fn synchronise(
    body: &mut TriMesh,
    labels: &[Part],
    joints: &PoseJoints,
    scale: f64,
    obs: &Observation,
) {
    let limbs = [
        (
            Part::LeftArm,
            1.0,
            obs.arm_angles.map(|a| a.0),
            joints.shoulder_left.on(&body.positions, scale),
        ),
        (
            Part::RightArm,
            -1.0,
            obs.arm_angles.map(|a| a.1),
            joints.shoulder_right.on(&body.positions, scale),
        ),
        (
            Part::LeftLeg,
            1.0,
            obs.leg_angles.map(|a| a.0),
            joints.hip_left.on(&body.positions, scale),
        ),
        (
            Part::RightLeg,
            -1.0,
            obs.leg_angles.map(|a| a.1),
            joints.hip_right.on(&body.positions, scale),
        ),
    ];
    for (part, side, target, joint) in limbs {
        let leg = matches!(part, Part::LeftLeg | Part::RightLeg);
        let Some(target) = target else { continue };
        let Some((_, axis)) = limb_axis(&body.positions, labels, part) else {
            continue;
        };
        let delta = (target - abduction(axis, side)) * side;
        if delta.abs() < 1e-3 || delta.abs() > MAX_POSE_CHANGE_RAD {
            continue;
        }
        let pivot = DVec2::new(joint.x, joint.y);
        let rot = DMat3::from_rotation_z(delta);
        let q = DVec3::new(joint.x, joint.y, 0.0);
        for (p, l) in body.positions.iter_mut().zip(labels) {
            let rel = DVec2::new(p.x, p.y) - pivot;
            let own = *l == part;
            let near_joint = *l == Part::Torso && rel.length() < 2.0 * BLEND_HALF_M;
            if !own && !near_joint {
                continue;
            }
            let along = rel.dot(axis);
            let w = smoothstep((along + BLEND_HALF_M) / (2.0 * BLEND_HALF_M))
                * if own { 1.0 } else { 0.5 };
            if w <= 0.0 {
                continue;
            }
            // Legs are sheared sideways rather than turned: a subject who stands with the
            // feet further apart keeps them flat on the floor (turned, the feet tilt and
            // rise: the avatar floated up to 10 mm and its stature came out short).
            let moved = if leg {
                DVec3::new(p.x + delta.tan() * (joint.y - p.y), p.y, p.z)
            } else {
                rot * (*p - q) + q
            };
            *p = *p * (1.0 - w) + moved * w;
        }
    }
}

/// Largest arm/leg rotation pose synchronisation applies (beyond it the landmarks are
/// more likely wrong than the pose that different).
const MAX_POSE_CHANGE_RAD: f64 = 0.6;

fn smoothstep(x: f64) -> f64 {
    let x = x.clamp(0.0, 1.0);
    x * x * (3.0 - 2.0 * x)
}

/// Vertex groups moved rigidly (head, hands, feet), from the template's sidecar.
pub fn rigid_groups(t: &Template) -> Vec<Vec<u32>> {
    let r = &t.info.rigid;
    let n = t.mesh.vertex_count() as u32;
    [
        &r.head,
        &r.hand_left,
        &r.hand_right,
        &r.foot_left,
        &r.foot_right,
    ]
    .into_iter()
    .map(|g| g.iter().copied().filter(|&i| i < n).collect::<Vec<u32>>())
    .filter(|g| g.len() >= 3)
    .collect()
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
        if (next - r)
            .to_cols_array()
            .iter()
            .map(|x| x.abs())
            .sum::<f64>()
            < 1e-13
        {
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

/// Shortest and longest reach of the arm samples from the shoulder, fractions of stature.
const ARM_SAMPLE_REACH: (f64, f64) = (0.08, 0.24);
/// Samples along one candidate arm direction.
const ARM_SAMPLES: usize = 16;
/// Step and range of the abduction search, radians.
const ARM_ANGLE_STEP: f64 = 0.01;
const ARM_ANGLE_RANGE: (f64, f64) = (0.12, 1.4);
/// Fraction of the samples that must fall inside the silhouette for a direction to lie
/// along the arm.
const ARM_INSIDE_FRACTION: f64 = 0.85;

/// Arm abduction seen in the front silhouette, for when the landmarks give none: from
/// each shoulder joint, directions in the front (XY) plane are swept from nearly
/// horizontal downward; the first run of directions whose ray stays inside the silhouette
/// is the arm, and its middle is the arm's axis. None for an arm whose run reaches the
/// torso (arm against the body: no gap to tell them apart).
pub fn observed_arm_angles(
    front: (&crate::camera::Camera, super::correspond::MaskRef<'_>),
    shoulders: [DVec3; 2],
    stature_m: f64,
) -> Option<(f64, f64)> {
    let (cam, mask) = front;
    let mut out = [0.0f64; 2];
    for (k, (side, j)) in [(1.0f64, shoulders[0]), (-1.0, shoulders[1])]
        .into_iter()
        .enumerate()
    {
        let inside = |theta: f64| -> bool {
            let d = DVec3::new(side * theta.sin(), -theta.cos(), 0.0);
            let mut hits = 0;
            for i in 0..ARM_SAMPLES {
                let f = i as f64 / (ARM_SAMPLES - 1) as f64;
                let s = (ARM_SAMPLE_REACH.0 + f * (ARM_SAMPLE_REACH.1 - ARM_SAMPLE_REACH.0))
                    * stature_m;
                if cam
                    .project(j + d * s)
                    .map(|px| mask.occupancy(px) >= 0.5)
                    .unwrap_or(false)
                {
                    hits += 1;
                }
            }
            hits as f64 >= ARM_INSIDE_FRACTION * ARM_SAMPLES as f64
        };
        let mut theta = ARM_ANGLE_RANGE.1;
        let mut run: Option<(f64, f64)> = None;
        while theta >= ARM_ANGLE_RANGE.0 {
            if inside(theta) {
                run = Some(run.map_or((theta, theta), |r| (theta, r.1)));
            } else if run.is_some() {
                break;
            }
            theta -= ARM_ANGLE_STEP;
        }
        let (lo, hi) = run?;
        if lo < ARM_ANGLE_RANGE.0 + ARM_ANGLE_STEP {
            return None;
        }
        out[k] = 0.5 * (lo + hi);
    }
    Some((out[0], out[1]))
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

    /// Legs set further apart than the template's are sheared: the feet move out and
    /// stay at floor height, the head does not move; arms turned out rise at the hand.
    #[test]
    fn synchronised_legs_keep_the_feet_on_the_floor() {
        let lib = crate::body::ShapeLibrary::shared().expect("the bundled shape library");
        let t = lib.template();
        let lm = template_part_landmarks(t).expect("landmarks");
        let labels = super::super::parts::label_parts(&t.mesh, &t.mesh.one_rings(), &lm);
        let joints = PoseJoints::new(t);
        let mut body = t.mesh.clone();
        let angle = |m: &TriMesh, part: Part, side: f64| {
            let (_, axis) = limb_axis(&m.positions, &labels, part).expect("limb");
            abduction(axis, side)
        };
        let (legs, arms) = (
            (
                angle(&body, Part::LeftLeg, 1.0),
                angle(&body, Part::RightLeg, -1.0),
            ),
            (
                angle(&body, Part::LeftArm, 1.0),
                angle(&body, Part::RightArm, -1.0),
            ),
        );
        let obs = Observation {
            arm_angles: Some((arms.0 + 0.15, arms.1 + 0.15)),
            leg_angles: Some((legs.0 + 0.07, legs.1 + 0.07)),
            ..Observation::new(t.info.stature_m, DVec3::ZERO)
        };
        synchronise(&mut body, &labels, &joints, 1.0, &obs);
        let low = |m: &TriMesh| m.positions.iter().map(|p| p.y).fold(f64::MAX, f64::min);
        let high = |m: &TriMesh| m.positions.iter().map(|p| p.y).fold(f64::MIN, f64::max);
        assert!((low(&body) - low(&t.mesh)).abs() < 1e-4, "soles moved");
        assert!((high(&body) - high(&t.mesh)).abs() < 1e-4, "head moved");
        let l = angle(&body, Part::LeftLeg, 1.0);
        assert!(
            (l - (legs.0 + 0.07)).abs() < 0.02,
            "left leg {l} want {}",
            legs.0 + 0.07
        );
        let a = angle(&body, Part::LeftArm, 1.0);
        assert!(
            (a - (arms.0 + 0.15)).abs() < 0.03,
            "left arm {a} want {}",
            arms.0 + 0.15
        );
    }

    #[test]
    fn rigid_restore_is_exact_for_a_rigid_motion() {
        let rest: Vec<DVec3> = (0..20)
            .map(|i| DVec3::new((i as f64).sin(), (i as f64 * 0.7).cos(), i as f64 * 0.05))
            .collect();
        let r = DMat3::from_rotation_z(0.3);
        let mut moved: Vec<DVec3> = rest
            .iter()
            .map(|p| r * *p + DVec3::new(0.1, 0.2, 0.3))
            .collect();
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
