//! Lifting front-view landmarks to the station frame with perspective rays (replacing the
//! paper's orthographic assumption, method.md section 5).
//!
//! A landmark seen at front pixel p_f lies on the front ray r_f(t). Start on the plane
//! z = 0; at the current point's height y, the side contour's axis (the paper's step 1:
//! midpoint of the front-most and back-most side contour points at that height) gives
//! z_side(y), computed on the plane x = the point's x; the new point is r_f cut by the
//! plane z = z_side(y). Two or three rounds settle both views.
//!
//! The side contour on the plane x = x0 is the side contour on x = 0 scaled about the
//! side camera's centre (central projection between parallel planes is a homothety),
//! so one table of the side axis on x = 0 serves every x0.

use super::graze::GrazeProfile;
use super::zones;
use crate::camera::Camera;
use glam::{DVec2, DVec3};

/// Which station axis a view plane is normal to.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PlaneAxis {
    /// Plane z = c; coordinates (X, Y). The front view's.
    Z,
    /// Plane x = c; coordinates (Z, Y). The side view's.
    X,
}

/// The ray of a camera through undistorted normalised coordinates `n`, cut by the plane
/// `axis = value`; returns the plane coordinates (see [`PlaneAxis`]).
#[inline]
pub fn to_plane(cam: &Camera, n: DVec2, axis: PlaneAxis, value: f64) -> DVec2 {
    let p = ray_plane(cam, n, axis, value);
    match axis {
        PlaneAxis::Z => DVec2::new(p.x, p.y),
        PlaneAxis::X => DVec2::new(p.z, p.y),
    }
}

/// The station point where the ray through `n` meets the plane `axis = value` (far along
/// the ray when parallel).
#[inline]
pub fn ray_plane(cam: &Camera, n: DVec2, axis: PlaneAxis, value: f64) -> DVec3 {
    let rt = cam.camera_from_station.rotation.transpose();
    let c = cam.center_in_station();
    let d = rt * DVec3::new(n.x, n.y, 1.0);
    let (cc, dd) = match axis {
        PlaneAxis::Z => (c.z, d.z),
        PlaneAxis::X => (c.x, d.x),
    };
    let t = if dd.abs() > 1e-12 {
        (value - cc) / dd
    } else {
        1e6
    };
    c + d * t
}

/// How far beyond the side contour's height range the axis is continued, metres.
const AXIS_CLAMP_M: f64 = 0.05;
/// Height step of the side-axis table, metres.
const AXIS_TABLE_STEP_M: f64 = 0.004;

/// The side contour's axis (midpoint of its widest inside interval at each height, the
/// paper's step 1 made robust to a hand held in front of the body) on the plane x = 0,
/// tabulated by height, plus the homothety to other planes x = x0.
#[derive(Debug, Clone, Default)]
pub struct SideAxis {
    v0: f64,
    min_u: Vec<f64>,
    max_u: Vec<f64>,
    /// Side camera centre (x, y, z).
    center: DVec3,
}

impl SideAxis {
    /// Tabulates the axis of a side plane contour ((Z, Y) on x = 0).
    pub fn new(plane: &[DVec2], side: &Camera) -> Self {
        let mut s = SideAxis {
            center: side.center_in_station(),
            ..Default::default()
        };
        let n = plane.len();
        if n < 3 {
            return s;
        }
        let (lo, hi) = plane
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), p| {
                (lo.min(p.y), hi.max(p.y))
            });
        s.v0 = lo;
        let rows = ((hi - lo) / AXIS_TABLE_STEP_M) as usize + 1;
        // Crossings of every table row (half-open rule), then per row the widest inside
        // interval: the trunk (or leg), not a hand held in front of it.
        let mut cross: Vec<(usize, f64)> = Vec::new();
        for i in 0..n {
            let (a, b) = (plane[i], plane[(i + 1) % n]);
            let (ya, yb) = (a.y.min(b.y), a.y.max(b.y));
            let mut k = ((ya - lo) / AXIS_TABLE_STEP_M).ceil().max(0.0) as usize;
            while k < rows {
                let v = lo + k as f64 * AXIS_TABLE_STEP_M;
                if v > yb {
                    break;
                }
                if (a.y <= v) != (b.y <= v) {
                    cross.push((k, a.x + (v - a.y) / (b.y - a.y) * (b.x - a.x)));
                }
                k += 1;
            }
        }
        cross.sort_by(|p, q| p.0.cmp(&q.0).then(p.1.total_cmp(&q.1)));
        s.min_u = vec![f64::INFINITY; rows];
        s.max_u = vec![f64::NEG_INFINITY; rows];
        let mut j = 0;
        while j < cross.len() {
            let k = cross[j].0;
            let mut e = j;
            while e < cross.len() && cross[e].0 == k {
                e += 1;
            }
            let row = &cross[j..e];
            let widest = row
                .chunks_exact(2)
                .max_by(|p, q| (p[1].1 - p[0].1).total_cmp(&(q[1].1 - q[0].1)));
            if let Some(w) = widest {
                s.min_u[k] = w[0].1;
                s.max_u[k] = w[1].1;
            }
            j = e;
        }
        s
    }

    fn row_axis(&self, k: usize) -> Option<f64> {
        let (a, b) = (*self.min_u.get(k)?, *self.max_u.get(k)?);
        (a <= b).then_some(0.5 * (a + b))
    }

    /// The axis z at height `y` on the plane x = 0.
    pub fn at(&self, y: f64) -> Option<f64> {
        if self.min_u.is_empty() {
            return None;
        }
        // Slightly above the side contour's top (the front view's head top is seen on a
        // rim a little higher) or below its bottom: the nearest row with an axis.
        let reach = AXIS_CLAMP_M / AXIS_TABLE_STEP_M;
        let last = (self.min_u.len() - 1) as f64;
        let f = (y - self.v0) / AXIS_TABLE_STEP_M;
        if f < -reach || f > last + reach {
            return None;
        }
        if f <= 0.0 || f >= last {
            let range: Box<dyn Iterator<Item = usize>> = if f <= 0.0 {
                Box::new(0..self.min_u.len())
            } else {
                Box::new((0..self.min_u.len()).rev())
            };
            return range
                .take(reach.ceil() as usize + 1)
                .find_map(|k| self.row_axis(k));
        }
        let k = f.floor() as usize;
        let t = f - k as f64;
        match (self.row_axis(k), self.row_axis(k + 1)) {
            (Some(a), Some(b)) => Some(a + t * (b - a)),
            (Some(a), None) => Some(a),
            (None, Some(b)) => Some(b),
            _ => None,
        }
    }

    /// The axis z at height `y` on the plane x = `x0`.
    pub fn at_plane(&self, y: f64, x0: f64) -> Option<f64> {
        let c = self.center;
        if c.x.abs() < 1e-9 {
            return self.at(y);
        }
        // Points on x = x0 are those on x = 0 scaled about the centre by k.
        let k = (c.x - x0) / c.x;
        if k <= 1e-6 {
            return None;
        }
        let y0 = c.y + (y - c.y) / k;
        self.at(y0).map(|z0| c.z + (z0 - c.z) * k)
    }
}

