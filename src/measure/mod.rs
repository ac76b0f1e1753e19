//! Body measurements on a standing body mesh: stature and tape girths, implementing
//! the operational definitions of `shared/spec/measurements.md` (the station's
//! `measure`, its reported values, the synthetic truth and every evaluation use them).
//!
//! # Conventions
//! - Input: a [`TriMesh`] in the station frame (`shared/spec/formats.md`): metres, +Y up,
//!   the subject faces +Z, +X is the subject's LEFT, standing in an A-pose. Nothing here
//!   uses vertex indices: levels are found from the sections themselves.
//! - **Heights** are measured from the mesh's own lowest point y0 (a body floating above
//!   the floor is measured as if it stood on it); fractions of the stature S are taken
//!   from there. Reported levels (`levels.*_m`) are station y, i.e. y0 + height.
//! - Output lengths in millimetres (`*_mm`).
//!
//! # Building blocks (spec "Building blocks")
//! - **Slice** at y: the cut of the surface by the plane y, split into **loops** by the
//!   connectivity of the cut segments (segments of triangles sharing a crossed edge are
//!   one loop; a hole leaves an open piece, a non-manifold edge joins the pieces that
//!   meet there). See [`slicer`].
//! - **Girth** of a loop: the perimeter of the convex hull of its points in (x, z).
//! - **Body axis** x: the x of the centroid of the hull of the largest loop (hull area)
//!   of the slice at [`AXIS_PROBE_OF_STATURE`] S.
//! - **Torso loop**: the loop reaching at least [`TORSO_REACH_OF_STATURE`] S to each
//!   side of the axis (several: the largest hull area). **Side loops** are all others,
//!   left (+X) or right by the x of their hull centroid; a side's **thigh loop** is its
//!   largest side loop (hull area) below the crotch.
//!
//! # Levels
//! - **Crotch**: the lowest height, searched upwards from
//!   [`CROTCH_SEARCH_BOTTOM_OF_STATURE`] S on a [`GRID_STEP_M`] grid, with a torso loop;
//!   then bisection to [`FINE_STEP_M`] (the reported level has a torso loop).
//! - **Armpit**: the highest height, searched downwards from
//!   [`ARMPIT_SEARCH_TOP_OF_STATURE`] S (not below [`ARMPIT_SEARCH_BOTTOM_OF_STATURE`]
//!   S), with a torso loop and on each side a side loop of girth at least
//!   [`ARM_MIN_GIRTH_OF_STATURE`] S; same grid and bisection.
//!
//! # Measurements (spec table; every extremum on a [`GRID_STEP_M`] grid, refined on a
//! [`FINE_STEP_M`] grid within one grid step around the best grid point)
//! - `stature`: highest minus lowest point.
//! - `chest_girth`: the largest torso girth from the armpit down to
//!   [`CHEST_BAND_OF_STATURE`] S below it.
//! - Waist and hip, in the spec's order: (1) the least torso girth between crotch and
//!   chest gives a first waist level; (2) `hip_girth_max`: the largest torso girth
//!   between the crotch and that level; (3) `waist_girth`: the least torso girth between
//!   the `hip_girth_max` level and the chest level; (4) `hip_girth`: the torso girth
//!   where the torso loop reaches furthest back (least z) between crotch and waist.
//! - `thigh_girth_left` / `_right`: the largest girth of that side's thigh loop from
//!   [`THIGH_BAND_BELOW_CROTCH_M`].0 to .1 below the crotch.
//!
//! The band grids are anchored at the crotch (torso bands: crotch + k step up to the
//! armpit, which is added as the last sample; thigh band: from its top down), and a
//! band's own ends count as grid points. The torso grid is sliced once and serves
//! every torso band (it is also returned as [`Measurements::torso_profile`]).
//!
//! # Speed
//! A [`Measurer`] keeps the triangles' edge table (while the topology stays), a height
//! index of the triangles (listing only those near the heights a measurement cuts, from
//! the thigh band under the lowest crotch searched to the armpit search's top: the head
//! and lower legs, about half a body's triangles, are not indexed) and all section
//! buffers between calls: each slice visits only the triangles near its level, and
//! [`Measurer::measure_into`] allocates nothing once warm. Torso questions (crotch scan, torso grid, band refinements) cut only the loops
//! across the plane x = axis ([`slicer::SectionScratch::cut_across_x`]: the same loops,
//! arms and hands skipped, and started only from the triangles spanning that plane, which
//! the index lists per height bucket once the axis is known); the crotch scan skips,
//! without slicing, the grid heights
//! below the lowest triangle across that plane; the level scans only test loop extents
//! and hulls are built where a rule needs them, their points sorted by merging the
//! monotone runs a loop's points come in. The free [`measure`] and [`girth_at`]
//! use one such `Measurer` per thread.

