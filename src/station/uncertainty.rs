//! How sure the station is of each measurement: an uncertainty in millimetres from what
//! the cameras actually showed (issue 19, item 5).
//!
//! A girth is taken around a section whose width the front view shows and whose depth the
//! side view shows; what lies between the extremes comes from the candidate body. So the
//! error of a girth has three parts, each estimated per frame and then over the window
//! the shown value is smoothed on ([`crate::pipeline::smooth`]):
//! - **the extents**: at the measurement's level (the edges within [`LEVEL_HALF_WINDOW_M`]
//!   of it), each side of each extent was either seen (an edge of that part in that view:
//!   its error is the residual between the edge and the fitted section, per side) or not
//!   (hidden behind an arm or a hand, or the other leg, or outside the mask: it is
//!   interpolated from the nearest edges shown, and known the worse the further they
//!   are, up to what the rest of the body tells about that extent, [`Prior`], from real
//!   people; see [`crate::fit::sections::AxisEvidence::unseen_share`]).
//!   A girth moves by about pi/2 times a change of either extent (an ellipse's perimeter
//!   is about pi (a + b)), so `sigma_extents^2 = (pi/2)^2 (sigma_w^2 + sigma_d^2)`;
//! - **the shape between the extents**: a share of the girth ([`shape_share`]): how far
//!   real people's girths lie from what their breadth and depth say (ANSUR II);
//! - **stability**: the standard deviation of the per-frame values in the window.
//!
//! The reported value is `±2 sigma` (about 95 % if the errors were normal). A measurement
//! whose `±` exceeds its ANSUR II observer tolerance ([`tolerance_mm`]) is flagged as
//! uncertain: the station did not see it well enough to vouch for it.
//!
//! Units: metres for heights and residuals, millimetres for what is reported.

use crate::fit::sections::{AxisEvidence, LevelEvidence, Region};
use crate::measure::Measurements;

/// Edges within this height of a measurement's level count for it, metres (a tape is a
/// few centimetres wide, and one entry of a section chain is about a centimetre).
pub const LEVEL_HALF_WINDOW_M: f64 = 0.02;

/// The girth's share that the section's shape between its extents may be off by
/// (standard deviation, fraction of the girth): over ANSUR II's 6,068 adults, the spread
/// of the circumference about its regression on breadth, depth, their product and sex,
/// over the mean circumference (`python3 tools/ansur_priors.py`: chest 23.6 mm, waist
/// 16.3 mm, buttocks 16.3 mm). Two views show a section's extents, never its shape, and a
/// person is not the candidate body: the shape is known as well as real people's girths
/// follow from their extents. It includes ANSUR II's own measuring noise, so it is an
/// upper bound. ANSUR II has no thigh breadth or depth: the thigh takes the buttocks'
/// share (the nearest section, as round).
pub fn shape_share(key: &str) -> f64 {
    match key {
        "chest_girth" => 0.0231,
        "waist_girth" => 0.0179,
        _ => 0.0159,
    }
}

/// Standard deviation of the stature's own error, mm: the head top and the soles are
/// found on the silhouettes to about this (the landmark evaluation's mean |error| is
/// 0.7-1.2 mm, its worst 2-5 mm).
pub const STATURE_SIGMA_MM: f64 = 1.5;

/// How far an extent can be from what the rest of the body says, mm (standard
/// deviation): the spread of real people's breadth (depth) about its regression on
/// depth (breadth), stature, weight and sex over ANSUR II's 6,068 adults, printed by
/// `python3 tools/ansur_priors.py`. An extent the view did not show is known this well.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Prior {
    pub width_mm: f64,
    pub depth_mm: f64,
}

/// [`Prior`] of a girth's section (chest, waist, hip: ANSUR II's chest, waist and
/// buttock breadths and depths; the thigh, of which ANSUR II has no breadth or depth,
/// takes its girth's spread (17.9 mm) shared between its two extents, 17.9 / (pi/2) /
/// sqrt 2 = 8 mm each).
pub fn prior(key: &str) -> Option<Prior> {
    let (w, d) = match key {
        "chest_girth" => (13.1, 13.6),
        "waist_girth" => (15.1, 15.0),
        "hip_girth" => (13.8, 11.3),
        "thigh_girth_left" | "thigh_girth_right" => (8.0, 8.0),
        _ => return None,
    };
    Some(Prior {
        width_mm: w,
        depth_mm: d,
    })
}