/// Lifts a front ray (normalised coordinates `n`) into the station frame.
pub fn lift_front_ray(front: &Camera, n: DVec2, axis: &SideAxis, iterations: usize) -> DVec3 {
    let mut z = 0.0;
    let mut p = ray_plane(front, n, PlaneAxis::Z, z);
    for _ in 0..iterations {
        match axis.at_plane(p.y, p.x) {
            Some(zs) => z = zs,
            None => break,
        }
        p = ray_plane(front, n, PlaneAxis::Z, z);
    }
    p
}

/// The height of the landmark whose grazing ray from `camera` was lifted to `p`: the ray
/// crosses the landmark's depth off the landmark by the template section's offset for
/// the ray's slope ([`GrazeProfile`]), scaled to a body of stature `size`. `along_x`:
/// the slope is taken along X (side camera), else along Z (front camera). Unchanged
/// without a size or when the camera is at the landmark's depth.
pub fn grazed_height(
    camera: &Camera,
    p: DVec3,
    along_x: bool,
    profile: &GrazeProfile,
    size: f64,
) -> f64 {
    let c = camera.center_in_station();
    let d = if along_x { c.x - p.x } else { c.z - p.z };
    if size <= 0.0 || d.abs() < 1e-6 {
        return p.y;
    }
    p.y - profile.apparent_offset((c.y - p.y) / d, size)
}

/// The normalised front ray through the meeting point of the flanks of the gap whose
/// traced apex is contour point `apex` ([`zones::wedge_apex`]), with the pixel's size on
/// the front plane z = 0 taken at the apex.
pub fn wedge_point(front: &Camera, plane: &[DVec2], apex: usize) -> Option<DVec2> {
    let top = *plane.get(apex)?;
    let n = plane_point_to_normalized(front, top)?;
    let fx = front.intrinsics.fx;
    if fx.is_nan() || fx <= 0.0 {
        return None;
    }
    let px = (to_plane(front, n + DVec2::new(1.0 / fx, 0.0), PlaneAxis::Z, 0.0) - top).length();
    let p = zones::wedge_apex(plane, apex, px)?;
    plane_point_to_normalized(front, p)
}

/// The feet's band above the floor, in units of stature (about 5 cm on an adult).
const FOOT_BAND_REL: f64 = 0.03;
/// Shortest heel-to-toe extent taken as feet (metres): less is a cut-off or lost foot.
const MIN_FOOT_LENGTH_M: f64 = 0.12;

/// The middle of the feet's heel-to-toe extent (z) in the side contour's plane (Z, Y),
/// from the contour points within [`FOOT_BAND_REL`] of the floor. None without a stature
/// or when the extent is shorter than a foot.
pub fn feet_centre_z(side_plane: &[DVec2], stature: f64) -> Option<f64> {
    if stature <= 0.0 {
        return None;
    }
    let band = FOOT_BAND_REL * stature;
    let (lo, hi) = side_plane
        .iter()
        .filter(|p| p.y < band)
        .fold((f64::MAX, f64::MIN), |(lo, hi), p| {
            (lo.min(p.x), hi.max(p.x))
        });
    (hi - lo >= MIN_FOOT_LENGTH_M).then_some(0.5 * (lo + hi))
}

/// Normalised coordinates of the front ray through a point of the front plane z = 0.
pub fn plane_point_to_normalized(front: &Camera, p: DVec2) -> Option<DVec2> {
    let c = front.camera_from_station.apply(DVec3::new(p.x, p.y, 0.0));
    (c.z > 1e-9).then(|| DVec2::new(c.x / c.z, c.y / c.z))
}