pub mod cli;
pub mod slicer;

use crate::mesh::TriMesh;
use glam::DVec3;
use serde::{Deserialize, Serialize};
use slicer::{HullStats, LevelIndex, SectionScratch};

pub use cli::{run, MeasureArgs};

/// Height (fraction of stature) of the slice whose largest loop gives the body axis.
pub const AXIS_PROBE_OF_STATURE: f64 = 0.60;
/// How far a torso loop reaches to each side of the body axis, fraction of stature.
pub const TORSO_REACH_OF_STATURE: f64 = 0.04;
/// The crotch search starts here (fraction of stature) and goes up.
pub const CROTCH_SEARCH_BOTTOM_OF_STATURE: f64 = 0.30;
/// The armpit search starts here (fraction of stature) and goes down.
pub const ARMPIT_SEARCH_TOP_OF_STATURE: f64 = 0.88;
/// The armpit search stops here (fraction of stature).
pub const ARMPIT_SEARCH_BOTTOM_OF_STATURE: f64 = 0.62;
/// Least girth of an arm loop at the armpit level, fraction of stature.
pub const ARM_MIN_GIRTH_OF_STATURE: f64 = 0.05;
/// Depth of the chest band below the armpit, fraction of stature.
pub const CHEST_BAND_OF_STATURE: f64 = 0.10;
/// Thigh band below the crotch (top, bottom), metres.
pub const THIGH_BAND_BELOW_CROTCH_M: (f64, f64) = (0.01, 0.08);
/// Grid step of every search, metres.
pub const GRID_STEP_M: f64 = 0.002;
/// Step of the refinement grid and tolerance of the level bisections, metres.
pub const FINE_STEP_M: f64 = 0.000_25;
/// Heights of a mesh measured as a standing person, metres (a mesh outside is refused
/// with [`MeasureError::InvalidMesh`]: millimetres, or a fit that blew up).
pub const MIN_STATURE_M: f64 = 0.5;
pub const MAX_STATURE_M: f64 = 3.0;
/// Fine steps on each side of the best grid point that a refinement visits (one grid
/// step minus one fine step: the grid points themselves are already known).
const FINE_STEPS_PER_SIDE: i32 = 7;
/// Report keys of the tape girths (`measurements_mm`), without the informational
/// [`HIP_GIRTH_MAX_KEY`].
pub const GIRTH_KEYS: [&str; 5] = [
    "chest_girth",
    "waist_girth",
    "hip_girth",
    "thigh_girth_left",
    "thigh_girth_right",
];
/// The optional, informational report key of the largest torso girth below the waist.
pub const HIP_GIRTH_MAX_KEY: &str = "hip_girth_max";

const MM_PER_M: f64 = 1000.0;

/// Heights (station y, metres) of the levels the measurements were taken at, and the
/// body axis.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MeasurementLevels {
    /// x of the body axis, metres.
    pub axis_x_m: f64,
    pub crotch_m: f64,
    pub armpit_m: f64,
    pub chest_m: f64,
    pub waist_m: f64,
    pub hip_m: f64,
    pub hip_girth_max_m: f64,
    pub thigh_left_m: f64,
    pub thigh_right_m: f64,
}

/// One sample of the torso girth profile.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct GirthSample {
    pub height_m: f64,
    pub girth_mm: f64,
    /// How far back the torso loop reaches there (its least z, station metres): the
    /// hip's level is where this is least.
    #[serde(default)]
    pub back_z_m: f64,
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
    /// The largest torso girth between the crotch and the waist (informational).
    pub hip_girth_max_mm: f64,
    pub levels: MeasurementLevels,
    /// Torso girth on the [`GRID_STEP_M`] grid from the crotch to the armpit, upward.
    pub torso_profile: Vec<GirthSample>,
}

