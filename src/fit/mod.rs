//! The fit: from two silhouettes to an avatar and its measurements (method.md section 3).
//!
//! First fit of a subject:
//! 1. **Candidate** ([`shape`]): the library body whose torso/thigh descriptor is nearest
//!    to the silhouettes' (all library bodies, precomputed), then Gauss-Newton on its macro
//!    parameters; scaled to the observed stature and placed where the subject stands.
//! 2. **Pose synchronisation** ([`pose`]): arms and legs rotated about the shoulder and
//!    hip joints (linear blend skinning) to the angles seen in the front view.
//! 3. **Correspondence** ([`correspond`]): control vertices with left/right/front/back
//!    status and their targets on the silhouettes, either variant.
//! 4. **Refit**: the mean value deformer moves the controls to their targets while every
//!    other vertex keeps its mean value encoding (or its Laplacian coordinate, with
//!    [`deformer::DeformerKind::Laplacian`]); head, hands and feet are then put back
//!    rigidly (best rigid fit of their rest shape).
//!
//! Later frames warm-start: same candidate and controls, new targets, a warm solve.
//!
//! Units: metres, station frame (+Y up, +Z toward the front camera, +X the subject's left).

pub mod armpit;
pub mod correspond;
pub mod deformer;
mod first;
pub mod one_view;
pub mod parts;
pub mod pose;
pub mod section_prior;
pub mod sections;
pub mod shape;
pub mod turn;

use crate::body::{ShapeLibrary, ShapeParams, AGE_MAX_YEARS, AGE_MIN_YEARS};
use crate::camera::StationCalibration;
use crate::deform::{DecodeOptions, DecoderKind};
use crate::mesh::TriMesh;
use correspond::{ControlSet, MaskRef, Part, SearchOptions, TargetStats, Variant};
use deformer::{DeformerKind, FitDeformer};
use glam::DVec3;
use std::sync::Arc;

