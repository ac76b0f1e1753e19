//! Undistortion with the station calibration (issue 4, step 1).
//!
//! Two routes, both from the camera's OpenCV model (`camera::Intrinsics`):
//! - [`RemapTable`]: computed once per camera, maps every pixel of the undistorted image
//!   (same K, no distortion) to its source in the distorted frame; bilinear, fixed-point
//!   weights (1/256), for display and overlays.
//! - [`PointUndistorter`]: undistorts individual pixels (contour points), which is all
//!   the pipeline needs and far cheaper than remapping the frame. Newton's method with the
//!   analytic Jacobian of the distortion; output in undistorted pixels (K applied again),
//!   the same as `cv2.undistortPoints(..., P=K)`.

use crate::camera::Intrinsics;
use glam::DVec2;
use image::RgbImage;

/// Fixed-point scale of the bilinear weights.
const WEIGHT_ONE: u32 = 256;
/// Newton iterations at most for one point.
const NEWTON_MAX_ITER: usize = 12;
/// Convergence in normalised coordinates (about 1e-9 px at f = 1000 px).
const NEWTON_TOL: f64 = 1e-12;

/// Per-pixel source positions of an undistortion, computed once per camera.
#[derive(Debug, Clone)]
pub struct RemapTable {
    pub width: u32,
    pub height: u32,
    /// Index of the top-left source pixel, or `u32::MAX` when the source is outside.
    src_index: Vec<u32>,
    /// Bilinear weights (x, y) in 1/256.
    weights: Vec<[u8; 2]>,
}

impl RemapTable {
    /// Builds the table for a camera: destination pixel (u, v) of the ideal pinhole image
    /// takes the distorted frame at `K * distort(K^-1 (u, v))`.
    pub fn new(intr: &Intrinsics) -> Self {
        let (w, h) = (intr.width, intr.height);
        let mut src_index = Vec::with_capacity((w * h) as usize);
        let mut weights = Vec::with_capacity((w * h) as usize);
        for v in 0..h {
            for u in 0..w {
                let n = DVec2::new(
                    (u as f64 - intr.cx) / intr.fx,
                    (v as f64 - intr.cy) / intr.fy,
                );
                let s = intr.to_pixel(intr.distort(n));
                let (x0, y0) = (s.x.floor(), s.y.floor());
                if x0 < 0.0 || y0 < 0.0 || x0 + 1.0 > (w - 1) as f64 || y0 + 1.0 > (h - 1) as f64 {
                    src_index.push(u32::MAX);
                    weights.push([0, 0]);
                    continue;
                }
                let fx = ((s.x - x0) * WEIGHT_ONE as f64).round().min(255.0) as u8;
                let fy = ((s.y - y0) * WEIGHT_ONE as f64).round().min(255.0) as u8;
                src_index.push(y0 as u32 * w + x0 as u32);
                weights.push([fx, fy]);
            }
        }
        RemapTable {
            width: w,
            height: h,
            src_index,
            weights,
        }
    }

    /// Undistorts a frame into `out` (resized if needed); pixels whose source falls
    /// outside the frame are black.
    pub fn remap_rgb(&self, src: &RgbImage, out: &mut RgbImage) {
        if out.width() != self.width || out.height() != self.height {
            *out = RgbImage::new(self.width, self.height);
        }
        if src.width() != self.width || src.height() != self.height {
            return;
        }
        let s = src.as_raw();
        let w = self.width as usize;
        let dst = out.as_mut();
        for (i, (&idx, &[fx, fy])) in self.src_index.iter().zip(&self.weights).enumerate() {
            let o = &mut dst[3 * i..3 * i + 3];
            if idx == u32::MAX {
                o.copy_from_slice(&[0, 0, 0]);
                continue;
            }
            let (fx, fy) = (fx as u32, fy as u32);
            let a = 3 * idx as usize;
            let c = a + 3 * w;
            for ch in 0..3 {
                let top = s[a + ch] as u32 * (WEIGHT_ONE - fx) + s[a + 3 + ch] as u32 * fx;
                let bot = s[c + ch] as u32 * (WEIGHT_ONE - fx) + s[c + 3 + ch] as u32 * fx;
                o[ch] = ((top * (WEIGHT_ONE - fy) + bot * fy + WEIGHT_ONE * WEIGHT_ONE / 2) >> 16)
                    as u8;
            }
        }
    }
}