impl Measurements {
    /// The `measurements_mm` object of `report.json` (`shared/spec/formats.md`,
    /// `shared/spec/measurements.md`): keys `stature`, [`GIRTH_KEYS`] and the optional
    /// [`HIP_GIRTH_MAX_KEY`], values in millimetres.
    pub fn to_report_map(&self) -> serde_json::Map<String, serde_json::Value> {
        let mut m = serde_json::Map::new();
        for (k, v) in [
            ("stature", self.stature_mm),
            ("chest_girth", self.chest_girth_mm),
            ("waist_girth", self.waist_girth_mm),
            ("hip_girth", self.hip_girth_mm),
            ("thigh_girth_left", self.thigh_girth_left_mm),
            ("thigh_girth_right", self.thigh_girth_right_mm),
            (HIP_GIRTH_MAX_KEY, self.hip_girth_max_mm),
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
    #[error("no body axis: the slice at y = {y_m:.3} m ({AXIS_PROBE_OF_STATURE} of the stature) is empty; not a standing body?")]
    NoTorso { y_m: f64 },
    #[error("no crotch: no torso loop appears between y = {bottom_m:.3} m and {top_m:.3} m above two separate legs; legs together or not a standing body?")]
    NoCrotch { bottom_m: f64, top_m: f64 },
    #[error("no {side} thigh loop between y = {bottom_m:.3} m and {top_m:.3} m")]
    NoLeg {
        side: BodySide,
        bottom_m: f64,
        top_m: f64,
    },
    #[error("no armpit: never a torso with both arms apart from it between y = {bottom_m:.3} m and {top_m:.3} m (arms against the body, or not an A-pose?)")]
    NoArmpit { bottom_m: f64, top_m: f64 },
    #[error("no torso loop between y = {bottom_m:.3} m and {top_m:.3} m while measuring {what}")]
    NoTorsoAt {
        bottom_m: f64,
        top_m: f64,
        what: &'static str,
    },
}

/// The subject's side: left is +X in the station frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum BodySide {
    Left,
    Right,
}

impl BodySide {
    /// Whether x lies on this side of x = `axis_x`.
    fn holds(self, x: f64, axis_x: f64) -> bool {
        match self {
            BodySide::Left => x > axis_x,
            BodySide::Right => x < axis_x,
        }
    }
}

impl std::fmt::Display for BodySide {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            BodySide::Left => "left",
            BodySide::Right => "right",
        })
    }
}

/// Which loop(s) of a horizontal slice a girth is taken around.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum LoopSelector {
    /// The hull of every loop of the slice together.
    Whole,
    /// The torso loop about the body axis x = `axis_x` (reach: [`TORSO_REACH_OF_STATURE`]
    /// of the mesh's stature).
    Torso { axis_x: f64 },
    /// The largest (hull area) side loop on `side` of x = `axis_x` by its hull centroid
    /// (below the crotch: the thigh loop).
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

/// A torso loop's hull at one height (internal to the band searches).
#[derive(Debug, Clone, Copy)]
struct Sample {
    y: f64,
    hull: HullStats,
}

/// What a band search looks for.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Objective {
    MaxGirth,
    MinGirth,
    /// The torso loop reaching furthest back (least z).
    MinZ,
}

impl Objective {
    /// Smaller is better.
    fn key(self, h: &HullStats) -> f64 {
        match self {
            Objective::MaxGirth => -h.perimeter_m,
            Objective::MinGirth => h.perimeter_m,
            Objective::MinZ => h.z_min,
        }
    }
}

/// Slack on band ends and grid counts, metres (float rounding of sums of steps).
const HEIGHT_EPS_M: f64 = 1e-9;

fn in_band(y: f64, band: (f64, f64)) -> bool {
    y >= band.0 - HEIGHT_EPS_M && y <= band.1 + HEIGHT_EPS_M
}

/// Whether a loop reaches at least `reach` to each side of x = `axis_x`.
fn straddles(l: &slicer::LoopInfo, axis_x: f64, reach: f64) -> bool {
    l.x_min <= axis_x - reach && l.x_max >= axis_x + reach
}

/// The lowest y of the triangles of `mesh` that have vertices on both sides of (or on)
/// the vertical plane x = `axis_x` (+inf when none does).
fn lowest_across_plane_x(mesh: &TriMesh, axis_x: f64) -> f64 {
    let mut lowest = f64::INFINITY;
    for t in &mesh.triangles {
        let [a, b, c] = t.map(|v| mesh.positions[v as usize]);
        let (x_lo, x_hi) = (a.x.min(b.x).min(c.x), a.x.max(b.x).max(c.x));
        if x_lo <= axis_x && x_hi >= axis_x {
            lowest = lowest.min(a.y.min(b.y).min(c.y));
        }
    }
    lowest
}

/// Heights this close to a critical height are cut, never skipped: a section counts a
/// vertex within `ON_PLANE_EPS_M` of its plane as on it, so its loops there may be those
/// of the other side.
pub const CRITICAL_TIE_M: f64 = 1e-9;

/// The critical heights of the armpit search are taken this far beyond its ends (well
/// above [`CRITICAL_TIE_M`], well inside the height index's margin).
const CRITICAL_RANGE_MARGIN_M: f64 = 1e-6;

/// The highest height below which the grid heights under `y` (down to it, exclusive)
/// have the loops of `y`: the highest critical height below `y`, raised by the tie
/// margin; `y` itself (nothing known) when a critical height lies within the margin.
fn lower_critical(critical: &[f64], y: f64) -> f64 {
    // Sorted: the first at or above y - tie.
    let k = critical.partition_point(|&c| c < y - CRITICAL_TIE_M);
    if critical.get(k).is_some_and(|&c| c <= y + CRITICAL_TIE_M) {
        return y;
    }
    match k.checked_sub(1) {
        Some(j) => critical[j] + CRITICAL_TIE_M,
        None => f64::NEG_INFINITY,
    }
}

