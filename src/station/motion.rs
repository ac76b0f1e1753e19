//! A still-picture gate (issue 20: a person walking behind the shopper neither breaks
//! the fit nor is measured). A shopper holding the pose sways by a pixel or two between
//! frames; someone walking behind who merges with the shopper's outline, or a shopper
//! moving, changes it by a large share. The station compares each view's final person
//! mask with the previous frame's and does not measure a pair whose outline moved:
//! [`crate::landmarks::Verdict::Moving`]. The last measurements stay on screen.
//!
//! Measured on synthetic recordings (dev seeds 20000-20011, 20200-20205 camouflaged and
//! 20500-20505 with a passer-by; the station's masks): a still subject changes 0.2-1.2 %
//! of its mask's area between frames, up to 7 % where camouflaged clothing flickers in
//! and out of the backdrop model's mask; a passer-by merged with the outline 20-72 %.

use crate::camera::View;
use crate::imgproc::Mask;
use crate::landmarks::Verdict;

/// Share of the person's mask area (pixels that changed between two frames over the
/// current area) above which the outline is taken as moving: halfway (on a log scale)
/// between a camouflaged still subject's flicker (7 %) and the least a merged passer-by
/// changed (20 %; see the module docs).
pub const MAX_STILL_CHANGE: f64 = 0.1;

/// The previous frame's person masks and the last measured change.
#[derive(Debug, Default)]
pub struct MotionGate {
    prev: [Mask; 2],
    /// Share of the area that changed in the last frame, per view (front, side); None
    /// where there was nothing to compare.
    pub change: [Option<f64>; 2],
}

impl MotionGate {
    /// Compares `masks` (front, side) with the previous frame's, keeps them for the next
    /// frame, and pushes [`Verdict::Moving`] for each view whose outline moved. A view
    /// without a person in this frame or the previous one gives no verdict (the first
    /// frame of a shopper on the mark is judged by the other verdicts alone).
    pub fn observe(&mut self, masks: [&Mask; 2], verdicts: &mut Vec<Verdict>) {
        for (k, view) in View::BOTH.into_iter().enumerate() {
            let (prev, now) = (&mut self.prev[k], masks[k]);
            self.change[k] = changed_share(prev, now);
            if self.change[k].is_some_and(|c| c > MAX_STILL_CHANGE) {
                verdicts.push(Verdict::Moving { view });
            }
            prev.width = now.width;
            prev.height = now.height;
            prev.data.clear();
            prev.data.extend_from_slice(&now.data);
        }
    }

    /// Forgets the previous frame (a new subject, a scene learned again).
    pub fn reset(&mut self) {
        for m in &mut self.prev {
            m.data.clear();
        }
        self.change = [None; 2];
    }
}

/// Pixels that differ between `prev` and `now` over the area of `now`; None when
/// either is empty or they differ in size.
fn changed_share(prev: &Mask, now: &Mask) -> Option<f64> {
    if prev.width != now.width || prev.height != now.height || prev.data.len() != now.data.len() {
        return None;
    }
    // One pass over both masks (the per-frame path): the area of each and their
    // difference, counted in byte lanes over blocks short enough not to overflow them
    // (the compiler vectorises a byte-wide count; a word-wide one runs ten times slower).
    const BLOCK: usize = 255 * 32;
    let (mut area, mut prev_area, mut changed) = (0usize, 0usize, 0usize);
    for (pa, na) in prev.data.chunks(BLOCK).zip(now.data.chunks(BLOCK)) {
        let (mut p, mut n, mut c) = ([0u8; 32], [0u8; 32], [0u8; 32]);
        let (pc, nc) = (pa.chunks_exact(32), na.chunks_exact(32));
        let (pr, nr) = (pc.remainder(), nc.remainder());
        for (x, y) in pc.zip(nc) {
            for k in 0..32 {
                let (a, b) = ((x[k] != 0) as u8, (y[k] != 0) as u8);
                p[k] += a;
                n[k] += b;
                c[k] += a ^ b;
            }
        }
        let sum = |v: [u8; 32]| v.iter().map(|&x| x as usize).sum::<usize>();
        prev_area += sum(p);
        area += sum(n);
        changed += sum(c);
        for (x, y) in pr.iter().zip(nr) {
            let (a, b) = ((*x != 0) as usize, (*y != 0) as usize);
            prev_area += a;
            area += b;
            changed += a ^ b;
        }
    }
    (area > 0 && prev_area > 0).then(|| changed as f64 / area as f64)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn disc(w: u32, h: u32, cx: f64, r: f64) -> Mask {
        let mut m = Mask::new(w, h);
        for y in 0..h {
            for x in 0..w {
                let (dx, dy) = (x as f64 - cx, y as f64 - h as f64 / 2.0);
                if dx * dx + dy * dy <= r * r {
                    m.data[(y * w + x) as usize] = 255;
                }
            }
        }
        m
    }

    #[test]
    fn a_sway_passes_and_a_walker_joining_the_outline_does_not() {
        let mut gate = MotionGate::default();
        let mut v = Vec::new();
        let still = disc(200, 200, 100.0, 60.0);
        let empty = Mask::new(200, 200);
        // Stepping on: nothing to compare. Then a one-pixel sway: still.
        gate.observe([&still, &empty], &mut v);
        assert!(v.is_empty() && gate.change == [None, None]);
        gate.observe([&disc(200, 200, 101.0, 60.0), &empty], &mut v);
        assert!(v.is_empty(), "{v:?} {:?}", gate.change);
        // Someone merging with the outline on the right.
        let mut merged = disc(200, 200, 101.0, 60.0);
        let walker = disc(200, 200, 170.0, 25.0);
        for (m, w) in merged.data.iter_mut().zip(&walker.data) {
            *m |= *w;
        }
        gate.observe([&merged, &empty], &mut v);
        assert_eq!(v, vec![Verdict::Moving { view: View::Front }]);
        assert!(gate.change[1].is_none());
    }

    #[test]
    fn the_lane_count_equals_a_plain_count() {
        // Sizes that are not multiples of the lanes or the blocks, any non-zero value
        // counting as person, and whole blocks of person (where a byte lane would wrap).
        let mut state = 0x9e37_79b9_7f4a_7c15u64;
        let mut next = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            state
        };
        for (w, h) in [(97, 131), (720, 1280), (1, 33)] {
            let (mut prev, mut now) = (Mask::new(w, h), Mask::new(w, h));
            for (i, (a, b)) in prev.data.iter_mut().zip(now.data.iter_mut()).enumerate() {
                let r = next();
                *a = if i < 40_000 {
                    255
                } else {
                    (r & 0xff) as u8 & 0x81
                };
                *b = if i < 20_000 {
                    1
                } else {
                    ((r >> 8) & 0xff) as u8 & 0x81
                };
            }
            let (mut area, mut changed) = (0usize, 0usize);
            for (a, b) in prev.data.iter().zip(&now.data) {
                area += (*b != 0) as usize;
                changed += ((*a != 0) != (*b != 0)) as usize;
            }
            let want = changed as f64 / area as f64;
            let got = changed_share(&prev, &now).expect("both have a person");
            assert_eq!(got, want, "{w} x {h}");
        }
    }
}
