//! The station: wires silhouettes, the fit and measurements into the pipeline's
//! [`FrameProcessor`], and runs `fitstation replay` and `fitstation fit`.
//!
//! Per frame pair: learn the backdrop (first frames of a session), segment both views,
//! find contours, landmarks and verdicts, fit or refit the avatar, measure it, smooth the
//! measurements over frames. A frame with a bad verdict is skipped and said (the last fit
//! is kept); nothing already fitted is lost.
//!
//! Units: metres in the station frame, millimetres for measurements, pixels for overlays.

pub mod faults;
pub mod motion;
pub mod output;
pub mod person_masks;
pub mod pose_change;
pub mod side_limbs;
pub mod uncertainty;

use crate::body::ShapeLibrary;
use crate::camera::{StationCalibration, View};
use crate::fit::correspond::MaskRef;
use crate::fit::sections::{SideOccluder, MAX_SIDE_OCCLUDERS};
use crate::fit::{FitOptions, FitStats, Fitter, Observation};
use crate::imgproc::Mask;
use crate::landmarks::graze::TemplateProfiles;
use crate::landmarks::{LandmarkName, Verdict};
use crate::measure::Measurements;
use crate::mesh::TriMesh;
use crate::pipeline::smooth::{SmoothedPoints, SmoothedValue};
use crate::pipeline::timing::FrameTimer;
use crate::pipeline::{
    FitSnapshot, FramePair, FrameProcessor, MeasurementValue, Phase, ViewOverlay,
};
use crate::silhouette::{SilhouetteExecutor, SilhouetteOptions, SilhouetteResult, ViewAnalysis};
use glam::{DVec2, DVec3};
use std::sync::Arc;

/// Timing stage of the learned person network on both views (run on some pairs only).
pub const PERSON_MASK_STAGE: &str = "person_mask";
/// Timing stage of the segmentation the network's map is fused into, on those pairs.
pub const FUSED_SEGMENTATION_STAGE: &str = "silhouettes_fused";
/// Timing stage of the side view's arms from the pose network, on the pairs it runs.
pub const SIDE_LIMBS_STAGE: &str = "side_limbs";
/// Timing stage of the source fault checks that open every pair (`faults`).
pub const FAULT_SCREEN_STAGE: &str = "fault_screen";
/// Timing stage closing every processed pair: the snapshot's overlays for the screen
/// (the avatar's outline in both views), the frames handed to it, the last good result.
pub const SCREEN_STAGE: &str = "screen";
/// The stages that run only because of the person network.
pub const NETWORK_STAGES: [&str; 3] = [
    PERSON_MASK_STAGE,
    FUSED_SEGMENTATION_STAGE,
    SIDE_LIMBS_STAGE,
];

/// Measurement report keys in display order (`report.json` `measurements_mm`).
pub const MEASUREMENT_KEYS: [&str; 6] = [
    "stature",
    "chest_girth",
    "waist_girth",
    "hip_girth",
    "thigh_girth_left",
    "thigh_girth_right",
];

/// The views the station fits from (`--views`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, clap::ValueEnum, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum ViewSet {
    /// Both cameras (a pair without a side frame is still fitted from the front alone).
    #[default]
    Both,
    /// The front camera alone: the side frames are not looked at (the evaluation of
    /// one-camera fitting, a front photo with a typed stature).
    Front,
}

impl ViewSet {
    /// The names of the views, as `report.json` `views` lists them.
    pub fn names(self) -> &'static [&'static str] {
        match self {
            ViewSet::Both => &["front", "side"],
            ViewSet::Front => &["front"],
        }
    }
}

/// Said on screen and in the report while the station fits from the front view alone.
pub const ONE_VIEW_MESSAGE: &str = "No side view: measuring from the front camera alone \
     (depths from the shape library, wider ±)";

