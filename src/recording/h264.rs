//! H.264 in MP4: one video track per file, encoded with OpenH264 (built from source by
//! the `openh264` crate) and muxed/demuxed with the `mp4` crate.
//!
//! # Stream layout written
//! - One `avc1` track, timescale [`TIMESCALE`], constant frame duration from the fps.
//! - Samples are length-prefixed NAL units (4-byte big-endian lengths), as MP4 requires.
//!   SPS and PPS go into the `avcC` box and are also kept in-band in every IDR sample,
//!   so a file cut before its index (`moov`, written last) can still be recovered from
//!   the media data alone.
//! - An IDR frame every [`IDR_PERIOD_FRAMES`] frames.
//!
//! # Reading
//! Any H.264 MP4 (other tools write High profile with B-frames): samples are stored in
//! decoding order, and a stream with B-frames presents them in another order. The
//! decoder gives its pictures in presentation order, some samples later, so frame `k` is
//! the `k`-th picture out of the decoder (counted from a restart point), not the picture
//! of sample `k`; the pictures still held at the end of the stream are flushed.
//! Decoding restarts at the last sync sample at or before a requested frame when going
//! back or jumping ahead, if that sample is a clean boundary (every sample decoded
//! before it is also presented before it, from the composition offsets; so the first
//! picture out after it is its own frame). MP4 samples are converted to Annex-B (start
//! codes) and, on sync samples, the avcC SPS/PPS are prepended before they reach the
//! decoder (stack.md "Video files"). A file without a readable index is scanned: the
//! `mdat` payload is walked NAL by NAL and every complete picture is decoded; the rest
//! is reported.

use image::RgbImage;
use openh264::decoder::{Decoder, DecoderConfig, Flush};
use openh264::encoder::{
    BitRate, Encoder, EncoderConfig, FrameRate, FrameType, IntraFramePeriod, RateControlMode,
};
use openh264::formats::{RgbSliceU8, YUVBuffer, YUVSource};
use openh264::OpenH264API;
use std::fs::File;
use std::io::{BufReader, Read, Seek, SeekFrom};
use std::path::{Path, PathBuf};

/// Media timescale of the written tracks (ticks per second).
pub const TIMESCALE: u32 = 90_000;
/// Frames between IDR (key) frames.
pub const IDR_PERIOD_FRAMES: u32 = 30;
/// Bits per pixel per frame of the target bit rate (0.2 bpp: 720p30 at ~5.5 Mbit/s).
pub const BITS_PER_PIXEL: f64 = 0.2;
const NAL_SPS: u8 = 7;
const NAL_PPS: u8 = 8;
const NAL_IDR: u8 = 5;
const NAL_SLICE: u8 = 1;
const START_CODE: [u8; 4] = [0, 0, 0, 1];

/// Errors of MP4/H.264 files.
#[derive(Debug, thiserror::Error)]
pub enum VideoError {
    #[error("{file}: {msg}")]
    File { file: PathBuf, msg: String },
    #[error("{file}: {source}")]
    Io {
        file: PathBuf,
        source: std::io::Error,
    },
}

fn verr(file: &Path, msg: impl Into<String>) -> VideoError {
    VideoError::File {
        file: file.to_path_buf(),
        msg: msg.into(),
    }
}

/// Splits an Annex-B byte stream into NAL units (without start codes).
pub fn annexb_nals(stream: &[u8]) -> Vec<&[u8]> {
    let mut starts = Vec::new();
    let mut i = 0;
    while i + 3 <= stream.len() {
        if stream[i] == 0 && stream[i + 1] == 0 && stream[i + 2] == 1 {
            starts.push((i, i + 3));
            i += 3;
        } else {
            i += 1;
        }
    }
    let mut out = Vec::with_capacity(starts.len());
    for (k, &(_, payload)) in starts.iter().enumerate() {
        let mut end = starts.get(k + 1).map_or(stream.len(), |s| s.0);
        // A 4-byte start code leaves a zero before the next 3-byte code.
        while end > payload && stream[end - 1] == 0 && k + 1 < starts.len() {
            end -= 1;
        }
        if end > payload {
            out.push(&stream[payload..end]);
        }
    }
    out
}

/// Writes one H.264 MP4 file frame by frame.
pub struct Mp4VideoWriter {
    path: PathBuf,
    encoder: Encoder,
    /// Unbuffered: each sample reaches the file as it is written, so a recording cut
    /// before its index is recovered up to its last whole sample.
    mp4: Option<mp4::Mp4Writer<File>>,
    file: Option<File>,
    width: u32,
    height: u32,
    frame_ticks: u32,
    frames: u64,
    yuv: YUVBuffer,
    sample: Vec<u8>,
}