/// Gauss-Newton steps of one decode (a warm refit is one decode; convergence continues
/// over the following frames).
const DECODE_ITERATIONS_PER_SOLVE: usize = 8;
/// Whether the environment asks for the fit's diagnostic prints (`FITSTATION_DEBUG`), read
/// once per process: the per-frame paths must not look up the environment.
/// The cameras' centres (front, side) the section maps read each edge at its rim's depth
/// from ([`sections::SectionScratch::eyes`]); None without [`FitOptions::rim_depth`].
fn rim_depth_eyes(
    on: bool,
    views: [(&crate::camera::Camera, correspond::MaskRef<'_>); 2],
) -> Option<[glam::DVec3; 2]> {
    on.then(|| {
        [
            views[0].0.center_in_station(),
            views[1].0.center_in_station(),
        ]
    })
}

pub(crate) fn debug_enabled() -> bool {
    static DEBUG: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
    *DEBUG.get_or_init(|| std::env::var_os("FITSTATION_DEBUG").is_some())
}

/// Correspondence rounds of an intermediate pass of the first fit.
const INTERMEDIATE_ROUNDS: usize = 2;
/// Decodes per correspondence round of a first fit.
const FIRST_FIT_SOLVES: usize = 4;

/// Height (fraction of stature) at which the candidate is placed on the silhouettes.
const PLACEMENT_LEVEL: f64 = 0.55;
/// Largest front-to-back offset of the trunk's centre at [`PLACEMENT_LEVEL`] from the
/// landmarks' torso point, as a fraction of stature (a posture's lean between the two
/// heights; the evaluation sets measure 3-19 mm, i.e. up to about 0.011).
const PLACEMENT_MAX_LEAN: f64 = 0.02;

/// Environment variable that turns [`FitOptions::waist_prior`] off (value `off`).
pub const WAIST_PRIOR_ENV: &str = "FITSTATION_WAIST_PRIOR";
/// Environment variable that turns [`FitOptions::turn_from_toes`] off (value `off`).
pub const TURN_ENV: &str = "FITSTATION_TURN";
/// Environment switch: `on` refines the cup size with the other macro parameters
/// ([`FitOptions::refine_cup`]).
pub const CUP_ENV: &str = "FITSTATION_CUP";
/// Environment variable that turns [`FitOptions::rim_depth`] off (value `off`).
pub const RIM_DEPTH_ENV: &str = "FITSTATION_RIM_DEPTH";

/// Options of the fit.
#[derive(Debug, Clone)]
pub struct FitOptions {
    pub variant: Variant,
    /// The deformer of the refit (mean value, the default, or Laplacian).
    pub deformer: DeformerKind,
    /// The mean value deformer's decoder.
    pub decoder: DecoderKind,
    /// Refine the candidate's macro parameters (Gauss-Newton) after the library search.
    pub refine_shape: bool,
    /// Levenberg-Marquardt iterations of the shape refinement (each: a forward-difference
    /// Jacobian, 6 bodies (7 with the cup size), and one or more trial steps). 8: with 4
    /// a subject whose cost has a narrow valley stopped half-way (evaluation subject 09:
    /// girths +30 mm).
    pub shape_iterations: usize,
    /// Correspondence/solve rounds of the first fit (targets are recomputed each round).
    pub first_fit_rounds: usize,
    pub search: SearchOptions,
    /// Number of library bodies the candidate is chosen from.
    pub library_size: usize,
    /// Section-consistent dense targets on the trunk and legs ([`sections`]); off: only
    /// the paper's sparse extreme controls.
    pub dense_sections: bool,
    /// Give the waist band the section shape of real people's waists
    /// ([`section_prior`]) instead of the candidate's; needs `dense_sections`. On unless
    /// the environment sets [`WAIST_PRIOR_ENV`] to `off` (to compare with the candidate's
    /// shape: `FITSTATION_WAIST_PRIOR=off fitstation eval ...`).
    pub waist_prior: bool,
    /// Passes of the first fit: after the first, the candidate is chosen again against
    /// the previous pass's fitted avatar and fitted from scratch.
    pub candidate_passes: usize,
    /// Turn the candidate by the turn on the mark the side view's toes show
    /// ([`turn`]) before its controls are chosen. On unless the environment sets
    /// [`TURN_ENV`] to `off` (to compare: `FITSTATION_TURN=off fitstation eval ...`).
    pub turn_from_toes: bool,
    /// Read each silhouette edge at the depth of its section's rim, along its viewing ray,
    /// not at the control vertex's depth ([`sections`]). On unless the environment sets
    /// [`RIM_DEPTH_ENV`] to `off` (to compare: `FITSTATION_RIM_DEPTH=off fitstation eval`).
    pub rim_depth: bool,
    /// Refine the library's cup size ([`ShapeParams::cup`]) jointly with the other macro
    /// parameters. Off unless the environment sets [`CUP_ENV`] to `on`: on the
    /// development ANSUR set it brought the women's chest, hip and thighs closer but their
    /// waists further off (the library's larger cups also lower the bust toward the
    /// waist; see docs/evaluation.md, session 31).
    pub refine_cup: bool,
}

impl Default for FitOptions {
    fn default() -> Self {
        FitOptions {
            variant: Variant::PerspectiveRim,
            deformer: DeformerKind::Mvc,
            decoder: DecoderKind::FastGaussNewton,
            refine_shape: true,
            shape_iterations: 8,
            first_fit_rounds: 3,
            search: SearchOptions::default(),
            library_size: 252,
            dense_sections: true,
            waist_prior: std::env::var(WAIST_PRIOR_ENV).as_deref() != Ok("off"),
            candidate_passes: 3,
            turn_from_toes: std::env::var(TURN_ENV).as_deref() != Ok("off"),
            rim_depth: std::env::var(RIM_DEPTH_ENV).as_deref() != Ok("off"),
            refine_cup: std::env::var(CUP_ENV).as_deref() == Ok("on"),
        }
    }
}

/// What the fitter needs to know besides the silhouettes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Observation {
    /// Stature (typed by the operator, or from the silhouettes), metres.
    pub stature_m: f64,
    /// A point inside the torso at about hip height (station frame).
    pub torso_point: DVec3,
    /// Arm abduction seen in the front view: angle of shoulder -> wrist from straight
    /// down, radians, left and right (positive = away from the body). None if unknown.
    pub arm_angles: Option<(f64, f64)>,
    /// Leg spread seen in the front view: angle of hip -> ankle from straight down.
    pub leg_angles: Option<(f64, f64)>,
    /// Where the arms and hands are in the side view (forearm, hand: from the person
    /// model's keypoints), as capsules in the station's (y, z) plane: an edge of the side
    /// silhouette inside one may be the limb's, not the trunk's or the thigh's, and is
    /// not taken as theirs. All None when unknown (the trunk's own smooth trend then
    /// tells occluders apart, see [`sections`]).
    pub side_occluders: [Option<sections::SideOccluder>; sections::MAX_SIDE_OCCLUDERS],
    /// The stature was lifted from the front view alone onto the plane z = this (no
    /// side view, no typed stature): a fit without the side view moves it to the head's
    /// depth ([`one_view`]). None: typed, or seen by both views.
    pub stature_plane_z: Option<f64>,
}

impl Observation {
    /// An observation of a subject of `stature_m` whose hips are about `torso_point`,
    /// with nothing else known.
    pub fn new(stature_m: f64, torso_point: DVec3) -> Observation {
        Observation {
            stature_m,
            torso_point,
            arm_angles: None,
            leg_angles: None,
            side_occluders: [None; sections::MAX_SIDE_OCCLUDERS],
            stature_plane_z: None,
        }
    }
}

/// Errors of the fit.
#[derive(Debug, thiserror::Error)]
pub enum FitError {
    #[error("the silhouettes do not show a torso where the subject should stand")]
    NoTorso,
    #[error("too few silhouette correspondences ({found} of {total}): is the subject fully in view of both cameras?")]
    TooFewTargets { found: usize, total: usize },
    #[error("deformation failed: {0}")]
    Deform(String),
    #[error("body model: {0}")]
    Body(String),
}

/// Statistics of one fit.
#[derive(Debug, Clone, Default, serde::Serialize)]
pub struct FitStats {
    pub controls: usize,
    pub targets: TargetStats,
    pub decode_iterations: usize,
    /// Mean distance of the found targets from their vertices after the solve, mm.
    pub residual_mm: f64,
    pub warm: bool,
    pub params: Option<ShapeParams>,
    /// Standard deviation (mm) of a stature the front view alone gave (lifted from it and
    /// moved to the head's depth, [`one_view::stature_sd_mm`]); None when the side view
    /// or the operator gave it.
    pub stature_sd_mm: Option<f64>,
    /// The turn on the mark the candidate was given at the subject's first fit
    /// ([`turn`]), degrees; None when the toes showed none.
    pub turn_deg: Option<f64>,
    /// Vertices of pockets between arm and trunk brought down after the solve
    /// ([`armpit`]).
    pub armpit_peaks: usize,
    /// The environment switches the fit ran with (`report.json` `fit.switches`).
    pub switches: Option<FitSwitches>,
}

/// The fit's environment switches ([`WAIST_PRIOR_ENV`], [`TURN_ENV`], [`RIM_DEPTH_ENV`],
/// [`CUP_ENV`]) as one fit used them, so that a report says how it was made.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
pub struct FitSwitches {
    pub waist_prior: bool,
    pub turn_from_toes: bool,
    pub rim_depth: bool,
    pub refine_cup: bool,
}

impl FitSwitches {
    /// The switches of `opts`.
    pub fn of(opts: &FitOptions) -> FitSwitches {
        FitSwitches {
            waist_prior: opts.waist_prior,
            turn_from_toes: opts.turn_from_toes,
            rim_depth: opts.rim_depth,
            refine_cup: opts.refine_cup,
        }
    }

    /// The settings that differ from the station's own behaviour (an empty environment),
    /// as `VARIABLE=value`.
    pub fn changed(&self) -> Vec<String> {
        [
            (!self.waist_prior, WAIST_PRIOR_ENV, "off"),
            (!self.turn_from_toes, TURN_ENV, "off"),
            (!self.rim_depth, RIM_DEPTH_ENV, "off"),
            (self.refine_cup, CUP_ENV, "on"),
        ]
        .iter()
        .filter(|(changed, _, _)| *changed)
        .map(|(_, var, value)| format!("{var}={value}"))
        .collect()
    }
}

/// Per-subject state kept between frames.
struct SubjectState {
    params: ShapeParams,
    controls: ControlSet,
    /// Dense section targets' plan, and its vertices that are not sparse controls.
    plan: Option<sections::SectionPlan>,
    dense: Vec<u32>,
    deformer: FitDeformer,
    rest: TriMesh,
    /// Vertices of the rigid parts (head, hands, feet), held at the candidate's positions.
    pinned: Vec<u32>,
    positions: Vec<DVec3>,
    /// The turn the candidate was given ([`turn`]) and a point of the vertical it was
    /// turned about.
    turn: Option<(turn::TurnEstimate, DVec3)>,
    /// With a turn: `rest` turned back to face the front camera (the sections are
    /// mapped in the body's own axes); empty without.
    rest_square: Vec<DVec3>,
}

/// How far beyond the candidate's bounding box (each side, metres) a fitted avatar may
/// reach before the solve is taken to have diverged: section scales stay within 1.25
/// and the arms' pose moves them by tens of centimetres at most.
const MAX_REACH_BEYOND_CANDIDATE_M: f64 = 0.3;

impl SubjectState {
    /// Why the current avatar is not a body (see [`diverged`]), or None.
    fn implausible(&self) -> Option<String> {
        diverged(&self.positions, &self.rest.positions)
    }
}

/// Why `avatar` is not a deformation of `candidate` (a non-finite vertex, or one far
/// outside the candidate's box: a solve that diverged), or None.
fn diverged(avatar: &[DVec3], candidate: &[DVec3]) -> Option<String> {
    let bounds = |ps: &[DVec3]| {
        ps.iter().fold(
            (DVec3::splat(f64::MAX), DVec3::splat(f64::MIN)),
            |(lo, hi), p| (lo.min(*p), hi.max(*p)),
        )
    };
    if avatar.iter().any(|p| !p.is_finite()) {
        return Some("the deformation diverged (a vertex is not finite)".into());
    }
    let (rlo, rhi) = bounds(candidate);
    let (lo, hi) = bounds(avatar);
    let m = DVec3::splat(MAX_REACH_BEYOND_CANDIDATE_M);
    if lo.cmplt(rlo - m).any() || hi.cmpgt(rhi + m).any() {
        let (a, c) = (hi - lo, rhi - rlo);
        return Some(format!(
            "the deformation diverged (the avatar spans {:.2} x {:.2} x {:.2} m, its \
             candidate {:.2} x {:.2} x {:.2} m)",
            a.x, a.y, a.z, c.x, c.y, c.z
        ));
    }
    None
}

/// The fitter: owns the library, its descriptors and the subject's state and scratch.
pub struct Fitter {
    library: Arc<ShapeLibrary>,
    opts: FitOptions,
    template_labels: Vec<Part>,
    /// The template's edges (for true cross-sections in the shape descriptor).
    edges: Vec<[u32; 2]>,
    pose_joints: pose::PoseJoints,
    rigid: Vec<Vec<u32>>,
    /// The template's left and right foot vertices (the turn on the mark, [`turn`]).
    feet: [Vec<u32>; 2],
    library_params: Vec<ShapeParams>,
    library_descriptors: Vec<shape::ShapeDescriptor>,
    subject: Option<SubjectState>,
    centroids: Vec<DVec3>,
    targets: Vec<Option<DVec3>>,
    /// `targets` turned back with a turned candidate (see [`SubjectState::rest_square`]).
    targets_square: Vec<Option<DVec3>>,
    target_buf: Vec<DVec3>,
    section_scratch: sections::SectionScratch,
    /// The side view's limb capsules of the current call (see [`Observation`]).
    side_occluders: [Option<sections::SideOccluder>; sections::MAX_SIDE_OCCLUDERS],
    vertex_targets: Vec<Option<DVec3>>,
    /// The avatar before a warm refit (restored when the refit diverges).
    backup: Vec<DVec3>,
    /// Tests: the next decode fails as diverged, its positions left not finite.
    #[cfg(test)]
    fail_next_decode: bool,
    /// Rasterised silhouette of the candidate (first fit only).
    raster: Vec<u8>,
    /// The library bodies' mean depths relative to their toes (a fit without the side
    /// view places the trunk by them, [`one_view`]).
    depth_offsets: Option<one_view::DepthOffsets>,
    /// Pockets the skinning leaves where the arms meet the trunk, taken out of every
    /// avatar ([`armpit`]).
    armpit_peaks: armpit::ArmpitPeaks,
}

impl Fitter {
    /// Prepares the fitter: part labels of the template and the library's descriptors.
    pub fn new(library: Arc<ShapeLibrary>, opts: FitOptions) -> Result<Self, FitError> {
        let template = library.template();
        let rings = template.mesh.one_rings();
        let lm = pose::template_part_landmarks(template).map_err(FitError::Body)?;
        let template_labels = parts::label_parts(&template.mesh, &rings, &lm);
        let armpit_peaks = armpit::ArmpitPeaks::new(
            &template.mesh.positions,
            rings,
            [lm.left_armpit, lm.right_armpit],
        );
        let mut library_params = Vec::with_capacity(opts.library_size);
        let mut library_descriptors = Vec::with_capacity(opts.library_size);
        let mut buf = Vec::new();
        let edges = shape::unique_edges(&template.mesh.triangles);
        let mut offsets = Vec::with_capacity(opts.library_size);
        for seed in 0..opts.library_size as u64 {
            let p = ShapeLibrary::sample_adult(seed);
            library.body_into(&p, &mut buf);
            library_descriptors.push(shape::mesh_descriptor(&buf, &edges, &template_labels));
            library_params.push(p);
            let stature = buf.iter().map(|p| p.y).fold(f64::MIN, f64::max);
            offsets.extend(
                shape::torso_centre(&buf, &edges, &template_labels, PLACEMENT_LEVEL * stature)
                    .and_then(|c| one_view::DepthOffsets::of_body(&buf, c)),
            );
        }
        let depth_offsets = one_view::DepthOffsets::mean(&offsets);
        let pose_joints = pose::PoseJoints::new(template);
        let rigid = pose::rigid_groups(template);
        let n = template.mesh.vertex_count() as u32;
        let feet = [
            &template.info.rigid.foot_left,
            &template.info.rigid.foot_right,
        ]
        .map(|g| g.iter().copied().filter(|&i| i < n).collect());
        Ok(Fitter {
            feet,
            edges,
            pose_joints,
            rigid,
            library,
            opts,
            template_labels,
            library_params,
            library_descriptors,
            subject: None,
            centroids: Vec::new(),
            targets: Vec::new(),
            targets_square: Vec::new(),
            target_buf: Vec::new(),
            section_scratch: Default::default(),
            side_occluders: [None; sections::MAX_SIDE_OCCLUDERS],
            vertex_targets: Vec::new(),
            backup: Vec::new(),
            #[cfg(test)]
            fail_next_decode: false,
            raster: Vec::new(),
            depth_offsets,
            armpit_peaks,
        })
    }

    pub fn options(&self) -> &FitOptions {
        &self.opts
    }

    /// Forgets the subject (next call fits from nothing).
    pub fn reset(&mut self) {
        self.subject = None;
    }

    pub fn has_subject(&self) -> bool {
        self.subject.is_some()
    }

    /// Triangles of the template (and so of every avatar).
    pub fn template_triangles(&self) -> &[[u32; 3]] {
        &self.library.template().mesh.triangles
    }

    /// The template's part labels (#V).
    pub fn labels(&self) -> &[Part] {
        &self.template_labels
    }

    /// Fits (first frame) or refits (later frames) to the two silhouettes. Returns the
    /// avatar's vertex positions (template order, station frame).
    pub fn fit(
        &mut self,
        calib: &StationCalibration,
        front: MaskRef<'_>,
        side: MaskRef<'_>,
        obs: &Observation,
    ) -> Result<(&[DVec3], FitStats), FitError> {
        self.fit_views(calib, front, Some(side), obs)
    }

    /// [`Fitter::fit`] with the side view optional. Without it (the side camera lost, or
    /// a front photo alone) the fit goes by the front view and the stature: the library
    /// body is chosen and refined on the front widths alone, so its depths are the shape
    /// library's for a body of those widths and that stature (the library's prior of
    /// what is not seen), and the side view's controls hold the candidate's positions (no
    /// target: the section maps leave z as the candidate's). A warm refit without the
    /// side view keeps the depths of the last frames that saw it.
    pub fn fit_views(
        &mut self,
        calib: &StationCalibration,
        front: MaskRef<'_>,
        side: Option<MaskRef<'_>>,
        obs: &Observation,
    ) -> Result<(&[DVec3], FitStats), FitError> {
        // An empty side mask: every side-view search starts outside it and finds nothing.
        let unseen = MaskRef {
            width: 0,
            height: 0,
            data: &[],
        };
        let views = [(&calib.front, front), (&calib.side, side.unwrap_or(unseen))];
        let placed;
        let mut stature_sd_mm = None;
        let obs = match side {
            Some(_) => obs,
            None => {
                let (o, sd) = self.place_in_depth(calib, front, obs);
                placed = o;
                stature_sd_mm = sd;
                &placed
            }
        };
        self.side_occluders = obs.side_occluders;
        let warm = self.subject.is_some();
        let mut stats = FitStats {
            warm,
            stature_sd_mm,
            ..Default::default()
        };
        if !warm {
            let passes = self.opts.candidate_passes.max(1);
            for pass in 0..passes {
                // After the first pass the candidate is chosen again against the fitted
                // avatar's sections, which (unlike the raw silhouettes) have the arms and
                // the other leg told apart, and that candidate is fitted from scratch.
                // Intermediate passes only need the sections, not convergence.
                let last = pass + 1 == passes;
                let rounds = if last {
                    self.opts.first_fit_rounds
                } else {
                    self.opts.first_fit_rounds.min(INTERMEDIATE_ROUNDS)
                };
                let t0 = std::time::Instant::now();
                let fitted = if pass > 0 {
                    let Some(d) = self.avatar_descriptor() else {
                        break;
                    };
                    stats = FitStats {
                        warm,
                        stature_sd_mm,
                        ..Default::default()
                    };
                    Some(d)
                } else {
                    None
                };
                let fitted = match (fitted, side) {
                    // The fitted avatar's depths are the candidate's when no view saw
                    // them: the next choice goes by what was seen.
                    (Some(mut d), None) => {
                        d.torso_depth.iter_mut().for_each(|x| *x = f64::NAN);
                        Some(d)
                    }
                    (d, _) => d,
                };
                self.first_fit(calib, front, side, obs, fitted.as_ref())?;
                let t1 = std::time::Instant::now();
                if let Err(e) = self.rounds(views, false, rounds, &mut stats) {
                    // A diverged decode leaves no body to refit: the next frame chooses
                    // one afresh.
                    self.subject = None;
                    return Err(e);
                }
                if debug_enabled() {
                    eprintln!(
                        "pass {pass}: setup {:.1} ms, rounds {:.1} ms",
                        (t1 - t0).as_secs_f64() * 1e3,
                        t1.elapsed().as_secs_f64() * 1e3
                    );
                }
            }
            if let Some(why) = self.subject.as_ref().and_then(SubjectState::implausible) {
                // Nothing to go back to: the next frame chooses a body afresh.
                self.subject = None;
                return Err(FitError::Deform(why));
            }
        } else {
            if let Some(s) = &self.subject {
                self.backup.clone_from(&s.positions);
            }
            let refit = self.rounds(views, true, 1, &mut stats);
            if let Err(e) = refit {
                // A diverged decode leaves its positions non-finite or kilometres away:
                // the last good avatar stays (on screen, and as the next frame's start).
                if let Some(s) = self.subject.as_mut() {
                    s.positions.clone_from(&self.backup);
                }
                return Err(e);
            }
            if let Some(s) = self.subject.as_mut() {
                if let Some(why) = s.implausible() {
                    // Keep the last good avatar on screen and in the measurements.
                    s.positions.clone_from(&self.backup);
                    return Err(FitError::Deform(why));
                }
            }
        }
        let Some(s) = self.subject.as_mut() else {
            return Err(FitError::NoTorso);
        };
        stats.armpit_peaks = self.armpit_peaks.flatten(&mut s.positions);
        // Residual after the solve.
        let mut sum = 0.0;
        let mut n = 0usize;
        for (c, t) in s.controls.controls.iter().zip(&self.targets) {
            if let Some(t) = t {
                sum += (s.positions[c.vertex as usize] - *t).length();
                n += 1;
            }
        }
        stats.residual_mm = if n > 0 { 1e3 * sum / n as f64 } else { 0.0 };
        stats.controls = s.controls.controls.len();
        stats.params = Some(s.params.clone());
        stats.switches = Some(FitSwitches::of(&self.opts));
        stats.turn_deg = s.turn.map(|(t, _)| t.yaw.to_degrees());
        Ok((&s.positions, stats))
    }

    /// Without the side view: the trunk placed in depth behind the toes the front view
    /// sees on the floor, by the library's mean proportions, and a stature lifted from
    /// the front view moved to the head's depth ([`one_view`]). The observation as it
    /// was when the feet are not seen. With it, the standard deviation (mm) of a stature
    /// lifted from the front view.
    fn place_in_depth(
        &self,
        calib: &StationCalibration,
        front: MaskRef<'_>,
        obs: &Observation,
    ) -> (Observation, Option<f64>) {
        let (Some(toes), Some(d)) = (
            one_view::toes_on_floor(&calib.front, front),
            self.depth_offsets,
        ) else {
            return (*obs, None);
        };
        let mut o = *obs;
        let (toes_z, believed) = d.believed_toes_z(toes.z, obs.stature_m);
        let mut stature_sd_mm = None;
        if let Some(plane_z) = obs.stature_plane_z {
            // The head's depth depends on the stature only through the offset: one step.
            let head_z = toes_z + d.head_top_rel * obs.stature_m;
            o.stature_m = one_view::height_at_depth(&calib.front, obs.stature_m, plane_z, head_z);
            o.stature_plane_z = None;
            // Toes not believed stand anywhere within the mark's tolerance (uniform).
            let toes_sd_m = if believed {
                one_view::floor_metres_per_row(&calib.front, toes)
                    .map_or(one_view::MARK_TOLERANCE_M, |m| one_view::TOE_ROW_SD_PX * m)
            } else {
                one_view::MARK_TOLERANCE_M / 3f64.sqrt()
            };
            let head = DVec3::new(toes.x, o.stature_m, head_z);
            stature_sd_mm = Some(one_view::stature_sd_mm(
                &calib.front,
                head,
                toes_sd_m,
                d.head_top_sd_rel * o.stature_m,
            ));
        }
        o.torso_point.z = toes_z + d.trunk_rel * o.stature_m;
        if debug_enabled() {
            eprintln!(
                "one view: toes {toes:?} (believed: {believed}), trunk z {:.4}, stature {:.4} -> {:.4}",
                o.torso_point.z, obs.stature_m, o.stature_m
            );
        }
        (o, stature_sd_mm)
    }

    /// Correspondence and decoding rounds on the current subject state.
    fn rounds(
        &mut self,
        views: [(&crate::camera::Camera, MaskRef<'_>); 2],
        warm: bool,
        rounds: usize,
        stats: &mut FitStats,
    ) -> Result<(), FitError> {
        let Some(s) = self.subject.as_mut() else {
            return Err(FitError::NoTorso);
        };
        for _ in 0..rounds {
            let ts = correspond::find_targets(
                &s.positions,
                &s.controls,
                views,
                &self.opts.search,
                self.side_occluders.iter().any(Option::is_some),
                &mut self.centroids,
                &mut self.targets,
            );
            stats.targets = ts;
            // Out of the controls a view could give a target: a side view that is not
            // there (the front camera alone) has none to give.
            let side_seen = !views[1].1.data.is_empty();
            let total = s
                .controls
                .controls
                .iter()
                .filter(|c| side_seen || c.status.view() == crate::camera::View::Front)
                .count();
            if ts.found * 4 < total {
                return Err(FitError::TooFewTargets {
                    found: ts.found,
                    total,
                });
            }
            // Controls without a target this frame hold their current position; the rigid
            // parts hold the candidate's.
            self.vertex_targets.clear();
            if let Some(plan) = &s.plan {
                // Mapped from the candidate itself, not from the last frame's avatar: each
                // frame's surface is a function of the candidate and this frame's targets
                // (no drift through a run of bad masks).
                match s.turn {
                    // A turned candidate's sections are mapped in its own axes: its
                    // targets turned back with it, the mapped targets turned forward.
                    Some((t, about)) => {
                        let back = turn::Turning::new(about, -t.yaw);
                        self.section_scratch.eyes = rim_depth_eyes(self.opts.rim_depth, views)
                            .map(|e| e.map(|p| back.apply(p)));
                        self.targets_square.clear();
                        self.targets_square
                            .extend(self.targets.iter().map(|p| p.map(|p| back.apply(p))));
                        plan.targets(
                            &s.rest_square,
                            &s.controls,
                            &self.targets_square,
                            &self.side_occluders,
                            &mut self.section_scratch,
                            &mut self.vertex_targets,
                        );
                        let forward = turn::Turning::new(about, t.yaw);
                        for p in self.vertex_targets.iter_mut().flatten() {
                            *p = forward.apply(*p);
                        }
                    }
                    None => {
                        self.section_scratch.eyes = rim_depth_eyes(self.opts.rim_depth, views);
                        plan.targets(
                            &s.rest.positions,
                            &s.controls,
                            &self.targets,
                            &self.side_occluders,
                            &mut self.section_scratch,
                            &mut self.vertex_targets,
                        )
                    }
                }
            }
            let dense_at = |v: u32| self.vertex_targets.get(v as usize).copied().flatten();
            self.target_buf.clear();
            for (c, t) in s.controls.controls.iter().zip(&self.targets) {
                self.target_buf.push(
                    dense_at(c.vertex)
                        .or(*t)
                        .unwrap_or(s.positions[c.vertex as usize]),
                );
            }
            for &v in &s.dense {
                self.target_buf
                    .push(dense_at(v).unwrap_or(s.positions[v as usize]));
            }
            self.target_buf
                .extend(s.pinned.iter().map(|&v| s.rest.positions[v as usize]));
            #[cfg(test)]
            if std::mem::take(&mut self.fail_next_decode) {
                s.positions.iter_mut().for_each(|p| *p = DVec3::NAN);
                return Err(FitError::Deform("injected divergence".into()));
            }
            let solves = if warm { 1 } else { FIRST_FIT_SOLVES };
            for _ in 0..solves {
                let rep = s
                    .deformer
                    .solve(&self.target_buf, &mut s.positions)
                    .map_err(|e| FitError::Deform(e.to_string()))?;
                stats.decode_iterations += rep.iterations;
                if debug_enabled() {
                    eprintln!("decode: {rep:?}");
                }
                if rep.converged {
                    break;
                }
            }
        }
        Ok(())
    }

    /// Shape descriptor of the current avatar, in its own frame (soles at zero).
    fn avatar_descriptor(&self) -> Option<shape::ShapeDescriptor> {
        let s = self.subject.as_ref()?;
        let floor = s.positions.iter().map(|p| p.y).fold(f64::MAX, f64::min);
        let mut lifted: Vec<DVec3> = s.positions.iter().map(|p| *p - DVec3::Y * floor).collect();
        // The library's bodies face the front camera: the avatar is compared turned back.
        if let Some((t, about)) = s.turn {
            turn::turn(&mut lifted, about, -t.yaw);
        }
        Some(shape::mesh_descriptor(
            &lifted,
            &self.edges,
            &self.template_labels,
        ))
    }

    /// What the two views showed of `region` within `half_window_m` of height `y` at the
    /// last fit (see [`sections::SectionPlan::evidence_at`]); None without a subject or
    /// dense section targets.
    pub fn level_evidence(
        &self,
        region: sections::Region,
        y: f64,
        half_window_m: f64,
    ) -> Option<sections::LevelEvidence> {
        let plan = self.subject.as_ref()?.plan.as_ref()?;
        plan.evidence_at(&self.section_scratch, region, y, half_window_m)
    }

    /// The trunk's back edges the side view showed at the last fit, (height, z) in
    /// metres, bottom up; empty without dense section targets.
    pub fn seen_back_edges(&self) -> &[(f64, f64)] {
        &self.section_scratch.back_edges
    }

    /// Breadth and depth (x and z extents, metres) of the current avatar's trunk at each
    /// height of `ys`: its torso's (and legs') vertices only, not its arms, whatever
    /// touches them. All None without a subject.
    pub fn trunk_extents_at(&self, ys: &[f64]) -> Vec<Option<(f64, f64)>> {
        match self.subject.as_ref() {
            Some(s) => {
                shape::trunk_extents_at(&s.positions, &self.edges, &self.template_labels, ys)
            }
            None => vec![None; ys.len()],
        }
    }

    /// The current avatar as a mesh (template triangles).
    pub fn avatar(&self) -> Option<TriMesh> {
        let s = self.subject.as_ref()?;
        Some(TriMesh::new(
            s.positions.clone(),
            self.library.template().mesh.triangles.clone(),
        ))
    }
}

impl Fitter {
    /// Stretches `body` vertically (soles and crown fixed, piecewise linear about the
    /// crotch) so that the front camera sees its crotch where it sees the subject's: the
    /// top of the gap between the legs on the vertical line through the trunk's centre
    /// `axis`, found the same way on the silhouette and on the body's own rasterised
    /// silhouette (so the camera's perspective cancels).
    fn align_crotch(
        &mut self,
        body: &mut TriMesh,
        calib: &StationCalibration,
        front: MaskRef<'_>,
        axis: DVec3,
        stature: f64,
    ) {
        let (y_from, y_to) = (CROTCH_SEARCH.0 * stature, CROTCH_SEARCH.1 * stature);
        let cam = &calib.front;
        let Some(seen) = shape::gap_top_on_axis(cam, front, axis.x, axis.z, y_from, y_to) else {
            return;
        };
        // A gap top outside the range of human proportions is a mask that lost the legs'
        // inner edges (trousers of the backdrop's colour), not a crotch: keep the
        // candidate's own.
        let ratio = seen / stature.max(1e-6);
        if !(CROTCH_RATIO.0..=CROTCH_RATIO.1).contains(&ratio) {
            if debug_enabled() {
                eprintln!("crotch: seen {seen:.4} ({ratio:.3} of stature) ignored");
            }
            return;
        }
        for _ in 0..CROTCH_ROUNDS {
            shape::rasterize_band(
                &body.positions,
                &body.triangles,
                cam,
                front.width,
                front.height,
                (y_from - CROTCH_BAND_MARGIN_M, y_to + CROTCH_BAND_MARGIN_M),
                &mut self.raster,
            );
            let own_mask = MaskRef {
                width: front.width,
                height: front.height,
                data: &self.raster,
            };
            let Some(own) = shape::gap_top_on_axis(cam, own_mask, axis.x, axis.z, y_from, y_to)
            else {
                return;
            };
            let d = seen - own;
            if d.abs() > MAX_CROTCH_SHIFT_M || d.abs() < 1e-4 {
                return;
            }
            if debug_enabled() {
                eprintln!("crotch: seen {seen:.4} own {own:.4}");
            }
            let low = (own + d) / own;
            let high = (stature - own - d) / (stature - own);
            body.map_positions(|p| {
                let y = if p.y <= own {
                    p.y * low
                } else {
                    own + d + (p.y - own) * high
                };
                DVec3::new(p.x, y, p.z)
            });
        }
    }
}

/// Heights (fractions of stature) between which the crotch is looked for.
const CROTCH_SEARCH: (f64, f64) = (0.30, 0.60);
/// Rounds of the crotch alignment (rasterise, compare, stretch).
const CROTCH_ROUNDS: usize = 2;
/// Margin around the search band within which triangles are rasterised, metres.
const CROTCH_BAND_MARGIN_M: f64 = 0.05;
/// Largest crotch correction believed, metres (more: the observation is wrong).
const MAX_CROTCH_SHIFT_M: f64 = 0.08;
/// Plausible crotch height as a fraction of stature: adults measure about 0.47 (ANSUR II
/// crotch height over stature, both sexes), a few standard deviations of about 0.013
/// either way.
const CROTCH_RATIO: (f64, f64) = (0.42, 0.52);

/// [`shape_refine`]'s indices of the macro parameters but the cup size.
pub(crate) const MACRO_PARAMS: [usize; 6] = [0, 1, 2, 3, 4, 5];
/// [`shape_refine`]'s indices of every macro parameter, the cup size last.
pub(crate) const ALL_PARAMS: [usize; 7] = [0, 1, 2, 3, 4, 5, 6];

/// Gauss-Newton with a finite-difference Jacobian on the shape descriptor over the macro
/// parameters (gender, muscle, weight, height, proportions, age, cup size); they stay in
/// range.
fn shape_refine(
    library: &ShapeLibrary,
    edges: &[[u32; 2]],
    labels: &[Part],
    start: ShapeParams,
    observed: &shape::ShapeDescriptor,
    iterations: usize,
    free: &[usize],
) -> (ShapeParams, f64) {
    const STEP: f64 = 0.02;
    const DAMPING: f64 = 1e-4;
    const MIN_DAMPING: f64 = 1e-6;
    const LM_TRIES: usize = 4;
    let debug = debug_enabled();
    let obs = observed.as_vec();
    let mut buf = Vec::new();
    let residual = |p: &ShapeParams, buf: &mut Vec<DVec3>| -> Vec<f64> {
        library.body_into(p, buf);
        let d = shape::mesh_descriptor(buf, edges, labels).as_vec();
        d.iter()
            .zip(&obs)
            .map(|(a, b)| {
                if a.is_finite() && b.is_finite() {
                    a - b
                } else {
                    0.0
                }
            })
            .collect()
    };
    // Age enters normalised to 0..1 over the library's adult range.
    let age_span = AGE_MAX_YEARS - AGE_MIN_YEARS;
    let get = |p: &ShapeParams, j: usize| {
        [
            p.gender,
            p.muscle,
            p.weight,
            p.height,
            p.proportions,
            (p.age_years - AGE_MIN_YEARS) / age_span,
            p.cup,
        ][j]
    };
    let set = |p: &mut ShapeParams, j: usize, v: f64| match j {
        0 => p.gender = v.clamp(0.0, 1.0),
        1 => p.muscle = v.clamp(0.0, 1.0),
        2 => p.weight = v.clamp(0.0, 1.0),
        3 => p.height = v.clamp(0.0, 1.0),
        4 => p.proportions = v.clamp(0.0, 1.0),
        6 => p.cup = v.clamp(0.0, 1.0),
        _ => p.age_years = AGE_MIN_YEARS + v.clamp(0.0, 1.0) * age_span,
    };
    const NP: usize = 7;
    let mut p = start;
    let mut r = residual(&p, &mut buf);
    let cost = |r: &[f64]| r.iter().map(|x| x * x).sum::<f64>();
    // Levenberg-Marquardt damping, carried from one iteration to the next: lowered after
    // a step that lowers the cost, raised until one does.
    let mut damping = DAMPING;
    for _ in 0..iterations {
        let mut jac = vec![[0.0f64; NP]; r.len()];
        for &j in free.iter().filter(|&&j| j < NP) {
            let mut q = p.clone();
            let h = if get(&p, j) + STEP > 1.0 { -STEP } else { STEP };
            set(&mut q, j, get(&p, j) + h);
            let rq = residual(&q, &mut buf);
            for (i, row) in jac.iter_mut().enumerate() {
                row[j] = (rq[i] - r[i]) / h;
            }
        }
        // Normal equations (NP x NP), solved by Gaussian elimination with damping.
        let mut a = [[0.0f64; NP]; NP];
        let mut g = [0.0f64; NP];
        for (row, ri) in jac.iter().zip(&r) {
            for i in 0..NP {
                g[i] += row[i] * ri;
                for k in 0..NP {
                    a[i][k] += row[i] * row[k];
                }
            }
        }
        // Levenberg-Marquardt: raise the damping until the step lowers the cost.
        let trace = (0..NP).map(|i| a[i][i]).sum::<f64>().max(1e-12);
        let mut improved = false;
        for _ in 0..LM_TRIES {
            let mut ad = a;
            for (i, row) in ad.iter_mut().enumerate() {
                row[i] += damping * trace;
            }
            let Some(delta) = solve_small(ad, g.map(|x| -x)) else {
                break;
            };
            let mut q = p.clone();
            for (j, d) in delta.iter().enumerate() {
                set(&mut q, j, get(&p, j) + d.clamp(-0.3, 0.3));
            }
            let rq = residual(&q, &mut buf);
            if debug {
                eprintln!(
                    "shape refine: cost {:.3e} -> {:.3e} (damping {damping:.0e})",
                    cost(&r),
                    cost(&rq)
                );
            }
            if cost(&rq) < cost(&r) {
                p = q;
                r = rq;
                improved = true;
                damping = (damping * 0.1).max(MIN_DAMPING);
                break;
            }
            damping *= 10.0;
        }
        if !improved {
            break;
        }
    }
    if debug {
        let st = observed.stature_m;
        eprintln!(
            "shape residual mm: {:?}",
            r.iter().map(|x| (x * st * 1e3).round()).collect::<Vec<_>>()
        );
    }
    let c = cost(&r);
    (p, c)
}

/// Solves a small dense system by Gaussian elimination with partial pivoting.
// Index arithmetic over several arrays reads better with indices.
#[allow(clippy::needless_range_loop)]
pub(crate) fn solve_small<const N: usize>(
    mut a: [[f64; N]; N],
    mut b: [f64; N],
) -> Option<[f64; N]> {
    for c in 0..N {
        let piv = (c..N).max_by(|&i, &j| a[i][c].abs().total_cmp(&a[j][c].abs()))?;
        if a[piv][c].abs() < 1e-15 {
            return None;
        }
        a.swap(c, piv);
        b.swap(c, piv);
        for r in c + 1..N {
            let f = a[r][c] / a[c][c];
            for k in c..N {
                a[r][k] -= f * a[c][k];
            }
            b[r] -= f * b[c];
        }
    }
    let mut x = [0.0; N];
    for r in (0..N).rev() {
        let s: f64 = (r + 1..N).map(|k| a[r][k] * x[k]).sum();
        x[r] = (b[r] - s) / a[r][r];
    }
    Some(x)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A diverged solve is told from a deformed body: the candidate moved and scaled
    /// within its box passes, a vertex thrown far off or not finite does not.
    #[test]
    fn a_diverged_avatar_is_told_from_a_deformed_one() {
        let candidate: Vec<DVec3> = (0..200)
            .map(|i| {
                let t = i as f64 / 199.0;
                DVec3::new(0.2 * (7.0 * t).sin(), 1.75 * t, 0.12 * (5.0 * t).cos())
            })
            .collect();
        let deformed: Vec<DVec3> = candidate
            .iter()
            .map(|p| DVec3::new(1.2 * p.x + 0.05, p.y * 1.05, 1.2 * p.z - 0.03))
            .collect();
        assert_eq!(diverged(&deformed, &candidate), None);
        let mut thrown = deformed.clone();
        thrown[17].y = 4.0e13;
        let why = diverged(&thrown, &candidate).expect("a vertex 4e13 m up");
        assert!(why.contains("diverged"), "{why}");
        let mut wide = deformed.clone();
        wide[3].x -= 0.8;
        assert!(diverged(&wide, &candidate).is_some());
        let mut nan = deformed;
        nan[5].z = f64::NAN;
        assert!(diverged(&nan, &candidate).is_some());
    }

    /// A refit whose decode diverges keeps the last good avatar (the next frame starts
    /// from it and fits again); a first fit that diverges leaves no body, and the next
    /// frame chooses one afresh.
    #[test]
    fn a_diverged_decode_keeps_the_last_good_avatar() {
        let dir = std::env::temp_dir().join(format!("fitstation-diverge-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        let rec = dir.join("rec");
        let mut cfg = crate::synth::SynthConfig::from_seed(7);
        cfg.empty_frames = 10;
        cfg.subject_frames = 1;
        cfg.format = crate::recording::FrameFormat::Png;
        crate::synth::render_recording(&cfg, &rec).expect("render");
        let truth = crate::synth::load_truth(&crate::synth::truth_dir(&rec)).expect("truth");
        let calib = StationCalibration::load(&rec.join("station.yaml")).expect("calibration");
        let mask = |view: &str| {
            let p = crate::synth::truth_dir(&rec).join(format!("masks/{view}/000010.png"));
            let img = image::open(p).expect("mask").to_luma8();
            (img.width(), img.height(), img.into_raw())
        };
        let (f, s) = (mask("front"), mask("side"));
        let views = || {
            (
                MaskRef {
                    width: f.0,
                    height: f.1,
                    data: &f.2,
                },
                MaskRef {
                    width: s.0,
                    height: s.1,
                    data: &s.2,
                },
            )
        };
        let crotch = DVec3::from_array(truth.landmarks["crotch"]);
        let obs = Observation::new(
            truth.measurements_mm["stature"] / 1000.0,
            crotch + DVec3::new(0.0, 0.08, 0.0),
        );
        let library = Arc::new(ShapeLibrary::load_default().expect("the bundled shape library"));
        let mut fitter = Fitter::new(library, FitOptions::default()).expect("fitter");
        let (front, side) = views();
        let good = fitter
            .fit(&calib, front, side, &obs)
            .expect("first fit")
            .0
            .to_vec();
        fitter.fail_next_decode = true;
        let (front, side) = views();
        assert!(fitter.fit(&calib, front, side, &obs).is_err());
        let kept = &fitter
            .subject
            .as_ref()
            .expect("the subject is kept")
            .positions;
        assert_eq!(kept, &good, "the last good avatar is restored");
        let (front, side) = views();
        let next = fitter
            .fit(&calib, front, side, &obs)
            .expect("the next refit")
            .0;
        assert!(next.iter().all(|p| p.is_finite()));
        // A first fit that diverges: no body is left to refit from.
        fitter.reset();
        fitter.fail_next_decode = true;
        let (front, side) = views();
        assert!(fitter.fit(&calib, front, side, &obs).is_err());
        assert!(fitter.subject.is_none());
        let (front, side) = views();
        assert!(
            fitter.fit(&calib, front, side, &obs).is_ok(),
            "chosen afresh"
        );
        std::fs::remove_dir_all(&dir).ok();
    }

    /// The bundled library with the template's part labels and edges (what
    /// [`shape_refine`] needs besides a start and a descriptor).
    fn descriptor_setup() -> (&'static ShapeLibrary, Vec<Part>, Vec<[u32; 2]>) {
        let library = ShapeLibrary::shared().expect("the bundled shape library");
        let template = library.template();
        let rings = template.mesh.one_rings();
        let lm = pose::template_part_landmarks(template).expect("template landmarks");
        let labels = parts::label_parts(&template.mesh, &rings, &lm);
        let edges = shape::unique_edges(&template.mesh.triangles);
        (library, labels, edges)
    }

    /// The macro-parameter refinement recovers a library body from its own descriptor,
    /// starting from the average adult: the descriptor's residual ends under a millimetre
    /// (the damping carried between iterations lets it cross the narrow valleys of the
    /// cost within the default iteration count).
    #[test]
    fn shape_refinement_recovers_a_body_from_its_descriptor() {
        let (library, labels, edges) = descriptor_setup();
        let truth = ShapeParams {
            gender: 0.8,
            age_years: 45.0,
            muscle: 0.4,
            weight: 0.7,
            height: 0.35,
            proportions: 0.6,
            cup: 0.7,
        };
        let observed = shape::mesh_descriptor(&library.body(&truth).positions, &edges, &labels);
        let start = ShapeParams::default();
        let (_, start_cost) = shape_refine(
            library,
            &edges,
            &labels,
            start.clone(),
            &observed,
            0,
            &ALL_PARAMS,
        );
        let (fitted, cost) = shape_refine(
            library,
            &edges,
            &labels,
            start,
            &observed,
            FitOptions::default().shape_iterations,
            &ALL_PARAMS,
        );
        let n = observed.as_vec().len() as f64;
        let rms_mm = (cost / n).sqrt() * observed.stature_m * 1e3;
        assert!(
            cost < 0.01 * start_cost,
            "cost {start_cost:.3e} -> {cost:.3e}"
        );
        assert!(
            rms_mm < 1.0,
            "rms residual {rms_mm:.2} mm, fitted {fitted:?}"
        );
    }

    #[test]
    fn the_cup_size_is_free_only_when_asked() {
        let (library, labels, edges) = descriptor_setup();
        let truth = ShapeParams {
            gender: 0.05,
            age_years: 35.0,
            weight: 0.6,
            cup: 0.9,
            ..Default::default()
        };
        let observed = shape::mesh_descriptor(&library.body(&truth).positions, &edges, &labels);
        // Started where the library search would leave it: the macro parameters about
        // right, the cup size the library's average.
        let start = ShapeParams {
            gender: 0.1,
            age_years: 30.0,
            weight: 0.55,
            cup: 0.5,
            ..Default::default()
        };
        let cost_of = |p: &ShapeParams| {
            shape_refine(
                library,
                &edges,
                &labels,
                p.clone(),
                &observed,
                0,
                &ALL_PARAMS,
            )
            .1
        };
        // The descriptor sees the cup: the start with the truth's cup is far closer.
        let cup_alone = ShapeParams {
            cup: truth.cup,
            ..start.clone()
        };
        assert!(cost_of(&cup_alone) < 0.2 * cost_of(&start));
        let it = FitOptions::default().shape_iterations;
        let refine = |free: &[usize]| {
            shape_refine(library, &edges, &labels, start.clone(), &observed, it, free)
        };
        let (with_cup, cost_with) = refine(&ALL_PARAMS);
        let (without, cost_without) = refine(&MACRO_PARAMS);
        assert_eq!(without.cup, 0.5, "the cup size moved though not free");
        assert_ne!(with_cup.cup, 0.5, "the cup size did not move though free");
        // Not a recovery of the truth's cup: the joint refinement from this start ends in
        // another valley (muscle and weight up, the cup at 0; cost 1.18e-3 against
        // 1.23e-3 without the cup, 2.6e-3 at the start): the reason the fit does not free
        // the cup by default (FitOptions::refine_cup).
        assert!(
            cost_with < cost_without,
            "cost with the cup {cost_with:.3e}, without {cost_without:.3e}"
        );
    }

    #[test]
    fn a_fit_names_the_switches_it_ran_with() {
        let mut opts = FitOptions {
            waist_prior: true,
            turn_from_toes: true,
            rim_depth: true,
            refine_cup: false,
            ..FitOptions::default()
        };
        assert!(FitSwitches::of(&opts).changed().is_empty());
        opts.refine_cup = true;
        opts.rim_depth = false;
        assert_eq!(
            FitSwitches::of(&opts).changed(),
            ["FITSTATION_RIM_DEPTH=off", "FITSTATION_CUP=on"]
        );
    }

    #[test]
    fn small_solver() {
        let a = [[4.0, 1.0, 0.0], [1.0, 3.0, 1.0], [0.0, 1.0, 2.0]];
        let x = [1.0, -2.0, 3.0];
        let b = [
            a[0][0] * x[0] + a[0][1] * x[1],
            a[1][0] * x[0] + a[1][1] * x[1] + a[1][2] * x[2],
            a[2][1] * x[1] + a[2][2] * x[2],
        ];
        let s = solve_small(a, b).unwrap();
        for i in 0..3 {
            assert!((s[i] - x[i]).abs() < 1e-12);
        }
    }
}
