//! Two cameras as one [`crate::pipeline::FrameSource`]: frames from the front and side
//! cameras are paired by capture timestamp ([`PairMatcher`]), and a camera that drops
//! out is reopened on a backoff schedule ([`Reconnector`]) while the screen shows it.
//!
//! The pairing and reconnect logic are pure (time is passed in, seconds on one monotonic
//! clock) and tested in the default build. The capture workers that run them over two
//! devices ([`device::DevicePairSource`]) are in the default build too, tested with fake
//! cameras that fail on a schedule ([`device::FakeCameras`]); the real devices
//! (`CameraPairSource`, V4L2 through nokhwa, MJPEG decoded with zune-jpeg) are behind
//! the cargo feature `camera`. [`inject`] makes any frame source fail the same ways.

#[cfg(feature = "camera")]
mod camera;
pub mod device;
pub mod inject;
#[cfg(feature = "camera")]
pub use camera::{CameraPairSource, NokhwaCameras};
pub use device::{CaptureControls, DevicePairSource};

use std::collections::VecDeque;

/// Largest capture-time difference (seconds) for two frames to count as one moment:
/// half a frame period at 30 fps.
pub const DEFAULT_MAX_SKEW_S: f64 = 1.0 / 60.0;
/// Frames kept per camera while waiting for the other camera's match.
pub const PAIR_QUEUE: usize = 4;

/// Two frames (of any type) captured at about the same moment.
#[derive(Debug, Clone, PartialEq)]
pub struct Matched<T> {
    pub front: T,
    pub side: T,
    /// Mean of the two capture times.
    pub timestamp_s: f64,
    /// side time - front time.
    pub skew_s: f64,
}

/// Pairs frames of two free-running cameras by capture timestamp.
///
/// Rule: look at the oldest waiting frame of each camera; if their times differ by at
/// most `max_skew_s` they form a pair, otherwise the older one can never be matched
/// (the other camera's frames only get newer) and is dropped.
#[derive(Debug)]
pub struct PairMatcher<T> {
    max_skew_s: f64,
    front: VecDeque<(f64, T)>,
    side: VecDeque<(f64, T)>,
    dropped: u64,
}

impl<T> PairMatcher<T> {
    pub fn new(max_skew_s: f64) -> Self {
        PairMatcher {
            max_skew_s,
            front: VecDeque::new(),
            side: VecDeque::new(),
            dropped: 0,
        }
    }

    pub fn push_front(&mut self, t_s: f64, frame: T) {
        Self::push(&mut self.front, &mut self.dropped, t_s, frame);
    }

    pub fn push_side(&mut self, t_s: f64, frame: T) {
        Self::push(&mut self.side, &mut self.dropped, t_s, frame);
    }

    fn push(q: &mut VecDeque<(f64, T)>, dropped: &mut u64, t_s: f64, frame: T) {
        // A timestamp going backwards (camera restarted) invalidates what is queued.
        if q.back().is_some_and(|(t, _)| *t >= t_s) {
            *dropped += q.len() as u64;
            q.clear();
        }
        q.push_back((t_s, frame));
        while q.len() > PAIR_QUEUE {
            q.pop_front();
            *dropped += 1;
        }
    }

    /// The next pair, if the queues hold one.
    pub fn pop_pair(&mut self) -> Option<Matched<T>> {
        loop {
            let tf = self.front.front()?.0;
            let ts = self.side.front()?.0;
            if (ts - tf).abs() <= self.max_skew_s {
                let (tf, front) = self.front.pop_front()?;
                let (ts, side) = self.side.pop_front()?;
                return Some(Matched {
                    front,
                    side,
                    timestamp_s: 0.5 * (tf + ts),
                    skew_s: ts - tf,
                });
            }
            if tf < ts {
                self.front.pop_front();
            } else {
                self.side.pop_front();
            }
            self.dropped += 1;
        }
    }

    /// Frames that could not be paired.
    pub fn dropped(&self) -> u64 {
        self.dropped
    }

    /// Forgets everything waiting (a camera was reopened).
    pub fn clear(&mut self) {
        self.front.clear();
        self.side.clear();
    }
}

/// Backoff between attempts to reopen a lost camera (seconds).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ReconnectPolicy {
    pub first_retry_s: f64,
    pub max_retry_s: f64,
    /// No frame for this long means the camera is gone even without an error.
    pub stall_timeout_s: f64,
}

impl Default for ReconnectPolicy {
    fn default() -> Self {
        ReconnectPolicy {
            first_retry_s: 0.5,
            max_retry_s: 5.0,
            stall_timeout_s: 2.0,
        }
    }
}

/// Connection state of one camera as shown on screen.
#[derive(Debug, Clone, PartialEq)]
pub enum Link {
    /// Never opened yet: try now.
    Closed,
    Streaming {
        last_frame_s: f64,
    },
    Lost {
        since_s: f64,
        next_try_s: f64,
        attempts: u32,
        reason: String,
    },
}

