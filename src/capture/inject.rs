//! Fault injection on frame sources: [`FaultInjector`] wraps any [`FrameSource`] and,
//! on a schedule in the source's own time, makes it fail the way USB cameras and their
//! drivers fail on a shop floor. It is the `--inject SPEC` option of `fitstation replay`
//! and the fake two-camera device of the fault tests.
//!
//! The wrapper splits each pair of the inner source into its two camera streams and
//! pairs them again with the capture layer's own [`PairMatcher`] (the bound
//! [`DEFAULT_MAX_SKEW_S`]), as `CameraPairSource` does with real cameras: a
//! dropped camera therefore yields no pairs (and the frames of the other camera are
//! never paired with a stale one), exactly as on the live path.
//!
//! # Faults ([`FaultKind`])
//! - `stall`: the source blocks, no frame at all for the duration (frames are lost).
//! - `drop-front` / `drop-side`: one camera delivers nothing; the source says the
//!   camera is lost ([`SourceError::Disconnected`]) for each frame time.
//! - `cut-side`: the side camera lost for longer than the stall timeout: as the live
//!   source then does ([`super::DevicePairSource`]), the front frames go on alone, as
//!   front-only pairs (an empty side frame), which the station fits from the front view.
//! - `reorder`: consecutive pairs are delivered swapped (k+1 before k).
//! - `duplicate`: every pair is delivered twice.
//! - `corrupt-front` / `corrupt-side`: the camera's frame is random bytes.
//! - `resize-front` / `resize-side`: the camera's frame has the wrong size (half).
//! - `exposure`, `exposure-front`, `exposure-side` (`=GAIN`, default
//!   [`DEFAULT_EXPOSURE_GAIN`]): the frames are suddenly `GAIN` times brighter.
//!
//! # Time
//! Fault windows are in seconds of the inner source's timestamps ([`FramePair`]
//! `timestamp_s`), `[start, start + duration)`. Offline nothing sleeps; with
//! [`FaultInjector::real_time`] each swallowed frame costs one frame period of wall time,
//! so that a paced replay on screen stalls as long as the schedule says.

use super::{PairMatcher, DEFAULT_MAX_SKEW_S};
use crate::camera::{StationCalibration, View};
use crate::pipeline::{FramePair, FrameSource, SourceError};
use crate::synth::rng::SplitMix64;
use image::RgbImage;
use std::collections::VecDeque;
use std::sync::Arc;
use std::time::Duration;

/// Brightness gain of an `exposure` fault without `=GAIN`: well outside the exposure
/// drift the backdrop model divides out (0.8 to 1.25, `segment`).
pub const DEFAULT_EXPOSURE_GAIN: f64 = 1.8;
/// Frame period assumed for real-time pacing when the inner source has no frame rate.
const FALLBACK_PERIOD_S: f64 = 1.0 / 30.0;
/// Seed of the corrupt frames' random bytes (runs are reproducible).
const NOISE_SEED: u64 = 0x000f_a017;

/// One kind of fault.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum FaultKind {
    /// No frame at all.
    Stall,
    /// One camera delivers nothing.
    Drop(View),
    /// The side camera is gone for long: front-only pairs.
    CutSide,
    /// Pairs delivered swapped in twos.
    Reorder,
    /// Every pair delivered twice.
    Duplicate,
    /// A camera's frame is random bytes of the right size.
    Corrupt(View),
    /// A camera's frame has the wrong size.
    Resize(View),
    /// Frames `gain` times brighter: one camera, or both (`None`).
    Exposure { view: Option<View>, gain: f64 },
}

impl FaultKind {
    /// The SPEC name of the fault ("drop-side").
    pub fn name(&self) -> String {
        let v = |view: &View| view.name();
        match self {
            FaultKind::Stall => "stall".into(),
            FaultKind::Drop(view) => format!("drop-{}", v(view)),
            FaultKind::CutSide => "cut-side".into(),
            FaultKind::Reorder => "reorder".into(),
            FaultKind::Duplicate => "duplicate".into(),
            FaultKind::Corrupt(view) => format!("corrupt-{}", v(view)),
            FaultKind::Resize(view) => format!("resize-{}", v(view)),
            FaultKind::Exposure { view: None, gain } => format!("exposure={gain}"),
            FaultKind::Exposure {
                view: Some(view),
                gain,
            } => format!("exposure-{}={gain}", v(view)),
        }
    }

