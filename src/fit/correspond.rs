//! Correspondence between template vertices and the two silhouettes (method.md section 3,
//! Zhong's "control vertices" with left/right/front/back status).
//!
//! Two variants, chosen by [`Variant`]:
//! - [`Variant::SliceExtremes`], the paper's: slice each body part every mean edge length
//!   L; in each slice the vertices of least/greatest x (status right/left, front view) and
//!   z (back/front, side view) become control vertices. The target moves the vertex along
//!   the station x (or z) axis onto the silhouette, as the paper's horizontal segment.
//! - [`Variant::PerspectiveRim`], for calibrated perspective cameras: in each slice the
//!   vertices of extreme bearing seen from each camera centre (the rim, where viewing rays
//!   graze the surface) become control vertices, and the target moves the vertex
//!   perpendicular to its viewing ray until it lies on the ray through the silhouette
//!   boundary.
//!
//! In both, the search runs from inside the part outward (the paper's status constraint):
//! from the point of the segment nearest the slice's part centroid, along the status
//! direction, to the first place where the silhouette is left. A vertex therefore can
//! only snap to the boundary on its own side of its own part (never to an arm's outer edge
//! from the torso, never to the far side of the body). Slices whose centroid falls outside
//! the silhouette give no target (part not aligned; said in the statistics).
//!
//! Conventions: station frame (metres, +Y up, +Z toward the front camera, +X the
//! subject's left); silhouettes are masks in each camera's distorted pixels, so points
//! are projected with the full lens model and no image is ever undistorted.

use crate::camera::{Camera, View};
use crate::mesh::TriMesh;
use glam::{DVec2, DVec3};

/// A body part label of a template vertex.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Part {
    Head,
    Torso,
    LeftArm,
    RightArm,
    LeftLeg,
    RightLeg,
}

impl Part {
    pub const ALL: [Part; 6] = [
        Part::Head,
        Part::Torso,
        Part::LeftArm,
        Part::RightArm,
        Part::LeftLeg,
        Part::RightLeg,
    ];
    pub fn is_arm(self) -> bool {
        matches!(self, Part::LeftArm | Part::RightArm)
    }
}

/// The side of its part a control vertex lies on (the paper's status).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Status {
    /// Greatest x: the subject's left side (front view).
    Left,
    /// Least x (front view).
    Right,
    /// Greatest z (side view).
    Front,
    /// Least z (side view).
    Back,
}

impl Status {
    pub fn view(self) -> View {
        match self {
            Status::Left | Status::Right => View::Front,
            Status::Front | Status::Back => View::Side,
        }
    }
    /// Outward station axis of this status (the paper's segment direction).
    pub fn axis(self) -> DVec3 {
        match self {
            Status::Left => DVec3::X,
            Status::Right => DVec3::NEG_X,
            Status::Front => DVec3::Z,
            Status::Back => DVec3::NEG_Z,
        }
    }
}

/// Which correspondence to build.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Variant {
    SliceExtremes,
    PerspectiveRim,
}

/// One control vertex: which vertex, on which side of which part, in which slice.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Control {
    pub vertex: u32,
    pub part: Part,
    pub status: Status,
    /// Index of the slice (band) the vertex was chosen in; centroids are per slice.
    pub slice: u32,
}

/// A read-only binary silhouette in one camera's distorted pixels.
#[derive(Debug, Clone, Copy)]
pub struct MaskRef<'a> {
    pub width: u32,
    pub height: u32,
    /// Row-major, 0 = background, 255 = person; values between are the share of the
    /// pixel's ramp across the outline (above 127: person).
    pub data: &'a [u8],
}

