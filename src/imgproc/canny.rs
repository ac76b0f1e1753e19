//! Canny edge detection (the paper's edge step, method.md section 5), following the
//! conventions of `cv2.Canny(gray, low, high)` so the two can be compared pixel by pixel:
//! 3x3 Sobel with replicated borders, L1 gradient magnitude `|dx| + |dy|`, non-maximum
//! suppression in four direction sectors split at tan(22.5 deg), hysteresis from pixels
//! above `high` through 8-connected pixels above `low`. No smoothing is applied (as
//! OpenCV): blur first if the image is noisy.

/// tan(22.5 deg) in Q15, as OpenCV's sector test.
const TAN22_Q15: i64 = 13573;

/// Scratch buffers of [`canny`], reused between frames.
#[derive(Debug, Clone, Default)]
pub struct CannyScratch {
    dx: Vec<i16>,
    dy: Vec<i16>,
    mag: Vec<i32>,
    /// 0 = candidate, 1 = not an edge, 2 = edge.
    state: Vec<u8>,
    stack: Vec<usize>,
}

const NOT_EDGE: u8 = 1;
const CANDIDATE: u8 = 0;
const EDGE: u8 = 2;

/// Canny edges of a grey image (`width * height` bytes) into `out` (0/255).
/// `low`/`high` are thresholds on the L1 gradient magnitude (swapped if reversed).
pub fn canny(
    gray: &[u8],
    width: usize,
    height: usize,
    low: f64,
    high: f64,
    out: &mut Vec<u8>,
    s: &mut CannyScratch,
) {
    let n = width * height;
    out.clear();
    out.resize(n, 0);
    if width == 0 || height == 0 || gray.len() < n {
        return;
    }
    let (low, high) = if low > high { (high, low) } else { (low, high) };
    let (low, high) = (low.floor() as i32, high.floor() as i32);
    s.dx.resize(n, 0);
    s.dy.resize(n, 0);
    s.mag.resize(n, 0);
    s.state.clear();
    s.state.resize(n, NOT_EDGE);
    let px = |x: isize, y: isize| -> i32 {
        let xc = x.clamp(0, width as isize - 1) as usize;
        let yc = y.clamp(0, height as isize - 1) as usize;
        gray[yc * width + xc] as i32
    };
    for y in 0..height as isize {
        for x in 0..width as isize {
            let gx = (px(x + 1, y - 1) - px(x - 1, y - 1))
                + 2 * (px(x + 1, y) - px(x - 1, y))
                + (px(x + 1, y + 1) - px(x - 1, y + 1));
            let gy = (px(x - 1, y + 1) - px(x - 1, y - 1))
                + 2 * (px(x, y + 1) - px(x, y - 1))
                + (px(x + 1, y + 1) - px(x + 1, y - 1));
            let i = y as usize * width + x as usize;
            s.dx[i] = gx as i16;
            s.dy[i] = gy as i16;
            s.mag[i] = gx.abs() + gy.abs();
        }
    }
    // Magnitude outside the image is 0.
    let mag = |x: isize, y: isize| -> i32 {
        if x < 0 || y < 0 || x >= width as isize || y >= height as isize {
            0
        } else {
            s.mag[y as usize * width + x as usize]
        }
    };
    s.stack.clear();
    for y in 0..height as isize {
        for x in 0..width as isize {
            let i = y as usize * width + x as usize;
            let m = s.mag[i];
            if m <= low {
                continue;
            }
            let (xs, ys) = (s.dx[i] as i64, s.dy[i] as i64);
            let ax = xs.abs();
            let ay = ys.abs() << 15;
            let tg22x = ax * TAN22_Q15;
            let is_max = if ay < tg22x {
                m > mag(x - 1, y) && m >= mag(x + 1, y)
            } else if ay > tg22x + (ax << 16) {
                m > mag(x, y - 1) && m >= mag(x, y + 1)
            } else {
                let sgn: isize = if (xs ^ ys) < 0 { -1 } else { 1 };
                m > mag(x - sgn, y - 1) && m > mag(x + sgn, y + 1)
            };
            if !is_max {
                continue;
            }
            if m > high {
                s.state[i] = EDGE;
                s.stack.push(i);
            } else {
                s.state[i] = CANDIDATE;
            }
        }
    }
    // Hysteresis.
    while let Some(i) = s.stack.pop() {
        let (x, y) = ((i % width) as isize, (i / width) as isize);
        for dy in -1..=1isize {
            for dx in -1..=1isize {
                let (nx, ny) = (x + dx, y + dy);
                if nx < 0 || ny < 0 || nx >= width as isize || ny >= height as isize {
                    continue;
                }
                let j = ny as usize * width + nx as usize;
                if s.state[j] == CANDIDATE {
                    s.state[j] = EDGE;
                    s.stack.push(j);
                }
            }
        }
    }
    for (o, &st) in out.iter_mut().zip(&s.state) {
        *o = if st == EDGE { super::MASK_ON } else { 0 };
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_step_gives_one_thin_edge() {
        let (w, h) = (20, 10);
        let img: Vec<u8> = (0..w * h)
            .map(|i| if i % w < 10 { 20 } else { 200 })
            .collect();
        let (mut out, mut s) = (Vec::new(), CannyScratch::default());
        canny(&img, w, h, 50.0, 150.0, &mut out, &mut s);
        for y in 0..h {
            let on: Vec<usize> = (0..w).filter(|&x| out[y * w + x] != 0).collect();
            assert_eq!(on.len(), 1, "row {y}: {on:?}");
            assert!(on[0] == 9 || on[0] == 10);
        }
    }

    #[test]
    fn a_flat_image_has_no_edges() {
        let (w, h) = (8, 8);
        let img = vec![128u8; w * h];
        let (mut out, mut s) = (Vec::new(), CannyScratch::default());
        canny(&img, w, h, 10.0, 30.0, &mut out, &mut s);
        assert!(out.iter().all(|&v| v == 0));
    }
}
