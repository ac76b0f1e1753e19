//! The influence field of a handle: which vertices follow a dragged vertex, and how far.
//!
//! The vertices within `reach` of the handle along the surface (Dijkstra over the mesh
//! edges) are free; the handle is fixed at its new place and everything else stays where
//! it is. The free vertices take the bi-Laplacian (thin-plate) displacement: the one that
//! minimises `sum_i |(L d)_i|^2 / A_i` over every vertex whose row touches the free region,
//! with `L` the cotangent Laplacian and `A_i` a third of the area of the triangles around
//! vertex i (Botsch and Kobbelt 2004). The displacement of every vertex is the handle's
//! offset times one scalar, so the field is solved once per handle, as a scalar, and a
//! drag only scales it. The bi-Laplacian keeps the surface smooth at the handle (a
//! Laplacian would leave a spike there) and its rows over the first fixed ring make the
//! bump meet the held surface with a matching slope.

use crate::deform::cotangent;
use crate::mesh::TriMesh;
use std::cmp::Reverse;
use std::collections::hash_map::Entry;
use std::collections::{BinaryHeap, HashMap, HashSet};

/// Smallest cotangent weight kept (obtuse angles give negative ones).
const MIN_WEIGHT: f64 = 1e-3;
/// Smallest vertex area (m^2): a vertex of degenerate triangles only.
const MIN_AREA_M2: f64 = 1e-12;
/// Relative residual at which the conjugate gradients stop.
const CG_TOLERANCE: f64 = 1e-11;

/// Why a field could not be made.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum FieldError {
    #[error("vertex {vertex} is not on the avatar ({count} vertices)")]
    NoSuchVertex { vertex: u32, count: usize },
    #[error("the reach must be positive and finite (got {0} m)")]
    BadReach(f64),
    #[error("the surface around the handle could not be solved ({0} unknowns did not converge)")]
    NotConverged(usize),
}

/// The mesh's edges as adjacency lists (both directions, without repeats).
pub struct Adjacency {
    offsets: Vec<u32>,
    neighbours: Vec<u32>,
    /// Per vertex, the triangles around it.
    tri_offsets: Vec<u32>,
    tris: Vec<u32>,
}

impl Adjacency {
    /// # Panics
    /// Never: triangles whose indices are outside the mesh are skipped.
    pub fn new(mesh: &TriMesh) -> Adjacency {
        let n = mesh.positions.len();
        let valid = |t: &[u32; 3]| t.iter().all(|&i| (i as usize) < n);
        let mut pairs: Vec<(u32, u32)> = Vec::with_capacity(mesh.triangles.len() * 6);
        let mut tri_pairs: Vec<(u32, u32)> = Vec::with_capacity(mesh.triangles.len() * 3);
        for (ti, t) in mesh.triangles.iter().enumerate() {
            if !valid(t) {
                continue;
            }
            for k in 0..3 {
                let (a, b) = (t[k], t[(k + 1) % 3]);
                if a != b {
                    pairs.push((a, b));
                    pairs.push((b, a));
                }
                tri_pairs.push((t[k], ti as u32));
            }
        }
        pairs.sort_unstable();
        pairs.dedup();
        tri_pairs.sort_unstable();
        tri_pairs.dedup();
        let csr = |pairs: &[(u32, u32)]| {
            let mut offsets = vec![0u32; n + 1];
            for &(a, _) in pairs {
                offsets[a as usize + 1] += 1;
            }
            for i in 0..n {
                offsets[i + 1] += offsets[i];
            }
            (offsets, pairs.iter().map(|&(_, b)| b).collect::<Vec<_>>())
        };
        let (offsets, neighbours) = csr(&pairs);
        let (tri_offsets, tris) = csr(&tri_pairs);
        Adjacency {
            offsets,
            neighbours,
            tri_offsets,
            tris,
        }
    }

    fn neighbours(&self, v: u32) -> &[u32] {
        &self.neighbours[self.offsets[v as usize] as usize..self.offsets[v as usize + 1] as usize]
    }

