//! Tests of the body module: the committed template, the macro model, sampling, file
//! robustness, the importer's frame decisions and prepare() across topologies.

use super::import::{import_mpfb2, parse_target, read_target};
use super::library::{Knot, LibraryData, LibraryMeta, TargetData, Variable};
use super::*;
use crate::mesh::section::{convex_hull, signed_area, slice, Plane};
use glam::{DVec2, DVec3};
use std::io::Write;
use std::path::Path;
use std::sync::OnceLock;

fn lib() -> &'static ShapeLibrary {
    static LIB: OnceLock<ShapeLibrary> = OnceLock::new();
    LIB.get_or_init(|| ShapeLibrary::load_default().expect("embedded library loads"))
}

#[test]
fn shared_library_is_the_default_one() {
    let s = ShapeLibrary::shared().unwrap();
    assert!(std::ptr::eq(s, ShapeLibrary::shared().unwrap()));
    assert_eq!(s.template().mesh, lib().template().mesh);
    let j = &lib().template().info.joints;
    assert_eq!(j.get("knee_left"), Some(j.knee_left));
    assert_eq!(j.get("no_such_joint"), None);
}

fn stature(m: &TriMesh) -> f64 {
    m.bounds().map(|b| b.size().y).unwrap_or(0.0)
}

/// Convex-hull area of the torso section (the loop around the body axis) at height `y`.
fn torso_hull_area(m: &TriMesh, y: f64, axis_x: f64) -> f64 {
    let loops = slice(m, &Plane::horizontal(y));
    let torso: Vec<DVec2> = loops
        .iter()
        .filter(|l| {
            let (lo, hi) = l
                .points
                .iter()
                .fold((f64::INFINITY, f64::NEG_INFINITY), |a, p| {
                    (a.0.min(p.x), a.1.max(p.x))
                });
            lo < axis_x && hi > axis_x
        })
        .flat_map(|l| l.points.iter().copied())
        .collect();
    signed_area(&convex_hull(&torso)).abs()
}

#[test]
fn template_is_closed_outward_and_human_sized() {
    let t = lib().template();
    let m = &t.mesh;
    // MakeHuman's body group is closed (its eyes are separate helper geometry).
    assert_eq!(m.boundary_edge_count(), 0, "boundary edges in the template");
    assert!(m.volume() > 0.0, "template is not oriented outward");
    // The topmost vertex's normal points up (outward).
    let n = m.vertex_normals();
    let top = (0..m.vertex_count())
        .max_by(|&a, &b| m.positions[a].y.total_cmp(&m.positions[b].y))
        .unwrap();
    assert!(n[top].y > 0.5, "top normal {:?}", n[top]);
    let st = stature(m);
    assert!((1.6..=1.8).contains(&st), "stature {st}");
    // A plausible volume for a ~60 kg adult (0.04 .. 0.12 m^3).
    assert!((0.04..0.12).contains(&m.volume()), "volume {}", m.volume());
    let bb = m.bounds().unwrap();
    assert!(bb.min.y.abs() < 1e-9, "soles at {}", bb.min.y);
    assert_eq!(t.info.vertex_count, m.vertex_count());
}

#[test]
fn template_faces_plus_z_and_stands_on_the_mark() {
    let t = lib().template();
    let m = &t.mesh;
    let j = &t.info.joints;
    // Toes point +Z: the foot reaches much farther ahead of the ankle than behind it.
    for (foot, ankle) in [
        (&t.info.rigid.foot_left, j.ankle_left),
        (&t.info.rigid.foot_right, j.ankle_right),
    ] {
        let zs: Vec<f64> = foot
            .iter()
            .map(|&i| m.positions[i as usize].z - ankle.z)
            .collect();
        let ahead = zs.iter().cloned().fold(f64::NEG_INFINITY, f64::max);
        let behind = -zs.iter().cloned().fold(f64::INFINITY, f64::min);
        assert!(
            ahead > 2.0 * behind,
            "toes {ahead} m ahead, heel {behind} m behind"
        );
    }
    // The face is ahead: at the head joint's height the section reaches farther forward
    // of the neck than the back of the head reaches behind... the nose is the most
    // forward point of the head, so the head's z extent lies ahead of the neck's centre.
    let head_pts: Vec<DVec3> = t
        .info
        .rigid
        .head
        .iter()
        .map(|&i| m.positions[i as usize])
        .collect();
    let zmax = head_pts
        .iter()
        .map(|p| p.z)
        .fold(f64::NEG_INFINITY, f64::max);
    let zmin = head_pts.iter().map(|p| p.z).fold(f64::INFINITY, f64::min);
    assert!(zmax - j.neck.z > j.neck.z - zmin, "face not toward +Z");
    // Left on +X: every left joint has x > 0, every right joint x < 0.
    for (name, p) in j.named() {
        if name.ends_with("_left") {
            assert!(p.x > 0.02, "{name} at x {}", p.x);
        }
        if name.ends_with("_right") {
            assert!(p.x < -0.02, "{name} at x {}", p.x);
        }
    }
    // Centred on the mark: the feet's centroids straddle x = z = 0.
    let c = |s: &[u32]| s.iter().map(|&i| m.positions[i as usize]).sum::<DVec3>() / s.len() as f64;
    let mid = 0.5 * (c(&t.info.rigid.foot_left) + c(&t.info.rigid.foot_right));
    assert!(mid.x.abs() < 1e-9 && mid.z.abs() < 1e-9, "mark at {mid:?}");
}

