//! Landmarks of one view by anthropometric zones (method.md section 1, steps 1-5 and 7),
//! computed on the contour mapped to a vertical plane through the mark: for the front
//! view the plane z = 0, coordinates (u, v) = (X, Y) in metres; for the side view the
//! plane x = x0, (u, v) = (Z, Y). Working in metres on that plane instead of in pixels
//! removes the camera's tilt and lens distortion from the zone tests; the perspective
//! depth is restored afterwards by `lift`.
//!
//! Polygons here are closed, counter-clockwise in (u, v) (v up).

use glam::DVec2;

/// A crossing of a closed polygon with the horizontal line v = const.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Crossing {
    pub u: f64,
    /// Edge `edge -> edge + 1` (mod n).
    pub edge: usize,
}

/// Crossings of the polygon with v = `v`, sorted by u (half-open rule, so a vertex on the
/// line counts once).
pub fn crossings(poly: &[DVec2], v: f64, out: &mut Vec<Crossing>) {
    out.clear();
    let n = poly.len();
    for i in 0..n {
        let (a, b) = (poly[i], poly[(i + 1) % n]);
        if (a.y <= v) != (b.y <= v) {
            let t = (v - a.y) / (b.y - a.y);
            out.push(Crossing {
                u: a.x + t * (b.x - a.x),
                edge: i,
            });
        }
    }
    out.sort_by(|p, q| p.u.total_cmp(&q.u));
}

/// Crossings of the polygon with the line `origin + s * dir` (dir unit), as parameters s
/// with their edges, sorted by s.
pub fn line_crossings(poly: &[DVec2], origin: DVec2, dir: DVec2, out: &mut Vec<(f64, usize)>) {
    out.clear();
    let n = poly.len();
    let normal = dir.perp();
    for i in 0..n {
        let (a, b) = (poly[i], poly[(i + 1) % n]);
        let (da, db) = ((a - origin).dot(normal), (b - origin).dot(normal));
        if (da <= 0.0) != (db <= 0.0) {
            let t = da / (da - db);
            let p = a + (b - a) * t;
            out.push(((p - origin).dot(dir), i));
        }
    }
    out.sort_by(|p, q| p.0.total_cmp(&q.0));
}

/// Indices from `from` to `to` inclusive, walking forward around a cycle of `n`.
pub fn cyclic_len(from: usize, to: usize, n: usize) -> usize {
    (to + n - from) % n + 1
}

/// Points within this height of a gap's highest point form its top; the apex is the
/// top's middle point (a rounded or flat gap top has no single highest point).
pub const APEX_PLATEAU_M: f64 = 0.002;

/// The apex of a gap (crotch, armpit): the gap is the outside interval between the
/// crossings on edges `ea` and `eb` of the line v = `v0`. Of the two contour paths
/// joining those edges, the one that stays above the line closes the gap from above;
/// its highest point is the apex (the middle of the points within `APEX_PLATEAU_M` of
/// it). Returns the apex's point index.
pub fn gap_apex(poly: &[DVec2], ea: usize, eb: usize, v0: f64) -> Option<usize> {
    let top = gap_top(poly, ea, eb, v0)?;
    let n = poly.len();
    let level = poly[top].y - APEX_PLATEAU_M;
    let (mut back, mut fwd) = (0, 0);
    while back < n / 2 && poly[(top + n - back - 1) % n].y >= level {
        back += 1;
    }
    while fwd < n / 2 && poly[(top + fwd + 1) % n].y >= level {
        fwd += 1;
    }
    Some((top + n - back + (back + fwd) / 2) % n)
}

/// Centroid and principal axis (unit, sign arbitrary) of a set of points: the direction
/// of the largest spread, which a total least squares line follows. None when empty.
pub fn principal_axis(pts: &[DVec2]) -> Option<(DVec2, DVec2)> {
    if pts.is_empty() {
        return None;
    }
    let c = pts.iter().copied().sum::<DVec2>() / pts.len() as f64;
    let (mut sxx, mut sxy, mut syy) = (0.0, 0.0, 0.0);
    for p in pts {
        let d = *p - c;
        sxx += d.x * d.x;
        sxy += d.x * d.y;
        syy += d.y * d.y;
    }
    let angle = 0.5 * (2.0 * sxy).atan2(sxx - syy);
    Some((c, DVec2::new(angle.cos(), angle.sin())))
}

/// Flank points used by [`wedge_apex`]: this far below the apex, in pixels (nearer, the
/// mask's own rounding of the apex bends the flanks; farther, the gap is no longer a
/// wedge).
const WEDGE_FLANK_PX: (f64, f64) = (1.0, 8.0);
/// Width from which a gap is kept open by the mask, pixels: the 3x3 majority filters of
/// the segmentation close a gap one pixel wide.
const WEDGE_RESOLVED_PX: f64 = 2.0;
/// Fewest flank points on each side for a line.
const WEDGE_MIN_POINTS: usize = 3;
/// The apex moves by at most this many pixels: a narrow wedge (small `theta`) would
/// otherwise be extended far along flanks that are fitted over a few pixels only.
pub const WEDGE_MAX_MOVE_PX: f64 = WEDGE_RESOLVED_PX;

