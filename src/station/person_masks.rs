//! The learned person mask behind the backdrop segmentation (issue 20, item 3): runs a
//! person network on each view's person crop at a low rate and hands its probability to
//! the background models, which use it where they are unsure ([`crate::segment::fusion`]).
//!
//! The network is BlazePose's ([`crate::person::PoseLandmarker`]): its person mask is made
//! for a whole body, and on clothing of the backdrop's colour it kept what the selfie
//! network (made for a face and shoulders near the camera) lost: on session 23's
//! camouflage set the fused masks' IoU went from 0.970 / 0.962 (front / side) to 0.982 /
//! 0.976, and up on the plain sets too (`docs/evaluation.md`, session 24). It also gives
//! the side view's keypoints, which [`super::side_limbs`] takes instead of running the
//! same network again. Without the pose model file the selfie network
//! ([`crate::person::SelfieSegmenter`]) segments; without either the station segments with
//! the backdrop alone and says so once.
//!
//! The network costs about 50 ms a view, so it runs on the first frame that shows someone
//! (then that frame is segmented again with the prior), then every [`EVERY_FRAMES`] frames
//! to follow the subject, and sooner (after [`RETRY_FRAMES`]) when the backdrop's
//! silhouettes are refused (nobody, several people, arms on the trunk, legs together, a
//! blended side). In between, each frame's segmentation uses the kept prior, at the cost
//! of a pass over the prior's cells.
//!
//! The crop is the square around the person's pieces as the backdrop sees them (every
//! large component, not only the largest: a shirt lost in the backdrop splits the head
//! from the legs) inside the projected standing volume over the mark; when the pieces
//! are too short to be a person, the standing volume itself.
//!
//! Units: metres in the station frame, pixels in each camera's distorted image.

use crate::camera::{Camera, StationCalibration, View};
use crate::landmarks::Verdict;
use crate::person::{FrameRef, PersonModel, PersonOutput, PoseLandmarker, Roi, SelfieSegmenter};
use crate::segment::fusion::PersonPrior;
use crate::segment::{standing_volume_box, PixelBox};
use crate::silhouette::{SilhouetteExecutor, SilhouetteResult};
use glam::DVec3;

/// Frames between two runs of the network while the silhouettes are accepted.
pub const EVERY_FRAMES: usize = 8;
/// Frames between two runs while the silhouettes are refused.
pub const RETRY_FRAMES: usize = 3;
/// The crop: the pieces' box, squared and widened by this, for the pose network (a margin
/// round the body, as its own person detector would give) and for the selfie network
/// (which does best on a tight crop, `tests/suite/person_models.rs`).
const POSE_CROP_SCALE: f32 = 1.25;
const SELFIE_CROP_SCALE: f32 = 1.1;
/// A component of at least this many coarse cells is a piece of the person.
const MIN_PIECE_CELLS: u64 = 150;
/// The pieces' box must be at least this fraction of the standing volume's height.
const MIN_PIECES_HEIGHT: f64 = 0.4;
/// Margin below the mark's image in a crop extended to the feet (fraction of the
/// standing volume's image height).
const FEET_MARGIN: f64 = 0.03;
/// Someone is in view when a view's largest component has this many pixels.
const SOMEONE_PX: u64 = 1500;

/// The person network and when it last ran for the current subject.
pub struct PersonMasks {
    model: Option<Box<dyn PersonModel + Send>>,
    /// The crop's widening for the network loaded.
    crop_scale: f32,
    out: PersonOutput,
    /// Whether `out` holds the side view's keypoints of the current frame's run.
    side_pose: bool,
    /// Frames since the network last ran (None: no prior for this subject yet).
    since: Option<usize>,
    /// Why the fusion is off, said once.
    pub unavailable: Option<String>,
}

impl PersonMasks {
    /// Loads the pose network, or the selfie network without it (`person::find_model`);
    /// without either the station segments with the backdrop alone.
    pub fn load() -> PersonMasks {
        let boxed = |m: PoseLandmarker| Box::new(m) as Box<dyn PersonModel + Send>;
        let (model, crop_scale, unavailable) = match PoseLandmarker::load_default() {
            Ok(m) => (Some(boxed(m)), POSE_CROP_SCALE, None),
            Err(pose_error) => match SelfieSegmenter::load_default() {
                Ok(m) => (
                    Some(Box::new(m) as Box<dyn PersonModel + Send>),
                    SELFIE_CROP_SCALE,
                    Some(format!(
                        "the pose model is not available, the person mask comes from the selfie model (it loses more clothing of the backdrop's colour): {pose_error}"
                    )),
                ),
                Err(e) => (
                    None,
                    POSE_CROP_SCALE,
                    Some(format!(
                        "the person segmentation model is not available, clothing in the backdrop's colour may be lost: {pose_error}; {e}"
                    )),
                ),
            },
        };
        PersonMasks {
            model,
            crop_scale,
            out: PersonOutput::new(),
            side_pose: false,
            since: None,
            unavailable,
        }
    }

