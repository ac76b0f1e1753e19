//! The synthetic station scene: a room with two fabric backdrops and a textured floor,
//! lights near the cameras and over the mark, soft floor shadows of the subject, a
//! shaded body in tight clothing, and the camera's film (optics blur, vignetting, white
//! balance, exposure flicker, gamma and sensor noise).
//!
//! # Conventions
//! - Station frame, metres: +Y up, +Z toward the front camera, +X the subject's left,
//!   origin on the floor at the mark. The room is the box
//!   `x in [side_x, FAR_M], y in [0, ceiling], z in [back_z, FAR_M]`; the backdrop of
//!   the front camera is the wall `z = back_z`, that of the side camera `x = side_x`.
//! - Radiance is linear, relative (1.0 is a white surface under the nominal light);
//!   frames are 8-bit sRGB-like after the film model.
//! - Floor shadows live on a grid of [`SHADOW_CELL_M`] cells around the mark.

use super::raster::Rasterizer;
use super::rng::{fbm2, value_noise3, SplitMix64};
use crate::camera::Camera;
use glam::{DVec2, DVec3};

pub use super::film::Film;

/// Distance of the far walls (behind the cameras) from the mark, metres.
pub const FAR_M: f64 = 5.0;
/// Half size of the floor shadow grid, metres.
pub const SHADOW_HALF_M: f64 = 1.4;
/// Cell of the floor shadow grid, metres.
pub const SHADOW_CELL_M: f64 = 0.01;
/// Penumbra blur of cast shadows (box-blur radius, cells, applied twice).
pub const PENUMBRA_CELLS: usize = 3;
/// Blur of the contact (ambient occlusion) shadow under the feet, cells.
pub const CONTACT_CELLS: usize = 4;
/// Body parts lower than this cast the dark contact shadow, metres.
pub const CONTACT_HEIGHT_M: f64 = 0.10;
/// Reference distance of the light falloff, metres.
pub const LIGHT_REF_M: f64 = 3.0;
/// Maximum number of lights.
pub const MAX_LIGHTS: usize = 4;

/// A point light (diffuse only), intensity relative at [`LIGHT_REF_M`].
#[derive(Debug, Clone, Copy)]
pub struct Light {
    pub position: DVec3,
    pub intensity: f32,
}

/// Materials and colours of one scene (linear RGB albedos).
#[derive(Debug, Clone)]
pub struct Look {
    pub backdrop: [f32; 3],
    pub backdrop_fold_m: f64,
    pub backdrop_fold_depth: f32,
    pub floor: [f32; 3],
    pub walls: [f32; 3],
    pub mark: [f32; 3],
    pub shirt: [f32; 3],
    pub leggings: [f32; 3],
    pub skin: [f32; 3],
    pub hair: [f32; 3],
    pub shoes: [f32; 3],
    pub pattern_seed: u64,
}

/// The room, its lights and its look.
#[derive(Debug, Clone)]
pub struct Scene {
    /// z of the front camera's backdrop (negative), metres.
    pub back_z: f64,
    /// x of the side camera's backdrop (negative), metres.
    pub side_x: f64,
    pub ceiling: f64,
    pub lights: Vec<Light>,
    pub ambient: f32,
    pub look: Look,
}

fn srgb_to_linear(c: [u8; 3]) -> [f32; 3] {
    c.map(|v| (v as f32 / 255.0).powf(2.2))
}

/// The 8-bit level of a linear albedo (inverse of `srgb_to_linear`).
fn linear_to_srgb(c: [f32; 3]) -> [f32; 3] {
    c.map(|v| 255.0 * v.max(0.0).powf(1.0 / 2.2))
}

/// How the subject's clothing colours are chosen.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Clothing {
    /// From the lists of shirts and leggings, by the seed.
    #[default]
    Drawn,
    /// Shirt and leggings in the backdrop's colour, [`CAMOUFLAGE_MIN_LEVELS`] to
    /// [`CAMOUFLAGE_MAX_LEVELS`] 8-bit levels off ([`Look::camouflage`]).
    Camouflage,
}

/// Distance of camouflage clothing from the backdrop's colour (8-bit levels, Euclidean
/// over R, G, B).
pub const CAMOUFLAGE_MIN_LEVELS: f64 = 15.0;
pub const CAMOUFLAGE_MAX_LEVELS: f64 = 40.0;

