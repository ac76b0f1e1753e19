//! Recordings: a folder with `station.yaml`, the two cameras' frames (PNG/JPEG frame
//! folders or H.264 MP4 files) and an optional `recording.yaml`, exactly as
//! `../shared/spec/formats.md` "A recording" describes.
//!
//! # Conventions
//! - Frame k of `front` and frame k of `side` were captured at the same moment; frames
//!   are `image::RgbImage`, pixels as OpenCV (origin at the top-left pixel's centre).
//! - Frame folders win over MP4 files when both exist. In a frame folder the files are
//!   `front/000000.png` (6-digit index, `.png`, `.jpg` or `.jpeg`); an index present in
//!   only one view is skipped and reported.
//! - A bad frame is a warning and a skipped frame, never a panic: [`Recording::frame_pair`]
//!   returns an error for it, [`Recording::warnings`] collects what went wrong.
//! - `recording.yaml` is optional; its known keys are `fps`, `stature_m`, `notes`,
//!   `date`; other keys are ignored.

pub mod h264;

use crate::camera::{CameraError, StationCalibration, View};
use h264::{Mp4VideoReader, Mp4VideoWriter, VideoError};
use image::RgbImage;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// Frame rate assumed when `recording.yaml` does not give one.
pub const DEFAULT_FPS: f64 = 30.0;
/// JPEG quality of written JPEG frames.
pub const JPEG_QUALITY: u8 = 92;
/// Name of the calibration file inside a recording.
pub const STATION_FILE: &str = "station.yaml";
/// Name of the optional metadata file inside a recording.
pub const META_FILE: &str = "recording.yaml";

/// Errors of recording I/O.
#[derive(Debug, thiserror::Error)]
pub enum RecordingError {
    #[error("{path}: {source}")]
    Io {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error(transparent)]
    Calibration(#[from] CameraError),
    #[error(
        "{dir}: no frames (expected front/ and side/ frame folders or front.mp4 and side.mp4)"
    )]
    NoFrames { dir: PathBuf },
    #[error("frame {k} is out of range: the recording has {len} frame pairs")]
    OutOfRange { k: usize, len: usize },
    #[error("{path}: {msg}")]
    Image { path: PathBuf, msg: String },
    #[error(transparent)]
    Video(#[from] VideoError),
    #[error("{path}: {msg}")]
    Meta { path: PathBuf, msg: String },
    #[error(transparent)]
    Output(#[from] crate::io::atomic::AtomicError),
}

fn io_err(path: &Path) -> impl Fn(std::io::Error) -> RecordingError + '_ {
    move |source| RecordingError::Io {
        path: path.to_path_buf(),
        source,
    }
}

/// The optional `recording.yaml`.
#[derive(Debug, Clone, PartialEq)]
pub struct RecordingMeta {
    pub fps: f64,
    /// Operator-entered stature, metres.
    pub stature_m: Option<f64>,
    pub notes: Option<String>,
    pub date: Option<String>,
}

impl Default for RecordingMeta {
    fn default() -> Self {
        RecordingMeta {
            fps: DEFAULT_FPS,
            stature_m: None,
            notes: None,
            date: None,
        }
    }
}

impl RecordingMeta {
    /// Parses the flat `key: value` YAML of `recording.yaml`.
    pub fn parse(text: &str, path: &Path) -> Result<RecordingMeta, RecordingError> {
        let mut m = RecordingMeta::default();
        let bad = |msg: String| RecordingError::Meta {
            path: path.to_path_buf(),
            msg,
        };
        for (n, line) in text.lines().enumerate() {
            let t = line.trim();
            if t.is_empty()
                || t.starts_with('#')
                || t.starts_with('%')
                || t == "---"
                || line.starts_with(' ')
            {
                continue;
            }
            let Some((key, value)) = t.split_once(':') else {
                continue;
            };
            let value = unquote(value.trim());
            match key.trim() {
                "fps" => {
                    m.fps = value
                        .parse::<f64>()
                        .ok()
                        .filter(|f| *f > 0.0 && *f <= 1000.0)
                        .ok_or_else(|| {
                            bad(format!("line {}: fps '{value}' is not a frame rate", n + 1))
                        })?
                }
                "stature_m" => {
                    m.stature_m = Some(
                        value
                            .parse::<f64>()
                            .ok()
                            .filter(|s| *s > 0.5 && *s < 2.8)
                            .ok_or_else(|| {
                                bad(format!(
                                    "line {}: stature_m '{value}' is not a stature in metres",
                                    n + 1
                                ))
                            })?,
                    )
                }
                "notes" => m.notes = Some(value.to_string()),
                "date" => m.date = Some(value.to_string()),
                _ => {}
            }
        }
        Ok(m)
    }

