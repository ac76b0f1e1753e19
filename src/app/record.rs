//! Recording a session to a recording folder (formats.md "A recording"):
//! `station.yaml`, `front/000000.png ...`, `side/000000.png ...` (same indices, frames
//! captured in pairs) and an optional `recording.yaml` with the frame rate.
//!
//! [`RecordingWriter`] writes synchronously (used by tests and by the background
//! writer); [`Recorder`] runs one on its own thread behind a bounded queue so the capture
//! thread never waits for PNG encoding: a full queue drops the pair and counts it.
//! Nothing about the person is written besides the frames themselves.
//! (A small local writer: `src/recording` is built by another engineer.)

use crate::camera::StationCalibration;
use crate::pipeline::FramePair;
use image::codecs::png::{CompressionType, FilterType, PngEncoder};
use image::{ImageEncoder, RgbImage};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::mpsc::{sync_channel, SyncSender, TrySendError};
use std::sync::Arc;
use std::thread::JoinHandle;

/// Why recording failed.
#[derive(Debug, thiserror::Error)]
pub enum RecordError {
    #[error("{path}: {source}")]
    Io {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("{path}: cannot encode PNG: {msg}")]
    Encode { path: PathBuf, msg: String },
    #[error("{0} already holds a recording (front/ exists): choose a new folder")]
    NotEmpty(PathBuf),
    #[error(transparent)]
    Output(#[from] crate::io::atomic::AtomicError),
}

/// Writes frame pairs into a recording folder, numbering from 0.
pub struct RecordingWriter {
    dir: PathBuf,
    next: u64,
}

fn io_err(path: &Path) -> impl FnOnce(std::io::Error) -> RecordError + '_ {
    move |source| RecordError::Io {
        path: path.to_path_buf(),
        source,
    }
}

impl RecordingWriter {
    /// Creates `dir` (and its `front/`, `side/`), writes `station.yaml` when the
    /// calibration is known and `recording.yaml` with the frame rate when known.
    pub fn create(
        dir: &Path,
        calibration: Option<&StationCalibration>,
        fps: Option<f64>,
    ) -> Result<Self, RecordError> {
        if dir.join("front").exists() {
            return Err(RecordError::NotEmpty(dir.to_path_buf()));
        }
        for sub in ["front", "side"] {
            crate::io::atomic::create_dir(&dir.join(sub))?;
        }
        if let Some(cal) = calibration {
            crate::io::atomic::write(&dir.join("station.yaml"), cal.to_yaml_string())?;
        }
        let p = dir.join("recording.yaml");
        let mut meta = String::from("# written by fitstation (operator recording)\n");
        if let Some(fps) = fps {
            meta.push_str(&format!("fps: {fps}\n"));
        }
        crate::io::atomic::write(&p, meta)?;
        Ok(RecordingWriter {
            dir: dir.to_path_buf(),
            next: 0,
        })
    }

    pub fn dir(&self) -> &Path {
        &self.dir
    }

    /// Pairs written so far.
    pub fn frames_written(&self) -> u64 {
        self.next
    }

    /// Writes one pair as `front/NNNNNN.png` and `side/NNNNNN.png`.
    pub fn write_pair(&mut self, front: &RgbImage, side: &RgbImage) -> Result<(), RecordError> {
        let name = format!("{:06}.png", self.next);
        write_png(&self.dir.join("front").join(&name), front)?;
        write_png(&self.dir.join("side").join(&name), side)?;
        self.next += 1;
        Ok(())
    }
}

/// Writes one frame atomically: a recording cut mid-frame keeps every whole frame and
/// no half one (the reader skips an index that only one view has).
fn write_png(path: &Path, img: &RgbImage) -> Result<(), RecordError> {
    crate::io::atomic::write_with(path, |w| {
        // Fast compression: a 720p frame pair must keep up with the cameras.
        PngEncoder::new_with_quality(&mut *w, CompressionType::Fast, FilterType::Sub)
            .write_image(
                img.as_raw(),
                img.width(),
                img.height(),
                image::ExtendedColorType::Rgb8,
            )
            .map_err(|e| RecordError::Encode {
                path: path.to_path_buf(),
                msg: e.to_string(),
            })
    })
}

/// Pairs waiting for the writer thread; more are dropped (and counted).
const RECORD_QUEUE: usize = 16;

/// Counters shown next to the recording indicator.
#[derive(Debug, Default)]
pub struct RecorderStats {
    pub written: AtomicU64,
    pub dropped: AtomicU64,
    /// Set when the writer failed; the message is in `Recorder::finish`.
    pub failed: std::sync::atomic::AtomicBool,
}

/// A recording in progress: a writer thread fed through a bounded queue.
pub struct Recorder {
    sender: Option<SyncSender<FramePair>>,
    thread: Option<JoinHandle<Result<u64, RecordError>>>,
    stats: Arc<RecorderStats>,
    dir: PathBuf,
}

impl Recorder {
    pub fn start(
        dir: &Path,
        calibration: Option<&StationCalibration>,
        fps: Option<f64>,
    ) -> Result<Self, RecordError> {
        let mut writer = RecordingWriter::create(dir, calibration, fps)?;
        let (sender, receiver) = sync_channel::<FramePair>(RECORD_QUEUE);
        let stats = Arc::new(RecorderStats::default());
        let st = stats.clone();
        let thread = std::thread::Builder::new()
            .name("record".into())
            .spawn(move || {
                while let Ok(pair) = receiver.recv() {
                    if let Err(e) = writer.write_pair(&pair.front, &pair.side) {
                        st.failed.store(true, Ordering::Relaxed);
                        return Err(e);
                    }
                    st.written.store(writer.frames_written(), Ordering::Relaxed);
                }
                Ok(writer.frames_written())
            })
            .map_err(io_err(dir))?;
        Ok(Recorder {
            sender: Some(sender),
            thread: Some(thread),
            stats,
            dir: dir.to_path_buf(),
        })
    }

