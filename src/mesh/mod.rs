//! Mesh core: an indexed triangle mesh with ordered one-rings, normals, file I/O,
//! horizontal cross-sections and their convex hulls.
//!
//! # Conventions
//! - Positions are `DVec3` in metres. Meshes that live in the station frame use its axes
//!   (`../shared/spec/formats.md`): +Y up, +Z toward the front camera (the subject faces
//!   +Z), +X the subject's left, origin on the floor at the centre of the mark.
//! - Triangles are counter-clockwise seen from outside (outward normals by the right-hand
//!   rule).
//! - A one-ring is the list of a vertex's neighbours in counter-clockwise order seen from
//!   outside; on the boundary it starts and ends at the two boundary neighbours.

pub mod io;
pub mod section;

use glam::DVec3;

/// An indexed triangle mesh. `positions` is #V x 3 (metres), `triangles` is #F x 3 indices.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct TriMesh {
    pub positions: Vec<DVec3>,
    pub triangles: Vec<[u32; 3]>,
}

/// Axis-aligned bounding box.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Aabb {
    pub min: DVec3,
    pub max: DVec3,
}

impl Aabb {
    pub fn from_points(points: &[DVec3]) -> Option<Self> {
        let first = *points.first()?;
        let mut b = Aabb {
            min: first,
            max: first,
        };
        for p in points {
            b.min = b.min.min(*p);
            b.max = b.max.max(*p);
        }
        Some(b)
    }
    pub fn size(&self) -> DVec3 {
        self.max - self.min
    }
    pub fn center(&self) -> DVec3 {
        0.5 * (self.min + self.max)
    }
}

/// Ordered one-rings of every vertex in compressed form.
///
/// `neighbours(v)` lists v's neighbours counter-clockwise seen from outside. A vertex on
/// the boundary (or at a non-manifold spot the ordering could not close) is flagged in
/// `is_boundary`; its ring is an open fan from one boundary neighbour to the other.
#[derive(Debug, Clone, Default)]
pub struct OneRings {
    offsets: Vec<u32>,
    ring: Vec<u32>,
    is_boundary: Vec<bool>,
}

impl OneRings {
    /// Builds the ordered one-rings of `mesh`. O(#F) time.
    pub fn new(mesh: &TriMesh) -> Self {
        let n = mesh.positions.len();
        // Incident (next, prev) pairs per vertex: for triangle (a, b, c) the vertex a sees
        // the directed edge b -> c in its ring.
        let mut count = vec![0u32; n + 1];
        for t in &mesh.triangles {
            for &v in t {
                count[v as usize + 1] += 1;
            }
        }
        for i in 0..n {
            count[i + 1] += count[i];
        }
        let mut fill = count.clone();
        let mut edges = vec![(0u32, 0u32); mesh.triangles.len() * 3];
        for t in &mesh.triangles {
            for k in 0..3 {
                let v = t[k] as usize;
                let e = (t[(k + 1) % 3], t[(k + 2) % 3]);
                edges[fill[v] as usize] = e;
                fill[v] += 1;
            }
        }
        let mut offsets = Vec::with_capacity(n + 1);
        let mut ring = Vec::with_capacity(edges.len() + n);
        let mut is_boundary = vec![false; n];
        offsets.push(0u32);
        let mut used: Vec<bool> = Vec::new();
        for v in 0..n {
            let fan = &edges[count[v] as usize..count[v + 1] as usize];
            if fan.is_empty() {
                is_boundary[v] = true;
                offsets.push(ring.len() as u32);
                continue;
            }
            used.clear();
            used.resize(fan.len(), false);
            // Start at an edge whose tail is no other edge's head (a boundary start).
            let start = (0..fan.len())
                .find(|&i| !fan.iter().any(|e| e.1 == fan[i].0))
                .unwrap_or(0);
            let open = fan.iter().any(|e| !fan.iter().any(|f| f.1 == e.0));
            let begin = ring.len();
            ring.push(fan[start].0);
            let mut cur = start;
            used[cur] = true;
            let mut closed = false;
            loop {
                let head = fan[cur].1;
                if !open && head == fan[start].0 {
                    closed = true;
                    break;
                }
                ring.push(head);
                match (0..fan.len()).find(|&i| !used[i] && fan[i].0 == head) {
                    Some(next) => {
                        used[next] = true;
                        cur = next;
                    }
                    None => break,
                }
            }
            let complete = used.iter().all(|u| *u);
            if !complete {
                // Non-manifold fan: keep the unique neighbours, mark it open.
                for e in fan {
                    for w in [e.0, e.1] {
                        if !ring[begin..].contains(&w) {
                            ring.push(w);
                        }
                    }
                }
            }
            is_boundary[v] = open || !closed || !complete;
            offsets.push(ring.len() as u32);
        }
        OneRings {
            offsets,
            ring,
            is_boundary,
        }
    }