    /// The YAML text of this metadata.
    pub fn to_yaml(&self) -> String {
        let mut s = format!(
            "# fitstation recording metadata (all keys optional)\nfps: {}\n",
            self.fps
        );
        if let Some(h) = self.stature_m {
            s.push_str(&format!("stature_m: {h}\n"));
        }
        if let Some(d) = &self.date {
            s.push_str(&format!("date: \"{}\"\n", escape(d)));
        }
        if let Some(n) = &self.notes {
            s.push_str(&format!("notes: \"{}\"\n", escape(n)));
        }
        s
    }
}

fn unquote(v: &str) -> &str {
    let v = v.trim();
    if v.len() >= 2
        && ((v.starts_with('"') && v.ends_with('"')) || (v.starts_with('\'') && v.ends_with('\'')))
    {
        &v[1..v.len() - 1]
    } else {
        v
    }
}

fn escape(s: &str) -> String {
    s.replace(['"', '\n', '\\'], " ")
}

/// How frames are stored.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum FrameFormat {
    Png,
    Jpeg,
    Mp4,
}

enum Source {
    Folder {
        front: Vec<PathBuf>,
        /// None where the side folder has no frame of that index (side camera lost).
        side: Vec<Option<PathBuf>>,
    },
    Video {
        front: Box<Mp4VideoReader>,
        side: Box<Mp4VideoReader>,
        len: usize,
    },
}

/// An open recording.
pub struct Recording {
    dir: PathBuf,
    calibration: StationCalibration,
    meta: RecordingMeta,
    source: Source,
    warnings: Vec<String>,
}

fn list_frames(dir: &Path) -> Result<BTreeMap<u64, PathBuf>, RecordingError> {
    let mut out = BTreeMap::new();
    for e in std::fs::read_dir(dir).map_err(io_err(dir))? {
        let p = e.map_err(io_err(dir))?.path();
        let (Some(stem), Some(ext)) = (
            p.file_stem().and_then(|s| s.to_str()),
            p.extension().and_then(|s| s.to_str()),
        ) else {
            continue;
        };
        let ext = ext.to_ascii_lowercase();
        if !matches!(ext.as_str(), "png" | "jpg" | "jpeg") || stem.len() != 6 {
            continue;
        }
        if let Ok(k) = stem.parse::<u64>() {
            out.insert(k, p);
        }
    }
    Ok(out)
}