/// Decides when to reopen a camera: pure, driven by events and the time.
#[derive(Debug, Clone)]
pub struct Reconnector {
    policy: ReconnectPolicy,
    link: Link,
}

impl Reconnector {
    pub fn new(policy: ReconnectPolicy) -> Self {
        Reconnector {
            policy,
            link: Link::Closed,
        }
    }

    pub fn link(&self) -> &Link {
        &self.link
    }

    pub fn is_streaming(&self) -> bool {
        matches!(self.link, Link::Streaming { .. })
    }

    /// Should the caller try to open the device now?
    pub fn should_open(&self, now_s: f64) -> bool {
        match &self.link {
            Link::Closed => true,
            Link::Streaming { .. } => false,
            Link::Lost { next_try_s, .. } => now_s >= *next_try_s,
        }
    }

    /// The device opened (or a frame arrived).
    pub fn on_frame(&mut self, now_s: f64) {
        self.link = Link::Streaming {
            last_frame_s: now_s,
        };
    }

    /// Opening or reading failed.
    pub fn on_error(&mut self, now_s: f64, reason: impl Into<String>) {
        let (since_s, attempts) = match &self.link {
            Link::Lost {
                since_s, attempts, ..
            } => (*since_s, attempts + 1),
            _ => (now_s, 1),
        };
        // Doubling backoff: first_retry, 2x, 4x ... capped.
        let wait = (self.policy.first_retry_s
            * 2f64.powi(attempts.saturating_sub(1).min(16) as i32))
        .min(self.policy.max_retry_s);
        self.link = Link::Lost {
            since_s,
            next_try_s: now_s + wait,
            attempts,
            reason: reason.into(),
        };
    }

    /// Checks for a stalled stream (no frames, no error); true when it just got lost.
    pub fn check_stall(&mut self, now_s: f64) -> bool {
        if let Link::Streaming { last_frame_s } = self.link {
            if now_s - last_frame_s > self.policy.stall_timeout_s {
                self.on_error(now_s, "no frames");
                return true;
            }
        }
        false
    }

    /// A one-line status for the screen, `None` while streaming.
    pub fn problem(&self, name: &str, now_s: f64) -> Option<String> {
        match &self.link {
            Link::Streaming { .. } => None,
            Link::Closed => Some(format!("{name} camera: opening")),
            Link::Lost {
                since_s,
                next_try_s,
                attempts,
                reason,
            } => Some(format!(
                "{name} camera lost {:.0} s ago ({reason}); retry {attempts} in {:.1} s",
                now_s - since_s,
                (next_try_s - now_s).max(0.0)
            )),
        }
    }
}

/// Camera pixel formats the station asks for.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PixelFormat {
    Mjpeg,
    Yuyv,
}

/// How to open the two cameras.
#[derive(Debug, Clone, PartialEq)]
pub struct CaptureConfig {
    /// Index ("0") or device path ("/dev/video0").
    pub front: String,
    pub side: String,
    pub width: u32,
    pub height: u32,
    pub fps: u32,
    pub format: PixelFormat,
    pub max_skew_s: f64,
    pub reconnect: ReconnectPolicy,
    /// Manual exposure once locked, in V4L2 units of 100 us.
    pub exposure_100us: i64,
}

impl Default for CaptureConfig {
    fn default() -> Self {
        CaptureConfig {
            front: "0".into(),
            side: "1".into(),
            width: 1280,
            height: 720,
            fps: 30,
            format: PixelFormat::Mjpeg,
            max_skew_s: DEFAULT_MAX_SKEW_S,
            reconnect: ReconnectPolicy::default(),
            exposure_100us: 150,
        }
    }
}

/// A camera named by index ("0") or device path ("/dev/video2"), as a V4L2 index.
pub fn device_index(name: &str) -> Option<u32> {
    let name = name.trim();
    if let Ok(i) = name.parse::<u32>() {
        return Some(i);
    }
    name.strip_prefix("/dev/video").and_then(|n| n.parse().ok())
}

