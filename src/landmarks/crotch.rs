//! Where the perineum is, given where the front camera sees the top of the leg gap.
//!
//! The front camera sees the crotch as the apex of the gap between the legs: the highest
//! ray that passes under the body all the way through it. Under the crotch the body's
//! midline section is a trough, lowest at the perineum and rising toward the pubis in
//! front and the buttocks behind. A camera above the crotch looks down, so its highest
//! clear ray grazes the trough's front slope and passes the perineum's depth *below* it
//! (a camera below the crotch grazes the back slope). Lifting the apex onto the body axis
//! therefore puts the crotch too low by an amount that grows with the ray's slope: 4-15 mm
//! on the synthetic sets, where cameras sit 0.1-0.7 m above the crotch at 2.4-3.5 m.
//!
//! [`CrotchProfile`] is the trough of a template body (its midline section under the
//! crotch). For a ray of slope `s` (height gained per metre toward the front camera),
//! the ray through the perineum's depth that just clears the trough lies
//! `min_u (p(u) - s u)` above the perineum, where `p(u)` is the trough's height above
//! the perineum at depth offset `u` (+Z, toward the front camera). That is a
//! drop (a negative height) for any slope when the trough is lowest at `u = 0`. A body
//! `k` times the template's size has the trough `k p(u / k)` and so `k` times the drop.
//! The template's trough stands in for the subject's: it is a prior, the subject's own
//! trough is hidden from both cameras.

use crate::body::Template;
use crate::mesh::section::{slice, Plane};
use glam::DVec3;

/// Samples either side of the perineum's depth.
const HALF: usize = 60;
/// Sample spacing, in units of the template's stature (about 4 mm on an adult).
const STEP_REL: f64 = 1.0 / 400.0;
/// Section points more than this far below the crotch (in units of stature) are legs
/// crossing the midline, not the trough.
const BELOW_TOL_REL: f64 = 0.015;

/// The template's midline trough under the crotch, relative to the crotch and in units
/// of the template's stature (so it scales with the subject).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CrotchProfile {
    /// Height above the crotch of the trough's underside at depth offset
    /// `(k - HALF) * STEP_REL` (both in units of stature); `INFINITY` where the midline
    /// section has no surface (a ray passes freely there).
    heights: [f32; 2 * HALF + 1],
}

impl CrotchProfile {
    /// The trough of `template`'s midline section (x = its crotch's x), from its prepared
    /// crotch (`TemplateInfo::landmarks`). `None` when the section has no surface near
    /// the crotch (no trough to speak of: an unprepared template).
    pub fn from_template(template: &Template) -> Option<CrotchProfile> {
        let stature = template.info.stature_m;
        let c = template.info.landmarks.crotch;
        if stature.is_nan() || stature <= 0.0 {
            return None;
        }
        // The plane's basis for a normal along X maps a point to (z, -y).
        let loops = slice(&template.mesh, &Plane::new(c, DVec3::X));
        let mut heights = [f32::INFINITY; 2 * HALF + 1];
        let mut found = false;
        for (k, h) in heights.iter_mut().enumerate() {
            let z = c.z + (k as f64 - HALF as f64) * STEP_REL * stature;
            let mut lowest = f64::INFINITY;
            for l in &loops {
                let n = l.points.len();
                let segs = if l.closed { n } else { n.saturating_sub(1) };
                for i in 0..segs {
                    let (a, b) = (l.points[i], l.points[(i + 1) % n]);
                    if (a.x - z) * (b.x - z) > 0.0 || a.x == b.x {
                        continue;
                    }
                    let t = (z - a.x) / (b.x - a.x);
                    let y = -(a.y + t * (b.y - a.y));
                    if y >= c.y - BELOW_TOL_REL * stature {
                        lowest = lowest.min(y);
                    }
                }
            }
            if lowest.is_finite() {
                *h = ((lowest - c.y) / stature) as f32;
                found = true;
            }
        }
        found.then_some(CrotchProfile { heights })
    }

