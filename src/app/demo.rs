//! A synthetic station for developing and testing the screen without cameras or a fit:
//! [`DemoSource`] draws a simple figure (capsules between joints) on a textured backdrop
//! through the nominal station cameras, moving slightly; [`DemoProcessor`] turns those
//! frames into [`FitSnapshot`]s with a contour, landmarks, bones, a capsule avatar and
//! measurements that settle over time. [`FramesOnlyProcessor`] shows live frames with no
//! fit (for `fitstation live` until the real processor is plugged in).
//!
//! Conventions: station frame in metres (+Y up, +Z toward the front camera, +X the
//! subject's left); pixels of the (undistorted, nominal) demo cameras; portrait frames
//! [`DEMO_WIDTH`] x [`DEMO_HEIGHT`]. The demo timeline is a function of the frame index
//! (not of wall time), so runs are reproducible.

use crate::camera::{StationCalibration, View};
use crate::mesh::{shapes, TriMesh};
use crate::pipeline::timing::FrameTimer;
use crate::pipeline::{
    FitSnapshot, FramePair, FrameProcessor, FrameSource, MeasurementValue, Phase, SourceError,
    ViewOverlay,
};
use glam::{DMat3, DVec2, DVec3};
use image::{Rgb, RgbImage};
use std::collections::VecDeque;
use std::sync::Arc;

/// Demo frame width in pixels (portrait 720p).
pub const DEMO_WIDTH: u32 = 720;
/// Demo frame height in pixels.
pub const DEMO_HEIGHT: u32 = 1280;
/// Demo frame rate.
pub const DEMO_FPS: f64 = 30.0;
/// Nominal demo cameras: focal length (px), distance from the mark, height, aim height (m).
const DEMO_FOCAL_PX: f64 = 1000.0;
const DEMO_CAMERA_DISTANCE_M: f64 = 3.0;
const DEMO_CAMERA_HEIGHT_M: f64 = 1.0;
const DEMO_AIM_HEIGHT_M: f64 = 0.9;

/// Demo timeline, in frames at [`DEMO_FPS`]: empty backdrop, then nobody, a badly placed
/// subject, a good pose while the fit settles, the subject leaves; then it repeats.
const LEARN_FRAMES: u64 = 30;
const EMPTY_FRAMES: u64 = 30;
const GUIDING_FRAMES: u64 = 30;
const POSE_FRAMES: u64 = 300;
const LEAVE_FRAMES: u64 = 60;
const CYCLE_FRAMES: u64 = LEARN_FRAMES + EMPTY_FRAMES + GUIDING_FRAMES + POSE_FRAMES + LEAVE_FRAMES;

/// Where the demo subject is in the timeline.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Act {
    Learn,
    Empty,
    BadPose,
    Pose { frames_in: u64 },
    Gone,
}

fn act(index: u64) -> Act {
    let k = index % CYCLE_FRAMES;
    if k < LEARN_FRAMES {
        // Only the first cycle learns; later cycles show an empty scene instead.
        if index < CYCLE_FRAMES {
            Act::Learn
        } else {
            Act::Empty
        }
    } else if k < LEARN_FRAMES + EMPTY_FRAMES {
        Act::Empty
    } else if k < LEARN_FRAMES + EMPTY_FRAMES + GUIDING_FRAMES {
        Act::BadPose
    } else if k < LEARN_FRAMES + EMPTY_FRAMES + GUIDING_FRAMES + POSE_FRAMES {
        Act::Pose {
            frames_in: k - LEARN_FRAMES - EMPTY_FRAMES - GUIDING_FRAMES,
        }
    } else {
        Act::Gone
    }
}

