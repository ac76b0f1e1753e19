//! Per-stage timing: a stopwatch for one frame and running statistics (median, p95, mean)
//! over a run, as written to `report.json` under `timings_ms`.

use std::collections::BTreeMap;
use std::time::Instant;

/// Times the stages of one frame in order.
#[derive(Debug)]
pub struct FrameTimer {
    last: Instant,
    stages: Vec<(String, f64)>,
}

impl Default for FrameTimer {
    fn default() -> Self {
        Self::start()
    }
}

impl FrameTimer {
    pub fn start() -> Self {
        FrameTimer {
            last: Instant::now(),
            stages: Vec::new(),
        }
    }
    /// Closes the current stage under `name`; returns its duration in ms.
    pub fn lap(&mut self, name: &str) -> f64 {
        let now = Instant::now();
        let ms = (now - self.last).as_secs_f64() * 1e3;
        self.last = now;
        self.stages.push((name.to_string(), ms));
        ms
    }
    /// Restarts the clock without recording (e.g. after waiting for a frame).
    pub fn skip(&mut self) {
        self.last = Instant::now();
    }
    pub fn stages(&self) -> &[(String, f64)] {
        &self.stages
    }
    pub fn into_stages(self) -> Vec<(String, f64)> {
        self.stages
    }
}

/// Collected durations per stage over a run.
#[derive(Debug, Default, Clone)]
pub struct TimingStats {
    samples: BTreeMap<String, Vec<f64>>,
    order: Vec<String>,
}

/// Median, 95th percentile and mean of one stage, milliseconds, over the `count` frames
/// that ran it (a stage that runs on some frames only, as the person network, costs
/// `mean * count / frames` a frame on average).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct StageSummary {
    pub median: f64,
    pub p95: f64,
    pub mean: f64,
    pub count: usize,
}

impl TimingStats {
    pub fn add(&mut self, stage: &str, ms: f64) {
        if !self.samples.contains_key(stage) {
            self.order.push(stage.to_string());
        }
        self.samples.entry(stage.to_string()).or_default().push(ms);
    }
    pub fn add_all(&mut self, stages: &[(String, f64)]) {
        for (s, ms) in stages {
            self.add(s, *ms);
        }
    }
    /// Stages in first-seen order with their summaries.
    pub fn summary(&self) -> Vec<(String, StageSummary)> {
        self.order
            .iter()
            .filter_map(|s| {
                let v = self.samples.get(s)?;
                Some((
                    s.clone(),
                    StageSummary {
                        median: percentile(v, 0.5),
                        p95: percentile(v, 0.95),
                        mean: v.iter().sum::<f64>() / v.len().max(1) as f64,
                        count: v.len(),
                    },
                ))
            })
            .collect()
    }
    /// The `timings_ms` object of `report.json`.
    pub fn to_json(&self) -> serde_json::Value {
        let mut m = serde_json::Map::new();
        for (s, sum) in self.summary() {
            m.insert(
                s,
                serde_json::json!({
                    "median": round3(sum.median),
                    "p95": round3(sum.p95),
                    "mean": round3(sum.mean),
                    "count": sum.count,
                }),
            );
        }
        serde_json::Value::Object(m)
    }
}

fn round3(v: f64) -> f64 {
    (v * 1000.0).round() / 1000.0
}

/// Nearest-rank percentile of unsorted samples (0 for none).
pub fn percentile(samples: &[f64], q: f64) -> f64 {
    if samples.is_empty() {
        return 0.0;
    }
    let mut v = samples.to_vec();
    v.sort_by(|a, b| a.total_cmp(b));
    let rank = ((q * v.len() as f64).ceil() as usize).clamp(1, v.len());
    v[rank - 1]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn percentiles() {
        let v: Vec<f64> = (1..=100).map(|i| i as f64).collect();
        assert_eq!(percentile(&v, 0.5), 50.0);
        assert_eq!(percentile(&v, 0.95), 95.0);
        assert_eq!(percentile(&[], 0.5), 0.0);
        let mut t = TimingStats::default();
        t.add("segment", 2.0);
        t.add("fit", 5.0);
        t.add("segment", 4.0);
        let s = t.summary();
        assert_eq!(s[0].0, "segment");
        assert_eq!(s[0].1.median, 2.0);
        assert_eq!(s[0].1.p95, 4.0);
        assert_eq!((s[0].1.mean, s[0].1.count), (3.0, 2));
        assert_eq!((s[1].1.mean, s[1].1.count), (5.0, 1));
        let j = t.to_json();
        assert_eq!(j["segment"]["mean"], 3.0);
        assert_eq!(j["segment"]["count"], 2);
    }
}
