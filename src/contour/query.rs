//! Fast queries on a view's silhouette for the fitter: point-in-mask through a per-row
//! span list, and the nearest point on the contour through a uniform grid of contour
//! segments. The fitter projects template rim points into the view and pulls them onto
//! the contour with these.
//!
//! Pixels are the frame's own (distorted) pixels, origin at the centre of the top-left
//! pixel.

use super::Contour;
use crate::imgproc::{find_run_edge, Mask};
use glam::DVec2;

/// Foreground spans `[x0, x1)` per row of a mask.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct MaskSpans {
    pub width: u32,
    pub height: u32,
    /// `row_start[y]..row_start[y+1]` index `spans`.
    pub row_start: Vec<u32>,
    pub spans: Vec<[u32; 2]>,
}

impl MaskSpans {
    /// Rebuilds the spans from a mask (reuses the vectors).
    pub fn rebuild(&mut self, mask: &Mask) {
        self.width = mask.width;
        self.height = mask.height;
        self.row_start.clear();
        self.spans.clear();
        let w = mask.width as usize;
        for y in 0..mask.height as usize {
            self.row_start.push(self.spans.len() as u32);
            let row = &mask.data[y * w..(y + 1) * w];
            let mut x = 0;
            while x < w {
                let x0 = find_run_edge(row, x, true);
                if x0 >= w {
                    break;
                }
                x = find_run_edge(row, x0, false);
                self.spans.push([x0 as u32, x as u32]);
            }
        }
        self.row_start.push(self.spans.len() as u32);
    }

    /// Starts an empty span list of a `width` x `height` mask, to be given its spans in
    /// raster order with [`Self::push_span`] and closed with [`Self::finish`].
    pub fn begin(&mut self, width: u32, height: u32) {
        self.width = width;
        self.height = height;
        self.row_start.clear();
        self.spans.clear();
    }

    /// Appends the span `[x0, x1)` of row `y` (rows in increasing order, spans of a row
    /// left to right); a span touching the previous one of its row extends it.
    pub fn push_span(&mut self, y: u32, x0: u32, x1: u32) {
        let y = y as usize;
        let row_open = self.row_start.len() == y + 1;
        while self.row_start.len() <= y {
            self.row_start.push(self.spans.len() as u32);
        }
        if row_open && self.spans.len() > self.row_start[y] as usize {
            if let Some(last) = self.spans.last_mut() {
                if last[1] == x0 {
                    last[1] = x1;
                    return;
                }
            }
        }
        self.spans.push([x0, x1]);
    }

    /// Closes the span list started by [`Self::begin`].
    pub fn finish(&mut self) {
        while self.row_start.len() <= self.height as usize {
            self.row_start.push(self.spans.len() as u32);
        }
    }

    /// True when the pixel containing `p` is foreground.
    pub fn contains(&self, p: DVec2) -> bool {
        let (x, y) = (p.x.round(), p.y.round());
        if x < 0.0 || y < 0.0 || x >= self.width as f64 || y >= self.height as f64 {
            return false;
        }
        let (x, y) = (x as u32, y as usize);
        let (a, b) = (self.row_start[y] as usize, self.row_start[y + 1] as usize);
        self.spans[a..b].iter().any(|s| s[0] <= x && x < s[1])
    }
}

/// The nearest point of a contour to a query point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NearestOnContour {
    pub point: DVec2,
    pub distance_px: f64,
    /// Segment `segment -> segment + 1` (mod n) of the contour.
    pub segment: usize,
    /// Position along that segment, 0..1.
    pub t: f64,
}

/// Contour segments binned in a uniform grid of `cell_px` squares.
#[derive(Debug, Clone, Default)]
pub struct ContourGrid {
    cell_px: f64,
    origin: DVec2,
    cols: usize,
    rows: usize,
    cell_start: Vec<u32>,
    items: Vec<u32>,
    points: Vec<DVec2>,
}

/// Grid cell size for contour queries, pixels.
pub const GRID_CELL_PX: f64 = 16.0;