/// ANSUR II's observer tolerance of a measurement, mm (the spread between two trained
/// measurers: the accuracy a station must reach).
pub fn tolerance_mm(key: &str) -> Option<f64> {
    Some(match key {
        "stature" => 6.0,
        "chest_girth" => 14.0,
        "waist_girth" => 12.0,
        "hip_girth" => 12.0,
        "thigh_girth_left" | "thigh_girth_right" => 6.0,
        _ => return None,
    })
}

/// The level and region a measurement is taken at on a measured avatar.
pub fn level_of(key: &str, m: &Measurements) -> Option<(Region, f64)> {
    let l = &m.levels;
    Some(match key {
        "chest_girth" => (Region::Torso, l.chest_m),
        "waist_girth" => (Region::Torso, l.waist_m),
        "hip_girth" => (Region::Torso, l.hip_m),
        "thigh_girth_left" => (Region::LeftThigh, l.thigh_left_m),
        "thigh_girth_right" => (Region::RightThigh, l.thigh_right_m),
        _ => return None,
    })
}

/// Variance (mm^2) of one extent from what its view showed: per side, the edge's residual
/// where seen, where not a share of half the prior's variance that grows with the gap to
/// the nearest edge shown.
fn extent_variance(e: AxisEvidence, prior_mm: f64) -> f64 {
    let seen = e.seen.clamp(0.0, 1.0);
    let rms_mm = e.rms_m * 1000.0;
    2.0 * (seen * rms_mm * rms_mm + e.unseen_share.clamp(0.0, 1.0) * 0.5 * prior_mm * prior_mm)
}

/// The standard deviation (mm) of a girth of `girth_mm` from one frame's evidence at its
/// level; without evidence (no dense sections, level outside every chain) both extents
/// count as unseen.
pub fn frame_sigma_mm(key: &str, girth_mm: f64, evidence: Option<LevelEvidence>) -> f64 {
    let Some(p) = prior(key) else {
        return STATURE_SIGMA_MM;
    };
    let (vw, vd) = match evidence {
        Some(e) => (
            extent_variance(e.width, p.width_mm),
            extent_variance(e.depth, p.depth_mm),
        ),
        None => (p.width_mm * p.width_mm, p.depth_mm * p.depth_mm),
    };
    let half_pi = std::f64::consts::FRAC_PI_2;
    let shape = shape_share(key) * girth_mm;
    (half_pi * half_pi * (vw + vd) + shape * shape).sqrt()
}

/// How far a section's depth can be from what the front view and the stature show, mm
/// (root mean square). A fit without the side view takes the depth from the shape
/// library's body for those widths and that stature, so this is how far real people's
/// depths lie from the library's depth-given-breadth-and-stature line: over ANSUR II's
/// 6,068 adults against the library's 252 bodies (`python3 tools/ansur_priors.py`,
/// "front view alone", "rms about library line"). It counts the mean offset between
/// ANSUR and the library (chest +41.8, waist -7.8, hip +14.5 mm) with the spread about
/// it (25.3, 17.3, 18.9 mm): the offset is partly one of definitions (calipers at
/// ANSUR's landmarks against section extents at the spec's levels) and partly the
/// library's bodies being shallower than people, and one view cannot tell which. ANSUR
/// II has no thigh breadth or depth: the thigh takes its girth's spread given hip
/// breadth and stature (33.0 mm), all as depth, over pi/2.
pub fn depth_prior_one_view_mm(key: &str) -> Option<f64> {
    Some(match key {
        "chest_girth" => 48.9,
        "waist_girth" => 19.0,
        "hip_girth" => 23.8,
        "thigh_girth_left" | "thigh_girth_right" => 21.0,
        _ => return None,
    })
}

/// [`frame_sigma_mm`] of a frame fitted without the side view: the width as the front
/// view showed it, the depth unseen and known as well as [`depth_prior_one_view_mm`]
/// says (whatever the evidence says of the depth is the candidate's, not a view's).
pub fn frame_sigma_one_view_mm(key: &str, girth_mm: f64, evidence: Option<LevelEvidence>) -> f64 {
    let (Some(p), Some(depth_mm)) = (prior(key), depth_prior_one_view_mm(key)) else {
        return STATURE_SIGMA_MM;
    };
    let vw = match evidence {
        Some(e) => extent_variance(e.width, p.width_mm),
        None => p.width_mm * p.width_mm,
    };
    let half_pi = std::f64::consts::FRAC_PI_2;
    let shape = shape_share(key) * girth_mm;
    (half_pi * half_pi * (vw + depth_mm * depth_mm) + shape * shape).sqrt()
}