/// Measurement executor: owns the triangle height index and the section buffers, so
/// measuring a fitted body every frame allocates only the result.
#[derive(Debug, Clone, Default)]
pub struct Measurer {
    index: LevelIndex,
    section: SectionScratch,
    /// The torso grid from the crotch to the armpit.
    profile: Vec<Sample>,
    /// Positions the index was built for (`loaded` once built).
    loaded_positions: Vec<DVec3>,
    loaded: bool,
    y_min: f64,
    y_max: f64,
    /// The armpit search cuts every grid height unless told the loops' critical heights
    /// ([`Measurer::find_armpit`]); tests compare both.
    cut_every_armpit_height: bool,
    critical: CriticalScratch,
}

/// Buffers of [`LevelIndex::critical_heights`].
#[derive(Debug, Clone, Default)]
struct CriticalScratch {
    marks: Vec<u16>,
    seen: Vec<u32>,
    heights: Vec<f64>,
}

impl Measurer {
    pub fn new() -> Self {
        Self::default()
    }

    /// A measurer whose armpit search cuts every grid height, without skipping those
    /// between two critical heights where the loops cannot have the arms apart: the
    /// same values, slower (for tests that check exactly that).
    pub fn cutting_every_armpit_height() -> Self {
        Measurer {
            cut_every_armpit_height: true,
            ..Self::default()
        }
    }

    /// A measurer that takes neither short cut of a closed surface: it cuts every grid
    /// height of the armpit search, and every section with the general cut instead of
    /// walking its loops. The same values, slower (for tests).
    pub fn without_short_cuts() -> Self {
        Measurer {
            cut_every_armpit_height: true,
            section: SectionScratch::default().never_walking(),
            ..Self::default()
        }
    }

    /// Checks the mesh and rebuilds the height index for it, unless it is the mesh the
    /// index was last built for (same triangles and bit-identical positions).
    ///
    /// With `everywhere` false the index lists only the triangles near the heights
    /// [`Measurer::measure_into`] cuts ([`Measurer::measured_heights`]); with it true,
    /// every triangle (an index built either way serves a height it covers).
    fn load(&mut self, mesh: &TriMesh, everywhere: bool) -> Result<(), MeasureError> {
        if self.loaded
            && self.loaded_positions == mesh.positions
            && self.index.topology_matches(&mesh.triangles)
            && (!everywhere || self.index.covers_everywhere())
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
        // Heights of the vertices in use (stray unused vertices do not count).
        let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
        for t in &mesh.triangles {
            for &v in t {
                let y = mesh.positions[v as usize].y;
                lo = lo.min(y);
                hi = hi.max(y);
            }
        }
        // A standing adult in metres. Anything else (a mesh in millimetres, a fit that
        // blew up) would make the height searches walk millions of grid steps.
        if !(MIN_STATURE_M..=MAX_STATURE_M).contains(&(hi - lo)) {
            return Err(MeasureError::InvalidMesh(format!(
                "the body is {:.3} m tall: not a standing person in metres \
                 ({MIN_STATURE_M}-{MAX_STATURE_M} m)",
                hi - lo
            )));
        }
        self.y_min = lo;
        self.y_max = hi;
        if everywhere {
            self.index.rebuild(mesh, lo, hi);
        } else {
            self.index
                .rebuild_window(mesh, lo, hi, self.measured_heights());
        }
        self.loaded_positions.clone_from(&mesh.positions);
        self.loaded = true;
        Ok(())
    }

    /// Every height [`Measurer::measure_into`] cuts lies in here: the crotch search from
    /// [`CROTCH_SEARCH_BOTTOM_OF_STATURE`] S up (the thigh band reaches
    /// [`THIGH_BAND_BELOW_CROTCH_M`].1 below a crotch found there), up to the armpit
    /// search's top, [`ARMPIT_SEARCH_TOP_OF_STATURE`] S (grid rounding aside: a millimetre
    /// of margin on each side).
    fn measured_heights(&self) -> (f64, f64) {
        const MARGIN_M: f64 = 0.001;
        (
            self.at_stature(CROTCH_SEARCH_BOTTOM_OF_STATURE)
                - THIGH_BAND_BELOW_CROTCH_M.1
                - MARGIN_M,
            self.at_stature(ARMPIT_SEARCH_TOP_OF_STATURE.max(AXIS_PROBE_OF_STATURE)) + MARGIN_M,
        )
    }

    fn stature(&self) -> f64 {
        self.y_max - self.y_min
    }

