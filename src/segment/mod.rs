//! Segmentation of the person in a kiosk frame (issue 4, step 2).
//!
//! A per-pixel background model is learned from empty-scene frames. A pixel is background
//! when it lies within the noise radius of the model colour, or when it differs only in
//! brightness within `[shadow_min_brightness, highlight_max_brightness]` with little
//! chromaticity change (Horprasert, Harwood and Davis 1999: brightness distortion
//! `alpha = I.E/|E|^2`, chromaticity distortion `|I - alpha E|`). That tolerates sensor
//! noise, small exposure changes and the shadow at the feet. Where a shadow is explained
//! (the shadow zone, below), the chromaticity tolerance is an angle: the noise radius
//! seen from the unshadowed colour, so it shrinks with the brightness ratio
//! (`|I - alpha E| <= chroma_k tau alpha / g`). A shadow scales the backdrop's colour and
//! keeps its direction; a dark shoe of the floor's hue turns it by more than the floor's
//! own variation does at that brightness. Elsewhere only the exposure varies and the
//! tolerance stays the full radius (applied there too, it refused one JPEG frame for
//! arms touching the torso).
//!
//! A cast shadow is only explained where one can fall: the *shadow zone*, the pixels whose
//! viewing ray meets the floor within [`FLOOR_SHADOW_RADIUS_M`] of the mark
//! ([`floor_shadow_zone`], from the calibration; without a calibration the whole frame is
//! zone). Elsewhere (the backdrop behind the person) only exposure changes are tolerated
//! (`lit_min_brightness`), so grey or dark clothing in front of a backdrop of the same hue
//! is no longer taken for a shadow; and no surface gets brighter by more than
//! `highlight_max_brightness` when a person steps in (a person only takes light away;
//! the margin takes exposure drift and the optics' halo of bright parts on a dark
//! backdrop, which would otherwise join a hand to the hip across a narrow gap).
//!
//! Legs in trousers of the floor's own hue look like their own cast shadow where they
//! cross the floor's image: shadow-like cells between foreground cells of the same
//! column are bridged into the person (`bridge_columns`), when the column's foreground
//! above them reaches outside the shadow zone (a leg hangs from a thigh seen against the
//! backdrop; the shadowed floor between a side view's far and near foot has only the
//! far foot, inside the zone, above it).
//! The zone flag rides in the top bit of the pixel's packed noise radius. Everything is evaluated
//! without per-pixel division: with `d = I - E`, `|I - alpha E|^2 |E|^2 = |d|^2 |E|^2 -
//! (d.E)^2` and `alpha - 1 = d.E / |E|^2`.
//!
//! Every frame is first put at the model's exposure: its gain `g` is the median
//! brightness ratio of a sparse sample of pixels away from the person's last box that
//! keep the model's chromaticity ([`BackgroundModel::estimate_gain`]), and the tests
//! compare with `g E` (flicker and exposure drift move the whole backdrop; the brightness
//! tolerances then only have to cover what is left about it).
//!
//! Per frame: the test runs on every second pixel of every second row (a 2x coarse
//! grid); with a person in the last frame, only about the person's last box (and the
//! learned prior's support), the rest of the frame sampled one cell in 16 and tested in
//! full where a sample changed and wherever a changed region leads from there
//! (`classify::classify_around_person`; the labels are the full test's but for patches
//! too thin to hold a sample). The coarse mask is cleaned by a 3x3 majority filter, its
//! largest 8-connected component is kept with its holes filled (except holes that look
//! like the backdrop seen through a gap: mostly unchanged, or shadowed inside the shadow
//! zone), and the full-resolution mask is that component upsampled, with every pixel
//! within one coarse cell of its border re-tested at full resolution (then a 3x3
//! majority among those pixels). The model keeps adapting slowly (a running mean) on a
//! rotating band of rows, away from the person.
//!
//! Still images (the paper's case) go through [`key_still`]: against an empty-scene image
//! if there is one, else against a backdrop colour keyed from the image border.
//!
//! # Conventions
//! Pixels (column, row), origin at the top-left pixel; masks are 0/255, full resolution;
//! colours are 8-bit sRGB values used as they are (no linearisation), except for the
//! sub-pixel edge score ([`EdgeScorer`]), which compares colours in linear light.

mod adapt;
mod band;
mod body;
mod classify;
pub mod fusion;
mod still;
#[cfg(test)]
mod tests;
mod zone;

#[cfg(test)]
use classify::{bridge_columns, gather_coarse_row};
pub use still::{backdrop_from_border, key_still};
pub use zone::{floor_shadow_zone, standing_volume_box};

use crate::imgproc::{self, Mask, RunComponents};
use image::RgbImage;

