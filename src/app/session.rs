//! A whole kiosk session scripted from a recording, so that every screen of the kiosk
//! flow ([`super::flow`]) can be reached in replay: the recording's empty-scene frames
//! and subject frames are replayed in the order of a visit, timed from the flow's own
//! settings:
//!
//! 1. the backdrop is learnt (empty frames), then the empty scene shows ("step onto
//!    the mark");
//! 2. the shopper stands too close: the subject composited lower in both pictures, feet
//!    cut off at the bottom edge (the station's cut-off verdict: pose guidance);
//! 3. the shopper steps onto the mark (the recording's subject frames, in order) and
//!    holds still (its last subject frame, repeated) through the countdown until the
//!    measurements settle: the result card;
//! 4. the shopper leaves (empty frames) for longer than the idle timeout: everything is
//!    cleared. The script then loops from the empty scene.
//!
//! [`SessionSource`] is a [`FrameSource`] at the recording's frame rate (timestamps =
//! index / fps); [`trace_kiosk`] runs a processor and the flow over it frame by frame on
//! the source's clock (no frame dropped, no wall clock), for tests.
//!
//! Frames are the recording's pixels; the cut-off composite moves the subject as the
//! station's own segmentation masks it (backdrop learnt from the empty frames).

use super::flow::{FlowAction, FlowConfig, FlowInput, FlowState, KioskFlow};
use crate::camera::StationCalibration;
use crate::pipeline::{FramePair, FrameProcessor, FrameSource, SourceError};
use crate::recording::Recording;
use crate::silhouette::{SilhouetteExecutor, SilhouetteOptions};
use image::RgbImage;
use std::path::Path;
use std::sync::Arc;

/// A pixel whose largest channel difference to the empty scene exceeds this (grey
/// levels) belongs to the subject (or its shadow) for the scripted composites.
pub const PERSON_DIFF: u8 = 40;
/// A frame with more than this fraction of subject pixels shows the subject.
pub const SUBJECT_FRACTION: f64 = 0.002;
/// How far below the bottom edge the cut-off composite pushes the subject's lowest
/// pixel, as a fraction of the frame height.
pub const CUT_OFF_FRACTION: f64 = 0.06;
/// Seconds of the empty scene after learning, of pose guidance, of the result card on
/// screen, and beyond the idle timeout (margin for the timeout to pass).
pub const EMPTY_S: f64 = 1.0;
pub const GUIDANCE_S: f64 = 1.5;
pub const RESULT_S: f64 = 2.0;
/// Extra hold beyond the countdown and the settle wait (frames in flight).
pub const HOLD_MARGIN_S: f64 = 0.5;
pub const LEAVE_MARGIN_S: f64 = 1.5;

/// Why a session cannot be scripted from a recording.
#[derive(Debug, thiserror::Error)]
pub enum SessionError {
    #[error(transparent)]
    Recording(#[from] crate::recording::RecordingError),
    #[error("{0}: the recording needs {1} empty-scene frames at its start (the backdrop) and then frames with the subject; it has {2} empty and {3} subject frames")]
    Content(String, usize, usize, usize),
}

/// What a scripted frame shows.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Shot {
    /// The k-th empty-scene frame (cycled).
    Empty(usize),
    /// The k-th subject frame.
    Subject(usize),
    /// The shopper too close to the cameras: feet cut off.
    CutOff,
}

/// One part of the visit.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Segment {
    pub name: &'static str,
    pub shots: Vec<Shot>,
}

/// Plans the visit for `fps` and the flow's timing; the first segment is learning.
pub fn script(
    fps: f64,
    flow: &FlowConfig,
    learn_frames: usize,
    empty: usize,
    subject: usize,
) -> Vec<Segment> {
    let n = |s: f64| (s * fps).ceil().max(1.0) as usize;
    let empties = |count: usize, from: usize| -> Vec<Shot> {
        (0..count)
            .map(|k| Shot::Empty((from + k) % empty.max(1)))
            .collect()
    };
    let last = subject.saturating_sub(1);
    vec![
        Segment {
            name: "learn the backdrop",
            shots: empties(learn_frames, 0),
        },
        Segment {
            name: "empty scene",
            shots: empties(n(EMPTY_S), learn_frames),
        },
        Segment {
            name: "too close: feet cut off",
            shots: vec![Shot::CutOff; n(GUIDANCE_S)],
        },
        Segment {
            name: "step onto the mark",
            shots: (0..subject).map(Shot::Subject).collect(),
        },
        Segment {
            name: "hold still",
            shots: vec![
                Shot::Subject(last);
                n(flow.countdown_s + flow.settle_timeout_s + HOLD_MARGIN_S)
            ],
        },
        Segment {
            name: "look at the result",
            shots: vec![Shot::Subject(last); n(RESULT_S)],
        },
        Segment {
            name: "leave",
            shots: empties(n(flow.idle_timeout_s + LEAVE_MARGIN_S), 0),
        },
    ]
}