/// Node spacing of the undistortion grid, pixels. Bilinear interpolation of the smooth
/// undistortion map on this grid errs by about 1e-3 px for ordinary lenses (the
/// OpenCV check bounds it at 0.05 px).
pub const UNDISTORT_GRID_PX: f64 = 8.0;

/// Undistorts pixels of one camera (contour points, landmarks): exact Newton solves on a
/// grid of nodes computed once, bilinear interpolation between them per point.
#[derive(Debug, Clone)]
pub struct PointUndistorter {
    pub intrinsics: Intrinsics,
    no_distortion: bool,
    cols: usize,
    rows: usize,
    /// Undistorted normalised coordinates at the grid nodes, row-major.
    grid: Vec<DVec2>,
}

impl PointUndistorter {
    pub fn new(intrinsics: Intrinsics) -> Self {
        let no_distortion = intrinsics.dist.iter().all(|&k| k == 0.0);
        let mut u = PointUndistorter {
            intrinsics,
            no_distortion,
            cols: 0,
            rows: 0,
            grid: Vec::new(),
        };
        if !no_distortion {
            u.cols = (intrinsics.width as f64 / UNDISTORT_GRID_PX).ceil() as usize + 2;
            u.rows = (intrinsics.height as f64 / UNDISTORT_GRID_PX).ceil() as usize + 2;
            let mut grid = Vec::with_capacity(u.cols * u.rows);
            for r in 0..u.rows {
                for c in 0..u.cols {
                    grid.push(
                        u.normalized_exact(DVec2::new(c as f64, r as f64) * UNDISTORT_GRID_PX),
                    );
                }
            }
            u.grid = grid;
        }
        u
    }

    /// Distorted pixel -> undistorted normalised coordinates (x/z, y/z), from the grid
    /// (exact solve outside the image).
    #[inline]
    pub fn normalized(&self, px: DVec2) -> DVec2 {
        if self.no_distortion {
            let i = &self.intrinsics;
            return DVec2::new((px.x - i.cx) / i.fx, (px.y - i.cy) / i.fy);
        }
        let g = px / UNDISTORT_GRID_PX;
        if !(g.x >= 0.0 && g.y >= 0.0) {
            return self.normalized_exact(px);
        }
        let (c, r) = (g.x as usize, g.y as usize);
        if c + 1 >= self.cols || r + 1 >= self.rows {
            return self.normalized_exact(px);
        }
        let (fx, fy) = (g.x - c as f64, g.y - r as f64);
        let k = r * self.cols + c;
        let (a, b) = (self.grid[k], self.grid[k + 1]);
        let (d, e) = (self.grid[k + self.cols], self.grid[k + self.cols + 1]);
        let top = a + (b - a) * fx;
        let bot = d + (e - d) * fx;
        top + (bot - top) * fy
    }

