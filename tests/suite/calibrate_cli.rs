//! `fitstation calibrate` end to end on a rendered station written to disk: the full
//! run, the operator checks, OpenCV reading the station.yaml written, and the safe
//! write (a worse calibration never silently replaces a better one). Also the
//! messages for a placement board seen by one camera only and an empty folder.

use fitstation::calibrate::board::BoardSpec;
use fitstation::calibrate::linalg::rotation_angle_deg;
use fitstation::calibrate::render::{synthetic_station, RenderOptions};
use fitstation::camera::{StationCalibration, View};
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

const VIEWS: usize = 6;
const BOARD_HEIGHT_MM: f64 = 550.0;

fn fitstation(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_fitstation"))
        .args(args)
        .output()
        .expect("run fitstation")
}

fn text(o: &Output) -> String {
    format!(
        "{}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    )
}

fn p(path: &Path) -> &str {
    path.to_str().expect("utf-8 temp path")
}

fn ps(path: PathBuf) -> String {
    path.to_str().expect("utf-8 temp path").to_string()
}

fn have_cv2() -> bool {
    let ok = Command::new("python3")
        .args(["-c", "import cv2"])
        .output()
        .map(|o| o.status.success())
        .unwrap_or(false);
    if !ok {
        if std::env::var_os("CI").is_some() {
            panic!("python3 with cv2 is required in CI");
        }
        println!("SKIPPED: cv2.FileStorage check: python3 with cv2 not found");
    }
    ok
}

#[test]
fn calibrate_command_end_to_end() {
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("calibrate_cli");
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("temp dir");
    let board = BoardSpec {
        cols: 9,
        rows: 6,
        square_m: 0.08,
    };
    let syn = synthetic_station(
        &board,
        VIEWS,
        BOARD_HEIGHT_MM / 1000.0,
        &RenderOptions {
            supersample: 3,
            ..RenderOptions::default()
        },
    );
    syn.write(&dir).expect("write station");
    let out = dir.join("station.yaml");
    let (front, side) = (ps(dir.join("front")), ps(dir.join("side")));
    let (st_front, st_side) = (
        ps(dir.join("station_front.png")),
        ps(dir.join("station_side.png")),
    );
    let empty_side = ps(dir.join("empty_side.png"));
    let height = format!("{BOARD_HEIGHT_MM}");
    let full = [
        "calibrate",
        "--board",
        "9x6",
        "--square-mm",
        "80",
        "--front",
        &front,
        "--side",
        &side,
        "--station-front",
        &st_front,
        "--station-side",
        &st_side,
        "--board-height-mm",
        &height,
        "--out",
        p(&out),
    ];
    let o = fitstation(&full);
    println!("{}", text(&o));
    assert!(o.status.success());
    let cal = StationCalibration::load(&out).expect("station.yaml readable");
    for view in View::BOTH {
        let (got, want) = (cal.camera(view), syn.truth.camera(view));
        let pos = (got.center_in_station() - want.center_in_station()).length();
        let rot = rotation_angle_deg(
            &got.camera_from_station.rotation,
            &want.camera_from_station.rotation,
        );
        println!(
            "{}: position {:.1} mm, rotation {:.3} deg from truth",
            view.name(),
            pos * 1000.0,
            rot
        );
        assert!(pos < 0.010 && rot < 0.2);
    }

    // The checks, both spellings.
    for args in [
        vec!["calibrate", "check", p(&out)],
        vec!["calibrate", "--check", p(&out)],
    ] {
        let o = fitstation(&args);
        let t = text(&o);
        assert!(
            o.status.success() && t.contains("Station checks") && t.contains("all checks passed"),
            "{t}"
        );
        assert!(t.contains("mm per pixel") && t.contains("girth"), "{t}");
    }

    // OpenCV reads what we wrote.
    if have_cv2() {
        let script =
            PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/opencv/calib_filestorage.py");
        let o = Command::new("python3")
            .arg(script)
            .arg(&out)
            .output()
            .expect("python3");
        assert!(o.status.success(), "{}", text(&o));
        let v: serde_json::Value = serde_json::from_slice(&o.stdout).expect("json");
        let k: Vec<f64> = v["front"]["camera_matrix"]["data"]
            .as_array()
            .expect("K")
            .iter()
            .filter_map(|x| x.as_f64())
            .collect();
        assert_eq!(k.len(), 9);
        assert!((k[0] - cal.front.intrinsics.fx).abs() < 1e-9);
        let t: Vec<f64> = v["side"]["translation"]["data"]
            .as_array()
            .expect("t")
            .iter()
            .filter_map(|x| x.as_f64())
            .collect();
        assert!((t[2] - cal.side.camera_from_station.translation.z).abs() < 1e-12);
        assert_eq!(
            v["side"]["image_height"].as_i64(),
            Some(cal.side.intrinsics.height as i64)
        );
    }

    // A worse calibration goes to station.new.yaml; the good file stays.
    let good = std::fs::read_to_string(&out).expect("read");
    let flattered = good.replace(
        &format!("front_rms_px: \"{}\"", field(&good, "front_rms_px")),
        "front_rms_px: \"0.0010\"",
    );
    assert_ne!(flattered, good);
    std::fs::write(&out, &flattered).expect("write");
    let again = [
        "calibrate",
        "--board",
        "9x6",
        "--square-mm",
        "80",
        "--front",
        &front,
        "--out",
        p(&out),
    ];
    let o = fitstation(&again);
    let t = text(&o);
    println!("{t}");
    assert!(o.status.success() && t.contains("NOT replacing"), "{t}");
    assert_eq!(std::fs::read_to_string(&out).expect("read"), flattered);
    assert!(dir.join("station.new.yaml").exists());
    // With --force it replaces, keeping a backup.
    let mut forced = again.to_vec();
    forced.push("--force");
    let o = fitstation(&forced);
    let t = text(&o);
    assert!(
        o.status.success() && t.contains("previous calibration kept as"),
        "{t}"
    );
    assert_eq!(
        std::fs::read_to_string(dir.join("station.yaml.bak")).expect("backup"),
        flattered
    );

    // The placement board seen by the front camera only.
    let wall = image::GrayImage::from_pixel(
        syn.truth.side.intrinsics.width,
        syn.truth.side.intrinsics.height,
        image::Luma([175]),
    );
    wall.save(dir.join("empty_side.png")).expect("png");
    let one = [
        "calibrate",
        "--board",
        "9x6",
        "--square-mm",
        "80",
        "--station-front",
        &st_front,
        "--station-side",
        &empty_side,
        "--board-height-mm",
        &height,
        "--out",
        p(&out),
    ];
    let o = fitstation(&one);
    let t = text(&o);
    assert!(
        !o.status.success()
            && t.contains("found by the front camera only")
            && t.contains("45 degrees"),
        "{t}"
    );

    // An empty folder.
    std::fs::create_dir_all(dir.join("nothing")).expect("dir");
    let (nothing, x) = (ps(dir.join("nothing")), ps(dir.join("x.yaml")));
    let o = fitstation(&[
        "calibrate",
        "--board",
        "9x6",
        "--square-mm",
        "80",
        "--front",
        &nothing,
        "--side",
        &side,
        "--out",
        &x,
    ]);
    let t = text(&o);
    assert!(!o.status.success() && t.contains("no images"), "{t}");
}

/// The quoted value of a scalar key in a FileStorage text.
fn field<'a>(text: &'a str, key: &str) -> &'a str {
    text.lines()
        .find_map(|l| l.strip_prefix(&format!("{key}: ")))
        .map(|v| v.trim_matches('"'))
        .unwrap_or("")
}
