//! Where the arms and hands are in the side view, from the learned pose model
//! ([`crate::person::PoseLandmarker`]): the fit's side-view limb capsules
//! ([`crate::fit::sections::SideOccluder`]).
//!
//! Two silhouettes cannot tell a forearm or a hand in front of the belly from the belly.
//! The pose network finds the elbows, wrists and hands in the side frame; each arm's
//! upper arm, forearm and hand become capsules in the station's (y, z) plane, at the x of
//! that arm as the front view sees it. An edge of the side silhouette inside a capsule
//! is then not taken for the trunk's (or the thigh's).
//!
//! The network costs tens of milliseconds, so it runs on the side view's person crop at a
//! subject's first fit and then every [`EVERY_FRAMES`] fitted frames (a subject holding
//! the pose moves the arms little in between); the capsules are kept in between. Without
//! the model file, or when the network finds no person, the fit goes on without capsules
//! (its smooth-trend test then tells occluders apart) and says so once.
//!
//! Units: metres in the station frame, pixels in the side camera's distorted image.

use crate::camera::Camera;
use crate::fit::sections::{SideOccluder, MAX_SIDE_OCCLUDERS};
use crate::landmarks::LandmarkName;
use crate::person::{kp, FrameRef, PersonModel, PersonOutput, PoseLandmarker, Roi};
use crate::silhouette::SilhouetteResult;
use glam::{DVec2, DVec3};

/// Fitted frames between two runs of the pose network.
pub const EVERY_FRAMES: usize = 10;
/// The crop fed to the network: the side silhouette's box, squared and widened by this.
const CROP_SCALE: f32 = 1.25;
/// The network's person presence below which its keypoints are not used.
const MIN_PRESENCE: f32 = 0.5;
/// Capsule radii, metres: half an adult's upper arm, forearm and hand thickness seen from
/// the side (the keypoints sit on the limb's axis).
const UPPER_ARM_RADIUS_M: f64 = 0.045;
const FOREARM_RADIUS_M: f64 = 0.04;
const HAND_RADIUS_M: f64 = 0.045;
/// The fingers' reach beyond the network's hand point (on the index knuckle), as a
/// share of the wrist-to-knuckle length (an adult's fingers are about as long as the
/// palm).
const FINGERS_BEYOND_KNUCKLES: f64 = 1.0;
/// The x of an arm when the front view's landmarks do not give it, metres from the
/// mark's centre line (an adult's forearm in an A-pose).
const DEFAULT_ARM_X_M: f64 = 0.3;

/// The side view's limb capsules of the current subject and the network that finds them.
pub struct SideLimbs {
    model: Option<PoseLandmarker>,
    out: PersonOutput,
    occluders: [Option<SideOccluder>; MAX_SIDE_OCCLUDERS],
    /// Fitted frames since the network last ran (None: run at the next frame).
    since: Option<usize>,
    /// Why the capsules are missing, said once.
    pub unavailable: Option<String>,
}

impl SideLimbs {
    /// Loads the pose network from the models folder (`person::find_model`); without it
    /// the station runs without side-view capsules.
    pub fn load() -> SideLimbs {
        let (model, unavailable) = match PoseLandmarker::load_default() {
            Ok(m) => (Some(m), None),
            Err(e) => (
                None,
                Some(format!(
                    "the person model is not available, the side view's arms are told from the trunk by shape alone: {e}"
                )),
            ),
        };
        SideLimbs {
            model,
            out: PersonOutput::new(),
            occluders: [None; MAX_SIDE_OCCLUDERS],
            since: None,
            unavailable,
        }
    }

    /// No network: the fit tells the side view's arms from the trunk by shape alone.
    pub fn off() -> SideLimbs {
        SideLimbs {
            model: None,
            out: PersonOutput::new(),
            occluders: [None; MAX_SIDE_OCCLUDERS],
            since: None,
            unavailable: None,
        }
    }

    /// Forgets the subject's capsules (the next frame runs the network).
    pub fn reset(&mut self) {
        self.occluders = [None; MAX_SIDE_OCCLUDERS];
        self.since = None;
    }

    /// Whether the network runs on this frame (the first of a subject, then every
    /// [`EVERY_FRAMES`]).
    pub fn due(&self) -> bool {
        self.model.is_some() && self.since.is_none_or(|n| n + 1 >= EVERY_FRAMES)
    }

    /// The capsules from the pose network's output on this frame's side view, run for
    /// another purpose (the person mask, [`super::person_masks`]): counts as this
    /// frame's run.
    pub fn adopt(
        &mut self,
        out: &PersonOutput,
        side_camera: &Camera,
        result: &SilhouetteResult,
    ) -> [Option<SideOccluder>; MAX_SIDE_OCCLUDERS] {
        if self.model.is_none() {
            return self.occluders;
        }
        self.since = Some(0);
        self.occluders = capsules(out, side_camera, result);
        self.occluders
    }

    /// The capsules for this frame: the network's on the side frame when due, else the
    /// last ones. Errors of the network leave the last capsules and are returned as a
    /// message.
    pub fn update(
        &mut self,
        side_frame: &image::RgbImage,
        side_camera: &Camera,
        result: &SilhouetteResult,
    ) -> Result<[Option<SideOccluder>; MAX_SIDE_OCCLUDERS], String> {
        if !self.due() {
            self.since = self.since.map(|n| n + 1);
            return Ok(self.occluders);
        }
        self.since = Some(0);
        let Some(model) = self.model.as_mut() else {
            return Ok(self.occluders);
        };
        let pts = &result.side.contour.points;
        let Some((lo, hi)) = bounds(pts.iter().copied()) else {
            return Ok(self.occluders);
        };
        let roi = Roi::square_around(
            lo.x as f32,
            lo.y as f32,
            hi.x as f32,
            hi.y as f32,
            CROP_SCALE,
        );
        model
            .infer(FrameRef::from_image(side_frame), roi, &mut self.out)
            .map_err(|e| format!("side view pose network: {e}"))?;
        self.occluders = capsules(&self.out, side_camera, result);
        Ok(self.occluders)
    }
}

