//! Contours of a silhouette mask (issue 4, step 3): the ordered outer boundary of each
//! 8-connected component (Suzuki and Abe 1985, border following of outer borders), even
//! resampling by arc length, and sub-pixel refinement of the boundary along its normal.
//!
//! # Conventions
//! - Points are pixels (column, row) with the origin at the centre of the top-left pixel,
//!   in the frame's own (distorted) pixels. A traced contour lists the centres of the
//!   boundary pixels of the component, each once per visit, as `cv2.findContours(...,
//!   RETR_EXTERNAL, CHAIN_APPROX_NONE)` does.
//! - Contours are closed: the last point connects to the first.
//! - Refined contours lie on the estimated edge itself (the 50 % level of the colour
//!   difference to the backdrop), so about half a pixel outside the boundary pixels.

pub mod chordal;
pub mod query;

pub use query::{ContourGrid, MaskSpans, NearestOnContour, SilhouetteTarget};

use crate::imgproc::Mask;
use glam::DVec2;

/// An ordered closed contour in pixels.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Contour {
    /// Ordered points, pixels; the last connects back to the first.
    pub points: Vec<DVec2>,
}

impl Contour {
    /// Twice the signed area (shoelace; positive when counter-clockwise in the (x, y)
    /// coordinate sense, which is clockwise on screen since rows go down).
    pub fn signed_area2(&self) -> f64 {
        signed_area2(&self.points)
    }
    /// Perimeter in pixels.
    pub fn length(&self) -> f64 {
        closed_length(&self.points)
    }
    pub fn len(&self) -> usize {
        self.points.len()
    }
    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }
}

/// Twice the signed area of a closed polygon.
pub fn signed_area2(p: &[DVec2]) -> f64 {
    let n = p.len();
    (0..n).map(|i| p[i].perp_dot(p[(i + 1) % n])).sum()
}

/// Length of a closed polyline.
pub fn closed_length(p: &[DVec2]) -> f64 {
    let n = p.len();
    (0..n).map(|i| p[i].distance(p[(i + 1) % n])).sum()
}

/// The 8 neighbour offsets, clockwise on screen starting east.
const DIRS: [(i64, i64); 8] = [
    (1, 0),
    (1, 1),
    (0, 1),
    (-1, 1),
    (-1, 0),
    (-1, -1),
    (0, -1),
    (1, -1),
];
/// Direction index of west (the background pixel left of a raster-scan start).
const WEST: usize = 4;

/// Follows the outer border of the component containing `start` (Suzuki and Abe,
/// algorithm 1, steps 3.1-3.5, outer border). `start` must be a foreground pixel whose
/// west neighbour is background (e.g. the first pixel of a run). Appends the border
/// pixels to `out` in order.
pub fn follow_outer_border(mask: &Mask, start: (i64, i64), out: &mut Vec<(i64, i64)>) {
    let on = |x: i64, y: i64| mask.get(x, y);
    let (sx, sy) = start;
    if !on(sx, sy) {
        return;
    }
    // 3.1: clockwise from the west neighbour, the first foreground neighbour.
    let mut first = None;
    for k in 0..8 {
        let d = (WEST + k) % 8;
        let (dx, dy) = DIRS[d];
        if on(sx + dx, sy + dy) {
            first = Some(d);
            break;
        }
    }
    out.push(start);
    let Some(d1) = first else {
        return; // isolated pixel
    };
    let p1 = (sx + DIRS[d1].0, sy + DIRS[d1].1);
    // 3.2: (i2, j2) = p1 seen from (i3, j3) = start.
    let mut cur = start;
    let mut back = d1; // direction from cur to the previous border pixel
    let guard = 8 * (mask.width as usize + 2) * (mask.height as usize + 2);
    loop {
        // 3.3: counter-clockwise from the element after `back`.
        let mut next = None;
        for k in 1..=8 {
            let d = (back + 8 - k) % 8;
            let (dx, dy) = DIRS[d];
            if on(cur.0 + dx, cur.1 + dy) {
                next = Some(d);
                break;
            }
        }
        let Some(d4) = next else {
            return;
        };
        let p4 = (cur.0 + DIRS[d4].0, cur.1 + DIRS[d4].1);
        // 3.5: back at the start, about to repeat the first step.
        if p4 == start && cur == p1 {
            return;
        }
        back = (d4 + 4) % 8;
        cur = p4;
        out.push(cur);
        if out.len() > guard {
            return; // cannot happen on a valid mask; guards against a logic error
        }
    }
}

