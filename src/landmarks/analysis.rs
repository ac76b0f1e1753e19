//! The paper's zone rules on one view's plane contour (method.md section 1, steps 2-5
//! and 7). See `zones` for the plane coordinates.

use super::zones::{self, Crossing};
use super::{ContourPart, ContourRange, Status};
use glam::DVec2;

/// Lines tried when looking for the crotch gap: from `y_c - CROTCH_SCAN_FROM_H * h` up to
/// `y_c - CROTCH_SCAN_TO_H * h`.
const CROTCH_SCAN_FROM_H: f64 = 1.0;
const CROTCH_SCAN_TO_H: f64 = 0.0;
/// Lines tried for the armpit gaps, from high to low (in h above y_c).
const ARMPIT_SCAN_FROM_H: f64 = 1.8;
const ARMPIT_SCAN_TO_H: f64 = 0.3;
const SCAN_STEP_H: f64 = 0.1;
/// Zones (in h, relative to the figure's centre). The paper's zones, slightly widened so
/// that a subject a little off the ideal proportions still fits.
const CROTCH_ZONE_X_H: f64 = 0.3;
const CROTCH_ZONE_Y_H: f64 = 1.0;
const ARMPIT_ZONE_X_H: (f64, f64) = (0.1, 1.2);
const ARMPIT_ZONE_Y_H: (f64, f64) = (0.3, 2.5);
/// The acromion target g = (+-0.8 h, 2.5 h) about the figure's centre (step 4), used
/// when no crotch was found.
const ACROMION_G_H: (f64, f64) = (0.8, 2.5);
/// With a crotch, g = (crotch.x +- 0.8 h, crotch.y + 2.45 h): the template analysis's
/// definition (`body::prepare`), so that the station's acromions and the template's are
/// the same landmark (the paper's g is given loosely "about mid-height").
use crate::body::prepare::{ACROMION_G_X_H, ACROMION_G_Y_H};
/// Acromion candidates are above y_c + this (in h).
const ACROMION_MIN_Y_H: f64 = 1.5;
/// Heights above the crotch of the limb joints (second table), in h.
pub const KNEE_H: f64 = -1.5;
pub const ANKLE_H: f64 = -3.0;
pub const SHOULDER_H: f64 = 2.4;
pub const ELBOW_H: f64 = 1.4;
pub const WRIST_H: f64 = 0.6;
pub const HAND_H: f64 = 0.5;
/// Height of the upper arm's middle (for the shoulder's axis), in h above the crotch.
const UPPER_ARM_H: f64 = 1.9;
/// Offset of the extra cuts that give a limb's axis direction, in h.
const AXIS_CUT_OFFSET_H: f64 = 0.25;

/// Landmarks of the front contour, as indices into the plane contour.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct FrontFeatures {
    pub head_top: Option<usize>,
    /// Height of the head top on the plane, metres.
    pub stature: f64,
    /// Figure centre: x = area centroid, y = stature / 2.
    pub center: DVec2,
    /// Head length, stature / 7.
    pub h: f64,
    pub crotch: Option<usize>,
    pub armpit_left: Option<usize>,
    pub armpit_right: Option<usize>,
    pub acromion_left: Option<usize>,
    pub acromion_right: Option<usize>,
}

/// Features of the side contour.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct SideFeatures {
    pub head_top: Option<usize>,
    pub stature: f64,
}

