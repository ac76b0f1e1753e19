//! Where a landmark is, given where a camera's grazing ray says it is.
//!
//! Two landmarks are the end of a silhouette rather than a point on it: the crotch is the
//! apex of the gap between the legs, the highest ray that passes *under* the body, and
//! the head top is the highest ray that touches the head, passing *over* it. Such a ray
//! grazes the body where the body's section is tangent to it, not at the landmark, and
//! the lift cuts it at the landmark's depth (the body axis):
//!
//! - Under the crotch the midline section is a trough, lowest at the perineum and rising
//!   toward the pubis in front and the buttocks behind. A front camera above the crotch
//!   looks down, so its highest clear ray grazes the trough's front slope and crosses the
//!   perineum's depth *below* the perineum: 4-15 mm on the synthetic sets, where cameras
//!   sit 0.1-0.7 m above the crotch at 2.4-3.5 m.
//! - Over the head the section is a dome. A camera below the head top looks up, so the
//!   ray that grazes the dome's near slope crosses the top's depth *above* the top: about
//!   +2 mm in each view on the synthetic sets. The acromions, on the front silhouette's
//!   shoulder line, are the same case over the shoulder's top.
//!
//! [`GrazeProfile`] is a template body's section at the landmark (under it or over it).
//! For a ray of slope `s` (height gained per metre along the section's horizontal axis)
//! the ray through the landmark's depth that just clears a trough lies
//! `min_u (p(u) - s u)` above the landmark, and the one that just touches a dome
//! `max_u (p(u) - s u)`, where `p(u)` is the section's height relative to the landmark at
//! offset `u`. A body `k` times the template's size has `k p(u / k)` and so `k` times the
//! offset. The template's section stands in for the subject's, which neither camera sees.

use crate::body::Template;
use crate::mesh::section::{slice, Plane};
use glam::DVec3;

/// Samples either side of the landmark.
const HALF: usize = 60;
/// Sample spacing, in units of the template's stature (about 4 mm on an adult).
const STEP_REL: f64 = 1.0 / 400.0;
/// Section points more than this far beyond the landmark (below a trough's bottom, in
/// units of stature) belong to other parts (legs crossing the midline), not the trough.
const BEYOND_TOL_REL: f64 = 0.015;

/// A dome's section is kept this far below its top (in units of stature; a head is about
/// 0.13): lower surfaces (shoulders) never meet a ray of a kiosk camera's slope.
const DOME_DEPTH_REL: f64 = 0.06;

/// Which side of the section a ray grazes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Graze {
    /// The section's underside, above the landmark (the trough under the crotch).
    Under,
    /// The section's top, below the landmark (the dome of the head).
    Over,
}

/// A template's section at a landmark, relative to it and in units of the template's
/// stature (so it scales with the subject).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GrazeProfile {
    graze: Graze,
    /// Height relative to the landmark of the grazed surface at offset
    /// `(k - HALF) * STEP_REL` along the section's horizontal axis (both in units of
    /// stature); NaN where the section has no surface (a ray passes freely there).
    heights: [f32; 2 * HALF + 1],
}

impl GrazeProfile {
    /// The section of `mesh` (of stature `stature`) through `landmark` with the plane of
    /// normal `normal` (X: the section along Z, seen by the front camera; Z: along X,
    /// seen by the side camera); the surface just above the landmark (`Under`) or the top
    /// of the section (`Over`). None without surface near the landmark.
    pub fn of_mesh(
        mesh: &crate::mesh::TriMesh,
        stature: f64,
        landmark: DVec3,
        normal: DVec3,
        graze: Graze,
    ) -> Option<GrazeProfile> {
        if stature.is_nan() || stature <= 0.0 {
            return None;
        }
        let plane = Plane::new(landmark, normal);
        let (bu, bv) = plane.basis();
        let origin = plane.normal * plane.offset;
        // The section's horizontal axis (the one of X and Z in the plane).
        let axis = if normal.x.abs() > 0.5 {
            DVec3::Z
        } else {
            DVec3::X
        };
        let to_3d = |p: glam::DVec2| origin + bu * p.x + bv * p.y;
        let loops = slice(mesh, &plane);
        let mut heights = [f32::NAN; 2 * HALF + 1];
        let mut found = false;
        for (k, h) in heights.iter_mut().enumerate() {
            let at = landmark.dot(axis) + (k as f64 - HALF as f64) * STEP_REL * stature;
            let mut best = f64::NAN;
            for l in &loops {
                let n = l.points.len();
                let segs = if l.closed { n } else { n.saturating_sub(1) };
                for i in 0..segs {
                    let (a, b) = (to_3d(l.points[i]), to_3d(l.points[(i + 1) % n]));
                    let (ua, ub) = (a.dot(axis), b.dot(axis));
                    if (ua - at) * (ub - at) > 0.0 || ua == ub {
                        continue;
                    }
                    let y = a.y + (at - ua) / (ub - ua) * (b.y - a.y);
                    let keep = match graze {
                        Graze::Under => y >= landmark.y - BEYOND_TOL_REL * stature,
                        Graze::Over => y >= landmark.y - DOME_DEPTH_REL * stature,
                    };
                    if !keep {
                        continue;
                    }
                    best = match (graze, best.is_nan()) {
                        (_, true) => y,
                        (Graze::Under, false) => best.min(y),
                        (Graze::Over, false) => best.max(y),
                    };
                }
            }
            if best.is_finite() {
                *h = ((best - landmark.y) / stature) as f32;
                found = true;
            }
        }
        found.then_some(GrazeProfile { graze, heights })
    }

