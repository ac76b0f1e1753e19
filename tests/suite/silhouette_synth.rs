//! The silhouette stage on the synthetic renderer's recordings (`fitstation::synth`:
//! shaded MakeHuman-based bodies in tight clothing, random station geometry within the
//! kiosk's ranges, lens distortion, optics blur, vignetting, noise, flicker, sway, soft
//! shadows): mask IoU against the truth masks of every subject frame, and the heights of
//! the head top, crotch, armpits and acromions against the truth landmarks of the mesh.
//!
//! The seeds are the first seeds whose drawn look is hard for a background model (grey
//! or dark clothing close to the backdrop or floor colour, selected by the scene colours
//! alone, before any rendering) plus a few ordinary ones. Environment:
//! - `SILHOUETTE_SEEDS=1,2,3` renders and scores those seeds instead;
//! - `SILHOUETTE_EVAL_SET=dir` scores every `subject_*` recording of a
//!   `fitstation synth-set` folder instead (MP4 or PNG);
//! - `SILHOUETTE_SYNTH_DUMP=dir` keeps frame, our mask and the truth mask of each view.
//!
//! Skipped (SKIPPED line) when the body source is not on this machine.

use fitstation::camera::View;
use fitstation::imgproc::Mask;
use fitstation::landmarks::graze::TemplateProfiles;
use fitstation::landmarks::LandmarkName;
use fitstation::recording::{FrameFormat, Recording};
use fitstation::silhouette::{SilhouetteExecutor, SilhouetteOptions, SilhouetteResult};
use fitstation::synth::rng::SplitMix64;
use fitstation::synth::scene::Scene;
use fitstation::synth::{self, load_truth, render_recording, truth_dir, SynthConfig};
use std::path::{Path, PathBuf};

/// Mask IoU floor of every frame. The target is 0.98 for the mean; on these
/// hard-look seeds the mean is 0.978 and the worst frame 0.942 (0.967 and 0.904 before
/// the shadow's chromaticity tolerance became an angle: dark shoes and legs of the floor's
/// hue were taken for their shadow). The floors guard against that coming back.
const MIN_IOU: f64 = 0.93;
/// Mean IoU over all frames and views.
const MIN_MEAN_IOU: f64 = 0.97;
/// Stature (the head top) within 5 mm: the 10 mm for landmark heights, halved
/// since the head top is moved down by the template's dome for each view's grazing ray
/// (`landmarks::graze`; 3.0 mm worst on these seeds, 7.4-12.7 mm on the evaluation sets
/// before).
const MAX_HEIGHT_ERR_M: f64 = 0.005;
/// Crotch height within the 10 mm. The front camera sees the crotch as the apex
/// of the leg gap, which its ray reaches below the perineum when it looks down or up
/// through the body (4-15 mm on the evaluation sets before); the station corrects for
/// that with the template's trough under the crotch (`landmarks::graze`), which is why
/// the executor here gets the shape library's template.
const MAX_CROTCH_ERR_M: f64 = 0.010;
/// Armpits and acromions: the 10 mm holds on these seeds (9.4 and 6.7 mm worst)
/// but not on every evaluation set (armpits 11.5-17 mm worst on the fitted frames of the
/// 12- and 24-subject sets, the same on the renderer's own masks: the narrow fold between
/// arm and torso closes in the image below where they meet; acromions up to 11 mm).
/// This bound guards against regressions.
const MAX_ARM_ERR_M: f64 = 0.012;
/// Acromions on these seeds: 6.7 mm worst with the shoulder's section (`landmarks::graze`),
/// 9.8 mm without.
const MAX_ACROMION_ERR_M: f64 = 0.008;
/// Hard-look seeds and ordinary seeds scored by default.
const HARD_SEEDS: usize = 5;
const EASY_SEEDS: [u64; 2] = [2, 5];
/// Seeds scanned for hard looks.
const SCAN_SEEDS: std::ops::Range<u64> = 1..400;
/// A clothing colour this close (sRGB distance, 8-bit units) to the backdrop or floor
/// colour makes a hard look.
const HARD_COLOUR_DISTANCE: f32 = 60.0;

fn body_available() -> bool {
    match synth::subject_mesh(&synth::subject::SubjectParams::sample(1)) {
        Ok(_) => true,
        Err(e) => {
            println!("SKIPPED: no body source ({e}); silhouette tests on synthetic recordings did not run");
            false
        }
    }
}

fn tmp(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!(
        "fitstation-silhouette-synth-{}-{name}",
        std::process::id()
    ));
    let _ = std::fs::remove_dir_all(&d);
    let _ = std::fs::remove_dir_all(truth_dir(&d));
    d
}