impl ContourGrid {
    /// Bins the segments of a closed contour.
    pub fn rebuild(&mut self, contour: &[DVec2], cell_px: f64) {
        self.points.clear();
        self.points.extend_from_slice(contour);
        self.cell_start.clear();
        self.items.clear();
        self.cell_px = cell_px.max(1.0);
        let n = contour.len();
        if n == 0 {
            self.cols = 0;
            self.rows = 0;
            return;
        }
        let (mut lo, mut hi) = (contour[0], contour[0]);
        for &p in contour {
            lo = lo.min(p);
            hi = hi.max(p);
        }
        self.origin = lo - DVec2::splat(1.0);
        self.cols = ((hi.x - self.origin.x) / self.cell_px) as usize + 2;
        self.rows = ((hi.y - self.origin.y) / self.cell_px) as usize + 2;
        let mut counts = vec![0u32; self.cols * self.rows + 1];
        let cells_of = |a: DVec2, b: DVec2, this: &ContourGrid| {
            let (lo, hi) = (a.min(b), a.max(b));
            let c0 = ((lo.x - this.origin.x) / this.cell_px) as usize;
            let c1 = ((hi.x - this.origin.x) / this.cell_px) as usize;
            let r0 = ((lo.y - this.origin.y) / this.cell_px) as usize;
            let r1 = ((hi.y - this.origin.y) / this.cell_px) as usize;
            (c0, c1.min(this.cols - 1), r0, r1.min(this.rows - 1))
        };
        for i in 0..n {
            let (c0, c1, r0, r1) = cells_of(contour[i], contour[(i + 1) % n], self);
            for r in r0..=r1 {
                for c in c0..=c1 {
                    counts[r * self.cols + c + 1] += 1;
                }
            }
        }
        for k in 1..counts.len() {
            counts[k] += counts[k - 1];
        }
        self.items.resize(counts[counts.len() - 1] as usize, 0);
        let mut fill = counts.clone();
        for i in 0..n {
            let (c0, c1, r0, r1) = cells_of(contour[i], contour[(i + 1) % n], self);
            for r in r0..=r1 {
                for c in c0..=c1 {
                    let k = r * self.cols + c;
                    self.items[fill[k] as usize] = i as u32;
                    fill[k] += 1;
                }
            }
        }
        self.cell_start = counts;
    }

    /// The nearest point on the contour (None for an empty contour).
    pub fn nearest(&self, q: DVec2) -> Option<NearestOnContour> {
        let n = self.points.len();
        if n == 0 {
            return None;
        }
        let mut best: Option<NearestOnContour> = None;
        let consider = |i: usize, best: &mut Option<NearestOnContour>| {
            let (a, b) = (self.points[i], self.points[(i + 1) % n]);
            let ab = b - a;
            let l2 = ab.length_squared();
            let t = if l2 > 0.0 {
                ((q - a).dot(ab) / l2).clamp(0.0, 1.0)
            } else {
                0.0
            };
            let p = a + ab * t;
            let d = p.distance(q);
            if best.is_none_or(|b| d < b.distance_px) {
                *best = Some(NearestOnContour {
                    point: p,
                    distance_px: d,
                    segment: i,
                    t,
                });
            }
        };
        // Ring search around the query's cell (clamped into the grid).
        let fc = ((q.x - self.origin.x) / self.cell_px).floor();
        let fr = ((q.y - self.origin.y) / self.cell_px).floor();
        let cc = fc.clamp(0.0, (self.cols - 1) as f64) as i64;
        let cr = fr.clamp(0.0, (self.rows - 1) as f64) as i64;
        let max_ring = self.cols.max(self.rows) as i64;
        for ring in 0..=max_ring {
            if ring > 0 {
                // Rings 0..ring-1 cover this square of cells; anything unvisited lies
                // outside it.
                let r = ring - 1;
                let lo = self.origin + DVec2::new((cc - r) as f64, (cr - r) as f64) * self.cell_px;
                let hi = self.origin
                    + DVec2::new((cc + r + 1) as f64, (cr + r + 1) as f64) * self.cell_px;
                if cc - r <= 0
                    && cr - r <= 0
                    && cc + r >= self.cols as i64 - 1
                    && cr + r >= self.rows as i64 - 1
                {
                    break;
                }
                let bound = (q.x - lo.x)
                    .min(hi.x - q.x)
                    .min(q.y - lo.y)
                    .min(hi.y - q.y)
                    .max(0.0);
                if best.is_some_and(|b| b.distance_px <= bound) {
                    break;
                }
            }
            for r in (cr - ring)..=(cr + ring) {
                for c in (cc - ring)..=(cc + ring) {
                    if (r - cr).abs() != ring && (c - cc).abs() != ring {
                        continue;
                    }
                    if r < 0 || c < 0 || r >= self.rows as i64 || c >= self.cols as i64 {
                        continue;
                    }
                    let k = r as usize * self.cols + c as usize;
                    for &i in
                        &self.items[self.cell_start[k] as usize..self.cell_start[k + 1] as usize]
                    {
                        consider(i as usize, &mut best);
                    }
                }
            }
        }
        best
    }
}

