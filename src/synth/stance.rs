//! A varied stance for synthetic subjects (`synth-set --stance varied`).
//!
//! People do not stand in the template's A-pose: per subject, drawn from the seed, the
//! arms are raised or lowered at the shoulders (abduction in the front plane,
//! [`ARM_ABDUCTION_DEG`] from rest, each side its own), the elbows bent
//! ([`ELBOW_FLEXION_DEG`], the forearm swinging forward towards +Z about a hinge
//! perpendicular to the upper arm, so that in the side view forearm and hand come in
//! front of the belly and thigh), the legs set apart or together ([`LEG_ABDUCTION_DEG`],
//! both alike) and the whole body turned about the vertical through the mark (up to
//! [`YAW_DEG`]).
//!
//! # Skinning
//! Not the fit's own linear blend skinning (`fit::pose`), on purpose: every vertex gets
//! its own rotation about the joint, whose *angle* is the joint's angle times a weight
//! that rises smoothly (smoothstep) with the vertex's distance along the limb across
//! the joint, over a wide blend ([`SHOULDER_BLEND_HALF_M`], [`HIP_BLEND_HALF_M`]);
//! rotations are interpolated, not matrices, so the joint bends without the volume loss
//! of blended matrices. Joints are chained from the hand up: elbow then shoulder,
//! ankle then hip. The ankle turns back by the hip's angle, so the feet stay flat; the
//! body is then put back on the floor and on the mark (feet's midpoint) before the turn.
//! Joints are the template's (sidecar skeleton), carried to the body by nearby
//! vertices. Head, hands and feet move rigidly (their weights are 0 or 1).
//!
//! # Conventions
//! Canonical body frame (metres, soles on y = 0, facing +Z, +X the subject's left); a
//! positive abduction moves the limb away from the body; a positive yaw turns the
//! subject's front from +Z towards +X (a right-handed rotation about +Y).

use super::rng::SplitMix64;
use super::subject::{part_labels, SubjectError};
use crate::body::Template;
use crate::fit::correspond::Part;
use crate::fit::pose::JointAnchor;
use crate::mesh::TriMesh;
use glam::{DMat3, DVec3};

/// Range of the arms' abduction from rest, degrees.
pub const ARM_ABDUCTION_DEG: (f64, f64) = (-12.0, 10.0);
/// Range of the elbows' flexion from rest, degrees.
pub const ELBOW_FLEXION_DEG: (f64, f64) = (0.0, 15.0);
/// Range of the legs' abduction from rest, degrees.
pub const LEG_ABDUCTION_DEG: (f64, f64) = (-3.0, 4.0);
/// Largest turn of the whole body, degrees.
pub const YAW_DEG: f64 = 4.0;
/// Half-widths of the blends along the limb across the joints, metres.
pub const SHOULDER_BLEND_HALF_M: f64 = 0.10;
pub const ELBOW_BLEND_HALF_M: f64 = 0.04;
pub const HIP_BLEND_HALF_M: f64 = 0.08;
pub const ANKLE_BLEND_HALF_M: f64 = 0.03;
/// Share of the limb's rotation the trunk takes next to the shoulder or hip.
const TRUNK_SHARE: f64 = 0.35;
/// Stream label of the stance draw.
const STANCE_STREAM: u64 = 0x57A4CE;

/// A drawn stance (recorded in truth.json as `stance`). Pairs are (left, right).
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Stance {
    pub arm_abduction_deg: [f64; 2],
    pub elbow_flexion_deg: [f64; 2],
    pub leg_abduction_deg: f64,
    pub yaw_deg: f64,
}

impl Stance {
    /// The rest stance turned on the mark by `yaw_deg` (`synth --turn-deg`).
    pub fn turned(yaw_deg: f64) -> Stance {
        Stance {
            arm_abduction_deg: [0.0, 0.0],
            elbow_flexion_deg: [0.0, 0.0],
            leg_abduction_deg: 0.0,
            yaw_deg,
        }
    }

    /// The stance of `seed` (deterministic).
    pub fn sample(seed: u64) -> Stance {
        let mut rng = SplitMix64::stream(seed, STANCE_STREAM);
        let mut arm = || rng.range(ARM_ABDUCTION_DEG.0, ARM_ABDUCTION_DEG.1);
        let arm_abduction_deg = [arm(), arm()];
        let elbow_flexion_deg = [
            rng.range(ELBOW_FLEXION_DEG.0, ELBOW_FLEXION_DEG.1),
            rng.range(ELBOW_FLEXION_DEG.0, ELBOW_FLEXION_DEG.1),
        ];
        Stance {
            arm_abduction_deg,
            elbow_flexion_deg,
            leg_abduction_deg: rng.range(LEG_ABDUCTION_DEG.0, LEG_ABDUCTION_DEG.1),
            yaw_deg: rng.range(-YAW_DEG, YAW_DEG),
        }
    }
}