    /// How far above the landmark (metres, negative: below) a ray of slope `slope`
    /// crosses the landmark's depth when it just clears the trough (`Under`) or just
    /// touches the dome (`Over`) of a body of stature `stature_m`. `slope` is the height
    /// the ray gains per metre along +Z (front profiles) or +X (side profiles).
    pub fn apparent_offset(&self, slope: f64, stature_m: f64) -> f64 {
        let values = self
            .heights
            .iter()
            .enumerate()
            .filter(|(_, h)| h.is_finite())
            .map(|(k, &h)| f64::from(h) - slope * (k as f64 - HALF as f64) * STEP_REL);
        let rel = match self.graze {
            Graze::Under => values.fold(f64::INFINITY, f64::min),
            Graze::Over => values.fold(f64::NEG_INFINITY, f64::max),
        };
        if rel.is_finite() {
            rel * stature_m
        } else {
            0.0
        }
    }

    /// The profile's extent with a surface (first and last offsets along its axis) and
    /// its extreme height relative to the landmark (lowest for `Under`, highest for
    /// `Over`), all in metres for a body of stature `stature_m`.
    pub fn extent(&self, stature_m: f64) -> (f64, f64, f64) {
        let mut first = None;
        let mut last = 0.0;
        let mut extreme = f64::NAN;
        for (k, &h) in self.heights.iter().enumerate() {
            if h.is_finite() {
                let u = (k as f64 - HALF as f64) * STEP_REL * stature_m;
                first.get_or_insert(u);
                last = u;
                let h = f64::from(h) * stature_m;
                extreme = match (self.graze, extreme.is_nan()) {
                    (_, true) => h,
                    (Graze::Under, false) => extreme.min(h),
                    (Graze::Over, false) => extreme.max(h),
                };
            }
        }
        (first.unwrap_or(0.0), last, extreme)
    }
}

/// The template sections the lift corrects with.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TemplateProfiles {
    /// The trough under the crotch, along Z (front camera).
    pub crotch: Option<GrazeProfile>,
    /// The dome of the head along Z (front camera) and along X (side camera).
    pub head_front: Option<GrazeProfile>,
    pub head_side: Option<GrazeProfile>,
    /// The top of each shoulder along Z through the acromion (front camera).
    pub acromion_left: Option<GrazeProfile>,
    pub acromion_right: Option<GrazeProfile>,
}

impl TemplateProfiles {
    /// The profiles of a prepared template: the crotch and the acromions from its
    /// analysis (`TemplateInfo::landmarks`), the head top its highest vertex.
    pub fn of_template(t: &Template) -> TemplateProfiles {
        let stature = t.info.stature_m;
        let top = t
            .mesh
            .positions
            .iter()
            .copied()
            .max_by(|a, b| a.y.total_cmp(&b.y));
        let head = |normal: DVec3| {
            top.and_then(|p| GrazeProfile::of_mesh(&t.mesh, stature, p, normal, Graze::Over))
        };
        let shoulder = |a: DVec3| GrazeProfile::of_mesh(&t.mesh, stature, a, DVec3::X, Graze::Over);
        TemplateProfiles {
            crotch: GrazeProfile::of_mesh(
                &t.mesh,
                stature,
                t.info.landmarks.crotch,
                DVec3::X,
                Graze::Under,
            ),
            head_front: head(DVec3::X),
            head_side: head(DVec3::Z),
            acromion_left: shoulder(t.info.landmarks.acromion_left),
            acromion_right: shoulder(t.info.landmarks.acromion_right),
        }
    }