    fn triangles(&self, v: u32) -> &[u32] {
        &self.tris[self.tri_offsets[v as usize] as usize..self.tri_offsets[v as usize + 1] as usize]
    }
}

/// Surface distance from `from` to every vertex nearer than `reach` (Dijkstra over the
/// edges); the vertices in the order they were settled, `from` first.
pub fn within_reach(mesh: &TriMesh, adj: &Adjacency, from: u32, reach: f64) -> Vec<(u32, f64)> {
    let mut best: HashMap<u32, f64> = HashMap::new();
    let mut settled: HashSet<u32> = HashSet::new();
    let mut done: Vec<(u32, f64)> = Vec::new();
    let mut heap = BinaryHeap::new();
    best.insert(from, 0.0);
    // Non-negative f64s order as their bit patterns.
    heap.push(Reverse((0f64.to_bits(), from)));
    while let Some(Reverse((bits, v))) = heap.pop() {
        if !settled.insert(v) {
            continue;
        }
        let d = f64::from_bits(bits);
        done.push((v, d));
        for &u in adj.neighbours(v) {
            let nd = d + mesh.positions[v as usize].distance(mesh.positions[u as usize]);
            if nd < reach && !settled.contains(&u) && best.get(&u).is_none_or(|&b| nd < b) {
                best.insert(u, nd);
                heap.push(Reverse((nd.to_bits(), u)));
            }
        }
    }
    done
}

/// The scalar influence of a handle: `(vertex, weight)` for every vertex that moves, the
/// handle first with weight 1. A vertex moves by `weight * offset`.
pub fn influence(
    mesh: &TriMesh,
    adj: &Adjacency,
    handle: u32,
    reach: f64,
) -> Result<Vec<(u32, f64)>, FieldError> {
    let n = mesh.positions.len();
    if handle as usize >= n {
        return Err(FieldError::NoSuchVertex {
            vertex: handle,
            count: n,
        });
    }
    if !(reach.is_finite() && reach > 0.0) {
        return Err(FieldError::BadReach(reach));
    }
    let region = within_reach(mesh, adj, handle, reach);
    let free: Vec<u32> = region.iter().skip(1).map(|&(v, _)| v).collect();
    if free.is_empty() {
        return Ok(vec![(handle, 1.0)]);
    }
    let system = Bilaplacian::new(mesh, adj, handle, &free);
    let s = system.solve().ok_or(FieldError::NotConverged(free.len()))?;
    let mut out = Vec::with_capacity(free.len() + 1);
    out.push((handle, 1.0));
    out.extend(free.iter().copied().zip(s).filter(|&(_, w)| w != 0.0));
    Ok(out)
}

/// The bi-Laplacian system of the free vertices with the handle at 1 and the rest at 0.
struct Bilaplacian {
    free: usize,
    /// Rows of L over the local vertices: (neighbour local index, weight); a neighbour
    /// outside the local set is dropped (its value is 0, and it is never a free vertex).
    rows: Vec<Vec<(usize, f64)>>,
    /// Diagonal of L (minus the sum of the row's weights, with the dropped neighbours).
    diag: Vec<f64>,
    area: Vec<f64>,
}

