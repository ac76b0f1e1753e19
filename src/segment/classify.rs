//! The coarse grid of a frame (see the module docs of [`super`]): the frame's exposure
//! gain, the colour test of every second pixel of every second row against the model,
//! and the bridging of shadow-like cells of a leg into the person.

use super::fusion::SUPPORT_LEVEL;
use super::{
    keep_out_box, luma8, BackgroundModel, ExposureStats, BRIDGED, CLIP_HIGH_LUMA, CLIP_LOW_LUMA,
    COARSE, MAX_GAIN, MIN_GAIN, NO_RUN, WEAK,
};

impl BackgroundModel {
    /// The frame's exposure gain against the model: the median brightness ratio
    /// `alpha = I.E / |E|^2` over a sparse grid of pixels away from the person's last box
    /// whose colour is the model's up to brightness (low chromaticity distortion), not
    /// clipped. Exposure flicker and drift scale the whole backdrop; the person covers a
    /// minority of the sample, and the chromaticity gate drops most of it. Without enough
    /// samples, or when the estimate is implausible for an exposure change, the gain is 1.
    pub(super) fn estimate_gain(&mut self, raw: &[u8]) -> f32 {
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

    /// Labels the cells of the coarse grid against the model at gain `g`: foreground
    /// ([`crate::imgproc::MASK_ON`]), changed but explained as shadow or exposure
    /// ([`WEAK`]), or unchanged (0); returns the exposure statistics of the cells' colours
    /// and the number of cells tested.
    ///
    /// Every cell is tested on a frame without a person in the last one. With one, the
    /// cells are tested where the person can be and the rest of the frame is sampled
    /// ([`Self::classify_around_person`]): the labels are those of the full test but for
    /// changed patches too thin to hold a sample (less than [`BLOCK`] cells across),
    /// which the majority filter and the size rules drop anyway.
    ///
    /// One coarse row span at a time is gathered into packed 32-bit colours, then tested
    /// branch-free (the compiler vectorises it).
    pub(super) fn classify_coarse(&mut self, raw: &[u8], g: f32) -> (ExposureStats, u64) {
        let (_, _, cw, ch) = self.grid();
        self.coarse.clear();
        self.coarse.resize(cw * ch, 0);
        self.row_rgb.resize(cw, 0);
        let test = CellTest::new(&self.opts, g);
        if self.opts.sample_outside_person {
            if let Some(dense) = self.dense_blocks() {
                return self.classify_around_person(raw, &test, dense);
            }
        }
        let mut counts = LumaCounts::default();
        for cy in 0..ch {
            counts.add(self.classify_span(raw, &test, cy, 0, cw));
        }
        (counts.stats(), counts.n)
    }

    /// The blocks of [`BLOCK`] x [`BLOCK`] cells tested in full before any sampling,
    /// `(bx0, by0, bx1, by1)` (max exclusive): the person's last box and the learned
    /// prior's support (the cells it may make person, [`super::fusion::SUPPORT_LEVEL`]),
    /// grown by [`DENSE_MARGIN_CELLS`]. None without a last box, or when
    /// they cover more than [`MAX_DENSE_SHARE`] of the frame (sampling the rest would not
    /// pay).
    fn dense_blocks(&self) -> Option<(usize, usize, usize, usize)> {
        let (_, _, cw, ch) = self.grid();
        let c = COARSE as usize;
        let b = self.last_box?;
        let (mut x0, mut y0, mut x1, mut y1) = (
            b.min_x as usize / c,
            b.min_y as usize / c,
            (b.max_x as usize).div_ceil(c),
            (b.max_y as usize).div_ceil(c),
        );
        if let Some(p) = &self.prior {
            // Where the prior can make a cell person, unless the fusion was told to
            // trust levels below the support's.
            let o = &self.fusion.opts;
            let support_ok = o.min_prob.min(o.zone_min_prob) * 255.0 >= SUPPORT_LEVEL as f32;
            let (px0, py0, px1, py1) = if support_ok {
                p.support_box()
            } else {
                p.cell_box()
            };
            if px1 > px0 && py1 > py0 {
                (x0, y0, x1, y1) = (x0.min(px0), y0.min(py0), x1.max(px1), y1.max(py1));
            }
        }
        let m = DENSE_MARGIN_CELLS;
        let (bw, bh) = (cw.div_ceil(BLOCK), ch.div_ceil(BLOCK));
        let blocks = (
            x0.saturating_sub(m) / BLOCK,
            y0.saturating_sub(m) / BLOCK,
            ((x1 + m).div_ceil(BLOCK)).min(bw),
            ((y1 + m).div_ceil(BLOCK)).min(bh),
        );
        let area = (blocks.2.saturating_sub(blocks.0)) * (blocks.3.saturating_sub(blocks.1));
        (area as f64 <= MAX_DENSE_SHARE * (bw * bh) as f64).then_some(blocks)
    }

    /// The coarse labels tested in full on the `dense` blocks and sampled elsewhere: one
    /// cell of every other block is tested, and a block whose sample changed is tested in
    /// full. So is every neighbour (8-connected) of a block tested in full that holds a
    /// changed cell, until none is left: a changed region that reaches the person's
    /// blocks or holds a sample (a passer-by, an arm out of the last box) is labelled
    /// whole. The exposure statistics count a sampled block's sample for its cells.
    fn classify_around_person(
        &mut self,
        raw: &[u8],
        test: &CellTest,
        (dx0, dy0, dx1, dy1): (usize, usize, usize, usize),
    ) -> (ExposureStats, u64) {
        let (w, _, cw, ch) = self.grid();
        let (bw, bh) = (cw.div_ceil(BLOCK), ch.div_ceil(BLOCK));
        let mut counts = LumaCounts::default();
        let mut blocks = std::mem::take(&mut self.block_state);
        blocks.clear();
        blocks.resize(bw * bh, BLOCK_SAMPLED);
        let mut queue = std::mem::take(&mut self.block_queue);
        queue.clear();
        // The person's blocks, row spans at a time.
        let (cx0, cx1) = (dx0 * BLOCK, (dx1 * BLOCK).min(cw));
        for cy in dy0 * BLOCK..(dy1 * BLOCK).min(ch) {
            counts.add(self.classify_span(raw, test, cy, cx0, cx1));
        }
        for by in dy0..dy1 {
            blocks[by * bw + dx0..by * bw + dx1].fill(BLOCK_DENSE);
        }
        // The ring of the person's blocks: those holding a changed cell open their
        // neighbours.
        for by in dy0..dy1 {
            for bx in dx0..dx1 {
                let ring = by == dy0 || by + 1 == dy1 || bx == dx0 || bx + 1 == dx1;
                if ring && self.block_changed(bx, by) {
                    push_neighbours(&mut queue, &blocks, bx, by, bw, bh);
                }
            }
        }
        // One sample a block elsewhere: the cell at the block's centre.
        let mut sampled_luma = std::mem::take(&mut self.block_luma);
        sampled_luma.clear();
        sampled_luma.resize(bw * bh, 0);
        let m = &self.coarse_model;
        for by in 0..bh {
            let cy = (by * BLOCK + BLOCK / 2).min(ch - 1);
            let y = cy * COARSE as usize;
            for bx in 0..bw {
                let b = by * bw + bx;
                if blocks[b] != BLOCK_SAMPLED {
                    continue;
                }
                let cx = (bx * BLOCK + BLOCK / 2).min(cw - 1);
                let x = cx * COARSE as usize;
                let i = 3 * (y * w + x);
                let v = u32::from_le_bytes([raw[i], raw[i + 1], raw[i + 2], 0]);
                let k = cy * cw + cx;
                let label = test.label(v, m.er[k], m.eg[k], m.eb[k], m.tau2[k], m.zone[k]);
                sampled_luma[b] = luma8(v & 0xff, (v >> 8) & 0xff, v >> 16) as u8;
                if label != 0 {
                    queue.push(b as u32);
                }
            }
        }
        // The flood: test queued blocks in full; those with a changed cell open their
        // neighbours.
        while let Some(b) = queue.pop() {
            let b = b as usize;
            if blocks[b] == BLOCK_DENSE {
                continue;
            }
            blocks[b] = BLOCK_DENSE;
            let (bx, by) = (b % bw, b / bw);
            let (cx0, cx1) = (bx * BLOCK, ((bx + 1) * BLOCK).min(cw));
            for cy in by * BLOCK..((by + 1) * BLOCK).min(ch) {
                counts.add(self.classify_span(raw, test, cy, cx0, cx1));
            }
            if self.block_changed(bx, by) {
                push_neighbours(&mut queue, &blocks, bx, by, bw, bh);
            }
        }
        // The blocks only sampled count their sample for each of their cells.
        let tested = counts.n;
        for (b, _) in blocks
            .iter()
            .enumerate()
            .filter(|(_, &s)| s == BLOCK_SAMPLED)
        {
            let (bx, by) = (b % bw, b / bw);
            let cells = ((bx + 1) * BLOCK).min(cw) - bx * BLOCK;
            let cells = (cells * (((by + 1) * BLOCK).min(ch) - by * BLOCK)) as u64;
            let l = sampled_luma[b] as u32;
            counts.luma_sum += l as u64 * cells;
            counts.hi += (l >= CLIP_HIGH_LUMA as u32) as u64 * cells;
            counts.lo += (l <= CLIP_LOW_LUMA as u32) as u64 * cells;
            counts.n += cells;
        }
        self.block_state = blocks;
        self.block_queue = queue;
        self.block_luma = sampled_luma;
        (counts.stats(), tested)
    }

    /// True when block `(bx, by)` holds a changed cell.
    fn block_changed(&self, bx: usize, by: usize) -> bool {
        let (_, _, cw, ch) = self.grid();
        let (cx0, cx1) = (bx * BLOCK, ((bx + 1) * BLOCK).min(cw));
        (by * BLOCK..((by + 1) * BLOCK).min(ch)).any(|cy| {
            self.coarse[cy * cw + cx0..cy * cw + cx1]
                .iter()
                .any(|&v| v != 0)
        })
    }

    /// Labels cells `cx0..cx1` of coarse row `cy` (see [`CellTest`]); returns the exposure
    /// counts of their colours.
    fn classify_span(
        &mut self,
        raw: &[u8],
        test: &CellTest,
        cy: usize,
        cx0: usize,
        cx1: usize,
    ) -> LumaCounts {
        let (w, _, cw, _) = self.grid();
        let n = cx1 - cx0;
        let y = cy * COARSE as usize;
        let row = &raw[3 * y * w..3 * (y + 1) * w];
        let span_px = &row[(6 * cx0).min(row.len())..(6 * cx1).min(row.len())];
        let rgb = &mut self.row_rgb[..n];
        gather_coarse_row(span_px, rgb);
        // Exposure statistics (integer, vectorised).
        let (mut sum, mut n_hi, mut n_lo) = (0u32, 0u32, 0u32);
        for &v in rgb.iter() {
            let (r, g, b) = (v & 0xff, (v >> 8) & 0xff, v >> 16);
            let l = luma8(r, g, b);
            sum += l;
            n_hi += (l >= CLIP_HIGH_LUMA as u32) as u32;
            n_lo += (l <= CLIP_LOW_LUMA as u32) as u32;
        }
        let m = &self.coarse_model;
        let span = cy * cw + cx0..cy * cw + cx1;
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
            *o = test.label(v, er, eg, eb, tau2, zone);
        }
        LumaCounts {
            luma_sum: sum as u64,
            hi: n_hi as u64,
            lo: n_lo as u64,
            n: n as u64,
        }
    }

