//! Girths and levels on analytic shapes with known answers (the checks of
//! `shared/spec/measurements.md`): circular and elliptic cylinders, a prism with a
//! concave notch the tape must bridge, and "stick bodies" of stacked elliptic cylinders
//! whose crotch, armpit and every girth are known.

use fitstation::measure::{girth_at, measure, BodySide, LoopSelector, MeasureError, Measurer};
use fitstation::mesh::section::{slice, Plane};
use fitstation::mesh::{shapes, TriMesh};
use glam::DVec3;
use std::f64::consts::PI;

/// Required agreement of girths with their analytic values, metres (the issue: 0.5 mm).
const GIRTH_TOL_M: f64 = 0.5e-3;
/// Segments of test cylinders: the inscribed polygon is within 0.01 mm of the curve.
const SEGMENTS: usize = 512;

/// Ramanujan's second approximation of the perimeter of an ellipse (semi-axes a, b).
fn ramanujan(a: f64, b: f64) -> f64 {
    let h = ((a - b) / (a + b)).powi(2);
    PI * (a + b) * (1.0 + 3.0 * h / (10.0 + (4.0 - 3.0 * h).sqrt()))
}

/// Appends `part` moved by `offset` to `body`.
fn add(body: &mut TriMesh, part: TriMesh, offset: DVec3) {
    let base = body.positions.len() as u32;
    body.positions
        .extend(part.positions.iter().map(|p| *p + offset));
    body.triangles
        .extend(part.triangles.iter().map(|t| t.map(|v| v + base)));
}

fn ellipse_prism(a: f64, b: f64, y0: f64, y1: f64, x: f64) -> (TriMesh, DVec3) {
    (
        shapes::elliptic_cylinder(a, b, y1 - y0, 3, SEGMENTS),
        DVec3::new(x, y0, 0.0),
    )
}

#[test]
fn circular_cylinder_girth_is_two_pi_r() {
    for r in [0.05, 0.15, 0.4] {
        let m = shapes::elliptic_cylinder(r, r, 1.0, 4, SEGMENTS);
        for y in [0.013, 0.5, 0.77] {
            let g = girth_at(&m, y, LoopSelector::Whole).expect("section");
            assert!((g - 2.0 * PI * r).abs() < GIRTH_TOL_M, "r {r} y {y}: {g}");
            let t = girth_at(&m, y, LoopSelector::Torso { axis_x: 0.0 }).expect("torso loop");
            assert_eq!(g, t);
        }
    }
}

#[test]
fn elliptic_cylinder_girth_is_ramanujan_perimeter() {
    for (a, b) in [(0.18, 0.11), (0.12, 0.2), (0.3, 0.05)] {
        let m = shapes::elliptic_cylinder(a, b, 0.6, 2, SEGMENTS);
        let g = girth_at(&m, 0.31, LoopSelector::Whole).expect("section");
        assert!(
            (g - ramanujan(a, b)).abs() < GIRTH_TOL_M,
            "a {a} b {b}: {g} vs {}",
            ramanujan(a, b)
        );
    }
}

#[test]
fn tape_bridges_a_concave_notch() {
    // A block 0.30 x 0.20 m with a chamfered front-left corner and a V notch 8 cm deep
    // in its front face. Hull by hand: back 0.30 + left side 0.15 + chamfer 0.05 sqrt 2
    // + front 0.25 (straight over the notch) + right side 0.20.
    let profile = [
        (-0.15, -0.10),
        (0.15, -0.10),
        (0.15, 0.05),
        (0.10, 0.10),
        (0.03, 0.10),
        (0.0, 0.02),
        (-0.03, 0.10),
        (-0.15, 0.10),
    ];
    let m = shapes::profile_prism(&profile, 1.0, 3);
    let hull = 0.30 + 0.15 + 0.05 * 2f64.sqrt() + 0.25 + 0.20;
    let notch_extra = 2.0 * (0.03f64 * 0.03 + 0.08 * 0.08).sqrt() - 0.06;
    for y in [0.2, 0.55] {
        let g = girth_at(&m, y, LoopSelector::Whole).expect("section");
        assert!((g - hull).abs() < GIRTH_TOL_M, "y {y}: {g} vs {hull}");
        let g = girth_at(&m, y, LoopSelector::Torso { axis_x: 0.0 }).expect("torso loop");
        assert!((g - hull).abs() < GIRTH_TOL_M, "y {y}: {g} vs {hull}");
        // The section itself does follow the notch: the tape is shorter by its detour.
        let raw = slice(&m, &Plane::horizontal(y))[0].perimeter();
        assert!((raw - g - notch_extra).abs() < 1e-9, "raw {raw} hull {g}");
    }
}

