//! The person on the coarse grid (see the module docs of [`super`]): the cleaned labels'
//! largest person-sized component, its holes filled except those that look like the
//! backdrop seen through a gap, and its box and border contacts.

use super::{BackgroundModel, BorderTouch, PixelBox, SegmentStats, COARSE, OPEN_HOLE_FRACTION};
use super::{OPEN_HOLE_MIN_CELLS, WEAK};
use crate::imgproc::{self, Mask};

impl BackgroundModel {
    /// Cleans the coarse labels with a 3x3 majority filter and returns the person's
    /// 8-connected component when it is person-sized: the largest, or with a standing
    /// volume set ([`Self::set_standing_box`]) the one with most cells inside it (a
    /// passer-by behind the shopper may be larger in the side view, which it nears).
    /// `stats` gets the count of large components, the person's size, the size of the
    /// largest other one that stands in the volume (a second person in the booth) and
    /// the number of those outside it (bystanders).
    pub(super) fn largest_component(&mut self, stats: &mut SegmentStats) -> Option<usize> {
        let (_, _, cw, ch) = self.grid();
        let nc = (cw * ch) as f32;
        imgproc::majority3x3(&self.coarse, cw, ch, &mut self.coarse_clean, &mut self.tmp);
        self.runs
            .compute(&self.coarse_clean, cw as u32, ch as u32, true, true);
        let cell = (COARSE * COARSE) as u64;
        let min_area = ((self.opts.min_person_fraction * nc) as u64).max(1);
        let comps = &self.runs.components;
        stats.large_components = comps.iter().filter(|c| c.area >= min_area).count() as u32;
        let Some(volume) = self.standing_cells else {
            let (first, second) = self.runs.two_largest();
            stats.second_px = second.map_or(0, |c| comps[c].area * cell);
            let body = first.filter(|&c| comps[c].area >= min_area)?;
            stats.largest_px = comps[body].area * cell;
            return Some(body);
        };
        // The large component with most cells in the volume (ties: the larger).
        let inside = |c: usize| cells_in_box(&self.runs, c, volume);
        let body = (0..comps.len())
            .filter(|&c| comps[c].area >= min_area)
            .max_by_key(|&c| (inside(c), comps[c].area))?;
        stats.largest_px = comps[body].area * cell;
        stats.second_px = 0;
        stats.bystanders = 0;
        for c in (0..comps.len()).filter(|&c| c != body && comps[c].area >= min_area) {
            if inside(c) as f64 >= IN_BOOTH_SHARE * comps[c].area as f64 {
                stats.second_px = stats.second_px.max(comps[c].area * cell);
            } else {
                stats.bystanders += 1;
            }
        }
        Some(body)
    }

    /// Writes component `body` into the coarse body mask with its holes filled, unless
    /// they look like the backdrop seen through a gap (between an arm and the trunk,
    /// between the feet): most of their cells unchanged, or darkened like a shadow inside
    /// the shadow zone. A part of the person that only matches the backdrop in places (a
    /// white shirt on a white backdrop) keeps enough changed cells to be filled.
    pub(super) fn fill_body_holes(&mut self, body: usize) {
        let (_, _, cw, ch) = self.grid();
        imgproc::write_component(&self.runs, body, &mut self.coarse_body);
        if self.opts.open_holes {
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
    }

    /// The person's pixel box: component `body`'s coarse box grown by one cell.
    pub(super) fn person_box(&self, body: usize) -> PixelBox {
        let c = self.runs.components[body];
        PixelBox {
            min_x: (c.min_x.saturating_sub(1)) * COARSE,
            min_y: (c.min_y.saturating_sub(1)) * COARSE,
            max_x: ((c.max_x + 1) * COARSE).min(self.width),
            max_y: ((c.max_y + 1) * COARSE).min(self.height),
        }
    }
}

/// Which image borders the final mask touches.
pub(super) fn border_touch(mask: &Mask) -> BorderTouch {
    let (w, h) = (mask.width as usize, mask.height as usize);
    BorderTouch {
        top: mask.data[..w].iter().any(|&v| v != 0),
        bottom: mask.data[(h - 1) * w..].iter().any(|&v| v != 0),
        left: (0..h).any(|y| mask.data[y * w] != 0),
        right: (0..h).any(|y| mask.data[y * w + w - 1] != 0),
    }
}

/// A large component with at least this share of its cells inside the standing volume
/// over the mark stands in the booth (a second shopper), not behind it.
const IN_BOOTH_SHARE: f64 = 0.5;

/// Cells of component `comp` of `runs` inside `b` (cells, max exclusive).
fn cells_in_box(runs: &imgproc::RunComponents, comp: usize, b: PixelBox) -> u64 {
    let mut n = 0u64;
    let rows = b.min_y as usize..(b.max_y as usize).min(runs.height as usize);
    for y in rows {
        let (r0, r1) = (runs.row_start[y], runs.row_start[y + 1]);
        for (run, &label) in runs.runs[r0..r1].iter().zip(&runs.label[r0..r1]) {
            if label as usize != comp {
                continue;
            }
            let (x0, x1) = (run.x0.max(b.min_x), run.x1.min(b.max_x));
            n += x1.saturating_sub(x0) as u64;
        }
    }
    n
}
