//! A test phantom: an articulated body of capsules and ellipsoids in an A-pose, a small
//! ray-casting renderer that films it through a station camera over a textured wall and
//! floor (with a shadow at the feet, sensor noise and exposure flicker), and exact ground
//! truth for the landmark heights. For tests and benches until the synthetic renderer
//! (`synth`) is integrated; not used by the station itself.
//!
//! # Conventions
//! Station frame, metres (+Y up, +Z toward the front camera, +X the subject's left),
//! soles on y = 0, the subject facing +Z. Every limb and trunk primitive has its axis or
//! centre in the plane z = `offset.z`, so the orthographic front silhouette is the
//! section of the body by that plane: the ground truth below is computed on it.

use crate::camera::Camera;
use crate::imgproc::{Mask, PointUndistorter};
use glam::{DVec2, DVec3};
use image::RgbImage;

/// Body colours (sRGB).
const SKIN: [f64; 3] = [212.0, 168.0, 142.0];
const SHIRT: [f64; 3] = [62.0, 104.0, 172.0];
const TROUSERS: [f64; 3] = [58.0, 72.0, 118.0];
const SHOES: [f64; 3] = [150.0, 64.0, 44.0];
const WALL: [f64; 3] = [168.0, 170.0, 156.0];
const FLOOR: [f64; 3] = [128.0, 116.0, 104.0];
/// Wall distance behind the mark, metres.
const WALL_DISTANCE_M: f64 = 1.3;
/// Shadow on the floor around the feet: half-extents (x, z) and darkening.
const SHADOW_HALF_X_M: f64 = 0.38;
const SHADOW_HALF_Z_M: f64 = 0.32;
const SHADOW_FACTOR: f64 = 0.55;
/// A limb segment's axis, from one joint to the next.
pub type AxisSegment = (DVec3, DVec3);

/// Limb capsules per side in `Phantom::new` (upper arm, forearm, hand, thigh, shank, foot).
const PRIMS_PER_SIDE: usize = 6;
/// Supersampling grid per pixel on the silhouette's edge.
const EDGE_SAMPLES: usize = 4;

/// A primitive of the phantom.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Shape {
    Capsule { a: DVec3, b: DVec3, r: f64 },
    Ellipsoid { c: DVec3, radii: DVec3 },
}

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Primitive {
    pub shape: Shape,
    pub color: [f64; 3],
    bound_c: DVec3,
    bound_r: f64,
}

impl Primitive {
    fn new(shape: Shape, color: [f64; 3]) -> Self {
        let (bound_c, bound_r) = match shape {
            Shape::Capsule { a, b, r } => ((a + b) * 0.5, a.distance(b) * 0.5 + r),
            Shape::Ellipsoid { c, radii } => (c, radii.max_element()),
        };
        Primitive {
            shape,
            color,
            bound_c,
            bound_r,
        }
    }

    /// True when the point is inside.
    pub fn contains(&self, p: DVec3) -> bool {
        match self.shape {
            Shape::Capsule { a, b, r } => {
                let e = b - a;
                let t = ((p - a).dot(e) / e.length_squared()).clamp(0.0, 1.0);
                (a + e * t).distance_squared(p) <= r * r
            }
            Shape::Ellipsoid { c, radii } => ((p - c) / radii).length_squared() <= 1.0,
        }
    }