/// The outer contours of all 8-connected components of a mask, largest component first.
/// Unlike `RETR_EXTERNAL`, components inside another's hole are returned too.
pub fn trace_outer(mask: &Mask) -> Vec<Contour> {
    let mut rc = crate::imgproc::RunComponents::default();
    if mask.data.len() < (mask.width * mask.height) as usize {
        return Vec::new();
    }
    rc.compute(&mask.data, mask.width, mask.height, true, true);
    let mut order: Vec<usize> = (0..rc.components.len()).collect();
    order.sort_by_key(|&c| std::cmp::Reverse(rc.components[c].area));
    let mut px = Vec::new();
    order
        .into_iter()
        .map(|c| {
            let r = rc.runs[rc.components[c].first_run];
            px.clear();
            follow_outer_border(mask, (r.x0 as i64, r.y as i64), &mut px);
            Contour {
                points: px
                    .iter()
                    .map(|&(x, y)| DVec2::new(x as f64, y as f64))
                    .collect(),
            }
        })
        .collect()
}

/// Resamples a closed polyline to points evenly spaced by arc length (about `spacing`
/// pixels apart, at least 3 points) into `out`.
pub fn resample_closed(points: &[DVec2], spacing: f64, out: &mut Vec<DVec2>) {
    out.clear();
    let n = points.len();
    if n < 3 || spacing <= 0.0 {
        out.extend_from_slice(points);
        return;
    }
    let total = closed_length(points);
    let m = ((total / spacing).round() as usize).max(3);
    let step = total / m as f64;
    let mut seg = 0;
    let mut seg_start = 0.0; // arc length at points[seg]
    let mut seg_len = points[0].distance(points[1 % n]);
    for k in 0..m {
        let s = k as f64 * step;
        while seg_start + seg_len < s && seg < n - 1 {
            seg_start += seg_len;
            seg += 1;
            seg_len = points[seg].distance(points[(seg + 1) % n]);
        }
        let t = if seg_len > 0.0 {
            ((s - seg_start) / seg_len).clamp(0.0, 1.0)
        } else {
            0.0
        };
        out.push(points[seg].lerp(points[(seg + 1) % n], t));
    }
}

/// Sub-pixel refinement of the edge, along each point's outward normal.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SubpixelOptions {
    /// Half-length of the profile along the normal, pixels.
    pub reach_px: f64,
    /// Step of the profile samples, pixels.
    pub step_px: f64,
    /// Minimum inside-outside difference of the score to trust the profile.
    pub min_contrast: f32,
    /// Neighbours (each side) used for the tangent.
    pub tangent_span: usize,
}

impl Default for SubpixelOptions {
    fn default() -> Self {
        SubpixelOptions {
            reach_px: 3.0,
            step_px: 1.0,
            min_contrast: 12.0,
            tangent_span: 2,
        }
    }
}

/// Offset along the outward normal applied when a profile has too little contrast:
/// boundary pixel centres lie half a pixel inside the edge.
const DEFAULT_EDGE_OFFSET_PX: f64 = 0.5;
/// Largest shift a profile may apply, pixels.
const MAX_EDGE_SHIFT_PX: f64 = 2.5;