/// A standing "stick body" in the station frame, all parts elliptic prisms along +Y.
struct StickBody {
    mesh: TriMesh,
    crotch: f64,
    armpit: f64,
    stature: f64,
    leg_r: f64,
    hip: (f64, f64),
    waist: (f64, f64),
    chest: (f64, f64),
    /// Heights of the boundaries between the hip, waist and chest segments.
    hip_top: f64,
    waist_top: f64,
}

fn stick_body(with_arms: bool, leg_gap: f64) -> StickBody {
    let (crotch, armpit, stature) = (0.80, 1.30, 1.75);
    let leg_r = 0.08;
    let (hip, waist, chest) = ((0.17, 0.125), (0.14, 0.10), (0.16, 0.115));
    let (hip_top, waist_top) = (crotch + 0.15, crotch + 0.35);
    let mut mesh = TriMesh::default();
    for side in [-1.0, 1.0] {
        let (m, o) = ellipse_prism(leg_r, leg_r, 0.0, crotch, side * (leg_r + 0.5 * leg_gap));
        add(&mut mesh, m, o);
    }
    for (ab, y0, y1) in [
        (hip, crotch, hip_top),
        (waist, hip_top, waist_top),
        (chest, waist_top, armpit),
    ] {
        let (m, o) = ellipse_prism(ab.0, ab.1, y0, y1, 0.0);
        add(&mut mesh, m, o);
    }
    if with_arms {
        for side in [-1.0, 1.0] {
            let (m, o) = ellipse_prism(0.04, 0.04, 0.75, armpit, side * 0.25);
            add(&mut mesh, m, o);
        }
    }
    // Shoulders (wide enough to join the arms), neck, head.
    for (ab, y0, y1) in [
        ((0.30, 0.12), armpit, 1.45),
        ((0.06, 0.06), 1.45, 1.55),
        ((0.09, 0.1), 1.55, stature),
    ] {
        let (m, o) = ellipse_prism(ab.0, ab.1, y0, y1, 0.0);
        add(&mut mesh, m, o);
    }
    StickBody {
        mesh,
        crotch,
        armpit,
        stature,
        leg_r,
        hip,
        waist,
        chest,
        hip_top,
        waist_top,
    }
}

#[test]
fn stick_body_levels_and_girths_are_the_analytic_ones() {
    let b = stick_body(true, 0.04);
    let m = measure(&b.mesh).expect("stick body measures");
    let lv = &m.levels;
    assert!(
        (m.stature_mm - b.stature * 1e3).abs() < 1e-6,
        "stature {}",
        m.stature_mm
    );
    assert!(
        (lv.crotch_m - b.crotch).abs() < 1e-3,
        "crotch {}",
        lv.crotch_m
    );
    assert!(
        (lv.armpit_m - b.armpit).abs() < 1e-3,
        "armpit {}",
        lv.armpit_m
    );
    let tol_mm = GIRTH_TOL_M * 1e3;
    let check = |what: &str, got: f64, want_m: f64| {
        assert!(
            (got - want_m * 1e3).abs() < tol_mm,
            "{what}: {got} mm vs {} mm",
            want_m * 1e3
        );
    };
    check("chest", m.chest_girth_mm, ramanujan(b.chest.0, b.chest.1));
    check("waist", m.waist_girth_mm, ramanujan(b.waist.0, b.waist.1));
    check("hip", m.hip_girth_mm, ramanujan(b.hip.0, b.hip.1));
    check("thigh left", m.thigh_girth_left_mm, 2.0 * PI * b.leg_r);
    check("thigh right", m.thigh_girth_right_mm, 2.0 * PI * b.leg_r);
    // Levels lie in the segments that carry those girths.
    assert!(
        lv.hip_m > b.crotch && lv.hip_m < b.hip_top,
        "hip level {}",
        lv.hip_m
    );
    assert!(
        lv.waist_m > b.hip_top && lv.waist_m < b.waist_top,
        "waist level {}",
        lv.waist_m
    );
    assert!(
        lv.chest_m > b.waist_top && lv.chest_m <= lv.armpit_m,
        "chest level {}",
        lv.chest_m
    );
    for y in [lv.thigh_left_m, lv.thigh_right_m] {
        assert!(
            y >= b.crotch - 0.0801 && y <= b.crotch - 0.0099,
            "thigh level {y}"
        );
    }
    // hip_girth_max: the largest torso girth below the waist is the hip segment's.
    check("hip max", m.hip_girth_max_mm, ramanujan(b.hip.0, b.hip.1));
    assert!(lv.hip_girth_max_m >= lv.crotch_m && lv.hip_girth_max_m < b.hip_top);
    // Profile: the 2 mm grid from the crotch, then the armpit; each sample the girth of
    // the segment at its height.
    let p = &m.torso_profile;
    assert_eq!(
        p.len(),
        ((lv.armpit_m - lv.crotch_m) / 0.002).ceil() as usize + 1
    );
    assert_eq!(p[0].height_m, lv.crotch_m);
    assert_eq!(p[p.len() - 1].height_m, lv.armpit_m);
    for w in p[..p.len() - 1].windows(2) {
        assert!((w[1].height_m - w[0].height_m - 0.002).abs() < 1e-9);
    }
    for s in p {
        let ab = if s.height_m < b.hip_top {
            b.hip
        } else if s.height_m < b.waist_top {
            b.waist
        } else {
            b.chest
        };
        check("profile", s.girth_mm, ramanujan(ab.0, ab.1));
    }
}