fn to_srgb(c: [f32; 3]) -> [f32; 3] {
    c.map(|v| 255.0 * v.max(0.0).powf(1.0 / 2.2))
}

fn dist(a: [f32; 3], b: [f32; 3]) -> f32 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}

/// How hard a seed's look is: the smallest distance of shirt / leggings to the backdrop
/// or floor colour (the scene is drawn from the same stream as `render_recording` does).
fn look_hardness(seed: u64) -> f32 {
    let calib = fitstation::camera::StationCalibration::nominal(720, 1280, 1300.0, 2.6, 1.0, 0.9);
    let mut rng = SplitMix64::stream(seed, 0x5C);
    let scene = Scene::random(&mut rng, [&calib.front, &calib.side]);
    let l = &scene.look;
    let mut d = f32::MAX;
    for cloth in [l.shirt, l.leggings] {
        for bg in [l.backdrop, l.floor] {
            d = d.min(dist(to_srgb(cloth), to_srgb(bg)));
        }
    }
    d
}

fn default_seeds() -> Vec<u64> {
    let mut seeds: Vec<u64> = SCAN_SEEDS
        .filter(|&s| look_hardness(s) < HARD_COLOUR_DISTANCE)
        .take(HARD_SEEDS)
        .collect();
    seeds.extend(EASY_SEEDS);
    seeds
}

/// Heights compared with the truth: (ours, truth key).
const HEIGHTS: [(LandmarkName, &str); 6] = [
    (LandmarkName::HeadTop, "head_top"),
    (LandmarkName::Crotch, "crotch"),
    (LandmarkName::ArmpitLeft, "left_armpit"),
    (LandmarkName::ArmpitRight, "right_armpit"),
    (LandmarkName::AcromionLeft, "left_acromion"),
    (LandmarkName::AcromionRight, "right_acromion"),
];

/// Scores of one subject frame pair.
struct FrameScore {
    name: String,
    index: usize,
    iou: [f64; 2],
    /// Height error (ours - truth), metres, per entry of `HEIGHTS`.
    height_err: [Option<f64>; 6],
    /// No verdict refuses the frame: the station fits it.
    fitted: bool,
}

fn load_mask(path: &Path) -> Mask {
    let t = image::open(path).expect("truth mask").to_luma8();
    Mask {
        width: t.width(),
        height: t.height(),
        data: t.into_raw(),
    }
}

fn evaluate(rec_dir: &Path, name: &str, out: &mut Vec<FrameScore>) {
    let tdir = truth_dir(rec_dir);
    let truth = load_truth(&tdir).expect("truth");
    let mut rec = Recording::open(rec_dir).expect("open");
    let calib = rec.calibration().clone();
    let opts = SilhouetteOptions {
        template_profiles: Some(
            TemplateProfiles::of_shape_library().expect("the bundled shape library"),
        ),
        ..SilhouetteOptions::default()
    };
    let mut ex = SilhouetteExecutor::new(&calib, opts);
    let mut res = SilhouetteResult::empty();
    let dump = std::env::var_os("SILHOUETTE_SYNTH_DUMP").map(PathBuf::from);
    for f in &truth.per_frame {
        let (front, side) = rec.frame_pair(f.index).expect("frame");
        if !f.subject {
            ex.learn_background(&front, &side).expect("learn");
            continue;
        }
        ex.process_into(&front, &side, &mut res).expect("process");
        let mut iou = [0.0; 2];
        for (k, (view, mask)) in [
            (View::Front, &res.masks.front),
            (View::Side, &res.masks.side),
        ]
        .into_iter()
        .enumerate()
        {
            let path = tdir
                .join("masks")
                .join(view.name())
                .join(format!("{:06}.png", f.index));
            iou[k] = mask.iou(&load_mask(&path));
            if let Some(d) = &dump {
                let _ = std::fs::create_dir_all(d);
                let tag = format!("{name}_{}_{}", f.index, view.name());
                let frame = if view == View::Front { &front } else { &side };
                frame
                    .save(d.join(format!("{tag}_frame.png")))
                    .expect("save");
                image::GrayImage::from_raw(mask.width, mask.height, mask.data.clone())
                    .expect("mask")
                    .save(d.join(format!("{tag}_ours.png")))
                    .expect("save");
                std::fs::copy(&path, d.join(format!("{tag}_truth.png"))).expect("copy");
            }
        }
        let lm = &res.landmarks;
        let mut height_err = [None; 6];
        for (k, (ours, key)) in HEIGHTS.iter().enumerate() {
            let got = if *ours == LandmarkName::HeadTop {
                Some(lm.stature_m).filter(|&s| s > 0.0)
            } else {
                lm.get(*ours).map(|p| p.station.y)
            };
            let want = truth.landmarks.get(*key).map(|p| p[1]);
            if let (Some(g), Some(w)) = (got, want) {
                height_err[k] = Some(g - w);
            }
        }
        out.push(FrameScore {
            name: name.to_string(),
            index: f.index,
            iou,
            height_err,
            fitted: !lm.verdicts.iter().any(|v| v.blocks_fit()),
        });
    }
}