const BACKDROPS: [[u8; 3]; 7] = [
    [200, 200, 196],
    [120, 170, 120],
    [70, 140, 80],
    [150, 155, 165],
    [210, 205, 190],
    [90, 110, 150],
    [60, 60, 64],
];
const FLOORS: [[u8; 3]; 5] = [
    [120, 118, 112],
    [150, 130, 100],
    [90, 92, 96],
    [170, 165, 155],
    [110, 85, 60],
];
const SHIRTS: [[u8; 3]; 9] = [
    [30, 30, 34],
    [200, 40, 40],
    [40, 70, 150],
    [230, 230, 225],
    [60, 120, 70],
    [140, 140, 150],
    [90, 40, 110],
    [210, 160, 50],
    [200, 200, 196],
];
const LEGGINGS: [[u8; 3]; 6] = [
    [25, 25, 30],
    [40, 45, 70],
    [70, 70, 75],
    [90, 60, 50],
    [120, 120, 125],
    [30, 60, 40],
];
const SKINS: [[u8; 3]; 6] = [
    [240, 200, 170],
    [225, 180, 145],
    [200, 150, 110],
    [160, 110, 75],
    [120, 80, 55],
    [90, 60, 40],
];
const HAIRS: [[u8; 3]; 4] = [[30, 22, 18], [90, 60, 35], [180, 150, 100], [120, 120, 115]];
const SHOES: [[u8; 3]; 3] = [[20, 20, 20], [230, 230, 230], [60, 50, 45]];

fn pick<const N: usize>(rng: &mut SplitMix64, list: &[[u8; 3]; N]) -> [f32; 3] {
    let i = (rng.uniform() * N as f64) as usize;
    srgb_to_linear(list[i.min(N - 1)])
}

impl Look {
    /// Dresses the subject in the backdrop's colour: shirt and leggings each a random
    /// direction and a distance of [`CAMOUFLAGE_MIN_LEVELS`]..[`CAMOUFLAGE_MAX_LEVELS`]
    /// 8-bit levels from the backdrop (turned back where a channel would leave 0..255).
    pub fn camouflage(&mut self, rng: &mut SplitMix64) {
        let base = linear_to_srgb(self.backdrop);
        self.shirt = camouflage_colour(base, rng);
        self.leggings = camouflage_colour(base, rng);
    }

    /// Another person's clothes, skin and hair, drawn from `rng` (a passer-by's look in
    /// the subject's room).
    pub fn redress(&mut self, rng: &mut SplitMix64) {
        self.shirt = pick(rng, &SHIRTS);
        self.leggings = pick(rng, &LEGGINGS);
        self.skin = pick(rng, &SKINS);
        self.hair = pick(rng, &HAIRS);
        self.shoes = pick(rng, &SHOES);
        self.pattern_seed = rng.next_u64();
    }
}

/// A colour `CAMOUFLAGE_MIN_LEVELS..CAMOUFLAGE_MAX_LEVELS` levels from `base` (8-bit
/// levels) in a random direction, as a linear albedo.
fn camouflage_colour(base: [f32; 3], rng: &mut SplitMix64) -> [f32; 3] {
    let dist = rng.range(CAMOUFLAGE_MIN_LEVELS, CAMOUFLAGE_MAX_LEVELS) as f32;
    let mut dir = [
        rng.normal() as f32,
        rng.normal() as f32,
        rng.normal() as f32,
    ];
    let n = (dir[0] * dir[0] + dir[1] * dir[1] + dir[2] * dir[2])
        .sqrt()
        .max(1e-6);
    dir = dir.map(|d| d / n);
    // A channel that would leave the range turns back (the distance is kept).
    for (d, b) in dir.iter_mut().zip(base) {
        if !(0.0..=255.0).contains(&(b + dist * *d)) {
            *d = -*d;
        }
    }
    let level: [u8; 3] =
        std::array::from_fn(|k| (base[k] + dist * dir[k]).round().clamp(0.0, 255.0) as u8);
    srgb_to_linear(level)
}

