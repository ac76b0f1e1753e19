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
//! grid), the coarse mask is cleaned by a 3x3 majority filter, its largest 8-connected
//! component is kept with its holes filled (except holes that look like the backdrop
//! seen through a gap: mostly unchanged, or shadowed inside the shadow zone), and the
//! full-resolution mask is that
//! component upsampled, with every pixel within one coarse cell of its border re-tested
//! at full resolution (then a 3x3 majority among those pixels). The model keeps
//! adapting slowly (a running mean) on a rotating band of rows, away from the person.
//!
//! Still images (the paper's case) go through [`key_still`]: against an empty-scene image
//! if there is one, else against a backdrop colour keyed from the image border.
//!
//! # Conventions
//! Pixels (column, row), origin at the top-left pixel; masks are 0/255, full resolution;
//! colours are 8-bit sRGB values used as they are (no linearisation), except for the
//! sub-pixel edge score ([`EdgeScorer`]), which compares colours in linear light.

pub mod fusion;

use crate::camera::Camera;
use crate::imgproc::{self, Mask, RunComponents, MASK_ON};
use glam::DVec2;
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
    /// changed cells (see [`bridge_columns`]).
    column_top: Vec<u32>,
    /// Per coarse column: the current run of changed cells holds a foreground cell
    /// outside the shadow zone (see [`bridge_columns`]).
    column_anchored: Vec<bool>,
    /// No shadow zone was set (no calibration): every pixel may be shadow.
    zone_everywhere: bool,
    tmp: Vec<u8>,
    eroded: Vec<u8>,
    dilated: Vec<u8>,
    runs: RunComponents,
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
    fusion: fusion::FusionRule,
    fuse_scratch: fusion::FuseScratch,
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
/// change, and such a cell bridged into the person (see [`bridge_columns`]). Foreground is
/// [`MASK_ON`], unchanged 0.
const WEAK: u8 = 2;
const BRIDGED: u8 = 253; // odd: the majority filter counts `v & 1`
/// Holes of fewer coarse cells are always filled (noise inside the body).
const OPEN_HOLE_MIN_CELLS: u64 = 8;
/// A hole stays open when at least this fraction of its cells is background evidence.
const OPEN_HOLE_FRACTION: f64 = 0.5;

/// Marks a column without an open run in [`bridge_columns`].
const NO_RUN: u32 = u32::MAX;

/// Promotes WEAK cells that lie in a column between two foreground cells, with only
/// changed cells between them, to BRIDGED (foreground), when the column's unbroken run
/// of changed cells above them holds a foreground cell outside the shadow zone (`zone`,
/// one flag per coarse cell, 1 in the zone); other WEAK cells stay WEAK (even, so
/// background to the majority filter).
///
/// A standing person is a vertical figure: where legs in trousers of the floor's own hue
/// cross the floor's image they look like their own cast shadow (darker, same chroma),
/// but they hang from the clearly changed thighs, seen against the backdrop above the
/// zone, down to the shoes. A floor shadow beside the feet has no foreground above it in
/// its column; the floor seen through the gap between the legs ends in unchanged (lit)
/// floor before anything below; and the shadowed floor between the two feet of a side
/// view lies under the far foot, which stands inside the zone with lit floor above it.
/// Without a calibration the whole frame is zone and the anchor is not asked for.
fn bridge_columns(
    coarse: &mut [u8],
    zone: &[u8],
    cw: usize,
    ch: usize,
    zone_everywhere: bool,
    top: &mut Vec<u32>,
    anchored: &mut Vec<bool>,
) {
    const CHUNK: usize = 16;
    top.clear();
    top.resize(cw, NO_RUN);
    anchored.clear();
    anchored.resize(cw, false);
    for cy in 0..ch {
        let row = cy * cw;
        let mut cx = 0;
        while cx < cw {
            // Most of a frame is unchanged: close the runs of a whole chunk at once.
            if cx % CHUNK == 0 {
                let end = (cx + CHUNK).min(cw);
                if coarse[row + cx..row + end].iter().all(|&v| v == 0) {
                    top[cx..end].fill(NO_RUN);
                    anchored[cx..end].fill(false);
                    cx = end;
                    continue;
                }
            }
            match coarse[row + cx] {
                0 => {
                    top[cx] = NO_RUN;
                    anchored[cx] = false;
                }
                WEAK => {}
                _ => {
                    let t = top[cx];
                    if t != NO_RUN && (t as usize) + 1 < cy && (anchored[cx] || zone_everywhere) {
                        for y in t as usize + 1..cy {
                            coarse[y * cw + cx] = BRIDGED;
                        }
                    }
                    top[cx] = cy as u32;
                    anchored[cx] |= zone[row + cx] == 0;
                }
            }
            cx += 1;
        }
    }
}