#[test]
fn landmarks_are_in_anatomical_order() {
    let i = &lib().template().info;
    let l = &i.landmarks;
    let j = &i.joints;
    let st = i.stature_m;
    // Crotch about 0.45-0.5 of stature, armpits below acromions below the neck cut.
    assert!(
        (0.42..0.52).contains(&(l.crotch_y / st)),
        "crotch {}",
        l.crotch_y / st
    );
    assert!(l.crotch_y < l.armpit_y && l.armpit_y < l.acromion_y && l.acromion_y < l.neck_cut_y);
    assert!(j.ankle_left.y < j.knee_left.y && j.knee_left.y < l.crotch_y);
    assert!(j.wrist_left.y < j.elbow_left.y && j.elbow_left.y < j.shoulder_left.y);
    assert!(
        j.hip.y < j.waist.y
            && j.waist.y < j.chest.y
            && j.chest.y < j.neck.y
            && j.neck.y < j.head_top.y
    );
    // Arms hang outward in the A-pose.
    assert!(j.shoulder_left.x < j.elbow_left.x && j.elbow_left.x < j.wrist_left.x);
    // Rigid parts: plausible shares of the surface and where they belong.
    let m = &lib().template().mesh;
    for (name, part, ok) in [
        (
            "head",
            &i.rigid.head,
            &(|p: DVec3| p.y > l.neck_cut_y) as &dyn Fn(DVec3) -> bool,
        ),
        ("hand_left", &i.rigid.hand_left, &|p: DVec3| {
            p.x > j.elbow_left.x
        }),
        ("hand_right", &i.rigid.hand_right, &|p: DVec3| {
            p.x < j.elbow_right.x
        }),
        ("foot_left", &i.rigid.foot_left, &|p: DVec3| {
            p.y < j.knee_left.y && p.x > 0.0
        }),
        ("foot_right", &i.rigid.foot_right, &|p: DVec3| {
            p.y < j.knee_right.y && p.x < 0.0
        }),
    ] {
        assert!(
            part.len() > 50 && part.len() < m.vertex_count() / 3,
            "{name}: {} vertices",
            part.len()
        );
        assert!(
            part.iter().all(|&v| ok(m.positions[v as usize])),
            "{name} has stray vertices"
        );
    }
}

#[test]
fn default_body_is_the_template_and_body_into_matches() {
    let l = lib();
    let b = l.body(&ShapeParams::default());
    assert_eq!(b, l.template().mesh);
    let p = ShapeLibrary::sample_adult(7);
    let b = l.body(&p);
    let mut buf = Vec::new();
    l.body_into(&p, &mut buf);
    assert_eq!(b.positions, buf);
    assert_eq!(b.triangles, l.template().mesh.triangles);
    assert!(
        b.positions
            .iter()
            .map(|v| v.y)
            .fold(f64::INFINITY, f64::min)
            .abs()
            < 1e-12
    );
}

fn params(f: impl Fn(&mut ShapeParams)) -> ShapeParams {
    let mut p = ShapeParams::default();
    f(&mut p);
    p
}

#[test]
fn weight_widens_waist_and_hips() {
    let l = lib();
    for gender in [0.0, 1.0] {
        let thin = l.body(&params(|p| {
            p.gender = gender;
            p.weight = 0.2
        }));
        let heavy = l.body(&params(|p| {
            p.gender = gender;
            p.weight = 0.8
        }));
        let (it, ih) = (prepare(&thin).unwrap(), prepare(&heavy).unwrap());
        for (name, yt, yh) in [
            ("waist", it.joints.waist.y, ih.joints.waist.y),
            ("hip", it.joints.hip.y, ih.joints.hip.y),
        ] {
            let at = torso_hull_area(&thin, yt, it.landmarks.crotch.x);
            let ah = torso_hull_area(&heavy, yh, ih.landmarks.crotch.x);
            assert!(
                ah > 1.08 * at,
                "gender {gender} {name}: heavy {ah} vs thin {at}"
            );
        }
        let (vh, vt) = (heavy.volume(), thin.volume());
        assert!(
            vh > 1.1 * vt,
            "gender {gender}: volume heavy {vh} thin {vt}"
        );
    }
}

#[test]
fn cup_size_deepens_a_womans_bust_and_leaves_a_man_and_the_average_cup_alone() {
    let l = lib();
    // The front of the trunk (largest z of the vertices within the shoulders' width)
    // between the armpits and 15 cm below them.
    let bust_front = |b: &TriMesh| {
        let i = prepare(b).unwrap();
        let top = 0.5 * (i.landmarks.armpit_left.y + i.landmarks.armpit_right.y);
        let half = 0.5 * (i.landmarks.armpit_left.x - i.landmarks.armpit_right.x);
        b.positions
            .iter()
            .filter(|p| p.y < top && p.y > top - 0.15 && p.x.abs() < half)
            .map(|p| p.z)
            .fold(f64::MIN, f64::max)
    };
    let woman = |cup: f64| {
        l.body(&params(|p| {
            p.gender = 0.0;
            p.cup = cup
        }))
    };
    let (small, large) = (bust_front(&woman(0.0)), bust_front(&woman(1.0)));
    let average = bust_front(&woman(0.5));
    assert!(
        large > average + 0.02 && average > small,
        "bust front small {small} average {average} large {large}"
    );
    // The library's breast targets are keyed on women: a man's body does not change.
    let man = |cup: f64| {
        l.body(&params(|p| {
            p.gender = 1.0;
            p.cup = cup
        }))
    };
    assert_eq!(man(0.0).positions, man(1.0).positions);
    // The average cup is the body of before the cup size was a parameter: the template.
    assert_eq!(
        l.body(&ShapeParams::default()).positions,
        l.template().mesh.positions
    );
}

