//! Steps 3 and 5: growing the grid from a seed corner, and numbering it physically.

use super::*;

/// Grid under construction: `idx[j][i]` are candidate indices.
pub(super) struct Grid {
    pub(super) idx: Vec<Vec<usize>>,
}

impl Grid {
    pub(super) fn ni(&self) -> usize {
        self.idx.first().map_or(0, |r| r.len())
    }
    pub(super) fn nj(&self) -> usize {
        self.idx.len()
    }
}

impl CornerDetector {
    /// Step 3: tries seeds until a full board grows; Err(Some(dims)) gives the largest
    /// partial grid.
    pub(super) fn grow_board(
        &mut self,
        board: &BoardSpec,
    ) -> Result<Vec<DVec2>, Option<(usize, usize)>> {
        let mut order: Vec<usize> = (0..self.cands.len()).collect();
        order.sort_by(|&a, &b| self.cands[b].response.total_cmp(&self.cands[a].response));
        let mut best: Option<(usize, usize)> = None;
        let mut tried = 0;
        for &seed in &order {
            if tried >= MAX_SEEDS {
                break;
            }
            if self.used[seed] {
                continue;
            }
            let Some(mut grid) = self.seed_grid(seed) else {
                continue;
            };
            tried += 1;
            self.grow(&mut grid, board);
            let dims = (grid.ni(), grid.nj());
            if (dims.0 == board.cols && dims.1 == board.rows)
                || (dims.0 == board.rows && dims.1 == board.cols)
            {
                if !self.continues_beyond(&grid) {
                    return Ok(self.orient(&grid, board));
                }
            } else if best.is_none_or(|b| b.0 * b.1 < dims.0 * dims.1) {
                best = Some(dims);
            }
            // Corners of a failed grid may seed again only if it was small.
            if dims.0 * dims.1 > 9 {
                for row in &grid.idx {
                    for &k in row {
                        self.used[k] = true;
                    }
                }
            }
        }
        Err(best)
    }

    /// Nearest unused candidate to `p` within `tol` (excluding `skip`).
    pub(super) fn nearest(&self, p: DVec2, tol: f64, skip: &[usize]) -> Option<usize> {
        let mut best = None;
        let mut best_d = tol * tol;
        for (k, c) in self.cands.iter().enumerate() {
            if self.used[k] || skip.contains(&k) {
                continue;
            }
            let d = (c.pos - p).length_squared();
            if d < best_d {
                best_d = d;
                best = Some(k);
            }
        }
        best
    }

    /// Nearest candidate from `from` in direction `dir` (within the neighbour angle).
    pub(super) fn neighbour_along(&self, from: usize, dir: DVec2) -> Option<(usize, f64)> {
        let p = self.cands[from].pos;
        let cos_max = NEIGHBOUR_ANGLE_DEG.to_radians().cos();
        let mut best: Option<(usize, f64)> = None;
        for (k, c) in self.cands.iter().enumerate() {
            if k == from || self.used[k] {
                continue;
            }
            let d = c.pos - p;
            let len = d.length();
            if len < 2.0 || d.dot(dir) < cos_max * len {
                continue;
            }
            // The neighbour's own edges must run along ours.
            let para = |u: DVec2| u.dot(dir).abs() > cos_max;
            if !(para(c.dir_a) || para(c.dir_b)) {
                continue;
            }
            if best.is_none_or(|b| len < b.1) {
                best = Some((k, len));
            }
        }
        best
    }

