//! Mesh simplification by edge collapse with quadric error metrics (Garland & Heckbert
//! 1997): every vertex carries the sum of the squared-distance quadrics of its faces'
//! planes (area weighted); the edge whose merged vertex has the least quadric error is
//! collapsed first, to the quadric's minimiser when it lies near the edge, otherwise to
//! the best of the two ends and the midpoint.
//!
//! Collapses keep a closed 2-manifold closed: an edge collapses only when its two end
//! rings share exactly the two opposite vertices (the link condition) and no surviving
//! triangle flips or degenerates. Used to make a template of another topology and vertex
//! count from the library's body (units unchanged, metres).

use crate::mesh::TriMesh;
use glam::{DMat3, DVec3};
use std::cmp::Ordering;
use std::collections::BinaryHeap;

/// A collapse is refused when a surviving face normal turns by more than this
/// (cosine of the angle between old and new normal).
const MIN_NORMAL_COS: f64 = 0.2;
/// The quadric minimiser is used only within this many edge lengths of the midpoint.
const MAX_SHIFT_EDGES: f64 = 1.0;
/// Relative determinant below which the quadric system counts as singular.
const SINGULAR_REL: f64 = 1e-9;

/// Symmetric 4x4 quadric, upper triangle: a2 ab ac ad b2 bc bd c2 cd d2.
#[derive(Clone, Copy, Default)]
struct Quadric([f64; 10]);

impl Quadric {
    fn from_plane(n: DVec3, d: f64, w: f64) -> Self {
        let (a, b, c) = (n.x, n.y, n.z);
        Quadric(
            [
                a * a,
                a * b,
                a * c,
                a * d,
                b * b,
                b * c,
                b * d,
                c * c,
                c * d,
                d * d,
            ]
            .map(|v| v * w),
        )
    }
    fn add(&self, o: &Quadric) -> Quadric {
        let mut r = self.0;
        for (x, y) in r.iter_mut().zip(o.0) {
            *x += y;
        }
        Quadric(r)
    }
    fn eval(&self, v: DVec3) -> f64 {
        let q = &self.0;
        let (x, y, z) = (v.x, v.y, v.z);
        q[0] * x * x
            + 2.0 * q[1] * x * y
            + 2.0 * q[2] * x * z
            + 2.0 * q[3] * x
            + q[4] * y * y
            + 2.0 * q[5] * y * z
            + 2.0 * q[6] * y
            + q[7] * z * z
            + 2.0 * q[8] * z
            + q[9]
    }
    fn minimiser(&self) -> Option<DVec3> {
        let q = &self.0;
        let a = DMat3::from_cols(
            DVec3::new(q[0], q[1], q[2]),
            DVec3::new(q[1], q[4], q[5]),
            DVec3::new(q[2], q[5], q[7]),
        );
        let scale = q[0].abs() + q[4].abs() + q[7].abs();
        let det = a.determinant();
        if scale <= 0.0 || det.abs() <= SINGULAR_REL * scale * scale * scale {
            return None;
        }
        Some(a.inverse() * -DVec3::new(q[3], q[6], q[8]))
    }
}

#[derive(PartialEq)]
struct Candidate {
    cost: f64,
    a: u32,
    b: u32,
    ver_a: u32,
    ver_b: u32,
    target: DVec3,
}
impl Eq for Candidate {}
impl Ord for Candidate {
    fn cmp(&self, o: &Self) -> Ordering {
        // Min-heap on cost, ties by vertex ids for determinism.
        o.cost
            .total_cmp(&self.cost)
            .then(o.a.cmp(&self.a))
            .then(o.b.cmp(&self.b))
    }
}
impl PartialOrd for Candidate {
    fn partial_cmp(&self, o: &Self) -> Option<Ordering> {
        Some(self.cmp(o))
    }
}

struct State {
    pos: Vec<DVec3>,
    tris: Vec<[u32; 3]>,
    tri_alive: Vec<bool>,
    vtris: Vec<Vec<u32>>,
    alive: Vec<bool>,
    version: Vec<u32>,
    quad: Vec<Quadric>,
}

impl State {
    fn neighbours(&self, v: u32) -> Vec<u32> {
        let mut n: Vec<u32> = Vec::new();
        for &t in &self.vtris[v as usize] {
            for &w in &self.tris[t as usize] {
                if w != v && !n.contains(&w) {
                    n.push(w);
                }
            }
        }
        n
    }

    fn candidate(&self, a: u32, b: u32) -> Candidate {
        let q = self.quad[a as usize].add(&self.quad[b as usize]);
        let (pa, pb) = (self.pos[a as usize], self.pos[b as usize]);
        let mid = 0.5 * (pa + pb);
        let len = (pa - pb).length();
        let mut best = (q.eval(mid), mid);
        for p in [pa, pb] {
            let c = q.eval(p);
            if c < best.0 {
                best = (c, p);
            }
        }
        if let Some(p) = q
            .minimiser()
            .filter(|p| (*p - mid).length() <= MAX_SHIFT_EDGES * len)
        {
            let c = q.eval(p);
            if c < best.0 {
                best = (c, p);
            }
        }
        Candidate {
            cost: best.0.max(0.0),
            a,
            b,
            ver_a: self.version[a as usize],
            ver_b: self.version[b as usize],
            target: best.1,
        }
    }

