//! The surface landmarks of a standing body (method.md section 1 steps 2-4): crotch,
//! armpits and acromions on horizontal sections, and the head top.

use super::{
    bisect, has_side_loop, loops_at, spans, Analysis, Side, ACROMION_G_X_H, ACROMION_G_Y_H,
    BISECT_TOL_M, ENVELOPE_BIN_M, HEADS_PER_STATURE, SCAN_STEP_M,
};
use crate::body::BodyError;
use crate::mesh::TriMesh;
use glam::{DVec2, DVec3};

/// The surface landmarks of a body mesh alone (method.md section 1 steps 2-4, on
/// horizontal sections as described in the module docs), without the skeleton or the
/// rigid parts: what [`prepare`] finds first, and what the station reports for a fitted
/// avatar (the same definitions as the template's, so a fitted body and its truth are
/// compared like with like).
///
/// # Errors
/// A mesh that is not a standing person in an A-pose: no crotch, an arm that never
/// separates from the torso, no shoulder envelope.
pub fn surface_landmarks(mesh: &TriMesh) -> Result<SurfaceLandmarks, BodyError> {
    mesh.validate().map_err(BodyError::Prepare)?;
    let bb = mesh
        .bounds()
        .ok_or_else(|| BodyError::Prepare("empty mesh".into()))?;
    let stature = bb.size().y;
    if !(0.5..=3.0).contains(&stature) {
        return Err(BodyError::Prepare(format!(
            "stature {stature:.3} m is not a person's"
        )));
    }
    let floor_y = bb.min.y;
    let h = stature / HEADS_PER_STATURE;
    let cx = bb.center().x;
    let top_i = (0..mesh.vertex_count())
        .max_by(|&a, &b| mesh.positions[a].y.total_cmp(&mesh.positions[b].y))
        .unwrap_or(0);
    let top = mesh.positions[top_i];
    let (crotch_x, crotch_y) = find_crotch(mesh, floor_y, stature, cx)?;
    let mut an = Analysis {
        mesh,
        h,
        crotch: DVec3::new(crotch_x, crotch_y, 0.0),
        top,
    };
    an.crotch.z = an.axis_z(crotch_y + 2.0 * BISECT_TOL_M);
    let armpits = find_armpits(&an)?;
    let acromions = find_acromions(&an, &armpits)?;
    Ok(SurfaceLandmarks {
        stature,
        floor_y,
        top_index: top_i,
        top,
        crotch: an.crotch,
        armpits,
        acromions,
    })
}

/// The crotch (step 2), `(x, y)`: the lowest height where a loop spans the body's axis
/// `cx`, scanning up the legs, then midway between the inner edges of the two thighs.
fn find_crotch(
    mesh: &TriMesh,
    floor_y: f64,
    stature: f64,
    cx: f64,
) -> Result<(f64, f64), BodyError> {
    let any_span = |y: f64| loops_at(mesh, y).iter().any(|l| spans(l, cx));
    let mut y = floor_y + 0.3 * stature;
    let y_end = floor_y + 0.7 * stature;
    while y < y_end && !any_span(y) {
        y += SCAN_STEP_M;
    }
    if y >= y_end || y <= floor_y + 0.3 * stature {
        return Err(BodyError::Prepare(
            "no crotch: found no two separate legs joining into a torso".into(),
        ));
    }
    let crotch_y = bisect(y - SCAN_STEP_M, y, any_span);
    // Crotch x: between the inner edges of the two thighs just below.
    let below = loops_at(mesh, crotch_y - 2.0 * BISECT_TOL_M);
    let thigh = |sign: f64| {
        below
            .iter()
            .filter(|l| (l.centroid.x - cx) * sign > 0.0)
            .max_by(|a, b| a.area.total_cmp(&b.area))
    };
    let crotch_x = match (thigh(1.0), thigh(-1.0)) {
        (Some(l), Some(r)) => 0.5 * (l.xmin + r.xmax),
        _ => cx,
    };
    Ok((crotch_x, crotch_y))
}

