//! The shopper's turn on the mark, read from the toes in the side view (issue 19, item 4).
//!
//! A shopper standing a few degrees turned on the mark puts one leg ahead of the other
//! in depth: a turn by `theta` about the vertical moves a point at `x` by `-x sin theta`
//! along z. The side camera sees the two legs over each other, and the fit gives each
//! edge of their union to the leg of the candidate that reaches out to it. An unturned
//! candidate always gives both edges to the near leg (perspective makes it the larger), so
//! with the far leg ahead (a turn toward the side camera) the union's depth, one leg's
//! depth plus the offset, became both legs' depth: thighs read 3-5 mm too large a degree.
//!
//! The side view shows the turn at the floor. The far foot stands further from the side
//! camera, so its toes appear higher in the picture than the near foot's, above the near
//! foot's toe cap: each foot's toe front is seen on its own. Scanned along the line at a
//! few heights over the floor on each foot's own vertical plane (`x` of that foot, from
//! the candidate posed to the front view), the first silhouette pixel from the front is
//! that foot's toe front, with the side camera's full projection (no perspective scale to
//! undo). The far toe's offset ahead of the near one is matched against the candidate's
//! own feet turned (feet pointing outward change a turned pair's offset: not simply the
//! feet's separation times the sine of the turn). The candidate is then turned by that
//! before its controls are chosen, so the legs' union in the side view is the union of
//! legs that stand like the shopper's, and its sections are mapped in its own axes
//! ([`super::sections`], turned back and forward again).
//!
//! A foot plane whose toe row is not clear of the near foot's toe cap (a side camera
//! mounted too low, feet too close together), toes the mask lost (shoes the colour of the
//! floor) or a turn beyond what the stance checks let through give no estimate: the
//! candidate stays unturned, as before.
//!
//! Units: metres, station frame (+Y up, +Z toward the front camera, +X the subject's
//! left); angles in radians, positive turning the front (+Z) toward +X.

use super::correspond::MaskRef;
use super::shape::first_inside;
use crate::camera::Camera;
use glam::DVec3;

/// Scans per foot, evenly from its sole up to [`SCAN_TOP_M`] over it: the toe's tip lies
/// in between, on a shoe or a bare foot.
const SCAN_HEIGHTS: usize = 11;
/// Top of the scans over the candidate's sole, metres.
const SCAN_TOP_M: f64 = 0.04;
/// How far in front of and behind the candidate's toe the scan runs, metres: a foot placed
/// within the mark's tolerance.
const SCAN_REACH_M: f64 = 0.12;
/// The far foot's toe row must lie this many pixels clear of the near foot's toe cap.
const CLEAR_PX: f64 = 3.0;
/// Margin over the near foot's own toe-cap height when checking that clearance, metres
/// (a shoe is taller than the candidate's bare foot).
const TOE_CAP_MARGIN_M: f64 = 0.02;
/// Depth of a foot's toe tip, metres.
const TIP_DEPTH_M: f64 = 0.01;
/// Fewest feet' separation (metres, across the side camera's view) that defines a turn.
pub const MIN_SEPARATION_M: f64 = 0.08;
/// Shortest near foot seen (toe front to heel back), a share of the candidate's foot. A
/// pale shoe's heel lost against the floor leaves the toes where they are (seen on the
/// development sets: 0.84-0.89, the turn read within 2.3 degrees, better than none);
/// a foot seen at under 0.8 has lost 5 cm or more, toes as likely as heel (0.46 and
/// 0.64 there: pale bare feet whose toes the mask lost, a turn read 9 degrees wrong).
pub const MIN_LENGTH_SHARE: f64 = 0.8;
/// Fewest clear scans per foot.
pub const MIN_HEIGHTS: usize = 2;
/// Largest turn believed, radians (10 degrees): beyond, a foot placed ahead of the other
/// or a lost toe, not a turn of the body.
pub const MAX_TURN_RAD: f64 = 10.0 * std::f64::consts::PI / 180.0;

/// One foot of the posed candidate: its vertical plane, sole and toe.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Foot {
    /// Mean x of the foot's toe tip (its vertices within [`TIP_DEPTH_M`] of its front):
    /// the plane its toe front is scanned on.
    pub x: f64,
    /// Sole height (lowest vertex).
    pub sole_y: f64,
    /// Front of the toes (largest z).
    pub toe_z: f64,
    /// Height over the sole of the foot's vertices within 3 cm of its toe front.
    pub toe_cap_m: f64,
    /// Mean x of the heel (vertices within [`TIP_DEPTH_M`] of its back).
    pub heel_x: f64,
    /// Back of the heel (smallest z).
    pub heel_z: f64,
}