    /// Link condition and fold-over test for collapsing b into a at `p`.
    fn can_collapse(&self, a: u32, b: u32, p: DVec3) -> bool {
        let shared = self.vtris[a as usize]
            .iter()
            .filter(|t| self.tris[**t as usize].contains(&b))
            .count();
        if shared != 2 {
            return false;
        }
        let na = self.neighbours(a);
        let nb = self.neighbours(b);
        if na.iter().filter(|w| nb.contains(w)).count() != 2 {
            return false;
        }
        // Each end must keep at least 3 neighbours after the collapse.
        if na.len() + nb.len() < 2 + 2 + 3 {
            return false;
        }
        for &v in &[a, b] {
            for &t in &self.vtris[v as usize] {
                let tri = self.tris[t as usize];
                if tri.contains(&a) && tri.contains(&b) {
                    continue;
                }
                let old = tri.map(|i| self.pos[i as usize]);
                let new = tri.map(|i| {
                    if i == a || i == b {
                        p
                    } else {
                        self.pos[i as usize]
                    }
                });
                let n_old = (old[1] - old[0]).cross(old[2] - old[0]);
                let n_new = (new[1] - new[0]).cross(new[2] - new[0]);
                let (lo, ln) = (n_old.length(), n_new.length());
                if ln <= 1e-6 * lo.max(1e-30) || n_old.dot(n_new) < MIN_NORMAL_COS * lo * ln {
                    return false;
                }
            }
        }
        true
    }

    fn collapse(&mut self, a: u32, b: u32, p: DVec3) {
        self.pos[a as usize] = p;
        self.quad[a as usize] = self.quad[a as usize].add(&self.quad[b as usize]);
        let bt = std::mem::take(&mut self.vtris[b as usize]);
        for t in bt {
            let tri = self.tris[t as usize];
            if tri.contains(&a) {
                self.tri_alive[t as usize] = false;
                for &w in &tri {
                    if w != b {
                        self.vtris[w as usize].retain(|x| *x != t);
                    }
                }
            } else {
                self.tris[t as usize] = tri.map(|i| if i == b { a } else { i });
                self.vtris[a as usize].push(t);
            }
        }
        self.alive[b as usize] = false;
        self.version[a as usize] += 1;
    }
}

/// Simplifies a closed triangle mesh to about `target_vertices` vertices (fewer collapses
/// when no more edge passes the manifold and fold-over tests). Returns a compacted mesh
/// whose vertex order follows the input's (survivors keep their relative order).
pub fn decimate(mesh: &TriMesh, target_vertices: usize) -> TriMesh {
    let n = mesh.vertex_count();
    let mut st = State {
        pos: mesh.positions.clone(),
        tris: mesh.triangles.clone(),
        tri_alive: vec![true; mesh.triangle_count()],
        vtris: vec![Vec::new(); n],
        alive: vec![true; n],
        version: vec![0; n],
        quad: vec![Quadric::default(); n],
    };
    for (i, t) in mesh.triangles.iter().enumerate() {
        let [p0, p1, p2] = t.map(|v| mesh.positions[v as usize]);
        let c = (p1 - p0).cross(p2 - p0);
        let area2 = c.length();
        if area2 > 0.0 {
            let nrm = c / area2;
            let q = Quadric::from_plane(nrm, -nrm.dot(p0), 0.5 * area2);
            for &v in t {
                st.quad[v as usize] = st.quad[v as usize].add(&q);
            }
        }
        for &v in t {
            st.vtris[v as usize].push(i as u32);
        }
    }
    let mut heap = BinaryHeap::new();
    for t in &mesh.triangles {
        for k in 0..3 {
            let (a, b) = (t[k], t[(k + 1) % 3]);
            if a < b {
                heap.push(st.candidate(a, b));
            }
        }
    }
    let mut count = n;
    while count > target_vertices {
        let Some(c) = heap.pop() else { break };
        let (a, b) = (c.a as usize, c.b as usize);
        if !st.alive[a] || !st.alive[b] || st.version[a] != c.ver_a || st.version[b] != c.ver_b {
            continue;
        }
        if !st.can_collapse(c.a, c.b, c.target) {
            continue;
        }
        st.collapse(c.a, c.b, c.target);
        count -= 1;
        for w in st.neighbours(c.a) {
            let (x, y) = if c.a < w { (c.a, w) } else { (w, c.a) };
            heap.push(st.candidate(x, y));
        }
    }
    let tris: Vec<[u32; 3]> = st
        .tris
        .iter()
        .zip(&st.tri_alive)
        .filter(|(_, a)| **a)
        .map(|(t, _)| *t)
        .collect();
    let mut out = TriMesh::new(st.pos, tris);
    out.compact();
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::shapes;

    #[test]
    fn sphere_stays_closed_and_round() {
        let m = shapes::uv_sphere(1.0, 30, 60);
        let d = decimate(&m, m.vertex_count() / 4);
        assert!(
            d.vertex_count() <= m.vertex_count() / 4 + 1,
            "{} vertices",
            d.vertex_count()
        );
        assert_eq!(d.boundary_edge_count(), 0);
        assert!(d.volume() > 0.0);
        // Volume of the simplified sphere within 3 % of the original.
        assert!(
            (d.volume() / m.volume() - 1.0).abs() < 0.03,
            "{} vs {}",
            d.volume(),
            m.volume()
        );
        for p in &d.positions {
            assert!(
                (p.length() - 1.0).abs() < 0.05,
                "vertex at radius {}",
                p.length()
            );
        }
    }
}