/// Options of the station processor.
#[derive(Debug, Clone)]
pub struct StationOptions {
    /// Frames of empty scene learned as the backdrop at the start of a session.
    pub backdrop_frames: usize,
    /// Operator-entered stature (metres); otherwise it comes from the silhouettes.
    pub stature_m: Option<f64>,
    pub fit: FitOptions,
    pub silhouette: SilhouetteOptions,
    /// Stability (mm, spread of the recent window) under which a girth counts as settled.
    pub settled_mm: f64,
    /// Run the learned pose model on the side view to tell the arms from the trunk
    /// ([`side_limbs`]), and the learned person mask where the backdrop model is unsure
    /// ([`person_masks`]); off, the fit tells the arms apart by shape alone and the
    /// backdrop model segments alone.
    pub person_model: bool,
    /// Write each processed frame pair's masks as `DIR/{front,side}/NNNNNN.png` (the
    /// evaluation's mask IoU); not timed.
    pub masks_out: Option<std::path::PathBuf>,
    /// Diagnostics (`eval --truth-masks`): take each frame pair's silhouettes from
    /// `DIR/{front,side}/NNNNNN.png` (a synthetic recording's true masks) instead of the
    /// segmentation; a pair without them is segmented as usual.
    pub truth_masks: Option<std::path::PathBuf>,
    /// The views to fit from; with [`ViewSet::Both`] a pair without a side frame (the
    /// side camera lost) is fitted from the front view alone.
    pub views: ViewSet,
}

impl Default for StationOptions {
    fn default() -> Self {
        StationOptions {
            backdrop_frames: 10,
            stature_m: None,
            fit: FitOptions::default(),
            silhouette: SilhouetteOptions::default(),
            settled_mm: 2.0,
            person_model: true,
            masks_out: None,
            truth_masks: None,
            views: ViewSet::Both,
        }
    }
}

/// Counters over a run, for `report.json` `frames`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize)]
pub struct FrameCounts {
    pub total: usize,
    pub with_subject: usize,
    pub fitted: usize,
    /// Of the fitted pairs, those fitted from the front view alone (no side frame, or
    /// `--views front`).
    pub fitted_front_only: usize,
}

/// The station's frame processor.
pub struct StationProcessor {
    calib: StationCalibration,
    opts: StationOptions,
    silhouettes: SilhouetteExecutor,
    fitter: Fitter,
    learned: usize,
    smoothed: Vec<SmoothedValue>,
    /// The previous frame's person masks: a moving outline is not measured.
    motion: motion::MotionGate,
    /// Per measurement, the per-frame standard deviations from what the views showed
    /// ([`uncertainty::frame_sigma_mm`]), over the same window as the values.
    sigmas: Vec<SmoothedValue>,
    pub counts: FrameCounts,
    last_avatar: Option<Arc<TriMesh>>,
    pub last_measurements: Option<Measurements>,
    pub last_fit: Option<FitStats>,
    /// The silhouettes' landmarks of the fitted frames (see [`Self::landmarks`]).
    landmark_windows: SmoothedPoints,
    /// The pose the library body was chosen on, against the held pose.
    pose: pose_change::PoseTracker,
    /// Reused silhouette buffers (masks, contours) of the per-frame path.
    silhouette_result: SilhouetteResult,
    /// The side view's arms and hands from the person model, for the fit.
    side_limbs: side_limbs::SideLimbs,
    /// Source faults (stall, order, corrupt frames, exposure) found before the stages.
    faults: faults::FaultMonitor,
    /// The learned person mask the segmentation falls back on where unsure.
    person_masks: person_masks::PersonMasks,
    /// Messages of the person mask said once per run.
    said_person_masks: bool,
    /// The views the last fitted pair was fitted from.
    last_views: Option<ViewSet>,
    /// The side camera's pixel at the mark, metres (what the side view can tell apart).
    side_pixel_m: f64,
    /// The empty image that stands for a side frame not looked at.
    no_frame: image::RgbImage,
}

/// The side camera's pixel footprint at the mark (its distance over its focal length),
/// metres; 0 for a degenerate calibration.
fn side_pixel_at_mark_m(calib: &StationCalibration) -> f64 {
    let cam = &calib.side;
    let d = cam.center_in_station().length();
    let f = cam.intrinsics.fx.max(cam.intrinsics.fy);
    if d.is_finite() && f > 0.0 {
        d / f
    } else {
        0.0
    }
}

