//! Body measurements on a standing body mesh: stature and tape girths after
//! ISO 8559-1:2017, found geometrically on any topology.
//!
//! # Conventions
//! - Input: a [`TriMesh`] in the station frame (`shared/spec/formats.md`): metres, +Y up,
//!   the subject faces +Z, +X is the subject's LEFT, soles on y = 0, standing in an
//!   A-pose (arms away from the torso below the armpits, legs apart below the crotch).
//!   Nothing here uses vertex indices: levels are found from the sections themselves.
//! - Output: lengths in millimetres (`*_mm`), heights of levels in metres (`*_m`, station
//!   y, i.e. above the floor when the soles are on y = 0).
//! - A **girth** is a tape measure: the perimeter of the convex hull of a horizontal
//!   cross-section loop, because a tape bridges hollows (between the breasts, the
//!   navel, the spine groove). Sections come from slicing the mesh at height y and
//!   splitting the cut into connected loops (torso, arms, legs are separate loops).
//!
//! # Landmark levels (found in this order)
//! - **Body axis** x: the middle of the x-extent of the central loop (below) through
//!   the bounding box centre at [`TORSO_PROBE_OF_STATURE`] of the stature (always the
//!   abdomen on an adult: crotch height is 0.44-0.50 of stature).
//! - Loops are **central** (torso) when the body axis crosses the middle 60 % of their
//!   x-extent ([`slicer::CENTRAL_MARGIN_OF_WIDTH`]), else **left** (+X) or **right** by
//!   the middle of their extent: thighs that press through each other on a
//!   self-intersecting mesh stay two legs.
//! - **Crotch** (`levels.crotch_m`): the highest level without a central loop, i.e. the
//!   lower body is two separate leg loops. Searched downward from the probe in
//!   [`COARSE_STEP_M`] steps, then bisected to [`LEVEL_TOLERANCE_M`].
//! - **Armpit** (`levels.armpit_m`): the top of the highest run of levels (between the
//!   crotch and [`ARMPIT_SEARCH_TOP_OF_STATURE`] of the stature, below the ears) at which
//!   both arms are loops separate from the torso, and above which the torso loop reaches
//!   over where the arms were (they have joined it). Taking the highest run makes a
//!   forearm or hand that touches the hip lower down harmless; the joining test rejects
//!   shoulder tops that slice as two caps beside a narrower neck. Found by scanning down
//!   from the search top in [`COARSE_STEP_M`] steps, then bisected to
//!   [`LEVEL_TOLERANCE_M`]. The torso's x-extent just below it gives the armpit x
//!   positions.
//! - `span` = armpit - crotch: the other levels are fractions of it, so they scale with
//!   the trunk rather than with the legs.
//!
//! # Measurements
//! - **Stature** (ISO 8559-1 5.1.1): max y - min y of the mesh (soles to vertex).
//! - **Chest girth** (5.3.4: horizontal girth under the armpits, over the shoulder
//!   blades and across the chest/bust prominence): the maximum torso girth in the band
//!   [armpit - [`CHEST_BAND_OF_SPAN`] span, armpit - [`CHEST_TOP_OFFSET_OF_SPAN`] span].
//!   A quarter of the trunk below the armpit reaches the bust point of a full bust; the
//!   small top offset keeps the tape off the armpit hollow itself. If an arm touches
//!   the torso inside the band, the torso loop is cut at the armpit x positions widened
//!   by [`ARM_CUT_MARGIN_M`] (the tape runs under the arms, not around them).
//! - **Waist girth** (5.3.10: natural waist, between the lowest rib and the top of the
//!   hip bone): the least torso girth in [crotch + [`WAIST_BAND_OF_SPAN`].0 span,
//!   crotch + [`WAIST_BAND_OF_SPAN`].1 span]. Roughly (from typical adult proportions,
//!   not a cited table), the iliac crest sits near half of the crotch-armpit span above
//!   the crotch and the lowest rib near two thirds; the band is widened on both sides so
//!   that it holds the natural waist of short- and long-waisted people, and the minimum
//!   does the locating. When the least girth lies on the band's edge there is no
//!   natural waist to find (a belly rounder than the ribs): the tape then goes at
//!   [`WAIST_NO_NARROWING_OF_SPAN`], midway between iliac crest and lowest rib. On 24
//!   MakeHuman adults (young/old, female/male, every muscle/weight extreme) the least
//!   girth fell between 0.47 and 0.80 of the span; only the most obese reached the
//!   band's top, under the ribs.
//! - **Hip girth** (5.3.13: horizontal girth at the level of greatest buttock
//!   prominence): the torso girth at the middle of the buttocks' bulge between the
//!   crotch and the waist: the run of levels around the one where the torso reaches
//!   furthest back (least z) whose back lies within [`HIP_PLATEAU_M`] of that point (on
//!   a round seat the single deepest level wanders along a nearly flat back line). Not
//!   the maximum girth of that band: just above the crotch the torso loop holds the
//!   tops of both thighs, whose hull is often the widest section of all and is not
//!   what a tape round the buttocks reads.
//! - **Thigh girth, left and right** (5.3.20: horizontal girth of the thigh just below
//!   the gluteal fold): the hull girth of each leg loop [`THIGH_DROP_OF_STATURE`] of
//!   the stature below the crotch (the gluteal fold lies a few centimetres below the
//!   crotch). Left is the loop on the +X side of the body axis.
//! - **Torso profile**: torso girth every ~[`PROFILE_STEP_M`] from the crotch to the
//!   armpit (at the middles of equal steps).
//!
//! Chest, waist and hip levels are first picked on the profile, then refined by
//! golden-section search within one profile step around the pick, to
//! [`REFINE_TOLERANCE_M`].
//!
//! # Speed
//! A [`Measurer`] keeps the triangles' edge table (while the topology stays), a height
//! index of the triangles and all section buffers between calls: each section visits
//! only the triangles near its level, and [`Measurer::measure_into`] allocates nothing
//! once warm. The free [`measure`] and [`girth_at`] use one such `Measurer` per thread.

