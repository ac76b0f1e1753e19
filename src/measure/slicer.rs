//! Fast repeated horizontal sections of one mesh, split into connected loops, with the
//! convex hull of each loop: the geometric core of [`super::Measurer`].
//!
//! Conventions: heights `y` in metres (station frame, +Y up); a section lives in the
//! (x, z) plane and its points are `DVec2::new(x, z)`; +X is the subject's left, +Z the
//! front. Lengths and areas of hulls are metres and square metres.
//!
//! [`LevelIndex`] buckets the triangles by the height range they span (built once per
//! mesh, O(#F)), so a section at `y` visits only the triangles of one bucket instead of
//! the whole mesh. [`SectionScratch`] owns every buffer a section needs, so slicing the
//! same mesh at hundreds of levels allocates nothing once the buffers have grown.
//!
//! This is a local, allocation-free sibling of [`crate::mesh::section::slice`] and
//! [`crate::mesh::section::convex_hull`] (those allocate per call and chain loops in
//! order, which girths do not need: a loop's convex hull needs only its point set).

use crate::mesh::TriMesh;
use glam::{DVec2, DVec3};

/// Vertices closer than this to the cutting plane (metres) are treated as lying just
/// above it, so no section segment degenerates (same rule as `mesh::section::slice`).
const ON_PLANE_EPS_M: f64 = 1e-12;
/// Slack of the single-precision triangle height ranges of a [`LevelIndex`], metres:
/// far above their rounding error (a triangle within it of the plane is cut exactly).
pub const RANGE_SLACK_M: f64 = 1e-5;
/// Upper bound on the number of height buckets of a [`LevelIndex`].
const MAX_BUCKETS: usize = 4096;

/// Triangles bucketed by height, and which triangle lies across each triangle edge.
///
/// Bucket `b` covers `[y0 + b h, y0 + (b+1) h)` and lists every triangle whose y-range
/// meets it (compressed rows). The edge neighbours depend only on the triangle list, so
/// they are kept while the topology stays the same (a fitted template every frame).
#[derive(Debug, Clone, Default)]
pub struct LevelIndex {
    y0: f64,
    bucket_h: f64,
    n_buckets: usize,
    offsets: Vec<u32>,
    /// The bucket's triangles with their height and x ranges, so that a section reads
    /// its bucket sequentially and rejects the triangles it does not cross without
    /// fetching their vertices.
    entries: Vec<Entry>,
    counts: Vec<u32>,
    ranges: Vec<(f64, f64)>,
    /// First and last bucket of each triangle ([`NOT_LISTED`]: outside the window).
    spans: Vec<(u32, u32)>,
    /// Heights whose sections find every triangle they cross (see
    /// [`LevelIndex::rebuild_window`]); before the first build no bucket exists, so no
    /// height finds anything.
    covered: (f64, f64),
    /// The triangle list the neighbours were built for.
    topology: Vec<[u32; 3]>,
    /// `neighbours[t][e]`: the triangle across edge e (vertices e, e+1) of t, or
    /// `NO_NEIGHBOUR` on a boundary. At a non-manifold edge the triangles sharing it
    /// are linked in a cycle, which still puts them in one loop.
    neighbours: Vec<[u32; 3]>,
    /// Whether the triangle list is a closed 2-manifold: every edge shared by exactly
    /// two triangles and the triangles about every vertex one fan (see
    /// [`LevelIndex::critical_heights`]).
    closed_manifold: bool,
    /// Triangles around each vertex (compressed rows), to find edge neighbours.
    vertex_offsets: Vec<u32>,
    vertex_triangles: Vec<u32>,
    /// The entries whose x range spans `axis_x` (within [`RANGE_SLACK_M`]), bucket by
    /// bucket in the same order (compressed rows): a cut keeping only the loops across
    /// that plane starts only from them, so it need not read the others.
    axis_x: Option<f64>,
    axis_offsets: Vec<u32>,
    axis_entries: Vec<Entry>,
}

/// A triangle as listed in a bucket of a [`LevelIndex`].
#[derive(Debug, Clone, Copy, Default)]
pub struct Entry {
    pub triangle: u32,
    /// Lowest and highest y of the triangle, single precision (compare with
    /// [`RANGE_SLACK_M`]).
    pub y_range: [f32; 2],
    /// Lowest and highest x of the triangle, likewise.
    pub x_range: [f32; 2],
}

impl Entry {
    /// Whether the triangle may cross height `y` (false only when it certainly does not).
    #[inline]
    fn may_cross(&self, y: f64) -> bool {
        let r = self.y_range;
        f64::from(r[0]) <= y + RANGE_SLACK_M && f64::from(r[1]) >= y - RANGE_SLACK_M
    }
}

/// The section segment of the triangle with vertices `t` at height `y`: its (x, z)
/// ends and the triangle edges (e: vertices e, e+1) they lie on; `None` if it does not
/// cross. Vertices within [`ON_PLANE_EPS_M`] of the plane count as above it, and each
/// crossing point is interpolated from the edge's lower-indexed vertex, so both
/// triangles that share an edge compute the bit-identical point.
fn triangle_segment(mesh: &TriMesh, t: [u32; 3], y: f64) -> Option<([DVec2; 2], [u8; 2])> {
    let d = plane_offsets(mesh, t, y);
    let [e0, e1] = crossed_edges(&d)?;
    Some((
        [
            edge_crossing(mesh, t, &d, e0),
            edge_crossing(mesh, t, &d, e1),
        ],
        [e0 as u8, e1 as u8],
    ))
}

/// Marks a boundary edge in [`LevelIndex`]'s neighbour table.
const NO_NEIGHBOUR: u32 = u32::MAX;
/// The bucket span of a triangle a windowed [`LevelIndex`] does not list.
const NOT_LISTED: (u32, u32) = (u32::MAX, u32::MAX);

impl LevelIndex {
    /// Rebuilds the index for `mesh` (indices must already be checked in range).
    ///
    /// The bucket height is half the mean height span of a triangle (at least the mesh
    /// height / [`MAX_BUCKETS`]), so a triangle sits in about three buckets and a
    /// section visits about 1.5 times the triangles it actually cuts (the others are
    /// rejected by their stored height range without touching the mesh).
    pub fn rebuild(&mut self, mesh: &TriMesh, y_min: f64, y_max: f64) {
        self.rebuild_window(mesh, y_min, y_max, (f64::NEG_INFINITY, f64::INFINITY));
    }

