//! Chessboard inner-corner detection with sub-pixel refinement.
//!
//! Pipeline (all in pixels, origin at the centre of the top-left pixel, as OpenCV):
//! 1. Saddle response: the grey image smoothed by a Gaussian (sigma = the detection
//!    scale), Hessian by finite differences, response `Ixy² - Ixx Iyy` (= -det H, large
//!    and positive only where the image is a saddle, i.e. an X-junction of four squares;
//!    edges give ~0, blobs give negative). Non-maximum suppression keeps local peaks.
//! 2. Ring test (after the "ChESS" idea of Bennett and Lasenby 2014): grey levels on a
//!    circle around the peak must cross their mid level exactly four times, opposite
//!    crossings must be nearly opposite (straight edges through the corner); the two
//!    crossing lines give the two edge directions.
//! 3. Grid growing (after Geiger et al. 2012, "Automatic camera and range sensor
//!    calibration using a single shot", sec. 3): a seed corner with neighbours along
//!    both edge directions gives a 3x3 grid; whole rows or columns are added while
//!    every predicted corner (quadratic extrapolation along the grid line) has a
//!    candidate nearby, up to the board's size.
//! 4. Sub-pixel refinement as OpenCV's `cornerSubPix` (Förstner 1987): the corner `p`
//!    minimises `sum_q w_q (g_qᵀ (q - p))²` over a window, g_q the image gradient.
//! 5. Numbering resolved physically: the printed side faces the camera, so the image of
//!    the board is never mirrored (columns x rows keep the image's handedness), and rows
//!    run downward. Corners come out in OpenCV's order (row-major, row 0 on top).
//!
//! [`CornerDetector`] keeps its scratch buffers between frames (no per-frame allocation
//! once the image size is fixed).

use super::board::{BoardSpec, Target};
use glam::DVec2;

/// Detection scales (Gaussian sigma, pixels), tried in order until the board is found.
pub const DETECTION_SCALES_PX: [f64; 2] = [1.5, 3.0];
/// Candidates keep responses above this fraction of the image's strongest response.
pub const RESPONSE_FRACTION: f32 = 0.02;
/// Half size of the non-maximum suppression window, pixels.
pub const NMS_RADIUS_PX: isize = 3;
/// Largest number of candidate corners kept per image (strongest first).
pub const MAX_CANDIDATES: usize = 3000;
/// Samples on the ring test circle.
pub const RING_SAMPLES: usize = 36;
/// Smallest grey-level contrast on the ring (0-255 scale).
pub const MIN_RING_CONTRAST: f64 = 12.0;
/// Opposite mid-level crossings must be within this angle of opposite, degrees.
pub const MAX_EDGE_BEND_DEG: f64 = 30.0;
/// Two edge directions must differ by at least this angle, degrees.
pub const MIN_EDGE_ANGLE_DEG: f64 = 15.0;
/// A grid neighbour must lie within this angle of the edge direction, degrees.
pub const NEIGHBOUR_ANGLE_DEG: f64 = 22.0;
/// Prediction tolerance while growing, as a fraction of the local corner spacing.
pub const GROW_TOLERANCE: f64 = 0.3;
/// Seeds tried per scale before giving up.
pub const MAX_SEEDS: usize = 60;
/// Largest half-window of the sub-pixel refinement, pixels (OpenCV's usual 11x11).
pub const MAX_SUBPIX_HALF_WINDOW: i32 = 5;
/// The point-symmetry step may move a corner at most this far, pixels.
pub const SYMMETRY_MAX_SHIFT_PX: f64 = 1.0;
/// Gaussian weight of the point-symmetry window, sigma as a fraction of its half size.
pub const SYMMETRY_WEIGHT_FRACTION: f64 = 0.6;
/// Sub-pixel iterations stop when the corner moves less than this, pixels.
pub const SUBPIX_EPS_PX: f64 = 1e-3;
/// Largest number of sub-pixel iterations.
pub const SUBPIX_MAX_ITER: usize = 40;

/// The board found in one image.
#[derive(Debug, Clone, PartialEq)]
pub struct Detection {
    /// Inner corners in OpenCV's order (`rows` rows of `cols`), pixels.
    pub corners: Vec<DVec2>,
    /// Blur of the board's edges: the Gaussian sigma (pixels) that a sharp step would
    /// need to show the measured ratio of contrast to steepest gradient.
    pub blur_sigma_px: f64,
    /// Median grey-level contrast between black and white squares along the board's
    /// edges (circle grids: between the sheet and the dots, over all dot candidates).
    pub contrast: f64,
    /// Smallest distance between neighbouring corners, pixels.
    pub min_spacing_px: f64,
}

/// Why the board was not found.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum DetectError {
    #[error("image is empty")]
    Empty,
    #[error("board not found ({candidates} corner-like points or dots){}: is the whole board in view, large enough (squares 10 px or more) and evenly lit?", blur_hint(*blur_sigma_px))]
    NotFound {
        candidates: usize,
        blur_sigma_px: Option<f64>,
    },
    #[error("found only {found_cols}x{found_rows} of the board's {cols}x{rows} grid points: the board is partly out of view, covered, or the --board size is wrong{}", blur_hint(*blur_sigma_px))]
    Partial {
        found_cols: usize,
        found_rows: usize,
        cols: usize,
        rows: usize,
        blur_sigma_px: Option<f64>,
    },
}

impl DetectError {
    /// The image's blur estimate when it is above [`super::MAX_BLUR_SIGMA_PX`].
    pub fn blurred(&self) -> Option<f64> {
        match self {
            DetectError::NotFound {
                blur_sigma_px: Some(s),
                ..
            }
            | DetectError::Partial {
                blur_sigma_px: Some(s),
                ..
            } if *s > super::MAX_BLUR_SIGMA_PX => Some(*s),
            _ => None,
        }
    }
}

fn blur_hint(b: Option<f64>) -> String {
    match b {
        Some(s) if s > super::MAX_BLUR_SIGMA_PX => {
            format!("; the image looks blurred (edge sigma ~{s:.1} px)")
        }
        _ => String::new(),
    }
}

/// Blur and contrast measured across one edge.
struct EdgeProfile {
    sigma_px: f64,
    contrast: f64,
}

