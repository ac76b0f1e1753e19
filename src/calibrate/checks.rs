//! Station checks an operator can act on, computed from `station.yaml` alone.
//!
//! - The angle between the two optical axes and its distance from 90 degrees.
//! - Each camera's height (m), downward tilt and roll (degrees), its distance to the
//!   mark and how far its optical axis passes beside the mark (horizontal aim).
//! - Whether the standing volume (a box 2.1 m tall and 1 m x 1 m around the mark) is
//!   fully in view, with the pixel margin to each image edge (negative = cut off).
//! - Millimetres per pixel at the subject: depth of the volume's centre line at mid
//!   height divided by the focal length in pixels.
//! - Girth error per pixel of silhouette error: if the silhouette grows by one pixel on
//!   every side in both views, a horizontal section's width grows by 2 px x (mm/px of
//!   the front camera) and its depth by 2 px x (mm/px of the side camera), so both
//!   semi-axes of the section's ellipse grow by one pixel's worth; the perimeter of an
//!   ellipse grows by about pi (da + db) (exact for circles, within a few percent for
//!   body sections).
//!
//! Units: metres in the station frame (+Y up, +Z toward the front camera), pixels,
//! degrees, millimetres where named `_mm`.

use crate::camera::{Camera, StationCalibration, View};
use glam::{DVec2, DVec3};

/// The standing volume: height and width (square footprint centred on the mark), metres.
pub const VOLUME_HEIGHT_M: f64 = 2.1;
pub const VOLUME_WIDTH_M: f64 = 1.0;
/// Height at which mm/px is quoted (middle of the body), metres.
pub const SUBJECT_HEIGHT_M: f64 = 1.05;
/// Samples per edge of the volume when projecting it.
const EDGE_SAMPLES: usize = 24;
/// The optical axes should be within this of 90 degrees.
pub const MAX_AXES_OFF_SQUARE_DEG: f64 = 3.0;
/// A camera should be level within this roll.
pub const MAX_ROLL_DEG: f64 = 2.0;
/// The optical axis should pass the mark within this horizontal angle.
pub const MAX_AIM_OFF_DEG: f64 = 5.0;

/// Distances of the projected volume to the image edges, pixels (negative = cut off).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Margins {
    pub left: f64,
    pub right: f64,
    pub top: f64,
    pub bottom: f64,
}

impl Margins {
    pub fn all_in_view(&self) -> bool {
        self.left >= 0.0 && self.right >= 0.0 && self.top >= 0.0 && self.bottom >= 0.0
    }
}

/// Checks of one camera.
#[derive(Debug, Clone, PartialEq)]
pub struct CameraChecks {
    pub view: View,
    pub position_m: DVec3,
    pub height_m: f64,
    /// Positive when the camera looks downward.
    pub tilt_down_deg: f64,
    /// Rotation of the image about the optical axis (0 = level).
    pub roll_deg: f64,
    /// Horizontal angle between the optical axis and the direction to the mark.
    pub aim_off_deg: f64,
    /// Horizontal distance to the mark, metres.
    pub distance_m: f64,
    pub mm_per_px: f64,
    /// None when part of the volume is behind the camera.
    pub volume_margins_px: Option<Margins>,
}

/// All station checks.
#[derive(Debug, Clone, PartialEq)]
pub struct StationChecks {
    /// Angle between the two optical axes in 3-D, degrees.
    pub axes_angle_deg: f64,
    /// The same angle seen from above (horizontal components only), degrees: what an
    /// operator adjusts by panning a camera.
    pub plan_angle_deg: f64,
    /// `|plan_angle_deg - 90|`.
    pub axes_off_square_deg: f64,
    pub front: CameraChecks,
    pub side: CameraChecks,
    /// Girth change (mm) for one pixel of silhouette error on every side.
    pub girth_mm_per_px: f64,
    /// Operator actions, empty when all is well.
    pub actions: Vec<String>,
}

impl StationChecks {
    pub fn all_ok(&self) -> bool {
        self.actions.is_empty()
    }
}