pub mod cli;
pub mod slicer;

use crate::mesh::TriMesh;
use glam::DVec3;
use serde::{Deserialize, Serialize};
use slicer::{HullStats, LevelIndex, Placement, SectionScratch};

pub use cli::{run, MeasureArgs};

/// Height (fraction of stature above the soles) where the torso is certainly one loop.
pub const TORSO_PROBE_OF_STATURE: f64 = 0.6;
/// The crotch search gives up below this fraction of the stature.
pub const CROTCH_SEARCH_BOTTOM_OF_STATURE: f64 = 0.3;
/// The armpit search stops at this fraction of the stature (shoulders are at about
/// 0.82, the ears at about 0.93: ear loops must not pass for arms).
pub const ARMPIT_SEARCH_TOP_OF_STATURE: f64 = 0.85;
/// Step of the coarse level searches, metres.
pub const COARSE_STEP_M: f64 = 0.02;
/// Bisection tolerance of the crotch and armpit levels, metres.
pub const LEVEL_TOLERANCE_M: f64 = 1e-4;
/// How far below a found level (crotch, armpit) its section is read: the legs just
/// under the crotch, the torso's x-extent (armpit x positions) just under the armpit.
pub const CLEARANCE_BELOW_LEVEL_M: f64 = 0.002;
/// Chest band depth below the armpit, fraction of the crotch-armpit span.
pub const CHEST_BAND_OF_SPAN: f64 = 0.25;
/// Top of the chest band below the armpit, fraction of the span.
pub const CHEST_TOP_OFFSET_OF_SPAN: f64 = 0.01;
/// Margin added outside the armpit x positions before cutting off a touching arm.
pub const ARM_CUT_MARGIN_M: f64 = 0.005;
/// Waist band, fractions of the span above the crotch.
pub const WAIST_BAND_OF_SPAN: (f64, f64) = (0.45, 0.8);
/// Waist level, fraction of the span above the crotch, when the torso has no narrowing
/// inside the waist band: midway between the iliac crest (~0.5) and the lowest rib
/// (~0.67), the fallback tape position of the WHO waist protocol.
pub const WAIST_NO_NARROWING_OF_SPAN: f64 = 0.58;
/// Depth tolerance of the buttocks' bulge, metres: levels whose back is within this of
/// the most posterior point belong to the bulge whose middle is the hip level.
pub const HIP_PLATEAU_M: f64 = 0.003;
/// Thigh level below the crotch, fraction of the stature.
pub const THIGH_DROP_OF_STATURE: f64 = 0.03;
/// Torso profile spacing, metres (the exact step divides the span evenly).
pub const PROFILE_STEP_M: f64 = 0.01;
/// Bracket width at which the local refinement around a picked level stops, metres.
pub const REFINE_TOLERANCE_M: f64 = 0.5e-3;