    /// Neighbours of `v`, counter-clockwise seen from outside.
    #[inline]
    pub fn neighbours(&self, v: usize) -> &[u32] {
        &self.ring[self.offsets[v] as usize..self.offsets[v + 1] as usize]
    }
    /// Whether `v`'s ring is open (mesh boundary or non-manifold).
    #[inline]
    pub fn is_boundary(&self, v: usize) -> bool {
        self.is_boundary[v]
    }
    pub fn vertex_count(&self) -> usize {
        self.is_boundary.len()
    }
    /// Total number of (vertex, neighbour) entries.
    pub fn entry_count(&self) -> usize {
        self.ring.len()
    }
    /// Offset of `v`'s first entry in the flat ring array (for per-entry side tables).
    #[inline]
    pub fn offset(&self, v: usize) -> usize {
        self.offsets[v] as usize
    }
}

impl TriMesh {
    pub fn new(positions: Vec<DVec3>, triangles: Vec<[u32; 3]>) -> Self {
        TriMesh {
            positions,
            triangles,
        }
    }
    pub fn vertex_count(&self) -> usize {
        self.positions.len()
    }
    pub fn triangle_count(&self) -> usize {
        self.triangles.len()
    }
    pub fn bounds(&self) -> Option<Aabb> {
        Aabb::from_points(&self.positions)
    }
    pub fn one_rings(&self) -> OneRings {
        OneRings::new(self)
    }

    /// Checks that every index is in range and no triangle repeats a vertex.
    pub fn validate(&self) -> Result<(), String> {
        let n = self.positions.len() as u32;
        for (i, t) in self.triangles.iter().enumerate() {
            if t.iter().any(|&v| v >= n) {
                return Err(format!("triangle {i} indexes a vertex beyond {n}"));
            }
            if t[0] == t[1] || t[1] == t[2] || t[0] == t[2] {
                return Err(format!("triangle {i} repeats a vertex"));
            }
        }
        if self.positions.iter().any(|p| !p.is_finite()) {
            return Err("a vertex position is not finite".into());
        }
        Ok(())
    }

    /// Area-weighted vertex normals (unit length; zero for isolated vertices).
    pub fn vertex_normals(&self) -> Vec<DVec3> {
        let mut n = vec![DVec3::ZERO; self.positions.len()];
        for t in &self.triangles {
            let [a, b, c] = t.map(|i| self.positions[i as usize]);
            let fn_ = (b - a).cross(c - a);
            for &i in t {
                n[i as usize] += fn_;
            }
        }
        for v in &mut n {
            *v = v.normalize_or_zero();
        }
        n
    }

    /// Mean edge length (each undirected edge of a closed mesh counted twice).
    pub fn mean_edge_length(&self) -> f64 {
        let mut sum = 0.0;
        let mut cnt = 0usize;
        for t in &self.triangles {
            for k in 0..3 {
                sum += (self.positions[t[k] as usize] - self.positions[t[(k + 1) % 3] as usize])
                    .length();
                cnt += 1;
            }
        }
        if cnt == 0 {
            0.0
        } else {
            sum / cnt as f64
        }
    }