    /// True when the fault changes the frames of `view`.
    fn touches(&self, view: View) -> bool {
        match self {
            FaultKind::Drop(v) | FaultKind::Corrupt(v) | FaultKind::Resize(v) => *v == view,
            FaultKind::CutSide => view == View::Side,
            FaultKind::Exposure { view: v, .. } => v.is_none_or(|v| v == view),
            _ => false,
        }
    }
}

/// A fault over a window of source time.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Fault {
    pub kind: FaultKind,
    pub start_s: f64,
    pub duration_s: f64,
}

impl Fault {
    /// True when the fault is active at source time `t_s`.
    pub fn active_at(&self, t_s: f64) -> bool {
        t_s >= self.start_s && t_s < self.start_s + self.duration_s
    }
    /// End of the window (s).
    pub fn end_s(&self) -> f64 {
        self.start_s + self.duration_s
    }
}

/// A SPEC that could not be read.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("--inject '{item}': {msg} (expected KIND[=GAIN]@START:DURATION, e.g. drop-side@40:60)")]
pub struct SpecError {
    pub item: String,
    pub msg: String,
}

/// The SPEC syntax, for `--help`.
pub const SPEC_HELP: &str = "Inject faults into the frame source: a comma-separated list of \
KIND[=GAIN]@START:DURATION, times in seconds of the recording (e.g. \
'drop-side@4:2,stall@8:1.5,exposure=1.8@12:0.5'). KIND is stall, drop-front, drop-side, \
cut-side (front-only pairs, the side camera lost for long), reorder, duplicate, corrupt-front, corrupt-side, resize-front, resize-side, exposure, \
exposure-front or exposure-side (GAIN: brightness factor of exposure faults, default 1.8).";

/// Reads a fault schedule: `KIND[=GAIN]@START:DURATION[,...]` (see [`SPEC_HELP`]).
///
/// # Errors
/// An unknown kind, a missing `@` or `:`, a time that is not a finite non-negative
/// number, a zero duration, or a gain that is not a positive number.
pub fn parse_spec(spec: &str) -> Result<Vec<Fault>, SpecError> {
    let mut out = Vec::new();
    for item in spec.split(',').map(str::trim).filter(|s| !s.is_empty()) {
        out.push(parse_fault(item)?);
    }
    if out.is_empty() {
        return Err(SpecError {
            item: spec.into(),
            msg: "no fault given".into(),
        });
    }
    Ok(out)
}

/// Reads one `KIND[=GAIN]@START:DURATION`.
fn parse_fault(item: &str) -> Result<Fault, SpecError> {
    let bad = |msg: &str| SpecError {
        item: item.into(),
        msg: msg.into(),
    };
    let (head, window) = item
        .split_once('@')
        .ok_or_else(|| bad("no '@START:DURATION'"))?;
    let (start, duration) = window
        .split_once(':')
        .ok_or_else(|| bad("no ':DURATION' after the start time"))?;
    let seconds = |s: &str, what: &str| -> Result<f64, SpecError> {
        s.trim()
            .parse::<f64>()
            .ok()
            .filter(|v| v.is_finite() && *v >= 0.0)
            .ok_or_else(|| bad(&format!("{what} '{s}' is not a time in seconds")))
    };
    let start_s = seconds(start, "start")?;
    let duration_s = seconds(duration, "duration")?;
    if duration_s <= 0.0 {
        return Err(bad("the duration must be more than zero"));
    }
    let (name, gain) = match head.split_once('=') {
        Some((n, g)) => {
            let gain = g
                .trim()
                .parse::<f64>()
                .ok()
                .filter(|v| v.is_finite() && *v > 0.0)
                .ok_or_else(|| bad(&format!("gain '{g}' is not a positive number")))?;
            (n.trim(), Some(gain))
        }
        None => (head.trim(), None),
    };
    let kind = fault_kind(name, gain).ok_or_else(|| bad(&format!("unknown fault '{name}'")))?;
    if gain.is_some() && !matches!(kind, FaultKind::Exposure { .. }) {
        return Err(bad("only exposure faults take '=GAIN'"));
    }
    Ok(Fault {
        kind,
        start_s,
        duration_s,
    })
}