    /// Distance along the ray (unit `d`) to the primitive if it is hit.
    fn hit(&self, o: DVec3, d: DVec3) -> Option<f64> {
        // Bounding sphere first.
        let w = self.bound_c - o;
        let tc = w.dot(d);
        if w.length_squared() - tc * tc > self.bound_r * self.bound_r {
            return None;
        }
        match self.shape {
            Shape::Capsule { a, b, r } => {
                let e = b - a;
                let w = o - a;
                let (bb, cc, dd, ee) = (d.dot(e), e.dot(e), d.dot(w), e.dot(w));
                let denom = cc - bb * bb;
                let s = if denom > 1e-12 {
                    ((ee - bb * dd) / denom).clamp(0.0, 1.0)
                } else {
                    0.0
                };
                let t = s * bb - dd;
                let q = a + e * s;
                let dist2 = (o + d * t).distance_squared(q);
                (dist2 <= r * r && t > 0.0).then(|| t - (r * r - dist2).sqrt())
            }
            Shape::Ellipsoid { c, radii } => {
                let (o2, d2) = ((o - c) / radii, d / radii);
                let (qa, qb, qc) = (d2.dot(d2), 2.0 * o2.dot(d2), o2.dot(o2) - 1.0);
                let disc = qb * qb - 4.0 * qa * qc;
                (disc >= 0.0)
                    .then(|| (-qb - disc.sqrt()) / (2.0 * qa))
                    .filter(|&t| t > 0.0)
            }
        }
    }
}

/// Pose and placement of the phantom.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PhantomParams {
    /// Arm angle from the vertical, degrees (0 = hanging against the body).
    pub arm_abduction_deg: f64,
    /// Half the distance between the ankles minus the hip joints' half-distance (0 =
    /// straight legs; negative closes them).
    pub leg_spread_m: f64,
    /// Half the distance between the hip joints.
    pub hip_half_m: f64,
    /// Where the mark-centred body stands (x, z; y is ignored).
    pub offset: DVec3,
    /// Uniform scale about the floor point under the body.
    pub scale: f64,
}

impl Default for PhantomParams {
    fn default() -> Self {
        PhantomParams {
            arm_abduction_deg: 32.0,
            leg_spread_m: 0.06,
            hip_half_m: 0.092,
            offset: DVec3::ZERO,
            scale: 1.0,
        }
    }
}

/// The phantom's landmarks by definition, on its orthographic front silhouette.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PhantomTruth {
    pub stature: f64,
    pub crotch: Option<DVec2>,
    pub armpit_left: Option<DVec2>,
    pub armpit_right: Option<DVec2>,
    pub acromion_left: DVec2,
    pub acromion_right: DVec2,
}

/// An articulated body of primitives.
#[derive(Debug, Clone, PartialEq)]
pub struct Phantom {
    pub params: PhantomParams,
    pub prims: Vec<Primitive>,
}

impl Phantom {
    pub fn new(params: PhantomParams) -> Self {
        let s = params.scale;
        let o = DVec3::new(params.offset.x, 0.0, params.offset.z);
        let at = |x: f64, y: f64, z: f64| o + DVec3::new(x, y, z) * s;
        let mut prims = Vec::new();
        let mut cap = |a: DVec3, b: DVec3, r: f64, c: [f64; 3]| {
            prims.push(Primitive::new(Shape::Capsule { a, b, r: r * s }, c))
        };
        // Trunk and head.
        cap(at(0.0, 1.45, 0.0), at(0.0, 1.57, 0.0), 0.055, SKIN);
        cap(at(-0.17, 1.42, 0.0), at(0.17, 1.42, 0.0), 0.055, SHIRT);
        // Limbs.
        let th = params.arm_abduction_deg.to_radians();
        for side in [-1.0f64, 1.0] {
            let sh = at(side * 0.19, 1.40, 0.0);
            let dir = DVec3::new(side * th.sin(), -th.cos(), 0.0);
            let el = sh + dir * 0.30 * s;
            let wr = el + dir * 0.26 * s;
            cap(sh, el, 0.047, SHIRT);
            cap(el, wr, 0.038, SKIN);
            cap(wr, wr + dir * 0.11 * s, 0.036, SKIN);
            let hx = side * params.hip_half_m;
            let ax = side * (params.hip_half_m + params.leg_spread_m);
            let kn = at(0.5 * (hx + ax), 0.48, 0.0);
            cap(at(hx, 0.86, 0.0), kn, 0.076, TROUSERS);
            cap(kn, at(ax, 0.10, 0.0), 0.052, TROUSERS);
            cap(
                at(ax, 0.04, -0.05),
                at(ax + side * 0.02, 0.04, 0.15),
                0.04,
                SHOES,
            );
        }
        let mut ell = |c: DVec3, r: DVec3, col: [f64; 3]| {
            prims.push(Primitive::new(Shape::Ellipsoid { c, radii: r * s }, col))
        };
        ell(at(0.0, 1.625, 0.0), DVec3::new(0.078, 0.105, 0.095), SKIN);
        ell(at(0.0, 1.27, 0.0), DVec3::new(0.165, 0.23, 0.11), SHIRT);
        ell(at(0.0, 0.99, 0.0), DVec3::new(0.17, 0.2, 0.12), TROUSERS);
        Phantom { params, prims }
    }

