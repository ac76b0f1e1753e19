//! Reference checks against OpenCV on the same rendered images (issue 7).
//!
//! Two runs of our pipeline are compared, each with its OpenCV counterpart:
//! - default corners (Förstner + point-symmetry refinement) against
//!   cv2.findChessboardCornersSB(CALIB_CB_ACCURACY), and its intrinsics against
//!   cv2.calibrateCamera on the SB corners;
//! - Förstner-only corners (our `cornerSubPix`) against cv2.findChessboardCorners +
//!   cv2.cornerSubPix(11x11), and its intrinsics against cv2.calibrateCamera on those.
//!
//! Tolerances: median corner distance < 0.05 px (default corners against BOTH OpenCV
//! detectors), fx fy cx cy within 0.3%, RMS within 0.02 px. The optimiser alone:
//! cv2.calibrateCamera on OUR corners reproduces our numbers (1e-4 relative).
//!
//! Needs python3 with cv2 and numpy; without them the test prints `SKIPPED` and passes,
//! except when the environment variable `CI` is set.

use fitstation::calibrate::board::{BoardSpec, Target};
use fitstation::calibrate::corners::{median, CornerDetector, SubpixMethod};
use fitstation::calibrate::intrinsics::{
    calibrate_intrinsics, CameraViews, IntrinsicsCalibration, ViewInput, ViewOutcome,
};
use fitstation::calibrate::render::{
    rigs, true_corners, Background, BoardRenderer, Pattern, RenderOptions,
};
use fitstation::calibrate::Progress;
use glam::DVec2;
use serde_json::Value;
use std::path::PathBuf;
use std::process::Command;

const CORNER_MEDIAN_TOL_PX: f64 = 0.05;
const INTRINSICS_REL_TOL: f64 = 0.003;
const RMS_TOL_PX: f64 = 0.02;
/// Same corners, same model: the two optimisers must agree closely.
const SAME_CORNERS_REL_TOL: f64 = 1e-4;
const SAME_CORNERS_RMS_TOL_PX: f64 = 1e-3;
const VIEWS: usize = 8;

fn have_cv2() -> bool {
    let ok = Command::new("python3")
        .args(["-c", "import cv2, numpy"])
        .output()
        .map(|o| o.status.success())
        .unwrap_or(false);
    if !ok {
        if std::env::var_os("CI").is_some() {
            panic!("python3 with cv2 and numpy is required in CI (pip install opencv-python-headless numpy)");
        }
        println!("SKIPPED: calibrate_opencv: python3 with cv2 + numpy not found");
    }
    ok
}

fn num(v: &Value, key: &str) -> f64 {
    v.get(key).and_then(|x| x.as_f64()).unwrap_or(f64::NAN)
}

fn floats(v: &Value) -> Vec<f64> {
    v.as_array()
        .map(|a| a.iter().filter_map(|x| x.as_f64()).collect())
        .unwrap_or_default()
}

/// Corners of the views our calibration used (null for the others), as JSON.
fn used_corners(views: &CameraViews, cal: &IntrinsicsCalibration) -> Value {
    Value::Array(
        views
            .views
            .iter()
            .zip(&cal.views)
            .map(|(v, r)| match (&v.detection, &r.outcome) {
                (Ok(d), ViewOutcome::Used { .. }) => {
                    serde_json::json!(d.corners.iter().map(|p| [p.x, p.y]).collect::<Vec<_>>())
                }
                _ => Value::Null,
            })
            .collect(),
    )
}

/// Median distance of a JSON list of per-image corner lists to the nearest true corner.
fn truth_median(corners: &Value, truths: &[Vec<DVec2>]) -> f64 {
    let mut errs = Vec::new();
    for (img, truth) in corners.as_array().into_iter().flatten().zip(truths) {
        for p in img.as_array().into_iter().flatten() {
            let (Some(x), Some(y)) = (p[0].as_f64(), p[1].as_f64()) else {
                continue;
            };
            let q = DVec2::new(x, y);
            errs.push(
                truth
                    .iter()
                    .map(|t| (*t - q).length())
                    .fold(f64::INFINITY, f64::min),
            );
        }
    }
    median(&mut errs).unwrap_or(f64::NAN)
}

