//! OpenCV reference checks (tests/opencv/silhouette_check.py) on the same inputs:
//! point undistortion against `cv2.undistortPoints` (< 0.05 px), the outer contour of a
//! mask against `cv2.findContours` (the same boundary pixels), Canny against `cv2.Canny`
//! at the same thresholds (>= 95 % of edge pixels agree), and the time of our
//! segmentation beside `cv2.createBackgroundSubtractorMOG2` on the same frames (printed,
//! not asserted). Without cv2 the checks print SKIPPED and pass, except under `CI`.

use crate::silhouette_common;

use fitstation::contour::trace_outer;
use fitstation::imgproc::Mask;
use fitstation::imgproc::{canny, to_gray, CannyScratch, PointUndistorter};
use fitstation::landmarks::phantom::SceneParams;
use fitstation::segment::{BackgroundModel, SegmentOptions};
use glam::DVec2;
use serde_json::json;
use silhouette_common::*;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

/// Thresholds of the Canny comparison (L1 gradient).
const CANNY_LOW: f64 = 60.0;
const CANNY_HIGH: f64 = 150.0;

fn cv2_available() -> bool {
    let ok = Command::new("python3")
        .args(["-c", "import cv2"])
        .output()
        .map(|o| o.status.success())
        .unwrap_or(false);
    if !ok {
        assert!(
            std::env::var_os("CI").is_none(),
            "CI is set but python3 cannot import cv2 (pip install opencv-python-headless numpy)"
        );
        println!("SKIPPED: python3 with cv2 is not available; OpenCV reference checks not run");
    }
    ok
}

fn workdir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!(
        "fitstation_silhouette_{name}_{}",
        std::process::id()
    ));
    std::fs::create_dir_all(&d).expect("temp dir");
    d
}

fn run_check(check: &str, dir: &Path) {
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/opencv/silhouette_check.py");
    let out = Command::new("python3")
        .arg(&script)
        .arg(check)
        .arg(dir)
        .output()
        .expect("run python3");
    print!("{}", String::from_utf8_lossy(&out.stdout));
    eprint!("{}", String::from_utf8_lossy(&out.stderr));
    assert!(out.status.success(), "OpenCV check '{check}' failed");
    let _ = std::fs::remove_dir_all(dir);
}

fn save_mask(m: &Mask, path: &Path) {
    image::GrayImage::from_raw(m.width, m.height, m.data.clone())
        .expect("mask size")
        .save(path)
        .expect("save mask");
}

#[test]
fn undistorted_points_match_opencv() {
    if !cv2_available() {
        return;
    }
    let calib = station();
    let mut i = calib.front.intrinsics;
    // Stronger than the station's lens, to make the check meaningful.
    i.dist = [-0.12, 0.05, 0.001, -0.0005, -0.01];
    let u = PointUndistorter::new(i);
    let mut pts = Vec::new();
    for y in (0..i.height).step_by(37) {
        for x in (0..i.width).step_by(29) {
            pts.push(DVec2::new(x as f64 + 0.25, y as f64 + 0.75));
        }
    }
    pts.push(DVec2::new(0.0, 0.0));
    pts.push(DVec2::new(i.width as f64 - 1.0, i.height as f64 - 1.0));
    let ours: Vec<[f64; 2]> = pts.iter().map(|&p| u.undistort(p).to_array()).collect();
    let dir = workdir("undistort");
    let doc = json!({
        "K": i.k_rows(),
        "dist": i.dist,
        "distorted": pts.iter().map(|p| p.to_array()).collect::<Vec<_>>(),
        "ours": ours,
    });
    std::fs::write(dir.join("points.json"), doc.to_string()).expect("write");
    run_check("undistort", &dir);
}

#[test]
fn contour_matches_find_contours() {
    if !cv2_available() {
        return;
    }
    let p = render(
        &[subject()],
        SceneParams {
            seed: 41,
            ..Default::default()
        },
    );
    for (k, mask) in [&p.front_truth, &p.side_truth].into_iter().enumerate() {
        let c = &trace_outer(mask)[0];
        let dir = workdir(&format!("contour{k}"));
        save_mask(mask, &dir.join("mask.png"));
        let pts: Vec<[f64; 2]> = c.points.iter().map(|p| p.to_array()).collect();
        std::fs::write(
            dir.join("contour.json"),
            json!({ "points": pts }).to_string(),
        )
        .expect("write");
        run_check("contour", &dir);
    }
}

#[test]
fn canny_matches_opencv() {
    if !cv2_available() {
        return;
    }
    let p = render(
        &[subject()],
        SceneParams {
            seed: 42,
            ..Default::default()
        },
    );
    let mut gray = Vec::new();
    to_gray(&p.front, &mut gray);
    let (w, h) = (p.front.width() as usize, p.front.height() as usize);
    let (mut edges, mut s) = (Vec::new(), CannyScratch::default());
    canny(&gray, w, h, CANNY_LOW, CANNY_HIGH, &mut edges, &mut s);
    let dir = workdir("canny");
    image::GrayImage::from_raw(w as u32, h as u32, gray)
        .expect("size")
        .save(dir.join("gray.png"))
        .expect("save");
    image::GrayImage::from_raw(w as u32, h as u32, edges)
        .expect("size")
        .save(dir.join("edges.png"))
        .expect("save");
    std::fs::write(
        dir.join("canny.json"),
        json!({"low": CANNY_LOW, "high": CANNY_HIGH}).to_string(),
    )
    .expect("write");
    run_check("canny", &dir);
}

#[test]
fn segmentation_timing_beside_mog2() {
    if !cv2_available() {
        return;
    }
    let dir = workdir("mog2");
    std::fs::create_dir_all(dir.join("frames")).expect("dir");
    let mut frames = Vec::new();
    for k in 0..3 {
        frames.push(empty_cached(k).front.clone());
    }
    for k in 0..5u64 {
        let gain = 1.0 + 0.02 * (k as f64 - 2.0);
        frames.push(
            render(
                &[subject()],
                SceneParams {
                    seed: 50 + k,
                    gain,
                    ..Default::default()
                },
            )
            .front,
        );
    }
    for (k, f) in frames.iter().enumerate() {
        f.save(dir.join("frames").join(format!("{k:06}.png")))
            .expect("save frame");
    }
    let (w, h) = frames[0].dimensions();
    let mut model = BackgroundModel::new(w, h, SegmentOptions::default());
    for f in &frames[..3] {
        model.learn(f).expect("learn");
    }
    let mut mask = Mask::new(w, h);
    let mut times = Vec::new();
    for _ in 0..3 {
        for f in &frames[3..] {
            let t = Instant::now();
            model.segment(f, &mut mask).expect("segment");
            times.push(t.elapsed().as_secs_f64() * 1e3);
        }
    }
    times.sort_by(f64::total_cmp);
    println!(
        "ours: BackgroundModel::segment on {w}x{h} colour frames: median {:.2} ms, min {:.2} ms per frame",
        times[times.len() / 2],
        times[0]
    );
    run_check("mog2", &dir);
}