/// Moves each point of a closed contour (in place) onto the edge along its outward
/// normal: with `score` a per-pixel difference to the background (e.g. colour distance,
/// high inside), the profile's samples, normalised between the inside and outside
/// values, are the fractions of each unit step covered by the person, and their sum
/// places the edge (the area method; exact for a straight anti-aliased edge). `score` is sampled
/// at integer pixels and interpolated bilinearly.
pub fn refine_subpixel(
    points: &mut [DVec2],
    score: &dyn Fn(i64, i64) -> f32,
    opts: &SubpixelOptions,
    scratch: &mut Vec<DVec2>,
) {
    let n = points.len();
    if n < 3 {
        return;
    }
    let orient = if signed_area2(points) >= 0.0 {
        1.0
    } else {
        -1.0
    };
    scratch.clear();
    scratch.extend_from_slice(points);
    // The profile's pixels are scored once per point: a memo over the square of pixels
    // a profile can reach (samples of one profile share half their pixels).
    let mut memo = ScoreMemo::default();
    let k = opts.tangent_span.max(1);
    let steps = (opts.reach_px / opts.step_px).round() as i64;
    let ends_on_reach = ((steps as f64) * opts.step_px - opts.reach_px).abs() < 1e-12;
    let mut profile: Vec<f32> = Vec::with_capacity(2 * steps.max(0) as usize + 1);
    for i in 0..n {
        let t = scratch[(i + k) % n] - scratch[(i + n - k % n) % n];
        let len = t.length();
        if len < 1e-9 {
            continue;
        }
        let t = t / len;
        let normal = DVec2::new(t.y, -t.x) * orient; // outward
        let p = scratch[i];
        memo.start(p);
        let mut at = |s: f64| memo.bilinear(p + normal * s, score);
        // The profile's samples; its ends are the inside and outside values when the
        // reach is a whole number of steps.
        profile.clear();
        profile.extend((-steps..=steps).map(|j| at(j as f64 * opts.step_px)));
        let (inside, outside) = if ends_on_reach {
            (profile[0], profile[profile.len() - 1])
        } else {
            (at(-opts.reach_px), at(opts.reach_px))
        };
        let mut shift = DEFAULT_EDGE_OFFSET_PX;
        if inside - outside >= opts.min_contrast {
            // Area method: each unit sample along the normal contributes its fraction of
            // foreground; the fractions sum to the edge's distance from the profile start.
            let mut covered = 0.0;
            for &v in profile.iter() {
                covered +=
                    (((v - outside) / (inside - outside)) as f64).clamp(0.0, 1.0) * opts.step_px;
            }
            shift = -opts.reach_px - 0.5 * opts.step_px + covered;
        }
        points[i] = p + normal * shift.clamp(-MAX_EDGE_SHIFT_PX, MAX_EDGE_SHIFT_PX);
    }
}

/// Half size of [`ScoreMemo`]'s square, pixels.
const MEMO_R: i64 = 5;
const MEMO_SIDE: i64 = 2 * MEMO_R + 2;

/// Scores of the pixels about one contour point, computed on first use (see
/// [`refine_subpixel`]); pixels beyond the square are scored directly.
struct ScoreMemo {
    x0: i64,
    y0: i64,
    /// Point counter; a value is valid where its stamp equals it.
    stamp: u32,
    stamps: [u32; (MEMO_SIDE * MEMO_SIDE) as usize],
    values: [f32; (MEMO_SIDE * MEMO_SIDE) as usize],
}

impl Default for ScoreMemo {
    fn default() -> Self {
        ScoreMemo {
            x0: 0,
            y0: 0,
            stamp: 0,
            stamps: [0; (MEMO_SIDE * MEMO_SIDE) as usize],
            values: [0.0; (MEMO_SIDE * MEMO_SIDE) as usize],
        }
    }
}