fn fmt_err(e: Option<f64>) -> String {
    e.map_or("   -   ".into(), |e| format!("{:+7.1}", e * 1e3))
}

#[test]
fn synthetic_recordings_segment_and_give_landmark_heights() {
    if !body_available() {
        return;
    }
    let mut scores = Vec::new();
    if let Some(set) = std::env::var_os("SILHOUETTE_EVAL_SET") {
        let mut dirs: Vec<PathBuf> = std::fs::read_dir(&set)
            .expect("eval set")
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| {
                p.is_dir()
                    && p.file_name()
                        .is_some_and(|n| !n.to_string_lossy().ends_with(".truth"))
            })
            .collect();
        dirs.sort();
        for d in dirs {
            let name = d
                .file_name()
                .unwrap_or_default()
                .to_string_lossy()
                .into_owned();
            evaluate(&d, &name, &mut scores);
        }
    } else {
        let seeds: Vec<u64> = match std::env::var("SILHOUETTE_SEEDS") {
            Ok(s) => s.split(',').filter_map(|v| v.trim().parse().ok()).collect(),
            Err(_) => default_seeds(),
        };
        for seed in seeds {
            let out = tmp(&format!("s{seed}"));
            let mut cfg = SynthConfig::from_seed(seed);
            cfg.empty_frames = 10;
            cfg.subject_frames = 2;
            cfg.format = FrameFormat::Png;
            render_recording(&cfg, &out).expect("render");
            println!("seed {seed}: look hardness {:.0}", look_hardness(seed));
            evaluate(&out, &format!("seed {seed}"), &mut scores);
            let _ = std::fs::remove_dir_all(&out);
            let _ = std::fs::remove_dir_all(truth_dir(&out));
        }
    }
    println!(
        "{:<12} {:>5} {:>7} {:>7} | height error mm: {:>7} {:>7} {:>7} {:>7} {:>7} {:>7}",
        "recording",
        "frame",
        "IoU F",
        "IoU S",
        "top",
        "crotch",
        "armp L",
        "armp R",
        "acro L",
        "acro R"
    );
    let mut worst_iou = 1.0f64;
    let mut worst = [0.0f64; 6];
    let mut missing = Vec::new();
    for s in &scores {
        println!(
            "{:<12} {:>5} {:>7.4} {:>7.4} | {:>22} {} {} {} {} {} {}",
            s.name,
            s.index,
            s.iou[0],
            s.iou[1],
            "",
            fmt_err(s.height_err[0]),
            fmt_err(s.height_err[1]),
            fmt_err(s.height_err[2]),
            fmt_err(s.height_err[3]),
            fmt_err(s.height_err[4]),
            fmt_err(s.height_err[5]),
        );
        worst_iou = worst_iou.min(s.iou[0]).min(s.iou[1]);
        for k in 0..6 {
            match s.height_err[k] {
                Some(e) => worst[k] = worst[k].max(e.abs()),
                None => missing.push(format!("{} {}: {}", s.name, s.index, HEIGHTS[k].1)),
            }
        }
    }
    let mean_iou =
        scores.iter().map(|s| s.iou[0] + s.iou[1]).sum::<f64>() / (2 * scores.len().max(1)) as f64;
    // The masks the station goes on to fit (no verdict refuses the frame).
    let fitted: Vec<&FrameScore> = scores.iter().filter(|s| s.fitted).collect();
    let view_mean =
        |k: usize| fitted.iter().map(|s| s.iou[k]).sum::<f64>() / fitted.len().max(1) as f64;
    println!(
        "frames the station fits: {} of {}, mean IoU {:.4} (front {:.4}, side {:.4})",
        fitted.len(),
        scores.len(),
        0.5 * (view_mean(0) + view_mean(1)),
        view_mean(0),
        view_mean(1)
    );
    println!(
        "worst IoU {worst_iou:.4}, mean IoU {mean_iou:.4}; worst |height error| mm: top {:.1}, crotch {:.1}, armpits {:.1}/{:.1}, acromions {:.1}/{:.1}",
        worst[0] * 1e3,
        worst[1] * 1e3,
        worst[2] * 1e3,
        worst[3] * 1e3,
        worst[4] * 1e3,
        worst[5] * 1e3
    );
    let mut worst_fitted = [0.0f64; 6];
    for s in &fitted {
        for (w, e) in worst_fitted.iter_mut().zip(s.height_err) {
            *w = w.max(e.map_or(0.0, f64::abs));
        }
    }
    println!(
        "frames the station fits: worst |height error| mm: top {:.1}, crotch {:.1}, armpits {:.1}/{:.1}, acromions {:.1}/{:.1}",
        worst_fitted[0] * 1e3,
        worst_fitted[1] * 1e3,
        worst_fitted[2] * 1e3,
        worst_fitted[3] * 1e3,
        worst_fitted[4] * 1e3,
        worst_fitted[5] * 1e3
    );
    // Mean signed and mean absolute height error over the fitted frames.
    let (mut sum, mut abs, mut n) = ([0.0f64; 6], [0.0f64; 6], [0usize; 6]);
    let mut within_10mm = 0usize;
    for s in &fitted {
        for k in 0..6 {
            if let Some(e) = s.height_err[k] {
                sum[k] += e;
                abs[k] += e.abs();
                n[k] += 1;
                within_10mm += (e.abs() <= 0.010) as usize;
            }
        }
    }
    let means: Vec<String> = (0..6)
        .map(|k| {
            let m = n[k].max(1) as f64;
            format!(
                "{} {:+.1} ({:.1})",
                HEIGHTS[k].1,
                1e3 * sum[k] / m,
                1e3 * abs[k] / m
            )
        })
        .collect();
    println!(
        "frames the station fits: mean height error mm (mean |error|): {}; within 10 mm: {within_10mm} of {}",
        means.join(", "),
        n.iter().sum::<usize>()
    );
    assert!(!scores.is_empty());
    assert!(missing.is_empty(), "landmarks not found: {missing:?}");
    assert!(worst_iou >= MIN_IOU, "IoU {worst_iou}");
    assert!(mean_iou >= MIN_MEAN_IOU, "mean IoU {mean_iou}");
    assert!(
        worst[0] < MAX_HEIGHT_ERR_M && worst[1] < MAX_CROTCH_ERR_M,
        "{worst:?}"
    );
    assert!(worst[2..].iter().all(|&w| w < MAX_ARM_ERR_M), "{worst:?}");
    assert!(
        worst[4..].iter().all(|&w| w < MAX_ACROMION_ERR_M),
        "{worst:?}"
    );
}