impl Foot {
    /// The foot of these vertices; None for fewer than 3.
    fn of(points: impl Iterator<Item = DVec3> + Clone) -> Option<Foot> {
        let n = points.clone().count();
        if n < 3 {
            return None;
        }
        let sole_y = points.clone().map(|p| p.y).fold(f64::MAX, f64::min);
        let toe_z = points.clone().map(|p| p.z).fold(f64::MIN, f64::max);
        let tip = points.clone().filter(|p| p.z > toe_z - TIP_DEPTH_M);
        let x = tip.clone().map(|p| p.x).sum::<f64>() / tip.count().max(1) as f64;
        let heel_z = points.clone().map(|p| p.z).fold(f64::MAX, f64::min);
        let heel = points.clone().filter(|p| p.z < heel_z + TIP_DEPTH_M);
        let heel_x = heel.clone().map(|p| p.x).sum::<f64>() / heel.count().max(1) as f64;
        let cap = points
            .filter(|p| p.z > toe_z - 0.03)
            .map(|p| p.y)
            .fold(f64::MIN, f64::max);
        Some(Foot {
            x,
            sole_y,
            toe_z,
            toe_cap_m: cap - sole_y,
            heel_x,
            heel_z,
        })
    }
}

/// What the toes showed.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TurnEstimate {
    /// The turn, radians (positive: the front turned toward +X).
    pub yaw: f64,
    /// The far foot's toe front ahead of the near foot's, metres.
    pub toe_offset_m: f64,
    /// Clear scans of the foot with fewer.
    pub heights: usize,
    /// The near foot seen, toe front to heel back, over the candidate's foot.
    pub near_length_share: f64,
}

/// Why the toes gave no turn.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum NoTurn {
    /// No side silhouette, or a foot of fewer than 3 vertices.
    Unseen,
    /// The candidate's feet stand closer than [`MIN_SEPARATION_M`] across the view.
    FeetTogether,
    /// Fewer than [`MIN_HEIGHTS`] scans of a foot found its toe clear of the other foot
    /// (`near`, `far`: clear scans of each).
    ToesNotApart { near: usize, far: usize },
    /// The near foot, toe front to heel back, is shorter than [`MIN_LENGTH_SHARE`] of the
    /// candidate's (metres): its toe or heel is lost in the mask.
    NearFootShort { seen_m: f64, candidate_m: f64 },
    /// The toes' offset (metres) is beyond what any turn up to [`MAX_TURN_RAD`] makes.
    BeyondBelieved { toe_offset_m: f64 },
}