impl StationProcessor {
    pub fn new(
        calib: StationCalibration,
        library: Arc<ShapeLibrary>,
        mut opts: StationOptions,
    ) -> Result<Self, crate::fit::FitError> {
        if opts.silhouette.template_profiles.is_none() {
            opts.silhouette.template_profiles =
                Some(TemplateProfiles::of_template(library.template()));
        }
        let fitter = Fitter::new(library, opts.fit.clone())?;
        let side_pixel_m = side_pixel_at_mark_m(&calib);
        Ok(StationProcessor {
            silhouettes: SilhouetteExecutor::new(&calib, opts.silhouette),
            calib,
            side_pixel_m,
            fitter,
            learned: 0,
            smoothed: vec![SmoothedValue::default(); MEASUREMENT_KEYS.len()],
            motion: motion::MotionGate::default(),
            sigmas: vec![SmoothedValue::default(); MEASUREMENT_KEYS.len()],
            counts: FrameCounts::default(),
            last_avatar: None,
            last_measurements: None,
            last_fit: None,
            landmark_windows: SmoothedPoints::default(),
            pose: Default::default(),
            silhouette_result: SilhouetteResult::empty(),
            side_limbs: if opts.person_model {
                side_limbs::SideLimbs::load()
            } else {
                side_limbs::SideLimbs::off()
            },
            faults: faults::FaultMonitor::default(),
            person_masks: if opts.person_model {
                person_masks::PersonMasks::load()
            } else {
                person_masks::PersonMasks::off()
            },
            said_person_masks: false,
            last_views: None,
            no_frame: image::RgbImage::new(0, 0),
            opts,
        })
    }

    /// The silhouettes' landmarks of the subject, smoothed over the fitted frames like
    /// the girths ([`SmoothedPoints`]): computed when asked (the report), not per frame.
    pub fn landmarks(&self) -> Vec<(String, DVec3)> {
        self.landmark_windows.values()
    }

    /// The smoothed measurements (key, value mm, stability mm).
    pub fn measurements(&self) -> Vec<MeasurementValue> {
        MEASUREMENT_KEYS
            .iter()
            .zip(self.smoothed.iter().zip(&self.sigmas))
            .filter_map(|(k, (s, sigma))| {
                let pm = sigma.value().map_or(f64::INFINITY, |f| {
                    uncertainty::reported_pm_mm(f, s.std_dev())
                });
                Some(MeasurementValue {
                    name: k.to_string(),
                    value_mm: s.value()?,
                    stability_mm: s.stability(),
                    uncertainty_mm: pm,
                    uncertain: uncertainty::tolerance_mm(k).is_none_or(|t| !(pm <= t)),
                })
            })
            .collect()
    }

    /// The station's options.
    pub fn options(&self) -> &StationOptions {
        &self.opts
    }

    /// The views the reported values were last fitted from (None before a fit).
    pub fn views(&self) -> Option<ViewSet> {
        self.last_views
    }

    /// Largest frame-to-frame change of each girth over the recent window (mm).
    pub fn max_steps(&self) -> Vec<(String, f64)> {
        MEASUREMENT_KEYS
            .iter()
            .zip(&self.smoothed)
            .map(|(k, s)| (k.to_string(), s.max_step()))
            .collect()
    }

    pub fn avatar(&self) -> Option<Arc<TriMesh>> {
        self.last_avatar.clone()
    }

    fn is_settled(&self) -> bool {
        self.smoothed
            .iter()
            .all(|s| s.len() >= 3 && s.stability() <= self.opts.settled_mm)
    }

    fn process_inner(&mut self, pair: &FramePair, timer: &mut FrameTimer) -> FitSnapshot {
        self.counts.total += 1;
        let no_frame = std::mem::take(&mut self.no_frame);
        let s = self.process_views(pair, timer, &no_frame);
        self.no_frame = no_frame;
        s
    }

