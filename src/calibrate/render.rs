//! A chessboard renderer with known truth, for tests and for rehearsing the operator
//! procedure without a station.
//!
//! For every output pixel, `supersample x supersample` sub-pixel samples are traced:
//! distorted pixel -> undistorted normalised coordinates (OpenCV model, inverted once
//! per pixel corner and interpolated inside the pixel) -> viewing ray -> intersection
//! with the board plane -> black or white square, white sheet margin, or the background
//! (a light-grey wall, and a darker floor when the station frame is known). The averaged
//! image is then blurred mildly (Gaussian, sigma in pixels) and gets Gaussian noise (grey
//! levels) from a seeded generator, so renders are reproducible.
//!
//! Conventions: pixel centres at integer (u, v) as OpenCV; camera frame x right, y down,
//! z forward; board frame as in [`super::board`]; station frame metres, +Y up.

use super::board::BoardSpec;
use crate::camera::{Intrinsics, Rigid};
use glam::{DVec2, DVec3};

/// Grey levels of the rendered scene (0-255).
pub const BLACK_LEVEL: f64 = 35.0;
pub const WHITE_LEVEL: f64 = 215.0;
pub const WALL_LEVEL: f64 = 175.0;
pub const FLOOR_LEVEL: f64 = 135.0;

/// What lies behind the board.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Background {
    /// A uniform wall.
    Wall,
    /// The station: the floor (station Y = 0) in a darker grey, walls elsewhere.
    /// Holds the camera pose in the station frame.
    Station { camera_from_station: Rigid },
}

/// Render settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RenderOptions {
    /// Samples per pixel along each axis.
    pub supersample: u32,
    /// Gaussian blur after sampling, pixels (0 = none).
    pub blur_sigma_px: f64,
    /// Gaussian noise, grey levels (0 = none).
    pub noise_sigma: f64,
    /// White margin of the printed sheet beyond the outer squares, in squares.
    pub margin_squares: f64,
    /// Seed of the noise generator.
    pub seed: u64,
}

impl Default for RenderOptions {
    fn default() -> Self {
        RenderOptions {
            supersample: 4,
            blur_sigma_px: 0.6,
            noise_sigma: 2.0,
            margin_squares: 0.6,
            seed: 1,
        }
    }
}

/// Renders boards seen by one camera; keeps the undistortion lattice between renders.
pub struct BoardRenderer {
    intrinsics: Intrinsics,
    /// Undistorted normalised coordinates at pixel corners, `(w + 1) x (h + 1)`.
    lattice: Vec<DVec2>,
    accum: Vec<f64>,
    tmp: Vec<f64>,
}

impl BoardRenderer {
    pub fn new(intrinsics: Intrinsics) -> Self {
        let (w, h) = (intrinsics.width as usize, intrinsics.height as usize);
        let mut lattice = Vec::with_capacity((w + 1) * (h + 1));
        for j in 0..=h {
            for i in 0..=w {
                lattice
                    .push(intrinsics.undistort_pixel(DVec2::new(i as f64 - 0.5, j as f64 - 0.5)));
            }
        }
        BoardRenderer {
            intrinsics,
            lattice,
            accum: vec![0.0; w * h],
            tmp: vec![0.0; w * h],
        }
    }

    pub fn intrinsics(&self) -> &Intrinsics {
        &self.intrinsics
    }

    /// Renders `board` posed at `camera_from_board` in front of `background`.
    pub fn render(
        &mut self,
        board: &BoardSpec,
        camera_from_board: &Rigid,
        background: Background,
        opts: &RenderOptions,
    ) -> image::GrayImage {
        let (w, h) = (
            self.intrinsics.width as usize,
            self.intrinsics.height as usize,
        );
        let board_from_camera = camera_from_board.inverse();
        let origin_b = board_from_camera.translation;
        let rot_b = board_from_camera.rotation;
        let station = match background {
            Background::Station {
                camera_from_station,
            } => Some(camera_from_station.inverse()),
            Background::Wall => None,
        };
        let s = opts.supersample.max(1) as usize;
        let inv = 1.0 / s as f64;
        let weight = 1.0 / (s * s) as f64;
        for j in 0..h {
            for i in 0..w {
                let c00 = self.lattice[j * (w + 1) + i];
                let c10 = self.lattice[j * (w + 1) + i + 1];
                let c01 = self.lattice[(j + 1) * (w + 1) + i];
                let c11 = self.lattice[(j + 1) * (w + 1) + i + 1];
                let mut sum = 0.0;
                for sy in 0..s {
                    let fy = (sy as f64 + 0.5) * inv;
                    for sx in 0..s {
                        let fx = (sx as f64 + 0.5) * inv;
                        let n = c00 * ((1.0 - fx) * (1.0 - fy))
                            + c10 * (fx * (1.0 - fy))
                            + c01 * ((1.0 - fx) * fy)
                            + c11 * (fx * fy);
                        let dir_cam = DVec3::new(n.x, n.y, 1.0);
                        sum += self.shade(
                            board,
                            opts.margin_squares,
                            origin_b,
                            rot_b * dir_cam,
                            station.as_ref(),
                            dir_cam,
                        );
                    }
                }
                self.accum[j * w + i] = sum * weight;
            }
        }
        if opts.blur_sigma_px > 0.0 {
            gaussian_blur(&mut self.accum, &mut self.tmp, w, h, opts.blur_sigma_px);
        }
        let mut rng = SplitMix64(opts.seed);
        let mut out = image::GrayImage::new(w as u32, h as u32);
        for (px, v) in out.pixels_mut().zip(&self.accum) {
            let noisy = v + opts.noise_sigma * rng.gaussian();
            px.0[0] = noisy.round().clamp(0.0, 255.0) as u8;
        }
        out
    }

