//! The fit alone, on perfect silhouettes: synthetic subjects' true masks (no segmentation
//! error) through the fitter, measured and compared with the truth. Separates the fit's
//! own error from the segmenter's.

use fitstation::body::ShapeLibrary;
use fitstation::camera::StationCalibration;
use fitstation::fit::correspond::{MaskRef, Variant};
use fitstation::fit::section_prior::{ellipse_perimeter, WAIST_HULL_TO_ELLIPSE};
use fitstation::fit::{FitOptions, Fitter, Observation};
use fitstation::mesh::TriMesh;
use fitstation::recording::FrameFormat;
use fitstation::synth::{load_truth, render_recording, truth_dir, SynthConfig};
use glam::DVec3;
use std::sync::Arc;

fn load_mask(path: &std::path::Path) -> (u32, u32, Vec<u8>) {
    let img = image::open(path).expect("mask").to_luma8();
    (img.width(), img.height(), img.into_raw())
}

/// Fits seed `seed` on its true masks and returns (measured, truth) per report key.
fn fit_seed(lib: &Arc<ShapeLibrary>, seed: u64, variant: Variant) -> Vec<(String, f64, f64)> {
    // The bodies are the shape library's, whose waists are rounder than nearly every real
    // person's: the fit's real-people waist shape (`fit::section_prior`, tested below)
    // would add 20-35 mm to these waists. What this checks is the fit's own machinery.
    let opts = FitOptions {
        variant,
        waist_prior: false,
        ..FitOptions::default()
    };
    fit_seed_with(lib, seed, opts).0
}

/// [`fit_seed`] with `opts`; also returns the fitted avatar's waist girth over the
/// perimeter of the ellipse of its trunk's breadth and depth at the waist level.
fn fit_seed_with(
    lib: &Arc<ShapeLibrary>,
    seed: u64,
    opts: FitOptions,
) -> (Vec<(String, f64, f64)>, f64) {
    static RUN: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);
    let run = RUN.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    let variant = opts.variant;
    let dir = std::env::temp_dir().join(format!(
        "fitstation-fit-true-{}-{seed}-{run}",
        std::process::id()
    ));
    let _ = std::fs::remove_dir_all(&dir);
    let rec = dir.join("rec");
    let mut cfg = SynthConfig::from_seed(seed);
    cfg.empty_frames = 10;
    cfg.subject_frames = 1;
    cfg.format = FrameFormat::Png;
    render_recording(&cfg, &rec).expect("render");
    let truth = load_truth(&truth_dir(&rec)).expect("truth");
    let calib = StationCalibration::load(&rec.join("station.yaml")).expect("calib");
    let (fw, fh, fm) = load_mask(&truth_dir(&rec).join("masks/front/000010.png"));
    let (sw, sh, sm) = load_mask(&truth_dir(&rec).join("masks/side/000010.png"));
    let crotch = DVec3::from_array(truth.landmarks["crotch"]);
    let obs = Observation::new(
        truth.measurements_mm["stature"] / 1000.0,
        crotch + DVec3::new(0.0, 0.08, 0.0),
    );
    let mut fitter = Fitter::new(lib.clone(), opts).expect("fitter");
    let front = MaskRef {
        width: fw,
        height: fh,
        data: &fm,
    };
    let side = MaskRef {
        width: sw,
        height: sh,
        data: &sm,
    };
    let (pos, stats) = fitter.fit(&calib, front, side, &obs).expect("fit");
    eprintln!("seed {seed} {variant:?}: {stats:?}");
    let avatar = TriMesh::new(pos.to_vec(), fitter.template_triangles().to_vec());
    let measured = fitstation::measure::measure(&avatar).expect("measure");
    let (b, d) =
        fitter.trunk_extents_at(&[measured.levels.waist_m])[0].expect("trunk at the waist");
    let fullness = measured.waist_girth_mm / (1000.0 * ellipse_perimeter(b, d));
    let m = measured.to_report_map();
    // The truth mesh measured by the same module (not the renderer's own figures).
    let true_mesh = fitstation::mesh::io::read_obj(&truth_dir(&rec).join("mesh.obj"), None)
        .expect("truth mesh");
    let t = fitstation::measure::measure(&true_mesh)
        .expect("measure truth")
        .to_report_map();
    std::fs::remove_dir_all(&dir).ok();
    let rows = t
        .iter()
        .map(|(k, v)| {
            (
                k.clone(),
                m.get(k).and_then(|x| x.as_f64()).unwrap_or(f64::NAN),
                v.as_f64().unwrap_or(f64::NAN),
            )
        })
        .collect();
    (rows, fullness)
}

/// The fitted waist's section is as full as real people's (ANSUR II's median), whatever
/// the candidate's; without the prior it keeps the library body's rounder one.
#[test]
fn the_fitted_waist_has_real_peoples_section_shape() {
    let lib = Arc::new(ShapeLibrary::load_default().expect("library"));
    let with = |waist_prior| {
        let opts = FitOptions {
            waist_prior,
            ..FitOptions::default()
        };
        fit_seed_with(&lib, 11, opts)
    };
    let (on_rows, on) = with(true);
    let (off_rows, off) = with(false);
    let waist = |rows: &[(String, f64, f64)]| {
        rows.iter()
            .find(|r| r.0 == "waist_girth")
            .map(|r| r.1)
            .expect("waist")
    };
    eprintln!(
        "waist fullness: prior {on:.4} ({:.1} mm), candidate's {off:.4} ({:.1} mm)",
        waist(&on_rows),
        waist(&off_rows)
    );
    assert!((on - WAIST_HULL_TO_ELLIPSE).abs() < 0.012, "{on}");
    assert!((on - off).abs() > 0.005, "{on} vs {off}");
    assert!((waist(&on_rows) - waist(&off_rows)).abs() > 3.0);
}

/// Largest error of one girth on one subject, mm.
const GIRTH_TOLERANCE_MM: f64 = 35.0;

#[test]
fn fit_on_true_silhouettes_recovers_girths() {
    let lib = Arc::new(ShapeLibrary::load_default().expect("library"));
    for variant in [Variant::PerspectiveRim, Variant::SliceExtremes] {
        for seed in [11, 12] {
            let rows = fit_seed(&lib, seed, variant);
            for (k, got, want) in &rows {
                eprintln!(
                    "  {k:<18} fitted {got:8.1}  truth {want:8.1}  error {:+6.1}",
                    got - want
                );
            }
            for (k, got, want) in rows {
                // The targets are mean errors over the evaluation set (chest 14,
                // waist/hip 12, thigh 6 mm; README); one subject may sit further out, but
                // not beyond 2.5 times the chest tolerance (a broken stage gives hundreds).
                let tol = if k == "stature" {
                    8.0
                } else {
                    GIRTH_TOLERANCE_MM
                };
                assert!(
                    (got - want).abs() < tol,
                    "seed {seed} {variant:?} {k}: {got:.1} vs {want:.1}"
                );
            }
        }
    }
}