    /// [`Self::process_inner`] with the side frame the station looks at: the pair's, or
    /// `no_frame` (empty) when it has none or the station fits from the front alone.
    fn process_views(
        &mut self,
        pair: &FramePair,
        timer: &mut FrameTimer,
        no_frame: &image::RgbImage,
    ) -> FitSnapshot {
        let side_frame: &image::RgbImage = if self.opts.views == ViewSet::Both && pair.has_side() {
            &pair.side
        } else {
            no_frame
        };
        for (view, img) in [
            (crate::camera::View::Front, &*pair.front),
            (crate::camera::View::Side, side_frame),
        ] {
            if view == crate::camera::View::Side && !crate::pipeline::has_frame(img) {
                continue;
            }
            if let Err(e) = self.calib.check_frame_size(view, img.width(), img.height()) {
                let mut s = FitSnapshot::empty(pair.index, Phase::LearningBackdrop);
                s.messages.push(e.to_string());
                return s;
            }
        }
        if self.learned < self.opts.backdrop_frames {
            let mut s = FitSnapshot::empty(pair.index, Phase::LearningBackdrop);
            match self.silhouettes.learn_background(&pair.front, side_frame) {
                Ok(()) => self.learned += 1,
                Err(e) => s.messages.push(format!("backdrop frame skipped: {e}")),
            }
            timer.lap("learn_backdrop");
            s.messages.insert(
                0,
                format!(
                    "Learning the empty scene ({}/{})",
                    self.learned, self.opts.backdrop_frames
                ),
            );
            return s;
        }
        if let Some(dir) = &self.opts.truth_masks {
            let [front, side] = crate::camera::View::BOTH.map(|v| read_mask(dir, v, pair.index));
            self.silhouettes.give_masks(front, side);
        }
        // The silhouette result is reused frame after frame (its masks and contours keep
        // their buffers): taken out of `self` for the frame, put back after.
        let mut result = std::mem::replace(&mut self.silhouette_result, SilhouetteResult::empty());
        if let Err(e) = self
            .silhouettes
            .process_into(&pair.front, side_frame, &mut result)
        {
            self.silhouette_result = result;
            let mut s = self.snapshot(pair.index, Phase::Guiding, None);
            s.messages.push(format!("frame skipped: {e}"));
            return s;
        }
        timer.lap("silhouettes");
        let mut notes = Vec::new();
        if let Err(e) = self.fuse_person_mask(&pair.front, side_frame, timer, &mut result) {
            notes.push(e);
        }
        if !self.said_person_masks {
            self.said_person_masks = true;
            notes.extend(self.person_masks.unavailable.take());
        }
        // A side view that lost part of the person to the backdrop (a trunk shallower
        // than any adult's) would fit a body without hips: that frame is measured from
        // the front view alone, as without a side camera (the front's segmentation
        // kept), and said.
        let side_lost = Verdict::BlendsIntoBackdrop { view: View::Side };
        let side_frame = if result.landmarks.verdicts.contains(&side_lost) {
            self.silhouettes.leave_side_out(&mut result);
            notes.push(side_lost.message());
            no_frame
        } else {
            side_frame
        };
        // Not measured while the outline moves (someone walking behind, the shopper
        // moving): see `motion`.
        let before = result.landmarks.verdicts.len();
        self.motion.observe(
            [&result.masks.front, &result.masks.side],
            &mut result.landmarks.verdicts,
        );
        if result.landmarks.verdicts.len() > before && self.person_masks.just_ran() {
            // The network's map of a moving picture may hold the passer-by: not kept.
            self.person_masks.retry_soon();
        }
        let mut s = self.fit_and_measure(pair, side_frame, timer, &result);
        s.messages.extend(notes);
        self.silhouette_result = result;
        s
    }

    /// Runs the learned person mask when due and segments the frame again with it (the
    /// network and the second segmentation timed as `person_mask` and
    /// `silhouettes_fused`); otherwise counts the frame.
    ///
    /// # Errors
    /// A message when the network or the second segmentation fails (the frame keeps its
    /// first silhouettes).
    fn fuse_person_mask(
        &mut self,
        front: &image::RgbImage,
        side: &image::RgbImage,
        timer: &mut FrameTimer,
        result: &mut SilhouetteResult,
    ) -> Result<(), String> {
        if !self
            .person_masks
            .due(result, &self.silhouettes, &self.calib)
        {
            self.person_masks.tick();
            return Ok(());
        }
        let ran = self
            .person_masks
            .run(front, side, &self.calib, &mut self.silhouettes);
        timer.lap(PERSON_MASK_STAGE);
        let mut fused = SilhouetteResult::empty();
        std::mem::swap(&mut fused, result);
        let again = self.silhouettes.process_into(front, side, &mut fused);
        timer.lap(FUSED_SEGMENTATION_STAGE);
        match again {
            Ok(()) => *result = fused,
            Err(e) => {
                // `fused` may be half written: segment the frame as it was.
                let _ = self
                    .silhouettes
                    .set_person_prior(crate::camera::View::Front, None);
                let _ = self
                    .silhouettes
                    .set_person_prior(crate::camera::View::Side, None);
                self.silhouettes
                    .process_into(front, side, &mut fused)
                    .map_err(|e| format!("frame segmented again without the person mask: {e}"))?;
                *result = fused;
                return Err(format!("person mask not used on this frame: {e}"));
            }
        }
        ran
    }