    /// Station y of a height given as a fraction of the stature above the lowest point.
    fn at_stature(&self, fraction: f64) -> f64 {
        self.y_min + fraction * self.stature()
    }

    fn cut(&mut self, mesh: &TriMesh, y: f64) {
        self.section.cut(mesh, &self.index, y);
    }

    /// Cuts at `y` keeping only the loops across the plane x = `axis_x`: enough for
    /// every torso question (a torso loop reaches to both sides of the axis), and
    /// arms and hands are not cut.
    fn cut_torso(&mut self, mesh: &TriMesh, y: f64, axis_x: f64) {
        self.section.cut_across_x(mesh, &self.index, y, axis_x);
    }

    /// Whether the last slice has a torso loop about x = `axis_x` (loop extents only).
    fn has_torso(&self, axis_x: f64) -> bool {
        let reach = TORSO_REACH_OF_STATURE * self.stature();
        self.section
            .loops()
            .iter()
            .any(|l| straddles(l, axis_x, reach))
    }

    /// Index and hull of the torso loop of the last slice: the loop straddling the axis
    /// by the reach; of several, the largest hull area.
    fn torso(&mut self, axis_x: f64) -> Option<(usize, HullStats)> {
        let reach = TORSO_REACH_OF_STATURE * self.stature();
        let mut best: Option<(usize, HullStats)> = None;
        for i in 0..self.section.loops().len() {
            if !straddles(&self.section.loops()[i], axis_x, reach) {
                continue;
            }
            if let Some(h) = self.section.loop_hull(i) {
                if best.is_none_or(|(_, b)| h.area_m2 > b.area_m2) {
                    best = Some((i, h));
                }
            }
        }
        best
    }

    /// Index of the torso loop of the last slice, without a hull when only one loop
    /// straddles the axis.
    fn torso_index(&mut self, axis_x: f64) -> Option<usize> {
        let reach = TORSO_REACH_OF_STATURE * self.stature();
        let loops = self.section.loops();
        let mut straddling = loops
            .iter()
            .enumerate()
            .filter(|(_, l)| straddles(l, axis_x, reach));
        let first = straddling.next()?.0;
        if straddling.next().is_none() {
            return Some(first);
        }
        self.torso(axis_x).map(|(i, _)| i)
    }

    /// Hull of the largest (hull area) side loop of the last slice on `side` of
    /// x = `axis_x` by its hull centroid (the torso loop is not a side loop).
    fn side_loop(&mut self, side: BodySide, axis_x: f64) -> Option<HullStats> {
        let torso = self.torso_index(axis_x);
        let mut best: Option<HullStats> = None;
        for i in 0..self.section.loops().len() {
            let l = self.section.loops()[i];
            // A loop wholly on the other side has its centroid there too.
            let other_side = match side {
                BodySide::Left => l.x_max <= axis_x,
                BodySide::Right => l.x_min >= axis_x,
            };
            if Some(i) == torso || other_side {
                continue;
            }
            if let Some(h) = self.section.loop_hull(i) {
                if side.holds(h.centroid_x, axis_x) && best.is_none_or(|b| h.area_m2 > b.area_m2) {
                    best = Some(h);
                }
            }
        }
        best
    }

    /// Whether the last slice has, on `side` of the axis, a side loop (not loop
    /// `torso`) of girth at least `min_girth` (metres). Hulls are built only when the
    /// loop's extent leaves the answer open: a convex hull's perimeter lies between
    /// twice its larger extent and twice the sum of its extents.
    fn has_arm(&mut self, side: BodySide, axis_x: f64, torso: usize, min_girth: f64) -> bool {
        for i in 0..self.section.loops().len() {
            let l = self.section.loops()[i];
            let (w, d) = (l.x_max - l.x_min, l.z_max - l.z_min);
            let (wholly_on_side, wholly_other) = match side {
                BodySide::Left => (l.x_min > axis_x, l.x_max <= axis_x),
                BodySide::Right => (l.x_max < axis_x, l.x_min >= axis_x),
            };
            if i == torso || wholly_other || 2.0 * (w + d) < min_girth {
                continue;
            }
            if wholly_on_side && 2.0 * w.max(d) >= min_girth {
                return true;
            }
            if let Some(h) = self.section.loop_hull(i) {
                if h.perimeter_m >= min_girth && side.holds(h.centroid_x, axis_x) {
                    return true;
                }
            }
        }
        false
    }

    /// The armpit predicate on the last slice: a torso loop, and on each side a
    /// separate arm loop of girth at least [`ARM_MIN_GIRTH_OF_STATURE`] S.
    fn arms_apart(&mut self, axis_x: f64) -> bool {
        let min_girth = ARM_MIN_GIRTH_OF_STATURE * self.stature();
        let Some(torso) = self.torso_index(axis_x) else {
            return false;
        };
        self.has_arm(BodySide::Left, axis_x, torso, min_girth)
            && self.has_arm(BodySide::Right, axis_x, torso, min_girth)
    }