#[test]
fn measurements_follow_rigid_shifts_and_scale() {
    let b = stick_body(true, 0.05);
    let base = measure(&b.mesh).expect("stick body");
    let mut moved = b.mesh.clone();
    moved.map_positions(|p| p + DVec3::new(0.31, 0.0, -0.27));
    let m = measure(&moved).expect("moved body");
    assert!((m.chest_girth_mm - base.chest_girth_mm).abs() < 1e-6);
    assert!((m.thigh_girth_left_mm - base.thigh_girth_left_mm).abs() < 1e-6);
    assert!((m.levels.crotch_m - base.levels.crotch_m).abs() < 1e-9);
    assert!((m.levels.axis_x_m - base.levels.axis_x_m - 0.31).abs() < 1e-9);
    // Heights count from the mesh's own lowest point: a body floating 5 cm up measures
    // the same, its levels 5 cm higher.
    let mut lifted = b.mesh.clone();
    lifted.map_positions(|p| p + DVec3::new(0.0, 0.05, 0.0));
    let m = measure(&lifted).expect("lifted body");
    for (got, want) in [
        (m.stature_mm, base.stature_mm),
        (m.chest_girth_mm, base.chest_girth_mm),
        (m.waist_girth_mm, base.waist_girth_mm),
        (m.hip_girth_mm, base.hip_girth_mm),
        (m.thigh_girth_left_mm, base.thigh_girth_left_mm),
    ] {
        assert!((got - want).abs() < 1e-6, "{got} vs {want}");
    }
    assert!((m.levels.crotch_m - base.levels.crotch_m - 0.05).abs() < 1e-6);
    assert!((m.levels.armpit_m - base.levels.armpit_m - 0.05).abs() < 1e-6);
    let s = 1.1;
    let mut scaled = b.mesh.clone();
    scaled.map_positions(|p| p * s);
    let m = measure(&scaled).expect("scaled body");
    for (got, want) in [
        (m.stature_mm, base.stature_mm),
        (m.chest_girth_mm, base.chest_girth_mm),
        (m.waist_girth_mm, base.waist_girth_mm),
        (m.hip_girth_mm, base.hip_girth_mm),
        (m.thigh_girth_right_mm, base.thigh_girth_right_mm),
    ] {
        assert!(
            (got - s * want).abs() < 1e-6 * want,
            "{got} vs {} x {want}",
            s
        );
    }
}

