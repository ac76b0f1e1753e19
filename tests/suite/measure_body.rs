//! Measurements of the MakeHuman base body (CC0, `base.obj` group `body`, decimetres,
//! Y up, facing +Z): plausible adult values, symmetric thighs, +X is the subject's left.
//! When the file is missing (it is extracted by hand, not installed by `.ci/run`) the
//! tests print a loud SKIPPED line and pass.

use fitstation::measure::{cli, measure, LoopSelector};
use fitstation::mesh::io::{read_obj, write_obj};
use fitstation::mesh::TriMesh;
use glam::DVec3;

/// The raw MakeHuman base mesh in the cache directory (`fitstation::io::cache`).
fn base_obj() -> std::path::PathBuf {
    fitstation::io::cache::makehuman_base_obj()
}
/// MakeHuman stores decimetres.
const METRES_PER_UNIT: f64 = 0.1;

/// The body in the station frame (metres, soles on y = 0), or `None` (skipped) if the
/// MakeHuman data is not on this machine.
fn body_in_station() -> Option<TriMesh> {
    let base = base_obj();
    let path = base.as_path();
    if !path.exists() {
        println!(
            "SKIPPED: {} not found (MakeHuman base mesh)",
            base.display()
        );
        assert!(
            std::env::var_os("CI").is_none(),
            "{} missing in CI (.ci/run installs it)",
            base.display()
        );
        return None;
    }
    let mut m = read_obj(path, Some("body")).expect("MakeHuman body group");
    let floor = m
        .positions
        .iter()
        .map(|p| p.y)
        .fold(f64::INFINITY, f64::min)
        * METRES_PER_UNIT;
    m.map_positions(|p| p * METRES_PER_UNIT - DVec3::new(0.0, floor, 0.0));
    Some(m)
}

#[test]
fn makehuman_faces_plus_z_with_its_left_on_plus_x() {
    let Some(_) = body_in_station() else { return };
    let centroid = |group: &str| {
        let m = read_obj(&base_obj(), Some(group)).expect("joint group");
        m.positions.iter().copied().sum::<DVec3>() / m.positions.len() as f64
    };
    // MakeHuman names the subject's own left "l".
    let (left_eye, right_eye) = (centroid("joint-l-eye"), centroid("joint-r-eye"));
    assert!(
        left_eye.x > 0.0 && right_eye.x < 0.0,
        "{left_eye} {right_eye}"
    );
    let (left_knee, right_knee) = (centroid("joint-l-knee"), centroid("joint-r-knee"));
    assert!(left_knee.x > 0.0 && right_knee.x < 0.0);
    // Eyes are in front of the head's centre: the subject faces +Z.
    let head = read_obj(&base_obj(), Some("body")).expect("body");
    let top = head
        .positions
        .iter()
        .map(|p| p.y)
        .fold(f64::NEG_INFINITY, f64::max);
    let head_pts: Vec<DVec3> = head
        .positions
        .iter()
        .copied()
        .filter(|p| p.y > top - 2.0)
        .collect();
    let head_mid_z = head_pts.iter().map(|p| p.z).sum::<f64>() / head_pts.len() as f64;
    assert!(left_eye.z > head_mid_z);
}