    fn select(&mut self, selector: LoopSelector) -> Option<HullStats> {
        match selector {
            LoopSelector::Whole => self.section.whole_hull(),
            LoopSelector::Torso { axis_x } => self.torso(axis_x).map(|(_, h)| h),
            LoopSelector::Side { side, axis_x } => self.side_loop(side, axis_x),
        }
    }

    /// Tape girth (metres) at height `y` around the loop(s) chosen by `selector`, as
    /// [`girth_at`]; the height index is rebuilt only when the mesh changed.
    pub fn girth_at(&mut self, mesh: &TriMesh, y: f64, selector: LoopSelector) -> Option<f64> {
        self.load(mesh, true).ok()?;
        self.cut(mesh, y);
        self.select(selector).map(|h| h.perimeter_m)
    }

    /// The torso loop's hull at height `y`.
    fn torso_at(&mut self, mesh: &TriMesh, y: f64, axis_x: f64) -> Option<Sample> {
        self.cut_torso(mesh, y, axis_x);
        self.torso(axis_x).map(|(_, hull)| Sample { y, hull })
    }

    /// Bisects between a height where `pred` (slicing itself) is false and one where it
    /// is true until they are [`FINE_STEP_M`] apart; returns the true end.
    fn bisect(
        &mut self,
        _mesh: &TriMesh,
        mut no: f64,
        mut yes: f64,
        mut pred: impl FnMut(&mut Self, f64) -> bool,
    ) -> f64 {
        while (yes - no).abs() > FINE_STEP_M + HEIGHT_EPS_M {
            let mid = 0.5 * (no + yes);
            if pred(self, mid) {
                yes = mid;
            } else {
                no = mid;
            }
        }
        yes
    }

    /// Body axis: x of the hull centroid of the largest loop (hull area) at
    /// [`AXIS_PROBE_OF_STATURE`] S.
    fn body_axis(&mut self, mesh: &TriMesh) -> Result<f64, MeasureError> {
        let y = self.at_stature(AXIS_PROBE_OF_STATURE);
        self.cut(mesh, y);
        let mut best: Option<HullStats> = None;
        for i in 0..self.section.loops().len() {
            if let Some(h) = self.section.loop_hull(i) {
                if best.is_none_or(|b| h.area_m2 > b.area_m2) {
                    best = Some(h);
                }
            }
        }
        best.map(|h| h.centroid_x)
            .ok_or(MeasureError::NoTorso { y_m: y })
    }

    /// Crotch: the lowest grid height from [`CROTCH_SEARCH_BOTTOM_OF_STATURE`] S up
    /// with a torso loop, then bisected against the grid height below it. The search
    /// ends at the axis probe; a torso at its very start means the legs are not apart.
    ///
    /// Grid heights below the lowest triangle that reaches across the plane x = axis
    /// are skipped without slicing: a loop straddling the axis has a segment crossing
    /// that plane, so none of them has a torso loop (the legs' gap).
    fn find_crotch(&mut self, mesh: &TriMesh, axis_x: f64) -> Result<f64, MeasureError> {
        let bottom = self.at_stature(CROTCH_SEARCH_BOTTOM_OF_STATURE);
        let top = self.at_stature(AXIS_PROBE_OF_STATURE);
        let n = ((top - bottom) / GRID_STEP_M + HEIGHT_EPS_M).floor() as usize;
        let lowest_across = lowest_across_plane_x(mesh, axis_x);
        let first = ((lowest_across - bottom) / GRID_STEP_M - 1.0)
            .floor()
            .clamp(0.0, n as f64) as usize;
        for k in first..=n {
            let y = bottom + k as f64 * GRID_STEP_M;
            self.cut_torso(mesh, y, axis_x);
            if self.has_torso(axis_x) {
                if k == 0 {
                    break;
                }
                return Ok(self.bisect(mesh, y - GRID_STEP_M, y, |m, y| {
                    m.cut_torso(mesh, y, axis_x);
                    m.has_torso(axis_x)
                }));
            }
        }
        Err(MeasureError::NoCrotch {
            bottom_m: bottom,
            top_m: top,
        })
    }