#[test]
fn measurer_reuse_gives_the_same_result() {
    let a = stick_body(true, 0.04);
    let b = stick_body(true, 0.07);
    let mut measurer = Measurer::new();
    let first = measurer.measure(&a.mesh).expect("a");
    let other = measurer.measure(&b.mesh).expect("b");
    assert!((other.levels.crotch_m - first.levels.crotch_m).abs() < 2e-3);
    assert_eq!(measurer.measure(&a.mesh).expect("a again"), first);
    let mut out = other.clone();
    measurer.measure_into(&a.mesh, &mut out).expect("a into");
    assert_eq!(out, first);
    // A failed measurement leaves the previous result untouched.
    let no_arms = stick_body(false, 0.04);
    assert!(measurer.measure_into(&no_arms.mesh, &mut out).is_err());
    assert_eq!(out, first);
    assert_eq!(fitstation::measure::measure(&a.mesh).expect("fresh"), first);
}

#[test]
fn leg_selector_picks_each_side() {
    let b = stick_body(true, 0.04);
    for side in [BodySide::Left, BodySide::Right] {
        let g = girth_at(&b.mesh, 0.4, LoopSelector::Side { side, axis_x: 0.0 }).expect("leg");
        assert!((g - 2.0 * PI * b.leg_r).abs() < GIRTH_TOL_M);
    }
    // Only one leg on the +X side: shift the axis past both legs and none is left of it.
    assert!(girth_at(
        &b.mesh,
        0.4,
        LoopSelector::Side {
            side: BodySide::Left,
            axis_x: 0.5
        }
    )
    .is_none());
    // Whole section = hull of both legs: two half circles and two bridges.
    let g = girth_at(&b.mesh, 0.4, LoopSelector::Whole).expect("legs");
    let centre_gap = 2.0 * (b.leg_r + 0.02);
    assert!(
        (g - (2.0 * PI * b.leg_r + 2.0 * centre_gap)).abs() < GIRTH_TOL_M,
        "{g}"
    );
    // No loop crosses the axis below the crotch.
    assert!(girth_at(&b.mesh, 0.4, LoopSelector::Torso { axis_x: 0.0 }).is_none());
}

/// Profile of the chest with the arms pressed against its sides: the chest ellipse,
/// except that within |z| < `tab_half_z` of the sides it runs out to |x| = `tab_x`.
fn chest_with_arm_tabs(a: f64, b: f64, tab_half_z: f64, tab_x: f64) -> Vec<(f64, f64)> {
    (0..SEGMENTS)
        .map(|s| {
            let th = 2.0 * PI * s as f64 / SEGMENTS as f64;
            let (x, z) = (a * th.cos(), b * th.sin());
            if z.abs() < tab_half_z {
                (tab_x * x.signum(), z)
            } else {
                (x, z)
            }
        })
        .collect()
}

#[test]
fn arms_pressed_to_the_chest_are_inside_the_tape() {
    // The lower chest (7 cm above the waist segment, inside the chest band) is one loop
    // with the arms pressed to its sides, out to |x| = 0.24 m; the arms are free again
    // higher up, so the armpit is still found where the shoulders join them. The spec
    // does not cut arms off: the chest girth is the largest torso girth in the band,
    // here the hull round the pressed arms.
    let b = stick_body(true, 0.04);
    let (tab_half_z, tab_x) = (0.03, 0.24);
    let profile = chest_with_arm_tabs(b.chest.0, b.chest.1, tab_half_z, tab_x);
    let tabbed = shapes::profile_prism(&profile, 0.07, 2);
    let mut body = TriMesh::default();
    let lower_top = b.waist_top + 0.07;
    for part in split_parts(&b.mesh) {
        let lo = part
            .positions
            .iter()
            .map(|p| p.y)
            .fold(f64::INFINITY, f64::min);
        if (lo - b.waist_top).abs() < 1e-9 {
            let (m, o) = ellipse_prism(b.chest.0, b.chest.1, lower_top, b.armpit, 0.0);
            add(&mut body, m, o);
        } else {
            add(&mut body, part, DVec3::ZERO);
        }
    }
    add(&mut body, tabbed, DVec3::new(0.0, b.waist_top, 0.0));
    let m = measure(&body).expect("body with touching arms");
    assert!(
        (m.levels.armpit_m - b.armpit).abs() < 1e-3,
        "armpit {}",
        m.levels.armpit_m
    );
    let pts: Vec<glam::DVec2> = profile
        .iter()
        .map(|&(x, z)| glam::DVec2::new(x, z))
        .collect();
    let want = fitstation::mesh::section::hull_perimeter(&pts) * 1e3;
    check_close("chest", m.chest_girth_mm, want);
    assert!(
        m.levels.chest_m > b.waist_top && m.levels.chest_m < lower_top,
        "chest level {}",
        m.levels.chest_m
    );
    // Far larger than the free chest above it.
    assert!(want > ramanujan(b.chest.0, b.chest.1) * 1e3 + 100.0);
}

