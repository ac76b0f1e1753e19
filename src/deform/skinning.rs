//! Linear blend skinning on a template skeleton, for large pose differences before the
//! fine mean value fit (method.md section 3; Kazmi et al. 2015 eq. 1:
//! `V_c = sum_i W_i M_i,c M_i,d^-1 V_d`). Metres, the mesh's frame.
//!
//! # Conventions
//! - A skeleton is a list of named joints with positions and parent indices (a forest).
//! - Joint `j` owns the segments from itself to each of its children (rotating the elbow
//!   moves the forearm); a leaf joint owns the point where it sits. One bone transform
//!   per joint, `bone_transforms[j] = M_j,c M_j,d^-1`, maps rest positions to posed ones.
//! - Skinning weights are geometric: inverse fourth power of the distance to the joint's
//!   segments (plus a millimetre so a vertex on a bone stays finite), the
//!   [`MAX_INFLUENCES`] largest kept and normalised to sum to one. Smooth across the
//!   Voronoi boundaries between bones; no diffusion over the mesh, so a vertex close to a
//!   wrong limb (a hand near the thigh) can borrow its weight: pose the template with
//!   arms away from the body, as the station's A-pose does.

use crate::mesh::TriMesh;
use glam::{DAffine3, DMat3, DQuat, DVec3};

/// Most joints influencing one vertex.
pub const MAX_INFLUENCES: usize = 4;
/// Falloff exponent of the distance weights.
const FALLOFF_POWER: i32 = 4;
/// Distance added before the falloff so vertices on a bone stay finite, metres.
const FALLOFF_OFFSET_M: f64 = 1e-3;

/// One joint of a skeleton.
#[derive(Debug, Clone, PartialEq)]
pub struct Joint {
    pub name: String,
    /// Rest position, metres.
    pub position: DVec3,
    /// Index of the parent joint; `None` for a root.
    pub parent: Option<usize>,
}

/// A template skeleton: named joints and their hierarchy.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Skeleton {
    pub joints: Vec<Joint>,
}

/// Errors of skeleton construction and posing.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum SkeletonError {
    #[error("joint {joint} ({name}) names parent {parent}, which does not exist")]
    BadParent {
        joint: usize,
        name: String,
        parent: usize,
    },
    #[error("the hierarchy has a cycle through joint {0}")]
    Cycle(usize),
    #[error("joint {0} has a non-finite position")]
    NonFinite(usize),
    #[error("{got} posed joint positions for {expected} joints")]
    PoseCount { got: usize, expected: usize },
    #[error("no joint named {0}")]
    UnknownJoint(String),
}

impl Skeleton {
    /// Checks parents (in range, no cycle) and positions.
    ///
    /// # Errors
    /// [`SkeletonError`] naming the offending joint.
    pub fn new(joints: Vec<Joint>) -> Result<Self, SkeletonError> {
        for (j, joint) in joints.iter().enumerate() {
            if !joint.position.is_finite() {
                return Err(SkeletonError::NonFinite(j));
            }
            if let Some(p) = joint.parent {
                if p >= joints.len() {
                    return Err(SkeletonError::BadParent {
                        joint: j,
                        name: joint.name.clone(),
                        parent: p,
                    });
                }
            }
        }
        for start in 0..joints.len() {
            let mut cur = joints[start].parent;
            let mut steps = 0;
            while let Some(p) = cur {
                steps += 1;
                if steps > joints.len() {
                    return Err(SkeletonError::Cycle(start));
                }
                cur = joints[p].parent;
            }
        }
        Ok(Skeleton { joints })
    }

    /// Index of the joint called `name`.
    pub fn index_of(&self, name: &str) -> Result<usize, SkeletonError> {
        self.joints
            .iter()
            .position(|j| j.name == name)
            .ok_or_else(|| SkeletonError::UnknownJoint(name.to_string()))
    }

    /// Children of joint `j`.
    pub fn children(&self, j: usize) -> impl Iterator<Item = usize> + '_ {
        self.joints
            .iter()
            .enumerate()
            .filter(move |(_, k)| k.parent == Some(j))
            .map(|(i, _)| i)
    }
}