/// The fault named `name` (SPEC spelling).
fn fault_kind(name: &str, gain: Option<f64>) -> Option<FaultKind> {
    let gain = gain.unwrap_or(DEFAULT_EXPOSURE_GAIN);
    Some(match name {
        "stall" => FaultKind::Stall,
        "drop-front" => FaultKind::Drop(View::Front),
        "drop-side" => FaultKind::Drop(View::Side),
        "cut-side" => FaultKind::CutSide,
        "reorder" => FaultKind::Reorder,
        "duplicate" => FaultKind::Duplicate,
        "corrupt-front" => FaultKind::Corrupt(View::Front),
        "corrupt-side" => FaultKind::Corrupt(View::Side),
        "resize-front" => FaultKind::Resize(View::Front),
        "resize-side" => FaultKind::Resize(View::Side),
        "exposure" => FaultKind::Exposure { view: None, gain },
        "exposure-front" => FaultKind::Exposure {
            view: Some(View::Front),
            gain,
        },
        "exposure-side" => FaultKind::Exposure {
            view: Some(View::Side),
            gain,
        },
        _ => return None,
    })
}

/// A [`FrameSource`] that injects faults into another one (module docs).
pub struct FaultInjector {
    inner: Box<dyn FrameSource>,
    faults: Vec<Fault>,
    /// Per fault: started (said) yet, ended (said) yet.
    said: Vec<(bool, bool)>,
    matcher: PairMatcher<RgbImage>,
    /// Pairs ready to be given (duplicates, a reordered pair after its successor).
    out: VecDeque<FramePair>,
    /// The pair held back by `reorder`, given after the next one.
    held: Option<FramePair>,
    /// Sleep one frame period per swallowed frame (a paced replay on screen).
    real_time: bool,
    log_to_stderr: bool,
    events: Vec<String>,
    rng: SplitMix64,
    /// Pairs formed so far: the index of the next one.
    formed: u64,
    /// Source time since which `drop-side` has swallowed the side frames.
    side_dropped_since: Option<f64>,
    /// After this long without side frames the side camera counts as lost and the
    /// front frames go on alone ([`super::ReconnectPolicy::stall_timeout_s`], as the
    /// camera pair source does).
    side_lost_after_s: f64,
}

impl FaultInjector {
    /// Wraps `inner`; nothing sleeps and nothing is printed (tests, offline replay).
    pub fn new(inner: Box<dyn FrameSource>, faults: Vec<Fault>) -> Self {
        let said = vec![(false, false); faults.len()];
        FaultInjector {
            inner,
            faults,
            said,
            matcher: PairMatcher::new(DEFAULT_MAX_SKEW_S),
            out: VecDeque::new(),
            held: None,
            real_time: false,
            log_to_stderr: false,
            events: Vec::new(),
            rng: SplitMix64::new(NOISE_SEED),
            formed: 0,
            side_dropped_since: None,
            side_lost_after_s: super::ReconnectPolicy::default().stall_timeout_s,
        }
    }

    /// Swallowed frames take their frame period of wall time (a paced source on screen).
    pub fn real_time(mut self, on: bool) -> Self {
        self.real_time = on;
        self
    }

    /// Print each fault's start and end on stderr (the replay's log).
    pub fn log_to_stderr(mut self, on: bool) -> Self {
        self.log_to_stderr = on;
        self
    }

    /// What was injected so far, one line per fault start and end.
    pub fn events(&self) -> &[String] {
        &self.events
    }

    /// Frames the pairing could not match (a dropped camera's partner frames).
    pub fn unpaired_frames(&self) -> u64 {
        self.matcher.dropped()
    }

    /// Records the start and end of fault windows as source time passes `t_s`.
    fn note_windows(&mut self, t_s: f64, index: u64) {
        for (f, said) in self.faults.iter().zip(self.said.iter_mut()) {
            let mut line = None;
            if !said.0 && f.active_at(t_s) {
                said.0 = true;
                line = Some(format!(
                    "inject: {} from {:.2} s for {:.2} s (frame {index})",
                    f.kind.name(),
                    f.start_s,
                    f.duration_s
                ));
            } else if said.0 && !said.1 && t_s >= f.end_s() {
                said.1 = true;
                line = Some(format!(
                    "inject: {} ended at {:.2} s (frame {index})",
                    f.kind.name(),
                    f.end_s()
                ));
            }
            if let Some(l) = line {
                if self.log_to_stderr {
                    eprintln!("{l}");
                }
                self.events.push(l);
            }
        }
    }

    /// The faults active at `t_s`.
    fn active(&self, t_s: f64) -> Vec<FaultKind> {
        self.faults
            .iter()
            .filter(|f| f.active_at(t_s))
            .map(|f| f.kind)
            .collect()
    }