#[test]
fn height_slider_makes_taller_bodies() {
    let l = lib();
    let mut last = 0.0;
    for h in [0.3, 0.45, 0.55, 0.7] {
        let s = stature(&l.body(&params(|p| p.height = h)));
        assert!(s > last + 0.02, "height {h}: stature {s} after {last}");
        last = s;
    }
}

#[test]
fn men_are_taller_with_broader_chests_women_wider_hips() {
    let l = lib();
    let f = l.body(&params(|p| p.gender = 0.0));
    let m = l.body(&params(|p| p.gender = 1.0));
    assert!(
        stature(&m) > stature(&f) + 0.05,
        "male {} female {}",
        stature(&m),
        stature(&f)
    );
    let (fi, mi) = (prepare(&f).unwrap(), prepare(&m).unwrap());
    let ratio = |b: &TriMesh, i: &TemplateInfo| {
        torso_hull_area(b, i.joints.hip.y, i.landmarks.crotch.x)
            / torso_hull_area(b, i.joints.chest.y, i.landmarks.crotch.x)
    };
    let (rf, rm) = (ratio(&f, &fi), ratio(&m, &mi));
    assert!(rf > 1.1 * rm, "hip/chest area: female {rf}, male {rm}");
    // Shoulders: men's acromions farther apart relative to stature.
    let sw = |i: &TemplateInfo| {
        (i.landmarks.acromion_left.x - i.landmarks.acromion_right.x) / i.stature_m
    };
    assert!(
        sw(&mi) > sw(&fi),
        "shoulder width {} vs {}",
        sw(&mi),
        sw(&fi)
    );
}

#[test]
fn age_changes_the_body_smoothly() {
    let l = lib();
    let a = l.body(&params(|p| p.age_years = 30.0));
    let b = l.body(&params(|p| p.age_years = 30.5));
    let c = l.body(&params(|p| p.age_years = 80.0));
    let d = |x: &TriMesh, y: &TriMesh| {
        x.positions
            .iter()
            .zip(&y.positions)
            .map(|(p, q)| (*p - *q).length())
            .fold(0.0, f64::max)
    };
    assert!(
        d(&a, &b) < 0.005,
        "half a year moves a vertex {} m",
        d(&a, &b)
    );
    assert!(d(&a, &c) > 0.01, "fifty years move no vertex");
    // Below 25 years the library clamps (adults only).
    assert_eq!(
        l.body(&params(|p| p.age_years = 10.0)),
        l.body(&params(|p| p.age_years = 25.0))
    );
}

#[test]
fn sampled_adults_are_deterministic_and_in_adult_ranges() {
    let l = lib();
    assert_eq!(
        ShapeLibrary::sample_adult(42),
        ShapeLibrary::sample_adult(42)
    );
    assert_ne!(
        ShapeLibrary::sample_adult(42),
        ShapeLibrary::sample_adult(43)
    );
    let (mut men, mut women) = (0, 0);
    let (mut lo, mut hi) = (f64::INFINITY, 0.0f64);
    let mut buf = Vec::new();
    for seed in 0..300 {
        let p = ShapeLibrary::sample_adult(seed);
        assert_eq!(p, p.clamp(), "seed {seed} outside the documented ranges");
        if p.gender > 0.5 {
            men += 1
        } else {
            women += 1
        }
        l.body_into(&p, &mut buf);
        let ys = buf.iter().map(|v| v.y);
        let s = ys.clone().fold(f64::NEG_INFINITY, f64::max) - ys.fold(f64::INFINITY, f64::min);
        assert!(
            (1.45..=2.05).contains(&s),
            "seed {seed}: stature {s} for {p:?}"
        );
        lo = lo.min(s);
        hi = hi.max(s);
    }
    assert!(men > 100 && women > 100, "{men} men, {women} women");
    assert!(hi - lo > 0.25, "statures only span {lo}..{hi}");
}

#[test]
fn clamp_handles_out_of_range_and_nan() {
    let p = ShapeParams {
        gender: 2.0,
        age_years: 10.0,
        muscle: f64::NAN,
        weight: -1.0,
        height: 0.3,
        proportions: 7.0,
        cup: -3.0,
    }
    .clamp();
    assert_eq!(p.gender, 1.0);
    assert_eq!(p.age_years, AGE_MIN_YEARS);
    assert_eq!(p.muscle, 0.5);
    assert_eq!(p.weight, 0.0);
    assert_eq!(p.height, 0.3);
    assert_eq!(p.proportions, 1.0);
    assert_eq!(p.cup, 0.0);
    // Extreme sliders still give finite bodies.
    let b = lib().body(&ShapeParams {
        gender: 9.0,
        age_years: 1e9,
        muscle: 1.0,
        weight: 1.0,
        height: 1.0,
        proportions: 0.0,
        cup: 1.0,
    });
    assert!(b.positions.iter().all(|v| v.is_finite()));
}

