//! Camera frames prepared for the screen, once per frame pair, on the `capture` thread
//! (not on the screen's): box-filtered by an integer factor down to about the size of
//! the view on screen and written as RGBA8 (sRGB bytes as they came from the camera),
//! ready for `wgpu::Queue::write_texture`.
//!
//! Conventions: sizes are pixels, `[width, height]`; a frame of `w` x `h` pixels shown
//! by factor `f` becomes `floor(w / f)` x `floor(h / f)` (partial blocks at the right
//! and bottom edges, at most `f - 1` pixels, are left out). Buffers come from a small
//! pool and are reused once the screen has let go of them: no allocation per frame.

use std::sync::Arc;

/// Longest side of a camera frame as prepared for display (pixels).
pub const DISPLAY_MAX_PX: u32 = 640;

/// Display images kept for reuse: enough for both views of every pair in flight (read
/// ahead, in the pair slot, being processed, in the snapshot slot, on screen), plus
/// the one being written.
const POOL_SIZE: usize = 12;

/// Bits of the fixed-point reciprocal that replaces the division of a block sum by
/// the block's pixel count. Exact (same result as integer division) for sums of up to
/// `255 * n` as long as `255 * n * n < 2^RECIP_BITS`, i.e. for blocks up to 15 x 15.
const RECIP_BITS: u32 = 24;
/// Largest factor served by the reciprocal (larger ones divide).
const RECIP_MAX_FACTOR: usize = 15;

/// A camera frame at display resolution.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct DisplayImage {
    /// Size of `rgba` in pixels.
    pub size: [u32; 2],
    /// Size of the camera frame it shows (overlays are in the frame's pixels).
    pub frame_size: [u32; 2],
    /// Row-major RGBA8, `4 * size[0] * size[1]` bytes, alpha 255.
    pub rgba: Vec<u8>,
}

/// Integer box-filter factor for showing a `w` x `h` frame in a view of `target_px`
/// pixels: the largest factor that keeps the picture at least as large as the view
/// (sampling stays sharp), and at least the one that brings the longer side down to
/// [`DISPLAY_MAX_PX`].
pub fn display_factor(w: u32, h: u32, target_px: Option<[f32; 2]>) -> u32 {
    let cap = w.max(h).div_ceil(DISPLAY_MAX_PX).max(1);
    let Some([tw, th]) = target_px.filter(|t| t[0] >= 1.0 && t[1] >= 1.0) else {
        return cap;
    };
    let fit = (w as f32 / tw).max(h as f32 / th).floor().max(1.0) as u32;
    fit.max(cap)
}

/// Reusable state of [`Downscaler::prepare`].
#[derive(Debug, Default)]
pub struct Downscaler {
    /// Per output column and channel: the sum over the current block row.
    row_sums: Vec<u32>,
    pool: Vec<Arc<DisplayImage>>,
}

impl Downscaler {
    /// `frame` box-filtered by `factor` into a pooled buffer: one nobody else holds
    /// any more (the screen has dropped it), or a new one while the pool is not full.
    pub fn prepare(&mut self, frame: &image::RgbImage, factor: u32) -> Arc<DisplayImage> {
        let free = self.pool.iter_mut().position(|a| Arc::get_mut(a).is_some());
        if let Some(img) = free.and_then(|k| self.pool.get_mut(k)) {
            if let Some(buf) = Arc::get_mut(img) {
                downscale_into(frame, factor, &mut self.row_sums, buf);
            }
            return img.clone();
        }
        let mut buf = DisplayImage::default();
        downscale_into(frame, factor, &mut self.row_sums, &mut buf);
        let fresh = Arc::new(buf);
        if self.pool.len() < POOL_SIZE {
            self.pool.push(fresh.clone());
        }
        fresh
    }
}

/// Box-filters `frame` down by `factor` into `out` (its buffer reused).
pub fn downscale_into(
    frame: &image::RgbImage,
    factor: u32,
    row_sums: &mut Vec<u32>,
    out: &mut DisplayImage,
) {
    let (w, h) = (frame.width() as usize, frame.height() as usize);
    // A frame smaller than one block is shown as it is.
    let f = (factor.max(1) as usize).min(w.max(1)).min(h.max(1));
    let (ow, oh) = (w / f, h / f);
    out.size = [ow as u32, oh as u32];
    out.frame_size = [w as u32, h as u32];
    out.rgba.clear();
    out.rgba.reserve(ow * oh * 4);
    row_sums.clear();
    row_sums.resize(ow * 3, 0);
    let raw = frame.as_raw();
    let n = (f * f) as u64;
    let recip = (1u64 << RECIP_BITS).div_ceil(n);
    for oy in 0..oh {
        row_sums.fill(0);
        for dy in 0..f {
            let y = oy * f + dy;
            let Some(row) = raw.get(y * w * 3..(y * w + ow * f) * 3) else {
                break;
            };
            // The common factors unrolled: the per-pixel loop is the whole cost.
            match f {
                1 => add_row::<1>(row, row_sums),
                2 => add_row::<2>(row, row_sums),
                3 => add_row::<3>(row, row_sums),
                4 => add_row::<4>(row, row_sums),
                _ => add_row_dyn(row, f, row_sums),
            }
        }
        if f <= RECIP_MAX_FACTOR {
            for s in row_sums.chunks_exact(3) {
                let d = |v: u32| ((v as u64 * recip) >> RECIP_BITS) as u8;
                out.rgba
                    .extend_from_slice(&[d(s[0]), d(s[1]), d(s[2]), 255]);
            }
        } else {
            let n = n as u32;
            for s in row_sums.chunks_exact(3) {
                out.rgba.extend_from_slice(&[
                    (s[0] / n) as u8,
                    (s[1] / n) as u8,
                    (s[2] / n) as u8,
                    255,
                ]);
            }
        }
    }
}

