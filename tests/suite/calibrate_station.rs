//! End-to-end calibration on rendered boards with known truth (issue 7): both cameras'
//! intrinsics from hand-held board views, then their poses in the station frame from
//! the placement board at the mark. Accuracy targets: focal length within 0.5%, camera
//! rotation within 0.2 degrees, camera position within 10 mm.

use fitstation::calibrate::board::{BoardSpec, Target};
use fitstation::calibrate::corners::CornerDetector;
use fitstation::calibrate::extrinsics::{place_camera, Placement};
use fitstation::calibrate::intrinsics::{calibrate_intrinsics, CameraViews, ViewInput};
use fitstation::calibrate::linalg::rotation_angle_deg;
use fitstation::calibrate::render::{synthetic_station, Pattern, RenderOptions};
use fitstation::calibrate::{check_station, Progress};
use fitstation::camera::{Camera, StationCalibration, View};

const FOCAL_TOL: f64 = 0.005;
const ROTATION_TOL_DEG: f64 = 0.2;
const POSITION_TOL_M: f64 = 0.010;
/// Views per camera: enough for a stable calibration, few enough for a fast test.
const VIEWS: usize = 8;
/// Circle radius of the circle-grid target, as a fraction of the centre spacing.
const CIRCLE_RADIUS_FRACTION: f64 = 0.3;

fn board() -> BoardSpec {
    BoardSpec {
        cols: 9,
        rows: 6,
        square_m: 0.08,
    }
}

fn views_of(
    camera: &str,
    imgs: &[image::GrayImage],
    board: &BoardSpec,
    target: Target,
) -> CameraViews {
    let mut det = CornerDetector::for_target(target);
    let views = imgs
        .iter()
        .enumerate()
        .map(|(i, img)| ViewInput {
            name: format!("view_{i:02}"),
            detection: det.detect(img, board),
        })
        .collect();
    CameraViews {
        camera: camera.into(),
        width: imgs[0].width(),
        height: imgs[0].height(),
        views,
    }
}

#[test]
fn rendered_station_is_recovered_within_tolerance() {
    station_within_tolerance(Target::Chessboard, Pattern::Chessboard);
}

#[test]
fn rendered_station_with_a_circle_grid_is_recovered_within_tolerance() {
    station_within_tolerance(
        Target::Circles,
        Pattern::Circles {
            radius_fraction: CIRCLE_RADIUS_FRACTION,
        },
    );
}

fn station_within_tolerance(target: Target, pattern: Pattern) {
    let board = board();
    let height = 0.55;
    let opts = RenderOptions {
        supersample: 3,
        pattern,
        ..RenderOptions::default()
    };
    let syn = synthetic_station(&board, VIEWS, height, &opts);
    let mut quiet = |_: &Progress| {};
    let placement = Placement {
        board,
        lowest_row_height_m: height,
    };
    let mut cams = Vec::new();
    for (view, imgs, station_img) in [
        (View::Front, &syn.front_views, &syn.station_front),
        (View::Side, &syn.side_views, &syn.station_side),
    ] {
        let truth = syn.truth.camera(view);
        let views = views_of(view.name(), imgs, &board, target);
        let cal =
            calibrate_intrinsics(&views, &board, &mut quiet).unwrap_or_else(|e| panic!("{e}"));
        println!("[{}] {cal}", target.name());
        let i = cal.intrinsics;
        let t = truth.intrinsics;
        let fx_err = (i.fx - t.fx).abs() / t.fx;
        let fy_err = (i.fy - t.fy).abs() / t.fy;
        println!(
            "{} intrinsics vs truth: fx {:+.3}% fy {:+.3}% cx {:+.2} px cy {:+.2} px k1 {:+.4}",
            view.name(),
            100.0 * (i.fx - t.fx) / t.fx,
            100.0 * (i.fy - t.fy) / t.fy,
            i.cx - t.cx,
            i.cy - t.cy,
            i.dist[0] - t.dist[0]
        );
        assert!(
            fx_err < FOCAL_TOL && fy_err < FOCAL_TOL,
            "{} focal off: fx {fx_err} fy {fy_err}",
            view.name()
        );

        let det = CornerDetector::for_target(target)
            .detect(station_img, &board)
            .unwrap_or_else(|e| panic!("{} station image: {e}", view.name()));
        let placed =
            place_camera(view, &i, &det.corners, &placement).unwrap_or_else(|e| panic!("{e}"));
        let rot_err = rotation_angle_deg(
            &placed.camera_from_station.rotation,
            &truth.camera_from_station.rotation,
        );
        let cam = Camera {
            intrinsics: i,
            camera_from_station: placed.camera_from_station,
        };
        let pos_err = (cam.center_in_station() - truth.center_in_station()).length();
        println!(
            "{} pose vs truth: rotation {:.3} deg, position {:.1} mm (at {:?}), placement RMS {:.3} px",
            view.name(),
            rot_err,
            pos_err * 1000.0,
            cam.center_in_station(),
            placed.rms_px
        );
        assert!(placed.warnings.is_empty(), "{:?}", placed.warnings);
        assert!(
            rot_err < ROTATION_TOL_DEG,
            "{} rotation off by {rot_err} deg",
            view.name()
        );
        assert!(
            pos_err < POSITION_TOL_M,
            "{} position off by {pos_err} m",
            view.name()
        );
        cams.push(cam);
    }
    let station = StationCalibration {
        front: cams[0],
        side: cams[1],
        extra: Vec::new(),
    };
    let checks = check_station(&station);
    let truth_checks = check_station(&syn.truth);
    println!("{checks}");
    assert!((checks.plan_angle_deg - truth_checks.plan_angle_deg).abs() < 2.0 * ROTATION_TOL_DEG);
    assert!((checks.front.height_m - truth_checks.front.height_m).abs() < POSITION_TOL_M);
}