/// Midpoint subdivision (each triangle into four): another topology with more vertices.
fn subdivide(m: &TriMesh) -> TriMesh {
    let mut pos = m.positions.clone();
    let mut mid = std::collections::HashMap::new();
    let mut tris = Vec::new();
    let mut midpoint = |a: u32, b: u32, pos: &mut Vec<DVec3>| -> u32 {
        *mid.entry((a.min(b), a.max(b))).or_insert_with(|| {
            pos.push(0.5 * (pos[a as usize] + pos[b as usize]));
            (pos.len() - 1) as u32
        })
    };
    for t in &m.triangles {
        let [a, b, c] = *t;
        let (ab, bc, ca) = (
            midpoint(a, b, &mut pos),
            midpoint(b, c, &mut pos),
            midpoint(c, a, &mut pos),
        );
        tris.extend([[a, ab, ca], [ab, b, bc], [ca, bc, c], [ab, bc, ca]]);
    }
    TriMesh::new(pos, tris)
}

fn assert_infos_agree(a: &TemplateInfo, b: &TemplateInfo, tol_m: f64, what: &str) {
    for ((name, p), (_, q)) in a.joints.named().into_iter().zip(b.joints.named()) {
        assert!(
            (p - q).length() < tol_m,
            "{what}: {name} differs by {} m ({p:?} vs {q:?})",
            (p - q).length()
        );
    }
    let (la, lb) = (&a.landmarks, &b.landmarks);
    for (name, x, y) in [
        ("crotch_y", la.crotch_y, lb.crotch_y),
        ("armpit_y", la.armpit_y, lb.armpit_y),
        ("acromion_y", la.acromion_y, lb.acromion_y),
        ("neck_cut_y", la.neck_cut_y, lb.neck_cut_y),
    ] {
        assert!((x - y).abs() < tol_m, "{what}: {name} {x} vs {y}");
    }
    assert!((a.stature_m - b.stature_m).abs() < 0.005, "{what}: stature");
}

#[test]
fn prepare_agrees_across_topologies() {
    let t = lib().template();
    let fresh = prepare(&t.mesh).unwrap();
    // The stored sidecar is what prepare() gives today.
    assert_infos_agree(&fresh, &t.info, 1e-6, "sidecar");
    let dec = decimate::decimate(&t.mesh, t.mesh.vertex_count() * 35 / 100);
    assert!(dec.vertex_count() < t.mesh.vertex_count() / 2);
    assert_eq!(dec.boundary_edge_count(), 0);
    let di = prepare(&dec).unwrap();
    assert_infos_agree(&fresh, &di, 0.02, "decimated");
    let sub = subdivide(&t.mesh);
    let si = prepare(&sub).unwrap();
    assert_infos_agree(&fresh, &si, 0.02, "subdivided");
    // Rigid parts cover the same region: compare bounding boxes (vertex centroids would
    // depend on the vertex density).
    let bbox = |m: &TriMesh, s: &[u32]| {
        let pts: Vec<DVec3> = s.iter().map(|&i| m.positions[i as usize]).collect();
        crate::mesh::Aabb::from_points(&pts).unwrap()
    };
    for (name, a, b) in [
        ("head", &fresh.rigid.head, &di.rigid.head),
        ("hand_left", &fresh.rigid.hand_left, &di.rigid.hand_left),
        ("hand_right", &fresh.rigid.hand_right, &di.rigid.hand_right),
        ("foot_left", &fresh.rigid.foot_left, &di.rigid.foot_left),
        ("foot_right", &fresh.rigid.foot_right, &di.rigid.foot_right),
    ] {
        let (ba, bb) = (bbox(&t.mesh, a), bbox(&dec, b));
        let d = (ba.min - bb.min).length().max((ba.max - bb.max).length());
        assert!(d < 0.02, "{name} box moved {d} m");
    }
}

#[test]
fn prepare_finds_a_shifted_copy_shifted() {
    let t = lib().template();
    let mut m = t.mesh.clone();
    let shift = DVec3::new(0.3, 0.1, -0.2);
    m.map_positions(|p| p + shift);
    let i = prepare(&m).unwrap();
    for ((name, p), (_, q)) in t.info.joints.named().into_iter().zip(i.joints.named()) {
        assert!(
            (p + shift - q).length() < 0.003,
            "{name}: {p:?} + shift vs {q:?}"
        );
    }
}

#[test]
fn prepare_rejects_non_bodies() {
    assert!(prepare(&TriMesh::default()).is_err());
    // A closed cylinder of a person's height has no legs.
    let c = crate::mesh::shapes::elliptic_cylinder(0.15, 0.1, 1.7, 40, 32);
    let e = prepare(&c).unwrap_err();
    assert!(e.to_string().contains("crotch"), "{e}");
}

// ---------- file robustness ----------