impl Mp4VideoWriter {
    /// Creates `path` for `width` x `height` frames (both even) at `fps`.
    pub fn create(path: &Path, width: u32, height: u32, fps: f64) -> Result<Self, VideoError> {
        if !width.is_multiple_of(2) || !height.is_multiple_of(2) || width == 0 || height == 0 {
            return Err(verr(
                path,
                format!("H.264 needs even frame sizes, got {width}x{height}"),
            ));
        }
        if !(fps > 0.0 && fps <= 240.0) {
            return Err(verr(path, format!("frame rate {fps} out of range")));
        }
        let bitrate = (BITS_PER_PIXEL * width as f64 * height as f64 * fps) as u32;
        let config = EncoderConfig::new()
            .bitrate(BitRate::from_bps(bitrate))
            .max_frame_rate(FrameRate::from_hz(fps as f32))
            .rate_control_mode(RateControlMode::Bufferbased)
            .skip_frames(false)
            .intra_frame_period(IntraFramePeriod::from_num_frames(IDR_PERIOD_FRAMES));
        let encoder = Encoder::with_api_config(openh264::OpenH264API::from_source(), config)
            .map_err(|e| verr(path, format!("H.264 encoder: {e}")))?;
        // A stream, not atomic: a file cut before its index is recovered by the reader.
        let file =
            crate::io::atomic::create_recoverable(path).map_err(|e| verr(path, e.cause()))?;
        Ok(Mp4VideoWriter {
            path: path.to_path_buf(),
            encoder,
            mp4: None,
            file: Some(file),
            width,
            height,
            frame_ticks: (TIMESCALE as f64 / fps).round() as u32,
            frames: 0,
            yuv: YUVBuffer::new(width as usize, height as usize),
            sample: Vec::new(),
        })
    }

    /// Encodes and appends one frame.
    pub fn push(&mut self, frame: &RgbImage) -> Result<(), VideoError> {
        if frame.width() != self.width || frame.height() != self.height {
            return Err(verr(
                &self.path,
                format!(
                    "frame is {}x{}, the video {}x{}",
                    frame.width(),
                    frame.height(),
                    self.width,
                    self.height
                ),
            ));
        }
        let src = RgbSliceU8::new(frame.as_raw(), (self.width as usize, self.height as usize));
        self.yuv.read_rgb8(src);
        let path = self.path.clone();
        let bits = self
            .encoder
            .encode(&self.yuv)
            .map_err(|e| verr(&path, format!("H.264 encode: {e}")))?;
        if matches!(bits.frame_type(), FrameType::Skip | FrameType::Invalid) {
            return Err(verr(&path, "the encoder skipped a frame"));
        }
        let annexb = bits.to_vec();
        let nals = annexb_nals(&annexb);
        self.sample.clear();
        let mut sps = None;
        let mut pps = None;
        let mut sync = false;
        for nal in &nals {
            let Some(&head) = nal.first() else { continue };
            match head & 0x1f {
                NAL_SPS => sps = Some(nal.to_vec()),
                NAL_PPS => pps = Some(nal.to_vec()),
                NAL_IDR => sync = true,
                _ => {}
            }
            self.sample
                .extend_from_slice(&(nal.len() as u32).to_be_bytes());
            self.sample.extend_from_slice(nal);
        }
        if self.mp4.is_none() {
            let (Some(sps), Some(pps)) = (sps, pps) else {
                return Err(verr(&path, "the first encoded frame carries no SPS/PPS"));
            };
            let file = self
                .file
                .take()
                .ok_or_else(|| verr(&path, "writer already finished"))?;
            let config = mp4::Mp4Config {
                major_brand: str::parse("isom").map_err(|_| verr(&path, "brand"))?,
                minor_version: 512,
                compatible_brands: ["isom", "iso2", "avc1", "mp41"]
                    .iter()
                    .filter_map(|b| str::parse(b).ok())
                    .collect(),
                timescale: TIMESCALE,
            };
            let mut w = mp4::Mp4Writer::write_start(file, &config)
                .map_err(|e| verr(&path, e.to_string()))?;
            let track = mp4::TrackConfig {
                track_type: mp4::TrackType::Video,
                timescale: TIMESCALE,
                language: "und".into(),
                media_conf: mp4::MediaConfig::AvcConfig(mp4::AvcConfig {
                    width: self.width as u16,
                    height: self.height as u16,
                    seq_param_set: sps,
                    pic_param_set: pps,
                }),
            };
            w.add_track(&track)
                .map_err(|e| verr(&path, e.to_string()))?;
            self.mp4 = Some(w);
        }
        let sample = mp4::Mp4Sample {
            start_time: self.frames * self.frame_ticks as u64,
            duration: self.frame_ticks,
            rendering_offset: 0,
            is_sync: sync,
            bytes: bytes::Bytes::copy_from_slice(&self.sample),
        };
        if let Some(w) = self.mp4.as_mut() {
            w.write_sample(1, &sample)
                .map_err(|e| verr(&path, e.to_string()))?;
        }
        self.frames += 1;
        Ok(())
    }