fn intrinsics_close(label: &str, cal: &IntrinsicsCalibration, cv: &Value) {
    let i = cal.intrinsics;
    let ours = [i.fx, i.fy, i.cx, i.cy];
    let theirs = [num(cv, "fx"), num(cv, "fy"), num(cv, "cx"), num(cv, "cy")];
    let rel: Vec<f64> = ours
        .iter()
        .zip(&theirs)
        .map(|(a, b)| (a - b).abs() / b.abs())
        .collect();
    let worst = rel.iter().copied().fold(0.0, f64::max);
    println!(
        "{label}: OpenCV fx {:.2} fy {:.2} cx {:.2} cy {:.2} RMS {:.4} | ours fx {:.2} fy {:.2} cx {:.2} cy {:.2} RMS {:.4} | worst relative difference {:.3}%, RMS difference {:.4} px",
        theirs[0], theirs[1], theirs[2], theirs[3], num(cv, "rms"),
        i.fx, i.fy, i.cx, i.cy, cal.rms_px, 100.0 * worst, (cal.rms_px - num(cv, "rms")).abs()
    );
    assert!(
        worst < INTRINSICS_REL_TOL,
        "{label}: intrinsics differ: {rel:?}"
    );
    assert!(
        (num(cv, "rms") - cal.rms_px).abs() < RMS_TOL_PX,
        "{label}: RMS differs"
    );
}