    pub(super) fn seed_grid(&self, seed: usize) -> Option<Grid> {
        let c = self.cands[seed];
        let (pa, da) = self.neighbour_along(seed, c.dir_a)?;
        let (ma, dma) = self.neighbour_along(seed, -c.dir_a)?;
        let (pb, db) = self.neighbour_along(seed, c.dir_b)?;
        let (mb, dmb) = self.neighbour_along(seed, -c.dir_b)?;
        let ratio_ok = |x: f64, y: f64| x / y < 1.6 && y / x < 1.6;
        if !ratio_ok(da, dma) || !ratio_ok(db, dmb) {
            return None;
        }
        let p = |k: usize| self.cands[k].pos;
        let tol = GROW_TOLERANCE * da.min(dma).min(db).min(dmb);
        let mut taken = vec![seed, pa, ma, pb, mb];
        let mut diag = |a: usize, b: usize| -> Option<usize> {
            let k = self.nearest(p(a) + p(b) - c.pos, tol, &taken)?;
            taken.push(k);
            Some(k)
        };
        let mm = diag(ma, mb)?;
        let pm = diag(pa, mb)?;
        let mp = diag(ma, pb)?;
        let pp = diag(pa, pb)?;
        Some(Grid {
            idx: vec![vec![mm, mb, pm], vec![ma, seed, pa], vec![mp, pb, pp]],
        })
    }

    pub(super) fn grow(&mut self, grid: &mut Grid, board: &BoardSpec) {
        let fits = |ni: usize, nj: usize| {
            (ni <= board.cols && nj <= board.rows) || (ni <= board.rows && nj <= board.cols)
        };
        for row in &grid.idx {
            for &k in row {
                self.used[k] = true;
            }
        }
        loop {
            let mut grown = false;
            for side in 0..4 {
                let (ni, nj) = (grid.ni(), grid.nj());
                let ok = if side < 2 {
                    fits(ni + 1, nj)
                } else {
                    fits(ni, nj + 1)
                };
                if ok && self.extend(grid, side) {
                    grown = true;
                }
            }
            if !grown {
                break;
            }
        }
    }

    /// Adds one column (side 0 right, 1 left) or row (2 bottom, 3 top) if every corner of
    /// it is found.
    pub(super) fn extend(&mut self, grid: &mut Grid, side: usize) -> bool {
        let preds = self.predict_line(grid, side);
        let mut new = Vec::with_capacity(preds.len());
        for (pred, tol) in preds {
            match self.nearest(pred, tol, &new) {
                Some(c) => new.push(c),
                None => return false,
            }
        }
        for &c in &new {
            self.used[c] = true;
        }
        match side {
            0 => grid
                .idx
                .iter_mut()
                .zip(&new)
                .for_each(|(row, &c)| row.push(c)),
            1 => grid
                .idx
                .iter_mut()
                .zip(&new)
                .for_each(|(row, &c)| row.insert(0, c)),
            2 => grid.idx.push(new),
            _ => grid.idx.insert(0, new),
        }
        true
    }

    /// Predicted positions (and tolerances) of the corners one line beyond side `side`
    /// (0 right, 1 left, 2 bottom, 3 top): quadratic extrapolation along each grid line.
    pub(super) fn predict_line(&self, grid: &Grid, side: usize) -> Vec<(DVec2, f64)> {
        let (ni, nj) = (grid.ni(), grid.nj());
        let line_len = if side < 2 { nj } else { ni };
        let pts = |k: usize, depth: usize| -> DVec2 {
            let idx = match side {
                0 => grid.idx[k][ni - 1 - depth],
                1 => grid.idx[k][depth],
                2 => grid.idx[nj - 1 - depth][k],
                _ => grid.idx[depth][k],
            };
            self.cands[idx].pos
        };
        (0..line_len)
            .map(|k| {
                let (p1, p2, p3) = (pts(k, 0), pts(k, 1), pts(k, 2));
                (
                    p1 * 3.0 - p2 * 3.0 + p3,
                    GROW_TOLERANCE * (p1 - p2).length(),
                )
            })
            .collect()
    }

    /// True when saddle points continue the grid past one of its borders: then it is a
    /// piece of a larger pattern (a tiled floor, a patterned shirt), not the board, whose
    /// corners are surrounded by its white margin.
    pub(super) fn continues_beyond(&self, grid: &Grid) -> bool {
        (0..4).any(|side| {
            let preds = self.predict_line(grid, side);
            let hits = preds
                .iter()
                .filter(|(p, tol)| {
                    self.cands
                        .iter()
                        .any(|c| (c.pos - *p).length_squared() < tol * tol)
                })
                .count();
            2 * hits > preds.len()
        })
    }

