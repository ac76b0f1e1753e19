//! No pockets where the arms meet the trunk.
//!
//! Turning an arm toward the body about its shoulder (pose synchronisation, a linear
//! blend) lifts the vertices just inside the joint with it while their trunk neighbours
//! stay: the armpit's apex can end up a few millimetres above every one of its
//! neighbours. Sliced just under such a peak the avatar shows a small closed loop, a
//! pocket in the surface between arm and trunk, before the arm comes free of the trunk.
//! A pocket that grows past the spec's arm size (0.05 x stature, about 90 mm) counts as
//! the arm having left the trunk (`../shared/spec/measurements.md`, armpit level), and
//! the chest, the largest trunk girth under the armpit, then takes both arms in (+300 to
//! +480 mm). Neither the template nor any library body has a peak there: the fold is
//! the skinning's.
//!
//! So after each fit, a vertex near either armpit that stands above everything around
//! it (alone or with neighbours) is brought down to just under the highest way out of
//! its patch: a flood from the zone's rim, as a terrain's pits are filled, upside down.
//!
//! Units: metres, station frame (+Y up).

use crate::mesh::OneRings;
use glam::DVec3;
use std::cmp::Ordering;
use std::collections::BinaryHeap;

/// Reach of an armpit's zone about the template's armpit landmark, metres.
const ZONE_M: f64 = 0.06;
/// How far under the vertex it comes down past a lowered vertex is put, metres.
const BELOW_M: f64 = 1e-4;

/// The vertices about the template's two armpits and the template's one-rings.
#[derive(Debug, Clone)]
pub struct ArmpitPeaks {
    zone: Vec<u32>,
    in_zone: Vec<bool>,
    rings: OneRings,
    /// Scratch of [`Self::flatten`]: settled vertices and the frontier.
    settled: Vec<bool>,
    frontier: BinaryHeap<Frontier>,
}

/// A settled vertex on the frontier of the flood, highest first.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Frontier {
    y: f64,
    v: u32,
}

impl Eq for Frontier {}

impl PartialOrd for Frontier {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}

impl Ord for Frontier {
    fn cmp(&self, other: &Self) -> Ordering {
        self.y.total_cmp(&other.y).then(other.v.cmp(&self.v))
    }
}

impl ArmpitPeaks {
    /// The zone: template vertices within [`ZONE_M`] of either armpit landmark.
    pub fn new(template: &[DVec3], rings: OneRings, armpits: [DVec3; 2]) -> Self {
        let in_zone: Vec<bool> = template
            .iter()
            .map(|p| armpits.iter().any(|a| p.distance(*a) <= ZONE_M))
            .collect();
        let zone = (0..template.len() as u32)
            .filter(|&i| in_zone[i as usize])
            .collect();
        ArmpitPeaks {
            zone,
            in_zone,
            settled: vec![false; template.len()],
            rings,
            frontier: BinaryHeap::new(),
        }
    }

    /// Vertices of the zone.
    pub fn zone(&self) -> &[u32] {
        &self.zone
    }

    /// Lowers every peak of the zone (a vertex, or a patch of them, standing above
    /// everything around it) until each vertex of the zone has a rising path out of the
    /// zone; returns how many vertices moved. Only heights change.
    ///
    /// A flood from the zone's rim, highest first: a vertex reached from a settled
    /// neighbour keeps its height when it is lower, else it comes down to [`BELOW_M`]
    /// under that neighbour (no rising way out of the zone but through it).
    pub fn flatten(&mut self, positions: &mut [DVec3]) -> usize {
        if positions.len() != self.in_zone.len() || self.zone.is_empty() {
            return 0;
        }
        self.frontier.clear();
        for &v in &self.zone {
            self.settled[v as usize] = false;
        }
        // The rim: vertices outside the zone beside it, and the zone's own vertices on
        // an open edge of the mesh.
        for &v in &self.zone {
            let v = v as usize;
            if self.rings.is_boundary(v) || !positions[v].is_finite() {
                self.settled[v] = true;
                self.frontier.push(Frontier {
                    y: positions[v].y,
                    v: v as u32,
                });
            }
            for &w in self.rings.neighbours(v) {
                if !self.in_zone[w as usize] && positions[w as usize].is_finite() {
                    self.frontier.push(Frontier {
                        y: positions[w as usize].y,
                        v: w,
                    });
                }
            }
        }
        let mut moved = 0;
        while let Some(Frontier { y, v }) = self.frontier.pop() {
            for &w in self.rings.neighbours(v as usize) {
                let wi = w as usize;
                if !self.in_zone[wi] || self.settled[wi] {
                    continue;
                }
                self.settled[wi] = true;
                if positions[wi].y > y {
                    positions[wi].y = y - BELOW_M;
                    moved += 1;
                }
                self.frontier.push(Frontier {
                    y: positions[wi].y,
                    v: w,
                });
            }
        }
        moved
    }