/// Steps 2-4 on the front plane contour (CCW, (X, Y) metres).
pub fn analyse_front(plane: &[DVec2]) -> FrontFeatures {
    let mut f = FrontFeatures::default();
    let n = plane.len();
    if n < 8 {
        return f;
    }
    let top = (0..n)
        .max_by(|&a, &b| plane[a].y.total_cmp(&plane[b].y))
        .unwrap_or(0);
    f.head_top = Some(top);
    f.stature = plane[top].y;
    f.h = f.stature / 7.0;
    let cx = zones::centroid(plane).map_or(plane[top].x, |c| c.x);
    f.center = DVec2::new(cx, f.stature / 2.0);
    let (c, h) = (f.center, f.h);
    if h <= 0.0 {
        return f;
    }
    let mut cr: Vec<Crossing> = Vec::new();

    // Step 2: the crotch, apex of the gap between the legs.
    let steps = ((CROTCH_SCAN_FROM_H - CROTCH_SCAN_TO_H) / SCAN_STEP_H).round() as usize;
    for k in 0..=steps {
        let v = c.y - CROTCH_SCAN_FROM_H * h + k as f64 * SCAN_STEP_H * h;
        zones::crossings(plane, v, &mut cr);
        // Gaps are (cr[2j+1], cr[2j+2]); take the one nearest the centre line.
        let gap = (0..cr.len().saturating_sub(2) / 2)
            .map(|j| (cr[2 * j + 1], cr[2 * j + 2]))
            .min_by(|a, b| gap_dist(a, c.x).total_cmp(&gap_dist(b, c.x)));
        let Some((a, b)) = gap else { continue };
        if gap_dist(&(a, b), c.x) > CROTCH_ZONE_X_H * h {
            continue;
        }
        if let Some(apex) = zones::gap_apex(plane, a.edge, b.edge, v) {
            let p = plane[apex];
            if (p.x - c.x).abs() <= CROTCH_ZONE_X_H * h && (p.y - c.y).abs() <= CROTCH_ZONE_Y_H * h
            {
                f.crotch = Some(apex);
            }
        }
        break;
    }

    // Step 3: the armpits, apexes of the gaps between the torso and each arm.
    let steps = ((ARMPIT_SCAN_FROM_H - ARMPIT_SCAN_TO_H) / SCAN_STEP_H).round() as usize;
    for side in [1.0f64, -1.0] {
        for k in 0..=steps {
            let v = c.y + ARMPIT_SCAN_FROM_H * h - k as f64 * SCAN_STEP_H * h;
            zones::crossings(plane, v, &mut cr);
            // The inside interval holding the centre line is the torso.
            let Some(j) = (0..cr.len() / 2).find(|&j| cr[2 * j].u <= c.x && c.x <= cr[2 * j + 1].u)
            else {
                continue;
            };
            let gap = if side > 0.0 {
                (2 * j + 2 < cr.len()).then(|| (cr[2 * j + 1], cr[2 * j + 2]))
            } else {
                (j >= 1).then(|| (cr[2 * j - 1], cr[2 * j]))
            };
            let Some((a, b)) = gap else { continue };
            if let Some(apex) = zones::gap_apex(plane, a.edge, b.edge, v) {
                let p = plane[apex];
                let dx = side * (p.x - c.x);
                let dy = p.y - c.y;
                if dx >= ARMPIT_ZONE_X_H.0 * h
                    && dx <= ARMPIT_ZONE_X_H.1 * h
                    && dy >= ARMPIT_ZONE_Y_H.0 * h
                    && dy <= ARMPIT_ZONE_Y_H.1 * h
                {
                    if side > 0.0 {
                        f.armpit_left = Some(apex);
                    } else {
                        f.armpit_right = Some(apex);
                    }
                }
            }
            break;
        }
    }

    // Step 4: the acromions, the contour points closest to g (crotch-relative when the
    // crotch is known, see ACROMION_G_Y_H).
    let crotch = f.crotch.map(|i| plane[i]);
    for side in [1.0f64, -1.0] {
        let g = match crotch {
            Some(k) => DVec2::new(k.x + side * ACROMION_G_X_H * h, k.y + ACROMION_G_Y_H * h),
            None => DVec2::new(c.x + side * ACROMION_G_H.0 * h, c.y + ACROMION_G_H.1 * h),
        };
        let best = (0..n)
            .filter(|&i| {
                plane[i].y >= c.y + ACROMION_MIN_Y_H * h && side * (plane[i].x - c.x) > 0.0
            })
            .min_by(|&a, &b| {
                plane[a]
                    .distance_squared(g)
                    .total_cmp(&plane[b].distance_squared(g))
            });
        if side > 0.0 {
            f.acromion_left = best;
        } else {
            f.acromion_right = best;
        }
    }
    f
}

fn gap_dist(g: &(Crossing, Crossing), x: f64) -> f64 {
    if x < g.0.u {
        g.0.u - x
    } else if x > g.1.u {
        x - g.1.u
    } else {
        0.0
    }
}

