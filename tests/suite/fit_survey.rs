//! Survey of the fit on true silhouettes over several seeds (ignored by default; run with
//! `FIT_SEEDS=11,12,7,3,21 cargo test --release --test suite fit_survey:: -- --ignored --nocapture`).
//! Prints each girth's error, and the torso section's width and depth (avatar vs truth) at
//! the truth's hip, waist and chest levels, to tell shape errors from level errors.
//! Writes the avatar and truth meshes to `/tmp/fit_survey/<seed>/` for inspection.

use fitstation::body::ShapeLibrary;
use fitstation::camera::StationCalibration;
use fitstation::fit::correspond::{MaskRef, Variant};
use fitstation::fit::{FitOptions, Fitter, Observation};
use fitstation::mesh::section::{slice, Plane};
use fitstation::mesh::TriMesh;
use fitstation::recording::FrameFormat;
use fitstation::synth::{load_truth, render_recording, truth_dir, SynthConfig};
use glam::DVec3;
use std::sync::Arc;

fn load_mask(path: &std::path::Path) -> (u32, u32, Vec<u8>) {
    let img = image::open(path).expect("mask").to_luma8();
    (img.width(), img.height(), img.into_raw())
}

/// Width and depth of the section loop containing x = `axis_x` at height `y`.
fn extents(mesh: &TriMesh, y: f64, axis_x: f64) -> (f64, f64) {
    let loops = slice(mesh, &Plane::horizontal(y));
    let mut best = (f64::NAN, f64::NAN);
    let mut best_w = 0.0;
    for l in loops {
        let (lo, hi) = l
            .points
            .iter()
            .fold((f64::MAX, f64::MIN), |(a, b), p| (a.min(p.x), b.max(p.x)));
        if lo < axis_x && hi > axis_x && hi - lo > best_w {
            let (zl, zh) = l
                .points
                .iter()
                .fold((f64::MAX, f64::MIN), |(a, b), p| (a.min(p.y), b.max(p.y)));
            best_w = hi - lo;
            best = (1e3 * (hi - lo), 1e3 * (zh - zl));
        }
    }
    best
}

