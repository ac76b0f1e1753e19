//! The person at full resolution (see the module docs of [`super`]): the coarse body
//! upsampled, then every pixel within one coarse cell of its border re-tested against
//! the model and settled by a 3x3 majority among those pixels.

use super::{prefetch, BackgroundModel, BAND_BG, BAND_FG, BAND_NONE, BRIDGED, COARSE, JOINED};
use crate::imgproc::{self, Mask, MASK_ON};

impl BackgroundModel {
    /// Fills `mask_out` (all zero, the frame's size) with the coarse body, each cell
    /// a `COARSE` x `COARSE` block of pixels; returns the pixels set.
    pub(super) fn upsample_body(&self, mask_out: &mut Mask) -> u64 {
        let (w, h, cw, ch) = self.grid();
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
        upsampled_px
    }

    /// Lists the band's cells: those of the coarse body's border, where its 3x3 erosion
    /// and dilation differ.
    pub(super) fn find_band_cells(&mut self) {
        let (_, _, cw, ch) = self.grid();
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
    }

    /// Re-tests every pixel of the band's cells against the model at full resolution
    /// (foreground, or changed in a bridged cell, or made person by the fusion) and
    /// lists the band's pixels.
    pub(super) fn retest_band(&mut self, raw: &[u8]) {
        let (w, h, cw, _) = self.grid();
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
            let (fused_ratio2, shadow_stays) = self.fused_min_ratio2(cx, cy);
            for dy in 0..COARSE as usize {
                for dx in 0..COARSE as usize {
                    let (x, y) = (cx * COARSE as usize + dx, cy * COARSE as usize + dy);
                    if x < w && y < h {
                        let i = y * w + x;
                        let p = [raw[3 * i], raw[3 * i + 1], raw[3 * i + 2]];
                        self.band_state[i] = if label == JOINED
                            || self.is_foreground(i, p)
                            || (bridged && self.is_changed(i, p))
                            || (fused_ratio2.is_finite()
                                && (self.ratio2(i, p) >= fused_ratio2
                                    || (super::fusion::POOL
                                        && label == super::fusion::FUSED
                                        && !shadow_stays
                                        && self.pooled_reaches_px(raw, x, y, fused_ratio2)))
                                && !(shadow_stays && self.is_darkened(i, p)))
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
    }

    /// Settles each band pixel by a 3x3 majority of the re-tested labels (outside the
    /// band: the upsampled label) and writes it into `mask_out`; returns the person's
    /// pixels, `upsampled_px` corrected by the band's changes.
    pub(super) fn settle_band(&mut self, mask_out: &mut Mask, mut upsampled_px: u64) -> u64 {
        let (w, h, _, _) = self.grid();
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
        for (&[x, y], &v) in self.band_px.iter().zip(&self.band_out) {
            let i = y as usize * w + x as usize;
            let old = &mut mask_out.data[i];
            upsampled_px = upsampled_px + (v != 0) as u64 - (*old != 0) as u64;
            *old = v;
            self.band_state[i] = BAND_NONE;
        }
        upsampled_px
    }
}
