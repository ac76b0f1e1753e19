//! Lifting both views' landmarks into the station frame and filling the silhouette
//! result's parts, pixels and landmark verdicts (the geometry is [`crate::landmarks::lift`]'s).

use super::{SilhouetteOptions, SilhouetteResult};
use crate::camera::{Camera, StationCalibration};
use crate::landmarks::analysis::{self, FrontFeatures, SideFeatures};
use crate::landmarks::graze::TemplateProfiles;
use crate::landmarks::lift::{
    feet_centre_z, grazed_height, lift_front_ray, plane_point_to_normalized, ray_plane,
    wedge_point, PlaneAxis, SideAxis,
};
use crate::landmarks::{LandmarkName, NamedPoint, Verdict};
use glam::{DVec2, DVec3};

/// Lifts every landmark and joint, fills the parts, pixels and the landmark verdicts.
pub fn lift_all(
    calib: &StationCalibration,
    front_norm: &[DVec2],
    side_norm: &[DVec2],
    ff: &FrontFeatures,
    sf: &SideFeatures,
    opts: &SilhouetteOptions,
    out: &mut SilhouetteResult,
) {
    let lift = Lift {
        front: &calib.front,
        side: &calib.side,
        axis: SideAxis::new(&out.side.plane, &calib.side),
        front_norm,
        side_norm,
        iters: opts.lift_iterations,
        profiles: opts.template_profiles.as_ref(),
    };
    let mut pts: Vec<(LandmarkName, DVec3)> = Vec::new();
    let stature = lift.head_top(ff, sf, &mut pts);
    let h = stature / 7.0;
    lift.front_landmarks(ff, &out.front.plane, stature, &mut pts);
    let crotch = pts
        .iter()
        .find(|p| p.0 == LandmarkName::Crotch)
        .map(|p| p.1);
    if let Some(c) = crotch {
        lift.joints(c, h, ff, &out.front.plane, &mut pts);
    }
    fill_parts(&lift.axis, ff, crotch, stature, out);
    record_points(lift.front, lift.side, &pts, stature, out);
    landmark_verdicts(&lift.axis, ff, crotch, h, stature, opts, out);
}

/// What lifting a front-view point needs: both cameras, the side view's body axis, the
/// views' normalized contour points and the template's sections.
struct Lift<'a> {
    front: &'a Camera,
    side: &'a Camera,
    axis: SideAxis,
    front_norm: &'a [DVec2],
    side_norm: &'a [DVec2],
    iters: usize,
    profiles: Option<&'a TemplateProfiles>,
}

impl Lift<'_> {
    /// Front contour point `i` in the station frame: on its ray, at the depth the side
    /// view's body axis gives.
    fn front_point(&self, i: usize) -> DVec3 {
        lift_front_ray(self.front, self.front_norm[i], &self.axis, self.iters)
    }

    /// Stature: the head top of both views (pushed onto `pts`), metres; 0 without one.
    /// Each view's ray over the head grazes the dome's near slope, so with the template's
    /// dome both are moved down onto the top and averaged; without it the higher is taken.
    fn head_top(
        &self,
        ff: &FrontFeatures,
        sf: &SideFeatures,
        pts: &mut Vec<(LandmarkName, DVec3)>,
    ) -> f64 {
        let (front, side, profiles) = (self.front, self.side, self.profiles);
        let mut stature = 0.0f64;
        if let Some(i) = ff.head_top {
            let mut p = self.front_point(i);
            let front_top = match profiles.and_then(|t| t.head_front.as_ref()) {
                Some(dome) => grazed_height(front, p, false, dome, p.y),
                None => p.y,
            };
            stature = front_top;
            if let Some(j) = sf.head_top {
                let ps = ray_plane(side, self.side_norm[j], PlaneAxis::X, p.x);
                stature = match profiles.and_then(|t| t.head_side.as_ref()) {
                    Some(dome) => 0.5 * (front_top + grazed_height(side, ps, true, dome, ps.y)),
                    None => stature.max(ps.y),
                };
            }
            p.y = stature;
            pts.push((LandmarkName::HeadTop, p));
        }
        stature
    }

    /// The crotch, armpits and acromions of the front view: the armpits at the wedge
    /// between arm and trunk; the crotch and acromions moved to where the template's
    /// sections say the grazing rays touch.
    fn front_landmarks(
        &self,
        ff: &FrontFeatures,
        front_plane: &[DVec2],
        stature: f64,
        pts: &mut Vec<(LandmarkName, DVec3)>,
    ) {
        use LandmarkName::*;
        let (front, axis) = (self.front, &self.axis);
        for (name, idx) in [
            (Crotch, ff.crotch),
            (ArmpitLeft, ff.armpit_left),
            (ArmpitRight, ff.armpit_right),
            (AcromionLeft, ff.acromion_left),
            (AcromionRight, ff.acromion_right),
        ] {
            if let Some(i) = idx {
                let mut p = match name {
                    ArmpitLeft | ArmpitRight => wedge_point(front, front_plane, i).map_or_else(
                        || self.front_point(i),
                        |n| lift_front_ray(front, n, axis, self.iters),
                    ),
                    _ => self.front_point(i),
                };
                let section = self.profiles.and_then(|t| match name {
                    Crotch => t.crotch.as_ref(),
                    AcromionLeft => t.acromion_left.as_ref(),
                    AcromionRight => t.acromion_right.as_ref(),
                    _ => None,
                });
                if let Some(section) = section {
                    p.y = grazed_height(front, p, false, section, stature);
                    p.z = axis.at_plane(p.y, p.x).unwrap_or(p.z);
                }
                pts.push((name, p));
            }
        }
    }

    /// The joints from the crotch `c` and the head height `h` (a seventh of the stature):
    /// on the body axis (first table), the thigh roots beside the crotch, and the limbs'
    /// from cuts of the front outline (second table), lifted.
    fn joints(
        &self,
        c: DVec3,
        h: f64,
        ff: &FrontFeatures,
        front_plane: &[DVec2],
        pts: &mut Vec<(LandmarkName, DVec3)>,
    ) {
        use LandmarkName::*;
        let axis = &self.axis;
        let (front, iters) = (self.front, self.iters);
        // First table: joints on the body axis.
        for (name, k) in [
            (Hip, 0.2),
            (Abdomen, 0.5),
            (Waist, 1.0),
            (Chest, 1.5),
            (Neck, 2.4),
            (Head, 2.6),
        ] {
            let y = c.y + k * h;
            let z = axis.at_plane(y, c.x).unwrap_or(c.z);
            pts.push((name, DVec3::new(c.x, y, z)));
        }
        let z = axis.at_plane(c.y, c.x).unwrap_or(c.z);
        pts.push((ThighRootLeft, DVec3::new(c.x + 0.33 * h, c.y, z)));
        pts.push((ThighRootRight, DVec3::new(c.x - 0.33 * h, c.y, z)));
        // Second table: limb joints from cuts, then lifted.
        for (name, p) in analysis::limb_joints(front_plane, ff, c.y, h) {
            if let Some(n) = plane_point_to_normalized(front, p) {
                pts.push((name, lift_front_ray(front, n, axis, iters)));
            }
        }
    }
}