/// [`hip_level_sigma_mm`] from what the side view showed rather than from the avatar:
/// the hip is where the person's back reaches furthest, and where the trunk's back edges
/// (`back_edges`, (height, z) in metres, as the fit took them) lie within `resolution_m`
/// of the furthest one between the avatar's crotch and waist levels, the person's
/// furthest point may be at any of those heights, though the avatar's back, smoothed
/// over a few centimetres, reaches furthest at one. The girths the avatar has at those
/// heights, against the reported one: half the largest difference is the sigma. 0 with
/// no edge in the band.
pub fn hip_seen_level_sigma_mm(
    m: &Measurements,
    back_edges: &[(f64, f64)],
    resolution_m: f64,
) -> f64 {
    level_openness_sigma_mm(m, back_edges.iter().copied(), resolution_m)
}

/// Half the largest difference from the reported hip girth of the avatar's girths at the
/// heights of `backs` ((height, back z), metres) whose back lies within `resolution_m` of
/// the furthest one between the crotch and waist levels; 0 with none in that band.
fn level_openness_sigma_mm(
    m: &Measurements,
    backs: impl Iterator<Item = (f64, f64)> + Clone,
    resolution_m: f64,
) -> f64 {
    let l = &m.levels;
    let in_band = |&(y, _): &(f64, f64)| y >= l.crotch_m && y <= l.waist_m;
    let Some(back) = backs
        .clone()
        .filter(in_band)
        .map(|(_, z)| z)
        .min_by(f64::total_cmp)
    else {
        return 0.0;
    };
    let worst = backs
        .filter(in_band)
        .filter(|&(_, z)| z <= back + resolution_m)
        .filter_map(|(y, _)| profile_girth_at(m, y))
        .map(|g| (g - m.hip_girth_mm).abs())
        .fold(0.0, f64::max);
    0.5 * worst
}

/// The avatar's torso girth at the profile sample nearest height `y` (the lower of two
/// as near); the profile runs upward.
fn profile_girth_at(m: &Measurements, y: f64) -> Option<f64> {
    let p = &m.torso_profile;
    let i = p.partition_point(|s| s.height_m < y);
    let below = i.checked_sub(1).and_then(|j| p.get(j));
    match (below, p.get(i)) {
        (Some(a), Some(b)) if (b.height_m - y) < (y - a.height_m) => Some(b.girth_mm),
        (Some(a), _) => Some(a.girth_mm),
        (None, b) => b.map(|b| b.girth_mm),
    }
}

/// The hip girth the station reports (mm): its estimate of the spec's hip girth of the
/// person, whose level is where the torso reaches furthest back. The side view shows the
/// back to about a pixel (`resolution_m`, the side camera's pixel at the subject), and on
/// a flat buttock the avatar's back lies within that of its furthest point over
/// centimetres of height where the girth changes fast: the girth at the avatar's one
/// furthest point is then a draw from that range (a development body's level fell 6 cm,
/// to the thighs' tops, +112 mm). So each of the avatar's torso profile samples between
/// the crotch and waist levels is weighted by its chance of being the person's furthest
/// point, `exp(-(z - z_back) / resolution_m)` (the argmin of levels whose backs carry
/// independent Gumbel errors of that scale), and the girth is the weighted mean. The
/// spec's girth at the avatar's own level with no profile or no resolution.
pub fn hip_girth_over_levels_mm(m: &Measurements, resolution_m: f64) -> f64 {
    let l = &m.levels;
    let band = || {
        m.torso_profile
            .iter()
            .filter(|s| s.height_m >= l.crotch_m && s.height_m <= l.waist_m)
            .filter(|s| s.back_z_m.is_finite() && s.girth_mm.is_finite())
    };
    let Some(back) = band().map(|s| s.back_z_m).min_by(f64::total_cmp) else {
        return m.hip_girth_mm;
    };
    if !(resolution_m > 0.0) {
        return m.hip_girth_mm;
    }
    let (mut sum_w, mut sum_wg) = (0.0, 0.0);
    for s in band() {
        let w = (-(s.back_z_m - back) / resolution_m).exp();
        sum_w += w;
        sum_wg += w * s.girth_mm;
    }
    sum_wg / sum_w
}

