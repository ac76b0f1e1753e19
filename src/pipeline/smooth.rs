//! Measurement smoothing over frames: each measurement keeps a short window of recent
//! values; the shown value is their trimmed mean (the mean of the window without its
//! [`TRIM`] lowest and highest values: robust to bad frames like a median, but it moves
//! smoothly where a median jumps between neighbouring order statistics) and the
//! stability is their spread (max - min, mm), which falls as the fit settles.

use std::collections::VecDeque;

/// Frames a measurement's window holds.
pub const WINDOW: usize = 9;
/// Values dropped from each end of the sorted window before averaging (a full window
/// tolerates this many bad frames on either side).
pub const TRIM: usize = 2;

/// A sliding window of one measurement's recent values (mm).
#[derive(Debug, Clone, Default)]
pub struct SmoothedValue {
    recent: VecDeque<f64>,
}

impl SmoothedValue {
    pub fn push(&mut self, value_mm: f64) {
        if !value_mm.is_finite() {
            return;
        }
        if self.recent.len() == WINDOW {
            self.recent.pop_front();
        }
        self.recent.push_back(value_mm);
    }
    /// Trimmed mean of the window (None before the first value): [`TRIM`] values dropped
    /// from each end, fewer while the window is filling (always at least one kept).
    pub fn value(&self) -> Option<f64> {
        if self.recent.is_empty() {
            return None;
        }
        let mut v: Vec<f64> = self.recent.iter().copied().collect();
        v.sort_by(|a, b| a.total_cmp(b));
        let n = v.len();
        let trim = TRIM.min((n - 1) / 2);
        let kept = &v[trim..n - trim];
        Some(kept.iter().sum::<f64>() / kept.len() as f64)
    }
    /// Spread of the window (mm); infinite until three values are in.
    pub fn stability(&self) -> f64 {
        if self.recent.len() < 3 {
            return f64::INFINITY;
        }
        let lo = self.recent.iter().copied().fold(f64::MAX, f64::min);
        let hi = self.recent.iter().copied().fold(f64::MIN, f64::max);
        hi - lo
    }
    /// Standard deviation of the window's values (mm); 0 with fewer than two.
    pub fn std_dev(&self) -> f64 {
        let n = self.recent.len();
        if n < 2 {
            return 0.0;
        }
        let mean = self.recent.iter().sum::<f64>() / n as f64;
        let ss: f64 = self.recent.iter().map(|v| (v - mean) * (v - mean)).sum();
        (ss / (n - 1) as f64).sqrt()
    }
    /// Largest change between consecutive values in the window (mm).
    pub fn max_step(&self) -> f64 {
        self.recent
            .iter()
            .zip(self.recent.iter().skip(1))
            .map(|(a, b)| (b - a).abs())
            .fold(0.0, f64::max)
    }
    pub fn len(&self) -> usize {
        self.recent.len()
    }
    pub fn is_empty(&self) -> bool {
        self.recent.is_empty()
    }
    pub fn clear(&mut self) {
        self.recent.clear();
    }
}

/// Named 3-D points (landmarks, metres) smoothed coordinate by coordinate with a
/// [`SmoothedValue`] each: a subject holding still has one set of landmarks, and a single
/// frame's crotch or armpit (a gap closed by a few pixels) does not move them.
#[derive(Debug, Clone, Default)]
pub struct SmoothedPoints {
    windows: Vec<(String, [SmoothedValue; 3])>,
}

impl SmoothedPoints {
    /// Adds one frame's points (a name not seen this frame keeps its window).
    pub fn push<'a>(&mut self, points: impl IntoIterator<Item = (&'a str, glam::DVec3)>) {
        for (name, p) in points {
            let k = match self.windows.iter().position(|(n, _)| n == name) {
                Some(k) => k,
                None => {
                    self.windows.push((name.to_string(), Default::default()));
                    self.windows.len() - 1
                }
            };
            for (w, v) in self.windows[k].1.iter_mut().zip(p.to_array()) {
                // Millimetres, the unit SmoothedValue documents.
                w.push(1e3 * v);
            }
        }
    }
    /// The smoothed points (metres), in the order first seen.
    pub fn values(&self) -> Vec<(String, glam::DVec3)> {
        self.windows
            .iter()
            .filter_map(|(name, [x, y, z])| {
                Some((
                    name.clone(),
                    glam::DVec3::new(x.value()?, y.value()?, z.value()?) * 1e-3,
                ))
            })
            .collect()
    }
    pub fn clear(&mut self) {
        self.windows.clear();
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec3;

    #[test]
    fn smoothed_points_ignore_a_single_frames_outlier() {
        let mut s = SmoothedPoints::default();
        assert!(s.values().is_empty());
        let armpit = DVec3::new(0.17, 1.25, -0.11);
        for k in 0..5 {
            // Frame 2's armpit is 15 mm low (its gap closed by a few pixels); the crotch
            // is only seen from frame 1 on.
            let y = if k == 2 { armpit.y - 0.015 } else { armpit.y };
            let mut frame = vec![("armpit_left", DVec3::new(armpit.x, y, armpit.z))];
            if k >= 1 {
                frame.push(("crotch", DVec3::new(0.0, 0.8, -0.1)));
            }
            s.push(frame);
        }
        let v = s.values();
        assert_eq!(v.len(), 2);
        assert_eq!(v[0].0, "armpit_left");
        assert!((v[0].1 - armpit).length() < 1e-9, "{:?}", v[0].1);
        assert!((v[1].1 - DVec3::new(0.0, 0.8, -0.1)).length() < 1e-9);
        s.clear();
        assert!(s.values().is_empty());
    }

    #[test]
    fn trimmed_mean_ignores_outliers_and_stability_settles() {
        let mut s = SmoothedValue::default();
        assert_eq!(s.value(), None);
        for v in [900.0, 901.0, 1500.0, 899.0, 900.5] {
            s.push(v);
        }
        // Five values: one dropped from each end; the outlier goes.
        assert!((s.value().unwrap() - (900.0 + 900.5 + 901.0) / 3.0).abs() < 1e-9);
        for v in [10.0, 2000.0, 901.0, 900.0] {
            s.push(v);
        }
        // A full window tolerates two outliers on one side and one on the other.
        let v = s.value().unwrap();
        assert!((899.0..=901.0).contains(&v), "{v}");
        assert!(s.stability() > 500.0);
        for _ in 0..WINDOW {
            s.push(900.0);
        }
        assert_eq!(s.stability(), 0.0);
        assert_eq!(s.max_step(), 0.0);
        s.push(f64::NAN);
        assert_eq!(s.len(), WINDOW);
    }
}