impl Recording {
    /// Opens a recording folder: reads `station.yaml` (required), `recording.yaml`
    /// (optional) and indexes the frames.
    ///
    /// # Errors
    /// A missing or invalid calibration, no frames at all, an unreadable video index
    /// that cannot be recovered. Partial damage (an index present in one view only, a
    /// truncated MP4) is a warning.
    pub fn open(dir: &Path) -> Result<Recording, RecordingError> {
        let calibration = StationCalibration::load(&dir.join(STATION_FILE))?;
        let meta_path = dir.join(META_FILE);
        let meta = if meta_path.is_file() {
            RecordingMeta::parse(
                &std::fs::read_to_string(&meta_path).map_err(io_err(&meta_path))?,
                &meta_path,
            )?
        } else {
            RecordingMeta::default()
        };
        let mut warnings = Vec::new();
        let (fd, sd) = (dir.join("front"), dir.join("side"));
        let source = if fd.is_dir() && sd.is_dir() {
            let f = list_frames(&fd)?;
            let s = list_frames(&sd)?;
            let mut front = Vec::new();
            let mut side = Vec::new();
            let mut front_only: Vec<u64> = Vec::new();
            for (k, p) in &f {
                front.push(p.clone());
                side.push(s.get(k).cloned());
                if !s.contains_key(k) {
                    front_only.push(*k);
                }
            }
            if let Some(first) = front_only.first() {
                // A lost side camera: those pairs are fitted from the front view alone.
                warnings.push(format!(
                    "{} frames from {first:06} on have no side frame: read as front-only pairs",
                    front_only.len()
                ));
            }
            for k in s.keys().filter(|k| !f.contains_key(k)) {
                warnings.push(format!("frame {k:06}: side only, skipped"));
            }
            if front.is_empty() {
                return Err(RecordingError::NoFrames {
                    dir: dir.to_path_buf(),
                });
            }
            Source::Folder { front, side }
        } else if dir.join("front.mp4").is_file() && dir.join("side.mp4").is_file() {
            let front = Mp4VideoReader::open(&dir.join("front.mp4"))?;
            let side = Mp4VideoReader::open(&dir.join("side.mp4"))?;
            warnings.extend(front.warnings().iter().cloned());
            warnings.extend(side.warnings().iter().cloned());
            if front.len() != side.len() {
                warnings.push(format!(
                    "front.mp4 holds {} frames, side.mp4 {}: using the first {}",
                    front.len(),
                    side.len(),
                    front.len().min(side.len())
                ));
            }
            let len = front.len().min(side.len());
            if len == 0 {
                return Err(RecordingError::NoFrames {
                    dir: dir.to_path_buf(),
                });
            }
            Source::Video {
                front: Box::new(front),
                side: Box::new(side),
                len,
            }
        } else {
            return Err(RecordingError::NoFrames {
                dir: dir.to_path_buf(),
            });
        };
        Ok(Recording {
            dir: dir.to_path_buf(),
            calibration,
            meta,
            source,
            warnings,
        })
    }

    pub fn dir(&self) -> &Path {
        &self.dir
    }
    pub fn calibration(&self) -> &StationCalibration {
        &self.calibration
    }
    pub fn metadata(&self) -> &RecordingMeta {
        &self.meta
    }
    /// Number of frame pairs.
    pub fn len(&self) -> usize {
        match &self.source {
            Source::Folder { front, .. } => front.len(),
            Source::Video { len, .. } => *len,
        }
    }
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
    /// Problems met so far (skipped indices, recovered files, unreadable frames).
    pub fn warnings(&self) -> &[String] {
        &self.warnings
    }

    /// The k-th frame pair (front, side), checked against the calibration's sizes. In a
    /// folder recording whose side folder lacks frame k (the side camera was lost), the
    /// side image is empty (0 x 0, see [`crate::pipeline::FramePair::has_side`]).
    ///
    /// # Errors
    /// Out of range, unreadable or undecodable frame, or a size that does not match
    /// `station.yaml`. The error is also added to [`Recording::warnings`].
    pub fn frame_pair(&mut self, k: usize) -> Result<(RgbImage, RgbImage), RecordingError> {
        let r = self.read_pair(k);
        if let Err(e) = &r {
            // Once per frame: a looping replay reads a bad frame again on every pass.
            let w = format!("frame {k}: {e}");
            if !self.warnings.contains(&w) {
                self.warnings.push(w);
            }
        }
        r
    }

    fn read_pair(&mut self, k: usize) -> Result<(RgbImage, RgbImage), RecordingError> {
        let len = self.len();
        if k >= len {
            return Err(RecordingError::OutOfRange { k, len });
        }
        let (front, side) = match &mut self.source {
            Source::Folder { front, side } => (
                load_image(&front[k])?,
                match &side[k] {
                    Some(p) => load_image(p)?,
                    None => RgbImage::new(0, 0),
                },
            ),
            Source::Video { front, side, .. } => (front.frame(k)?, side.frame(k)?),
        };
        for (view, img) in [(View::Front, &front), (View::Side, &side)] {
            if !crate::pipeline::has_frame(img) && view == View::Side {
                continue;
            }
            self.calibration
                .check_frame_size(view, img.width(), img.height())?;
        }
        Ok((front, side))
    }
}