type Pair = (Arc<RgbImage>, Arc<RgbImage>);

/// The scripted visit as a frame source (loops from the empty scene when `looping`).
pub struct SessionSource {
    calibration: StationCalibration,
    fps: f64,
    empty: Vec<Pair>,
    subject: Vec<Pair>,
    cut_off: Pair,
    segments: Vec<Segment>,
    /// Position: segment and shot within it.
    at: (usize, usize),
    given: u64,
    pub looping: bool,
    name: String,
}

impl SessionSource {
    /// Reads a recording (its first `learn_frames` frames must be the empty scene) and
    /// scripts a visit for `flow`.
    ///
    /// # Errors
    /// An unreadable recording, or one without enough empty or subject frames.
    pub fn open(dir: &Path, flow: &FlowConfig, learn_frames: usize) -> Result<Self, SessionError> {
        let mut rec = Recording::open(dir)?;
        let fps = rec.metadata().fps.max(1.0);
        let calibration = rec.calibration().clone();
        let mut empty: Vec<Pair> = Vec::new();
        let mut subject: Vec<Pair> = Vec::new();
        for k in 0..rec.len() {
            let (f, s) = rec.frame_pair(k)?;
            let pair = (Arc::new(f), Arc::new(s));
            let shows_subject = empty.first().is_some_and(|(ef, es)| {
                subject_fraction(&pair.0, ef).max(subject_fraction(&pair.1, es)) > SUBJECT_FRACTION
            });
            if shows_subject {
                subject.push(pair);
            } else if subject.is_empty() {
                empty.push(pair);
            }
        }
        let name = dir.display().to_string();
        let (Some(first_empty), Some(first_subject)) = (empty.first(), subject.first()) else {
            return Err(SessionError::Content(
                name,
                learn_frames,
                empty.len(),
                subject.len(),
            ));
        };
        if empty.len() < learn_frames {
            return Err(SessionError::Content(
                name,
                learn_frames,
                empty.len(),
                subject.len(),
            ));
        }
        let learn = &empty[..learn_frames.min(empty.len())];
        let (mf, ms) = subject_masks(&calibration, learn, first_subject);
        let cut_off = (
            Arc::new(cut_off_composite(&first_subject.0, &first_empty.0, &mf)),
            Arc::new(cut_off_composite(&first_subject.1, &first_empty.1, &ms)),
        );
        let segments = script(fps, flow, learn_frames, empty.len(), subject.len());
        Ok(SessionSource {
            calibration,
            fps,
            empty,
            subject,
            cut_off,
            segments,
            at: (0, 0),
            given: 0,
            looping: false,
            name: format!("kiosk session from {name}"),
        })
    }

    pub fn segments(&self) -> &[Segment] {
        &self.segments
    }

    /// Pairs in one pass of the script.
    pub fn len(&self) -> usize {
        self.segments.iter().map(|s| s.shots.len()).sum()
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The name of the segment the next pair belongs to.
    pub fn segment_name(&self) -> Option<&'static str> {
        self.segments.get(self.at.0).map(|s| s.name)
    }

    fn frames(&self, shot: Shot) -> Option<&Pair> {
        match shot {
            Shot::Empty(k) => self.empty.get(k % self.empty.len().max(1)),
            Shot::Subject(k) => self.subject.get(k),
            Shot::CutOff => Some(&self.cut_off),
        }
    }
}

impl FrameSource for SessionSource {
    fn next_pair(&mut self) -> Result<Option<FramePair>, SourceError> {
        loop {
            let Some(seg) = self.segments.get(self.at.0) else {
                if !self.looping {
                    return Ok(None);
                }
                // Learning happens once: loop from the empty scene.
                self.at = (1.min(self.segments.len().saturating_sub(1)), 0);
                continue;
            };
            let Some(&shot) = seg.shots.get(self.at.1) else {
                self.at = (self.at.0 + 1, 0);
                continue;
            };
            self.at.1 += 1;
            let index = self.given;
            let Some((f, s)) = self.frames(shot) else {
                return Err(SourceError::Skipped(format!(
                    "{shot:?} is not in the recording"
                )));
            };
            let pair = FramePair {
                index,
                timestamp_s: index as f64 / self.fps,
                front: (**f).clone().into(),
                side: (**s).clone().into(),
            };
            self.given += 1;
            return Ok(Some(pair));
        }
    }
    fn calibration(&self) -> Option<&StationCalibration> {
        Some(&self.calibration)
    }
    fn fps(&self) -> Option<f64> {
        Some(self.fps)
    }
    fn describe(&self) -> String {
        self.name.clone()
    }
}