/// The standard deviation (mm) the hip's level adds to its girth. The hip is taken
/// where the torso reaches furthest back (the spec's definition), and on a flat buttock
/// the back lies within a pixel of its furthest point over several centimetres of
/// height, where the girth changes fast: the side view cannot say where in that range
/// the person's furthest point is. Over the avatar's torso profile between the crotch
/// and waist levels, the heights whose back lies within `resolution_m` (the side
/// camera's pixel at the subject) of the furthest give girths up to this far from the
/// reported one; half of it is the sigma (the `±` then spans the range). 0 without a
/// profile.
pub fn hip_level_sigma_mm(m: &Measurements, resolution_m: f64) -> f64 {
    level_openness_sigma_mm(
        m,
        m.torso_profile.iter().map(|s| (s.height_m, s.back_z_m)),
        resolution_m,
    )
}

/// The standard deviation (mm) of a torso girth whose tape loop takes in more than the
/// trunk: a convex section's perimeter is at most its bounding box's, `2 (w + d)`, so a
/// girth beyond that for the trunk's own breadth `w` and depth `d` at the level (the
/// avatar's torso vertices, `trunk_m`) went around something else too, an arm the avatar
/// holds against its side. At least the excess is not the person's trunk: it is the
/// sigma. 0 when the girth is within the bound or the extents are unknown.
pub fn loop_excess_sigma_mm(girth_mm: f64, trunk_m: Option<(f64, f64)>) -> f64 {
    let Some((w, d)) = trunk_m else {
        return 0.0;
    };
    (girth_mm - 2000.0 * (w + d)).max(0.0)
}

