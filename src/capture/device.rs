//! The camera seam: two capture workers, one per camera, each opening its device through
//! a [`DeviceOpener`], reading frames from a [`CameraDevice`], reopening a lost device on
//! the [`Reconnector`] schedule and sending stamped frames to [`DevicePairSource`], which
//! pairs them with [`PairMatcher`] (bound [`CaptureConfig::max_skew_s`]) as one
//! [`FrameSource`]. The real cameras (nokhwa/V4L2, feature `camera`) are one opener;
//! [`FakeCameras`] is another, which fails on a fault schedule, so that the reconnect
//! path is tested in the default build without hardware.
//!
//! Timestamps: seconds since the source was opened, from the device's capture time when
//! it gives one (wall clock, seconds since the UNIX epoch) and it agrees with the dequeue
//! time within [`MAX_TIMESTAMP_DISAGREEMENT_S`], else the dequeue time; both workers on
//! the same clock.

use super::inject::{Fault, FaultKind};
use super::{CaptureConfig, PairMatcher, Reconnector};
use crate::camera::{StationCalibration, View};
use crate::pipeline::{FramePair, FrameSource, SourceError};
use image::RgbImage;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::mpsc::{sync_channel, Receiver, RecvTimeoutError, SyncSender, TrySendError};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// Frames buffered between the workers and the pairing.
const FRAME_QUEUE: usize = 4;
/// How long `next_pair` waits before reporting a lost camera.
const WAIT_FOR_FRAMES: Duration = Duration::from_millis(200);
/// Worker poll while a camera is lost.
const LOST_POLL: Duration = Duration::from_millis(50);
/// A device timestamp further than this from the dequeue time is not trusted (s).
pub const MAX_TIMESTAMP_DISAGREEMENT_S: f64 = 1.0;

/// One frame as a device gives it.
pub struct DeviceFrame {
    pub image: RgbImage,
    /// The driver's capture time, seconds since the UNIX epoch, when it gives one.
    pub captured_unix_s: Option<f64>,
}

/// Why a device gave no frame.
#[derive(Debug, Clone, PartialEq)]
pub enum DeviceError {
    /// This frame is bad (corrupt transfer): skip it, keep the device.
    BadFrame(String),
    /// The device is gone or failing: drop it and reopen on schedule.
    Lost(String),
}

/// An open camera (made and used on its worker's thread only).
pub trait CameraDevice {
    /// The next frame (blocks until one is there).
    fn frame(&mut self) -> Result<DeviceFrame, DeviceError>;
    /// Switch to manual exposure and fixed white balance.
    fn lock_controls(&mut self) -> Result<(), String>;
}

/// A device just opened, with what is wrong with it if anything (another frame size).
pub struct Opened {
    pub device: Box<dyn CameraDevice>,
    pub warning: Option<String>,
}

/// Opens the front or side camera.
pub trait DeviceOpener: Send + Sync {
    /// Opens the camera of `view`, or says why it cannot.
    fn open(&self, view: View) -> Result<Opened, String>;
}

/// Switches shared with the screen.
#[derive(Debug, Default)]
pub struct CaptureControls {
    lock_requested: AtomicBool,
    /// Bumped on each request so reopened cameras lock again.
    lock_generation: AtomicU64,
    stop: AtomicBool,
}

impl CaptureControls {
    /// Lock exposure and white balance on both cameras (now and after reopens).
    pub fn request_lock(&self) {
        self.lock_requested.store(true, Ordering::Relaxed);
        self.lock_generation.fetch_add(1, Ordering::Relaxed);
    }
}

struct Frame {
    view: View,
    t_s: f64,
    image: RgbImage,
}

/// Per view, what is wrong with its camera now.
type Problems = Arc<Mutex<[Option<String>; 2]>>;