/// The colours of every second pixel of an RGB row, packed red in the low byte
/// (`out[k]` is pixel `2k`); `out` holds `ceil(pixels / 2)` values.
const _: () = assert!(COARSE == 2, "gather_coarse_row takes every second pixel");
fn gather_coarse_row(row: &[u8], rgb: &mut [u32]) {
    let cw = rgb.len();
    // Four cells (24 bytes) from three 64-bit loads.
    let quads = row.chunks_exact(24);
    let done = (4 * quads.len()).min(cw);
    for (v, q) in rgb.chunks_exact_mut(4).zip(quads) {
        let word = |k: usize| {
            let mut b = [0u8; 8];
            b.copy_from_slice(&q[8 * k..8 * k + 8]);
            u64::from_le_bytes(b)
        };
        let (a, b, c) = (word(0), word(1), word(2));
        const C: u64 = 0x00ff_ffff;
        v[0] = (a & C) as u32;
        v[1] = (((a >> 48) | (b << 16)) & C) as u32;
        v[2] = ((b >> 32) & C) as u32;
        v[3] = ((c >> 16) & C) as u32;
    }
    // The rest cell by cell, then an odd last pixel if any.
    let cells = row[(6 * done).min(row.len())..].chunks_exact(6);
    let last = cells.remainder();
    for (v, p) in rgb[done..].iter_mut().zip(cells) {
        *v = u32::from_le_bytes([p[0], p[1], p[2], 0]);
    }
    if let ([pr, pg, pb, ..], Some(v)) = (last, rgb.last_mut()) {
        *v = u32::from_le_bytes([*pr, *pg, *pb, 0]);
    }
}

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
            tmp: Vec::new(),
            eroded: Vec::new(),
            dilated: Vec::new(),
            runs: RunComponents::default(),
            hole_runs: RunComponents::default(),
            open_holes: Vec::new(),
            band_state: vec![BAND_NONE; n],
            band_px: Vec::new(),
            band_cells: Vec::new(),
            band_out: Vec::new(),
            prior: None,
            fusion: fusion::FusionRule::default(),
            fuse_scratch: fusion::FuseScratch::default(),
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

    /// Sets the shadow zone (non-zero pixels of `zone`, same size as the model): where the
    /// person's cast shadow may fall. Outside it only exposure changes count as
    /// background. Before this call the whole frame is zone.
    ///
    /// # Errors
    /// `ZoneSize` when `zone` differs in size from the model.
    pub fn set_shadow_zone(&mut self, zone: &Mask) -> Result<(), SegmentError> {
        if zone.width != self.width || zone.height != self.height {
            return Err(SegmentError::ZoneSize {
                want_w: self.width,
                want_h: self.height,
                got_w: zone.width,
                got_h: zone.height,
            });
        }
        let w = self.width as usize;
        let cw = w.div_ceil(COARSE as usize);
        self.zone_everywhere = zone.data.iter().all(|&v| v != 0);
        for (i, &v) in zone.data.iter().enumerate() {
            let z = (v != 0) as u8;
            self.zone[i] = z;
            let t = &mut self.px[i].tau2;
            *t = (*t & TAU2_MAX) | if z != 0 { ZONE_BIT } else { 0 };
            let (x, y) = (i % w, i / w);
            if x.is_multiple_of(COARSE as usize) && y.is_multiple_of(COARSE as usize) {
                let k = (y / COARSE as usize) * cw + x / COARSE as usize;
                if let Some(c) = self.coarse_model.zone.get_mut(k) {
                    *c = z;
                }
            }
        }
        Ok(())
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
        let ee = er * er + eg * eg + eb * eb;
        let tau2 = m.radius2();
        let dr = p[0] as f32 - er;
        let dg = p[1] as f32 - eg;
        let db = p[2] as f32 - eb;
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

    /// True when pixel `i` differs from the gain-scaled model beyond its noise radius
    /// (foreground or a shadow / exposure change).
    #[inline(always)]
    fn is_changed(&self, i: usize, p: [u8; 3]) -> bool {
        let m = self.px[i];
        let e = m.color();
        let g = self.gain;
        let d = [0, 1, 2].map(|c| p[c] as f32 - g * e[c]);
        d[0] * d[0] + d[1] * d[1] + d[2] * d[2] > m.radius2()
    }

    /// The frame's exposure gain against the model: the median brightness ratio
    /// `alpha = I.E / |E|^2` over a sparse grid of pixels away from the person's last box
    /// whose colour is the model's up to brightness (low chromaticity distortion), not
    /// clipped. Exposure flicker and drift scale the whole backdrop; the person covers a
    /// minority of the sample, and the chromaticity gate drops most of it. Without enough
    /// samples, or when the estimate is implausible for an exposure change, the gain is 1.
    fn estimate_gain(&mut self, raw: &[u8]) -> f32 {
        const MIN_SAMPLES: usize = 64;
        let (w, h) = (self.width as usize, self.height as usize);
        // About a thousand samples or more, at most every 16th pixel (3600 at 720p).
        let step = (((w * h) as f64 / 1024.0).sqrt() as usize).clamp(1, 16);
        let keep_out = self.last_box.map(keep_out_box);
        self.gain_samples.clear();
        let ck2 = self.opts.chroma_k * self.opts.chroma_k;
        for y in (step / 2..h).step_by(step) {
            for x in (step / 2..w).step_by(step) {
                if let Some((x0, y0, x1, y1)) = keep_out {
                    if x >= x0 && x < x1 && y >= y0 && y < y1 {
                        continue;
                    }
                }
                let i = y * w + x;
                let p = [raw[3 * i], raw[3 * i + 1], raw[3 * i + 2]];
                if p.iter().any(|&v| v >= CLIP_HIGH_LUMA || v <= CLIP_LOW_LUMA) {
                    continue;
                }
                let m = self.px[i];
                let e = m.color();
                let ee = e[0] * e[0] + e[1] * e[1] + e[2] * e[2];
                if ee < 400.0 {
                    continue; // too dark a model for a ratio
                }
                let pe = p[0] as f32 * e[0] + p[1] as f32 * e[1] + p[2] as f32 * e[2];
                let alpha = pe / ee;
                let c = [0, 1, 2].map(|k| p[k] as f32 - alpha * e[k]);
                if c[0] * c[0] + c[1] * c[1] + c[2] * c[2] > ck2 * m.radius2() {
                    continue;
                }
                self.gain_samples.push(alpha);
            }
        }
        if self.gain_samples.len() < MIN_SAMPLES {
            return 1.0;
        }
        let mid = self.gain_samples.len() / 2;
        let (_, &mut g, _) = self
            .gain_samples
            .select_nth_unstable_by(mid, f32::total_cmp);
        if (MIN_GAIN..=MAX_GAIN).contains(&g) {
            g
        } else {
            1.0
        }
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
        let (w, h) = (self.width as usize, self.height as usize);
        let (cw, ch) = (w.div_ceil(COARSE as usize), h.div_ceil(COARSE as usize));
        let raw = frame.as_raw();
        let mut stats = SegmentStats {
            frame_index: self.frames,
            ..Default::default()
        };
        let mut clock = PhaseClock::start();

        // 1. Coarse classification and exposure statistics: gather one coarse row into
        // packed 32-bit colours, then a branch-free test the compiler vectorises.
        self.coarse.clear();
        self.coarse.resize(cw * ch, 0);
        self.row_rgb.resize(cw, 0);
        let (mut luma_sum, mut hi, mut lo) = (0u64, 0u64, 0u64);
        let o = self.opts;
        let ck2 = o.chroma_k * o.chroma_k;
        // Brightness bounds about the frame's exposure gain g: alpha = 1 + d.E/|E|^2 is
        // compared with g * bound, so d.E is compared with (g * bound - 1) |E|^2.
        let g = self.estimate_gain(raw);
        self.gain = g;
        stats.gain = g;
        let gm1 = g - 1.0;
        let (klo_zone, klo_lit, khi) = (
            g * o.shadow_min_brightness - 1.0,
            g * o.lit_min_brightness - 1.0,
            g * o.highlight_max_brightness - 1.0,
        );
        let klo_step = klo_zone - klo_lit;
        let inv_g = 1.0 / g;
        for cy in 0..ch {
            let y = cy * COARSE as usize;
            let row = &raw[3 * y * w..3 * (y + 1) * w];
            let rgb = &mut self.row_rgb;
            gather_coarse_row(row, rgb);
            // Exposure statistics (integer, vectorised).
            let (mut sum, mut n_hi, mut n_lo) = (0u32, 0u32, 0u32);
            for &v in rgb.iter() {
                let (r, g, b) = (v & 0xff, (v >> 8) & 0xff, v >> 16);
                let l = luma8(r, g, b);
                sum += l;
                n_hi += (l >= CLIP_HIGH_LUMA as u32) as u32;
                n_lo += (l <= CLIP_LOW_LUMA as u32) as u32;
            }
            luma_sum += sum as u64;
            hi += n_hi as u64;
            lo += n_lo as u64;
            let m = &self.coarse_model;
            let span = cy * cw..(cy + 1) * cw;
            let out = &mut self.coarse[span.clone()];
            let it = out
                .iter_mut()
                .zip(rgb.iter())
                .zip(
                    m.er[span.clone()]
                        .iter()
                        .zip(&m.eg[span.clone()])
                        .zip(&m.eb[span.clone()]),
                )
                .zip(m.tau2[span.clone()].iter().zip(&m.zone[span]));
            for (((o, &v), ((&er, &eg), &eb)), (&tau2, &zone)) in it {
                let (r, g, b) = (v & 0xff, (v >> 8) & 0xff, v >> 16);
                // Integer differences and dot products (exact), f32 for the products.
                let (er, eg, eb) = (er as i32, eg as i32, eb as i32);
                let (dr, dg, db) = (r as i32 - er, g as i32 - eg, b as i32 - eb);
                let dd = (dr * dr + dg * dg + db * db) as f32;
                let de = (dr * er + dg * eg + db * eb) as f32;
                let ee = (er * er + eg * eg + eb * eb) as f32;
                let tau2 = tau2 as f32;
                let zone = zone as f32; // 1 in the shadow zone, else 0
                let klo = klo_lit + zone * klo_step;
                let chroma_ee = dd * ee - de * de;
                // In the shadow zone the chromaticity tolerance scales with the brightness
                // ratio (see `chroma_k`): (alpha / g) |E|^2, at most |E|^2.
                let lit_ee = ee + zone * (((ee + de) * inv_g).clamp(0.0, ee) - ee);
                // |I - gE|^2 = |d - (g-1)E|^2
                let dg2 = dd - 2.0 * gm1 * de + gm1 * gm1 * ee;
                let cand = dg2 > tau2;
                let fg = cand
                    & ((chroma_ee * ee > ck2 * tau2 * lit_ee * lit_ee)
                        | (de < klo * ee)
                        | (de > khi * ee));
                // 255: foreground; 1: changed, but explained as shadow or exposure (WEAK).
                *o = (fg as u8).wrapping_neg() | (cand as u8) << 1;
            }
        }
        stats.phase_ms.classify = clock.lap();
        // The learned person prior decides the cells the backdrop is unsure of.
        let (mut coarse, mut scratch) = (
            std::mem::take(&mut self.coarse),
            std::mem::take(&mut self.fuse_scratch),
        );
        stats.fused_px =
            self.fuse_coarse(raw, &mut coarse, cw, &mut scratch) * (COARSE * COARSE) as u64;
        (self.coarse, self.fuse_scratch) = (coarse, scratch);
        stats.phase_ms.fuse = clock.lap();
        // WEAK cells are even: the majority filter below (which counts `v & 1`) takes
        // them as background without a clean-up pass.
        if o.bridge_columns {
            bridge_columns(
                &mut self.coarse,
                &self.coarse_model.zone,
                cw,
                ch,
                self.zone_everywhere,
                &mut self.column_top,
                &mut self.column_anchored,
            );
        }
        let nc = (cw * ch) as f32;
        stats.exposure = ExposureStats::from_counts(luma_sum, hi, lo, cw * ch);
        stats.backdrop = self.backdrop_exposure;

        stats.phase_ms.classify += clock.lap();
        // 2. Clean-up, components, largest with holes filled.
        imgproc::majority3x3(&self.coarse, cw, ch, &mut self.coarse_clean, &mut self.tmp);
        self.runs
            .compute(&self.coarse_clean, cw as u32, ch as u32, true, true);
        let cell = (COARSE * COARSE) as u64;
        let min_area = (self.opts.min_person_fraction * nc) as u64;
        stats.large_components = self
            .runs
            .components
            .iter()
            .filter(|c| c.area >= min_area.max(1))
            .count() as u32;
        let (first, second) = self.runs.two_largest();
        stats.second_px = second.map_or(0, |c| self.runs.components[c].area * cell);
        mask_out.reset(self.width, self.height);
        let body = match first {
            Some(c) if self.runs.components[c].area >= min_area.max(1) => c,
            _ => {
                self.open_holes.clear();
                self.frames += 1;
                self.last_box = None;
                self.adapt(frame, None);
                return Ok(stats);
            }
        };
        stats.largest_px = self.runs.components[body].area * cell;
        // Holes: filled, unless they look like the backdrop seen through a gap (between
        // an arm and the trunk, between the feet): most of their cells unchanged, or
        // darkened like a shadow inside the shadow zone. A part of the person that only
        // matches the backdrop in places (a white shirt on a white backdrop) keeps enough
        // changed cells to be filled.
        imgproc::write_component(&self.runs, body, &mut self.coarse_body);
        if o.open_holes {
            let (coarse, zone) = (&self.coarse, &self.coarse_model.zone);
            imgproc::fill_holes_selective(
                &mut self.coarse_body,
                cw as u32,
                ch as u32,
                &mut self.hole_runs,
                &mut self.hole_evidence,
                |y, x0, x1| {
                    let row = y * cw;
                    coarse[row + x0..row + x1]
                        .iter()
                        .zip(&zone[row + x0..row + x1])
                        .filter(|&(&c, &z)| c == 0 || (c == WEAK && z != 0))
                        .count() as u64
                },
                OPEN_HOLE_MIN_CELLS,
                OPEN_HOLE_FRACTION,
                &mut self.open_holes,
            );
        } else {
            self.open_holes.clear();
            imgproc::fill_holes(
                &mut self.coarse_body,
                cw as u32,
                ch as u32,
                &mut self.hole_runs,
            );
        }

        stats.phase_ms.components = clock.lap();
        // 3. Upsample, then re-test the band along the border at full resolution.
        // (mask_out is all zero here: fill the coarse runs, then copy the row down.)
        let mut upsampled_px = 0u64;
        let c2 = COARSE as usize;
        for cy in 0..ch {
            let crow = &self.coarse_body[cy * cw..(cy + 1) * cw];
            let y = cy * c2;
            let (first, rest) = mask_out.data[y * w..].split_at_mut(w);
            let mut x = 0;
            let mut any = false;
            while x < cw {
                let Some(a) = crow[x..].iter().position(|&v| v != 0) else {
                    break;
                };
                let x0 = x + a;
                let len = crow[x0..].iter().position(|&v| v == 0).unwrap_or(cw - x0);
                x = x0 + len;
                let span = &mut first[x0 * c2..(x * c2).min(w)];
                span.fill(MASK_ON);
                upsampled_px += (span.len() * c2.min(h - y)) as u64;
                any = true;
            }
            if any {
                for dy in 1..c2 {
                    if y + dy < h {
                        rest[(dy - 1) * w..dy * w].copy_from_slice(first);
                    }
                }
            }
        }
        stats.phase_ms.upsample = clock.lap();
        imgproc::erode3x3(&self.coarse_body, cw, ch, &mut self.eroded, &mut self.tmp);
        imgproc::dilate3x3(&self.coarse_body, cw, ch, &mut self.dilated, &mut self.tmp);
        self.band_px.clear();
        self.band_cells.clear();
        const SKIP_CHUNK: usize = 16;
        // The band's cells first (no model access), then their pixels: the model rows of
        // the cell a few places ahead are prefetched, as the band's cells are scattered
        // along the person's outline and every one of them misses the cache.
        for cy in 0..ch {
            let (er_row, di_row) = (
                &self.eroded[cy * cw..(cy + 1) * cw],
                &self.dilated[cy * cw..(cy + 1) * cw],
            );
            if er_row == di_row {
                continue;
            }
            let mut cx = 0;
            while cx < cw {
                if cx % SKIP_CHUNK == 0 {
                    let end = (cx + SKIP_CHUNK).min(cw);
                    if er_row[cx..end] == di_row[cx..end] {
                        cx = end;
                        continue;
                    }
                }
                if er_row[cx] != di_row[cx] {
                    self.band_cells.push([cx as u32, cy as u32]);
                }
                cx += 1;
            }
        }
        const AHEAD: usize = 8;
        for k in 0..self.band_cells.len() {
            if let Some(&[ax, ay]) = self.band_cells.get(k + AHEAD) {
                let i = (ay * COARSE) as usize * w + (ax * COARSE) as usize;
                prefetch(&self.px, i);
                prefetch(&self.px, i + w);
                prefetch(raw, 3 * i);
                prefetch(raw, 3 * (i + w));
            }
            let [cx, cy] = self.band_cells[k];
            let (cx, cy) = (cx as usize, cy as usize);
            // A changed pixel keeps its cell's verdict when the cell was bridged, or when
            // the cell's own sample was foreground in the shadow zone: there the shadow
            // tolerance explains a shaded shoe's heel like the floor's shadow, and
            // clearing those pixels would cut a far foot off the leg it touches.
            let label = self.coarse[cy * cw + cx];
            let bridged =
                label == BRIDGED || (label == MASK_ON && self.coarse_model.zone[cy * cw + cx] != 0);
            // Pixels the fusion makes person (see `fusion`).
            let fused_ratio2 = self.fused_min_ratio2(cx, cy);
            for dy in 0..COARSE as usize {
                for dx in 0..COARSE as usize {
                    let (x, y) = (cx * COARSE as usize + dx, cy * COARSE as usize + dy);
                    if x < w && y < h {
                        let i = y * w + x;
                        let p = [raw[3 * i], raw[3 * i + 1], raw[3 * i + 2]];
                        self.band_state[i] = if self.is_foreground(i, p)
                            || (bridged && self.is_changed(i, p))
                            || (fused_ratio2.is_finite() && self.ratio2(i, p) >= fused_ratio2)
                        {
                            BAND_FG
                        } else {
                            BAND_BG
                        };
                        self.band_px.push([x as u32, y as u32]);
                    }
                }
            }
        }
        // 3x3 majority over band pixels (outside the band: the upsampled label).
        self.band_out.clear();
        let (state, up) = (&self.band_state, &mask_out.data);
        let vote = |j: usize| -> i32 {
            let s = state[j];
            ((s == BAND_FG) | ((s == BAND_NONE) & (up[j] != 0))) as i32
        };
        for &[x, y] in &self.band_px {
            let (x, y) = (x as usize, y as usize);
            let mut votes = 0;
            if x > 0 && y > 0 && x + 1 < w && y + 1 < h {
                let c = y * w + x;
                for row in [c - w, c, c + w] {
                    votes += vote(row - 1) + vote(row) + vote(row + 1);
                }
            } else {
                for ny in y.saturating_sub(1)..=(y + 1).min(h - 1) {
                    for nx in x.saturating_sub(1)..=(x + 1).min(w - 1) {
                        votes += vote(ny * w + nx);
                    }
                }
            }
            self.band_out.push(if votes >= 5 { MASK_ON } else { 0 });
        }
        stats.band_px = self.band_px.len() as u32;
        for (&[x, y], &v) in self.band_px.iter().zip(&self.band_out) {
            let i = y as usize * w + x as usize;
            let old = &mut mask_out.data[i];
            upsampled_px = upsampled_px + (v != 0) as u64 - (*old != 0) as u64;
            *old = v;
            self.band_state[i] = BAND_NONE;
        }

        stats.phase_ms.band = clock.lap();
        // 4. Statistics of the final mask (box from the coarse component, +-1 cell).
        let c = self.runs.components[body];
        let pb = PixelBox {
            min_x: (c.min_x.saturating_sub(1)) * COARSE,
            min_y: (c.min_y.saturating_sub(1)) * COARSE,
            max_x: ((c.max_x + 1) * COARSE).min(self.width),
            max_y: ((c.max_y + 1) * COARSE).min(self.height),
        };
        stats.person_box = Some(pb);
        stats.person_px = upsampled_px;
        stats.touches = BorderTouch {
            top: mask_out.data[..w].iter().any(|&v| v != 0),
            bottom: mask_out.data[(h - 1) * w..].iter().any(|&v| v != 0),
            left: (0..h).any(|y| mask_out.data[y * w] != 0),
            right: (0..h).any(|y| mask_out.data[y * w + w - 1] != 0),
        };
        self.frames += 1;
        stats.phase_ms.stats = clock.lap();
        self.last_box = Some(pb);
        self.adapt(frame, Some(pb));
        stats.phase_ms.adapt = clock.lap();
        Ok(stats)
    }

    /// Running-mean update of a rotating band of rows, outside the person's box.
    fn adapt(&mut self, frame: &RgbImage, person: Option<PixelBox>) {
        let rate = self.opts.adapt_rate;
        if rate <= 0.0 {
            return;
        }
        let w = self.width as usize;
        let raw = frame.as_raw();
        let phase = self.frames % ADAPT_ROW_STRIDE;
        let keep_out = person.map(keep_out_box);
        let cw = w.div_ceil(COARSE as usize);
        let mut y = phase as usize;
        while y < self.height as usize {
            // The row's spans outside the person's box.
            let (a, b) = match keep_out {
                Some((x0, y0, x1, y1)) if y >= y0 && y < y1 => ((0, x0.min(w)), (x1.min(w), w)),
                _ => ((0, w), (w, w)),
            };
            let coarse_row = y
                .is_multiple_of(COARSE as usize)
                .then(|| (y / COARSE as usize) * cw);
            for x in (a.0..a.1).chain(b.0..b.1) {
                let i = y * w + x;
                let p = [raw[3 * i], raw[3 * i + 1], raw[3 * i + 2]];
                if self.is_foreground(i, p) {
                    continue; // someone else, or a change too large to learn silently
                }
                // The raw colour: the model follows a lasting drift of the light, so the
                // gain only has the frame's flicker about it to explain. The noise radius
                // and the zone stay.
                let e = self.px[i].color();
                let m = [0, 1, 2].map(|c| (e[c] + rate * (p[c] as f32 - e[c])).clamp(1.0, 255.0));
                self.px[i].e_q8 = m.map(|v| (v * COLOR_Q + 0.5) as u16);
                if let Some(row) = coarse_row.filter(|_| x.is_multiple_of(COARSE as usize)) {
                    let k = row + x / COARSE as usize;
                    if k < self.coarse_model.er.len() {
                        self.coarse_model.set_colour(k, m);
                    }
                }
            }
            y += ADAPT_ROW_STRIDE as usize;
        }
    }
}

