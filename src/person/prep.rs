//! Network input: a frame rectangle resampled to the square input, RGB in [0, 1].

use super::{FrameRef, Roi, INPUT_SIZE};

/// Most sub-samples per input cell and axis (the area average of a strongly shrunk ROI).
const MAX_SUBSAMPLES: usize = 4;

/// Writes `roi` of `frame` into `out` as `INPUT_SIZE x INPUT_SIZE` NHWC RGB floats in
/// [0, 1]. Each input cell averages `n x n` frame pixels sampled evenly over the cell
/// (`n` = the shrink factor rounded up, at most 4): an area average for the usual
/// downscale, nearest pixel when enlarging. Samples outside the frame are black.
///
/// # Panics
/// When `out` is not `INPUT_SIZE * INPUT_SIZE * 3` long (a caller's bug, not data).
pub fn resample_roi(frame: FrameRef<'_>, roi: Roi, out: &mut [f32]) {
    assert_eq!(
        out.len(),
        INPUT_SIZE * INPUT_SIZE * 3,
        "resample_roi: output size"
    );
    let cell_w = roi.width / INPUT_SIZE as f32;
    let cell_h = roi.height / INPUT_SIZE as f32;
    let nx = (cell_w.ceil() as usize).clamp(1, MAX_SUBSAMPLES);
    let ny = (cell_h.ceil() as usize).clamp(1, MAX_SUBSAMPLES);
    let norm = 1.0 / (255.0 * (nx * ny) as f32);
    let (fw, fh) = (frame.width as i64, frame.height as i64);
    // Frame column of every sub-sample of every input column (-1 outside the frame); the
    // same on every row, so computed once, on the stack.
    let mut cols = [-1i64; INPUT_SIZE * MAX_SUBSAMPLES];
    for u in 0..INPUT_SIZE {
        for s in 0..nx {
            let x = roi.x0 + (u as f32 + (s as f32 + 0.5) / nx as f32) * cell_w;
            let i = x.floor() as i64;
            if (0..fw).contains(&i) {
                cols[u * nx + s] = i;
            }
        }
    }
    for v in 0..INPUT_SIZE {
        let out_row = &mut out[v * INPUT_SIZE * 3..(v + 1) * INPUT_SIZE * 3];
        out_row.fill(0.0);
        for t in 0..ny {
            let y = roi.y0 + (v as f32 + (t as f32 + 0.5) / ny as f32) * cell_h;
            let j = y.floor() as i64;
            if !(0..fh).contains(&j) {
                continue;
            }
            let src_row =
                &frame.rgb[j as usize * frame.width * 3..(j as usize + 1) * frame.width * 3];
            for u in 0..INPUT_SIZE {
                let (mut r, mut g, mut b) = (0u32, 0u32, 0u32);
                for &i in &cols[u * nx..(u + 1) * nx] {
                    if i >= 0 {
                        let p = &src_row[i as usize * 3..i as usize * 3 + 3];
                        r += u32::from(p[0]);
                        g += u32::from(p[1]);
                        b += u32::from(p[2]);
                    }
                }
                let o = &mut out_row[u * 3..u * 3 + 3];
                o[0] += r as f32 * norm;
                o[1] += g as f32 * norm;
                o[2] += b as f32 * norm;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn frame(w: usize, h: usize) -> Vec<u8> {
        let mut rgb = vec![0u8; w * h * 3];
        for j in 0..h {
            for i in 0..w {
                let p = &mut rgb[(j * w + i) * 3..(j * w + i) * 3 + 3];
                p[0] = (i % 256) as u8;
                p[1] = (j % 256) as u8;
                p[2] = 200;
            }
        }
        rgb
    }

    #[test]
    fn identity_roi_copies_the_frame() {
        let rgb = frame(256, 256);
        let f = FrameRef::new(&rgb, 256, 256).expect("frame");
        let mut out = vec![0.0; INPUT_SIZE * INPUT_SIZE * 3];
        resample_roi(f, Roi::full_frame(256, 256), &mut out);
        for (k, (&o, &p)) in out.iter().zip(&rgb).enumerate() {
            assert!((o - p as f32 / 255.0).abs() < 1e-6, "value {k}");
        }
    }

    #[test]
    fn shrinking_averages_and_outside_is_black() {
        let (w, h) = (1024, 512);
        let rgb = frame(w, h);
        let f = FrameRef::new(&rgb, w, h).expect("frame");
        let mut out = vec![0.0; INPUT_SIZE * INPUT_SIZE * 3];
        // a square ROI 1024 wide: 4 frame pixels a cell; the lower half is below the frame
        let roi = Roi {
            x0: 0.0,
            y0: 0.0,
            width: 1024.0,
            height: 1024.0,
        };
        resample_roi(f, roi, &mut out);
        // cell (u=10, v=5) averages columns 40..44 and rows 20..24
        let o = &out[(5 * INPUT_SIZE + 10) * 3..(5 * INPUT_SIZE + 10) * 3 + 3];
        assert!((o[0] - 41.5 / 255.0).abs() < 1e-5, "{o:?}");
        assert!((o[1] - 21.5 / 255.0).abs() < 1e-5, "{o:?}");
        assert!((o[2] - 200.0 / 255.0).abs() < 1e-5, "{o:?}");
        let below = &out[(200 * INPUT_SIZE + 10) * 3..(200 * INPUT_SIZE + 10) * 3 + 3];
        assert_eq!(below, &[0.0, 0.0, 0.0]);
    }
}
