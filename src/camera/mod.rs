//! Camera model of the station: OpenCV's pinhole with five distortion coefficients, and
//! the calibration of the two cameras in the station frame (`station.yaml`).
//!
//! # Conventions
//! - Station frame (`../shared/spec/formats.md`): metres, +Y up, +Z toward the front
//!   camera, +X the subject's left, origin on the floor at the mark.
//! - Camera frame: OpenCV's, x right, y down, z forward. `x_cam = R x_station + t`
//!   (`camera_from_station`).
//! - Pixels: (u, v) with the origin at the centre of the top-left pixel, as OpenCV.
//! - Distortion: k1 k2 p1 p2 k3 (OpenCV's model).

pub mod filestorage;

use glam::{DMat3, DVec2, DVec3};

/// Intrinsic parameters of one camera (OpenCV model).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Intrinsics {
    pub width: u32,
    pub height: u32,
    pub fx: f64,
    pub fy: f64,
    pub cx: f64,
    pub cy: f64,
    /// k1, k2, p1, p2, k3.
    pub dist: [f64; 5],
}

impl Intrinsics {
    /// Applies lens distortion to normalised image coordinates (x/z, y/z).
    #[inline]
    pub fn distort(&self, n: DVec2) -> DVec2 {
        let [k1, k2, p1, p2, k3] = self.dist;
        let (x, y) = (n.x, n.y);
        let r2 = x * x + y * y;
        let radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3));
        DVec2::new(
            x * radial + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x),
            y * radial + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y,
        )
    }

    /// Normalised (distorted) coordinates to pixels.
    #[inline]
    pub fn to_pixel(&self, d: DVec2) -> DVec2 {
        DVec2::new(self.fx * d.x + self.cx, self.fy * d.y + self.cy)
    }

    /// Projects a point in the camera frame to pixels (None behind the camera).
    #[inline]
    pub fn project_camera_point(&self, p: DVec3) -> Option<DVec2> {
        if p.z <= 1e-9 {
            return None;
        }
        Some(self.to_pixel(self.distort(DVec2::new(p.x / p.z, p.y / p.z))))
    }

    /// Inverts the distortion: pixel -> undistorted normalised coordinates.
    /// Fixed-point iteration as OpenCV, refined by Newton steps until the
    /// reprojection is exact to 1e-12 (converges for any lens that is monotonic
    /// over the image).
    pub fn undistort_pixel(&self, px: DVec2) -> DVec2 {
        let d = DVec2::new((px.x - self.cx) / self.fx, (px.y - self.cy) / self.fy);
        if self.dist.iter().all(|&k| k == 0.0) {
            return d;
        }
        let mut n = d;
        for _ in 0..20 {
            // Newton on f(n) = distort(n) - d with a numeric Jacobian.
            let f = self.distort(n) - d;
            if f.length() < 1e-14 {
                break;
            }
            let h = 1e-7;
            let jx = (self.distort(n + DVec2::new(h, 0.0)) - self.distort(n)) / h;
            let jy = (self.distort(n + DVec2::new(0.0, h)) - self.distort(n)) / h;
            let det = jx.x * jy.y - jy.x * jx.y;
            if det.abs() < 1e-12 {
                n -= f;
                continue;
            }
            let step = DVec2::new(
                (jy.y * f.x - jy.x * f.y) / det,
                (-jx.y * f.x + jx.x * f.y) / det,
            );
            n -= step;
        }
        n
    }

    /// The camera matrix K as a row-major array.
    pub fn k_rows(&self) -> [f64; 9] {
        [self.fx, 0.0, self.cx, 0.0, self.fy, self.cy, 0.0, 0.0, 1.0]
    }
}

/// A rigid transform `x_to = rotation * x_from + translation`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Rigid {
    pub rotation: DMat3,
    pub translation: DVec3,
}