/// The demo body: joints of an A-pose (station frame, metres) and limb radii.
#[derive(Debug, Clone)]
pub struct DemoBody {
    pub joints: Vec<(&'static str, DVec3)>,
    /// Capsules between joints: (joint a, joint b, radius m).
    pub limbs: Vec<(usize, usize, f64)>,
    pub head_radius_m: f64,
}

const HEAD: usize = 0;
const NECK: usize = 1;

impl DemoBody {
    /// The body at time `t_s`, swaying slightly; `arms_spread` (0 = A-pose, 1 = arms
    /// raised) makes a pose to correct.
    pub fn at(t_s: f64, arms_spread: f64) -> Self {
        let sway = DVec3::new(0.012 * (t_s * 0.9).sin(), 0.0, 0.008 * (t_s * 0.7).cos());
        let arm = |side: f64, y: f64, out: f64| DVec3::new(side * out, y, 0.0);
        let joints = vec![
            ("head", DVec3::new(0.0, 1.64, 0.0)),
            ("neck", DVec3::new(0.0, 1.50, 0.0)),
            ("shoulder_left", DVec3::new(0.19, 1.44, 0.0)),
            ("shoulder_right", DVec3::new(-0.19, 1.44, 0.0)),
            (
                "elbow_left",
                arm(1.0, 1.18 + 0.25 * arms_spread, 0.29 + 0.15 * arms_spread),
            ),
            (
                "elbow_right",
                arm(-1.0, 1.18 + 0.25 * arms_spread, 0.29 + 0.15 * arms_spread),
            ),
            (
                "wrist_left",
                arm(1.0, 0.95 + 0.5 * arms_spread, 0.38 + 0.3 * arms_spread),
            ),
            (
                "wrist_right",
                arm(-1.0, 0.95 + 0.5 * arms_spread, 0.38 + 0.3 * arms_spread),
            ),
            ("pelvis", DVec3::new(0.0, 0.95, 0.0)),
            ("hip_left", DVec3::new(0.09, 0.90, 0.0)),
            ("hip_right", DVec3::new(-0.09, 0.90, 0.0)),
            ("knee_left", DVec3::new(0.11, 0.50, 0.01)),
            ("knee_right", DVec3::new(-0.11, 0.50, 0.01)),
            ("ankle_left", DVec3::new(0.12, 0.08, 0.0)),
            ("ankle_right", DVec3::new(-0.12, 0.08, 0.0)),
        ]
        .into_iter()
        .map(|(n, p)| (n, p + sway * (p.y / 1.7)))
        .collect();
        let limbs = vec![
            (NECK, 8, 0.14), // torso (neck -> pelvis), drawn wide
            (2, 4, 0.05),    // upper arms
            (3, 5, 0.05),
            (4, 6, 0.04), // forearms
            (5, 7, 0.04),
            (9, 11, 0.075), // thighs
            (10, 12, 0.075),
            (11, 13, 0.055), // shins
            (12, 14, 0.055),
            (2, 3, 0.06),  // shoulders
            (9, 10, 0.08), // hips
        ];
        DemoBody {
            joints,
            limbs,
            head_radius_m: 0.1,
        }
    }

    /// Bones as joint index pairs (the limbs' axes).
    fn bones(&self) -> Vec<(usize, usize)> {
        self.limbs.iter().map(|l| (l.0, l.1)).collect()
    }