    /// Distorted pixel -> undistorted normalised coordinates by Newton's method.
    pub fn normalized_exact(&self, px: DVec2) -> DVec2 {
        let i = &self.intrinsics;
        let d = DVec2::new((px.x - i.cx) / i.fx, (px.y - i.cy) / i.fy);
        if self.no_distortion {
            return d;
        }
        let [k1, k2, p1, p2, k3] = i.dist;
        let mut n = d;
        for _ in 0..NEWTON_MAX_ITER {
            let (x, y) = (n.x, n.y);
            let r2 = x * x + y * y;
            let radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3));
            let dradial = k1 + r2 * (2.0 * k2 + 3.0 * k3 * r2); // d radial / d r2
            let fx = x * radial + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x) - d.x;
            let fy = y * radial + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y - d.y;
            // Jacobian of the OpenCV distortion.
            let j11 = radial + 2.0 * x * x * dradial + 2.0 * p1 * y + 6.0 * p2 * x;
            let j12 = 2.0 * x * y * dradial + 2.0 * p1 * x + 2.0 * p2 * y;
            let j21 = 2.0 * x * y * dradial + 2.0 * p1 * x + 2.0 * p2 * y;
            let j22 = radial + 2.0 * y * y * dradial + 6.0 * p1 * y + 2.0 * p2 * x;
            let det = j11 * j22 - j12 * j21;
            if det.abs() < 1e-12 {
                break;
            }
            let step = DVec2::new((j22 * fx - j12 * fy) / det, (-j21 * fx + j11 * fy) / det);
            n -= step;
            if step.length_squared() < NEWTON_TOL * NEWTON_TOL {
                break;
            }
        }
        n
    }

    /// Distorted pixel -> undistorted pixel (same K), as `cv2.undistortPoints(.., P=K)`.
    #[inline]
    pub fn undistort(&self, px: DVec2) -> DVec2 {
        if self.no_distortion {
            return px;
        }
        self.intrinsics.to_pixel(self.normalized(px))
    }

    /// Distorted pixel -> undistorted pixel by Newton's method (no grid).
    pub fn undistort_exact(&self, px: DVec2) -> DVec2 {
        if self.no_distortion {
            return px;
        }
        self.intrinsics.to_pixel(self.normalized_exact(px))
    }

    /// Undistorted pixel -> distorted pixel.
    #[inline]
    pub fn distort(&self, undistorted_px: DVec2) -> DVec2 {
        if self.no_distortion {
            return undistorted_px;
        }
        let i = &self.intrinsics;
        let n = DVec2::new(
            (undistorted_px.x - i.cx) / i.fx,
            (undistorted_px.y - i.cy) / i.fy,
        );
        i.to_pixel(i.distort(n))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::StationCalibration;

    fn intr() -> Intrinsics {
        let mut i = StationCalibration::nominal(1280, 720, 1000.0, 3.0, 1.2, 1.0)
            .front
            .intrinsics;
        i.dist = [-0.12, 0.05, 0.001, -0.0005, -0.01];
        i
    }

    #[test]
    fn point_undistortion_inverts_distortion() {
        let u = PointUndistorter::new(intr());
        for &(x, y) in &[
            (0.0, 0.0),
            (640.0, 360.0),
            (1279.0, 719.0),
            (30.0, 700.0),
            (1003.3, 17.9),
        ] {
            let p = DVec2::new(x, y);
            let back = u.distort(u.undistort_exact(p));
            assert!((back - p).length() < 1e-6, "{p} -> {back}");
            // The grid's interpolation stays far below the 0.05 px of the OpenCV check.
            let grid = u.undistort(p);
            assert!(
                (grid - u.undistort_exact(p)).length() < 0.01,
                "{p}: grid {grid}"
            );
        }
    }

    #[test]
    fn remap_moves_a_dot_to_its_undistorted_place() {
        let i = intr();
        let t = RemapTable::new(&i);
        let u = PointUndistorter::new(i);
        let mut img = RgbImage::new(i.width, i.height);
        let dot = DVec2::new(150.0, 100.0);
        for y in 95..106 {
            for x in 145..156 {
                img.put_pixel(x, y, image::Rgb([255, 255, 255]));
            }
        }
        let mut out = RgbImage::new(1, 1);
        t.remap_rgb(&img, &mut out);
        let (mut sx, mut sy, mut sw) = (0.0, 0.0, 0.0);
        for (x, y, p) in out.enumerate_pixels() {
            let w = p.0[0] as f64;
            sx += w * x as f64;
            sy += w * y as f64;
            sw += w;
        }
        let c = DVec2::new(sx / sw, sy / sw);
        let expect = u.undistort(dot);
        assert!((c - expect).length() < 1.0, "centroid {c} vs {expect}");
    }
}
