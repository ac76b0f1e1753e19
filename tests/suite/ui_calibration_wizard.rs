//! The operator's calibration wizard (the station screen's, on its worker thread) driven
//! through rendered board frames with known truth: live detection keeps sharp new views
//! of each lens, the lenses are solved, the placement board at the mark places both
//! cameras, the station checks are computed, and saving never replaces a better
//! `station.yaml` unless forced (a backup is kept).

use fitstation::app::calib_wizard::{
    CalibrationWizard, SaveOutcome, WizardAction, WizardCore, WizardSettings, WizardStep,
};
use fitstation::calibrate::board::{BoardSpec, Target};
use fitstation::calibrate::render::{synthetic_station, RenderOptions};
use fitstation::camera::{StationCalibration, View};
use std::sync::Arc;

/// Accuracy the wizard must reach on rendered frames (as `tests/calibrate_station.rs`).
const FOCAL_TOL: f64 = 0.005;
const POSITION_TOL_M: f64 = 0.010;
/// Board views rendered per camera.
const VIEWS: usize = 8;
const BOARD_HEIGHT_M: f64 = 0.55;

fn board() -> BoardSpec {
    BoardSpec {
        cols: 9,
        rows: 6,
        square_m: 0.08,
    }
}

fn rgb(g: &image::GrayImage) -> Arc<image::RgbImage> {
    Arc::new(image::DynamicImage::ImageLuma8(g.clone()).to_rgb8())
}