    /// A closed triangle mesh of the body: spheres at joints, cylinders along limbs,
    /// torso and limb girths scaled by `girth_scale`.
    pub fn mesh(&self, girth_scale: f64) -> TriMesh {
        let mut out = TriMesh::new(Vec::new(), Vec::new());
        let head = self.joints[HEAD].1;
        append(
            &mut out,
            shapes::uv_sphere(self.head_radius_m, 10, 16),
            DMat3::IDENTITY,
            head,
        );
        for &(a, b, r) in &self.limbs {
            let (pa, pb) = (self.joints[a].1, self.joints[b].1);
            let r = r * girth_scale;
            let axis = pb - pa;
            let len = axis.length();
            if len < 1e-6 {
                continue;
            }
            // Torso is flatter front-to-back than side-to-side.
            let (ra, rb) = if a == NECK {
                (r * 1.15, r * 0.8)
            } else {
                (r, r)
            };
            let cyl = shapes::elliptic_cylinder(ra, rb, len, 4, 16);
            append(&mut out, cyl, rotation_from_y(axis / len), pa);
            append(
                &mut out,
                shapes::uv_sphere(r.min(ra.min(rb)), 6, 12),
                DMat3::IDENTITY,
                pb,
            );
        }
        out
    }
}

/// A rotation taking +Y to `dir` (unit), keeping +X roughly in the XY plane.
fn rotation_from_y(dir: DVec3) -> DMat3 {
    let y = dir;
    let helper = if y.z.abs() < 0.9 { DVec3::Z } else { DVec3::X };
    let x = helper.cross(y).normalize();
    let z = x.cross(y);
    DMat3::from_cols(x, y, z)
}

fn append(out: &mut TriMesh, part: TriMesh, rot: DMat3, offset: DVec3) {
    let base = out.positions.len() as u32;
    out.positions
        .extend(part.positions.iter().map(|&p| rot * p + offset));
    out.triangles.extend(
        part.triangles
            .iter()
            .map(|t| [t[0] + base, t[1] + base, t[2] + base]),
    );
}

/// The nominal calibration used by the demo cameras.
pub fn demo_calibration() -> StationCalibration {
    StationCalibration::nominal(
        DEMO_WIDTH,
        DEMO_HEIGHT,
        DEMO_FOCAL_PX,
        DEMO_CAMERA_DISTANCE_M,
        DEMO_CAMERA_HEIGHT_M,
        DEMO_AIM_HEIGHT_M,
    )
}

/// A frame source drawing the demo timeline; endless unless `max_frames` is set.
pub struct DemoSource {
    calibration: StationCalibration,
    index: u64,
    max_frames: Option<u64>,
    backdrop_front: RgbImage,
    backdrop_side: RgbImage,
    width: u32,
    height: u32,
}

impl DemoSource {
    pub fn new(max_frames: Option<u64>) -> Self {
        Self::with_size(DEMO_WIDTH, DEMO_HEIGHT, max_frames)
    }

