//! Faults of the frame source, found before the stages: [`FaultMonitor`] looks at each
//! frame pair the station is given and either lets it through (with a note when frames
//! come back after a gap) or skips it with a message, so that the station keeps its last
//! good measurements through stalls, lost cameras, reordered, duplicated or corrupt
//! frames and sudden exposure changes, and resumes by itself when good frames return.
//!
//! The checks, in order (each a function below):
//! 1. frame sizes against the calibration (a wrongly sized frame is skipped);
//! 2. order: a pair older than the last one, or the same pair again, is skipped;
//! 3. content: a frame of random bytes (corrupt transfer) is skipped;
//! 4. time: a gap longer than [`MAX_GAP_S`] since the last pair is said (a stalled
//!    source or a lost camera) and the pair is used;
//! 5. exposure: frames much brighter or darker than the learned backdrop are skipped;
//!    when that lasts [`EXPOSURE_RELEARN_S`], the scene has changed and the backdrop is
//!    learnt again. Nothing else re-learns it: after a stall or a lost camera the old
//!    backdrop is kept when the scene still matches it.
//!
//! Pairing: the station only ever receives pairs; two frames further apart than
//! [`crate::capture::DEFAULT_MAX_SKEW_S`] are never paired by the capture layer
//! ([`crate::capture::PairMatcher`]), live or under fault injection.
//!
//! Units: seconds of the source's clock (`FramePair::timestamp_s`), 8-bit luma.

use super::StationProcessor;
use crate::camera::{StationCalibration, View};
use crate::pipeline::{has_frame, FitSnapshot, FramePair, Phase};
use crate::silhouette::SilhouetteExecutor;
use image::RgbImage;
use std::sync::Arc;

/// A longer time per pair since the last one (s; the gap over the pairs numbered in
/// between, which the station's own newest-wins queue may have dropped) means frames
/// never came: the source stalled or a camera was gone. Cameras run at 7.5 fps or more.
pub const MAX_GAP_S: f64 = 0.25;
/// Exposure ratio against the backdrop beyond which a frame is an exposure fault: the
/// range the backdrop model divides out by itself is 0.8 to 1.25 (`segment`).
pub const EXPOSURE_JUMP: f64 = 1.25;
/// An exposure fault lasting this long (s) is a changed scene: learn the backdrop again.
pub const EXPOSURE_RELEARN_S: f64 = 1.0;
/// Mean luma step between horizontal neighbours above which a frame is random bytes
/// (a camera image: a few levels; uniform noise: about 85).
pub const NOISE_STEP: f64 = 40.0;
/// Sampling step (pixels) of the luma grid used by the exposure and noise checks.
const SAMPLE_STEP: u32 = 16;
/// The exposure check samples bands of 1/`BAND_FRACTION` of the frame at its top,
/// left and right.
const BAND_FRACTION: u32 = 6;
/// Backdrop luma below which a sample says nothing about the exposure ratio.
const MIN_REFERENCE_LUMA: f32 = 20.0;

/// The phase and frames of the last snapshot made from a good pair.
#[derive(Debug, Clone)]
struct LastGood {
    phase: Phase,
    front: Option<Arc<RgbImage>>,
    side: Option<Arc<RgbImage>>,
}

/// What the monitor decided for a pair.
#[derive(Debug, Clone, PartialEq)]
pub enum Screened {
    /// Use the pair; `notes` say what happened before it (frames back after a gap).
    Pass { notes: Vec<String>, relearn: bool },
    /// Skip the pair and say why.
    Skip(String),
}

/// The per-session state of the fault checks (module docs).
#[derive(Debug, Default)]
pub struct FaultMonitor {
    /// Index and time of the last pair in order.
    last: Option<(u64, f64)>,
    /// Per view, the summed sampled luma of the learnt backdrop frames and their count.
    reference: [Vec<f32>; 2],
    reference_frames: u32,
    /// When the current exposure fault started (source time).
    exposure_off_since: Option<f64>,
    /// The fault that skipped the last pairs, said again when good frames come back.
    faulted: Option<String>,
    /// The last good snapshot's phase and frames, shown while pairs are skipped.
    last_good: Option<LastGood>,
    /// Scratch: sampled luma of the current frame.
    luma: Vec<f32>,
}

