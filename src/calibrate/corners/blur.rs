//! Blur and contrast across the board's edges (what the operator is told when a board
//! is not found).

use super::*;

/// Blur and contrast measured across one edge.
pub(super) struct EdgeProfile {
    pub(super) sigma_px: f64,
    pub(super) contrast: f64,
}

/// 10-90% rise of a Gaussian-blurred step, in sigmas (2 x 1.2816).
pub(super) const RISE_10_90_PER_SIGMA: f64 = 2.563;
/// Edge profiles reach this fraction of the corner spacing to either side.
pub(super) const EDGE_PROFILE_REACH: f64 = 0.45;
/// Global blur estimate: grid cell (one edge sample per cell), edges used, fewest edges
/// for an answer, and the reach of each profile, pixels.
pub(super) const GLOBAL_BLUR_CELL_PX: usize = 16;
pub(super) const GLOBAL_BLUR_EDGES: usize = 200;
pub(super) const GLOBAL_BLUR_MIN_EDGES: usize = 10;
pub(super) const GLOBAL_BLUR_REACH_PX: f64 = 10.0;
/// Sample step along an edge profile, pixels.
pub(super) const EDGE_PROFILE_STEP_PX: f64 = 0.25;

impl CornerDetector {
    /// Blur across the edge between two neighbouring corners `a` and `b`: the raw grey
    /// profile perpendicular to the edge at its midpoint (averaged over a short strip
    /// along the edge), its plateaus, and the 10-90% rise width; a Gaussian-blurred step
    /// rises 10-90% over 2.563 sigma.
    pub(super) fn edge_profile(&self, a: DVec2, b: DVec2) -> Option<EdgeProfile> {
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
    pub(super) fn profile_across(
        &self,
        n: DVec2,
        mid: DVec2,
        half_len: f64,
    ) -> Option<EdgeProfile> {
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
    pub(super) fn global_blur_estimate(&self) -> Option<f64> {
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