impl Scene {
    /// A scene drawn from `rng`: backdrop distances, colours, lights. `cameras` are the
    /// station cameras (lights hang above them, as on a kiosk).
    pub fn random(rng: &mut SplitMix64, cameras: [&Camera; 2]) -> Scene {
        let back_z = -rng.range(0.8, 1.5);
        let side_x = -rng.range(0.8, 1.5);
        let mut lights = Vec::with_capacity(MAX_LIGHTS);
        for cam in cameras {
            let c = cam.center_in_station();
            let sideways = DVec3::new(-c.z, 0.0, c.x).normalize_or_zero() * rng.range(-0.4, 0.4);
            lights.push(Light {
                position: c + DVec3::new(0.0, rng.range(0.4, 0.9), 0.0) + sideways,
                intensity: rng.range(0.35, 0.55) as f32,
            });
        }
        lights.push(Light {
            position: DVec3::new(rng.range(-0.3, 0.3), 2.6, rng.range(-0.2, 0.6)),
            intensity: rng.range(0.15, 0.3) as f32,
        });
        let look = Look {
            backdrop: pick(rng, &BACKDROPS),
            backdrop_fold_m: rng.range(0.2, 0.5),
            backdrop_fold_depth: rng.range(0.02, 0.08) as f32,
            floor: pick(rng, &FLOORS),
            walls: srgb_to_linear([200, 198, 192]),
            mark: srgb_to_linear(if rng.chance(0.5) {
                [220, 180, 40]
            } else {
                [230, 230, 230]
            }),
            shirt: pick(rng, &SHIRTS),
            leggings: pick(rng, &LEGGINGS),
            skin: pick(rng, &SKINS),
            hair: pick(rng, &HAIRS),
            shoes: pick(rng, &SHOES),
            pattern_seed: rng.next_u64(),
        };
        Scene {
            back_z,
            side_x,
            ceiling: 2.7,
            lights,
            ambient: rng.range(0.25, 0.35) as f32,
            look,
        }
    }

    /// Diffuse irradiance at `p` with normal `n` (unit), per light (unshadowed) and
    /// ambient (hemispherical: surfaces facing up see more sky).
    pub fn irradiance(&self, p: DVec3, n: DVec3) -> Irradiance {
        let mut lights = [0.0f32; MAX_LIGHTS];
        for (k, l) in self.lights.iter().enumerate().take(MAX_LIGHTS) {
            let d = l.position - p;
            let d2 = d.length_squared().max(1e-6);
            let cos = (n.dot(d) / d2.sqrt()).max(0.0);
            lights[k] = l.intensity * (cos * LIGHT_REF_M * LIGHT_REF_M / d2) as f32;
        }
        let ambient = self.ambient * (0.75 + 0.25 * n.y as f32);
        Irradiance { ambient, lights }
    }

    /// Where a viewing ray leaves the room: the surface, point and its normal.
    pub fn trace(&self, origin: DVec3, dir: DVec3) -> Option<(Surface, DVec3, DVec3)> {
        let planes = [
            (Surface::Floor, 1usize, 0.0, DVec3::Y),
            (Surface::Ceiling, 1, self.ceiling, -DVec3::Y),
            (Surface::BackBackdrop, 2, self.back_z, DVec3::Z),
            (Surface::Wall, 2, FAR_M, -DVec3::Z),
            (Surface::SideBackdrop, 0, self.side_x, DVec3::X),
            (Surface::Wall, 0, FAR_M, -DVec3::X),
        ];
        let mut best: Option<(f64, Surface, DVec3)> = None;
        for (s, axis, value, normal) in planes {
            let d = dir[axis];
            if d.abs() < 1e-12 || d * normal[axis] >= 0.0 {
                continue; // parallel, or leaving through the back of the plane
            }
            let t = (value - origin[axis]) / d;
            if t > 0.0 && best.is_none_or(|b| t < b.0) {
                best = Some((t, s, normal));
            }
        }
        best.map(|(t, s, n)| (s, origin + dir * t, n))
    }