impl FaultMonitor {
    /// Decides about one pair; `learning` is true while the backdrop is being learnt.
    pub fn screen(
        &mut self,
        pair: &FramePair,
        calib: &StationCalibration,
        learning: bool,
    ) -> Screened {
        if let Some(e) = wrong_size(pair, calib) {
            return self.skip(e);
        }
        if let Some(e) = self.out_of_order(pair) {
            return self.skip(e);
        }
        let gap = self.last.and_then(|last| missing_time(last, pair));
        self.last = Some((pair.index, pair.timestamp_s));
        if let Some(e) = corrupt(pair) {
            return self.skip(e);
        }
        let mut notes = Vec::new();
        if let Some(gap_s) = gap {
            notes.push(format!(
                "No frames for {gap_s:.1} s (stalled source or lost camera): measuring again"
            ));
        }
        let mut relearn = false;
        if learning {
            self.learn_reference(pair);
        } else {
            match self.exposure_check(pair) {
                ExposureCheck::Fine => {}
                ExposureCheck::Jump(e) => return self.skip(e),
                ExposureCheck::SceneChanged(e) => {
                    notes.push(e);
                    relearn = true;
                }
            }
        }
        if let Some(f) = self.faulted.take() {
            notes.push(format!("Good frames again after: {f}"));
        }
        Screened::Pass { notes, relearn }
    }

    /// Records a skipped pair's reason and returns the verdict.
    fn skip(&mut self, reason: String) -> Screened {
        self.faulted = Some(reason.clone());
        Screened::Skip(reason)
    }

    /// A pair older than the last one in order, or the same one again.
    fn out_of_order(&self, pair: &FramePair) -> Option<String> {
        let (index, t) = self.last?;
        if pair.index == index {
            return Some(format!(
                "Frame pair {} came twice: the copy is skipped",
                pair.index
            ));
        }
        if pair.index < index || pair.timestamp_s < t {
            return Some(format!(
                "Frame pair {} came out of order (after pair {index}): skipped",
                pair.index
            ));
        }
        None
    }

    /// Adds a backdrop frame pair to the exposure reference.
    fn learn_reference(&mut self, pair: &FramePair) {
        for (k, frame) in [&pair.front, &pair.side].into_iter().enumerate() {
            if !has_frame(frame) {
                continue; // a camera that gave nothing (a front-only pair)
            }
            sample_luma(frame, &mut self.luma);
            let r = &mut self.reference[k];
            if r.len() != self.luma.len() || self.reference_frames == 0 {
                r.clear();
                r.resize(self.luma.len(), 0.0);
            }
            for (a, b) in r.iter_mut().zip(&self.luma) {
                *a += *b;
            }
        }
        self.reference_frames += 1;
    }

    /// Compares both frames' exposure with the backdrop's.
    fn exposure_check(&mut self, pair: &FramePair) -> ExposureCheck {
        if self.reference_frames == 0 {
            return ExposureCheck::Fine;
        }
        let mut worst: Option<(View, f64)> = None;
        for (k, (view, frame)) in [(View::Front, &pair.front), (View::Side, &pair.side)]
            .into_iter()
            .enumerate()
        {
            if !has_frame(frame) {
                continue;
            }
            sample_luma(frame, &mut self.luma);
            let Some(ratio) =
                exposure_ratio(&self.luma, &self.reference[k], self.reference_frames as f32)
            else {
                continue;
            };
            if worst.is_none_or(|(_, w)| ratio.ln().abs() > w.ln().abs()) {
                worst = Some((view, ratio));
            }
        }
        let Some((view, ratio)) = worst.filter(|(_, r)| !within_exposure(*r)) else {
            self.exposure_off_since = None;
            return ExposureCheck::Fine;
        };
        let since = *self.exposure_off_since.get_or_insert(pair.timestamp_s);
        let lasted = pair.timestamp_s - since;
        if lasted >= EXPOSURE_RELEARN_S {
            self.exposure_off_since = None;
            self.reference_frames = 0;
            return ExposureCheck::SceneChanged(format!(
                "The scene changed ({} camera exposure x{ratio:.2} for {lasted:.1} s): \
                 learning the backdrop again, keep the area in front of the cameras empty",
                view.name()
            ));
        }
        ExposureCheck::Jump(format!(
            "Sudden exposure change on the {} camera (x{ratio:.1} against the backdrop): \
             frame skipped, last measurements kept",
            view.name()
        ))
    }

    /// Remembers the phase and frames of a snapshot made from a good pair.
    pub fn remember(&mut self, s: &FitSnapshot) {
        self.last_good = Some(LastGood {
            phase: s.phase,
            front: s.front_frame.clone(),
            side: s.side_frame.clone(),
        });
    }
}

/// The outcome of the exposure check.
enum ExposureCheck {
    Fine,
    /// A sudden change: skip the frame.
    Jump(String),
    /// The change lasted: the scene is another one.
    SceneChanged(String),
}

/// True when an exposure ratio is within what the backdrop model absorbs.
fn within_exposure(ratio: f64) -> bool {
    (1.0 / EXPOSURE_JUMP..=EXPOSURE_JUMP).contains(&ratio)
}

