//! The screen's own timings (milliseconds): rolling per-stage statistics over the
//! most recent samples (bounded memory and cost however long the station runs), and
//! the frame clock, which notes when each screen frame has been presented.
//!
//! A screen frame ends when eframe has submitted and presented it; the app has no hook
//! there, but egui-wgpu drops the frame's paint callbacks right after presenting, so a
//! [`FrameEndProbe`] carried by a paint callback records the end of its frame in its
//! `Drop`. From those ends come the frame rate (mean, and the 5th percentile as the
//! inverse of the 95th percentile frame interval), the time from the start of the
//! screen's work to the present, and the latency from a frame pair leaving the source
//! to the present of the screen frame that first shows its fit.

use std::sync::{Arc, Mutex};
use std::time::Instant;

/// Samples kept per stage (about a minute at 30 per second).
pub const WINDOW: usize = 2048;

/// Name of the frame-interval stage (present to present).
pub const FRAME_INTERVAL: &str = "frame interval";
/// Name of the screen-frame stage (start of the screen's work to present).
pub const FRAME_TO_PRESENT: &str = "ui to present";
/// Name of the latency stage (pair leaves the source to present of its fit).
pub const ARRIVAL_TO_PRESENT: &str = "arrival to screen";

/// Median, 5th and 95th percentiles and mean of one stage (ms) over its window.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Summary {
    pub median: f64,
    pub p5: f64,
    pub p95: f64,
    pub mean: f64,
    /// Samples in the window.
    pub count: usize,
    /// Samples ever added.
    pub total: u64,
}

#[derive(Debug, Clone)]
struct Stage {
    name: String,
    samples: Vec<f64>,
    next: usize,
    total: u64,
}

/// Rolling statistics per named stage, in first-seen order. Adding a sample to a known
/// stage allocates nothing.
#[derive(Debug, Clone, Default)]
pub struct RollingStats {
    stages: Vec<Stage>,
}

impl RollingStats {
    pub fn add(&mut self, stage: &str, ms: f64) {
        if !ms.is_finite() {
            return;
        }
        let k = match self.stages.iter().position(|s| s.name == stage) {
            Some(k) => k,
            None => {
                self.stages.push(Stage {
                    name: stage.to_string(),
                    samples: Vec::with_capacity(WINDOW),
                    next: 0,
                    total: 0,
                });
                self.stages.len() - 1
            }
        };
        let Some(s) = self.stages.get_mut(k) else {
            return;
        };
        if s.samples.len() < WINDOW {
            s.samples.push(ms);
        } else if let Some(slot) = s.samples.get_mut(s.next) {
            *slot = ms;
        }
        s.next = (s.next + 1) % WINDOW;
        s.total += 1;
    }

    pub fn add_all(&mut self, stages: &[(String, f64)]) {
        for (s, ms) in stages {
            self.add(s, *ms);
        }
    }

    /// The summary of one stage, if it has samples.
    pub fn get(&self, stage: &str) -> Option<Summary> {
        self.stages
            .iter()
            .find(|s| s.name == stage)
            .and_then(summarise)
    }

    /// Every stage with samples, first-seen order.
    pub fn summary(&self) -> Vec<(String, Summary)> {
        self.stages
            .iter()
            .filter_map(|s| summarise(s).map(|v| (s.name.clone(), v)))
            .collect()
    }
}

/// Nearest-rank percentiles of a stage's window.
fn summarise(s: &Stage) -> Option<Summary> {
    if s.samples.is_empty() {
        return None;
    }
    let mut v = s.samples.clone();
    v.sort_by(|a, b| a.total_cmp(b));
    let at = |q: f64| {
        let rank = ((q * v.len() as f64).ceil() as usize).clamp(1, v.len());
        v.get(rank - 1).copied().unwrap_or(0.0)
    };
    Some(Summary {
        median: at(0.5),
        p5: at(0.05),
        p95: at(0.95),
        mean: v.iter().sum::<f64>() / v.len() as f64,
        count: v.len(),
        total: s.total,
    })
}

/// Frame rate figures from the frame intervals.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct FrameRate {
    /// Frames per second over the window (inverse of the mean interval).
    pub mean_fps: f64,
    /// The rate that 95% of the frames reach or beat: inverse of the 95th percentile
    /// interval.
    pub p5_fps: f64,
}

impl FrameRate {
    pub fn from_intervals(s: &Summary) -> Self {
        let inv = |ms: f64| if ms > 0.0 { 1e3 / ms } else { 0.0 };
        FrameRate {
            mean_fps: inv(s.mean),
            p5_fps: inv(s.p95),
        }
    }
}

#[derive(Debug, Default)]
struct ClockState {
    last_end: Option<Instant>,
    frames: u64,
    stats: RollingStats,
}

/// Shared record of the ends of screen frames.
#[derive(Debug, Clone, Default)]
pub struct FrameClock {
    state: Arc<Mutex<ClockState>>,
}

