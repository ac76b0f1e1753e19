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
/// crotch (about 0.47 of stature on adults) to just below the armpits (about 0.75): the
/// top level carries the chest, which the second fitting pass needs to tell bodies apart.
pub const TORSO_LEVELS: [f64; 13] = [
    0.50, 0.52, 0.54, 0.56, 0.58, 0.60, 0.62, 0.64, 0.66, 0.68, 0.70, 0.72, 0.74,
];
/// Heights (fractions of stature) at which the thighs are sampled (below the crotch).
pub const THIGH_LEVELS: [f64; 2] = [0.40, 0.43];

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

/// The undirected edges of a triangle list, each once (for [`mesh_descriptor`]).
pub fn unique_edges(triangles: &[[u32; 3]]) -> Vec<[u32; 2]> {
    let mut e: Vec<[u32; 2]> = triangles
        .iter()
        .flat_map(|t| [[t[0], t[1]], [t[1], t[2]], [t[2], t[0]]])
        .map(|[a, b]| if a < b { [a, b] } else { [b, a] })
        .collect();
    e.sort_unstable();
    e.dedup();
    e
}

/// Whether a vertex of this part counts for the trunk's extents at a height: the torso
/// and the legs (part labels follow the template's crotch, so on a body with other
/// proportions the buttocks may carry leg labels above its own crotch; a silhouette does
/// not know labels either). Arms and head never.
fn is_trunk(l: Part) -> bool {
    matches!(l, Part::Torso | Part::LeftLeg | Part::RightLeg)
}

/// Extents (component-wise min and max) of the mesh's true cross-sections at the heights
/// `ys` (ascending), over the edges whose both ends `select` accepts. One pass over the
/// edges: every edge crossing a height contributes its crossing point (vertex bands
/// would miss rows of a coarse mesh).
fn section_extents(
    positions: &[DVec3],
    edges: &[[u32; 2]],
    labels: &[Part],
    ys: &[f64],
    select: impl Fn(Part) -> bool,
) -> Vec<Option<(DVec3, DVec3)>> {
    let mut out: Vec<Option<(DVec3, DVec3)>> = vec![None; ys.len()];
    for &[a, b] in edges {
        let (Some(&la), Some(&lb)) = (labels.get(a as usize), labels.get(b as usize)) else {
            continue;
        };
        if !(select(la) && select(lb)) {
            continue;
        }
        let (pa, pb) = (positions[a as usize], positions[b as usize]);
        let (lo, hi) = if pa.y <= pb.y { (pa, pb) } else { (pb, pa) };
        if hi.y - lo.y < 1e-12 {
            continue;
        }
        let first = ys.partition_point(|&y| y < lo.y);
        for (k, &y) in ys.iter().enumerate().skip(first) {
            if y >= hi.y {
                break;
            }
            let q = lo + (hi - lo) * ((y - lo.y) / (hi.y - lo.y));
            let e = out[k].get_or_insert((q, q));
            e.0 = e.0.min(q);
            e.1 = e.1.max(q);
        }
    }
    out
}

/// Descriptor of a body mesh (vertex positions with the template's part labels and
/// edges), standing with soles on y = 0.
pub fn mesh_descriptor(
    positions: &[DVec3],
    edges: &[[u32; 2]],
    labels: &[Part],
) -> ShapeDescriptor {
    let stature = positions.iter().map(|p| p.y).fold(f64::MIN, f64::max)
        - positions.iter().map(|p| p.y).fold(f64::MAX, f64::min);
    let stature = stature.max(1e-6);
    let ratio = |e: Option<(DVec3, DVec3)>, axis: usize| -> f64 {
        match e {
            Some((lo, hi)) if hi[axis] > lo[axis] => (hi[axis] - lo[axis]) / stature,
            _ => f64::NAN,
        }
    };
    let torso_ys: Vec<f64> = TORSO_LEVELS.iter().map(|l| l * stature).collect();
    let trunk = section_extents(positions, edges, labels, &torso_ys, is_trunk);
    let thigh_ys: Vec<f64> = THIGH_LEVELS.iter().map(|l| l * stature).collect();
    let left = section_extents(positions, edges, labels, &thigh_ys, |l| l == Part::LeftLeg);
    let right = section_extents(positions, edges, labels, &thigh_ys, |l| l == Part::RightLeg);
    ShapeDescriptor {
        torso_width: trunk.iter().map(|e| ratio(*e, 0)).collect(),
        torso_depth: trunk.iter().map(|e| ratio(*e, 2)).collect(),
        thigh_width: left
            .iter()
            .zip(&right)
            .flat_map(|(l, r)| [ratio(*l, 0), ratio(*r, 0)])
            .collect(),
        stature_m: stature,
    }
}

/// Centre of the x and z extents of the trunk's cross-section (torso and legs, see
/// [`is_trunk`]) at height `y`.
pub fn torso_centre(
    positions: &[DVec3],
    edges: &[[u32; 2]],
    labels: &[Part],
    y: f64,
) -> Option<DVec3> {
    let (lo, hi) = section_extents(positions, edges, labels, &[y], is_trunk)
        .first()
        .copied()
        .flatten()?;
    (hi.x > lo.x).then(|| DVec3::new(0.5 * (lo.x + hi.x), y, 0.5 * (lo.z + hi.z)))
}

/// Breadth (x extent) and depth (z extent) of the trunk's cross-section (torso and
/// legs) at height `y`, metres.
pub fn trunk_extents(
    positions: &[DVec3],
    edges: &[[u32; 2]],
    labels: &[Part],
    y: f64,
) -> Option<(f64, f64)> {
    trunk_extents_at(positions, edges, labels, &[y])
        .first()
        .copied()
        .flatten()
}