    /// No network: the backdrop model alone segments.
    pub fn off() -> PersonMasks {
        PersonMasks {
            model: None,
            crop_scale: POSE_CROP_SCALE,
            out: PersonOutput::new(),
            side_pose: false,
            since: None,
            unavailable: None,
        }
    }

    /// Forgets the subject (the next frame showing someone runs the network).
    pub fn reset(&mut self, silhouettes: &mut SilhouetteExecutor) {
        self.since = None;
        for view in View::BOTH {
            // Made at nothing: clearing cannot fail.
            let _ = silhouettes.set_person_prior(view, None);
        }
    }

    /// Whether the network runs on this frame, judged on its backdrop silhouettes: before
    /// the first run, when a view shows someone whole or in pieces (a shirt lost in the
    /// backdrop leaves no person-sized component, only a head and legs).
    pub fn due(
        &self,
        result: &SilhouetteResult,
        silhouettes: &SilhouetteExecutor,
        calib: &StationCalibration,
    ) -> bool {
        self.due_given(result, || someone_in_pieces(result, silhouettes, calib))
    }

    /// [`Self::due`] with the pieces' test given (asked only before the first run when no
    /// view holds a person-sized component).
    fn due_given(&self, result: &SilhouetteResult, in_pieces: impl FnOnce() -> bool) -> bool {
        if self.model.is_none() {
            return false;
        }
        match self.since {
            None => someone_in_view(result) || in_pieces(),
            Some(n) => n + 1 >= EVERY_FRAMES || (n + 1 >= RETRY_FRAMES && refused(result)),
        }
    }

    /// Makes the network run on the next frame (the subject's pose changed: the kept
    /// prior shows the limbs where they were).
    pub fn expire(&mut self) {
        if self.since.is_some() {
            self.since = Some(EVERY_FRAMES);
        }
    }

    /// Whether the network ran on the current frame.
    pub fn just_ran(&self) -> bool {
        self.since == Some(0)
    }

    /// Makes the network run again [`RETRY_FRAMES`] frames from now: its map of this
    /// frame is not to be kept (someone walking behind the shopper was in it).
    pub fn retry_soon(&mut self) {
        if self.since.is_some() {
            self.since = Some(EVERY_FRAMES.saturating_sub(RETRY_FRAMES));
        }
    }

    /// Counts a frame on which the network did not run.
    pub fn tick(&mut self) {
        self.since = self.since.map(|n| n + 1);
        self.side_pose = false;
    }

    /// The side view's output of the network's run on this frame when it gives keypoints
    /// (the pose network), for [`super::side_limbs`].
    pub fn side_pose(&self) -> Option<&PersonOutput> {
        (self.just_ran() && self.side_pose).then_some(&self.out)
    }

    /// Runs the network on both views' person crops and gives the background models its
    /// probability as their prior.
    ///
    /// # Errors
    /// A message when the network fails on a view (that view keeps no prior).
    pub fn run(
        &mut self,
        front: &image::RgbImage,
        side: &image::RgbImage,
        calib: &StationCalibration,
        silhouettes: &mut SilhouetteExecutor,
    ) -> Result<(), String> {
        self.since = Some(0);
        self.side_pose = false;
        let Some(model) = self.model.as_mut() else {
            return Ok(());
        };
        let mut errors = Vec::new();
        for (view, frame) in [(View::Front, front), (View::Side, side)] {
            let (w, h) = (frame.width(), frame.height());
            let volume = standing_volume_box(calib.camera(view), w, h);
            let Some(volume) = volume else {
                let _ = silhouettes.set_person_prior(view, None); // clearing cannot fail
                continue;
            };
            let crop = person_crop(silhouettes, calib.camera(view), view, volume);
            let roi = Roi::square_around(
                crop.min_x as f32,
                crop.min_y as f32,
                crop.max_x as f32,
                crop.max_y as f32,
                self.crop_scale,
            );
            match model.infer(FrameRef::from_image(frame), roi, &mut self.out) {
                Ok(()) => {
                    // The side view runs last: `out` keeps its keypoints.
                    self.side_pose = view == View::Side && !self.out.keypoints.is_empty();
                    let mask = &self.out.mask;
                    let prior = PersonPrior::from_probability(w, h, roi_box(roi, w, h), |x, y| {
                        mask.at(x, y)
                    });
                    if let Err(e) = silhouettes.set_person_prior(view, Some(prior)) {
                        errors.push(format!("{} view person mask: {e}", view.name()));
                    }
                }
                Err(e) => {
                    let _ = silhouettes.set_person_prior(view, None); // clearing cannot fail
                    errors.push(format!("{} view person mask: {e}", view.name()));
                }
            }
        }
        if errors.is_empty() {
            Ok(())
        } else {
            Err(errors.join("; "))
        }
    }
}

/// True when a view's backdrop silhouette holds something person-sized.
fn someone_in_view(result: &SilhouetteResult) -> bool {
    [&result.front, &result.side]
        .iter()
        .any(|a| a.stats.largest_px >= SOMEONE_PX)
}