    /// Writes the frame pair's final masks under `dir` (`front/`, `side/`, `NNNNNN.png`).
    fn write_masks(&self, dir: &std::path::Path, index: u64) -> Result<(), String> {
        let masks = &self.silhouette_result.masks;
        for (view, m) in [("front", &masks.front), ("side", &masks.side)] {
            if m.data.is_empty() {
                continue;
            }
            let d = dir.join(view);
            std::fs::create_dir_all(&d).map_err(|e| format!("{}: {e}", d.display()))?;
            let img = image::GrayImage::from_raw(m.width, m.height, m.data.clone())
                .ok_or_else(|| format!("{view} mask has the wrong size"))?;
            let p = d.join(format!("{index:06}.png"));
            img.save(&p).map_err(|e| format!("{}: {e}", p.display()))?;
        }
        Ok(())
    }

    /// The part of a frame after the silhouettes: verdicts, fit, measurements.
    fn fit_and_measure(
        &mut self,
        pair: &FramePair,
        side_frame: &image::RgbImage,
        timer: &mut FrameTimer,
        result: &SilhouetteResult,
    ) -> FitSnapshot {
        let side_seen = crate::pipeline::has_frame(side_frame);
        if let Some(s) = self.refusal(pair, result) {
            return s;
        }
        let Some(mut obs) = observation(result, self.opts.stature_m) else {
            let mut s = self.snapshot(pair.index, Phase::Guiding, Some(result));
            s.messages
                .push("The landmarks could not be found in this frame.".into());
            return s;
        };
        let masks = &result.masks;
        let fit_mask = |view| {
            let (m, soft) = masks.fit_mask(view);
            MaskRef {
                width: m.width,
                height: m.height,
                data: if soft.len() == m.data.len() {
                    soft
                } else {
                    &m.data
                },
            }
        };
        let front = fit_mask(View::Front);
        let side = side_seen.then(|| fit_mask(View::Side));
        let mut notes = Vec::new();
        let first = self.follow_pose(result, &mut notes);
        if side_seen {
            obs.side_occluders = self.side_arms(side_frame, result, timer, &mut notes);
        } else if !(self.opts.views == ViewSet::Both && pair.has_side()) {
            // (A side frame that lost the body is said as its verdict.)
            notes.push(ONE_VIEW_MESSAGE.to_string());
        }
        let fit = self
            .fitter
            .fit_views(&self.calib, front, side, &obs)
            .map(|(p, st)| (p.to_vec(), st));
        timer.lap(if first { "first_fit" } else { "refit" });
        if first && fit.is_ok() {
            self.pose.chosen_now();
        }
        let (positions, stats) = match fit {
            Ok(x) => x,
            Err(e) => {
                let mut s = self.snapshot(pair.index, Phase::Guiding, Some(result));
                s.messages.push(format!("fit skipped: {e}"));
                return s;
            }
        };
        let triangles = self.fitter.template_triangles().to_vec();
        let avatar = TriMesh::new(positions, triangles);
        let measured = self.measure_avatar(&avatar, side_seen, stats.stature_sd_mm);
        timer.lap("measure");
        if let Err(e) = measured {
            let mut s = self.snapshot(pair.index, Phase::Guiding, Some(result));
            s.messages.push(format!("measurement skipped: {e}"));
            return s;
        }
        self.last_avatar = Some(Arc::new(avatar));
        self.last_fit = Some(stats);
        self.landmark_windows.push(
            result
                .landmarks
                .points
                .iter()
                .map(|p| (p.name.as_str(), p.station)),
        );
        let phase = if self.is_settled() {
            Phase::Settled
        } else {
            Phase::Fitting
        };
        let mut s = self.snapshot(pair.index, phase, Some(result));
        s.messages.extend(notes);
        s.messages.extend(
            result
                .landmarks
                .verdicts
                .iter()
                .filter(|v| !v.blocks_fit() && !matches!(v, Verdict::NoPerson))
                .map(|v| v.message()),
        );
        s
    }

    /// The snapshot of a pair that is not fitted because of its verdicts (nobody on the
    /// mark, a verdict that blocks the fit), or None when it is to be fitted.
    fn refusal(&mut self, pair: &FramePair, result: &SilhouetteResult) -> Option<FitSnapshot> {
        let verdicts = &result.landmarks.verdicts;
        if verdicts.iter().any(|v| matches!(v, Verdict::NoPerson)) {
            let mut s = self.snapshot(pair.index, Phase::WaitingForSubject, Some(result));
            s.messages.push(Verdict::NoPerson.message());
            return Some(s);
        }
        self.counts.with_subject += 1;
        // While the outline moves, the pose verdicts judge someone else's limbs too: only
        // the wait is said.
        let moving = verdicts.iter().any(|v| matches!(v, Verdict::Moving { .. }));
        let blocking: Vec<String> = verdicts
            .iter()
            .filter(|v| v.blocks_fit() && (!moving || matches!(v, Verdict::Moving { .. })))
            .map(|v| v.message())
            .collect();
        if blocking.is_empty() {
            return None;
        }
        let mut s = self.snapshot(pair.index, Phase::Guiding, Some(result));
        s.messages.extend(blocking);
        Some(s)
    }