/// The shadow zone of a calibrated camera (see the module docs): pixels whose viewing ray
/// meets the floor (y = 0) within `radius_m` of the mark, written into `out` (resized to
/// the camera's frame). Tested once per block of [`ZONE_BLOCK_PX`] pixels.
pub fn floor_shadow_zone(camera: &Camera, radius_m: f64, out: &mut Mask) {
    let (w, h) = (camera.intrinsics.width, camera.intrinsics.height);
    out.reset(w, h);
    let b = ZONE_BLOCK_PX;
    for by in (0..h).step_by(b as usize) {
        for bx in (0..w).step_by(b as usize) {
            let c = DVec2::new(
                (bx + b / 2).min(w - 1) as f64,
                (by + b / 2).min(h - 1) as f64,
            );
            let ray = camera.ray_through_pixel(c);
            if ray.dir.y >= -1e-9 {
                continue; // at or above the horizon: never the floor
            }
            let p = ray.at(-ray.origin.y / ray.dir.y);
            if p.x.hypot(p.z) > radius_m {
                continue;
            }
            for y in by..(by + b).min(h) {
                let row = (y * w) as usize;
                out.data[row + bx as usize..row + (bx + b).min(w) as usize].fill(MASK_ON);
            }
        }
    }
}

/// Segments a still image (the paper's case: one image per view against a plain
/// backdrop). With `empty`, the empty-scene image of the same view is the background;
/// without, the backdrop colour is keyed from the left and right image borders (per row,
/// interpolated across, smoothed over rows), which tolerates a vertical light gradient.
///
/// # Errors
/// `FrameSize` when `empty` differs in size from `frame`; `Empty` for a 0-pixel frame.
pub fn key_still(frame: &RgbImage, empty: Option<&RgbImage>) -> Result<Mask, SegmentError> {
    let (w, h) = frame.dimensions();
    if w == 0 || h == 0 {
        return Err(SegmentError::Empty);
    }
    let opts = SegmentOptions {
        adapt_rate: 0.0,
        ..Default::default()
    };
    let mut model = BackgroundModel::new(w, h, opts);
    match empty {
        Some(e) => model.learn(e)?,
        None => {
            let backdrop = backdrop_from_border(frame);
            model.learn(&backdrop)?;
        }
    }
    let mut mask = Mask::new(w, h);
    model.segment(frame, &mut mask)?;
    Ok(mask)
}