    /// Albedo of a room surface at `p`.
    pub fn albedo(&self, s: Surface, p: DVec3) -> [f32; 3] {
        let look = &self.look;
        let seed = look.pattern_seed;
        match s {
            Surface::BackBackdrop | Surface::SideBackdrop => {
                // Fabric: vertical folds, slow blotches and a fine weave.
                let across = if s == Surface::BackBackdrop { p.x } else { p.z };
                let phase = fbm2(across * 0.7, p.y * 0.3, 2, seed) as f64 * 6.0;
                let fold =
                    (std::f64::consts::TAU * across / look.backdrop_fold_m + phase).sin() as f32;
                let blotch = fbm2(across * 2.0, p.y * 2.0, 3, seed ^ 11) - 0.5;
                let weave = value_noise3(across * 400.0, p.y * 400.0, 0.0, seed ^ 7) - 0.5;
                let k = 1.0 + look.backdrop_fold_depth * fold + 0.12 * blotch + 0.06 * weave;
                look.backdrop.map(|c| c * k)
            }
            Surface::Floor => {
                let base = look.floor;
                // Carpet tiles of 0.5 m with slightly different tone, fine fibre noise.
                let tile = ((p.x / 0.5).floor() as i64, (p.z / 0.5).floor() as i64);
                let tone = super::rng::hash3(tile.0, tile.1, 3, seed) - 0.5;
                let fibre = value_noise3(p.x * 300.0, p.z * 300.0, 1.0, seed) - 0.5;
                let blot = fbm2(p.x * 3.0, p.z * 3.0, 3, seed ^ 5) - 0.5;
                let k = 1.0 + 0.06 * tone + 0.15 * fibre + 0.1 * blot;
                // The standing mark: a tape cross 0.3 m wide with 5 cm arms.
                let on_mark = (p.x.abs() < 0.15 && p.z.abs() < 0.025)
                    || (p.z.abs() < 0.15 && p.x.abs() < 0.025);
                if on_mark {
                    look.mark
                } else {
                    base.map(|c| c * k)
                }
            }
            Surface::Ceiling | Surface::Wall => {
                let k = 1.0 + 0.05 * (fbm2(p.x + p.z, p.y, 2, seed ^ 3) - 0.5);
                look.walls.map(|c| c * k)
            }
        }
    }
}

/// A room surface.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Surface {
    Floor,
    Ceiling,
    BackBackdrop,
    SideBackdrop,
    Wall,
}

/// Irradiance split into ambient and per-light parts (so floor shadows can dim each).
#[derive(Debug, Clone, Copy)]
pub struct Irradiance {
    pub ambient: f32,
    pub lights: [f32; MAX_LIGHTS],
}

impl Irradiance {
    pub fn total(&self) -> f32 {
        self.ambient + self.lights.iter().sum::<f32>()
    }
}

/// One floor pixel kept for re-lighting under the subject's shadow.
#[derive(Debug, Clone, Copy)]
struct FloorPixel {
    index: u32,
    cell: u32,
    albedo: [f32; 3],
    irradiance: Irradiance,
}

/// Floor shadows of the subject: per-light cast shadow and a contact shadow, each a
/// blurred coverage grid in [0, 1] over the square of half size [`SHADOW_HALF_M`].
#[derive(Debug, Clone)]
pub struct FloorShadows {
    n: usize,
    cast: Vec<Vec<f32>>,
    contact: Vec<f32>,
}

impl FloorShadows {
    fn cells() -> usize {
        (2.0 * SHADOW_HALF_M / SHADOW_CELL_M).round() as usize
    }

    /// Index of the cell holding floor point (x, z), if on the grid.
    pub fn cell(x: f64, z: f64) -> Option<usize> {
        let n = Self::cells();
        let i = ((x + SHADOW_HALF_M) / SHADOW_CELL_M).floor();
        let j = ((z + SHADOW_HALF_M) / SHADOW_CELL_M).floor();
        if i < 0.0 || j < 0.0 || i >= n as f64 || j >= n as f64 {
            return None;
        }
        Some(j as usize * n + i as usize)
    }

