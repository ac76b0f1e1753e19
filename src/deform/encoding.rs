//! Mean value encoding of each vertex in the tangent plane of its ordered one-ring
//! (method.md section 2; Kraevoy and Sheffer's mean value encoding). Metres throughout;
//! weights and normal coefficients are dimensionless.
//!
//! Departures from the text, all invariant to rigid motion and uniform scale:
//! - The plane normal is `sum (v_i - l) x (v_{i+1} - l)`, outward for the crate's
//!   counter-clockwise rings; method.md writes the opposite order (inward). The sign
//!   cancels in decoding (every normal term carries it twice).
//! - On an open ring (mesh boundary, non-manifold spot) the polygon is not closed and the
//!   tangential weights are the minimum-norm affine weights that reproduce the projected
//!   vertex. The same weights replace mean value weights whenever those are undefined or
//!   fail to reproduce the vertex (zero sum, NaN).
//! - A projected vertex on a ring vertex takes that vertex's weight 1; on a ring edge the
//!   linear interpolation along that edge (the limits of the mean value weights).
//! - Collinear neighbours: the plane is the one through their line that contains the
//!   vertex. A vertex right above a neighbour (or on a ring of zero size) makes the
//!   tangent coefficients `b_i` unusable; such a vertex stores its height over the plane
//!   relative to the ring's mean radius instead ([`RingEncodingKind::RingHeight`]).

use crate::mesh::{OneRings, TriMesh};
use glam::{DMat3, DVec3};

/// Relative size under which a length counts as zero (relative to the ring radius).
const REL_EPS: f64 = 1e-10;
/// Largest |c_i| kept before b_i = c_i / sqrt(1 - c_i^2) is formed.
const MAX_ELEVATION_SINE: f64 = 1.0 - 1e-9;
/// Ridge of the minimum-norm affine weight system, relative to its trace.
const AFFINE_RIDGE: f64 = 1e-11;
/// Refinement steps of the minimum-norm affine weights.
const AFFINE_REFINEMENTS: usize = 3;
/// Reproduction tolerance of the tangential weights, relative to the ring radius (the
/// mean value weights fall back to affine weights beyond it).
const WEIGHT_REPRODUCTION_TOL: f64 = 1e-10;
/// Reproduction tolerance of the whole decoding at rest, relative to the ring radius (the
/// normal part falls back to [`RingEncodingKind::RingHeight`] beyond it).
const REPRODUCTION_TOL: f64 = 1e-7;
/// Largest ring decoded by the single-pass path of [`MeanValueEncoding::decode_vertex`]
/// (its scratch lives on the stack); larger rings take the general path.
const FAST_RING: usize = 16;

/// How a vertex's normal component is encoded.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RingEncodingKind {
    /// The paper's tangent coefficients `b_i` (the usual case).
    Tangent,
    /// Height over the ring plane divided by the ring's mean radius (degenerate rings).
    RingHeight,
    /// No neighbours: the vertex decodes to itself.
    Isolated,
}

/// Mean value encoding of every vertex of a mesh.
///
/// Per ring entry (indexed like [`OneRings`]): the tangential weight `w_i` and the
/// normal coefficient `b_i`; per vertex: the encoding kind and, for
/// [`RingEncodingKind::RingHeight`], the relative height.
#[derive(Debug, Clone)]
pub struct MeanValueEncoding {
    rings: OneRings,
    weights: Vec<f64>,
    tangents: Vec<f64>,
    kind: Vec<RingEncodingKind>,
    ring_height: Vec<f64>,
}

/// The plane of a ring: centre `l`, unit normal `n`, mean distance of the ring to `l`.
#[derive(Debug, Clone, Copy)]
struct RingPlane {
    centre: DVec3,
    normal: DVec3,
    radius: f64,
}