fn load_image(path: &Path) -> Result<RgbImage, RecordingError> {
    let bytes = std::fs::read(path).map_err(io_err(path))?;
    decode_frame(&bytes, path)
}

/// Largest frame side accepted, pixels (a 4K camera is 3840; a header that claims more
/// is refused before any pixel memory is taken).
pub const MAX_FRAME_SIDE: u32 = 8192;
/// Most memory one decoded frame may take, bytes (an 8K x 8K RGBA frame).
pub const MAX_FRAME_BYTES: u64 = 8192 * 8192 * 4;

/// Decodes one frame file's bytes (PNG or JPEG, told by its content) into RGB; `path`
/// only names the source in errors. The frame path of [`Recording::frame_pair`].
///
/// # Errors
/// [`RecordingError::Image`] for an unknown format, a corrupt file or a frame larger
/// than [`MAX_FRAME_SIDE`].
pub fn decode_frame(bytes: &[u8], path: &Path) -> Result<RgbImage, RecordingError> {
    let bad = |msg: String| RecordingError::Image {
        path: path.to_path_buf(),
        msg,
    };
    let mut reader = image::ImageReader::new(std::io::Cursor::new(bytes))
        .with_guessed_format()
        .map_err(|e| bad(e.to_string()))?;
    let mut limits = image::Limits::default();
    limits.max_image_width = Some(MAX_FRAME_SIDE);
    limits.max_image_height = Some(MAX_FRAME_SIDE);
    limits.max_alloc = Some(MAX_FRAME_BYTES);
    reader.limits(limits);
    let img = reader.decode().map_err(|e| bad(e.to_string()))?;
    Ok(img.to_rgb8())
}

/// Writes a recording: `station.yaml` at creation, then frame pairs, then `finish`.
pub struct RecordingWriter {
    dir: PathBuf,
    calibration: StationCalibration,
    format: FrameFormat,
    meta: RecordingMeta,
    videos: Option<(Mp4VideoWriter, Mp4VideoWriter)>,
    count: usize,
}

impl RecordingWriter {
    /// Creates `dir` (and its frame folders) and writes `station.yaml`.
    pub fn new(
        dir: &Path,
        calibration: &StationCalibration,
        format: FrameFormat,
    ) -> Result<Self, RecordingError> {
        Self::with_meta(dir, calibration, format, RecordingMeta::default())
    }

    /// As [`RecordingWriter::new`], with the metadata written to `recording.yaml` at once
    /// (so a recording cut before `finish` replays at its frame rate) and again by
    /// `finish`.
    pub fn with_meta(
        dir: &Path,
        calibration: &StationCalibration,
        format: FrameFormat,
        meta: RecordingMeta,
    ) -> Result<Self, RecordingError> {
        crate::io::atomic::create_dir(dir)?;
        // `recording.yaml` before `station.yaml`: a folder holding `station.yaml` is a
        // recording, so a writer stopped between the two leaves no recording without its
        // metadata (each file itself is written whole, `io::atomic`).
        crate::io::atomic::write(&dir.join(META_FILE), meta.to_yaml())?;
        calibration.save(&dir.join(STATION_FILE))?;
        let videos = match format {
            FrameFormat::Png | FrameFormat::Jpeg => {
                for v in View::BOTH {
                    let d = dir.join(v.name());
                    crate::io::atomic::create_dir(&d)?;
                }
                None
            }
            FrameFormat::Mp4 => {
                let (f, s) = (&calibration.front.intrinsics, &calibration.side.intrinsics);
                Some((
                    Mp4VideoWriter::create(&dir.join("front.mp4"), f.width, f.height, meta.fps)?,
                    Mp4VideoWriter::create(&dir.join("side.mp4"), s.width, s.height, meta.fps)?,
                ))
            }
        };
        Ok(RecordingWriter {
            dir: dir.to_path_buf(),
            calibration: calibration.clone(),
            format,
            meta,
            videos,
            count: 0,
        })
    }