const MM_PER_M: f64 = 1000.0;

/// Heights (station y, metres) of the levels the measurements were taken at.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MeasurementLevels {
    pub crotch_m: f64,
    pub armpit_m: f64,
    pub chest_m: f64,
    pub waist_m: f64,
    pub hip_m: f64,
    pub thigh_m: f64,
}

/// One sample of the torso girth profile.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct GirthSample {
    pub height_m: f64,
    pub girth_mm: f64,
}

/// Stature and tape girths of one body (see the module docs for the definitions).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Measurements {
    pub stature_mm: f64,
    pub chest_girth_mm: f64,
    pub waist_girth_mm: f64,
    pub hip_girth_mm: f64,
    pub thigh_girth_left_mm: f64,
    pub thigh_girth_right_mm: f64,
    pub levels: MeasurementLevels,
    /// Torso girth every ~[`PROFILE_STEP_M`] from the crotch to the armpit, upward.
    pub torso_profile: Vec<GirthSample>,
}

impl Measurements {
    /// The `measurements_mm` object of `report.json` (`shared/spec/formats.md`): keys
    /// `stature`, `chest_girth`, `waist_girth`, `hip_girth`, `thigh_girth_left`,
    /// `thigh_girth_right`, values in millimetres.
    pub fn to_report_map(&self) -> serde_json::Map<String, serde_json::Value> {
        let mut m = serde_json::Map::new();
        for (k, v) in [
            ("stature", self.stature_mm),
            ("chest_girth", self.chest_girth_mm),
            ("waist_girth", self.waist_girth_mm),
            ("hip_girth", self.hip_girth_mm),
            ("thigh_girth_left", self.thigh_girth_left_mm),
            ("thigh_girth_right", self.thigh_girth_right_mm),
        ] {
            m.insert(k.to_string(), serde_json::json!(v));
        }
        m
    }
}

/// Why a mesh could not be measured.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum MeasureError {
    #[error("the mesh has no triangles")]
    EmptyMesh,
    #[error("invalid mesh: {0}")]
    InvalidMesh(String),
    #[error("no torso: no central section loop about the body axis at y = {y_m:.3} m ({TORSO_PROBE_OF_STATURE} of the stature); not a standing body?")]
    NoTorso { y_m: f64 },
    #[error("no crotch: the lower body is not two separate legs anywhere between y = {bottom_m:.3} m and {top_m:.3} m; legs together or not a standing body?")]
    NoCrotch { bottom_m: f64, top_m: f64 },
    #[error("no {side} leg loop at y = {y_m:.3} m")]
    NoLeg { side: BodySide, y_m: f64 },
    #[error("no armpit: the arms are never both separate from the torso between y = {bottom_m:.3} m and {top_m:.3} m (arms against the body, or not an A-pose?)")]
    NoArmpit { bottom_m: f64, top_m: f64 },
    #[error("no torso loop at y = {y_m:.3} m while measuring {what}")]
    NoTorsoAt { y_m: f64, what: &'static str },
}

/// The subject's side: left is +X in the station frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum BodySide {
    Left,
    Right,
}

impl std::fmt::Display for BodySide {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            BodySide::Left => "left",
            BodySide::Right => "right",
        })
    }
}

/// Which loop(s) of a horizontal section a girth is taken around.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum LoopSelector {
    /// The hull of every loop of the section together.
    Whole,
    /// The central loop about x = `axis_x` (see [`slicer::Placement`]; the largest by
    /// bounding box if several are, e.g. a cavity inside the body).
    Torso { axis_x: f64 },
    /// As [`LoopSelector::Torso`], keeping only the part of the loop with x in
    /// [`x_min`, `x_max`]: cuts off an arm that touches the torso.
    TorsoClipped { axis_x: f64, x_min: f64, x_max: f64 },
    /// The largest loop (by bounding box) placed on `side` of x = `axis_x` (a leg,
    /// below the crotch; left = +X).
    Side { side: BodySide, axis_x: f64 },
}