#[test]
fn makehuman_body_has_plausible_adult_measurements() {
    let Some(body) = body_in_station() else {
        return;
    };
    let m = measure(&body).expect("MakeHuman body measures");
    println!("{}", cli::table(&m));
    let within = |what: &str, v: f64, lo: f64, hi: f64| {
        assert!(
            v >= lo && v <= hi,
            "{what} = {v:.1} mm outside [{lo}, {hi}]"
        );
    };
    within("stature", m.stature_mm, 1600.0, 1800.0);
    // The raw MakeHuman mesh's upper arms touch its trunk between about 1.22 and 1.38 m
    // (its slices there are one loop from arm to arm), so by shared/spec/measurements.md
    // the tape at the chest level, within 0.10 x stature under the armpits, goes around
    // the arms too (1228 mm). The station's template has its arms apart
    // (tests/measure_template.rs).
    within("chest", m.chest_girth_mm, 850.0, 1300.0);
    assert!(
        m.levels.chest_m < m.levels.armpit_m
            && m.levels.chest_m >= m.levels.armpit_m - 0.1 * m.stature_mm / 1000.0 - 1e-6,
        "chest level {} outside the armpit {} window",
        m.levels.chest_m,
        m.levels.armpit_m
    );
    within("waist", m.waist_girth_mm, 650.0, 950.0);
    within("hip", m.hip_girth_mm, 850.0, 1100.0);
    within("thigh left", m.thigh_girth_left_mm, 450.0, 650.0);
    within("thigh right", m.thigh_girth_right_mm, 450.0, 650.0);
    let asym = (m.thigh_girth_left_mm - m.thigh_girth_right_mm).abs() / m.thigh_girth_right_mm;
    assert!(asym < 0.02, "thighs differ by {:.2} %", asym * 100.0);
    // Levels in anatomical order, and the girths ordered as on any adult.
    let l = &m.levels;
    assert!(l.thigh_left_m < l.crotch_m && l.crotch_m < l.hip_m && l.hip_m < l.waist_m);
    assert!(l.waist_m < l.chest_m && l.chest_m <= l.armpit_m);
    assert!(m.waist_girth_mm < m.hip_girth_mm && m.waist_girth_mm < m.chest_girth_mm);
    // The waist is the least torso girth of the grid between crotch and chest (spec
    // step 1 finds it, step 3 keeps it above the hip_girth_max level).
    let min_profile = m
        .torso_profile
        .iter()
        .filter(|s| s.height_m <= l.chest_m)
        .map(|s| s.girth_mm)
        .fold(f64::INFINITY, f64::min);
    assert!(m.waist_girth_mm <= min_profile + 1e-9);
    // A girth read back at a reported level agrees with the reported value.
    let axis_x = l.axis_x_m;
    let g = fitstation::measure::girth_at(&body, l.waist_m, LoopSelector::Torso { axis_x })
        .expect("waist");
    assert!((g * 1e3 - m.waist_girth_mm).abs() < 1e-6);
    // The station-frame body for `fitstation measure` by hand.
    let out = std::env::temp_dir().join("fitstation_makehuman_body.obj");
    write_obj(&out, &body).expect("write station-frame body");
}

#[test]
fn json_report_has_the_report_keys() {
    let Some(body) = body_in_station() else {
        return;
    };
    let m = measure(&body).expect("MakeHuman body measures");
    let json = cli::json_report(&m, 1.0, 1.0);
    let mm = json["measurements_mm"]
        .as_object()
        .expect("measurements_mm object");
    let keys: Vec<&str> = mm.keys().map(|k| k.as_str()).collect();
    let mut want = vec![
        "stature",
        "chest_girth",
        "waist_girth",
        "hip_girth",
        "thigh_girth_left",
        "thigh_girth_right",
        "hip_girth_max",
    ];
    want.sort();
    let mut got = keys.clone();
    got.sort();
    assert_eq!(got, want);
    assert_eq!(mm["chest_girth"].as_f64(), Some(m.chest_girth_mm));
    assert_eq!(mm["thigh_girth_left"].as_f64(), Some(m.thigh_girth_left_mm));
    let back: fitstation::measure::Measurements =
        serde_json::from_value(serde_json::to_value(&m).expect("serialise")).expect("deserialise");
    assert_eq!(back, m);
}

/// MakeHuman's macro targets (per-vertex offsets of the base mesh, decimetres) in the
/// cache directory.
fn targets_dir() -> std::path::PathBuf {
    fitstation::io::cache::makehuman_mpfb2_dir().join("targets/macrodetails")
}