/// The template's limb joints of one side, carried to a body.
#[derive(Debug, Clone)]
pub struct LimbJoints {
    pub shoulder: DVec3,
    pub elbow: DVec3,
    pub wrist: DVec3,
    pub hip: DVec3,
    pub knee: DVec3,
    pub ankle: DVec3,
}

/// Anchors of the template's joints (left, right).
struct JointAnchors {
    stature: f64,
    sides: [[JointAnchor; 6]; 2],
}

impl JointAnchors {
    fn new(t: &Template) -> JointAnchors {
        let p = &t.mesh.positions;
        let j = &t.info.joints;
        let side = |s: [DVec3; 6]| s.map(|q| JointAnchor::new(p, q));
        JointAnchors {
            stature: t.info.stature_m,
            sides: [
                side([
                    j.shoulder_left,
                    j.elbow_left,
                    j.wrist_left,
                    j.thigh_root_left,
                    j.knee_left,
                    j.ankle_left,
                ]),
                side([
                    j.shoulder_right,
                    j.elbow_right,
                    j.wrist_right,
                    j.thigh_root_right,
                    j.knee_right,
                    j.ankle_right,
                ]),
            ],
        }
    }
    fn on(&self, positions: &[DVec3], stature: f64) -> [LimbJoints; 2] {
        let s = stature / self.stature.max(1e-6);
        [0, 1].map(|i| {
            let [a, b, c, d, e, f] = &self.sides[i];
            LimbJoints {
                shoulder: a.on(positions, s),
                elbow: b.on(positions, s),
                wrist: c.on(positions, s),
                hip: d.on(positions, s),
                knee: e.on(positions, s),
                ankle: f.on(positions, s),
            }
        })
    }
}

/// The joints of a body in the template's vertex order (left, right).
pub fn limb_joints(mesh: &TriMesh, template: &Template) -> Option<[LimbJoints; 2]> {
    let stature = mesh.bounds()?.size().y;
    Some(JointAnchors::new(template).on(&mesh.positions, stature))
}

fn smoothstep(t: f64) -> f64 {
    let t = t.clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}

/// Weight of a joint's rotation at `p`: 0 before the joint, 1 after, rising across
/// `half` either side of it along `axis` (unit, pointing down the limb).
fn along(p: DVec3, joint: DVec3, axis: DVec3, half: f64) -> f64 {
    smoothstep(((p - joint).dot(axis) + half) / (2.0 * half))
}

/// Rotation of `p` about the line through `pivot` along unit `axis` by `rad`.
fn turn(p: DVec3, pivot: DVec3, axis: DVec3, rad: f64) -> DVec3 {
    if rad == 0.0 {
        return p;
    }
    pivot + DMat3::from_axis_angle(axis, rad) * (p - pivot)
}

/// The elbow's hinge: perpendicular to the upper arm and to +Z, oriented so that a
/// positive rotation swings the forearm forward (+Z).
pub fn elbow_hinge(j: &LimbJoints) -> DVec3 {
    let u = (j.elbow - j.shoulder).normalize_or_zero();
    let k = u.cross(DVec3::Z).normalize_or_zero();
    if k == DVec3::ZERO {
        DVec3::X
    } else {
        k
    }
}