impl MaskRef<'_> {
    /// Bilinear occupancy in [0, 1] at a pixel position (0 outside the image).
    #[inline]
    pub fn occupancy(&self, p: DVec2) -> f64 {
        let (w, h) = (self.width as i64, self.height as i64);
        if !(p.x > -1.0 && p.y > -1.0 && p.x < w as f64 && p.y < h as f64) {
            return 0.0;
        }
        let x0 = crate::contour::fast_floor(p.x);
        let y0 = crate::contour::fast_floor(p.y);
        let (fx, fy) = (p.x - x0 as f64, p.y - y0 as f64);
        let at = |x: i64, y: i64| -> f64 {
            if x < 0 || y < 0 || x >= w || y >= h {
                0.0
            } else {
                // A 0/255 mask, or one whose outline's pixels carry a ramp through it
                // (`contour::soften_span_ends`): the occupancy crosses one half there.
                f64::from(self.data.get((y * w + x) as usize).copied().unwrap_or(0)) / 255.0
            }
        };
        let top = at(x0, y0) * (1.0 - fx) + at(x0 + 1, y0) * fx;
        let bot = at(x0, y0 + 1) * (1.0 - fx) + at(x0 + 1, y0 + 1) * fx;
        top * (1.0 - fy) + bot * fy
    }
}

/// Parameters of the correspondence search.
#[derive(Debug, Clone, Copy)]
pub struct SearchOptions {
    /// Furthest the search goes beyond the vertex's current position, metres.
    pub reach_m: f64,
    /// Sampling step along the projected segment, pixels.
    pub step_px: f64,
    /// Largest accepted move of a control vertex, metres.
    pub max_shift_m: f64,
    /// Largest accepted difference from the neighbouring controls' moves, metres.
    pub max_jump_m: f64,
}

impl Default for SearchOptions {
    fn default() -> Self {
        SearchOptions {
            reach_m: 0.12,
            step_px: 0.5,
            max_shift_m: 0.08,
            max_jump_m: 0.02,
        }
    }
}

/// The control vertices of a template and the slices they came from.
#[derive(Debug, Clone, Default)]
pub struct ControlSet {
    pub controls: Vec<Control>,
    /// Vertices of each slice (band of one part), to recompute centroids as the mesh moves.
    pub slice_members: Vec<Vec<u32>>,
    /// Per slice: vertices of each other part (arms, torso, legs; not the head) in the same
    /// height band, whose silhouettes can merge with the slice's part (see [`occluded`]).
    /// Each group with its part.
    pub slice_occluders: Vec<Vec<(Part, Vec<u32>)>>,
    /// Per leg slice: the other leg's vertices in the same band (in the side view the two
    /// legs overlap; only the one reaching further out owns the silhouette's edge).
    pub slice_rivals: Vec<Vec<u32>>,
    /// Part of each slice.
    pub slice_part: Vec<Part>,
    /// Height band of each slice (bands are shared by all parts: band k of the left leg
    /// and band k of the right leg lie at the same height).
    pub slice_band: Vec<u32>,
    pub variant: Option<Variant>,
}

/// Why a control got no target this frame.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize)]
pub struct TargetStats {
    pub found: usize,
    /// The part's centroid projects outside the silhouette.
    pub anchor_outside: usize,
    /// No boundary within reach.
    pub no_boundary: usize,
    /// Behind a camera or outside the image.
    pub not_visible: usize,
    /// Found, but moved too far, or unlike its neighbours along the same side of the part.
    pub rejected: usize,
    /// The edge may belong to another part in this view (arm over the torso, other leg).
    pub occluded: usize,
}