/// Checks one camera.
pub fn check_camera(view: View, cam: &Camera) -> CameraChecks {
    let pos = cam.center_in_station();
    let axis = cam.axis_in_station();
    let right = cam.camera_from_station.rotation.transpose() * DVec3::X;
    let to_mark = DVec2::new(-pos.x, -pos.z);
    let axis_h = DVec2::new(axis.x, axis.z);
    let aim_off_deg = if to_mark.length() > 1e-9 && axis_h.length() > 1e-9 {
        to_mark.angle_to(axis_h).to_degrees().abs()
    } else {
        0.0
    };
    let i = &cam.intrinsics;
    let depth = cam
        .camera_from_station
        .apply(DVec3::new(0.0, SUBJECT_HEIGHT_M, 0.0))
        .z;
    let mm_per_px = depth / (0.5 * (i.fx + i.fy)) * 1000.0;
    CameraChecks {
        view,
        position_m: pos,
        height_m: pos.y,
        tilt_down_deg: (-axis.y).clamp(-1.0, 1.0).asin().to_degrees(),
        roll_deg: right.y.clamp(-1.0, 1.0).asin().to_degrees(),
        aim_off_deg,
        distance_m: to_mark.length(),
        mm_per_px,
        volume_margins_px: volume_margins(cam),
    }
}

fn volume_margins(cam: &Camera) -> Option<Margins> {
    let h = VOLUME_WIDTH_M * 0.5;
    let corners: Vec<DVec3> = [0.0, VOLUME_HEIGHT_M]
        .iter()
        .flat_map(|&y| [(-h, -h), (h, -h), (h, h), (-h, h)].map(|(x, z)| DVec3::new(x, y, z)))
        .collect();
    let edges = [
        (0, 1),
        (1, 2),
        (2, 3),
        (3, 0),
        (4, 5),
        (5, 6),
        (6, 7),
        (7, 4),
        (0, 4),
        (1, 5),
        (2, 6),
        (3, 7),
    ];
    let (mut lo, mut hi) = (DVec2::splat(f64::INFINITY), DVec2::splat(f64::NEG_INFINITY));
    for (a, b) in edges {
        for s in 0..=EDGE_SAMPLES {
            let t = s as f64 / EDGE_SAMPLES as f64;
            let p = corners[a].lerp(corners[b], t);
            let q = cam.project(p)?;
            lo = lo.min(q);
            hi = hi.max(q);
        }
    }
    let i = &cam.intrinsics;
    Some(Margins {
        left: lo.x,
        top: lo.y,
        right: (i.width as f64 - 1.0) - hi.x,
        bottom: (i.height as f64 - 1.0) - hi.y,
    })
}

/// Computes all checks of a calibration.
pub fn check_station(cal: &StationCalibration) -> StationChecks {
    let front = check_camera(View::Front, &cal.front);
    let side = check_camera(View::Side, &cal.side);
    let angle = cal
        .front
        .axis_in_station()
        .dot(cal.side.axis_in_station())
        .clamp(-1.0, 1.0)
        .acos()
        .to_degrees();
    let (fa, sa) = (cal.front.axis_in_station(), cal.side.axis_in_station());
    let plan = DVec2::new(fa.x, fa.z)
        .angle_to(DVec2::new(sa.x, sa.z))
        .abs()
        .to_degrees();
    let off = (plan - 90.0).abs();
    let girth = std::f64::consts::PI * (front.mm_per_px + side.mm_per_px);
    let mut actions = Vec::new();
    if off > MAX_AXES_OFF_SQUARE_DEG {
        actions.push(format!("seen from above the optical axes meet at {plan:.1} deg, {off:.1} deg off square: turn the side camera so that both aim at the mark at right angles"));
    }
    for c in [&front, &side] {
        let name = c.view.name();
        if c.roll_deg.abs() > MAX_ROLL_DEG {
            actions.push(format!(
                "{name} camera is rolled {:.1} deg: level it",
                c.roll_deg
            ));
        }
        if c.aim_off_deg > MAX_AIM_OFF_DEG {
            actions.push(format!(
                "{name} camera aims {:.1} deg beside the mark: pan it toward the mark",
                c.aim_off_deg
            ));
        }
        match c.volume_margins_px {
            None => actions.push(format!("{name} camera: part of the standing volume is behind the camera: move the camera back")),
            Some(m) if !m.all_in_view() => {
                let mut cut = Vec::new();
                if m.top < 0.0 {
                    cut.push(format!("top by {:.0} px", -m.top));
                }
                if m.bottom < 0.0 {
                    cut.push(format!("bottom by {:.0} px", -m.bottom));
                }
                if m.left < 0.0 {
                    cut.push(format!("left by {:.0} px", -m.left));
                }
                if m.right < 0.0 {
                    cut.push(format!("right by {:.0} px", -m.right));
                }
                let advice = if (m.top < 0.0) != (m.bottom < 0.0) && m.top + m.bottom >= 0.0 {
                    "tilt the camera toward the cut side"
                } else if (m.left < 0.0) != (m.right < 0.0) && m.left + m.right >= 0.0 {
                    "pan the camera toward the cut side"
                } else {
                    "move the camera back or use a wider lens setting"
                };
                actions.push(format!("{name} camera does not see the whole standing volume (cut at the {}): {advice}, then recalibrate the extrinsics", cut.join(", ")));
            }
            Some(_) => {}
        }
    }
    StationChecks {
        axes_angle_deg: angle,
        plan_angle_deg: plan,
        axes_off_square_deg: off,
        front,
        side,
        girth_mm_per_px: girth,
        actions,
    }
}