thread_local! {
    /// The [`Measurer`] behind the free functions: one per thread, so that calling
    /// [`measure`] every frame (or [`girth_at`] at many levels of one mesh) reuses the
    /// edge table, the height index and the buffers, as an owned `Measurer` would.
    static THREAD_MEASURER: std::cell::RefCell<Measurer> = std::cell::RefCell::new(Measurer::new());
}

fn with_thread_measurer<R>(f: impl FnOnce(&mut Measurer) -> R) -> R {
    THREAD_MEASURER.with(|m| match m.try_borrow_mut() {
        Ok(mut m) => f(&mut m),
        // Only reachable if `f` itself calls back in here: use a fresh one.
        Err(_) => f(&mut Measurer::new()),
    })
}

/// Tape girth (metres) of the section of `mesh` at height `y` around the loop(s) chosen
/// by `selector`; `None` when no such loop exists or the mesh is invalid.
///
/// Uses this thread's cached [`Measurer`]: the first call on a mesh builds its height
/// index (O(#F)), further calls on the same mesh only cut one section.
pub fn girth_at(mesh: &TriMesh, y: f64, selector: LoopSelector) -> Option<f64> {
    with_thread_measurer(|m| m.girth_at(mesh, y, selector))
}

/// Measures a standing body (see the module docs).
///
/// # Errors
/// [`MeasureError`] when the mesh is empty or invalid, or is not a standing body in an
/// A-pose (no torso, no gap between the legs, arms never apart from the torso).
///
/// Uses this thread's cached [`Measurer`] (see [`girth_at`]); own a `Measurer` and call
/// [`Measurer::measure_into`] to also reuse the result's memory.
pub fn measure(mesh: &TriMesh) -> Result<Measurements, MeasureError> {
    with_thread_measurer(|m| m.measure(mesh))
}

/// A girth at one level, with the loop's extent (internal to the level searches).
#[derive(Debug, Clone, Copy)]
struct Sample {
    y: f64,
    hull: HullStats,
}

/// What a local refinement looks for.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Objective {
    MaxGirth,
    MinGirth,
    /// The most posterior torso point (least z).
    MinZ,
}

impl Objective {
    fn key(self, h: &HullStats) -> f64 {
        match self {
            Objective::MaxGirth => -h.perimeter_m,
            Objective::MinGirth => h.perimeter_m,
            Objective::MinZ => h.z_min,
        }
    }
}

/// Measurement executor: owns the triangle height index and the section buffers, so
/// measuring a fitted body every frame allocates only the result.
#[derive(Debug, Clone, Default)]
pub struct Measurer {
    index: LevelIndex,
    section: SectionScratch,
    profile: Vec<Sample>,
    /// Positions the index was built for (`loaded` once built).
    loaded_positions: Vec<DVec3>,
    loaded: bool,
    y_min: f64,
    y_max: f64,
    x_mid: f64,
}

impl Measurer {
    pub fn new() -> Self {
        Self::default()
    }

    /// Checks the mesh and rebuilds the height index for it, unless it is the mesh the
    /// index was last built for (same triangles and bit-identical positions).
    fn load(&mut self, mesh: &TriMesh) -> Result<(), MeasureError> {
        if self.loaded
            && self.loaded_positions == mesh.positions
            && self.index.topology_matches(&mesh.triangles)
        {
            return Ok(());
        }
        self.loaded = false;
        if mesh.triangles.is_empty() || mesh.positions.is_empty() {
            return Err(MeasureError::EmptyMesh);
        }
        let n = mesh.positions.len() as u32;
        if let Some(i) = mesh
            .triangles
            .iter()
            .position(|t| t.iter().any(|&v| v >= n))
        {
            return Err(MeasureError::InvalidMesh(format!(
                "triangle {i} indexes a vertex beyond {n}"
            )));
        }
        if mesh.positions.iter().any(|p| !p.is_finite()) {
            return Err(MeasureError::InvalidMesh(
                "a vertex position is not finite".into(),
            ));
        }
        // Bounds of the vertices in use (stray unused vertices do not count).
        let (mut lo, mut hi) = (DVec3::INFINITY, DVec3::NEG_INFINITY);
        for t in &mesh.triangles {
            for &v in t {
                let p = mesh.positions[v as usize];
                lo = lo.min(p);
                hi = hi.max(p);
            }
        }
        self.y_min = lo.y;
        self.y_max = hi.y;
        self.x_mid = 0.5 * (lo.x + hi.x);
        self.index.rebuild(mesh, lo.y, hi.y);
        self.loaded_positions.clone_from(&mesh.positions);
        self.loaded = true;
        Ok(())
    }