/// Chooses control vertices on `mesh` (the pose-synchronised candidate).
///
/// `labels` gives each vertex's part (#V). `slice_step_m` is the paper's L (the mean edge
/// length). Head vertices are never controls (the head is moved rigidly); arms are only
/// controlled in the front view (in the side view they overlap the torso).
pub fn select_controls(
    mesh: &TriMesh,
    labels: &[Part],
    excluded: &[bool],
    slice_step_m: f64,
    variant: Variant,
    front: &Camera,
    side: &Camera,
) -> ControlSet {
    let mut set = ControlSet {
        variant: Some(variant),
        ..Default::default()
    };
    let Some(bb) = mesh.bounds() else { return set };
    let step = slice_step_m.max(1e-3);
    let nslices = ((bb.size().y / step).ceil() as usize).max(1);
    let band_of = |p: DVec3| (((p.y - bb.min.y) / step).max(0.0) as usize).min(nslices - 1);
    // Every labelled vertex by part and band (rigid parts included: a hand can hide a hip).
    let mut all_bands: Vec<Vec<Vec<u32>>> = vec![vec![Vec::new(); nslices]; Part::ALL.len()];
    for (v, p) in mesh.positions.iter().enumerate() {
        if let Some(l) = labels.get(v) {
            if *l != Part::Head {
                all_bands[part_index(*l)][band_of(*p)].push(v as u32);
            }
        }
    }
    for part in Part::ALL {
        if part == Part::Head {
            continue;
        }
        let rival = match part {
            Part::LeftLeg => Some(Part::RightLeg),
            Part::RightLeg => Some(Part::LeftLeg),
            _ => None,
        };
        let mut bands: Vec<Vec<u32>> = vec![Vec::new(); nslices];
        for (v, p) in mesh.positions.iter().enumerate() {
            if labels.get(v) != Some(&part) || excluded.get(v).copied().unwrap_or(false) {
                continue;
            }
            bands[band_of(*p)].push(v as u32);
        }
        for (k, members) in bands.into_iter().enumerate() {
            if members.len() < 4 {
                continue;
            }
            let slice = set.slice_members.len() as u32;
            let mut occluders = Vec::new();
            for other in Part::ALL {
                let vs = &all_bands[part_index(other)][k];
                if other != part && other != Part::Head && Some(other) != rival && !vs.is_empty() {
                    occluders.push((other, vs.clone()));
                }
            }
            set.slice_occluders.push(occluders);
            set.slice_rivals.push(
                rival
                    .map(|r| all_bands[part_index(r)][k].clone())
                    .unwrap_or_default(),
            );
            let statuses: &[Status] = if part.is_arm() {
                &[Status::Left, Status::Right]
            } else {
                &[Status::Left, Status::Right, Status::Front, Status::Back]
            };
            for &status in statuses {
                let cam = match status.view() {
                    View::Front => front,
                    View::Side => side,
                };
                let key = |v: u32| extreme_key(variant, cam, status, mesh.positions[v as usize]);
                if let Some(&best) = members.iter().max_by(|a, b| key(**a).total_cmp(&key(**b))) {
                    if !set.controls.iter().any(|c| c.vertex == best) {
                        set.controls.push(Control {
                            vertex: best,
                            part,
                            status,
                            slice,
                        });
                    }
                }
            }
            set.slice_members.push(members);
            set.slice_part.push(part);
            set.slice_band.push(k as u32);
        }
    }
    set
}

/// How far `p` lies toward `status`'s side: along the station axis for the paper's
/// slice extremes, as the bearing seen from `cam` for the perspective rim (the vertex with
/// the largest key is the one the view's silhouette edge belongs to).
pub(crate) fn extreme_key(variant: Variant, cam: &Camera, status: Status, p: DVec3) -> f64 {
    match variant {
        Variant::SliceExtremes => p.dot(status.axis()),
        Variant::PerspectiveRim => bearing(cam, status, p).0,
    }
}

fn part_index(p: Part) -> usize {
    Part::ALL.iter().position(|q| *q == p).unwrap_or(0)
}

/// Bearing of `p` seen from `cam`, along the image axis that `status` points along (signed
/// so that larger is further toward the status side), in radians-ish (tangent) units, and
/// the depth of `p` in front of the camera.
#[inline]
fn bearing(cam: &Camera, status: Status, p: DVec3) -> (f64, f64) {
    let c = cam.camera_from_station.apply(p);
    let axis_cam = cam.camera_from_station.rotation * status.axis();
    let u = if c.z > 1e-6 { c.x / c.z } else { 0.0 };
    (u * axis_cam.x.signum(), c.z)
}

