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
    /// What is printed on the sheet.
    pub pattern: Pattern,
}

/// The printed pattern.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub enum Pattern {
    /// Black and white squares (inner corners at the grid points).
    #[default]
    Chessboard,
    /// Black circles centred on the grid points, radius as a fraction of the spacing.
    Circles { radius_fraction: f64 },
}

impl Default for RenderOptions {
    fn default() -> Self {
        RenderOptions {
            supersample: 4,
            blur_sigma_px: 0.6,
            noise_sigma: 2.0,
            margin_squares: 0.6,
            seed: 1,
            pattern: Pattern::Chessboard,
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
    /// Region id seen at each pixel corner, and whether a pixel straddles regions.
    classes: Vec<u64>,
    values: Vec<f64>,
    mixed: Vec<bool>,
    /// Pattern of the render in progress.
    pattern: Pattern,
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
            classes: vec![0; (w + 1) * (h + 1)],
            values: vec![0.0; (w + 1) * (h + 1)],
            mixed: vec![false; w * h],
            pattern: Pattern::Chessboard,
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
        self.pattern = opts.pattern;
        let s = opts.supersample.max(1) as usize;
        let inv = 1.0 / s as f64;
        let weight = 1.0 / (s * s) as f64;
        let margin = opts.margin_squares;
        let ray = |n: DVec2| {
            let dir_cam = DVec3::new(n.x, n.y, 1.0);
            (rot_b * dir_cam, dir_cam)
        };
        // Adaptive supersampling: classify the pixel corners; a pixel is sampled
        // finely when any corner in its 3x3 neighbourhood sees another region (a
        // square's corner can poke into a pixel without covering any of its corners,
        // but then it covers corners of the neighbours, squares being wider than 2 px).
        let lw = w + 1;
        for (k, n) in self.lattice.iter().enumerate() {
            let (db, dc) = ray(*n);
            let (class, value) = self.shade(board, margin, origin_b, db, station.as_ref(), dc);
            self.classes[k] = class;
            self.values[k] = value;
        }
        for j in 0..h {
            for i in 0..w {
                let k = j * lw + i;
                let c = self.classes[k];
                self.mixed[j * w + i] = self.classes[k + 1] != c
                    || self.classes[k + lw] != c
                    || self.classes[k + lw + 1] != c;
            }
        }
        for j in 0..h {
            for i in 0..w {
                let fine = (j.saturating_sub(1)..(j + 2).min(h)).any(|jj| {
                    (i.saturating_sub(1)..(i + 2).min(w)).any(|ii| self.mixed[jj * w + ii])
                });
                let c00 = self.lattice[j * lw + i];
                let c10 = self.lattice[j * lw + i + 1];
                let c01 = self.lattice[(j + 1) * lw + i];
                let c11 = self.lattice[(j + 1) * lw + i + 1];
                let at = |fx: f64, fy: f64| {
                    c00 * ((1.0 - fx) * (1.0 - fy))
                        + c10 * (fx * (1.0 - fy))
                        + c01 * ((1.0 - fx) * fy)
                        + c11 * (fx * fy)
                };
                if !fine {
                    // One region over the pixel: its grey level at any corner.
                    self.accum[j * w + i] = self.values[j * lw + i];
                    continue;
                }
                let mut sum = 0.0;
                for sy in 0..s {
                    let fy = (sy as f64 + 0.5) * inv;
                    for sx in 0..s {
                        let fx = (sx as f64 + 0.5) * inv;
                        let (db, dc) = ray(at(fx, fy));
                        sum += self
                            .shade(board, margin, origin_b, db, station.as_ref(), dc)
                            .1;
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
        for (px, v) in out.as_mut().chunks_mut(2).zip(self.accum.chunks(2)) {
            let (a, b) = rng.gaussian_pair();
            for ((p, v), n) in px.iter_mut().zip(v).zip([a, b]) {
                *p = (v + opts.noise_sigma * n).round().clamp(0.0, 255.0) as u8;
            }
        }
        out
    }

    /// The scene along one camera ray: (region id, grey level). Region ids: 0 wall,
    /// 1 floor, 2 sheet margin, 3+ one id per chessboard square.
    fn shade(
        &self,
        board: &BoardSpec,
        margin: f64,
        origin_b: DVec3,
        dir_b: DVec3,
        station: Option<&Rigid>,
        dir_cam: DVec3,
    ) -> (u64, f64) {
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
            let i = (p.x / board.square_m).floor();
            let j = (p.y / board.square_m).floor();
            match self.pattern {
                Pattern::Chessboard => {
                    let inside =
                        i >= -1.0 && j >= -1.0 && i < board.cols as f64 && j < board.rows as f64;
                    if !inside {
                        (2, WHITE_LEVEL)
                    } else {
                        let id = 3 + (i + 2.0) as u64 * 4096 + (j + 2.0) as u64;
                        (
                            id,
                            if board.is_black(p.x, p.y) {
                                BLACK_LEVEL
                            } else {
                                WHITE_LEVEL
                            },
                        )
                    }
                }
                Pattern::Circles { radius_fraction } => {
                    let (c, r) = (
                        (p.x / board.square_m).round(),
                        (p.y / board.square_m).round(),
                    );
                    let on_grid =
                        c >= 0.0 && r >= 0.0 && c < board.cols as f64 && r < board.rows as f64;
                    let d = DVec2::new(p.x - c * board.square_m, p.y - r * board.square_m).length();
                    if on_grid && d <= radius_fraction * board.square_m {
                        (3 + c as u64 * 4096 + r as u64, BLACK_LEVEL)
                    } else {
                        (2, WHITE_LEVEL)
                    }
                }
            }
        } else if floor_t.is_finite() {
            (1, FLOOR_LEVEL)
        } else {
            (0, WALL_LEVEL)
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
    let r = radius as usize;
    for y in 0..h {
        let row = &img[y * w..(y + 1) * w];
        for (x, o) in tmp[y * w..(y + 1) * w].iter_mut().enumerate() {
            let mut s = 0.0;
            if x >= r && x + r < w {
                for (kv, v) in kernel.iter().zip(&row[x - r..=x + r]) {
                    s += kv * v;
                }
            } else {
                for (k, kv) in kernel.iter().enumerate() {
                    let xx = (x as isize + k as isize - radius).clamp(0, w as isize - 1) as usize;
                    s += kv * row[xx];
                }
            }
            *o = s;
        }
    }
    img.iter_mut().for_each(|v| *v = 0.0);
    for y in 0..h {
        for (k, kv) in kernel.iter().enumerate() {
            let yy = (y as isize + k as isize - radius).clamp(0, h as isize - 1) as usize;
            let (src, dst) = (&tmp[yy * w..(yy + 1) * w], &mut img[y * w..(y + 1) * w]);
            for (o, v) in dst.iter_mut().zip(src) {
                *o += kv * v;
            }
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
        self.gaussian_pair().0
    }
    /// Two independent standard normals (Box-Muller).
    pub fn gaussian_pair(&mut self) -> (f64, f64) {
        let (u1, u2) = (self.uniform(), self.uniform());
        let r = (-2.0 * u1.ln()).sqrt();
        let (s, c) = (std::f64::consts::TAU * u2).sin_cos();
        (r * c, r * s)
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

    /// Landscape 1280x720 lens with mild barrel distortion (the OpenCV comparison).
    pub fn landscape_intrinsics() -> Intrinsics {
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

    /// Portrait 720x1280 lens of the front camera (a standing person fills the height).
    pub fn front_intrinsics() -> Intrinsics {
        Intrinsics {
            width: 720,
            height: 1280,
            fx: 1012.0,
            fy: 1010.0,
            cx: 357.0,
            cy: 644.0,
            dist: [-0.11, 0.09, 0.0008, -0.0005, -0.02],
        }
    }

    /// Portrait 720x1280 lens of the side camera.
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

    /// Both cameras at station-like places (portrait frames): front ~3 m on +Z at 1.25 m, side ~3 m on +X
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
        // Depth so that the sheet spans 45-80% of the image's shorter side.
        let sheet_extent = (board.cols.max(board.rows) as f64 + 3.2) * m;
        let focal = 0.5 * (intrinsics.fx + intrinsics.fy);
        let short_side = w.min(h);
        let mut out = Vec::with_capacity(count);
        for k in 0..MAX_TRIES {
            if out.len() == count {
                break;
            }
            let depth = sheet_extent * focal / (short_side * (0.45 + 0.35 * rng.uniform()));
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

/// A rendered station: board photos for both cameras, the placement board at the mark
/// seen by both, and the truth.
#[derive(Debug, Clone)]
pub struct SyntheticStation {
    pub truth: crate::camera::StationCalibration,
    pub board: BoardSpec,
    /// Height of the placement board's lowest inner-corner row, metres.
    pub board_height_m: f64,
    pub front_views: Vec<image::GrayImage>,
    pub side_views: Vec<image::GrayImage>,
    pub station_front: image::GrayImage,
    pub station_side: image::GrayImage,
}

/// Renders a [`SyntheticStation`] with the rigs of [`rigs`]: `views` hand-held board
/// poses per camera and the placement board at the mark (calib/README.md procedure).
pub fn synthetic_station(
    board: &BoardSpec,
    views: usize,
    board_height_m: f64,
    opts: &RenderOptions,
) -> SyntheticStation {
    use crate::camera::View;
    let truth = rigs::station_truth();
    let placement = super::extrinsics::Placement {
        board: *board,
        lowest_row_height_m: board_height_m,
    };
    let station_from_board = placement.station_from_board();
    let mut out_views: Vec<Vec<image::GrayImage>> = Vec::new();
    let mut stations = Vec::new();
    for (k, view) in View::BOTH.iter().enumerate() {
        let cam = truth.camera(*view);
        let mut r = BoardRenderer::new(cam.intrinsics);
        let poses = rigs::handheld_poses(
            board,
            &cam.intrinsics,
            views,
            opts.seed.wrapping_add(101 * k as u64),
        );
        let imgs = poses
            .iter()
            .enumerate()
            .map(|(i, p)| {
                r.render(
                    board,
                    p,
                    Background::Wall,
                    &RenderOptions {
                        seed: opts.seed.wrapping_add(1000 * k as u64 + i as u64),
                        ..*opts
                    },
                )
            })
            .collect();
        out_views.push(imgs);
        let cs = cam.camera_from_station;
        let camera_from_board = Rigid {
            rotation: cs.rotation * station_from_board.rotation,
            translation: cs.rotation * station_from_board.translation + cs.translation,
        };
        stations.push(r.render(
            board,
            &camera_from_board,
            Background::Station {
                camera_from_station: cs,
            },
            &RenderOptions {
                seed: opts.seed.wrapping_add(7 + k as u64),
                ..*opts
            },
        ));
    }
    let side_views = out_views.pop().unwrap_or_default();
    let front_views = out_views.pop().unwrap_or_default();
    let station_side = stations.pop().unwrap_or_default();
    let station_front = stations.pop().unwrap_or_default();
    SyntheticStation {
        truth,
        board: *board,
        board_height_m,
        front_views,
        side_views,
        station_front,
        station_side,
    }
}

impl SyntheticStation {
    /// Writes `front/view_NN.png`, `side/view_NN.png`, `station_front.png`,
    /// `station_side.png` and `truth.yaml` under `dir`.
    pub fn write(&self, dir: &std::path::Path) -> Result<(), String> {
        let err = |p: &std::path::Path, e: &dyn std::fmt::Display| format!("{}: {e}", p.display());
        for (sub, imgs) in [("front", &self.front_views), ("side", &self.side_views)] {
            let d = dir.join(sub);
            crate::io::atomic::create_dir(&d).map_err(|e| e.to_string())?;
            for (i, img) in imgs.iter().enumerate() {
                let p = d.join(format!("view_{i:02}.png"));
                crate::io::atomic::save_image(&p, img).map_err(|e| err(&p, &e.cause()))?;
            }
        }
        for (name, img) in [
            ("station_front.png", &self.station_front),
            ("station_side.png", &self.station_side),
        ] {
            let p = dir.join(name);
            crate::io::atomic::save_image(&p, img).map_err(|e| err(&p, &e.cause()))?;
        }
        let p = dir.join("truth.yaml");
        self.truth.save(&p).map_err(|e| err(&p, &e))
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