    /// Lets the learned person prior ([`super::fusion`]) decide the cells the backdrop is
    /// unsure of; returns the pixels it made person.
    pub(super) fn fuse_person_prior(&mut self, raw: &[u8]) -> u64 {
        let (_, _, cw, _) = self.grid();
        let (mut coarse, mut scratch) = (
            std::mem::take(&mut self.coarse),
            std::mem::take(&mut self.fuse_scratch),
        );
        let fused = self.fuse_coarse(raw, &mut coarse, cw, &mut scratch);
        (self.coarse, self.fuse_scratch) = (coarse, scratch);
        fused * (COARSE * COARSE) as u64
    }

    /// Promotes the shadow-like cells of a leg in trousers of the floor's hue into the
    /// person (see [`bridge_columns`]), when the options ask for it.
    pub(super) fn bridge_shadowed_columns(&mut self) {
        if !self.opts.bridge_columns {
            return;
        }
        let (_, _, cw, ch) = self.grid();
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
}

/// Side of the blocks of the sampled classification, in coarse cells
/// ([`BackgroundModel::classify_around_person`]): one cell in `BLOCK * BLOCK` is tested
/// away from the person, and a changed region at least this wide holds a sample.
pub(super) const BLOCK: usize = 4;
/// Margin about the person's last box (and the prior's) tested in full, in coarse cells:
/// a person moves less than this between two frames.
const DENSE_MARGIN_CELLS: usize = 16;
/// Above this share of the frame's blocks about the person, every cell is tested.
const MAX_DENSE_SHARE: f64 = 0.85;
/// States of a block in [`BackgroundModel::classify_around_person`].
pub(super) const BLOCK_SAMPLED: u8 = 0;
pub(super) const BLOCK_DENSE: u8 = 1;

/// Queues the neighbours of block `(bx, by)` not yet tested in full.
fn push_neighbours(
    queue: &mut Vec<u32>,
    blocks: &[u8],
    bx: usize,
    by: usize,
    bw: usize,
    bh: usize,
) {
    for ny in by.saturating_sub(1)..(by + 2).min(bh) {
        for nx in bx.saturating_sub(1)..(bx + 2).min(bw) {
            let n = ny * bw + nx;
            if blocks[n] != BLOCK_DENSE {
                queue.push(n as u32);
            }
        }
    }
}

/// Luma sum and clipped and crushed counts over `n` cells ([`ExposureStats`]).
#[derive(Debug, Clone, Copy, Default)]
struct LumaCounts {
    luma_sum: u64,
    hi: u64,
    lo: u64,
    n: u64,
}

impl LumaCounts {
    fn add(&mut self, o: LumaCounts) {
        self.luma_sum += o.luma_sum;
        self.hi += o.hi;
        self.lo += o.lo;
        self.n += o.n;
    }