    /// Writes the index (`moov`) and closes the file.
    pub fn finish(mut self) -> Result<u64, VideoError> {
        let path = self.path.clone();
        let Some(mut w) = self.mp4.take() else {
            return Err(verr(&path, "no frames were written"));
        };
        w.write_end().map_err(|e| verr(&path, e.to_string()))?;
        let mut inner = w.into_writer();
        std::io::Write::flush(&mut inner).map_err(|source| VideoError::Io {
            file: path.clone(),
            source,
        })?;
        inner.sync_all().map_err(|source| VideoError::Io {
            file: path.clone(),
            source,
        })?;
        Ok(self.frames)
    }
}

/// Where a picture's NAL units are in the file (recovery without an index).
#[derive(Debug, Clone)]
struct RawPicture {
    /// (offset, length) of each NAL unit belonging to this picture, file order.
    nals: Vec<(u64, u32)>,
    /// An IDR picture (decoding may start here).
    idr: bool,
}

enum Index {
    /// The MP4 index: the reader and the track id.
    Track {
        reader: Box<mp4::Mp4Reader<BufReader<File>>>,
        track: u32,
        sps: Vec<u8>,
        pps: Vec<u8>,
    },
    /// A video track in another codec than H.264 (frames, width, height): frames come
    /// from ffmpeg.
    External { len: usize, width: u32, height: u32 },
    /// No usable index: pictures found by walking the media data.
    Scanned {
        file: BufReader<File>,
        pictures: Vec<RawPicture>,
    },
}

/// Reads one H.264 MP4 file frame by frame (sequential reading is cheap; going back
/// restarts decoding at the last clean sync sample).
pub struct Mp4VideoReader {
    path: PathBuf,
    index: Index,
    decoder: Decoder,
    len: usize,
    width: u32,
    height: u32,
    /// Decoding-order index of the next sample to feed the decoder.
    next_sample: usize,
    /// Presentation index (frame) of the next picture the decoder gives.
    next_out: usize,
    /// Pictures flushed from the decoder at the end of the stream, in order.
    pending: std::collections::VecDeque<RgbImage>,
    /// Samples decoding may restart at, ascending: sync samples with every earlier
    /// sample presented before them (their sample index is their frame index).
    sync: Vec<usize>,
    last: Option<(usize, RgbImage)>,
    annexb: Vec<u8>,
    warnings: Vec<String>,
    /// Streams OpenH264 cannot decode (4:2:2 / 4:4:4 chroma, more than 8 bits) go
    /// through an installed `ffmpeg` instead.
    external: Option<FfmpegPipe>,
}

/// A decoder that keeps reordered pictures until they are due (no flush after each
/// sample: that would take a picture out of order).
fn new_decoder(path: &Path) -> Result<Decoder, VideoError> {
    Decoder::with_api_config(
        OpenH264API::from_source(),
        DecoderConfig::new().flush_after_decode(Flush::NoFlush),
    )
    .map_err(|e| verr(path, format!("H.264 decoder: {e}")))
}

/// The sync samples at which decoding can restart with the frame of the same index: every
/// sample decoded before it is presented before it and every sample decoded after it is
/// presented after it (not so at an open group's I-frame, whose leading B-frames follow
/// it in decoding order and precede it on screen). `cts` are the samples' composition
/// times in decoding order.
fn clean_restarts(sync: &[usize], cts: &[i64]) -> Vec<usize> {
    let mut min_after = vec![i64::MAX; cts.len() + 1];
    for i in (0..cts.len()).rev() {
        min_after[i] = min_after[i + 1].min(cts[i]);
    }
    let mut max_before = vec![i64::MIN; cts.len() + 1];
    for i in 0..cts.len() {
        max_before[i + 1] = max_before[i].max(cts[i]);
    }
    sync.iter()
        .copied()
        .filter(|&i| i < cts.len() && max_before[i] < cts[i] && min_after[i + 1] > cts[i])
        .collect()
}

