//! Still images (the paper's case): keying one image per view against an empty-scene
//! image, or against a backdrop estimated from the image's left and right borders.

use super::{BackgroundModel, SegmentError, SegmentOptions, KEY_BORDER_PX, KEY_ROW_SMOOTH};
use crate::imgproc::Mask;
use image::RgbImage;

/// Segments a still image (the paper's case: one image per view against a plain
/// backdrop). With `empty`, the empty-scene image of the same view is the background;
/// without, the backdrop colour is keyed from the left and right image borders (per row,
/// interpolated across, smoothed over rows), which tolerates a vertical light gradient.
///
/// # Errors
/// `FrameSize` when `empty` differs in size from `frame`; `Empty` for a 0-pixel frame.
pub fn key_still(frame: &RgbImage, empty: Option<&RgbImage>) -> Result<Mask, SegmentError> {
    let (w, h) = frame.dimensions();
    if w == 0 || h == 0 {
        return Err(SegmentError::Empty);
    }
    let opts = SegmentOptions {
        adapt_rate: 0.0,
        ..Default::default()
    };
    let mut model = BackgroundModel::new(w, h, opts);
    match empty {
        Some(e) => model.learn(e)?,
        None => {
            let backdrop = backdrop_from_border(frame);
            model.learn(&backdrop)?;
        }
    }
    let mut mask = Mask::new(w, h);
    model.segment(frame, &mut mask)?;
    Ok(mask)
}

/// An image of the backdrop alone, estimated from the left and right border strips of a
/// still image (per row, interpolated across, smoothed over rows).
pub fn backdrop_from_border(frame: &RgbImage) -> RgbImage {
    let (w, h) = frame.dimensions();
    let strip = KEY_BORDER_PX.min(w / 4).max(1);
    let mut left = vec![[0f32; 3]; h as usize];
    let mut right = vec![[0f32; 3]; h as usize];
    for y in 0..h {
        for x in 0..strip {
            let pl = frame.get_pixel(x, y).0;
            let pr = frame.get_pixel(w - 1 - x, y).0;
            for c in 0..3 {
                left[y as usize][c] += pl[c] as f32 / strip as f32;
                right[y as usize][c] += pr[c] as f32 / strip as f32;
            }
        }
    }
    let smooth = |v: &[[f32; 3]]| -> Vec<[f32; 3]> {
        (0..v.len())
            .map(|y| {
                let (a, b) = (
                    y.saturating_sub(KEY_ROW_SMOOTH),
                    (y + KEY_ROW_SMOOTH + 1).min(v.len()),
                );
                let mut s = [0f32; 3];
                for row in &v[a..b] {
                    for c in 0..3 {
                        s[c] += row[c] / (b - a) as f32;
                    }
                }
                s
            })
            .collect()
    };
    let (left, right) = (smooth(&left), smooth(&right));
    let mut out = RgbImage::new(w, h);
    for (x, y, p) in out.enumerate_pixels_mut() {
        let t = if w > 1 {
            x as f32 / (w - 1) as f32
        } else {
            0.0
        };
        let (l, r) = (left[y as usize], right[y as usize]);
        p.0 = [0, 1, 2].map(|c| (l[c] + t * (r[c] - l[c])).round().clamp(0.0, 255.0) as u8);
    }
    out
}