/// The time without frames before `pair` (s) when the source left a hole after the
/// pair `(index, t_s)`: more than [`MAX_GAP_S`] per pair numbered in between (pairs
/// numbered in between were given, and dropped downstream when the station was busy).
fn missing_time((index, t_s): (u64, f64), pair: &FramePair) -> Option<f64> {
    let gap_s = pair.timestamp_s - t_s;
    let pairs = pair.index.saturating_sub(index).max(1) as f64;
    (gap_s / pairs > MAX_GAP_S).then_some(gap_s)
}

/// A frame whose size is not its camera's.
fn wrong_size(pair: &FramePair, calib: &StationCalibration) -> Option<String> {
    for (view, f) in [(View::Front, &pair.front), (View::Side, &pair.side)] {
        if view == View::Side && !has_frame(f) {
            continue; // the side camera gave nothing: a front-only pair
        }
        if let Err(e) = calib.check_frame_size(view, f.width(), f.height()) {
            return Some(format!(
                "Corrupt {} frame ({e}): skipped, last measurements kept",
                view.name()
            ));
        }
    }
    None
}

/// A frame made of random bytes.
fn corrupt(pair: &FramePair) -> Option<String> {
    for (view, f) in [(View::Front, &pair.front), (View::Side, &pair.side)] {
        let step = mean_neighbour_step(f);
        if step > NOISE_STEP {
            return Some(format!(
                "Corrupt {} frame (random bytes, mean pixel step {step:.0}): skipped, last \
                 measurements kept",
                view.name()
            ));
        }
    }
    None
}

/// Rec. 601 luma of an RGB pixel.
fn luma(p: &image::Rgb<u8>) -> f32 {
    0.299 * p[0] as f32 + 0.587 * p[1] as f32 + 0.114 * p[2] as f32
}

/// Mean absolute luma difference between horizontal neighbours, every
/// [`SAMPLE_STEP`]-th row.
fn mean_neighbour_step(f: &RgbImage) -> f64 {
    let (mut sum, mut n) = (0.0f64, 0u64);
    for y in (SAMPLE_STEP / 2..f.height()).step_by(SAMPLE_STEP as usize) {
        let mut prev: Option<f32> = None;
        for x in 0..f.width() {
            let l = luma(f.get_pixel(x, y));
            if let Some(p) = prev {
                sum += (l - p).abs() as f64;
                n += 1;
            }
            prev = Some(l);
        }
    }
    if n == 0 {
        0.0
    } else {
        sum / n as f64
    }
}

/// Luma on a grid of every [`SAMPLE_STEP`]-th pixel of the frame's top and side
/// bands (a [`BAND_FRACTION`] of the height and of the width: where the backdrop shows
/// beside a subject on the mark), row by row, into `out`.
fn sample_luma(f: &RgbImage, out: &mut Vec<f32>) {
    out.clear();
    let (w, h) = (f.width(), f.height());
    let (band_x, band_y) = (w / BAND_FRACTION, h / BAND_FRACTION);
    for y in (SAMPLE_STEP / 2..h).step_by(SAMPLE_STEP as usize) {
        for x in (SAMPLE_STEP / 2..w).step_by(SAMPLE_STEP as usize) {
            if y < band_y || x < band_x || x >= w - band_x {
                out.push(luma(f.get_pixel(x, y)));
            }
        }
    }
}

/// Median of frame / backdrop luma over the samples where the backdrop is bright
/// enough (robust to a person covering less than half of the frame). `reference` holds
/// sums over `frames` backdrop frames. None without enough samples.
fn exposure_ratio(samples: &[f32], reference: &[f32], frames: f32) -> Option<f64> {
    if samples.len() != reference.len() || frames <= 0.0 {
        return None;
    }
    let mut ratios: Vec<f32> = samples
        .iter()
        .zip(reference)
        .map(|(s, r)| (*s, r / frames))
        .filter(|(_, r)| *r >= MIN_REFERENCE_LUMA)
        .map(|(s, r)| s.max(1.0) / r)
        .collect();
    if ratios.len() < 16 {
        return None;
    }
    let mid = ratios.len() / 2;
    let (_, m, _) = ratios.select_nth_unstable_by(mid, f32::total_cmp);
    Some(*m as f64)
}

impl StationProcessor {
    /// Screens a pair for source faults: `Ok(notes)` to process it (notes to add to its
    /// snapshot), or `Err(snapshot)` with the last good result and the fault.
    pub(super) fn screen_faults(
        &mut self,
        pair: &FramePair,
    ) -> Result<Vec<String>, Box<FitSnapshot>> {
        let learning = self.learned < self.opts.backdrop_frames;
        match self.faults.screen(pair, &self.calib, learning) {
            Screened::Pass { notes, relearn } => {
                if relearn {
                    self.relearn_backdrop();
                }
                Ok(notes)
            }
            Screened::Skip(reason) => Err(Box::new(self.fault_snapshot(pair, reason))),
        }
    }