impl Mp4VideoReader {
    pub fn open(path: &Path) -> Result<Self, VideoError> {
        let file = File::open(path).map_err(|source| VideoError::Io {
            file: path.to_path_buf(),
            source,
        })?;
        let size = file
            .metadata()
            .map_err(|source| VideoError::Io {
                file: path.to_path_buf(),
                source,
            })?
            .len();
        let mut warnings = Vec::new();
        let mut external = None;
        let index = match Self::open_index(path, &file, size) {
            Ok(i) => i,
            Err(msg) if let Some((len, w, h, codec)) = other_video_track(&file, size) => {
                // A readable MP4 whose video is not H.264 (MPEG-4 Part 2 from OpenCV's
                // VideoWriter, say): not what spec/formats.md asks for, but readable.
                let pipe = FfmpegPipe::new(path, u32::from(w), u32::from(h)).map_err(|e| {
                    verr(
                        path,
                        format!(
                            "{msg}: the video track is {codec}; recordings hold H.264 \
                             (spec/formats.md) and ffmpeg, used for other codecs when \
                             installed, could not be run ({e})"
                        ),
                    )
                })?;
                warnings.push(format!(
                    "{}: the video track is {codec}, not H.264: decoded by ffmpeg",
                    path.display()
                ));
                external = Some(pipe);
                Index::External {
                    len,
                    width: u32::from(w),
                    height: u32::from(h),
                }
            }
            Err(msg) => {
                let pictures = scan_mdat(path, size)?;
                if pictures.is_empty() {
                    // Cut before its index with nothing recoverable (a codec other than
                    // H.264 cannot be walked without the index): say so, rather than let
                    // the recording report "no frames" for a file that is there.
                    return Err(verr(
                        path,
                        format!(
                            "{msg}; no complete H.264 picture in the media data either: \
                             the file was cut before its index was written (frames of \
                             other codecs cannot be recovered without it)"
                        ),
                    ));
                }
                warnings.push(format!(
                    "{}: {msg}; recovered {} frame(s) from the media data (file cut short?)",
                    path.display(),
                    pictures.len()
                ));
                let f = File::open(path).map_err(|source| VideoError::Io {
                    file: path.to_path_buf(),
                    source,
                })?;
                Index::Scanned {
                    file: BufReader::new(f),
                    pictures,
                }
            }
        };
        let sync: Vec<usize> = match &index {
            Index::Track { reader, track, .. } => {
                let t = reader.tracks().get(track);
                let sync: Vec<usize> = match t.and_then(|t| t.trak.mdia.minf.stbl.stss.as_ref()) {
                    // No sync table: every sample is a sync sample (ISO 14496-12).
                    None => (0..t.map_or(0, |t| t.sample_count() as usize)).collect(),
                    Some(stss) => stss
                        .entries
                        .iter()
                        .filter(|&&e| e >= 1)
                        .map(|&e| e as usize - 1)
                        .collect(),
                };
                match t {
                    Some(t) => clean_restarts(&sync, &composition_times(t)),
                    None => sync,
                }
            }
            Index::Scanned { pictures, .. } => pictures
                .iter()
                .enumerate()
                .filter(|(_, p)| p.idr)
                .map(|(i, _)| i)
                .collect(),
            Index::External { .. } => Vec::new(),
        };
        let (len, width, height) = match &index {
            Index::Track { reader, track, .. } => {
                let t = reader
                    .tracks()
                    .get(track)
                    .ok_or_else(|| verr(path, "track vanished"))?;
                (
                    t.sample_count() as usize,
                    t.width() as u32,
                    t.height() as u32,
                )
            }
            Index::Scanned { pictures, .. } => (pictures.len(), 0, 0),
            Index::External { len, width, height } => (*len, *width, *height),
        };
        let external = match &index {
            Index::External { .. } => external,
            Index::Track { sps, .. } => match SpsFormat::parse(sps) {
                Some(f) if !f.openh264_decodes() => {
                    let pipe = FfmpegPipe::new(path, width, height).map_err(|e| {
                        verr(
                            path,
                            format!(
                                "H.264 {f}: the built-in decoder (OpenH264) reads 8-bit 4:2:0 \
                                 only, and ffmpeg, used for other streams when installed, \
                                 could not be run ({e}); re-encode with `ffmpeg -i IN \
                                 -pix_fmt yuv420p OUT.mp4`"
                            ),
                        )
                    })?;
                    warnings.push(format!(
                        "{}: H.264 {f} is decoded by ffmpeg (OpenH264 reads 8-bit 4:2:0 only)",
                        path.display()
                    ));
                    Some(pipe)
                }
                _ => None,
            },
            Index::Scanned { .. } => None,
        };
        let decoder = new_decoder(path)?;
        Ok(Mp4VideoReader {
            external,
            path: path.to_path_buf(),
            index,
            decoder,
            len,
            width,
            height,
            next_sample: 0,
            next_out: 0,
            pending: Default::default(),
            sync,
            last: None,
            annexb: Vec::new(),
            warnings,
        })
    }

    fn open_index(path: &Path, file: &File, size: u64) -> Result<Index, String> {
        let f = file.try_clone().map_err(|e| e.to_string())?;
        let reader = mp4::Mp4Reader::read_header(BufReader::new(f), size)
            .map_err(|e| format!("no readable MP4 index ({e})"))?;
        let track = reader
            .tracks()
            .iter()
            .filter(|(_, t)| matches!(t.media_type(), Ok(mp4::MediaType::H264)))
            .map(|(id, _)| *id)
            .min()
            .ok_or_else(|| format!("{}: no H.264 video track", path.display()))?;
        let t = reader.tracks().get(&track).ok_or("track vanished")?;
        let sps = t
            .sequence_parameter_set()
            .map_err(|e| e.to_string())?
            .to_vec();
        let pps = t
            .picture_parameter_set()
            .map_err(|e| e.to_string())?
            .to_vec();
        Ok(Index::Track {
            reader: Box::new(reader),
            track,
            sps,
            pps,
        })
    }

