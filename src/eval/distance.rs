//! Point-to-surface distances: from points (a fitted avatar's vertices) to the closest
//! point of a triangle mesh (the true body), through a uniform grid of triangle lists.
//!
//! Units are those of the inputs (metres in the station). The closest point on a
//! triangle follows the Voronoi-region case analysis of Ericson, *Real-Time Collision
//! Detection* (2005), section 5.1.5.

use crate::mesh::TriMesh;
use glam::DVec3;

/// Closest point to `p` on triangle (a, b, c).
pub fn closest_point_on_triangle(p: DVec3, a: DVec3, b: DVec3, c: DVec3) -> DVec3 {
    let ab = b - a;
    let ac = c - a;
    let ap = p - a;
    let d1 = ab.dot(ap);
    let d2 = ac.dot(ap);
    if d1 <= 0.0 && d2 <= 0.0 {
        return a; // vertex region A
    }
    let bp = p - b;
    let d3 = ab.dot(bp);
    let d4 = ac.dot(bp);
    if d3 >= 0.0 && d4 <= d3 {
        return b; // vertex region B
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        return a + ab * (d1 / (d1 - d3)); // edge AB
    }
    let cp = p - c;
    let d5 = ab.dot(cp);
    let d6 = ac.dot(cp);
    if d6 >= 0.0 && d5 <= d6 {
        return c; // vertex region C
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        return a + ac * (d2 / (d2 - d6)); // edge AC
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        return b + (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6))); // edge BC
    }
    let denom = 1.0 / (va + vb + vc);
    a + ab * (vb * denom) + ac * (vc * denom) // inside the face
}

/// A uniform grid over a mesh's triangles for nearest-surface queries.
#[derive(Debug, Clone)]
pub struct SurfaceGrid {
    min: DVec3,
    cell: f64,
    dims: [usize; 3],
    offsets: Vec<u32>,
    items: Vec<u32>,
    tris: Vec<[DVec3; 3]>,
}

/// Cells along the longest side of the grid (bounded memory, ~2 cm cells for a body).
const CELLS_LONG_SIDE: f64 = 96.0;

impl SurfaceGrid {
    /// Builds the grid; `None` for a mesh without triangles.
    pub fn new(mesh: &TriMesh) -> Option<SurfaceGrid> {
        let tris: Vec<[DVec3; 3]> = mesh
            .triangles
            .iter()
            .filter_map(|t| {
                Some([
                    *mesh.positions.get(t[0] as usize)?,
                    *mesh.positions.get(t[1] as usize)?,
                    *mesh.positions.get(t[2] as usize)?,
                ])
            })
            .collect();
        if tris.is_empty() {
            return None;
        }
        let mut min = DVec3::splat(f64::INFINITY);
        let mut max = DVec3::splat(f64::NEG_INFINITY);
        for t in &tris {
            for p in t {
                min = min.min(*p);
                max = max.max(*p);
            }
        }
        let size = (max - min).max(DVec3::splat(1e-6));
        let cell = (size.max_element() / CELLS_LONG_SIDE).max(1e-6);
        let dims = [0, 1, 2].map(|k| ((size[k] / cell).ceil() as usize).max(1));
        let ncell = dims[0] * dims[1] * dims[2];
        let cell_of = |p: DVec3| -> [usize; 3] {
            [0, 1, 2].map(|k| (((p[k] - min[k]) / cell).floor().max(0.0) as usize).min(dims[k] - 1))
        };
        let mut counts = vec![0u32; ncell + 1];
        let ranges: Vec<([usize; 3], [usize; 3])> = tris
            .iter()
            .map(|t| {
                let lo = t[0].min(t[1]).min(t[2]);
                let hi = t[0].max(t[1]).max(t[2]);
                (cell_of(lo), cell_of(hi))
            })
            .collect();
        let idx = |c: [usize; 3]| (c[2] * dims[1] + c[1]) * dims[0] + c[0];
        for (lo, hi) in &ranges {
            for z in lo[2]..=hi[2] {
                for y in lo[1]..=hi[1] {
                    for x in lo[0]..=hi[0] {
                        counts[idx([x, y, z]) + 1] += 1;
                    }
                }
            }
        }
        for i in 0..ncell {
            counts[i + 1] += counts[i];
        }
        let mut fill = counts.clone();
        let mut items = vec![0u32; counts[ncell] as usize];
        for (ti, (lo, hi)) in ranges.iter().enumerate() {
            for z in lo[2]..=hi[2] {
                for y in lo[1]..=hi[1] {
                    for x in lo[0]..=hi[0] {
                        let c = idx([x, y, z]);
                        items[fill[c] as usize] = ti as u32;
                        fill[c] += 1;
                    }
                }
            }
        }
        Some(SurfaceGrid {
            min,
            cell,
            dims,
            offsets: counts,
            items,
            tris,
        })
    }