/// A seed whose front camera looks down on the crotch steeply: the leg gap's apex lifted
/// onto the body axis is 12.5 mm below the perineum there (3.1 mm with the trough).
const STEEP_FRONT_CAMERA_SEED: u64 = 1003;

/// `fitstation landmarks` on one still pair of a synthetic recording (its last empty
/// frames as the backdrop images) gives the crotch within the 10 mm of the mesh's
/// perineum: the command raises the leg gap's apex by the shape library's trough.
#[test]
fn the_landmarks_command_places_the_crotch_at_the_perineum() {
    if !body_available() {
        return;
    }
    let out = tmp("cli");
    let mut cfg = SynthConfig::from_seed(STEEP_FRONT_CAMERA_SEED);
    cfg.empty_frames = 10;
    cfg.subject_frames = 1;
    cfg.format = FrameFormat::Png;
    render_recording(&cfg, &out).expect("render");
    let truth = load_truth(&truth_dir(&out)).expect("truth");
    let want = truth.landmarks["crotch"][1];
    let png = |view: &str, i: usize| out.join(view).join(format!("{i:06}.png"));
    let cli = std::process::Command::new(env!("CARGO_BIN_EXE_fitstation"))
        .arg("landmarks")
        .args(["--front".as_ref(), png("front", 10).as_os_str()])
        .args(["--side".as_ref(), png("side", 10).as_os_str()])
        .args(["--front-bg".as_ref(), png("front", 9).as_os_str()])
        .args(["--side-bg".as_ref(), png("side", 9).as_os_str()])
        .args(["--calib".as_ref(), out.join("station.yaml").as_os_str()])
        .arg("--json")
        .output()
        .expect("run fitstation");
    assert!(
        cli.status.success(),
        "{}",
        String::from_utf8_lossy(&cli.stderr)
    );
    let j: serde_json::Value = serde_json::from_slice(&cli.stdout).expect("JSON");
    let got = j["landmarks"]["crotch"]["station"]["y"]
        .as_f64()
        .expect("crotch y");
    println!("crotch: {got:.4} m, truth {want:.4} m");
    assert!((got - want).abs() < MAX_CROTCH_ERR_M, "{got} vs {want}");
    let _ = std::fs::remove_dir_all(&out);
    let _ = std::fs::remove_dir_all(truth_dir(&out));
}