    /// Waits one frame period when pacing in real time (a frame that never came).
    fn pace_swallowed(&self) {
        if self.real_time {
            let period = self
                .inner
                .fps()
                .filter(|f| f.is_finite() && *f > 0.0)
                .map_or(FALLBACK_PERIOD_S, |f| 1.0 / f);
            std::thread::sleep(Duration::from_secs_f64(period));
        }
    }

    /// Applies the active frame faults to one camera's frame.
    fn damage(&mut self, view: View, frame: RgbImage, active: &[FaultKind]) -> RgbImage {
        let mut frame = frame;
        for k in active.iter().filter(|k| k.touches(view)) {
            frame = match k {
                FaultKind::Corrupt(_) => random_frame(&mut self.rng, frame.width(), frame.height()),
                FaultKind::Resize(_) => wrong_size_frame(&frame),
                FaultKind::Exposure { gain, .. } => exposed(frame, *gain),
                _ => frame,
            };
        }
        frame
    }

    /// Feeds one inner pair through the per-camera faults and the pairing; returns the
    /// pair formed, if any, or the error a real pair source would give.
    fn through_cameras(
        &mut self,
        pair: FramePair,
        active: &[FaultKind],
    ) -> Result<Option<FramePair>, SourceError> {
        let t = pair.timestamp_s;
        let dropped = |v: View| active.contains(&FaultKind::Drop(v));
        // A side camera silent past the stall timeout is lost: front-only pairs, as the
        // camera pair source gives them.
        self.side_dropped_since = if dropped(View::Side) {
            self.side_dropped_since.or(Some(t))
        } else {
            None
        };
        let side_lost = !dropped(View::Front)
            && self
                .side_dropped_since
                .is_some_and(|t0| t - t0 > self.side_lost_after_s);
        if active.contains(&FaultKind::CutSide) || side_lost {
            self.matcher.clear();
            let index = self.formed;
            self.formed += 1;
            let front = self.damage(View::Front, Arc::unwrap_or_clone(pair.front), active);
            return Ok(Some(FramePair {
                index,
                timestamp_s: t,
                front: front.into(),
                side: RgbImage::new(0, 0).into(),
            }));
        }
        if !dropped(View::Front) {
            let f = self.damage(View::Front, Arc::unwrap_or_clone(pair.front), active);
            self.matcher.push_front(t, f);
        }
        if !dropped(View::Side) {
            let s = self.damage(View::Side, Arc::unwrap_or_clone(pair.side), active);
            self.matcher.push_side(t, s);
        }
        match self.matcher.pop_pair() {
            Some(m) => {
                // Numbered as formed, like a camera pair source: frames lost before
                // pairing leave no hole in the numbers, only in the time.
                let index = self.formed;
                self.formed += 1;
                Ok(Some(FramePair {
                    index,
                    timestamp_s: m.timestamp_s,
                    front: m.front.into(),
                    side: m.side.into(),
                }))
            }
            None => {
                let lost: Vec<&str> = View::BOTH
                    .into_iter()
                    .filter(|v| dropped(*v))
                    .map(|v| v.name())
                    .collect();
                if lost.is_empty() {
                    Ok(None)
                } else {
                    Err(SourceError::Disconnected(format!(
                        "{} camera lost: no frames",
                        lost.join(" and ")
                    )))
                }
            }
        }
    }

    /// Puts a formed pair into the output queue, applying the pair-level faults.
    fn queue_pair(&mut self, pair: FramePair, active: &[FaultKind]) {
        if active.contains(&FaultKind::Reorder) {
            match self.held.take() {
                None => {
                    self.held = Some(pair);
                    return;
                }
                Some(earlier) => {
                    self.out.push_back(pair);
                    self.out.push_back(earlier);
                    return;
                }
            }
        }
        if let Some(earlier) = self.held.take() {
            self.out.push_back(earlier);
        }
        if active.contains(&FaultKind::Duplicate) {
            self.out.push_back(pair.clone());
        }
        self.out.push_back(pair);
    }
}