    /// Shadows of `positions`/`triangles` (station frame) under the scene's lights: each
    /// triangle projected from the light onto the floor (planar projection), filled, and
    /// blurred into a penumbra; the contact shadow is the vertical projection of the
    /// parts lower than [`CONTACT_HEIGHT_M`] (feet), blurred more.
    pub fn compute(scene: &Scene, positions: &[DVec3], triangles: &[[u32; 3]]) -> FloorShadows {
        let n = Self::cells();
        let mut cast = Vec::with_capacity(scene.lights.len());
        for l in scene.lights.iter().take(MAX_LIGHTS) {
            let mut grid = vec![0.0f32; n * n];
            let to_floor = |p: DVec3| -> Option<DVec2> {
                let h = l.position.y - p.y;
                if h <= 1e-3 {
                    return None;
                }
                let s = l.position.y / h;
                let q = l.position + (p - l.position) * s;
                Some(DVec2::new(q.x, q.z))
            };
            for t in triangles {
                let (Some(a), Some(b), Some(c)) = (
                    positions.get(t[0] as usize).and_then(|p| to_floor(*p)),
                    positions.get(t[1] as usize).and_then(|p| to_floor(*p)),
                    positions.get(t[2] as usize).and_then(|p| to_floor(*p)),
                ) else {
                    continue;
                };
                fill_grid(&mut grid, n, [a, b, c], 1.0);
            }
            blur(&mut grid, n, PENUMBRA_CELLS);
            cast.push(grid);
        }
        let mut contact = vec![0.0f32; n * n];
        for t in triangles {
            let Some(ps) = t
                .iter()
                .map(|&i| positions.get(i as usize).copied())
                .collect::<Option<Vec<DVec3>>>()
            else {
                continue;
            };
            if ps.iter().all(|p| p.y < CONTACT_HEIGHT_M) {
                let v = ps.iter().map(|p| DVec2::new(p.x, p.z)).collect::<Vec<_>>();
                fill_grid(&mut contact, n, [v[0], v[1], v[2]], 1.0);
            }
        }
        blur(&mut contact, n, CONTACT_CELLS);
        blur(&mut contact, n, CONTACT_CELLS);
        FloorShadows { n, cast, contact }
    }
}

/// Fills a floor triangle (x, z) into the grid with `value` (max).
fn fill_grid(grid: &mut [f32], n: usize, t: [DVec2; 3], value: f32) {
    let to_cell = |p: DVec2| (p + DVec2::splat(SHADOW_HALF_M)) / SHADOW_CELL_M - DVec2::splat(0.5);
    let [a, b, c] = t.map(to_cell);
    let area = (b - a).perp_dot(c - a);
    if area.abs() < 1e-12 {
        return;
    }
    let x0 = a.x.min(b.x).min(c.x).ceil().max(0.0) as i64;
    let x1 = (a.x.max(b.x).max(c.x).floor() as i64).min(n as i64 - 1);
    let y0 = a.y.min(b.y).min(c.y).ceil().max(0.0) as i64;
    let y1 = (a.y.max(b.y).max(c.y).floor() as i64).min(n as i64 - 1);
    for y in y0..=y1 {
        for x in x0..=x1 {
            let p = DVec2::new(x as f64, y as f64);
            let l0 = (b - p).perp_dot(c - p) / area;
            let l1 = (c - p).perp_dot(a - p) / area;
            if l0 >= 0.0 && l1 >= 0.0 && l0 + l1 <= 1.0 {
                let i = y as usize * n + x as usize;
                grid[i] = grid[i].max(value);
            }
        }
    }
}

/// Two passes of a separable box blur of radius `r` cells.
fn blur(grid: &mut [f32], n: usize, r: usize) {
    let mut tmp = vec![0.0f32; grid.len()];
    for _ in 0..2 {
        box_pass(grid, &mut tmp, n, r, true);
        box_pass(&tmp, grid, n, r, false);
    }
}

fn box_pass(src: &[f32], dst: &mut [f32], n: usize, r: usize, horizontal: bool) {
    let w = (2 * r + 1) as f32;
    for a in 0..n {
        for b in 0..n {
            let lo = b.saturating_sub(r);
            let hi = (b + r).min(n - 1);
            let mut s = 0.0;
            for k in lo..=hi {
                s += if horizontal {
                    src[a * n + k]
                } else {
                    src[k * n + a]
                };
            }
            if horizontal {
                dst[a * n + b] = s / w;
            } else {
                dst[b * n + a] = s / w;
            }
        }
    }
}

/// Grid step of the exactly undistorted pixel grid, pixels.
pub const RAY_GRID_PX: u32 = 4;

/// Undistorted normalised coordinates of a camera's pixels: exact
/// ([`crate::camera::Intrinsics::undistort_pixel`]) at every [`RAY_GRID_PX`]-th pixel,
/// bilinearly interpolated in between.
pub struct RayGrid {
    nodes: Vec<DVec2>,
    cols: usize,
}