/// What the fitter needs of one view's silhouette: the ordered outer contour (distorted
/// pixels, sub-pixel), point-in-mask and nearest-point-on-contour queries.
#[derive(Debug, Clone, Default)]
pub struct SilhouetteTarget {
    pub contour: Contour,
    pub spans: MaskSpans,
    pub grid: ContourGrid,
}

impl SilhouetteTarget {
    /// Builds the queries for a mask and its contour.
    pub fn rebuild(&mut self, mask: &Mask, contour: &Contour) {
        self.spans.rebuild(mask);
        self.rebuild_contour(contour);
    }
    /// Builds the contour queries; the spans are the caller's (e.g. from
    /// [`super::fill_polygon_spans`]).
    pub fn rebuild_contour(&mut self, contour: &Contour) {
        self.contour.points.clear();
        self.contour.points.extend_from_slice(&contour.points);
        self.grid.rebuild(&contour.points, GRID_CELL_PX);
    }
    pub fn new(mask: &Mask, contour: &Contour) -> Self {
        let mut s = SilhouetteTarget::default();
        s.rebuild(mask, contour);
        s
    }
    /// True when the pixel at `p` belongs to the person.
    pub fn contains(&self, p: DVec2) -> bool {
        self.spans.contains(p)
    }
    /// The nearest contour point.
    pub fn nearest(&self, p: DVec2) -> Option<NearestOnContour> {
        self.grid.nearest(p)
    }
    /// Distance to the contour, negative inside the mask (pixels); None without contour.
    pub fn signed_distance(&self, p: DVec2) -> Option<f64> {
        let d = self.grid.nearest(p)?.distance_px;
        Some(if self.contains(p) { -d } else { d })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nearest_matches_brute_force() {
        let pts: Vec<DVec2> = (0..200)
            .map(|i| {
                let a = i as f64 / 200.0 * std::f64::consts::TAU;
                DVec2::new(
                    300.0 + 120.0 * a.cos() + 30.0 * (5.0 * a).sin(),
                    200.0 + 80.0 * a.sin(),
                )
            })
            .collect();
        let mut g = ContourGrid::default();
        g.rebuild(&pts, GRID_CELL_PX);
        let mut s = 12345u64;
        for _ in 0..500 {
            s = s
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            let q = DVec2::new(
                (s >> 33) as f64 % 700.0 - 50.0,
                (s >> 13) as f64 % 500.0 - 50.0,
            );
            let brute = (0..pts.len())
                .map(|i| {
                    let (a, b) = (pts[i], pts[(i + 1) % pts.len()]);
                    let t = ((q - a).dot(b - a) / (b - a).length_squared()).clamp(0.0, 1.0);
                    (a + (b - a) * t).distance(q)
                })
                .fold(f64::INFINITY, f64::min);
            let got = g.nearest(q).unwrap().distance_px;
            assert!((got - brute).abs() < 1e-9, "{q}: {got} vs {brute}");
        }
    }

    #[test]
    fn spans_answer_point_in_mask() {
        let mut m = Mask::new(10, 5);
        for x in 2..6 {
            m.data[2 * 10 + x] = 255;
        }
        let mut s = MaskSpans::default();
        s.rebuild(&m);
        assert!(s.contains(DVec2::new(3.2, 1.8)));
        assert!(!s.contains(DVec2::new(6.0, 2.0)));
        assert!(!s.contains(DVec2::new(-3.0, 2.0)));
    }
}