/// Two cameras as one frame source.
pub struct DevicePairSource {
    config: CaptureConfig,
    calibration: Option<StationCalibration>,
    controls: Arc<CaptureControls>,
    frames: Receiver<Frame>,
    problems: Problems,
    matcher: PairMatcher<RgbImage>,
    index: u64,
    /// When each camera's last frame came (front, side); a camera silent for longer
    /// than [`super::ReconnectPolicy::stall_timeout_s`] is reported lost.
    last_frame: [Instant; 2],
    /// The side camera has given a frame since the source opened.
    side_started: bool,
}

impl DevicePairSource {
    /// Starts both camera workers. Never fails: a missing camera is reported by
    /// `next_pair` as disconnected and retried.
    pub fn open(
        config: CaptureConfig,
        calibration: Option<StationCalibration>,
        opener: Arc<dyn DeviceOpener>,
    ) -> Self {
        let controls = Arc::new(CaptureControls::default());
        let (tx, rx) = sync_channel(FRAME_QUEUE);
        let problems: Problems = Arc::new(Mutex::new([None, None]));
        let epoch = Instant::now();
        let epoch_wall_s = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map(|d| d.as_secs_f64())
            .unwrap_or(0.0);
        for view in View::BOTH {
            let worker = Worker {
                view,
                opener: opener.clone(),
                config: config.clone(),
                controls: controls.clone(),
                tx: tx.clone(),
                problems: problems.clone(),
                epoch,
                epoch_wall_s,
            };
            let spawned = std::thread::Builder::new()
                .name(format!("camera-{}", view.name()))
                .spawn(move || worker.run());
            if let Err(e) = spawned {
                if let Ok(mut p) = problems.lock() {
                    p[view as usize] = Some(format!("cannot start the camera thread: {e}"));
                }
            }
        }
        DevicePairSource {
            matcher: PairMatcher::new(config.max_skew_s),
            config,
            calibration,
            controls,
            frames: rx,
            problems,
            index: 0,
            last_frame: [epoch; 2],
            side_started: false,
        }
    }

    /// The exposure/white-balance lock switch (for the screen's backdrop-learnt hook).
    pub fn controls(&self) -> Arc<CaptureControls> {
        self.controls.clone()
    }

    /// The cameras silent for longer than the stall timeout (a device that blocks
    /// without an error), in one line.
    /// True when the side camera gave no frame for longer than the stall timeout.
    /// (A side camera that never gave a frame is not lost but not started: the station
    /// waits for both to learn the backdrop.)
    fn side_lost(&self) -> bool {
        self.side_started
            && self.last_frame[View::Side as usize].elapsed().as_secs_f64()
                > self.config.reconnect.stall_timeout_s
    }

    fn silent(&self) -> Option<String> {
        let timeout_s = self.config.reconnect.stall_timeout_s;
        let v: Vec<String> = View::BOTH
            .into_iter()
            .map(|v| (v, self.last_frame[v as usize].elapsed().as_secs_f64()))
            .filter(|(_, quiet_s)| *quiet_s > timeout_s)
            .map(|(v, quiet_s)| format!("{} camera: no frames for {quiet_s:.1} s", v.name()))
            .collect();
        (!v.is_empty()).then(|| v.join("; "))
    }

    /// What is wrong with the cameras, both in one line.
    fn problem(&self) -> Option<String> {
        let p = self.problems.lock().ok()?;
        let v: Vec<&str> = p.iter().flatten().map(|s| s.as_str()).collect();
        if v.is_empty() {
            None
        } else {
            Some(v.join("; "))
        }
    }
}

impl Drop for DevicePairSource {
    fn drop(&mut self) {
        self.controls.stop.store(true, Ordering::Relaxed);
    }
}

