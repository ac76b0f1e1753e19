//! The synthetic camera's film: radiance in, an 8-bit sRGB frame out, through the optics'
//! blur, vignetting, white balance, exposure, the gamma curve and the sensor's noise.

use super::rng::SplitMix64;

/// The camera's film: optics blur, vignetting, white balance, exposure and noise.
#[derive(Debug, Clone)]
pub struct Film {
    /// Radiance that maps to full scale before the gamma curve.
    pub exposure: f32,
    pub white_balance: [f32; 3],
    /// Relative brightness loss at the image corner.
    pub vignetting: f32,
    /// Standard deviation of the frame-to-frame exposure flicker (relative).
    pub flicker: f32,
    /// Read noise (8-bit levels) and shot-noise gain (levels per level).
    pub read_noise: f32,
    pub shot_gain: f32,
    gamma_lut: Vec<f32>,
    normal_table: Vec<f32>,
}

const GAMMA_LUT_SIZE: usize = 4096;
/// Where auto exposure puts the 98th percentile of the empty scene (linear, 1 = clip).
pub const AUTO_EXPOSURE_TARGET: f32 = 0.8;
const GAMMA_LUT_MAX: f32 = 2.0;
const NORMAL_TABLE_BITS: u32 = 12;

impl Film {
    pub fn random(rng: &mut SplitMix64) -> Film {
        let gamma_lut = (0..GAMMA_LUT_SIZE)
            .map(|i| {
                255.0
                    * (i as f32 / (GAMMA_LUT_SIZE - 1) as f32 * GAMMA_LUT_MAX)
                        .min(1.0)
                        .powf(1.0 / 2.2)
            })
            .collect();
        // Normal quantiles, approximated by sorted Box-Muller draws (deterministic).
        let mut g = SplitMix64::new(0x006E_6F69_7365);
        let mut normal_table: Vec<f32> = (0..1usize << NORMAL_TABLE_BITS)
            .map(|_| g.normal() as f32)
            .collect();
        normal_table.sort_by(f32::total_cmp);
        Film {
            exposure: rng.range(0.85, 1.1) as f32,
            white_balance: [
                rng.range(0.95, 1.05) as f32,
                1.0,
                rng.range(0.95, 1.05) as f32,
            ],
            vignetting: rng.range(0.1, 0.3) as f32,
            flicker: rng.range(0.005, 0.02) as f32,
            read_noise: rng.range(1.0, 2.5) as f32,
            shot_gain: rng.range(0.01, 0.04) as f32,
            gamma_lut,
            normal_table,
        }
    }

    /// Auto exposure: scales the exposure so the 98th percentile of the scene's
    /// brightest channel lands at [`AUTO_EXPOSURE_TARGET`] of full scale (before the
    /// random offset drawn in [`Film::random`]).
    pub fn auto_expose(&mut self, radiance: &[[f32; 3]]) {
        let mut v: Vec<f32> = radiance
            .iter()
            .step_by(7)
            .map(|p| p[0].max(p[1]).max(p[2]))
            .collect();
        if v.is_empty() {
            return;
        }
        let k = (v.len() as f32 * 0.98) as usize;
        let k = k.min(v.len() - 1);
        let (_, p98, _) = v.select_nth_unstable_by(k, f32::total_cmp);
        if *p98 > 1e-6 {
            self.exposure *= AUTO_EXPOSURE_TARGET / *p98;
        }
    }

    /// Develops `radiance` (row-major, the size of `out`; modified in place by the optics
    /// blur) into `out`. `gain` is this frame's exposure factor (flicker), `rng` the
    /// noise stream. A radiance buffer of another size leaves `out` untouched.
    pub fn develop(
        &self,
        radiance: &mut [[f32; 3]],
        scratch: &mut Vec<[f32; 3]>,
        gain: f32,
        rng: &mut SplitMix64,
        out: &mut image::RgbImage,
    ) {
        let (w, h) = (out.width() as usize, out.height() as usize);
        if radiance.len() != w * h || w == 0 {
            return;
        }
        blur121(radiance, scratch, w, h);
        let (cx, cy) = (0.5 * (w as f32 - 1.0), 0.5 * (h as f32 - 1.0));
        let r2max = cx * cx + cy * cy;
        let lut_scale = (GAMMA_LUT_SIZE - 1) as f32 / GAMMA_LUT_MAX;
        // Noise standard deviation per output level (read + shot noise).
        let sigma: [f32; 256] = std::array::from_fn(|l| {
            (self.read_noise * self.read_noise + self.shot_gain * l as f32).sqrt()
        });
        let mask = (1u64 << NORMAL_TABLE_BITS) - 1;
        let buf: &mut [u8] = out.as_mut();
        let mut bits = 0u64;
        let mut left = 0u32;
        let gamma = &self.gamma_lut[..];
        let normal = &self.normal_table[..];
        for (y, (row_in, row_out)) in radiance
            .chunks_exact(w)
            .zip(buf.chunks_exact_mut(3 * w))
            .enumerate()
        {
            let dy = y as f32 - cy;
            let row_k = self.exposure * gain;
            for (x, (px, o)) in row_in.iter().zip(row_out.chunks_exact_mut(3)).enumerate() {
                let dx = x as f32 - cx;
                let k = row_k * (1.0 - self.vignetting * (dx * dx + dy * dy) / r2max) * lut_scale;
                for c in 0..3 {
                    let li = ((px[c] * k * self.white_balance[c]) as usize).min(GAMMA_LUT_SIZE - 1);
                    let level = gamma[li];
                    if left == 0 {
                        bits = rng.next_u64();
                        left = 64 / NORMAL_TABLE_BITS;
                    }
                    let z = normal[(bits & mask) as usize];
                    bits >>= NORMAL_TABLE_BITS;
                    left -= 1;
                    let s = sigma[(level as usize).min(255)];
                    o[c] = (level + s * z + 0.5).clamp(0.0, 255.0) as u8;
                }
            }
        }
    }
}

/// Separable [1 2 1]/4 blur (the lens's point spread), in place.
fn blur121(img: &mut [[f32; 3]], tmp: &mut Vec<[f32; 3]>, w: usize, h: usize) {
    if w < 2 || h < 2 || img.len() < w * h {
        return;
    }
    tmp.clear();
    tmp.resize(img.len(), [0.0; 3]);
    #[inline]
    fn mix(a: &[f32; 3], b: &[f32; 3], c: &[f32; 3]) -> [f32; 3] {
        [
            0.25 * (a[0] + c[0]) + 0.5 * b[0],
            0.25 * (a[1] + c[1]) + 0.5 * b[1],
            0.25 * (a[2] + c[2]) + 0.5 * b[2],
        ]
    }
    for (src, dst) in img.chunks_exact(w).zip(tmp.chunks_exact_mut(w)) {
        dst[0] = mix(&src[0], &src[0], &src[1]);
        for x in 1..w - 1 {
            dst[x] = mix(&src[x - 1], &src[x], &src[x + 1]);
        }
        dst[w - 1] = mix(&src[w - 2], &src[w - 1], &src[w - 1]);
    }
    for y in 0..h {
        let up = &tmp[y.saturating_sub(1) * w..][..w];
        let mid = &tmp[y * w..][..w];
        let dn = &tmp[(y + 1).min(h - 1) * w..][..w];
        let out = &mut img[y * w..][..w];
        for x in 0..w {
            out[x] = mix(&up[x], &mid[x], &dn[x]);
        }
    }
}