    /// How far above the perineum (metres, negative: below) a ray of slope `slope`
    /// passes at the perineum's depth when it just clears the trough of a body of
    /// stature `stature_m`. `slope` is the height the ray gains per metre toward +Z
    /// (positive for a front camera above the crotch).
    pub fn apparent_offset(&self, slope: f64, stature_m: f64) -> f64 {
        let min_rel = self
            .heights
            .iter()
            .enumerate()
            .filter(|(_, h)| h.is_finite())
            .map(|(k, &h)| f64::from(h) - slope * (k as f64 - HALF as f64) * STEP_REL)
            .fold(f64::INFINITY, f64::min);
        if min_rel.is_finite() {
            min_rel * stature_m
        } else {
            0.0
        }
    }

    /// The trough's depth range with a surface (back, front: depth offsets from the
    /// crotch along +Z) and its lowest height above the crotch, all in metres for a body
    /// of stature `stature_m` (for reports and tests).
    pub fn extent(&self, stature_m: f64) -> (f64, f64, f64) {
        let mut first = None;
        let mut last = 0.0;
        let mut lowest = f64::INFINITY;
        for (k, &h) in self.heights.iter().enumerate() {
            if h.is_finite() {
                let u = (k as f64 - HALF as f64) * STEP_REL * stature_m;
                first.get_or_insert(u);
                last = u;
                lowest = lowest.min(f64::from(h) * stature_m);
            }
        }
        (first.unwrap_or(0.0), last, lowest)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A trough p(u) = u^2 / (2 r) in units of stature has drop -s^2 r / 2.
    fn parabola(r_rel: f64) -> CrotchProfile {
        let mut heights = [f32::INFINITY; 2 * HALF + 1];
        for (k, h) in heights.iter_mut().enumerate() {
            let u = (k as f64 - HALF as f64) * STEP_REL;
            *h = (u * u / (2.0 * r_rel)) as f32;
        }
        CrotchProfile { heights }
    }

    #[test]
    fn a_parabolic_trough_drops_the_ray_by_its_conjugate() {
        let p = parabola(0.25);
        let stature = 1.7;
        for s in [0.0f64, 0.1, -0.1, 0.2, 0.3] {
            let want = -s * s * 0.25 / 2.0 * stature;
            let got = p.apparent_offset(s, stature);
            // The minimum is taken over samples 4 mm apart: within a sample's worth.
            assert!((got - want).abs() < 2e-4, "slope {s}: {got} vs {want}");
        }
        // Symmetric trough: the sign of the slope does not matter; size scales the drop.
        assert!((p.apparent_offset(0.2, 1.7) - p.apparent_offset(-0.2, 1.7)).abs() < 1e-9);
        assert!((p.apparent_offset(0.2, 1.8) / p.apparent_offset(0.2, 0.9) - 2.0).abs() < 1e-9);
    }

    #[test]
    fn a_ray_clears_a_trough_without_surface_freely() {
        let p = CrotchProfile {
            heights: [f32::INFINITY; 2 * HALF + 1],
        };
        assert_eq!(p.apparent_offset(0.3, 1.7), 0.0);
    }

    #[test]
    fn the_templates_trough_is_lowest_near_the_crotch_and_rises_both_ways() {
        let lib = match crate::body::ShapeLibrary::shared() {
            Ok(l) => l,
            Err(e) => panic!("the bundled shape library must load: {e}"),
        };
        let t = lib.template();
        let p = CrotchProfile::from_template(t).expect("the template has a trough");
        let (back, front, _) = p.extent(1.0);
        let (_, _, lowest) = p.extent(t.info.stature_m);
        // The trough spans the body's depth at the crotch (10-30 cm) ...
        assert!(front - back > 0.05 && front - back < 0.2, "{back} {front}");
        // ... its lowest point is the crotch (within a few millimetres) ...
        assert!(lowest.abs() < 0.005, "lowest {lowest}");
        // ... and a sloping ray passes below the crotch, the more the steeper.
        let st = t.info.stature_m;
        let (d1, d2) = (p.apparent_offset(0.1, st), p.apparent_offset(0.25, st));
        assert!(d2 < d1 && d1 < 0.0, "{d1} {d2}");
        assert!(d2 > -0.05, "{d2}");
    }
}