    /// As [`LevelIndex::rebuild`], listing only the triangles that reach into the heights
    /// `window` (clipped to `y_min..y_max`): a section at a height outside it is not
    /// asked for ([`LevelIndex::covers`] says which are), and the triangles far from
    /// every height asked (a standing body's head and lower legs) cost nothing.
    pub fn rebuild_window(&mut self, mesh: &TriMesh, y_min: f64, y_max: f64, window: (f64, f64)) {
        if self.topology != mesh.triangles {
            self.rebuild_neighbours(&mesh.triangles);
        }
        let y_min = y_min.max(window.0);
        let y_max = y_max.min(window.1).max(y_min);
        self.covered = (window.0 - RANGE_SLACK_M, window.1 + RANGE_SLACK_M);
        // A triangle within the range slack of a covered height may be cut there.
        let (keep_lo, keep_hi) = (y_min - 2.0 * RANGE_SLACK_M, y_max + 2.0 * RANGE_SLACK_M);
        let height = (y_max - y_min).max(f64::MIN_POSITIVE);
        self.ranges.clear();
        let mut span_sum = 0.0;
        let mut kept = 0usize;
        for t in &mesh.triangles {
            let r = tri_y_range(mesh, t);
            if r.1 >= keep_lo && r.0 <= keep_hi {
                span_sum += r.1 - r.0;
                kept += 1;
            }
            self.ranges.push(r);
        }
        let mean_span = span_sum / kept.max(1) as f64;
        let bucket_h = (0.5 * mean_span)
            .max(height / MAX_BUCKETS as f64)
            .max(f64::MIN_POSITIVE);
        let n_buckets = ((height / bucket_h).ceil() as usize).clamp(1, MAX_BUCKETS);
        self.y0 = y_min;
        self.bucket_h = bucket_h;
        self.n_buckets = n_buckets;
        let mut counts = std::mem::take(&mut self.counts);
        counts.clear();
        counts.resize(n_buckets, 0);
        let mut spans = std::mem::take(&mut self.spans);
        spans.clear();
        for &(lo, hi) in &self.ranges {
            if hi < keep_lo || lo > keep_hi {
                spans.push(NOT_LISTED);
                continue;
            }
            let (b0, b1) = (self.bucket(lo), self.bucket(hi));
            spans.push((b0 as u32, b1 as u32));
            for c in &mut counts[b0..=b1] {
                *c += 1;
            }
        }
        self.offsets.clear();
        self.offsets.push(0);
        let mut acc = 0u32;
        for &c in &counts {
            acc += c;
            self.offsets.push(acc);
        }
        self.entries.clear();
        self.entries.resize(acc as usize, Entry::default());
        // Reuse counts as fill cursors.
        for (c, &o) in counts.iter_mut().zip(&self.offsets) {
            *c = o;
        }
        for (i, &(b0, b1)) in spans.iter().enumerate() {
            if (b0, b1) == NOT_LISTED {
                continue;
            }
            let (lo, hi) = self.ranges[i];
            let xs = mesh.triangles[i].map(|v| mesh.positions[v as usize].x);
            let entry = Entry {
                triangle: i as u32,
                y_range: [lo as f32, hi as f32],
                x_range: [
                    xs[0].min(xs[1]).min(xs[2]) as f32,
                    xs[0].max(xs[1]).max(xs[2]) as f32,
                ],
            };
            for c in &mut counts[b0 as usize..=b1 as usize] {
                self.entries[*c as usize] = entry;
                *c += 1;
            }
        }
        self.spans = spans;
        self.counts = counts;
        self.axis_x = None;
    }

    /// Lists, per bucket, the entries spanning the plane x = `axis_x` (see
    /// [`LevelIndex::entries_across_x`]); kept until the next rebuild.
    pub fn index_axis(&mut self, axis_x: f64) {
        self.axis_offsets.clear();
        self.axis_entries.clear();
        self.axis_offsets.push(0);
        for b in 0..self.n_buckets {
            let (lo, hi) = (self.offsets[b] as usize, self.offsets[b + 1] as usize);
            self.axis_entries
                .extend(self.entries[lo..hi].iter().filter(|e| spans_x(e, axis_x)));
            self.axis_offsets.push(self.axis_entries.len() as u32);
        }
        self.axis_x = Some(axis_x);
    }

    /// The candidate entries at height `y` that span the plane x = `axis_x`, in bucket
    /// order: from the axis list when it was built for this very `axis_x`, else filtered
    /// from the bucket.
    fn entries_across_x(&self, y: f64, axis_x: f64) -> impl Iterator<Item = &Entry> {
        let indexed = self.axis_x.is_some_and(|a| a.to_bits() == axis_x.to_bits())
            && self.axis_offsets.len() == self.n_buckets + 1;
        let (listed, all): (&[Entry], &[Entry]) = if indexed {
            let range = self.bucket_range(y);
            if range.is_empty() {
                (&[], &[])
            } else {
                let b = self.bucket(y);
                let (lo, hi) = (
                    self.axis_offsets[b] as usize,
                    self.axis_offsets[b + 1] as usize,
                );
                (&self.axis_entries[lo..hi], &[])
            }
        } else {
            (&[], self.candidate_entries(y))
        };
        listed
            .iter()
            .chain(all.iter().filter(move |e| spans_x(e, axis_x)))
    }

    /// Edge neighbours through vertex -> triangle lists (linear time, no sorting).
    fn rebuild_neighbours(&mut self, triangles: &[[u32; 3]]) {
        self.topology.clear();
        self.topology.extend_from_slice(triangles);
        self.neighbours.clear();
        self.neighbours.resize(triangles.len(), [NO_NEIGHBOUR; 3]);
        let n_vertices = triangles
            .iter()
            .flatten()
            .map(|&v| v as usize + 1)
            .max()
            .unwrap_or(0);
        let (offsets, incident) = (&mut self.vertex_offsets, &mut self.vertex_triangles);
        offsets.clear();
        offsets.resize(n_vertices + 1, 0);
        for &v in triangles.iter().flatten() {
            offsets[v as usize + 1] += 1;
        }
        for i in 0..n_vertices {
            offsets[i + 1] += offsets[i];
        }
        incident.clear();
        incident.resize(offsets[n_vertices] as usize, 0);
        let mut cursor = std::mem::take(&mut self.counts);
        cursor.clear();
        cursor.extend_from_slice(&offsets[..n_vertices]);
        for (t, tri) in triangles.iter().enumerate() {
            for &v in tri {
                incident[cursor[v as usize] as usize] = t as u32;
                cursor[v as usize] += 1;
            }
        }
        self.counts = cursor;
        let mut edge_manifold = true;
        for (t, tri) in triangles.iter().enumerate() {
            for e in 0..3 {
                let (a, b) = (tri[e], tri[(e + 1) % 3]);
                let around_a =
                    &incident[offsets[a as usize] as usize..offsets[a as usize + 1] as usize];
                // The triangles sharing edge a-b form a cycle in id order: the next
                // larger id, else the smallest (the only other one on a manifold edge).
                let (mut next, mut first, mut sharing) = (NO_NEIGHBOUR, NO_NEIGHBOUR, 0);
                for &u in around_a {
                    if u as usize == t || !triangles[u as usize].contains(&b) {
                        continue;
                    }
                    sharing += 1;
                    first = first.min(u);
                    if u as usize > t {
                        next = next.min(u);
                    }
                }
                edge_manifold &= sharing == 1 && a != b;
                self.neighbours[t][e] = if next != NO_NEIGHBOUR { next } else { first };
            }
        }
        self.closed_manifold = edge_manifold && self.single_fans(triangles);
    }

    /// Whether the triangles about every vertex form a single fan (on a mesh whose
    /// every edge has exactly two triangles): walking from one of them across the
    /// edges at the vertex comes back after visiting all of them.
    fn single_fans(&self, triangles: &[[u32; 3]]) -> bool {
        let n_vertices = self.vertex_offsets.len().saturating_sub(1);
        for v in 0..n_vertices as u32 {
            let around = &self.vertex_triangles[self.vertex_offsets[v as usize] as usize
                ..self.vertex_offsets[v as usize + 1] as usize];
            let Some(&start) = around.first() else {
                continue;
            };
            let (mut prev, mut t, mut steps) = (NO_NEIGHBOUR, start, 0usize);
            loop {
                let tri = triangles[t as usize];
                let Some(k) = tri.iter().position(|&u| u == v) else {
                    return false;
                };
                if tri[(k + 1) % 3] == v || tri[(k + 2) % 3] == v {
                    return false; // a degenerate triangle
                }
                // Across the edge at v not come from (edges k and k + 2 hold v), so
                // the walk needs no consistent orientation.
                let (a, b) = (
                    self.neighbours[t as usize][k],
                    self.neighbours[t as usize][(k + 2) % 3],
                );
                let next = if a != prev { a } else { b };
                (prev, t) = (t, next);
                steps += 1;
                if t == NO_NEIGHBOUR || steps > around.len() {
                    return false;
                }
                if t == start {
                    break;
                }
            }
            if steps != around.len() {
                return false;
            }
        }
        true
    }

