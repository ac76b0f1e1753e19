//! The waist's section shape from real people, not from the candidate.
//!
//! Two orthogonal silhouettes fix a section's breadth (front view) and depth (side view)
//! but say nothing about how full its corners are between those four rims: [`super::
//! sections`] keeps the candidate's shape there, scaled to both views. The tape girth
//! depends on that shape as much as on the extents, and the shape library's waists are
//! rounder than people's: on ANSUR II (6,068 adults), the waist circumference is a median
//! [`WAIST_HULL_TO_ELLIPSE`] times the perimeter of the ellipse of the same waist breadth
//! and depth (quartiles 1.044 and 1.069, about the same for women and men and across
//! depth/breadth ratios), while the candidates' waists come out near 1.02-1.03.
//!
//! So about the candidate's waist level the trunk's mapped sections are made fuller or
//! rounder at their corners, keeping their extents, until the waist section's convex hull
//! is that multiple of its ellipse: a radial push about the section's centre by
//! `1 + k sin^2(2 theta)` (theta the angle in coordinates normalised by the half-extents:
//! none at the four rims, most at the corners), each side then rescaled back onto its rim.
//! Through the waist band each section is taken the same way toward that shape, fully
//! from halfway below to halfway above the waist and fading to none at the candidate's
//! hip and chest levels, so the level the waist is taken at (the smallest girth) does not
//! jump to the band's edge, and a section already fuller than a waist is made rounder.
//!
//! Units: metres, station frame (+Y up, +Z toward the front camera, +X the subject's left).

use crate::measure::slicer::hull_stats;
use glam::{DVec2, DVec3};

/// Median over ANSUR II (both files) of waist circumference over the Ramanujan perimeter
/// of the ellipse with the waist breadth and depth as axes (all three taken at the
/// omphalion). Checked against the data in the tests.
pub const WAIST_HULL_TO_ELLIPSE: f64 = 1.056;

/// Height bins the band's sections are gathered in, metres (the template's vertex rows
/// are about 1 cm apart); a section is the vertices of its bin and the two beside it.
const BIN_M: f64 = 0.01;
/// Bounds of the corner push: a section squarer than a rounded box, or rounder than a
/// diamond, is not a waist.
const K_RANGE: (f64, f64) = (-0.3, 0.5);
/// The push tried first to find how the ratio answers (the answer is nearly linear).
const K_PROBE: f64 = 0.1;
/// Fewest vertices a section needs to be reshaped.
const MIN_POINTS: usize = 12;

/// Perimeter of the ellipse with full axes `b` and `d` (Ramanujan's first formula).
pub fn ellipse_perimeter(b: f64, d: f64) -> f64 {
    let (a, c) = (0.5 * b, 0.5 * d);
    std::f64::consts::PI * (3.0 * (a + c) - ((3.0 * a + c) * (a + 3.0 * c)).sqrt())
}

/// The candidate's levels the band is laid on (station y, metres).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WaistBand {
    pub hip_y: f64,
    pub waist_y: f64,
    pub chest_y: f64,
}

impl WaistBand {
    /// None unless hip < waist < chest.
    pub fn new(hip_y: f64, waist_y: f64, chest_y: f64) -> Option<WaistBand> {
        (hip_y.is_finite() && chest_y.is_finite() && hip_y < waist_y && waist_y < chest_y)
            .then_some(WaistBand {
                hip_y,
                waist_y,
                chest_y,
            })
    }

    /// Weight of the waist's shape at height `y`: one from halfway between hip and waist
    /// to halfway between waist and chest, fading linearly to none at the hip and chest.
    pub fn weight(&self, y: f64) -> f64 {
        let lo_full = 0.5 * (self.hip_y + self.waist_y);
        let hi_full = 0.5 * (self.waist_y + self.chest_y);
        if y <= self.hip_y || y >= self.chest_y {
            0.0
        } else if y < lo_full {
            (y - self.hip_y) / (lo_full - self.hip_y)
        } else if y > hi_full {
            (self.chest_y - y) / (self.chest_y - hi_full)
        } else {
            1.0
        }
    }
}