impl RayGrid {
    pub fn new(camera: &Camera) -> RayGrid {
        let (w, h) = (camera.intrinsics.width, camera.intrinsics.height);
        let cols = (w.saturating_sub(1) / RAY_GRID_PX + 2) as usize;
        let rows = (h.saturating_sub(1) / RAY_GRID_PX + 2) as usize;
        let mut nodes = Vec::with_capacity(cols * rows);
        for r in 0..rows {
            for c in 0..cols {
                let px = DVec2::new(
                    (c as u32 * RAY_GRID_PX) as f64,
                    (r as u32 * RAY_GRID_PX) as f64,
                );
                nodes.push(camera.intrinsics.undistort_pixel(px));
            }
        }
        RayGrid { nodes, cols }
    }

    /// Undistorted normalised coordinates of pixel (x, y).
    #[inline]
    pub fn normalized(&self, x: u32, y: u32) -> DVec2 {
        let (c, r) = ((x / RAY_GRID_PX) as usize, (y / RAY_GRID_PX) as usize);
        let (fx, fy) = (
            (x % RAY_GRID_PX) as f64 / RAY_GRID_PX as f64,
            (y % RAY_GRID_PX) as f64 / RAY_GRID_PX as f64,
        );
        let at = |cc: usize, rr: usize| self.nodes[(rr * self.cols + cc).min(self.nodes.len() - 1)];
        let top = at(c, r).lerp(at(c + 1, r), fx);
        let bottom = at(c, r + 1).lerp(at(c + 1, r + 1), fx);
        top.lerp(bottom, fy)
    }
}

/// The static background of one camera: the empty room's radiance per pixel, and the
/// floor pixels needed to re-light it under the subject's shadows.
#[derive(Debug, Clone)]
pub struct Background {
    pub width: u32,
    pub height: u32,
    /// Linear radiance, row-major.
    pub empty: Vec<[f32; 3]>,
    floor: Vec<FloorPixel>,
}

impl Background {
    /// Ray casts every pixel of `camera` through the exact inverse of its lens model.
    pub fn render(scene: &Scene, camera: &Camera) -> Background {
        let (w, h) = (camera.intrinsics.width, camera.intrinsics.height);
        let mut empty = vec![[0.0f32; 3]; w as usize * h as usize];
        let mut floor = Vec::new();
        // Exact inverse lens model at grid nodes every RAY_GRID_PX pixels, bilinear in
        // between (the inverse distortion is smooth: the interpolation error is below
        // 5e-3 px for the station's lenses, see the test below).
        let rays = RayGrid::new(camera);
        let origin = camera.center_in_station();
        let rt = camera.camera_from_station.rotation.transpose();
        for y in 0..h {
            for x in 0..w {
                let i = (y * w + x) as usize;
                let n = rays.normalized(x, y);
                let dir = (rt * DVec3::new(n.x, n.y, 1.0)).normalize();
                let Some((s, p, n)) = scene.trace(origin, dir) else {
                    continue;
                };
                let albedo = scene.albedo(s, p);
                let irr = scene.irradiance(p, n);
                let e = irr.total();
                empty[i] = albedo.map(|a| a * e);
                if s == Surface::Floor {
                    if let Some(cell) = FloorShadows::cell(p.x, p.z) {
                        floor.push(FloorPixel {
                            index: i as u32,
                            cell: cell as u32,
                            albedo,
                            irradiance: irr,
                        });
                    }
                }
            }
        }
        Background {
            width: w,
            height: h,
            empty,
            floor,
        }
    }

    /// The background with the subject's floor shadows, into `out` (resized).
    pub fn with_shadows(&self, shadows: &FloorShadows, out: &mut Vec<[f32; 3]>) {
        out.clear();
        out.extend_from_slice(&self.empty);
        for f in &self.floor {
            let c = f.cell as usize;
            if c >= shadows.n * shadows.n {
                continue;
            }
            let ao = 1.0 - 0.75 * shadows.contact[c];
            let mut e = f.irradiance.ambient * ao;
            for (k, l) in f.irradiance.lights.iter().enumerate() {
                let sh = shadows.cast.get(k).map_or(0.0, |g| g[c]);
                e += l * (1.0 - 0.85 * sh) * (0.5 + 0.5 * ao);
            }
            out[f.index as usize] = f.albedo.map(|a| a * e);
        }
    }
}

/// What a body surface point is dressed in.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Material {
    Skin,
    Shirt,
    Leggings,
    Hair,
    Shoes,
}