/// Fits the plane of method.md section 2 to the neighbours `nb` of a vertex at `own`.
/// `own` is only used to orient the plane when the neighbours are collinear.
fn ring_plane(
    nb: &[u32],
    closed: bool,
    positions: &[DVec3],
    own: DVec3,
    need_radius: bool,
) -> RingPlane {
    let m = nb.len();
    let at = |i: usize| positions[nb[i] as usize];
    let mut centre = DVec3::ZERO;
    for i in 0..m {
        centre += at(i);
    }
    centre /= m as f64;
    let mut far = DVec3::ZERO;
    let mut far2 = -1.0;
    let mut sum = DVec3::ZERO;
    let mut prev = at(m - 1) - centre;
    for i in 0..m {
        let d = at(i) - centre;
        let l2 = d.length_squared();
        if l2 > far2 {
            far2 = l2;
            far = d;
        }
        // sum_i (v_i - l) x (v_{i+1} - l), the open fan without its closing edge.
        if closed || i > 0 {
            sum += prev.cross(d);
        }
        prev = d;
    }
    let mean_radius = || (0..m).map(|i| (at(i) - centre).length()).sum::<f64>() / m as f64;
    if sum.length() > REL_EPS * far2 && sum.is_finite() {
        let radius = if need_radius { mean_radius() } else { 0.0 };
        return RingPlane {
            centre,
            normal: sum.normalize(),
            radius,
        };
    }
    let radius = mean_radius();
    let normal = if radius > 0.0 && far2 > 0.0 {
        // Collinear neighbours: the plane through their line containing the vertex.
        let dir = far / far2.sqrt();
        let off = own - centre;
        let perp = off - off.dot(dir) * dir;
        if perp.length() > REL_EPS * radius {
            perp.normalize()
        } else {
            dir.any_orthonormal_vector()
        }
    } else {
        let off = own - centre;
        if off.length() > 0.0 && off.is_finite() {
            off.normalize()
        } else {
            DVec3::Y
        }
    };
    RingPlane {
        centre,
        normal,
        radius,
    }
}

/// Minimum-norm affine weights `w` with `sum w = 1` and `sum w q_i = target` for 2-D
/// points `q` (ridge-regularised so collinear or coincident points stay finite).
fn affine_weights(q: &[[f64; 2]], target: [f64; 2], out: &mut [f64]) {
    let m = q.len();
    // Rows of A: [1, x_i, y_i]; G = A^T A (3 x 3); w = A (G + eps I)^-1 b.
    let mut g = DMat3::ZERO;
    for p in q {
        let a = DVec3::new(1.0, p[0], p[1]);
        g += DMat3::from_cols(a * a.x, a * a.y, a * a.z);
    }
    let ridge = AFFINE_RIDGE * (g.x_axis.x + g.y_axis.y + g.z_axis.z).max(f64::MIN_POSITIVE);
    g += DMat3::from_diagonal(DVec3::splat(ridge));
    let g_inv = g.inverse();
    let b = DVec3::new(1.0, target[0], target[1]);
    let z = g_inv * b;
    for (i, p) in q.iter().enumerate() {
        out[i] = z.x + z.y * p[0] + z.z * p[1];
    }
    // Iterative refinement removes the bias of the ridge where the system is regular.
    for _ in 0..AFFINE_REFINEMENTS {
        let mut r = b;
        for (w, p) in out.iter().zip(q) {
            r -= *w * DVec3::new(1.0, p[0], p[1]);
        }
        let dz = g_inv * r;
        for (i, p) in q.iter().enumerate() {
            out[i] += dz.x + dz.y * p[0] + dz.z * p[1];
        }
    }
    let sum: f64 = out.iter().sum();
    if !(sum.is_finite() && sum.abs() > REL_EPS) {
        out.iter_mut().for_each(|w| *w = 1.0 / m as f64);
    } else {
        // Exact partition of unity despite the ridge.
        out.iter_mut().for_each(|w| *w /= sum);
    }
}

/// Mean value weights of the origin in the closed 2-D polygon `q` (signed angles, so a
/// point outside a non-convex ring still gets weights); `None` when undefined.
fn mean_value_weights(q: &[[f64; 2]], radius: f64, out: &mut [f64]) -> Option<()> {
    let m = q.len();
    let len = |p: [f64; 2]| (p[0] * p[0] + p[1] * p[1]).sqrt();
    // On a ring vertex: weight 1 there.
    for i in 0..m {
        if len(q[i]) <= REL_EPS * radius {
            out.iter_mut().for_each(|w| *w = 0.0);
            out[i] = 1.0;
            return Some(());
        }
    }
    // On a ring edge: linear interpolation along it.
    for i in 0..m {
        let j = (i + 1) % m;
        let (ri, rj) = (len(q[i]), len(q[j]));
        let cross = q[i][0] * q[j][1] - q[i][1] * q[j][0];
        let dot = q[i][0] * q[j][0] + q[i][1] * q[j][1];
        if cross.abs() <= REL_EPS * ri * rj && dot < 0.0 {
            out.iter_mut().for_each(|w| *w = 0.0);
            out[i] = rj / (ri + rj);
            out[j] = ri / (ri + rj);
            return Some(());
        }
    }
    // w_i* = (tan(a_{i-1}/2) + tan(a_i/2)) / |v_i' - v'|, tan(a/2) = cross / (r r' + dot).
    let tan_half = |i: usize| {
        let j = (i + 1) % m;
        let cross = q[i][0] * q[j][1] - q[i][1] * q[j][0];
        let dot = q[i][0] * q[j][0] + q[i][1] * q[j][1];
        cross / (len(q[i]) * len(q[j]) + dot)
    };
    let mut sum = 0.0;
    let mut prev = tan_half(m - 1);
    for i in 0..m {
        let cur = tan_half(i);
        out[i] = (prev + cur) / len(q[i]);
        sum += out[i];
        prev = cur;
    }
    if !sum.is_finite() || sum.abs() * radius <= REL_EPS {
        return None;
    }
    out.iter_mut().for_each(|w| *w /= sum);
    out.iter().all(|w| w.is_finite()).then_some(())
}