impl FrameClock {
    /// A probe for the frame whose work started at `started`; `arrival` is when the pair
    /// behind a fit first shown in this frame left the source.
    pub fn probe(&self, started: Instant, arrival: Option<Instant>) -> FrameEndProbe {
        FrameEndProbe {
            state: self.state.clone(),
            started,
            arrival,
        }
    }

    /// Frames presented so far.
    pub fn frames(&self) -> u64 {
        self.state.lock().map(|s| s.frames).unwrap_or(0)
    }

    /// Frame intervals, frame-to-present times and latencies.
    pub fn stats(&self) -> RollingStats {
        self.state
            .lock()
            .map(|s| s.stats.clone())
            .unwrap_or_default()
    }

    /// Notes the end of a frame at `end` (what a probe does when dropped).
    #[cfg(test)]
    fn frame_ended(&self, started: Instant, arrival: Option<Instant>, end: Instant) {
        record_end(&self.state, started, arrival, end);
    }
}

fn record_end(state: &Mutex<ClockState>, started: Instant, arrival: Option<Instant>, end: Instant) {
    let Ok(mut s) = state.lock() else {
        return;
    };
    let ms = |a: Instant| end.saturating_duration_since(a).as_secs_f64() * 1e3;
    if let Some(prev) = s.last_end {
        let interval = ms(prev);
        s.stats.add(FRAME_INTERVAL, interval);
    }
    s.last_end = Some(end);
    s.frames += 1;
    let busy = ms(started);
    s.stats.add(FRAME_TO_PRESENT, busy);
    if let Some(a) = arrival {
        let latency = ms(a);
        s.stats.add(ARRIVAL_TO_PRESENT, latency);
    }
}

/// Carried by a paint callback; records the end of its frame when dropped (after the
/// frame is presented).
#[derive(Debug)]
pub struct FrameEndProbe {
    state: Arc<Mutex<ClockState>>,
    started: Instant,
    arrival: Option<Instant>,
}

impl Drop for FrameEndProbe {
    fn drop(&mut self) {
        super::trace::ev("present", 0);
        record_end(&self.state, self.started, self.arrival, Instant::now());
    }
}

/// An empty paint callback that carries a [`FrameEndProbe`]: egui-wgpu keeps it until
/// the frame is presented. Its rectangle must lie inside the window (egui culls
/// callbacks outside the clip rectangle, which would end the probe early).
pub struct FrameEndCallback {
    pub probe: FrameEndProbe,
}

impl eframe::egui_wgpu::CallbackTrait for FrameEndCallback {
    fn paint(
        &self,
        _info: egui::PaintCallbackInfo,
        _render_pass: &mut eframe::egui_wgpu::wgpu::RenderPass<'static>,
        _resources: &eframe::egui_wgpu::CallbackResources,
    ) {
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::time::Duration;

    #[test]
    fn rolling_window_forgets_old_samples() {
        let mut r = RollingStats::default();
        for k in 0..WINDOW {
            r.add("a", 1000.0 + k as f64);
        }
        for _ in 0..WINDOW {
            r.add("a", 1.0);
        }
        r.add("b", 5.0);
        let a = r.get("a").expect("a");
        assert_eq!((a.median, a.p95, a.count), (1.0, 1.0, WINDOW));
        assert_eq!(a.total, 2 * WINDOW as u64);
        let names: Vec<String> = r.summary().into_iter().map(|(n, _)| n).collect();
        assert_eq!(names, ["a", "b"]);
        assert!(r.get("c").is_none());
    }

    #[test]
    fn percentiles_and_rates() {
        let mut r = RollingStats::default();
        for k in 1..=100 {
            r.add("x", k as f64);
        }
        let s = r.get("x").expect("x");
        assert_eq!((s.p5, s.median, s.p95), (5.0, 50.0, 95.0));
        assert!((s.mean - 50.5).abs() < 1e-9);
        let f = FrameRate::from_intervals(&s);
        assert!((f.mean_fps - 1e3 / 50.5).abs() < 1e-9);
        assert!((f.p5_fps - 1e3 / 95.0).abs() < 1e-9);
    }

    #[test]
    fn a_dropped_probe_records_its_frame() {
        let clock = FrameClock::default();
        let t0 = Instant::now();
        let arrival = t0.checked_sub(Duration::from_millis(40));
        drop(clock.probe(t0, arrival));
        assert_eq!(clock.frames(), 1);
        // A second frame, ended at a given time.
        let t1 = t0 + Duration::from_millis(10);
        clock.frame_ended(t1, None, t1 + Duration::from_millis(5));
        let st = clock.stats();
        assert_eq!(clock.frames(), 2);
        assert_eq!(st.get(FRAME_INTERVAL).map(|s| s.count), Some(1));
        assert_eq!(st.get(FRAME_TO_PRESENT).map(|s| s.count), Some(2));
        let lat = st.get(ARRIVAL_TO_PRESENT).expect("latency");
        assert_eq!(lat.count, 1);
        if arrival.is_some() {
            assert!(lat.median >= 40.0, "{}", lat.median);
        }
    }
}