/// True when a view's backdrop pieces inside the standing volume (components of at least
/// [`MIN_PIECE_CELLS`] cells) span at least [`MIN_PIECES_HEIGHT`] of its height: someone
/// whose clothing matched the backdrop between the head and the legs.
fn someone_in_pieces(
    result: &SilhouetteResult,
    silhouettes: &SilhouetteExecutor,
    calib: &StationCalibration,
) -> bool {
    View::BOTH.iter().any(|&view| {
        let mask = match view {
            View::Front => &result.masks.front,
            View::Side => &result.masks.side,
        };
        let Some(volume) = standing_volume_box(calib.camera(view), mask.width, mask.height) else {
            return false;
        };
        let min_height = MIN_PIECES_HEIGHT * (volume.max_y - volume.min_y) as f64;
        silhouettes
            .model(view)
            .foreground_box(MIN_PIECE_CELLS, volume)
            .is_some_and(|b| (b.max_y - b.min_y) as f64 >= min_height)
    })
}

/// True when the silhouettes were refused for what a lost piece of clothing causes.
fn refused(result: &SilhouetteResult) -> bool {
    result.landmarks.verdicts.iter().any(|v| {
        matches!(
            v,
            Verdict::NoPerson
                | Verdict::MultiplePeople
                | Verdict::ArmsTouchingTorso { .. }
                | Verdict::LegsTogether
                | Verdict::BlendsIntoBackdrop { .. }
        )
    })
}

/// The box fed to the network: the person's pieces inside the standing volume, down to
/// the mark at least (lower legs and feet lost against the floor would otherwise fall
/// out of the crop), or the volume when the pieces are too short to be a person.
fn person_crop(
    silhouettes: &SilhouetteExecutor,
    camera: &Camera,
    view: View,
    volume: PixelBox,
) -> PixelBox {
    let min_height = MIN_PIECES_HEIGHT * (volume.max_y - volume.min_y) as f64;
    // The soles on the mark: pieces that stop short of them are extended to a little
    // below (pieces reaching them are kept as they are).
    let margin = FEET_MARGIN * (volume.max_y - volume.min_y) as f64;
    let mark_y = camera.project(DVec3::ZERO).map(|p| p.y);
    let reach = |b: &PixelBox| match mark_y {
        Some(y) if (b.max_y as f64) < y - 2.0 * margin => (y + margin).max(0.0) as u32,
        _ => b.max_y,
    };
    silhouettes
        .model(view)
        .foreground_box(MIN_PIECE_CELLS, volume)
        .filter(|b| (b.max_y - b.min_y) as f64 >= min_height)
        .map(|b| PixelBox {
            max_y: reach(&b).clamp(b.max_y, volume.max_y.max(b.max_y)),
            ..b
        })
        .unwrap_or(volume)
}

/// The pixels of a network crop inside a `w x h` frame.
fn roi_box(roi: Roi, w: u32, h: u32) -> PixelBox {
    PixelBox {
        min_x: roi.x0.clamp(0.0, w as f32) as u32,
        min_y: roi.y0.clamp(0.0, h as f32) as u32,
        max_x: (roi.x0 + roi.width).ceil().clamp(0.0, w as f32) as u32,
        max_y: (roi.y0 + roi.height).ceil().clamp(0.0, h as f32) as u32,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_standing_volume_holds_the_mark_in_both_views() {
        let calib = StationCalibration::nominal(720, 1280, 1100.0, 3.0, 1.1, 1.0);
        for view in View::BOTH {
            let cam = calib.camera(view);
            let b = standing_volume_box(cam, 720, 1280).expect("in view");
            for y in [0.1, 1.0, 1.8] {
                let p = cam.project(DVec3::new(0.0, y, 0.0)).expect("projects");
                assert!(
                    p.x >= b.min_x as f64
                        && p.x < b.max_x as f64
                        && p.y >= b.min_y as f64
                        && p.y < b.max_y as f64,
                    "{view:?} {y}: {p} outside {b:?}"
                );
            }
        }
    }

    #[test]
    fn the_network_runs_at_first_then_at_a_low_rate() {
        let mut m = PersonMasks::load();
        assert!(m.model.is_some(), "{:?}", m.unavailable);
        let mut r = SilhouetteResult::empty();
        assert!(!m.due_given(&r, || false), "nobody in view");
        assert!(m.due_given(&r, || true), "someone in pieces");
        r.front.stats.largest_px = 50_000;
        assert!(m.due_given(&r, || false));
        m.since = Some(0);
        let mut runs = 0;
        for _ in 0..3 * EVERY_FRAMES {
            if m.due_given(&r, || false) {
                runs += 1;
                m.since = Some(0);
            } else {
                m.tick();
            }
        }
        assert_eq!(runs, 3);
        // Refused silhouettes bring the next run forward.
        r.landmarks.verdicts.push(Verdict::MultiplePeople);
        m.since = Some(RETRY_FRAMES - 1);
        assert!(m.due_given(&r, || false));
        assert!(!PersonMasks::off().due_given(&r, || true));
    }
}