/// Skinning weights: per vertex up to [`MAX_INFLUENCES`] (joint, weight) pairs summing to
/// one; unused slots have weight zero.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct SkinWeights {
    pub joints: Vec<[u32; MAX_INFLUENCES]>,
    pub weights: Vec<[f64; MAX_INFLUENCES]>,
}

impl SkinWeights {
    pub fn vertex_count(&self) -> usize {
        self.weights.len()
    }
}

fn segment_distance(p: DVec3, a: DVec3, b: DVec3) -> f64 {
    let ab = b - a;
    let len2 = ab.length_squared();
    let t = if len2 > 0.0 {
        ((p - a).dot(ab) / len2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    (p - (a + t * ab)).length()
}

/// Geometric skinning weights of `mesh` on `skel` (see the module docs). A skeleton
/// without joints gives zero weights (and [`linear_blend`] then copies the rest pose).
pub fn skin_weights(mesh: &TriMesh, skel: &Skeleton) -> SkinWeights {
    let nj = skel.joints.len();
    // Segments owned by each joint.
    let mut segments: Vec<(usize, DVec3, DVec3)> = Vec::new();
    for (j, joint) in skel.joints.iter().enumerate() {
        let mut has_child = false;
        for c in skel.children(j) {
            segments.push((j, joint.position, skel.joints[c].position));
            has_child = true;
        }
        if !has_child {
            segments.push((j, joint.position, joint.position));
        }
    }
    let n = mesh.positions.len();
    let mut out = SkinWeights {
        joints: vec![[0; MAX_INFLUENCES]; n],
        weights: vec![[0.0; MAX_INFLUENCES]; n],
    };
    if nj == 0 {
        return out;
    }
    let mut dist = vec![f64::INFINITY; nj];
    for (v, &p) in mesh.positions.iter().enumerate() {
        dist.iter_mut().for_each(|d| *d = f64::INFINITY);
        for &(j, a, b) in &segments {
            dist[j] = dist[j].min(segment_distance(p, a, b));
        }
        // The MAX_INFLUENCES nearest joints.
        let mut best: [(f64, u32); MAX_INFLUENCES] = [(f64::INFINITY, 0); MAX_INFLUENCES];
        for (j, &d) in dist.iter().enumerate() {
            if d < best[MAX_INFLUENCES - 1].0 {
                let mut k = MAX_INFLUENCES - 1;
                while k > 0 && best[k - 1].0 > d {
                    best[k] = best[k - 1];
                    k -= 1;
                }
                best[k] = (d, j as u32);
            }
        }
        let mut sum = 0.0;
        let mut w = [0.0; MAX_INFLUENCES];
        for (k, &(d, _)) in best.iter().enumerate() {
            if d.is_finite() {
                w[k] = (d + FALLOFF_OFFSET_M).powi(-FALLOFF_POWER);
                sum += w[k];
            }
        }
        for k in 0..MAX_INFLUENCES {
            out.joints[v][k] = best[k].1;
            out.weights[v][k] = if sum > 0.0 && sum.is_finite() {
                w[k] / sum
            } else if k == 0 {
                1.0
            } else {
                0.0
            };
        }
    }
    out
}

/// Linear blend skinning: `out_v = sum_k w_vk T_k(rest_v)` (Kazmi et al. eq. 1).
/// `bone_transforms` has one rest-to-posed transform per joint; a joint index beyond it
/// counts as the identity. Writes `min(rest.len(), w.vertex_count(), out.len())` vertices.
pub fn linear_blend(
    rest: &[DVec3],
    w: &SkinWeights,
    bone_transforms: &[DAffine3],
    out: &mut [DVec3],
) {
    let n = rest.len().min(w.vertex_count()).min(out.len());
    for v in 0..n {
        let p = rest[v];
        let mut acc = DVec3::ZERO;
        let mut wsum = 0.0;
        for k in 0..MAX_INFLUENCES {
            let wk = w.weights[v][k];
            if wk == 0.0 {
                continue;
            }
            let q = bone_transforms
                .get(w.joints[v][k] as usize)
                .map_or(p, |t| t.transform_point3(p));
            acc += wk * q;
            wsum += wk;
        }
        out[v] = if wsum > 0.0 { acc / wsum } else { p };
    }
}

/// Rest-to-posed bone transforms from posed joint positions: joint `j` rotates by the
/// smallest rotation taking its rest child direction (the mean over its children) to the
/// posed one and carries its rest position to the posed one; a leaf takes its parent's
/// rotation. Bone length changes are not modelled (the fine fit absorbs them).
///
/// # Errors
/// [`SkeletonError::PoseCount`] when the counts differ, [`SkeletonError::NonFinite`].
pub fn pose_bone_transforms(
    skel: &Skeleton,
    posed: &[DVec3],
) -> Result<Vec<DAffine3>, SkeletonError> {
    let nj = skel.joints.len();
    if posed.len() != nj {
        return Err(SkeletonError::PoseCount {
            got: posed.len(),
            expected: nj,
        });
    }
    if let Some(j) = posed.iter().position(|p| !p.is_finite()) {
        return Err(SkeletonError::NonFinite(j));
    }
    let mut rot: Vec<Option<DQuat>> = vec![None; nj];
    for j in 0..nj {
        let mut rest_dir = DVec3::ZERO;
        let mut posed_dir = DVec3::ZERO;
        for c in skel.children(j) {
            rest_dir += (skel.joints[c].position - skel.joints[j].position).normalize_or_zero();
            posed_dir += (posed[c] - posed[j]).normalize_or_zero();
        }
        if rest_dir.length() > 0.0 && posed_dir.length() > 0.0 {
            rot[j] = Some(DQuat::from_rotation_arc(
                rest_dir.normalize(),
                posed_dir.normalize(),
            ));
        }
    }
    // Leaves (and joints whose children sit on them) inherit the nearest ancestor's rotation.
    let mut out = Vec::with_capacity(nj);
    for j in 0..nj {
        let mut q = rot[j];
        let mut cur = skel.joints[j].parent;
        let mut steps = 0;
        while q.is_none() {
            match cur {
                Some(p) if steps <= nj => {
                    q = rot[p];
                    cur = skel.joints[p].parent;
                    steps += 1;
                }
                _ => break,
            }
        }
        let m = DMat3::from_quat(q.unwrap_or(DQuat::IDENTITY));
        let t = posed[j] - m * skel.joints[j].position;
        out.push(DAffine3::from_mat3_translation(m, t));
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::shapes;

    fn arm() -> Skeleton {
        Skeleton::new(vec![
            Joint {
                name: "shoulder".into(),
                position: DVec3::new(0.0, 0.0, 0.0),
                parent: None,
            },
            Joint {
                name: "elbow".into(),
                position: DVec3::new(0.0, 0.5, 0.0),
                parent: Some(0),
            },
            Joint {
                name: "wrist".into(),
                position: DVec3::new(0.0, 1.0, 0.0),
                parent: Some(1),
            },
        ])
        .unwrap()
    }

    #[test]
    fn weights_sum_to_one_and_follow_the_nearest_bone() {
        let m = shapes::elliptic_cylinder(0.05, 0.05, 1.0, 20, 12);
        let w = skin_weights(&m, &arm());
        for v in 0..m.vertex_count() {
            let s: f64 = w.weights[v].iter().sum();
            assert!((s - 1.0).abs() < 1e-12);
            let y = m.positions[v].y;
            if y < 0.3 {
                assert_eq!(w.joints[v][0], 0, "vertex at y {y}");
            } else if y > 0.55 && y < 0.95 {
                assert_eq!(w.joints[v][0], 1, "vertex at y {y}");
            }
        }
    }

    #[test]
    fn posing_a_straight_arm_unchanged_gives_identities() {
        let s = arm();
        let posed: Vec<DVec3> = s.joints.iter().map(|j| j.position).collect();
        for t in pose_bone_transforms(&s, &posed).unwrap() {
            assert!(t.abs_diff_eq(DAffine3::IDENTITY, 1e-12));
        }
    }

    #[test]
    fn bad_hierarchies_are_rejected() {
        let j = |p| Joint {
            name: "a".into(),
            position: DVec3::ZERO,
            parent: p,
        };
        assert!(matches!(
            Skeleton::new(vec![j(Some(3))]),
            Err(SkeletonError::BadParent { .. })
        ));
        assert!(matches!(
            Skeleton::new(vec![j(Some(1)), j(Some(0))]),
            Err(SkeletonError::Cycle(_))
        ));
    }
}