/// Subsampling factor of the coarse grid.
pub const COARSE: u32 = 2;
/// Rows of the model updated per frame: one in `ADAPT_ROW_STRIDE`.
const ADAPT_ROW_STRIDE: u64 = 32;
/// Margin around the person's box (pixels) kept out of adaptation.
const ADAPT_MARGIN_PX: u32 = 24;
/// Sensor noise assumed when the model was learned from a single frame (8-bit units).
const DEFAULT_NOISE_SIGMA: f32 = 4.0;
/// Range of plausible frame exposure gains (a locked camera drifts by a few percent; a
/// larger change is a new lighting the model has to learn, not a gain to divide out).
const MIN_GAIN: f32 = 0.8;
const MAX_GAIN: f32 = 1.25;
/// Width of the border strips used to key a still image's backdrop (pixels).
const KEY_BORDER_PX: u32 = 12;
/// Rows averaged (each side) when smoothing the keyed backdrop colour.
const KEY_ROW_SMOOTH: usize = 16;
/// Luma at or above which a pixel counts as clipped white.
const CLIP_HIGH_LUMA: u8 = 250;
/// Luma at or below which a pixel counts as crushed black.
const CLIP_LOW_LUMA: u8 = 5;
/// Floor points within this distance of the mark (metres) may carry the person's cast
/// shadow: a standing person lit from above and from the cameras' side shades the floor
/// around the feet, not the floor metres away.
pub const FLOOR_SHADOW_RADIUS_M: f64 = 1.5;
/// Block of pixels sharing one zone test in [`floor_shadow_zone`] (the zone's border need
/// not be exact: it only switches the shadow tolerance).
const ZONE_BLOCK_PX: u32 = 4;
/// Bit of `PixelModel::tau2` flagging a pixel of the shadow zone; the radius keeps the
/// other 15 bits.
const ZONE_BIT: u16 = 0x8000;
const TAU2_MAX: u16 = ZONE_BIT - 1;

/// The sRGB decoding curve at the 256 8-bit levels (and a copy of the last, for
/// interpolation), scaled to 0..255.
fn srgb_to_linear() -> &'static [f32; 257] {
    static LUT: std::sync::OnceLock<[f32; 257]> = std::sync::OnceLock::new();
    LUT.get_or_init(|| {
        std::array::from_fn(|k| {
            let e = k.min(255) as f64 / 255.0;
            let l = if e <= 0.04045 {
                e / 12.92
            } else {
                ((e + 0.055) / 1.055).powf(2.4)
            };
            (255.0 * l) as f32
        })
    })
}

/// Colour distance between a frame and a background model in linear light (sRGB
/// decoded, scaled to 0..255), at the pixel nearest (x, y) inside the frame: the
/// sub-pixel edge score. The lens mixes person and backdrop in linear light, before the
/// camera encodes its levels, so the coverage of an edge pixel is linear in this
/// distance and not in the encoded one (which would put the edge of a dark person on a
/// pale backdrop inside the person).
pub struct EdgeScorer<'a> {
    px: &'a [PixelModel],
    raw: &'a [u8],
    w: i64,
    h: i64,
    lut: &'static [f32; 257],
}

impl EdgeScorer<'_> {
    #[inline]
    pub fn score(&self, x: i64, y: i64) -> f32 {
        let i = (y.clamp(0, self.h - 1) * self.w + x.clamp(0, self.w - 1)) as usize;
        let (Some(m), Some(p)) = (self.px.get(i), self.raw.get(3 * i..3 * i + 3)) else {
            return 0.0;
        };
        let mut dd = 0.0;
        for (&v, &q) in p.iter().zip(&m.e_q8) {
            let a = self.lut[v as usize];
            // The model is kept in 1/256 levels: interpolate the curve.
            let q = q as usize;
            let (k, f) = ((q >> 8).min(255), (q & 255) as f32 * (1.0 / 256.0));
            let b = self.lut[k] + f * (self.lut[k + 1] - self.lut[k]);
            dd += (a - b) * (a - b);
        }
        dd.sqrt()
    }
}