/// Splits a mesh made by [`add`] into its connected parts (by shared vertices).
fn split_parts(mesh: &TriMesh) -> Vec<TriMesh> {
    let n = mesh.positions.len();
    let mut parent: Vec<usize> = (0..n).collect();
    fn find(p: &mut [usize], mut i: usize) -> usize {
        while p[i] != i {
            p[i] = p[p[i]];
            i = p[i];
        }
        i
    }
    for t in &mesh.triangles {
        for e in 0..3 {
            let (a, b) = (
                find(&mut parent, t[e] as usize),
                find(&mut parent, t[(e + 1) % 3] as usize),
            );
            parent[a] = b;
        }
    }
    let mut parts: Vec<(usize, TriMesh)> = Vec::new();
    for t in &mesh.triangles {
        let r = find(&mut parent, t[0] as usize);
        let k = match parts.iter().position(|(root, _)| *root == r) {
            Some(k) => k,
            None => {
                parts.push((
                    r,
                    TriMesh {
                        positions: mesh.positions.clone(),
                        triangles: Vec::new(),
                    },
                ));
                parts.len() - 1
            }
        };
        parts[k].1.triangles.push(*t);
    }
    parts
        .into_iter()
        .map(|(_, mut m)| {
            m.compact();
            m
        })
        .collect()
}

#[test]
fn thighs_pressing_through_each_other_stay_two_legs() {
    // A self-intersecting mesh, as a fit of heavy thighs can give: the leg prisms
    // overlap by 4 cm (a quarter of a thigh's width) across the body axis.
    let b = stick_body(true, -0.04);
    let m = measure(&b.mesh).expect("body with overlapping thighs");
    assert!(
        (m.levels.crotch_m - b.crotch).abs() < 1e-3,
        "crotch {}",
        m.levels.crotch_m
    );
    for g in [m.thigh_girth_left_mm, m.thigh_girth_right_mm] {
        assert!(
            (g - 2e3 * PI * b.leg_r).abs() < GIRTH_TOL_M * 1e3,
            "thigh {g}"
        );
    }
}

#[test]
fn arms_joining_at_different_heights_give_the_lower_armpit() {
    // The left arm joins the torso at the armpit (1.30 m), the right arm 4 cm higher:
    // between the two, one prism holds the torso and the left arm.
    let b = stick_body(true, 0.04);
    let mut body = TriMesh::default();
    for part in split_parts(&b.mesh) {
        let lo = part
            .positions
            .iter()
            .map(|p| p.y)
            .fold(f64::INFINITY, f64::min);
        let x = part.positions.iter().map(|p| p.x).sum::<f64>() / part.positions.len() as f64;
        if (lo - b.armpit).abs() < 1e-9 {
            // Shoulders now start higher.
            let (m, o) = ellipse_prism(0.30, 0.12, b.armpit + 0.04, 1.45, 0.0);
            add(&mut body, m, o);
        } else if (lo - 0.75).abs() < 1e-9 && x < 0.0 {
            let (m, o) = ellipse_prism(0.04, 0.04, 0.75, b.armpit + 0.04, -0.25);
            add(&mut body, m, o);
        } else {
            add(&mut body, part, DVec3::ZERO);
        }
    }
    let (m, o) = ellipse_prism(0.23, 0.12, b.armpit, b.armpit + 0.04, 0.07);
    add(&mut body, m, o);
    let m = measure(&body).expect("body with uneven armpits");
    assert!(
        (m.levels.armpit_m - b.armpit).abs() < 1e-3,
        "armpit {}",
        m.levels.armpit_m
    );
    check_close(
        "chest",
        m.chest_girth_mm,
        ramanujan(b.chest.0, b.chest.1) * 1e3,
    );
}

fn check_close(what: &str, got_mm: f64, want_mm: f64) {
    assert!(
        (got_mm - want_mm).abs() < GIRTH_TOL_M * 1e3,
        "{what}: {got_mm} mm vs {want_mm} mm"
    );
}

