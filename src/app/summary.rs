//! What a run of the screen did, printed by the CLI at exit: frames, rates, latencies
//! and the CPU time of the process and its threads.

use super::stats;
use std::path::PathBuf;

/// Figures of a run, printed by the CLI at exit.
#[derive(Debug, Clone, Default)]
pub struct RunSummary {
    pub ui_frames: u64,
    pub seconds: f64,
    pub snapshots_shown: u64,
    pub dropped_pairs: u64,
    /// Frame-rate of new snapshots shown over the last second before exit.
    pub recent_snapshot_fps: f64,
    pub recent_ui_fps: f64,
    pub screenshot: Option<PathBuf>,
    /// Median / p95 of the screen's own work per frame (ms).
    pub ui_timings: Vec<(String, f64, f64)>,
    /// CPU time of the whole process (all threads: source, processor, screen, the
    /// software renderer), seconds, where the OS tells it.
    pub cpu_seconds: Option<f64>,
    /// CPU seconds per thread group (`capture`, `process`, the screen's main thread,
    /// `llvmpipe` for Mesa's software rasteriser...), live threads only.
    pub thread_cpu: Vec<(String, f64)>,
    /// Screen frames presented (see [`stats`]).
    pub presented_frames: u64,
    /// Frame rate from the intervals between presents (over the last
    /// [`stats::WINDOW`] frames).
    pub frame_rate: Option<stats::FrameRate>,
    /// From the start of the screen's work on a frame to its present (ms).
    pub frame_to_present: Option<stats::Summary>,
    /// From a frame pair leaving the source to the present of the screen frame that
    /// first shows its fit (ms).
    pub latency: Option<stats::Summary>,
}

/// User + system CPU seconds of this process from `/proc/self/stat` (Linux).
pub(super) fn process_cpu_seconds() -> Option<f64> {
    let stat = std::fs::read_to_string("/proc/self/stat").ok()?;
    // Fields after the parenthesised command name; utime and stime are fields 14, 15.
    let rest = stat.get(stat.rfind(')')? + 2..)?;
    let f: Vec<&str> = rest.split_whitespace().collect();
    let utime: f64 = f.get(11)?.parse().ok()?;
    let stime: f64 = f.get(12)?.parse().ok()?;
    // Linux reports clock ticks of USER_HZ, 100 on every mainstream configuration.
    const USER_HZ: f64 = 100.0;
    Some((utime + stime) / USER_HZ)
}

impl std::fmt::Display for RunSummary {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let rate = |n: u64| {
            if self.seconds > 0.0 {
                n as f64 / self.seconds
            } else {
                0.0
            }
        };
        writeln!(
            f,
            "ui: {} frames in {:.2} s ({:.1} fps mean, {:.1} fps last second); snapshots shown {} ({:.1}/s mean, {:.1}/s last second); pairs dropped {}",
            self.ui_frames,
            self.seconds,
            rate(self.ui_frames),
            self.recent_ui_fps,
            self.snapshots_shown,
            rate(self.snapshots_shown),
            self.recent_snapshot_fps,
            self.dropped_pairs
        )?;
        if let Some(r) = &self.frame_rate {
            writeln!(
                f,
                "screen: {:.1} fps mean, {:.1} fps p5 (from {} presented frames){}",
                r.mean_fps,
                r.p5_fps,
                self.presented_frames,
                self.frame_to_present
                    .map(|s| format!(
                        "; start of work to present median {:.1} ms, p95 {:.1} ms",
                        s.median, s.p95
                    ))
                    .unwrap_or_default()
            )?;
        }
        if let Some(l) = &self.latency {
            writeln!(
                f,
                "latency, pair leaves the source to its fit presented: median {:.1} ms, p95 {:.1} ms ({} fits)",
                l.median, l.p95, l.count
            )?;
        }
        if let Some(cpu) = self.cpu_seconds {
            writeln!(
                f,
                "cpu: {cpu:.2} s over {:.2} s wall ({:.0}% of one core)",
                self.seconds,
                if self.seconds > 0.0 {
                    100.0 * cpu / self.seconds
                } else {
                    0.0
                }
            )?;
        }
        if !self.thread_cpu.is_empty() && self.ui_frames > 0 {
            let per: Vec<String> = self
                .thread_cpu
                .iter()
                .filter(|(_, c)| *c > 0.0)
                .map(|(n, c)| format!("{n} {:.1}", 1e3 * c / self.ui_frames as f64))
                .collect();
            writeln!(f, "cpu ms per screen frame by thread: {}", per.join(", "))?;
        }
        for (s, med, p95) in &self.ui_timings {
            writeln!(f, "stage {s}: median {med:.2} ms, p95 {p95:.2} ms")?;
        }
        if let Some(p) = &self.screenshot {
            writeln!(f, "screenshot: {}", p.display())?;
        }
        Ok(())
    }
}

/// CPU seconds of this process's live threads grouped by name, numbered workers
/// together ("llvmpipe-0", "llvmpipe-1" -> "llvmpipe"), from `/proc/self/task` (Linux;
/// empty elsewhere). Sorted by CPU time, largest first.
pub fn thread_cpu_seconds() -> Vec<(String, f64)> {
    const USER_HZ: f64 = 100.0;
    let mut groups: Vec<(String, f64)> = Vec::new();
    let Ok(dir) = std::fs::read_dir("/proc/self/task") else {
        return groups;
    };
    for entry in dir.flatten() {
        let Ok(stat) = std::fs::read_to_string(entry.path().join("stat")) else {
            continue;
        };
        let (Some(open), Some(close)) = (stat.find('('), stat.rfind(')')) else {
            continue;
        };
        let name = stat.get(open + 1..close).unwrap_or("?");
        let group = name
            .trim_end_matches(|c: char| c.is_ascii_digit())
            .trim_end_matches(['-', ':', ' '])
            .to_string();
        let f: Vec<&str> = stat
            .get(close + 2..)
            .unwrap_or("")
            .split_whitespace()
            .collect();
        let ticks = |k: usize| f.get(k).and_then(|v| v.parse::<f64>().ok()).unwrap_or(0.0);
        let secs = (ticks(11) + ticks(12)) / USER_HZ;
        match groups.iter_mut().find(|(g, _)| *g == group) {
            Some((_, s)) => *s += secs,
            None => groups.push((group, secs)),
        }
    }
    groups.sort_by(|a, b| b.1.total_cmp(&a.1));
    groups
}