/// The parts of both outlines: the front's from its features, the side's split at the
/// crotch's height (else 45 % of the stature) about the side view's body axis.
fn fill_parts(
    axis: &SideAxis,
    ff: &FrontFeatures,
    crotch: Option<DVec3>,
    stature: f64,
    out: &mut SilhouetteResult,
) {
    analysis::front_parts(&out.front.plane, ff, &mut out.front.parts);
    let crotch_y = crotch.map_or(stature * 0.45, |c| c.y);
    let side_axis_x0 = |v: f64| axis.at(v);
    analysis::side_parts(
        &out.side.plane,
        crotch_y,
        &side_axis_x0,
        &mut out.side.parts,
    );
}

/// The landmarks with their pixels in both views, and the stature, into `out`.
fn record_points(
    front: &Camera,
    side: &Camera,
    pts: &[(LandmarkName, DVec3)],
    stature: f64,
    out: &mut SilhouetteResult,
) {
    let lm = &mut out.landmarks;
    lm.stature_m = stature;
    for (name, p) in pts {
        let (fp, sp) = (front.project(*p), side.project(*p));
        lm.points.push(NamedPoint {
            name: name.as_str().to_string(),
            landmark: *name,
            station: *p,
            front_px: fp,
            side_px: sp,
        });
        if let Some(fp) = fp {
            out.front.landmarks_px.push((*name, fp));
        }
        if let Some(sp) = sp {
            out.side.landmarks_px.push((*name, sp));
        }
    }
}

/// The verdicts that need the landmarks: legs together (no crotch), arms touching the
/// torso (no armpit), and off the mark.
fn landmark_verdicts(
    axis: &SideAxis,
    ff: &FrontFeatures,
    crotch: Option<DVec3>,
    h: f64,
    stature: f64,
    opts: &SilhouetteOptions,
    out: &mut SilhouetteResult,
) {
    let lm = &mut out.landmarks;
    if ff.crotch.is_none() {
        lm.verdicts.push(Verdict::LegsTogether);
    }
    let (l, r) = (ff.armpit_left.is_none(), ff.armpit_right.is_none());
    if l || r {
        lm.verdicts
            .push(Verdict::ArmsTouchingTorso { left: l, right: r });
    }
    // Position on the mark: x from the crotch (else the figure's centre); z from the
    // feet, which are what stands on the mark (the body's axis at the hips lies a few
    // centimetres behind the feet's centre), else from the side axis at hip height.
    let (x, y) = match crotch {
        Some(c) => (c.x, c.y + 0.2 * h),
        None => (ff.center.x, ff.center.y),
    };
    let z = feet_centre_z(&out.side.plane, stature).or_else(|| axis.at_plane(y, x));
    if let Some(z) = z {
        if (x * x + z * z).sqrt() > opts.verdicts.off_mark_m {
            lm.verdicts.push(Verdict::OffMark { dx_m: x, dz_m: z });
        }
    }
}