#[test]
fn shoulder_tops_beside_the_neck_are_not_armpits() {
    // Two small caps on the shoulders, separate from the neck: slices through them show
    // "two loops beside the torso" as arms do, but above them the torso narrows to the
    // neck instead of taking them in.
    let mut b = stick_body(true, 0.04);
    for side in [-1.0, 1.0] {
        let (m, o) = ellipse_prism(0.05, 0.05, 1.45, 1.48, side * 0.2);
        add(&mut b.mesh, m, o);
    }
    let m = measure(&b.mesh).expect("body with shoulder caps");
    assert!(
        (m.levels.armpit_m - b.armpit).abs() < 1e-3,
        "armpit {}",
        m.levels.armpit_m
    );
}

#[test]
fn not_a_standing_body_is_a_clear_error() {
    assert_eq!(measure(&TriMesh::default()), Err(MeasureError::EmptyMesh));
    let cyl = shapes::elliptic_cylinder(0.15, 0.1, 1.7, 10, 64);
    assert!(
        matches!(measure(&cyl), Err(MeasureError::NoCrotch { .. })),
        "{:?}",
        measure(&cyl)
    );
    let no_arms = stick_body(false, 0.04);
    assert!(matches!(
        measure(&no_arms.mesh),
        Err(MeasureError::NoArmpit { .. })
    ));
    let mut bad = cyl.clone();
    bad.triangles.push([0, 1, 999_999]);
    assert!(matches!(measure(&bad), Err(MeasureError::InvalidMesh(_))));
    let mut nan = cyl;
    nan.positions[3].x = f64::NAN;
    assert!(matches!(measure(&nan), Err(MeasureError::InvalidMesh(_))));
    assert!(girth_at(&TriMesh::default(), 0.5, LoopSelector::Whole).is_none());
    // Not in metres, or one vertex thrown far off (a fit that blew up): refused at once,
    // not searched over millions of 2 mm grid steps.
    let body = stick_body(true, 0.04).mesh;
    assert!(measure(&body).is_ok());
    let mut mm = body.clone();
    mm.positions.iter_mut().for_each(|p| *p *= 1000.0);
    assert!(matches!(measure(&mm), Err(MeasureError::InvalidMesh(_))));
    let mut thrown = body;
    let last = thrown.triangles[0][0] as usize;
    thrown.positions[last].y = 1.0e12;
    let err = measure(&thrown).expect_err("a vertex 1e12 m up");
    assert!(
        matches!(&err, MeasureError::InvalidMesh(why) if why.contains("tall")),
        "{err}"
    );
}