/// Step 4 of the side: the head top of the side contour.
pub fn analyse_side(plane: &[DVec2]) -> SideFeatures {
    let n = plane.len();
    if n < 3 {
        return SideFeatures::default();
    }
    let top = (0..n)
        .max_by(|&a, &b| plane[a].y.total_cmp(&plane[b].y))
        .unwrap_or(0);
    SideFeatures {
        head_top: Some(top),
        stature: plane[top].y,
    }
}

fn range(from: usize, to: usize, n: usize) -> ContourRange {
    ContourRange {
        start: from,
        len: (to + n - from) % n,
    }
}

fn lowest(plane: &[DVec2], r: ContourRange) -> usize {
    r.indices(plane.len())
        .min_by(|&a, &b| plane[a].y.total_cmp(&plane[b].y))
        .unwrap_or(r.start)
}

/// Indices of the front landmarks needed to split the contour into parts.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FrontSplit {
    pub acromion_left: usize,
    pub head_top: usize,
    pub acromion_right: usize,
    pub armpit_right: usize,
    pub crotch: usize,
    pub armpit_left: usize,
}

impl FrontSplit {
    pub fn from(f: &FrontFeatures) -> Option<Self> {
        Some(FrontSplit {
            acromion_left: f.acromion_left?,
            head_top: f.head_top?,
            acromion_right: f.acromion_right?,
            armpit_right: f.armpit_right?,
            crotch: f.crotch?,
            armpit_left: f.armpit_left?,
        })
    }
    /// Checks the counter-clockwise order aL, head top, aR, pR, crotch, pL.
    fn ordered(&self, n: usize) -> bool {
        let seq = [
            self.acromion_left,
            self.head_top,
            self.acromion_right,
            self.armpit_right,
            self.crotch,
            self.armpit_left,
        ];
        let rel: Vec<usize> = seq.iter().map(|&i| (i + n - seq[0]) % n).collect();
        rel.windows(2).all(|w| w[0] < w[1])
    }
    pub fn right_arm(&self, n: usize) -> ContourRange {
        range(self.acromion_right, self.armpit_right, n)
    }
    pub fn left_arm(&self, n: usize) -> ContourRange {
        range(self.armpit_left, self.acromion_left, n)
    }
}

/// Step 5: front contour parts with left/right status. Counter-clockwise from the left
/// acromion: head (torso), right arm, right torso side, right leg, left leg, left torso
/// side, left arm. Limbs split at their lowest point into the two halves.
pub fn front_parts(plane: &[DVec2], f: &FrontFeatures, out: &mut Vec<ContourPart>) {
    out.clear();
    let n = plane.len();
    let Some(s) = FrontSplit::from(f) else { return };
    if !s.ordered(n) {
        return;
    }
    let crotch_y = plane[s.crotch].y;
    // Hips: where the path from an armpit to the crotch first drops below the crotch.
    let path_r = range(s.armpit_right, s.crotch, n);
    let hip_r = path_r
        .indices(n)
        .find(|&i| plane[i].y < crotch_y)
        .unwrap_or(s.crotch);
    let path_l = range(s.crotch, s.armpit_left, n);
    let hip_l = path_l
        .indices(n)
        .filter(|&i| plane[i].y < crotch_y)
        .last()
        .map_or(s.armpit_left, |i| (i + 1) % n);
    let hand_r = lowest(plane, s.right_arm(n));
    let hand_l = lowest(plane, s.left_arm(n));
    let sole_r = lowest(plane, range(hip_r, s.crotch, n));
    let sole_l = lowest(plane, range(s.crotch, hip_l, n));
    let mut push = |name: &'static str, status: Status, a: usize, b: usize| {
        let r = range(a, b, n);
        if r.len > 0 {
            out.push(ContourPart {
                name: name.to_string(),
                status,
                range: r,
            });
        }
    };
    push("torso", Status::Left, s.acromion_left, s.head_top);
    push("torso", Status::Right, s.head_top, s.acromion_right);
    push("right_arm", Status::Right, s.acromion_right, hand_r);
    push("right_arm", Status::Left, hand_r, s.armpit_right);
    push("torso", Status::Right, s.armpit_right, hip_r);
    push("right_leg", Status::Right, hip_r, sole_r);
    push("right_leg", Status::Left, sole_r, s.crotch);
    push("left_leg", Status::Right, s.crotch, sole_l);
    push("left_leg", Status::Left, sole_l, hip_l);
    push("torso", Status::Left, hip_l, s.armpit_left);
    push("left_arm", Status::Right, s.armpit_left, hand_l);
    push("left_arm", Status::Left, hand_l, s.acromion_left);
}