impl FrameSource for DevicePairSource {
    fn next_pair(&mut self) -> Result<Option<FramePair>, SourceError> {
        let deadline = Instant::now() + WAIT_FOR_FRAMES;
        loop {
            let left = deadline.saturating_duration_since(Instant::now());
            match self.frames.recv_timeout(left) {
                Ok(f) => {
                    self.last_frame[f.view as usize] = Instant::now();
                    self.side_started |= f.view == View::Side;
                    if f.view == View::Front && self.side_lost() {
                        // The side camera has been silent past the stall timeout: the
                        // front frames go on alone (the station fits them from the front
                        // view) until it is back.
                        self.matcher.clear();
                        let index = self.index;
                        self.index += 1;
                        return Ok(Some(FramePair {
                            index,
                            timestamp_s: f.t_s,
                            front: f.image.into(),
                            side: RgbImage::new(0, 0).into(),
                        }));
                    }
                    match f.view {
                        View::Front => self.matcher.push_front(f.t_s, f.image),
                        View::Side => self.matcher.push_side(f.t_s, f.image),
                    }
                    if let Some(m) = self.matcher.pop_pair() {
                        let index = self.index;
                        self.index += 1;
                        return Ok(Some(FramePair {
                            index,
                            timestamp_s: m.timestamp_s,
                            front: m.front.into(),
                            side: m.side.into(),
                        }));
                    }
                }
                Err(RecvTimeoutError::Timeout) => {
                    return Err(match self.problem().or_else(|| self.silent()) {
                        Some(p) => SourceError::Disconnected(p),
                        None => SourceError::Skipped("no matching frame pair yet".into()),
                    });
                }
                Err(RecvTimeoutError::Disconnected) => {
                    return Err(SourceError::Fatal("both camera threads stopped".into()));
                }
            }
        }
    }

    fn calibration(&self) -> Option<&StationCalibration> {
        self.calibration.as_ref()
    }

    fn fps(&self) -> Option<f64> {
        // The cameras pace themselves; the runner must not add its own pacing.
        None
    }

    fn describe(&self) -> String {
        format!(
            "cameras {} + {} ({}x{} @ {} fps {:?})",
            self.config.front,
            self.config.side,
            self.config.width,
            self.config.height,
            self.config.fps,
            self.config.format
        )
    }
}

/// The capture thread of one camera.
struct Worker {
    view: View,
    opener: Arc<dyn DeviceOpener>,
    config: CaptureConfig,
    controls: Arc<CaptureControls>,
    tx: SyncSender<Frame>,
    problems: Problems,
    epoch: Instant,
    /// `epoch` as seconds since the UNIX epoch (the clock of device timestamps).
    epoch_wall_s: f64,
}

impl Worker {
    /// Seconds since the source was opened.
    fn now(&self) -> f64 {
        self.epoch.elapsed().as_secs_f64()
    }

    /// Sets (or clears) this camera's problem line.
    fn set_problem(&self, p: Option<String>) {
        if let Ok(mut all) = self.problems.lock() {
            all[self.view as usize] = p;
        }
    }

    /// The frame's time on the source clock: the device's, when it agrees with `now`.
    fn stamp(&self, frame: &DeviceFrame, now: f64) -> f64 {
        frame
            .captured_unix_s
            .map(|t| t - self.epoch_wall_s)
            .filter(|t| (t - now).abs() < MAX_TIMESTAMP_DISAGREEMENT_S)
            .unwrap_or(now)
    }

    /// Opens the device when the reconnect schedule says so; None while it is lost.
    fn try_open(&self, link: &mut Reconnector) -> Option<Box<dyn CameraDevice>> {
        let now = self.now();
        if !link.should_open(now) {
            self.set_problem(link.problem(self.view.name(), now));
            std::thread::sleep(LOST_POLL);
            return None;
        }
        match self.opener.open(self.view) {
            Ok(opened) => {
                link.on_frame(now);
                self.set_problem(opened.warning);
                Some(opened.device)
            }
            Err(e) => {
                link.on_error(now, e);
                self.set_problem(link.problem(self.view.name(), now));
                None
            }
        }
    }

    /// Locks exposure once per lock request (again after every reopen).
    fn lock_if_asked(&self, device: &mut dyn CameraDevice, locked_generation: &mut u64) {
        let generation = self.controls.lock_generation.load(Ordering::Relaxed);
        if self.controls.lock_requested.load(Ordering::Relaxed) && generation != *locked_generation
        {
            *locked_generation = generation;
            if let Err(e) = device.lock_controls() {
                self.set_problem(Some(format!(
                    "{} camera: cannot lock exposure/white balance: {e}",
                    self.view.name()
                )));
            }
        }
    }