/// Whether the silhouette edge a control looks for may belong to another part (the paper
/// has the operator separate the arm in the side photo; a live station cannot).
///
/// Seen from the control's camera, in the control's band: another part whose extent comes
/// within [`OCCLUSION_MARGIN_M`] of the control's own extreme (it touches or crosses the
/// edge: an arm sticking out behind the back, a hand against the hip) hides the edge;
/// a part wholly inside or clearly beyond (with a gap) does not. For a leg in the side
/// view, the other leg hides the edge only when it reaches further out.
///
/// With `side_arms_seen` (the side view's arms located by the pose network, see
/// [`super::sections::SideOccluder`]) the avatar's arms hide no back edge of the trunk in
/// the side view: the edge is searched and the arms seen in the picture decide whether it
/// is theirs. The avatar's arm is only as good as the candidate's pose and depth: a trunk
/// fitted too shallow has its own arm over its back edge and never sees the back.
fn occluded(
    positions: &[DVec3],
    set: &ControlSet,
    c: &Control,
    cam: &Camera,
    side_arms_seen: bool,
) -> bool {
    let (u_c, depth) = bearing(cam, c.status, positions[c.vertex as usize]);
    let margin_m = match c.status.view() {
        View::Front => OCCLUSION_MARGIN_M,
        View::Side => SIDE_OCCLUSION_MARGIN_M,
    };
    let margin = margin_m / depth.max(0.1);
    let slice = c.slice as usize;
    let near = |vs: &[u32]| -> Option<(f64, f64)> {
        let (mut lo, mut hi) = (f64::MAX, f64::MIN);
        for &v in vs {
            let (u, _) = bearing(cam, c.status, positions[v as usize]);
            lo = lo.min(u);
            hi = hi.max(u);
        }
        (hi >= lo).then_some((lo, hi))
    };
    // The back only: in an A-pose the forearms and hands hang before the trunk's front,
    // where the avatar's arm still says which front edges may be theirs (the waist of
    // the demo flickered by 30 mm a frame without it); behind the back an arm is rare.
    let trunk_in_side = c.part == Part::Torso && c.status == Status::Back;
    for (part, group) in set
        .slice_occluders
        .get(slice)
        .map(|g| g.as_slice())
        .unwrap_or(&[])
    {
        if side_arms_seen && trunk_in_side && part.is_arm() {
            continue;
        }
        if let Some((lo, hi)) = near(group) {
            if lo <= u_c + margin && hi >= u_c - margin {
                return true;
            }
        }
    }
    if let Some((lo, hi)) = set.slice_rivals.get(slice).and_then(|o| near(o)) {
        let hidden = match c.status.view() {
            View::Side => hi > u_c,
            View::Front => lo <= u_c + margin && hi >= u_c - margin,
        };
        if hidden {
            return true;
        }
    }
    false
}

/// How close (metres, at the control's depth) another part's silhouette may come to a
/// control's edge before the edge is taken as hidden.
const OCCLUSION_MARGIN_M: f64 = 0.005;
/// The same in the side view, where the arms lie over the trunk and the legs over each
/// other: only a part reaching out to the edge hides it.
const SIDE_OCCLUSION_MARGIN_M: f64 = 0.003;

