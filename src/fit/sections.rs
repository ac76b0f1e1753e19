//! Section-consistent targets for the trunk and the legs (an addition to method.md
//! section 3's correspondence).
//!
//! The paper moves only the slice-extreme control vertices and lets the mean value
//! decoding carry the rest of the surface. Mean value coordinates keep each vertex's
//! offset from its neighbours' plane in absolute terms, so between sparse controls the
//! surface keeps the candidate's curvature: a section that should shrink stays round and
//! bulges past its extremes, and its girth comes out too large. The two views say more
//! than four points per slice, though: the front view fixes the section's x extent and
//! the side view its z extent. Here every slice of the trunk and of each leg is mapped by
//! an axis-wise affine map (x' = x + a + (s - 1)(x - c), the same for z) that takes its
//! extreme controls onto their targets; the scales and shifts are smoothed along the
//! part with a running median (a notch or a stray target does not ripple the surface;
//! on the trunk only a value Hampel's rule calls stray is replaced, so the chest keeps
//! its widening under the armpits), filled in from the neighbours where a view gives only one side or none (an arm over
//! the trunk, the other leg), and blended linearly in height between slice centres. Every
//! vertex of those slices then gets the mapped position as its target, so the section
//! keeps the candidate's (the statistical shape prior's) shape, scaled to both views
//! (about the waist, real people's shape: [`super::section_prior`]).
//!
//! In the side view the legs overlap: there the two legs of one height band share one z
//! map, fitted to the union of both (whichever leg owns an edge gives its target).
//!
//! Units: metres, station frame (+Y up, +Z toward the front camera, +X the subject's left).

use super::correspond::{extreme_key, ControlSet, Part, Status, Variant};
use super::section_prior::{reshape, PriorScratch, WaistBand};
use crate::camera::{Camera, View};
use glam::DVec3;

/// Half-width of the running median along a part, in slices (about 3 cm each side at
/// the template's 1 cm slice step).
const SMOOTH_HALF_WINDOW: usize = 3;
/// Smallest span between a slice's two extreme controls that defines a scale, metres.
const MIN_SPAN_M: f64 = 0.005;
/// A slice of the candidate is scaled by at most this factor (or its inverse): the
/// candidate was chosen to match the silhouettes, a larger scale is a broken mask.
const MAX_SCALE: f64 = 1.25;

/// Which station axis a chain maps.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Axis {
    X,
    Z,
}

impl Axis {
    fn of(self, p: DVec3) -> f64 {
        match self {
            Axis::X => p.x,
            Axis::Z => p.z,
        }
    }
    /// Outward residual beyond which an edge is taken as another part's (see
    /// [`outward_inliers`]).
    fn outward_tolerance(self) -> f64 {
        match self {
            Axis::X => FRONT_OUTWARD_TOLERANCE_M,
            Axis::Z => OUTWARD_TOLERANCE_M,
        }
    }
    fn statuses(self) -> (Status, Status) {
        match self {
            Axis::X => (Status::Left, Status::Right),
            Axis::Z => (Status::Front, Status::Back),
        }
    }
}

/// One height band of a chain: the slices it maps (one, or both legs in the side view).
#[derive(Debug, Clone)]
struct Entry {
    slices: Vec<u32>,
}

/// The slices of one part (or of both legs) along one axis, in band order.
#[derive(Debug, Clone)]
struct Chain {
    axis: Axis,
    entries: Vec<Entry>,
}

/// The chains of a control set, built once per subject.
#[derive(Debug, Clone, Default)]
pub struct SectionPlan {
    chains: Vec<Chain>,
    /// Per slice: (chain, entry) of its x map and of its z map, if it has dense targets.
    slot: Vec<[Option<(u32, u32)>; 2]>,
    /// Controls of each slice.
    by_slice: Vec<Vec<u32>>,
    /// Vertices that receive dense targets (members of trunk and leg slices).
    pub vertices: Vec<u32>,
    /// Per control: the candidate's own rim point at the control's height (see
    /// [`SectionPlan::set_rims`]); empty until set.
    rims: Vec<DVec3>,
    /// The trunk's vertices and the candidate's waist band, for the waist's section
    /// shape ([`super::section_prior`]); no reshaping without a band.
    torso_vertices: Vec<u32>,
    waist_band: Option<WaistBand>,
}

/// Per-entry delta map `d(x) = alpha + beta * x` and the entry's centre height.
#[derive(Debug, Clone, Copy, Default)]
struct Delta {
    alpha: f64,
    beta: f64,
    y: f64,
    /// The coordinate the scale is taken about (the section's centre).
    mid: f64,
}

/// What the views showed of one entry of a chain, for the measurements' uncertainty:
/// per side (the chain's high then low status), the edge's residual against the fitted
/// map (metres, the observed edge minus where the map puts the candidate's rim), or NaN
/// where the view showed no edge of the part (occluded, trimmed as another part's, or
/// outside the mask).
#[derive(Debug, Clone, Copy)]
pub struct EntryEvidence {
    pub y: f64,
    pub residual: [f64; 2],
}

/// The body region a measurement is taken on, for [`SectionPlan::evidence_at`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Region {
    Torso,
    LeftThigh,
    RightThigh,
}

/// How well one view showed one extent (width or depth) of a region about a height.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AxisEvidence {
    /// Fraction of the region's edges (both sides, entries within the window) that the
    /// view showed, 0..1.
    pub seen: f64,
    /// Root mean square residual of the edges shown, metres (per side).
    pub rms_m: f64,
    /// Over the same edges, the mean of `min(1, gap / UNSEEN_GAP_FULL_M)^2` for those the
    /// view did not show (0 for those it did), where `gap` is the height to the nearest
    /// edge it showed on the same side: an edge between shown neighbours is interpolated
    /// from them, one far from any is the candidate's guess.
    pub unseen_share: f64,
}

/// Height gap to the nearest shown edge beyond which an unshown edge is known no better
/// than the candidate body knows it, metres (about the height of a hand).
pub const UNSEEN_GAP_FULL_M: f64 = 0.10;

/// What both views showed of a region about a height.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LevelEvidence {
    /// The front view: the region's x extent.
    pub width: AxisEvidence,
    /// The side view: the region's z extent.
    pub depth: AxisEvidence,
}

/// Most limb capsules an observation carries for the side view (forearm and hand of
/// each arm, and a spare pair).
pub const MAX_SIDE_OCCLUDERS: usize = 6;

/// A limb segment seen in the side view (a forearm, a hand), as a capsule in the station's
/// (y, z) plane: the segment from `a` to `b` (each `(y, z)`, metres) widened by `radius`.
/// The side camera looks along x, so an edge of the side silhouette at height y and depth
/// z inside the capsule may be the limb's.
///
/// The capsule lies on the plane x = `x` (the limb's, as the front view places it). An
/// edge found at another x (the trunk's outline) is first moved along the side camera's
/// ray from `eye` onto that plane ([`SideOccluder::covers_seen`]): an arm a quarter of a
/// metre nearer or further than the trunk meets the same ray several centimetres higher
/// or lower and nearer or further from the camera's height.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SideOccluder {
    pub a: glam::DVec2,
    pub b: glam::DVec2,
    pub radius: f64,
    /// The x of the capsule's plane, metres.
    pub x: f64,
    /// The side camera's centre, station frame.
    pub eye: DVec3,
}

impl SideOccluder {
    /// Whether the point `(y, z)` lies within the capsule widened by `margin`.
    pub fn covers(&self, y: f64, z: f64, margin: f64) -> bool {
        self.axis_distance(y, z) <= self.radius + margin
    }

    /// Distance of the point `(y, z)` from the capsule's axis segment, metres.
    fn axis_distance(&self, y: f64, z: f64) -> f64 {
        let p = glam::DVec2::new(y, z);
        let ab = self.b - self.a;
        let t = if ab.length_squared() > 1e-12 {
            ((p - self.a).dot(ab) / ab.length_squared()).clamp(0.0, 1.0)
        } else {
            0.0
        };
        (self.a + ab * t).distance(p)
    }

