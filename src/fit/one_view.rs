//! Fitting from the front view alone (issue 23): where the body stands in depth, and its
//! stature, without the side view.
//!
//! Two views place the trunk in depth by its side silhouette; one view cannot, and a
//! front camera a few metres away sees a body 10 cm behind the plane it assumes about
//! 3 % too narrow. What the front view does show in depth is where the feet meet the
//! floor: the lowest row of the silhouette is the front of the toes on the floor (y = 0),
//! and a ray meets the floor at one point. The body's own proportions (the library body's
//! toe-to-trunk offset, scaled to the stature) then place the trunk behind the toes.
//! The head top lifted onto the plane z = 0 is moved along its ray to the head's depth.
//!
//! Units: metres, station frame (+Y up, +Z toward the front camera, +X the subject's
//! left); pixels as OpenCV (origin at the top-left pixel's centre).

use super::correspond::MaskRef;
use crate::camera::Camera;
use glam::{DVec2, DVec3};

/// Person pixels a mask row needs to count as the lowest row of the feet (a stray pixel
/// or two of noise do not).
const MIN_FOOT_ROW_PX: usize = 4;
/// Height band over the floor within which a body's vertices count as its feet' soles
/// and toes, a fraction of stature.
const FOOT_BAND_REL: f64 = 0.015;

/// How far from the mark (metres) the feet' centre may be: the landmarks' off-mark
/// verdict's distance ([`crate::landmarks::VerdictOptions`] `off_mark_m`): a subject
/// further off is asked to step onto the mark. Toes seen further away are a lost lower
/// edge of the feet (feet of the floor's colour), not a subject standing there.
pub const MARK_TOLERANCE_M: f64 = 0.10;

/// Standard deviation of the feet's lowest silhouette row about the floor contact,
/// pixels: the mask's lower edge sits a few pixels above where the toes meet the floor
/// (shadow and anti-aliasing at a grazing angle; seen while building the placement).
pub const TOE_ROW_SD_PX: f64 = 3.0;

/// The depths of a standing body relative to its toes, fractions of its stature: the
/// trunk's centre, the head top and the feet' centre behind (negative: -Z of) the front
/// of the toes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DepthOffsets {
    pub trunk_rel: f64,
    pub head_top_rel: f64,
    pub feet_rel: f64,
    /// Spread (standard deviation) of `head_top_rel` over the bodies averaged by
    /// [`Self::mean`]: how well the head's depth follows from the toes'. 0 for one body.
    pub head_top_sd_rel: f64,
}

impl DepthOffsets {
    /// Offsets of a body (station-like frame, soles at y = 0) whose trunk's centre at the
    /// placement height is `trunk_centre`. None for a degenerate body.
    pub fn of_body(positions: &[DVec3], trunk_centre: DVec3) -> Option<DepthOffsets> {
        let stature = positions.iter().map(|p| p.y).fold(f64::MIN, f64::max);
        if !(stature > 0.1) {
            return None;
        }
        let (heel_z, toe_z) = positions
            .iter()
            .filter(|p| p.y < FOOT_BAND_REL * stature)
            .fold((f64::MAX, f64::MIN), |(lo, hi), p| {
                (lo.min(p.z), hi.max(p.z))
            });
        let head = positions.iter().max_by(|a, b| a.y.total_cmp(&b.y))?;
        (toe_z >= heel_z).then(|| DepthOffsets {
            trunk_rel: (trunk_centre.z - toe_z) / stature,
            head_top_rel: (head.z - toe_z) / stature,
            feet_rel: (0.5 * (heel_z + toe_z) - toe_z) / stature,
            head_top_sd_rel: 0.0,
        })
    }

    /// Mean of several bodies' offsets, with the spread of the head's.
    pub fn mean(all: &[DepthOffsets]) -> Option<DepthOffsets> {
        let n = all.len() as f64;
        let head_top_rel = all.iter().map(|d| d.head_top_rel).sum::<f64>() / n;
        let var = all
            .iter()
            .map(|d| (d.head_top_rel - head_top_rel).powi(2))
            .sum::<f64>()
            / n;
        (n > 0.0).then(|| DepthOffsets {
            trunk_rel: all.iter().map(|d| d.trunk_rel).sum::<f64>() / n,
            head_top_rel,
            feet_rel: all.iter().map(|d| d.feet_rel).sum::<f64>() / n,
            head_top_sd_rel: var.sqrt(),
        })
    }

    /// The toes' depth to place a body of `stature_m` by, and whether the seen toes'
    /// `toes_z` were believed: feet centred within [`MARK_TOLERANCE_M`] of the mark have
    /// their toes within that plus half a foot (the library's) of it; toes seen further
    /// away are a lost lower edge of the feet, and the toes of feet centred on the mark
    /// are taken instead.
    pub fn believed_toes_z(&self, toes_z: f64, stature_m: f64) -> (f64, bool) {
        let half_foot = -self.feet_rel * stature_m;
        if toes_z.abs() <= MARK_TOLERANCE_M + half_foot {
            (toes_z, true)
        } else {
            (half_foot, false)
        }
    }
}

/// Where the front of the feet meets the floor, as the front camera sees it: the ray
/// through the middle of the silhouette's lowest row (its lower edge) meets y = 0. None
/// without a row of feet or a ray that meets the floor in front of the camera.
pub fn toes_on_floor(cam: &Camera, front: MaskRef<'_>) -> Option<DVec3> {
    let (w, h) = (front.width as usize, front.height as usize);
    if front.data.len() < w * h {
        return None;
    }
    let row = (0..h).rev().find_map(|y| {
        let line = &front.data[y * w..(y + 1) * w];
        let (n, sum) = line
            .iter()
            .enumerate()
            .filter(|(_, &v)| v > 127)
            .fold((0usize, 0usize), |(n, s), (x, _)| (n + 1, s + x));
        (n >= MIN_FOOT_ROW_PX).then(|| DVec2::new(sum as f64 / n as f64, y as f64 + 0.5))
    })?;
    let ray = cam.ray_through_pixel(row);
    if ray.dir.y.abs() < 1e-9 {
        return None;
    }
    let t = -ray.origin.y / ray.dir.y;
    (t > 0.0).then(|| ray.at(t))
}