/// Fraction of pixels of `frame` that differ from `empty` by more than [`PERSON_DIFF`].
pub fn subject_fraction(frame: &RgbImage, empty: &RgbImage) -> f64 {
    if frame.dimensions() != empty.dimensions() || frame.is_empty() {
        return 0.0;
    }
    let n = frame
        .pixels()
        .zip(empty.pixels())
        .filter(|(a, b)| differs(a.0, b.0))
        .count();
    n as f64 / (frame.width() as f64 * frame.height() as f64)
}

fn differs(a: [u8; 3], b: [u8; 3]) -> bool {
    a.iter().zip(&b).any(|(x, y)| x.abs_diff(*y) > PERSON_DIFF)
}

/// The subject of `subject` (pixels where `mask` is non-zero, row-major, grown by
/// [`MASK_GROW_PX`] to take the blended border along) moved down over the empty scene
/// `empty` until the mask's lowest row is [`CUT_OFF_FRACTION`] of the height below the
/// bottom edge. A mask of the wrong size or with no pixel leaves `subject` as it is.
pub fn cut_off_composite(subject: &RgbImage, empty: &RgbImage, mask: &[u8]) -> RgbImage {
    let (w, h) = subject.dimensions();
    let (wu, hu) = (w as usize, h as usize);
    if empty.dimensions() != (w, h) || mask.len() != wu * hu {
        return subject.clone();
    }
    let grown = grow(mask, wu, hu, MASK_GROW_PX);
    let Some(lowest) = (0..hu)
        .rev()
        .find(|&y| grown[y * wu..(y + 1) * wu].iter().any(|&m| m != 0))
    else {
        return subject.clone();
    };
    let shift = (hu - 1 - lowest) + (CUT_OFF_FRACTION * h as f64).ceil() as usize;
    let mut out = empty.clone();
    for y in shift..hu {
        let sy = y - shift;
        for x in 0..wu {
            if grown[sy * wu + x] != 0 {
                out.put_pixel(x as u32, y as u32, *subject.get_pixel(x as u32, sy as u32));
            }
        }
    }
    out
}

/// Pixels the subject mask is grown by before compositing.
pub const MASK_GROW_PX: usize = 2;

/// A binary mask dilated by a square of half-size `r`.
fn grow(mask: &[u8], w: usize, h: usize, r: usize) -> Vec<u8> {
    let mut rows = vec![0u8; w * h];
    for y in 0..h {
        for x in 0..w {
            if mask[y * w + x] != 0 {
                let (x0, x1) = (x.saturating_sub(r), (x + r).min(w - 1));
                rows[y * w + x0..=y * w + x1].fill(1);
            }
        }
    }
    let mut out = vec![0u8; w * h];
    for y in 0..h {
        let (y0, y1) = (y.saturating_sub(r), (y + r).min(h - 1));
        for x in 0..w {
            if (y0..=y1).any(|yy| rows[yy * w + x] != 0) {
                out[y * w + x] = 1;
            }
        }
    }
    out
}

/// The subject's mask in both views as the station segments it (its backdrop learnt
/// from `empties`), or the pixels that differ from the first empty frame when the
/// segmentation fails.
fn subject_masks(
    calibration: &StationCalibration,
    empties: &[Pair],
    subject: &Pair,
) -> (Vec<u8>, Vec<u8>) {
    let diff = |f: &RgbImage, e: &RgbImage| -> Vec<u8> {
        f.pixels()
            .zip(e.pixels())
            .map(|(a, b)| u8::from(differs(a.0, b.0)))
            .collect()
    };
    let mut ex = SilhouetteExecutor::new(calibration, SilhouetteOptions::default());
    let learnt = empties
        .iter()
        .all(|(f, s)| ex.learn_background(f, s).is_ok());
    if learnt {
        if let Ok(r) = ex.process(&subject.0, &subject.1) {
            return (r.masks.front.data, r.masks.side.data);
        }
    }
    match empties.first() {
        Some((ef, es)) => (diff(&subject.0, ef), diff(&subject.1, es)),
        None => (Vec::new(), Vec::new()),
    }
}