    /// The silhouette point `seen` (station frame, found at its own x) moved along the
    /// side camera's ray onto the capsule's plane, as `(y, z)`.
    fn on_plane(&self, seen: DVec3) -> (f64, f64) {
        let d = seen.x - self.eye.x;
        let s = (self.x - self.eye.x) / d;
        if !(d.abs() > 1e-9 && s > 0.0) {
            return (seen.y, seen.z);
        }
        let q = self.eye + (seen - self.eye) * s;
        (q.y, q.z)
    }

    /// Whether the silhouette point `seen` (station frame, found at its own x) lies on
    /// the capsule once moved along the side camera's ray onto the capsule's plane.
    pub fn covers_seen(&self, seen: DVec3, margin: f64) -> bool {
        let (y, z) = self.on_plane(seen);
        self.covers(y, z, margin)
    }

    /// Whether the silhouette edge `seen` could be the limb's own outline: on the
    /// capsule's plane it lies within `margin` of the capsule's surface. An edge deep
    /// inside the capsule is not the limb's: had the limb been there, its outline would
    /// stand further out than the edge the view shows.
    pub fn outline_covers_seen(&self, seen: DVec3, margin: f64) -> bool {
        let (y, z) = self.on_plane(seen);
        (self.axis_distance(y, z) - self.radius).abs() <= margin
    }
}

/// An edge of the side silhouette within this of a limb capsule is taken as the limb's,
/// metres (the capsule is drawn from keypoints, which sit inside the limb).
const OCCLUDER_MARGIN_M: f64 = 0.015;
/// With the limbs of the side view known, the smooth-trend test of [`outward_inliers`]
/// only guards against gross mistakes (a passer-by, a bag): an edge within this of the
/// trend is the part's own, however far the candidate's shape is from it, metres.
const KNOWN_OCCLUDERS_OUTWARD_TOLERANCE_M: f64 = 0.05;

/// Chain indices in [`SectionPlan::new`]'s order.
const CHAIN_TORSO_X: usize = 0;
const CHAIN_TORSO_Z: usize = 1;
const CHAIN_LEFT_LEG_X: usize = 2;
const CHAIN_RIGHT_LEG_X: usize = 3;
const CHAIN_LEGS_Z: usize = 4;

/// Scratch of [`SectionPlan::targets`].
#[derive(Debug, Clone, Default)]
pub struct SectionScratch {
    deltas: Vec<Vec<Delta>>,
    /// Per chain, per entry: what the views showed at the last call.
    evidence: Vec<Vec<EntryEvidence>>,
    raw_scale: Vec<Option<f64>>,
    trend_y: Vec<f64>,
    trend_d: Vec<f64>,
    window: Vec<f64>,
    centres: Vec<f64>,
    scales: Vec<f64>,
    /// Per entry of the chain being fitted: (rim, edge) per side, and the rims' middle.
    constraints: Vec<[Option<(f64, f64)>; 2]>,
    mids: Vec<f64>,
    raw_shift: Vec<Option<f64>>,
    shifts: Vec<f64>,
    prior: PriorScratch,
    /// The trunk's back edges the side view showed at the last call, taken as the
    /// trunk's own (not a limb's): (entry height, z), metres.
    pub back_edges: Vec<(f64, f64)>,
    /// Per entry of the chain being fitted, the x of the edge taken on each side (hi, lo),
    /// metres: where the side view's edge was found, for the limb capsules' test.
    edge_x: Vec<[f64; 2]>,
    /// The front and side cameras' centres, in the frame of the targets and rims of the
    /// next [`SectionPlan::targets`] call: each edge is read at its rim's depth (see
    /// [`at_rim_depth`]). None: at the control vertex's depth.
    pub eyes: Option<[DVec3; 2]>,
}

fn dense_part(p: Part) -> bool {
    matches!(p, Part::Torso | Part::LeftLeg | Part::RightLeg)
}

impl SectionPlan {
    /// Builds the chains of `set` (trunk x and z, each leg's x, both legs' z).
    pub fn new(set: &ControlSet) -> Self {
        let n = set.slice_members.len();
        let mut by_slice = vec![Vec::new(); n];
        for (i, c) in set.controls.iter().enumerate() {
            if let Some(b) = by_slice.get_mut(c.slice as usize) {
                b.push(i as u32);
            }
        }
        let mut plan = SectionPlan {
            slot: vec![[None, None]; n],
            by_slice,
            ..Default::default()
        };
        let slices_of = |part: Part| -> Vec<u32> {
            let mut v: Vec<u32> = (0..n as u32)
                .filter(|&s| set.slice_part.get(s as usize) == Some(&part))
                .collect();
            v.sort_by_key(|&s| set.slice_band.get(s as usize).copied().unwrap_or(0));
            v
        };
        let single = |slices: &[u32], axis: Axis| Chain {
            axis,
            entries: slices.iter().map(|&s| Entry { slices: vec![s] }).collect(),
        };
        let band_of = |s: u32| set.slice_band.get(s as usize).copied();
        let torso = slices_of(Part::Torso);
        let left = slices_of(Part::LeftLeg);
        let right = slices_of(Part::RightLeg);
        let mut chains = vec![
            single(&torso, Axis::X),
            single(&torso, Axis::Z),
            single(&left, Axis::X),
            single(&right, Axis::X),
        ];
        // Both legs' z: one entry per band holding either leg's slice or both.
        let mut legs: std::collections::BTreeMap<u32, Vec<u32>> = Default::default();
        for &s in left.iter().chain(&right) {
            let band = set.slice_band.get(s as usize).copied().unwrap_or(0);
            legs.entry(band).or_default().push(s);
        }
        chains.push(Chain {
            axis: Axis::Z,
            entries: legs.into_values().map(|slices| Entry { slices }).collect(),
        });
        for (ci, chain) in chains.iter().enumerate() {
            let k = match chain.axis {
                Axis::X => 0,
                Axis::Z => 1,
            };
            for (ei, e) in chain.entries.iter().enumerate() {
                for &s in &e.slices {
                    plan.slot[s as usize][k] = Some((ci as u32, ei as u32));
                }
            }
        }
        // Where trunk and legs share a band (the crotch, the buttocks' lowest rows), the
        // trunk's vertices take the legs' depth map of that band: one map at one height.
        // With the trunk's own map there, the buttocks' lowest rows moved with the trunk
        // above them (fitted to the buttocks' back, its front filled in from the belly)
        // while the thighs' rows beside them moved with the legs, 20-50 mm apart on some
        // bodies: the step squared the thighs' tops at the back, fuller than any library
        // body's (hull over the ellipse of their extents 1.03-1.06 on 7 of 16 development
        // avatars, the library's 0.98-1.03).
        let leg_z: std::collections::BTreeMap<u32, (u32, u32)> = left
            .iter()
            .chain(&right)
            .filter_map(|&s| Some((band_of(s)?, plan.slot[s as usize][1]?)))
            .collect();
        for &s in &torso {
            if let Some(&z) = band_of(s).and_then(|b| leg_z.get(&b)) {
                plan.slot[s as usize][1] = Some(z);
            }
        }
        plan.chains = chains;
        for (s, members) in set.slice_members.iter().enumerate() {
            if set.slice_part.get(s).copied().is_some_and(dense_part) {
                plan.vertices.extend_from_slice(members);
            }
            if set.slice_part.get(s) == Some(&Part::Torso) {
                plan.torso_vertices.extend_from_slice(members);
            }
        }
        plan
    }

    /// Sets the candidate's waist band: [`Self::targets`] then gives the band's sections
    /// the waist shape of [`super::section_prior`]. None: the candidate's shape.
    pub fn set_waist_band(&mut self, band: Option<WaistBand>) {
        self.waist_band = band;
    }

    /// Turns the recorded rims by `yaw` about the vertical through `about` (see
    /// [`super::turn`]): rims found on a turned candidate, for maps made in its own axes.
    pub fn turn_rims(&mut self, about: DVec3, yaw: f64) {
        super::turn::turn(&mut self.rims, about, yaw);
    }