    fn cut(&mut self, mesh: &TriMesh, y: f64) {
        self.section.cut(mesh, &self.index, y);
    }

    /// Index of the torso loop of the last section: the largest (by bounding box, a
    /// cheap stand-in for area) central loop about x = `axis_x`.
    fn torso_loop(&self, axis_x: f64) -> Option<usize> {
        self.section
            .loops()
            .iter()
            .enumerate()
            .filter(|(_, l)| l.placement(axis_x) == Placement::Central)
            .max_by(|a, b| box_area(a.1).total_cmp(&box_area(b.1)))
            .map(|(i, _)| i)
    }

    /// Whether the last section has a loop placed left and one placed right of the
    /// axis (legs below the crotch, arms between the hands and the armpits).
    fn loops_on_both_sides(&self, axis_x: f64) -> bool {
        let loops = self.section.loops();
        loops.iter().any(|l| l.placement(axis_x) == Placement::Left)
            && loops
                .iter()
                .any(|l| l.placement(axis_x) == Placement::Right)
    }

    /// With a torso loop and loops on both sides of it in the last section: the
    /// innermost x of the left loops and of the right loops (where the arms begin).
    fn arm_inner_edges(&self, axis_x: f64) -> Option<(f64, f64)> {
        self.torso_loop(axis_x)?;
        let loops = self.section.loops();
        let left = loops
            .iter()
            .filter(|l| l.placement(axis_x) == Placement::Left)
            .map(|l| l.x_min)
            .fold(f64::INFINITY, f64::min);
        let right = loops
            .iter()
            .filter(|l| l.placement(axis_x) == Placement::Right)
            .map(|l| l.x_max)
            .fold(f64::NEG_INFINITY, f64::max);
        (left.is_finite() && right.is_finite()).then_some((left, right))
    }

    fn select(&mut self, selector: LoopSelector) -> Option<HullStats> {
        match selector {
            LoopSelector::Whole => self.section.whole_hull(),
            LoopSelector::Torso { axis_x } => {
                let i = self.torso_loop(axis_x)?;
                self.section.loop_hull(i, None)
            }
            LoopSelector::TorsoClipped {
                axis_x,
                x_min,
                x_max,
            } => {
                let i = self.torso_loop(axis_x)?;
                let info = self.section.loops()[i];
                let clip = (info.x_min < x_min || info.x_max > x_max).then_some((x_min, x_max));
                self.section.loop_hull(i, clip)
            }
            LoopSelector::Side { side, axis_x } => {
                let on_side = |l: &slicer::LoopInfo| match side {
                    BodySide::Left => l.placement(axis_x) == Placement::Left,
                    BodySide::Right => l.placement(axis_x) == Placement::Right,
                };
                let i = self
                    .section
                    .loops()
                    .iter()
                    .enumerate()
                    .filter(|(_, l)| on_side(l))
                    .max_by(|a, b| box_area(a.1).total_cmp(&box_area(b.1)))
                    .map(|(i, _)| i)?;
                self.section.loop_hull(i, None)
            }
        }
    }

    /// Tape girth (metres) at height `y` around the loop(s) chosen by `selector`, as
    /// [`girth_at`]; the height index is rebuilt only when the mesh changed.
    pub fn girth_at(&mut self, mesh: &TriMesh, y: f64, selector: LoopSelector) -> Option<f64> {
        self.load(mesh).ok()?;
        self.hull_at(mesh, y, selector).map(|h| h.perimeter_m)
    }

    /// Cuts at `y` and returns the hull of the selected loop.
    fn hull_at(&mut self, mesh: &TriMesh, y: f64, selector: LoopSelector) -> Option<HullStats> {
        self.cut(mesh, y);
        self.select(selector)
    }

    /// Bisects between `lo` (predicate false) and `hi` (predicate true) to
    /// [`LEVEL_TOLERANCE_M`]; returns the final (lo, hi).
    fn bisect(
        &mut self,
        mesh: &TriMesh,
        mut lo: f64,
        mut hi: f64,
        pred: impl Fn(&Self) -> bool,
    ) -> (f64, f64) {
        while (hi - lo).abs() > LEVEL_TOLERANCE_M {
            let mid = 0.5 * (lo + hi);
            self.cut(mesh, mid);
            if pred(self) {
                hi = mid;
            } else {
                lo = mid;
            }
        }
        (lo, hi)
    }

