//! Step 4: sub-pixel refinement (Förstner, as OpenCV's `cornerSubPix`, then the point
//! symmetry refinement).

use super::*;

impl CornerDetector {
    /// Step 4: Förstner / cornerSubPix iteration with a Gaussian window of half size
    /// `half` pixels. None when the system is singular (a flat patch).
    pub(super) fn subpix(&self, start: DVec2, half: i32) -> Option<DVec2> {
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
    pub(super) fn symmetric_refine(&self, start: DVec2, half: i32) -> Option<DVec2> {
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
}