impl std::fmt::Display for StationChecks {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        writeln!(f, "Station checks")?;
        writeln!(
            f,
            "  optical axes: {:.2} deg apart in 3-D; seen from above {:.2} deg ({:.2} deg from square)",
            self.axes_angle_deg, self.plan_angle_deg, self.axes_off_square_deg
        )?;
        for c in [&self.front, &self.side] {
            writeln!(
                f,
                "  {:<5} camera: at ({:.3}, {:.3}, {:.3}) m, height {:.3} m, {:.2} m from the mark, tilt {:.1} deg {}, roll {:.1} deg, aim {:.1} deg beside the mark",
                c.view.name(),
                c.position_m.x,
                c.position_m.y,
                c.position_m.z,
                c.height_m,
                c.distance_m,
                c.tilt_down_deg.abs(),
                if c.tilt_down_deg >= 0.0 { "down" } else { "up" },
                c.roll_deg,
                c.aim_off_deg
            )?;
            writeln!(
                f,
                "          {:.2} mm per pixel at the subject ({SUBJECT_HEIGHT_M} m high)",
                c.mm_per_px
            )?;
            match c.volume_margins_px {
                Some(m) => writeln!(
                    f,
                    "          standing volume ({VOLUME_WIDTH_M} m wide, {VOLUME_HEIGHT_M} m tall) {}: margins left {:.0}, right {:.0}, top {:.0}, bottom {:.0} px",
                    if m.all_in_view() { "fully in view" } else { "NOT fully in view" },
                    m.left,
                    m.right,
                    m.top,
                    m.bottom
                )?,
                None => writeln!(f, "          standing volume partly behind the camera")?,
            }
        }
        writeln!(
            f,
            "  one pixel of silhouette error on every side changes a girth by about {:.1} mm",
            self.girth_mm_per_px
        )?;
        if self.actions.is_empty() {
            writeln!(f, "  all checks passed")?;
        } else {
            for a in &self.actions {
                writeln!(f, "  ACTION: {a}")?;
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nominal_station_passes_and_a_turned_camera_fails() {
        let s = StationCalibration::nominal(720, 1280, 1100.0, 3.2, 1.1, 1.05);
        let c = check_station(&s);
        assert!((c.plan_angle_deg - 90.0).abs() < 1e-6);
        // Both cameras look down a little, so in 3-D the axes meet slightly under 90.
        assert!(c.axes_angle_deg < 90.0 && c.axes_angle_deg > 89.0);
        assert!((c.front.height_m - 1.1).abs() < 1e-9);
        assert!(c.front.tilt_down_deg > 0.0);
        // 3.2 m / 1100 px = 2.9 mm/px.
        assert!((c.front.mm_per_px - 3200.0 / 1100.0).abs() < 0.01);
        assert!(c.all_ok(), "{c}");
        let mut bad = s.clone();
        bad.side.camera_from_station = crate::camera::Rigid::camera_looking_at(
            DVec3::new(3.2, 1.1, 0.0),
            DVec3::new(0.0, 1.05, 0.6),
            DVec3::Y,
        );
        let c = check_station(&bad);
        assert!(c.axes_off_square_deg > 5.0);
        assert!(!c.all_ok());
        let mut low = s.clone();
        low.front.camera_from_station = crate::camera::Rigid::camera_looking_at(
            DVec3::new(0.0, 0.5, 2.0),
            DVec3::new(0.0, 0.3, 0.0),
            DVec3::Y,
        );
        let c = check_station(&low);
        assert!(
            c.front.volume_margins_px.is_some_and(|m| m.top < 0.0),
            "{c}"
        );
    }
}