/// Asks the CPU to bring `v[i]`'s cache line in (no effect elsewhere than x86-64, or
/// past the slice's end).
#[inline(always)]
fn prefetch<T>(v: &[T], i: usize) {
    #[cfg(target_arch = "x86_64")]
    if let Some(e) = v.get(i) {
        use std::arch::x86_64::{_mm_prefetch, _MM_HINT_T0};
        // SAFETY: SSE is part of the x86-64 baseline, and a prefetch is a hint: it reads
        // nothing into the program and never faults (the address is a live element).
        unsafe { _mm_prefetch::<_MM_HINT_T0>((e as *const T).cast::<i8>()) };
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = (v, i);
}

/// Tuning of the segmentation. Thresholds are in 8-bit colour units.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SegmentOptions {
    /// Noise radius: `k * sigma` of the pixel's learned noise (per-channel sigma times
    /// sqrt(3) for the colour distance), at least `min_distance`.
    pub noise_k: f32,
    pub min_distance: f32,
    /// Chromaticity distortion above which a pixel is foreground, in units of the noise
    /// radius; in the shadow zone, of the noise radius scaled by the pixel's brightness
    /// ratio to the exposed model (at most 1): the angle the noise radius subtends at the
    /// unshadowed colour.
    pub chroma_k: f32,
    /// In the shadow zone, darker than this fraction of the model brightness is
    /// foreground; between this and 1 (with low chromaticity distortion) is shadow, kept
    /// as background. A cast shadow keeps the ambient light and the other lamps' light.
    pub shadow_min_brightness: f32,
    /// Outside the shadow zone, darker than this fraction is foreground (only exposure
    /// flicker and drift are tolerated there).
    pub lit_min_brightness: f32,
    /// Brighter than this multiple of the model brightness is foreground.
    pub highlight_max_brightness: f32,
    /// Running-mean rate of the adaptation (0 disables it).
    pub adapt_rate: f32,
    /// Components smaller than this fraction of the frame are ignored (not a person).
    pub min_person_fraction: f32,
    /// Bridge shadow-like cells between foreground cells of a column (see
    /// `bridge_columns`).
    pub bridge_columns: bool,
    /// Keep holes open that look like the backdrop (see `segment`); else fill every hole.
    pub open_holes: bool,
    /// With a person in the last frame, test every cell only about the person (and the
    /// learned prior) and sample the rest of the frame, testing in full where a sample
    /// changed (see `classify_coarse`); else test every cell of every frame.
    pub sample_outside_person: bool,
}

impl Default for SegmentOptions {
    fn default() -> Self {
        SegmentOptions {
            noise_k: 4.0,
            min_distance: 14.0,
            chroma_k: 1.0,
            shadow_min_brightness: 0.5,
            lit_min_brightness: 0.85,
            highlight_max_brightness: 1.25,
            adapt_rate: 0.05,
            min_person_fraction: 0.01,
            bridge_columns: true,
            open_holes: true,
            sample_outside_person: true,
        }
    }
}

/// Errors of the segmentation.
#[derive(Debug, thiserror::Error)]
pub enum SegmentError {
    #[error("frame is {got_w}x{got_h} but the background model is {want_w}x{want_h}")]
    FrameSize {
        want_w: u32,
        want_h: u32,
        got_w: u32,
        got_h: u32,
    },
    #[error(
        "the background model has not learned an empty scene yet: show the empty backdrop first"
    )]
    NotReady,
    #[error("empty frame (0 pixels)")]
    Empty,
    #[error("shadow zone is {got_w}x{got_h} but the background model is {want_w}x{want_h}")]
    ZoneSize {
        want_w: u32,
        want_h: u32,
        got_w: u32,
        got_h: u32,
    },
}

/// Which image borders the person touches.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct BorderTouch {
    pub top: bool,
    pub bottom: bool,
    pub left: bool,
    pub right: bool,
}

/// A pixel box, min inclusive, max exclusive.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PixelBox {
    pub min_x: u32,
    pub min_y: u32,
    pub max_x: u32,
    pub max_y: u32,
}

/// What the segmentation saw in one frame.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct SegmentStats {
    /// Foreground pixels of the output mask (the person; holes filled but for the open ones).
    pub person_px: u64,
    /// Components (coarse grid) above `min_person_fraction` of the frame.
    pub large_components: u32,
    /// Area of the largest and second largest component, in full-resolution pixels.
    pub largest_px: u64,
    pub second_px: u64,
    /// Large components other than the person's that stand outside the standing volume
    /// over the mark (people walking by behind the shopper; see
    /// [`BackgroundModel::set_standing_box`]); 0 without a standing volume.
    pub bystanders: u32,
    /// Box of the person in full-resolution pixels.
    pub person_box: Option<PixelBox>,
    pub touches: BorderTouch,
    /// Exposure statistics of the frame.
    pub exposure: ExposureStats,
    /// The same statistics of the learned empty scene, the reference of the exposure
    /// verdicts (a white or black backdrop is the scene, not an exposure fault).
    pub backdrop: ExposureStats,
    /// Frames segmented so far by this model.
    pub frame_index: u64,
    /// Exposure gain of the frame against the model (1 when it could not be estimated).
    pub gain: f32,
    /// Full-resolution pixels re-tested along the border.
    pub band_px: u32,
    /// Cells of the coarse grid given the colour test in full (all of them, unless the
    /// frame was sampled away from the person: see `SegmentOptions::sample_outside_person`).
    pub tested_cells: u64,
    /// Full-resolution pixels (coarse cells times four) made person by the learned
    /// person prior ([`fusion`]); 0 without a prior.
    pub fused_px: u64,
    /// Wall time of the phases.
    pub phase_ms: SegmentPhases,
}