    /// Records, per control, the candidate's rim point at the control's height: the point
    /// of the part's true cross-section there (crossings of the part's mesh edges with the
    /// horizontal plane) that lies furthest toward the control's side, as its view sees it.
    ///
    /// A slice is a band of vertices, and a band of a slanting row of the template holds
    /// only part of the section, so its extreme vertex can sit well inside the section's
    /// extreme; the silhouette edge found at the control's height is the section's rim,
    /// so the scale and shift must be taken against the rim, not the vertex.
    pub fn set_rims(
        &mut self,
        positions: &[DVec3],
        edges: &[[u32; 2]],
        labels: &[Part],
        set: &ControlSet,
        cameras: [&Camera; 2],
    ) {
        let variant = set.variant.unwrap_or(Variant::SliceExtremes);
        let Some((y0, y1)) = positions
            .iter()
            .map(|p| p.y)
            .fold(None, |acc: Option<(f64, f64)>, y| {
                Some(acc.map_or((y, y), |(a, b)| (a.min(y), b.max(y))))
            })
        else {
            return;
        };
        let bins = ((y1 - y0) / RIM_BIN_M).ceil().max(1.0) as usize;
        let bin_of = |y: f64| (((y - y0) / RIM_BIN_M).max(0.0) as usize).min(bins - 1);
        // Edges of the dense parts, bucketed by the height bins they span.
        let mut buckets: Vec<Vec<u32>> = vec![Vec::new(); bins];
        for (i, &[a, b]) in edges.iter().enumerate() {
            let (la, lb) = (labels.get(a as usize), labels.get(b as usize));
            if la != lb || !la.copied().is_some_and(dense_part) {
                continue;
            }
            let (ya, yb) = (positions[a as usize].y, positions[b as usize].y);
            for bucket in &mut buckets[bin_of(ya.min(yb))..=bin_of(ya.max(yb))] {
                bucket.push(i as u32);
            }
        }
        self.rims.clear();
        for c in &set.controls {
            let p = positions[c.vertex as usize];
            let cam = match c.status.view() {
                View::Front => cameras[0],
                View::Side => cameras[1],
            };
            let mut best = p;
            let mut best_key = extreme_key(variant, cam, c.status, p);
            for &i in &buckets[bin_of(p.y)] {
                let [a, b] = edges[i as usize];
                if labels.get(a as usize) != Some(&c.part) {
                    continue;
                }
                let (pa, pb) = (positions[a as usize], positions[b as usize]);
                if (pa.y - p.y) * (pb.y - p.y) > 0.0 || (pa.y - pb.y).abs() < 1e-12 {
                    continue;
                }
                let q = pa + (pb - pa) * ((p.y - pa.y) / (pb.y - pa.y));
                // Edges of the control's own part only: the other leg and the arms are
                // other parts.
                let key = extreme_key(variant, cam, c.status, q);
                if key > best_key {
                    best_key = key;
                    best = q;
                }
            }
            self.rims.push(best);
        }
    }

    /// Dense targets: writes into `out` (one entry per vertex of the mesh, resized) the
    /// mapped position of every vertex of [`Self::vertices`]; other entries are None.
    pub fn targets(
        &self,
        positions: &[DVec3],
        set: &ControlSet,
        targets: &[Option<DVec3>],
        occluders: &[Option<SideOccluder>],
        scratch: &mut SectionScratch,
        out: &mut Vec<Option<DVec3>>,
    ) {
        out.clear();
        out.resize(positions.len(), None);
        scratch.deltas.resize(self.chains.len(), Vec::new());
        scratch.evidence.resize(self.chains.len(), Vec::new());
        for ci in 0..self.chains.len() {
            let mut ds = std::mem::take(&mut scratch.deltas[ci]);
            let mut ev = std::mem::take(&mut scratch.evidence[ci]);
            // The known limbs are the arms: they free the trunk's side outline; the
            // thighs' own overlap in the side view keeps the smooth-trend test.
            let limbs = if ci == CHAIN_TORSO_Z { occluders } else { &[] };
            self.chain_deltas(
                ci, positions, set, targets, limbs, scratch, &mut ds, &mut ev,
            );
            scratch.deltas[ci] = ds;
            scratch.evidence[ci] = ev;
        }
        for (s, members) in set.slice_members.iter().enumerate() {
            let [sx, sz] = self.slot[s];
            if sx.is_none() && sz.is_none() {
                continue;
            }
            let is_leg = matches!(set.slice_part.get(s), Some(Part::LeftLeg | Part::RightLeg));
            for &v in members {
                let p = positions[v as usize];
                let mut q = p;
                let dx = sx.map(|(c, e)| self.blended(scratch, c, e, p.y));
                if let Some(d) = dx {
                    q.x += d.alpha + d.beta * p.x;
                }
                if let Some((c, e)) = sz {
                    let mut d = self.blended(scratch, c, e, p.y);
                    // The side view sees both legs as one: its depth is each leg's depth
                    // plus their stagger, an upper bound. A leg's depth is scaled by no more
                    // than its width (the front view sees each leg alone), about the same
                    // centre; so is the trunk's where it takes the legs' map.
                    let legs_map = is_leg || c as usize == CHAIN_LEGS_Z;
                    if let Some(x) = dx.filter(|x| legs_map && x.beta < d.beta) {
                        d.alpha += (d.beta - x.beta) * d.mid;
                        d.beta = x.beta;
                    }
                    q.z += d.alpha + d.beta * p.z;
                }
                out[v as usize] = Some(q);
            }
        }
        if let Some(band) = &self.waist_band {
            let push = reshape(band, &self.torso_vertices, out, &mut scratch.prior);
            if super::debug_enabled() {
                eprintln!("waist prior: {band:?} push {push:?}");
            }
        }
    }

    /// The map of entry `e` of chain `c` at height `y`, blended linearly with the
    /// neighbouring entry on the side of `y`.
    fn blended(&self, scratch: &SectionScratch, c: u32, e: u32, y: f64) -> Delta {
        let ds = &scratch.deltas[c as usize];
        let e = e as usize;
        let here = ds[e];
        let other = if y >= here.y {
            e + 1
        } else {
            e.wrapping_sub(1)
        };
        match ds.get(other) {
            Some(o) if (o.y - here.y).abs() > 1e-9 => {
                let t = ((y - here.y) / (o.y - here.y)).clamp(0.0, 1.0);
                Delta {
                    alpha: here.alpha * (1.0 - t) + o.alpha * t,
                    beta: here.beta * (1.0 - t) + o.beta * t,
                    y,
                    mid: here.mid * (1.0 - t) + o.mid * t,
                }
            }
            _ => here,
        }
    }

    /// What the views showed of `region` within `half_window_m` of height `y`, at the
    /// last call of [`Self::targets`] with `scratch`; None before one, or where the region
    /// has no entry within the window.
    pub fn evidence_at(
        &self,
        scratch: &SectionScratch,
        region: Region,
        y: f64,
        half_window_m: f64,
    ) -> Option<LevelEvidence> {
        let (cx, cz) = match region {
            Region::Torso => (CHAIN_TORSO_X, CHAIN_TORSO_Z),
            Region::LeftThigh => (CHAIN_LEFT_LEG_X, CHAIN_LEGS_Z),
            Region::RightThigh => (CHAIN_RIGHT_LEG_X, CHAIN_LEGS_Z),
        };
        let axis = |c: usize| -> Option<AxisEvidence> {
            let entries = scratch.evidence.get(c)?;
            let (mut n, mut seen, mut ss, mut unseen) = (0usize, 0usize, 0.0, 0.0);
            for e in entries {
                if (e.y - y).abs() > half_window_m {
                    continue;
                }
                for (side, r) in e.residual.into_iter().enumerate() {
                    n += 1;
                    if r.is_finite() {
                        seen += 1;
                        ss += r * r;
                    } else {
                        let gap = entries
                            .iter()
                            .filter(|o| o.residual[side].is_finite())
                            .map(|o| (o.y - e.y).abs())
                            .fold(f64::INFINITY, f64::min);
                        unseen += (gap / UNSEEN_GAP_FULL_M).min(1.0).powi(2);
                    }
                }
            }
            (n > 0).then(|| AxisEvidence {
                seen: seen as f64 / n as f64,
                rms_m: if seen > 0 {
                    (ss / seen as f64).sqrt()
                } else {
                    0.0
                },
                unseen_share: unseen / n as f64,
            })
        };
        Some(LevelEvidence {
            width: axis(cx)?,
            depth: axis(cz)?,
        })
    }