/// One frame of a kiosk trace.
#[derive(Debug, Clone, PartialEq)]
pub struct TraceStep {
    pub frame: u64,
    pub time_s: f64,
    pub state: FlowState,
    /// The flow asked to forget the shopper at this frame.
    pub cleared: bool,
    /// The station's messages for this frame (verdicts first).
    pub messages: Vec<String>,
}

/// Runs `processor` and the kiosk flow over every pair of `source` (at most
/// `max_pairs`), on the source's clock, clearing the processor's subject when the flow
/// says so.
pub fn trace_kiosk(
    source: &mut dyn FrameSource,
    processor: &mut dyn FrameProcessor,
    config: FlowConfig,
    max_pairs: usize,
) -> Vec<TraceStep> {
    let mut flow = KioskFlow::new(config);
    let mut out = Vec::new();
    for _ in 0..max_pairs {
        let pair = match source.next_pair() {
            Ok(Some(p)) => p,
            Ok(None) => break,
            Err(_) => continue,
        };
        let snap = processor.process(&pair);
        let mut cleared = flow.on_snapshot(&FlowInput::from_snapshot(&snap), pair.timestamp_s)
            == Some(FlowAction::ClearSubject);
        cleared |= flow.on_tick(pair.timestamp_s) == Some(FlowAction::ClearSubject);
        if cleared {
            processor.reset_subject();
        }
        out.push(TraceStep {
            frame: pair.index,
            time_s: pair.timestamp_s,
            state: flow.state().clone(),
            cleared,
            messages: snap.messages,
        });
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn script_orders_the_visit_and_scales_with_the_flow() {
        let cfg = FlowConfig {
            countdown_s: 2.0,
            idle_timeout_s: 4.0,
            result_display_s: 30.0,
            settle_timeout_s: 1.5,
        };
        let s = script(10.0, &cfg, 5, 8, 6);
        let names: Vec<&str> = s.iter().map(|s| s.name).collect();
        assert_eq!(names.first(), Some(&"learn the backdrop"));
        assert_eq!(names.last(), Some(&"leave"));
        assert_eq!(s[0].shots.len(), 5);
        assert!(s[0].shots.iter().all(|x| matches!(x, Shot::Empty(_))));
        let hold = s.iter().find(|x| x.name == "hold still").expect("hold");
        assert_eq!(hold.shots.len(), 40);
        // Long enough for the settle timeout: a card comes even if the fit jitters.
        assert!(hold.shots.len() as f64 / 10.0 > cfg.countdown_s + cfg.settle_timeout_s);
        assert!(hold.shots.iter().all(|x| *x == Shot::Subject(5)));
        let leave = s.iter().find(|x| x.name == "leave").expect("leave");
        assert_eq!(leave.shots.len(), 55);
        assert!(s.iter().any(|x| x.shots.contains(&Shot::CutOff)));
    }

    #[test]
    fn cut_off_moves_the_subject_past_the_bottom_edge() {
        let empty = RgbImage::from_pixel(20, 40, image::Rgb([100, 100, 100]));
        let mut subject = empty.clone();
        for y in 10..30 {
            for x in 8..12 {
                subject.put_pixel(x, y, image::Rgb([250, 20, 20]));
            }
        }
        // The mask marks the subject's inner part; growing it takes the border along.
        let mut mask = vec![0u8; 20 * 40];
        for y in 12..28 {
            for x in 9..11 {
                mask[y * 20 + x] = 255;
            }
        }
        let out = cut_off_composite(&subject, &empty, &mask);
        // The grown mask's bottom (row 29) is pushed past the last row.
        let g = MASK_GROW_PX as u32;
        let shift = (40 - 1 - (27 + g)) + (CUT_OFF_FRACTION * 40.0).ceil() as u32;
        assert_eq!(out.get_pixel(10, 39).0, [250, 20, 20]);
        assert_eq!(out.get_pixel(8, 39).0, [250, 20, 20]);
        assert_eq!(out.get_pixel(10, 12 - g + shift).0, [250, 20, 20]);
        assert_eq!(out.get_pixel(10, 12 - g + shift - 1).0, [100, 100, 100]);
        assert_eq!(out.get_pixel(2, 39).0, [100, 100, 100]);
        assert_eq!(cut_off_composite(&subject, &empty, &[]), subject);
        assert!(subject_fraction(&out, &empty) > 0.0);
        assert_eq!(subject_fraction(&empty, &empty), 0.0);
    }
}
