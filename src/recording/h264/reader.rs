//! Reading any H.264 MP4 in presentation order, restarts at clean sync samples, and the
//! fallbacks (a cut file's media data, an installed ffmpeg for other formats).

use super::*;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

pub(super) enum Index {
    /// The MP4 index: the reader and the track id.
    Track {
        reader: Box<mp4::Mp4Reader<ForwardOnly<BufReader<File>>>>,
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
    pub(super) path: PathBuf,
    pub(super) index: Index,
    pub(super) decoder: Decoder,
    pub(super) len: usize,
    pub(super) width: u32,
    pub(super) height: u32,
    /// Decoding-order index of the next sample to feed the decoder.
    pub(super) next_sample: usize,
    /// Presentation index (frame) of the next picture the decoder gives.
    pub(super) next_out: usize,
    /// Pictures flushed from the decoder at the end of the stream, in order.
    pub(super) pending: std::collections::VecDeque<RgbImage>,
    /// Samples decoding may restart at, ascending: sync samples with every earlier
    /// sample presented before them (their sample index is their frame index).
    pub(super) sync: Vec<usize>,
    pub(super) last: Option<(usize, RgbImage)>,
    pub(super) annexb: Vec<u8>,
    pub(super) warnings: Vec<String>,
    /// Streams OpenH264 cannot decode (4:2:2 / 4:4:4 chroma, more than 8 bits) go
    /// through an installed `ffmpeg` instead.
    pub(super) external: Option<FfmpegPipe>,
}

/// A decoder that keeps reordered pictures until they are due (no flush after each
/// sample: that would take a picture out of order).
pub(super) fn new_decoder(path: &Path) -> Result<Decoder, VideoError> {
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
pub(super) fn clean_restarts(sync: &[usize], cts: &[i64]) -> Vec<usize> {
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
    /// Opens an MP4 file: its H.264 track's index, else another codec's track through
    /// ffmpeg, else the pictures recovered from the media data.
    ///
    /// # Errors
    /// An unreadable file, or no index and nothing recoverable.
    pub fn open(path: &Path) -> Result<Self, VideoError> {
        let (file, size) = open_sized(path)?;
        let mut warnings = Vec::new();
        let (index, external) = Self::index_or_fallback(path, &file, size, &mut warnings)?;
        let sync = restart_samples(&index);
        let (len, width, height) = frames_and_size(path, &index)?;
        let external = match external {
            Some(pipe) => Some(pipe),
            None => external_for_format(path, &index, (width, height), &mut warnings)?,
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

    /// The H.264 index, else another codec's track (with its ffmpeg pipe), else the
    /// pictures walked from the media data of a file cut before its index.
    fn index_or_fallback(
        path: &Path,
        file: &File,
        size: u64,
        warnings: &mut Vec<String>,
    ) -> Result<(Index, Option<FfmpegPipe>), VideoError> {
        let msg = match Self::open_index(path, file, size) {
            Ok(i) => return Ok((i, None)),
            Err(msg) => msg,
        };
        if let Some((len, w, h, codec)) = other_video_track(file, size) {
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
            let index = Index::External {
                len,
                width: u32::from(w),
                height: u32::from(h),
            };
            return Ok((index, Some(pipe)));
        }
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
        let (f, _) = open_sized(path)?;
        let index = Index::Scanned {
            file: BufReader::new(f),
            pictures,
        };
        Ok((index, None))
    }

    pub(super) fn open_index(path: &Path, file: &File, size: u64) -> Result<Index, String> {
        let f = file.try_clone().map_err(|e| e.to_string())?;
        let (guarded, header_read) = ForwardOnly::new(BufReader::new(f));
        let reader = mp4::Mp4Reader::read_header(guarded, size)
            .map_err(|e| format!("no readable MP4 index ({e})"))?;
        header_read.store(true, Ordering::Relaxed);
        let track = reader
            .tracks()
            .iter()
            .filter(|(_, t)| matches!(t.media_type(), Ok(mp4::MediaType::H264)))
            .map(|(id, _)| *id)
            .min()
            .ok_or_else(|| format!("{}: no H.264 video track", path.display()))?;
        let t = reader.tracks().get(&track).ok_or("track vanished")?;
        // Every sample takes at least a byte of the file: a larger count is a damaged
        // index (and would size the per-sample tables below from the file's word).
        if u64::from(t.sample_count()) > size {
            return Err(format!(
                "the index claims {} samples in a file of {size} bytes",
                t.sample_count()
            ));
        }
        let stbl = &t.trak.mdia.minf.stbl;
        // The mp4 crate reads a sample's time from `stts` and panics on a sample the
        // table does not cover (fuzz case `ok-read-sample-stts-short`):
        // such an index is damaged too (checked below).
        let timed: u64 = stbl
            .stts
            .entries
            .iter()
            .map(|e| u64::from(e.sample_count))
            .sum();
        // ... and divides by an `stsc` entry's samples per chunk: zero is damage too.
        if stbl.stsc.entries.iter().any(|e| e.samples_per_chunk == 0) {
            return Err("the index has a chunk of zero samples".into());
        }
        // Chunks count from 1; the crate subtracts 1 from a chunk number of 0 (fuzz case
        // `ok-stsc-first-chunk-zero`).
        if stbl.stsc.entries.iter().any(|e| e.first_chunk == 0) {
            return Err("the index has a chunk numbered 0".into());
        }
        let per_chunk = stbl.stsc.entries.iter().map(|e| e.samples_per_chunk).max();
        sample_sizes_fit(
            stbl.stsz.sample_size,
            &stbl.stsz.sample_sizes,
            per_chunk.unwrap_or(1),
            t.sample_count(),
            size,
        )?;
        // A fragmented file (`moof`) is not what a station records, and the crate's
        // fragment arithmetic is unchecked: recovered from the media data instead.
        if !t.trafs.is_empty() {
            return Err("a fragmented MP4 (moof boxes)".into());
        }
        if timed < u64::from(t.sample_count()) {
            return Err(format!(
                "the index times {timed} of its {} samples",
                t.sample_count()
            ));
        }
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
                // Once each: a looping replay decodes the same bad sample every pass.
                Err(e) if !self.warnings.contains(&e.to_string()) => {
                    self.warnings.push(e.to_string())
                }
                Err(_) => {}
                Ok(_) => {}
            }
        }
        Err(verr(&self.path, format!("frame {k} not decoded")))
    }

    /// The pictures the decoder still holds (end of the stream), in order.
    pub(super) fn flush(&mut self) -> Result<Vec<RgbImage>, VideoError> {
        let path = self.path.clone();
        let rest = self
            .decoder
            .flush_remaining()
            .map_err(|e| verr(&path, format!("H.264 flush: {e}")))?;
        Ok(rest.iter().map(to_rgb).collect())
    }

    /// Feeds sample `i` (decoding order) to the decoder; the picture it gives, if any
    /// (a reordering stream gives its pictures later).
    pub(super) fn decode_sample(&mut self, i: usize) -> Result<Option<RgbImage>, VideoError> {
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
                let ps = sample.is_sync.then_some((sps.as_slice(), pps.as_slice()));
                sample_to_annexb(&sample.bytes, ps, &mut self.annexb)
                    .map_err(|m| verr(&path, format!("frame {i}: {m}")))?;
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

/// Backward seeks allowed while the mp4 crate reads an index (a valid file needs a few:
/// the crate re-reads some sample entries).
const MAX_BACKWARD_SEEKS: u32 = 4096;

/// A reader for the mp4 crate's header parse that limits seeks backwards until
/// `header_read` is set: a box whose size is smaller than its header (0, say) sends the
/// crate back to where it was, forever. Past [`MAX_BACKWARD_SEEKS`] a seek is an I/O
/// error, so the parse fails and the file is treated as one without a readable index.
/// Sample reads afterwards seek freely.
pub(super) struct ForwardOnly<R> {
    inner: R,
    furthest: u64,
    backward_seeks: u32,
    header_read: Arc<AtomicBool>,
}

impl<R: Seek> ForwardOnly<R> {
    /// The wrapper and the flag that lifts the guard once the header is read.
    fn new(inner: R) -> (Self, Arc<AtomicBool>) {
        let header_read = Arc::new(AtomicBool::new(false));
        let r = ForwardOnly {
            inner,
            furthest: 0,
            backward_seeks: 0,
            header_read: header_read.clone(),
        };
        (r, header_read)
    }
}

impl<R: Read + Seek> Read for ForwardOnly<R> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let n = self.inner.read(buf)?;
        if !self.header_read.load(Ordering::Relaxed) {
            let at = self.inner.stream_position()?;
            self.furthest = self.furthest.max(at);
        }
        Ok(n)
    }
}

impl<R: Seek> Seek for ForwardOnly<R> {
    fn seek(&mut self, pos: SeekFrom) -> std::io::Result<u64> {
        if self.header_read.load(Ordering::Relaxed) || pos == SeekFrom::Current(0) {
            return self.inner.seek(pos);
        }
        let at = self.inner.seek(pos)?;
        if at < self.furthest {
            self.backward_seeks += 1;
            if self.backward_seeks > MAX_BACKWARD_SEEKS {
                return Err(std::io::Error::new(
                    std::io::ErrorKind::InvalidData,
                    format!("box sizes keep sending the index back (to byte {at}): damaged index"),
                ));
            }
        }
        self.furthest = self.furthest.max(at);
        Ok(at)
    }
}

/// Opens a file and reads its size.
fn open_sized(path: &Path) -> Result<(File, u64), VideoError> {
    let io = |source| VideoError::Io {
        file: path.to_path_buf(),
        source,
    };
    let file = File::open(path).map_err(io)?;
    let size = file.metadata().map_err(io)?.len();
    Ok((file, size))
}

/// The samples decoding may restart at: the index's clean sync samples, or the
/// recovered IDR pictures (none for a stream ffmpeg decodes).
fn restart_samples(index: &Index) -> Vec<usize> {
    match index {
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
    }
}

/// Frame count, width and height (pixels) per the index (size 0 x 0 until decoded
/// for recovered files).
fn frames_and_size(path: &Path, index: &Index) -> Result<(usize, u32, u32), VideoError> {
    Ok(match index {
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
    })
}

/// An ffmpeg pipe for an H.264 track whose SPS asks for more than OpenH264 decodes
/// (not 8-bit 4:2:0); None when OpenH264 will do.
fn external_for_format(
    path: &Path,
    index: &Index,
    (width, height): (u32, u32),
    warnings: &mut Vec<String>,
) -> Result<Option<FfmpegPipe>, VideoError> {
    let Index::Track { sps, .. } = index else {
        return Ok(None);
    };
    let Some(f) = SpsFormat::parse(sps).filter(|f| !f.openh264_decodes()) else {
        return Ok(None);
    };
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
    Ok(Some(pipe))
}

/// The first video track of a readable MP4 that holds no H.264 track: (frames, width,
/// height, codec name).
pub(super) fn other_video_track(file: &File, size: u64) -> Option<(usize, u16, u16, String)> {
    // The clone shares the file position the failed H.264 look left behind.
    let mut f = file.try_clone().ok()?;
    f.seek(SeekFrom::Start(0)).ok()?;
    let reader = mp4::Mp4Reader::read_header(ForwardOnly::new(BufReader::new(f)).0, size).ok()?;
    let mut tracks: Vec<_> = reader.tracks().iter().collect();
    tracks.sort_by_key(|(id, _)| **id);
    let (_, t) = tracks
        .into_iter()
        .find(|(_, t)| matches!(t.track_type(), Ok(mp4::TrackType::Video)))?;
    // An H.264 track whose index was refused is damaged, not another codec: its
    // pictures are recovered from the media data.
    if matches!(t.media_type(), Ok(mp4::MediaType::H264)) {
        return None;
    }
    let codec = match t.box_type() {
        Ok(b) => b.to_string(),
        Err(_) => "a codec the MP4 reader does not know (MPEG-4 Part 2?)".to_string(),
    };
    let (w, h) = (t.width(), t.height());
    let n = t.sample_count();
    (n > 0 && u64::from(n) <= size && w > 0 && h > 0).then_some((n as usize, w, h, codec))
}

/// A decoded picture as 8-bit RGB.
pub(super) fn to_rgb(yuv: &openh264::decoder::DecodedYUV<'_>) -> RgbImage {
    let (w, h) = yuv.dimensions();
    let mut img = RgbImage::new(w as u32, h as u32);
    yuv.write_rgb8(img.as_mut());
    img
}

/// The crate sums the sizes of the samples before a sample in its chunk in 32 bits: the
/// index (`stsz`: one `fixed` size, or else one size per sample; the most samples an
/// `stsc` chunk holds) is damage when its samples add up to more than the file, or when
/// a chunk's can sum past 32 bits.
pub(super) fn sample_sizes_fit(
    fixed: u32,
    sizes: &[u32],
    per_chunk: u32,
    count: u32,
    file_size: u64,
) -> Result<(), String> {
    let per_chunk = u64::from(per_chunk);
    if fixed > 0 {
        let total = u64::from(fixed) * u64::from(count);
        let chunk = u64::from(fixed) * per_chunk.min(u64::from(count));
        if total > file_size || chunk > u64::from(u32::MAX) {
            return Err(format!(
                "the index gives {count} samples of {fixed} bytes in a file of {file_size} bytes"
            ));
        }
        return Ok(());
    }
    let total: u64 = sizes.iter().map(|&n| u64::from(n)).sum();
    if total > file_size {
        return Err(format!(
            "the index's samples add up to {total} bytes in a file of {file_size} bytes"
        ));
    }
    if total > u64::from(u32::MAX) {
        // Any run of `per_chunk` consecutive samples: a chunk's are among them.
        let w = usize::try_from(per_chunk).unwrap_or(usize::MAX).max(1);
        let mut run: u64 = 0;
        for (i, &n) in sizes.iter().enumerate() {
            run += u64::from(n);
            if i >= w {
                run -= u64::from(sizes[i - w]);
            }
            if run > u64::from(u32::MAX) {
                return Err("the index has a chunk larger than 4 GiB".into());
            }
        }
    }
    Ok(())
}

/// Composition times of a track's samples in decoding order: decoding times (`stts`)
/// plus composition offsets (`ctts`, none: presented in decoding order).
pub(super) fn composition_times(t: &mp4::Mp4Track) -> Vec<i64> {
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
            time = time.saturating_add(i64::from(e.sample_delta));
        }
    }
    cts.resize(n, time);
    if let Some(ctts) = &stbl.ctts {
        // Entries run over the samples in order; counts beyond the last sample are
        // ignored (a damaged table may claim billions).
        let mut i = 0usize;
        for e in &ctts.entries {
            let end = i.saturating_add(e.sample_count as usize).min(n);
            for c in &mut cts[i..end] {
                *c = c.saturating_add(i64::from(e.sample_offset));
            }
            i = end;
        }
    }
    cts
}