/// The bones a body is dressed by (canonical frame, metres): torso axis, legs and
/// arms as joint chains, from the body's skeleton (`crate::body::prepare`, method.md
/// section 1 step 7).
#[derive(Debug, Clone)]
pub struct Skeleton {
    /// Hip joint to neck joint.
    pub torso: [DVec3; 2],
    /// Thigh root, knee, ankle (left, right).
    pub legs: [[DVec3; 3]; 2],
    /// Shoulder, elbow, wrist, hand (left, right).
    pub arms: [[DVec3; 4]; 2],
    /// Height below which the head and neck end (the neck cut).
    pub neck_cut_y: f64,
    pub crotch_y: f64,
    pub armpit_y: f64,
}

impl Skeleton {
    /// The skeleton of a prepared template body.
    pub fn from_template(info: &crate::body::TemplateInfo) -> Skeleton {
        let j = &info.joints;
        let l = &info.landmarks;
        Skeleton {
            torso: [j.hip, j.neck],
            legs: [
                [j.thigh_root_left, j.knee_left, j.ankle_left],
                [j.thigh_root_right, j.knee_right, j.ankle_right],
            ],
            arms: [
                [j.shoulder_left, j.elbow_left, j.wrist_left, j.hand_left],
                [j.shoulder_right, j.elbow_right, j.wrist_right, j.hand_right],
            ],
            neck_cut_y: l.neck_cut_y,
            crotch_y: l.crotch_y,
            armpit_y: l.armpit_y,
        }
    }
}

/// Distance from `p` to segment [a, b] and the segment parameter of the closest point.
fn segment_distance(p: DVec3, a: DVec3, b: DVec3) -> (f64, f64) {
    let ab = b - a;
    let t = ((p - a).dot(ab) / ab.length_squared().max(1e-12)).clamp(0.0, 1.0);
    ((a + ab * t - p).length(), t)
}

/// Which part of the body a point belongs to.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BodyPart {
    Head,
    Torso,
    Leg,
    /// `upper` = on the upper arm (shoulder to elbow) within `sleeve` of its length.
    Arm {
        sleeve: bool,
    },
}

/// Fraction of the upper arm a short sleeve covers.
const SLEEVE_OF_UPPER_ARM: f64 = 0.45;
/// The top ends this fraction of the crotch-armpit span above the crotch.
const HEM_OF_SPAN: f64 = 0.25;

/// How a body is dressed: each surface point goes to its nearest bone.
#[derive(Debug, Clone)]
pub struct Dress {
    pub stature_m: f64,
    pub head_centre_z: f64,
    pub skeleton: Skeleton,
}

impl Dress {
    pub fn new(mesh: &crate::mesh::TriMesh, skeleton: Skeleton) -> Dress {
        let (h, head_centre_z) = match mesh.bounds() {
            Some(b) => {
                let h = b.size().y;
                let top: Vec<f64> = mesh
                    .positions
                    .iter()
                    .filter(|p| p.y > 0.9 * h)
                    .map(|p| p.z)
                    .collect();
                (h, top.iter().sum::<f64>() / top.len().max(1) as f64)
            }
            None => (1.0, 0.0),
        };
        Dress {
            stature_m: h,
            head_centre_z,
            skeleton,
        }
    }

    /// The body part of canonical point `p`: above the neck cut the head, else the bone
    /// (torso axis, leg or arm chain) nearest to it.
    pub fn part(&self, p: DVec3) -> BodyPart {
        let sk = &self.skeleton;
        if p.y > sk.neck_cut_y {
            return BodyPart::Head;
        }
        let mut best = (
            segment_distance(p, sk.torso[0], sk.torso[1]).0,
            BodyPart::Torso,
        );
        for leg in &sk.legs {
            for w in leg.windows(2) {
                let d = segment_distance(p, w[0], w[1]).0;
                if d < best.0 {
                    best = (d, BodyPart::Leg);
                }
            }
        }
        for arm in &sk.arms {
            for (k, w) in arm.windows(2).enumerate() {
                let (d, t) = segment_distance(p, w[0], w[1]);
                if d < best.0 {
                    best = (
                        d,
                        BodyPart::Arm {
                            sleeve: k == 0 && t < SLEEVE_OF_UPPER_ARM,
                        },
                    );
                }
            }
        }
        best.1
    }