    /// Step 5: numbers the grid as the physical board (not mirrored, rows downward) and
    /// returns the positions in OpenCV's order.
    pub(super) fn orient(&self, grid: &Grid, board: &BoardSpec) -> Vec<DVec2> {
        let (ni, nj) = (grid.ni(), grid.nj());
        let at = |i: usize, j: usize| self.cands[grid.idx[j][i]].pos;
        let mut best: Option<(f64, Vec<DVec2>)> = None;
        for transpose in [false, true] {
            let (cols, rows) = if transpose { (nj, ni) } else { (ni, nj) };
            if cols != board.cols || rows != board.rows {
                continue;
            }
            for flip in 0..4 {
                let get = |c: usize, r: usize| {
                    let c = if flip & 1 == 1 { cols - 1 - c } else { c };
                    let r = if flip & 2 == 2 { rows - 1 - r } else { r };
                    if transpose {
                        at(r, c)
                    } else {
                        at(c, r)
                    }
                };
                let col_dir =
                    get(cols - 1, 0) - get(0, 0) + get(cols - 1, rows - 1) - get(0, rows - 1);
                let row_dir =
                    get(0, rows - 1) - get(0, 0) + get(cols - 1, rows - 1) - get(cols - 1, 0);
                let cross = col_dir.x * row_dir.y - col_dir.y * row_dir.x;
                if cross <= 0.0 {
                    continue; // mirrored: the printed side would face away
                }
                let down = row_dir.normalize_or_zero().y;
                if best.as_ref().is_none_or(|b| down > b.0) {
                    let pts = (0..rows)
                        .flat_map(|r| (0..cols).map(move |c| (c, r)))
                        .map(|(c, r)| get(c, r))
                        .collect();
                    best = Some((down, pts));
                }
            }
        }
        best.map(|b| b.1).unwrap_or_default()
    }

    /// Final sub-pixel refinement with a window fitted to the local spacing, plus the
    /// blur and contrast measures.
    pub(super) fn finish(&self, mut points: Vec<DVec2>, board: &BoardSpec) -> Detection {
        let n = points.len();
        let mut min_spacing = f64::INFINITY;
        let mut nearest = vec![f64::INFINITY; n];
        for i in 0..n {
            for j in 0..n {
                if i != j {
                    let d = (points[i] - points[j]).length();
                    nearest[i] = nearest[i].min(d);
                }
            }
            min_spacing = min_spacing.min(nearest[i]);
        }
        for (p, near) in points.iter_mut().zip(&nearest) {
            let half = ((0.4 * near).floor() as i32).clamp(2, MAX_SUBPIX_HALF_WINDOW);
            if let Some(q) = self.subpix(*p, half) {
                if (q - *p).length() < 0.5 * near {
                    *p = q;
                }
            }
            if self.method == SubpixMethod::PointSymmetry {
                if let Some(q) = self.symmetric_refine(*p, half) {
                    if (q - *p).length() < SYMMETRY_MAX_SHIFT_PX {
                        *p = q;
                    }
                }
            }
        }
        // Blur and contrast from profiles across the edges between row neighbours.
        let mut blurs = Vec::new();
        let mut contrasts = Vec::new();
        for r in 0..board.rows {
            for c in 0..board.cols.saturating_sub(1) {
                let (Some(a), Some(b)) = (
                    points.get(r * board.cols + c),
                    points.get(r * board.cols + c + 1),
                ) else {
                    continue;
                };
                if let Some(e) = self.edge_profile(*a, *b) {
                    blurs.push(e.sigma_px);
                    contrasts.push(e.contrast);
                }
            }
        }
        Detection {
            corners: points,
            blur_sigma_px: median(&mut blurs).unwrap_or(0.0),
            contrast: median(&mut contrasts).unwrap_or(0.0),
            min_spacing_px: min_spacing,
        }
    }
}