/// Adds `weight` x the target `name` (a gzipped "index dx dy dz" list) to `mesh`, in
/// base-mesh units; the body group holds the base mesh's first vertices in order.
fn apply_target(mesh: &mut TriMesh, name: &str, weight: f64) {
    use std::io::Read;
    let path = targets_dir().join(format!("{name}.target.gz"));
    let file = std::fs::File::open(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let mut text = String::new();
    flate2::read::GzDecoder::new(file)
        .read_to_string(&mut text)
        .unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    for line in text.lines().filter(|l| !l.starts_with('#')) {
        let f: Vec<f64> = line
            .split_whitespace()
            .filter_map(|t| t.parse().ok())
            .collect();
        if let [i, dx, dy, dz] = f[..] {
            if let Some(p) = mesh.positions.get_mut(i as usize) {
                *p += weight * DVec3::new(dx, dy, dz);
            }
        }
    }
}

/// A MakeHuman young adult of `gender` ("female" / "male", the three ethnic targets
/// mixed equally) plus `extra` targets, in the station frame.
fn makehuman_variant(gender: &str, extra: &[&str]) -> TriMesh {
    let mut m = read_obj(&base_obj(), Some("body")).expect("MakeHuman body group");
    for ethnic in ["caucasian", "african", "asian"] {
        apply_target(&mut m, &format!("{ethnic}-{gender}-young"), 1.0 / 3.0);
    }
    for name in extra {
        apply_target(&mut m, name, 1.0);
    }
    let floor = m
        .positions
        .iter()
        .map(|p| p.y)
        .fold(f64::INFINITY, f64::min)
        * METRES_PER_UNIT;
    m.map_positions(|p| p * METRES_PER_UNIT - DVec3::new(0.0, floor, 0.0));
    m
}

#[test]
fn makehuman_women_and_men_of_every_build_measure_plausibly() {
    if body_in_station().is_none() {
        return;
    }
    let mut by_weight = Vec::new();
    for gender in ["female", "male"] {
        let builds = [
            (
                "minweight",
                format!("universal-{gender}-young-averagemuscle-minweight"),
            ),
            ("average", String::new()),
            (
                "maxweight",
                format!("universal-{gender}-young-averagemuscle-maxweight"),
            ),
            (
                "maxmuscle",
                format!("universal-{gender}-young-maxmuscle-averageweight"),
            ),
        ];
        for (build, target) in &builds {
            let extra: Vec<&str> = [target.as_str()]
                .into_iter()
                .filter(|t| !t.is_empty())
                .collect();
            let body = makehuman_variant(gender, &extra);
            let m = measure(&body).unwrap_or_else(|e| panic!("{gender} {build}: {e}"));
            let what = format!("{gender} {build}: {m:?}");
            let (s, l) = (m.stature_mm / 1e3, &m.levels);
            // Adult proportions: crotch 0.42-0.52 and armpit 0.70-0.80 of stature.
            assert!((0.42..0.52).contains(&(l.crotch_m / s)), "{what}");
            assert!((0.70..0.80).contains(&(l.armpit_m / s)), "{what}");
            assert!(
                l.thigh_left_m < l.crotch_m && l.crotch_m < l.hip_m && l.hip_m < l.waist_m,
                "{what}"
            );
            assert!(l.waist_m < l.chest_m && l.chest_m <= l.armpit_m, "{what}");
            assert!(
                m.waist_girth_mm < m.chest_girth_mm && m.waist_girth_mm < m.hip_girth_mm,
                "{what}"
            );
            assert!(m.thigh_girth_left_mm < m.hip_girth_mm, "{what}");
            let asym =
                (m.thigh_girth_left_mm - m.thigh_girth_right_mm).abs() / m.thigh_girth_right_mm;
            assert!(asym < 0.02, "{what}");
            for g in [m.chest_girth_mm, m.waist_girth_mm, m.hip_girth_mm] {
                assert!((500.0..1500.0).contains(&g), "{what}");
            }
            if *build != "maxmuscle" {
                by_weight.push((gender, *build, m));
            }
        }
    }
    // Weight only adds girth: min < average < max weight for every tape girth.
    for w in by_weight.windows(3).filter(|w| w[0].0 == w[2].0) {
        for girth in [
            |m: &fitstation::measure::Measurements| m.chest_girth_mm,
            |m: &fitstation::measure::Measurements| m.waist_girth_mm,
            |m: &fitstation::measure::Measurements| m.hip_girth_mm,
            |m: &fitstation::measure::Measurements| m.thigh_girth_left_mm,
        ] {
            let (a, b, c) = (girth(&w[0].2), girth(&w[1].2), girth(&w[2].2));
            assert!(
                a < b && b < c,
                "{} {}/{}/{}: {a} {b} {c}",
                w[0].0,
                w[0].1,
                w[1].1,
                w[2].1
            );
        }
    }
}
