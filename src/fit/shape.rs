//! Candidate selection and shape refinement (method.md section 3, "candidate model").
//!
//! The paper compares silhouettes of 252 scanned bodies (0.148 s per comparison). Here
//! each library body is summarised once by a descriptor: the width (x extent) and depth
//! (z extent) of its torso at fixed fractions of its stature, plus the widths of its
//! thighs, all divided by stature. The observed descriptor comes from the two silhouettes
//! through the same search along station axes that correspondence uses, so a candidate is
//! picked from the whole library in well under a millisecond. The candidate's macro
//! parameters are then refined by Gauss-Newton on the same descriptor, evaluated on
//! freshly generated bodies (the library is a continuous statistical shape model).
//!
//! Units: metres, station frame. Descriptors are dimensionless (divided by stature).

use super::correspond::{MaskRef, Part};
use crate::camera::Camera;
use glam::DVec3;

/// Heights (fractions of stature) at which the torso is sampled: from just above the
/// crotch (about 0.47 of stature on adults) to below the armpits (about 0.72).
pub const TORSO_LEVELS: [f64; 12] = [
    0.50, 0.52, 0.54, 0.56, 0.58, 0.60, 0.62, 0.64, 0.66, 0.68, 0.70, 0.72,
];
/// Heights (fractions of stature) at which the thighs are sampled (below the crotch).
pub const THIGH_LEVELS: [f64; 2] = [0.40, 0.43];
/// Half-thickness of the band of vertices taken as one level, metres.
const BAND_HALF_M: f64 = 0.008;

/// Torso widths and depths and thigh widths (left, right) at the levels above, divided by
/// stature.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct ShapeDescriptor {
    pub torso_width: Vec<f64>,
    pub torso_depth: Vec<f64>,
    pub thigh_width: Vec<f64>,
    pub stature_m: f64,
}

impl ShapeDescriptor {
    /// Squared distance between two descriptors; entries missing in `observed` (NaN) are
    /// skipped. Depths weigh as much as widths.
    pub fn distance2(&self, observed: &ShapeDescriptor) -> f64 {
        let mut s = 0.0;
        for (a, b) in self
            .torso_width
            .iter()
            .zip(&observed.torso_width)
            .chain(self.torso_depth.iter().zip(&observed.torso_depth))
            .chain(self.thigh_width.iter().zip(&observed.thigh_width))
        {
            if a.is_finite() && b.is_finite() {
                s += (a - b) * (a - b);
            }
        }
        s
    }

    /// The descriptor as one vector (for least squares), NaN where unobserved.
    pub fn as_vec(&self) -> Vec<f64> {
        self.torso_width
            .iter()
            .chain(&self.torso_depth)
            .chain(&self.thigh_width)
            .copied()
            .collect()
    }
}

/// Descriptor of a body mesh (vertex positions with the template's part labels), standing
/// with soles on y = 0.
pub fn mesh_descriptor(positions: &[DVec3], labels: &[Part]) -> ShapeDescriptor {
    let stature = positions.iter().map(|p| p.y).fold(f64::MIN, f64::max)
        - positions.iter().map(|p| p.y).fold(f64::MAX, f64::min);
    let stature = stature.max(1e-6);
    let extent = |level: f64, part: Part, axis: usize| -> f64 {
        let y = level * stature;
        let (mut lo, mut hi) = (f64::MAX, f64::MIN);
        for (p, l) in positions.iter().zip(labels) {
            if *l == part && (p.y - y).abs() <= BAND_HALF_M {
                let c = p.to_array()[axis];
                lo = lo.min(c);
                hi = hi.max(c);
            }
        }
        if hi > lo {
            (hi - lo) / stature
        } else {
            f64::NAN
        }
    };
    ShapeDescriptor {
        torso_width: TORSO_LEVELS
            .iter()
            .map(|&l| extent(l, Part::Torso, 0))
            .collect(),
        torso_depth: TORSO_LEVELS
            .iter()
            .map(|&l| extent(l, Part::Torso, 2))
            .collect(),
        thigh_width: THIGH_LEVELS
            .iter()
            .flat_map(|&l| [extent(l, Part::LeftLeg, 0), extent(l, Part::RightLeg, 0)])
            .collect(),
        stature_m: stature,
    }
}

/// Centre of the x and z extents of the torso vertices within a band around height `y`.
pub fn torso_centre(positions: &[DVec3], labels: &[Part], y: f64) -> Option<DVec3> {
    let (mut lo, mut hi) = (DVec3::splat(f64::MAX), DVec3::splat(f64::MIN));
    for (p, l) in positions.iter().zip(labels) {
        if *l == Part::Torso && (p.y - y).abs() <= BAND_HALF_M {
            lo = lo.min(*p);
            hi = hi.max(*p);
        }
    }
    (hi.x > lo.x).then(|| DVec3::new(0.5 * (lo.x + hi.x), y, 0.5 * (lo.z + hi.z)))
}