    /// Fits the chain's maps into `out`, one [`Delta`] per entry, and records in
    /// `evidence` what the views showed of each entry.
    #[allow(clippy::too_many_arguments)]
    fn chain_deltas(
        &self,
        ci: usize,
        positions: &[DVec3],
        set: &ControlSet,
        targets: &[Option<DVec3>],
        occluders: &[Option<SideOccluder>],
        scratch: &mut SectionScratch,
        out: &mut Vec<Delta>,
        evidence: &mut Vec<EntryEvidence>,
    ) {
        let chain = &self.chains[ci];
        let mut constraints = std::mem::take(&mut scratch.constraints);
        let mut mids = std::mem::take(&mut scratch.mids);
        self.gather_constraints(
            chain,
            positions,
            set,
            targets,
            scratch,
            &mut constraints,
            &mut mids,
        );
        let raw_constraints = if super::debug_enabled() && chain.axis == Axis::Z {
            Some(constraints.clone())
        } else {
            None
        };
        drop_foreign_edges(chain.axis, occluders, scratch, &mut constraints);
        if ci == CHAIN_TORSO_Z {
            scratch.back_edges.clear();
            for (c, &y) in constraints.iter().zip(&scratch.centres) {
                if let Some((_, z)) = c[1] {
                    scratch.back_edges.push((y, z));
                }
            }
        }
        if let Some(raw) = raw_constraints {
            print_side_constraints(occluders, &scratch.centres, &raw, &constraints);
        }
        // The trunk keeps the part's own changes of scale (Hampel's rule); the legs'
        // side-view depth is the union of both legs, an upper bound whose peaks are as
        // likely the other leg's: their maps keep the plain running median.
        let keep_own = ci == CHAIN_TORSO_X || ci == CHAIN_TORSO_Z;
        fit_maps(&constraints, &mids, keep_own, scratch, out, evidence);
        scratch.constraints = constraints;
        scratch.mids = mids;
    }

    /// Per entry of the chain: its centre height (into `scratch.centres`), the middle of
    /// the candidate's rims on the two sides (`mids`), and per side the edge the view
    /// showed, as (the candidate's rim, the edge) along the chain's axis (`constraints`).
    #[allow(clippy::too_many_arguments)]
    fn gather_constraints(
        &self,
        chain: &Chain,
        positions: &[DVec3],
        set: &ControlSet,
        targets: &[Option<DVec3>],
        scratch: &mut SectionScratch,
        constraints: &mut Vec<[Option<(f64, f64)>; 2]>,
        mids: &mut Vec<f64>,
    ) {
        let (hi_status, lo_status) = chain.axis.statuses();
        scratch.centres.clear();
        scratch.edge_x.clear();
        constraints.clear();
        mids.clear();
        for e in &chain.entries {
            let (mut hi, mut lo) = (f64::MIN, f64::MAX);
            let mut c_hi: Option<(f64, f64)> = None;
            let mut c_lo: Option<(f64, f64)> = None;
            let mut x_edge = [0.0f64; 2];
            let mut ysum = 0.0;
            let mut yn = 0usize;
            for &s in &e.slices {
                if let Some(members) = set.slice_members.get(s as usize) {
                    for &v in members {
                        ysum += positions[v as usize].y;
                        yn += 1;
                    }
                }
                for &ci in &self.by_slice[s as usize] {
                    let c = &set.controls[ci as usize];
                    let at = self
                        .rims
                        .get(ci as usize)
                        .copied()
                        .unwrap_or(positions[c.vertex as usize]);
                    let p = chain.axis.of(at);
                    let target = targets.get(ci as usize).copied().flatten();
                    let t = target.map(|t| {
                        let eye = scratch.eyes.map(|e| match chain.axis {
                            Axis::X => e[0],
                            Axis::Z => e[1],
                        });
                        at_rim_depth(chain.axis, eye, at, t)
                    });
                    let tx = target.map_or(0.0, |t| t.x);
                    if c.status == hi_status {
                        hi = hi.max(p);
                        if let Some(t) = t {
                            // Of two owners, the one reaching further.
                            if c_hi.is_none_or(|(_, t0)| t > t0) {
                                c_hi = Some((p, t));
                                x_edge[0] = tx;
                            }
                        }
                    } else if c.status == lo_status {
                        lo = lo.min(p);
                        if let Some(t) = t {
                            if c_lo.is_none_or(|(_, t0)| t < t0) {
                                c_lo = Some((p, t));
                                x_edge[1] = tx;
                            }
                        }
                    }
                }
            }
            scratch
                .centres
                .push(if yn > 0 { ysum / yn as f64 } else { 0.0 });
            mids.push(if hi >= lo { 0.5 * (hi + lo) } else { 0.0 });
            constraints.push([c_hi, c_lo]);
            scratch.edge_x.push(x_edge);
        }
    }
}

/// A point's coordinate along one axis (the view's depth or its across axis).
type AxisCoord = fn(DVec3) -> f64;

/// The edge a target stands for, along `axis`, at the depth of the candidate's rim `rim`
/// (the depth the scale and shift are taken at). The target lies where the viewing ray
/// from `eye` through the silhouette's edge meets the control vertex's depth, and a
/// slice's vertex (its extreme vertex when the controls were chosen) can lie centimetres
/// nearer the camera than its section's rim, or further: read there, the edge is off by
/// its offset from the camera's centre line times the depth difference over the distance
/// (an edge 15 cm off the line, 5 cm of depth, 2.5 m away: 3 mm), the same way on every
/// frame. Along the same ray at the rim's depth it is the rim's. Without an eye, or for a
/// ray along the depth axis, the target's own coordinate.
fn at_rim_depth(axis: Axis, eye: Option<DVec3>, rim: DVec3, target: DVec3) -> f64 {
    let Some(eye) = eye else {
        return axis.of(target);
    };
    // The depth axis of the view: x for the side camera, z for the front one.
    let (depth, across): (AxisCoord, AxisCoord) = match axis {
        Axis::Z => (|p: DVec3| p.x, |p: DVec3| p.z),
        Axis::X => (|p: DVec3| p.z, |p: DVec3| p.x),
    };
    let run = depth(target) - depth(eye);
    if run.abs() < 1e-6 {
        return across(target);
    }
    let s = (depth(rim) - depth(eye)) / run;
    if !(s > 0.0) {
        return across(target);
    }
    across(eye) + s * (across(target) - across(eye))
}

/// Drops the edges that are not the part's own: occlusion only ever adds to a
/// silhouette, so an edge that stands out beyond the part's smooth trend may be an arm's
/// or a hand's in front of the trunk. Without known limbs every such edge is dropped.
/// With them (the side view's capsules), the limbs explain the edges they cover; one that
/// stands out where no limb is (a belly, a bust the candidate lacks) is the part's own,
/// unless it is a gross outlier of the trend.
fn drop_foreign_edges(
    axis: Axis,
    occluders: &[Option<SideOccluder>],
    scratch: &mut SectionScratch,
    constraints: &mut [[Option<(f64, f64)>; 2]],
) {
    let known = axis == Axis::Z && occluders.iter().any(Option::is_some);
    for side in 0..2 {
        let sign = if side == 0 { 1.0 } else { -1.0 };
        scratch.trend_y.clear();
        scratch.trend_d.clear();
        for (e, c) in constraints.iter().enumerate() {
            if let Some((p, t)) = c[side] {
                scratch.trend_y.push(scratch.centres[e]);
                scratch.trend_d.push(sign * (t - p));
            }
        }
        let tight = outward_inliers(&scratch.trend_y, &scratch.trend_d, axis.outward_tolerance());
        // Only with known limbs: the gross-outlier test (no copy of `tight` otherwise).
        let loose = known.then(|| {
            outward_inliers(
                &scratch.trend_y,
                &scratch.trend_d,
                KNOWN_OCCLUDERS_OUTWARD_TOLERANCE_M,
            )
        });
        let mut k = 0;
        for (e, c) in constraints.iter_mut().enumerate() {
            let Some((_, t)) = c[side] else { continue };
            let on_trend = tight.get(k).copied().unwrap_or(true);
            // On the tight trend is plausible too: the loose trend, pulled by hands and a
            // bust, can leave the trunk's own stretch of edges as inward outliers.
            let plausible = on_trend
                || loose
                    .as_ref()
                    .is_some_and(|l| l.get(k).copied().unwrap_or(true));
            // In the side view, an edge inside a known limb's capsule may be the limb's.
            let seen = DVec3::new(scratch.edge_x[e][side], scratch.centres[e], t);
            let in_limb = known
                && occluders
                    .iter()
                    .flatten()
                    .any(|o| o.outline_covers_seen(seen, OCCLUDER_MARGIN_M));
            if !(plausible && (on_trend || (known && !in_limb))) {
                c[side] = None;
            }
            k += 1;
        }
    }
}

