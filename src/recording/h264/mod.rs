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

mod ffmpeg;
mod reader;
mod recover;
mod sps;
mod writer;

use ffmpeg::FfmpegPipe;
pub use reader::Mp4VideoReader;
use recover::{scan_mdat, RawPicture};
use sps::SpsFormat;
pub use writer::Mp4VideoWriter;

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

/// Converts one MP4 sample (4-byte big-endian length-prefixed NAL units) to Annex-B
/// (start codes) appended to `out`, with the SPS and PPS first when given (sync
/// samples, stack.md "Video files").
///
/// # Errors
/// A zero or overlong NAL length (the message names it).
pub fn sample_to_annexb(
    sample: &[u8],
    parameter_sets: Option<(&[u8], &[u8])>,
    out: &mut Vec<u8>,
) -> Result<(), String> {
    if let Some((sps, pps)) = parameter_sets {
        for ps in [sps, pps] {
            out.extend_from_slice(&START_CODE);
            out.extend_from_slice(ps);
        }
    }
    let mut p = 0usize;
    while p + 4 <= sample.len() {
        let n =
            u32::from_be_bytes([sample[p], sample[p + 1], sample[p + 2], sample[p + 3]]) as usize;
        p += 4;
        if n == 0 || n > sample.len() - p {
            return Err(format!("corrupt NAL length {n} at byte {}", p - 4));
        }
        out.extend_from_slice(&START_CODE);
        out.extend_from_slice(&sample[p..p + n]);
        p += n;
    }
    Ok(())
}

/// Decodes one MP4 sample on its own with a fresh decoder, as the reader does for a sync
/// sample (SPS and PPS prepended when given; the stream's format is read from the SPS
/// first). The decoder's pictures, in order (a reordering stream gives them at the
/// flush). `name` only names the source in errors. Used by the fuzz target
/// `h264_sample` and its regression tests.
///
/// # Errors
/// A corrupt NAL length, an SPS OpenH264 cannot decode, or a decoder error.
pub fn decode_sample_bytes(
    sample: &[u8],
    parameter_sets: Option<(&[u8], &[u8])>,
    name: &Path,
) -> Result<Vec<RgbImage>, VideoError> {
    if let Some(f) = parameter_sets.and_then(|(sps, _)| SpsFormat::parse(sps)) {
        if !f.openh264_decodes() {
            return Err(verr(name, format!("H.264 {f}: not decoded by OpenH264")));
        }
    }
    let mut annexb = Vec::with_capacity(sample.len() + 64);
    sample_to_annexb(sample, parameter_sets, &mut annexb).map_err(|m| verr(name, m))?;
    let mut decoder = reader::new_decoder(name)?;
    let mut out = Vec::new();
    if let Some(yuv) = decoder
        .decode(&annexb)
        .map_err(|e| verr(name, format!("H.264 decode: {e}")))?
    {
        out.push(reader::to_rgb(&yuv));
    }
    let rest = decoder
        .flush_remaining()
        .map_err(|e| verr(name, format!("H.264 flush: {e}")))?;
    out.extend(rest.iter().map(reader::to_rgb));
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::reader::{clean_restarts, sample_sizes_fit};
    use super::*;

    #[test]
    fn an_index_the_mp4_crate_would_overflow_on_is_damage() {
        // One size per sample: they must fit in the file, and a chunk's in 32 bits.
        assert!(sample_sizes_fit(0, &[100, 200, 300], 2, 3, 1000).is_ok());
        assert!(sample_sizes_fit(0, &[100, 200, 800], 2, 3, 1000).is_err());
        let big = [u32::MAX / 2 + 1, u32::MAX / 2 + 1, 7];
        assert!(sample_sizes_fit(0, &big, 1, 3, 1 << 40).is_ok());
        assert!(sample_sizes_fit(0, &big, 2, 3, 1 << 40).is_err());
        // One size for all of them.
        assert!(sample_sizes_fit(10, &[], 4, 100, 1000).is_ok());
        assert!(sample_sizes_fit(11, &[], 4, 100, 1000).is_err());
        assert!(sample_sizes_fit(u32::MAX, &[], 2, 2, 1 << 40).is_err());
        // The case the CI's fuzz run found: an `stsc` chunk numbered 0 (the crate
        // subtracted 1 from it). The index is refused and the frames come from the
        // media data.
        let case = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("tests/fuzz_cases/mp4/ok-stsc-first-chunk-zero");
        let reader = Mp4VideoReader::open(&case).unwrap();
        assert!(
            reader
                .warnings()
                .iter()
                .any(|w| w.contains("chunk numbered 0")),
            "{:?}",
            reader.warnings()
        );
    }

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