/// Exposure statistics over the coarse grid: mean luma (0..255, Rec. 601 weights) and the
/// fractions of cells clipped white (luma >= 250) and crushed black (<= 5).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ExposureStats {
    pub mean_luma: f32,
    pub clipped_high: f32,
    pub clipped_low: f32,
}

impl ExposureStats {
    /// From the luma sum and the clipped and crushed counts of `n` cells.
    fn from_counts(luma_sum: u64, clipped_high: u64, clipped_low: u64, n: usize) -> Self {
        if n == 0 {
            return ExposureStats::default();
        }
        let n = n as f32;
        ExposureStats {
            mean_luma: luma_sum as f32 / n,
            clipped_high: clipped_high as f32 / n,
            clipped_low: clipped_low as f32 / n,
        }
    }
}

/// Integer luma (Rec. 601 weights) of an 8-bit colour, as the exposure statistics count it.
#[inline(always)]
fn luma8(r: u32, g: u32, b: u32) -> u32 {
    (77 * r + 150 * g + 29 * b) >> 8
}

/// Milliseconds spent in each phase of [`BackgroundModel::segment`].
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize)]
pub struct SegmentPhases {
    pub classify: f32,
    /// The fusion with the learned person prior ([`fusion`]).
    pub fuse: f32,
    pub components: f32,
    pub upsample: f32,
    pub band: f32,
    pub stats: f32,
    pub adapt: f32,
}

struct PhaseClock(std::time::Instant);

impl PhaseClock {
    fn start() -> Self {
        PhaseClock(std::time::Instant::now())
    }
    fn lap(&mut self) -> f32 {
        let now = std::time::Instant::now();
        let ms = (now - self.0).as_secs_f32() * 1e3;
        self.0 = now;
        ms
    }
}

/// Per-pixel colour statistics of the empty scene (see the module docs).
#[derive(Debug, Clone)]
pub struct BackgroundModel {
    pub width: u32,
    pub height: u32,
    pub opts: SegmentOptions,
    learned_frames: u32,
    sum: Vec<[f32; 3]>,
    sum_sq: Vec<f32>,
    /// Model of every pixel (one cache line holds about three pixels).
    px: Vec<PixelModel>,
    /// The model at the coarse-grid pixels (every second pixel of every second row),
    /// contiguous for the per-frame test.
    coarse_model: ModelPlane,
    /// One coarse row of the frame, per channel.
    row_rgb: Vec<u32>,
    /// Shadow zone of every pixel (1 in the zone); see the module docs.
    zone: Vec<u8>,
    frames: u64,
    /// Exposure gain of the current frame against the model (see [`Self::estimate_gain`]).
    gain: f32,
    /// Exposure statistics of the model's colours (set when the learning is finalised).
    backdrop_exposure: ExposureStats,
    /// The person's box in the previous frame (kept out of the gain estimate).
    last_box: Option<PixelBox>,
    // Scratch.
    gain_samples: Vec<f32>,
    hole_evidence: Vec<u64>,
    coarse: Vec<u8>,
    coarse_clean: Vec<u8>,
    coarse_body: Vec<u8>,
    /// Per coarse column: row of the last foreground cell of the current unbroken run of
    /// changed cells (see [`classify::bridge_columns`]).
    column_top: Vec<u32>,
    /// Per coarse column: the current run of changed cells holds a foreground cell
    /// outside the shadow zone (see [`classify::bridge_columns`]).
    column_anchored: Vec<bool>,
    /// No shadow zone was set (no calibration): every pixel may be shadow.
    zone_everywhere: bool,
    tmp: Vec<u8>,
    eroded: Vec<u8>,
    dilated: Vec<u8>,
    runs: RunComponents,
    /// Components of `runs` that are further pieces of the person (see
    /// `body::find_pieces`).
    pieces: Vec<usize>,
    hole_runs: RunComponents,
    /// Coarse runs of the holes left open in the last frame (see [`Self::open_holes`]).
    open_holes: Vec<imgproc::Run>,
    band_state: Vec<u8>,
    /// Pixels of the band, `[x, y]`.
    band_px: Vec<[u32; 2]>,
    /// Cells of the band, `[cx, cy]`.
    band_cells: Vec<[u32; 2]>,
    band_out: Vec<u8>,
    /// The learned person prior ([`fusion`]), when the station gave one.
    prior: Option<fusion::PersonPrior>,
    /// The image of the standing volume over the mark, in coarse cells (see
    /// [`Self::set_standing_box`]).
    standing_cells: Option<PixelBox>,
    fusion: fusion::FusionRule,
    fuse_scratch: fusion::FuseScratch,
    /// Per block of the sampled classification: tested in full or sampled (see
    /// `classify::classify_around_person`), the blocks queued for a full test, and the
    /// luma of each block's sample.
    block_state: Vec<u8>,
    block_queue: Vec<u32>,
    block_luma: Vec<u8>,
}