/// The apex of a wedge-shaped gap (the armpit between torso and arm). A mask closes a gap
/// where it is narrower than [`WEDGE_RESOLVED_PX`], so the traced apex (`apex`, a point
/// index of the polygon `poly`, v up, pixels of size `px` in its units) lies below the
/// point where the gap's sides meet, by more the narrower the wedge.
///
/// Each flank is the contour from `WEDGE_FLANK_PX.0` to `.1` pixels below the apex,
/// fitted with a line (total least squares: a flank may lie at any angle); the lines meet
/// at `m`. A wedge of opening angle `theta` is `WEDGE_RESOLVED_PX` wide at
/// `t = WEDGE_RESOLVED_PX / (2 tan(theta / 2))` below its tip, so the apex is moved from
/// the traced point toward `m` by at most `t` (a rounded top meets its flanks' lines
/// well above itself and only moves by `t`), and by at most [`WEDGE_MAX_MOVE_PX`]. None
/// when the flanks are short or parallel, or meet below the traced apex.
pub fn wedge_apex(poly: &[DVec2], apex: usize, px: f64) -> Option<DVec2> {
    let n = poly.len();
    if n < 8 || apex >= n || px.is_nan() || px <= 0.0 {
        return None;
    }
    let top = poly[apex];
    // A flank's line: centroid and unit direction pointing away from the apex.
    let fit = |forward: bool| -> Option<(DVec2, DVec2)> {
        let mut pts = Vec::with_capacity(16);
        for k in 1..n / 4 {
            let p = poly[if forward {
                (apex + k) % n
            } else {
                (apex + n - k) % n
            }];
            let depth = (top.y - p.y) / px;
            if depth > WEDGE_FLANK_PX.1 {
                break;
            }
            if depth < -0.5 {
                // The contour climbs above the apex: not a wedge's side.
                return None;
            }
            if depth >= WEDGE_FLANK_PX.0 {
                pts.push(p);
            }
        }
        if pts.len() < WEDGE_MIN_POINTS {
            return None;
        }
        let (c, mut dir) = principal_axis(&pts)?;
        if dir.dot(c - top) < 0.0 {
            dir = -dir;
        }
        Some((c, dir))
    };
    let (c1, d1) = fit(true)?;
    let (c2, d2) = fit(false)?;
    let cross = d1.perp_dot(d2);
    if cross.abs() < 1e-6 {
        return None;
    }
    // c1 + s d1 = c2 + r d2.
    let s = (c2 - c1).perp_dot(d2) / cross;
    let meet = c1 + s * d1;
    let to_meet = meet - top;
    if to_meet.y <= 0.0 {
        return None;
    }
    let half = 0.5 * d1.dot(d2).clamp(-1.0, 1.0).acos();
    let t = WEDGE_RESOLVED_PX * px / (2.0 * half.tan().max(1e-6));
    let dist = to_meet.length();
    Some(top + to_meet * (t.min(WEDGE_MAX_MOVE_PX * px) / dist).min(1.0))
}

fn gap_top(poly: &[DVec2], ea: usize, eb: usize, v0: f64) -> Option<usize> {
    let n = poly.len();
    if n < 3 {
        return None;
    }
    let best_on = |from: usize, to: usize| -> (bool, usize, usize) {
        let len = cyclic_len(from, to, n);
        let mut above = true;
        let mut best = from;
        for k in 0..len {
            let i = (from + k) % n;
            if poly[i].y < v0 - 1e-9 {
                above = false;
            }
            if poly[i].y > poly[best].y {
                best = i;
            }
        }
        (above, best, len)
    };
    let p1 = best_on((ea + 1) % n, eb);
    let p2 = best_on((eb + 1) % n, ea);
    match (p1.0, p2.0) {
        (true, false) => Some(p1.1),
        (false, true) => Some(p2.1),
        (true, true) => Some(if p1.2 <= p2.2 { p1.1 } else { p2.1 }),
        (false, false) => None,
    }
}

/// Area centroid of a closed polygon (None when degenerate).
pub fn centroid(poly: &[DVec2]) -> Option<DVec2> {
    let n = poly.len();
    let (mut a2, mut c) = (0.0, DVec2::ZERO);
    for i in 0..n {
        let (p, q) = (poly[i], poly[(i + 1) % n]);
        let cr = p.perp_dot(q);
        a2 += cr;
        c += (p + q) * cr;
    }
    if a2.abs() < 1e-12 {
        return None;
    }
    Some(c / (3.0 * a2))
}