    /// Signed volume (positive for a closed, outward-oriented mesh), cubic metres.
    pub fn volume(&self) -> f64 {
        self.triangles
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|i| self.positions[i as usize]);
                a.dot(b.cross(c)) / 6.0
            })
            .sum()
    }

    /// Surface area, square metres.
    pub fn area(&self) -> f64 {
        self.triangles
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|i| self.positions[i as usize]);
                0.5 * (b - a).cross(c - a).length()
            })
            .sum()
    }

    /// Number of edges used by exactly one triangle (0 for a watertight mesh).
    pub fn boundary_edge_count(&self) -> usize {
        let mut edges: Vec<(u32, u32)> = Vec::with_capacity(self.triangles.len() * 3);
        for t in &self.triangles {
            for k in 0..3 {
                let (a, b) = (t[k], t[(k + 1) % 3]);
                edges.push((a.min(b), a.max(b)));
            }
        }
        edges.sort_unstable();
        let mut count = 0;
        let mut i = 0;
        while i < edges.len() {
            let mut j = i + 1;
            while j < edges.len() && edges[j] == edges[i] {
                j += 1;
            }
            if j - i == 1 {
                count += 1;
            }
            i = j;
        }
        count
    }

    /// Applies `f` to every position.
    pub fn map_positions(&mut self, f: impl Fn(DVec3) -> DVec3) {
        for p in &mut self.positions {
            *p = f(*p);
        }
    }

    /// Keeps only the vertices used by triangles, renumbering in the original order;
    /// returns the old index of each kept vertex.
    pub fn compact(&mut self) -> Vec<u32> {
        let mut used = vec![false; self.positions.len()];
        for t in &self.triangles {
            for &v in t {
                used[v as usize] = true;
            }
        }
        let mut map = vec![u32::MAX; self.positions.len()];
        let mut kept = Vec::new();
        for (old, &u) in used.iter().enumerate() {
            if u {
                map[old] = kept.len() as u32;
                kept.push(old as u32);
            }
        }
        for t in &mut self.triangles {
            for v in t.iter_mut() {
                *v = map[*v as usize];
            }
        }
        self.positions = kept.iter().map(|&o| self.positions[o as usize]).collect();
        kept
    }
}

/// Small deterministic meshes for tests and examples.
pub mod shapes {
    use super::TriMesh;
    use glam::DVec3;
    use std::f64::consts::TAU;

    /// A closed UV sphere (poles + `rings` latitude rings of `segments` vertices).
    pub fn uv_sphere(radius: f64, rings: usize, segments: usize) -> TriMesh {
        let mut p = vec![DVec3::new(0.0, radius, 0.0)];
        for r in 1..=rings {
            let th = std::f64::consts::PI * r as f64 / (rings + 1) as f64;
            for s in 0..segments {
                let ph = TAU * s as f64 / segments as f64;
                p.push(radius * DVec3::new(th.sin() * ph.cos(), th.cos(), -th.sin() * ph.sin()));
            }
        }
        p.push(DVec3::new(0.0, -radius, 0.0));
        let south = (p.len() - 1) as u32;
        let idx = |r: usize, s: usize| (1 + r * segments + s % segments) as u32;
        let mut t = Vec::new();
        for s in 0..segments {
            t.push([0, idx(0, s), idx(0, s + 1)]);
            t.push([south, idx(rings - 1, s + 1), idx(rings - 1, s)]);
        }
        for r in 0..rings - 1 {
            for s in 0..segments {
                t.push([idx(r, s), idx(r + 1, s), idx(r + 1, s + 1)]);
                t.push([idx(r, s), idx(r + 1, s + 1), idx(r, s + 1)]);
            }
        }
        TriMesh::new(p, t)
    }

    /// A closed cylinder along +Y with an elliptic cross-section (semi-axes `a` in x,
    /// `b` in z), from y = 0 to `height`, capped at both ends with a centre vertex.
    pub fn elliptic_cylinder(
        a: f64,
        b: f64,
        height: f64,
        rings: usize,
        segments: usize,
    ) -> TriMesh {
        profile_prism(
            &(0..segments)
                .map(|s| {
                    let ph = TAU * s as f64 / segments as f64;
                    (a * ph.cos(), b * ph.sin())
                })
                .collect::<Vec<_>>(),
            height,
            rings,
        )
    }