/// Adds one input row to the block sums, `F` pixels per output column.
fn add_row<const F: usize>(row: &[u8], sums: &mut [u32]) {
    for (acc, block) in sums.chunks_exact_mut(3).zip(row.chunks_exact(3 * F)) {
        let (mut r, mut g, mut b) = (0u32, 0u32, 0u32);
        for k in 0..F {
            r += block[3 * k] as u32;
            g += block[3 * k + 1] as u32;
            b += block[3 * k + 2] as u32;
        }
        acc[0] += r;
        acc[1] += g;
        acc[2] += b;
    }
}

fn add_row_dyn(row: &[u8], f: usize, sums: &mut [u32]) {
    for (acc, block) in sums.chunks_exact_mut(3).zip(row.chunks_exact(3 * f)) {
        for px in block.chunks_exact(3) {
            acc[0] += px[0] as u32;
            acc[1] += px[1] as u32;
            acc[2] += px[2] as u32;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pixel(img: &DisplayImage, x: usize, y: usize) -> [u8; 4] {
        let k = 4 * (y * img.size[0] as usize + x);
        [
            img.rgba[k],
            img.rgba[k + 1],
            img.rgba[k + 2],
            img.rgba[k + 3],
        ]
    }

    #[test]
    fn downscale_keeps_aspect_and_averages() {
        let mut img = image::RgbImage::new(1280, 720);
        for (x, _, p) in img.enumerate_pixels_mut() {
            *p = if x % 2 == 0 {
                image::Rgb([200, 0, 0])
            } else {
                image::Rgb([0, 0, 100])
            };
        }
        let mut d = Downscaler::default();
        let f = display_factor(1280, 720, None);
        assert_eq!(f, 2);
        let out = d.prepare(&img, f);
        assert_eq!(out.size, [640, 360]);
        assert_eq!(out.frame_size, [1280, 720]);
        assert_eq!(pixel(&out, 40, 1), [100, 0, 50, 255]);
        let small = image::RgbImage::new(100, 50);
        let f = display_factor(100, 50, None);
        assert_eq!(d.prepare(&small, f).size, [100, 50]);
        // A view of 420 px: the picture stays at least that wide.
        let f = display_factor(1280, 720, Some([420.0, 800.0]));
        assert_eq!(f, 3);
        let out = d.prepare(&img, f);
        assert_eq!(out.size, [426, 240]);
        // Odd factor over alternating columns: 2 red + 1 blue, then 1 red + 2 blue.
        assert_eq!(pixel(&out, 0, 0), [133, 0, 33, 255]);
        assert_eq!(pixel(&out, 1, 0), [66, 0, 66, 255]);
    }

    /// The reciprocal gives integer division's result for every block size it serves
    /// and every block sum (all values of a block the same or not).
    #[test]
    fn reciprocal_matches_integer_division() {
        for f in 1..=RECIP_MAX_FACTOR as u64 {
            let n = f * f;
            let recip = (1u64 << RECIP_BITS).div_ceil(n);
            for s in 0..=255 * n {
                assert_eq!((s * recip) >> RECIP_BITS, s / n, "factor {f}, sum {s}");
            }
        }
    }

    #[test]
    fn every_factor_averages_its_block() {
        // A ramp: the mean of a block is known in closed form.
        let (w, h) = (97u32, 61u32);
        let img = image::RgbImage::from_fn(w, h, |x, y| {
            image::Rgb([(x * 2) as u8, (y * 3) as u8, ((x + y) % 256) as u8])
        });
        let mut d = Downscaler::default();
        for f in [1u32, 2, 3, 4, 5, 7, 16] {
            let out = d.prepare(&img, f);
            assert_eq!(out.size, [w / f, h / f], "factor {f}");
            assert_eq!(out.rgba.len(), 4 * (w / f * (h / f)) as usize);
            let (ox, oy) = ((w / f - 1) as usize, (h / f - 1) as usize);
            let mut sum = [0u32; 3];
            for y in 0..f {
                for x in 0..f {
                    let p = img.get_pixel(ox as u32 * f + x, oy as u32 * f + y);
                    for c in 0..3 {
                        sum[c] += p[c] as u32;
                    }
                }
            }
            let n = f * f;
            let want = [
                (sum[0] / n) as u8,
                (sum[1] / n) as u8,
                (sum[2] / n) as u8,
                255,
            ];
            assert_eq!(pixel(&out, ox, oy), want, "factor {f}");
        }
    }

    #[test]
    fn buffers_are_reused_once_released() {
        let img = image::RgbImage::new(64, 32);
        let mut d = Downscaler::default();
        let a = d.prepare(&img, 2);
        let pa = Arc::as_ptr(&a);
        // Still held by the screen: a different buffer.
        let b = d.prepare(&img, 2);
        assert_ne!(Arc::as_ptr(&b), pa);
        drop(a);
        let c = d.prepare(&img, 2);
        assert_eq!(Arc::as_ptr(&c), pa);
        // Never more than the pool keeps, however many are held.
        let held: Vec<_> = (0..3 * POOL_SIZE).map(|_| d.prepare(&img, 2)).collect();
        assert_eq!(held.len(), 3 * POOL_SIZE);
        assert!(d.pool.len() <= POOL_SIZE);
    }
}