impl ScoreMemo {
    /// Centres the memo on `p`, forgetting the previous point's values.
    fn start(&mut self, p: DVec2) {
        if self.stamp == u32::MAX {
            self.stamps.fill(0);
            self.stamp = 0;
        }
        self.stamp += 1;
        self.x0 = fast_floor(p.x) - MEMO_R;
        self.y0 = fast_floor(p.y) - MEMO_R;
    }

    #[inline]
    fn get(&mut self, x: i64, y: i64, score: &dyn Fn(i64, i64) -> f32) -> f32 {
        let (dx, dy) = (x - self.x0, y - self.y0);
        if !(0..MEMO_SIDE).contains(&dx) || !(0..MEMO_SIDE).contains(&dy) {
            return score(x, y);
        }
        let k = (dy * MEMO_SIDE + dx) as usize;
        if self.stamps[k] != self.stamp {
            self.stamps[k] = self.stamp;
            self.values[k] = score(x, y);
        }
        self.values[k]
    }

    /// The score interpolated bilinearly at `p`.
    #[inline]
    fn bilinear(&mut self, p: DVec2, score: &dyn Fn(i64, i64) -> f32) -> f32 {
        let (x0, y0) = (fast_floor(p.x), fast_floor(p.y));
        let (fx, fy) = ((p.x - x0 as f64) as f32, (p.y - y0 as f64) as f32);
        let a = self.get(x0, y0, score) * (1.0 - fx) + self.get(x0 + 1, y0, score) * fx;
        let b = self.get(x0, y0 + 1, score) * (1.0 - fx) + self.get(x0 + 1, y0 + 1, score) * fx;
        a * (1.0 - fy) + b * fy
    }
}

/// Rasterises a closed polygon (pixels) into `mask`: a pixel is set (255) when its
/// centre lies inside (even-odd rule, half-open rows); the rest of the mask is cleared.
/// With the sub-pixel contour as the polygon this puts the mask's border on the 50 %
/// level of the edge, as a coverage-based ground truth does. Returns the pixels set.
/// `scratch` holds the (row, x) crossings.
pub fn fill_polygon(points: &[DVec2], mask: &mut Mask, scratch: &mut Vec<(u32, f32)>) -> u64 {
    fill_polygon_rows(points, mask, scratch, |_, _, _| {})
}

/// [`fill_polygon`], also writing the filled spans into `spans` (the same as
/// `spans.rebuild(mask)` after the fill, without reading the mask back).
pub fn fill_polygon_spans(
    points: &[DVec2],
    mask: &mut Mask,
    scratch: &mut Vec<(u32, f32)>,
    spans: &mut query::MaskSpans,
) -> u64 {
    spans.begin(mask.width, mask.height);
    let set = fill_polygon_rows(points, mask, scratch, |y, x0, x1| {
        spans.push_span(y, x0, x1)
    });
    spans.finish();
    set
}

/// [`fill_polygon`], calling `span(y, x0, x1)` for each filled span in raster order.
fn fill_polygon_rows(
    points: &[DVec2],
    mask: &mut Mask,
    scratch: &mut Vec<(u32, f32)>,
    mut span: impl FnMut(u32, u32, u32),
) -> u64 {
    mask.data.fill(0);
    let n = points.len();
    let (w, h) = (mask.width as i64, mask.height as i64);
    if n < 3 || w == 0 || h == 0 {
        return 0;
    }
    scratch.clear();
    for i in 0..n {
        let (a, b) = (points[i], points[(i + 1) % n]);
        if a.y == b.y {
            continue;
        }
        let (lo, hi) = if a.y < b.y { (a, b) } else { (b, a) };
        // Rows whose centre y satisfies lo.y <= y < hi.y.
        let f = fast_floor(lo.y);
        let mut y = (if (f as f64) < lo.y { f + 1 } else { f }).max(0);
        while (y as f64) < hi.y && y < h {
            let t = (y as f64 - lo.y) / (hi.y - lo.y);
            scratch.push((y as u32, (lo.x + t * (hi.x - lo.x)) as f32));
            y += 1;
        }
    }
    scratch.sort_unstable_by(|p, q| p.0.cmp(&q.0).then(p.1.total_cmp(&q.1)));
    let mut set = 0u64;
    for pair in scratch.chunks_exact(2) {
        let (r, xa, xb) = (pair[0].0, pair[0].1, pair[1].1);
        if pair[1].0 != r {
            continue; // cannot happen for a closed polygon
        }
        // Pixel centres x with xa <= x < xb.
        let x0 = (xa.ceil() as i64).clamp(0, w);
        let x1 = (xb.ceil() as i64).clamp(0, w);
        if x1 > x0 {
            let row = r as usize * w as usize;
            mask.data[row + x0 as usize..row + x1 as usize].fill(crate::imgproc::MASK_ON);
            set += (x1 - x0) as u64;
            span(r, x0 as u32, x1 as u32);
        }
    }
    set
}