    fn shade(
        &self,
        board: &BoardSpec,
        margin: f64,
        origin_b: DVec3,
        dir_b: DVec3,
        station: Option<&Rigid>,
        dir_cam: DVec3,
    ) -> f64 {
        // Board plane z = 0 in the board frame.
        let mut board_t = f64::INFINITY;
        if dir_b.z.abs() > 1e-12 {
            let t = -origin_b.z / dir_b.z;
            if t > 0.0 {
                let p = origin_b + dir_b * t;
                if board.on_sheet(p.x, p.y, margin) {
                    board_t = t;
                }
            }
        }
        let mut floor_t = f64::INFINITY;
        if let Some(station_from_camera) = station {
            let o = station_from_camera.translation;
            let d = station_from_camera.rotation * dir_cam;
            if d.y < -1e-12 {
                floor_t = -o.y / d.y;
            }
        }
        if board_t < floor_t {
            let p = origin_b + dir_b * board_t;
            if board.is_black(p.x, p.y) {
                BLACK_LEVEL
            } else {
                WHITE_LEVEL
            }
        } else if floor_t.is_finite() {
            FLOOR_LEVEL
        } else {
            WALL_LEVEL
        }
    }
}

/// Separable Gaussian blur of a `w x h` float image in place (`tmp` is scratch).
pub fn gaussian_blur(img: &mut [f64], tmp: &mut [f64], w: usize, h: usize, sigma: f64) {
    let radius = (3.0 * sigma).ceil() as isize;
    let kernel: Vec<f64> = (-radius..=radius)
        .map(|k| (-(k * k) as f64 / (2.0 * sigma * sigma)).exp())
        .collect();
    let norm: f64 = kernel.iter().sum();
    let kernel: Vec<f64> = kernel.iter().map(|k| k / norm).collect();
    for y in 0..h {
        for x in 0..w {
            let mut s = 0.0;
            for (k, kv) in kernel.iter().enumerate() {
                let xx = (x as isize + k as isize - radius).clamp(0, w as isize - 1) as usize;
                s += kv * img[y * w + xx];
            }
            tmp[y * w + x] = s;
        }
    }
    for y in 0..h {
        for x in 0..w {
            let mut s = 0.0;
            for (k, kv) in kernel.iter().enumerate() {
                let yy = (y as isize + k as isize - radius).clamp(0, h as isize - 1) as usize;
                s += kv * tmp[yy * w + x];
            }
            img[y * w + x] = s;
        }
    }
}

/// SplitMix64 generator with Box-Muller normals (reproducible test noise).
pub struct SplitMix64(pub u64);

impl SplitMix64 {
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    /// Uniform in (0, 1).
    pub fn uniform(&mut self) -> f64 {
        ((self.next_u64() >> 11) as f64 + 0.5) / (1u64 << 53) as f64
    }
    /// Standard normal.
    pub fn gaussian(&mut self) -> f64 {
        let (u1, u2) = (self.uniform(), self.uniform());
        (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
    }
}

/// Projects the board's inner corners (OpenCV order) through the camera: the true
/// corner positions of a render.
pub fn true_corners(
    intrinsics: &Intrinsics,
    board: &BoardSpec,
    camera_from_board: &Rigid,
) -> Vec<Option<DVec2>> {
    board
        .object_points()
        .iter()
        .map(|p| intrinsics.project_camera_point(camera_from_board.apply(*p)))
        .collect()
}

/// A few station-like test rigs.
pub mod rigs {
    use super::*;
    use crate::camera::{Camera, StationCalibration};

    /// Landscape 1280x720 lens with mild barrel distortion (front camera of the tests).
    pub fn front_intrinsics() -> Intrinsics {
        Intrinsics {
            width: 1280,
            height: 720,
            fx: 1010.0,
            fy: 1008.0,
            cx: 645.0,
            cy: 356.0,
            dist: [-0.11, 0.09, 0.0008, -0.0005, -0.02],
        }
    }

    /// Portrait 720x1280 lens (side camera of the tests).
    pub fn side_intrinsics() -> Intrinsics {
        Intrinsics {
            width: 720,
            height: 1280,
            fx: 1050.0,
            fy: 1052.0,
            cx: 362.0,
            cy: 636.0,
            dist: [-0.09, 0.06, -0.0004, 0.0006, -0.01],
        }
    }