#[test]
#[ignore]
fn survey() {
    let seeds: Vec<u64> = std::env::var("FIT_SEEDS")
        .unwrap_or_else(|_| "11,12,7,3,21".into())
        .split(',')
        .filter_map(|s| s.trim().parse().ok())
        .collect();
    let variant = if std::env::var("FIT_VARIANT").as_deref() == Ok("slice") {
        Variant::SliceExtremes
    } else {
        Variant::PerspectiveRim
    };
    let lib = Arc::new(ShapeLibrary::load_default().expect("library"));
    let mut fitter = Fitter::new(
        lib,
        FitOptions {
            variant,
            ..FitOptions::default()
        },
    )
    .expect("fitter");
    let keys = [
        "chest_girth",
        "waist_girth",
        "hip_girth",
        "thigh_girth_left",
        "thigh_girth_right",
    ];
    let mut sums = [0.0f64; 5];
    for &seed in &seeds {
        let dir = std::env::temp_dir().join(format!(
            "fitstation-fit-survey-{}-{seed}",
            std::process::id()
        ));
        let _ = std::fs::remove_dir_all(&dir);
        let rec = dir.join("rec");
        let mut cfg = SynthConfig::from_seed(seed);
        cfg.empty_frames = 10;
        cfg.subject_frames = 3;
        cfg.format = FrameFormat::Png;
        render_recording(&cfg, &rec).expect("render");
        let truth = load_truth(&truth_dir(&rec)).expect("truth");
        let calib = StationCalibration::load(&rec.join("station.yaml")).expect("calib");
        let crotch = DVec3::from_array(truth.landmarks["crotch"]);
        let obs = Observation::new(
            truth.measurements_mm["stature"] / 1000.0,
            crotch + DVec3::new(0.0, 0.08, 0.0),
        );
        fitter.reset();
        let mut times = Vec::new();
        let mut pos = Vec::new();
        for f in 10..13 {
            let (fw, fh, fm) = load_mask(&truth_dir(&rec).join(format!("masks/front/{f:06}.png")));
            let (sw, sh, sm) = load_mask(&truth_dir(&rec).join(format!("masks/side/{f:06}.png")));
            let t0 = std::time::Instant::now();
            let (p, stats) = fitter
                .fit(
                    &calib,
                    MaskRef {
                        width: fw,
                        height: fh,
                        data: &fm,
                    },
                    MaskRef {
                        width: sw,
                        height: sh,
                        data: &sm,
                    },
                    &obs,
                )
                .expect("fit");
            times.push(t0.elapsed().as_secs_f64() * 1e3);
            if f == 10 {
                eprintln!("seed {seed}: first fit {:?}", stats.targets);
                pos = p.to_vec();
            }
        }
        let avatar = TriMesh::new(pos, fitter.template_triangles().to_vec());
        let true_mesh = fitstation::mesh::io::read_obj(&truth_dir(&rec).join("mesh.obj"), None)
            .expect("truth mesh");
        let out = std::path::PathBuf::from(format!("/tmp/fit_survey/{seed}"));
        std::fs::create_dir_all(&out).ok();
        fitstation::mesh::io::write_obj(&out.join("avatar.obj"), &avatar).ok();
        fitstation::mesh::io::write_obj(&out.join("truth.obj"), &true_mesh).ok();
        let m = fitstation::measure::measure(&avatar).expect("measure");
        let t = fitstation::measure::measure(&true_mesh).expect("measure truth");
        let (mm, tm) = (m.to_report_map(), t.to_report_map());
        let mut line = format!("seed {seed:>3}:");
        for (i, k) in keys.iter().enumerate() {
            let e = mm[*k].as_f64().unwrap_or(f64::NAN) - tm[*k].as_f64().unwrap_or(f64::NAN);
            sums[i] += e.abs();
            line += &format!(" {k} {e:+6.1}");
        }
        eprintln!("{line}  times ms {times:.1?}");
        let lv = &t.levels;
        for (name, y) in [
            ("hip", lv.hip_m),
            ("waist", lv.waist_m),
            ("chest", lv.chest_m),
        ] {
            let (aw, ad) = extents(&avatar, y, crotch.x);
            let (tw, td) = extents(&true_mesh, y, crotch.x);
            eprintln!("   {name:<6} y {y:.3}: width {aw:6.1} vs {tw:6.1} ({:+5.1}), depth {ad:6.1} vs {td:6.1} ({:+5.1})", aw - tw, ad - td);
        }
        let leg = |mesh: &TriMesh, y: f64| -> (f64, f64) {
            let loops = slice(mesh, &Plane::horizontal(y));
            let mut best = (f64::NAN, f64::NAN, 0.0);
            for l in loops {
                let (lo, hi) = l
                    .points
                    .iter()
                    .fold((f64::MAX, f64::MIN), |(a, b), p| (a.min(p.x), b.max(p.x)));
                let (zl, zh) = l
                    .points
                    .iter()
                    .fold((f64::MAX, f64::MIN), |(a, b), p| (a.min(p.y), b.max(p.y)));
                if 0.5 * (lo + hi) > crotch.x + 0.03 && hi - lo > best.2 && hi - lo < 0.3 {
                    best = (1e3 * (hi - lo), 1e3 * (zh - zl), hi - lo);
                }
            }
            (best.0, best.1)
        };
        let (aw, ad) = leg(&avatar, lv.thigh_left_m);
        let (tw, td) = leg(&true_mesh, lv.thigh_left_m);
        eprintln!("   thighL y {:.3}: width {aw:6.1} vs {tw:6.1} ({:+5.1}), depth {ad:6.1} vs {td:6.1} ({:+5.1})", lv.thigh_left_m, aw - tw, ad - td);
        eprintln!(
            "   levels avatar/truth: crotch {:.3}/{:.3} hip {:.3}/{:.3} waist {:.3}/{:.3} chest {:.3}/{:.3} armpit {:.3}/{:.3}",
            m.levels.crotch_m, lv.crotch_m, m.levels.hip_m, lv.hip_m, m.levels.waist_m, lv.waist_m, m.levels.chest_m, lv.chest_m, m.levels.armpit_m, lv.armpit_m
        );
        std::fs::remove_dir_all(&dir).ok();
    }
    let n = seeds.len().max(1) as f64;
    eprintln!(
        "mean abs error mm: {}",
        keys.iter()
            .zip(&sums)
            .map(|(k, s)| format!("{k} {:.1}", s / n))
            .collect::<Vec<_>>()
            .join(", ")
    );
}