/// Puts the two ends of every span of a polygon's fill (`crossings`: its sorted (row, x)
/// crossings, as [`fill_polygon`] leaves them in its scratch) on ramps in `data` (a
/// `width`-wide 0/255 mask of that fill): along a row, the value through the pixel
/// centres is 255 × (0.5 + distance inside the crossing), so that a bilinear occupancy
/// (value / 255) crosses one half at the crossing itself, within 0.1 px, instead of at the
/// pixel border nearest to it. Pixels inside keep a value above 127 and pixels outside
/// one of 127 or less: thresholded, the mask is unchanged.
pub fn soften_span_ends(crossings: &[(u32, f32)], width: u32, data: &mut [u8]) {
    let w = width as i64;
    // 255 x the ramp's value at pixel centre x, for a crossing at c with the inside
    // toward `dir` (+1: x > c inside).
    let ramp = |x: i64, c: f64, dir: f64| 255.0 * (0.5 + dir * (x as f64 - c));
    for pair in crossings.chunks_exact(2) {
        let (r, xa, xb) = (pair[0].0, pair[0].1 as f64, pair[1].1 as f64);
        if pair[1].0 != r || xb <= xa {
            continue;
        }
        let row = r as usize * width as usize;
        let x0 = xa.ceil() as i64; // first pixel centre inside
        let x1 = xb.ceil() as i64; // first pixel centre outside on the right
        for (x, v) in [
            (x0, ramp(x0, xa, 1.0).min(ramp(x0, xb, -1.0))),
            (x1 - 1, ramp(x1 - 1, xa, 1.0).min(ramp(x1 - 1, xb, -1.0))),
        ] {
            if x1 > x0 && (0..w).contains(&x) {
                if let Some(d) = data.get_mut(row + x as usize) {
                    if *d > 127 {
                        *d = v.round().clamp(128.0, 255.0) as u8;
                    }
                }
            }
        }
        for (x, v) in [(x0 - 1, ramp(x0 - 1, xa, 1.0)), (x1, ramp(x1, xb, -1.0))] {
            if (0..w).contains(&x) {
                if let Some(d) = data.get_mut(row + x as usize) {
                    if *d <= 127 {
                        *d = (*d).max(v.round().clamp(0.0, 127.0) as u8);
                    }
                }
            }
        }
    }
}