/// `FITSTATION_DEBUG`: the side view's edges per entry of a chain, as found and as kept.
fn print_side_constraints(
    occluders: &[Option<SideOccluder>],
    centres: &[f64],
    raw: &[[Option<(f64, f64)>; 2]],
    kept: &[[Option<(f64, f64)>; 2]],
) {
    let f = |o: Option<(f64, f64)>| o.map_or("-".to_string(), |(_, t)| format!("{t:.3}"));
    for (e, (r, c)) in raw.iter().zip(kept).enumerate() {
        eprintln!(
            "SIDEZ {} y {:.3} front {} kept {} back {} kept {}",
            occluders.iter().any(Option::is_some),
            centres[e],
            f(r[0]),
            f(c[0]),
            f(r[1]),
            f(c[1])
        );
    }
}

/// The chain's maps from the edges kept: per entry the scale that takes the candidate's
/// span onto the edges' and the shift that centres it, each smoothed along the chain by a
/// running median and filled in where the view showed nothing; and per entry the
/// residual of each edge against its map (the evidence of what the view showed).
fn fit_maps(
    constraints: &[[Option<(f64, f64)>; 2]],
    mids: &[f64],
    keep_own: bool,
    scratch: &mut SectionScratch,
    out: &mut Vec<Delta>,
    evidence: &mut Vec<EntryEvidence>,
) {
    let m = constraints.len();
    scratch.raw_scale.clear();
    scratch
        .raw_scale
        .extend(constraints.iter().map(|c| match c {
            [Some((ph, th)), Some((pl, tl))] if ph - pl > MIN_SPAN_M && th > tl => {
                Some(((th - tl) / (ph - pl)).clamp(1.0 / MAX_SCALE, MAX_SCALE))
            }
            _ => None,
        }));
    // Scales: running median of the observed ones, filled in from the nearest.
    running_median(
        &scratch.raw_scale,
        keep_own,
        &mut scratch.window,
        &mut scratch.scales,
    );
    fill(&mut scratch.scales, 1.0);
    // Shifts (delta at the entry's mid) given the smoothed scale.
    scratch.raw_shift.clear();
    for e in 0..m {
        let s = scratch.scales[e];
        let c = mids[e];
        let mut sum = 0.0;
        let mut n = 0;
        for (p, t) in constraints[e].iter().flatten() {
            sum += t - (c + s * (p - c));
            n += 1;
        }
        scratch.raw_shift.push((n > 0).then(|| sum / n as f64));
    }
    running_median(
        &scratch.raw_shift,
        keep_own,
        &mut scratch.window,
        &mut scratch.shifts,
    );
    fill(&mut scratch.shifts, 0.0);
    // delta(x) = shift + (s - 1)(x - mid) = alpha + beta x.
    out.clear();
    evidence.clear();
    for e in 0..m {
        let beta = scratch.scales[e] - 1.0;
        let d = Delta {
            alpha: scratch.shifts[e] - beta * mids[e],
            beta,
            y: scratch.centres[e],
            mid: mids[e],
        };
        out.push(d);
        evidence.push(EntryEvidence {
            y: d.y,
            residual: constraints[e]
                .map(|c| c.map_or(f64::NAN, |(p, t)| t - (p + d.alpha + d.beta * p))),
        });
    }
}

/// Height bins of the edge buckets in [`SectionPlan::set_rims`], metres.
const RIM_BIN_M: f64 = 0.01;

/// Fewest observed values a running-median window needs (fewer: filled in by
/// interpolation between better-supported neighbours instead).
const MIN_MEDIAN_SUPPORT: usize = 3;

/// Running median over `SMOOTH_HALF_WINDOW` each side of the present values (None: no
/// value there); NaN where a window has fewer than [`MIN_MEDIAN_SUPPORT`]. With
/// `keep_own`, a value that Hampel's rule calls the part's own is kept instead (below).
fn running_median(
    values: &[Option<f64>],
    keep_own: bool,
    window: &mut Vec<f64>,
    out: &mut Vec<f64>,
) {
    out.clear();
    let m = values.len();
    for i in 0..m {
        window.clear();
        let lo = i.saturating_sub(SMOOTH_HALF_WINDOW);
        let hi = (i + SMOOTH_HALF_WINDOW + 1).min(m);
        window.extend(values[lo..hi].iter().flatten());
        if window.len() < MIN_MEDIAN_SUPPORT {
            out.push(f64::NAN);
            continue;
        }
        let med = median_in_place(window);
        // Hampel's rule: a value within HAMPEL_K robust deviations of its neighbours'
        // median is the part's own and kept (a median alone cuts every peak and trough
        // of a changing scale: the chest's widening under the armpits); one further out
        // is a stray target and replaced by the median.
        let keep = values[i].filter(|&x| {
            if !keep_own {
                return false;
            }
            for w in window.iter_mut() {
                *w = (*w - med).abs();
            }
            let mad = median_in_place(window);
            (x - med).abs() <= HAMPEL_K * MAD_TO_SIGMA * mad
        });
        out.push(keep.unwrap_or(med));
    }
}

/// Median of `w` (non-empty), sorting it.
fn median_in_place(w: &mut [f64]) -> f64 {
    w.sort_by(|a, b| a.total_cmp(b));
    let k = w.len();
    if k % 2 == 1 {
        w[k / 2]
    } else {
        0.5 * (w[k / 2 - 1] + w[k / 2])
    }
}

/// Hampel's outlier rule: robust standard deviations (the median absolute deviation
/// times [`MAD_TO_SIGMA`], a normal's sigma) a value may lie from its window's median.
const HAMPEL_K: f64 = 3.0;
const MAD_TO_SIGMA: f64 = 1.4826;

/// Gaps up to this many entries are bridged by linear interpolation; across a longer
/// gap each side's value is held and the two meet in a linear ramp of this length in the
/// gap's middle. A long unobserved stretch (the shoulders under the arms in the front
/// view) says nothing about a trend between its ends: holding the nearest observation
/// keeps the candidate's own shape there, scaled as its nearest observed neighbour.
const RAMP_ENTRIES: usize = 2 * SMOOTH_HALF_WINDOW + 1;

/// Fills NaN entries of `v` from the nearest finite ones: linear interpolation across
/// short gaps, hold-and-ramp across long ones (see [`RAMP_ENTRIES`]), constant beyond the
/// ends; `default` when none is finite.
fn fill(v: &mut [f64], default: f64) {
    let known: Vec<usize> = (0..v.len()).filter(|&i| v[i].is_finite()).collect();
    if known.is_empty() {
        v.iter_mut().for_each(|x| *x = default);
        return;
    }
    for i in 0..v.len() {
        if v[i].is_finite() {
            continue;
        }
        let next = known.partition_point(|&k| k < i);
        v[i] = match (next.checked_sub(1).map(|j| known[j]), known.get(next)) {
            (Some(a), Some(&b)) => {
                let gap = b - a - 1;
                let t = if gap <= RAMP_ENTRIES {
                    (i - a) as f64 / (b - a) as f64
                } else {
                    // Ramp over RAMP_ENTRIES + 1 steps centred in the gap.
                    let ramp = RAMP_ENTRIES as f64 + 1.0;
                    let start = a as f64 + 0.5 * ((b - a) as f64 - ramp);
                    ((i as f64 - start) / ramp).clamp(0.0, 1.0)
                };
                v[a] * (1.0 - t) + v[b] * t
            }
            (Some(a), None) => v[a],
            (None, Some(&b)) => v[b],
            (None, None) => default,
        };
    }
}