/// Model of one pixel in eight bytes (the band re-test is bound by memory latency):
/// colour E in 1/256 of a level, and the squared noise radius (15 bits) with the shadow
/// zone flag in the top bit ([`ZONE_BIT`]).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
struct PixelModel {
    e_q8: [u16; 3],
    tau2: u16,
}

/// Fixed-point scale of `PixelModel::e_q8`.
const COLOR_Q: f32 = 256.0;

impl PixelModel {
    #[inline(always)]
    fn color(&self) -> [f32; 3] {
        self.e_q8.map(|v| v as f32 * (1.0 / COLOR_Q))
    }
    #[inline(always)]
    fn radius2(&self) -> f32 {
        (self.tau2 & TAU2_MAX) as f32
    }
    #[inline(always)]
    fn in_zone(&self) -> bool {
        self.tau2 & ZONE_BIT != 0
    }
}

/// The model at the coarse-grid pixels in 8-bit colour and 16-bit squared radius (five
/// bytes a pixel: the per-frame test is bound by memory traffic).
#[derive(Debug, Clone, Default)]
struct ModelPlane {
    er: Vec<u8>,
    eg: Vec<u8>,
    eb: Vec<u8>,
    tau2: Vec<u16>,
    /// 1 in the shadow zone, else 0.
    zone: Vec<u8>,
}

impl ModelPlane {
    /// Exposure statistics of the model's colours, as [`BackgroundModel::segment`]
    /// computes them for a frame.
    fn exposure(&self) -> ExposureStats {
        let (mut sum, mut hi, mut lo) = (0u64, 0u64, 0u64);
        for ((&r, &g), &b) in self.er.iter().zip(&self.eg).zip(&self.eb) {
            let l = luma8(r as u32, g as u32, b as u32);
            sum += l as u64;
            hi += (l >= CLIP_HIGH_LUMA as u32) as u64;
            lo += (l <= CLIP_LOW_LUMA as u32) as u64;
        }
        ExposureStats::from_counts(sum, hi, lo, self.er.len())
    }

    /// Sets the colour of coarse cell `k` (in range) from a model colour in 8-bit units.
    #[inline]
    fn set_colour(&mut self, k: usize, m: [f32; 3]) {
        self.er[k] = (m[0] + 0.5) as u8;
        self.eg[k] = (m[1] + 0.5) as u8;
        self.eb[k] = (m[2] + 0.5) as u8;
    }
}

/// Coarse labels of the classification: changed but explained as shadow or exposure
/// change, and such a cell bridged into the person (see [`classify::bridge_columns`]). Foreground is
/// [`crate::imgproc::MASK_ON`], unchanged 0.
const WEAK: u8 = 2;
const BRIDGED: u8 = 253; // odd: the majority filter counts `v & 1`
/// A cell joining a piece of the person to the body where the prior says person
/// ([`BackgroundModel::join_pieces`]): kept at full resolution whatever its colour.
const JOINED: u8 = 249;
/// Holes of fewer coarse cells are always filled (noise inside the body).
const OPEN_HOLE_MIN_CELLS: u64 = 8;
/// A hole stays open when at least this fraction of its cells is background evidence.
const OPEN_HOLE_FRACTION: f64 = 0.5;

/// Marks a column without an open run in [`classify::bridge_columns`].
const NO_RUN: u32 = u32::MAX;

/// The person's box grown by [`ADAPT_MARGIN_PX`] as `(x0, y0, x1, y1)`: pixels the
/// backdrop statistics (adaptation, exposure gain) keep away from.
fn keep_out_box(b: PixelBox) -> (usize, usize, usize, usize) {
    (
        b.min_x.saturating_sub(ADAPT_MARGIN_PX) as usize,
        b.min_y.saturating_sub(ADAPT_MARGIN_PX) as usize,
        (b.max_x + ADAPT_MARGIN_PX) as usize,
        (b.max_y + ADAPT_MARGIN_PX) as usize,
    )
}