    /// Armpit: the highest grid height from [`ARMPIT_SEARCH_TOP_OF_STATURE`] S down to
    /// [`ARMPIT_SEARCH_BOTTOM_OF_STATURE`] S where both arms are apart from the torso,
    /// then bisected against the grid height above it.
    ///
    /// Arms apart need at least three loops (a torso and one arm on each side). Where a
    /// cut has fewer, every grid height down to the next critical height below it has as
    /// few ([`LevelIndex::critical_heights`]: the loops change only there), and is not
    /// cut. Heights within [`CRITICAL_TIE_M`] of a critical height are always cut.
    fn find_armpit(&mut self, mesh: &TriMesh, axis_x: f64) -> Result<f64, MeasureError> {
        let top = self.at_stature(ARMPIT_SEARCH_TOP_OF_STATURE);
        let bottom = self.at_stature(ARMPIT_SEARCH_BOTTOM_OF_STATURE);
        let n = ((top - bottom) / GRID_STEP_M + HEIGHT_EPS_M).floor() as usize;
        let crit = &mut self.critical;
        let critical = !self.cut_every_armpit_height
            && self.index.critical_heights(
                mesh,
                bottom - CRITICAL_RANGE_MARGIN_M,
                top + CRITICAL_RANGE_MARGIN_M,
                &mut crit.marks,
                &mut crit.seen,
                &mut crit.heights,
            );
        // Grid heights above this one and below the last cut are known to lack the arms.
        let mut known_down_to = f64::INFINITY;
        for k in 0..=n {
            let y = top - k as f64 * GRID_STEP_M;
            if y > known_down_to {
                continue;
            }
            self.cut(mesh, y);
            if critical && self.section.loops().len() < 3 {
                known_down_to = lower_critical(&self.critical.heights, y);
            }
            if self.arms_apart(axis_x) {
                if k == 0 {
                    return Ok(y);
                }
                return Ok(self.bisect(mesh, y + GRID_STEP_M, y, |m, y| {
                    m.cut(mesh, y);
                    m.arms_apart(axis_x)
                }));
            }
        }
        Err(MeasureError::NoArmpit {
            bottom_m: bottom,
            top_m: top,
        })
    }

    /// The torso grid: crotch + k [`GRID_STEP_M`] below the armpit, then the armpit.
    fn build_profile(&mut self, mesh: &TriMesh, axis_x: f64, crotch: f64, armpit: f64) {
        let mut profile = std::mem::take(&mut self.profile);
        profile.clear();
        let n = ((armpit - crotch) / GRID_STEP_M + HEIGHT_EPS_M).floor() as usize;
        for k in 0..=n {
            let y = crotch + k as f64 * GRID_STEP_M;
            if y >= armpit - HEIGHT_EPS_M {
                break;
            }
            profile.extend(self.torso_at(mesh, y, axis_x));
        }
        profile.extend(self.torso_at(mesh, armpit, axis_x));
        self.profile = profile;
    }

    /// The best torso sample by `objective` in `band` (station y): over the grid
    /// samples inside it and `ends` (the band's ends where they are known samples),
    /// then over the fine grid within one grid step of the best, inside the band.
    fn band_extremum(
        &mut self,
        mesh: &TriMesh,
        axis_x: f64,
        band: (f64, f64),
        ends: &[Sample],
        objective: Objective,
    ) -> Option<Sample> {
        let better = |s: &Sample, best: &Option<Sample>| {
            best.is_none_or(|b| objective.key(&s.hull) < objective.key(&b.hull))
        };
        let mut best: Option<Sample> = None;
        for s in self.profile.iter().chain(ends) {
            if in_band(s.y, band) && better(s, &best) {
                best = Some(*s);
            }
        }
        let grid_best = best?;
        for j in -FINE_STEPS_PER_SIDE..=FINE_STEPS_PER_SIDE {
            let y = grid_best.y + j as f64 * FINE_STEP_M;
            if j == 0 || !in_band(y, band) {
                continue;
            }
            if let Some(s) = self.torso_at(mesh, y, axis_x) {
                if better(&s, &best) {
                    best = Some(s);
                }
            }
        }
        best
    }