fn tiny_library() -> LibraryData {
    LibraryData {
        meta: LibraryMeta {
            source: "test".into(),
            variables: vec![Variable {
                name: "weight".into(),
                knots: vec![
                    Knot {
                        name: "minweight".into(),
                        value: 0.0,
                    },
                    Knot {
                        name: "averageweight".into(),
                        value: 0.5,
                    },
                    Knot {
                        name: "maxweight".into(),
                        value: 1.0,
                    },
                ],
            }],
        },
        base: vec![[0, 0, 0], [100000, 0, 0], [0, 100000, 0], [0, 0, 100000]],
        triangles: vec![[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]],
        targets: vec![TargetData {
            name: "maxweight".into(),
            factor: 1.0,
            keys: vec!["maxweight".into()],
            indices: vec![1, 3],
            offsets: vec![[1000, -5, 7], [0, 0, -300]],
        }],
    }
}

#[test]
fn library_file_round_trips() {
    let d = tiny_library();
    let bytes = d.encode();
    assert_eq!(LibraryData::decode(&bytes, Path::new("t.fsl")).unwrap(), d);
}

#[test]
fn truncated_or_corrupt_library_files_give_errors_naming_the_file() {
    let d = tiny_library();
    let raw = d.encode_raw();
    let file = Path::new("hostile.fsl");
    for cut in 0..raw.len() {
        let e = LibraryData::decode_raw(&raw[..cut], file).expect_err("truncated stream accepted");
        assert!(e.to_string().contains("hostile.fsl"), "{e}");
    }
    // Single-byte mutations never panic; each either parses or is an error.
    for i in 0..raw.len() {
        for v in [0u8, 0x7f, 0x80, 0xff] {
            let mut r = raw.clone();
            r[i] = v;
            if let Err(e) = LibraryData::decode_raw(&r, file) {
                assert!(e.to_string().contains("hostile.fsl"));
            }
        }
    }
    let bytes = d.encode();
    for cut in [0, 4, 8, 12, bytes.len() / 2, bytes.len() - 1] {
        assert!(LibraryData::decode(&bytes[..cut], file).is_err());
    }
    let mut bad = bytes.clone();
    bad[0] = b'X';
    assert!(LibraryData::decode(&bad, file)
        .unwrap_err()
        .to_string()
        .contains("magic"));
    // A target keyed on an unknown knot is refused when building the library.
    let mut d2 = tiny_library();
    d2.targets[0].keys = vec!["hugeweight".into()];
    let e = ShapeLibrary::from_data(d2, None, file).unwrap_err();
    assert!(e.to_string().contains("hugeweight"), "{e}");
}