/// Floor without a libm call (baseline x86-64 has no rounding instruction).
#[inline(always)]
pub(crate) fn fast_floor(v: f64) -> i64 {
    let t = v as i64;
    if (t as f64) > v {
        t - 1
    } else {
        t
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn mask_from(rows: &[&str]) -> Mask {
        let h = rows.len() as u32;
        let w = rows[0].len() as u32;
        Mask {
            width: w,
            height: h,
            data: rows
                .iter()
                .flat_map(|r| r.bytes().map(|b| if b == b'#' { 255 } else { 0 }))
                .collect(),
        }
    }

    #[test]
    fn traces_a_square_once_around() {
        let m = mask_from(&["......", ".####.", ".####.", ".####.", "......"]);
        let c = trace_outer(&m);
        assert_eq!(c.len(), 1);
        assert_eq!(c[0].points.len(), 10);
        for p in &c[0].points {
            assert!(p.y == 1.0 || p.y == 3.0 || p.x == 1.0 || p.x == 4.0, "{p}");
        }
    }

    #[test]
    fn traces_single_pixels_and_necks() {
        let m = mask_from(&["#.....", "......", "..#...", "...#..", "..#...", "......"]);
        let c = trace_outer(&m);
        assert_eq!(c.len(), 2);
        assert_eq!(c[0].points.len(), 4); // 3 pixels, the middle one visited twice
        assert_eq!(c[1].points.len(), 1);
    }

    #[test]
    fn every_contour_point_is_a_border_pixel() {
        // A blob with a concavity and a hole.
        let m = mask_from(&[
            "..........",
            ".#######..",
            ".##...###.",
            ".##.#.###.",
            ".##...##..",
            ".###.####.",
            ".#.....##.",
            "..........",
        ]);
        let c = &trace_outer(&m)[0];
        for p in &c.points {
            let (x, y) = (p.x as i64, p.y as i64);
            assert!(m.get(x, y));
            let border = (-1..=1)
                .any(|dy| (-1..=1).any(|dx| (dx != 0 || dy != 0) && !m.get(x + dx, y + dy)));
            assert!(border, "{p} is interior");
        }
        // Consecutive points are 8-neighbours.
        for w in c.points.windows(2) {
            let d = w[1] - w[0];
            assert!(d.x.abs() <= 1.0 && d.y.abs() <= 1.0 && d != DVec2::ZERO);
        }
    }

    #[test]
    fn filled_polygon_sets_the_pixel_centres_inside() {
        let mut m = Mask::new(10, 8);
        let sq = [
            DVec2::new(1.5, 1.2),
            DVec2::new(6.2, 1.2),
            DVec2::new(6.2, 5.0),
            DVec2::new(1.5, 5.0),
        ];
        let mut s = Vec::new();
        let n = fill_polygon(&sq, &mut m, &mut s);
        // x centres 2..=6, y centres 2..=4.
        assert_eq!(n, 5 * 3);
        assert!(
            m.get(2, 2)
                && m.get(6, 4)
                && !m.get(1, 2)
                && !m.get(7, 2)
                && !m.get(2, 5)
                && !m.get(2, 1)
        );
    }

    #[test]
    fn spans_written_by_the_fill_are_the_masks_own() {
        // A star with concave notches and a part beyond the frame.
        let pts: Vec<DVec2> = (0..40)
            .map(|i| {
                let a = i as f64 / 40.0 * std::f64::consts::TAU;
                let r = if i % 2 == 0 { 30.0 } else { 12.5 };
                DVec2::new(35.3 + r * a.cos(), 28.7 + r * a.sin())
            })
            .collect();
        let mut m = Mask::new(60, 50);
        let (mut s, mut spans) = (Vec::new(), query::MaskSpans::default());
        let n = fill_polygon_spans(&pts, &mut m, &mut s, &mut spans);
        let mut read_back = query::MaskSpans::default();
        read_back.rebuild(&m);
        assert_eq!(spans, read_back);
        assert_eq!(n, m.area());
        assert!(n > 500);
    }

    /// The ramps put a row's one-half crossing on the polygon's own edge (within 0.1 px,
    /// where the binary fill is off by up to half a pixel), and thresholded they are the
    /// fill again.
    #[test]
    fn softened_span_ends_cross_one_half_on_the_outline() {
        let (w, h) = (40u32, 12u32);
        for k in 0..20 {
            let (xa, xb) = (5.0 + 0.05 * k as f64, 30.0 - 0.037 * k as f64);
            let quad = [
                DVec2::new(xa, 0.5),
                DVec2::new(xb, 0.5),
                DVec2::new(xb, 10.5),
                DVec2::new(xa, 10.5),
            ];
            let mut m = Mask::new(w, h);
            let mut s = Vec::new();
            fill_polygon(&quad, &mut m, &mut s);
            let mut soft = m.data.clone();
            soften_span_ends(&s, w, &mut soft);
            let binary: Vec<u8> = soft
                .iter()
                .map(|&v| if v > 127 { 255 } else { 0 })
                .collect();
            assert_eq!(binary, m.data);
            // The one-half crossings of row 5, by linear interpolation between centres.
            let row = &soft[5 * w as usize..6 * w as usize];
            let occ = |x: usize| row[x] as f64 / 255.0;
            let cross = |x: usize| x as f64 + (0.5 - occ(x)) / (occ(x + 1) - occ(x));
            let left = (0..w as usize - 1).find(|&x| occ(x) < 0.5 && occ(x + 1) >= 0.5);
            let right = (0..w as usize - 1).find(|&x| occ(x) >= 0.5 && occ(x + 1) < 0.5);
            let (Some(l), Some(r)) = (left, right) else {
                panic!("no crossing in row 5 for k = {k}");
            };
            assert!((cross(l) - xa).abs() < 0.1, "left {} vs {xa}", cross(l));
            assert!((cross(r) - xb).abs() < 0.1, "right {} vs {xb}", cross(r));
            // The binary fill's crossings sit on pixel borders.
            let hard = |x: usize| m.data[5 * w as usize + x] > 127;
            let hl = (0..w as usize).find(|&x| hard(x)).map(|x| x as f64 - 0.5);
            assert!(hl.is_some_and(|b| (b - xa).abs() <= 0.5 + 1e-9));
        }
        // A span narrower than a pixel keeps its one centre inside.
        let sliver = [
            DVec2::new(10.7, 0.5),
            DVec2::new(11.3, 0.5),
            DVec2::new(11.3, 3.5),
            DVec2::new(10.7, 3.5),
        ];
        let mut m = Mask::new(w, h);
        let mut s = Vec::new();
        fill_polygon(&sliver, &mut m, &mut s);
        let mut soft = m.data.clone();
        soften_span_ends(&s, w, &mut soft);
        let row = &soft[2 * w as usize..3 * w as usize];
        assert!(
            row[11] > 127 && row[10] <= 127 && row[12] <= 127,
            "{:?}",
            &row[9..13]
        );
    }

    #[test]
    fn resampling_is_even() {
        let sq = [
            DVec2::new(0.0, 0.0),
            DVec2::new(10.0, 0.0),
            DVec2::new(10.0, 10.0),
            DVec2::new(0.0, 10.0),
        ];
        let mut out = Vec::new();
        resample_closed(&sq, 1.0, &mut out);
        assert_eq!(out.len(), 40);
        for i in 0..out.len() {
            let d = out[i].distance(out[(i + 1) % out.len()]);
            assert!((d - 1.0).abs() < 1e-9, "{d}");
        }
    }

    #[test]
    fn subpixel_finds_an_antialiased_edge() {
        // Vertical edge at x = 10.3: pixel value = coverage * 100.
        let edge = 10.3;
        let score =
            |x: i64, _y: i64| -> f32 { (100.0 * (edge + 0.5 - x as f64).clamp(0.0, 1.0)) as f32 };
        // Boundary pixel centres x = 10 going down (clockwise on screen, area < 0 for
        // a curve whose inside is on the left... use a closed loop around the region).
        let mut pts: Vec<DVec2> = (0..20).map(|y| DVec2::new(10.0, y as f64)).collect();
        pts.extend((0..20).rev().map(|y| DVec2::new(-30.0, y as f64)));
        let mut s = Vec::new();
        refine_subpixel(&mut pts, &score, &SubpixelOptions::default(), &mut s);
        for p in &pts[3..17] {
            assert!((p.x - edge).abs() < 0.05, "{p}");
        }
    }
}