/// Where the silhouette is left when walking from `start` along `dir` (station frame),
/// or None when `start` is not inside the silhouette or no boundary is within `reach_m`.
pub fn silhouette_exit(
    cam: &Camera,
    mask: MaskRef<'_>,
    start: DVec3,
    dir: DVec3,
    reach_m: f64,
) -> Option<DVec3> {
    let occ = |t: f64| {
        cam.project(start + dir * t)
            .map(|px| mask.occupancy(px))
            .unwrap_or(0.0)
    };
    if occ(0.0) < 0.5 {
        return None;
    }
    let a = cam.project(start)?;
    let b = cam.project(start + dir * reach_m)?;
    let n = (((b - a).length() / 0.5).ceil() as usize).clamp(2, 8000);
    let mut prev = 0.0;
    for i in 1..=n {
        let t = reach_m * i as f64 / n as f64;
        if mask.occupancy(a + (b - a) * (i as f64 / n as f64)) < 0.5 {
            let (mut lo, mut hi) = (prev, t);
            for _ in 0..14 {
                let mid = 0.5 * (lo + hi);
                if occ(mid) >= 0.5 {
                    lo = mid
                } else {
                    hi = mid
                }
            }
            return Some(start + dir * (0.5 * (lo + hi)));
        }
        prev = t;
    }
    None
}

/// The centre of the silhouettes' cross-section at height `y`: iterates between the two
/// views (x from the front, z from the side) starting at `guess`.
pub fn section_centre(
    front: (&Camera, MaskRef<'_>),
    side: (&Camera, MaskRef<'_>),
    y: f64,
    guess: DVec3,
) -> Option<(DVec3, f64, f64)> {
    const REACH_M: f64 = 0.6;
    let mut c = DVec3::new(guess.x, y, guess.z);
    let mut width = f64::NAN;
    let mut depth = f64::NAN;
    for _ in 0..3 {
        let l = silhouette_exit(front.0, front.1, c, DVec3::X, REACH_M)?;
        let r = silhouette_exit(front.0, front.1, c, DVec3::NEG_X, REACH_M)?;
        c.x = 0.5 * (l.x + r.x);
        width = l.x - r.x;
        let f = silhouette_exit(side.0, side.1, c, DVec3::Z, REACH_M)?;
        let b = silhouette_exit(side.0, side.1, c, DVec3::NEG_Z, REACH_M)?;
        c.z = 0.5 * (f.z + b.z);
        depth = f.z - b.z;
    }
    Some((c, width, depth))
}

/// The observed descriptor from the two silhouettes. `stature_m` is the subject's
/// stature, `centre` a point inside the torso (from landmarks, or the mark), `crotch_x`
/// the x of the crotch and `thigh_offset_m` the thigh centres' distance from it.
pub fn observed_descriptor(
    front: (&Camera, MaskRef<'_>),
    side: (&Camera, MaskRef<'_>),
    stature_m: f64,
    centre: DVec3,
) -> ShapeDescriptor {
    let mut d = ShapeDescriptor {
        stature_m,
        ..Default::default()
    };
    let mut c = centre;
    for &l in &TORSO_LEVELS {
        match section_centre(front, side, l * stature_m, c) {
            Some((cc, w, dep)) => {
                c = cc;
                d.torso_width.push(w / stature_m);
                d.torso_depth.push(dep / stature_m);
            }
            None => {
                d.torso_width.push(f64::NAN);
                d.torso_depth.push(f64::NAN);
            }
        }
    }
    // Thighs: start half way between the body axis and the torso's side at hip level.
    let hip_half = d
        .torso_width
        .first()
        .copied()
        .filter(|w| w.is_finite())
        .unwrap_or(0.2)
        * stature_m
        * 0.5;
    for &l in &THIGH_LEVELS {
        for side_sign in [1.0, -1.0] {
            let start = DVec3::new(c.x + side_sign * hip_half * 0.5, l * stature_m, c.z);
            let outer = silhouette_exit(front.0, front.1, start, DVec3::X * side_sign, 0.4);
            let inner = silhouette_exit(front.0, front.1, start, DVec3::X * -side_sign, 0.4);
            d.thigh_width.push(match (outer, inner) {
                (Some(o), Some(i)) => (o.x - i.x).abs() / stature_m,
                _ => f64::NAN,
            });
        }
    }
    d
}