const BAND_NONE: u8 = 0;
const BAND_BG: u8 = 1;
const BAND_FG: u8 = 2;

impl BackgroundModel {
    pub fn new(width: u32, height: u32, opts: SegmentOptions) -> Self {
        let n = (width * height) as usize;
        BackgroundModel {
            width,
            height,
            opts,
            learned_frames: 0,
            sum: vec![[0.0; 3]; n],
            sum_sq: vec![0.0; n],
            px: vec![PixelModel::default(); n],
            coarse_model: ModelPlane::default(),
            row_rgb: Vec::new(),
            zone: vec![1; n],
            frames: 0,
            gain: 1.0,
            backdrop_exposure: ExposureStats::default(),
            last_box: None,
            gain_samples: Vec::new(),
            hole_evidence: Vec::new(),
            coarse: Vec::new(),
            coarse_clean: Vec::new(),
            coarse_body: Vec::new(),
            column_top: Vec::new(),
            column_anchored: Vec::new(),
            zone_everywhere: true,
            standing_cells: None,
            tmp: Vec::new(),
            eroded: Vec::new(),
            dilated: Vec::new(),
            runs: RunComponents::default(),
            pieces: Vec::new(),
            hole_runs: RunComponents::default(),
            open_holes: Vec::new(),
            band_state: vec![BAND_NONE; n],
            band_px: Vec::new(),
            band_cells: Vec::new(),
            band_out: Vec::new(),
            prior: None,
            fusion: fusion::FusionRule::default(),
            fuse_scratch: fusion::FuseScratch::default(),
            block_state: Vec::new(),
            block_queue: Vec::new(),
            block_luma: Vec::new(),
        }
    }

    fn check(&self, frame: &RgbImage) -> Result<(), SegmentError> {
        if frame.width() == 0 || frame.height() == 0 {
            return Err(SegmentError::Empty);
        }
        if frame.width() != self.width || frame.height() != self.height {
            return Err(SegmentError::FrameSize {
                want_w: self.width,
                want_h: self.height,
                got_w: frame.width(),
                got_h: frame.height(),
            });
        }
        Ok(())
    }

    /// Adds one empty-scene frame to the model (call it for each of the first frames of a
    /// recording or session). The model is ready after the first frame; more frames
    /// measure each pixel's noise instead of assuming it.
    ///
    /// # Errors
    /// `FrameSize` / `Empty` when the frame does not fit the model.
    pub fn learn(&mut self, empty: &RgbImage) -> Result<(), SegmentError> {
        self.check(empty)?;
        for (i, p) in empty.pixels().enumerate() {
            let [r, g, b] = p.0.map(|v| v as f32);
            let s = &mut self.sum[i];
            s[0] += r;
            s[1] += g;
            s[2] += b;
            self.sum_sq[i] += r * r + g * g + b * b;
        }
        self.learned_frames += 1;
        self.finalize();
        Ok(())
    }

    /// True once at least one empty frame was learned.
    pub fn is_ready(&self) -> bool {
        self.learned_frames > 0
    }

    /// Empty-scene frames learned.
    pub fn learned_frames(&self) -> u32 {
        self.learned_frames
    }

    fn finalize(&mut self) {
        let n = self.learned_frames as f32;
        let o = self.opts;
        let cn = (self.width as usize).div_ceil(COARSE as usize)
            * (self.height as usize).div_ceil(COARSE as usize);
        let c = &mut self.coarse_model;
        for v in [&mut c.er, &mut c.eg, &mut c.eb] {
            v.clear();
            v.resize(cn, 0);
        }
        c.tau2.clear();
        c.tau2.resize(cn, 0);
        c.zone.clear();
        c.zone.resize(cn, 1);
        for i in 0..self.sum.len() {
            let s = self.sum[i];
            let m = [s[0] / n, s[1] / n, s[2] / n];
            // Per-channel variance (mean over channels); a single frame gives none.
            let var = if self.learned_frames > 1 {
                ((self.sum_sq[i] / n - (m[0] * m[0] + m[1] * m[1] + m[2] * m[2])) / 3.0).max(0.0)
            } else {
                DEFAULT_NOISE_SIGMA * DEFAULT_NOISE_SIGMA
            };
            let radius = (o.noise_k * (3.0 * var).sqrt()).max(o.min_distance);
            self.set_model(i, m, radius * radius);
        }
        self.backdrop_exposure = self.coarse_model.exposure();
    }

    /// Exposure statistics of the learned empty scene (zero before learning).
    pub fn backdrop_exposure(&self) -> ExposureStats {
        self.backdrop_exposure
    }

