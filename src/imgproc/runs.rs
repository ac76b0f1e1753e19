//! Run-length connected components of a binary mask (8-connectivity for the foreground,
//! 4-connectivity for the background), component statistics, and hole filling.
//!
//! A run is a horizontal span `[x0, x1)` of foreground pixels in row `y`. Labelling is
//! union-find over runs: a run joins every run of the row above whose span overlaps it
//! (extended by one pixel each side for 8-connectivity). A silhouette has a few runs per
//! row, so this is much cheaper than a pixel-wise labelling.

/// A horizontal span of foreground pixels `[x0, x1)` in row `y`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Run {
    pub y: u32,
    pub x0: u32,
    pub x1: u32,
}

/// Statistics of one connected component.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Component {
    /// Pixels.
    pub area: u64,
    /// Bounding box, inclusive min and exclusive max, in pixels.
    pub min_x: u32,
    pub min_y: u32,
    pub max_x: u32,
    pub max_y: u32,
    /// Index of the component's first run (topmost row, leftmost) in `RunComponents::runs`.
    pub first_run: usize,
}

impl Component {
    /// True when the component touches the image border.
    pub fn touches_border(&self, width: u32, height: u32) -> bool {
        self.min_x == 0 || self.min_y == 0 || self.max_x >= width || self.max_y >= height
    }
}

/// Runs of a mask, their component labels and per-component statistics. Reused between
/// frames (the vectors keep their capacity).
#[derive(Debug, Clone, Default)]
pub struct RunComponents {
    pub width: u32,
    pub height: u32,
    /// All runs in raster order.
    pub runs: Vec<Run>,
    /// First run of each row (`row_start[y]..row_start[y+1]`), `height + 1` entries.
    pub row_start: Vec<usize>,
    /// Component index of each run (dense, 0..components.len()).
    pub label: Vec<u32>,
    /// Components sorted by decreasing area.
    pub components: Vec<Component>,
    parent: Vec<u32>,
    root_to_comp: Vec<u32>,
}

/// First index at or after `from` whose byte is non-zero (`nonzero`) or zero, else
/// `row.len()`. Skips eight bytes at a time over uniform stretches (mask rows are long
/// runs of 0 or 255).
#[inline]
pub fn find_run_edge(row: &[u8], from: usize, nonzero: bool) -> usize {
    const WORD: usize = 8;
    let skip = if nonzero { 0u64 } else { u64::MAX };
    let mut x = from;
    while x < row.len() {
        if x + WORD <= row.len() {
            let mut b = [0u8; WORD];
            b.copy_from_slice(&row[x..x + WORD]);
            if u64::from_ne_bytes(b) == skip {
                x += WORD;
                continue;
            }
        }
        if (row[x] != 0) == nonzero {
            return x;
        }
        x += 1;
    }
    row.len()
}

fn find(parent: &mut [u32], mut a: u32) -> u32 {
    while parent[a as usize] != a {
        let p = parent[parent[a as usize] as usize];
        parent[a as usize] = p;
        a = p;
    }
    a
}

fn union(parent: &mut [u32], a: u32, b: u32) {
    let (ra, rb) = (find(parent, a), find(parent, b));
    if ra != rb {
        let (lo, hi) = if ra < rb { (ra, rb) } else { (rb, ra) };
        parent[hi as usize] = lo;
    }
}

impl RunComponents {
    /// Extracts runs of `value == on` pixels and labels them.
    /// `eight` selects 8-connectivity (else 4).
    pub fn compute(&mut self, data: &[u8], width: u32, height: u32, on: bool, eight: bool) {
        self.width = width;
        self.height = height;
        self.runs.clear();
        self.row_start.clear();
        let w = width as usize;
        for y in 0..height as usize {
            self.row_start.push(self.runs.len());
            let row = &data[y * w..(y + 1) * w];
            let mut x = 0;
            while x < w {
                let x0 = find_run_edge(row, x, on);
                if x0 >= w {
                    break;
                }
                x = find_run_edge(row, x0, !on);
                self.runs.push(Run {
                    y: y as u32,
                    x0: x0 as u32,
                    x1: x as u32,
                });
            }
        }
        self.row_start.push(self.runs.len());
        self.label_runs(eight);
    }

