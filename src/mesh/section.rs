//! Plane cross-sections of a mesh as closed loops, 2-D convex hulls and perimeters.
//!
//! A horizontal section at height `y` (metres, station frame) is returned in the (x, z)
//! plane: `DVec2::new(x, z)`. A general plane section is returned in the plane's own
//! orthonormal basis (see [`Plane::basis`]).

use super::TriMesh;
use glam::{DVec2, DVec3};

/// A plane `normal . p = offset` (normal of unit length).
#[derive(Debug, Clone, Copy)]
pub struct Plane {
    pub normal: DVec3,
    pub offset: f64,
}

impl Plane {
    pub fn new(point: DVec3, normal: DVec3) -> Self {
        let n = normal.normalize();
        Plane {
            normal: n,
            offset: n.dot(point),
        }
    }
    /// The horizontal plane at height `y`.
    pub fn horizontal(y: f64) -> Self {
        Plane {
            normal: DVec3::Y,
            offset: y,
        }
    }
    /// Two in-plane unit axes (u, v) with u x v = normal. For the horizontal plane
    /// u = +X and v = +Z... mapped so that a section's 2-D point is (x, z).
    pub fn basis(&self) -> (DVec3, DVec3) {
        if (self.normal - DVec3::Y).length() < 1e-12 {
            return (DVec3::X, DVec3::Z);
        }
        let helper = if self.normal.x.abs() < 0.9 {
            DVec3::X
        } else {
            DVec3::Z
        };
        let u = (helper - self.normal * self.normal.dot(helper)).normalize();
        let v = self.normal.cross(u);
        (u, v)
    }
    #[inline]
    pub fn signed_distance(&self, p: DVec3) -> f64 {
        self.normal.dot(p) - self.offset
    }
}

/// Cuts `mesh` with `plane` and chains the cut segments into polylines.
///
/// Each returned loop is a list of 2-D points in the plane basis; `closed` tells whether
/// it returned to its start (every loop of a watertight mesh does). Vertices exactly on the
/// plane are nudged by 1e-12 m so no segment degenerates.
pub fn slice(mesh: &TriMesh, plane: &Plane) -> Vec<SectionLoop> {
    let (u, v) = plane.basis();
    let eps = 1e-12;
    let d: Vec<f64> = mesh
        .positions
        .iter()
        .map(|p| {
            let s = plane.signed_distance(*p);
            if s.abs() < eps {
                eps
            } else {
                s
            }
        })
        .collect();
    // Segments keyed by the mesh edges they cross, so chaining is exact (no tolerance).
    let mut segs: Vec<((u32, u32), (u32, u32))> = Vec::new();
    for t in &mesh.triangles {
        let mut cut = [(0u32, 0u32); 2];
        let mut k = 0;
        for e in 0..3 {
            let (a, b) = (t[e], t[(e + 1) % 3]);
            if (d[a as usize] > 0.0) != (d[b as usize] > 0.0) && k < 2 {
                cut[k] = (a.min(b), a.max(b));
                k += 1;
            }
        }
        if k == 2 {
            segs.push((cut[0], cut[1]));
        }
    }
    let point_of = |e: (u32, u32)| {
        let (pa, pb) = (mesh.positions[e.0 as usize], mesh.positions[e.1 as usize]);
        let (da, db) = (d[e.0 as usize], d[e.1 as usize]);
        let t = da / (da - db);
        let p = pa + (pb - pa) * t;
        DVec2::new(p.dot(u), p.dot(v))
    };
    // Adjacency: each crossed edge appears in at most two segments on a manifold mesh.
    let mut by_edge: std::collections::HashMap<(u32, u32), Vec<usize>> =
        std::collections::HashMap::with_capacity(segs.len() * 2);
    for (i, s) in segs.iter().enumerate() {
        by_edge.entry(s.0).or_default().push(i);
        by_edge.entry(s.1).or_default().push(i);
    }
    let mut used = vec![false; segs.len()];
    let mut loops = Vec::new();
    for start in 0..segs.len() {
        if used[start] {
            continue;
        }
        used[start] = true;
        let first_edge = segs[start].0;
        let mut chain = vec![first_edge, segs[start].1];
        let mut cur_edge = segs[start].1;
        let mut closed = false;
        loop {
            if cur_edge == first_edge {
                chain.pop();
                closed = true;
                break;
            }
            let next = by_edge
                .get(&cur_edge)
                .and_then(|l| l.iter().copied().find(|&i| !used[i]));
            match next {
                Some(i) => {
                    used[i] = true;
                    let s = segs[i];
                    cur_edge = if s.0 == cur_edge { s.1 } else { s.0 };
                    chain.push(cur_edge);
                }
                None => break,
            }
        }
        loops.push(SectionLoop {
            points: chain.into_iter().map(point_of).collect(),
            closed,
        });
    }
    loops
}