    #[inline]
    fn set_model(&mut self, i: usize, m: [f32; 3], tau2: f32) {
        let w = self.width as usize;
        self.set_model_xy(i, i % w, i / w, m, tau2);
    }

    /// Sets pixel `i` = (x, y) of the model (and its coarse copy when on the coarse grid).
    /// Values are positive, so `+ 0.5` and truncation round them without a libm call.
    #[inline]
    fn set_model_xy(&mut self, i: usize, x: usize, y: usize, m: [f32; 3], tau2: f32) {
        // Keep |E| away from zero so the ratios stay defined on black backdrops.
        let m = m.map(|v| v.clamp(1.0, 255.0));
        let zone = self.zone.get(i).copied().unwrap_or(1);
        let tau2_q = ((tau2.clamp(0.0, TAU2_MAX as f32) + 0.5) as u16).min(TAU2_MAX)
            | if zone != 0 { ZONE_BIT } else { 0 };
        self.px[i] = PixelModel {
            e_q8: m.map(|v| (v * COLOR_Q + 0.5) as u16),
            tau2: tau2_q,
        };
        if x.is_multiple_of(COARSE as usize) && y.is_multiple_of(COARSE as usize) {
            let cw = (self.width as usize).div_ceil(COARSE as usize);
            let k = (y / COARSE as usize) * cw + x / COARSE as usize;
            let c = &mut self.coarse_model;
            if k < c.er.len() {
                c.set_colour(k, m);
                c.tau2[k] = tau2_q & TAU2_MAX;
                c.zone[k] = zone;
            }
        }
    }

    /// The holes of the last frame's person that were left open (the backdrop seen
    /// through a gap, see the module docs), as runs of the coarse grid: cell `(x, y)`
    /// covers the pixels `[COARSE x, COARSE (x + 1)) x [COARSE y, COARSE (y + 1))`. The
    /// mask of [`Self::segment`] has them open, with their border re-tested at full
    /// resolution.
    pub fn open_holes(&self) -> &[imgproc::Run] {
        &self.open_holes
    }

    /// The model colour of a pixel.
    pub fn model_rgb(&self, x: u32, y: u32) -> [f32; 3] {
        let i = (y * self.width + x) as usize;
        self.px[i].color()
    }

    /// Horprasert-style foreground test of pixel index `i` with colour `p`, against the
    /// model scaled by the frame's exposure gain.
    #[inline(always)]
    fn is_foreground(&self, i: usize, p: [u8; 3]) -> bool {
        let m = self.px[i];
        let [er, eg, eb] = m.color();
        // A channel the model saw clipped is left out ([`classify::unclipped_weights`]).
        let w =
            classify::unclipped_weights((er + 0.5) as i32, (eg + 0.5) as i32, (eb + 0.5) as i32)
                .map(|k| k as f32);
        let [er, eg, eb] = [er * w[0], eg * w[1], eb * w[2]];
        let ee = er * er + eg * eg + eb * eb;
        let tau2 = m.radius2();
        let dr = (p[0] as f32 - er) * w[0];
        let dg = (p[1] as f32 - eg) * w[1];
        let db = (p[2] as f32 - eb) * w[2];
        let dd = dr * dr + dg * dg + db * db;
        let de = dr * er + dg * eg + db * eb;
        let o = &self.opts;
        let g = self.gain;
        let gm1 = g - 1.0;
        // |I - gE|^2 = |d - (g-1)E|^2
        let dg2 = dd - 2.0 * gm1 * de + gm1 * gm1 * ee;
        // |I - alpha E|^2 |E|^2
        let chroma_ee = dd * ee - de * de;
        // In the shadow zone: (alpha / g) |E|^2, at most |E|^2.
        let lit_ee = if m.in_zone() {
            ((ee + de) / g).clamp(0.0, ee)
        } else {
            ee
        };
        let ck = o.chroma_k * o.chroma_k;
        let darkest = if m.in_zone() {
            o.shadow_min_brightness
        } else {
            o.lit_min_brightness
        };
        dg2 > tau2
            && (chroma_ee * ee > ck * tau2 * lit_ee * lit_ee
                || de < (g * darkest - 1.0) * ee
                || de > (g * o.highlight_max_brightness - 1.0) * ee)
    }

    /// Pixel `i` of colour `p` against the gain-scaled model: the difference `p - gE`,
    /// the model's colour `E` and its squared noise radius.
    #[inline(always)]
    fn difference(&self, i: usize, p: [u8; 3]) -> ([f32; 3], [f32; 3], f32) {
        let m = self.px[i];
        let e = m.color();
        let g = self.gain;
        ([0, 1, 2].map(|c| p[c] as f32 - g * e[c]), e, m.radius2())
    }