impl FrameSource for FaultInjector {
    fn next_pair(&mut self) -> Result<Option<FramePair>, SourceError> {
        loop {
            if let Some(p) = self.out.pop_front() {
                return Ok(Some(p));
            }
            let Some(pair) = self.inner.next_pair()? else {
                // The end: a pair held back by `reorder` still goes out.
                return Ok(self.held.take());
            };
            self.note_windows(pair.timestamp_s, pair.index);
            let active = self.active(pair.timestamp_s);
            if active.contains(&FaultKind::Stall) {
                self.pace_swallowed();
                continue;
            }
            match self.through_cameras(pair, &active) {
                Ok(Some(p)) => self.queue_pair(p, &active),
                Ok(None) => self.pace_swallowed(),
                Err(e) => {
                    self.pace_swallowed();
                    return Err(e);
                }
            }
        }
    }

    fn calibration(&self) -> Option<&StationCalibration> {
        self.inner.calibration()
    }

    fn fps(&self) -> Option<f64> {
        self.inner.fps()
    }

    fn describe(&self) -> String {
        let spec: Vec<String> = self
            .faults
            .iter()
            .map(|f| format!("{}@{}:{}", f.kind.name(), f.start_s, f.duration_s))
            .collect();
        format!("{} with faults {}", self.inner.describe(), spec.join(","))
    }
}

/// A frame of random bytes (a corrupt transfer decoded as pixels).
fn random_frame(rng: &mut SplitMix64, width: u32, height: u32) -> RgbImage {
    let mut bytes = vec![0u8; (width as usize) * (height as usize) * 3];
    for chunk in bytes.chunks_mut(8) {
        let r = rng.next_u64().to_le_bytes();
        chunk.copy_from_slice(&r[..chunk.len()]);
    }
    RgbImage::from_raw(width, height, bytes).unwrap_or_else(|| RgbImage::new(width, height))
}

/// A frame of half the size (a camera that fell back to another mode).
fn wrong_size_frame(frame: &RgbImage) -> RgbImage {
    let (w, h) = ((frame.width() / 2).max(1), (frame.height() / 2).max(1));
    RgbImage::from_fn(w, h, |x, y| *frame.get_pixel(2 * x, 2 * y))
}

