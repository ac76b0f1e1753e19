//! One camera and the second deformer (issue 23 items 3 and 1), end to end on the bundled
//! demo recording: a front photo alone is fitted and says so, with a wider `±` than the
//! two photos; a recording whose side folder stops half way keeps producing results;
//! `--deformer laplacian` fits the same subject with sane girths.

use fitstation::recording::Recording;
use serde_json::Value;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::Mutex;

/// The tests run one at a time (the machine's two cores are shared).
static SERIAL: Mutex<()> = Mutex::new(());

const GIRTHS: [&str; 5] = [
    "chest_girth",
    "waist_girth",
    "hip_girth",
    "thigh_girth_left",
    "thigh_girth_right",
];

fn demo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("recordings/demo")
}

use crate::common;

fn tmp(name: &str) -> common::TempDir {
    common::tmp_dir("onecam", name)
}

fn fitstation(args: &[&str]) -> Value {
    let o = Command::new(env!("CARGO_BIN_EXE_fitstation"))
        .args(args)
        .output()
        .expect("run fitstation");
    assert!(
        o.status.success(),
        "fitstation {args:?} failed: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    let out = args
        .iter()
        .position(|a| *a == "--out")
        .map(|i| PathBuf::from(args[i + 1]))
        .expect("--out");
    let text = std::fs::read_to_string(out.join("report.json")).expect("report.json");
    serde_json::from_str(&text).expect("report JSON")
}

fn truth() -> Value {
    let text = std::fs::read_to_string(demo().with_extension("truth").join("truth.json"))
        .expect("demo truth");
    serde_json::from_str(&text).expect("truth JSON")
}

fn num(v: &Value, keys: &[&str]) -> f64 {
    keys.iter()
        .fold(v, |v, k| &v[*k])
        .as_f64()
        .unwrap_or_else(|| panic!("no number at {keys:?}"))
}

fn views(report: &Value) -> Vec<String> {
    report["views"]
        .as_array()
        .expect("views")
        .iter()
        .map(|v| v.as_str().expect("view name").to_string())
        .collect()
}

fn p(path: &Path) -> &str {
    path.to_str().expect("utf-8 path")
}

/// A front photo alone (with its empty scene and the operator's stature) is fitted from
/// the front view, the report says so, every girth's `±` is wider than the two photos'
/// and still holds the truth.
#[test]
fn a_front_photo_alone_is_fitted_with_a_wider_uncertainty() {
    let _g = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    let dir = tmp("photo");
    let mut rec = Recording::open(&demo()).expect("demo recording");
    let (front_bg, side_bg) = rec.frame_pair(0).expect("backdrop pair");
    let (front, side) = rec.frame_pair(20).expect("subject pair");
    for (name, img) in [
        ("front_bg.png", &front_bg),
        ("side_bg.png", &side_bg),
        ("front.png", &front),
        ("side.png", &side),
    ] {
        img.save(dir.join(name)).expect("write still");
    }
    let truth = truth();
    let stature = format!("{:.0}", num(&truth, &["measurements_mm", "stature"]));
    let calib = demo().join("station.yaml");
    let (one_out, two_out) = (dir.join("one"), dir.join("two"));
    let common = |out: &Path| {
        vec![
            "fit".to_string(),
            "--front".into(),
            p(&dir.join("front.png")).into(),
            "--front-bg".into(),
            p(&dir.join("front_bg.png")).into(),
            "--calib".into(),
            p(&calib).into(),
            "--stature-mm".into(),
            stature.clone(),
            "--out".into(),
            p(out).into(),
        ]
    };
    let one_args = common(&one_out);
    let one = fitstation(&one_args.iter().map(String::as_str).collect::<Vec<_>>());
    let mut two_args = common(&two_out);
    two_args.extend(
        [
            "--side",
            p(&dir.join("side.png")),
            "--side-bg",
            p(&dir.join("side_bg.png")),
        ]
        .map(String::from),
    );
    let two = fitstation(&two_args.iter().map(String::as_str).collect::<Vec<_>>());

    assert_eq!(views(&one), ["front"]);
    assert_eq!(views(&two), ["front", "side"]);
    assert_eq!(num(&one, &["frames", "fitted_front_only"]), 1.0);
    let said = one["messages"].to_string();
    assert!(said.contains("front camera alone"), "{said}");
    for k in GIRTHS {
        let (pm1, pm2) = (
            num(&one, &["uncertainty_mm", k]),
            num(&two, &["uncertainty_mm", k]),
        );
        assert!(
            pm1 > pm2 * 1.3,
            "{k}: one view ±{pm1} against two views ±{pm2}"
        );
        let err = num(&one, &["measurements_mm", k]) - num(&truth, &["measurements_mm", k]);
        assert!(
            err.abs() <= pm1,
            "{k}: one-view error {err:+.1} mm outside ±{pm1}"
        );
    }
}

/// A recording whose side folder stops after frame 16 (the side camera cut while the
/// subject stands): every later pair is still fitted, from the front view alone, and the
/// report says which views its values came from.
#[test]
fn a_recording_with_the_side_camera_cut_half_way_keeps_producing_results() {
    let _g = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    const CUT: usize = 17;
    let dir = tmp("cut");
    let rec_dir = dir.join("rec");
    for v in ["front", "side"] {
        std::fs::create_dir_all(rec_dir.join(v)).expect("frame folder");
    }
    std::fs::copy(demo().join("station.yaml"), rec_dir.join("station.yaml")).expect("calib");
    let mut rec = Recording::open(&demo()).expect("demo recording");
    let n = rec.len();
    assert!(n > CUT + 4, "demo has {n} pairs");
    for k in 0..n {
        let (front, side) = rec.frame_pair(k).expect("demo pair");
        front
            .save(rec_dir.join("front").join(format!("{k:06}.png")))
            .expect("front frame");
        if k < CUT {
            side.save(rec_dir.join("side").join(format!("{k:06}.png")))
                .expect("side frame");
        }
    }
    let out = dir.join("out");
    let report = fitstation(&["replay", p(&rec_dir), "--out", p(&out), "--json"]);
    let with_subject = num(&report, &["frames", "with_subject"]);
    let fitted = num(&report, &["frames", "fitted"]);
    let front_only = num(&report, &["frames", "fitted_front_only"]);
    assert_eq!(fitted, with_subject, "{}", report["frames"]);
    assert_eq!(front_only, (n - CUT) as f64, "{}", report["frames"]);
    assert_eq!(views(&report), ["front"]);
    let after_cut = report["series"]
        .as_array()
        .expect("series")
        .iter()
        .filter(|r| r["frame"].as_f64().is_some_and(|f| f >= CUT as f64))
        .count();
    assert_eq!(after_cut, n - CUT, "the series stops at the cut");
    let truth = truth();
    for k in GIRTHS {
        let err = num(&report, &["measurements_mm", k]) - num(&truth, &["measurements_mm", k]);
        let pm = num(&report, &["uncertainty_mm", k]);
        assert!(
            err.abs() <= pm,
            "{k}: error {err:+.1} mm after the cut, ±{pm}"
        );
    }
}

/// `--deformer laplacian` is the fit's deformer (the avatar differs from the mean value
/// one where the controls leave it free) and its girths are as close to the truth.
#[test]
fn the_laplacian_deformer_fits_the_demo_with_sane_girths() {
    let _g = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    let dir = tmp("laplacian");
    let (lap_out, mvc_out) = (dir.join("laplacian"), dir.join("mvc"));
    let rec = demo();
    let lap = fitstation(&[
        "replay",
        p(&rec),
        "--out",
        p(&lap_out),
        "--deformer",
        "laplacian",
        "--json",
    ]);
    let mvc = fitstation(&["replay", p(&rec), "--out", p(&mvc_out), "--json"]);
    assert_eq!(lap["deformer"], "laplacian");
    assert_eq!(mvc["deformer"], "mvc");
    assert_eq!(num(&lap, &["frames", "fitted"]), 12.0);
    let truth = truth();
    for k in GIRTHS {
        let err = num(&lap, &["measurements_mm", k]) - num(&truth, &["measurements_mm", k]);
        assert!(err.abs() < 25.0, "{k}: Laplacian error {err:+.1} mm");
    }
    let vertices = |path: &Path| -> Vec<[f64; 3]> {
        std::fs::read_to_string(path.join("avatar.obj"))
            .expect("avatar")
            .lines()
            .filter_map(|l| l.strip_prefix("v "))
            .map(|l| {
                let c: Vec<f64> = l
                    .split_whitespace()
                    .map(|x| x.parse().expect("number"))
                    .collect();
                [c[0], c[1], c[2]]
            })
            .collect()
    };
    let (a, b) = (vertices(&lap_out), vertices(&mvc_out));
    assert_eq!(a.len(), b.len());
    let moved = a
        .iter()
        .zip(&b)
        .map(|(p, q)| (0..3).map(|i| (p[i] - q[i]).powi(2)).sum::<f64>().sqrt())
        .fold(0.0, f64::max);
    assert!(
        moved > 1e-3,
        "the two deformers gave the same avatar (max {moved} m apart)"
    );
}