impl Rigid {
    pub const IDENTITY: Rigid = Rigid {
        rotation: DMat3::IDENTITY,
        translation: DVec3::ZERO,
    };
    #[inline]
    pub fn apply(&self, p: DVec3) -> DVec3 {
        self.rotation * p + self.translation
    }
    pub fn inverse(&self) -> Rigid {
        let rt = self.rotation.transpose();
        Rigid {
            rotation: rt,
            translation: -(rt * self.translation),
        }
    }
    /// Builds the camera pose of a camera at `eye` looking at `target` with the image
    /// "up" toward `up` (OpenCV axes: y down in the image).
    pub fn camera_looking_at(eye: DVec3, target: DVec3, up: DVec3) -> Rigid {
        let z = (target - eye).normalize();
        let x = z.cross(up).normalize(); // right
        let y = z.cross(x); // down
                            // Rows of R are the camera axes expressed in the station frame.
        let rotation = DMat3::from_cols(x, y, z).transpose();
        Rigid {
            rotation,
            translation: -(rotation * eye),
        }
    }
}

/// One calibrated camera: intrinsics and pose in the station frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Camera {
    pub intrinsics: Intrinsics,
    /// x_cam = R x_station + t.
    pub camera_from_station: Rigid,
}

/// A viewing ray in the station frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Ray {
    pub origin: DVec3,
    /// Unit direction.
    pub dir: DVec3,
}

impl Ray {
    pub fn at(&self, t: f64) -> DVec3 {
        self.origin + self.dir * t
    }
}

impl Camera {
    /// Projects a station point to distorted pixels (None behind the camera).
    #[inline]
    pub fn project(&self, point_in_station: DVec3) -> Option<DVec2> {
        self.intrinsics
            .project_camera_point(self.camera_from_station.apply(point_in_station))
    }
    /// Projects without lens distortion (the undistorted image).
    #[inline]
    pub fn project_undistorted(&self, point_in_station: DVec3) -> Option<DVec2> {
        let p = self.camera_from_station.apply(point_in_station);
        if p.z <= 1e-9 {
            return None;
        }
        Some(self.intrinsics.to_pixel(DVec2::new(p.x / p.z, p.y / p.z)))
    }
    /// Camera centre in the station frame.
    pub fn center_in_station(&self) -> DVec3 {
        self.camera_from_station.inverse().translation
    }
    /// Optical axis (unit) in the station frame.
    pub fn axis_in_station(&self) -> DVec3 {
        self.camera_from_station.rotation.transpose() * DVec3::Z
    }
    /// The viewing ray through a (distorted) pixel, in the station frame.
    pub fn ray_through_pixel(&self, px: DVec2) -> Ray {
        let n = self.intrinsics.undistort_pixel(px);
        self.ray_through_normalized(n)
    }
    /// The viewing ray through undistorted normalised coordinates.
    pub fn ray_through_normalized(&self, n: DVec2) -> Ray {
        let rt = self.camera_from_station.rotation.transpose();
        Ray {
            origin: self.center_in_station(),
            dir: (rt * DVec3::new(n.x, n.y, 1.0)).normalize(),
        }
    }
}

/// Which of the two station cameras.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum View {
    Front,
    Side,
}

impl View {
    pub const BOTH: [View; 2] = [View::Front, View::Side];
    pub fn name(self) -> &'static str {
        match self {
            View::Front => "front",
            View::Side => "side",
        }
    }
}

/// Calibration of both cameras (the content of `station.yaml`).
#[derive(Debug, Clone, PartialEq)]
pub struct StationCalibration {
    pub front: Camera,
    pub side: Camera,
    /// Keys the file held beyond the required ones (kept verbatim on rewrite).
    pub extra: Vec<(String, String)>,
}

impl StationCalibration {
    pub fn camera(&self, view: View) -> &Camera {
        match view {
            View::Front => &self.front,
            View::Side => &self.side,
        }
    }