impl MeanValueEncoding {
    /// Encodes every vertex of `mesh` (method.md section 2). `rings` must be the one-rings
    /// of `mesh`. Never produces NaN or infinities (see the module docs for degenerate
    /// rings).
    pub fn encode(mesh: &TriMesh, rings: &OneRings) -> Self {
        let n = mesh.positions.len();
        let entries = rings.entry_count();
        let mut enc = MeanValueEncoding {
            rings: rings.clone(),
            weights: vec![0.0; entries],
            tangents: vec![0.0; entries],
            kind: vec![RingEncodingKind::Isolated; n],
            ring_height: vec![0.0; n],
        };
        let mut q: Vec<[f64; 2]> = Vec::new();
        for v in 0..n.min(rings.vertex_count()) {
            enc.encode_vertex(v, &mesh.positions, &mut q);
        }
        enc
    }

    fn encode_vertex(&mut self, v: usize, positions: &[DVec3], q: &mut Vec<[f64; 2]>) {
        let nb = self.rings.neighbours(v);
        let m = nb.len();
        let off = self.rings.offset(v);
        if m == 0 {
            self.kind[v] = RingEncodingKind::Isolated;
            return;
        }
        let closed = !self.rings.is_boundary(v);
        let own = positions[v];
        let plane = ring_plane(nb, closed, positions, own, true);
        let n = plane.normal;
        // Projection onto the plane through l with normal n (d = -n.l; the plane of
        // method.md passes through the mean of the neighbours).
        let project = |p: DVec3| p - (p - plane.centre).dot(n) * n;
        let own_p = project(own);
        let e1 = n.any_orthonormal_vector();
        let e2 = n.cross(e1);
        // In-plane coordinates relative to v', in units of the ring radius (weights are
        // scale-free; the unit keeps the tolerances relative).
        let radius = plane.radius.max(f64::MIN_POSITIVE);
        q.clear();
        for &i in nb {
            let d = (project(positions[i as usize]) - own_p) / radius;
            q.push([d.dot(e1), d.dot(e2)]);
        }
        let w = &mut self.weights[off..off + m];
        let ok = closed && m >= 3 && mean_value_weights(q, 1.0, w).is_some();
        let reproduces = |w: &[f64]| {
            let (mut x, mut y) = (0.0, 0.0);
            for (wi, p) in w.iter().zip(q.iter()) {
                x += wi * p[0];
                y += wi * p[1];
            }
            (x * x + y * y).sqrt() <= WEIGHT_REPRODUCTION_TOL
        };
        if !ok || !reproduces(w) {
            affine_weights(q, [0.0, 0.0], w);
        }
        // Normal coefficients c_i = ((v - v_i).n) / |v - v_i|, b_i = c_i / sqrt(1 - c_i^2).
        for (k, &i) in nb.iter().enumerate() {
            let d = own - positions[i as usize];
            let len = d.length();
            let c = if len > REL_EPS * radius {
                (d.dot(n) / len).clamp(-MAX_ELEVATION_SINE, MAX_ELEVATION_SINE)
            } else {
                0.0
            };
            self.tangents[off + k] = c / (1.0 - c * c).sqrt();
        }
        self.kind[v] = RingEncodingKind::Tangent;
        let decoded = self.decode_vertex(v, positions);
        if !(decoded.is_finite() && (decoded - own).length() <= REPRODUCTION_TOL * radius) {
            self.kind[v] = RingEncodingKind::RingHeight;
            self.ring_height[v] = if plane.radius > 0.0 {
                (own - plane.centre).dot(n) / plane.radius
            } else {
                0.0
            };
        }
    }