/// Midpoint of the outermost crossings of an open chain (the points of `r`) with the line
/// `origin + s dir`, keeping the crossings nearest `origin` on each side.
fn chain_cut(plane: &[DVec2], r: ContourRange, origin: DVec2, dir: DVec2) -> Option<DVec2> {
    let n = plane.len();
    let normal = dir.perp();
    let (mut neg, mut pos): (Option<f64>, Option<f64>) = (None, None);
    for k in 0..r.len.saturating_sub(1) {
        let i = (r.start + k) % n;
        let (a, b) = (plane[i], plane[(i + 1) % n]);
        let (da, db) = ((a - origin).dot(normal), (b - origin).dot(normal));
        if (da <= 0.0) == (db <= 0.0) {
            continue;
        }
        let p = a + (b - a) * (da / (da - db));
        let s = (p - origin).dot(dir);
        if s < 0.0 {
            neg = Some(neg.map_or(s, |q: f64| q.max(s)));
        } else {
            pos = Some(pos.map_or(s, |q: f64| q.min(s)));
        }
    }
    Some(origin + dir * (0.5 * (neg? + pos?)))
}

/// Centre of the horizontal cut through a limb chain at height v: the midpoint of the
/// chain's extreme crossings.
fn horizontal_cut(plane: &[DVec2], r: ContourRange, v: f64) -> Option<DVec2> {
    let n = plane.len();
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for k in 0..r.len.saturating_sub(1) {
        let i = (r.start + k) % n;
        let (a, b) = (plane[i], plane[(i + 1) % n]);
        if (a.y <= v) != (b.y <= v) {
            let u = a.x + (v - a.y) / (b.y - a.y) * (b.x - a.x);
            lo = lo.min(u);
            hi = hi.max(u);
        }
    }
    (hi > lo).then(|| DVec2::new(0.5 * (lo + hi), v))
}

/// A limb joint at height `v` (step 7, second table) with the limb-axis correction:
/// the horizontal cut's centre, then a cut perpendicular to the local limb axis (from the
/// centres of cuts `offset` above and below) through it, re-centred.
pub fn limb_joint(plane: &[DVec2], r: ContourRange, v: f64, offset: f64) -> Option<DVec2> {
    let m0 = horizontal_cut(plane, r, v)?;
    let (Some(up), Some(dn)) = (
        horizontal_cut(plane, r, v + offset),
        horizontal_cut(plane, r, v - offset),
    ) else {
        return Some(m0);
    };
    let axis = (up - dn).normalize_or_zero();
    if axis == DVec2::ZERO {
        return Some(m0);
    }
    let mut m = m0;
    for _ in 0..2 {
        match chain_cut(plane, r, m, axis.perp()) {
            Some(c) => m = c,
            None => break,
        }
    }
    Some(m)
}