    /// Follows the held pose: one that differs from the pose the body was chosen on has
    /// the body chosen again (see `pose_change`) and the shown values settle anew.
    /// Returns whether this frame's fit is a first fit.
    fn follow_pose(&mut self, result: &SilhouetteResult, notes: &mut Vec<String>) -> bool {
        if self.pose.observe(&result.landmarks.points) && self.fitter.has_subject() {
            self.fitter.reset();
            for s in self.smoothed.iter_mut().chain(&mut self.sigmas) {
                s.clear();
            }
            self.landmark_windows.clear();
            self.person_masks.expire();
            notes.push("The pose changed: the body is chosen again on the held pose.".to_string());
        }
        let first = !self.fitter.has_subject();
        if first {
            self.side_limbs.reset();
            notes.extend(self.side_limbs.unavailable.take());
        }
        first
    }

    /// The side view's arms from the person model (run at a low rate, kept between).
    fn side_arms(
        &mut self,
        side_frame: &image::RgbImage,
        result: &SilhouetteResult,
        timer: &mut FrameTimer,
        notes: &mut Vec<String>,
    ) -> [Option<SideOccluder>; MAX_SIDE_OCCLUDERS] {
        // The person mask's network, run on this frame, already found the side view's
        // keypoints.
        if let Some(out) = self.person_masks.side_pose() {
            return self.side_limbs.adopt(out, &self.calib.side, result);
        }
        let network_runs = self.side_limbs.due();
        let arms = match self.side_limbs.update(side_frame, &self.calib.side, result) {
            Ok(o) => o,
            Err(e) => {
                notes.push(e);
                Default::default()
            }
        };
        if network_runs {
            timer.lap(SIDE_LIMBS_STAGE);
        }
        arms
    }

    /// Measures the fitted avatar and adds its values and their frame uncertainties
    /// (one-view ones without the side view; `stature_sd_mm`: the fit's standard
    /// deviation of a stature the front view alone gave) to the smoothed windows.
    fn measure_avatar(
        &mut self,
        avatar: &TriMesh,
        side_seen: bool,
        stature_sd_mm: Option<f64>,
    ) -> Result<(), String> {
        let mut m = crate::measure::measure(avatar).map_err(|e| e.to_string())?;
        // The hip: the avatar's girths about its furthest-back level, each by its chance
        // of being the person's (the side view places the back to a pixel).
        m.hip_girth_mm = uncertainty::hip_girth_over_levels_mm(&m, self.side_pixel_m);
        let map = m.to_report_map();
        // The avatar's own trunk at the torso girths' levels, in one pass over its edges.
        let torso_levels = [m.levels.chest_m, m.levels.waist_m, m.levels.hip_m];
        let trunk = self.fitter.trunk_extents_at(&torso_levels);
        for (k, (s, sigma)) in MEASUREMENT_KEYS
            .iter()
            .zip(self.smoothed.iter_mut().zip(self.sigmas.iter_mut()))
        {
            let Some(v) = map.get(*k).and_then(|v| v.as_f64()) else {
                continue;
            };
            s.push(v);
            let level = uncertainty::level_of(k, &m);
            let evidence = level.and_then(|(region, y)| {
                self.fitter
                    .level_evidence(region, y, uncertainty::LEVEL_HALF_WINDOW_M)
            });
            let mut frame_sigma = match (side_seen, *k == "stature", stature_sd_mm) {
                (false, true, Some(sd)) => uncertainty::STATURE_SIGMA_MM.hypot(sd),
                (true, ..) => uncertainty::frame_sigma_mm(k, v, evidence),
                _ => uncertainty::frame_sigma_one_view_mm(k, v, evidence),
            };
            if *k == "hip_girth" {
                // The level's openness as the avatar's back and as the side view showed it:
                // the larger (the same openness, seen twice, is not added).
                let open = uncertainty::hip_level_sigma_mm(&m, self.side_pixel_m).max(
                    uncertainty::hip_seen_level_sigma_mm(
                        &m,
                        self.fitter.seen_back_edges(),
                        self.side_pixel_m,
                    ),
                );
                frame_sigma = frame_sigma.hypot(open);
            }
            if let Some((crate::fit::sections::Region::Torso, y)) = level {
                let extents = torso_levels
                    .iter()
                    .position(|&t| t == y)
                    .and_then(|i| trunk[i]);
                frame_sigma = frame_sigma.hypot(uncertainty::loop_excess_sigma_mm(v, extents));
            }
            if crate::fit::debug_enabled() {
                eprintln!("evidence {k}: {evidence:?} -> {frame_sigma:.1}");
            }
            sigma.push(frame_sigma);
        }
        self.last_measurements = Some(m);
        self.counts.fitted += 1;
        self.counts.fitted_front_only += !side_seen as usize;
        self.last_views = Some(if side_seen {
            ViewSet::Both
        } else {
            ViewSet::Front
        });
        Ok(())
    }

