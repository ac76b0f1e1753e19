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

mod blobs;
mod blur;
mod grid;
mod saddle;
mod subpix;

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