    /// Appends one frame pair (sizes must match the calibration).
    pub fn push_pair(&mut self, front: &RgbImage, side: &RgbImage) -> Result<(), RecordingError> {
        for (view, img) in [(View::Front, front), (View::Side, side)] {
            self.calibration
                .check_frame_size(view, img.width(), img.height())?;
        }
        match (&mut self.videos, self.format) {
            (Some((vf, vs)), _) => {
                vf.push(front)?;
                vs.push(side)?;
            }
            (None, fmt) => {
                let ext = if fmt == FrameFormat::Jpeg {
                    "jpg"
                } else {
                    "png"
                };
                for (view, img) in [(View::Front, front), (View::Side, side)] {
                    let p = self
                        .dir
                        .join(view.name())
                        .join(format!("{:06}.{ext}", self.count));
                    save_image(&p, img, fmt)?;
                }
            }
        }
        self.count += 1;
        Ok(())
    }

    /// Frame pairs written so far.
    pub fn len(&self) -> usize {
        self.count
    }
    pub fn is_empty(&self) -> bool {
        self.count == 0
    }

    /// Closes the videos (writes their index) and rewrites `recording.yaml`.
    pub fn finish(mut self) -> Result<PathBuf, RecordingError> {
        if let Some((f, s)) = self.videos.take() {
            f.finish()?;
            s.finish()?;
        }
        crate::io::atomic::write(&self.dir.join(META_FILE), self.meta.to_yaml())?;
        Ok(self.dir)
    }
}

/// Writes one frame atomically (a cut write leaves no frame, never half of one).
fn save_image(path: &Path, img: &RgbImage, fmt: FrameFormat) -> Result<(), RecordingError> {
    crate::io::atomic::write_with(path, |w| {
        let r = match fmt {
            FrameFormat::Jpeg => {
                image::codecs::jpeg::JpegEncoder::new_with_quality(&mut *w, JPEG_QUALITY)
                    .encode_image(img)
            }
            _ => img.write_to(&mut *w, image::ImageFormat::Png),
        };
        r.map_err(|e| RecordingError::Image {
            path: path.to_path_buf(),
            msg: e.to_string(),
        })
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn meta_round_trips_and_ignores_unknown_keys() {
        let m = RecordingMeta {
            fps: 25.0,
            stature_m: Some(1.72),
            notes: Some("a: b".into()),
            date: None,
        };
        let text = m.to_yaml() + "operator_only_key: 3\n";
        let back = RecordingMeta::parse(&text, Path::new("r.yaml")).unwrap();
        assert_eq!(back, m);
    }

    #[test]
    fn a_recording_folder_never_holds_station_yaml_without_its_metadata() {
        // The metadata cannot be written (a folder stands where recording.yaml goes):
        // the writer fails before station.yaml, which marks a folder as a recording.
        let dir = std::env::temp_dir().join(format!("fitstation-rec-order-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(dir.join(META_FILE)).unwrap();
        let calib = StationCalibration::nominal(720, 1280, 1100.0, 3.0, 1.1, 1.0);
        assert!(RecordingWriter::new(&dir, &calib, FrameFormat::Png).is_err());
        assert!(
            !dir.join(STATION_FILE).exists(),
            "station.yaml written without recording.yaml"
        );
        // Otherwise both are there.
        std::fs::remove_dir_all(dir.join(META_FILE)).unwrap();
        RecordingWriter::new(&dir, &calib, FrameFormat::Png).unwrap();
        assert!(dir.join(STATION_FILE).is_file() && dir.join(META_FILE).is_file());
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn meta_rejects_nonsense_stature() {
        assert!(RecordingMeta::parse("stature_m: 17\n", Path::new("r.yaml")).is_err());
    }

    #[test]
    fn annexb_split_finds_every_nal() {
        let s = [
            0, 0, 0, 1, 0x67, 1, 2, 0, 0, 1, 0x68, 3, 0, 0, 0, 1, 0x65, 9, 9,
        ];
        let n = h264::annexb_nals(&s);
        assert_eq!(
            n,
            vec![&[0x67u8, 1, 2][..], &[0x68, 3][..], &[0x65, 9, 9][..]]
        );
    }
}
