//! Chordal-axis skeleton of a silhouette polygon (issue 4, step 4; Igarashi et al.'s
//! Teddy, after Prasad's chordal axis transform): a constrained Delaunay triangulation
//! (spade) of the closed contour, with the contour's edges as constraints, classifies
//! each inside triangle by the number of its sides on the contour:
//! - sleeve (one contour side): the axis joins the midpoints of its two chords;
//! - terminal (two contour sides): the end of a limb; the axis stops at its chord;
//! - junction (no contour side): the axis joins its centroid to its three chord midpoints.
//!
//! Along a limb held at any angle, the sleeve segments follow the limb's medial line, so
//! the skeleton gives limb axes without horizontal cuts (the remark at the end of
//! method.md section 1). Not on the per-frame path (it allocates; about a millisecond for
//! a contour of a thousand points).
//!
//! # Conventions
//! Any 2-D frame (pixels or plane metres); the polygon is closed implicitly (last point
//! joins the first), either orientation, without repeated closing point.

use glam::DVec2;
use spade::{ConstrainedDelaunayTriangulation, Point2, Triangulation};

/// A triangle side at least this fraction of the shorter contour arc between its ends
/// closes a sliver along a nearly straight stretch of contour: it is treated as contour,
/// not as a chord across the shape.
const SLIVER_CHORD_ARC: f64 = 0.9;

/// Kind of an inside triangle of the chordal-axis triangulation.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TriangleKind {
    Terminal,
    Sleeve,
    Junction,
}

/// One segment of the chordal axis.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AxisSegment {
    pub a: DVec2,
    pub b: DVec2,
    /// Length of the chord(s) the segment joins (the local width of the shape).
    pub width: f64,
    pub kind: TriangleKind,
}

/// The chordal axis of a polygon.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ChordalAxis {
    pub segments: Vec<AxisSegment>,
    /// Centroids of the junction triangles (where limbs meet the torso).
    pub junctions: Vec<DVec2>,
    /// Inside triangles of the triangulation.
    pub triangles: usize,
}

/// Errors of the chordal axis.
#[derive(Debug, thiserror::Error)]
pub enum ChordalError {
    #[error("the polygon needs at least 3 distinct points, got {0}")]
    TooFewPoints(usize),
    #[error("a polygon point is not finite")]
    NotFinite,
    #[error("the triangulation failed: {0}")]
    Triangulation(String),
}

/// Computes the chordal axis of a simple polygon (see the module docs). Consecutive
/// repeated points are dropped; contour edges that would cross an earlier one (a
/// self-touching contour) are left out of the constraints.
///
/// # Errors
/// Fewer than 3 distinct points, non-finite coordinates, or a triangulation failure.
pub fn chordal_axis(polygon: &[DVec2]) -> Result<ChordalAxis, ChordalError> {
    let mut pts: Vec<DVec2> = Vec::with_capacity(polygon.len());
    for &p in polygon {
        if !p.is_finite() {
            return Err(ChordalError::NotFinite);
        }
        if pts.last() != Some(&p) {
            pts.push(p);
        }
    }
    while pts.len() > 1 && pts.first() == pts.last() {
        pts.pop();
    }
    if pts.len() < 3 {
        return Err(ChordalError::TooFewPoints(pts.len()));
    }
    let n = pts.len();
    let vertices: Vec<Point2<f64>> = pts.iter().map(|p| Point2::new(p.x, p.y)).collect();
    let edges: Vec<[usize; 2]> = (0..n).map(|i| [i, (i + 1) % n]).collect();
    let cdt: ConstrainedDelaunayTriangulation<Point2<f64>> =
        ConstrainedDelaunayTriangulation::try_bulk_load_cdt(vertices, edges, |_| {})
            .map_err(|e| ChordalError::Triangulation(format!("{e:?}")))?;

    // Cumulative contour length at each point (and the full perimeter at the end).
    let mut arc = Vec::with_capacity(n + 1);
    arc.push(0.0);
    for i in 0..n {
        arc.push(arc[i] + pts[i].distance(pts[(i + 1) % n]));
    }
    let mut out = ChordalAxis::default();
    let v2 = |p: Point2<f64>| DVec2::new(p.x, p.y);
    for face in cdt.inner_faces() {
        let [p0, p1, p2] = face.positions().map(v2);
        let centroid = (p0 + p1 + p2) / 3.0;
        if !inside(&pts, centroid) {
            continue;
        }
        out.triangles += 1;
        // Chords: the triangle's sides that are not contour edges.
        let mut chords: [(DVec2, f64); 3] = [(DVec2::ZERO, 0.0); 3];
        let mut k = 0;
        for e in face.adjacent_edges() {
            let [va, vb] = e.vertices().map(|v| v.fix().index());
            if !e.is_constraint_edge() && !is_sliver_side(&arc, va, vb, e.length_2().sqrt()) {
                let [a, b] = e.positions().map(v2);
                chords[k] = ((a + b) * 0.5, a.distance(b));
                k += 1;
            }
        }
        match k {
            2 => out.segments.push(AxisSegment {
                a: chords[0].0,
                b: chords[1].0,
                width: 0.5 * (chords[0].1 + chords[1].1),
                kind: TriangleKind::Sleeve,
            }),
            3 => {
                out.junctions.push(centroid);
                for &(m, w) in &chords {
                    out.segments.push(AxisSegment {
                        a: centroid,
                        b: m,
                        width: w,
                        kind: TriangleKind::Junction,
                    });
                }
            }
            // A terminal triangle (k == 1) ends its limb at the chord; a lone triangle
            // (k == 0) has no axis.
            _ => {}
        }
    }
    Ok(out)
}