/// An image of the backdrop alone, estimated from the left and right border strips of a
/// still image (per row, interpolated across, smoothed over rows).
pub fn backdrop_from_border(frame: &RgbImage) -> RgbImage {
    let (w, h) = frame.dimensions();
    let strip = KEY_BORDER_PX.min(w / 4).max(1);
    let mut left = vec![[0f32; 3]; h as usize];
    let mut right = vec![[0f32; 3]; h as usize];
    for y in 0..h {
        for x in 0..strip {
            let pl = frame.get_pixel(x, y).0;
            let pr = frame.get_pixel(w - 1 - x, y).0;
            for c in 0..3 {
                left[y as usize][c] += pl[c] as f32 / strip as f32;
                right[y as usize][c] += pr[c] as f32 / strip as f32;
            }
        }
    }
    let smooth = |v: &[[f32; 3]]| -> Vec<[f32; 3]> {
        (0..v.len())
            .map(|y| {
                let (a, b) = (
                    y.saturating_sub(KEY_ROW_SMOOTH),
                    (y + KEY_ROW_SMOOTH + 1).min(v.len()),
                );
                let mut s = [0f32; 3];
                for row in &v[a..b] {
                    for c in 0..3 {
                        s[c] += row[c] / (b - a) as f32;
                    }
                }
                s
            })
            .collect()
    };
    let (left, right) = (smooth(&left), smooth(&right));
    let mut out = RgbImage::new(w, h);
    for (x, y, p) in out.enumerate_pixels_mut() {
        let t = if w > 1 {
            x as f32 / (w - 1) as f32
        } else {
            0.0
        };
        let (l, r) = (left[y as usize], right[y as usize]);
        p.0 = [0, 1, 2].map(|c| (l[c] + t * (r[c] - l[c])).round().clamp(0.0, 255.0) as u8);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An image whose pixel (x, y) is `colour(x, y, r)`, with `r` from a xorshift
    /// sequence seeded by `seed` (the noise).
    fn painted(
        w: u32,
        h: u32,
        seed: u32,
        mut colour: impl FnMut(u32, u32, u32) -> [u8; 3],
    ) -> RgbImage {
        let mut img = RgbImage::new(w, h);
        let mut s = seed.wrapping_mul(2654435761).wrapping_add(1);
        for (x, y, p) in img.enumerate_pixels_mut() {
            s ^= s << 13;
            s ^= s >> 17;
            s ^= s << 5;
            p.0 = colour(x, y, s);
        }
        img
    }

    /// A shadow zone of the rows from `y0` down (the floor's image).
    fn zone_from_row(w: u32, h: u32, y0: u32) -> Mask {
        let mut zone = Mask::new(w, h);
        zone.data[(y0 * w) as usize..].fill(255);
        zone
    }

    fn scene(w: u32, h: u32, person: bool, shadow: bool, seed: u32) -> RgbImage {
        painted(w, h, seed, |x, y, s| {
            let n = (s % 7) as i32 - 3;
            let base = 150 + ((x / 8 + y / 8) % 2) as i32 * 20;
            let mut c = [base + n, base + 5 + n, base - 10 + n];
            if shadow && y > 80 && (30..90).contains(&x) {
                c = c.map(|v| v * 7 / 10);
            }
            if person && (40..70).contains(&x) && (20..90).contains(&y) {
                c = [200 + n, 120 + n, 90 + n];
            }
            c.map(|v| v.clamp(0, 255) as u8)
        })
    }

    #[test]
    fn person_is_found_and_shadow_is_not() {
        let (w, h) = (120, 100);
        let mut m = BackgroundModel::new(w, h, SegmentOptions::default());
        for k in 0..5 {
            m.learn(&scene(w, h, false, false, k)).unwrap();
        }
        let mut mask = Mask::new(1, 1);
        let st = m.segment(&scene(w, h, true, true, 99), &mut mask).unwrap();
        let mut truth = Mask::new(w, h);
        for y in 20..90 {
            for x in 40..70 {
                truth.data[(y * w + x) as usize] = 255;
            }
        }
        let iou = mask.iou(&truth);
        assert!(iou > 0.97, "iou {iou}");
        assert_eq!(st.large_components, 1);
        assert_eq!(st.person_px, mask.area());
        assert!(!st.touches.bottom);
    }

    fn scaled(img: &RgbImage, gain: f32) -> RgbImage {
        let mut out = img.clone();
        for p in out.pixels_mut() {
            p.0 =
                p.0.map(|v| (v as f32 * gain).round().clamp(0.0, 255.0) as u8);
        }
        out
    }

    #[test]
    fn the_model_follows_a_slow_light_drift_where_nobody_is() {
        let (w, h) = (120, 100);
        let opts = SegmentOptions {
            adapt_rate: 1.0,
            ..Default::default()
        };
        let mut adaptive = BackgroundModel::new(w, h, opts);
        let mut fixed = BackgroundModel::new(
            w,
            h,
            SegmentOptions {
                adapt_rate: 0.0,
                ..opts
            },
        );
        let empty = scene(w, h, false, false, 3);
        adaptive.learn(&empty).unwrap();
        fixed.learn(&empty).unwrap();
        let mut mask = Mask::new(1, 1);
        // Light rising in steps each within the brightness tolerance, a full sweep of
        // the adaptation's rows per step.
        for gain in [1.1f32, 1.2, 1.3, 1.4, 1.5] {
            for _ in 0..ADAPT_ROW_STRIDE {
                adaptive.segment(&scaled(&empty, gain), &mut mask).unwrap();
            }
        }
        let bright = scaled(&scene(w, h, true, false, 4), 1.5);
        let st = adaptive.segment(&bright, &mut mask).unwrap();
        let box_ = st.person_box.unwrap();
        assert!(
            box_.min_x >= 36 && box_.max_x <= 74 && box_.min_y >= 16 && box_.max_y <= 94,
            "{box_:?}"
        );
        // Without adaptation the whole brighter frame is foreground.
        let st = fixed.segment(&bright, &mut mask).unwrap();
        assert!(st.person_px > (w * h) as u64 / 2, "{}", st.person_px);
    }

    #[test]
    fn darker_same_hue_is_shadow_only_inside_the_shadow_zone() {
        let (w, h) = (120, 100);
        let empty = scene(w, h, false, false, 5);
        // A "person" of the backdrop's own hue at 70 % of its brightness.
        let mut frame = scene(w, h, false, false, 6);
        for y in 20..90 {
            for x in 40..70 {
                let p = frame.get_pixel_mut(x, y);
                p.0 = p.0.map(|v| (v as u32 * 7 / 10) as u8);
            }
        }
        let mut mask = Mask::new(1, 1);
        let mut m = BackgroundModel::new(w, h, SegmentOptions::default());
        m.learn(&empty).unwrap();
        // Whole frame zone (no calibration): explained as a cast shadow.
        assert_eq!(m.segment(&frame, &mut mask).unwrap().person_px, 0);
        // Zone on the bottom rows only (the floor): the figure is found, a shadow on the
        // floor rows is not.
        m.set_shadow_zone(&zone_from_row(w, h, 85)).unwrap();
        let st = m.segment(&frame, &mut mask).unwrap();
        let b = st.person_box.unwrap();
        assert!(
            b.min_y <= 22 && b.max_y >= 84 && b.min_x <= 42 && b.max_x >= 68,
            "{b:?}"
        );
        assert!(matches!(
            m.set_shadow_zone(&Mask::new(3, 3)),
            Err(SegmentError::ZoneSize { .. })
        ));
    }

    #[test]
    fn a_dark_shoe_of_the_floors_hue_is_not_taken_for_its_shadow() {
        // A brown floor; a shadow at 60 % of its brightness; a shoe at the same brightness
        // whose colour is turned by 11 levels across the floor's (a greyer brown): within
        // the noise radius (14) at full brightness, beyond it at 60 % (8.4).
        let (w, h) = (120, 100);
        let floor = [150.0f32, 115.0, 80.0];
        let across = [-1.0f32, 0.5, 1.2]; // nearly orthogonal to the floor's colour
        let n = across.iter().map(|v| v * v).sum::<f32>().sqrt();
        let shoe = [0, 1, 2].map(|c| 0.6 * floor[c] + 11.0 * across[c] / n);
        // The floor with rectangles (columns, rows, colour) painted over it, plus noise.
        type Patch = (std::ops::Range<u32>, std::ops::Range<u32>, [f32; 3]);
        let paint = |seed: u32, patches: &[Patch]| {
            painted(w, h, seed, |x, y, s| {
                let n = (s % 5) as f32 - 2.0;
                let c = patches
                    .iter()
                    .find(|(xs, ys, _)| xs.contains(&x) && ys.contains(&y))
                    .map_or(floor, |p| p.2);
                c.map(|v| (v + n).round().clamp(0.0, 255.0) as u8)
            })
        };
        let mut m = BackgroundModel::new(w, h, SegmentOptions::default());
        for k in 0..5 {
            m.learn(&paint(k, &[])).unwrap();
        }
        let mut mask = Mask::new(1, 1);
        // Whole frame zone (no calibration): a shadow may fall anywhere.
        let shadow = floor.map(|v| 0.6 * v);
        let frame = paint(9, &[(10..50, 40..70, shoe), (70..110, 40..70, shadow)]);
        let st = m.segment(&frame, &mut mask).unwrap();
        let b = st.person_box.expect("the shoe is found");
        assert!(
            b.min_x <= 12 && b.max_x >= 48 && b.min_y <= 42 && b.max_y >= 68 && b.max_x <= 54,
            "{b:?}"
        );
        let shoe_px = 40 * 30;
        assert!(
            st.person_px.abs_diff(shoe_px) < shoe_px / 20,
            "{} pixels for a shoe of {shoe_px}",
            st.person_px
        );
        // Outside the shadow zone only the exposure varies and the tolerance stays the
        // full noise radius: a patch at 90 % brightness turned by 12.8 levels (beyond
        // the angle's 12.6, within the radius's 14) is backdrop there, not person.
        let dim = [0, 1, 2].map(|c| 0.9 * floor[c] + 12.8 * across[c] / n);
        let frame = paint(11, &[(30..90, 20..60, dim)]);
        m.set_shadow_zone(&zone_from_row(w, h, 90)).unwrap();
        let st = m.segment(&frame, &mut mask).unwrap();
        assert_eq!(st.person_px, 0, "{:?}", st.person_box);
    }

    #[test]
    fn weak_cells_are_bridged_only_between_foreground_cells_of_their_column() {
        const F: u8 = MASK_ON;
        const W: u8 = WEAK;
        // Columns: a leg (thigh, shin of the floor's hue, shoe); the floor seen between
        // the legs (ends in lit floor); a shadow beside the feet (nothing above).
        #[rustfmt::skip]
        let mut c = vec![
            F, F, 0,
            W, W, 0,
            W, W, W,
            F, 0, W,
            0, 0, F,
        ];
        let (mut top, mut anchored) = (Vec::new(), Vec::new());
        let zone = vec![1; 15];
        bridge_columns(&mut c, &zone, 3, 5, true, &mut top, &mut anchored);
        #[rustfmt::skip]
        let want = vec![
            F, F, 0,
            BRIDGED, W, 0,
            BRIDGED, W, W,
            F, 0, W,
            0, 0, F,
        ];
        assert_eq!(c, want);
    }

    #[test]
    fn a_bridge_needs_foreground_outside_the_shadow_zone_above_it() {
        const F: u8 = MASK_ON;
        const W: u8 = WEAK;
        // Columns: a shin of the floor's hue under a thigh seen against the backdrop
        // (row 0 is outside the zone); the shadowed floor of a side view between the far
        // foot (row 2, in the zone, lit floor above it) and the near foot (row 4).
        #[rustfmt::skip]
        let cells = vec![
            F, 0,
            W, 0,
            F, F,
            W, W,
            F, F,
        ];
        #[rustfmt::skip]
        let zone = vec![
            0, 0,
            1, 1,
            1, 1,
            1, 1,
            1, 1,
        ];
        let (mut top, mut anchored) = (Vec::new(), Vec::new());
        let mut c = cells.clone();
        bridge_columns(&mut c, &zone, 2, 5, false, &mut top, &mut anchored);
        #[rustfmt::skip]
        let want = vec![
            F, 0,
            BRIDGED, 0,
            F, F,
            BRIDGED, W,
            F, F,
        ];
        assert_eq!(c, want);
        // Without a calibration (zone everywhere) both columns are bridged.
        let mut c = cells;
        bridge_columns(&mut c, &[1; 10], 2, 5, true, &mut top, &mut anchored);
        assert_eq!(c[2 * 3 + 1], BRIDGED);
    }

    /// A far foot joined to the near leg by a shaded heel: the coarse test samples the
    /// heel's lit pixels (foreground), the full-resolution band sees mostly shadow-like
    /// pixels between them. In the shadow zone the cell's changed pixels stay body, so the
    /// mask stays one piece.
    #[test]
    fn a_shaded_heel_does_not_cut_the_foot_off_in_the_shadow_zone() {
        let (w, h) = (96u32, 90u32);
        let back = |x: u32, y: u32| -> [i32; 3] {
            let n = ((x * 7 + y * 13) % 5) as i32 - 2;
            [140 + n, 136 + n, 128 + n]
        };
        let frame = |person: bool| {
            RgbImage::from_fn(w, h, |x, y| {
                let mut c = back(x, y);
                if person {
                    let leg = (60..68).contains(&x) && (10..80).contains(&y);
                    let foot = (20..52).contains(&x) && (70..80).contains(&y);
                    let heel = (52..60).contains(&x) && (74..78).contains(&y);
                    if leg || foot || (heel && x % 2 == 0 && y % 2 == 0) {
                        c = [40, 50, 150];
                    } else if heel {
                        c = c.map(|v| v * 7 / 10);
                    }
                }
                image::Rgb(c.map(|v| v.clamp(0, 255) as u8))
            })
        };
        let mut m = BackgroundModel::new(w, h, SegmentOptions::default());
        for _ in 0..3 {
            m.learn(&frame(false)).unwrap();
        }
        // The floor (rows 60 and below) is the shadow zone.
        m.set_shadow_zone(&zone_from_row(w, h, 60)).unwrap();
        let mut mask = Mask::new(1, 1);
        m.segment(&frame(true), &mut mask).unwrap();
        let mut runs = RunComponents::default();
        runs.compute(&mask.data, w, h, true, true);
        assert_eq!(runs.components.len(), 1, "the foot is cut off");
        assert!(mask.get(30, 75), "the foot is lost");
        assert!(mask.get(55, 76), "the heel is not body");
    }

    #[test]
    fn the_edge_score_is_linear_in_the_covered_fraction() {
        let back = [200u8, 180, 160];
        let mut m = BackgroundModel::new(4, 4, SegmentOptions::default());
        m.learn(&RgbImage::from_pixel(4, 4, image::Rgb(back)))
            .expect("learn");
        // Pixels covering a black person by 0, 1/4, 1/2 and 1: the lens mixes in linear
        // light, the camera encodes the mixture.
        let lut = srgb_to_linear();
        let encode = |l: f32| {
            let l = (l / 255.0).clamp(0.0, 1.0);
            let e = if l <= 0.0031308 {
                12.92 * l
            } else {
                1.055 * l.powf(1.0 / 2.4) - 0.055
            };
            (255.0 * e).round() as u8
        };
        let mut frame = RgbImage::from_pixel(4, 4, image::Rgb(back));
        for (x, f) in [0.0f32, 0.25, 0.5, 1.0].into_iter().enumerate() {
            let px = back.map(|v| encode((1.0 - f) * lut[v as usize]));
            frame.put_pixel(x as u32, 0, image::Rgb(px));
        }
        let s = m.edge_scorer(&frame).expect("same size");
        let full = s.score(3, 0);
        assert!(full > 100.0, "{full}");
        assert!(s.score(0, 0) < 1.0);
        for (x, f) in [(1, 0.25f32), (2, 0.5)] {
            let got = s.score(x, 0) / full;
            assert!((got - f).abs() < 0.02, "coverage {f}: score fraction {got}");
        }
        // In encoded levels the half-covered pixel would read as much less than half.
        let enc = |x: u32| {
            let p = frame.get_pixel(x, 0).0;
            (0..3)
                .map(|c| (p[c] as f32 - back[c] as f32).powi(2))
                .sum::<f32>()
                .sqrt()
        };
        assert!(enc(2) / enc(3) < 0.35, "{}", enc(2) / enc(3));
        // A frame of another size has no score.
        assert!(m.edge_scorer(&RgbImage::new(3, 4)).is_none());
    }

    #[test]
    fn coarse_rows_are_gathered_whole_and_odd() {
        for w in [1usize, 2, 3, 7, 8, 9, 13, 16, 17, 33] {
            let row: Vec<u8> = (0..3 * w).map(|k| (k * 37 % 251) as u8).collect();
            let mut got = vec![0u32; w.div_ceil(2)];
            gather_coarse_row(&row, &mut got);
            let want: Vec<u32> = (0..w.div_ceil(2))
                .map(|k| {
                    let i = 6 * k;
                    u32::from_le_bytes([row[i], row[i + 1], row[i + 2], 0])
                })
                .collect();
            assert_eq!(got, want, "width {w}");
        }
    }

    #[test]
    fn the_frame_exposure_is_divided_out() {
        // The exposure drops by 10 % when the person steps in; the person wears the
        // backdrop's colour a third brighter than it. Against the unscaled model the
        // person is 1.2 times the backdrop (inside the highlight tolerance, so nothing is
        // found); against the model at the frame's exposure it is 1.33 times.
        let (w, h) = (120, 100);
        let empty = scene(w, h, false, false, 7);
        let mut frame = scaled(&scene(w, h, false, false, 8), 0.9);
        for y in 20..90 {
            for x in 40..70 {
                let e = empty.get_pixel(x, y).0;
                frame.put_pixel(x, y, image::Rgb(e.map(|v| (v as f32 * 1.2) as u8)));
            }
        }
        let mut m = BackgroundModel::new(w, h, SegmentOptions::default());
        m.learn(&empty).unwrap();
        let mut mask = Mask::new(1, 1);
        let st = m.segment(&frame, &mut mask).unwrap();
        assert!((st.gain - 0.9).abs() < 0.02, "gain {}", st.gain);
        let b = st.person_box.expect("person");
        assert!(
            b.min_x >= 38 && b.max_x <= 72 && b.min_y >= 18 && b.max_y <= 92,
            "{b:?}"
        );
        assert!(st.person_px > 30 * 70 * 9 / 10, "{}", st.person_px);
        // The same frame at the model's exposure: the gain is 1 and the person, 1.2 times
        // the backdrop, is within the exposure tolerance.
        let mut m = BackgroundModel::new(w, h, SegmentOptions::default());
        m.learn(&empty).unwrap();
        let st = m.segment(&scaled(&frame, 1.0 / 0.9), &mut mask).unwrap();
        assert!((st.gain - 1.0).abs() < 0.02, "gain {}", st.gain);
    }

    #[test]
    fn empty_scene_gives_no_person() {
        let (w, h) = (120, 100);
        let mut m = BackgroundModel::new(w, h, SegmentOptions::default());
        m.learn(&scene(w, h, false, false, 1)).unwrap();
        let mut mask = Mask::new(1, 1);
        let st = m.segment(&scene(w, h, false, true, 2), &mut mask).unwrap();
        assert_eq!(st.person_px, 0);
        assert!(matches!(
            BackgroundModel::new(w, h, SegmentOptions::default())
                .segment(&scene(w, h, false, false, 1), &mut mask),
            Err(SegmentError::NotReady)
        ));
    }
}