/// Midpoint of the outermost crossings of the line v = `v` (the paper's side axis, step
/// 1: the midpoint between the contour and its opposite intersection).
pub fn axis_at(poly: &[DVec2], v: f64, scratch: &mut Vec<Crossing>) -> Option<f64> {
    crossings(poly, v, scratch);
    if scratch.len() < 2 {
        return None;
    }
    Some(0.5 * (scratch[0].u + scratch[scratch.len() - 1].u))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An upside-down U (two legs joined at the top), CCW.
    fn arch() -> Vec<DVec2> {
        [
            (0.0, 0.0),
            (1.0, 0.0),
            (1.0, 2.0),
            (2.0, 2.0),
            (2.0, 0.0),
            (3.0, 0.0),
            (3.0, 3.0),
            (0.0, 3.0),
        ]
        .iter()
        .map(|&(x, y)| DVec2::new(x, y))
        .collect()
    }

    /// A block with a notch cut up from its bottom edge, sampled every half pixel (pixel
    /// size 1): the notch's sides leave the tip (0, 0) at `half_deg` either side of the
    /// vertical and are closed where the notch is narrower than `closed_px` (a flat top
    /// there, as a mask traces it); `parallel`: vertical sides `closed_px` apart up to
    /// v = -10 instead. Returns the polygon (CCW, v up) and the index of the top's middle.
    fn notch(half_deg: f64, closed_px: f64, parallel: bool) -> (Vec<DVec2>, usize) {
        let slope = half_deg.to_radians().tan();
        let bottom = -30.0;
        let top = if parallel {
            -10.0
        } else {
            -closed_px / (2.0 * slope)
        };
        let half = |v: f64| {
            if parallel {
                0.5 * closed_px
            } else {
                -v * slope
            }
        };
        let mut poly = vec![DVec2::new(-40.0, bottom)];
        // Up the notch's left side, across its top, down its right side.
        let mut v = bottom;
        while v < top {
            poly.push(DVec2::new(-half(v), v));
            v += 0.5;
        }
        poly.push(DVec2::new(-0.5 * closed_px, top));
        let apex = poly.len();
        poly.push(DVec2::new(0.0, top));
        let left = poly[1..apex].to_vec();
        poly.extend(left.iter().rev().map(|p| DVec2::new(-p.x, p.y)));
        poly.extend([(40.0, bottom), (40.0, 20.0), (-40.0, 20.0)].map(|(x, y)| DVec2::new(x, y)));
        (poly, apex)
    }

    #[test]
    fn a_wedge_closed_by_the_mask_gets_its_tip_back() {
        // Opening 2 x 35 degrees, closed 1.5 px wide: the top is 1.07 px below the tip.
        let (poly, apex) = notch(35.0, 1.5, false);
        assert!((poly[apex].y + 1.071).abs() < 1e-3, "{:?}", poly[apex]);
        let p = wedge_apex(&poly, apex, 1.0).expect("a wedge");
        assert!(p.length() < 0.05, "{p:?}");
        // A narrow wedge closed 4 px wide: its tip is 10 px up, the apex moves by the
        // most the mask can have closed.
        let (poly, apex) = notch(11.3, 4.0, false);
        let p = wedge_apex(&poly, apex, 1.0).expect("a wedge");
        assert!(
            (p.y - poly[apex].y - WEDGE_MAX_MOVE_PX).abs() < 0.05,
            "{p:?}"
        );
        assert!(p.x.abs() < 1e-6);
        // Parallel sides have no tip: the traced apex stays.
        let (poly, apex) = notch(0.0, 3.0, true);
        assert_eq!(wedge_apex(&poly, apex, 1.0), None);
        // A contour that rises above the apex next to it is no wedge.
        let mut bumpy = poly.clone();
        bumpy[apex + 2].y += 5.0;
        assert_eq!(wedge_apex(&bumpy, apex, 1.0), None);
    }

    #[test]
    fn apex_of_the_arch_gap() {
        let p = arch();
        let mut c = Vec::new();
        crossings(&p, 1.0, &mut c);
        assert_eq!(c.len(), 4);
        let apex = gap_apex(&p, c[1].edge, c[2].edge, 1.0).unwrap();
        assert_eq!(p[apex].y, 2.0);
        assert!(p[apex].x == 1.0 || p[apex].x == 2.0);
        assert_eq!(axis_at(&p, 1.0, &mut c), Some(1.5));
    }

    #[test]
    fn centroid_of_a_square() {
        let sq = [
            DVec2::new(0.0, 0.0),
            DVec2::new(2.0, 0.0),
            DVec2::new(2.0, 2.0),
            DVec2::new(0.0, 2.0),
        ];
        assert!((centroid(&sq).unwrap() - DVec2::ONE).length() < 1e-12);
    }
}