    /// The worker loop: open, read, send; drop and reopen a lost device.
    fn run(self) {
        let mut link = Reconnector::new(self.config.reconnect);
        let mut device: Option<Box<dyn CameraDevice>> = None;
        let mut locked_generation = 0u64;
        while !self.controls.stop.load(Ordering::Relaxed) {
            let Some(dev) = device.as_mut() else {
                device = self.try_open(&mut link);
                locked_generation = 0;
                continue;
            };
            self.lock_if_asked(&mut **dev, &mut locked_generation);
            match dev.frame() {
                Ok(frame) => {
                    let now = self.now();
                    link.on_frame(now);
                    let t_s = self.stamp(&frame, now);
                    self.set_problem(None);
                    let sent = self.tx.try_send(Frame {
                        view: self.view,
                        t_s,
                        image: frame.image,
                    });
                    if let Err(TrySendError::Disconnected(_)) = sent {
                        return;
                    }
                }
                Err(DeviceError::BadFrame(e)) => {
                    self.set_problem(Some(format!("{} camera: {e}", self.view.name())))
                }
                Err(DeviceError::Lost(e)) => {
                    device = None;
                    link.on_error(self.now(), e);
                    self.set_problem(link.problem(self.view.name(), self.now()));
                }
            }
        }
    }
}

/// Fake cameras for tests: frames of a plain colour whose red value is the frame
/// number (mod 256), at `fps`, with the faults of a schedule in seconds since the
/// opener was made (`stall` blocks both devices, `drop-*` makes one unplugged: reads fail
/// and it cannot be opened, `corrupt-*` gives bad frames, `resize-*` frames of half
/// the size, `exposure*` brighter frames; `reorder` and `duplicate` repeat or swap
/// capture times).
pub struct FakeCameras {
    pub width: u32,
    pub height: u32,
    pub fps: f64,
    faults: Vec<Fault>,
    epoch: Instant,
    epoch_wall_s: f64,
    /// Opens per view (front, side).
    pub opens: [AtomicU64; 2],
}

impl FakeCameras {
    /// Fake cameras of `width` x `height` at `fps`; the schedule's clock starts now.
    pub fn new(width: u32, height: u32, fps: f64, faults: Vec<Fault>) -> Self {
        FakeCameras {
            width,
            height,
            fps,
            faults,
            epoch: Instant::now(),
            epoch_wall_s: std::time::SystemTime::now()
                .duration_since(std::time::UNIX_EPOCH)
                .map(|d| d.as_secs_f64())
                .unwrap_or(0.0),
            opens: [AtomicU64::new(0), AtomicU64::new(0)],
        }
    }

    /// The faults of `view` active now.
    fn active(&self, view: View, t_s: f64) -> Vec<FaultKind> {
        self.faults
            .iter()
            .filter(|f| f.active_at(t_s))
            .map(|f| f.kind)
            .filter(|k| match k {
                FaultKind::Drop(v) | FaultKind::Corrupt(v) | FaultKind::Resize(v) => *v == view,
                FaultKind::Exposure { view: v, .. } => v.is_none_or(|v| v == view),
                _ => true,
            })
            .collect()
    }
}

/// A device of [`FakeCameras`].
struct FakeDevice {
    view: View,
    cameras: Arc<FakeCameras>,
    /// Frames given so far since the opener was made (numbers the next one).
    next: u64,
    last_unix_s: f64,
}

impl DeviceOpener for Arc<FakeCameras> {
    fn open(&self, view: View) -> Result<Opened, String> {
        let t = self.epoch.elapsed().as_secs_f64();
        if self.active(view, t).contains(&FaultKind::Drop(view)) {
            return Err(format!("{}: no such device", view.name()));
        }
        self.opens[view as usize].fetch_add(1, Ordering::Relaxed);
        Ok(Opened {
            device: Box::new(FakeDevice {
                view,
                cameras: self.clone(),
                next: (t * self.fps).ceil() as u64,
                last_unix_s: 0.0,
            }),
            warning: None,
        })
    }
}