    pub fn contains(&self, p: DVec3) -> bool {
        self.prims.iter().any(|q| q.contains(p))
    }

    /// Axis segments of one side's arm (upper arm, forearm, hand) and leg (thigh, shank);
    /// `side` is +1 for the subject's left, -1 for the right.
    pub fn limb_axes(&self, side: f64) -> (Vec<AxisSegment>, Vec<AxisSegment>) {
        // Layout of `new`: neck, shoulders, then six limb capsules per side (right first).
        let base = 2 + if side > 0.0 { PRIMS_PER_SIDE } else { 0 };
        let axis = |k: usize| match self.prims.get(base + k).map(|p| p.shape) {
            Some(Shape::Capsule { a, b, .. }) => Some((a, b)),
            _ => None,
        };
        let arm = [0, 1, 2].iter().filter_map(|&k| axis(k)).collect();
        let leg = [3, 4].iter().filter_map(|&k| axis(k)).collect();
        (arm, leg)
    }

    /// The middle of both feet's heel-to-toe extent (z): where the subject stands, which
    /// the station compares with the mark.
    pub fn feet_centre_z(&self) -> Option<f64> {
        let (mut lo, mut hi) = (f64::MAX, f64::MIN);
        for side in [0, PRIMS_PER_SIDE] {
            // The sixth limb capsule of each side is the foot (layout of `new`).
            if let Some(Shape::Capsule { a, b, r }) = self.prims.get(2 + side + 5).map(|p| p.shape)
            {
                lo = lo.min(a.z.min(b.z) - r);
                hi = hi.max(a.z.max(b.z) + r);
            }
        }
        (hi >= lo).then_some(0.5 * (lo + hi))
    }

    /// Height of the head top.
    pub fn stature(&self) -> f64 {
        (1.625 + 0.105) * self.params.scale
    }

    fn inside_front(&self, x: f64, y: f64) -> bool {
        self.contains(DVec3::new(x, y, self.params.offset.z))
    }