/// True when the side (a, b) spans a nearly straight stretch of contour (see
/// [`SLIVER_CHORD_ARC`]). `arc` holds the cumulative lengths, perimeter last.
fn is_sliver_side(arc: &[f64], a: usize, b: usize, length: f64) -> bool {
    let (Some(&la), Some(&lb), Some(&total)) = (arc.get(a), arc.get(b), arc.last()) else {
        return false;
    };
    let along = (la - lb).abs();
    let shorter = along.min(total - along);
    length >= SLIVER_CHORD_ARC * shorter
}

/// Crossing-number point-in-polygon test.
fn inside(poly: &[DVec2], p: DVec2) -> bool {
    let mut c = false;
    let n = poly.len();
    let mut j = n - 1;
    for i in 0..n {
        let (a, b) = (poly[i], poly[j]);
        if (a.y > p.y) != (b.y > p.y) && p.x < a.x + (p.y - a.y) * (b.x - a.x) / (b.y - a.y) {
            c = !c;
        }
        j = i;
    }
    c
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A rectangle `len` x `width` along direction `angle` (radians), its boundary sampled
    /// every `step`.
    fn limb(len: f64, width: f64, angle: f64, step: f64) -> Vec<DVec2> {
        let (u, v) = (
            DVec2::new(angle.cos(), angle.sin()),
            DVec2::new(-angle.sin(), angle.cos()),
        );
        let corners = [
            -0.5 * len * u - 0.5 * width * v,
            0.5 * len * u - 0.5 * width * v,
            0.5 * len * u + 0.5 * width * v,
            -0.5 * len * u + 0.5 * width * v,
        ];
        let mut out = Vec::new();
        for k in 0..4 {
            let (a, b) = (corners[k], corners[(k + 1) % 4]);
            let m = ((a.distance(b) / step).round() as usize).max(1);
            for i in 0..m {
                out.push(a + (b - a) * (i as f64 / m as f64));
            }
        }
        out
    }

    #[test]
    fn sleeves_follow_a_limb_at_any_angle() {
        for deg in [0.0f64, 23.0, 37.0, 61.0, 90.0, 128.0] {
            let a = deg.to_radians();
            let dir = DVec2::new(a.cos(), a.sin());
            let normal = DVec2::new(-a.sin(), a.cos());
            let (len, width) = (200.0, 30.0);
            let poly = limb(len, width, a, 2.0);
            let axis = chordal_axis(&poly).unwrap();
            let sleeves: Vec<_> = axis
                .segments
                .iter()
                .filter(|s| s.kind == TriangleKind::Sleeve)
                .collect();
            assert!(sleeves.len() > 20, "{deg} deg: {} sleeves", sleeves.len());
            // Away from the ends, sleeve midpoints lie on the centre line (all but the
            // few slivers between nearly collinear boundary points, which still stay
            // inside the limb's middle half) and the segments' summed direction is the
            // limb's.
            let mut sum = DVec2::ZERO;
            let (mut middle, mut centred) = (0usize, 0usize);
            for s in &sleeves {
                let m = 0.5 * (s.a + s.b);
                if m.dot(dir).abs() < 0.5 * len - width {
                    let off = m.dot(normal).abs();
                    assert!(off < 0.5 * width, "{deg} deg: {m}");
                    middle += 1;
                    centred += (off < 0.1 * width) as usize;
                    let d = s.b - s.a;
                    sum += if d.dot(dir) < 0.0 { -d } else { d };
                }
            }
            assert!(
                centred * 10 >= middle * 9,
                "{deg} deg: {centred} of {middle} centred"
            );
            let got = sum.normalize();
            assert!(got.dot(dir) > 0.999, "{deg} deg: axis {got} vs {dir}");
        }
    }

    #[test]
    fn a_branching_shape_has_a_junction() {
        // A "T": a bar with a stem; the axis branches where they meet.
        let poly = [
            DVec2::new(0.0, 0.0),
            DVec2::new(40.0, 0.0),
            DVec2::new(40.0, 100.0),
            DVec2::new(100.0, 100.0),
            DVec2::new(100.0, 140.0),
            DVec2::new(-60.0, 140.0),
            DVec2::new(-60.0, 100.0),
            DVec2::new(0.0, 100.0),
        ];
        // Densify the boundary so the triangulation has sleeves.
        let mut dense = Vec::new();
        for i in 0..poly.len() {
            let (a, b) = (poly[i], poly[(i + 1) % poly.len()]);
            let m = (a.distance(b) / 4.0).ceil() as usize;
            for k in 0..m {
                dense.push(a + (b - a) * (k as f64 / m as f64));
            }
        }
        let axis = chordal_axis(&dense).unwrap();
        assert!(!axis.junctions.is_empty());
        // The junction lies where stem and bar meet.
        assert!(axis
            .junctions
            .iter()
            .any(|j| (j.x - 20.0).abs() < 30.0 && (j.y - 120.0).abs() < 25.0));
        assert!(matches!(
            chordal_axis(&[DVec2::ZERO, DVec2::X, DVec2::X]),
            Err(ChordalError::TooFewPoints(2))
        ));
        assert!(matches!(
            chordal_axis(&[DVec2::ZERO, DVec2::X, DVec2::new(f64::NAN, 1.0)]),
            Err(ChordalError::NotFinite)
        ));
    }
}
