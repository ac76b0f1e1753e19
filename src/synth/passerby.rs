//! A second person walking behind the subject (issue 20, item 6): `synth-set
//! --passer-by`. A body of its own (the library's, drawn from the seed) in clothes of its
//! own crosses the room sideways between the subject and the front backdrop during the
//! middle half of the subject's frames ([`walk_frames`]): behind the subject in the front view, beside the subject
//! in the side view. It is drawn with a depth test against the subject, so whichever is
//! nearer a camera hides the other; it is not in the truth (masks, mesh, measurements are
//! the subject's alone), and its path is written to truth.json.
//!
//! Units: metres in the station frame (+Y up, +Z toward the front camera, +X toward the
//! side camera).

use super::raster::Rasterizer;
use super::rng::SplitMix64;
use super::scene::{self, Dress, Scene};
use super::subject::{subject_body, SubjectParams};
use super::SynthError;
use crate::camera::Camera;
use glam::{DMat3, DVec3};
use serde::{Deserialize, Serialize};

/// The passer-by's random stream (other draws of a seed stay as in a plain set).
const PASSER_BY_STREAM: u64 = 0x9A55;
/// Nearest the passer-by's path comes to the mark (its centre line), metres behind it.
const MIN_BEHIND_M: f64 = 0.55;
/// Clearance kept between the passer-by's centre line and a backdrop, metres.
const BACKDROP_CLEARANCE_M: f64 = 0.3;
/// Where the walk starts on the side camera's side, metres of x.
const START_X_M: f64 = 1.0;

/// The frames of the walk (first, count) among a recording's `subject_frames` after
/// `empty_frames`: the middle half, so that the subject is seen still before the
/// passer-by comes and after it has gone.
pub fn walk_frames(empty_frames: usize, subject_frames: usize) -> (usize, usize) {
    let first = empty_frames + subject_frames / 4;
    (first, (subject_frames / 2).max(1))
}

/// The passer-by's path as truth.json records it: a straight walk at constant speed
/// along x, from `from_x` to `to_x` at depth `z`, over frames `first_frame..=last_frame`.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct PasserByPath {
    pub z_m: f64,
    pub from_x_m: f64,
    pub to_x_m: f64,
    pub first_frame: usize,
    pub last_frame: usize,
    /// Where the passer-by's body comes from (a library body; not a person).
    pub body_source: String,
}

/// A passer-by ready to draw: its body facing its walking direction, clothes, path.
pub struct PasserBy {
    pub path: PasserByPath,
    /// The body as the library makes it (facing +Z: the clothes are laid out on it).
    canonical: crate::mesh::TriMesh,
    canonical_normals: Vec<DVec3>,
    /// Turn to the walking direction, and the lift that puts its feet on the floor.
    turn: DMat3,
    lift: f64,
    dress: Dress,
    scene: Scene,
    posed: Vec<DVec3>,
    normals: Vec<DVec3>,
    rasters: [Rasterizer; 2],
}

impl PasserBy {
    /// The passer-by of `seed` in `scene`, walking during frames
    /// `first_frame..first_frame + frames`.
    pub fn new(
        seed: u64,
        scene: &Scene,
        first_frame: usize,
        frames: usize,
        cameras: [&Camera; 2],
    ) -> Result<PasserBy, SynthError> {
        let mut rng = SplitMix64::stream(seed, PASSER_BY_STREAM);
        let params = SubjectParams::sample(rng.next_u64());
        let body = subject_body(&params)?;
        let info = crate::body::prepare(&body.mesh).map_err(|e| {
            SynthError::Invalid(format!("the passer-by's body cannot be analysed: {e}"))
        })?;
        let dress = Dress::new(&body.mesh, scene::Skeleton::from_template(&info));
        let mut look_scene = scene.clone();
        look_scene.look.redress(&mut rng);
        // Between the subject and the front backdrop, halfway between the two limits
        // (or against the backdrop's clearance where the room is too shallow).
        let (deepest, nearest) = (scene.back_z + BACKDROP_CLEARANCE_M, -MIN_BEHIND_M);
        let z = if deepest < nearest {
            0.5 * (deepest + nearest)
        } else {
            deepest
        };
        let to_x = (scene.side_x + BACKDROP_CLEARANCE_M).max(-START_X_M);
        // Facing the way it walks (-X): the library body faces +Z.
        let turn = DMat3::from_rotation_y(-std::f64::consts::FRAC_PI_2);
        let canonical = body.mesh;
        let lift = -canonical
            .positions
            .iter()
            .map(|p| p.y)
            .fold(f64::INFINITY, f64::min);
        let canonical_normals = canonical.vertex_normals();
        let n = canonical.positions.len();
        let raster = |c: &Camera| Rasterizer::new(c.intrinsics.width, c.intrinsics.height);
        Ok(PasserBy {
            path: PasserByPath {
                z_m: z,
                from_x_m: START_X_M,
                to_x_m: to_x,
                first_frame,
                last_frame: first_frame + frames.saturating_sub(1),
                body_source: body.source,
            },
            canonical,
            canonical_normals,
            turn,
            lift: if lift.is_finite() { lift } else { 0.0 },
            dress,
            scene: look_scene,
            posed: vec![DVec3::ZERO; n],
            normals: vec![DVec3::ZERO; n],
            rasters: [raster(cameras[0]), raster(cameras[1])],
        })
    }

    /// Where the passer-by's centre line is at frame `k`, None outside its walk.
    pub fn position(&self, k: usize) -> Option<DVec3> {
        let p = &self.path;
        if k < p.first_frame || k > p.last_frame {
            return None;
        }
        let span = (p.last_frame - p.first_frame).max(1) as f64;
        let t = (k - p.first_frame) as f64 / span;
        Some(DVec3::new(
            p.from_x_m + (p.to_x_m - p.from_x_m) * t,
            0.0,
            p.z_m,
        ))
    }

    /// Draws the passer-by at frame `k` into `radiance` of view `view` (0 front, 1 side)
    /// where it is nearer the camera than the subject (`subject`: the subject's raster of
    /// this frame, already drawn); nothing outside its walk.
    pub fn draw(
        &mut self,
        k: usize,
        view: usize,
        camera: &Camera,
        subject: &Rasterizer,
        radiance: &mut [[f32; 3]],
    ) {
        let Some(at) = self.position(k) else { return };
        let lift = DVec3::new(0.0, self.lift, 0.0);
        for (i, p) in self.canonical.positions.iter().enumerate() {
            self.posed[i] = self.turn * *p + at + lift;
            self.normals[i] = self.turn * self.canonical_normals[i];
        }
        let Some(raster) = self.rasters.get_mut(view) else {
            return;
        };
        raster.clear();
        raster.draw_mesh(camera, &self.posed, &self.canonical.triangles);
        for (i, px) in radiance.iter_mut().enumerate() {
            let Some(hit) = raster.hit_index(i) else {
                continue;
            };
            if subject
                .hit_index(i)
                .is_some_and(|s| s.depth_m <= hit.depth_m)
            {
                continue;
            }
            let Some(t) = self.canonical.triangles.get(hit.triangle as usize) else {
                continue;
            };
            let b = hit.bary.map(|v| v as f64);
            let interp = |arr: &[DVec3]| {
                arr[t[0] as usize] * b[0] + arr[t[1] as usize] * b[1] + arr[t[2] as usize] * b[2]
            };
            let posed = interp(&self.posed);
            let canonical = interp(&self.canonical.positions);
            let n = interp(&self.normals).normalize_or_zero();
            *px = scene::shade_body(&self.scene, &self.dress, canonical, posed, n);
        }
    }
}