    /// The heights, between `lo` and `hi`, of the vertices where the number of loops of
    /// a section may change (sorted, each once), into `out`; false, leaving `out` empty,
    /// unless the mesh is a closed 2-manifold and this index covers `lo..=hi`.
    ///
    /// On a closed triangulated surface the sections between two consecutive critical
    /// heights of the height function are the same number of loops. Vertices are
    /// ordered by (y, index), which breaks ties as a section does (a vertex on the plane
    /// counts as above it). A vertex is regular when its link changes between below and
    /// above it exactly twice; each triangle adds one such change to its middle vertex,
    /// so a vertex is critical unless it is the middle vertex of exactly two of its
    /// triangles (none: a lowest or highest point; four or more: a saddle, where loops
    /// merge or split). `marks` is scratch, one entry per vertex.
    pub fn critical_heights(
        &self,
        mesh: &TriMesh,
        lo: f64,
        hi: f64,
        marks: &mut Vec<u16>,
        seen: &mut Vec<u32>,
        out: &mut Vec<f64>,
    ) -> bool {
        out.clear();
        if !self.closed_manifold
            || self.neighbours.len() != mesh.triangles.len()
            || !(self.covers(lo) && self.covers(hi))
            || self.offsets.len() != self.n_buckets + 1
            || self.n_buckets == 0
        {
            return false;
        }
        const SEEN: u16 = 0x8000;
        marks.clear();
        marks.resize(mesh.positions.len(), 0);
        seen.clear();
        let y = |v: u32| mesh.positions[v as usize].y;
        let below = |a: u32, b: u32| (y(a), a) < (y(b), b);
        let (b_first, b_last) = (self.bucket(lo), self.bucket(hi));
        for b in b_first..=b_last {
            let (s, e) = (self.offsets[b] as usize, self.offsets[b + 1] as usize);
            for entry in &self.entries[s..e] {
                let t = entry.triangle;
                // Each triangle once: in the first of its buckets this loop visits.
                if (self.spans[t as usize].0 as usize).max(b_first) != b {
                    continue;
                }
                let [p, q, r] = mesh.triangles[t as usize];
                for v in [p, q, r] {
                    let h = y(v);
                    if h >= lo && h <= hi && marks[v as usize] & SEEN == 0 {
                        marks[v as usize] |= SEEN;
                        seen.push(v);
                    }
                }
                let middle = if below(p, q) == below(q, r) {
                    q
                } else if below(q, r) == below(r, p) {
                    r
                } else {
                    p
                };
                if marks[middle as usize] & SEEN != 0 {
                    marks[middle as usize] = marks[middle as usize].saturating_add(1);
                }
            }
        }
        for &v in seen.iter() {
            if marks[v as usize] & !SEEN != 2 {
                out.push(y(v));
            }
            marks[v as usize] = 0;
        }
        out.sort_by(f64::total_cmp);
        out.dedup();
        true
    }

    fn bucket(&self, y: f64) -> usize {
        let n = self.n_buckets.max(1);
        let b = (y - self.y0) / self.bucket_h;
        // Below the first bucket, or NaN: the first. Otherwise the cast truncates, which
        // for a non-negative value is its floor (without a call to `floor`, which the
        // baseline x86-64 target does not inline).
        if b >= 0.0 {
            (b as usize).min(n - 1)
        } else {
            0
        }
    }

    /// Whether a section at height `y` finds every triangle it crosses (the heights
    /// the index was built for: everywhere, or its window).
    pub fn covers(&self, y: f64) -> bool {
        y >= self.covered.0 && y <= self.covered.1
    }

    /// Whether the index lists every triangle (built by [`LevelIndex::rebuild`]).
    pub fn covers_everywhere(&self) -> bool {
        self.covered.0 == f64::NEG_INFINITY && self.covered.1 == f64::INFINITY
    }

    /// Whether the edge neighbours were built for this triangle list.
    pub fn topology_matches(&self, triangles: &[[u32; 3]]) -> bool {
        self.topology == triangles
    }

    /// Number of height buckets and of (bucket, triangle) entries.
    pub fn size(&self) -> (usize, usize) {
        (self.n_buckets, self.entries.len())
    }

    /// Triangles that may cross height `y` (a superset of those that do), with their
    /// vertices and height ranges.
    pub fn candidate_entries(&self, y: f64) -> &[Entry] {
        &self.entries[self.bucket_range(y)]
    }

    fn bucket_range(&self, y: f64) -> std::ops::Range<usize> {
        if self.offsets.len() != self.n_buckets + 1 || self.n_buckets == 0 || !self.covers(y) {
            return 0..0;
        }
        let b = self.bucket(y);
        self.offsets[b] as usize..self.offsets[b + 1] as usize
    }
}

/// Whether an entry's x range spans the plane x = `axis_x` (within [`RANGE_SLACK_M`]).
#[inline]
fn spans_x(e: &Entry, axis_x: f64) -> bool {
    let r = e.x_range;
    f64::from(r[0]) <= axis_x + RANGE_SLACK_M && f64::from(r[1]) >= axis_x - RANGE_SLACK_M
}

fn tri_y_range(mesh: &TriMesh, t: &[u32; 3]) -> (f64, f64) {
    let ys = t.map(|v| mesh.positions[v as usize].y);
    (ys[0].min(ys[1]).min(ys[2]), ys[0].max(ys[1]).max(ys[2]))
}

/// One connected loop of a section (a closed curve on a watertight mesh).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LoopInfo {
    /// Extent of the loop in x and z (metres).
    pub x_min: f64,
    pub x_max: f64,
    pub z_min: f64,
    pub z_max: f64,
    /// Range of this loop's segments in [`SectionScratch`]'s grouped segment order.
    seg_start: u32,
    seg_end: u32,
}

impl LoopInfo {
    /// A loop of no points yet over segments `seg_start..seg_end`.
    fn empty(seg_start: u32, seg_end: u32) -> LoopInfo {
        LoopInfo {
            x_min: f64::INFINITY,
            x_max: f64::NEG_INFINITY,
            z_min: f64::INFINITY,
            z_max: f64::NEG_INFINITY,
            seg_start,
            seg_end,
        }
    }

    /// Widens the extents over a segment's ends.
    fn take_in(&mut self, seg: &[DVec2; 2]) {
        for p in seg {
            self.x_min = self.x_min.min(p.x);
            self.x_max = self.x_max.max(p.x);
            self.z_min = self.z_min.min(p.y);
            self.z_max = self.z_max.max(p.y);
        }
    }
}

/// Perimeter, area, centroid and extent of a convex hull.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HullStats {
    /// Perimeter of the hull, metres: the tape girth.
    pub perimeter_m: f64,
    /// Area of the hull, square metres.
    pub area_m2: f64,
    /// Centroid of the hull's area (x, z), metres (the mean of its corners when the
    /// hull has no area).
    pub centroid_x: f64,
    pub centroid_z: f64,
    pub x_min: f64,
    pub x_max: f64,
    pub z_min: f64,
    pub z_max: f64,
}