/// Poses `mesh` (a body in the template's vertex order, canonical frame) into
/// `stance`: arms, elbows, legs, back on the floor and the mark, then the turn.
///
/// # Errors
/// The mesh is not in the template's vertex order or has no vertices.
pub fn apply(mesh: &mut TriMesh, template: &Template, stance: &Stance) -> Result<(), SubjectError> {
    let labels = part_labels(mesh, template, "posing a stance")?;
    let joints =
        limb_joints(mesh, template).ok_or_else(|| SubjectError::Invalid("empty mesh".into()))?;
    let rest = mesh.positions.clone();
    for (i, side) in [(0usize, 1.0f64), (1, -1.0)] {
        let j = &joints[i];
        let (arm, leg) = if i == 0 {
            (Part::LeftArm, Part::LeftLeg)
        } else {
            (Part::RightArm, Part::RightLeg)
        };
        let u = (j.elbow - j.shoulder).normalize_or_zero();
        let d = (j.wrist - j.elbow).normalize_or_zero();
        let bisector = (u + d).normalize_or_zero();
        let hinge = elbow_hinge(j);
        let shoulder_rad = side * stance.arm_abduction_deg[i].to_radians();
        let elbow_rad = stance.elbow_flexion_deg[i].to_radians();
        let thigh = (j.knee - j.hip).normalize_or_zero();
        let shin = (j.ankle - j.knee).normalize_or_zero();
        let hip_rad = side * stance.leg_abduction_deg.to_radians();
        for ((p, q), l) in mesh.positions.iter_mut().zip(&rest).zip(&labels) {
            let q = *q;
            if *l == arm {
                let te = along(q, j.elbow, bisector, ELBOW_BLEND_HALF_M);
                let ts = along(q, j.shoulder, u, SHOULDER_BLEND_HALF_M);
                let q1 = turn(q, j.elbow, hinge, elbow_rad * te);
                *p = turn(q1, j.shoulder, DVec3::Z, shoulder_rad * ts);
            } else if *l == leg {
                let ta = along(q, j.ankle, shin, ANKLE_BLEND_HALF_M);
                let th = along(q, j.hip, thigh, HIP_BLEND_HALF_M);
                let q1 = turn(q, j.ankle, DVec3::Z, -hip_rad * ta);
                *p = turn(q1, j.hip, DVec3::Z, hip_rad * th);
            } else if *l == Part::Torso && q.x * side > 0.0 {
                // The trunk next to the joint takes a share of the limb's turn, fading
                // with distance from the joint and towards the midline.
                let mut moved = q;
                let ds = (q - j.shoulder).length();
                if ds < 2.0 * SHOULDER_BLEND_HALF_M {
                    let w = along(q, j.shoulder, u, SHOULDER_BLEND_HALF_M)
                        * (1.0 - smoothstep(ds / (2.0 * SHOULDER_BLEND_HALF_M)))
                        * TRUNK_SHARE;
                    moved = turn(moved, j.shoulder, DVec3::Z, shoulder_rad * w);
                }
                let dh = (q - j.hip).length();
                if dh < 2.0 * HIP_BLEND_HALF_M {
                    let w = along(q, j.hip, thigh, HIP_BLEND_HALF_M)
                        * (1.0 - smoothstep(dh / (2.0 * HIP_BLEND_HALF_M)))
                        * smoothstep(q.x * side / j.hip.x.abs().max(1e-3))
                        * TRUNK_SHARE;
                    moved = turn(moved, j.hip, DVec3::Z, hip_rad * w);
                }
                *p = moved;
            }
        }
    }
    // Back on the floor and on the mark (the feet's midpoint), then the turn.
    let min_y = mesh
        .positions
        .iter()
        .map(|p| p.y)
        .fold(f64::INFINITY, f64::min);
    let rigid = &template.info.rigid;
    let centroid = |set: &[u32]| {
        set.iter()
            .filter_map(|&i| mesh.positions.get(i as usize))
            .copied()
            .sum::<DVec3>()
            / set.len().max(1) as f64
    };
    let mark = 0.5 * (centroid(&rigid.foot_left) + centroid(&rigid.foot_right));
    let shift = DVec3::new(mark.x, min_y, mark.z);
    let yaw = DMat3::from_rotation_y(stance.yaw_deg.to_radians());
    mesh.map_positions(|p| yaw * (p - shift));
    mesh.validate().map_err(SubjectError::Invalid)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::body::{ShapeLibrary, ShapeParams};

    fn lib() -> Option<&'static ShapeLibrary> {
        ShapeLibrary::shared().ok()
    }

    fn angle_deg(a: DVec3, b: DVec3) -> f64 {
        a.angle_between(b).to_degrees()
    }

    /// A point on a limb's axis carried to a mesh: the centroid of the template's 40
    /// vertices nearest to it (all around the limb, so the centroid stays on the axis
    /// when the limb turns).
    fn limb_point(t: &Template, a: DVec3, b: DVec3, s: f64, mesh: &TriMesh) -> DVec3 {
        let q = a.lerp(b, s);
        let mut idx: Vec<usize> = (0..t.mesh.positions.len()).collect();
        idx.sort_by(|&i, &j| {
            (t.mesh.positions[i] - q)
                .length_squared()
                .total_cmp(&(t.mesh.positions[j] - q).length_squared())
        });
        idx.truncate(40);
        idx.iter().map(|&i| mesh.positions[i]).sum::<DVec3>() / idx.len() as f64
    }

    /// Upper arm and forearm directions measured on the mesh, each from two points well
    /// away from the blends (left side).
    fn arm_dirs(t: &Template, mesh: &TriMesh, side: usize) -> (DVec3, DVec3) {
        let j = &t.info.joints;
        let (sh, el, wr) = if side == 0 {
            (j.shoulder_left, j.elbow_left, j.wrist_left)
        } else {
            (j.shoulder_right, j.elbow_right, j.wrist_right)
        };
        let u = limb_point(t, sh, el, 0.7, mesh) - limb_point(t, sh, el, 0.5, mesh);
        let f = limb_point(t, el, wr, 1.0, mesh) - limb_point(t, el, wr, 0.55, mesh);
        (u, f)
    }

    #[test]
    fn elbow_angle_on_the_mesh_is_the_drawn_one() {
        let Some(lib) = lib() else { return };
        let t = lib.template();
        let rest = lib.body(&ShapeParams::default());
        for (abd, flex) in [(0.0, 12.0), (8.0, 15.0), (-10.0, 5.0)] {
            let stance = Stance {
                arm_abduction_deg: [abd, abd],
                elbow_flexion_deg: [flex, 0.5 * flex],
                leg_abduction_deg: 0.0,
                yaw_deg: 0.0,
            };
            let mut posed = rest.clone();
            apply(&mut posed, t, &stance).expect("poses");
            for side in 0..2 {
                let (u0, f0) = arm_dirs(t, &rest, side);
                let (u1, f1) = arm_dirs(t, &posed, side);
                let bend = angle_deg(u1, f1) - angle_deg(u0, f0);
                let raised = angle_deg(u0, u1);
                eprintln!("abd {abd} flex {flex} side {side}: bend {bend:.2}, upper arm turned {raised:.2}");
                assert!(
                    (bend - stance.elbow_flexion_deg[side]).abs() < 1.0,
                    "{bend}"
                );
                assert!((raised - abd.abs()).abs() < 1.0, "{raised}");
                // Forward: the wrist comes towards +Z.
                if stance.elbow_flexion_deg[side] > 0.0 {
                    assert!(f1.normalize().z > f0.normalize().z);
                }
            }
        }
    }

    #[test]
    fn feet_stay_flat_on_the_floor_on_the_mark_and_the_body_turns() {
        let Some(lib) = lib() else { return };
        let t = lib.template();
        let rest = lib.body(&ShapeParams::default());
        for legs in [-3.0, 4.0] {
            let stance = Stance {
                arm_abduction_deg: [5.0, -7.0],
                elbow_flexion_deg: [10.0, 3.0],
                leg_abduction_deg: legs,
                yaw_deg: 3.0,
            };
            let mut posed = rest.clone();
            apply(&mut posed, t, &stance).expect("poses");
            let rigid = &t.info.rigid;
            for foot in [&rigid.foot_left, &rigid.foot_right] {
                let low = foot
                    .iter()
                    .map(|&i| posed.positions[i as usize].y)
                    .fold(f64::INFINITY, f64::min);
                assert!(low.abs() < 1e-3, "foot sole at {low}");
                // Flat: the sole's vertices keep their heights relative to each other.
                let spread = |m: &TriMesh| {
                    let ys: Vec<f64> = foot.iter().map(|&i| m.positions[i as usize].y).collect();
                    ys.iter().fold(f64::NEG_INFINITY, |a, &b| a.max(b))
                        - ys.iter().fold(f64::INFINITY, |a, &b| a.min(b))
                };
                assert!((spread(&posed) - spread(&rest)).abs() < 2e-3);
            }
            // Feet apart (or together) by about the leg length times the angle.
            let feet_x = |m: &TriMesh, set: &[u32]| {
                set.iter().map(|&i| m.positions[i as usize].x).sum::<f64>() / set.len() as f64
            };
            let gap = |m: &TriMesh| feet_x(m, &rigid.foot_left) - feet_x(m, &rigid.foot_right);
            let moved = gap(&posed) - gap(&rest);
            assert!(moved * legs > 0.0 && moved.abs() < 0.15, "{moved}");
            // The head is rigid and turned by the yaw.
            let head = &rigid.head;
            let (a, b) = head.iter().fold((head[0], head[0]), |(lo, hi), &i| {
                let x = rest.positions[i as usize].x;
                (
                    if x < rest.positions[lo as usize].x {
                        i
                    } else {
                        lo
                    },
                    if x > rest.positions[hi as usize].x {
                        i
                    } else {
                        hi
                    },
                )
            });
            let dir = |m: &TriMesh| m.positions[b as usize] - m.positions[a as usize];
            let yaw = |v: DVec3| (-v.z).atan2(v.x).to_degrees();
            let turned = yaw(dir(&posed)) - yaw(dir(&rest));
            assert!((turned - stance.yaw_deg).abs() < 0.05, "{turned}");
        }
    }

    /// At rest-ish angles (arms 6 degrees in, elbows bent fully) the arms stay apart
    /// from the trunk in the front view: at every height from the crotch to 5 cm under
    /// the armpits, the trunk's vertices end before the arm's begin, with a gap.
    #[test]
    fn arms_stay_apart_from_the_trunk_in_the_front_view() {
        let Some(lib) = lib() else { return };
        let t = lib.template();
        let heavy = ShapeParams {
            weight: 0.85,
            ..ShapeParams::default()
        };
        for params in [ShapeParams::default(), heavy] {
            let mut posed = lib.body(&params);
            let stance = Stance {
                arm_abduction_deg: [-6.0, -6.0],
                elbow_flexion_deg: [15.0, 15.0],
                leg_abduction_deg: 0.0,
                yaw_deg: 0.0,
            };
            apply(&mut posed, t, &stance).expect("poses");
            let labels = part_labels(&posed, t, "test").expect("labels");
            let lm = &t.info.landmarks;
            let k = posed.bounds().expect("b").size().y / t.info.stature_m;
            let (lo, hi) = (lm.crotch_y * k, lm.armpit_y * k - 0.05);
            let mut y = lo;
            let mut smallest_gap = f64::INFINITY;
            while y < hi {
                for (side, arm) in [(1.0, Part::LeftArm), (-1.0, Part::RightArm)] {
                    let band = |want: Part| {
                        posed
                            .positions
                            .iter()
                            .zip(&labels)
                            .filter(move |(p, l)| **l == want && (p.y - y).abs() < 0.01)
                            .map(move |(p, _)| p.x * side)
                    };
                    let trunk_out = band(Part::Torso).fold(f64::NEG_INFINITY, f64::max);
                    let arm_in = band(arm).fold(f64::INFINITY, f64::min);
                    if trunk_out.is_finite() && arm_in.is_finite() {
                        smallest_gap = smallest_gap.min(arm_in - trunk_out);
                    }
                }
                y += 0.02;
            }
            eprintln!(
                "weight {}: smallest front-view gap {smallest_gap:.3} m",
                params.weight
            );
            assert!(smallest_gap > 0.005, "{smallest_gap}");
        }
    }

    /// The same seed makes the same body, with and without an ANSUR person.
    #[test]
    fn a_seed_makes_the_same_posed_body() {
        use crate::synth::subject::{subject_body, SubjectParams};
        let mut params = SubjectParams::sample(20011);
        params.stance = Some(Stance::sample(20011));
        let a = subject_body(&params).expect("body");
        let b = subject_body(&params).expect("body");
        assert_eq!(a.mesh.positions, b.mesh.positions);
        let mut rest = params.clone();
        rest.stance = None;
        let r = subject_body(&rest).expect("body");
        assert!(a
            .mesh
            .positions
            .iter()
            .zip(&r.mesh.positions)
            .any(|(p, q)| (*p - *q).length() > 0.01));
    }

    #[test]
    fn the_draw_is_deterministic_and_in_range() {
        for seed in 20000..20050 {
            let s = Stance::sample(seed);
            assert_eq!(s, Stance::sample(seed));
            assert!(s
                .arm_abduction_deg
                .iter()
                .all(|a| (ARM_ABDUCTION_DEG.0..ARM_ABDUCTION_DEG.1).contains(a)));
            assert!(s
                .elbow_flexion_deg
                .iter()
                .all(|a| (ELBOW_FLEXION_DEG.0..ELBOW_FLEXION_DEG.1).contains(a)));
            assert!((LEG_ABDUCTION_DEG.0..LEG_ABDUCTION_DEG.1).contains(&s.leg_abduction_deg));
            assert!(s.yaw_deg.abs() <= YAW_DEG);
        }
    }
}