/// One cross-section polyline.
#[derive(Debug, Clone, PartialEq)]
pub struct SectionLoop {
    pub points: Vec<DVec2>,
    pub closed: bool,
}

impl SectionLoop {
    /// Perimeter (closing segment included when closed), metres.
    pub fn perimeter(&self) -> f64 {
        polyline_length(&self.points, self.closed)
    }
    /// Centroid of the points.
    pub fn centroid(&self) -> DVec2 {
        self.points.iter().copied().sum::<DVec2>() / self.points.len().max(1) as f64
    }
    /// Absolute enclosed area (shoelace), square metres.
    pub fn area(&self) -> f64 {
        signed_area(&self.points).abs()
    }
}

pub fn polyline_length(p: &[DVec2], closed: bool) -> f64 {
    let mut s: f64 = p.windows(2).map(|w| (w[1] - w[0]).length()).sum();
    if closed && p.len() > 2 {
        s += (p[0] - p[p.len() - 1]).length();
    }
    s
}

pub fn signed_area(p: &[DVec2]) -> f64 {
    let n = p.len();
    (0..n).map(|i| p[i].perp_dot(p[(i + 1) % n])).sum::<f64>() * 0.5
}

/// Convex hull of 2-D points (Andrew's monotone chain), counter-clockwise, no repeated
/// or collinear points. Fewer than 3 distinct points are returned as they are.
pub fn convex_hull(points: &[DVec2]) -> Vec<DVec2> {
    let mut p: Vec<DVec2> = points.iter().copied().filter(|q| q.is_finite()).collect();
    p.sort_by(|a, b| a.x.total_cmp(&b.x).then(a.y.total_cmp(&b.y)));
    p.dedup();
    if p.len() < 3 {
        return p;
    }
    let cross = |o: DVec2, a: DVec2, b: DVec2| (a - o).perp_dot(b - o);
    let mut h: Vec<DVec2> = Vec::with_capacity(2 * p.len());
    for &q in &p {
        while h.len() >= 2 && cross(h[h.len() - 2], h[h.len() - 1], q) <= 0.0 {
            h.pop();
        }
        h.push(q);
    }
    let lower = h.len() + 1;
    for &q in p.iter().rev().skip(1) {
        while h.len() >= lower && cross(h[h.len() - 2], h[h.len() - 1], q) <= 0.0 {
            h.pop();
        }
        h.push(q);
    }
    h.pop();
    h
}

/// Perimeter of the convex hull of `points`: how a tape measure lies over them.
pub fn hull_perimeter(points: &[DVec2]) -> f64 {
    polyline_length(&convex_hull(points), true)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::shapes;

    #[test]
    fn hull_of_square_with_inner_points() {
        let pts = [
            DVec2::new(0.0, 0.0),
            DVec2::new(1.0, 0.0),
            DVec2::new(1.0, 1.0),
            DVec2::new(0.0, 1.0),
            DVec2::new(0.5, 0.5),
            DVec2::new(0.5, 0.0),
        ];
        let h = convex_hull(&pts);
        assert_eq!(h.len(), 4);
        assert!((hull_perimeter(&pts) - 4.0).abs() < 1e-12);
        assert!(signed_area(&h) > 0.0);
    }

    #[test]
    fn cylinder_section_is_one_closed_loop() {
        let m = shapes::elliptic_cylinder(0.15, 0.15, 1.0, 5, 64);
        let loops = slice(&m, &Plane::horizontal(0.43));
        assert_eq!(loops.len(), 1);
        assert!(loops[0].closed);
        // Both triangles of every side quad are cut: 128 points on the 64-gon.
        assert_eq!(loops[0].points.len(), 128);
        // Inscribed 64-gon perimeter.
        let expect = 2.0 * 64.0 * 0.15 * (std::f64::consts::PI / 64.0).sin();
        assert!((loops[0].perimeter() - expect).abs() < 1e-9);
    }

    #[test]
    fn slice_through_a_vertex_ring_is_still_closed() {
        let m = shapes::elliptic_cylinder(0.1, 0.2, 1.0, 4, 16);
        let loops = slice(&m, &Plane::horizontal(0.5));
        assert_eq!(loops.len(), 1);
        assert!(loops[0].closed);
    }

    #[test]
    fn slanted_plane_basis_is_orthonormal() {
        let pl = Plane::new(DVec3::ZERO, DVec3::new(0.3, 1.0, 0.2));
        let (u, v) = pl.basis();
        assert!(u.dot(v).abs() < 1e-12 && u.dot(pl.normal).abs() < 1e-12);
        assert!((u.cross(v) - pl.normal).length() < 1e-12);
    }
}
