//! The person on the coarse grid (see the module docs of [`super`]): the cleaned labels'
//! largest person-sized component, its holes filled except those that look like the
//! backdrop seen through a gap, and its box and border contacts.

use super::{BackgroundModel, BorderTouch, PixelBox, SegmentStats, COARSE, OPEN_HOLE_FRACTION};
use super::{JOINED, OPEN_HOLE_MIN_CELLS, WEAK};
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
        self.pieces.clear();
        let Some(volume) = self.standing_cells else {
            let first = self.runs.two_largest().0;
            let body = first.filter(|&c| comps[c].area >= min_area)?;
            self.find_pieces(body, min_area);
            let comps = &self.runs.components;
            let pieces = &self.pieces;
            stats.second_px = (0..comps.len())
                .filter(|&c| c != body && !pieces.contains(&c))
                .map(|c| comps[c].area * cell)
                .max()
                .unwrap_or(0);
            stats.largest_px = self.person_cells(body) * cell;
            stats.large_components -= self.large_pieces(min_area);
            return Some(body);
        };
        // The large component with most cells in the volume (ties: the larger).
        let inside = |c: usize| cells_in_box(&self.runs, c, volume);
        let body = (0..comps.len())
            .filter(|&c| comps[c].area >= min_area)
            .max_by_key(|&c| (inside(c), comps[c].area))?;
        self.find_pieces(body, min_area);
        let comps = &self.runs.components;
        let inside = |c: usize| cells_in_box(&self.runs, c, volume);
        stats.largest_px = self.person_cells(body) * cell;
        stats.large_components -= self.large_pieces(min_area);
        stats.second_px = 0;
        stats.bystanders = 0;
        for c in (0..comps.len())
            .filter(|&c| c != body && comps[c].area >= min_area && !self.pieces.contains(&c))
        {
            if inside(c) as f64 >= IN_BOOTH_SHARE * comps[c].area as f64 {
                stats.second_px = stats.second_px.max(comps[c].area * cell);
            } else {
                stats.bystanders += 1;
            }
        }
        Some(body)
    }

    /// The other pieces of the person whose clothing the backdrop lost in a band (a
    /// shirt of the wall's colour leaves the head above it, or the legs below it, apart
    /// from the rest): components of at least `min_area / PIECE_AREA_DIV` cells that the
    /// learned person prior covers ([`PIECE_PRIOR_SHARE`] of their cells at p >= 0.5),
    /// within the body's columns (or stacked on it and spanning its columns: the trunk
    /// with its arms out over legs the volume rule chose as the body) and at most
    /// [`PIECE_GAP_DIV`]-th of its height above or below it. Without a prior there are
    /// none (a piece could be anything).
    fn find_pieces(&mut self, body: usize, min_area: u64) {
        let Some(prior) = self.prior.as_ref() else {
            return;
        };
        let comps = &self.runs.components;
        let b = comps[body];
        let gap = ((b.max_y - b.min_y) / PIECE_GAP_DIV).max(1);
        let min_piece = (min_area / PIECE_AREA_DIV).max(1);
        for (c, k) in comps.iter().enumerate() {
            if k.area < min_piece {
                continue;
            }
            let beside = k.min_x >= b.min_x && k.max_x <= b.max_x;
            // A piece stacked on the body that is wider than it (the trunk with its arms
            // out, above legs the volume rule chose as the body), or under it.
            let stacked = (k.min_y + gap <= b.min_y || k.max_y >= b.max_y + gap)
                && b.min_x >= k.min_x
                && b.max_x <= k.max_x;
            let beside = beside || stacked;
            let near = k.max_y + gap >= b.min_y && k.min_y <= b.max_y + gap;
            if c == body || !beside || !near {
                continue;
            }
            let covered = prior_cells(&self.runs, c, prior);
            if covered as f64 >= PIECE_PRIOR_SHARE * k.area as f64 {
                self.pieces.push(c);
            }
        }
    }

    /// Cells of the body and its pieces.
    fn person_cells(&self, body: usize) -> u64 {
        let comps = &self.runs.components;
        comps[body].area + self.pieces.iter().map(|&c| comps[c].area).sum::<u64>()
    }

    /// How many of the pieces are person-sized components themselves.
    fn large_pieces(&self, min_area: u64) -> u32 {
        let comps = &self.runs.components;
        self.pieces
            .iter()
            .filter(|&&c| comps[c].area >= min_area)
            .count() as u32
    }

    /// Joins the pieces to the body in the coarse body mask: each piece's cells, and in
    /// each of its columns the cells from the piece toward the body (down from a piece
    /// above it, up from one below) while the prior says person, until the body is met.
    /// The cells walked get [`JOINED`] so that the full-resolution border test keeps them
    /// (their colour is the backdrop's: that is why they were lost), and the piece stays
    /// one outline with the body.
    fn join_pieces(&mut self, body: usize) {
        let Some(prior) = self.prior.as_ref() else {
            return;
        };
        let (cw, ch) = (self.runs.width as usize, self.runs.height as usize);
        let comps = &self.runs.components;
        let b = comps[body];
        for &c in &self.pieces {
            for (r, run) in self.runs.runs.iter().enumerate() {
                if self.runs.label[r] as usize == c {
                    let y = run.y as usize;
                    self.coarse_body[y * cw + run.x0 as usize..y * cw + run.x1 as usize]
                        .fill(imgproc::MASK_ON);
                }
            }
            let k = comps[c];
            // Which way the body lies: in the piece's own columns, only above it (a lower
            // leg cut off at the knee, its foot on the floor beside the other) walks up,
            // only below it (a head over a lost shirt) walks down; side by side, or with
            // the body on both sides, they are joined by the rows they share, if at all.
            let columns = k.min_x as usize..(k.max_x as usize).min(cw);
            let body_in = |rows: std::ops::Range<usize>| {
                rows.into_iter().any(|y| {
                    self.coarse_body[y * cw + columns.start..y * cw + columns.end]
                        .contains(&imgproc::MASK_ON)
                })
            };
            let above = body_in(b.min_y as usize..k.min_y as usize);
            let below = body_in((k.max_y as usize + 1).min(ch)..(b.max_y as usize + 1).min(ch));
            let down = match (above, below) {
                (false, true) => true,
                (true, false) => false,
                _ => continue,
            };
            let reach = ((b.max_y - b.min_y) as usize / 2).max(1);
            let face = ((k.max_y - k.min_y) as usize / PIECE_FACE_DIV).max(2);
            let rows = k.min_y as usize..(k.max_y as usize + 1).min(ch);
            // One row toward the body (up from row 0 wraps past `ch`: the walk ends).
            let toward = |y: usize| if down { y + 1 } else { y.wrapping_sub(1) };
            for x in k.min_x as usize..(k.max_x as usize).min(cw) {
                // The piece's cell nearest the body in this column, if it lies on the
                // piece's face toward the body (not deep in it: the gap between two legs).
                let on = |y: &usize| self.coarse_body[y * cw + x] == imgproc::MASK_ON;
                let start = if down {
                    rows.clone().rev().find(on)
                } else {
                    rows.clone().find(on)
                };
                let Some(mut y) = start else { continue };
                let depth = if down {
                    k.max_y as usize - y
                } else {
                    y - k.min_y as usize
                };
                if depth > face {
                    continue;
                }
                for _ in 0..reach {
                    y = toward(y);
                    if y >= ch {
                        break;
                    }
                    let i = y * cw + x;
                    if self.coarse_body[i] == imgproc::MASK_ON
                        || prior.at_cell(x, y) < PIECE_PRIOR_LEVEL
                    {
                        break;
                    }
                    self.coarse_body[i] = imgproc::MASK_ON;
                    self.coarse[i] = JOINED;
                }
            }
        }
    }

    /// Writes component `body` into the coarse body mask with its holes filled, unless
    /// they look like the backdrop seen through a gap (between an arm and the trunk,
    /// between the feet): most of their cells unchanged, or darkened like a shadow inside
    /// the shadow zone. A part of the person that only matches the backdrop in places (a
    /// white shirt on a white backdrop) keeps enough changed cells to be filled.
    pub(super) fn fill_body_holes(&mut self, body: usize) {
        let (_, _, cw, ch) = self.grid();
        imgproc::write_component(&self.runs, body, &mut self.coarse_body);
        self.join_pieces(body);
        if self.opts.open_holes {
            let (coarse, zone) = (&self.coarse, &self.coarse_model.zone);
            // The backdrop seen through a hole, unless the person model is sure it is the
            // person (a white shirt on a white wall leaves holes of the wall's colour).
            let core = |x: usize, y: usize| self.prior.as_ref().is_some_and(|p| p.in_core(x, y));
            imgproc::fill_holes_selective(
                &mut self.coarse_body,
                cw as u32,
                ch as u32,
                &mut self.hole_runs,
                &mut self.hole_evidence,
                |y, x0, x1| {
                    let row = y * cw;
                    (x0..x1)
                        .filter(|&x| {
                            let (c, z) = (coarse[row + x], zone[row + x]);
                            (c == 0 || (c == WEAK && z != 0)) && !core(x, y)
                        })
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

    /// The person's pixel box: component `body`'s coarse box with its pieces', grown by
    /// one cell.
    pub(super) fn person_box(&self, body: usize) -> PixelBox {
        let comps = &self.runs.components;
        let c = self.pieces.iter().fold(comps[body], |a, &p| {
            let k = comps[p];
            imgproc::Component {
                min_x: a.min_x.min(k.min_x),
                min_y: a.min_y.min(k.min_y),
                max_x: a.max_x.max(k.max_x),
                max_y: a.max_y.max(k.max_y),
                ..a
            }
        });
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

/// A piece of the person is at least this fraction of a person-sized component.
const PIECE_AREA_DIV: u64 = 8;
/// A piece walks toward the body from the cells within this fraction of its height of
/// its face toward the body ([`BackgroundModel::join_pieces`]).
const PIECE_FACE_DIV: usize = 8;
/// ... at most this fraction of the body's height away from it.
const PIECE_GAP_DIV: u32 = 8;
/// ... with at least this share of its cells at the prior's [`PIECE_PRIOR_LEVEL`].
const PIECE_PRIOR_SHARE: f64 = 0.6;
/// The prior's 8-bit level of p = 0.5.
const PIECE_PRIOR_LEVEL: u8 = 128;

/// Cells of component `comp` of `runs` where `prior` says person (p >= 0.5).
fn prior_cells(
    runs: &imgproc::RunComponents,
    comp: usize,
    prior: &super::fusion::PersonPrior,
) -> u64 {
    let mut n = 0u64;
    for (run, &label) in runs.runs.iter().zip(&runs.label) {
        if label as usize == comp {
            n += (run.x0..run.x1)
                .filter(|&x| prior.at_cell(x as usize, run.y as usize) >= PIECE_PRIOR_LEVEL)
                .count() as u64;
        }
    }
    n
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