#[test]
fn corners_and_intrinsics_match_opencv() {
    if !have_cv2() {
        return;
    }
    let board = BoardSpec {
        cols: 9,
        rows: 6,
        square_m: 0.08,
    };
    let intr = rigs::landscape_intrinsics();
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("calibrate_opencv");
    std::fs::create_dir_all(&dir).expect("temp dir");
    let poses = rigs::handheld_poses(&board, &intr, VIEWS, 11);
    assert_eq!(poses.len(), VIEWS);
    let mut renderer = BoardRenderer::new(intr);
    let methods = [
        ("default", SubpixMethod::PointSymmetry),
        ("forstner", SubpixMethod::Forstner),
    ];
    let mut detectors: Vec<CornerDetector> = methods
        .iter()
        .map(|m| CornerDetector::with_method(m.1))
        .collect();
    let mut names = Vec::new();
    let mut inputs: Vec<Vec<ViewInput>> = vec![Vec::new(), Vec::new()];
    let mut truths = Vec::new();
    for (i, pose) in poses.iter().enumerate() {
        let opts = RenderOptions {
            supersample: 3,
            seed: 40 + i as u64,
            ..RenderOptions::default()
        };
        let img = renderer.render(&board, pose, Background::Wall, &opts);
        let path = dir.join(format!("view_{i:02}.png"));
        img.save(&path).expect("write png");
        names.push(path.display().to_string());
        truths.push(
            true_corners(&intr, &board, pose)
                .into_iter()
                .flatten()
                .collect::<Vec<_>>(),
        );
        for (d, inp) in detectors.iter_mut().zip(inputs.iter_mut()) {
            let det = d.detect(&img, &board);
            inp.push(ViewInput {
                name: format!("view_{i:02}"),
                detection: det,
            });
        }
    }
    let mut cals = Vec::new();
    let mut sets = serde_json::Map::new();
    for ((name, _), inp) in methods.iter().zip(inputs) {
        let views = CameraViews {
            camera: name.to_string(),
            width: intr.width,
            height: intr.height,
            views: inp,
        };
        let cal = calibrate_intrinsics(&views, &board, &mut |_: &Progress| {})
            .unwrap_or_else(|e| panic!("{e}"));
        let corners = used_corners(&views, &cal);
        println!(
            "our {name} corners: median distance to truth {:.4} px",
            truth_median(&corners, &truths)
        );
        sets.insert(name.to_string(), corners);
        cals.push(cal);
    }
    println!("{}", cals[0]);
    let ours = serde_json::json!({
        "cols": board.cols, "rows": board.rows, "square_m": board.square_m,
        "width": intr.width, "height": intr.height, "images": names, "corner_sets": sets,
    });
    let ours_path = dir.join("ours.json");
    let out_path = dir.join("opencv.json");
    std::fs::write(&ours_path, ours.to_string()).expect("write json");
    let script = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/opencv/calib_reference.py");
    let run = Command::new("python3")
        .arg(&script)
        .arg(&ours_path)
        .arg(&out_path)
        .output()
        .expect("run python3");
    assert!(
        run.status.success(),
        "calib_reference.py failed: {}",
        String::from_utf8_lossy(&run.stderr)
    );
    let cv: Value =
        serde_json::from_str(&std::fs::read_to_string(&out_path).expect("read opencv.json"))
            .expect("parse opencv.json");
    println!(
        "OpenCV {}: SB found {} of {VIEWS}, classic found {}; median distance to truth: SB {:.4} px, cornerSubPix {:.4} px",
        cv["opencv_version"], cv["found_sb"], cv["found_classic"],
        truth_median(&cv["sb_corners"], &truths), truth_median(&cv["subpix_corners"], &truths)
    );

    for (name, _) in &methods {
        let mut sb = floats(&cv["diffs"][name]["sb"]);
        let mut sp = floats(&cv["diffs"][name]["subpix"]);
        let (msb, msp) = (
            median(&mut sb).unwrap_or(f64::NAN),
            median(&mut sp).unwrap_or(f64::NAN),
        );
        println!("our {name} corners: median distance to SB {msb:.4} px ({} corners), to cornerSubPix {msp:.4} px ({} corners)", sb.len(), sp.len());
        if *name == "default" {
            assert!(msb < CORNER_MEDIAN_TOL_PX, "default corners vs SB: {msb}");
            assert!(
                msp < CORNER_MEDIAN_TOL_PX,
                "default corners vs cornerSubPix: {msp}"
            );
        } else {
            assert!(
                msp < CORNER_MEDIAN_TOL_PX,
                "Förstner corners vs cornerSubPix: {msp}"
            );
        }
    }
    intrinsics_close(
        "default pipeline vs calibrateCamera on SB corners",
        &cals[0],
        &cv["calib_sb"],
    );
    intrinsics_close(
        "Förstner pipeline vs calibrateCamera on cornerSubPix corners",
        &cals[1],
        &cv["calib_subpix"],
    );

    for ((name, _), cal) in methods.iter().zip(&cals) {
        let c = &cv["calib_ours"][name];
        let i = cal.intrinsics;
        let rel = [i.fx, i.fy, i.cx, i.cy]
            .iter()
            .zip([num(c, "fx"), num(c, "fy"), num(c, "cx"), num(c, "cy")])
            .map(|(a, b)| (a - b).abs() / b.abs())
            .fold(0.0, f64::max);
        println!("calibrateCamera on our {name} corners: RMS {:.5} vs ours {:.5}; fx fy cx cy differ by at most {:.1e} (relative)", num(c, "rms"), cal.rms_px, rel);
        assert!(
            rel < SAME_CORNERS_REL_TOL,
            "same corners, optimisers differ by {rel}"
        );
        assert!((num(c, "rms") - cal.rms_px).abs() < SAME_CORNERS_RMS_TOL_PX);
    }
    let t = intr;
    let pct = |v: f64, t: f64| 100.0 * (v / t - 1.0);
    println!(
        "vs truth: ours fx {:+.3}% fy {:+.3}% cx {:+.2} px cy {:+.2} px; OpenCV (SB) fx {:+.3}% fy {:+.3}% cx {:+.2} px cy {:+.2} px; OpenCV (cornerSubPix) fx {:+.3}% fy {:+.3}%",
        pct(cals[0].intrinsics.fx, t.fx), pct(cals[0].intrinsics.fy, t.fy), cals[0].intrinsics.cx - t.cx, cals[0].intrinsics.cy - t.cy,
        pct(num(&cv["calib_sb"], "fx"), t.fx), pct(num(&cv["calib_sb"], "fy"), t.fy),
        num(&cv["calib_sb"], "cx") - t.cx, num(&cv["calib_sb"], "cy") - t.cy,
        pct(num(&cv["calib_subpix"], "fx"), t.fx), pct(num(&cv["calib_subpix"], "fy"), t.fy)
    );
}

