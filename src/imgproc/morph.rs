//! Binary morphology on `0/255` masks with a 3x3 square: erosion, dilation (separable
//! min/max, the image border counts as background) and a 3x3 majority (median) filter,
//! which removes speckle noise without the corner-filling bias of a closing.

use super::MASK_ON;

/// Separable 3x3 min (`erode`) or max of `src` into `dst`; `tmp` is scratch. Written as
/// slice zips so the compiler vectorises the interior.
fn minmax3x3(
    src: &[u8],
    width: usize,
    height: usize,
    dst: &mut Vec<u8>,
    tmp: &mut Vec<u8>,
    take_max: bool,
) {
    let n = width * height;
    dst.resize(n, 0);
    tmp.resize(n, 0);
    if width == 0 || height == 0 || src.len() < n {
        return;
    }
    if take_max {
        minmax_passes(src, width, height, dst, tmp, |a, b| a.max(b));
    } else {
        minmax_passes(src, width, height, dst, tmp, |a, b| a.min(b));
    }
}

#[inline(always)]
fn minmax_passes(
    src: &[u8],
    width: usize,
    height: usize,
    dst: &mut [u8],
    tmp: &mut [u8],
    op: impl Fn(u8, u8) -> u8 + Copy,
) {
    // Horizontal pass; outside the image is background (0).
    for (r, t) in src.chunks_exact(width).zip(tmp.chunks_exact_mut(width)) {
        if width == 1 {
            t[0] = op(r[0], 0);
            continue;
        }
        t[0] = op(op(r[0], r[1]), 0);
        t[width - 1] = op(op(r[width - 2], r[width - 1]), 0);
        for (((o, &a), &b), &c) in t[1..width - 1]
            .iter_mut()
            .zip(&r[..width - 2])
            .zip(&r[1..width - 1])
            .zip(&r[2..])
        {
            *o = op(op(a, b), c);
        }
    }
    // Vertical pass.
    for y in 0..height {
        let mid = &tmp[y * width..(y + 1) * width];
        let d = &mut dst[y * width..(y + 1) * width];
        let up = if y > 0 {
            Some(&tmp[(y - 1) * width..y * width])
        } else {
            None
        };
        let dn = if y + 1 < height {
            Some(&tmp[(y + 1) * width..(y + 2) * width])
        } else {
            None
        };
        match (up, dn) {
            (Some(u), Some(w)) => {
                for (((o, &a), &b), &c) in d.iter_mut().zip(u).zip(mid).zip(w) {
                    *o = op(op(a, b), c);
                }
            }
            (Some(e), None) | (None, Some(e)) => {
                for ((o, &a), &b) in d.iter_mut().zip(e).zip(mid) {
                    *o = op(op(a, b), 0);
                }
            }
            (None, None) => {
                for (o, &b) in d.iter_mut().zip(mid) {
                    *o = op(b, 0);
                }
            }
        }
    }
}

/// 3x3 erosion of a binary mask.
pub fn erode3x3(src: &[u8], width: usize, height: usize, dst: &mut Vec<u8>, tmp: &mut Vec<u8>) {
    minmax3x3(src, width, height, dst, tmp, false);
}

/// 3x3 dilation of a binary mask.
pub fn dilate3x3(src: &[u8], width: usize, height: usize, dst: &mut Vec<u8>, tmp: &mut Vec<u8>) {
    minmax3x3(src, width, height, dst, tmp, true);
}

/// 3x3 majority filter: a pixel is on when at least 5 of the 9 pixels of its
/// neighbourhood are (outside the image counts as off). `tmp` holds column sums.
pub fn majority3x3(src: &[u8], width: usize, height: usize, dst: &mut Vec<u8>, tmp: &mut Vec<u8>) {
    let n = width * height;
    dst.resize(n, 0);
    tmp.resize(n, 0);
    if width == 0 || height == 0 || src.len() < n {
        return;
    }
    // Vertical 3-sums of 0/1 values (255 & 1 = 1).
    for y in 0..height {
        let mid = &src[y * width..(y + 1) * width];
        let t = &mut tmp[y * width..(y + 1) * width];
        for (o, &b) in t.iter_mut().zip(mid) {
            *o = b & 1;
        }
        if y > 0 {
            for (o, &a) in t.iter_mut().zip(&src[(y - 1) * width..y * width]) {
                *o += a & 1;
            }
        }
        if y + 1 < height {
            for (o, &c) in t.iter_mut().zip(&src[(y + 1) * width..(y + 2) * width]) {
                *o += c & 1;
            }
        }
    }
    let on = |s: u8| if s >= 5 { MASK_ON } else { 0 };
    for (t, d) in tmp.chunks_exact(width).zip(dst.chunks_exact_mut(width)) {
        if width == 1 {
            d[0] = on(t[0]);
            continue;
        }
        d[0] = on(t[0] + t[1]);
        d[width - 1] = on(t[width - 2] + t[width - 1]);
        for (((o, &a), &b), &c) in d[1..width - 1]
            .iter_mut()
            .zip(&t[..width - 2])
            .zip(&t[1..width - 1])
            .zip(&t[2..])
        {
            *o = on(a + b + c);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn majority_removes_specks_and_keeps_blocks() {
        let (w, h) = (12, 10);
        let mut m = vec![0u8; w * h];
        m[2 * w + 2] = MASK_ON; // speck
        for y in 4..9 {
            for x in 5..11 {
                m[y * w + x] = MASK_ON;
            }
        }
        m[6 * w + 7] = 0; // pinhole
        let (mut d, mut t) = (Vec::new(), Vec::new());
        majority3x3(&m, w, h, &mut d, &mut t);
        assert_eq!(d[2 * w + 2], 0);
        assert_eq!(d[6 * w + 7], MASK_ON);
        assert_eq!(d[6 * w + 5], MASK_ON);
        assert_eq!(d[3 * w + 7], 0);
    }

    #[test]
    fn erosion_then_dilation_of_a_block_is_the_block() {
        let (w, h) = (9, 8);
        let mut m = vec![0u8; w * h];
        for y in 2..6 {
            for x in 2..7 {
                m[y * w + x] = MASK_ON;
            }
        }
        let (mut e, mut d, mut t) = (Vec::new(), Vec::new(), Vec::new());
        erode3x3(&m, w, h, &mut e, &mut t);
        assert_eq!(e.iter().filter(|&&v| v != 0).count(), 2 * 3);
        dilate3x3(&e, w, h, &mut d, &mut t);
        assert_eq!(d, m);
    }
}