#[test]
fn hostile_target_lines_name_file_and_line() {
    let f = Path::new("x.target");
    for (text, line) in [
        ("0 0 0 0\n1 0.1 0.2\n", 2),
        ("# c\n\nx 1 2 3\n", 3),
        ("5 1 2 3\n", 1),
        ("1 nan 0 0\n", 1),
        ("1 1e300 0 0\n", 1),
        ("1 0 0 0 0\n", 1),
        ("-1 0 0 0\n", 1),
    ] {
        let e = parse_target(text.as_bytes(), f, 5)
            .err()
            .unwrap_or_else(|| panic!("accepted {text:?}"));
        let s = e.to_string();
        assert!(
            s.starts_with(&format!("x.target:{line}:")),
            "{text:?} -> {s}"
        );
    }
    let ok = parse_target("# header\n0 .1 -.2 3\n4 0 0 0\n".as_bytes(), f, 5).unwrap();
    assert_eq!(ok.entries.len(), 2);
    // A truncated gzip file is an error with the file name, not a panic.
    let dir = std::env::temp_dir().join(format!("fitstation-body-gz-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let mut enc = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::default());
    for i in 0..2000 {
        writeln!(enc, "{i} 0.{i} 0.1 -0.1").unwrap();
    }
    let gz = enc.finish().unwrap();
    let p = dir.join("cut.target.gz");
    std::fs::write(&p, &gz[..gz.len() / 2]).unwrap();
    let e = read_target(&p, 5000).unwrap_err().to_string();
    assert!(e.contains("cut.target.gz"), "{e}");
    std::fs::write(&p, b"not gzip at all").unwrap();
    assert!(read_target(&p, 5000)
        .unwrap_err()
        .to_string()
        .contains("cut.target.gz"));
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn garbled_sidecars_are_errors_with_line() {
    let f = Path::new("m.template.json");
    let good = serde_json::to_string_pretty(&lib().template().info).unwrap();
    let n = lib().template().mesh.vertex_count();
    assert!(TemplateInfo::from_json(&good, f, n).is_ok());
    let e = TemplateInfo::from_json(&good[..good.len() / 2], f, n)
        .unwrap_err()
        .to_string();
    assert!(e.starts_with("m.template.json:"), "{e}");
    let e = TemplateInfo::from_json(
        &good.replacen("\"stature_m\"", "\"stature_m\": \"tall\", \"x\"", 1),
        f,
        n,
    )
    .unwrap_err();
    assert!(e.to_string().starts_with("m.template.json:"), "{e}");
    assert!(TemplateInfo::from_json(&good, f, n + 1)
        .unwrap_err()
        .to_string()
        .contains("vertices"));
    let mut bad = lib().template().info.clone();
    bad.rigid.head.push(n as u32 + 5);
    let e = TemplateInfo::from_json(&serde_json::to_string(&bad).unwrap(), f, n).unwrap_err();
    assert!(e.to_string().contains("rigid"), "{e}");
}

// ---------- importer frame decisions on a synthetic figure ----------

/// Appends a box (decimetres) subdivided in y every 0.2 dm as quads to an OBJ text.
fn obj_box(v: &mut Vec<DVec3>, f: &mut Vec<Vec<u32>>, lo: DVec3, hi: DVec3) {
    let rings = ((hi.y - lo.y) / 0.2).ceil().max(1.0) as usize;
    let corners = [(lo.x, lo.z), (hi.x, lo.z), (hi.x, hi.z), (lo.x, hi.z)];
    let base = v.len() as u32;
    for r in 0..=rings {
        let y = lo.y + (hi.y - lo.y) * r as f64 / rings as f64;
        for &(x, z) in &corners {
            v.push(DVec3::new(x, y, z));
        }
    }
    let idx = |r: usize, k: usize| base + (r * 4 + k % 4) as u32;
    for r in 0..rings {
        for k in 0..4 {
            f.push(vec![
                idx(r, k),
                idx(r, k + 1),
                idx(r + 1, k + 1),
                idx(r + 1, k),
            ]);
        }
    }
    f.push(vec![idx(0, 3), idx(0, 2), idx(0, 1), idx(0, 0)]);
    f.push(vec![
        idx(rings, 0),
        idx(rings, 1),
        idx(rings, 2),
        idx(rings, 3),
    ]);
}

/// Writes a crude MakeHuman-like folder whose figure has been transformed by `xf`.
fn synthetic_mpfb2(dir: &Path, xf: impl Fn(DVec3) -> DVec3) {
    let (mut v, mut f) = (Vec::new(), Vec::new());
    let b = |x0: f64, y0: f64, z0: f64, x1: f64, y1: f64, z1: f64| {
        (DVec3::new(x0, y0, z0), DVec3::new(x1, y1, z1))
    };
    for (lo, hi) in [
        b(-1.5, 0.0, -1.0, 1.5, 6.0, 1.0),   // torso
        b(-0.8, 6.5, -1.0, 0.8, 8.5, 1.0),   // head
        b(0.3, -7.9, -0.6, 1.3, 0.0, 0.6),   // left leg
        b(-1.3, -7.9, -0.6, -0.3, 0.0, 0.6), // right leg
        b(0.3, -8.2, -0.6, 1.3, -7.9, 2.0),  // left foot, toes forward
        b(-1.3, -8.2, -0.6, -0.3, -7.9, 2.0),
    ] {
        obj_box(&mut v, &mut f, lo, hi);
    }
    let mut s = String::from("# synthetic\n");
    for p in &v {
        let q = xf(*p);
        s += &format!("v {} {} {}\n", q.x, q.y, q.z);
    }
    s += "g body\n";
    for face in &f {
        s += &format!(
            "f {}\n",
            face.iter()
                .map(|i| (i + 1).to_string())
                .collect::<Vec<_>>()
                .join(" ")
        );
    }
    // Eye helpers: small triangles in front of the head, left eye at +X.
    let mut n = v.len();
    for (name, x) in [("joint-l-eye", 0.3), ("joint-r-eye", -0.3)] {
        for d in [
            DVec3::ZERO,
            DVec3::new(0.05, 0.0, 0.0),
            DVec3::new(0.0, 0.05, 0.0),
        ] {
            let q = xf(DVec3::new(x, 7.3, 1.2) + d);
            s += &format!("v {} {} {}\n", q.x, q.y, q.z);
        }
        s += &format!("g {name}\nf {} {} {}\n", n + 1, n + 2, n + 3);
        n += 3;
    }
    std::fs::create_dir_all(dir.join("3dobjs")).unwrap();
    std::fs::write(dir.join("3dobjs/base.obj"), s).unwrap();
    let md = dir.join("targets/macrodetails");
    for sub in ["height", "proportions"] {
        std::fs::create_dir_all(md.join(sub)).unwrap();
    }
    std::fs::write(
        md.join("macro.json"),
        r#"{"macrotargets": {
            "gender": {"parts": [{"lowest": -0.01, "highest": 1.01, "low": "female", "high": "male"}]},
            "age": {"parts": [{"lowest": -0.01, "highest": 0.1874998, "low": "baby", "high": "child"},
                              {"lowest": 0.1874999, "highest": 0.49998, "low": "child", "high": "young"},
                              {"lowest": 0.49999, "highest": 1.01, "low": "young", "high": "old"}]},
            "weight": {"parts": [{"lowest": -0.01, "highest": 0.49998, "low": "minweight", "high": "averageweight"},
                                 {"lowest": 0.49999, "highest": 1.01, "low": "averageweight", "high": "maxweight"}]},
            "muscle": {"parts": [{"lowest": -0.01, "highest": 0.49998, "low": "minmuscle", "high": "averagemuscle"},
                                 {"lowest": 0.49999, "highest": 1.01, "low": "averagemuscle", "high": "maxmuscle"}]},
            "cupsize": {"parts": [{"lowest": -0.01, "highest": 0.49998, "low": "mincup", "high": "averagecup"},
                                  {"lowest": 0.49999, "highest": 1.01, "low": "averagecup", "high": "maxcup"}]},
            "firmness": {"parts": [{"lowest": -0.01, "highest": 0.4998, "low": "minfirmness", "high": "averagefirmness"},
                                   {"lowest": 0.4999, "highest": 1.01, "low": "averagefirmness", "high": "maxfirmness"}]}
        }}"#,
    )
    .unwrap();
    // Offsets are given in the file's (transformed) frame, like the positions.
    let gz = |name: &str, entries: &[(u32, DVec3)]| {
        let mut e = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::default());
        for (i, d) in entries {
            let q = xf(*d);
            writeln!(e, "{i} {} {} {}", q.x, q.y, q.z).unwrap();
        }
        std::fs::write(md.join(name), e.finish().unwrap()).unwrap();
    };
    gz(
        "universal-female-young-maxweight.target.gz",
        &[
            (0, DVec3::new(0.1, 0.0, 0.0)),
            (3, DVec3::new(0.0, 0.2, 0.0)),
        ],
    );
    gz(
        "universal-female-child-maxweight.target.gz",
        &[(0, DVec3::new(0.1, 0.0, 0.0))],
    );
    gz(
        "african-male-old.target.gz",
        &[(0, DVec3::new(0.3, 0.0, 0.0))],
    );
    // Breast macro targets: one kept, one at another firmness (weight 0 at the library's
    // fixed firmness), one child's, and a local modifier that is no macro target.
    let breast = dir.join("targets/breast");
    std::fs::create_dir_all(&breast).unwrap();
    for name in [
        "female-young-averagemuscle-averageweight-maxcup-averagefirmness",
        "female-young-averagemuscle-averageweight-maxcup-minfirmness",
        "female-child-averagemuscle-averageweight-maxcup-averagefirmness",
        "breast-dist-incr",
    ] {
        gz(
            &format!("../breast/{name}.target.gz"),
            &[(1, DVec3::new(0.0, 0.0, 0.05))],
        );
    }
}