    /// Number of frames the file holds (per its index, or recovered).
    pub fn len(&self) -> usize {
        self.len
    }
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }
    /// Frame size from the track header (0 until known for recovered files).
    pub fn size(&self) -> (u32, u32) {
        (self.width, self.height)
    }
    /// Problems met so far (recovery, undecodable frames).
    pub fn warnings(&self) -> &[String] {
        &self.warnings
    }

    /// Decodes frame `k`.
    pub fn frame(&mut self, k: usize) -> Result<RgbImage, VideoError> {
        if k >= self.len {
            return Err(verr(
                &self.path,
                format!("frame {k} beyond the {} frames", self.len),
            ));
        }
        if let Some(pipe) = &mut self.external {
            return pipe
                .frame(k)
                .map_err(|e| verr(&self.path, format!("frame {k}: ffmpeg: {e}")));
        }
        if let Some((i, img)) = &self.last {
            if *i == k {
                return Ok(img.clone());
            }
        }
        // Restart at the last clean sync sample at or before k when going back or when
        // it lies ahead of the decoder (skips decoding frames nobody asked for).
        let restart = self
            .sync
            .iter()
            .rev()
            .find(|&&i| i <= k)
            .copied()
            .unwrap_or(0);
        if k < self.next_out || restart > self.next_out {
            self.decoder = new_decoder(&self.path)?;
            self.next_sample = restart;
            self.next_out = restart;
            self.pending.clear();
        }
        // The decoder gives pictures in presentation order: count them out until frame
        // k's turn. A sample that fails to decode is taken to have been one picture.
        loop {
            let picture = if let Some(p) = self.pending.pop_front() {
                Ok(p)
            } else if self.next_sample < self.len {
                let i = self.next_sample;
                self.next_sample += 1;
                match self.decode_sample(i) {
                    Ok(Some(p)) => Ok(p),
                    Ok(None) => continue,
                    Err(e) => Err(e),
                }
            } else {
                // End of the stream: the pictures the decoder still holds.
                let rest = self.flush()?;
                if rest.is_empty() {
                    break;
                }
                self.pending.extend(rest);
                continue;
            };
            let at = self.next_out;
            self.next_out += 1;
            match picture {
                Ok(img) if at == k => {
                    self.last = Some((k, img.clone()));
                    return Ok(img);
                }
                Err(e) if at == k => return Err(e),
                Err(e) => self.warnings.push(e.to_string()),
                Ok(_) => {}
            }
        }
        Err(verr(&self.path, format!("frame {k} not decoded")))
    }

    /// The pictures the decoder still holds (end of the stream), in order.
    fn flush(&mut self) -> Result<Vec<RgbImage>, VideoError> {
        let path = self.path.clone();
        let rest = self
            .decoder
            .flush_remaining()
            .map_err(|e| verr(&path, format!("H.264 flush: {e}")))?;
        Ok(rest.iter().map(to_rgb).collect())
    }

    /// Feeds sample `i` (decoding order) to the decoder; the picture it gives, if any
    /// (a reordering stream gives its pictures later).
    fn decode_sample(&mut self, i: usize) -> Result<Option<RgbImage>, VideoError> {
        let path = self.path.clone();
        self.annexb.clear();
        match &mut self.index {
            Index::Track {
                reader,
                track,
                sps,
                pps,
            } => {
                let sample = reader
                    .read_sample(*track, i as u32 + 1)
                    .map_err(|e| verr(&path, format!("frame {i}: {e}")))?
                    .ok_or_else(|| verr(&path, format!("frame {i}: missing sample")))?;
                if sample.is_sync {
                    for ps in [&*sps, &*pps] {
                        self.annexb.extend_from_slice(&START_CODE);
                        self.annexb.extend_from_slice(ps);
                    }
                }
                let b: &[u8] = &sample.bytes;
                let mut p = 0usize;
                while p + 4 <= b.len() {
                    let n = u32::from_be_bytes([b[p], b[p + 1], b[p + 2], b[p + 3]]) as usize;
                    p += 4;
                    if n == 0 || p + n > b.len() {
                        return Err(verr(&path, format!("frame {i}: corrupt NAL length")));
                    }
                    self.annexb.extend_from_slice(&START_CODE);
                    self.annexb.extend_from_slice(&b[p..p + n]);
                    p += n;
                }
            }
            Index::External { .. } => {
                return Err(verr(&path, format!("frame {i}: no H.264 track")));
            }
            Index::Scanned { file, pictures } => {
                let pic = pictures
                    .get(i)
                    .ok_or_else(|| verr(&path, format!("frame {i} missing")))?;
                for &(off, n) in &pic.nals {
                    file.seek(SeekFrom::Start(off))
                        .map_err(|source| VideoError::Io {
                            file: path.clone(),
                            source,
                        })?;
                    let start = self.annexb.len() + START_CODE.len();
                    self.annexb.extend_from_slice(&START_CODE);
                    self.annexb.resize(start + n as usize, 0);
                    file.read_exact(&mut self.annexb[start..])
                        .map_err(|source| VideoError::Io {
                            file: path.clone(),
                            source,
                        })?;
                }
            }
        }
        let yuv = self
            .decoder
            .decode(&self.annexb)
            .map_err(|e| verr(&path, format!("sample {i}: H.264 decode: {e}")))?;
        let Some(yuv) = yuv else {
            return Ok(None);
        };
        let img = to_rgb(&yuv);
        (self.width, self.height) = img.dimensions();
        Ok(Some(img))
    }
}