    /// Both cameras at station-like places: front ~3 m on +Z at 1.25 m, side ~3 m on +X
    /// at 1.05 m, both slightly off-axis and aimed near the middle of the standing volume.
    pub fn station_truth() -> StationCalibration {
        let front = Camera {
            intrinsics: front_intrinsics(),
            camera_from_station: Rigid::camera_looking_at(
                DVec3::new(0.04, 1.25, 3.05),
                DVec3::new(0.0, 1.0, 0.05),
                DVec3::Y,
            ),
        };
        let side = Camera {
            intrinsics: side_intrinsics(),
            camera_from_station: Rigid::camera_looking_at(
                DVec3::new(2.95, 1.05, -0.03),
                DVec3::new(0.02, 1.0, 0.0),
                DVec3::Y,
            ),
        };
        StationCalibration {
            front,
            side,
            extra: Vec::new(),
        }
    }

    /// Hand-held board poses in front of a camera for intrinsic calibration: the board
    /// centre at 1.2-2 m, tilted 15-40 degrees about varied axes and spread over the
    /// image. Returns `camera_from_board` poses.
    pub fn handheld_poses(
        board: &BoardSpec,
        intrinsics: &Intrinsics,
        count: usize,
        seed: u64,
    ) -> Vec<Rigid> {
        const MAX_TRIES: usize = 2000;
        const EDGE_MARGIN_PX: f64 = 12.0;
        let mut rng = SplitMix64(seed);
        let centre = board.grid_centre();
        let (w, h) = (intrinsics.width as f64, intrinsics.height as f64);
        let half_fov_x = 0.5 * w / intrinsics.fx;
        let half_fov_y = 0.5 * h / intrinsics.fy;
        let m = board.square_m;
        let sheet = [
            DVec3::new(-1.6 * m, -1.6 * m, 0.0),
            DVec3::new((board.cols as f64 + 0.6) * m, -1.6 * m, 0.0),
            DVec3::new(-1.6 * m, (board.rows as f64 + 0.6) * m, 0.0),
            DVec3::new(
                (board.cols as f64 + 0.6) * m,
                (board.rows as f64 + 0.6) * m,
                0.0,
            ),
        ];
        let mut out = Vec::with_capacity(count);
        for k in 0..MAX_TRIES {
            if out.len() == count {
                break;
            }
            let depth = 1.2 + 0.8 * rng.uniform();
            let angle = std::f64::consts::TAU * (out.len() as f64 + 0.3 * rng.uniform())
                / count as f64
                + 0.7 * k as f64;
            let tilt = (18.0 + 22.0 * rng.uniform()).to_radians();
            let axis = DVec3::new(angle.cos(), angle.sin(), 0.0);
            let spin = (rng.uniform() - 0.5) * 0.6;
            let rot = glam::DMat3::from_axis_angle(axis, tilt) * glam::DMat3::from_rotation_z(spin);
            let place = DVec3::new(
                (2.0 * rng.uniform() - 1.0) * 0.5 * half_fov_x * depth,
                (2.0 * rng.uniform() - 1.0) * 0.5 * half_fov_y * depth,
                depth,
            );
            // Board centre at `place`, so t = place - R * centre.
            let c = DVec3::new(centre.x, centre.y, 0.0);
            let pose = Rigid {
                rotation: rot,
                translation: place - rot * c,
            };
            let visible = sheet.iter().all(|p| {
                intrinsics
                    .project_camera_point(pose.apply(*p))
                    .is_some_and(|q| {
                        q.x > EDGE_MARGIN_PX
                            && q.y > EDGE_MARGIN_PX
                            && q.x < w - EDGE_MARGIN_PX
                            && q.y < h - EDGE_MARGIN_PX
                    })
            });
            if visible {
                out.push(pose);
            }
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn render_is_dark_at_a_black_square_and_light_at_a_white_one() {
        let intr = Intrinsics {
            width: 160,
            height: 120,
            fx: 150.0,
            fy: 150.0,
            cx: 80.0,
            cy: 60.0,
            dist: [-0.1, 0.0, 0.0, 0.0, 0.0],
        };
        let board = BoardSpec {
            cols: 5,
            rows: 4,
            square_m: 0.05,
        };
        let pose = Rigid {
            rotation: glam::DMat3::IDENTITY,
            translation: DVec3::new(-0.1, -0.075, 0.8),
        };
        let mut r = BoardRenderer::new(intr);
        let img = r.render(&board, &pose, Background::Wall, &RenderOptions::default());
        // Centre of square (0,0)-(1,1) in board metres is white (i + j = 0 + 0 even -> black?):
        for (x, y) in [(0.025, 0.025), (0.075, 0.025)] {
            let p = intr
                .project_camera_point(pose.apply(DVec3::new(x, y, 0.0)))
                .unwrap();
            let v = img.get_pixel(p.x.round() as u32, p.y.round() as u32).0[0] as f64;
            let expect = if board.is_black(x, y) {
                BLACK_LEVEL
            } else {
                WHITE_LEVEL
            };
            assert!((v - expect).abs() < 15.0, "{x},{y}: {v} vs {expect}");
        }
    }
}