    /// Peaks of the zone in `positions`: vertices standing above every neighbour
    /// (tests, diagnostics).
    pub fn peaks(&self, positions: &[DVec3]) -> Vec<u32> {
        self.zone
            .iter()
            .copied()
            .filter(|&v| {
                let ring = self.rings.neighbours(v as usize);
                !ring.is_empty()
                    && !self.rings.is_boundary(v as usize)
                    && ring
                        .iter()
                        .all(|&w| positions[w as usize].y < positions[v as usize].y)
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::TriMesh;

    /// A grid of `n` x `n` vertices in the XZ plane at height 0 with one raised vertex in
    /// the middle and one beside it raised less.
    fn grid_with_peak(n: usize, peak: f64, shoulder: f64) -> TriMesh {
        let mut positions = Vec::new();
        for i in 0..n {
            for j in 0..n {
                positions.push(DVec3::new(i as f64 * 0.01, 0.0, j as f64 * 0.01));
            }
        }
        let mut triangles = Vec::new();
        for i in 0..n - 1 {
            for j in 0..n - 1 {
                let a = (i * n + j) as u32;
                let b = a + 1;
                let c = a + n as u32;
                let d = c + 1;
                triangles.push([a, b, d]);
                triangles.push([a, d, c]);
            }
        }
        let mid = n / 2 * n + n / 2;
        positions[mid].y = peak;
        positions[mid + 1].y = shoulder;
        TriMesh::new(positions, triangles)
    }

    #[test]
    fn a_peak_and_the_neighbour_it_leaves_standing_come_down() {
        let mesh = grid_with_peak(9, 0.003, 0.002);
        let rings = mesh.one_rings();
        let mid = 4 * 9 + 4;
        let mut peaks = ArmpitPeaks::new(&mesh.positions, rings, [mesh.positions[mid]; 2]);
        assert_eq!(peaks.peaks(&mesh.positions), vec![mid as u32]);
        let mut p = mesh.positions.clone();
        let moved = peaks.flatten(&mut p);
        // The peak and its raised neighbour stand together above the flat grid: both
        // come under it.
        assert_eq!(moved, 2);
        assert!(
            peaks.peaks(&p).is_empty(),
            "peaks left: {:?}",
            peaks.peaks(&p)
        );
        assert!(p[mid].y < 0.0 && p[mid + 1].y < 0.0);
        // Only those two moved, and only in height.
        for (i, (a, b)) in mesh.positions.iter().zip(&p).enumerate() {
            if i != mid && i != mid + 1 {
                assert_eq!(a, b);
            }
            assert_eq!((a.x, a.z), (b.x, b.z));
        }
    }

    #[test]
    fn a_surface_without_peaks_is_left_alone() {
        let mesh = grid_with_peak(9, -0.002, 0.0);
        let rings = mesh.one_rings();
        let mid = 4 * 9 + 4;
        let mut peaks = ArmpitPeaks::new(&mesh.positions, rings, [mesh.positions[mid]; 2]);
        let mut p = mesh.positions.clone();
        assert_eq!(peaks.flatten(&mut p), 0);
        assert_eq!(p, mesh.positions);
    }
}