    /// Golden-section search of `objective` over [max(band.0, y0 - step),
    /// min(band.1, y0 + step)] around the profile pick `start`, to [`REFINE_TOLERANCE_M`];
    /// returns the best level seen (`start` if none is better).
    fn refine(
        &mut self,
        mesh: &TriMesh,
        start: Sample,
        step: f64,
        band: (f64, f64),
        selector: &dyn Fn(f64) -> LoopSelector,
        objective: Objective,
    ) -> Sample {
        let inv_phi = 0.5 * (5f64.sqrt() - 1.0);
        let mut best = start;
        let eval = |m: &mut Self, y: f64, best: &mut Sample| -> f64 {
            match m.hull_at(mesh, y, selector(y)) {
                Some(h) => {
                    let k = objective.key(&h);
                    if k < objective.key(&best.hull) {
                        *best = Sample { y, hull: h };
                    }
                    k
                }
                None => f64::INFINITY,
            }
        };
        let (mut a, mut b) = (band.0.max(start.y - step), band.1.min(start.y + step));
        // The optimum may sit on the band's edge (chest just under the armpit): try it.
        for edge in [band.0, band.1] {
            if (edge - a).abs() < 1e-12 || (edge - b).abs() < 1e-12 {
                eval(self, edge, &mut best);
            }
        }
        let mut c = b - inv_phi * (b - a);
        let mut d = a + inv_phi * (b - a);
        let (mut fc, mut fd) = (eval(self, c, &mut best), eval(self, d, &mut best));
        while b - a > REFINE_TOLERANCE_M {
            if fc < fd {
                b = d;
                d = c;
                fd = fc;
                c = b - inv_phi * (b - a);
                fc = eval(self, c, &mut best);
            } else {
                a = c;
                c = d;
                fc = fd;
                d = a + inv_phi * (b - a);
                fd = eval(self, d, &mut best);
            }
        }
        best
    }

    /// Measures a standing body; see [`measure`] and the module docs.
    ///
    /// # Errors
    /// As [`measure`].
    pub fn measure(&mut self, mesh: &TriMesh) -> Result<Measurements, MeasureError> {
        let mut out = Measurements {
            stature_mm: 0.0,
            chest_girth_mm: 0.0,
            waist_girth_mm: 0.0,
            hip_girth_mm: 0.0,
            thigh_girth_left_mm: 0.0,
            thigh_girth_right_mm: 0.0,
            levels: MeasurementLevels {
                crotch_m: 0.0,
                armpit_m: 0.0,
                chest_m: 0.0,
                waist_m: 0.0,
                hip_m: 0.0,
                thigh_m: 0.0,
            },
            torso_profile: Vec::new(),
        };
        self.measure_into(mesh, &mut out)?;
        Ok(out)
    }