fn temp_dir(name: &str) -> std::path::PathBuf {
    let d = std::env::temp_dir().join(format!("fitstation-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).expect("temp dir");
    d
}

#[test]
fn wizard_calibrates_a_rendered_station_and_saves_safely() {
    let board = board();
    let opts = RenderOptions {
        supersample: 3,
        ..RenderOptions::default()
    };
    let syn = synthetic_station(&board, VIEWS, BOARD_HEIGHT_M, &opts);
    let dir = temp_dir("wizard");
    let out = dir.join("station.yaml");
    let settings = WizardSettings {
        board,
        target: Target::Chessboard,
        board_height_m: 0.6,
        out: out.clone(),
    };
    let wizard = CalibrationWizard::start(settings, None).expect("wizard thread");
    assert_eq!(wizard.view().step, WizardStep::Lenses);

    // Solving with no views and no loaded calibration says what to do.
    wizard.act(WizardAction::SolveLenses);
    wizard.sync();
    let v = wizard.view();
    assert_eq!(v.step, WizardStep::Lenses);
    assert!(v.status.contains("no board views"), "{}", v.status);

    // Live frames: each pair shows the board to both cameras.
    for (f, s) in syn.front_views.iter().zip(&syn.side_views) {
        wizard.offer_frames(rgb(f), rgb(s));
        // One pair at a time: the worker searches only the newest of a backlog.
        wizard.sync();
        let v = wizard.view();
        assert_eq!(v.detections.front.len(), 1, "{:?}", v.lines);
        assert_eq!(
            v.detections.front[0].corners_px.len(),
            board.cols * board.rows
        );
    }
    let v = wizard.view();
    assert_eq!(v.frames_searched, VIEWS as u64);
    assert!(
        v.lines
            .iter()
            .all(|l| l.contains(&format!("{VIEWS} views kept"))),
        "{:?}",
        v.lines
    );
    // The same frame again is not a new view.
    wizard.offer_frames(rgb(&syn.front_views[0]), rgb(&syn.side_views[0]));
    wizard.sync();
    assert!(
        wizard.view().lines[0].contains("same as"),
        "{:?}",
        wizard.view().lines
    );

    wizard.act(WizardAction::SolveLenses);
    wizard.sync();
    let v = wizard.view();
    assert_eq!(v.step, WizardStep::Placement, "{}", v.status);

    // The placement board seen by one camera only: a clear message, no station.
    wizard.act(WizardAction::SetBoardHeightMm(BOARD_HEIGHT_M * 1e3));
    let (w, h) = syn.station_side.dimensions();
    let wall = image::GrayImage::from_pixel(w, h, image::Luma([175]));
    wizard.offer_frames(rgb(&syn.station_front), rgb(&wall));
    wizard.sync();
    wizard.act(WizardAction::PlaceCameras);
    wizard.sync();
    let v = wizard.view();
    assert_eq!(v.step, WizardStep::Placement);
    assert!(v.status.contains("front camera only"), "{}", v.status);

    wizard.offer_frames(rgb(&syn.station_front), rgb(&syn.station_side));
    wizard.sync();
    wizard.act(WizardAction::PlaceCameras);
    wizard.sync();
    let v = wizard.view();
    assert_eq!(v.step, WizardStep::Review, "{}", v.status);
    let solved = v.solved.clone().expect("a solved station");
    for view in View::BOTH {
        let (c, t) = (solved.camera(view), syn.truth.camera(view));
        let fx_err = (c.intrinsics.fx - t.intrinsics.fx).abs() / t.intrinsics.fx;
        let pos_err = (c.center_in_station() - t.center_in_station()).length();
        println!(
            "{}: fx {:+.3}%, position {:.1} mm",
            view.name(),
            100.0 * fx_err,
            pos_err * 1e3
        );
        assert!(fx_err < FOCAL_TOL, "{} focal off by {fx_err}", view.name());
        assert!(
            pos_err < POSITION_TOL_M,
            "{} camera {pos_err} m off",
            view.name()
        );
    }
    assert!(
        v.checks.iter().any(|l| l.contains("optical axes")),
        "{:?}",
        v.checks
    );
    let rms = |cal: &StationCalibration, k: &str| -> f64 {
        cal.extra
            .iter()
            .find(|(key, _)| key == k)
            .and_then(|(_, v)| v.parse().ok())
            .unwrap_or(f64::NAN)
    };
    assert!(rms(&solved, "front_rms_px") < 0.5);

    // First save: written.
    wizard.act(WizardAction::Save { force: false });
    wizard.sync();
    assert_eq!(wizard.view().saved.as_deref(), Some(out.as_path()));
    let written = StationCalibration::load(&out).expect("station.yaml");
    assert_eq!(written.front.intrinsics, solved.front.intrinsics);

    // A better calibration on disk is not replaced; forcing keeps a backup.
    let mut better = solved.clone();
    for (k, v) in better.extra.iter_mut() {
        if k.ends_with("_rms_px") && !k.contains("placement") {
            *v = "0.0100".into();
        }
    }
    better.save(&out).expect("write better");
    let core = WizardCore::new(wizard.settings().clone(), None);
    // The core has nothing solved: saving says so.
    assert!(core.save(false).is_err());
    drop(core);
    wizard.act(WizardAction::Save { force: false });
    wizard.sync();
    let v = wizard.view();
    assert!(v.status.contains("NOT replacing"), "{}", v.status);
    let kept = StationCalibration::load(&out).expect("kept");
    assert_eq!(rms(&kept, "front_rms_px"), 0.01);
    assert!(dir.join("station.new.yaml").exists());
    wizard.act(WizardAction::Save { force: true });
    wizard.sync();
    assert!(
        wizard.view().status.contains("kept as"),
        "{}",
        wizard.view().status
    );
    assert!(dir.join("station.yaml.bak").exists());
    assert!(
        rms(
            &StationCalibration::load(&out).expect("new"),
            "front_rms_px"
        ) > 0.01
    );

    // Start over: back to the lenses, nothing solved.
    wizard.act(WizardAction::Reset);
    wizard.sync();
    let v = wizard.view();
    assert_eq!(v.step, WizardStep::Lenses);
    assert!(v.solved.is_none());
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn save_safely_keeps_a_better_file() {
    use fitstation::app::calib_wizard::save_safely;
    let dir = temp_dir("save-safely");
    let out = dir.join("station.yaml");
    let mut cal = fitstation::app::demo::demo_calibration();
    cal.extra.push(("front_rms_px".into(), "0.20".into()));
    assert!(matches!(
        save_safely(&cal, &out, false),
        Ok(SaveOutcome::Written { backup: None, .. })
    ));
    let mut worse = cal.clone();
    worse.extra = vec![("front_rms_px".into(), "0.50".into())];
    match save_safely(&worse, &out, false) {
        Ok(SaveOutcome::KeptBetter { new_path, reason }) => {
            assert!(new_path.exists());
            assert!(reason.contains("front"), "{reason}");
        }
        other => panic!("expected the better file kept, got {other:?}"),
    }
    // Not worse (within the tolerance): replaced with a backup.
    let mut same = cal.clone();
    same.extra = vec![("front_rms_px".into(), "0.21".into())];
    assert!(matches!(
        save_safely(&same, &out, false),
        Ok(SaveOutcome::Written {
            backup: Some(_),
            ..
        })
    ));
    let _ = std::fs::remove_dir_all(&dir);
}