/// 10-90% rise of a Gaussian-blurred step, in sigmas (2 x 1.2816).
const RISE_10_90_PER_SIGMA: f64 = 2.563;
/// Edge profiles reach this fraction of the corner spacing to either side.
const EDGE_PROFILE_REACH: f64 = 0.45;
/// Circle grids: local-mean window (image size divided by this), how much darker than
/// the local mean a blob pixel is (grey levels), smallest blob area (pixels), largest
/// blob area (image area divided by this), accepted filled-ellipse ratio, and the
/// padding of the weighted centroid box (pixels).
const BLOB_WINDOW_DIVISOR: usize = 12;
const BLOB_DARKER_THAN_MEAN: f64 = 10.0;
const MIN_BLOB_AREA_PX: f64 = 12.0;
const MAX_BLOB_AREA_DIVISOR: f64 = 50.0;
const BLOB_FILL_RANGE: (f64, f64) = (0.8, 1.25);
const BLOB_PAD_PX: usize = 2;
/// Global blur estimate: grid cell (one edge sample per cell), edges used, fewest edges
/// for an answer, and the reach of each profile, pixels.
const GLOBAL_BLUR_CELL_PX: usize = 16;
const GLOBAL_BLUR_EDGES: usize = 200;
const GLOBAL_BLUR_MIN_EDGES: usize = 10;
const GLOBAL_BLUR_REACH_PX: f64 = 10.0;
/// Sample step along an edge profile, pixels.
const EDGE_PROFILE_STEP_PX: f64 = 0.25;

#[derive(Debug, Clone, Copy)]
struct Candidate {
    pos: DVec2,
    response: f32,
    dir_a: DVec2,
    dir_b: DVec2,
}

/// How corners are refined to sub-pixel accuracy.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum SubpixMethod {
    /// OpenCV's `cornerSubPix` (Förstner): gradients orthogonal to `q - p`.
    Forstner,
    /// Förstner, then the point-symmetry refinement (lower bias; the default).
    #[default]
    PointSymmetry,
}

/// Reusable chessboard detector (owns its scratch images).
#[derive(Default)]
pub struct CornerDetector {
    method: SubpixMethod,
    target: Target,
    w: usize,
    h: usize,
    gray: Vec<f32>,
    smooth: Vec<f32>,
    tmp: Vec<f32>,
    resp: Vec<f32>,
    gx: Vec<f32>,
    gy: Vec<f32>,
    cands: Vec<Candidate>,
    used: Vec<bool>,
    /// Circle-grid scratch: integral image, component labels, flood-fill stack.
    integral: Vec<f64>,
    labels: Vec<u32>,
    /// Sheet-to-dot contrast of each circle candidate (parallel to `cands`).
    blob_contrast: Vec<f64>,
    stack: Vec<usize>,
}

/// Grid under construction: `idx[j][i]` are candidate indices.
struct Grid {
    idx: Vec<Vec<usize>>,
}

impl Grid {
    fn ni(&self) -> usize {
        self.idx.first().map_or(0, |r| r.len())
    }
    fn nj(&self) -> usize {
        self.idx.len()
    }
}

impl CornerDetector {
    pub fn new() -> Self {
        Self::default()
    }

    /// A detector for the given target (chessboard or circle grid).
    pub fn for_target(target: Target) -> Self {
        CornerDetector {
            target,
            ..Self::default()
        }
    }

    /// A detector with the given sub-pixel method.
    pub fn with_method(method: SubpixMethod) -> Self {
        CornerDetector {
            method,
            ..Self::default()
        }
    }

    /// Finds the target's grid points (chessboard inner corners or circle centres,
    /// as chosen by [`CornerDetector::for_target`]) in a grey image, in OpenCV's order.
    ///
    /// # Errors
    /// [`DetectError`] when no complete board is found.
    pub fn detect(
        &mut self,
        image: &image::GrayImage,
        board: &BoardSpec,
    ) -> Result<Detection, DetectError> {
        match self.target {
            Target::Chessboard => self.detect_chessboard(image, board),
            Target::Circles => self.detect_circles(image, board),
        }
    }

    /// Finds the board's inner corners in a grey image.
    ///
    /// # Errors
    /// [`DetectError`] when no complete board is found (with the largest partial grid
    /// or a blur estimate to tell the operator what to change).
    pub fn detect_chessboard(
        &mut self,
        image: &image::GrayImage,
        board: &BoardSpec,
    ) -> Result<Detection, DetectError> {
        self.load(image)?;
        let mut best_partial: Option<(usize, usize)> = None;
        let mut candidates = 0;
        for &scale in &DETECTION_SCALES_PX {
            self.find_candidates(scale);
            candidates = candidates.max(self.cands.len());
            match self.grow_board(board) {
                Ok(points) => return Ok(self.finish(points, board)),
                Err(Some(partial)) => {
                    if best_partial.is_none_or(|b| b.0 * b.1 < partial.0 * partial.1) {
                        best_partial = Some(partial);
                    }
                }
                Err(None) => {}
            }
        }
        match best_partial {
            Some((a, b)) if a * b >= 6 => {
                let (found_cols, found_rows) = if board.cols >= board.rows {
                    (a.max(b), a.min(b))
                } else {
                    (a.min(b), a.max(b))
                };
                Err(DetectError::Partial {
                    found_cols,
                    found_rows,
                    cols: board.cols,
                    rows: board.rows,
                    blur_sigma_px: self.global_blur_estimate(),
                })
            }
            _ => Err(DetectError::NotFound {
                candidates,
                blur_sigma_px: self.global_blur_estimate(),
            }),
        }
    }

    /// Finds a symmetric grid of dark circles (`board.cols x board.rows` centres,
    /// `board.square_m` apart) on a light sheet: dark blobs against the local mean
    /// (integral image), connected components kept when their second moments describe
    /// a filled ellipse, sub-pixel centres as grey-level-weighted centroids (unbiased
    /// for any symmetric blur of an ellipse), then the same grid growing and physical
    /// numbering as the chessboard. The image of a circle's centre is not the centre of
    /// its image ellipse under perspective; that shift (median 0.06 px over boards tilted
    /// 18-40 degrees in the tests) is shared with OpenCV's `findCirclesGrid`, and the
    /// calibration absorbs part of it. A chessboard has no
    /// such bias and stays the default.
    ///
    /// # Errors
    /// As [`CornerDetector::detect`].
    pub fn detect_circles(
        &mut self,
        image: &image::GrayImage,
        board: &BoardSpec,
    ) -> Result<Detection, DetectError> {
        self.load(image)?;
        blur_f32(
            &self.gray,
            &mut self.smooth,
            &mut self.tmp,
            self.w,
            self.h,
            DETECTION_SCALES_PX[0],
        );
        self.find_blobs();
        match self.grow_board(board) {
            Ok(points) => {
                let mut min_spacing = f64::INFINITY;
                for (i, a) in points.iter().enumerate() {
                    for b in &points[i + 1..] {
                        min_spacing = min_spacing.min((*a - *b).length());
                    }
                }
                Ok(Detection {
                    corners: points,
                    blur_sigma_px: self.global_blur_estimate().unwrap_or(0.0),
                    contrast: {
                        let mut c = self.blob_contrast.clone();
                        median(&mut c).unwrap_or(0.0)
                    },
                    min_spacing_px: min_spacing,
                })
            }
            Err(Some((a, b))) if a * b >= 6 => {
                let (found_cols, found_rows) = if board.cols >= board.rows {
                    (a.max(b), a.min(b))
                } else {
                    (a.min(b), a.max(b))
                };
                Err(DetectError::Partial {
                    found_cols,
                    found_rows,
                    cols: board.cols,
                    rows: board.rows,
                    blur_sigma_px: self.global_blur_estimate(),
                })
            }
            Err(_) => Err(DetectError::NotFound {
                candidates: self.cands.len(),
                blur_sigma_px: self.global_blur_estimate(),
            }),
        }
    }

