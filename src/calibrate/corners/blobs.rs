//! Circle grids: dark elliptical blobs as grid candidates (the saddle stage's counterpart
//! for a circle target).

use super::*;

/// Circle grids: local-mean window (image size divided by this), how much darker than
/// the local mean a blob pixel is (grey levels), smallest blob area (pixels), largest
/// blob area (image area divided by this), accepted filled-ellipse ratio, and the
/// padding of the weighted centroid box (pixels).
pub(super) const BLOB_WINDOW_DIVISOR: usize = 12;
pub(super) const BLOB_DARKER_THAN_MEAN: f64 = 10.0;
pub(super) const MIN_BLOB_AREA_PX: f64 = 12.0;
pub(super) const MAX_BLOB_AREA_DIVISOR: f64 = 50.0;
pub(super) const BLOB_FILL_RANGE: (f64, f64) = (0.8, 1.25);
pub(super) const BLOB_PAD_PX: usize = 2;

/// What the flood fill of one dark blob gathered: pixel count, first and second moments
/// of the pixel positions, bounding box, darkest grey level, and whether it touches the
/// image border.
struct BlobFill {
    n: f64,
    sx: f64,
    sy: f64,
    sxx: f64,
    sxy: f64,
    syy: f64,
    bbox: [usize; 4],
    darkest: f64,
    touches_border: bool,
}

impl CornerDetector {
    /// Dark elliptical blobs as grid candidates (directions from nearest neighbours).
    pub(super) fn find_blobs(&mut self) {
        let (w, h) = (self.w, self.h);
        self.local_mean_integral();
        let r = (w.max(h) / BLOB_WINDOW_DIVISOR).max(4);
        self.labels.clear();
        self.labels.resize(w * h, 0);
        let mut blobs: Vec<(DVec2, f32, f64)> = Vec::new();
        let mut next_label = 0u32;
        for start in 0..w * h {
            if self.labels[start] != 0 || !self.is_dark(start % w, start / w, r) {
                continue;
            }
            next_label += 1;
            let fill = self.fill_blob(start, next_label, r);
            if fill.touches_border
                || fill.n < MIN_BLOB_AREA_PX
                || fill.n > (w * h) as f64 / MAX_BLOB_AREA_DIVISOR
            {
                continue;
            }
            blobs.extend(self.blob_centre(&fill, next_label));
        }
        self.blob_candidates(&blobs);
    }

    /// The integral image of the grey levels (for the local means).
    fn local_mean_integral(&mut self) {
        let (w, h) = (self.w, self.h);
        let iw = w + 1;
        self.integral.clear();
        self.integral.resize(iw * (h + 1), 0.0);
        for y in 0..h {
            let mut row = 0.0;
            for x in 0..w {
                row += self.gray[y * w + x] as f64;
                self.integral[(y + 1) * iw + x + 1] = self.integral[y * iw + x + 1] + row;
            }
        }
    }

    /// True when pixel (x, y) is darker than the mean of its window of radius `r` by
    /// [`BLOB_DARKER_THAN_MEAN`].
    fn is_dark(&self, x: usize, y: usize, r: usize) -> bool {
        let (w, h) = (self.w, self.h);
        let iw = w + 1;
        let (x0, x1) = (x.saturating_sub(r), (x + r + 1).min(w));
        let (y0, y1) = (y.saturating_sub(r), (y + r + 1).min(h));
        let sum =
            self.integral[y1 * iw + x1] - self.integral[y0 * iw + x1] - self.integral[y1 * iw + x0]
                + self.integral[y0 * iw + x0];
        let mean = sum / ((x1 - x0) * (y1 - y0)) as f64;
        (self.gray[y * w + x] as f64) < mean - BLOB_DARKER_THAN_MEAN
    }