/// [`trunk_extents`] at each of `ys`, in one pass over the edges.
pub fn trunk_extents_at(
    positions: &[DVec3],
    edges: &[[u32; 2]],
    labels: &[Part],
    ys: &[f64],
) -> Vec<Option<(f64, f64)>> {
    section_extents(positions, edges, labels, ys, is_trunk)
        .into_iter()
        .map(|e| e.and_then(|(lo, hi)| (hi.x > lo.x).then_some((hi.x - lo.x, hi.z - lo.z))))
        .collect()
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
/// views (x from the front, z from the side) starting at `guess`. Without a side view
/// the depth is NaN and z stays the guess's.
pub fn section_centre(
    front: (&Camera, MaskRef<'_>),
    side: Option<(&Camera, MaskRef<'_>)>,
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
        let Some(side) = side else {
            continue;
        };
        let f = silhouette_exit(side.0, side.1, c, DVec3::Z, REACH_M)?;
        let b = silhouette_exit(side.0, side.1, c, DVec3::NEG_Z, REACH_M)?;
        c.z = 0.5 * (f.z + b.z);
        depth = f.z - b.z;
    }
    Some((c, width, depth))
}

/// The observed descriptor from the two silhouettes (without a side view, the depths are
/// NaN: unobserved, so the library search and the shape refinement go by the widths and
/// the stature alone, and the library's bodies supply the depth that goes with them). `stature_m` is the subject's
/// stature, `centre` a point inside the torso (from landmarks, or the mark), `crotch_x`
/// the x of the crotch and `thigh_offset_m` the thigh centres' distance from it.
pub fn observed_descriptor(
    front: (&Camera, MaskRef<'_>),
    side: Option<(&Camera, MaskRef<'_>)>,
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

/// Where, walking up the vertical line through (`x`, `z`) from `y_from` (which must lie in
/// the gap between the legs), the silhouette seen by `cam` begins: the crotch as that
/// camera sees it, on that line. None when the start is already inside the silhouette
/// (legs together) or nothing is met below `y_to`.
pub fn gap_top_on_axis(
    cam: &Camera,
    mask: MaskRef<'_>,
    x: f64,
    z: f64,
    y_from: f64,
    y_to: f64,
) -> Option<f64> {
    let t = first_inside(cam, mask, DVec3::new(x, y_from, z), DVec3::new(x, y_to, z))?;
    Some(y_from + t * (y_to - y_from))
}

/// Where, walking the segment from `a` to `b` (station frame), its image in `cam` first
/// enters the silhouette: the fraction of the way, refined by bisection to the
/// occupancy's half crossing. Steps of half a pixel; a point the camera cannot see counts
/// as outside. None when `a` is already inside or nothing is met before `b`.
pub fn first_inside(cam: &Camera, mask: MaskRef<'_>, a: DVec3, b: DVec3) -> Option<f64> {
    let occ = |t: f64| {
        cam.project(a + t * (b - a))
            .map(|px| mask.occupancy(px))
            .unwrap_or(0.0)
    };
    if occ(0.0) >= 0.5 {
        return None;
    }
    let pa = cam.project(a)?;
    let pb = cam.project(b)?;
    let n = (((pb - pa).length() / 0.5).ceil() as usize).clamp(2, 8000);
    let mut prev = 0.0;
    for i in 1..=n {
        let t = i as f64 / n as f64;
        if occ(t) >= 0.5 {
            let (mut lo, mut hi) = (prev, t);
            for _ in 0..14 {
                let mid = 0.5 * (lo + hi);
                if occ(mid) >= 0.5 {
                    hi = mid
                } else {
                    lo = mid
                }
            }
            return Some(0.5 * (lo + hi));
        }
        prev = t;
    }
    None
}

/// Rasterises into `out` (`width` x `height`, 255 = body) the silhouette that `cam` sees
/// of the triangles having a vertex with y in `y_range` (the band the caller looks at).
pub fn rasterize_band(
    positions: &[DVec3],
    triangles: &[[u32; 3]],
    cam: &Camera,
    width: u32,
    height: u32,
    y_range: (f64, f64),
    out: &mut Vec<u8>,
) {
    use glam::DVec2;
    let (w, h) = (width as usize, height as usize);
    out.clear();
    out.resize(w * h, 0);
    for t in triangles {
        let v = t.map(|i| positions[i as usize]);
        if !v.iter().any(|p| p.y >= y_range.0 && p.y <= y_range.1) {
            continue;
        }
        let (Some(p0), Some(p1), Some(p2)) =
            (cam.project(v[0]), cam.project(v[1]), cam.project(v[2]))
        else {
            continue;
        };
        let p = [p0, p1, p2];
        let area = (p1 - p0).perp_dot(p2 - p0);
        if area.abs() < 1e-12 {
            continue;
        }
        let min = p0.min(p1).min(p2).floor().max(DVec2::ZERO);
        let max = p0
            .max(p1)
            .max(p2)
            .ceil()
            .min(DVec2::new(w as f64 - 1.0, h as f64 - 1.0));
        if min.x > max.x || min.y > max.y {
            continue;
        }
        for y in min.y as usize..=max.y as usize {
            for x in min.x as usize..=max.x as usize {
                let q = DVec2::new(x as f64, y as f64);
                let w0 = (p[1] - q).perp_dot(p[2] - q) / area;
                let w1 = (p[2] - q).perp_dot(p[0] - q) / area;
                if w0 >= 0.0 && w1 >= 0.0 && w0 + w1 <= 1.0 {
                    out[y * w + x] = 255;
                }
            }
        }
    }
}
