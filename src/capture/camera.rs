//! The device side of capture (feature `camera`): one worker thread per camera opens it
//! through nokhwa/V4L2 at a fixed resolution, frame rate and pixel format (asked with
//! `RequestedFormatType::Closest`), decodes MJPEG with zune-jpeg (YUYV by
//! [`super::yuyv_to_rgb`]), stamps each frame on a clock shared by both workers and
//! sends it to [`CameraPairSource`], which pairs them with [`super::PairMatcher`].
//! A failing camera is dropped and reopened on the [`super::Reconnector`] schedule; the
//! screen sees [`SourceError::Disconnected`] meanwhile.
//!
//! Exposure and white balance: after [`CaptureControls::request_lock`] (the backdrop is
//! learnt) each worker switches its camera to manual exposure and fixed white balance
//! with raw V4L2 control ids (nokhwa has no auto/manual switch), and again after every
//! reopen. Timestamps: seconds since the source was opened, from the driver's capture
//! time when nokhwa gives one (else the dequeue time), both cameras on the same clock.

use super::{device_index, yuyv_to_rgb, CaptureConfig, PairMatcher, PixelFormat, Reconnector};
use crate::camera::StationCalibration;
use crate::pipeline::{FramePair, FrameSource, SourceError};
use image::RgbImage;
use nokhwa::utils::{
    CameraFormat, CameraIndex, ControlValueSetter, FrameFormat, KnownCameraControl,
    RequestedFormat, RequestedFormatType, Resolution,
};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::mpsc::{sync_channel, Receiver, RecvTimeoutError, SyncSender, TrySendError};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// V4L2 `V4L2_CID_EXPOSURE_AUTO`: 1 = manual.
const V4L2_CID_EXPOSURE_AUTO: u32 = 0x009a_0901;
const V4L2_EXPOSURE_MANUAL: i64 = 1;
/// V4L2 `V4L2_CID_EXPOSURE_ABSOLUTE`, in units of 100 us.
const V4L2_CID_EXPOSURE_ABSOLUTE: u32 = 0x009a_0902;
/// V4L2 `V4L2_CID_AUTO_WHITE_BALANCE`.
const V4L2_CID_AUTO_WHITE_BALANCE: u32 = 0x0098_090c;
/// Frames buffered between the workers and the pairing.
const FRAME_QUEUE: usize = 4;
/// How long `next_pair` waits before reporting a lost camera.
const WAIT_FOR_FRAMES: Duration = Duration::from_millis(200);
/// Worker poll while a camera is lost.
const LOST_POLL: Duration = Duration::from_millis(50);

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

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Which {
    Front,
    Side,
}

struct Frame {
    which: Which,
    t_s: f64,
    image: RgbImage,
}

/// Two live cameras as one frame source.
pub struct CameraPairSource {
    config: CaptureConfig,
    calibration: Option<StationCalibration>,
    controls: Arc<CaptureControls>,
    frames: Receiver<Frame>,
    problems: Arc<Mutex<[Option<String>; 2]>>,
    matcher: PairMatcher<RgbImage>,
    index: u64,
}

impl CameraPairSource {
    /// Starts both camera workers. Never fails: a missing camera is reported by
    /// `next_pair` as disconnected and retried.
    pub fn open(config: CaptureConfig, calibration: Option<StationCalibration>) -> Self {
        let controls = Arc::new(CaptureControls::default());
        let (tx, rx) = sync_channel(FRAME_QUEUE);
        let problems = Arc::new(Mutex::new([None, None]));
        let epoch = Instant::now();
        let epoch_wall_s = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map(|d| d.as_secs_f64())
            .unwrap_or(0.0);
        for (which, name) in [
            (Which::Front, config.front.clone()),
            (Which::Side, config.side.clone()),
        ] {
            let worker = Worker {
                which,
                device: name,
                config: config.clone(),
                controls: controls.clone(),
                tx: tx.clone(),
                problems: problems.clone(),
                epoch,
                epoch_wall_s,
            };
            let spawned = std::thread::Builder::new()
                .name(format!("camera-{which:?}"))
                .spawn(move || worker.run());
            if let Err(e) = spawned {
                if let Ok(mut p) = problems.lock() {
                    p[which as usize] = Some(format!("cannot start the camera thread: {e}"));
                }
            }
        }
        CameraPairSource {
            matcher: PairMatcher::new(config.max_skew_s),
            config,
            calibration,
            controls,
            frames: rx,
            problems,
            index: 0,
        }
    }