/// One reshaped bin's section: centre and half-extents of its points, its push, and the
/// extreme normalised coordinates after the push (to rescale each side onto its rim).
#[derive(Debug, Clone, Copy)]
struct BinFrame {
    centre: DVec2,
    half: DVec2,
    k: f64,
    /// Largest and least pushed u, then v.
    pushed: [f64; 4],
}

/// Reusable buffers of [`reshape`].
#[derive(Debug, Clone, Default)]
pub struct PriorScratch {
    bins: Vec<Vec<DVec2>>,
    frames: Vec<Option<BinFrame>>,
    pts: Vec<DVec2>,
    hull: Vec<DVec2>,
}

/// `sin^2(2 theta)` of the normalised point (u, v): 0 on the axes, 1 on the diagonals.
fn corner(u: f64, v: f64) -> f64 {
    let r2 = u * u + v * v;
    if r2 < 1e-18 {
        0.0
    } else {
        4.0 * u * u * v * v / (r2 * r2)
    }
}

/// Bounding centre and half-extents of `pts`.
fn frame_of(pts: &[DVec2]) -> (DVec2, DVec2) {
    let (mut lo, mut hi) = (DVec2::splat(f64::MAX), DVec2::splat(f64::MIN));
    for p in pts {
        lo = lo.min(*p);
        hi = hi.max(*p);
    }
    (0.5 * (lo + hi), 0.5 * (hi - lo))
}

/// Pushes the normalised points by `k` and returns the extremes [u max, u min, v max,
/// v min].
fn pushed_extremes(pts: &[DVec2], centre: DVec2, half: DVec2, k: f64) -> [f64; 4] {
    let mut e = [f64::MIN, f64::MAX, f64::MIN, f64::MAX];
    for p in pts {
        let n = (*p - centre) / half;
        let q = n * (1.0 + k * corner(n.x, n.y));
        e[0] = e[0].max(q.x);
        e[1] = e[1].min(q.x);
        e[2] = e[2].max(q.y);
        e[3] = e[3].min(q.y);
    }
    e
}

/// The normalised point `n` pushed by `k` and rescaled onto the rims by `ext`.
fn place(n: DVec2, k: f64, ext: &[f64; 4]) -> DVec2 {
    let q = n * (1.0 + k * corner(n.x, n.y));
    let sx = if q.x >= 0.0 { ext[0] } else { -ext[1] };
    let sz = if q.y >= 0.0 { ext[2] } else { -ext[3] };
    DVec2::new(
        if sx > 1e-9 { q.x / sx } else { q.x },
        if sz > 1e-9 { q.y / sz } else { q.y },
    )
}

/// Convex hull perimeter of `pts` after the push `k`, over the ellipse of its extents.
fn ratio(pts: &[DVec2], centre: DVec2, half: DVec2, k: f64, s: &mut PriorScratch) -> f64 {
    let ext = pushed_extremes(pts, centre, half, k);
    s.pts.clear();
    s.pts.extend(
        pts.iter()
            .map(|p| place((*p - centre) / half, k, &ext) * half),
    );
    let perimeter = hull_stats(&mut s.pts, &mut s.hull).map_or(0.0, |h| h.perimeter_m);
    perimeter / ellipse_perimeter(2.0 * half.x, 2.0 * half.y)
}

/// The push that brings the section `pts` (bounding `centre` and `half`-extents, hull
/// over ellipse `r0` unpushed) to `target`, by two secant steps from the probe; None if
/// the section is degenerate.
fn solve_k(
    pts: &[DVec2],
    centre: DVec2,
    half: DVec2,
    r0: f64,
    target: f64,
    s: &mut PriorScratch,
) -> Option<f64> {
    if pts.len() < MIN_POINTS || half.min_element() < 1e-3 {
        return None;
    }
    let (mut k0, mut r0) = (0.0, r0);
    let (mut k1, mut r1) = (K_PROBE, ratio(pts, centre, half, K_PROBE, s));
    for _ in 0..2 {
        if (r1 - r0).abs() < 1e-6 {
            break;
        }
        let k = (k1 + (target - r1) * (k1 - k0) / (r1 - r0)).clamp(K_RANGE.0, K_RANGE.1);
        (k0, r0) = (k1, r1);
        (k1, r1) = (k, ratio(pts, centre, half, k, s));
    }
    r1.is_finite().then_some(k1)
}