/// The first video track of a readable MP4 that holds no H.264 track: (frames, width,
/// height, codec name).
fn other_video_track(file: &File, size: u64) -> Option<(usize, u16, u16, String)> {
    // The clone shares the file position the failed H.264 look left behind.
    let mut f = file.try_clone().ok()?;
    f.seek(SeekFrom::Start(0)).ok()?;
    let reader = mp4::Mp4Reader::read_header(BufReader::new(f), size).ok()?;
    let mut tracks: Vec<_> = reader.tracks().iter().collect();
    tracks.sort_by_key(|(id, _)| **id);
    let (_, t) = tracks
        .into_iter()
        .find(|(_, t)| matches!(t.track_type(), Ok(mp4::TrackType::Video)))?;
    let codec = match t.box_type() {
        Ok(b) => b.to_string(),
        Err(_) => "a codec the MP4 reader does not know (MPEG-4 Part 2?)".to_string(),
    };
    let (w, h) = (t.width(), t.height());
    (t.sample_count() > 0 && w > 0 && h > 0).then(|| (t.sample_count() as usize, w, h, codec))
}

/// What a sequence parameter set says about the coded pictures.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct SpsFormat {
    profile_idc: u8,
    /// 0 monochrome, 1 4:2:0, 2 4:2:2, 3 4:4:4.
    chroma_format_idc: u32,
    bit_depth_luma: u32,
    bit_depth_chroma: u32,
}

impl SpsFormat {
    /// Parses the start of an SPS NAL unit (header byte included). None when it is too
    /// short or not an SPS.
    fn parse(sps: &[u8]) -> Option<SpsFormat> {
        if sps.len() < 4 || sps[0] & 0x1f != NAL_SPS {
            return None;
        }
        let profile_idc = sps[1];
        let mut f = SpsFormat {
            profile_idc,
            chroma_format_idc: 1,
            bit_depth_luma: 8,
            bit_depth_chroma: 8,
        };
        // The profiles whose SPS codes the chroma format and bit depths (H.264 7.3.2.1.1).
        if matches!(
            profile_idc,
            100 | 110 | 122 | 244 | 44 | 83 | 86 | 118 | 128 | 138 | 139 | 134 | 135
        ) {
            // The RBSP after level_idc, emulation prevention bytes (00 00 03) removed.
            let mut rbsp = Vec::with_capacity(sps.len());
            let mut zeros = 0;
            for &b in &sps[4..] {
                if zeros >= 2 && b == 3 {
                    zeros = 0;
                    continue;
                }
                zeros = if b == 0 { zeros + 1 } else { 0 };
                rbsp.push(b);
            }
            let mut bits = BitReader {
                data: &rbsp,
                pos: 0,
            };
            bits.ue()?; // seq_parameter_set_id
            f.chroma_format_idc = bits.ue()?;
            if f.chroma_format_idc == 3 {
                bits.bit()?; // separate_colour_plane_flag
            }
            f.bit_depth_luma = 8 + bits.ue()?;
            f.bit_depth_chroma = 8 + bits.ue()?;
        }
        Some(f)
    }

    /// OpenH264 decodes 8-bit 4:2:0 only.
    fn openh264_decodes(&self) -> bool {
        self.chroma_format_idc == 1 && self.bit_depth_luma == 8 && self.bit_depth_chroma == 8
    }
}

impl std::fmt::Display for SpsFormat {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let chroma = match self.chroma_format_idc {
            0 => "monochrome",
            1 => "4:2:0",
            2 => "4:2:2",
            3 => "4:4:4",
            _ => "unknown chroma",
        };
        write!(
            f,
            "profile {} ({chroma}, {}-bit)",
            self.profile_idc, self.bit_depth_luma
        )
    }
}

/// Big-endian bit reader for Exp-Golomb codes.
struct BitReader<'a> {
    data: &'a [u8],
    pos: usize,
}