    /// Distance from `p` to the surface.
    pub fn distance(&self, p: DVec3) -> f64 {
        let rel = (p - self.min) / self.cell;
        let inside = (0..3).all(|k| rel[k] >= 0.0 && rel[k] < self.dims[k] as f64);
        if !inside {
            // Outside the grid: exhaustive search (rare: badly wrong vertices only).
            return self
                .tris
                .iter()
                .map(|t| (closest_point_on_triangle(p, t[0], t[1], t[2]) - p).length())
                .fold(f64::INFINITY, f64::min);
        }
        let c = [0, 1, 2].map(|k| rel[k].floor() as i64);
        let mut best = f64::INFINITY;
        let max_r = *self.dims.iter().max().unwrap_or(&1) as i64;
        for r in 0..=max_r {
            // Visit the cells of the shell at Chebyshev distance r.
            for dz in -r..=r {
                for dy in -r..=r {
                    for dx in -r..=r {
                        if dx.abs().max(dy.abs()).max(dz.abs()) != r {
                            continue;
                        }
                        let q = [c[0] + dx, c[1] + dy, c[2] + dz];
                        if (0..3).any(|k| q[k] < 0 || q[k] >= self.dims[k] as i64) {
                            continue;
                        }
                        let ci = (q[2] as usize * self.dims[1] + q[1] as usize) * self.dims[0]
                            + q[0] as usize;
                        for &ti in
                            &self.items[self.offsets[ci] as usize..self.offsets[ci + 1] as usize]
                        {
                            let t = &self.tris[ti as usize];
                            best = best
                                .min((closest_point_on_triangle(p, t[0], t[1], t[2]) - p).length());
                        }
                    }
                }
            }
            // Every cell beyond this shell is at least r cells away from p.
            if best <= r as f64 * self.cell {
                break;
            }
        }
        best
    }
}

/// Summary of distances from points to a surface, millimetres.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct SurfaceDistance {
    pub mean_mm: f64,
    pub p95_mm: f64,
    pub max_mm: f64,
}

/// Distances from every point to the surface of `truth` (metres in, millimetres out).
pub fn surface_distance(points: &[DVec3], truth: &TriMesh) -> Option<SurfaceDistance> {
    let grid = SurfaceGrid::new(truth)?;
    let mut d: Vec<f64> = points.iter().map(|p| grid.distance(*p) * 1000.0).collect();
    if d.is_empty() {
        return None;
    }
    d.sort_by(f64::total_cmp);
    let mean = d.iter().sum::<f64>() / d.len() as f64;
    let p95 = d[((d.len() as f64 * 0.95).ceil() as usize)
        .saturating_sub(1)
        .min(d.len() - 1)];
    Some(SurfaceDistance {
        mean_mm: mean,
        p95_mm: p95,
        max_mm: d[d.len() - 1],
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::shapes;

    #[test]
    fn grid_agrees_with_brute_force() {
        let mesh = shapes::uv_sphere(0.5, 16, 32);
        let grid = SurfaceGrid::new(&mesh).unwrap();
        let mut g = crate::synth::rng::SplitMix64::new(5);
        for _ in 0..300 {
            let p = DVec3::new(g.range(-0.6, 0.6), g.range(-0.6, 0.6), g.range(-0.6, 0.6));
            let brute = mesh
                .triangles
                .iter()
                .map(|t| {
                    let [a, b, c] = t.map(|i| mesh.positions[i as usize]);
                    (closest_point_on_triangle(p, a, b, c) - p).length()
                })
                .fold(f64::INFINITY, f64::min);
            assert!((grid.distance(p) - brute).abs() < 1e-12, "{p}");
        }
    }

    #[test]
    fn closest_point_is_on_the_triangle_and_nearest() {
        let (a, b, c) = (DVec3::ZERO, DVec3::X, DVec3::Y);
        let q = closest_point_on_triangle(DVec3::new(0.2, 0.2, 1.0), a, b, c);
        assert!((q - DVec3::new(0.2, 0.2, 0.0)).length() < 1e-12, "{q}");
        assert_eq!(
            closest_point_on_triangle(DVec3::new(-1.0, -1.0, 0.0), a, b, c),
            a
        );
        let q = closest_point_on_triangle(DVec3::new(1.0, 1.0, 0.0), a, b, c);
        assert!((q - DVec3::new(0.5, 0.5, 0.0)).length() < 1e-12);
    }

    #[test]
    fn offset_surface_reports_the_offset() {
        let inner = shapes::uv_sphere(0.5, 24, 48);
        let outer = shapes::uv_sphere(0.51, 24, 48);
        let d = surface_distance(&outer.positions, &inner).unwrap();
        assert!((d.mean_mm - 10.0).abs() < 1.0, "{d:?}");
    }
}
