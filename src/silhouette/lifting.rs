//! Lifting both views' landmarks into the station frame and filling the silhouette
//! result's parts, pixels and landmark verdicts (the geometry is [`crate::landmarks::lift`]'s).

use super::{SilhouetteOptions, SilhouetteResult};
use crate::camera::StationCalibration;
use crate::landmarks::analysis::{self, FrontFeatures, SideFeatures};
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
    use LandmarkName::*;
    let (front, side) = (&calib.front, &calib.side);
    let axis = SideAxis::new(&out.side.plane, side);
    let iters = opts.lift_iterations;
    let lift_idx = |i: usize| lift_front_ray(front, front_norm[i], &axis, iters);
    let mut pts: Vec<(LandmarkName, DVec3)> = Vec::new();

    // Stature: the head top of both views. Each view's ray over the head grazes the
    // dome's near slope, so with the template's dome both are moved down onto the top
    // and averaged; without it the higher is taken.
    let profiles = opts.template_profiles.as_ref();
    let mut stature = 0.0f64;
    if let Some(i) = ff.head_top {
        let mut p = lift_idx(i);
        let front_top = match profiles.and_then(|t| t.head_front.as_ref()) {
            Some(dome) => grazed_height(front, p, false, dome, p.y),
            None => p.y,
        };
        stature = front_top;
        if let Some(j) = sf.head_top {
            let ps = ray_plane(side, side_norm[j], PlaneAxis::X, p.x);
            stature = match profiles.and_then(|t| t.head_side.as_ref()) {
                Some(dome) => 0.5 * (front_top + grazed_height(side, ps, true, dome, ps.y)),
                None => stature.max(ps.y),
            };
        }
        p.y = stature;
        pts.push((HeadTop, p));
    }
    let h = stature / 7.0;
    for (name, idx) in [
        (Crotch, ff.crotch),
        (ArmpitLeft, ff.armpit_left),
        (ArmpitRight, ff.armpit_right),
        (AcromionLeft, ff.acromion_left),
        (AcromionRight, ff.acromion_right),
    ] {
        if let Some(i) = idx {
            let mut p = match name {
                ArmpitLeft | ArmpitRight => wedge_point(front, &out.front.plane, i)
                    .map_or_else(|| lift_idx(i), |n| lift_front_ray(front, n, &axis, iters)),
                _ => lift_idx(i),
            };
            let section = profiles.and_then(|t| match name {
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
    let crotch = pts.iter().find(|p| p.0 == Crotch).map(|p| p.1);
    if let Some(c) = crotch {
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
        for (name, p) in analysis::limb_joints(&out.front.plane, ff, c.y, h) {
            if let Some(n) = plane_point_to_normalized(front, p) {
                pts.push((name, lift_front_ray(front, n, &axis, iters)));
            }
        }
    }

    // Parts.
    analysis::front_parts(&out.front.plane, ff, &mut out.front.parts);
    let crotch_y = crotch.map_or(stature * 0.45, |c| c.y);
    let side_axis_x0 = |v: f64| axis.at(v);
    analysis::side_parts(
        &out.side.plane,
        crotch_y,
        &side_axis_x0,
        &mut out.side.parts,
    );

    // Points with their pixels.
    let lm = &mut out.landmarks;
    lm.stature_m = stature;
    for (name, p) in &pts {
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

    // Verdicts that need the landmarks.
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