impl BitReader<'_> {
    fn bit(&mut self) -> Option<u32> {
        let b = self.data.get(self.pos / 8)?;
        let v = (b >> (7 - self.pos % 8)) & 1;
        self.pos += 1;
        Some(u32::from(v))
    }
    /// Unsigned Exp-Golomb code ue(v).
    fn ue(&mut self) -> Option<u32> {
        let mut zeros = 0;
        while self.bit()? == 0 {
            zeros += 1;
            if zeros > 31 {
                return None;
            }
        }
        let mut v = 1u64;
        for _ in 0..zeros {
            v = (v << 1) | u64::from(self.bit()?);
        }
        u32::try_from(v - 1).ok()
    }
}

/// Frames of a video decoded by an installed `ffmpeg` into raw RGB, read sequentially
/// from its output (going back restarts it).
struct FfmpegPipe {
    path: PathBuf,
    width: u32,
    height: u32,
    child: Option<std::process::Child>,
    /// Index of the next frame the pipe gives.
    next: usize,
}

impl FfmpegPipe {
    fn new(path: &Path, width: u32, height: u32) -> Result<FfmpegPipe, String> {
        if width == 0 || height == 0 {
            return Err("the track header gives no frame size".into());
        }
        let mut p = FfmpegPipe {
            path: path.to_path_buf(),
            width,
            height,
            child: None,
            next: 0,
        };
        p.restart()?;
        Ok(p)
    }

    fn restart(&mut self) -> Result<(), String> {
        self.stop();
        let child = std::process::Command::new("ffmpeg")
            .args(["-v", "error", "-nostdin", "-i"])
            .arg(&self.path)
            .args([
                "-fps_mode",
                "passthrough",
                "-f",
                "rawvideo",
                "-pix_fmt",
                "rgb24",
                "-",
            ])
            .stdin(std::process::Stdio::null())
            .stdout(std::process::Stdio::piped())
            .stderr(std::process::Stdio::null())
            .spawn()
            .map_err(|e| format!("cannot run ffmpeg: {e}"))?;
        self.child = Some(child);
        self.next = 0;
        Ok(())
    }

    fn stop(&mut self) {
        if let Some(mut c) = self.child.take() {
            let _ = c.kill();
            let _ = c.wait();
        }
    }

    fn frame(&mut self, k: usize) -> Result<RgbImage, String> {
        if k < self.next || self.child.is_none() {
            self.restart()?;
        }
        let mut img = RgbImage::new(self.width, self.height);
        loop {
            let out = self
                .child
                .as_mut()
                .and_then(|c| c.stdout.as_mut())
                .ok_or("no ffmpeg output")?;
            out.read_exact(&mut img)
                .map_err(|e| format!("frame {}: {e} (stream ended?)", self.next))?;
            self.next += 1;
            if self.next == k + 1 {
                return Ok(img);
            }
        }
    }
}

impl Drop for FfmpegPipe {
    fn drop(&mut self) {
        self.stop();
    }
}

/// A decoded picture as 8-bit RGB.
fn to_rgb(yuv: &openh264::decoder::DecodedYUV<'_>) -> RgbImage {
    let (w, h) = yuv.dimensions();
    let mut img = RgbImage::new(w as u32, h as u32);
    yuv.write_rgb8(img.as_mut());
    img
}

/// Composition times of a track's samples in decoding order: decoding times (`stts`)
/// plus composition offsets (`ctts`, none: presented in decoding order).
fn composition_times(t: &mp4::Mp4Track) -> Vec<i64> {
    let stbl = &t.trak.mdia.minf.stbl;
    let n = t.sample_count() as usize;
    let mut cts = Vec::with_capacity(n);
    let mut time = 0i64;
    for e in &stbl.stts.entries {
        for _ in 0..e.sample_count {
            if cts.len() == n {
                break;
            }
            cts.push(time);
            time += i64::from(e.sample_delta);
        }
    }
    cts.resize(n, time);
    if let Some(ctts) = &stbl.ctts {
        let mut i = 0usize;
        for e in &ctts.entries {
            for _ in 0..e.sample_count {
                if let Some(c) = cts.get_mut(i) {
                    *c += i64::from(e.sample_offset);
                }
                i += 1;
            }
        }
    }
    cts
}

/// Walks the top-level boxes to the `mdat` payload and splits it into pictures: NAL
/// units are 4-byte length-prefixed; a picture ends with its slice (one slice per
/// picture, as written here). Stops at the first NAL that runs past the end.
fn scan_mdat(path: &Path, size: u64) -> Result<Vec<RawPicture>, VideoError> {
    let io = |source| VideoError::Io {
        file: path.to_path_buf(),
        source,
    };
    let mut f = BufReader::new(File::open(path).map_err(io)?);
    let mut pos = 0u64;
    let mut head = [0u8; 8];
    while pos + 8 <= size {
        f.seek(SeekFrom::Start(pos)).map_err(io)?;
        f.read_exact(&mut head).map_err(io)?;
        let mut box_size = u32::from_be_bytes([head[0], head[1], head[2], head[3]]) as u64;
        let kind = &head[4..8];
        let mut header = 8u64;
        if box_size == 1 {
            let mut big = [0u8; 8];
            f.read_exact(&mut big).map_err(io)?;
            box_size = u64::from_be_bytes(big);
            header = 16;
        }
        if kind == b"mdat" {
            // An unfinished file still holds the placeholder size of an empty mdat (the
            // mp4 crate writes the real size last): then the media data run to the end.
            let end = if box_size <= header + 8 || pos + box_size > size {
                size
            } else {
                pos + box_size
            };
            let mut payload = pos + header;
            // The mp4 crate reserves 8 bytes for a 64-bit size as a `wide` box inside.
            let mut wide = [0u8; 8];
            if payload + 8 <= end && f.read_exact(&mut wide).is_ok() && &wide[4..8] == b"wide" {
                payload += 8;
            }
            return scan_nals(&mut f, payload, end, path);
        }
        if box_size < 8 {
            break;
        }
        pos += box_size;
    }
    Err(verr(
        path,
        "no media data (mdat) found: not an MP4 file or cut before any frame",
    ))
}