impl CameraDevice for FakeDevice {
    fn frame(&mut self) -> Result<DeviceFrame, DeviceError> {
        let c = self.cameras.clone();
        // Wait for the frame's time (blocking, like a driver); a stall blocks to its end.
        let (n, due, active) = loop {
            let due = self.next as f64 / c.fps;
            let now = c.epoch.elapsed().as_secs_f64();
            if due > now {
                std::thread::sleep(Duration::from_secs_f64(due - now));
            }
            let n = self.next;
            self.next += 1;
            let stalled = c
                .faults
                .iter()
                .find(|f| f.kind == FaultKind::Stall && f.active_at(due));
            match stalled {
                Some(f) => self.next = (f.end_s() * c.fps).ceil() as u64,
                None => break (n, due, c.active(self.view, due)),
            }
        };
        let mut unix_s = c.epoch_wall_s + due;
        for k in &active {
            match k {
                FaultKind::Drop(_) => return Err(DeviceError::Lost("ENODEV".into())),
                FaultKind::Corrupt(_) => {
                    return Err(DeviceError::BadFrame("corrupt MJPEG frame".into()))
                }
                FaultKind::Duplicate | FaultKind::Reorder => unix_s = self.last_unix_s,
                _ => {}
            }
        }
        self.last_unix_s = c.epoch_wall_s + due;
        let mut level = 100.0;
        let (mut w, mut h) = (c.width, c.height);
        for k in &active {
            match k {
                FaultKind::Resize(_) => (w, h) = ((w / 2).max(1), (h / 2).max(1)),
                FaultKind::Exposure { gain, .. } => level *= gain,
                _ => {}
            }
        }
        let pixel = image::Rgb([(n % 256) as u8, level.clamp(0.0, 255.0) as u8, 50]);
        Ok(DeviceFrame {
            image: RgbImage::from_pixel(w, h, pixel),
            captured_unix_s: Some(unix_s),
        })
    }