    /// Checks that frames of the given sizes belong to this calibration.
    pub fn check_frame_size(&self, view: View, width: u32, height: u32) -> Result<(), CameraError> {
        let i = self.camera(view).intrinsics;
        if i.width != width || i.height != height {
            return Err(CameraError::FrameSize {
                view: view.name(),
                calib_w: i.width,
                calib_h: i.height,
                frame_w: width,
                frame_h: height,
            });
        }
        Ok(())
    }

    /// A default kiosk geometry (for synthetic recordings and tests): both cameras at
    /// `distance_m` from the mark at `height_m`, aimed at `aim_height_m`.
    pub fn nominal(
        width: u32,
        height: u32,
        focal_px: f64,
        distance_m: f64,
        height_m: f64,
        aim_height_m: f64,
    ) -> Self {
        let intr = Intrinsics {
            width,
            height,
            fx: focal_px,
            fy: focal_px,
            cx: (width as f64 - 1.0) / 2.0,
            cy: (height as f64 - 1.0) / 2.0,
            dist: [0.0; 5],
        };
        let target = DVec3::new(0.0, aim_height_m, 0.0);
        let front = Camera {
            intrinsics: intr,
            camera_from_station: Rigid::camera_looking_at(
                DVec3::new(0.0, height_m, distance_m),
                target,
                DVec3::Y,
            ),
        };
        let side = Camera {
            intrinsics: intr,
            camera_from_station: Rigid::camera_looking_at(
                DVec3::new(distance_m, height_m, 0.0),
                target,
                DVec3::Y,
            ),
        };
        StationCalibration {
            front,
            side,
            extra: Vec::new(),
        }
    }
}

/// Errors of the camera model and calibration files.
#[derive(Debug, thiserror::Error)]
pub enum CameraError {
    #[error("{view} frames are {frame_w}x{frame_h} but the calibration is for {calib_w}x{calib_h}: recalibrate or use the station.yaml made for these cameras")]
    FrameSize {
        view: &'static str,
        calib_w: u32,
        calib_h: u32,
        frame_w: u32,
        frame_h: u32,
    },
    #[error("{file}: {msg}")]
    File { file: String, msg: String },
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cam() -> Camera {
        let mut c = StationCalibration::nominal(1280, 720, 1000.0, 3.0, 1.2, 1.0).front;
        c.intrinsics.dist = [-0.12, 0.05, 0.001, -0.0005, -0.01];
        c
    }

    #[test]
    fn undistort_inverts_distort() {
        let c = cam();
        for &(u, v) in &[(0.0, 0.0), (640.0, 360.0), (1279.0, 719.0), (100.0, 600.0)] {
            let n = c.intrinsics.undistort_pixel(DVec2::new(u, v));
            let back = c.intrinsics.to_pixel(c.intrinsics.distort(n));
            assert!(
                (back - DVec2::new(u, v)).length() < 1e-8,
                "{u},{v} -> {back}"
            );
        }
    }

    #[test]
    fn ray_hits_the_projected_point() {
        let c = cam();
        let p = DVec3::new(0.2, 1.4, 0.1);
        let px = c.project(p).unwrap();
        let r = c.ray_through_pixel(px);
        let t = (p - r.origin).dot(r.dir);
        assert!((r.at(t) - p).length() < 1e-9);
    }

    #[test]
    fn nominal_cameras_face_the_mark() {
        let s = StationCalibration::nominal(720, 1280, 1100.0, 3.0, 1.1, 1.0);
        assert!(s.front.axis_in_station().z < -0.99);
        assert!(s.side.axis_in_station().x < -0.99);
        // The subject's left (+X) appears on the image's right in the front camera... no:
        // the front camera faces the subject, so +X (subject's left) is image right.
        let l = s.front.project(DVec3::new(0.3, 1.0, 0.0)).unwrap();
        assert!(l.x > 360.0);
        // Up is image up.
        let h = s.front.project(DVec3::new(0.0, 1.8, 0.0)).unwrap();
        assert!(h.y < 640.0);
    }
}