    /// Number of encoded vertices.
    pub fn vertex_count(&self) -> usize {
        self.kind.len()
    }

    /// The one-rings the encoding refers to.
    pub fn rings(&self) -> &OneRings {
        &self.rings
    }

    /// Tangential weights `w_i` of `v`, in ring order (they sum to one).
    pub fn weights(&self, v: usize) -> &[f64] {
        let off = self.rings.offset(v);
        &self.weights[off..off + self.rings.neighbours(v).len()]
    }

    /// Normal coefficients `b_i` of `v`, in ring order.
    pub fn normal_coefficients(&self, v: usize) -> &[f64] {
        let off = self.rings.offset(v);
        &self.tangents[off..off + self.rings.neighbours(v).len()]
    }

    /// How `v`'s normal component is encoded.
    pub fn kind(&self, v: usize) -> RingEncodingKind {
        self.kind[v]
    }

    /// Distance from the projected vertex to the weighted combination of the projected
    /// neighbours (zero up to rounding: the reproduction property), metres.
    pub fn reproduction_error(&self, v: usize, positions: &[DVec3]) -> f64 {
        let nb = self.rings.neighbours(v);
        if nb.is_empty() {
            return 0.0;
        }
        let plane = ring_plane(
            nb,
            !self.rings.is_boundary(v),
            positions,
            positions[v],
            false,
        );
        let n = plane.normal;
        let project = |p: DVec3| p - (p - plane.centre).dot(n) * n;
        let mut p = DVec3::ZERO;
        for (w, &i) in self.weights(v).iter().zip(nb) {
            p += *w * project(positions[i as usize]);
        }
        (p - project(positions[v])).length()
    }

    /// Decodes `v` from the current positions of its neighbours (method.md section 2):
    /// `p = sum w_i v_i'`, `v_mv = p + sum w_i (|p - v_i'| b_i + (v_i - v_i').n) n`.
    /// `positions[v]` itself is only read for isolated vertices and to orient the plane
    /// of a collinear ring.
    #[inline]
    pub fn decode_vertex(&self, v: usize, positions: &[DVec3]) -> DVec3 {
        if let Some(p) = self.decode_closed_tangent(v, positions) {
            return p;
        }
        let parts = self.decode_parts(v, positions);
        parts.affine + parts.normal_offset
    }

    /// The common case of [`Self::decode_vertex`] in one pass over the ring: a closed
    /// ring of at most [`FAST_RING`] neighbours with tangent coefficients, whose plane is
    /// well defined. The same formulas as [`Self::decode_parts`] (which reads every
    /// neighbour three times and recomputes each projection); the offsets from the ring
    /// centre and their heights are kept on the stack. Why: the fast decoder evaluates
    /// this for every free vertex once per Gauss-Newton step. `None` for anything else.
    #[inline]
    fn decode_closed_tangent(&self, v: usize, positions: &[DVec3]) -> Option<DVec3> {
        let nb = self.rings.neighbours(v);
        let m = nb.len();
        if !(3..=FAST_RING).contains(&m)
            || self.kind[v] != RingEncodingKind::Tangent
            || self.rings.is_boundary(v)
        {
            return None;
        }
        let off = self.rings.offset(v);
        let w = &self.weights[off..off + m];
        let b = &self.tangents[off..off + m];
        let mut d = [DVec3::ZERO; FAST_RING];
        let mut centre = DVec3::ZERO;
        let mut affine = DVec3::ZERO; // sum w_i v_i
        for ((dk, &i), wk) in d.iter_mut().zip(nb).zip(w) {
            let p = positions[i as usize];
            *dk = p;
            centre += p;
            affine += *wk * p;
        }
        centre /= m as f64;
        // Offsets from the centre, the largest squared one, and the plane normal
        // sum (v_i - l) x (v_{i+1} - l) (see `ring_plane`).
        let mut far2 = -1.0f64;
        for dk in &mut d[..m] {
            *dk -= centre;
            far2 = far2.max(dk.length_squared());
        }
        let mut sum = DVec3::ZERO;
        let mut prev = d[m - 1];
        for &dk in &d[..m] {
            sum += prev.cross(dk);
            prev = dk;
        }
        let len = sum.length();
        if !(len > REL_EPS * far2 && sum.is_finite()) {
            return None; // collinear ring: the general path orients its plane
        }
        let n = sum / len;
        // Heights h_i = (v_i - l).n and their weighted sum.
        let mut h = [0.0f64; FAST_RING];
        let mut height = 0.0;
        for ((hk, dk), wk) in h.iter_mut().zip(&d[..m]).zip(w) {
            *hk = dk.dot(n);
            height += wk * *hk;
        }
        // p - v_i' = (affine - l - height n) - (d_i - h_i n).
        let a = affine - centre;
        let mut s = 0.0;
        for (((dk, hk), wk), bk) in d[..m].iter().zip(&h[..m]).zip(w).zip(b) {
            s += wk * ((a - *dk) - (height - hk) * n).length() * bk;
        }
        Some(affine + s * n)
    }