/// Outward residual (metres) beyond which an edge is taken as another part's.
const OUTWARD_TOLERANCE_M: f64 = 0.010;
/// The same for the front view's x edges: there the trunk's occluders (arms hanging
/// against it, a hand on the hip) add a whole limb's width, several centimetres, while the
/// trunk's own edge turns out quickly under the armpits, which a smooth trend misses.
const FRONT_OUTWARD_TOLERANCE_M: f64 = 0.025;
/// Inward residual beyond which an edge is dropped (a notch or hole in the mask).
const INWARD_TOLERANCE_M: f64 = 0.03;
/// Rounds of the trimmed trend fit.
const TREND_ROUNDS: usize = 5;

/// Which of the outward displacements `d` (at heights `y`) agree with their smooth trend:
/// a quadratic in height fitted by trimmed least squares, trimming mainly outward (an
/// occluding part can only push an edge out). Returns one flag per point.
fn outward_inliers(y: &[f64], d: &[f64], outward_tolerance: f64) -> Vec<bool> {
    let n = y.len();
    let mut keep = vec![true; n];
    if n < 6 {
        return keep;
    }
    let y0 = y.iter().sum::<f64>() / n as f64;
    for _ in 0..TREND_ROUNDS {
        // Normal equations of d ~ a + b (y - y0) + c (y - y0)^2 over the kept points.
        let mut ata = [[0.0f64; 3]; 3];
        let mut atb = [0.0f64; 3];
        let mut m = 0;
        for i in (0..n).filter(|&i| keep[i]) {
            let u = y[i] - y0;
            let row = [1.0, u, u * u];
            for r in 0..3 {
                atb[r] += row[r] * d[i];
                for c in 0..3 {
                    ata[r][c] += row[r] * row[c];
                }
            }
            m += 1;
        }
        if m < 4 {
            break;
        }
        for (r, row) in ata.iter_mut().enumerate() {
            row[r] += 1e-12;
        }
        let Some(coef) = super::solve_small(ata, atb) else {
            break;
        };
        let fit = |yy: f64| {
            let u = yy - y0;
            coef[0] + coef[1] * u + coef[2] * u * u
        };
        let next: Vec<bool> = (0..n)
            .map(|i| {
                let r = d[i] - fit(y[i]);
                r <= outward_tolerance && r >= -INWARD_TOLERANCE_M
            })
            .collect();
        if next == keep {
            break;
        }
        keep = next;
    }
    keep
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An edge read along its viewing ray: at the rim's depth when the vertex lies nearer
    /// the camera or further; unchanged without an eye or at the rim's own depth.
    #[test]
    fn an_edge_is_read_at_its_rims_depth_along_its_ray() {
        // A side camera 2.5 m along +x, at the origin's height and z.
        let eye = DVec3::new(2.5, 1.0, 0.0);
        // The edge seen at the vertex's depth (x = 0): z = -0.25, bearing -0.1.
        let target = DVec3::new(0.0, 1.0, -0.25);
        // The rim 0.1 m nearer the camera: the same ray there is at z = -0.24.
        let near = DVec3::new(0.1, 1.0, -0.2);
        assert!((at_rim_depth(Axis::Z, Some(eye), near, target) + 0.24).abs() < 1e-12);
        // 0.1 m further: -0.26.
        let far = DVec3::new(-0.1, 1.0, -0.2);
        assert!((at_rim_depth(Axis::Z, Some(eye), far, target) + 0.26).abs() < 1e-12);
        // At its own depth, or without an eye, the target's z.
        let level = DVec3::new(0.0, 1.0, -0.2);
        assert!((at_rim_depth(Axis::Z, Some(eye), level, target) + 0.25).abs() < 1e-12);
        assert_eq!(at_rim_depth(Axis::Z, None, near, target), -0.25);
        // The front view: a camera 3 m along +z reads x at the rim's z.
        let front = DVec3::new(0.0, 1.0, 3.0);
        let side_edge = DVec3::new(0.18, 1.0, 0.0);
        let behind = DVec3::new(0.15, 1.0, -0.06);
        let x = at_rim_depth(Axis::X, Some(front), behind, side_edge);
        assert!((x - 0.18 * 3.06 / 3.0).abs() < 1e-12, "{x}");
        // A rim behind the camera is not a depth along the ray: the target's own.
        let past = DVec3::new(3.0, 1.0, -0.2);
        assert_eq!(at_rim_depth(Axis::Z, Some(eye), past, target), -0.25);
    }
    use crate::fit::correspond::{select_controls, Variant};
    use crate::mesh::shapes;

    #[test]
    fn trimming_drops_a_contiguous_outward_bump_only() {
        // A smooth displacement profile with a 15-sample run pushed 5 cm out (an arm over
        // the trunk) and one sample 1.5 cm in (still within the inward tolerance).
        let y: Vec<f64> = (0..60).map(|i| 0.8 + 0.01 * i as f64).collect();
        let mut d: Vec<f64> = y
            .iter()
            .map(|y| 0.004 * (y - 1.0) + 0.01 * (y - 1.0).powi(2))
            .collect();
        for v in &mut d[20..35] {
            *v += 0.05;
        }
        d[50] -= 0.015;
        let keep = outward_inliers(&y, &d, OUTWARD_TOLERANCE_M);
        for (i, k) in keep.iter().enumerate() {
            assert_eq!(*k, !(20..35).contains(&i), "sample {i}");
        }
    }

    #[test]
    fn the_trunks_smoothing_keeps_a_peak_and_drops_a_stray_value() {
        // A scale rising to a peak and falling again (the chest under the armpits).
        let peak: Vec<Option<f64>> = [0.90, 0.92, 0.95, 1.00, 1.06, 1.12, 1.19, 1.18, 1.16]
            .iter()
            .map(|&v| Some(v))
            .collect();
        let (mut w, mut own, mut med) = (Vec::new(), Vec::new(), Vec::new());
        running_median(&peak, true, &mut w, &mut own);
        running_median(&peak, false, &mut w, &mut med);
        assert!((own[6] - 1.19).abs() < 1e-12, "{own:?}");
        assert!(med[6] < 1.17, "the median cuts the peak: {med:?}");
        // One stray target in a flat run is replaced by its neighbours' median, and a
        // missing one filled by it, in both modes.
        let mut stray: Vec<Option<f64>> = vec![Some(1.0); 9];
        stray[4] = Some(1.15);
        stray[2] = None;
        for keep in [true, false] {
            running_median(&stray, keep, &mut w, &mut own);
            assert!((own[4] - 1.0).abs() < 1e-12, "{own:?}");
            assert!((own[2] - 1.0).abs() < 1e-12, "{own:?}");
        }
    }

    #[test]
    fn fill_interpolates_between_and_holds_at_the_ends() {
        let mut v = vec![f64::NAN, 1.0, f64::NAN, f64::NAN, 4.0, f64::NAN];
        fill(&mut v, 0.0);
        assert_eq!(v, vec![1.0, 1.0, 2.0, 3.0, 4.0, 4.0]);
        let mut none = vec![f64::NAN; 3];
        fill(&mut none, 7.0);
        assert_eq!(none, vec![7.0; 3]);
        // A long gap holds each side and ramps in the middle.
        let n = 3 * RAMP_ENTRIES;
        let mut long = vec![f64::NAN; n];
        long[0] = 1.0;
        long[n - 1] = 2.0;
        fill(&mut long, 0.0);
        assert_eq!(long[1], 1.0);
        assert_eq!(long[n - 2], 2.0);
        assert!((long[(n - 1) / 2] - 1.5).abs() < 0.1, "{long:?}");
        assert!(long.windows(2).all(|w| w[1] >= w[0]), "monotone {long:?}");
    }

    /// An elliptic cylinder 0.30 x 0.20 m, 1 m tall, labelled trunk, and its slice-extreme
    /// controls every `step` metres.
    fn torso_cylinder(step: f64) -> (crate::mesh::TriMesh, ControlSet) {
        let mesh = shapes::elliptic_cylinder(0.15, 0.10, 1.0, 48, 40);
        let calib = crate::camera::StationCalibration::nominal(640, 480, 600.0, 3.0, 0.5, 0.5);
        let labels = vec![Part::Torso; mesh.vertex_count()];
        let excluded = vec![false; mesh.vertex_count()];
        let set = select_controls(
            &mesh,
            &labels,
            &excluded,
            step,
            Variant::SliceExtremes,
            &calib.front,
            &calib.side,
        );
        (mesh, set)
    }

    /// Targets at the controls, the front ones moved forward by `dz(y)`.
    fn front_moved(
        mesh: &crate::mesh::TriMesh,
        set: &ControlSet,
        dz: impl Fn(f64) -> f64,
    ) -> Vec<Option<DVec3>> {
        set.controls
            .iter()
            .map(|c| {
                let p = mesh.positions[c.vertex as usize];
                let d = if c.status == Status::Front {
                    dz(p.y)
                } else {
                    0.0
                };
                Some(p + DVec3::Z * d)
            })
            .collect()
    }

    /// The section plan's targets with one known side-view limb: the plan, its scratch
    /// (for the evidence) and the targets.
    fn targets_with_limb(
        mesh: &crate::mesh::TriMesh,
        set: &ControlSet,
        targets: &[Option<DVec3>],
        limb: SideOccluder,
    ) -> (SectionPlan, SectionScratch, Vec<Option<DVec3>>) {
        let plan = SectionPlan::new(set);
        let mut scratch = SectionScratch::default();
        let mut out = Vec::new();
        plan.targets(
            &mesh.positions,
            set,
            targets,
            &[Some(limb)],
            &mut scratch,
            &mut out,
        );
        (plan, scratch, out)
    }

    /// How far the front-most vertex between heights `y0` and `y1` moved (its target).
    fn front_shift(mesh: &crate::mesh::TriMesh, out: &[Option<DVec3>], y0: f64, y1: f64) -> f64 {
        let mut best = (f64::MIN, 0.0);
        for (v, t) in out.iter().enumerate() {
            let p = mesh.positions[v];
            if let Some(t) = t.filter(|_| p.y >= y0 && p.y <= y1 && p.x.abs() < 0.02) {
                if p.z > best.0 {
                    best = (p.z, t.z - p.z);
                }
            }
        }
        best.1
    }

    #[test]
    fn a_known_limb_hides_its_edges_and_the_trunk_is_followed_elsewhere() {
        // A cylinder (front at z = +0.10) seen by a side view whose front edge has a belly
        // 2 cm out between y = 0.25 and 0.45 and a forearm 6 cm out between 0.60 and 0.80.
        // With the forearm's capsule known, the belly is followed and the forearm ignored.
        let (mesh, set) = torso_cylinder(0.025);
        let out_at = |y: f64| {
            if (0.25..=0.45).contains(&y) {
                0.02
            } else if (0.60..=0.80).contains(&y) {
                0.06
            } else {
                0.0
            }
        };
        let targets = front_moved(&mesh, &set, out_at);
        let forearm = SideOccluder {
            a: glam::DVec2::new(0.60, 0.15),
            b: glam::DVec2::new(0.80, 0.15),
            radius: 0.02,
            x: 0.0,
            eye: DVec3::new(3.0, 0.7, 0.0),
        };
        assert!(forearm.covers(0.7, 0.16, 0.0) && !forearm.covers(0.7, 0.10, 0.015));
        let (plan, scratch, out) = targets_with_limb(&mesh, &set, &targets, forearm);
        let front_shift = |y0: f64, y1: f64| front_shift(&mesh, &out, y0, y1);
        let belly = front_shift(0.33, 0.37);
        let arm = front_shift(0.68, 0.72);
        assert!(belly > 0.012, "belly followed by {belly}");
        assert!(arm.abs() < 0.01, "forearm taken for the trunk: {arm}");
        // The forearm's heights count as unseen in the front-to-back evidence.
        let e = plan
            .evidence_at(&scratch, Region::Torso, 0.70, 0.05)
            .expect("evidence");
        assert!(e.depth.seen < 0.75 && e.width.seen > 0.99, "{e:?}");
    }

    /// The side camera sees a forearm a quarter of a metre nearer the far wall than the
    /// trunk: the trunk's edge on the forearm's ray is found at x = 0, 2.5 cm higher than
    /// where the ray meets the forearm's plane. Moved along its ray it is the forearm's;
    /// taken where it was found it would not be.
    #[test]
    fn a_seen_edge_is_tested_on_the_limbs_own_plane() {
        let forearm = SideOccluder {
            a: glam::DVec2::new(1.0, -0.07),
            b: glam::DVec2::new(0.92, 0.09),
            radius: 0.04,
            x: -0.3,
            eye: DVec3::new(3.2, 1.25, 0.04),
        };
        // A point 4.5 cm from the forearm's axis on its plane, seen at x = 0.
        let seen = DVec3::new(0.0, 1.0217, 0.0310);
        assert!(forearm.covers_seen(seen, 0.01));
        assert!(!forearm.covers(seen.y, seen.z, 0.01));
        // On the capsule's own plane nothing moves.
        let on_plane = DVec3::new(-0.3, 0.96, 0.01);
        assert_eq!(
            forearm.covers_seen(on_plane, 0.0),
            forearm.covers(0.96, 0.01, 0.0)
        );
        // Beyond the capsule on the far side of the axis stays beyond it.
        assert!(!forearm.covers_seen(DVec3::new(0.0, 0.90, -0.08), 0.01));
    }

    #[test]
    fn only_an_edge_on_a_limbs_outline_is_the_limbs() {
        // An upper arm drawn from keypoints behind the trunk (the capsule of dev varied
        // subject 22, session 19, whose back edges at the bust were all dropped as the
        // arm's). A back edge seen 2.2 cm from the arm's axis on its plane lies 2.3 cm
        // inside its 4.5 cm radius: had the arm been there, its outline would stand
        // further back than the edge the view showed, so the edge is the trunk's.
        let upper_arm = SideOccluder {
            a: glam::DVec2::new(1.3216, -0.1085),
            b: glam::DVec2::new(1.1400, -0.1511),
            radius: 0.045,
            x: 0.3245,
            eye: DVec3::new(2.5874, 1.3100, -0.0066),
        };
        let back = DVec3::new(0.0, 1.15, -0.190);
        assert!(upper_arm.covers_seen(back, OCCLUDER_MARGIN_M));
        assert!(!upper_arm.outline_covers_seen(back, OCCLUDER_MARGIN_M));
        // An edge on the capsule's surface (4.5 cm out on its plane, moved back along the
        // ray to x = 0), or a little beyond it, is the limb's.
        let (y, z) = (1.15, -0.1488 - 0.045);
        let s = (0.0 - upper_arm.eye.x) / (upper_arm.x - upper_arm.eye.x);
        let on_surface = upper_arm.eye + (DVec3::new(upper_arm.x, y, z) - upper_arm.eye) * s;
        assert!(upper_arm.outline_covers_seen(on_surface, OCCLUDER_MARGIN_M));
        let beyond = on_surface - DVec3::new(0.0, 0.0, 0.01);
        assert!(upper_arm.outline_covers_seen(beyond, OCCLUDER_MARGIN_M));
        assert!(
            !upper_arm.outline_covers_seen(beyond - DVec3::new(0.0, 0.0, 0.02), OCCLUDER_MARGIN_M)
        );
    }

    #[test]
    fn the_trunks_own_stretch_on_the_tight_trend_is_kept_when_fingers_pull_the_loose_one() {
        // Front edges of the side view relative to the candidate's rim, every 2 cm up the
        // trunk: the candidate's own front low down, then the person's lower belly 3.5 cm
        // flatter than the candidate's, fingers 3 cm out, a stretch hidden by the
        // forearms, and a bust 1.5 cm out. The loose (known-limb) trend takes the fingers
        // and the bust in and leaves the belly more than its inward tolerance below it.
        let mut pts = Vec::new();
        let mut y = 0.8;
        for (count, d) in [(15, 0.0), (6, -0.035), (3, 0.03)] {
            for _ in 0..count {
                pts.push((y, d));
                y += 0.02;
            }
        }
        y += 0.2;
        for _ in 0..15 {
            pts.push((y, 0.015));
            y += 0.02;
        }
        let (ys, ds): (Vec<f64>, Vec<f64>) = pts.iter().copied().unzip();
        let belly = 15..21;
        let loose = outward_inliers(&ys, &ds, KNOWN_OCCLUDERS_OUTWARD_TOLERANCE_M);
        assert!(!loose[belly.clone()].iter().any(|&k| k), "{loose:?}");
        let tight = outward_inliers(&ys, &ds, Axis::Z.outward_tolerance());
        assert!(tight[belly.clone()].iter().all(|&k| k), "{tight:?}");
        // A known limb far from every edge: the limbs are known, none covers an edge.
        let far_limb = SideOccluder {
            a: glam::DVec2::new(3.0, 1.0),
            b: glam::DVec2::new(3.1, 1.0),
            radius: 0.04,
            x: 0.3,
            eye: DVec3::new(3.0, 1.0, 0.0),
        };
        let mut scratch = SectionScratch {
            centres: ys.clone(),
            edge_x: vec![[0.0; 2]; ys.len()],
            ..Default::default()
        };
        let rim = 0.12;
        let mut constraints: Vec<[Option<(f64, f64)>; 2]> =
            ds.iter().map(|&d| [Some((rim, rim + d)), None]).collect();
        drop_foreign_edges(Axis::Z, &[Some(far_limb)], &mut scratch, &mut constraints);
        let kept: Vec<bool> = constraints.iter().map(|c| c[0].is_some()).collect();
        assert!(
            kept[belly].iter().all(|&k| k),
            "the belly dropped: {kept:?}"
        );
        // The fingers stand out of the tight trend where no limb is: the part's own by
        // the known-limb rule (a belly the candidate lacks), as before.
        assert!(kept[21..24].iter().all(|&k| k), "{kept:?}");
    }

    #[test]
    fn a_limb_over_the_trunks_own_outline_does_not_hide_it() {
        // The side view's forearm keypoints put its capsule over the trunk's front edge
        // (the arm passes beside the trunk, inside its outline): where that edge keeps the
        // trunk's smooth trend (a gentle 8 mm bulge here), it is the trunk's own and is
        // followed, not filled in from the edges around it.
        let (mesh, set) = torso_cylinder(0.025);
        let bulge = |y: f64| 0.008 * (-((y - 0.70) / 0.05).powi(2) / 2.0).exp();
        let targets = front_moved(&mesh, &set, bulge);
        let forearm = SideOccluder {
            a: glam::DVec2::new(0.60, 0.085),
            b: glam::DVec2::new(0.80, 0.085),
            radius: 0.02,
            x: 0.0,
            eye: DVec3::new(3.0, 0.7, 0.0),
        };
        assert!(forearm.covers(0.70, 0.108, OCCLUDER_MARGIN_M));
        let (_, _, out) = targets_with_limb(&mesh, &set, &targets, forearm);
        let moved = front_shift(&mesh, &out, 0.68, 0.72);
        assert!(
            moved > 0.005,
            "the bulge under the limb followed by {moved}"
        );
    }

    /// Where trunk and legs share height bands (the crotch), the trunk's vertices there
    /// take the legs' depth map, so that no step opens between them; above, the trunk
    /// keeps its own. A trunk (elliptic cylinder, 0.70-1.10 m) over two legs (0-0.75 m):
    /// the side view shows the trunk's back 4 cm further back than the candidate's, the
    /// legs where they are. Before, the trunk's rows at 0.70 and 0.75 m went back with the
    /// trunk while the legs' rows beside them stayed.
    #[test]
    fn the_trunk_takes_the_legs_depth_map_where_they_share_a_band() {
        let mut mesh = crate::mesh::TriMesh::default();
        let mut labels = Vec::new();
        for (part, a, b, h, x, y) in [
            (Part::Torso, 0.17, 0.12, 0.40, 0.0, 0.70),
            (Part::LeftLeg, 0.07, 0.08, 0.75, 0.09, 0.0),
            (Part::RightLeg, 0.07, 0.08, 0.75, -0.09, 0.0),
        ] {
            let rings = (h / 0.05f64).round() as usize;
            let m = shapes::elliptic_cylinder(a, b, h, rings, 32);
            let base = mesh.positions.len() as u32;
            mesh.positions
                .extend(m.positions.iter().map(|p| *p + DVec3::new(x, y, 0.0)));
            mesh.triangles
                .extend(m.triangles.iter().map(|t| t.map(|i| i + base)));
            labels.extend(std::iter::repeat_n(part, m.positions.len()));
        }
        let calib = crate::camera::StationCalibration::nominal(640, 480, 600.0, 3.0, 0.5, 0.5);
        let set = select_controls(
            &mesh,
            &labels,
            &vec![false; mesh.vertex_count()],
            0.02,
            Variant::SliceExtremes,
            &calib.front,
            &calib.side,
        );
        let targets: Vec<Option<DVec3>> = set
            .controls
            .iter()
            .map(|c| {
                let p = mesh.positions[c.vertex as usize];
                let back = c.part == Part::Torso && c.status == Status::Back;
                Some(p - DVec3::Z * if back { 0.04 } else { 0.0 })
            })
            .collect();
        let plan = SectionPlan::new(&set);
        let mut scratch = SectionScratch::default();
        let mut out = Vec::new();
        plan.targets(&mesh.positions, &set, &targets, &[], &mut scratch, &mut out);
        // The largest depth move of the trunk's vertices in a height range.
        let moved = |y0: f64, y1: f64| {
            out.iter()
                .enumerate()
                .filter(|&(v, _)| labels[v] == Part::Torso)
                .filter_map(|(v, t)| {
                    let p = mesh.positions[v];
                    t.filter(|_| p.y >= y0 && p.y <= y1)
                        .map(|t| (t.z - p.z).abs())
                })
                .fold(0.0f64, f64::max)
        };
        let shared = moved(0.69, 0.76);
        assert!(
            shared < 1e-6,
            "the trunk's rows beside the legs moved {shared} m"
        );
        let above = moved(0.85, 1.0);
        assert!(above > 0.03, "the trunk above followed its back: {above} m");
    }

    #[test]
    fn sections_take_every_vertex_to_the_scaled_section() {
        // Template: an elliptic cylinder 0.30 x 0.20 m; targets of its extreme controls as
        // if the subject were 0.33 x 0.18 m and 1 cm further forward. Every vertex must
        // land on the scaled, shifted ellipse (the map is affine per axis).
        let (mesh, set) = torso_cylinder(0.05);
        let (sx, sz, dz) = (1.1, 0.9, 0.01);
        let targets: Vec<Option<DVec3>> = set
            .controls
            .iter()
            .map(|c| {
                let p = mesh.positions[c.vertex as usize];
                Some(DVec3::new(p.x * sx, p.y, p.z * sz + dz))
            })
            .collect();
        let plan = SectionPlan::new(&set);
        let mut scratch = SectionScratch::default();
        let mut out = Vec::new();
        plan.targets(&mesh.positions, &set, &targets, &[], &mut scratch, &mut out);
        let mut n = 0;
        for (v, t) in out.iter().enumerate() {
            let Some(t) = t else { continue };
            let p = mesh.positions[v];
            assert!((t.x - p.x * sx).abs() < 1e-9, "x {} vs {}", t.x, p.x * sx);
            assert!(
                (t.z - (p.z * sz + dz)).abs() < 1e-9,
                "z {} vs {}",
                t.z,
                p.z * sz + dz
            );
            assert_eq!(t.y, p.y);
            n += 1;
        }
        assert!(
            n > mesh.vertex_count() * 9 / 10,
            "{n} of {}",
            mesh.vertex_count()
        );
    }
}