    /// The profiles of the shape library's template (None, with the reason, when the
    /// library cannot be loaded).
    pub fn of_shape_library() -> Result<TemplateProfiles, String> {
        crate::body::ShapeLibrary::shared()
            .map(|l| TemplateProfiles::of_template(l.template()))
            .map_err(|e| e.to_string())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A parabola p(u) = +-u^2 / (2 r) in units of stature.
    fn parabola(r_rel: f64, graze: Graze) -> GrazeProfile {
        let sign = if graze == Graze::Under { 1.0 } else { -1.0 };
        let mut heights = [f32::NAN; 2 * HALF + 1];
        for (k, h) in heights.iter_mut().enumerate() {
            let u = (k as f64 - HALF as f64) * STEP_REL;
            *h = (sign * u * u / (2.0 * r_rel)) as f32;
        }
        GrazeProfile { graze, heights }
    }

    #[test]
    fn a_parabola_offsets_the_ray_by_its_conjugate() {
        let stature = 1.7;
        for (graze, sign) in [(Graze::Under, -1.0), (Graze::Over, 1.0)] {
            let p = parabola(0.25, graze);
            for s in [0.0f64, 0.1, -0.1, 0.2, 0.3] {
                let want = sign * s * s * 0.25 / 2.0 * stature;
                let got = p.apparent_offset(s, stature);
                // The extreme is taken over samples 4 mm apart: within a sample's worth.
                assert!(
                    (got - want).abs() < 2e-4,
                    "{graze:?} slope {s}: {got} vs {want}"
                );
            }
            // Symmetric: the sign of the slope does not matter; size scales the offset.
            assert!((p.apparent_offset(0.2, 1.7) - p.apparent_offset(-0.2, 1.7)).abs() < 1e-9);
            assert!((p.apparent_offset(0.2, 1.8) / p.apparent_offset(0.2, 0.9) - 2.0).abs() < 1e-9);
        }
    }

    #[test]
    fn a_ray_passes_a_profile_without_surface_freely() {
        let p = GrazeProfile {
            graze: Graze::Under,
            heights: [f32::NAN; 2 * HALF + 1],
        };
        assert_eq!(p.apparent_offset(0.3, 1.7), 0.0);
    }

    #[test]
    fn the_templates_sections_are_where_the_landmarks_are() {
        let lib = crate::body::ShapeLibrary::shared().expect("the bundled shape library");
        let t = lib.template();
        let st = t.info.stature_m;
        let p = TemplateProfiles::of_template(t);
        let crotch = p.crotch.expect("the template has a trough");
        let (back, front, lowest) = crotch.extent(st);
        // The trough spans the body's depth at the crotch (10-30 cm), its lowest point is
        // the crotch (within a few millimetres), and a sloping ray passes below the
        // crotch, the more the steeper.
        assert!(front - back > 0.08 && front - back < 0.35, "{back} {front}");
        assert!(lowest.abs() < 0.005, "lowest {lowest}");
        let (d1, d2) = (
            crotch.apparent_offset(0.1, st),
            crotch.apparent_offset(0.25, st),
        );
        assert!(d2 < d1 && d1 < 0.0 && d2 > -0.05, "{d1} {d2}");
        // The head: the dome's top is the landmark, a level ray touches it there, a
        // sloping one crosses its depth above it, by millimetres.
        for dome in [p.head_front, p.head_side] {
            let dome = dome.expect("the template has a head");
            let (a, b, highest) = dome.extent(st);
            assert!(b - a > 0.1 && b - a < 0.3, "{a} {b}");
            assert!(highest.abs() < 1e-3, "highest {highest}");
            let (u1, u2) = (
                dome.apparent_offset(0.1, st),
                dome.apparent_offset(-0.25, st),
            );
            assert!(u1 > 0.0 && u2 > u1 && u2 < 0.02, "{u1} {u2}");
        }
        // The shoulders: a ray over them crosses the acromion's depth at or above it.
        for shoulder in [p.acromion_left, p.acromion_right] {
            let shoulder = shoulder.expect("the template has shoulders");
            let (level, steep) = (
                shoulder.apparent_offset(0.0, st),
                shoulder.apparent_offset(-0.25, st),
            );
            assert!(
                level >= 0.0 && steep > level && steep < 0.03,
                "{level} {steep}"
            );
        }
    }
}