    fn snapshot(&self, index: u64, phase: Phase, result: Option<&SilhouetteResult>) -> FitSnapshot {
        let mut s = FitSnapshot::empty(index, phase);
        if let Some(r) = result {
            s.front = overlay(&r.front);
            s.side = overlay(&r.side);
            s.landmarks_station = r
                .landmarks
                .points
                .iter()
                .map(|p| (p.name.clone(), p.station))
                .collect();
        }
        // The avatar's outline is the screen's to draw (operator mode only).
        s.front.camera = Some(self.calib.front);
        s.side.camera = Some(self.calib.side);
        s.avatar = self.last_avatar.clone();
        s.measurements = self.measurements();
        s
    }
}

impl FrameProcessor for StationProcessor {
    fn process(&mut self, pair: &FramePair) -> FitSnapshot {
        // Every stage of the pair on this thread is timed, so that `total` is the pair's
        // whole cost here (but for the engineer's `--masks-out` files, written after).
        let mut timer = FrameTimer::start();
        // A faulty pair is said and skipped, keeping the last good result (`faults`).
        let notes = match self.screen_faults(pair) {
            Ok(notes) => notes,
            Err(s) => return *s,
        };
        timer.lap(FAULT_SCREEN_STAGE);
        let mut s = self.process_inner(pair, &mut timer);
        // The screen shows the frames the overlays belong to (kept in memory only).
        s.front_frame = Some(pair.front.clone());
        s.side_frame = Some(pair.side.clone());
        self.after_screened(&mut s, notes);
        // The snapshot's overlays (the avatar's outline in both views), the frames for
        // the screen and the last good result kept for a fault.
        timer.lap(SCREEN_STAGE);
        let total: f64 = timer.stages().iter().map(|(_, ms)| ms).sum();
        let mut stages = timer.into_stages();
        stages.push(("total".into(), total));
        s.timings_ms = stages;
        if self.opts.person_model && s.phase != Phase::LearningBackdrop {
            // Part of `silhouettes` (not added to the total): the pass of both views'
            // segmentation that fuses the person mask in.
            let st = &self.silhouette_result;
            let fuse = st.front.stats.phase_ms.fuse + st.side.stats.phase_ms.fuse;
            s.timings_ms
                .push(("silhouettes_fuse_part".into(), fuse as f64));
        }
        if let Some(dir) = self.opts.masks_out.clone() {
            if s.phase != Phase::LearningBackdrop {
                if let Err(e) = self.write_masks(&dir, pair.index) {
                    s.messages.push(format!("masks not written: {e}"));
                }
            }
        }
        s
    }

    fn reset_subject(&mut self) {
        self.fitter.reset();
        for s in self.smoothed.iter_mut().chain(&mut self.sigmas) {
            s.clear();
        }
        self.last_avatar = None;
        self.last_measurements = None;
        self.last_fit = None;
        self.last_views = None;
        self.landmark_windows.clear();
        self.pose.clear();
        self.side_limbs.reset();
        self.person_masks.reset(&mut self.silhouettes);
        self.motion.reset();
        // The shopper has left: give the allocator's free pages back to the system, or
        // the heap keeps growing in steps with fragmentation (see crate::io::heap).
        crate::io::heap::release_free_memory();
    }
}