/// Buffers for one section at a time; reused between sections.
#[derive(Debug, Clone, Default)]
pub struct SectionScratch {
    /// Section segments (x, z) endpoints, in triangle order.
    segs: Vec<[DVec2; 2]>,
    /// Triangle of each segment and the triangles across the two edges it crosses.
    seg_tri: Vec<(u32, [u32; 2])>,
    /// Which ends of each segment it lists for hulls (each crossing point once).
    owned: Vec<[bool; 2]>,
    /// Per mesh triangle: (section number, the segment it gave in that section).
    seg_of_tri: Vec<(u32, u32)>,
    epoch: u32,
    parent: Vec<u32>,
    /// Segments still to grow from in [`SectionScratch::grow_cut`].
    stack: Vec<u32>,
    /// First segment of each growth of [`SectionScratch::grow_cut`].
    tree_starts: Vec<u32>,
    /// Loop label of each segment, then segments grouped by loop.
    label: Vec<u32>,
    grouped: Vec<u32>,
    /// Whether `grouped` and the loops' segment ranges belong to the last section.
    is_grouped: bool,
    cursor: Vec<u32>,
    loops: Vec<LoopInfo>,
    points: Vec<DVec2>,
    hull: Vec<DVec2>,
    /// [`SectionScratch::walk`]: the walked loops' crossing points, loop by loop in
    /// order around each, and each loop's range of them with its extents.
    traced_points: Vec<DVec2>,
    traced: Vec<LoopInfo>,
    /// Whether the last section was walked (its loops are `traced`).
    walked: bool,
    /// Never walk (tests compare the walk with the general cut).
    never_walk: bool,
}

/// Height differences of a triangle's corners from the plane y, a corner within
/// [`ON_PLANE_EPS_M`] of it counted just above (as [`triangle_segment`] does).
#[inline(always)]
fn plane_offsets(mesh: &TriMesh, t: [u32; 3], y: f64) -> [f64; 3] {
    t.map(|v| {
        let d = mesh.positions[v as usize].y - y;
        if d.abs() < ON_PLANE_EPS_M {
            ON_PLANE_EPS_M
        } else {
            d
        }
    })
}

/// The point where edge `e` of triangle `t` (corners e, e + 1; offsets `d`) crosses the
/// plane, interpolated from the edge's lower-indexed vertex as [`triangle_segment`] does.
#[inline(always)]
fn edge_crossing(mesh: &TriMesh, t: [u32; 3], d: &[f64; 3], e: usize) -> DVec2 {
    let (a, b) = (e, (e + 1) % 3);
    let (lo, hi) = ordered(t[a], t[b]);
    let (dl, dh) = if lo == t[a] {
        (d[a], d[b])
    } else {
        (d[b], d[a])
    };
    let (pl, ph) = (mesh.positions[lo as usize], mesh.positions[hi as usize]);
    let p: DVec3 = pl + (ph - pl) * (dl / (dl - dh));
    DVec2::new(p.x, p.z)
}

/// The edges of a triangle with offsets `d` that cross the plane, in edge order (None
/// unless exactly two do).
#[inline(always)]
fn crossed_edges(d: &[f64; 3]) -> Option<[usize; 2]> {
    let mut out = [0usize; 2];
    let mut k = 0;
    for e in 0..3 {
        if (d[e] > 0.0) != (d[(e + 1) % 3] > 0.0) {
            if k == 2 {
                return None;
            }
            out[k] = e;
            k += 1;
        }
    }
    (k == 2).then_some(out)
}

fn find(parent: &mut [u32], mut i: u32) -> u32 {
    while parent[i as usize] != i {
        let p = parent[i as usize];
        parent[i as usize] = parent[p as usize];
        i = p;
    }
    i
}

#[inline]
fn ordered(a: u32, b: u32) -> (u32, u32) {
    if a < b {
        (a, b)
    } else {
        (b, a)
    }
}

impl SectionScratch {
    /// Starts a new section: no segments, a new stamp for "this triangle's segment".
    fn begin(&mut self, mesh: &TriMesh) {
        self.segs.clear();
        self.seg_tri.clear();
        if self.seg_of_tri.len() != mesh.triangles.len() {
            self.seg_of_tri.clear();
            self.seg_of_tri.resize(mesh.triangles.len(), (0, 0));
            self.epoch = 0;
        }
        self.epoch = self.epoch.wrapping_add(1);
        if self.epoch == 0 {
            self.seg_of_tri.iter_mut().for_each(|s| s.0 = 0);
            self.epoch = 1;
        }
    }

    /// Adds the segment of triangle `ti` (if it crosses y) to the section; whether it did.
    fn add_segment(&mut self, mesh: &TriMesh, index: &LevelIndex, ti: u32, y: f64) -> bool {
        let t = mesh.triangles[ti as usize];
        let Some((ends, edges)) = triangle_segment(mesh, t, y) else {
            return false;
        };
        let s = self.segs.len() as u32;
        self.segs.push(ends);
        let nb = index.neighbours[ti as usize];
        self.seg_tri
            .push((ti, [nb[edges[0] as usize], nb[edges[1] as usize]]));
        self.seg_of_tri[ti as usize] = (self.epoch, s);
        true
    }

    fn visited(&self, ti: u32) -> bool {
        self.seg_of_tri[ti as usize].0 == self.epoch
    }

    /// Cuts `mesh` at height `y` through the candidate triangles of `index` (built
    /// for this mesh) and splits the cut into loops: segments of triangles that share
    /// a crossed edge belong to the same loop.
    ///
    /// On a closed 2-manifold the loops are walked instead ([`SectionScratch::walk`]):
    /// the same loops, extents and hulls, faster.
    pub fn cut(&mut self, mesh: &TriMesh, index: &LevelIndex, y: f64) {
        self.walked = !self.never_walk && self.walk(mesh, index, y, None);
        if !self.walked {
            self.grow_cut(mesh, index, y, None);
        }
    }

    /// As [`SectionScratch::cut`], keeping only the loops that cross the vertical plane
    /// x = `axis_x`: a loop reaching to both sides of the axis has a segment whose
    /// triangle spans the axis, and the loop is grown from there across crossed edges,
    /// so every such loop comes out exactly as the full cut gives it, and loops away
    /// from the axis (arms, hands) are never cut.
    pub fn cut_across_x(&mut self, mesh: &TriMesh, index: &LevelIndex, y: f64, axis_x: f64) {
        self.walked = !self.never_walk && self.walk(mesh, index, y, Some(axis_x));
        if !self.walked {
            self.grow_cut(mesh, index, y, Some(axis_x));
        }
    }

    /// Cuts with the general cut only, never walking loops (for tests comparing both).
    pub fn never_walking(mut self) -> Self {
        self.never_walk = true;
        self
    }

    /// The cut at `y` grown loop by loop: from each candidate triangle that crosses the
    /// plane and is not yet in a loop (with `across_x`, only those spanning that x),
    /// across crossed edges. A loop's segments are then contiguous, so the loops are
    /// labelled without a union-find (see [`SectionScratch::label_grown`]).
    fn grow_cut(&mut self, mesh: &TriMesh, index: &LevelIndex, y: f64, across_x: Option<f64>) {
        self.begin(mesh);
        let mut stack = std::mem::take(&mut self.stack);
        let mut starts = std::mem::take(&mut self.tree_starts);
        starts.clear();
        match across_x {
            Some(axis_x) => self.grow_from(
                mesh,
                index,
                y,
                index.entries_across_x(y, axis_x),
                &mut stack,
                &mut starts,
            ),
            None => self.grow_from(
                mesh,
                index,
                y,
                index.candidate_entries(y).iter(),
                &mut stack,
                &mut starts,
            ),
        }
        self.stack = stack;
        // Each growth is one loop: its segments are contiguous, so the loops need no
        // union-find (the same loops, in the same order of their first candidate, as
        // `split_into_loops` gives over the same segments).
        let grown = self.label_grown(&starts);
        self.tree_starts = starts;
        if !grown {
            self.split_into_loops();
        }
    }