    fn lock_controls(&mut self) -> Result<(), String> {
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::capture::inject::parse_spec;
    use crate::capture::ReconnectPolicy;

    /// Reads the fake cameras for `seconds`: per call, the pair's (time, front frame
    /// number, side frame number) or the error.
    /// Per `next_pair` call: (time, front frame number, side frame number) or the error.
    type Reads = Vec<Result<(f64, u8, u8), String>>;

    fn read(spec: &str, seconds: f64) -> (Reads, Arc<FakeCameras>) {
        let cams = Arc::new(FakeCameras::new(
            8,
            6,
            30.0,
            parse_spec(spec).expect("spec"),
        ));
        let config = CaptureConfig {
            width: 8,
            height: 6,
            reconnect: ReconnectPolicy {
                first_retry_s: 0.1,
                max_retry_s: 0.2,
                stall_timeout_s: 0.5,
            },
            ..CaptureConfig::default()
        };
        let mut src = DevicePairSource::open(config, None, Arc::new(cams.clone()));
        let start = Instant::now();
        let mut out = Vec::new();
        while start.elapsed().as_secs_f64() < seconds {
            out.push(match src.next_pair() {
                // A front-only pair (side camera lost) has side number 255.
                Ok(Some(p)) => Ok((
                    p.timestamp_s,
                    p.front[(0, 0)][0],
                    if p.has_side() { p.side[(0, 0)][0] } else { 255 },
                )),
                Ok(None) => break,
                Err(e) => Err(e.to_string()),
            });
        }
        (out, cams)
    }

    /// A side camera lost for longer than the stall timeout: the front frames go on as
    /// front-only pairs (the station fits them from the front view), and pairs again
    /// once the side is back.
    #[test]
    fn a_side_camera_lost_past_the_stall_timeout_leaves_front_only_pairs() {
        let (out, _) = read("drop-side@0.3:1.2", 2.2);
        let pairs: Vec<(f64, u8, u8)> = out.iter().flatten().copied().collect();
        let front_only: Vec<f64> = pairs.iter().filter(|p| p.2 == 255).map(|p| p.0).collect();
        assert!(front_only.len() >= 10, "{pairs:?}");
        // Only while the side is silent past the 0.5 s stall timeout.
        // (Until the side camera is reopened, on the 0.1-0.2 s retry schedule.)
        assert!(
            front_only.iter().all(|t| (0.75..1.95).contains(t)),
            "{front_only:?}"
        );
        assert!(
            pairs.iter().filter(|p| p.0 > 1.7 && p.2 != 255).count() >= 5,
            "two-camera pairs after: {pairs:?}"
        );
        for (t, f, s) in pairs.iter().filter(|p| p.2 != 255) {
            assert_eq!(f, s, "pair at {t:.3} s mixes frames {f} and {s}");
        }
    }

    #[test]
    fn an_unplugged_camera_is_reported_reopened_and_never_paired_stale() {
        let (out, cams) = read("drop-side@0.3:0.4", 1.4);
        let lost: Vec<&String> = out.iter().filter_map(|r| r.as_ref().err()).collect();
        assert!(
            lost.iter().any(|e| e.contains("side camera lost")),
            "{lost:?}"
        );
        let pairs: Vec<(f64, u8, u8)> = out.iter().flatten().copied().collect();
        // (Front-only pairs, side number 255, follow once the side is silent past the
        // stall timeout, until it is reopened.)
        for (t, f, s) in pairs.iter().filter(|p| p.2 != 255) {
            assert_eq!(f, s, "pair at {t:.3} s mixes frames {f} and {s}");
        }
        assert!(pairs.iter().any(|p| p.0 < 0.3), "pairs before");
        assert!(
            pairs.iter().filter(|p| p.0 > 0.8).count() >= 5,
            "pairs after: {pairs:?}"
        );
        // (Times are a few microseconds early: the source's clock starts after the fakes'.)
        assert!(
            pairs.iter().all(|p| !(0.31..0.69).contains(&p.0)),
            "{pairs:?}"
        );
        assert!(
            cams.opens[View::Side as usize].load(Ordering::Relaxed) >= 2,
            "reopened"
        );
        assert_eq!(cams.opens[View::Front as usize].load(Ordering::Relaxed), 1);
    }

    #[test]
    fn a_blocked_device_is_reported_lost_after_the_stall_timeout() {
        let (out, _) = read("stall@0.2:1.2", 1.8);
        let errors: Vec<&String> = out.iter().filter_map(|r| r.as_ref().err()).collect();
        assert!(
            errors
                .iter()
                .any(|e| e.contains("front camera: no frames for") && e.contains("side camera")),
            "{errors:?}"
        );
        let pairs: Vec<(f64, u8, u8)> = out.iter().flatten().copied().collect();
        assert!(
            pairs.iter().filter(|p| p.0 > 1.45).count() >= 3,
            "{pairs:?}"
        );
    }

    #[test]
    fn corrupt_and_stalled_frames_give_no_pair_and_capture_resumes() {
        let (out, _) = read("corrupt-front@0.2:0.3,stall@0.7:0.3", 1.4);
        let pairs: Vec<(f64, u8, u8)> = out.iter().flatten().copied().collect();
        assert!(
            pairs
                .iter()
                .all(|p| !(0.21..0.49).contains(&p.0) && !(0.71..0.99).contains(&p.0)),
            "{pairs:?}"
        );
        for (_, f, s) in &pairs {
            assert_eq!(f, s);
        }
        assert!(pairs.iter().filter(|p| p.0 > 1.0).count() >= 3, "{pairs:?}");
        assert!(
            out.iter()
                .any(|r| r.as_ref().is_err_and(|e| e.contains("corrupt MJPEG frame"))),
            "{out:?}"
        );
    }
}