impl Bilaplacian {
    fn new(mesh: &TriMesh, adj: &Adjacency, handle: u32, free: &[u32]) -> Bilaplacian {
        let mut order: Vec<u32> = free.to_vec();
        order.push(handle);
        // Local indices: the free vertices, the handle, then the ring around them (every
        // vertex whose Laplacian row touches a free one).
        let mut local: HashMap<u32, usize> =
            order.iter().enumerate().map(|(i, &v)| (v, i)).collect();
        for i in 0..order.len() {
            for &u in adj.neighbours(order[i]) {
                if let Entry::Vacant(e) = local.entry(u) {
                    e.insert(order.len());
                    order.push(u);
                }
            }
        }
        let m = order.len();
        // Every triangle around a local vertex, once: each local vertex gets its whole
        // area and the weights of all its edges (keyed by the neighbour's global index).
        let mut weights: Vec<HashMap<u32, f64>> = vec![HashMap::new(); m];
        let mut area = vec![0.0; m];
        let mut seen = HashSet::new();
        for &v in &order {
            for &t in adj.triangles(v) {
                if !seen.insert(t) {
                    continue;
                }
                let tri = mesh.triangles[t as usize];
                let p = tri.map(|k| mesh.positions[k as usize]);
                let a3 = (p[1] - p[0]).cross(p[2] - p[0]).length() / 6.0;
                for k in 0..3 {
                    // The angle at corner k weighs the opposite edge (a, b).
                    let (a, b) = (tri[(k + 1) % 3], tri[(k + 2) % 3]);
                    let c = 0.5 * cotangent(p[k], p[(k + 1) % 3], p[(k + 2) % 3]);
                    if let Some(&la) = local.get(&a) {
                        *weights[la].entry(b).or_default() += c;
                    }
                    if let Some(&lb) = local.get(&b) {
                        *weights[lb].entry(a).or_default() += c;
                    }
                    if let Some(&lk) = local.get(&tri[k]) {
                        area[lk] += a3;
                    }
                }
            }
        }
        let mut diag = vec![0.0; m];
        let mut rows = vec![Vec::new(); m];
        for i in 0..m {
            let mut sum = 0.0;
            // In neighbour order, so that a solve is the same from run to run.
            let mut ws: Vec<(u32, f64)> = weights[i].iter().map(|(&u, &w)| (u, w)).collect();
            ws.sort_unstable_by_key(|&(u, _)| u);
            for (u, w) in ws {
                let w = w.max(MIN_WEIGHT);
                sum += w;
                // A neighbour outside the local set is never free and is 0: dropped.
                if let Some(&lu) = local.get(&u) {
                    rows[i].push((lu, w));
                }
            }
            diag[i] = -sum;
            area[i] = area[i].max(MIN_AREA_M2);
        }
        Bilaplacian {
            free: free.len(),
            rows,
            diag,
            area,
        }
    }

    /// y = L x over the local vertices (x is 0 outside them).
    fn laplacian(&self, x: &[f64], y: &mut [f64]) {
        for (i, row) in self.rows.iter().enumerate() {
            let mut s = self.diag[i] * x[i];
            for &(j, w) in row {
                s += w * x[j];
            }
            y[i] = s;
        }
    }

    /// (L M^-1 L x) on the free vertices, x given on the free vertices (0 elsewhere but
    /// at the handle, whose value is `handle`).
    fn apply(&self, x: &[f64], handle: f64, full: &mut [f64], tmp: &mut [f64], out: &mut [f64]) {
        full.fill(0.0);
        full[..self.free].copy_from_slice(x);
        full[self.free] = handle;
        self.laplacian(full, tmp);
        for (t, a) in tmp.iter_mut().zip(&self.area) {
            *t /= a;
        }
        // L is symmetric: row k of L times tmp, for the free k only.
        for (k, o) in out.iter_mut().enumerate() {
            let mut s = self.diag[k] * tmp[k];
            for &(j, w) in &self.rows[k] {
                s += w * tmp[j];
            }
            *o = s;
        }
    }