/// Limb joints of the front view (second table), in plane coordinates, for the limbs
/// found. `crotch_y` and `h` are the station crotch height and head length.
pub fn limb_joints(
    plane: &[DVec2],
    f: &FrontFeatures,
    crotch_y: f64,
    h: f64,
) -> Vec<(super::LandmarkName, DVec2)> {
    use super::LandmarkName::*;
    let mut out = Vec::new();
    let n = plane.len();
    let Some(s) = FrontSplit::from(f) else {
        return out;
    };
    if !s.ordered(n) {
        return out;
    }
    let off = AXIS_CUT_OFFSET_H * h;
    // Legs: from the crotch around each foot to the hip on the same side.
    let crotch = s.crotch;
    let right_leg = range(s.armpit_right, crotch, n);
    let left_leg = range(crotch, s.armpit_left, n);
    for (leg, knee, ankle) in [
        (right_leg, KneeRight, AnkleRight),
        (left_leg, KneeLeft, AnkleLeft),
    ] {
        // Only the part below the crotch (the torso side is above it).
        if let Some(p) = limb_joint(plane, leg, crotch_y + KNEE_H * h, off) {
            out.push((knee, p));
        }
        if let Some(p) = limb_joint(plane, leg, crotch_y + ANKLE_H * h, off) {
            out.push((ankle, p));
        }
    }
    for (arm, sh, el, wr, ha) in [
        (
            s.right_arm(n),
            ShoulderRight,
            ElbowRight,
            WristRight,
            HandRight,
        ),
        (s.left_arm(n), ShoulderLeft, ElbowLeft, WristLeft, HandLeft),
    ] {
        let elbow = limb_joint(plane, arm, crotch_y + ELBOW_H * h, off);
        if let Some(p) = elbow {
            out.push((el, p));
        }
        if let Some(p) = limb_joint(plane, arm, crotch_y + WRIST_H * h, off) {
            out.push((wr, p));
        }
        if let Some(p) = limb_joint(plane, arm, crotch_y + HAND_H * h, off) {
            out.push((ha, p));
        }
        // The shoulder cut meets the arm chain only on its outer edge: extend the upper
        // arm's axis (upper-arm middle -> elbow) to the shoulder height instead.
        let upper = limb_joint(plane, arm, crotch_y + UPPER_ARM_H * h, off);
        if let (Some(e), Some(u)) = (elbow, upper) {
            let d = u - e;
            if d.y.abs() > 1e-6 {
                let v = crotch_y + SHOULDER_H * h;
                out.push((sh, e + d * ((v - e.y) / d.y)));
            }
        }
    }
    out
}

/// Step 6: side parts. `axis_z(v)` is the side axis at height v; points at or above
/// `crotch_y` are "side_torso", below "side_leg"; front when u >= axis.
pub fn side_parts(
    plane: &[DVec2],
    crotch_y: f64,
    axis_z: &dyn Fn(f64) -> Option<f64>,
    out: &mut Vec<ContourPart>,
) {
    out.clear();
    let n = plane.len();
    if n == 0 {
        return;
    }
    let label = |i: usize| -> (&'static str, Status) {
        let p = plane[i];
        let name = if p.y >= crotch_y {
            "side_torso"
        } else {
            "side_leg"
        };
        let status = match axis_z(p.y) {
            Some(z) if p.x < z => Status::Back,
            _ => Status::Front,
        };
        (name, status)
    };
    // Start at a label change so no run wraps around the end.
    let start = (0..n)
        .find(|&i| label(i) != label((i + n - 1) % n))
        .unwrap_or(0);
    let mut run_start = start;
    let mut cur = label(start);
    for k in 1..=n {
        let i = (start + k) % n;
        let l = label(i);
        if l != cur || k == n {
            out.push(ContourPart {
                name: cur.0.to_string(),
                status: cur.1,
                range: range(run_start, i, n).max_len(n),
            });
            run_start = i;
            cur = l;
        }
    }
}

impl ContourRange {
    /// A range of length 0 from `range(a, a)` means the whole contour.
    fn max_len(self, n: usize) -> Self {
        if self.len == 0 {
            ContourRange {
                start: self.start,
                len: n,
            }
        } else {
            self
        }
    }
}