/// The reported `±` (mm, two standard deviations) from the window's per-frame sigmas
/// (their trimmed mean, `sigma_frame_mm`) and the spread of its values (`values_sd_mm`).
pub fn reported_pm_mm(sigma_frame_mm: f64, values_sd_mm: f64) -> f64 {
    2.0 * (sigma_frame_mm * sigma_frame_mm + values_sd_mm * values_sd_mm).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Evidence with the given shown fractions, residual, and unshown edges far from any
    /// shown one.
    fn ev(seen_w: f64, seen_d: f64, rms_mm: f64) -> LevelEvidence {
        let axis = |seen: f64| AxisEvidence {
            seen,
            rms_m: rms_mm / 1000.0,
            unseen_share: 1.0 - seen,
        };
        LevelEvidence {
            width: axis(seen_w),
            depth: axis(seen_d),
        }
    }

    #[test]
    fn an_unseen_edge_between_close_neighbours_costs_little() {
        let mut near = ev(1.0, 0.5, 1.0);
        near.depth.unseen_share = 0.5 * 0.1f64.powi(2);
        let far = ev(1.0, 0.5, 1.0);
        let (n, f) = (
            frame_sigma_mm("hip_girth", 950.0, Some(near)),
            frame_sigma_mm("hip_girth", 950.0, Some(far)),
        );
        // Beyond the shape term (1.59 % of 950 mm): under 6 mm near, over 12 mm far.
        let extents = |total: f64| (total * total - (0.0159f64 * 950.0).powi(2)).sqrt();
        assert!(extents(n) < 6.0 && extents(f) > 12.0, "{n} {f}");
    }

    #[test]
    fn a_hidden_depth_widens_the_girth_by_the_prior() {
        let seen = frame_sigma_mm("waist_girth", 800.0, Some(ev(1.0, 1.0, 1.0)));
        let hidden = frame_sigma_mm("waist_girth", 800.0, Some(ev(1.0, 0.0, 1.0)));
        // Both extents seen to 1 mm a side: shape (1.79 % of 800 mm) and 1.57 * 2 mm.
        let shape = 0.0179 * 800.0;
        assert!(
            (seen - (shape * shape + (std::f64::consts::FRAC_PI_2 * 2.0).powi(2)).sqrt()).abs()
                < 0.05
        );
        // The depth unseen: its prior (15 mm) takes over, so the waist's sigma passes 20 mm.
        assert!(hidden > 20.0 && hidden < 30.0, "{hidden}");
        // No evidence at all is wider still.
        assert!(frame_sigma_mm("waist_girth", 800.0, None) > hidden);
    }

    #[test]
    fn residuals_widen_and_stability_adds() {
        let tight = frame_sigma_mm("chest_girth", 950.0, Some(ev(1.0, 1.0, 0.5)));
        let loose = frame_sigma_mm("chest_girth", 950.0, Some(ev(1.0, 1.0, 4.0)));
        // Four sides at 4 mm against 0.5 mm: (pi/2)^2 * 4 * (16 - 0.25) mm^2 more variance.
        let added = loose * loose - tight * tight;
        assert!(
            (added - 2.4674 * 4.0 * 15.75).abs() < 0.5,
            "{tight} {loose}"
        );
        assert!((reported_pm_mm(3.0, 4.0) - 10.0).abs() < 1e-9);
        assert_eq!(frame_sigma_mm("stature", 1700.0, None), STATURE_SIGMA_MM);
    }

    #[test]
    fn one_view_is_wider_than_two_even_with_the_depth_unseen() {
        for key in [
            "chest_girth",
            "waist_girth",
            "hip_girth",
            "thigh_girth_left",
        ] {
            let both = frame_sigma_mm(key, 900.0, Some(ev(1.0, 1.0, 1.0)));
            let hidden = frame_sigma_mm(key, 900.0, Some(ev(1.0, 0.0, 1.0)));
            let one = frame_sigma_one_view_mm(key, 900.0, Some(ev(1.0, 1.0, 1.0)));
            assert!(
                one > hidden && hidden > both,
                "{key}: {one} {hidden} {both}"
            );
        }
        assert_eq!(
            frame_sigma_one_view_mm("stature", 1700.0, None),
            STATURE_SIGMA_MM
        );
    }

    /// A back within a pixel of its furthest over several heights leaves the hip's level,
    /// and so its girth, open over that range; a clear furthest point does not.
    #[test]
    fn a_flat_buttock_widens_the_hip_by_the_girths_its_level_may_take() {
        let library = crate::body::ShapeLibrary::shared().expect("the bundled shape library");
        let mut m = crate::measure::measure(&library.template().mesh).expect("measured");
        let (crotch, waist) = (m.levels.crotch_m, m.levels.waist_m);
        let sample = |k: usize, back_mm: f64, girth_mm: f64| crate::measure::GirthSample {
            height_m: crotch + (waist - crotch) * k as f64 / 10.0,
            girth_mm,
            back_z_m: -0.2 - back_mm / 1000.0,
        };
        m.hip_girth_mm = 1000.0;
        // A clear furthest point (k = 3): the rest 5 mm or more in front of it.
        m.torso_profile = (0..=10)
            .map(|k| sample(k, if k == 3 { 5.0 } else { 0.0 }, 1030.0 - 10.0 * k as f64))
            .collect();
        assert_eq!(hip_level_sigma_mm(&m, 0.003), 0.0);
        // Flat from k = 2 to k = 6 (within 1 mm), the girth falling 10 mm a step: the
        // reported 1000 mm may be 40 mm smaller (k = 6 against k = 2).
        m.torso_profile = (0..=10)
            .map(|k| {
                let back = if (2..=6).contains(&k) {
                    5.0 - 0.2 * k as f64
                } else {
                    0.0
                };
                sample(k, back, 1020.0 - 10.0 * k as f64)
            })
            .collect();
        assert!((hip_level_sigma_mm(&m, 0.003) - 20.0).abs() < 1e-9);
        // Samples above the waist do not count.
        m.torso_profile.push(crate::measure::GirthSample {
            height_m: waist + 0.05,
            girth_mm: 500.0,
            back_z_m: -0.3,
        });
        assert!((hip_level_sigma_mm(&m, 0.003) - 20.0).abs() < 1e-9);
    }

    /// The side view's back edges, not the avatar's back, say where the hip may be: a
    /// ridge the avatar smoothed away, seen at the gluteal fold, opens the hip down there.
    #[test]
    fn a_back_seen_furthest_where_the_avatar_is_not_widens_the_hip() {
        let library = crate::body::ShapeLibrary::shared().expect("the bundled shape library");
        let mut m = crate::measure::measure(&library.template().mesh).expect("measured");
        let (crotch, waist) = (m.levels.crotch_m, m.levels.waist_m);
        let at = |k: usize| crotch + (waist - crotch) * k as f64 / 10.0;
        m.hip_girth_mm = 1000.0;
        m.levels.hip_m = at(5);
        // The avatar's girth falls 10 mm a step from 1050 at the crotch.
        m.torso_profile = (0..=10)
            .map(|k| crate::measure::GirthSample {
                height_m: at(k),
                girth_mm: 1050.0 - 10.0 * k as f64,
                back_z_m: -0.2,
            })
            .collect();
        // Seen: the back furthest at k = 5 alone.
        let clear: Vec<(f64, f64)> = (0..=10)
            .map(|k| (at(k), if k == 5 { -0.21 } else { -0.2 }))
            .collect();
        assert_eq!(hip_seen_level_sigma_mm(&m, &clear, 0.003), 0.0);
        // Seen: within 2 mm of the furthest at k = 1 (a ridge at the fold) and k = 5.
        let ridge: Vec<(f64, f64)> = (0..=10)
            .map(|k| {
                (
                    at(k),
                    if k == 1 {
                        -0.208
                    } else if k == 5 {
                        -0.21
                    } else {
                        -0.2
                    },
                )
            })
            .collect();
        // At k = 1 the avatar's girth is 1040: 40 mm from the reported 1000.
        assert!((hip_seen_level_sigma_mm(&m, &ridge, 0.003) - 20.0).abs() < 1e-9);
        // Edges outside the crotch-waist band and no edges at all count for nothing.
        let above = vec![(waist + 0.05, -0.3), (at(5), -0.21)];
        assert_eq!(hip_seen_level_sigma_mm(&m, &above, 0.003), 0.0);
        assert_eq!(hip_seen_level_sigma_mm(&m, &[], 0.003), 0.0);
    }

    /// The reported hip: the girth at a clear furthest-back level is that level's; on a
    /// back flat within a fraction of a pixel, the girths of the whole flat stretch count
    /// alike (the avatar's own furthest point there is a draw, not a measurement).
    #[test]
    fn a_flat_back_reports_the_girth_over_its_stretch_a_clear_one_its_own() {
        let library = crate::body::ShapeLibrary::shared().expect("the bundled shape library");
        let mut m = crate::measure::measure(&library.template().mesh).expect("measured");
        let (crotch, waist) = (m.levels.crotch_m, m.levels.waist_m);
        let at = |k: usize| crotch + (waist - crotch) * k as f64 / 10.0;
        let profile = |back: &dyn Fn(usize) -> f64| -> Vec<crate::measure::GirthSample> {
            (0..=10)
                .map(|k| crate::measure::GirthSample {
                    height_m: at(k),
                    girth_mm: 1100.0 - 10.0 * k as f64,
                    back_z_m: back(k),
                })
                .collect()
        };
        // A clear buttock at k = 5, 20 mm behind the rest (five pixels of 4 mm).
        m.torso_profile = profile(&|k| if k == 5 { -0.22 } else { -0.2 });
        m.hip_girth_mm = 1050.0;
        let clear = hip_girth_over_levels_mm(&m, 0.004);
        assert!((clear - 1050.0).abs() < 0.5, "{clear}");
        // Flat within 0.1 mm from k = 1 to k = 9, the avatar's furthest at k = 1 (the
        // thighs' tops, 1090): the stretch's girths alike, about their mean 1050.
        m.torso_profile = profile(&|k| match k {
            1 => -0.2101,
            2..=9 => -0.2100,
            _ => -0.19,
        });
        m.hip_girth_mm = 1090.0;
        let flat = hip_girth_over_levels_mm(&m, 0.004);
        assert!((flat - 1050.0).abs() < 1.0, "{flat}");
        // A finer camera tells 0.1 mm apart better, and leans further to k = 1, though
        // not to it alone.
        let fine = hip_girth_over_levels_mm(&m, 0.00005);
        assert!(fine > flat + 10.0 && fine < 1090.0, "{fine}");
        // Samples above the waist do not count; without a resolution or a profile the
        // girth at the avatar's level stays.
        m.torso_profile.push(crate::measure::GirthSample {
            height_m: waist + 0.05,
            girth_mm: 500.0,
            back_z_m: -0.3,
        });
        assert!((hip_girth_over_levels_mm(&m, 0.004) - flat).abs() < 1e-9);
        assert_eq!(hip_girth_over_levels_mm(&m, 0.0), 1090.0);
        m.torso_profile.clear();
        assert_eq!(hip_girth_over_levels_mm(&m, 0.004), 1090.0);
    }

    #[test]
    fn a_loop_longer_than_the_trunks_box_says_by_how_much() {
        // A 300 x 250 mm trunk: its girth is at most 1100 mm.
        assert_eq!(loop_excess_sigma_mm(950.0, Some((0.30, 0.25))), 0.0);
        assert!((loop_excess_sigma_mm(1450.0, Some((0.30, 0.25))) - 350.0).abs() < 1e-9);
        assert_eq!(loop_excess_sigma_mm(1450.0, None), 0.0);
    }

    #[test]
    fn every_reported_girth_has_a_prior_a_tolerance_and_a_level() {
        for key in crate::station::MEASUREMENT_KEYS {
            assert!(tolerance_mm(key).is_some(), "{key}");
            if key != "stature" {
                assert!(prior(key).is_some(), "{key}");
            }
        }
    }
}