    /// Ground truth of the landmarks on the orthographic front silhouette (the section
    /// z = offset.z), by the same definitions the station uses (method.md section 1).
    pub fn truth(&self) -> PhantomTruth {
        let ox = self.params.offset.x;
        let stature = self.stature();
        let h = stature / 7.0;
        let yc = stature / 2.0;
        // Crotch: the lowest body point on the centre line above the legs' gap.
        let crotch = if self.inside_front(ox, 0.3 * stature) {
            None
        } else {
            let (mut lo, mut hi) = (0.3 * stature, 0.7 * stature);
            if !self.inside_front(ox, hi) {
                None
            } else {
                for _ in 0..50 {
                    let m = 0.5 * (lo + hi);
                    if self.inside_front(ox, m) {
                        hi = m;
                    } else {
                        lo = m;
                    }
                }
                Some(DVec2::new(ox, hi))
            }
        };
        // Armpits: the highest line where the torso and the arm are apart.
        let armpit = |side: f64| -> Option<DVec2> {
            let gap_at = |y: f64| -> Option<f64> {
                let step = 0.0005;
                let mut state = 0; // 0 torso, 1 gap, 2 arm
                let mut gap_start = 0.0;
                let mut x = 0.0;
                while x < 0.7 {
                    let inside = self.inside_front(ox + side * x, y);
                    match (state, inside) {
                        (0, false) => {
                            state = 1;
                            gap_start = x;
                        }
                        (1, true) => return Some(ox + side * 0.5 * (gap_start + x)),
                        _ => {}
                    }
                    x += step;
                }
                None
            };
            let mut y = yc + 2.0 * h;
            let mut found = None;
            while y > yc {
                if let Some(x) = gap_at(y) {
                    found = Some((y, x));
                    break;
                }
                y -= 0.002;
            }
            let (mut lo, mut hi) = (found?.0, found?.0 + 0.002);
            let mut x = found?.1;
            for _ in 0..20 {
                let m = 0.5 * (lo + hi);
                match gap_at(m) {
                    Some(gx) => {
                        lo = m;
                        x = gx;
                    }
                    None => hi = m,
                }
            }
            Some(DVec2::new(x, lo))
        };
        // Acromions: the silhouette point closest to g = (crotch.x +- 0.8h, crotch.y +
        // 2.45h) (the definition of `body::prepare` and of the station), else to
        // (+-0.8h, 2.5h) from the centre.
        let acromion = |side: f64| -> DVec2 {
            use crate::body::prepare::{ACROMION_G_X_H, ACROMION_G_Y_H};
            let g = match crotch {
                Some(c) => DVec2::new(c.x + side * ACROMION_G_X_H * h, c.y + ACROMION_G_Y_H * h),
                None => DVec2::new(ox + side * 0.8 * h, yc + 2.5 * h),
            };
            let g_in = self.inside_front(g.x, g.y);
            let mut best = (f64::INFINITY, g);
            for k in 0..1440 {
                let a = k as f64 / 1440.0 * std::f64::consts::TAU;
                let dir = DVec2::new(a.cos(), a.sin());
                let mut r = 0.0;
                while r < best.0.min(0.2) {
                    let p = g + dir * r;
                    if self.inside_front(p.x, p.y) != g_in {
                        best = (r, p);
                        break;
                    }
                    r += 0.0002;
                }
            }
            best.1
        };
        PhantomTruth {
            stature,
            crotch,
            armpit_left: armpit(1.0),
            armpit_right: armpit(-1.0),
            acromion_left: acromion(1.0),
            acromion_right: acromion(-1.0),
        }
    }
}

/// Lighting, noise and exposure of one rendered frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SceneParams {
    /// Sensor noise, standard deviation per channel (8-bit units).
    pub noise_sigma: f64,
    /// Global exposure gain (flicker, under/over exposure).
    pub gain: f64,
    /// Shadow on the floor around the feet (only with a person).
    pub shadow: bool,
    /// Noise seed.
    pub seed: u64,
    /// A plain studio backdrop (one colour, no texture, wall and floor alike) instead of
    /// the textured wall and floor: the paper's still-image case.
    pub plain_backdrop: bool,
}

impl Default for SceneParams {
    fn default() -> Self {
        SceneParams {
            noise_sigma: 3.0,
            gain: 1.0,
            shadow: true,
            seed: 1,
            plain_backdrop: false,
        }
    }
}

#[inline]
fn hash(mut x: u64) -> u64 {
    x ^= x >> 33;
    x = x.wrapping_mul(0xff51afd7ed558ccd);
    x ^= x >> 33;
    x = x.wrapping_mul(0xc4ceb9fe1a85ec53);
    x ^ (x >> 33)
}