    /// A demo at another frame size (the cameras keep the nominal geometry, scaled).
    pub fn with_size(width: u32, height: u32, max_frames: Option<u64>) -> Self {
        let focal = DEMO_FOCAL_PX * height as f64 / DEMO_HEIGHT as f64;
        let calibration = StationCalibration::nominal(
            width,
            height,
            focal,
            DEMO_CAMERA_DISTANCE_M,
            DEMO_CAMERA_HEIGHT_M,
            DEMO_AIM_HEIGHT_M,
        );
        DemoSource {
            calibration,
            index: 0,
            max_frames,
            backdrop_front: backdrop(width, height, 0),
            backdrop_side: backdrop(width, height, 1),
            width,
            height,
        }
    }
}

/// A textured backdrop: soft stripes and a floor band, different per camera.
fn backdrop(width: u32, height: u32, seed: u32) -> RgbImage {
    let floor_y = height * 4 / 5;
    RgbImage::from_fn(width, height, |x, y| {
        if y >= floor_y {
            let c = if ((x / 40) + (y / 40)) % 2 == 0 {
                96
            } else {
                84
            };
            Rgb([c, c, c + 6])
        } else {
            let stripe = (((x + seed * 17) / 24) % 2) as u8 * 14;
            let grain = ((x.wrapping_mul(7919) ^ y.wrapping_mul(104_729) ^ seed) % 9) as u8;
            Rgb([188 + stripe + grain, 196 + stripe + grain, 204 + grain])
        }
    })
}

/// Clothing colour of the drawn figure.
const FIGURE_RGB: [u8; 3] = [52, 70, 112];
const SKIN_RGB: [u8; 3] = [206, 160, 130];

/// Projects body joints and draws the capsules into `img` (pixels of `view`).
fn draw_body(img: &mut RgbImage, cal: &StationCalibration, view: View, body: &DemoBody) {
    let cam = cal.camera(view);
    let px: Vec<Option<DVec2>> = body.joints.iter().map(|(_, p)| cam.project(*p)).collect();
    let depth = |p: DVec3| (p - cam.center_in_station()).length();
    let radius_px = |p: DVec3, r: f64| r * cam.intrinsics.fx / depth(p).max(0.1);
    let mut capsules: Vec<(DVec2, DVec2, f64, [u8; 3])> = Vec::new();
    for &(a, b, r) in &body.limbs {
        if let (Some(pa), Some(pb)) = (px[a], px[b]) {
            // Seen from the side, the torso is its front-to-back depth.
            let r = if a == NECK && view == View::Side {
                r * 0.8
            } else {
                r
            };
            let colour = if b == 6 || b == 7 {
                SKIN_RGB
            } else {
                FIGURE_RGB
            };
            capsules.push((pa, pb, radius_px(body.joints[a].1, r), colour));
        }
    }
    if let Some(h) = px[HEAD] {
        capsules.push((
            h,
            h,
            radius_px(body.joints[HEAD].1, body.head_radius_m),
            SKIN_RGB,
        ));
    }
    let (w, h) = (img.width() as i64, img.height() as i64);
    for (a, b, r, colour) in capsules {
        let x0 = (a.x.min(b.x) - r).floor().max(0.0) as i64;
        let x1 = ((a.x.max(b.x) + r).ceil() as i64).min(w - 1);
        let y0 = (a.y.min(b.y) - r).floor().max(0.0) as i64;
        let y1 = ((a.y.max(b.y) + r).ceil() as i64).min(h - 1);
        for y in y0..=y1 {
            for x in x0..=x1 {
                let p = DVec2::new(x as f64, y as f64);
                if segment_distance(p, a, b) <= r {
                    // Darker toward the capsule's edge: a little shading.
                    let k = 1.0 - 0.35 * (segment_distance(p, a, b) / r.max(1.0));
                    let c = Rgb([
                        (colour[0] as f64 * k) as u8,
                        (colour[1] as f64 * k) as u8,
                        (colour[2] as f64 * k) as u8,
                    ]);
                    img.put_pixel(x as u32, y as u32, c);
                }
            }
        }
    }
}

fn segment_distance(p: DVec2, a: DVec2, b: DVec2) -> f64 {
    let ab = b - a;
    let l2 = ab.length_squared();
    let t = if l2 > 0.0 {
        ((p - a).dot(ab) / l2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    (p - (a + t * ab)).length()
}

/// Arm spread of the badly placed subject (arms too high).
const BAD_POSE_ARMS: f64 = 0.9;

fn body_for(index: u64) -> Option<DemoBody> {
    let t = index as f64 / DEMO_FPS;
    match act(index) {
        Act::Learn | Act::Empty | Act::Gone => None,
        Act::BadPose => Some(DemoBody::at(t, BAD_POSE_ARMS)),
        Act::Pose { .. } => Some(DemoBody::at(t, 0.0)),
    }
}

impl FrameSource for DemoSource {
    fn next_pair(&mut self) -> Result<Option<FramePair>, SourceError> {
        if self.max_frames.is_some_and(|m| self.index >= m) {
            return Ok(None);
        }
        let index = self.index;
        self.index += 1;
        let mut front = self.backdrop_front.clone();
        let mut side = self.backdrop_side.clone();
        if let Some(body) = body_for(index) {
            draw_body(&mut front, &self.calibration, View::Front, &body);
            draw_body(&mut side, &self.calibration, View::Side, &body);
        }
        Ok(Some(FramePair {
            index,
            timestamp_s: index as f64 / DEMO_FPS,
            front: front.into(),
            side: side.into(),
        }))
    }

    fn calibration(&self) -> Option<&StationCalibration> {
        Some(&self.calibration)
    }

    fn fps(&self) -> Option<f64> {
        Some(DEMO_FPS)
    }

    fn describe(&self) -> String {
        format!("demo {}x{}", self.width, self.height)
    }
}

/// The demo subject's true measurements (mm) and the template's start values.
const DEMO_MEASUREMENTS: [(&str, f64, f64); 6] = [
    ("stature", 1742.0, 1700.0),
    ("chest_girth", 968.0, 1010.0),
    ("waist_girth", 812.0, 870.0),
    ("hip_girth", 990.0, 1030.0),
    ("thigh_girth_left", 566.0, 600.0),
    ("thigh_girth_right", 561.0, 600.0),
];
/// Settling time constant of the demo fit, in frames.
const SETTLE_FRAMES: f64 = 40.0;
/// Frames kept to compute a measurement's stability.
const STABILITY_WINDOW: usize = 15;
/// A measurement is settled when its recent spread is below this (mm).
pub const SETTLED_SPREAD_MM: f64 = 3.0;

/// The demo processor: knows the demo timeline, finds the figure in the frames (mask
/// by colour difference to the learnt backdrop) and synthesises the rest.
pub struct DemoProcessor {
    calibration: StationCalibration,
    backdrop: Option<(RgbImage, RgbImage)>,
    history: Vec<VecDeque<f64>>,
    mask: Vec<bool>,
}

/// Colour distance (sum of absolute channel differences) that counts as foreground.
const FOREGROUND_THRESHOLD: i32 = 60;
/// Row step of the demo contour (pixels).
const CONTOUR_ROW_STEP: usize = 6;

impl DemoProcessor {
    pub fn new(calibration: StationCalibration) -> Self {
        DemoProcessor {
            calibration,
            backdrop: None,
            history: vec![VecDeque::new(); DEMO_MEASUREMENTS.len()],
            mask: Vec::new(),
        }
    }

    /// A left/right outline of the foreground: per sampled row the leftmost and rightmost
    /// foreground pixel, down the left side and up the right.
    fn contour(mask: &mut Vec<bool>, frame: &RgbImage, backdrop: &RgbImage) -> Vec<DVec2> {
        let (w, h) = (frame.width() as usize, frame.height() as usize);
        if frame.dimensions() != backdrop.dimensions() {
            return Vec::new();
        }
        let (fr, br) = (frame.as_raw(), backdrop.as_raw());
        let mut left = Vec::new();
        let mut right = Vec::new();
        // Only the sampled rows are segmented: the outline needs nothing else.
        for y in (0..h).step_by(CONTOUR_ROW_STEP) {
            mask.clear();
            let row = y * w * 3..(y + 1) * w * 3;
            mask.extend(
                fr[row.clone()]
                    .chunks_exact(3)
                    .zip(br[row].chunks_exact(3))
                    .map(|(a, b)| {
                        let d = (a[0] as i32 - b[0] as i32).abs()
                            + (a[1] as i32 - b[1] as i32).abs()
                            + (a[2] as i32 - b[2] as i32).abs();
                        d > FOREGROUND_THRESHOLD
                    }),
            );
            let row = &mask[..];
            if let (Some(l), Some(r)) = (row.iter().position(|&m| m), row.iter().rposition(|&m| m))
            {
                left.push(DVec2::new(l as f64, y as f64));
                right.push(DVec2::new(r as f64, y as f64));
            }
        }
        right.reverse();
        left.extend(right);
        left
    }

    fn overlay(
        &mut self,
        view: View,
        frame: &RgbImage,
        body: &DemoBody,
        avatar: &TriMesh,
    ) -> ViewOverlay {
        let backdrop = match (&self.backdrop, view) {
            (Some((f, _)), View::Front) => f,
            (Some((_, s)), View::Side) => s,
            _ => return ViewOverlay::default(),
        };
        let contour = Self::contour(&mut self.mask, frame, backdrop);
        let cam = self.calibration.camera(view);
        let landmarks: Vec<(String, DVec2)> = body
            .joints
            .iter()
            .filter_map(|(n, p)| Some((n.to_string(), cam.project(*p)?)))
            .collect();
        let bones = body
            .bones()
            .into_iter()
            .filter_map(|(a, b)| {
                Some((
                    cam.project(body.joints[a].1)?,
                    cam.project(body.joints[b].1)?,
                ))
            })
            .collect();
        // Contour parts by height: above the neck, torso and arms, legs.
        let neck_y = cam.project(body.joints[NECK].1).map_or(0.0, |p| p.y);
        let hip_y = cam.project(body.joints[9].1).map_or(0.0, |p| p.y);
        let part = |name: &str, f: &dyn Fn(f64) -> bool| {
            (
                name.to_string(),
                contour
                    .iter()
                    .copied()
                    .filter(|p| f(p.y))
                    .collect::<Vec<_>>(),
            )
        };
        let parts = vec![
            part("head", &|y| y < neck_y),
            part("torso and arms", &|y| y >= neck_y && y < hip_y),
            part("legs", &|y| y >= hip_y),
        ];
        // The avatar's outline: the projected vertices' left/right extremes per band.
        let mut avatar_outline = Vec::new();
        let pts: Vec<DVec2> = avatar
            .positions
            .iter()
            .filter_map(|p| cam.project(*p))
            .collect();
        if let (Some(top), Some(bottom)) = (
            pts.iter().map(|p| p.y).min_by(|a, b| a.total_cmp(b)),
            pts.iter().map(|p| p.y).max_by(|a, b| a.total_cmp(b)),
        ) {
            let bands = 60;
            let mut l = Vec::new();
            let mut r = Vec::new();
            for k in 0..bands {
                let y0 = top + (bottom - top) * k as f64 / bands as f64;
                let y1 = top + (bottom - top) * (k + 1) as f64 / bands as f64;
                let xs = pts.iter().filter(|p| p.y >= y0 && p.y <= y1).map(|p| p.x);
                let (mn, mx) = xs.fold((f64::INFINITY, f64::NEG_INFINITY), |a, x| {
                    (a.0.min(x), a.1.max(x))
                });
                if mn.is_finite() {
                    l.push(DVec2::new(mn, 0.5 * (y0 + y1)));
                    r.push(DVec2::new(mx, 0.5 * (y0 + y1)));
                }
            }
            r.reverse();
            l.extend(r);
            avatar_outline = l;
        }
        ViewOverlay {
            contour,
            parts,
            landmarks,
            bones,
            avatar_outline,
            camera: None,
        }
    }
}

impl FrameProcessor for DemoProcessor {
    fn process(&mut self, pair: &FramePair) -> FitSnapshot {
        let mut timer = FrameTimer::start();
        let index = pair.index;
        let mut snap = FitSnapshot::empty(index, Phase::WaitingForSubject);
        snap.front_frame = Some(pair.front.clone());
        snap.side_frame = Some(pair.side.clone());
        match act(index) {
            Act::Learn => {
                self.backdrop = Some(((*pair.front).clone(), (*pair.side).clone()));
                snap.phase = Phase::LearningBackdrop;
                snap.messages
                    .push("Learning the backdrop: keep the scene empty".into());
                timer.lap("backdrop");
            }
            Act::Empty | Act::Gone => {
                if self.backdrop.is_none() {
                    self.backdrop = Some(((*pair.front).clone(), (*pair.side).clone()));
                }
                timer.lap("segment");
            }
            Act::BadPose => {
                snap.phase = Phase::Guiding;
                snap.messages.push("Lower your arms a little".into());
                let body = DemoBody::at(index as f64 / DEMO_FPS, BAD_POSE_ARMS);
                let avatar = body.mesh(1.0);
                snap.front = self.overlay(View::Front, &pair.front, &body, &avatar);
                snap.side = self.overlay(View::Side, &pair.side, &body, &avatar);
                timer.lap("segment");
            }
            Act::Pose { frames_in } => {
                let t = index as f64 / DEMO_FPS;
                let body = DemoBody::at(t, 0.0);
                let settle = (-(frames_in as f64) / SETTLE_FRAMES).exp();
                // Girths converge from the template to the subject, with a small wobble.
                let avatar = body.mesh(1.0 + 0.12 * settle + 0.01 * (t * 2.0).sin() * settle);
                snap.front = self.overlay(View::Front, &pair.front, &body, &avatar);
                snap.side = self.overlay(View::Side, &pair.side, &body, &avatar);
                timer.lap("segment");
                snap.landmarks_station = body
                    .joints
                    .iter()
                    .map(|(n, p)| (n.to_string(), *p))
                    .collect();
                snap.avatar = Some(Arc::new(avatar));
                timer.lap("fit");
                let mut all_settled = true;
                for (k, (name, truth, start)) in DEMO_MEASUREMENTS.iter().enumerate() {
                    let wobble = 6.0 * settle * (t * 3.0 + k as f64).sin();
                    let v = truth + (start - truth) * settle + wobble;
                    let h = &mut self.history[k];
                    h.push_back(v);
                    while h.len() > STABILITY_WINDOW {
                        h.pop_front();
                    }
                    let (mn, mx) = h.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |a, &x| {
                        (a.0.min(x), a.1.max(x))
                    });
                    let spread = mx - mn;
                    all_settled &= h.len() == STABILITY_WINDOW && spread < SETTLED_SPREAD_MM;
                    snap.measurements.push(MeasurementValue {
                        name: name.to_string(),
                        value_mm: v,
                        stability_mm: spread,
                        // The demo animates values without a fit behind them.
                        uncertainty_mm: f64::INFINITY,
                        uncertain: false,
                    });
                }
                snap.phase = if all_settled {
                    Phase::Settled
                } else {
                    Phase::Fitting
                };
                timer.lap("measure");
            }
        }
        if !matches!(act(index), Act::Pose { .. }) {
            for h in &mut self.history {
                h.clear();
            }
        }
        snap.timings_ms = timer.into_stages();
        snap
    }

    fn reset_subject(&mut self) {
        for h in &mut self.history {
            h.clear();
        }
    }
}

/// Shows frames only: no segmentation, no fit. For live cameras until the fit
/// processor is plugged in.
#[derive(Debug, Default)]
pub struct FramesOnlyProcessor;

impl FrameProcessor for FramesOnlyProcessor {
    fn process(&mut self, pair: &FramePair) -> FitSnapshot {
        let mut snap = FitSnapshot::empty(pair.index, Phase::WaitingForSubject);
        snap.messages
            .push("No fit processor connected: showing frames only".into());
        snap.front_frame = Some(pair.front.clone());
        snap.side_frame = Some(pair.side.clone());
        snap
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn timeline_covers_every_phase_in_order() {
        let mut src = DemoSource::with_size(180, 320, Some(CYCLE_FRAMES));
        let mut proc_ =
            DemoProcessor::new(src.calibration().cloned().expect("demo has a calibration"));
        let mut phases = Vec::new();
        while let Ok(Some(pair)) = src.next_pair() {
            let s = proc_.process(&pair);
            if phases.last() != Some(&s.phase) {
                phases.push(s.phase);
            }
            if s.phase == Phase::Fitting || s.phase == Phase::Settled {
                assert!(s.avatar.is_some());
                assert_eq!(s.measurements.len(), DEMO_MEASUREMENTS.len());
                assert!(
                    s.front.contour.len() > 10,
                    "the figure is found in the front frame"
                );
                assert!(
                    s.side.contour.len() > 10,
                    "the figure is found in the side frame"
                );
            }
        }
        assert_eq!(
            phases,
            vec![
                Phase::LearningBackdrop,
                Phase::WaitingForSubject,
                Phase::Guiding,
                Phase::Fitting,
                Phase::Settled,
                Phase::WaitingForSubject
            ]
        );
    }

    #[test]
    fn contour_encloses_the_projected_pelvis() {
        let mut src = DemoSource::with_size(360, 640, None);
        let mut proc_ = DemoProcessor::new(src.calibration().cloned().expect("calibration"));
        let cal = src.calibration().cloned().expect("calibration");
        let target = LEARN_FRAMES + EMPTY_FRAMES + GUIDING_FRAMES + 5;
        let mut snap = None;
        for _ in 0..=target {
            let pair = src.next_pair().expect("frame").expect("endless");
            snap = Some(proc_.process(&pair));
        }
        let snap = snap.expect("processed");
        let body = DemoBody::at(target as f64 / DEMO_FPS, 0.0);
        let pelvis = cal
            .front
            .project(body.joints[8].1)
            .expect("in front of the camera");
        let xs: Vec<f64> = snap
            .front
            .contour
            .iter()
            .filter(|p| (p.y - pelvis.y).abs() < 4.0)
            .map(|p| p.x)
            .collect();
        assert!(xs.len() >= 2);
        let (mn, mx) = xs.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |a, &x| {
            (a.0.min(x), a.1.max(x))
        });
        assert!(mn < pelvis.x && pelvis.x < mx, "{mn} < {} < {mx}", pelvis.x);
    }

    #[test]
    fn avatar_mesh_is_closed_and_outward() {
        let m = DemoBody::at(0.0, 0.0).mesh(1.0);
        assert_eq!(m.boundary_edge_count(), 0);
        assert!(m.volume() > 0.0);
        let b = m.bounds().expect("non-empty");
        assert!(b.size().y > 1.5 && b.size().y < 1.9, "{:?}", b.size());
    }
}