/// The armpits (step 3), left and right: scanning down from the neck, where an arm
/// separates from the torso, midway between the torso's edge and the arm's.
fn find_armpits(an: &Analysis<'_>) -> Result<[DVec3; 2], BodyError> {
    let (mesh, h) = (an.mesh, an.h);
    let (crotch_x, crotch_y) = (an.crotch.x, an.crotch.y);
    let mut armpits = [DVec3::ZERO; 2];
    for (k, side) in [Side::Left, Side::Right].into_iter().enumerate() {
        let start = crotch_y + 2.7 * h;
        let stop = crotch_y + 0.5 * h;
        let mut y = start;
        while y > stop && !has_side_loop(mesh, y, crotch_x, side) {
            y -= SCAN_STEP_M;
        }
        if y <= stop {
            return Err(BodyError::Prepare(format!(
                "no {side:?} armpit: the arm never separates from the torso"
            )));
        }
        let ay = bisect(y, y + SCAN_STEP_M, |t| {
            has_side_loop(mesh, t, crotch_x, side)
        });
        let loops = loops_at(mesh, ay - 2.0 * BISECT_TOL_M);
        let s = side.sign();
        let torso_edge = loops
            .iter()
            .filter(|l| spans(l, crotch_x))
            .map(|l| if s > 0.0 { l.xmax } else { l.xmin })
            .fold(crotch_x, |a, b| if (b - a) * s > 0.0 { b } else { a });
        let arm_edge = loops
            .iter()
            .filter(|l| !spans(l, crotch_x) && (l.centroid.x - crotch_x) * s > 0.0)
            .map(|l| if s > 0.0 { l.xmin } else { l.xmax })
            .fold(torso_edge, |a, b| if (b - a) * s > 0.0 { b } else { a });
        armpits[k] = DVec3::new(0.5 * (torso_edge + arm_edge), ay, an.axis_z(ay));
    }
    Ok(armpits)
}

/// The acromions (step 4), left and right: the point of the front upper envelope above
/// each armpit closest to the reference point g.
fn find_acromions(an: &Analysis<'_>, armpits: &[DVec3; 2]) -> Result<[DVec3; 2], BodyError> {
    let (mesh, h) = (an.mesh, an.h);
    let (crotch_x, crotch_y) = (an.crotch.x, an.crotch.y);
    let mut acromions = [DVec3::ZERO; 2];
    for (k, side) in [Side::Left, Side::Right].into_iter().enumerate() {
        let s = side.sign();
        let nbins = ((1.5 * h) / ENVELOPE_BIN_M).ceil() as usize;
        let mut env: Vec<Option<DVec3>> = vec![None; nbins];
        for p in &mesh.positions {
            let d = (p.x - crotch_x) * s;
            if d < 0.0 || p.y < armpits[k].y {
                continue;
            }
            let b = (d / ENVELOPE_BIN_M) as usize;
            if b < nbins && env[b].is_none_or(|q| p.y > q.y) {
                env[b] = Some(*p);
            }
        }
        let g = DVec2::new(
            crotch_x + s * ACROMION_G_X_H * h,
            crotch_y + ACROMION_G_Y_H * h,
        );
        acromions[k] = env
            .iter()
            .flatten()
            .min_by(|a, b| {
                (DVec2::new(a.x, a.y) - g)
                    .length()
                    .total_cmp(&(DVec2::new(b.x, b.y) - g).length())
            })
            .copied()
            .ok_or_else(|| BodyError::Prepare(format!("no {side:?} shoulder envelope")))?;
    }
    Ok(acromions)
}

/// What [`surface_landmarks`] finds (station frame, metres).
#[derive(Clone, Debug, PartialEq)]
pub struct SurfaceLandmarks {
    pub stature: f64,
    /// Lowest point of the mesh (the soles).
    pub floor_y: f64,
    /// The highest vertex (top of the head).
    pub top_index: usize,
    pub top: DVec3,
    pub crotch: DVec3,
    /// Left, right.
    pub armpits: [DVec3; 2],
    /// Left, right.
    pub acromions: [DVec3; 2],
}

impl SurfaceLandmarks {
    /// Named points as the station names them (`crotch`, `armpit_left`, ...,
    /// `head_top`).
    pub fn named(&self) -> [(&'static str, DVec3); 6] {
        [
            ("head_top", self.top),
            ("crotch", self.crotch),
            ("armpit_left", self.armpits[0]),
            ("armpit_right", self.armpits[1]),
            ("acromion_left", self.acromions[0]),
            ("acromion_right", self.acromions[1]),
        ]
    }
}