/// The frame `gain` times brighter (clipped at white).
fn exposed(mut frame: RgbImage, gain: f64) -> RgbImage {
    let g = gain as f32;
    for v in frame.iter_mut() {
        *v = (*v as f32 * g).round().clamp(0.0, 255.0) as u8;
    }
    frame
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Pairs 0.. at 10 fps, 4x2 frames whose first byte is the index.
    struct Counter {
        next: u64,
        len: u64,
    }

    impl FrameSource for Counter {
        fn next_pair(&mut self) -> Result<Option<FramePair>, SourceError> {
            if self.next >= self.len {
                return Ok(None);
            }
            let k = self.next;
            self.next += 1;
            let img = RgbImage::from_pixel(4, 2, image::Rgb([k as u8, 100, 100]));
            Ok(Some(FramePair {
                index: k,
                timestamp_s: k as f64 * 0.1,
                front: img.clone().into(),
                side: img.into(),
            }))
        }
        fn calibration(&self) -> Option<&StationCalibration> {
            None
        }
        fn describe(&self) -> String {
            "counter".into()
        }
    }

    /// Runs the injector to the end: per call, the pair index or the error.
    fn run(spec: &str) -> Vec<Result<(u64, u8, u8), String>> {
        let faults = parse_spec(spec).expect("spec");
        let mut inj = FaultInjector::new(Box::new(Counter { next: 0, len: 10 }), faults);
        let mut out = Vec::new();
        loop {
            match inj.next_pair() {
                Ok(Some(p)) => out.push(Ok((p.index, p.front[(0, 0)][0], p.side[(0, 0)][0]))),
                Ok(None) => break,
                Err(e) => out.push(Err(e.to_string())),
            }
        }
        out
    }

    /// The inner source's index of each pair given (from its pixels).
    fn indices(r: &[Result<(u64, u8, u8), String>]) -> Vec<u64> {
        r.iter()
            .filter_map(|x| x.as_ref().ok().map(|p| p.1 as u64))
            .collect()
    }

    #[test]
    fn spec_parses_and_rejects_with_clear_messages() {
        let f = parse_spec("drop-side@40:60, stall@100:5,exposure-front=0.5@1:2").unwrap();
        assert_eq!(f.len(), 3);
        assert_eq!(f[0].kind, FaultKind::Drop(View::Side));
        assert_eq!((f[1].start_s, f[1].duration_s), (100.0, 5.0));
        assert_eq!(
            f[2].kind,
            FaultKind::Exposure {
                view: Some(View::Front),
                gain: 0.5
            }
        );
        for (bad, says) in [
            ("", "no fault"),
            ("wobble@1:2", "unknown fault"),
            ("stall@1", "DURATION"),
            ("stall1:2", "@START"),
            ("stall@x:2", "not a time"),
            ("stall@1:0", "more than zero"),
            ("stall=2@1:1", "only exposure"),
            ("exposure=-1@1:1", "positive"),
        ] {
            let e = parse_spec(bad).expect_err(bad).to_string();
            assert!(e.contains(says), "{bad}: {e}");
        }
    }

    #[test]
    fn without_faults_every_pair_passes_in_order() {
        assert_eq!(indices(&run("stall@100:1")), (0..10).collect::<Vec<_>>());
    }

    #[test]
    fn stall_loses_the_frames_of_its_window_silently() {
        let r = run("stall@0.25:0.3");
        assert_eq!(indices(&r), vec![0, 1, 2, 6, 7, 8, 9]);
        assert!(r.iter().all(|x| x.is_ok()));
        // Numbered as formed: the hole is in the time only.
        let numbers: Vec<u64> = r.iter().flatten().map(|p| p.0).collect();
        assert_eq!(numbers, (0..7).collect::<Vec<_>>());
    }

    #[test]
    fn a_dropped_camera_is_lost_and_never_paired_with_a_stale_frame() {
        let r = run("drop-side@0.25:0.3");
        assert_eq!(indices(&r), vec![0, 1, 2, 6, 7, 8, 9]);
        let errors: Vec<&String> = r.iter().filter_map(|x| x.as_ref().err()).collect();
        assert_eq!(errors.len(), 3);
        assert!(errors[0].contains("side camera lost"), "{}", errors[0]);
        for p in r.iter().flatten() {
            assert_eq!(p.1, p.2, "front and side of one moment");
        }
    }

    #[test]
    fn a_side_camera_dropped_past_the_stall_timeout_leaves_front_only_pairs() {
        let faults = parse_spec("drop-side@0.45:10").unwrap();
        let mut inj = FaultInjector::new(Box::new(Counter { next: 0, len: 40 }), faults);
        // Off the frame times' grid (one frame per 0.1 s), so no frame sits on the edge.
        inj.side_lost_after_s = 1.95;
        let (mut lost, mut front_only, mut paired) = (0, Vec::new(), 0);
        loop {
            match inj.next_pair() {
                Ok(Some(p)) if p.side.width() == 0 => front_only.push(p.front[(0, 0)][0]),
                Ok(Some(_)) => paired += 1,
                Ok(None) => break,
                Err(_) => lost += 1,
            }
        }
        // Frames at 0.5 s to 2.4 s: lost (within the stall timeout); from 2.5 s on
        // the front frames alone.
        assert_eq!(paired, 5);
        assert_eq!(lost, 20);
        assert_eq!(front_only, (25..40).collect::<Vec<u8>>());
    }

    #[test]
    fn reorder_and_duplicate_at_pair_level() {
        assert_eq!(
            indices(&run("reorder@0.15:0.4")),
            vec![0, 1, 3, 2, 5, 4, 6, 7, 8, 9]
        );
        assert_eq!(
            indices(&run("duplicate@0.15:0.2")),
            vec![0, 1, 2, 2, 3, 3, 4, 5, 6, 7, 8, 9]
        );
        // A pair held back when the window closes (or the source ends) still goes out.
        assert_eq!(
            indices(&run("reorder@0.85:5")),
            vec![0, 1, 2, 3, 4, 5, 6, 7, 8, 9]
        );
    }

    #[test]
    fn frame_faults_change_only_their_camera() {
        let faults = parse_spec("resize-side@0:0.05,exposure-front=2@0.1:0.05").unwrap();
        let mut inj = FaultInjector::new(Box::new(Counter { next: 0, len: 3 }), faults);
        let p0 = inj.next_pair().unwrap().unwrap();
        assert_eq!((p0.front.width(), p0.side.width()), (4, 2));
        let p1 = inj.next_pair().unwrap().unwrap();
        assert_eq!((p1.front[(0, 0)][1], p1.side[(0, 0)][1]), (200, 100));
        let p2 = inj.next_pair().unwrap().unwrap();
        assert_eq!(p2.front, p2.side);
        assert_eq!(inj.events().len(), 4, "{:?}", inj.events());
    }
}