    /// Queues a pair without waiting; a full queue drops it.
    pub fn push(&self, pair: &FramePair) {
        if let Some(s) = &self.sender {
            match s.try_send(pair.clone()) {
                Ok(()) => {}
                Err(TrySendError::Full(_)) | Err(TrySendError::Disconnected(_)) => {
                    self.stats.dropped.fetch_add(1, Ordering::Relaxed);
                }
            }
        }
    }

    pub fn stats(&self) -> &RecorderStats {
        &self.stats
    }

    pub fn dir(&self) -> &Path {
        &self.dir
    }

    /// Stops, waits for the queue to drain; returns the pairs written.
    pub fn finish(mut self) -> Result<u64, RecordError> {
        self.sender.take();
        match self.thread.take().map(|t| t.join()) {
            Some(Ok(r)) => r,
            Some(Err(_)) => Err(RecordError::Encode {
                path: self.dir.clone(),
                msg: "the writer thread panicked".into(),
            }),
            None => Ok(0),
        }
    }
}

impl Drop for Recorder {
    fn drop(&mut self) {
        self.sender.take();
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

/// The folder of a new recording under `parent`, named by its UTC start time
/// (`20261122-094512`; `-2`, `-3`... appended when that name is taken).
pub fn session_dir(parent: &Path, now: std::time::SystemTime) -> PathBuf {
    const SECS_PER_DAY: u64 = 86_400;
    let secs = now
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| d.as_secs())
        .unwrap_or(0);
    let (y, m, d) = civil_from_days((secs / SECS_PER_DAY) as i64);
    let t = secs % SECS_PER_DAY;
    let name = format!(
        "{y:04}{m:02}{d:02}-{:02}{:02}{:02}",
        t / 3600,
        t / 60 % 60,
        t % 60
    );
    let mut dir = parent.join(&name);
    let mut k = 2;
    while dir.exists() {
        dir = parent.join(format!("{name}-{k}"));
        k += 1;
    }
    dir
}

/// Proleptic Gregorian (year, month, day) of a day count since 1970-01-01 (the
/// well-known era algorithm: 400-year eras of 146097 days, years starting in March).
fn civil_from_days(days: i64) -> (i64, u32, u32) {
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z.rem_euclid(146_097);
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let d = (doy - (153 * mp + 2) / 5 + 1) as u32;
    let m = if mp < 10 { mp + 3 } else { mp - 9 } as u32;
    let y = yoe + era * 400 + i64::from(m <= 2);
    (y, m, d)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::app::demo::demo_calibration;

    fn tmp(name: &str) -> PathBuf {
        let d =
            std::env::temp_dir().join(format!("fitstation-record-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        d
    }

    #[test]
    fn writes_the_recording_layout_and_reads_back() {
        let dir = tmp("layout");
        let cal = demo_calibration();
        let rec = Recorder::start(&dir, Some(&cal), Some(30.0)).expect("start");
        for i in 0..3u8 {
            let f = RgbImage::from_pixel(8, 6, image::Rgb([i, 2 * i, 3 * i]));
            let s = RgbImage::from_pixel(8, 6, image::Rgb([100 + i, 0, 0]));
            rec.push(&FramePair {
                index: 50 + i as u64,
                timestamp_s: 0.0,
                front: f.into(),
                side: s.into(),
            });
        }
        let n = rec.finish().expect("finish");
        assert_eq!(n, 3);
        for i in 0..3u8 {
            let f = image::open(dir.join("front").join(format!("{:06}.png", i)))
                .expect("front png")
                .to_rgb8();
            assert_eq!(f.get_pixel(3, 3), &image::Rgb([i, 2 * i, 3 * i]));
            let s = image::open(dir.join("side").join(format!("{:06}.png", i)))
                .expect("side png")
                .to_rgb8();
            assert_eq!(s.get_pixel(0, 0), &image::Rgb([100 + i, 0, 0]));
        }
        let back =
            StationCalibration::load(&dir.join("station.yaml")).expect("station.yaml reads back");
        assert_eq!(back.front.intrinsics.width, cal.front.intrinsics.width);
        assert!(std::fs::read_to_string(dir.join("recording.yaml"))
            .expect("meta")
            .contains("fps: 30"));
        // A second recording into the same folder is refused.
        assert!(matches!(
            RecordingWriter::create(&dir, None, None),
            Err(RecordError::NotEmpty(_))
        ));
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn session_folders_are_named_by_utc_time_and_never_reused() {
        assert_eq!(civil_from_days(0), (1970, 1, 1));
        assert_eq!(civil_from_days(59), (1970, 3, 1));
        // 2000-02-29 (a leap day of a century year divisible by 400).
        assert_eq!(civil_from_days(11_016), (2000, 2, 29));
        let parent = std::env::temp_dir().join(format!("fs_session_{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&parent);
        // 2026-11-22 09:45:12 UTC.
        let t = std::time::UNIX_EPOCH + std::time::Duration::from_secs(1_795_340_712);
        let a = session_dir(&parent, t);
        assert_eq!(a, parent.join("20261122-094512"));
        std::fs::create_dir_all(&a).expect("mkdir");
        assert_eq!(session_dir(&parent, t), parent.join("20261122-094512-2"));
        let _ = std::fs::remove_dir_all(&parent);
    }
}
