//! Steps 1 and 2: saddle response with non-maximum suppression, and the ring test that
//! keeps X-junctions and gives their two edge directions.

use super::*;

impl CornerDetector {
    /// Step 1 and 2: saddle peaks that pass the ring test, refined to sub-pixel.
    pub(super) fn find_candidates(&mut self, sigma: f64) {
        let (w, h) = (self.w, self.h);
        blur_f32(&self.gray, &mut self.smooth, &mut self.tmp, w, h, sigma);
        let s = &self.smooth;
        let mut max_r = 0.0f32;
        for y in 1..h - 1 {
            for x in 1..w - 1 {
                let i = y * w + x;
                let ixx = s[i + 1] - 2.0 * s[i] + s[i - 1];
                let iyy = s[i + w] - 2.0 * s[i] + s[i - w];
                let ixy = 0.25 * (s[i + w + 1] - s[i + w - 1] - s[i - w + 1] + s[i - w - 1]);
                let r = (ixy * ixy - ixx * iyy).max(0.0);
                self.resp[i] = r;
                max_r = max_r.max(r);
            }
        }
        for x in 0..w {
            self.resp[x] = 0.0;
            self.resp[(h - 1) * w + x] = 0.0;
        }
        for y in 0..h {
            self.resp[y * w] = 0.0;
            self.resp[y * w + w - 1] = 0.0;
        }
        let thr = max_r * RESPONSE_FRACTION;
        let ring_r = (2.5 * sigma).max(3.5);
        let border = (ring_r.ceil() as usize + 2).max(NMS_RADIUS_PX as usize + 1);
        let mut peaks: Vec<(f32, usize, usize)> = Vec::new();
        if max_r > 0.0 && w > 2 * border && h > 2 * border {
            for y in border..h - border {
                for x in border..w - border {
                    let r = self.resp[y * w + x];
                    if r <= thr {
                        continue;
                    }
                    let mut is_max = true;
                    'win: for dy in -NMS_RADIUS_PX..=NMS_RADIUS_PX {
                        for dx in -NMS_RADIUS_PX..=NMS_RADIUS_PX {
                            if dx == 0 && dy == 0 {
                                continue;
                            }
                            let j = ((y as isize + dy) as usize) * w + (x as isize + dx) as usize;
                            let o = self.resp[j];
                            // Ties broken by index so that plateaus keep one peak.
                            if o > r || (o == r && j < y * w + x) {
                                is_max = false;
                                break 'win;
                            }
                        }
                    }
                    if is_max {
                        peaks.push((r, x, y));
                    }
                }
            }
        }
        peaks.sort_by(|a, b| b.0.total_cmp(&a.0));
        peaks.truncate(MAX_CANDIDATES);
        self.cands.clear();
        for (r, x, y) in peaks {
            let p0 = DVec2::new(x as f64, y as f64);
            // The cheap ring test first; sub-pixel refinement only for survivors.
            let Some((dir_a, dir_b)) = self.ring_test(p0, ring_r) else {
                continue;
            };
            let half = (2.0 * sigma)
                .round()
                .clamp(2.0, MAX_SUBPIX_HALF_WINDOW as f64) as i32;
            let Some(p) = self.subpix(p0, half) else {
                continue;
            };
            if (p - p0).length() > 2.0 * sigma.max(1.0) {
                continue;
            }
            self.cands.push(Candidate {
                pos: p,
                response: r,
                dir_a,
                dir_b,
            });
        }
        self.used.clear();
        self.used.resize(self.cands.len(), false);
    }

    /// Ring test on the smoothed image; returns the two edge directions.
    pub(super) fn ring_test(&self, p: DVec2, radius: f64) -> Option<(DVec2, DVec2)> {
        let mut vals = [0.0f64; RING_SAMPLES];
        let step = std::f64::consts::TAU / RING_SAMPLES as f64;
        for (k, v) in vals.iter_mut().enumerate() {
            let a = k as f64 * step;
            *v = sample(
                &self.smooth,
                self.w,
                self.h,
                p + DVec2::new(a.cos(), a.sin()) * radius,
            )?;
        }
        let lo = vals.iter().copied().fold(f64::INFINITY, f64::min);
        let hi = vals.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        if hi - lo < MIN_RING_CONTRAST {
            return None;
        }
        let mid = 0.5 * (lo + hi);
        let mut crossings = [0.0f64; 4];
        let mut n = 0;
        let mut last_cross = None;
        let mut shortest_run = usize::MAX;
        for k in 0..RING_SAMPLES {
            let (a, b) = (vals[k], vals[(k + 1) % RING_SAMPLES]);
            if (a > mid) != (b > mid) {
                if n == 4 {
                    return None;
                }
                let f = (mid - a) / (b - a);
                crossings[n] = (k as f64 + f) * step;
                if let Some(l) = last_cross {
                    shortest_run = shortest_run.min(k - l);
                }
                last_cross = Some(k);
                n += 1;
            }
        }
        if n != 4 {
            return None;
        }
        // The wrap-around run.
        if let Some(l) = last_cross {
            let first = (crossings[0] / step).floor() as usize;
            shortest_run = shortest_run.min(first + RING_SAMPLES - l);
        }
        if shortest_run < 2 {
            return None;
        }
        let unit = |a: f64| DVec2::new(a.cos(), a.sin());
        let bend = MAX_EDGE_BEND_DEG.to_radians().cos();
        if unit(crossings[0]).dot(unit(crossings[2])) > -bend
            || unit(crossings[1]).dot(unit(crossings[3])) > -bend
        {
            return None;
        }
        let dir_a = (unit(crossings[0]) - unit(crossings[2])).normalize_or_zero();
        let dir_b = (unit(crossings[1]) - unit(crossings[3])).normalize_or_zero();
        if dir_a.dot(dir_b).abs() > MIN_EDGE_ANGLE_DEG.to_radians().cos() {
            return None;
        }
        Some((dir_a, dir_b))
    }
}