/// The arms' capsules from a pose network's side-view output (none when it found no
/// person); the arm's x from the front view's landmarks.
fn capsules(
    out: &PersonOutput,
    side_camera: &Camera,
    result: &SilhouetteResult,
) -> [Option<SideOccluder>; MAX_SIDE_OCCLUDERS] {
    if out.presence.is_none_or(|p| p < MIN_PRESENCE) {
        return [None; MAX_SIDE_OCCLUDERS];
    }
    let arm_x = |elbow: LandmarkName, wrist: LandmarkName, sign: f64| -> f64 {
        let xs: Vec<f64> = [elbow, wrist]
            .iter()
            .filter_map(|n| result.landmarks.get(*n).map(|p| p.station.x))
            .collect();
        if xs.is_empty() {
            sign * DEFAULT_ARM_X_M
        } else {
            xs.iter().sum::<f64>() / xs.len() as f64
        }
    };
    let arms = [
        (
            [
                kp::LEFT_SHOULDER,
                kp::LEFT_ELBOW,
                kp::LEFT_WRIST,
                LEFT_INDEX,
            ],
            arm_x(LandmarkName::ElbowLeft, LandmarkName::WristLeft, 1.0),
        ),
        (
            [
                kp::RIGHT_SHOULDER,
                kp::RIGHT_ELBOW,
                kp::RIGHT_WRIST,
                RIGHT_INDEX,
            ],
            arm_x(LandmarkName::ElbowRight, LandmarkName::WristRight, -1.0),
        ),
    ];
    let mut occ = [None; MAX_SIDE_OCCLUDERS];
    for (a, (ids, x)) in arms.iter().enumerate() {
        let yz: Vec<Option<DVec2>> = ids
            .iter()
            .map(|&i| {
                let k = out.keypoints.get(i)?;
                on_plane_x(side_camera, DVec2::new(k.x as f64, k.y as f64), *x)
            })
            .collect();
        let radii = [UPPER_ARM_RADIUS_M, FOREARM_RADIUS_M, HAND_RADIUS_M];
        for (s, r) in radii.iter().enumerate() {
            if let (Some(p), Some(q)) = (yz[s], yz[s + 1]) {
                // BlazePose's hand point sits on the knuckles: the fingers reach on.
                let q = if s == 2 {
                    q + (q - p) * FINGERS_BEYOND_KNUCKLES
                } else {
                    q
                };
                occ[3 * a + s] = Some(SideOccluder {
                    a: p,
                    b: q,
                    radius: *r,
                    x: *x,
                    eye: side_camera.center_in_station(),
                });
            }
        }
    }
    if crate::fit::debug_enabled() {
        eprintln!("side limb capsules (y, z) m: {:?}", occ);
        let px: Vec<(usize, f32, f32)> = (11..23)
            .filter_map(|i| out.keypoints.get(i).map(|k| (i, k.x, k.y)))
            .collect();
        eprintln!("side arm keypoints px: {px:?}");
    }
    occ
}

/// BlazePose's index-finger keypoints (the hand's far end).
const LEFT_INDEX: usize = 19;
const RIGHT_INDEX: usize = 20;

/// The pixel's viewing ray met with the plane `x = x_plane`, as station `(y, z)`.
fn on_plane_x(camera: &Camera, px: DVec2, x_plane: f64) -> Option<DVec2> {
    let ray = camera.ray_through_pixel(px);
    if ray.dir.x.abs() < 1e-9 {
        return None;
    }
    let t = (x_plane - ray.origin.x) / ray.dir.x;
    (t > 0.0).then(|| {
        let p: DVec3 = ray.at(t);
        DVec2::new(p.y, p.z)
    })
}

/// Bounding box of points (None when there are none).
fn bounds(points: impl Iterator<Item = DVec2>) -> Option<(DVec2, DVec2)> {
    points.fold(None, |acc, p| {
        Some(match acc {
            None => (p, p),
            Some((lo, hi)) => (lo.min(p), hi.max(p)),
        })
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_side_pixel_lands_on_the_arms_plane() {
        let calib = crate::camera::StationCalibration::nominal(720, 1280, 1100.0, 3.0, 1.1, 1.0);
        let p = DVec3::new(0.3, 1.0, 0.12);
        let px = calib.side.project(p).expect("in view");
        let yz = on_plane_x(&calib.side, px, 0.3).expect("on plane");
        assert!((yz - DVec2::new(1.0, 0.12)).length() < 1e-6, "{yz}");
        // The plane through the mark instead shifts z by the perspective.
        let mid = on_plane_x(&calib.side, px, 0.0).expect("on plane");
        assert!((mid.x - 1.0).abs() > 1e-4 || (mid.y - 0.12).abs() > 1e-4);
    }

    #[test]
    fn the_network_runs_at_first_and_then_every_few_frames() {
        let mut s = SideLimbs::load();
        if s.model.is_none() {
            panic!("{}", s.unavailable.unwrap_or_default());
        }
        assert!(s.due());
        s.since = Some(0);
        let mut runs = 0;
        for _ in 0..3 * EVERY_FRAMES {
            if s.due() {
                runs += 1;
                s.since = Some(0);
            } else {
                s.since = s.since.map(|n| n + 1);
            }
        }
        assert_eq!(runs, 3);
        s.reset();
        assert!(s.due());
    }
}