/// Metres along the floor's z per image row at a floor point, as `cam` sees it.
pub fn floor_metres_per_row(cam: &Camera, on_floor: DVec3) -> Option<f64> {
    const STEP_M: f64 = 0.01;
    let a = cam.project(on_floor)?;
    let b = cam.project(on_floor + DVec3::new(0.0, 0.0, STEP_M))?;
    let rows = (b.y - a.y).abs();
    (rows > 1e-9).then(|| STEP_M / rows)
}

/// Standard deviation (mm) of a stature lifted from the front view and moved along its
/// ray to the head's depth ([`height_at_depth`]): the head's depth is the toes' plus the
/// library's mean offset, so it is off by the toes' error (`toes_sd_m`) and by how far
/// people's heads stand from their toes beyond that mean (`head_top_sd_m`), and a depth
/// error moves the height by the ray's slope, `|head y - camera y| / |camera z - head z|`.
pub fn stature_sd_mm(cam: &Camera, head_top: DVec3, toes_sd_m: f64, head_top_sd_m: f64) -> f64 {
    let c = cam.center_in_station();
    let slope = (head_top.y - c.y).abs() / (c.z - head_top.z).abs().max(1e-3);
    slope * toes_sd_m.hypot(head_top_sd_m) * 1000.0
}

/// The height of a point seen at height `y_on_plane` on the plane z = `plane_z`, moved
/// along the camera's ray to the plane z = `z` (a point behind the plane it was lifted
/// onto is higher when the camera looks down on it).
pub fn height_at_depth(cam: &Camera, y_on_plane: f64, plane_z: f64, z: f64) -> f64 {
    let c = cam.center_in_station();
    let along = c.z - plane_z;
    if along.abs() < 1e-9 {
        return y_on_plane;
    }
    c.y + (y_on_plane - c.y) * (c.z - z) / along
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::StationCalibration;

    /// Prints the shape library's chest, waist and buttock breadths and depths (mm, at
    /// the measurement levels) and statures of the bodies the fit chooses from, as CSV:
    /// `tools/ansur_priors.py --library FILE` measures how far real people's depths are
    /// from what the library says for their breadths and stature (the one-view prior).
    /// `cargo test --release library_extents_csv -- --ignored --nocapture`
    #[test]
    #[ignore]
    fn library_extents_csv() {
        use crate::body::ShapeLibrary;
        let library = ShapeLibrary::shared().expect("the bundled shape library");
        let template = library.template();
        let rings = template.mesh.one_rings();
        let lm = crate::fit::pose::template_part_landmarks(template).expect("landmarks");
        let labels = crate::fit::parts::label_parts(&template.mesh, &rings, &lm);
        let edges = crate::fit::shape::unique_edges(&template.mesh.triangles);
        println!("LIBRARY_CSV stature,chestbreadth,chestdepth,waistbreadth,waistdepth,hipbreadth,buttockdepth");
        for seed in 0..crate::fit::FitOptions::default().library_size as u64 {
            let body = library.body(&ShapeLibrary::sample_adult(seed));
            let Ok(m) = crate::measure::measure(&body) else {
                continue;
            };
            let l = &m.levels;
            let at = |y| crate::fit::shape::trunk_extents(&body.positions, &edges, &labels, y);
            let (Some(c), Some(w), Some(h)) = (at(l.chest_m), at(l.waist_m), at(l.hip_m)) else {
                continue;
            };
            let stature = body.positions.iter().map(|p| p.y).fold(f64::MIN, f64::max);
            let mm = |v: f64| format!("{:.1}", v * 1000.0);
            println!(
                "LIBRARY_CSV {},{},{},{},{},{},{}",
                mm(stature),
                mm(c.0),
                mm(c.1),
                mm(w.0),
                mm(w.1),
                mm(h.0),
                mm(h.1)
            );
        }
    }

    #[test]
    fn the_floor_point_of_a_projected_toe_is_found_again() {
        let calib = StationCalibration::nominal(720, 1280, 1100.0, 3.3, 1.0, 0.9);
        let cam = &calib.front;
        let toe = DVec3::new(0.02, 0.0, 0.09);
        let px = cam.project(toe).expect("in view");
        let (w, h) = (720u32, 1280u32);
        let mut data = vec![0u8; (w * h) as usize];
        // A blob whose lower edge is the toe's row.
        let (x0, y0) = (px.x.round() as i64, (px.y - 0.5).round() as i64);
        for y in y0 - 40..=y0 {
            for x in x0 - 10..=x0 + 10 {
                data[(y as u32 * w + x as u32) as usize] = 255;
            }
        }
        let found = toes_on_floor(
            cam,
            MaskRef {
                width: w,
                height: h,
                data: &data,
            },
        )
        .expect("feet");
        assert!((found - toe).length() < 0.01, "{found:?} against {toe:?}");
        // Moving a point along its own ray: back on the plane it came from.
        let p = DVec3::new(0.0, 1.7, -0.1);
        let c = cam.center_in_station();
        let t = (0.0 - c.z) / (p.z - c.z);
        let on_plane = c + (p - c) * t;
        assert!((height_at_depth(cam, on_plane.y, 0.0, p.z) - p.y).abs() < 1e-9);
    }
}