/// The turn the side view's toes show, given the posed candidate's two feet (their
/// vertices, in the station frame) and the vertical line it would be turned about.
///
/// The toes' offset is not taken as the feet's separation times the sine of the turn:
/// feet point a little outward, and a turn brings one foot's toe round to the front and
/// takes the other's away, which adds to the offset of a turned pair. The candidate's own
/// feet, turned about `about`, give the offset each turn makes; the turn whose offset is
/// the one seen is the estimate.
pub fn turn_from_toes(
    cam: &Camera,
    mask: MaskRef<'_>,
    feet: [&[DVec3]; 2],
    about: DVec3,
) -> Result<TurnEstimate, NoTurn> {
    if mask.data.is_empty() {
        return Err(NoTurn::Unseen);
    }
    let planes = [
        Foot::of(feet[0].iter().copied()).ok_or(NoTurn::Unseen)?,
        Foot::of(feet[1].iter().copied()).ok_or(NoTurn::Unseen)?,
    ];
    let centre = cam.center_in_station();
    let dist = |f: &Foot| (f.x - centre.x).abs();
    let (near, far) = if dist(&planes[0]) <= dist(&planes[1]) {
        (0, 1)
    } else {
        (1, 0)
    };
    if (planes[near].x - planes[far].x).abs() < MIN_SEPARATION_M {
        return Err(NoTurn::FeetTogether);
    }
    // Each foot's toe front: the frontmost of its scans over the toe cap's heights
    // (the toe's tip, wherever the shoe puts it), each scan on the foot's own plane.
    let mut fronts = [None::<f64>; 2];
    let mut heights = [0usize; 2];
    for (k, (foot, other)) in [(planes[near], planes[far]), (planes[far], planes[near])]
        .into_iter()
        .enumerate()
    {
        for i in 0..SCAN_HEIGHTS {
            let y = foot.sole_y + SCAN_TOP_M * i as f64 / (SCAN_HEIGHTS - 1) as f64;
            let Some(z) = toe_front(cam, mask, foot.x, y, foot.toe_z) else {
                continue;
            };
            if !clear_of(cam, foot, other, y, z, k == 1) {
                continue;
            }
            heights[k] += 1;
            if fronts[k].is_none_or(|f| z > f) {
                fronts[k] = Some(z);
            }
        }
    }
    let not_apart = NoTurn::ToesNotApart {
        near: heights[0],
        far: heights[1],
    };
    let (Some(zn), Some(zf)) = (fronts[0], fronts[1]) else {
        return Err(not_apart);
    };
    if heights[0] < MIN_HEIGHTS || heights[1] < MIN_HEIGHTS {
        return Err(not_apart);
    }
    // A toe the mask lost (a pale foot on a pale floor) reads as a foot stepped back:
    // the near foot, seen whole, must be about as long as the candidate's.
    let n = planes[near];
    let heel = (0..SCAN_HEIGHTS)
        .filter_map(|i| {
            let y = n.sole_y + SCAN_TOP_M * i as f64 / (SCAN_HEIGHTS - 1) as f64;
            let z = heel_back(cam, mask, n.heel_x, y, n.heel_z)?;
            clear_of(cam, Foot { x: n.heel_x, ..n }, planes[far], y, z, false).then_some(z)
        })
        .fold(f64::MAX, f64::min);
    let (seen_m, candidate_m) = (zn - heel, n.toe_z - n.heel_z);
    if !(seen_m >= MIN_LENGTH_SHARE * candidate_m) {
        return Err(NoTurn::NearFootShort {
            seen_m,
            candidate_m,
        });
    }
    let toe_offset_m = zf - zn;
    // The candidate's toes' offset at a turn: increasing with the turn (the far foot
    // comes forward); solved by bisection within the turns believed.
    let offset_at = |yaw: f64| {
        toe_front_turned(feet[far], planes[far].sole_y, about, yaw)
            - toe_front_turned(feet[near], planes[near].sole_y, about, yaw)
    };
    let (mut lo, mut hi) = (-MAX_TURN_RAD, MAX_TURN_RAD);
    if !(offset_at(lo) <= toe_offset_m && toe_offset_m <= offset_at(hi)) {
        return Err(NoTurn::BeyondBelieved { toe_offset_m });
    }
    for _ in 0..40 {
        let mid = 0.5 * (lo + hi);
        if offset_at(mid) < toe_offset_m {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    Ok(TurnEstimate {
        yaw: 0.5 * (lo + hi),
        toe_offset_m,
        heights: heights[0].min(heights[1]),
        near_length_share: seen_m / candidate_m,
    })
}

/// Front (largest z) of a foot's toe region (its vertices up to [`SCAN_TOP_M`] over
/// `sole_y`) after turning it by `yaw` about the vertical through `about`.
fn toe_front_turned(points: &[DVec3], sole_y: f64, about: DVec3, yaw: f64) -> f64 {
    let t = Turning::new(about, yaw);
    points
        .iter()
        .filter(|p| p.y <= sole_y + SCAN_TOP_M)
        .map(|p| t.apply(*p).z)
        .fold(f64::MIN, f64::max)
}

/// Whether the point (`foot.x`, `y`, `z`) of a scan on `foot`'s plane is seen clear of
/// `other` foot: the far foot's point above the near foot's toe cap, the near foot's
/// below the far foot's sole, by [`CLEAR_PX`].
fn clear_of(cam: &Camera, foot: Foot, other: Foot, y: f64, z: f64, far: bool) -> bool {
    let here = cam.project(DVec3::new(foot.x, y, z));
    let there = if far {
        let cap_y = other.sole_y + other.toe_cap_m + TOE_CAP_MARGIN_M;
        cam.project(DVec3::new(other.x, cap_y, z))
    } else {
        cam.project(DVec3::new(other.x, other.sole_y, z))
    };
    match (here, there) {
        // Image rows grow downward: the far foot's point lies above (smaller row).
        (Some(p), Some(q)) if far => q.y - p.y >= CLEAR_PX,
        (Some(p), Some(q)) => p.y - q.y >= CLEAR_PX,
        _ => false,
    }
}

/// Frontmost z on the line (x, y, z), z within [`SCAN_REACH_M`] of `toe_z`, whose
/// projection lies in the silhouette; None when the line starts inside (something
/// reaches further forward there) or never enters it.
fn toe_front(cam: &Camera, mask: MaskRef<'_>, x: f64, y: f64, toe_z: f64) -> Option<f64> {
    let (a, b) = (toe_z + SCAN_REACH_M, toe_z - SCAN_REACH_M);
    let t = first_inside(cam, mask, DVec3::new(x, y, a), DVec3::new(x, y, b))?;
    Some(a + t * (b - a))
}

/// Backmost z on the line (x, y, z), z within [`SCAN_REACH_M`] of `heel_z`, whose
/// projection lies in the silhouette.
fn heel_back(cam: &Camera, mask: MaskRef<'_>, x: f64, y: f64, heel_z: f64) -> Option<f64> {
    let (a, b) = (heel_z - SCAN_REACH_M, heel_z + SCAN_REACH_M);
    let t = first_inside(cam, mask, DVec3::new(x, y, a), DVec3::new(x, y, b))?;
    Some(a + t * (b - a))
}

/// A turn by `yaw` about the vertical line through `about` (its y ignored), its sine and
/// cosine taken once.
#[derive(Debug, Clone, Copy)]
pub struct Turning {
    about: DVec3,
    sin: f64,
    cos: f64,
}

impl Turning {
    pub fn new(about: DVec3, yaw: f64) -> Turning {
        let (sin, cos) = yaw.sin_cos();
        Turning { about, sin, cos }
    }

    /// `p` turned.
    #[inline]
    pub fn apply(&self, p: DVec3) -> DVec3 {
        let (dx, dz) = (p.x - self.about.x, p.z - self.about.z);
        DVec3::new(
            self.about.x + self.cos * dx + self.sin * dz,
            p.y,
            self.about.z - self.sin * dx + self.cos * dz,
        )
    }
}

/// Turns `positions` by `yaw` about the vertical line through `about` (its y ignored).
pub fn turn(positions: &mut [DVec3], about: DVec3, yaw: f64) {
    let t = Turning::new(about, yaw);
    for p in positions.iter_mut() {
        *p = t.apply(*p);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::StationCalibration;
    use crate::fit::correspond::tests::render_mask;
    use crate::mesh::{shapes, TriMesh};

    /// Two shoes (ellipsoids 26 x 9 x 8 cm on the floor) 20 cm apart, toes toward +Z
    /// and out by `toe_out` each, the pair turned by `yaw` about the vertical through
    /// the origin; the shoes unturned beside it.
    fn feet(yaw: f64, toe_out: f64) -> (TriMesh, [Vec<DVec3>; 2]) {
        let mut mesh = TriMesh::default();
        let mut each: [Vec<DVec3>; 2] = Default::default();
        for (k, x) in [0.10f64, -0.10].into_iter().enumerate() {
            let mut shoe = shapes::uv_sphere(1.0, 12, 24);
            shoe.map_positions(|p| DVec3::new(0.045 * p.x, 0.04 * (p.y + 1.0), 0.13 * p.z));
            // The left shoe (+x) turns its toe toward +x, the right one toward -x.
            turn(&mut shoe.positions, DVec3::ZERO, toe_out * x.signum());
            shoe.map_positions(|p| p + DVec3::new(x, 0.0, 0.0));
            each[k] = shoe.positions.clone();
            turn(&mut shoe.positions, DVec3::ZERO, yaw);
            let base = mesh.positions.len() as u32;
            mesh.positions.extend_from_slice(&shoe.positions);
            mesh.triangles
                .extend(shoe.triangles.iter().map(|t| t.map(|i| i + base)));
        }
        (mesh, each)
    }

    fn estimate(
        calib: &StationCalibration,
        yaw_deg: f64,
        toe_out_deg: f64,
    ) -> Result<TurnEstimate, NoTurn> {
        let (mesh, unturned) = feet(yaw_deg.to_radians(), toe_out_deg.to_radians());
        let cam = &calib.side;
        let data = render_mask(&mesh, cam);
        let mask = MaskRef {
            width: cam.intrinsics.width,
            height: cam.intrinsics.height,
            data: &data,
        };
        turn_from_toes(cam, mask, [&unturned[0], &unturned[1]], DVec3::ZERO)
    }

    #[test]
    fn turning_sends_the_front_toward_plus_x() {
        let mut p = [DVec3::new(0.0, 1.0, 1.0), DVec3::new(1.0, 0.0, 0.0)];
        turn(&mut p, DVec3::new(0.0, 5.0, 0.0), 90f64.to_radians());
        assert!(
            (p[0] - DVec3::new(1.0, 1.0, 0.0)).length() < 1e-12,
            "{:?}",
            p[0]
        );
        assert!(
            (p[1] - DVec3::new(0.0, 0.0, -1.0)).length() < 1e-12,
            "{:?}",
            p[1]
        );
    }

    /// The kiosk's side camera (3 m away, 1.1 m up) reads the turn of a pair of shoes
    /// from their toes to within a degree, either way (one of its pixels, 3 mm at the
    /// feet, is 0.9 degrees over the 20 cm between them; seen: within 0.65).
    #[test]
    fn the_toes_in_the_side_view_tell_the_turn() {
        let calib = StationCalibration::nominal(1280, 720, 1000.0, 3.0, 1.1, 1.0);
        // Shoes pointing straight ahead, and out by 12 degrees each (their turned toes'
        // offset is then 30 % larger than the separation's share of it: the turn the
        // plain sine would read is that much too large).
        for toe_out in [0.0, 12.0] {
            for yaw in [-6.0, -3.0, 0.0, 2.0, 5.0] {
                let e = estimate(&calib, yaw, toe_out)
                    .unwrap_or_else(|e| panic!("no estimate at {yaw} degrees: {e:?}"));
                assert!(
                    (e.yaw.to_degrees() - yaw).abs() < 1.0,
                    "{yaw} degrees (toes out {toe_out}) read as {:.2}: {e:?}",
                    e.yaw.to_degrees()
                );
            }
        }
    }

    /// A near foot whose toes the mask lost (6 cm of them: a pale foot on a pale floor)
    /// would read as a 17-degree turn here (9 degrees on feet 40 cm apart); the near
    /// foot seen shorter than the candidate's gives none.
    #[test]
    fn a_near_foot_that_lost_its_toes_gives_no_turn() {
        let calib = StationCalibration::nominal(1280, 720, 1000.0, 3.0, 1.1, 1.0);
        let cam = &calib.side;
        let (mut mesh, unturned) = feet(0.0, 0.0);
        let near_x = if (0.10 - cam.center_in_station().x).abs()
            < (-0.10 - cam.center_in_station().x).abs()
        {
            0.10
        } else {
            -0.10
        };
        for p in mesh.positions.iter_mut() {
            if (p.x - near_x).abs() < 0.06 {
                p.z = -0.13 + 0.76 * (p.z + 0.13);
            }
        }
        let data = render_mask(&mesh, cam);
        let mask = MaskRef {
            width: cam.intrinsics.width,
            height: cam.intrinsics.height,
            data: &data,
        };
        let e = turn_from_toes(cam, mask, [&unturned[0], &unturned[1]], DVec3::ZERO);
        assert!(
            matches!(e, Err(NoTurn::NearFootShort { seen_m, candidate_m })
                if seen_m < 0.8 * candidate_m && seen_m > 0.7 * candidate_m),
            "{e:?}"
        );
    }

    /// A side camera at the feet' height cannot see one foot's toes clear of the
    /// other's; a turn past what a stance check lets through is not believed; a side
    /// view without a silhouette shows nothing. None of them gives a turn.
    #[test]
    fn no_turn_where_the_toes_cannot_show_one() {
        let low = StationCalibration::nominal(1280, 720, 1000.0, 3.0, 0.03, 0.03);
        let e = estimate(&low, 3.0, 0.0);
        assert!(matches!(e, Err(NoTurn::ToesNotApart { .. })), "{e:?}");
        let calib = StationCalibration::nominal(1280, 720, 1000.0, 3.0, 1.1, 1.0);
        let e = estimate(&calib, 14.0, 0.0);
        assert!(matches!(e, Err(NoTurn::BeyondBelieved { .. })), "{e:?}");
        let empty = vec![0u8; 1280 * 720];
        let mask = MaskRef {
            width: 1280,
            height: 720,
            data: &empty,
        };
        let (_, unturned) = feet(0.0, 0.0);
        assert_eq!(
            turn_from_toes(&calib.side, mask, [&unturned[0], &unturned[1]], DVec3::ZERO),
            Err(NoTurn::ToesNotApart { near: 0, far: 0 })
        );
    }
}
