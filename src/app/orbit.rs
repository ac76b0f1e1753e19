//! The orbit camera of the avatar view: it turns about +Y around `target`; yaw 0 looks
//! from +Z (the front camera's side), yaw +90 degrees from +X (the side camera's side).
//! Station frame, metres; drags and scrolls in points.

use glam::{Mat4, Vec3};

/// Orbit camera about the avatar.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OrbitCamera {
    /// Rotation about +Y, radians (0: from the front).
    pub yaw: f32,
    /// Elevation, radians (positive: from above).
    pub pitch: f32,
    pub distance_m: f32,
    pub target: Vec3,
}

/// A named viewpoint.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ViewPreset {
    Front,
    Side,
    ThreeQuarter,
}

/// Vertical field of view of the avatar view.
pub(super) const FOV_Y_RAD: f32 = 0.6;
pub(super) const NEAR_M: f32 = 0.05;
pub(super) const FAR_M: f32 = 50.0;
/// Radians of orbit per point of mouse drag.
pub(super) const ORBIT_RAD_PER_POINT: f32 = 0.01;
pub(super) const PITCH_LIMIT_RAD: f32 = 1.4;
pub(super) const DISTANCE_RANGE_M: (f32, f32) = (0.8, 12.0);

impl Default for OrbitCamera {
    fn default() -> Self {
        OrbitCamera {
            yaw: 0.0,
            pitch: 0.1,
            distance_m: 3.6,
            target: Vec3::new(0.0, 0.88, 0.0),
        }
    }
}

impl OrbitCamera {
    pub fn preset(&mut self, p: ViewPreset) {
        self.yaw = match p {
            ViewPreset::Front => 0.0,
            ViewPreset::Side => std::f32::consts::FRAC_PI_2,
            ViewPreset::ThreeQuarter => std::f32::consts::FRAC_PI_4,
        };
        self.pitch = 0.1;
    }

    /// Applies a mouse drag (points) and a scroll (points, positive zooms in).
    pub fn drag(&mut self, dx: f32, dy: f32, scroll: f32) {
        self.yaw -= dx * ORBIT_RAD_PER_POINT;
        self.pitch =
            (self.pitch + dy * ORBIT_RAD_PER_POINT).clamp(-PITCH_LIMIT_RAD, PITCH_LIMIT_RAD);
        self.distance_m = (self.distance_m * (-scroll * 0.002).exp())
            .clamp(DISTANCE_RANGE_M.0, DISTANCE_RANGE_M.1);
    }

    /// Sets the distance so a body of `size` (metres, x y z extents) fills the view of
    /// aspect width/height at any yaw, with a margin.
    pub fn fit(&mut self, size: Vec3, aspect: f32) {
        const MARGIN: f32 = 1.12;
        let t = (FOV_Y_RAD * 0.5).tan();
        let half_h = 0.5 * size.y;
        let half_w = 0.5 * size.x.max(size.z);
        let d = (half_h / t).max(half_w / (t * aspect.max(0.05))) * MARGIN + half_w;
        self.distance_m = d.clamp(DISTANCE_RANGE_M.0, DISTANCE_RANGE_M.1);
    }

    pub fn eye(&self) -> Vec3 {
        let dir = Vec3::new(
            self.yaw.sin() * self.pitch.cos(),
            self.pitch.sin(),
            self.yaw.cos() * self.pitch.cos(),
        );
        self.target + dir * self.distance_m
    }

    /// Clip-from-station matrix (wgpu depth 0..1) for an aspect ratio width/height.
    pub fn view_proj(&self, aspect: f32) -> Mat4 {
        let proj = Mat4::perspective_rh(FOV_Y_RAD, aspect.max(0.01), NEAR_M, FAR_M);
        proj * Mat4::look_at_rh(self.eye(), self.target, Vec3::Y)
    }
}