fn scan_nals(
    f: &mut BufReader<File>,
    start: u64,
    end: u64,
    path: &Path,
) -> Result<Vec<RawPicture>, VideoError> {
    let io = |source| VideoError::Io {
        file: path.to_path_buf(),
        source,
    };
    let mut pictures = Vec::new();
    let mut current = RawPicture {
        nals: Vec::new(),
        idr: false,
    };
    let mut pos = start;
    let mut len4 = [0u8; 4];
    let mut first = [0u8; 1];
    while pos + 5 <= end {
        f.seek(SeekFrom::Start(pos)).map_err(io)?;
        f.read_exact(&mut len4).map_err(io)?;
        let n = u32::from_be_bytes(len4);
        if n == 0 || pos + 4 + n as u64 > end {
            break;
        }
        f.read_exact(&mut first).map_err(io)?;
        current.nals.push((pos + 4, n));
        let kind = first[0] & 0x1f;
        if kind == NAL_IDR || kind == NAL_SLICE {
            current.idr = kind == NAL_IDR;
            pictures.push(std::mem::replace(
                &mut current,
                RawPicture {
                    nals: Vec::new(),
                    idr: false,
                },
            ));
        }
        pos += 4 + n as u64;
    }
    Ok(pictures)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_sps_tells_which_streams_openh264_decodes() {
        // Constrained Baseline: no chroma fields, 8-bit 4:2:0.
        let base = SpsFormat::parse(&[0x67, 66, 0xc0, 31, 0xda]).unwrap();
        assert!(base.openh264_decodes());
        // High: sps_id ue(0) = 1, chroma ue(1) = 010, depths ue(0) ue(0) = 1 1.
        let high = SpsFormat::parse(&[0x67, 100, 0, 31, 0b1010_1100]).unwrap();
        assert_eq!((high.chroma_format_idc, high.bit_depth_luma), (1, 8));
        assert!(high.openh264_decodes());
        // High 4:4:4 (ffmpeg's default for RGB input): chroma ue(3) = 00100, separate
        // planes 0, depths 1 1.
        let f444 = SpsFormat::parse(&[0x67, 244, 0, 31, 0b1001_0001, 0b1000_0000]).unwrap();
        assert_eq!(f444.chroma_format_idc, 3);
        assert!(!f444.openh264_decodes());
        assert_eq!(f444.to_string(), "profile 244 (4:4:4, 8-bit)");
        // High 10: chroma 4:2:0, luma depth ue(2) = 011 -> 10 bits.
        let f10 = SpsFormat::parse(&[0x67, 110, 0, 31, 0b1010_0110, 0b1000_0000]).unwrap();
        assert_eq!((f10.chroma_format_idc, f10.bit_depth_luma), (1, 10));
        assert!(!f10.openh264_decodes());
        // Not an SPS, or cut short.
        assert_eq!(SpsFormat::parse(&[0x68, 100, 0, 31, 0xff]), None);
        assert_eq!(SpsFormat::parse(&[0x67, 100, 0]), None);
        assert_eq!(SpsFormat::parse(&[0x67, 100, 0, 31, 0x00]), None);
    }

    #[test]
    fn restarts_only_where_the_frame_index_is_the_sample_index() {
        // Closed groups with B-frames (I P B B | I P B B), composition times in decoding
        // order: both I-frames are clean.
        let closed = [0, 3, 1, 2, 4, 7, 5, 6];
        assert_eq!(clean_restarts(&[0, 4], &closed), vec![0, 4]);
        // An open group: the second I-frame (decoded 4th, shown 7th) has leading
        // B-frames shown before it.
        let open = [0, 3, 1, 2, 6, 4, 5, 7];
        assert_eq!(clean_restarts(&[0, 4], &open), vec![0]);
        // No reordering: every sync sample is clean; out-of-range entries are dropped.
        assert_eq!(clean_restarts(&[0, 2, 9], &[0, 1, 2, 3]), vec![0, 2]);
    }
}