/// The side view's trunk depth over the front view's trunk breadth at the levels of
/// [`trunk_asymmetry`] (both plane contours in metres, heights from the floor): the
/// lower quartile over the levels; or, when less, the side view's extent over the wider
/// thigh's breadth below the crotch (median over its levels). The breadth is the front outline's interval around
/// the trunk's axis (the arms apart from it), the depth the side outline's whole extent
/// at that height (an arm in front of the trunk only adds to it). A side view that lost
/// the hips or the belly to the backdrop shows a trunk shallower than any adult's. None
/// without the front's landmarks or a side outline.
pub fn side_depth_ratio(
    front: &[DVec2],
    f: &FrontFeatures,
    side: &[DVec2],
    scratch: &mut Vec<Crossing>,
) -> Option<f64> {
    if side.len() < 3 {
        return None;
    }
    let mut ratios = [0.0f64; TRUNK_LEVELS];
    let mut n = 0;
    for (v, axis) in trunk_levels(front, f)? {
        zones::crossings(front, v, scratch);
        // The axis outside the front outline: that view's fault, judged elsewhere.
        let Some((a, b)) = interval_around(scratch, axis) else {
            continue;
        };
        let depth = extent_at(side, v, scratch);
        if b > a {
            ratios[n] = depth / (b - a);
            n += 1;
        }
    }
    let r = &mut ratios[..n];
    r.sort_by(f64::total_cmp);
    let trunk = r.get(n / 4).copied()?;
    // The thighs: the side view's extent over the wider thigh of the front view (the
    // side view sees both thighs as one), median over the levels below the crotch.
    let crotch = front[f.crotch?];
    let mut thighs = [0.0f64; THIGH_LEVELS];
    let mut m = 0;
    for k in 0..THIGH_LEVELS {
        let v = crotch.y
            - f.h
                * (THIGH_FROM_H
                    + (THIGH_TO_H - THIGH_FROM_H) * k as f64 / (THIGH_LEVELS - 1) as f64);
        zones::crossings(front, v, scratch);
        let i = scratch.iter().position(|c| c.u > crotch.x).unwrap_or(0);
        if i % 2 == 1 || i < 2 || i + 1 >= scratch.len() {
            // The crotch's column inside the outline (legs together) or a leg missing.
            continue;
        }
        let breadth = (scratch[i - 1].u - scratch[i - 2].u).max(scratch[i + 1].u - scratch[i].u);
        let depth = extent_at(side, v, scratch);
        if breadth > 0.0 {
            thighs[m] = depth / breadth;
            m += 1;
        }
    }
    let t = &mut thighs[..m];
    t.sort_by(f64::total_cmp);
    Some(t.get(m / 2).map_or(trunk, |&t| t.min(trunk)))
}

/// The whole extent of polygon `poly` at height `v` (its first crossing to its last; 0
/// where it has none).
fn extent_at(poly: &[DVec2], v: f64, scratch: &mut Vec<Crossing>) -> f64 {
    zones::crossings(poly, v, scratch);
    match (scratch.first(), scratch.last()) {
        (Some(a), Some(b)) => b.u - a.u,
        _ => 0.0,
    }
}

/// The inside interval of the sorted crossings `cr` (alternating in and out along u)
/// that holds `u`; None when `u` lies outside the polygon.
fn interval_around(cr: &[Crossing], u: f64) -> Option<(f64, f64)> {
    let i = cr.iter().position(|c| c.u > u).unwrap_or(0);
    (i % 2 == 1).then(|| (cr[i - 1].u, cr[i].u))
}

/// The [`TRUNK_LEVELS`] heights between the crotch and the lower armpit of the front
/// outline `plane` (less [`TRUNK_SKIP_LOW`] and [`TRUNK_SKIP_HIGH`] of that span), each
/// with the body axis's u there (the line from the crotch to the head top); None without
/// head top, crotch and armpits.
fn trunk_levels(plane: &[DVec2], f: &FrontFeatures) -> Option<impl Iterator<Item = (f64, f64)>> {
    let (top, crotch) = (plane[f.head_top?], plane[f.crotch?]);
    let armpit_y = plane[f.armpit_left?].y.min(plane[f.armpit_right?].y);
    let span = armpit_y - crotch.y;
    if span <= 0.0 || top.y <= crotch.y {
        return None;
    }
    Some((0..TRUNK_LEVELS).map(move |k| {
        let t = TRUNK_SKIP_LOW
            + (1.0 - TRUNK_SKIP_LOW - TRUNK_SKIP_HIGH) * (k as f64 + 0.5) / TRUNK_LEVELS as f64;
        let v = crotch.y + t * span;
        (
            v,
            crotch.x + (top.x - crotch.x) * (v - crotch.y) / (top.y - crotch.y),
        )
    }))
}

/// Levels below the crotch where [`side_depth_ratio`] compares the thighs, from
/// `THIGH_FROM_H` to `THIGH_TO_H` head lengths (stature / 7) below it.
const THIGH_LEVELS: usize = 5;
const THIGH_FROM_H: f64 = 0.3;
const THIGH_TO_H: f64 = 0.9;

/// Levels sampled by [`trunk_asymmetry`] between the crotch and the armpits.
const TRUNK_LEVELS: usize = 16;
/// Fractions of the crotch-to-armpit height left out at each end (the crotch's own
/// curve below, the armpit's fold above).
const TRUNK_SKIP_LOW: f64 = 0.15;
const TRUNK_SKIP_HIGH: f64 = 0.1;

