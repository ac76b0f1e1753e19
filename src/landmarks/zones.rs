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
