//! Writing: OpenH264 encoding muxed into one `avc1` track (see the module docs).

use super::*;

/// Writes one H.264 MP4 file frame by frame.
pub struct Mp4VideoWriter {
    pub(super) path: PathBuf,
    pub(super) encoder: Encoder,
    /// Unbuffered: each sample reaches the file as it is written, so a recording cut
    /// before its index is recovered up to its last whole sample.
    mp4: Option<mp4::Mp4Writer<File>>,
    pub(super) file: Option<File>,
    pub(super) width: u32,
    pub(super) height: u32,
    pub(super) frame_ticks: u32,
    pub(super) frames: u64,
    pub(super) yuv: YUVBuffer,
    pub(super) sample: Vec<u8>,
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