    /// Dark elliptical blobs as grid candidates (directions from nearest neighbours).
    fn find_blobs(&mut self) {
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
        let r = (w.max(h) / BLOB_WINDOW_DIVISOR).max(4);
        self.labels.clear();
        self.labels.resize(w * h, 0);
        let dark = |s: &Self, x: usize, y: usize| -> bool {
            let (x0, x1) = (x.saturating_sub(r), (x + r + 1).min(w));
            let (y0, y1) = (y.saturating_sub(r), (y + r + 1).min(h));
            let sum =
                s.integral[y1 * iw + x1] - s.integral[y0 * iw + x1] - s.integral[y1 * iw + x0]
                    + s.integral[y0 * iw + x0];
            let mean = sum / ((x1 - x0) * (y1 - y0)) as f64;
            (s.gray[y * w + x] as f64) < mean - BLOB_DARKER_THAN_MEAN
        };
        let mut blobs: Vec<(DVec2, f32, f64)> = Vec::new();
        let mut next_label = 0u32;
        for start in 0..w * h {
            if self.labels[start] != 0 || !dark(self, start % w, start / w) {
                continue;
            }
            next_label += 1;
            let label = next_label;
            self.labels[start] = label;
            self.stack.clear();
            self.stack.push(start);
            let (mut n, mut sx, mut sy, mut sxx, mut sxy, mut syy) =
                (0.0f64, 0.0, 0.0, 0.0, 0.0, 0.0);
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
                    if s.labels[j] == 0 && dark(s, j % w, j / w) {
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
            if touches_border || n < MIN_BLOB_AREA_PX || n > (w * h) as f64 / MAX_BLOB_AREA_DIVISOR
            {
                continue;
            }
            let (mx, my) = (sx / n, sy / n);
            let (cxx, cxy, cyy) = (sxx / n - mx * mx, sxy / n - mx * my, syy / n - my * my);
            // A filled ellipse of area A has det(cov) = (A / 4 pi)^2.
            let det = (cxx * cyy - cxy * cxy).max(0.0);
            let fill = n / (4.0 * std::f64::consts::PI * det.sqrt()).max(1e-9);
            if !(BLOB_FILL_RANGE.0..BLOB_FILL_RANGE.1).contains(&fill) {
                continue;
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
                continue;
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
            if ws > 0.0 {
                blobs.push((DVec2::new(wx / ws, wy / ws), n as f32, bg - fg));
            }
        }
        // Grid directions from the nearest neighbours.
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

    fn load(&mut self, image: &image::GrayImage) -> Result<(), DetectError> {
        let (w, h) = (image.width() as usize, image.height() as usize);
        if w < 16 || h < 16 {
            return Err(DetectError::Empty);
        }
        self.w = w;
        self.h = h;
        let n = w * h;
        for buf in [
            &mut self.gray,
            &mut self.smooth,
            &mut self.tmp,
            &mut self.resp,
            &mut self.gx,
            &mut self.gy,
        ] {
            buf.resize(n, 0.0);
        }
        for (d, p) in self.gray.iter_mut().zip(image.as_raw()) {
            *d = *p as f32;
        }
        // Raw central-difference gradients for the sub-pixel step.
        for y in 0..h {
            for x in 0..w {
                let xm = x.saturating_sub(1);
                let xp = (x + 1).min(w - 1);
                let ym = y.saturating_sub(1);
                let yp = (y + 1).min(h - 1);
                self.gx[y * w + x] = 0.5 * (self.gray[y * w + xp] - self.gray[y * w + xm]);
                self.gy[y * w + x] = 0.5 * (self.gray[yp * w + x] - self.gray[ym * w + x]);
            }
        }
        Ok(())
    }

    /// Step 1 and 2: saddle peaks that pass the ring test, refined to sub-pixel.
    fn find_candidates(&mut self, sigma: f64) {
        let (w, h) = (self.w, self.h);
        blur_f32(&self.gray, &mut self.smooth, &mut self.tmp, w, h, sigma);
        let s = &self.smooth;
        let mut max_r = 0.0f32;
        for y in 1..h - 1 {
            for x in 1..w - 1 {
                let i = y * w + x;
                let ixx = s[i + 1] - 2.0 * s[i] + s[i - 1];
                let iyy = s[i + w] - 2.0 * s[i] + s[i - w];
                let ixy = 0.25 * (s[i + w + 1] - s[i + w - 1] - s[i - w + 1] + s[i - w - 1]);
                let r = (ixy * ixy - ixx * iyy).max(0.0);
                self.resp[i] = r;
                max_r = max_r.max(r);
            }
        }
        for x in 0..w {
            self.resp[x] = 0.0;
            self.resp[(h - 1) * w + x] = 0.0;
        }
        for y in 0..h {
            self.resp[y * w] = 0.0;
            self.resp[y * w + w - 1] = 0.0;
        }
        let thr = max_r * RESPONSE_FRACTION;
        let ring_r = (2.5 * sigma).max(3.5);
        let border = (ring_r.ceil() as usize + 2).max(NMS_RADIUS_PX as usize + 1);
        let mut peaks: Vec<(f32, usize, usize)> = Vec::new();
        if max_r > 0.0 && w > 2 * border && h > 2 * border {
            for y in border..h - border {
                for x in border..w - border {
                    let r = self.resp[y * w + x];
                    if r <= thr {
                        continue;
                    }
                    let mut is_max = true;
                    'win: for dy in -NMS_RADIUS_PX..=NMS_RADIUS_PX {
                        for dx in -NMS_RADIUS_PX..=NMS_RADIUS_PX {
                            if dx == 0 && dy == 0 {
                                continue;
                            }
                            let j = ((y as isize + dy) as usize) * w + (x as isize + dx) as usize;
                            let o = self.resp[j];
                            // Ties broken by index so that plateaus keep one peak.
                            if o > r || (o == r && j < y * w + x) {
                                is_max = false;
                                break 'win;
                            }
                        }
                    }
                    if is_max {
                        peaks.push((r, x, y));
                    }
                }
            }
        }
        peaks.sort_by(|a, b| b.0.total_cmp(&a.0));
        peaks.truncate(MAX_CANDIDATES);
        self.cands.clear();
        for (r, x, y) in peaks {
            let p0 = DVec2::new(x as f64, y as f64);
            // The cheap ring test first; sub-pixel refinement only for survivors.
            let Some((dir_a, dir_b)) = self.ring_test(p0, ring_r) else {
                continue;
            };
            let half = (2.0 * sigma)
                .round()
                .clamp(2.0, MAX_SUBPIX_HALF_WINDOW as f64) as i32;
            let Some(p) = self.subpix(p0, half) else {
                continue;
            };
            if (p - p0).length() > 2.0 * sigma.max(1.0) {
                continue;
            }
            self.cands.push(Candidate {
                pos: p,
                response: r,
                dir_a,
                dir_b,
            });
        }
        self.used.clear();
        self.used.resize(self.cands.len(), false);
    }

    /// Ring test on the smoothed image; returns the two edge directions.
    fn ring_test(&self, p: DVec2, radius: f64) -> Option<(DVec2, DVec2)> {
        let mut vals = [0.0f64; RING_SAMPLES];
        let step = std::f64::consts::TAU / RING_SAMPLES as f64;
        for (k, v) in vals.iter_mut().enumerate() {
            let a = k as f64 * step;
            *v = sample(
                &self.smooth,
                self.w,
                self.h,
                p + DVec2::new(a.cos(), a.sin()) * radius,
            )?;
        }
        let lo = vals.iter().copied().fold(f64::INFINITY, f64::min);
        let hi = vals.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        if hi - lo < MIN_RING_CONTRAST {
            return None;
        }
        let mid = 0.5 * (lo + hi);
        let mut crossings = [0.0f64; 4];
        let mut n = 0;
        let mut last_cross = None;
        let mut shortest_run = usize::MAX;
        for k in 0..RING_SAMPLES {
            let (a, b) = (vals[k], vals[(k + 1) % RING_SAMPLES]);
            if (a > mid) != (b > mid) {
                if n == 4 {
                    return None;
                }
                let f = (mid - a) / (b - a);
                crossings[n] = (k as f64 + f) * step;
                if let Some(l) = last_cross {
                    shortest_run = shortest_run.min(k - l);
                }
                last_cross = Some(k);
                n += 1;
            }
        }
        if n != 4 {
            return None;
        }
        // The wrap-around run.
        if let Some(l) = last_cross {
            let first = (crossings[0] / step).floor() as usize;
            shortest_run = shortest_run.min(first + RING_SAMPLES - l);
        }
        if shortest_run < 2 {
            return None;
        }
        let unit = |a: f64| DVec2::new(a.cos(), a.sin());
        let bend = MAX_EDGE_BEND_DEG.to_radians().cos();
        if unit(crossings[0]).dot(unit(crossings[2])) > -bend
            || unit(crossings[1]).dot(unit(crossings[3])) > -bend
        {
            return None;
        }
        let dir_a = (unit(crossings[0]) - unit(crossings[2])).normalize_or_zero();
        let dir_b = (unit(crossings[1]) - unit(crossings[3])).normalize_or_zero();
        if dir_a.dot(dir_b).abs() > MIN_EDGE_ANGLE_DEG.to_radians().cos() {
            return None;
        }
        Some((dir_a, dir_b))
    }

    /// Step 4: Förstner / cornerSubPix iteration with a Gaussian window of half size
    /// `half` pixels. None when the system is singular (a flat patch).
    fn subpix(&self, start: DVec2, half: i32) -> Option<DVec2> {
        let mut c = start;
        let inv_w2 = 1.0 / (half as f64 * half as f64);
        for _ in 0..SUBPIX_MAX_ITER {
            let (mut a11, mut a12, mut a22, mut b1, mut b2) = (0.0, 0.0, 0.0, 0.0, 0.0);
            for dy in -half..=half {
                for dx in -half..=half {
                    let q = c + DVec2::new(dx as f64, dy as f64);
                    let gx = sample(&self.gx, self.w, self.h, q)?;
                    let gy = sample(&self.gy, self.w, self.h, q)?;
                    let wgt = (-((dx * dx + dy * dy) as f64) * inv_w2).exp();
                    let (xx, xy, yy) = (gx * gx * wgt, gx * gy * wgt, gy * gy * wgt);
                    a11 += xx;
                    a12 += xy;
                    a22 += yy;
                    b1 += xx * q.x + xy * q.y;
                    b2 += xy * q.x + yy * q.y;
                }
            }
            let det = a11 * a22 - a12 * a12;
            if det.abs() < 1e-9 * (a11 + a22).powi(2).max(1e-300) {
                return None;
            }
            let next = DVec2::new((a22 * b1 - a12 * b2) / det, (a11 * b2 - a12 * b1) / det);
            let moved = (next - c).length();
            c = next;
            if moved < SUBPIX_EPS_PX {
                break;
            }
        }
        if (c - start).length() > half as f64 + 1.0 {
            return None;
        }
        Some(c)
    }

    /// Step 4b: point-symmetry refinement. Around an inner corner the board is
    /// symmetric under a half turn (exactly for the two edge lines through the corner,
    /// to first order for the neighbouring squares), and any isotropic blur keeps that
    /// symmetry, so the corner minimises `sum_d w_d (S(p + d) - S(p - d))²` over the
    /// smoothed image S (Gauss-Newton). Bilinear interpolation errors at p + d and p - d
    /// have mirrored phases and cancel to second order, which removes most of the
    /// sampling bias left by the gradient method.
    fn symmetric_refine(&self, start: DVec2, half: i32) -> Option<DVec2> {
        let (w, h) = (self.w, self.h);
        let s = |q: DVec2| sample(&self.smooth, w, h, q);
        let grad = |q: DVec2| -> Option<DVec2> {
            Some(DVec2::new(
                s(q + DVec2::new(0.5, 0.0))? - s(q - DVec2::new(0.5, 0.0))?,
                s(q + DVec2::new(0.0, 0.5))? - s(q - DVec2::new(0.0, 0.5))?,
            ))
        };
        let sigma_w = SYMMETRY_WEIGHT_FRACTION * half as f64;
        let inv_2s2 = 1.0 / (2.0 * sigma_w * sigma_w);
        let r2_max = (half * half) as f64;
        let mut p = start;
        for _ in 0..SUBPIX_MAX_ITER {
            let (mut a11, mut a12, mut a22, mut b1, mut b2) = (0.0, 0.0, 0.0, 0.0, 0.0);
            for dy in 0..=half {
                for dx in -half..=half {
                    if (dy == 0 && dx <= 0) || ((dx * dx + dy * dy) as f64) > r2_max {
                        continue;
                    }
                    let d = DVec2::new(dx as f64, dy as f64);
                    let wgt = (-d.length_squared() * inv_2s2).exp();
                    let r = s(p + d)? - s(p - d)?;
                    let g = grad(p + d)? - grad(p - d)?;
                    a11 += wgt * g.x * g.x;
                    a12 += wgt * g.x * g.y;
                    a22 += wgt * g.y * g.y;
                    b1 += wgt * g.x * r;
                    b2 += wgt * g.y * r;
                }
            }
            let det = a11 * a22 - a12 * a12;
            if det.abs() < 1e-12 * (a11 + a22).powi(2).max(1e-300) {
                return None;
            }
            let step = DVec2::new(-(a22 * b1 - a12 * b2) / det, -(a11 * b2 - a12 * b1) / det);
            p += step;
            if step.length() < SUBPIX_EPS_PX {
                break;
            }
        }
        p.is_finite().then_some(p)
    }

    /// Step 3: tries seeds until a full board grows; Err(Some(dims)) gives the largest
    /// partial grid.
    fn grow_board(&mut self, board: &BoardSpec) -> Result<Vec<DVec2>, Option<(usize, usize)>> {
        let mut order: Vec<usize> = (0..self.cands.len()).collect();
        order.sort_by(|&a, &b| self.cands[b].response.total_cmp(&self.cands[a].response));
        let mut best: Option<(usize, usize)> = None;
        let mut tried = 0;
        for &seed in &order {
            if tried >= MAX_SEEDS {
                break;
            }
            if self.used[seed] {
                continue;
            }
            let Some(mut grid) = self.seed_grid(seed) else {
                continue;
            };
            tried += 1;
            self.grow(&mut grid, board);
            let dims = (grid.ni(), grid.nj());
            if (dims.0 == board.cols && dims.1 == board.rows)
                || (dims.0 == board.rows && dims.1 == board.cols)
            {
                if !self.continues_beyond(&grid) {
                    return Ok(self.orient(&grid, board));
                }
            } else if best.is_none_or(|b| b.0 * b.1 < dims.0 * dims.1) {
                best = Some(dims);
            }
            // Corners of a failed grid may seed again only if it was small.
            if dims.0 * dims.1 > 9 {
                for row in &grid.idx {
                    for &k in row {
                        self.used[k] = true;
                    }
                }
            }
        }
        Err(best)
    }

    /// Nearest unused candidate to `p` within `tol` (excluding `skip`).
    fn nearest(&self, p: DVec2, tol: f64, skip: &[usize]) -> Option<usize> {
        let mut best = None;
        let mut best_d = tol * tol;
        for (k, c) in self.cands.iter().enumerate() {
            if self.used[k] || skip.contains(&k) {
                continue;
            }
            let d = (c.pos - p).length_squared();
            if d < best_d {
                best_d = d;
                best = Some(k);
            }
        }
        best
    }

    /// Nearest candidate from `from` in direction `dir` (within the neighbour angle).
    fn neighbour_along(&self, from: usize, dir: DVec2) -> Option<(usize, f64)> {
        let p = self.cands[from].pos;
        let cos_max = NEIGHBOUR_ANGLE_DEG.to_radians().cos();
        let mut best: Option<(usize, f64)> = None;
        for (k, c) in self.cands.iter().enumerate() {
            if k == from || self.used[k] {
                continue;
            }
            let d = c.pos - p;
            let len = d.length();
            if len < 2.0 || d.dot(dir) < cos_max * len {
                continue;
            }
            // The neighbour's own edges must run along ours.
            let para = |u: DVec2| u.dot(dir).abs() > cos_max;
            if !(para(c.dir_a) || para(c.dir_b)) {
                continue;
            }
            if best.is_none_or(|b| len < b.1) {
                best = Some((k, len));
            }
        }
        best
    }

    fn seed_grid(&self, seed: usize) -> Option<Grid> {
        let c = self.cands[seed];
        let (pa, da) = self.neighbour_along(seed, c.dir_a)?;
        let (ma, dma) = self.neighbour_along(seed, -c.dir_a)?;
        let (pb, db) = self.neighbour_along(seed, c.dir_b)?;
        let (mb, dmb) = self.neighbour_along(seed, -c.dir_b)?;
        let ratio_ok = |x: f64, y: f64| x / y < 1.6 && y / x < 1.6;
        if !ratio_ok(da, dma) || !ratio_ok(db, dmb) {
            return None;
        }
        let p = |k: usize| self.cands[k].pos;
        let tol = GROW_TOLERANCE * da.min(dma).min(db).min(dmb);
        let mut taken = vec![seed, pa, ma, pb, mb];
        let mut diag = |a: usize, b: usize| -> Option<usize> {
            let k = self.nearest(p(a) + p(b) - c.pos, tol, &taken)?;
            taken.push(k);
            Some(k)
        };
        let mm = diag(ma, mb)?;
        let pm = diag(pa, mb)?;
        let mp = diag(ma, pb)?;
        let pp = diag(pa, pb)?;
        Some(Grid {
            idx: vec![vec![mm, mb, pm], vec![ma, seed, pa], vec![mp, pb, pp]],
        })
    }

    fn grow(&mut self, grid: &mut Grid, board: &BoardSpec) {
        let fits = |ni: usize, nj: usize| {
            (ni <= board.cols && nj <= board.rows) || (ni <= board.rows && nj <= board.cols)
        };
        for row in &grid.idx {
            for &k in row {
                self.used[k] = true;
            }
        }
        loop {
            let mut grown = false;
            for side in 0..4 {
                let (ni, nj) = (grid.ni(), grid.nj());
                let ok = if side < 2 {
                    fits(ni + 1, nj)
                } else {
                    fits(ni, nj + 1)
                };
                if ok && self.extend(grid, side) {
                    grown = true;
                }
            }
            if !grown {
                break;
            }
        }
    }

    /// Adds one column (side 0 right, 1 left) or row (2 bottom, 3 top) if every corner of
    /// it is found.
    fn extend(&mut self, grid: &mut Grid, side: usize) -> bool {
        let preds = self.predict_line(grid, side);
        let mut new = Vec::with_capacity(preds.len());
        for (pred, tol) in preds {
            match self.nearest(pred, tol, &new) {
                Some(c) => new.push(c),
                None => return false,
            }
        }
        for &c in &new {
            self.used[c] = true;
        }
        match side {
            0 => grid
                .idx
                .iter_mut()
                .zip(&new)
                .for_each(|(row, &c)| row.push(c)),
            1 => grid
                .idx
                .iter_mut()
                .zip(&new)
                .for_each(|(row, &c)| row.insert(0, c)),
            2 => grid.idx.push(new),
            _ => grid.idx.insert(0, new),
        }
        true
    }

    /// Predicted positions (and tolerances) of the corners one line beyond side `side`
    /// (0 right, 1 left, 2 bottom, 3 top): quadratic extrapolation along each grid line.
    fn predict_line(&self, grid: &Grid, side: usize) -> Vec<(DVec2, f64)> {
        let (ni, nj) = (grid.ni(), grid.nj());
        let line_len = if side < 2 { nj } else { ni };
        let pts = |k: usize, depth: usize| -> DVec2 {
            let idx = match side {
                0 => grid.idx[k][ni - 1 - depth],
                1 => grid.idx[k][depth],
                2 => grid.idx[nj - 1 - depth][k],
                _ => grid.idx[depth][k],
            };
            self.cands[idx].pos
        };
        (0..line_len)
            .map(|k| {
                let (p1, p2, p3) = (pts(k, 0), pts(k, 1), pts(k, 2));
                (
                    p1 * 3.0 - p2 * 3.0 + p3,
                    GROW_TOLERANCE * (p1 - p2).length(),
                )
            })
            .collect()
    }

    /// True when saddle points continue the grid past one of its borders: then it is a
    /// piece of a larger pattern (a tiled floor, a patterned shirt), not the board, whose
    /// corners are surrounded by its white margin.
    fn continues_beyond(&self, grid: &Grid) -> bool {
        (0..4).any(|side| {
            let preds = self.predict_line(grid, side);
            let hits = preds
                .iter()
                .filter(|(p, tol)| {
                    self.cands
                        .iter()
                        .any(|c| (c.pos - *p).length_squared() < tol * tol)
                })
                .count();
            2 * hits > preds.len()
        })
    }

    /// Step 5: numbers the grid as the physical board (not mirrored, rows downward) and
    /// returns the positions in OpenCV's order.
    fn orient(&self, grid: &Grid, board: &BoardSpec) -> Vec<DVec2> {
        let (ni, nj) = (grid.ni(), grid.nj());
        let at = |i: usize, j: usize| self.cands[grid.idx[j][i]].pos;
        let mut best: Option<(f64, Vec<DVec2>)> = None;
        for transpose in [false, true] {
            let (cols, rows) = if transpose { (nj, ni) } else { (ni, nj) };
            if cols != board.cols || rows != board.rows {
                continue;
            }
            for flip in 0..4 {
                let get = |c: usize, r: usize| {
                    let c = if flip & 1 == 1 { cols - 1 - c } else { c };
                    let r = if flip & 2 == 2 { rows - 1 - r } else { r };
                    if transpose {
                        at(r, c)
                    } else {
                        at(c, r)
                    }
                };
                let col_dir =
                    get(cols - 1, 0) - get(0, 0) + get(cols - 1, rows - 1) - get(0, rows - 1);
                let row_dir =
                    get(0, rows - 1) - get(0, 0) + get(cols - 1, rows - 1) - get(cols - 1, 0);
                let cross = col_dir.x * row_dir.y - col_dir.y * row_dir.x;
                if cross <= 0.0 {
                    continue; // mirrored: the printed side would face away
                }
                let down = row_dir.normalize_or_zero().y;
                if best.as_ref().is_none_or(|b| down > b.0) {
                    let pts = (0..rows)
                        .flat_map(|r| (0..cols).map(move |c| (c, r)))
                        .map(|(c, r)| get(c, r))
                        .collect();
                    best = Some((down, pts));
                }
            }
        }
        best.map(|b| b.1).unwrap_or_default()
    }

    /// Final sub-pixel refinement with a window fitted to the local spacing, plus the
    /// blur and contrast measures.
    fn finish(&self, mut points: Vec<DVec2>, board: &BoardSpec) -> Detection {
        let n = points.len();
        let mut min_spacing = f64::INFINITY;
        let mut nearest = vec![f64::INFINITY; n];
        for i in 0..n {
            for j in 0..n {
                if i != j {
                    let d = (points[i] - points[j]).length();
                    nearest[i] = nearest[i].min(d);
                }
            }
            min_spacing = min_spacing.min(nearest[i]);
        }
        for (p, near) in points.iter_mut().zip(&nearest) {
            let half = ((0.4 * near).floor() as i32).clamp(2, MAX_SUBPIX_HALF_WINDOW);
            if let Some(q) = self.subpix(*p, half) {
                if (q - *p).length() < 0.5 * near {
                    *p = q;
                }
            }
            if self.method == SubpixMethod::PointSymmetry {
                if let Some(q) = self.symmetric_refine(*p, half) {
                    if (q - *p).length() < SYMMETRY_MAX_SHIFT_PX {
                        *p = q;
                    }
                }
            }
        }
        // Blur and contrast from profiles across the edges between row neighbours.
        let mut blurs = Vec::new();
        let mut contrasts = Vec::new();
        for r in 0..board.rows {
            for c in 0..board.cols.saturating_sub(1) {
                let (Some(a), Some(b)) = (
                    points.get(r * board.cols + c),
                    points.get(r * board.cols + c + 1),
                ) else {
                    continue;
                };
                if let Some(e) = self.edge_profile(*a, *b) {
                    blurs.push(e.sigma_px);
                    contrasts.push(e.contrast);
                }
            }
        }
        Detection {
            corners: points,
            blur_sigma_px: median(&mut blurs).unwrap_or(0.0),
            contrast: median(&mut contrasts).unwrap_or(0.0),
            min_spacing_px: min_spacing,
        }
    }

    /// Blur across the edge between two neighbouring corners `a` and `b`: the raw grey
    /// profile perpendicular to the edge at its midpoint (averaged over a short strip
    /// along the edge), its plateaus, and the 10-90% rise width; a Gaussian-blurred step
    /// rises 10-90% over 2.563 sigma.
    fn edge_profile(&self, a: DVec2, b: DVec2) -> Option<EdgeProfile> {
        let along = b - a;
        let len = along.length();
        if len < 6.0 {
            return None;
        }
        let t = along / len;
        self.profile_across(
            DVec2::new(-t.y, t.x),
            (a + b) * 0.5,
            EDGE_PROFILE_REACH * len,
        )
    }

    /// The 10-90% measure on the profile through `mid` along unit `n`, `half_len` pixels
    /// to either side.
    fn profile_across(&self, n: DVec2, mid: DVec2, half_len: f64) -> Option<EdgeProfile> {
        let t = DVec2::new(n.y, -n.x);
        let steps = (2.0 * half_len / EDGE_PROFILE_STEP_PX).ceil() as usize;
        let mut prof = Vec::with_capacity(steps + 1);
        for k in 0..=steps {
            let off = -half_len + k as f64 * EDGE_PROFILE_STEP_PX;
            let mut v = 0.0;
            for s in [-1.0, 0.0, 1.0] {
                v += sample(&self.gray, self.w, self.h, mid + n * off + t * s)?;
            }
            prof.push(v / 3.0);
        }
        let m = (prof.len() / 6).max(1);
        let start = prof[..m].iter().sum::<f64>() / m as f64;
        let end = prof[prof.len() - m..].iter().sum::<f64>() / m as f64;
        let contrast = (end - start).abs();
        if contrast < MIN_RING_CONTRAST {
            return None;
        }
        // Orient the profile to rise, then find the 10% and 90% crossings.
        let rising: Vec<f64> = if end > start {
            prof
        } else {
            prof.iter().map(|v| -v).collect()
        };
        let (base, top) = if end > start {
            (start, end)
        } else {
            (-start, -end)
        };
        let crossing = |level: f64| -> Option<f64> {
            let thr = base + level * (top - base);
            rising
                .windows(2)
                .position(|w| w[0] < thr && w[1] >= thr)
                .map(|i| {
                    let f = (thr - rising[i]) / (rising[i + 1] - rising[i]);
                    (i as f64 + f) * EDGE_PROFILE_STEP_PX
                })
        };
        let width = crossing(0.9)? - crossing(0.1)?;
        Some(EdgeProfile {
            sigma_px: width.max(0.0) / RISE_10_90_PER_SIGMA,
            contrast,
        })
    }

    /// Blur of the whole image when no board was found: the 10-90% edge measure on the
    /// strongest edges anywhere (gradient peaks of the smoothed image, at most one per
    /// cell of a coarse grid), median over those with enough contrast.
    fn global_blur_estimate(&self) -> Option<f64> {
        let (w, h) = (self.w, self.h);
        if w < 3 * GLOBAL_BLUR_CELL_PX || h < 3 * GLOBAL_BLUR_CELL_PX {
            return None;
        }
        let s = &self.smooth;
        let mut picks: Vec<(f32, usize, usize)> = Vec::new();
        for cy in (GLOBAL_BLUR_CELL_PX..h - GLOBAL_BLUR_CELL_PX).step_by(GLOBAL_BLUR_CELL_PX) {
            for cx in (GLOBAL_BLUR_CELL_PX..w - GLOBAL_BLUR_CELL_PX).step_by(GLOBAL_BLUR_CELL_PX) {
                let mut best = (0.0f32, 0, 0);
                for y in cy..cy + GLOBAL_BLUR_CELL_PX {
                    for x in cx..cx + GLOBAL_BLUR_CELL_PX {
                        let i = y * w + x;
                        let gx = s[i + 1] - s[i - 1];
                        let gy = s[i + w] - s[i - w];
                        let g = gx * gx + gy * gy;
                        if g > best.0 {
                            best = (g, x, y);
                        }
                    }
                }
                picks.push(best);
            }
        }
        picks.sort_by(|a, b| b.0.total_cmp(&a.0));
        picks.truncate(GLOBAL_BLUR_EDGES);
        let mut sigmas = Vec::new();
        for (g, x, y) in picks {
            if g <= 0.0 {
                continue;
            }
            let i = y * w + x;
            let n = DVec2::new((s[i + 1] - s[i - 1]) as f64, (s[i + w] - s[i - w]) as f64)
                .normalize_or_zero();
            if let Some(e) =
                self.profile_across(n, DVec2::new(x as f64, y as f64), GLOBAL_BLUR_REACH_PX)
            {
                sigmas.push(e.sigma_px);
            }
        }
        if sigmas.len() < GLOBAL_BLUR_MIN_EDGES {
            return None;
        }
        median(&mut sigmas)
    }
}

/// Median of a slice (reorders it).
pub fn median(v: &mut [f64]) -> Option<f64> {
    if v.is_empty() {
        return None;
    }
    v.sort_by(|a, b| a.total_cmp(b));
    let n = v.len();
    Some(if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    })
}

/// Bilinear sample; None outside the image.
#[inline]
fn sample(img: &[f32], w: usize, h: usize, p: DVec2) -> Option<f64> {
    if !(p.x >= 0.0 && p.y >= 0.0 && p.x <= (w - 1) as f64 && p.y <= (h - 1) as f64) {
        return None;
    }
    let x0 = (p.x.floor() as usize).min(w - 2);
    let y0 = (p.y.floor() as usize).min(h - 2);
    let fx = p.x - x0 as f64;
    let fy = p.y - y0 as f64;
    let i = y0 * w + x0;
    let v00 = img[i] as f64;
    let v10 = img[i + 1] as f64;
    let v01 = img[i + w] as f64;
    let v11 = img[i + w + 1] as f64;
    Some(
        v00 * (1.0 - fx) * (1.0 - fy)
            + v10 * fx * (1.0 - fy)
            + v01 * (1.0 - fx) * fy
            + v11 * fx * fy,
    )
}

/// Separable Gaussian blur `src -> dst` (`tmp` is scratch), clamped borders.
fn blur_f32(src: &[f32], dst: &mut [f32], tmp: &mut [f32], w: usize, h: usize, sigma: f64) {
    let radius = (3.0 * sigma).ceil() as isize;
    let kernel: Vec<f32> = (-radius..=radius)
        .map(|k| (-(k * k) as f64 / (2.0 * sigma * sigma)).exp() as f32)
        .collect();
    let norm: f32 = kernel.iter().sum();
    let kernel: Vec<f32> = kernel.iter().map(|k| k / norm).collect();
    let r = radius as usize;
    for y in 0..h {
        let row = &src[y * w..(y + 1) * w];
        let out = &mut tmp[y * w..(y + 1) * w];
        for (x, o) in out.iter_mut().enumerate() {
            let mut s = 0.0;
            if x >= r && x + r < w {
                for (kv, v) in kernel.iter().zip(&row[x - r..=x + r]) {
                    s += kv * v;
                }
            } else {
                for (k, kv) in kernel.iter().enumerate() {
                    let xx = (x as isize + k as isize - radius).clamp(0, w as isize - 1) as usize;
                    s += kv * row[xx];
                }
            }
            *o = s;
        }
    }
    dst.iter_mut().for_each(|v| *v = 0.0);
    for y in 0..h {
        let out = &mut dst[y * w..(y + 1) * w];
        for (k, kv) in kernel.iter().enumerate() {
            let yy = (y as isize + k as isize - radius).clamp(0, h as isize - 1) as usize;
            let src_row = &tmp[yy * w..(yy + 1) * w];
            for (o, v) in out.iter_mut().zip(src_row) {
                *o += kv * v;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::render::{true_corners, Background, BoardRenderer, RenderOptions};
    use super::*;
    use crate::camera::{Intrinsics, Rigid};
    use glam::{DMat3, DVec3};

    fn small_camera() -> Intrinsics {
        Intrinsics {
            width: 480,
            height: 360,
            fx: 420.0,
            fy: 420.0,
            cx: 241.0,
            cy: 178.0,
            dist: [-0.1, 0.02, 0.0, 0.0, 0.0],
        }
    }

    fn render(board: &BoardSpec, pose: &Rigid) -> image::GrayImage {
        BoardRenderer::new(small_camera()).render(
            board,
            pose,
            Background::Wall,
            &RenderOptions::default(),
        )
    }

    fn pose(tilt_deg: f64, spin_deg: f64, board: &BoardSpec) -> Rigid {
        let rot = DMat3::from_axis_angle(DVec3::new(0.6, 0.8, 0.0), tilt_deg.to_radians())
            * DMat3::from_rotation_z(spin_deg.to_radians());
        let c = board.grid_centre();
        Rigid {
            rotation: rot,
            translation: DVec3::new(0.02, -0.01, 0.9) - rot * DVec3::new(c.x, c.y, 0.0),
        }
    }

    #[test]
    fn finds_a_tilted_board_in_order_and_to_subpixel() {
        let board = BoardSpec {
            cols: 7,
            rows: 5,
            square_m: 0.04,
        };
        // Spins around 180 degrees exercise the physical numbering.
        for spin in [0.0, 25.0, 170.0, -100.0] {
            let p = pose(30.0, spin, &board);
            let img = render(&board, &p);
            let det = CornerDetector::new()
                .detect(&img, &board)
                .unwrap_or_else(|e| panic!("spin {spin}: {e}"));
            let truth: Vec<DVec2> = true_corners(&small_camera(), &board, &p)
                .into_iter()
                .flatten()
                .collect();
            let same = |rev: bool| -> (f64, f64) {
                let mut e: Vec<f64> = (0..truth.len())
                    .map(|k| {
                        (det.corners[if rev { truth.len() - 1 - k } else { k }] - truth[k]).length()
                    })
                    .collect();
                let worst = e.iter().copied().fold(0.0, f64::max);
                (median(&mut e).unwrap_or(f64::INFINITY), worst)
            };
            // Upright boards keep the truth's numbering; an upside-down board is numbered
            // from its (new) top left, i.e. the truth's order reversed.
            let (med, worst) = if spin.abs() > 135.0 {
                same(true)
            } else if spin.abs() < 45.0 {
                same(false)
            } else {
                let (a, b) = (same(false), same(true));
                if a.0 < b.0 {
                    a
                } else {
                    b
                }
            };
            assert!(
                worst < 0.3 && med < 0.1,
                "spin {spin}: median {med} worst {worst}"
            );
            assert!(det.blur_sigma_px < 2.0, "blur {}", det.blur_sigma_px);
        }
    }

    #[test]
    fn empty_wall_and_cut_board_give_operator_errors() {
        let board = BoardSpec {
            cols: 7,
            rows: 5,
            square_m: 0.04,
        };
        let wall = image::GrayImage::from_pixel(200, 150, image::Luma([180]));
        assert!(matches!(
            CornerDetector::new().detect(&wall, &board),
            Err(DetectError::NotFound { .. })
        ));
        let mut p = pose(10.0, 0.0, &board);
        p.translation.x += 0.42; // push the board's right part out of the image
        let img = render(&board, &p);
        let e = CornerDetector::new().detect(&img, &board).unwrap_err();
        assert!(matches!(e, DetectError::Partial { .. }), "{e}");
    }

    /// Clutter where the wall shows: grey rectangles and small checker patches (which
    /// have saddle points of their own, and some have more than the board's corners).
    fn add_clutter(img: &mut image::GrayImage, seed: u64) {
        use super::super::render::{SplitMix64, WALL_LEVEL};
        let mut rng = SplitMix64(seed);
        let (w, h) = (img.width() as i64, img.height() as i64);
        let mut layer = vec![WALL_LEVEL as u8; (w * h) as usize];
        for _ in 0..40 {
            let (x0, y0) = (
                (rng.uniform() * w as f64) as i64,
                (rng.uniform() * h as f64) as i64,
            );
            let (rw, rh) = (
                8 + (rng.uniform() * 80.0) as i64,
                8 + (rng.uniform() * 80.0) as i64,
            );
            let v = (rng.uniform() * 255.0) as u8;
            let checker = rng.uniform() < 0.35;
            let cs = 4 + (rng.uniform() * 10.0) as i64;
            for y in y0.max(0)..(y0 + rh).min(h) {
                for x in x0.max(0)..(x0 + rw).min(w) {
                    let odd = ((x - x0) / cs + (y - y0) / cs) % 2 == 0;
                    layer[(y * w + x) as usize] = if checker && odd { 255 - v } else { v };
                }
            }
        }
        for (p, l) in img.pixels_mut().zip(&layer) {
            if p.0[0] == WALL_LEVEL as u8 {
                p.0[0] = *l;
            }
            p.0[0] = (p.0[0] as f64 + 2.0 * rng.gaussian())
                .round()
                .clamp(0.0, 255.0) as u8;
        }
    }

    #[test]
    fn finds_the_board_among_checkered_clutter() {
        let board = BoardSpec {
            cols: 7,
            rows: 5,
            square_m: 0.04,
        };
        let clean = RenderOptions {
            blur_sigma_px: 0.0,
            noise_sigma: 0.0,
            ..RenderOptions::default()
        };
        let mut r = BoardRenderer::new(small_camera());
        let mut det = CornerDetector::new();
        for (k, (tilt, spin)) in [(20.0, 10.0), (35.0, -20.0), (10.0, 95.0)]
            .iter()
            .enumerate()
        {
            let p = pose(*tilt, *spin, &board);
            let mut img = r.render(&board, &p, Background::Wall, &clean);
            add_clutter(&mut img, 11 + k as u64);
            let d = det
                .detect(&img, &board)
                .unwrap_or_else(|e| panic!("pose {k}: {e}"));
            let truth: Vec<DVec2> = true_corners(&small_camera(), &board, &p)
                .into_iter()
                .flatten()
                .collect();
            // Numbering aside, every detected corner must sit on a true corner.
            let worst = d
                .corners
                .iter()
                .map(|c| {
                    truth
                        .iter()
                        .map(|t| (*t - *c).length())
                        .fold(f64::INFINITY, f64::min)
                })
                .fold(0.0, f64::max);
            assert!(
                worst < 0.3,
                "pose {k}: a corner is {worst} px from any true corner"
            );
        }
    }

    #[test]
    fn finds_a_circle_grid_in_order() {
        use super::super::render::Pattern;
        let board = BoardSpec {
            cols: 7,
            rows: 5,
            square_m: 0.04,
        };
        let opts = RenderOptions {
            pattern: Pattern::Circles {
                radius_fraction: 0.3,
            },
            ..RenderOptions::default()
        };
        let mut r = BoardRenderer::new(small_camera());
        let mut det = CornerDetector::new();
        for (tilt, spin) in [(0.0, 5.0), (30.0, -15.0), (40.0, 20.0)] {
            let p = pose(tilt, spin, &board);
            let img = r.render(&board, &p, Background::Wall, &opts);
            let d = det
                .detect_circles(&img, &board)
                .unwrap_or_else(|e| panic!("tilt {tilt}: {e}"));
            let truth: Vec<DVec2> = true_corners(&small_camera(), &board, &p)
                .into_iter()
                .flatten()
                .collect();
            let mut e: Vec<f64> = d
                .corners
                .iter()
                .zip(&truth)
                .map(|(a, b)| (*a - *b).length())
                .collect();
            let worst = e.iter().copied().fold(0.0, f64::max);
            let med = median(&mut e).unwrap_or(f64::INFINITY);
            println!("circles tilt {tilt}: median {med:.3} px, worst {worst:.3} px");
            assert!(
                med < 0.1 && worst < 0.3,
                "tilt {tilt}: median {med} worst {worst}"
            );
            // A chessboard search on circles finds nothing.
            assert!(det.detect(&img, &board).is_err());
        }
    }
}