    /// Labels the runs already in `self.runs`/`self.row_start`.
    pub fn label_runs(&mut self, eight: bool) {
        let n = self.runs.len();
        self.parent.clear();
        self.parent.extend(0..n as u32);
        let ext = eight as u32;
        for y in 1..self.height as usize {
            let (a0, a1) = (self.row_start[y - 1], self.row_start[y]);
            let b1 = self.row_start[y + 1];
            let mut i = a0;
            for j in a1..b1 {
                let rj = self.runs[j];
                // Skip runs of the row above that end before this one starts.
                while i < a1 && self.runs[i].x1 + ext <= rj.x0 {
                    i += 1;
                }
                let mut k = i;
                while k < a1 && self.runs[k].x0 < rj.x1 + ext {
                    union(&mut self.parent, j as u32, k as u32);
                    k += 1;
                }
            }
        }
        // Dense component ids and statistics.
        self.root_to_comp.clear();
        self.root_to_comp.resize(n, u32::MAX);
        self.label.clear();
        self.components.clear();
        for r in 0..n {
            let root = find(&mut self.parent, r as u32) as usize;
            let run = self.runs[r];
            let c = if self.root_to_comp[root] == u32::MAX {
                self.root_to_comp[root] = self.components.len() as u32;
                self.components.push(Component {
                    area: 0,
                    min_x: run.x0,
                    min_y: run.y,
                    max_x: run.x1,
                    max_y: run.y + 1,
                    first_run: r,
                });
                self.components.len() - 1
            } else {
                self.root_to_comp[root] as usize
            };
            self.label.push(c as u32);
            let comp = &mut self.components[c];
            comp.area += (run.x1 - run.x0) as u64;
            comp.min_x = comp.min_x.min(run.x0);
            comp.max_x = comp.max_x.max(run.x1);
            comp.max_y = comp.max_y.max(run.y + 1);
        }
    }

    /// Index of the largest component, if any.
    pub fn largest(&self) -> Option<usize> {
        (0..self.components.len()).max_by_key(|&c| (self.components[c].area, usize::MAX - c))
    }

    /// The two largest components' indices (largest first).
    pub fn two_largest(&self) -> (Option<usize>, Option<usize>) {
        let mut best: (Option<usize>, Option<usize>) = (None, None);
        for c in 0..self.components.len() {
            let a = self.components[c].area;
            match best {
                (None, _) => best.0 = Some(c),
                (Some(b0), _) if a > self.components[b0].area => best = (Some(c), best.0),
                (_, None) => best.1 = Some(c),
                (_, Some(b1)) if a > self.components[b1].area => best.1 = Some(c),
                _ => {}
            }
        }
        best
    }

    /// Writes component `comp` into `out` (0/255), with its holes filled: background
    /// regions (4-connected) that do not reach the image border become foreground.
    /// `hole_scratch` is scratch for the background labelling.
    pub fn write_filled(&self, comp: usize, out: &mut Vec<u8>, hole_scratch: &mut RunComponents) {
        write_component(self, comp, out);
        fill_holes(out, self.width, self.height, hole_scratch);
    }
}

/// Writes component `comp` of `runs` into `out` (0/255), holes left open.
pub fn write_component(runs: &RunComponents, comp: usize, out: &mut Vec<u8>) {
    let (w, h) = (runs.width as usize, runs.height as usize);
    out.clear();
    out.resize(w * h, 0);
    for (r, run) in runs.runs.iter().enumerate() {
        if runs.label[r] as usize == comp {
            let y = run.y as usize;
            out[y * w + run.x0 as usize..y * w + run.x1 as usize].fill(super::MASK_ON);
        }
    }
}

/// Fills the holes of a binary mask in place, except the holes that look like the
/// background seen through a gap: `background_evidence(y, x0, x1)` counts the pixels of
/// the hole run `[x0, x1)` of row `y` that are explained as background, and a hole stays
/// open when it holds at least `min_open_area` pixels of which at least `open_fraction`
/// are such evidence. `evidence` is scratch (one counter per component); the runs of the
/// holes left open are written to `open` (cleared first).
#[allow(clippy::too_many_arguments)]
pub fn fill_holes_selective(
    mask: &mut [u8],
    width: u32,
    height: u32,
    scratch: &mut RunComponents,
    evidence: &mut Vec<u64>,
    mut background_evidence: impl FnMut(usize, usize, usize) -> u64,
    min_open_area: u64,
    open_fraction: f64,
    open: &mut Vec<Run>,
) {
    open.clear();
    let w = width as usize;
    scratch.compute(mask, width, height, false, false);
    evidence.clear();
    evidence.resize(scratch.components.len(), 0);
    for (r, run) in scratch.runs.iter().enumerate() {
        let c = scratch.label[r] as usize;
        let comp = &scratch.components[c];
        if !comp.touches_border(width, height) && comp.area >= min_open_area {
            evidence[c] += background_evidence(run.y as usize, run.x0 as usize, run.x1 as usize);
        }
    }
    for (r, run) in scratch.runs.iter().enumerate() {
        let c = scratch.label[r] as usize;
        let comp = &scratch.components[c];
        if comp.touches_border(width, height) {
            continue;
        }
        let is_open =
            comp.area >= min_open_area && evidence[c] as f64 >= open_fraction * comp.area as f64;
        if is_open {
            open.push(*run);
        } else {
            let y = run.y as usize;
            mask[y * w + run.x0 as usize..y * w + run.x1 as usize].fill(super::MASK_ON);
        }
    }
}