    /// Each side's thigh girth (metres) and its level: the largest girth of the side's
    /// thigh loop on the grid from [`THIGH_BAND_BELOW_CROTCH_M`].0 below the crotch
    /// down to .1, refined on the fine grid around each side's best grid level.
    fn thighs(
        &mut self,
        mesh: &TriMesh,
        axis_x: f64,
        crotch: f64,
    ) -> Result<[(f64, f64); 2], MeasureError> {
        let band = (
            crotch - THIGH_BAND_BELOW_CROTCH_M.1,
            crotch - THIGH_BAND_BELOW_CROTCH_M.0,
        );
        const SIDES: [BodySide; 2] = [BodySide::Left, BodySide::Right];
        let mut best: [Option<(f64, f64)>; 2] = [None; 2];
        let consider = |best: &mut Option<(f64, f64)>, y: f64, girth: f64| {
            if best.is_none_or(|b| girth > b.1) {
                *best = Some((y, girth));
            }
        };
        let n = ((band.1 - band.0) / GRID_STEP_M + HEIGHT_EPS_M).floor() as usize;
        for k in 0..=n {
            let y = band.1 - k as f64 * GRID_STEP_M;
            self.cut(mesh, y);
            for (slot, side) in best.iter_mut().zip(SIDES) {
                if let Some(h) = self.side_loop(side, axis_x) {
                    consider(slot, y, h.perimeter_m);
                }
            }
        }
        let mut out = [(0.0, 0.0); 2];
        for ((slot, side), out) in best.iter_mut().zip(SIDES).zip(&mut out) {
            let (grid_y, _) = slot.ok_or(MeasureError::NoLeg {
                side,
                bottom_m: band.0,
                top_m: band.1,
            })?;
            for j in -FINE_STEPS_PER_SIDE..=FINE_STEPS_PER_SIDE {
                let y = grid_y + j as f64 * FINE_STEP_M;
                if j == 0 || !in_band(y, band) {
                    continue;
                }
                self.cut(mesh, y);
                if let Some(h) = self.side_loop(side, axis_x) {
                    consider(slot, y, h.perimeter_m);
                }
            }
            *out = slot.unwrap_or((grid_y, 0.0));
        }
        Ok(out)
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
            hip_girth_max_mm: 0.0,
            levels: MeasurementLevels {
                axis_x_m: 0.0,
                crotch_m: 0.0,
                armpit_m: 0.0,
                chest_m: 0.0,
                waist_m: 0.0,
                hip_m: 0.0,
                hip_girth_max_m: 0.0,
                thigh_left_m: 0.0,
                thigh_right_m: 0.0,
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
        self.load(mesh, false)?;
        let stature = self.stature();
        let axis_x = self.body_axis(mesh)?;
        self.index.index_axis(axis_x);
        let crotch = self.find_crotch(mesh, axis_x)?;
        let armpit = self.find_armpit(mesh, axis_x)?;
        if armpit <= crotch {
            return Err(MeasureError::NoArmpit {
                bottom_m: crotch,
                top_m: self.at_stature(ARMPIT_SEARCH_TOP_OF_STATURE),
            });
        }
        self.build_profile(mesh, axis_x, crotch, armpit);
        let no_torso = |band: (f64, f64), what| MeasureError::NoTorsoAt {
            bottom_m: band.0,
            top_m: band.1,
            what,
        };
        let extremum = |m: &mut Self, band, ends: &[Sample], objective, what| {
            m.band_extremum(mesh, axis_x, band, ends, objective)
                .ok_or(no_torso(band, what))
        };
        let chest_band = (
            (armpit - CHEST_BAND_OF_STATURE * stature).max(crotch),
            armpit,
        );
        let chest = extremum(self, chest_band, &[], Objective::MaxGirth, "chest")?;
        // Waist and hip in the spec's order (1)-(4).
        let first_waist = extremum(
            self,
            (crotch, chest.y),
            &[chest],
            Objective::MinGirth,
            "waist",
        )?;
        let hip_max = extremum(
            self,
            (crotch, first_waist.y),
            &[first_waist],
            Objective::MaxGirth,
            "hip_girth_max",
        )?;
        let waist = extremum(
            self,
            (hip_max.y, chest.y),
            &[hip_max, chest],
            Objective::MinGirth,
            "waist",
        )?;
        let hip = extremum(self, (crotch, waist.y), &[waist], Objective::MinZ, "hip")?;
        let [(thigh_left_m, left), (thigh_right_m, right)] = self.thighs(mesh, axis_x, crotch)?;

        out.stature_mm = stature * MM_PER_M;
        out.chest_girth_mm = chest.hull.perimeter_m * MM_PER_M;
        out.waist_girth_mm = waist.hull.perimeter_m * MM_PER_M;
        out.hip_girth_mm = hip.hull.perimeter_m * MM_PER_M;
        out.hip_girth_max_mm = hip_max.hull.perimeter_m * MM_PER_M;
        out.thigh_girth_left_mm = left * MM_PER_M;
        out.thigh_girth_right_mm = right * MM_PER_M;
        out.levels = MeasurementLevels {
            axis_x_m: axis_x,
            crotch_m: crotch,
            armpit_m: armpit,
            chest_m: chest.y,
            waist_m: waist.y,
            hip_m: hip.y,
            hip_girth_max_m: hip_max.y,
            thigh_left_m,
            thigh_right_m,
        };
        out.torso_profile.clear();
        out.torso_profile
            .extend(self.profile.iter().map(|s| GirthSample {
                height_m: s.y,
                girth_mm: s.hull.perimeter_m * MM_PER_M,
                back_z_m: s.hull.z_min,
            }));
        Ok(())
    }
}