    /// The material at canonical point `p`: a short-sleeved top down to the hips,
    /// full-length leggings, shoes, hair on the crown, skin elsewhere.
    pub fn material(&self, p: DVec3) -> Material {
        let sk = &self.skeleton;
        let h = self.stature_m;
        let hem_y = sk.crotch_y + HEM_OF_SPAN * (sk.armpit_y - sk.crotch_y);
        match self.part(p) {
            BodyPart::Head => {
                if p.y > 0.935 * h && p.z < self.head_centre_z + 0.03 {
                    Material::Hair
                } else {
                    Material::Skin
                }
            }
            BodyPart::Arm { sleeve: true } => Material::Shirt,
            BodyPart::Arm { sleeve: false } => Material::Skin,
            BodyPart::Torso if p.y > hem_y => Material::Shirt,
            BodyPart::Torso | BodyPart::Leg if p.y < 0.035 * h => Material::Shoes,
            BodyPart::Torso | BodyPart::Leg => Material::Leggings,
        }
    }
}

/// Shades a body pixel: albedo of its material with a knit texture, diffuse light.
pub fn shade_body(
    scene: &Scene,
    dress: &Dress,
    canonical: DVec3,
    posed: DVec3,
    normal: DVec3,
) -> [f32; 3] {
    let look = &scene.look;
    let seed = look.pattern_seed;
    let m = dress.material(canonical);
    let (albedo, texture) = match m {
        Material::Skin => (look.skin, 0.03),
        Material::Shirt => (look.shirt, 0.10),
        Material::Leggings => (look.leggings, 0.08),
        Material::Hair => (look.hair, 0.25),
        Material::Shoes => (look.shoes, 0.05),
    };
    let fine = value_noise3(
        canonical.x * 500.0,
        canonical.y * 500.0,
        canonical.z * 500.0,
        seed ^ 99,
    ) - 0.5;
    let wrinkle = value_noise3(
        canonical.x * 25.0,
        canonical.y * 12.0,
        canonical.z * 25.0,
        seed ^ 77,
    ) - 0.5;
    let k = 1.0 + texture * fine + 0.5 * texture * wrinkle;
    let e = scene.irradiance(posed, normal).total();
    albedo.map(|a| a * k * e)
}

/// The body as drawn in one frame: station positions this frame, the undressed
/// canonical positions (same order, for materials), posed unit normals, triangles.
#[derive(Debug, Clone, Copy)]
pub struct BodyFrame<'a> {
    pub posed: &'a [DVec3],
    pub canonical: &'a [DVec3],
    pub normals: &'a [DVec3],
    pub triangles: &'a [[u32; 3]],
}

/// Renders the body into `radiance` over the background already there.
pub fn draw_body(
    scene: &Scene,
    dress: &Dress,
    camera: &Camera,
    raster: &mut Rasterizer,
    body: &BodyFrame<'_>,
    radiance: &mut [[f32; 3]],
) {
    raster.clear();
    raster.draw_mesh(camera, body.posed, body.triangles);
    for (i, px) in radiance.iter_mut().enumerate() {
        let Some(hit) = raster.hit_index(i) else {
            continue;
        };
        let Some(t) = body.triangles.get(hit.triangle as usize) else {
            continue;
        };
        let b = hit.bary.map(|v| v as f64);
        let interp = |arr: &[DVec3]| {
            arr[t[0] as usize] * b[0] + arr[t[1] as usize] * b[1] + arr[t[2] as usize] * b[2]
        };
        let p = interp(body.posed);
        let c = interp(body.canonical);
        let n = interp(body.normals).normalize_or_zero();
        *px = shade_body(scene, dress, c, p, n);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::StationCalibration;

    #[test]
    fn ray_grid_matches_exact_undistortion() {
        for dist in [
            [-0.18, 0.12, 0.0015, -0.0015, 0.02],
            [0.06, -0.05, -0.001, 0.001, -0.02],
        ] {
            let mut c = StationCalibration::nominal(1280, 720, 900.0, 3.0, 1.2, 1.0).front;
            c.intrinsics.dist = dist;
            let g = RayGrid::new(&c);
            let mut worst = 0.0f64;
            for y in (0..720).step_by(3) {
                for x in (0..1280).step_by(5) {
                    let n = g.normalized(x, y);
                    let back = c.intrinsics.to_pixel(c.intrinsics.distort(n));
                    worst = worst.max((back - DVec2::new(x as f64, y as f64)).length());
                }
            }
            assert!(
                worst < 5e-3,
                "interpolated rays miss their pixel by {worst} px"
            );
        }
    }
}