#[test]
fn importer_turns_and_mirrors_figures_into_the_station_frame() {
    let root = std::env::temp_dir().join(format!("fitstation-body-import-{}", std::process::id()));
    type Variant = (&'static str, fn(DVec3) -> DVec3, bool, bool);
    let variants: [Variant; 4] = [
        ("plain", |p| p, false, false),
        ("turned", |p| DVec3::new(-p.x, p.y, -p.z), true, false),
        ("mirrored", |p| DVec3::new(-p.x, p.y, p.z), false, true),
        ("backwards", |p| DVec3::new(p.x, p.y, -p.z), true, true),
    ];
    let mut reference: Option<Vec<[i32; 3]>> = None;
    for (name, xf, turned, mirrored) in variants {
        let dir = root.join(name);
        synthetic_mpfb2(&dir, xf);
        let r = import_mpfb2(&dir).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_eq!(
            (r.report.turned_180_about_y, r.report.mirrored_x),
            (turned, mirrored),
            "{name}"
        );
        assert!(
            r.report.left_eye_x_m > 0.0
                && r.report.eyes_ahead_m > 0.0
                && r.report.toes_ahead_m > 0.0
        );
        assert_eq!(
            r.report.targets_skipped_non_adult, 2,
            "{name}: child targets not skipped"
        );
        assert_eq!(r.report.targets_skipped_firmness, 1, "{name}");
        // The kept breast target carries its six knots; the local modifier is not read.
        let cup: Vec<_> = r
            .data
            .targets
            .iter()
            .filter(|t| t.keys.iter().any(|k| k == "maxcup"))
            .collect();
        assert_eq!(cup.len(), 1, "{name}");
        assert_eq!(
            cup[0].keys,
            [
                "female",
                "young",
                "averagemuscle",
                "averageweight",
                "maxcup",
                "averagefirmness"
            ]
        );
        assert_eq!(
            (cup[0].indices[0], cup[0].offsets[0]),
            (1, [0, 0, 500]),
            "{name}"
        );
        assert!(r
            .data
            .targets
            .iter()
            .all(|t| !t.name.starts_with("breast-")));
        // Every variant lands on the same station-frame figure, outward oriented.
        let m = TriMesh::new(
            r.data
                .base
                .iter()
                .map(|p| DVec3::new(p[0] as f64, p[1] as f64, p[2] as f64))
                .collect(),
            r.data.triangles.clone(),
        );
        assert!(m.volume() > 0.0, "{name}: inward");
        match &reference {
            None => reference = Some(r.data.base.clone()),
            Some(b) => assert_eq!(b, &r.data.base, "{name}: different station-frame geometry"),
        }
        // Offsets follow the frame: the female target moves vertex 0 by 0.01 m toward the
        // figure's own left, which is +X after import whatever the file's frame.
        let t = r
            .data
            .targets
            .iter()
            .find(|t| t.name.contains("female-young"))
            .unwrap();
        assert_eq!(t.indices[0], 0);
        assert_eq!(t.offsets[0], [1000, 0, 0], "{name}");
        // Race targets are premixed with weight 1/3.
        let race = r
            .data
            .targets
            .iter()
            .find(|t| t.name.starts_with("racemix"))
            .unwrap();
        assert_eq!(race.keys, vec!["male".to_string(), "old".to_string()]);
        assert_eq!(race.offsets[0], [1000, 0, 0]);
    }
    // A broken target file names its line.
    let md = root.join("plain/targets/macrodetails");
    std::fs::write(md.join("height/x-young.target.gz"), b"garbage").unwrap();
    let e = import_mpfb2(&root.join("plain")).unwrap_err().to_string();
    assert!(e.contains("x-young.target.gz"), "{e}");
    let _ = std::fs::remove_dir_all(&root);
}

#[test]
fn prepare_works_across_the_library() {
    let l = lib();
    let mut extremes: Vec<ShapeParams> = (0..24).map(ShapeLibrary::sample_adult).collect();
    for (g, w, m) in [
        (0.0, 0.9, 0.2),
        (1.0, 0.9, 0.9),
        (0.0, 0.1, 0.1),
        (1.0, 0.1, 0.9),
    ] {
        extremes.push(ShapeParams {
            gender: g,
            weight: w,
            muscle: m,
            ..Default::default()
        });
    }
    for p in extremes {
        let Template { mesh: b, info: i } =
            l.template_for(&p).unwrap_or_else(|e| panic!("{p:?}: {e}"));
        assert_eq!(b.vertex_count(), i.vertex_count);
        // Soles on the floor, feet around the mark.
        assert!(i.landmarks.sole_y.abs() < 1e-9, "{p:?}");
        let (j, lm) = (&i.joints, &i.landmarks);
        assert!(
            lm.crotch_y < lm.armpit_y && lm.armpit_y < lm.acromion_y,
            "{p:?}"
        );
        assert!(
            j.knee_left.y < lm.crotch_y && j.elbow_left.x > j.shoulder_left.x,
            "{p:?}"
        );
        assert!(j.hand_left.x > 0.0 && j.hand_right.x < 0.0, "{p:?}");
        // The library's centring used the template's feet: still near the mark.
        assert!(j.ankle_left.x > 0.0 && j.ankle_right.x < 0.0, "{p:?}");
    }
}

#[test]
fn load_from_folder_matches_the_embedded_library() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("templates");
    let l = ShapeLibrary::load(&dir).unwrap();
    assert_eq!(l.template().mesh, lib().template().mesh);
    assert_eq!(l.template().info, lib().template().info);
    let e = ShapeLibrary::load(Path::new("/nonexistent-dir"))
        .unwrap_err()
        .to_string();
    assert!(e.contains("nonexistent-dir"), "{e}");
    // Template::load reads the committed OBJ and its sidecar.
    let t = Template::load(&dir.join(library::TEMPLATE_MESH_FILE)).unwrap();
    assert_eq!(t.info, lib().template().info);
    assert!((t.mesh.positions[0] - lib().template().mesh.positions[0]).length() < 1e-5);
}