    /// A closed prism along +Y over a polygon (x, z) given counter-clockwise seen from +Y
    /// looking down... i.e. (x, z) ordered so that x -> z turns positively.
    pub fn profile_prism(profile: &[(f64, f64)], height: f64, rings: usize) -> TriMesh {
        let segments = profile.len();
        let mut p = Vec::new();
        for r in 0..=rings {
            let y = height * r as f64 / rings as f64;
            for &(x, z) in profile {
                p.push(DVec3::new(x, y, z));
            }
        }
        let idx = |r: usize, s: usize| (r * segments + s % segments) as u32;
        let mut t = Vec::new();
        for r in 0..rings {
            for s in 0..segments {
                // Outward: ring vertices go x -> z; seen from outside with +Y up the
                // sequence (r,s) -> (r,s+1) runs right to left, so wind accordingly.
                t.push([idx(r, s), idx(r + 1, s + 1), idx(r, s + 1)]);
                t.push([idx(r, s), idx(r + 1, s), idx(r + 1, s + 1)]);
            }
        }
        let (cx, cz) = profile.iter().fold((0.0, 0.0), |a, q| {
            (a.0 + q.0 / segments as f64, a.1 + q.1 / segments as f64)
        });
        let bottom = p.len() as u32;
        p.push(DVec3::new(cx, 0.0, cz));
        let top = p.len() as u32;
        p.push(DVec3::new(cx, height, cz));
        for s in 0..segments {
            t.push([bottom, idx(0, s + 1), idx(0, s)]);
            t.push([top, idx(rings, s), idx(rings, s + 1)]);
        }
        let mut m = TriMesh::new(p, t);
        if m.volume() < 0.0 {
            for tri in &mut m.triangles {
                tri.swap(1, 2);
            }
        }
        m
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sphere_is_closed_and_rings_are_closed() {
        let m = shapes::uv_sphere(1.0, 12, 24);
        assert_eq!(m.boundary_edge_count(), 0);
        assert!(m.volume() > 0.0);
        let r = m.one_rings();
        for v in 0..m.vertex_count() {
            assert!(!r.is_boundary(v), "vertex {v} open");
            assert!(r.neighbours(v).len() >= 3);
        }
        // Volume close to 4/3 pi.
        assert!((m.volume() - 4.18879).abs() < 0.3);
    }

    #[test]
    // Index arithmetic over several arrays reads better with indices.
    #[allow(clippy::needless_range_loop)]
    fn ring_order_is_counter_clockwise_from_outside() {
        let m = shapes::uv_sphere(1.0, 8, 16);
        let r = m.one_rings();
        let n = m.vertex_normals();
        for v in 0..m.vertex_count() {
            let nb = r.neighbours(v);
            let c = m.positions[v];
            let mut s = DVec3::ZERO;
            for i in 0..nb.len() {
                let a = m.positions[nb[i] as usize] - c;
                let b = m.positions[nb[(i + 1) % nb.len()] as usize] - c;
                s += a.cross(b);
            }
            assert!(s.dot(n[v]) > 0.0, "vertex {v} ring is clockwise");
        }
    }

    #[test]
    fn open_fan_is_flagged_boundary() {
        // A square of two triangles: every vertex is on the boundary.
        let m = TriMesh::new(
            vec![DVec3::ZERO, DVec3::X, DVec3::new(1.0, 1.0, 0.0), DVec3::Y],
            vec![[0, 1, 2], [0, 2, 3]],
        );
        let r = m.one_rings();
        assert!((0..4).all(|v| r.is_boundary(v)));
        assert_eq!(r.neighbours(0), &[1, 2, 3]);
        assert_eq!(m.boundary_edge_count(), 4);
    }

    #[test]
    fn prism_is_outward() {
        let m = shapes::elliptic_cylinder(0.2, 0.1, 1.0, 4, 32);
        assert!(m.volume() > 0.0);
        assert_eq!(m.boundary_edge_count(), 0);
    }
}