    /// Grows a loop from each of `entries` that crosses height `y` and is not yet in a
    /// loop, across crossed edges; `starts` gets each growth's first segment.
    fn grow_from<'a>(
        &mut self,
        mesh: &TriMesh,
        index: &LevelIndex,
        y: f64,
        entries: impl Iterator<Item = &'a Entry>,
        stack: &mut Vec<u32>,
        starts: &mut Vec<u32>,
    ) {
        for entry in entries {
            if !entry.may_cross(y) || self.visited(entry.triangle) {
                continue;
            }
            if !self.add_segment(mesh, index, entry.triangle, y) {
                continue;
            }
            starts.push(self.segs.len() as u32 - 1);
            stack.clear();
            stack.push(self.segs.len() as u32 - 1);
            while let Some(s) = stack.pop() {
                // Every triangle sharing a crossed edge crosses the plane too; the
                // neighbour table links all of them (a cycle at a non-manifold edge).
                for nb in self.seg_tri[s as usize].1 {
                    if nb != NO_NEIGHBOUR
                        && !self.visited(nb)
                        && self.add_segment(mesh, index, nb, y)
                    {
                        stack.push(self.segs.len() as u32 - 1);
                    }
                }
            }
        }
    }

    /// Labels the loops of [`SectionScratch::grow_cut`] from its growths (segments
    /// `starts[l]..starts[l + 1]` are loop `l`), as `split_into_loops` and `group` would:
    /// the same shared-point ownership, loop order, extents and segment ranges. Returns
    /// false, having labelled nothing usable, if a segment's neighbour lies in another
    /// growth (a neighbour table that does not link both ways).
    fn label_grown(&mut self, starts: &[u32]) -> bool {
        let n = self.segs.len();
        self.label.clear();
        self.label.resize(n, 0);
        for (l, &s0) in starts.iter().enumerate() {
            let s1 = starts.get(l + 1).map_or(n, |&e| e as usize);
            self.label[s0 as usize..s1].fill(l as u32);
        }
        self.owned.clear();
        for s in 0..n {
            let across = self.across(s);
            if across
                .iter()
                .flatten()
                .any(|&(_, other)| self.label[other as usize] != self.label[s])
            {
                return false;
            }
            self.owned.push(self.owns(s, &across));
        }
        self.loops.clear();
        for (l, &s0) in starts.iter().enumerate() {
            let s1 = starts.get(l + 1).map_or(n as u32, |&e| e);
            let mut info = LoopInfo::empty(s0, s1);
            for seg in &self.segs[s0 as usize..s1 as usize] {
                info.take_in(seg);
            }
            self.loops.push(info);
        }
        self.grouped.clear();
        self.grouped.extend(0..n as u32);
        self.is_grouped = true;
        true
    }

    /// Per crossed edge of segment `s`: the triangle across it and that triangle's
    /// segment in this section (None: a boundary, or no segment there).
    fn across(&self, s: usize) -> [Option<(u32, u32)>; 2] {
        self.seg_tri[s].1.map(|nb| {
            if nb == NO_NEIGHBOUR {
                return None;
            }
            let (stamp, other) = self.seg_of_tri[nb as usize];
            (stamp == self.epoch).then_some((nb, other))
        })
    }

    /// Which ends segment `s` lists for hulls: a crossing point shared with a neighbour's
    /// segment is listed by the one of the two on the larger triangle.
    fn owns(&self, s: usize, across: &[Option<(u32, u32)>; 2]) -> [bool; 2] {
        let t = self.seg_tri[s].0;
        across.map(|a| a.is_none_or(|(nb, _)| nb > t))
    }

    /// Unions the segments of the section into loops and labels them.
    fn split_into_loops(&mut self) {
        // Union each segment with the segments of the triangles across its edges.
        let n = self.segs.len();
        self.parent.clear();
        self.parent.extend(0..n as u32);
        self.owned.clear();
        for s in 0..n {
            let across = self.across(s);
            for &(_, other) in across.iter().flatten() {
                let (ra, rb) = (
                    find(&mut self.parent, s as u32),
                    find(&mut self.parent, other),
                );
                if ra != rb {
                    self.parent[ra as usize] = rb;
                }
            }
            self.owned.push(self.owns(s, &across));
        }
        // Label loops 0..L with their extents; grouping waits for a hull.
        self.is_grouped = false;
        self.label.clear();
        self.label.resize(n, u32::MAX);
        self.loops.clear();
        self.cursor.clear();
        let mut root_label = std::mem::take(&mut self.grouped);
        root_label.clear();
        root_label.resize(n, u32::MAX);
        for s in 0..n {
            let r = find(&mut self.parent, s as u32) as usize;
            if root_label[r] == u32::MAX {
                root_label[r] = self.loops.len() as u32;
                self.loops.push(LoopInfo::empty(0, 0));
                self.cursor.push(0);
            }
            let l = root_label[r];
            self.label[s] = l;
            self.cursor[l as usize] += 1;
            self.loops[l as usize].take_in(&self.segs[s]);
        }
        self.grouped = root_label;
    }

    /// Groups the last section's segments by loop (counting sort), once per section.
    fn group(&mut self) {
        if self.is_grouped {
            return;
        }
        self.is_grouped = true;
        let n = self.segs.len();
        let mut acc = 0u32;
        for (info, c) in self.loops.iter_mut().zip(self.cursor.iter_mut()) {
            info.seg_start = acc;
            acc += *c;
            info.seg_end = acc;
            *c = info.seg_start;
        }
        self.grouped.clear();
        self.grouped.resize(n, 0);
        for s in 0..n {
            let l = self.label[s] as usize;
            self.grouped[self.cursor[l] as usize] = s as u32;
            self.cursor[l] += 1;
        }
    }

    /// The cut at `y` on a closed 2-manifold (with `across_x`, only the loops across that
    /// plane): each loop is walked from a candidate triangle (one spanning the plane),
    /// triangle to triangle across its crossed edges, listing each crossing point once
    /// in order around the loop. The loops, their order, extents and point sets are the
    /// general cut's. Returns false, with nothing kept, where the index is not of a
    /// closed 2-manifold or a walk does not close (then the general cut runs).
    fn walk(&mut self, mesh: &TriMesh, index: &LevelIndex, y: f64, across_x: Option<f64>) -> bool {
        self.traced.clear();
        self.traced_points.clear();
        // (As for every cut, `index` must have been built for this mesh.)
        if !index.closed_manifold || index.neighbours.len() != mesh.triangles.len() {
            return false;
        }
        self.begin(mesh);
        let epoch = self.epoch;
        let (across, all): (Option<_>, &[Entry]) = match across_x {
            Some(axis_x) => (Some(index.entries_across_x(y, axis_x)), &[]),
            None => (None, index.candidate_entries(y)),
        };
        for entry in across.into_iter().flatten().chain(all.iter()) {
            let t0 = entry.triangle;
            if !entry.may_cross(y) || self.seg_of_tri[t0 as usize].0 == epoch {
                continue;
            }
            let tri0 = mesh.triangles[t0 as usize];
            let d0 = plane_offsets(mesh, tri0, y);
            let Some([_, first_out]) = crossed_edges(&d0) else {
                continue;
            };
            self.seg_of_tri[t0 as usize].0 = epoch;
            let start = self.traced_points.len() as u32;
            let mut info = LoopInfo::empty(start, start);
            let (mut t, mut tri, mut d, mut out) = (t0, tri0, d0, first_out);
            loop {
                let p = edge_crossing(mesh, tri, &d, out);
                info.take_in(&[p, p]);
                self.traced_points.push(p);
                let (a, b) = (tri[out], tri[(out + 1) % 3]);
                let next = index.neighbours[t as usize][out];
                if next == t0 {
                    break;
                }
                if next == NO_NEIGHBOUR || self.seg_of_tri[next as usize].0 == epoch {
                    self.traced.clear();
                    self.traced_points.clear();
                    return false;
                }
                self.seg_of_tri[next as usize].0 = epoch;
                let ntri = mesh.triangles[next as usize];
                let nd = plane_offsets(mesh, ntri, y);
                let Some(edges) = crossed_edges(&nd) else {
                    self.traced.clear();
                    self.traced_points.clear();
                    return false;
                };
                // Leave by the crossed edge that is not the one shared with `t`.
                let shared = |e: usize| {
                    let (u, v) = (ntri[e], ntri[(e + 1) % 3]);
                    (u == a && v == b) || (u == b && v == a)
                };
                out = if shared(edges[0]) { edges[1] } else { edges[0] };
                (t, tri, d) = (next, ntri, nd);
            }
            info.seg_end = self.traced_points.len() as u32;
            self.traced.push(info);
        }
        true
    }

    /// The loops of the last section.
    pub fn loops(&self) -> &[LoopInfo] {
        if self.walked {
            &self.traced
        } else {
            &self.loops
        }
    }

    /// Convex hull of loop `i` (each crossing point once); `None` if it has fewer
    /// than 3 hull corners.
    pub fn loop_hull(&mut self, i: usize) -> Option<HullStats> {
        if self.walked {
            let info = *self.traced.get(i)?;
            // Sorted in place by the hull: the walk's order is not needed again.
            let pts = &mut self.traced_points[info.seg_start as usize..info.seg_end as usize];
            return hull_stats(pts, &mut self.hull);
        }
        self.group();
        let info = *self.loops.get(i)?;
        self.points.clear();
        for &s in &self.grouped[info.seg_start as usize..info.seg_end as usize] {
            let [a, b] = self.segs[s as usize];
            let owned = self.owned[s as usize];
            if owned[0] {
                self.points.push(a);
            }
            if owned[1] {
                self.points.push(b);
            }
        }
        hull_stats(&mut self.points, &mut self.hull)
    }

    /// Convex hull of every loop of the section together.
    pub fn whole_hull(&mut self) -> Option<HullStats> {
        if self.walked {
            return hull_stats(&mut self.traced_points, &mut self.hull);
        }
        self.points.clear();
        for s in &self.segs {
            self.points.extend_from_slice(s);
        }
        hull_stats(&mut self.points, &mut self.hull)
    }
}