    /// The decoding split into the affine combination `sum w_i v_i` and the normal offset
    /// `s n` (their sum is [`Self::decode_vertex`]).
    #[inline]
    pub fn decode_parts(&self, v: usize, positions: &[DVec3]) -> DecodedParts {
        let nb = self.rings.neighbours(v);
        if nb.is_empty() || self.kind[v] == RingEncodingKind::Isolated {
            return DecodedParts {
                affine: positions[v],
                normal_offset: DVec3::ZERO,
            };
        }
        let off = self.rings.offset(v);
        let w = &self.weights[off..off + nb.len()];
        let need_radius = self.kind[v] == RingEncodingKind::RingHeight;
        let plane = ring_plane(
            nb,
            !self.rings.is_boundary(v),
            positions,
            positions[v],
            need_radius,
        );
        let n = plane.normal;
        let mut affine = DVec3::ZERO;
        let mut height = 0.0; // sum w_i (v_i - l).n
        for (wi, &i) in w.iter().zip(nb) {
            let p = positions[i as usize];
            affine += *wi * p;
            height += *wi * (p - plane.centre).dot(n);
        }
        // p = sum w_i v_i' = affine - height n.
        let p = affine - height * n;
        let s = match self.kind[v] {
            RingEncodingKind::Tangent => {
                let b = &self.tangents[off..off + nb.len()];
                let mut s = 0.0;
                for ((wi, bi), &i) in w.iter().zip(b).zip(nb) {
                    let pi = positions[i as usize];
                    let pi_proj = pi - (pi - plane.centre).dot(n) * n;
                    s += wi * (p - pi_proj).length() * bi;
                }
                s
            }
            // v_mv = p + eta * radius * n  =>  s = eta * radius - height.
            RingEncodingKind::RingHeight => self.ring_height[v] * plane.radius - height,
            RingEncodingKind::Isolated => 0.0,
        };
        DecodedParts {
            affine,
            normal_offset: s * n,
        }
    }

    /// Heap bytes held by the encoding (for the memory report).
    pub fn heap_bytes(&self) -> usize {
        let entries = self.weights.len();
        entries * (2 * 8 + 4) + self.kind.len() * (8 + 1 + 5)
    }
}

/// A mean value decoding split in two: `affine = sum w_i v_i`, `normal_offset = s n`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DecodedParts {
    pub affine: DVec3,
    pub normal_offset: DVec3,
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::shapes;

    #[test]
    fn sphere_encodes_and_decodes_to_itself() {
        let m = shapes::uv_sphere(0.3, 10, 20);
        let r = m.one_rings();
        let e = MeanValueEncoding::encode(&m, &r);
        for v in 0..m.vertex_count() {
            let s: f64 = e.weights(v).iter().sum();
            assert!((s - 1.0).abs() < 1e-12);
            assert!(e.reproduction_error(v, &m.positions) < 1e-12);
            assert!((e.decode_vertex(v, &m.positions) - m.positions[v]).length() < 1e-12);
            assert_eq!(e.kind(v), RingEncodingKind::Tangent);
        }
    }

    #[test]
    fn affine_weights_reproduce_a_point_outside() {
        let q = [[1.0, 0.0], [0.0, 1.0], [-1.0, 0.5]];
        let mut w = [0.0; 3];
        affine_weights(&q, [0.3, -0.2], &mut w);
        let x: f64 = w.iter().zip(&q).map(|(w, p)| w * p[0]).sum();
        let y: f64 = w.iter().zip(&q).map(|(w, p)| w * p[1]).sum();
        assert!((x - 0.3).abs() < 1e-9 && (y + 0.2).abs() < 1e-9);
        assert!((w.iter().sum::<f64>() - 1.0).abs() < 1e-12);
    }
}