    /// True when pixel `i` differs from the gain-scaled model beyond its noise radius
    /// (foreground or a shadow / exposure change).
    #[inline(always)]
    fn is_changed(&self, i: usize, p: [u8; 3]) -> bool {
        let (d, _, r2) = self.difference(i, p);
        d[0] * d[0] + d[1] * d[1] + d[2] * d[2] > r2
    }

    /// True when pixel `i` of colour `p` is changed and darker than the model (a shadow,
    /// when the model does not call it foreground).
    #[inline(always)]
    fn is_darkened(&self, i: usize, p: [u8; 3]) -> bool {
        let (d, e, r2) = self.difference(i, p);
        d[0] * d[0] + d[1] * d[1] + d[2] * d[2] > r2
            && d[0] * e[0] + d[1] * e[1] + d[2] * e[2] < 0.0
    }

    /// The sub-pixel edge score of `frame` against this model: colour distance in linear
    /// light (see [`EdgeScorer`]). None when the frame does not fit the model.
    pub fn edge_scorer<'a>(&'a self, frame: &'a RgbImage) -> Option<EdgeScorer<'a>> {
        let raw = frame.as_raw();
        if self.width == 0 || self.height == 0 || raw.len() != self.px.len() * 3 {
            return None;
        }
        Some(EdgeScorer {
            px: &self.px,
            raw,
            w: self.width as i64,
            h: self.height as i64,
            lut: srgb_to_linear(),
        })
    }

    /// Segments a frame into `mask_out` (resized to the frame): the largest person-sized
    /// component, its holes filled except those left open ([`Self::open_holes`]).
    ///
    /// The steps (see the module docs): put the frame at the model's exposure and label
    /// the coarse grid, let the person prior decide unsure cells, bridge the legs' shadowed
    /// cells, keep the largest component with its holes filled, upsample it and re-test
    /// its border at full resolution, then adapt the model away from the person.
    ///
    /// # Errors
    /// `NotReady` before any empty frame was learned; `FrameSize` / `Empty`.
    pub fn segment(
        &mut self,
        frame: &RgbImage,
        mask_out: &mut Mask,
    ) -> Result<SegmentStats, SegmentError> {
        self.check(frame)?;
        if !self.is_ready() {
            return Err(SegmentError::NotReady);
        }
        let raw = frame.as_raw();
        let mut stats = SegmentStats {
            frame_index: self.frames,
            ..Default::default()
        };
        let mut clock = PhaseClock::start();

        // 1. The coarse grid at the model's exposure (WEAK cells are even: the majority
        // filter of step 2, which counts `v & 1`, takes them as background).
        let g = self.estimate_gain(raw);
        self.gain = g;
        stats.gain = g;
        (stats.exposure, stats.tested_cells) = self.classify_coarse(raw, g);
        stats.phase_ms.classify = clock.lap();
        stats.fused_px = self.fuse_person_prior(raw);
        stats.phase_ms.fuse = clock.lap();
        self.bridge_shadowed_columns();
        stats.backdrop = self.backdrop_exposure;
        stats.phase_ms.classify += clock.lap();

        // 2. The person on the coarse grid: the largest component, holes filled.
        let body = self.largest_component(&mut stats);
        mask_out.reset(self.width, self.height);
        let Some(body) = body else {
            self.open_holes.clear();
            self.frames += 1;
            self.last_box = None;
            self.adapt(frame, None);
            return Ok(stats);
        };
        self.fill_body_holes(body);
        stats.phase_ms.components = clock.lap();

        // 3. Full resolution: upsample, then re-test the band along the border.
        let upsampled_px = self.upsample_body(mask_out);
        stats.phase_ms.upsample = clock.lap();
        self.find_band_cells();
        self.retest_band(raw);
        stats.person_px = self.settle_band(mask_out, upsampled_px);
        stats.band_px = self.band_px.len() as u32;
        stats.phase_ms.band = clock.lap();

        // 4. Statistics of the final mask (box from the coarse component, +-1 cell).
        let pb = self.person_box(body);
        stats.person_box = Some(pb);
        stats.touches = body::border_touch(mask_out);
        self.frames += 1;
        stats.phase_ms.stats = clock.lap();
        self.last_box = Some(pb);
        self.adapt(frame, Some(pb));
        stats.phase_ms.adapt = clock.lap();
        Ok(stats)
    }

    /// Frame and coarse grid sizes `(w, h, cw, ch)`, pixels and cells.
    #[inline]
    fn grid(&self) -> (usize, usize, usize, usize) {
        let (w, h) = (self.width as usize, self.height as usize);
        (
            w,
            h,
            w.div_ceil(COARSE as usize),
            h.div_ceil(COARSE as usize),
        )
    }
}