    /// Flood-fills the dark blob at pixel `start` (4-connected) with `label`, gathering
    /// its moments, box and darkest level.
    fn fill_blob(&mut self, start: usize, label: u32, r: usize) -> BlobFill {
        let (w, h) = (self.w, self.h);
        self.labels[start] = label;
        self.stack.clear();
        self.stack.push(start);
        let (mut n, mut sx, mut sy, mut sxx, mut sxy, mut syy) = (0.0f64, 0.0, 0.0, 0.0, 0.0, 0.0);
        let (mut bx0, mut by0, mut bx1, mut by1) = (usize::MAX, usize::MAX, 0, 0);
        let mut touches_border = false;
        let mut fg = f64::INFINITY;
        while let Some(i) = self.stack.pop() {
            let (x, y) = (i % w, i / w);
            let (fx, fy) = (x as f64, y as f64);
            n += 1.0;
            sx += fx;
            sy += fy;
            sxx += fx * fx;
            sxy += fx * fy;
            syy += fy * fy;
            bx0 = bx0.min(x);
            by0 = by0.min(y);
            bx1 = bx1.max(x);
            by1 = by1.max(y);
            fg = fg.min(self.gray[i] as f64);
            touches_border |= x == 0 || y == 0 || x + 1 == w || y + 1 == h;
            let visit = |j: usize, s: &mut Self| {
                if s.labels[j] == 0 && s.is_dark(j % w, j / w, r) {
                    s.labels[j] = label;
                    s.stack.push(j);
                }
            };
            if x > 0 {
                visit(i - 1, self);
            }
            if x + 1 < w {
                visit(i + 1, self);
            }
            if y > 0 {
                visit(i - w, self);
            }
            if y + 1 < h {
                visit(i + w, self);
            }
        }
        BlobFill {
            n,
            sx,
            sy,
            sxx,
            sxy,
            syy,
            bbox: [bx0, by0, bx1, by1],
            darkest: fg,
            touches_border,
        }
    }

    /// The blob's centre, area and contrast, when it is filled like an ellipse and
    /// stands out from the sheet: its centroid weighted by darkness over its padded box.
    fn blob_centre(&self, fill: &BlobFill, label: u32) -> Option<(DVec2, f32, f64)> {
        let (w, h) = (self.w, self.h);
        let (n, fg) = (fill.n, fill.darkest);
        let [bx0, by0, bx1, by1] = fill.bbox;
        let (mx, my) = (fill.sx / n, fill.sy / n);
        let (cxx, cxy, cyy) = (
            fill.sxx / n - mx * mx,
            fill.sxy / n - mx * my,
            fill.syy / n - my * my,
        );
        // A filled ellipse of area A has det(cov) = (A / 4 pi)^2.
        let det = (cxx * cyy - cxy * cxy).max(0.0);
        let fill = n / (4.0 * std::f64::consts::PI * det.sqrt()).max(1e-9);
        if !(BLOB_FILL_RANGE.0..BLOB_FILL_RANGE.1).contains(&fill) {
            return None;
        }
        // Weighted centroid over the padded box: weight = darkness between the sheet
        // (box border mean) and the blob's darkest level.
        let pad = BLOB_PAD_PX;
        let (x0, y0) = (bx0.saturating_sub(pad), by0.saturating_sub(pad));
        let (x1, y1) = ((bx1 + pad).min(w - 1), (by1 + pad).min(h - 1));
        let mut border = (0.0f64, 0.0f64);
        for y in y0..=y1 {
            for x in x0..=x1 {
                if x == x0 || x == x1 || y == y0 || y == y1 {
                    border.0 += self.gray[y * w + x] as f64;
                    border.1 += 1.0;
                }
            }
        }
        let bg = border.0 / border.1.max(1.0);
        if bg - fg < MIN_RING_CONTRAST {
            return None;
        }
        let (mut ws, mut wx, mut wy) = (0.0, 0.0, 0.0);
        for y in y0..=y1 {
            for x in x0..=x1 {
                let l = self.labels[y * w + x];
                if l != 0 && l != label {
                    continue;
                }
                let wt = ((bg - self.gray[y * w + x] as f64) / (bg - fg)).clamp(0.0, 1.0);
                ws += wt;
                wx += wt * x as f64;
                wy += wt * y as f64;
            }
        }
        (ws > 0.0).then(|| (DVec2::new(wx / ws, wy / ws), n as f32, bg - fg))
    }

    /// The blobs as grid candidates, their grid directions from the nearest neighbours.
    fn blob_candidates(&mut self, blobs: &[(DVec2, f32, f64)]) {
        self.cands.clear();
        let cos_par = NEIGHBOUR_ANGLE_DEG.to_radians().cos();
        self.blob_contrast.clear();
        for (k, (p, area, contrast)) in blobs.iter().enumerate() {
            let mut near: Vec<(f64, DVec2)> = blobs
                .iter()
                .enumerate()
                .filter(|(j, _)| *j != k)
                .map(|(_, (q, _, _))| ((*q - *p).length(), (*q - *p).normalize_or_zero()))
                .collect();
            near.sort_by(|a, b| a.0.total_cmp(&b.0));
            let Some(&(_, dir_a)) = near.first() else {
                continue;
            };
            let Some(&(_, dir_b)) = near
                .iter()
                .skip(1)
                .find(|(_, d)| d.dot(dir_a).abs() < cos_par)
            else {
                continue;
            };
            self.cands.push(Candidate {
                pos: *p,
                response: *area,
                dir_a,
                dir_b,
            });
            self.blob_contrast.push(*contrast);
        }
        self.used.clear();
        self.used.resize(self.cands.len(), false);
    }
}