/// What the fitter needs from the landmarks.
fn observation(r: &SilhouetteResult, stature_override: Option<f64>) -> Option<Observation> {
    let lm = &r.landmarks;
    let stature = stature_override.unwrap_or(lm.stature_m);
    if !(stature.is_finite() && stature > 0.5 && stature < 2.6) {
        return None;
    }
    let get = |n: LandmarkName| lm.get(n).map(|p| p.station);
    let hip = get(LandmarkName::Hip)
        .or_else(|| get(LandmarkName::Crotch).map(|c| c + DVec3::new(0.0, 0.05, 0.0)))?;
    let angle = |a: Option<DVec3>, b: Option<DVec3>, side: f64| -> Option<f64> {
        let d = b? - a?;
        Some((d.x * side).atan2(-d.y))
    };
    let arms = angle(
        get(LandmarkName::ShoulderLeft),
        get(LandmarkName::WristLeft),
        1.0,
    )
    .zip(angle(
        get(LandmarkName::ShoulderRight),
        get(LandmarkName::WristRight),
        -1.0,
    ));
    let legs = angle(
        get(LandmarkName::ThighRootLeft),
        get(LandmarkName::AnkleLeft),
        1.0,
    )
    .zip(angle(
        get(LandmarkName::ThighRootRight),
        get(LandmarkName::AnkleRight),
        -1.0,
    ));
    Some(Observation {
        stature_m: stature,
        torso_point: hip,
        arm_angles: arms,
        leg_angles: legs,
        side_occluders: [None; crate::fit::sections::MAX_SIDE_OCCLUDERS],
        // Without the side view the head top is lifted onto z = 0 (see `lifting`).
        stature_plane_z: (stature_override.is_none() && r.side.contour.is_empty()).then_some(0.0),
    })
}

fn overlay(a: &ViewAnalysis) -> ViewOverlay {
    let pts = &a.contour.points;
    ViewOverlay {
        contour: pts.clone(),
        parts: a
            .parts
            .iter()
            .map(|p| {
                (
                    p.name.clone(),
                    p.range
                        .indices(pts.len())
                        .filter_map(|i| pts.get(i).copied())
                        .collect(),
                )
            })
            .collect(),
        landmarks: a
            .landmarks_px
            .iter()
            .map(|(n, p)| (n.as_str().to_string(), *p))
            .collect(),
        bones: bones(a),
        avatar_outline: Vec::new(),
        camera: None,
    }
}

/// Skeleton bones between the joints seen in a view (pixels).
fn bones(a: &ViewAnalysis) -> Vec<(DVec2, DVec2)> {
    use LandmarkName::*;
    const CHAINS: [&[LandmarkName]; 5] = [
        &[Hip, Abdomen, Waist, Chest, Neck, Head, HeadTop],
        &[Neck, ShoulderLeft, ElbowLeft, WristLeft, HandLeft],
        &[Neck, ShoulderRight, ElbowRight, WristRight, HandRight],
        &[Hip, ThighRootLeft, KneeLeft, AnkleLeft],
        &[Hip, ThighRootRight, KneeRight, AnkleRight],
    ];
    let mut out = Vec::new();
    for chain in CHAINS {
        for w in chain.windows(2) {
            if let (Some(p), Some(q)) = (a.landmark(w[0]), a.landmark(w[1])) {
                out.push((p, q));
            }
        }
    }
    out
}

/// The avatar's outline in a camera: projected boundary of its vertices' convex...
/// approximated by the extreme projected vertex of each image row band (left and right
/// sides), enough to show how the fit sits on the silhouette.
/// Loads the default shape library (embedded in the binary).
pub fn default_library() -> anyhow::Result<std::sync::Arc<crate::body::ShapeLibrary>> {
    use anyhow::Context;
    Ok(std::sync::Arc::new(
        crate::body::ShapeLibrary::load_default().context("cannot load the shape library")?,
    ))
}

/// The mask `DIR/<view>/NNNNNN.png` of frame `index` (pixels above half grey are the
/// person), None when it cannot be read.
fn read_mask(dir: &std::path::Path, view: crate::camera::View, index: u64) -> Option<Mask> {
    let p = dir.join(view.name()).join(format!("{index:06}.png"));
    let g = image::open(p).ok()?.to_luma8();
    let mut m = Mask::new(g.width(), g.height());
    for (d, s) in m.data.iter_mut().zip(g.as_raw()) {
        *d = if *s > 127 { crate::imgproc::MASK_ON } else { 0 };
    }
    Some(m)
}