    /// Forgets the learnt backdrop: the next frames are learnt as the empty scene.
    fn relearn_backdrop(&mut self) {
        self.learned = 0;
        self.silhouettes = SilhouetteExecutor::new(&self.calib, self.silhouettes.opts);
    }

    /// The last good result (measurements, avatar, frames, phase) with the fault said.
    fn fault_snapshot(&self, pair: &FramePair, reason: String) -> FitSnapshot {
        let (phase, front, side) = match &self.faults.last_good {
            Some(g) => (g.phase, g.front.clone(), g.side.clone()),
            None => (Phase::LearningBackdrop, None, None),
        };
        let mut s = self.snapshot(pair.index, phase, None);
        s.messages.push(reason.clone());
        s.faults.push(reason);
        s.front_frame = front;
        s.side_frame = side;
        s
    }

    /// Adds the screen's notes to a processed pair's snapshot and remembers it as good.
    pub(super) fn after_screened(&mut self, s: &mut FitSnapshot, notes: Vec<String>) {
        if s.phase == Phase::LearningBackdrop && s.measurements.is_empty() {
            // Learning the backdrop again (a changed scene) keeps the last result.
            s.measurements = self.measurements();
            s.avatar = self.last_avatar.clone();
        }
        self.faults.remember(s);
        for n in notes.into_iter().rev() {
            s.messages.insert(0, n.clone());
            s.faults.insert(0, n);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pair(index: u64, t: f64, level: u8) -> FramePair {
        let img = RgbImage::from_fn(320, 240, |x, _| {
            image::Rgb([level, level, (x / 8) as u8 + level / 2])
        });
        FramePair {
            index,
            timestamp_s: t,
            front: img.clone().into(),
            side: img.into(),
        }
    }

    fn calib() -> StationCalibration {
        StationCalibration::nominal(320, 240, 300.0, 3.0, 1.2, 1.0)
    }

    fn is_pass(s: &Screened) -> bool {
        matches!(s, Screened::Pass { .. })
    }

    #[test]
    fn order_duplicates_and_gaps() {
        let c = calib();
        let mut m = FaultMonitor::default();
        assert!(is_pass(&m.screen(&pair(0, 0.0, 100), &c, true)));
        assert!(is_pass(&m.screen(&pair(1, 0.1, 100), &c, false)));
        assert!(
            matches!(m.screen(&pair(1, 0.1, 100), &c, false), Screened::Skip(e) if e.contains("twice"))
        );
        assert!(
            matches!(m.screen(&pair(0, 0.0, 100), &c, false), Screened::Skip(e) if e.contains("out of order"))
        );
        match m.screen(&pair(2, 2.0, 100), &c, false) {
            Screened::Pass { notes, relearn } => {
                assert!(!relearn);
                assert!(notes[0].contains("No frames for 1.9 s"), "{notes:?}");
                assert!(notes[1].contains("Good frames again"), "{notes:?}");
            }
            s => panic!("{s:?}"),
        }
    }

    #[test]
    fn corrupt_and_wrongly_sized_frames_are_skipped() {
        let c = calib();
        let mut m = FaultMonitor::default();
        let mut p = pair(0, 0.0, 100);
        let mut rng = crate::synth::rng::SplitMix64::new(1);
        p.side = RgbImage::from_fn(320, 240, |_, _| {
            let r = rng.next_u64().to_le_bytes();
            image::Rgb([r[0], r[1], r[2]])
        })
        .into();
        assert!(matches!(m.screen(&p, &c, true), Screened::Skip(e) if e.contains("random bytes")));
        let mut p = pair(1, 0.1, 100);
        p.front = RgbImage::new(160, 120).into();
        assert!(matches!(m.screen(&p, &c, true), Screened::Skip(e) if e.contains("Corrupt front")));
    }

    #[test]
    fn a_short_exposure_jump_is_skipped_and_a_lasting_one_relearns() {
        let c = calib();
        let mut m = FaultMonitor::default();
        assert!(is_pass(&m.screen(&pair(0, 0.0, 100), &c, true)));
        assert!(
            is_pass(&m.screen(&pair(1, 0.1, 110), &c, false)),
            "within the drift"
        );
        assert!(
            matches!(m.screen(&pair(2, 0.2, 180), &c, false), Screened::Skip(e) if e.contains("exposure"))
        );
        assert!(is_pass(&m.screen(&pair(3, 0.3, 100), &c, false)));
        for k in 4..14 {
            let s = m.screen(&pair(k, k as f64 * 0.1, 50), &c, false);
            assert!(matches!(s, Screened::Skip(_)), "{k}: {s:?}");
        }
        match m.screen(&pair(14, 1.5, 50), &c, false) {
            Screened::Pass { relearn, notes } => {
                assert!(relearn);
                assert!(notes[0].contains("The scene changed"), "{notes:?}");
            }
            s => panic!("{s:?}"),
        }
    }
}