#[test]
fn prepare_tolerates_small_holes_and_a_slight_turn() {
    let t = lib().template();
    // Punch holes: drop the triangles around a few vertices at the waist, the crotch, a
    // knee and an upper arm (as a scan with missing patches would have).
    let j = &t.info.joints;
    let mut m = t.mesh.clone();
    let near = |p: DVec3, c: DVec3| (p - c).length() < 0.012;
    let centres = [
        DVec3::new(j.waist.x + 0.1, j.waist.y, j.waist.z),
        t.info.landmarks.crotch,
        j.knee_left,
        0.5 * (j.shoulder_left + j.elbow_left),
    ];
    // Move each centre onto the nearest surface vertex.
    let centres: Vec<DVec3> = centres
        .iter()
        .map(|c| {
            *m.positions
                .iter()
                .min_by(|a, b| (**a - *c).length().total_cmp(&(**b - *c).length()))
                .unwrap()
        })
        .collect();
    let before = m.triangle_count();
    m.triangles.retain(|tri| {
        !tri.iter()
            .any(|&v| centres.iter().any(|c| near(m.positions[v as usize], *c)))
    });
    assert!(m.triangle_count() < before && m.boundary_edge_count() > 0);
    let holed = prepare(&m).unwrap();
    assert_infos_agree(&t.info, &holed, 0.02, "holed");
    // A 3 degree turn about Y (a scan not quite square to the cameras).
    let a = 3f64.to_radians();
    let rot = |p: DVec3| {
        DVec3::new(
            p.x * a.cos() + p.z * a.sin(),
            p.y,
            -p.x * a.sin() + p.z * a.cos(),
        )
    };
    let mut r = t.mesh.clone();
    r.map_positions(rot);
    let ri = prepare(&r).unwrap();
    for ((name, p), (_, q)) in t.info.joints.named().into_iter().zip(ri.joints.named()) {
        assert!(
            (rot(p) - q).length() < 0.02,
            "turned: {name} off by {}",
            (rot(p) - q).length()
        );
    }
}

#[test]
fn committed_decimated_template_agrees_with_the_library_template() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("templates");
    let t = Template::load(&dir.join("makehuman-adult-decimated.obj")).unwrap();
    assert!(t.mesh.vertex_count() < lib().template().mesh.vertex_count() / 2);
    assert_eq!(t.mesh.boundary_edge_count(), 0);
    // Its committed sidecar is what prepare() gives, and agrees with the library's.
    assert_infos_agree(
        &prepare(&t.mesh).unwrap(),
        &t.info,
        1e-6,
        "decimated sidecar",
    );
    assert_infos_agree(
        &lib().template().info,
        &t.info,
        0.02,
        "decimated vs library",
    );
}