/// Finds the target of every control on the current `positions`.
///
/// Writes one entry per control into `targets` (None: no reliable target this frame).
/// `side_arms_seen`: the side view's arms are located (see [`occluded`]).
pub fn find_targets(
    positions: &[DVec3],
    set: &ControlSet,
    views: [(&Camera, MaskRef<'_>); 2],
    opts: &SearchOptions,
    side_arms_seen: bool,
    centroids: &mut Vec<DVec3>,
    targets: &mut Vec<Option<DVec3>>,
) -> TargetStats {
    centroids.clear();
    centroids.extend(
        set.slice_members.iter().map(|m| {
            m.iter().map(|&v| positions[v as usize]).sum::<DVec3>() / m.len().max(1) as f64
        }),
    );
    targets.clear();
    let mut stats = TargetStats::default();
    let variant = set.variant.unwrap_or(Variant::SliceExtremes);
    let debug = super::debug_enabled();
    let mut occ_per: std::collections::BTreeMap<String, usize> = Default::default();
    for c in &set.controls {
        let (cam, mask) = match c.status.view() {
            View::Front => views[0],
            View::Side => views[1],
        };
        if occluded(positions, set, c, cam, side_arms_seen) {
            stats.occluded += 1;
            if debug {
                *occ_per
                    .entry(format!("{:?}/{:?}", c.part, c.status))
                    .or_default() += 1;
            }
            targets.push(None);
            continue;
        }
        let p = positions[c.vertex as usize];
        let centroid = centroids[c.slice as usize];
        let dir = match variant {
            Variant::SliceExtremes => c.status.axis(),
            Variant::PerspectiveRim => {
                // Horizontal direction perpendicular to the viewing ray, toward the status side.
                let ray = p - cam.center_in_station();
                let perp = DVec3::new(-ray.z, 0.0, ray.x).normalize_or_zero();
                if perp.dot(c.status.axis()) >= 0.0 {
                    perp
                } else {
                    -perp
                }
            }
        };
        let origin = p + dir * (centroid - p).dot(dir);
        let t_vertex = (p - origin).dot(dir);
        let t_max = t_vertex.max(0.0) + opts.reach_m;
        let (t, outcome) = first_exit(cam, mask, origin, dir, t_max, opts.step_px);
        match outcome {
            Exit::Found => {
                stats.found += 1;
                targets.push(Some(origin + dir * t));
            }
            Exit::AnchorOutside => {
                stats.anchor_outside += 1;
                targets.push(None);
            }
            Exit::None => {
                stats.no_boundary += 1;
                targets.push(None);
            }
            Exit::NotVisible => {
                stats.not_visible += 1;
                targets.push(None);
            }
        }
    }
    stats.rejected = reject_outliers(positions, set, targets, opts);
    stats.found -= stats.rejected.min(stats.found);
    if super::debug_enabled() {
        let mut per: std::collections::BTreeMap<String, [usize; 2]> = Default::default();
        for (c, t) in set.controls.iter().zip(targets.iter()) {
            let e = per
                .entry(format!("{:?}/{:?}", c.part, c.status))
                .or_default();
            e[0] += 1;
            if t.is_some() {
                e[1] += 1;
            }
        }
        eprintln!("targets per part/status (total, found): {per:?}; occluded: {occ_per:?}");
    }
    stats
}

/// Drops targets that move their vertex more than `max_shift_m`, or whose displacement
/// differs from the median of the neighbouring slices' controls on the same side of the
/// same part by more than `max_jump_m` (a silhouette notch, an arm touching the torso).
/// Returns how many were dropped.
fn reject_outliers(
    positions: &[DVec3],
    set: &ControlSet,
    targets: &mut [Option<DVec3>],
    opts: &SearchOptions,
) -> usize {
    const HALF_WINDOW: usize = 2;
    let disp: Vec<Option<f64>> = set
        .controls
        .iter()
        .zip(targets.iter())
        .map(|(c, t)| {
            t.map(|t| {
                (t - positions[c.vertex as usize]).length()
                    * (t - positions[c.vertex as usize])
                        .dot(c.status.axis())
                        .signum()
            })
        })
        .collect();
    let mut dropped = 0;
    // Chains: controls of one (part, status), in slice order (they were pushed that way).
    let mut chains: std::collections::HashMap<(Part, Status), Vec<usize>> =
        std::collections::HashMap::new();
    for (i, c) in set.controls.iter().enumerate() {
        chains.entry((c.part, c.status)).or_default().push(i);
    }
    let mut window: Vec<f64> = Vec::new();
    for chain in chains.values() {
        for (k, &i) in chain.iter().enumerate() {
            let Some(d) = disp[i] else { continue };
            if d.abs() > opts.max_shift_m {
                targets[i] = None;
                dropped += 1;
                continue;
            }
            window.clear();
            let lo = k.saturating_sub(HALF_WINDOW);
            let hi = (k + HALF_WINDOW + 1).min(chain.len());
            window.extend(chain[lo..hi].iter().filter_map(|&j| disp[j]));
            if window.len() < 3 {
                continue;
            }
            window.sort_by(|a, b| a.total_cmp(b));
            let median = window[window.len() / 2];
            if (d - median).abs() > opts.max_jump_m {
                targets[i] = None;
                dropped += 1;
            }
        }
    }
    dropped
}

enum Exit {
    Found,
    AnchorOutside,
    None,
    NotVisible,
}

/// Marches from `origin` along `dir` (metres, station frame) up to `t_max`, and returns the
/// parameter where the silhouette is first left.
fn first_exit(
    cam: &Camera,
    mask: MaskRef<'_>,
    origin: DVec3,
    dir: DVec3,
    t_max: f64,
    step_px: f64,
) -> (f64, Exit) {
    let occ =
        |t: f64| -> Option<f64> { cam.project(origin + dir * t).map(|px| mask.occupancy(px)) };
    let Some(o0) = occ(0.0) else {
        return (0.0, Exit::NotVisible);
    };
    if o0 < 0.5 {
        return (0.0, Exit::AnchorOutside);
    }
    let (Some(a), Some(b)) = (cam.project(origin), cam.project(origin + dir * t_max)) else {
        return (0.0, Exit::NotVisible);
    };
    let len_px = (b - a).length();
    let n = ((len_px / step_px).ceil() as usize).clamp(2, 4000);
    let mut prev_t = 0.0;
    for i in 1..=n {
        let t = t_max * i as f64 / n as f64;
        // Linear in pixels between the projected ends: exact enough for a coarse march,
        // the bisection below uses the true projection.
        let px = a + (b - a) * (i as f64 / n as f64);
        if mask.occupancy(px) < 0.5 {
            let (mut lo, mut hi) = (prev_t, t);
            for _ in 0..12 {
                let mid = 0.5 * (lo + hi);
                match occ(mid) {
                    Some(o) if o >= 0.5 => lo = mid,
                    _ => hi = mid,
                }
            }
            return (0.5 * (lo + hi), Exit::Found);
        }
        prev_t = t;
    }
    (0.0, Exit::None)
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::camera::StationCalibration;
    use crate::mesh::shapes;

    /// A torso slice's back edge with the avatar's arm reaching over it in the side view:
    /// hidden while the arm is only the avatar's guess, searched once the side view's
    /// arms are located (they decide later whether the edge is theirs).
    #[test]
    fn the_avatars_arm_hides_the_trunks_side_edge_only_while_the_arms_are_unseen() {
        let calib = StationCalibration::nominal(720, 1280, 1100.0, 3.0, 1.1, 1.0);
        // Vertex 0: the trunk's back at chest height; 1-2: the avatar's arm at that
        // height, from inside the trunk to past its back.
        let positions = vec![
            DVec3::new(0.0, 1.2, -0.20),
            DVec3::new(0.18, 1.2, -0.05),
            DVec3::new(0.18, 1.2, -0.22),
        ];
        let set = ControlSet {
            controls: vec![Control {
                vertex: 0,
                part: Part::Torso,
                status: Status::Back,
                slice: 0,
            }],
            slice_members: vec![vec![0]],
            slice_occluders: vec![vec![(Part::LeftArm, vec![1, 2])]],
            slice_rivals: vec![Vec::new()],
            slice_part: vec![Part::Torso],
            slice_band: vec![0],
            ..ControlSet::default()
        };
        let c = &set.controls[0];
        assert!(occluded(&positions, &set, c, &calib.side, false));
        assert!(!occluded(&positions, &set, c, &calib.side, true));
        // A leg is no arm: it still hides the edge.
        let mut legs = set.clone();
        legs.slice_occluders = vec![vec![(Part::LeftLeg, vec![1, 2])]];
        assert!(occluded(&positions, &legs, c, &calib.side, true));
        // The front view's controls keep the avatar's arms as occluders.
        let front = Control {
            status: Status::Left,
            ..*c
        };
        let arm_beside = vec![
            DVec3::new(0.15, 1.2, -0.1),
            DVec3::new(0.10, 1.2, -0.1),
            DVec3::new(0.20, 1.2, -0.1),
        ];
        assert!(occluded(&arm_beside, &set, &front, &calib.front, true));
    }

    /// The silhouette of a whole mesh, through the fitter's own rasteriser.
    pub(crate) fn render_mask(mesh: &TriMesh, cam: &Camera) -> Vec<u8> {
        let mut m = Vec::new();
        crate::fit::shape::rasterize_band(
            &mesh.positions,
            &mesh.triangles,
            cam,
            cam.intrinsics.width,
            cam.intrinsics.height,
            (f64::MIN, f64::MAX),
            &mut m,
        );
        m
    }

    #[test]
    fn targets_land_on_a_larger_cylinder() {
        // Template: a cylinder of radius 0.15; observed: radius 0.17. Every torso control
        // must be pulled out by about 2 cm, in both variants.
        let calib = StationCalibration::nominal(640, 480, 600.0, 3.0, 1.0, 1.0);
        let small = shapes::elliptic_cylinder(0.15, 0.15, 1.6, 32, 48);
        let big = shapes::elliptic_cylinder(0.17, 0.17, 1.6, 32, 48);
        let fm = render_mask(&big, &calib.front);
        let sm = render_mask(&big, &calib.side);
        let labels = vec![Part::Torso; small.vertex_count()];
        let excluded = vec![false; small.vertex_count()];
        for variant in [Variant::SliceExtremes, Variant::PerspectiveRim] {
            let set = select_controls(
                &small,
                &labels,
                &excluded,
                0.1,
                variant,
                &calib.front,
                &calib.side,
            );
            assert!(set.controls.len() > 40, "{}", set.controls.len());
            let views = [
                (
                    &calib.front,
                    MaskRef {
                        width: 640,
                        height: 480,
                        data: &fm,
                    },
                ),
                (
                    &calib.side,
                    MaskRef {
                        width: 640,
                        height: 480,
                        data: &sm,
                    },
                ),
            ];
            let (mut c, mut t) = (Vec::new(), Vec::new());
            let st = find_targets(
                &small.positions,
                &set,
                views,
                &SearchOptions::default(),
                false,
                &mut c,
                &mut t,
            );
            assert!(st.found > set.controls.len() * 8 / 10, "{st:?}");
            for (ctl, tg) in set.controls.iter().zip(&t) {
                let Some(tg) = tg else { continue };
                let p = small.positions[ctl.vertex as usize];
                let r = DVec2::new(tg.x, tg.z).length();
                // Where the silhouette ray meets the moved line: near radius 0.17 (the
                // slice-extreme variant overshoots slightly under perspective).
                assert!(
                    (r - 0.17).abs() < 0.006,
                    "{variant:?} {:?} r={r}",
                    ctl.status
                );
                assert!((tg.y - p.y).abs() < 1e-9);
            }
        }
    }

    #[test]
    fn anchor_outside_gives_no_target() {
        let calib = StationCalibration::nominal(320, 240, 300.0, 3.0, 1.0, 1.0);
        let m = shapes::elliptic_cylinder(0.15, 0.15, 1.6, 8, 24);
        let empty = vec![0u8; 320 * 240];
        let labels = vec![Part::Torso; m.vertex_count()];
        let set = select_controls(
            &m,
            &labels,
            &vec![false; m.vertex_count()],
            0.2,
            Variant::SliceExtremes,
            &calib.front,
            &calib.side,
        );
        let views = [
            (
                &calib.front,
                MaskRef {
                    width: 320,
                    height: 240,
                    data: &empty,
                },
            ),
            (
                &calib.side,
                MaskRef {
                    width: 320,
                    height: 240,
                    data: &empty,
                },
            ),
        ];
        let (mut c, mut t) = (Vec::new(), Vec::new());
        let st = find_targets(
            &m.positions,
            &set,
            views,
            &SearchOptions::default(),
            false,
            &mut c,
            &mut t,
        );
        assert_eq!(st.found, 0);
        assert_eq!(st.anchor_outside, set.controls.len());
    }
}