#[test]
fn report_map_and_cli_on_the_stick_body() {
    let b = stick_body(true, 0.04);
    let m = measure(&b.mesh).expect("stick body");
    let map = m.to_report_map();
    let mut keys: Vec<&str> = map.keys().map(|k| k.as_str()).collect();
    keys.sort_unstable();
    assert_eq!(
        keys,
        [
            "chest_girth",
            "hip_girth",
            "hip_girth_max",
            "stature",
            "thigh_girth_left",
            "thigh_girth_right",
            "waist_girth"
        ]
    );
    assert_eq!(map["waist_girth"].as_f64(), Some(m.waist_girth_mm));
    assert_eq!(map["stature"].as_f64(), Some(m.stature_mm));
    // The command reads a mesh file and measures it; a cylinder is a clear error.
    let dir = std::env::temp_dir().join(format!("fitstation_measure_cli_{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    let body_path = dir.join("stick.obj");
    fitstation::mesh::io::write_obj(&body_path, &b.mesh).expect("write body");
    for json in [false, true] {
        fitstation::measure::run(fitstation::measure::MeasureArgs {
            mesh: body_path.clone(),
            json,
        })
        .expect("measure the stick body file");
    }
    let cyl_path = dir.join("cylinder.obj");
    fitstation::mesh::io::write_obj(&cyl_path, &shapes::elliptic_cylinder(0.1, 0.1, 1.7, 4, 32))
        .expect("write cylinder");
    let err = fitstation::measure::run(fitstation::measure::MeasureArgs {
        mesh: cyl_path,
        json: false,
    })
    .expect_err("a cylinder is not a body");
    assert!(format!("{err:#}").contains("no crotch"), "{err:#}");
    std::fs::remove_dir_all(&dir).ok();
}

/// The stick body with the parts starting at height `lo` (within 1e-9) replaced by
/// `parts` (semi-axes, y0, y1, x of each elliptic prism).
fn replace_parts(b: &StickBody, lo: f64, parts: &[((f64, f64), f64, f64, f64)]) -> TriMesh {
    let mut body = TriMesh::default();
    for part in split_parts(&b.mesh) {
        let part_lo = part
            .positions
            .iter()
            .map(|p| p.y)
            .fold(f64::INFINITY, f64::min);
        if (part_lo - lo).abs() > 1e-9 {
            add(&mut body, part, DVec3::ZERO);
        }
    }
    for &(ab, y0, y1, x) in parts {
        let (m, o) = ellipse_prism(ab.0, ab.1, y0, y1, x);
        add(&mut body, m, o);
    }
    body
}

#[test]
fn thigh_is_the_fullest_girth_1_to_8_cm_below_the_crotch() {
    // Each leg: radius 8 cm, a bulge of 9 cm from 6.5 to 7.5 cm below the crotch (the
    // fullest part inside the band) and a larger one of 9.5 cm from 9 to 10 cm below
    // (outside the band: not the thigh). A fixed level (say 3 % of the stature, 5.25 cm
    // below) or the band's top would read 8 cm; ignoring the band, 9.5 cm.
    let b = stick_body(true, 0.04);
    let c = b.crotch;
    let r = b.leg_r;
    let mut legs = Vec::new();
    for side in [-1.0, 1.0] {
        let x = side * (r + 0.02);
        for (radius, y0, y1) in [
            (r, 0.0, c - 0.10),
            (0.095, c - 0.10, c - 0.09),
            (r, c - 0.09, c - 0.075),
            (0.09, c - 0.075, c - 0.065),
            (r, c - 0.065, c),
        ] {
            legs.push(((radius, radius), y0, y1, x));
        }
    }
    let body = replace_parts(&b, 0.0, &legs);
    let m = measure(&body).expect("body with bulging thighs");
    assert!(
        (m.levels.crotch_m - c).abs() < 1e-3,
        "crotch {}",
        m.levels.crotch_m
    );
    for (g, y) in [
        (m.thigh_girth_left_mm, m.levels.thigh_left_m),
        (m.thigh_girth_right_mm, m.levels.thigh_right_m),
    ] {
        check_close("thigh", g, 2e3 * PI * 0.09);
        assert!(y > c - 0.075 && y < c - 0.065, "thigh level {y}");
    }
}

#[test]
fn hip_is_the_furthest_back_level_and_hip_girth_max_the_widest() {
    // The hip segment now starts with 3 cm of "thigh tops" (wide, shallow: the widest
    // torso section below the waist, as above the crotch in an A-pose), then the
    // buttocks (deeper: they reach furthest back).
    let b = stick_body(true, 0.04);
    let (tops, seat) = ((0.19, 0.11), b.hip);
    let split = b.crotch + 0.03;
    let body = replace_parts(
        &b,
        b.crotch,
        &[(tops, b.crotch, split, 0.0), (seat, split, b.hip_top, 0.0)],
    );
    let m = measure(&body).expect("body with thigh tops");
    let lv = &m.levels;
    check_close("hip", m.hip_girth_mm, ramanujan(seat.0, seat.1) * 1e3);
    assert!(
        lv.hip_m > split && lv.hip_m < b.hip_top,
        "hip level {}",
        lv.hip_m
    );
    check_close(
        "hip_girth_max",
        m.hip_girth_max_mm,
        ramanujan(tops.0, tops.1) * 1e3,
    );
    assert!(
        lv.hip_girth_max_m >= lv.crotch_m && lv.hip_girth_max_m < split,
        "hip_girth_max level {}",
        lv.hip_girth_max_m
    );
    assert!(m.hip_girth_max_mm > m.hip_girth_mm + 15.0);
    // The waist is still the narrow segment above.
    check_close(
        "waist",
        m.waist_girth_mm,
        ramanujan(b.waist.0, b.waist.1) * 1e3,
    );
    assert!(lv.waist_m > b.hip_top && lv.waist_m < b.waist_top);
}