/// Circle centres against cv2.findCirclesGrid must agree to this median, pixels: both
/// estimate centroids, OpenCV from thresholded contours, we from grey-level weights.
const CIRCLE_MEDIAN_TOL_PX: f64 = 0.05;

#[test]
fn circle_grid_matches_opencv() {
    if !have_cv2() {
        return;
    }
    let board = BoardSpec {
        cols: 9,
        rows: 6,
        square_m: 0.08,
    };
    let intr = rigs::landscape_intrinsics();
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("calibrate_opencv_circles");
    std::fs::create_dir_all(&dir).expect("temp dir");
    let poses = rigs::handheld_poses(&board, &intr, VIEWS, 12);
    let mut renderer = BoardRenderer::new(intr);
    let mut det = CornerDetector::for_target(Target::Circles);
    let (mut names, mut inputs, mut truths) = (Vec::new(), Vec::new(), Vec::new());
    for (i, pose) in poses.iter().enumerate() {
        let opts = RenderOptions {
            supersample: 3,
            seed: 60 + i as u64,
            pattern: Pattern::Circles {
                radius_fraction: 0.3,
            },
            ..RenderOptions::default()
        };
        let img = renderer.render(&board, pose, Background::Wall, &opts);
        let path = dir.join(format!("circles_{i:02}.png"));
        img.save(&path).expect("write png");
        names.push(path.display().to_string());
        truths.push(
            true_corners(&intr, &board, pose)
                .into_iter()
                .flatten()
                .collect::<Vec<_>>(),
        );
        inputs.push(ViewInput {
            name: format!("circles_{i:02}"),
            detection: det.detect(&img, &board),
        });
    }
    let views = CameraViews {
        camera: "circles".into(),
        width: intr.width,
        height: intr.height,
        views: inputs,
    };
    let cal = calibrate_intrinsics(&views, &board, &mut |_: &Progress| {})
        .unwrap_or_else(|e| panic!("{e}"));
    let corners = used_corners(&views, &cal);
    let ours = serde_json::json!({
        "target": "circles", "cols": board.cols, "rows": board.rows, "square_m": board.square_m,
        "width": intr.width, "height": intr.height, "images": names,
        "corner_sets": { "default": corners.clone() },
    });
    let (ours_path, out_path) = (dir.join("ours.json"), dir.join("opencv.json"));
    std::fs::write(&ours_path, ours.to_string()).expect("write json");
    let script = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/opencv/calib_reference.py");
    let run = Command::new("python3")
        .arg(&script)
        .arg(&ours_path)
        .arg(&out_path)
        .output()
        .expect("run python3");
    assert!(
        run.status.success(),
        "calib_reference.py failed: {}",
        String::from_utf8_lossy(&run.stderr)
    );
    let cv: Value =
        serde_json::from_str(&std::fs::read_to_string(&out_path).expect("read")).expect("parse");
    let mut d = floats(&cv["diffs"]["default"]);
    let med = median(&mut d).unwrap_or(f64::NAN);
    println!(
        "circles: OpenCV findCirclesGrid found {} of {VIEWS}; median distance to truth: ours {:.4} px, OpenCV {:.4} px; ours vs OpenCV {med:.4} px over {} centres",
        cv["found"],
        truth_median(&corners, &truths),
        truth_median(&cv["circle_centres"], &truths),
        d.len()
    );
    assert!(
        !d.is_empty() && med < CIRCLE_MEDIAN_TOL_PX,
        "circle centres vs OpenCV: {med}"
    );
    intrinsics_close(
        "circle grid vs calibrateCamera on findCirclesGrid centres",
        &cal,
        &cv["calib_circles"],
    );
    let t = intr;
    println!(
        "circles vs truth: ours fx {:+.3}% fy {:+.3}%; OpenCV fx {:+.3}% fy {:+.3}%",
        100.0 * (cal.intrinsics.fx / t.fx - 1.0),
        100.0 * (cal.intrinsics.fy / t.fy - 1.0),
        100.0 * (num(&cv["calib_circles"], "fx") / t.fx - 1.0),
        100.0 * (num(&cv["calib_circles"], "fy") / t.fy - 1.0)
    );
}