    /// The exposure/white-balance lock switch (for the screen's backdrop-learnt hook).
    pub fn controls(&self) -> Arc<CaptureControls> {
        self.controls.clone()
    }

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

impl Drop for CameraPairSource {
    fn drop(&mut self) {
        self.controls.stop.store(true, Ordering::Relaxed);
    }
}

impl FrameSource for CameraPairSource {
    fn next_pair(&mut self) -> Result<Option<FramePair>, SourceError> {
        let deadline = Instant::now() + WAIT_FOR_FRAMES;
        loop {
            let left = deadline.saturating_duration_since(Instant::now());
            match self.frames.recv_timeout(left) {
                Ok(f) => {
                    match f.which {
                        Which::Front => self.matcher.push_front(f.t_s, f.image),
                        Which::Side => self.matcher.push_side(f.t_s, f.image),
                    }
                    if let Some(m) = self.matcher.pop_pair() {
                        let index = self.index;
                        self.index += 1;
                        return Ok(Some(FramePair {
                            index,
                            timestamp_s: m.timestamp_s,
                            front: m.front,
                            side: m.side,
                        }));
                    }
                }
                Err(RecvTimeoutError::Timeout) => {
                    return Err(match self.problem() {
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

struct Worker {
    which: Which,
    device: String,
    config: CaptureConfig,
    controls: Arc<CaptureControls>,
    tx: SyncSender<Frame>,
    problems: Arc<Mutex<[Option<String>; 2]>>,
    epoch: Instant,
    /// `epoch` as seconds since the UNIX epoch (the clock of driver timestamps).
    epoch_wall_s: f64,
}

/// A driver timestamp further than this from the dequeue time is not trusted (s).
const MAX_TIMESTAMP_DISAGREEMENT_S: f64 = 1.0;

impl Worker {
    fn now(&self) -> f64 {
        self.epoch.elapsed().as_secs_f64()
    }

    fn set_problem(&self, p: Option<String>) {
        if let Ok(mut all) = self.problems.lock() {
            all[self.which as usize] = p;
        }
    }

    fn name(&self) -> &'static str {
        match self.which {
            Which::Front => "front",
            Which::Side => "side",
        }
    }

    fn open(&self) -> Result<nokhwa::Camera, String> {
        let index = match device_index(&self.device) {
            Some(i) => CameraIndex::Index(i),
            None => CameraIndex::String(self.device.clone()),
        };
        let fourcc = match self.config.format {
            PixelFormat::Mjpeg => FrameFormat::MJPEG,
            PixelFormat::Yuyv => FrameFormat::YUYV,
        };
        let want = CameraFormat::new(
            Resolution::new(self.config.width, self.config.height),
            fourcc,
            self.config.fps,
        );
        let requested = RequestedFormat::new::<nokhwa::pixel_format::RgbFormat>(
            RequestedFormatType::Closest(want),
        );
        let mut cam = nokhwa::Camera::new(index, requested).map_err(|e| e.to_string())?;
        cam.open_stream().map_err(|e| e.to_string())?;
        let got = cam.camera_format();
        if got.resolution() != want.resolution() {
            // Closest may pick another size: say so, the calibration would not fit.
            self.set_problem(Some(format!(
                "{} camera delivers {}x{} instead of {}x{}",
                self.name(),
                got.resolution().width(),
                got.resolution().height(),
                self.config.width,
                self.config.height
            )));
        }
        Ok(cam)
    }

    fn lock_controls(&self, cam: &mut nokhwa::Camera) -> Result<(), String> {
        let set = |cam: &mut nokhwa::Camera, id: u32, v: ControlValueSetter| {
            cam.set_camera_control(KnownCameraControl::Other(id as u128), v)
                .map_err(|e| e.to_string())
        };
        set(
            cam,
            V4L2_CID_EXPOSURE_AUTO,
            ControlValueSetter::Integer(V4L2_EXPOSURE_MANUAL),
        )?;
        set(
            cam,
            V4L2_CID_EXPOSURE_ABSOLUTE,
            ControlValueSetter::Integer(self.config.exposure_100us),
        )?;
        set(
            cam,
            V4L2_CID_AUTO_WHITE_BALANCE,
            ControlValueSetter::Boolean(false),
        )?;
        Ok(())
    }

    fn decode(
        &self,
        bytes: &[u8],
        format: FrameFormat,
        w: u32,
        h: u32,
        rgb: &mut Vec<u8>,
    ) -> Result<RgbImage, String> {
        match format {
            FrameFormat::MJPEG => {
                use zune_jpeg::zune_core::bytestream::ZCursor;
                use zune_jpeg::zune_core::colorspace::ColorSpace;
                use zune_jpeg::zune_core::options::DecoderOptions;
                let opts = DecoderOptions::default().jpeg_set_out_colorspace(ColorSpace::RGB);
                let mut d = zune_jpeg::JpegDecoder::new_with_options(ZCursor::new(bytes), opts);
                let pixels = d
                    .decode()
                    .map_err(|e| format!("corrupt MJPEG frame: {e:?}"))?;
                let info = d.info().ok_or("MJPEG frame without a header")?;
                RgbImage::from_raw(info.width as u32, info.height as u32, pixels)
                    .ok_or_else(|| "MJPEG size mismatch".to_string())
            }
            FrameFormat::YUYV => {
                if !yuyv_to_rgb(bytes, w as usize, h as usize, rgb) {
                    return Err("short YUYV frame".into());
                }
                RgbImage::from_raw(w, h, std::mem::take(rgb))
                    .ok_or_else(|| "YUYV size mismatch".to_string())
            }
            other => Err(format!("unsupported pixel format {other:?}")),
        }
    }

    fn run(self) {
        let mut link = Reconnector::new(self.config.reconnect);
        let mut cam: Option<nokhwa::Camera> = None;
        let mut locked_generation = 0u64;
        let mut scratch = Vec::new();
        while !self.controls.stop.load(Ordering::Relaxed) {
            let now = self.now();
            if cam.is_none() {
                if !link.should_open(now) {
                    self.set_problem(link.problem(self.name(), now));
                    std::thread::sleep(LOST_POLL);
                    continue;
                }
                match self.open() {
                    Ok(c) => {
                        cam = Some(c);
                        link.on_frame(now);
                        locked_generation = 0;
                    }
                    Err(e) => {
                        link.on_error(now, e);
                        self.set_problem(link.problem(self.name(), now));
                        continue;
                    }
                }
            }
            let Some(c) = cam.as_mut() else { continue };
            let generation = self.controls.lock_generation.load(Ordering::Relaxed);
            if self.controls.lock_requested.load(Ordering::Relaxed)
                && generation != locked_generation
            {
                locked_generation = generation;
                if let Err(e) = self.lock_controls(c) {
                    self.set_problem(Some(format!(
                        "{} camera: cannot lock exposure/white balance: {e}",
                        self.name()
                    )));
                }
            }
            match c.frame() {
                Ok(buf) => {
                    let now = self.now();
                    link.on_frame(now);
                    // The driver's capture time (V4L2 monotonic, given as wall-clock by
                    // nokhwa) when there is one, else the time it was dequeued.
                    let t_s = buf
                        .capture_timestamp()
                        .map(|d| d.as_secs_f64() - self.epoch_wall_s)
                        .filter(|t| (t - now).abs() < MAX_TIMESTAMP_DISAGREEMENT_S)
                        .unwrap_or(now);
                    let res = buf.resolution();
                    match self.decode(
                        buf.buffer(),
                        buf.source_frame_format(),
                        res.width(),
                        res.height(),
                        &mut scratch,
                    ) {
                        Ok(image) => {
                            self.set_problem(None);
                            match self.tx.try_send(Frame {
                                which: self.which,
                                t_s,
                                image,
                            }) {
                                Ok(()) | Err(TrySendError::Full(_)) => {}
                                Err(TrySendError::Disconnected(_)) => return,
                            }
                        }
                        Err(e) => self.set_problem(Some(format!("{} camera: {e}", self.name()))),
                    }
                }
                Err(e) => {
                    // Unplugged or failing: drop the device and reopen on schedule.
                    cam = None;
                    link.on_error(self.now(), e.to_string());
                    self.set_problem(link.problem(self.name(), self.now()));
                }
            }
        }
    }
}