/// Smooth value noise in [-1, 1] on a 2-D lattice of spacing 1.
fn value_noise(p: DVec2, seed: u64) -> f64 {
    let (x0, y0) = (p.x.floor(), p.y.floor());
    let (fx, fy) = (p.x - x0, p.y - y0);
    let (sx, sy) = (fx * fx * (3.0 - 2.0 * fx), fy * fy * (3.0 - 2.0 * fy));
    let v = |i: f64, j: f64| -> f64 {
        let k = hash(
            ((i as i64 as u64).wrapping_mul(73856093))
                ^ ((j as i64 as u64).wrapping_mul(19349663))
                ^ seed,
        );
        (k >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
    };
    let a = v(x0, y0) + sx * (v(x0 + 1.0, y0) - v(x0, y0));
    let b = v(x0, y0 + 1.0) + sx * (v(x0 + 1.0, y0 + 1.0) - v(x0, y0 + 1.0));
    a + sy * (b - a)
}

/// Texture of the backdrop: a few octaves of value noise.
fn texture(p: DVec2) -> f64 {
    0.5 * value_noise(p * 12.0, 1) + 0.3 * value_noise(p * 31.0, 2) + 0.2 * value_noise(p * 83.0, 3)
}

/// Films phantoms through one camera.
#[derive(Debug, Clone)]
pub struct Renderer {
    pub camera: Camera,
    undistort: PointUndistorter,
    /// Unit ray directions through the pixel centres, row-major.
    rays: Vec<DVec3>,
}

impl Renderer {
    pub fn new(camera: Camera) -> Self {
        let i = camera.intrinsics;
        let undistort = PointUndistorter::new(i);
        let mut r = Renderer {
            camera,
            undistort,
            rays: Vec::new(),
        };
        r.rays = (0..i.height)
            .flat_map(|v| (0..i.width).map(move |u| DVec2::new(u as f64, v as f64)))
            .map(|p| r.ray(p))
            .collect();
        r
    }

    fn ray(&self, px: DVec2) -> DVec3 {
        let n = self.undistort.normalized(px);
        let rt = self.camera.camera_from_station.rotation.transpose();
        (rt * DVec3::new(n.x, n.y, 1.0)).normalize()
    }

    /// Colour of the backdrop (wall or floor) along a ray, before gain and noise.
    fn backdrop(
        &self,
        o: DVec3,
        d: DVec3,
        people: &[Phantom],
        shadow: bool,
        plain: bool,
    ) -> [f64; 3] {
        if plain {
            return WALL;
        }
        let axis = self.camera.axis_in_station();
        let horiz = DVec3::new(axis.x, 0.0, axis.z).normalize_or_zero();
        let wall_point = horiz * WALL_DISTANCE_M;
        let dn = d.dot(horiz);
        let t_wall = if dn > 1e-9 {
            (wall_point - o).dot(horiz) / dn
        } else {
            f64::INFINITY
        };
        let t_floor = if d.y < -1e-9 {
            -o.y / d.y
        } else {
            f64::INFINITY
        };
        if t_floor < t_wall {
            let p = o + d * t_floor;
            let mut c = FLOOR.map(|v| v * (1.0 + 0.12 * texture(DVec2::new(p.x, p.z))));
            if shadow {
                for ph in people {
                    let q = (DVec2::new(p.x, p.z)
                        - DVec2::new(ph.params.offset.x, ph.params.offset.z))
                        / DVec2::new(SHADOW_HALF_X_M, SHADOW_HALF_Z_M);
                    let r = q.length();
                    // Soft-edged shadow: full inside 0.6, fading out by 1.
                    let k = ((1.0 - r) / 0.4).clamp(0.0, 1.0);
                    let f = 1.0 - (1.0 - SHADOW_FACTOR) * k;
                    c = c.map(|v| v * f);
                }
            }
            c
        } else if t_wall.is_finite() {
            let p = o + d * t_wall;
            let side = horiz.cross(DVec3::Y);
            let uv = DVec2::new(p.dot(side), p.y);
            // A gentle vertical light gradient and texture.
            let g = 1.0 - 0.08 * (p.y - 1.0);
            WALL.map(|v| v * g * (1.0 + 0.10 * texture(uv)))
        } else {
            WALL
        }
    }

    /// The nearest body hit along a ray: (distance, colour).
    fn body(&self, o: DVec3, d: DVec3, people: &[Phantom]) -> Option<(f64, [f64; 3])> {
        let mut best: Option<(f64, [f64; 3])> = None;
        for ph in people {
            for q in &ph.prims {
                if let Some(t) = q.hit(o, d) {
                    if best.is_none_or(|b| t < b.0) {
                        let p = o + d * t;
                        let tex = 1.0 + 0.05 * value_noise(DVec2::new(p.x + p.z, p.y) * 40.0, 7);
                        best = Some((t, q.color.map(|v| v * tex)));
                    }
                }
            }
        }
        best
    }

    /// Renders a frame and the ground-truth mask (pixel centre inside a body).
    // Index arithmetic over several arrays reads better with indices.
    #[allow(clippy::needless_range_loop)]
    pub fn render(&self, people: &[Phantom], scene: &SceneParams) -> (RgbImage, Mask) {
        let i = self.camera.intrinsics;
        let (w, h) = (i.width as usize, i.height as usize);
        let o = self.camera.center_in_station();
        let shadow = scene.shadow && !people.is_empty();
        let mut hit = vec![false; w * h];
        let mut color = vec![[0f64; 3]; w * h];
        for k in 0..w * h {
            let d = self.rays[k];
            match self.body(o, d, people) {
                Some((_, c)) => {
                    hit[k] = true;
                    color[k] = c;
                }
                None => color[k] = self.backdrop(o, d, people, shadow, scene.plain_backdrop),
            }
        }
        // Anti-aliasing on the silhouette's edge.
        let mut img = RgbImage::new(i.width, i.height);
        let mut mask = Mask::new(i.width, i.height);
        for y in 0..h {
            for x in 0..w {
                let k = y * w + x;
                mask.data[k] = if hit[k] { 255 } else { 0 };
                let edge = (x > 0 && hit[k - 1] != hit[k])
                    || (x + 1 < w && hit[k + 1] != hit[k])
                    || (y > 0 && hit[k - w] != hit[k])
                    || (y + 1 < h && hit[k + w] != hit[k]);
                let mut c = color[k];
                if edge {
                    let mut acc = [0f64; 3];
                    let n = EDGE_SAMPLES;
                    for sy in 0..n {
                        for sx in 0..n {
                            let px = DVec2::new(
                                x as f64 + (sx as f64 + 0.5) / n as f64 - 0.5,
                                y as f64 + (sy as f64 + 0.5) / n as f64 - 0.5,
                            );
                            let d = self.ray(px);
                            let s = match self.body(o, d, people) {
                                Some((_, c)) => c,
                                None => self.backdrop(o, d, people, shadow, scene.plain_backdrop),
                            };
                            for ch in 0..3 {
                                acc[ch] += s[ch] / (n * n) as f64;
                            }
                        }
                    }
                    c = acc;
                }
                let flick = scene.gain;
                let px = img.get_pixel_mut(x as u32, y as u32);
                for ch in 0..3 {
                    let r = hash(
                        scene.seed.wrapping_mul(0x9E3779B97F4A7C15) ^ (k as u64 * 3 + ch as u64),
                    );
                    // Approximately Gaussian: sum of four uniforms (variance 4/12).
                    let u: f64 = (0..4)
                        .map(|j| ((r >> (16 * j)) & 0xffff) as f64 / 65535.0 - 0.5)
                        .sum();
                    let noise = u * scene.noise_sigma * (3.0f64).sqrt();
                    px.0[ch] = (c[ch] * flick + noise).round().clamp(0.0, 255.0) as u8;
                }
            }
        }
        (img, mask)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn phantom_truth_is_plausible() {
        let p = Phantom::new(PhantomParams::default());
        let t = p.truth();
        let c = t.crotch.unwrap();
        assert!(c.y > 0.7 && c.y < 0.85, "{c}");
        let a = t.armpit_left.unwrap();
        assert!(a.y > 1.25 && a.y < 1.45 && a.x > 0.1, "{a}");
        let ar = t.armpit_right.unwrap();
        assert!((a.y - ar.y).abs() < 1e-3 && (a.x + ar.x).abs() < 1e-3);
        assert!(
            t.acromion_left.y > 1.4 && t.acromion_left.x > 0.1,
            "{}",
            t.acromion_left
        );
        let together = Phantom::new(PhantomParams {
            leg_spread_m: 0.0,
            hip_half_m: 0.06,
            ..Default::default()
        });
        assert!(together.truth().crotch.is_none());
    }
}