/// Left-right asymmetry of the trunk in the front view: at [`TRUNK_LEVELS`] heights
/// between the crotch and the lower armpit, the trunk's half widths `l` and `r` either
/// side of the body axis (the line from the crotch to the head top), and `|r - l| /
/// (r + l)` (1 where the axis lies outside the silhouette); returned as the median over
/// the levels (None without head top, crotch and armpits).
///
/// A trunk seen from the front is nearly symmetric about that axis; a side of it that
/// blends into the backdrop (clothing of the backdrop's colour and brightness) leaves a
/// bay in the silhouette on that side only, which a fit would take for a thinner body.
pub fn trunk_asymmetry(
    plane: &[DVec2],
    f: &FrontFeatures,
    scratch: &mut Vec<Crossing>,
) -> Option<f64> {
    let mut values = [0.0f64; TRUNK_LEVELS];
    let mut n = 0;
    for (v, axis) in trunk_levels(plane, f)? {
        zones::crossings(plane, v, scratch);
        // The axis outside the silhouette means the middle of the trunk is missing: the
        // largest asymmetry.
        values[n] = interval_around(scratch, axis).map_or(1.0, |(a, b)| {
            let (l, r) = (axis - a, b - axis);
            (r - l).abs() / (r + l).max(f64::MIN_POSITIVE)
        });
        n += 1;
    }
    let v = &mut values[..n];
    v.sort_by(f64::total_cmp);
    Some(v[n / 2])
}

#[cfg(test)]
mod side_depth_tests {
    use super::*;

    /// A front outline (CCW, metres): legs from the floor to a crotch at 0.8 m, a trunk
    /// 0.34 m broad up to armpits at 1.35 m, a head to 1.7 m; and its features.
    fn front() -> (Vec<DVec2>, FrontFeatures) {
        let p = [
            (-0.17, 0.0),
            (-0.02, 0.0),
            (0.0, 0.8),
            (0.02, 0.0),
            (0.17, 0.0),
            (0.17, 1.35),
            (0.05, 1.45),
            (0.0, 1.7),
            (-0.05, 1.45),
            (-0.17, 1.35),
        ];
        let f = FrontFeatures {
            head_top: Some(7),
            stature: 1.7,
            center: DVec2::new(0.0, 0.85),
            h: 1.7 / 7.0,
            crotch: Some(2),
            armpit_left: Some(5),
            armpit_right: Some(9),
            ..Default::default()
        };
        (p.iter().map(|&(x, y)| DVec2::new(x, y)).collect(), f)
    }

    /// A side outline: legs `legs` deep (both as one), a trunk 0.24 m deep.
    fn side(legs: f64) -> Vec<DVec2> {
        let h = legs / 2.0;
        [
            (-h, 0.0),
            (h, 0.0),
            (h, 0.8),
            (0.12, 0.8),
            (0.12, 1.35),
            (0.03, 1.7),
            (-0.12, 1.35),
            (-0.12, 0.8),
            (-h, 0.8),
        ]
        .iter()
        .map(|&(x, y)| DVec2::new(x, y))
        .collect()
    }

    #[test]
    fn a_side_view_that_lost_the_thighs_is_shallower_than_any_adult() {
        let (f, ff) = front();
        let min = crate::landmarks::VerdictOptions::default().min_side_depth_ratio;
        let mut scratch = Vec::new();
        // Whole: the trunk's 0.24 over 0.34 is the least ratio.
        let whole = side_depth_ratio(&f, &ff, &side(0.17), &mut scratch).expect("measured");
        assert!((whole - 0.24 / 0.34).abs() < 0.01, "{whole}");
        assert!(whole > min);
        // The thighs lost to the backdrop down to 4 cm of depth: about 0.24 of a thigh.
        let lost = side_depth_ratio(&f, &ff, &side(0.04), &mut scratch).expect("measured");
        assert!(lost < min && lost > 0.2, "{lost}");
        // No side outline: not measured.
        assert_eq!(side_depth_ratio(&f, &ff, &[], &mut scratch), None);
    }
}