/// Lexicographic order of points: by x, then by z (total order on the floats).
#[inline(always)]
fn lex_less(a: &DVec2, b: &DVec2) -> bool {
    a.x.total_cmp(&b.x).then(a.y.total_cmp(&b.y)).is_lt()
}

/// Most monotone runs [`sort_lexicographic`] merges; more fall back to a general sort.
const MAX_RUNS: usize = 16;

/// Sorts `points` by x, then z, using `scratch` as merge buffer. A loop's points come in
/// nearly the order of the loop (the cut grows it segment by segment), and a loop's x
/// goes up on one side and down on the other: a few monotone runs, merged in linear
/// time. Points equal in both coordinates are the same point, so the result is the one
/// any sort gives.
fn sort_lexicographic(points: &mut [DVec2], scratch: &mut Vec<DVec2>) {
    let n = points.len();
    let mut runs = [0usize; MAX_RUNS + 1];
    let mut count = 0;
    let mut i = 0;
    while i < n {
        if count == MAX_RUNS {
            points.sort_unstable_by(|a, b| a.x.total_cmp(&b.x).then(a.y.total_cmp(&b.y)));
            return;
        }
        runs[count] = i;
        count += 1;
        let mut j = i + 1;
        if j < n && lex_less(&points[j], &points[j - 1]) {
            while j < n && lex_less(&points[j], &points[j - 1]) {
                j += 1;
            }
            points[i..j].reverse();
        } else {
            while j < n && !lex_less(&points[j], &points[j - 1]) {
                j += 1;
            }
        }
        i = j;
    }
    runs[count] = n;
    // Bottom-up: merge neighbouring runs until one is left.
    while count > 1 {
        let mut merged = 0;
        let mut k = 0;
        while k < count {
            let (lo, mid) = (runs[k], runs[k + 1]);
            if k + 1 < count {
                let hi = runs[k + 2];
                merge_runs(&mut points[lo..hi], mid - lo, scratch);
            }
            runs[merged] = lo;
            merged += 1;
            k += 2;
        }
        runs[merged] = n;
        count = merged;
    }
}

/// Merges the sorted halves `v[..mid]` and `v[mid..]` in place through `scratch`.
fn merge_runs(v: &mut [DVec2], mid: usize, scratch: &mut Vec<DVec2>) {
    if mid == 0 || mid == v.len() || !lex_less(&v[mid], &v[mid - 1]) {
        return; // already in order
    }
    scratch.clear();
    scratch.extend_from_slice(&v[..mid]);
    let (mut a, mut b, mut out) = (0, mid, 0);
    while a < scratch.len() && b < v.len() {
        if lex_less(&v[b], &scratch[a]) {
            v[out] = v[b];
            b += 1;
        } else {
            v[out] = scratch[a];
            a += 1;
        }
        out += 1;
    }
    while a < scratch.len() {
        v[out] = scratch[a];
        a += 1;
        out += 1;
    }
}