    /// Conjugate gradients (Jacobi preconditioned) for the free values.
    fn solve(&self) -> Option<Vec<f64>> {
        let (f, m) = (self.free, self.rows.len());
        let mut full = vec![0.0; m];
        let mut tmp = vec![0.0; m];
        let mut b = vec![0.0; f];
        self.apply(&vec![0.0; f], 1.0, &mut full, &mut tmp, &mut b);
        b.iter_mut().for_each(|v| *v = -*v);
        // diag(K)_k = L_kk^2 / A_k + sum_i L_ik^2 / A_i.
        let precond: Vec<f64> = (0..f)
            .map(|k| {
                let own = self.diag[k] * self.diag[k] / self.area[k];
                let others: f64 = self.rows[k]
                    .iter()
                    .map(|&(i, w)| w * w / self.area[i])
                    .sum();
                1.0 / (own + others)
            })
            .collect();
        let mut x = vec![0.0; f];
        let mut r = b.clone();
        let norm_b = dot(&b, &b).sqrt();
        if norm_b == 0.0 {
            return Some(x);
        }
        let mut z: Vec<f64> = r.iter().zip(&precond).map(|(r, p)| r * p).collect();
        let mut p = z.clone();
        let mut rz = dot(&r, &z);
        let mut q = vec![0.0; f];
        for _ in 0..(20 * f + 200) {
            self.apply(&p, 0.0, &mut full, &mut tmp, &mut q);
            let pq = dot(&p, &q);
            if !(pq > 0.0) {
                break;
            }
            let alpha = rz / pq;
            for i in 0..f {
                x[i] += alpha * p[i];
                r[i] -= alpha * q[i];
            }
            if dot(&r, &r).sqrt() <= CG_TOLERANCE * norm_b {
                return Some(x);
            }
            for i in 0..f {
                z[i] = r[i] * precond[i];
            }
            let rz_new = dot(&r, &z);
            let beta = rz_new / rz;
            rz = rz_new;
            for i in 0..f {
                p[i] = z[i] + beta * p[i];
            }
        }
        // Not converged to the tolerance: accept only a small residual.
        (dot(&r, &r).sqrt() <= 1e-6 * norm_b).then_some(x)
    }
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::shapes;

    #[test]
    fn the_field_is_one_at_the_handle_and_zero_beyond_the_reach() {
        let m = shapes::uv_sphere(0.2, 80, 160);
        let adj = Adjacency::new(&m);
        let handle = (m.positions.len() / 2) as u32;
        let f = influence(&m, &adj, handle, 0.1).unwrap();
        assert_eq!(f[0], (handle, 1.0));
        let h = m.positions[handle as usize];
        for &(v, w) in &f[1..] {
            let d = m.positions[v as usize].distance(h);
            assert!(d < 0.1 + 1e-9, "{v} at {d} m moves");
            assert!(w > -0.05 && w < 1.0, "weight {w} at {d} m");
        }
        // Smooth falloff: the weights of the nearest ring are near 1, the far ones near 0.
        let near: Vec<f64> = f[1..]
            .iter()
            .filter(|&&(v, _)| m.positions[v as usize].distance(h) < 0.015)
            .map(|&(_, w)| w)
            .collect();
        assert!(
            !near.is_empty() && near.iter().all(|&w| w > 0.8),
            "{near:?}"
        );
        let far = f[1..]
            .iter()
            .filter(|&&(v, _)| m.positions[v as usize].distance(h) > 0.09)
            .map(|&(_, w)| w.abs())
            .fold(0.0, f64::max);
        assert!(far < 0.05, "{far}");
    }

    #[test]
    fn a_reach_shorter_than_an_edge_moves_the_handle_alone() {
        let m = shapes::uv_sphere(0.2, 10, 20);
        let adj = Adjacency::new(&m);
        assert_eq!(influence(&m, &adj, 5, 1e-4).unwrap(), vec![(5, 1.0)]);
        assert!(matches!(
            influence(&m, &adj, 5, f64::NAN),
            Err(FieldError::BadReach(_))
        ));
        assert!(matches!(
            influence(&m, &adj, 9999, 0.1),
            Err(FieldError::NoSuchVertex { .. })
        ));
    }

    #[test]
    fn surface_distance_is_at_least_the_straight_line() {
        let m = shapes::uv_sphere(0.2, 20, 40);
        let adj = Adjacency::new(&m);
        let r = within_reach(&m, &adj, 30, 0.25);
        assert_eq!(r[0], (30, 0.0));
        for &(v, d) in &r {
            assert!(d + 1e-12 >= m.positions[v as usize].distance(m.positions[30]));
            assert!(d < 0.25);
        }
        let mut vs: Vec<u32> = r.iter().map(|&(v, _)| v).collect();
        vs.sort_unstable();
        vs.dedup();
        assert_eq!(vs.len(), r.len(), "a vertex settled twice");
    }
}