    /// As [`Measurer::measure`], writing into `out` and reusing its profile's memory:
    /// with a warm `Measurer` and `out`, a frame allocates nothing. On error `out` is
    /// left unchanged.
    ///
    /// # Errors
    /// As [`measure`].
    pub fn measure_into(
        &mut self,
        mesh: &TriMesh,
        out: &mut Measurements,
    ) -> Result<(), MeasureError> {
        self.load(mesh)?;
        let (y_min, y_max) = (self.y_min, self.y_max);
        let stature = y_max - y_min;
        let bounds_mid_x = self.x_mid;
        // Body axis from the abdomen section.
        let probe_y = y_min + TORSO_PROBE_OF_STATURE * stature;
        self.cut(mesh, probe_y);
        let probe = self
            .torso_loop(bounds_mid_x)
            .ok_or(MeasureError::NoTorso { y_m: probe_y })?;
        let info = self.section.loops()[probe];
        let axis_x = 0.5 * (info.x_min + info.x_max);
        let has_torso = move |m: &Self| m.torso_loop(axis_x).is_some();

        // Crotch: highest level without a loop across the axis, below the probe.
        let bottom = y_min + CROTCH_SEARCH_BOTTOM_OF_STATURE * stature;
        let mut y = probe_y;
        let crotch = loop {
            let below = y - COARSE_STEP_M;
            if below < bottom {
                return Err(MeasureError::NoCrotch {
                    bottom_m: bottom,
                    top_m: probe_y,
                });
            }
            self.cut(mesh, below);
            if !has_torso(self) {
                break self.bisect(mesh, below, y, has_torso).0;
            }
            y = below;
        };
        let leg_y = crotch - CLEARANCE_BELOW_LEVEL_M;
        self.cut(mesh, leg_y);
        for (side, ok) in [
            (
                BodySide::Left,
                self.section
                    .loops()
                    .iter()
                    .any(|l| l.placement(axis_x) == Placement::Left),
            ),
            (
                BodySide::Right,
                self.section
                    .loops()
                    .iter()
                    .any(|l| l.placement(axis_x) == Placement::Right),
            ),
        ] {
            if !ok {
                return Err(MeasureError::NoLeg { side, y_m: leg_y });
            }
        }

        // Armpit: scanning down from the search top, the first level where both arms
        // are loops apart from the torso, just below a level where the torso loop
        // reaches over where one of those arms is (it has joined; if the arms join at
        // different heights, this is the lower armpit). Shoulder tops that slice as
        // separate caps beside the neck fail the second test: above them the neck is
        // narrower, not wider.
        let arms_apart =
            move |m: &Self| m.torso_loop(axis_x).is_some() && m.loops_on_both_sides(axis_x);
        let top = y_min + ARMPIT_SEARCH_TOP_OF_STATURE * stature;
        let no_armpit = MeasureError::NoArmpit {
            bottom_m: crotch,
            top_m: top,
        };
        let mut above: Option<(f64, f64, f64)> = None;
        let mut y = top;
        let (a, b) = loop {
            if y <= crotch {
                return Err(no_armpit);
            }
            self.cut(mesh, y);
            match self.arm_inner_edges(axis_x) {
                Some((left_inner, right_inner)) => {
                    if let Some((y_above, x_min, x_max)) = above {
                        if x_max >= left_inner || x_min <= right_inner {
                            break (y, y_above);
                        }
                    }
                    above = None;
                }
                None => {
                    above = self.torso_loop(axis_x).map(|i| {
                        let l = self.section.loops()[i];
                        (y, l.x_min, l.x_max)
                    });
                }
            }
            y -= COARSE_STEP_M;
        };
        let not_apart = move |m: &Self| !arms_apart(m);
        let (_, armpit) = self.bisect(mesh, a, b, not_apart);
        let armpit_torso = self
            .hull_at(
                mesh,
                armpit - CLEARANCE_BELOW_LEVEL_M,
                LoopSelector::Torso { axis_x },
            )
            .ok_or(MeasureError::NoTorsoAt {
                y_m: armpit - CLEARANCE_BELOW_LEVEL_M,
                what: "armpit",
            })?;
        let span = armpit - crotch;

        // Torso profile; chest-band levels cut off touching arms at the armpit x.
        let chest_band = (
            armpit - CHEST_BAND_OF_SPAN * span,
            armpit - CHEST_TOP_OFFSET_OF_SPAN * span,
        );
        let cut_x = (
            armpit_torso.x_min - ARM_CUT_MARGIN_M,
            armpit_torso.x_max + ARM_CUT_MARGIN_M,
        );
        let torso_selector = move |y: f64| {
            if y >= chest_band.0 {
                LoopSelector::TorsoClipped {
                    axis_x,
                    x_min: cut_x.0,
                    x_max: cut_x.1,
                }
            } else {
                LoopSelector::Torso { axis_x }
            }
        };
        let n = ((span / PROFILE_STEP_M).round() as usize).max(2);
        let step = span / n as f64;
        let mut profile = std::mem::take(&mut self.profile);
        profile.clear();
        for k in 0..n {
            let y = crotch + (k as f64 + 0.5) * step;
            if let Some(hull) = self.hull_at(mesh, y, torso_selector(y)) {
                profile.push(Sample { y, hull });
            }
        }
        let pick = |band: (f64, f64), objective: Objective| {
            profile
                .iter()
                .filter(|s| s.y >= band.0 && s.y <= band.1)
                .min_by(|a, b| objective.key(&a.hull).total_cmp(&objective.key(&b.hull)))
                .copied()
        };

        let waist_band = (
            crotch + WAIST_BAND_OF_SPAN.0 * span,
            crotch + WAIST_BAND_OF_SPAN.1 * span,
        );
        let waist0 = pick(waist_band, Objective::MinGirth).ok_or(MeasureError::NoTorsoAt {
            y_m: waist_band.0,
            what: "waist",
        })?;
        let chest0 = pick(chest_band, Objective::MaxGirth).ok_or(MeasureError::NoTorsoAt {
            y_m: chest_band.0,
            what: "chest",
        })?;
        let mut waist = self.refine(
            mesh,
            waist0,
            step,
            waist_band,
            &torso_selector,
            Objective::MinGirth,
        );
        // No narrowing inside the band (the least girth is on its edge, as under an
        // obese belly): take the level midway between iliac crest and lowest rib.
        if (waist.y - waist_band.0).min(waist_band.1 - waist.y) <= REFINE_TOLERANCE_M {
            let y = crotch + WAIST_NO_NARROWING_OF_SPAN * span;
            let hull = self
                .hull_at(mesh, y, torso_selector(y))
                .ok_or(MeasureError::NoTorsoAt {
                    y_m: y,
                    what: "waist",
                })?;
            waist = Sample { y, hull };
        }
        let chest = self.refine(
            mesh,
            chest0,
            step,
            chest_band,
            &torso_selector,
            Objective::MaxGirth,
        );
        let hip_band = (crotch + LEVEL_TOLERANCE_M, waist.y);
        let hip0 = pick(hip_band, Objective::MinZ).ok_or(MeasureError::NoTorsoAt {
            y_m: crotch,
            what: "hip",
        })?;
        let deepest = self.refine(mesh, hip0, step, hip_band, &torso_selector, Objective::MinZ);
        // The buttocks' bulge: the profile levels next to the deepest one that reach
        // within HIP_PLATEAU_M of it. Its middle is the prominence; on a round or flat
        // seat the deepest point alone wanders along the bulge.
        let within = |s: &Sample| {
            s.y >= hip_band.0
                && s.y <= hip_band.1
                && s.hull.z_min <= deepest.hull.z_min + HIP_PLATEAU_M
        };
        let i0 = profile
            .iter()
            .position(|s| s.y == hip0.y)
            .unwrap_or_default();
        let (mut lo, mut hi) = (i0, i0);
        while lo > 0 && within(&profile[lo - 1]) {
            lo -= 1;
        }
        while hi + 1 < profile.len() && within(&profile[hi + 1]) {
            hi += 1;
        }
        let hip = if hi > lo {
            let y = 0.5 * (profile[lo].y + profile[hi].y);
            let hull = self
                .hull_at(mesh, y, torso_selector(y))
                .ok_or(MeasureError::NoTorsoAt {
                    y_m: y,
                    what: "hip",
                })?;
            Sample { y, hull }
        } else {
            deepest
        };

        self.profile = profile;

        // Thighs just below the gluteal fold.
        let thigh_y = crotch - THIGH_DROP_OF_STATURE * stature;
        self.cut(mesh, thigh_y);
        let mut thigh = [0.0; 2];
        for (slot, side) in thigh.iter_mut().zip([BodySide::Left, BodySide::Right]) {
            *slot = self
                .select(LoopSelector::Side { side, axis_x })
                .ok_or(MeasureError::NoLeg { side, y_m: thigh_y })?
                .perimeter_m;
        }

        out.stature_mm = stature * MM_PER_M;
        out.chest_girth_mm = chest.hull.perimeter_m * MM_PER_M;
        out.waist_girth_mm = waist.hull.perimeter_m * MM_PER_M;
        out.hip_girth_mm = hip.hull.perimeter_m * MM_PER_M;
        out.thigh_girth_left_mm = thigh[0] * MM_PER_M;
        out.thigh_girth_right_mm = thigh[1] * MM_PER_M;
        out.levels = MeasurementLevels {
            crotch_m: crotch,
            armpit_m: armpit,
            chest_m: chest.y,
            waist_m: waist.y,
            hip_m: hip.y,
            thigh_m: thigh_y,
        };
        out.torso_profile.clear();
        out.torso_profile
            .extend(self.profile.iter().map(|s| GirthSample {
                height_m: s.y,
                girth_mm: s.hull.perimeter_m * MM_PER_M,
            }));
        Ok(())
    }
}

fn box_area(l: &slicer::LoopInfo) -> f64 {
    (l.x_max - l.x_min) * (l.z_max - l.z_min)
}