/// YUYV (YUV 4:2:2, Y0 U Y1 V) to packed RGB, BT.601 limited range.
/// `out` receives width*height*3 bytes; returns false when `yuyv` is too short.
pub fn yuyv_to_rgb(yuyv: &[u8], width: usize, height: usize, out: &mut Vec<u8>) -> bool {
    let need = width * height * 2;
    if yuyv.len() < need || !width.is_multiple_of(2) {
        return false;
    }
    out.clear();
    out.reserve(width * height * 3);
    let conv = |y: u8, u: u8, v: u8| {
        let c = 1.164 * (y as f32 - 16.0);
        let d = u as f32 - 128.0;
        let e = v as f32 - 128.0;
        let cl = |x: f32| x.round().clamp(0.0, 255.0) as u8;
        [
            cl(c + 1.596 * e),
            cl(c - 0.392 * d - 0.813 * e),
            cl(c + 2.017 * d),
        ]
    };
    for q in yuyv[..need].chunks_exact(4) {
        out.extend_from_slice(&conv(q[0], q[1], q[3]));
        out.extend_from_slice(&conv(q[2], q[1], q[3]));
    }
    true
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pairs_by_timestamp_and_drops_the_unmatched() {
        let mut m = PairMatcher::new(0.010);
        // Side starts later and runs with a 3 ms offset; one front frame is extra.
        m.push_front(0.000, "f0");
        m.push_front(0.033, "f1");
        m.push_side(0.036, "s1");
        let p = m.pop_pair().expect("pair");
        assert_eq!((p.front, p.side), ("f1", "s1"));
        assert!((p.skew_s - 0.003).abs() < 1e-12);
        assert!((p.timestamp_s - 0.0345).abs() < 1e-12);
        assert_eq!(m.dropped(), 1);
        assert!(m.pop_pair().is_none());
        m.push_side(0.070, "s2");
        assert!(m.pop_pair().is_none(), "waits for the front frame");
        m.push_front(0.066, "f2");
        assert_eq!(m.pop_pair().map(|p| (p.front, p.side)), Some(("f2", "s2")));
    }

    #[test]
    fn queues_are_bounded_and_reset_on_time_going_back() {
        let mut m = PairMatcher::new(0.010);
        for k in 0..10 {
            m.push_front(k as f64 * 0.033, k);
        }
        assert_eq!(m.dropped(), (10 - PAIR_QUEUE) as u64);
        // The camera restarted: its clock starts again.
        m.push_front(0.0, 100);
        assert_eq!(m.dropped(), 10);
        m.push_side(0.001, 200);
        assert_eq!(m.pop_pair().map(|p| (p.front, p.side)), Some((100, 200)));
    }

    #[test]
    fn reconnect_backs_off_and_recovers() {
        let pol = ReconnectPolicy {
            first_retry_s: 0.5,
            max_retry_s: 2.0,
            stall_timeout_s: 1.0,
        };
        let mut r = Reconnector::new(pol);
        assert!(r.should_open(0.0));
        assert!(r.problem("front", 0.0).is_some());
        r.on_frame(0.1);
        assert!(r.is_streaming() && !r.should_open(0.2));
        assert_eq!(r.problem("front", 0.2), None);
        // Unplugged: retries at +0.5, then +1, then +2 (capped).
        r.on_error(1.0, "ENODEV");
        assert!(!r.should_open(1.4) && r.should_open(1.5));
        r.on_error(1.5, "ENODEV");
        assert!(!r.should_open(2.4) && r.should_open(2.5));
        r.on_error(2.5, "ENODEV");
        assert!(!r.should_open(4.4) && r.should_open(4.5));
        r.on_error(4.5, "ENODEV");
        assert!(r.should_open(6.5));
        match r.link() {
            Link::Lost {
                since_s, attempts, ..
            } => assert_eq!((*since_s, *attempts), (1.0, 4)),
            l => panic!("{l:?}"),
        }
        let msg = r.problem("front", 5.0).expect("problem shown");
        assert!(
            msg.contains("front camera lost 4 s ago") && msg.contains("ENODEV"),
            "{msg}"
        );
        // Plugged back: the next open succeeds and the backoff starts over.
        r.on_frame(6.6);
        assert!(r.is_streaming());
        r.on_error(7.0, "EIO");
        assert!(r.should_open(7.5));
    }

    #[test]
    fn a_silent_camera_counts_as_lost() {
        let mut r = Reconnector::new(ReconnectPolicy {
            first_retry_s: 0.5,
            max_retry_s: 2.0,
            stall_timeout_s: 1.0,
        });
        r.on_frame(0.0);
        assert!(!r.check_stall(0.9));
        assert!(r.check_stall(1.1));
        assert!(!r.is_streaming());
        assert!(!r.check_stall(5.0), "only once");
    }

    #[test]
    fn device_names() {
        assert_eq!(device_index("0"), Some(0));
        assert_eq!(device_index("/dev/video3"), Some(3));
        assert_eq!(device_index("/dev/sda"), None);
        assert_eq!(device_index("cam"), None);
    }

    #[test]
    fn yuyv_converts_grey_and_rejects_short_buffers() {
        let mut out = Vec::new();
        // Y=126 -> (126-16)*1.164 = 128; U=V=128: grey.
        assert!(yuyv_to_rgb(&[126, 128, 126, 128], 2, 1, &mut out));
        assert_eq!(out, vec![128, 128, 128, 128, 128, 128]);
        assert!(!yuyv_to_rgb(&[0; 3], 2, 1, &mut out));
        // Pure red-ish: V high.
        assert!(yuyv_to_rgb(&[81, 90, 81, 240], 2, 1, &mut out));
        assert!(out[0] > 200 && out[1] < 60 && out[2] < 60, "{out:?}");
    }
}