/// Andrew's monotone chain hull of `points` (sorted in place) into `hull`
/// (counter-clockwise in (x, z), no collinear points), then its perimeter and area.
pub fn hull_stats(points: &mut [DVec2], hull: &mut Vec<DVec2>) -> Option<HullStats> {
    sort_lexicographic(points, hull);
    hull.clear();
    let cross = |o: DVec2, a: DVec2, b: DVec2| (a - o).perp_dot(b - o);
    for &q in points.iter() {
        while hull.len() >= 2 && cross(hull[hull.len() - 2], hull[hull.len() - 1], q) <= 0.0 {
            hull.pop();
        }
        hull.push(q);
    }
    let lower = hull.len() + 1;
    for &q in points.iter().rev().skip(1) {
        while hull.len() >= lower && cross(hull[hull.len() - 2], hull[hull.len() - 1], q) <= 0.0 {
            hull.pop();
        }
        hull.push(q);
    }
    hull.pop();
    if hull.len() < 3 {
        return None;
    }
    let mut stats = HullStats {
        perimeter_m: 0.0,
        area_m2: 0.0,
        centroid_x: 0.0,
        centroid_z: 0.0,
        x_min: f64::INFINITY,
        x_max: f64::NEG_INFINITY,
        z_min: f64::INFINITY,
        z_max: f64::NEG_INFINITY,
    };
    // Centroid relative to the first corner, for precision far from the origin.
    let origin = hull[0];
    let (mut moment, mut mean) = (DVec2::ZERO, DVec2::ZERO);
    for i in 0..hull.len() {
        let (p, q) = (hull[i], hull[(i + 1) % hull.len()]);
        let (pr, qr) = (p - origin, q - origin);
        let cross = pr.perp_dot(qr);
        moment += (pr + qr) * cross;
        mean += pr;
        stats.perimeter_m += (q - p).length();
        stats.area_m2 += 0.5 * cross;
        stats.x_min = stats.x_min.min(p.x);
        stats.x_max = stats.x_max.max(p.x);
        stats.z_min = stats.z_min.min(p.y);
        stats.z_max = stats.z_max.max(p.y);
    }
    let centroid = if stats.area_m2 > f64::EPSILON * stats.perimeter_m * stats.perimeter_m {
        origin + moment / (6.0 * stats.area_m2)
    } else {
        origin + mean / hull.len() as f64
    };
    stats.centroid_x = centroid.x;
    stats.centroid_z = centroid.y;
    Some(stats)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::section::{hull_perimeter, slice, Plane};
    use crate::mesh::shapes;

    fn cut_all(mesh: &TriMesh, y: f64) -> SectionScratch {
        let mut idx = LevelIndex::default();
        let b = mesh.bounds().expect("non-empty test mesh");
        idx.rebuild(mesh, b.min.y, b.max.y);
        let mut s = SectionScratch::default();
        s.cut(mesh, &idx, y);
        s
    }

    #[test]
    fn index_candidates_cover_every_crossing_triangle() {
        let m = shapes::uv_sphere(0.3, 23, 31);
        let mut idx = LevelIndex::default();
        idx.rebuild(&m, -0.3, 0.3);
        for k in 0..97 {
            let y = -0.3 + 0.6 * (k as f64 + 0.37) / 97.0;
            let cand: Vec<u32> = idx
                .candidate_entries(y)
                .iter()
                .map(|e| e.triangle)
                .collect();
            for (i, t) in m.triangles.iter().enumerate() {
                let (lo, hi) = tri_y_range(&m, t);
                if lo < y && hi > y {
                    assert!(
                        cand.contains(&(i as u32)),
                        "triangle {i} crosses {y} but is not listed"
                    );
                }
            }
        }
    }

    #[test]
    fn hull_matches_mesh_section_hull() {
        let m = shapes::uv_sphere(0.25, 17, 40);
        for y in [-0.2, -0.05, 0.0013, 0.11, 0.2] {
            let mut s = cut_all(&m, y);
            assert_eq!(s.loops().len(), 1);
            let mine = s.loop_hull(0).expect("hull").perimeter_m;
            let pts: Vec<DVec2> = slice(&m, &Plane::horizontal(y))
                .iter()
                .flat_map(|l| l.points.clone())
                .collect();
            assert!(
                (mine - hull_perimeter(&pts)).abs() < 1e-12,
                "y {y}: {mine} vs {}",
                hull_perimeter(&pts)
            );
        }
    }

    /// `a` with `b` moved by `offset` added as a separate body.
    fn beside(mut a: TriMesh, b: &TriMesh, offset: DVec3) -> TriMesh {
        let off = a.positions.len() as u32;
        a.positions.extend(b.positions.iter().map(|p| *p + offset));
        a.triangles
            .extend(b.triangles.iter().map(|t| t.map(|v| v + off)));
        a
    }

    fn critical(mesh: &TriMesh, lo: f64, hi: f64) -> Option<Vec<f64>> {
        let mut idx = LevelIndex::default();
        let b = mesh.bounds().expect("non-empty test mesh");
        idx.rebuild(mesh, b.min.y, b.max.y);
        let (mut marks, mut seen, mut out) = (Vec::new(), Vec::new(), Vec::new());
        idx.critical_heights(mesh, lo, hi, &mut marks, &mut seen, &mut out)
            .then_some(out)
    }

    /// A sphere's only critical points are its poles (its rings are level, ties broken
    /// by index); two spheres at other heights have four; a sphere with a hole has no
    /// answer (not closed), nor heights outside the index.
    #[test]
    fn critical_heights_are_the_poles_of_spheres_and_none_on_an_open_mesh() {
        let ball = shapes::uv_sphere(0.2, 12, 24);
        let c = critical(&ball, -1.0, 1.0).expect("a sphere is closed");
        assert_eq!(c, vec![-0.2, 0.2]);
        assert_eq!(
            critical(&ball, 0.0, 0.1).expect("closed"),
            Vec::<f64>::new()
        );
        let two = beside(ball.clone(), &ball, DVec3::new(1.0, 0.05, 0.0));
        let c = critical(&two, -1.0, 1.0).expect("two closed spheres");
        assert_eq!(c, vec![-0.2, -0.2 + 0.05, 0.2, 0.2 + 0.05]);
        // The number of loops changes exactly at those heights.
        for (y, loops) in [(-0.17, 1), (0.0, 2), (0.22, 1)] {
            assert_eq!(cut_all(&two, y).loops().len(), loops, "at {y}");
        }
        let mut open = ball.clone();
        open.triangles.pop();
        assert!(critical(&open, -1.0, 1.0).is_none());
        let mut idx = LevelIndex::default();
        idx.rebuild_window(&ball, -0.2, 0.2, (-0.05, 0.05));
        let (mut marks, mut seen, mut out) = (Vec::new(), Vec::new(), Vec::new());
        assert!(!idx.critical_heights(&ball, -0.1, 0.1, &mut marks, &mut seen, &mut out));
        assert!(idx.critical_heights(&ball, -0.04, 0.04, &mut marks, &mut seen, &mut out));
    }

    #[test]
    fn the_grown_loops_equal_the_union_finds() {
        // Two prisms: the loops labelled from the growths and those of the union-find
        // fallback, over the same segments, agree in order, extents, ranges,
        // shared-point ownership and hulls.
        let a = beside(
            shapes::elliptic_cylinder(0.1, 0.07, 1.0, 5, 40),
            &shapes::elliptic_cylinder(0.05, 0.05, 1.0, 4, 24),
            DVec3::new(0.4, 0.1, 0.0),
        );
        for y in [0.33, 0.5, 0.77] {
            let mut grown = cut_all(&a, y);
            let mut unioned = grown.clone();
            unioned.split_into_loops();
            assert_eq!(grown.loops().len(), 2);
            assert_eq!(grown.owned, unioned.owned);
            for i in 0..2 {
                let (g, u) = (grown.loop_hull(i), unioned.loop_hull(i));
                assert_eq!(g, u, "loop {i} at {y}");
                assert_eq!(grown.loops()[i], unioned.loops()[i], "loop {i} at {y}");
            }
        }
    }

    #[test]
    fn two_separate_prisms_give_two_loops_with_their_own_hulls() {
        let a = beside(
            shapes::elliptic_cylinder(0.1, 0.1, 1.0, 3, 32),
            &shapes::elliptic_cylinder(0.1, 0.1, 1.0, 3, 32),
            DVec3::new(0.5, 0.0, 0.0),
        );
        let mut s = cut_all(&a, 0.5);
        assert_eq!(s.loops().len(), 2);
        let r = 0.1;
        let circle = 2.0 * 32.0 * r * (std::f64::consts::PI / 32.0).sin();
        let mut centres = Vec::new();
        for i in 0..2 {
            let h = s.loop_hull(i).expect("hull");
            assert!((h.perimeter_m - circle).abs() < 1e-9, "{}", h.perimeter_m);
            centres.push(h.centroid_x);
            assert!(h.centroid_z.abs() < 1e-9);
        }
        centres.sort_by(f64::total_cmp);
        assert!(
            centres[0].abs() < 1e-9 && (centres[1] - 0.5).abs() < 1e-9,
            "{centres:?}"
        );
        let whole = s.whole_hull().expect("whole").perimeter_m;
        assert!((whole - (circle + 2.0 * 0.5)).abs() < 1e-9, "{whole}");
    }

    #[test]
    fn the_run_merging_sort_equals_a_general_sort() {
        let mut seed = 7u64;
        let mut rnd = move || {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((seed >> 33) as f64 / (1u64 << 31) as f64) - 0.5
        };
        let mut scratch = Vec::new();
        for case in 0..200 {
            let n = case % 97 + 1;
            let mut pts: Vec<DVec2> = match case % 4 {
                // A loop's points in loop order, from a random start.
                0 => (0..n)
                    .map(|k| {
                        let a = (k as f64 + 13.0 * case as f64) / n as f64 * std::f64::consts::TAU;
                        DVec2::new(0.2 * a.cos() + 0.01 * rnd(), 0.1 * a.sin())
                    })
                    .collect(),
                // Random points with repeated coordinates and exact duplicates.
                1 => (0..n)
                    .map(|_| DVec2::new((rnd() * 4.0).round(), (rnd() * 4.0).round()))
                    .collect(),
                // Many short runs (the general sort).
                2 => (0..n).map(|_| DVec2::new(rnd(), rnd())).collect(),
                // Signed zeros and a descending run.
                _ => (0..n)
                    .map(|k| DVec2::new(if k % 2 == 0 { 0.0 } else { -0.0 }, -(k as f64)))
                    .collect(),
            };
            let mut want = pts.clone();
            want.sort_unstable_by(|a, b| a.x.total_cmp(&b.x).then(a.y.total_cmp(&b.y)));
            sort_lexicographic(&mut pts, &mut scratch);
            let bits = |v: &[DVec2]| {
                v.iter()
                    .map(|p| (p.x.to_bits(), p.y.to_bits()))
                    .collect::<Vec<_>>()
            };
            assert_eq!(bits(&pts), bits(&want), "case {case}");
        }
    }

    #[test]
    fn hull_centroid_of_a_triangle_and_of_an_offset_square() {
        let mut hull = Vec::new();
        let mut tri = [
            DVec2::new(0.0, 0.0),
            DVec2::new(3.0, 0.0),
            DVec2::new(0.0, 3.0),
        ];
        let h = hull_stats(&mut tri, &mut hull).expect("triangle");
        assert!((h.centroid_x - 1.0).abs() < 1e-12 && (h.centroid_z - 1.0).abs() < 1e-12);
        assert!((h.area_m2 - 4.5).abs() < 1e-12);
        // A square far from the origin, with a point inside that is not a corner.
        let c = DVec2::new(1000.3, -200.7);
        let mut sq = [
            c + DVec2::new(-0.1, -0.1),
            c + DVec2::new(0.1, -0.1),
            c + DVec2::new(0.1, 0.1),
            c + DVec2::new(-0.1, 0.1),
            c + DVec2::new(0.05, 0.02),
        ];
        let h = hull_stats(&mut sq, &mut hull).expect("square");
        assert!((h.centroid_x - c.x).abs() < 1e-9 && (h.centroid_z - c.y).abs() < 1e-9);
        assert!((h.perimeter_m - 0.8).abs() < 1e-12);
    }

    #[test]
    fn cut_across_x_keeps_exactly_the_loops_across_the_plane() {
        // A wide "torso" about x = 0 and two "arms" beside it.
        let mut m = shapes::elliptic_cylinder(0.15, 0.1, 1.0, 7, 48);
        for x in [-0.3, 0.3] {
            let arm = shapes::elliptic_cylinder(0.04, 0.04, 1.0, 5, 24);
            let off = m.positions.len() as u32;
            m.positions
                .extend(arm.positions.iter().map(|p| *p + DVec3::new(x, 0.0, 0.0)));
            m.triangles
                .extend(arm.triangles.iter().map(|t| t.map(|v| v + off)));
        }
        let mut idx = LevelIndex::default();
        idx.rebuild(&m, 0.0, 1.0);
        let (mut full, mut across) = (SectionScratch::default(), SectionScratch::default());
        for y in [0.05, 0.3337, 0.5, 0.91] {
            full.cut(&m, &idx, y);
            across.cut_across_x(&m, &idx, y, 0.0);
            assert_eq!(full.loops().len(), 3);
            assert_eq!(across.loops().len(), 1);
            let torso = (0..3)
                .find(|&i| full.loops()[i].x_min < 0.0 && full.loops()[i].x_max > 0.0)
                .expect("torso loop");
            assert_eq!(across.loop_hull(0), full.loop_hull(torso));
            // An axis through an arm keeps that arm only.
            across.cut_across_x(&m, &idx, y, 0.31);
            assert_eq!(across.loops().len(), 1);
            assert!((across.loops()[0].x_min - 0.26).abs() < 1e-9);
        }
    }

    /// Walking the loops gives the general cut's loops, in the same order: the same
    /// extents, the same hulls to the bit, each crossing point once, across a plane or
    /// all of them; an open mesh is cut, not walked.
    #[test]
    fn walked_loops_equal_the_cut_loops() {
        let ball = shapes::uv_sphere(0.2, 17, 31);
        let m = beside(
            shapes::elliptic_cylinder(0.15, 0.1, 1.0, 7, 48),
            &ball,
            DVec3::new(0.0, 0.5, 0.0),
        );
        let m = beside(m, &ball, DVec3::new(0.5, 0.45, 0.1));
        let mut idx = LevelIndex::default();
        idx.rebuild(&m, 0.0, 1.0);
        let mut cut = SectionScratch::default().never_walking();
        let mut walk = SectionScratch::default();
        for y in [0.05, 0.3337, 0.42, 0.5, 0.61, 0.91] {
            for axis in [None, Some(0.0), Some(0.01), Some(-0.12), Some(0.5)] {
                match axis {
                    Some(a) => {
                        cut.cut_across_x(&m, &idx, y, a);
                        walk.cut_across_x(&m, &idx, y, a);
                    }
                    None => {
                        cut.cut(&m, &idx, y);
                        walk.cut(&m, &idx, y);
                    }
                }
                assert!(walk.walked && !cut.walked, "closed surfaces are walked");
                assert_eq!(
                    walk.loops().len(),
                    cut.loops().len(),
                    "at {y}, axis {axis:?}"
                );
                for i in 0..cut.loops().len() {
                    let (a, b) = (walk.loops()[i], cut.loops()[i]);
                    assert_eq!(
                        (a.x_min, a.x_max, a.z_min, a.z_max),
                        (b.x_min, b.x_max, b.z_min, b.z_max)
                    );
                    assert_eq!(
                        a.seg_end - a.seg_start,
                        b.seg_end - b.seg_start,
                        "one point a segment"
                    );
                    assert_eq!(walk.loop_hull(i), cut.loop_hull(i));
                }
                assert_eq!(walk.whole_hull(), cut.whole_hull());
            }
        }
        let mut open = m.clone();
        open.triangles.pop();
        let mut idx = LevelIndex::default();
        idx.rebuild(&open, 0.0, 1.0);
        walk.cut(&open, &idx, 0.5);
        assert!(!walk.walked);
    }
}