/// Fills the holes of a binary mask in place (background components, 4-connected, that
/// do not touch the image border).
pub fn fill_holes(mask: &mut [u8], width: u32, height: u32, scratch: &mut RunComponents) {
    let w = width as usize;
    scratch.compute(mask, width, height, false, false);
    for (r, run) in scratch.runs.iter().enumerate() {
        let c = &scratch.components[scratch.label[r] as usize];
        if !c.touches_border(width, height) {
            let y = run.y as usize;
            mask[y * w + run.x0 as usize..y * w + run.x1 as usize].fill(super::MASK_ON);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::imgproc::MASK_ON;

    fn mask_from(rows: &[&str]) -> (Vec<u8>, u32, u32) {
        let h = rows.len() as u32;
        let w = rows[0].len() as u32;
        let data = rows
            .iter()
            .flat_map(|r| r.bytes().map(|b| if b == b'#' { MASK_ON } else { 0 }))
            .collect();
        (data, w, h)
    }

    #[test]
    fn eight_connectivity_joins_diagonals_and_four_does_not() {
        let (m, w, h) = mask_from(&["#....", ".#...", "...##", "...##"]);
        let mut rc = RunComponents::default();
        rc.compute(&m, w, h, true, true);
        assert_eq!(rc.components.len(), 2);
        rc.compute(&m, w, h, true, false);
        assert_eq!(rc.components.len(), 3);
        let big = rc.largest().unwrap();
        assert_eq!(rc.components[big].area, 4);
        assert_eq!((rc.components[big].min_x, rc.components[big].max_y), (3, 4));
    }

    #[test]
    fn holes_of_background_evidence_stay_open_and_others_are_filled() {
        let (m, w, h) = mask_from(&[
            "..........", //
            ".########.", //
            ".#..##.#..", //
            ".#..##.#..", //
            ".########.", //
            "..........", //
        ]);
        // The 2x2 hole (columns 2-3) is background evidence; the 1x2 hole (column 6) not.
        let evidence = |y: usize, x0: usize, x1: usize| {
            (x0..x1)
                .filter(|&x| (2..4).contains(&x) && (2..4).contains(&y))
                .count() as u64
        };
        let mut out = m.clone();
        let (mut s, mut ev, mut open) = (RunComponents::default(), Vec::new(), Vec::new());
        fill_holes_selective(&mut out, w, h, &mut s, &mut ev, evidence, 2, 0.5, &mut open);
        assert_eq!(out[2 * 10 + 2], 0);
        assert_eq!(out[3 * 10 + 3], 0);
        assert_eq!(out[2 * 10 + 6], MASK_ON);
        assert_eq!(
            open,
            vec![Run { y: 2, x0: 2, x1: 4 }, Run { y: 3, x0: 2, x1: 4 }]
        );
        // A hole below the minimum area is filled whatever its evidence.
        let mut out = m.clone();
        fill_holes_selective(&mut out, w, h, &mut s, &mut ev, evidence, 5, 0.5, &mut open);
        assert_eq!(out[2 * 10 + 2], MASK_ON);
        assert!(open.is_empty());
    }

    #[test]
    fn holes_are_filled_but_border_bays_are_not() {
        let (m, w, h) = mask_from(&[
            "........", //
            ".######.", //
            ".#..#.#.", //
            ".######.", //
            ".#......", //
        ]);
        let mut rc = RunComponents::default();
        rc.compute(&m, w, h, true, true);
        let mut out = Vec::new();
        let mut s = RunComponents::default();
        rc.write_filled(rc.largest().unwrap(), &mut out, &mut s);
        assert_eq!(out[2 * 8 + 2], MASK_ON);
        assert_eq!(out[2 * 8 + 5], MASK_ON);
        assert_eq!(out[4 * 8 + 3], 0);
        assert_eq!(out.iter().filter(|&&v| v != 0).count(), 19);
    }
}