    fn stats(&self) -> ExposureStats {
        ExposureStats::from_counts(self.luma_sum, self.hi, self.lo, self.n as usize)
    }
}

/// The per-cell colour test at one exposure gain (see the module docs of [`super`]).
pub(super) struct CellTest {
    ck2: f32,
    gm1: f32,
    klo_lit: f32,
    klo_step: f32,
    khi: f32,
    inv_g: f32,
}

impl CellTest {
    pub(super) fn new(o: &super::SegmentOptions, g: f32) -> Self {
        // Brightness bounds about the frame's exposure gain g: alpha = 1 + d.E/|E|^2 is
        // compared with g * bound, so d.E is compared with (g * bound - 1) |E|^2.
        let (klo_zone, klo_lit, khi) = (
            g * o.shadow_min_brightness - 1.0,
            g * o.lit_min_brightness - 1.0,
            g * o.highlight_max_brightness - 1.0,
        );
        CellTest {
            ck2: o.chroma_k * o.chroma_k,
            gm1: g - 1.0,
            klo_lit,
            klo_step: klo_zone - klo_lit,
            khi,
            inv_g: 1.0 / g,
        }
    }

    /// The label of a cell of packed colour `v` (red in the low byte) against the model
    /// colour `(er, eg, eb)`, squared noise radius `tau2` and shadow-zone flag `zone`:
    /// 255 foreground, [`WEAK`] changed but explained as shadow or exposure, 0 unchanged.
    /// Branch-free, so that a loop over a row vectorises.
    #[inline(always)]
    pub(super) fn label(&self, v: u32, er: u8, eg: u8, eb: u8, tau2: u16, zone: u8) -> u8 {
        let (r, g, b) = (v & 0xff, (v >> 8) & 0xff, v >> 16);
        // Integer differences and dot products (exact), f32 for the products.
        let (er, eg, eb) = (er as i32, eg as i32, eb as i32);
        // A channel the model saw clipped says only "at least this bright": it is
        // left out of the tests (unless all three are: a blown-out white).
        let [wr, wg, wb] = unclipped_weights(er, eg, eb);
        let (dr, dg, db) = (
            (r as i32 - er) * wr,
            (g as i32 - eg) * wg,
            (b as i32 - eb) * wb,
        );
        let (er, eg, eb) = (er * wr, eg * wg, eb * wb);
        let dd = (dr * dr + dg * dg + db * db) as f32;
        let de = (dr * er + dg * eg + db * eb) as f32;
        let ee = (er * er + eg * eg + eb * eb) as f32;
        let tau2 = tau2 as f32;
        let zone = zone as f32; // 1 in the shadow zone, else 0
        let klo = self.klo_lit + zone * self.klo_step;
        let chroma_ee = dd * ee - de * de;
        // In the shadow zone the chromaticity tolerance scales with the brightness
        // ratio (see `chroma_k`): (alpha / g) |E|^2, at most |E|^2.
        let lit_ee = ee + zone * (((ee + de) * self.inv_g).clamp(0.0, ee) - ee);
        // |I - gE|^2 = |d - (g-1)E|^2
        let gm1 = self.gm1;
        let dg2 = dd - 2.0 * gm1 * de + gm1 * gm1 * ee;
        let cand = dg2 > tau2;
        let fg = cand
            & ((chroma_ee * ee > self.ck2 * tau2 * lit_ee * lit_ee)
                | (de < klo * ee)
                | (de > self.khi * ee));
        // 255: foreground; 2: changed, but explained as shadow or exposure (WEAK).
        (fg as u8).wrapping_neg() | (cand as u8) << 1
    }
}

/// A model channel at or above this was clipped by the camera when the backdrop was
/// learned (8-bit).
pub(super) const CLIPPED_MODEL: i32 = 254;

/// Per channel 1, or 0 for a channel the model saw clipped ([`CLIPPED_MODEL`]) while
/// another was not. A clipped channel's true brightness is unknown above the clip: a
/// shadow falling on a saturated yellow floor mark (255, 237, 53) leaves its red channel
/// at 242 while green falls to 200, which no shadow does to a colour, and the mark
/// under a shopper's feet was taken for the person (and joined the feet, closing the gap
/// between the legs). Its unclipped channels still tell a shadow from a colour; a white
/// clipped in every channel keeps all three.
#[inline(always)]
pub(super) fn unclipped_weights(er: i32, eg: i32, eb: i32) -> [i32; 3] {
    let c = [
        (er >= CLIPPED_MODEL) as i32,
        (eg >= CLIPPED_MODEL) as i32,
        (eb >= CLIPPED_MODEL) as i32,
    ];
    let all = c[0] & c[1] & c[2];
    c.map(|k| 1 - k + k * all)
}

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
pub(super) fn bridge_columns(
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
pub(super) fn gather_coarse_row(row: &[u8], rgb: &mut [u32]) {
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
