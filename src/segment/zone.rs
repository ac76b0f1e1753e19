//! The shadow zone (see the module docs of [`super`]): where a person's cast shadow can
//! fall, from the calibration, and how the model keeps it.

use super::{BackgroundModel, PixelBox, SegmentError, COARSE, TAU2_MAX, ZONE_BIT, ZONE_BLOCK_PX};
use crate::camera::Camera;
use crate::imgproc::{Mask, MASK_ON};
use glam::{DVec2, DVec3};

impl BackgroundModel {
    /// Sets where the person stands: the image of the standing volume over the mark
    /// ([`standing_volume_box`], full-resolution pixels). The person is then the
    /// component with most of its cells inside it, and large components mostly outside it
    /// are bystanders, not a second person in the booth (see [`super::SegmentStats::bystanders`]).
    pub fn set_standing_box(&mut self, b: Option<PixelBox>) {
        self.standing_cells = b.map(|b| PixelBox {
            min_x: b.min_x / COARSE,
            min_y: b.min_y / COARSE,
            max_x: b.max_x.div_ceil(COARSE),
            max_y: b.max_y.div_ceil(COARSE),
        });
    }

    /// Sets the shadow zone (non-zero pixels of `zone`, same size as the model): where the
    /// person's cast shadow may fall. Outside it only exposure changes count as
    /// background. Before this call the whole frame is zone.
    ///
    /// # Errors
    /// `ZoneSize` when `zone` differs in size from the model.
    pub fn set_shadow_zone(&mut self, zone: &Mask) -> Result<(), SegmentError> {
        if zone.width != self.width || zone.height != self.height {
            return Err(SegmentError::ZoneSize {
                want_w: self.width,
                want_h: self.height,
                got_w: zone.width,
                got_h: zone.height,
            });
        }
        let w = self.width as usize;
        let cw = w.div_ceil(COARSE as usize);
        self.zone_everywhere = zone.data.iter().all(|&v| v != 0);
        for (i, &v) in zone.data.iter().enumerate() {
            let z = (v != 0) as u8;
            self.zone[i] = z;
            let t = &mut self.px[i].tau2;
            *t = (*t & TAU2_MAX) | if z != 0 { ZONE_BIT } else { 0 };
            let (x, y) = (i % w, i / w);
            if x.is_multiple_of(COARSE as usize) && y.is_multiple_of(COARSE as usize) {
                let k = (y / COARSE as usize) * cw + x / COARSE as usize;
                if let Some(c) = self.coarse_model.zone.get_mut(k) {
                    *c = z;
                }
            }
        }
        Ok(())
    }
}

/// The shadow zone of a calibrated camera (see the module docs): pixels whose viewing ray
/// meets the floor (y = 0) within `radius_m` of the mark, written into `out` (resized to
/// the camera's frame). Tested once per block of [`ZONE_BLOCK_PX`] pixels.
pub fn floor_shadow_zone(camera: &Camera, radius_m: f64, out: &mut Mask) {
    let (w, h) = (camera.intrinsics.width, camera.intrinsics.height);
    out.reset(w, h);
    let b = ZONE_BLOCK_PX;
    for by in (0..h).step_by(b as usize) {
        for bx in (0..w).step_by(b as usize) {
            let c = DVec2::new(
                (bx + b / 2).min(w - 1) as f64,
                (by + b / 2).min(h - 1) as f64,
            );
            let ray = camera.ray_through_pixel(c);
            if ray.dir.y >= -1e-9 {
                continue; // at or above the horizon: never the floor
            }
            let p = ray.at(-ray.origin.y / ray.dir.y);
            if p.x.hypot(p.z) > radius_m {
                continue;
            }
            for y in by..(by + b).min(h) {
                let row = (y * w) as usize;
                out.data[row + bx as usize..row + (bx + b).min(w) as usize].fill(MASK_ON);
            }
        }
    }
}

/// The standing volume over the mark, metres: half width (x), height, half depth (z).
const VOLUME_HALF_X_M: f64 = 0.6;
const VOLUME_HEIGHT_M: f64 = 2.2;
const VOLUME_HALF_Z_M: f64 = 0.5;

/// The pixel box of the standing volume over the mark in a `w x h` frame (clipped), or
/// None when it is out of view.
pub fn standing_volume_box(camera: &Camera, w: u32, h: u32) -> Option<PixelBox> {
    let mut lo = [f64::INFINITY; 2];
    let mut hi = [f64::NEG_INFINITY; 2];
    for sx in [-1.0, 1.0] {
        for y in [0.0, VOLUME_HEIGHT_M] {
            for sz in [-1.0, 1.0] {
                let p = DVec3::new(sx * VOLUME_HALF_X_M, y, sz * VOLUME_HALF_Z_M);
                if let Some(px) = camera.project(p) {
                    lo = [lo[0].min(px.x), lo[1].min(px.y)];
                    hi = [hi[0].max(px.x), hi[1].max(px.y)];
                }
            }
        }
    }
    let b = PixelBox {
        min_x: lo[0].clamp(0.0, w as f64) as u32,
        min_y: lo[1].clamp(0.0, h as f64) as u32,
        max_x: hi[0].ceil().clamp(0.0, w as f64) as u32,
        max_y: hi[1].ceil().clamp(0.0, h as f64) as u32,
    };
    (b.min_x < b.max_x && b.min_y < b.max_y).then_some(b)
}