/// Reshapes the trunk's mapped targets `out` (indexed by vertex) of `torso` vertices
/// within `band`, so that the waist section's hull is [`WAIST_HULL_TO_ELLIPSE`] times
/// its ellipse (see the module docs). Returns the push applied at the waist, or None
/// where the waist section could not be gathered (then nothing is changed).
// Index arithmetic over several arrays reads better with indices.
#[allow(clippy::needless_range_loop)]
pub fn reshape(
    band: &WaistBand,
    torso: &[u32],
    out: &mut [Option<DVec3>],
    s: &mut PriorScratch,
) -> Option<f64> {
    let n_bins = ((band.chest_y - band.hip_y) / BIN_M).ceil() as usize + 1;
    let bin_of = |y: f64| ((y - band.hip_y) / BIN_M).floor();
    s.bins.resize_with(n_bins, Vec::new);
    for b in &mut s.bins {
        b.clear();
    }
    for &v in torso {
        let Some(p) = out.get(v as usize).copied().flatten() else {
            continue;
        };
        let b = bin_of(p.y);
        if b >= 0.0 && (b as usize) < n_bins {
            s.bins[b as usize].push(DVec2::new(p.x, p.z));
        }
    }
    let gather = |bins: &[Vec<DVec2>], b: usize, pts: &mut Vec<DVec2>| {
        pts.clear();
        for bb in b.saturating_sub(1)..(b + 2).min(bins.len()) {
            pts.extend_from_slice(&bins[bb]);
        }
    };
    let waist_bin = bin_of(band.waist_y) as usize;
    let mut pts = Vec::new();
    gather(&s.bins, waist_bin, &mut pts);
    let (centre, half) = frame_of(&pts);
    let r0 = ratio(&pts, centre, half, 0.0, s);
    let k = solve_k(&pts, centre, half, r0, WAIST_HULL_TO_ELLIPSE, s)?;
    let mut frames = std::mem::take(&mut s.frames);
    frames.clear();
    for b in 0..n_bins {
        gather(&s.bins, b, &mut pts);
        let y = band.hip_y + (b as f64 + 0.5) * BIN_M;
        let (centre, half) = frame_of(&pts);
        let w = band.weight(y);
        // Each section is taken toward the waist's shape by the band's weight: its own
        // push, so that a section already fuller than the waist's is not pushed further.
        let kb = if b == waist_bin {
            Some(k)
        } else if w > 0.0 && pts.len() >= MIN_POINTS {
            let r0 = ratio(&pts, centre, half, 0.0, s);
            solve_k(
                &pts,
                centre,
                half,
                r0,
                r0 + w * (WAIST_HULL_TO_ELLIPSE - r0),
                s,
            )
        } else {
            None
        };
        frames.push(kb.filter(|&k| k != 0.0).map(|k| BinFrame {
            centre,
            half,
            k,
            pushed: pushed_extremes(&pts, centre, half, k),
        }));
    }
    for &v in torso {
        let Some(p) = out.get_mut(v as usize).and_then(|p| p.as_mut()) else {
            continue;
        };
        let b = bin_of(p.y);
        if b < 0.0 || b as usize >= n_bins {
            continue;
        }
        let Some(f) = frames[b as usize] else {
            continue;
        };
        let n = (DVec2::new(p.x, p.z) - f.centre) / f.half;
        let q = f.centre + place(n, f.k, &f.pushed) * f.half;
        p.x = q.x;
        p.z = q.y;
    }
    s.frames = frames;
    Some(k)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Rings of an elliptic cylinder (breadth 0.3, depth 0.22) from y 0.8 to 1.3.
    fn cylinder() -> (Vec<u32>, Vec<Option<DVec3>>) {
        let mut out = Vec::new();
        for row in 0..50 {
            let y = 0.8 + row as f64 * 0.01;
            for i in 0..48 {
                let t = i as f64 / 48.0 * std::f64::consts::TAU;
                out.push(Some(DVec3::new(
                    0.15 * t.cos() + 0.02,
                    y,
                    0.11 * t.sin() - 0.1,
                )));
            }
        }
        ((0..out.len() as u32).collect(), out)
    }

    fn section_at(out: &[Option<DVec3>], y: f64) -> Vec<DVec2> {
        out.iter()
            .flatten()
            .filter(|p| (p.y - y).abs() < 0.004)
            .map(|p| DVec2::new(p.x, p.z))
            .collect()
    }

    fn hull_ratio(pts: &[DVec2]) -> (f64, DVec2) {
        let (_, half) = frame_of(pts);
        let mut p = pts.to_vec();
        let mut h = Vec::new();
        let per = hull_stats(&mut p, &mut h).map_or(0.0, |h| h.perimeter_m);
        (per / ellipse_perimeter(2.0 * half.x, 2.0 * half.y), half)
    }

    #[test]
    fn the_waist_section_reaches_the_prior_and_keeps_its_extents() {
        let (torso, mut out) = cylinder();
        let band = WaistBand::new(0.85, 1.05, 1.25).expect("ordered levels");
        let before = hull_ratio(&section_at(&out, 1.05));
        assert!((before.0 - 1.0).abs() < 0.01, "an ellipse: {}", before.0);
        let k = reshape(&band, &torso, &mut out, &mut PriorScratch::default());
        assert!(k.is_some_and(|k| k > 0.0), "{k:?}");
        let (r, half) = hull_ratio(&section_at(&out, 1.05));
        assert!((r - WAIST_HULL_TO_ELLIPSE).abs() < 0.004, "waist ratio {r}");
        assert!(
            (half - before.1).abs().max_element() < 2e-4,
            "{half} vs {}",
            before.1
        );
        // Outside the band nothing moves; at its edges less than at the waist.
        assert!((hull_ratio(&section_at(&out, 0.82)).0 - before.0).abs() < 1e-9);
        assert!((hull_ratio(&section_at(&out, 1.28)).0 - before.0).abs() < 1e-9);
        let edge = hull_ratio(&section_at(&out, 1.22)).0;
        assert!(edge > before.0 && edge < r, "{edge}");
    }

    #[test]
    fn a_boxy_waist_is_made_rounder() {
        let (torso, mut out) = cylinder();
        for p in out.iter_mut().flatten() {
            // A superellipse of exponent 4 about the same centre.
            let (u, v) = ((p.x - 0.02) / 0.15, (p.z + 0.1) / 0.11);
            let r = (u.powi(4) + v.powi(4)).powf(0.25);
            p.x = 0.02 + 0.15 * u / r;
            p.z = -0.1 + 0.11 * v / r;
        }
        let band = WaistBand::new(0.85, 1.05, 1.25).expect("ordered levels");
        let before = hull_ratio(&section_at(&out, 1.05)).0;
        assert!(before > 1.1, "{before}");
        let k = reshape(&band, &torso, &mut out, &mut PriorScratch::default());
        assert!(k.is_some_and(|k| k < 0.0), "{k:?}");
        let r = hull_ratio(&section_at(&out, 1.05)).0;
        assert!((r - WAIST_HULL_TO_ELLIPSE).abs() < 0.006, "waist ratio {r}");
    }

    #[test]
    fn disordered_levels_or_no_waist_section_change_nothing() {
        assert!(WaistBand::new(1.0, 0.9, 1.2).is_none());
        assert!(WaistBand::new(0.9, 1.0, f64::NAN).is_none());
        let (torso, mut out) = cylinder();
        let band = WaistBand::new(1.40, 1.50, 1.60).expect("ordered levels");
        let before = out.clone();
        assert!(reshape(&band, &torso, &mut out, &mut PriorScratch::default()).is_none());
        assert_eq!(before, out);
    }

    #[test]
    fn the_constant_is_ansur_iis_median() {
        use crate::synth::ansur::{resolve_dir, AnsurTable, Sex};
        let dir = resolve_dir(None).expect("../shared/data/ansur2 beside the checkout");
        let table = AnsurTable::load(&dir).expect("ANSUR II files");
        let mut r: Vec<f64> = [Sex::Female, Sex::Male]
            .iter()
            .flat_map(|&s| table.rows(s))
            .map(|p| p.waistcircumference / ellipse_perimeter(p.waistbreadth, p.waistdepth))
            .collect();
        assert!(r.len() > 6000);
        r.sort_by(f64::total_cmp);
        let median = r[r.len() / 2];
        assert!((median - WAIST_HULL_TO_ELLIPSE).abs() < 0.0005, "{median}");
    }
}
