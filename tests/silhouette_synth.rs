//! The silhouette stage on the synthetic renderer's recordings (`fitstation::synth`:
//! shaded MakeHuman-based bodies in tight clothing, random station geometry within the
//! kiosk's ranges, lens distortion, optics blur, vignetting, noise, flicker, sway, soft
//! shadows): mask IoU against the truth masks of every subject frame, and the stature,
//! crotch and armpit heights against the truth landmarks of the body mesh.
//! Skipped (SKIPPED line) when the body source is not on this machine.

use fitstation::camera::View;
use fitstation::landmarks::{LandmarkName, SilhouetteExecutor, SilhouetteOptions};
use fitstation::recording::{FrameFormat, Recording};
use fitstation::segment::Mask;
use fitstation::synth::{self, load_truth, render_recording, truth_dir, SynthConfig};
use std::path::PathBuf;

/// Mask IoU floor on these recordings. The 0.98 holds on the phantom and the
/// MakeHuman renders (tests/silhouette_synthetic.rs, silhouette_mesh.rs); here dark
/// trousers against a floor of the same hue pass the shadow test (Horprasert's
/// brightness/chromaticity test cannot tell them apart) and are lost below the knee:
/// a known gap, measured rather than hidden.
const MIN_IOU: f64 = 0.75;
/// Stature and crotch height within 10 mm (issue 4 target for the landmark heights).
const MAX_HEIGHT_ERR_M: f64 = 0.010;
/// The truth armpit is a 3-D definition (highest slice where the arm's section is
/// separate from the torso's), the station's the apex of the silhouette gap. They agree
/// within millimetres on some seeds and differ by 12-14 cm on others (truth at 83 % of
/// the stature, ours at 75 %), so armpits are printed, not asserted.

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

#[test]
fn synthetic_recordings_segment_and_give_landmark_heights() {
    if !body_available() {
        return;
    }
    let mut worst_iou = 1.0f64;
    let mut worst = [0.0f64; 3];
    for seed in [5u64, 6, 7] {
        let out = tmp(&format!("s{seed}"));
        let mut cfg = SynthConfig::from_seed(seed);
        cfg.empty_frames = 10;
        cfg.subject_frames = 2;
        cfg.format = FrameFormat::Png;
        render_recording(&cfg, &out).expect("render");
        let tdir = truth_dir(&out);
        let truth = load_truth(&tdir).expect("truth");
        let mut rec = Recording::open(&out).expect("open");
        let calib = rec.calibration().clone();
        let mut ex = SilhouetteExecutor::new(&calib, SilhouetteOptions::default());
        for f in &truth.per_frame {
            let (front, side) = rec.frame_pair(f.index).expect("frame");
            if !f.subject {
                ex.learn_background(&front, &side).expect("learn");
                continue;
            }
            let res = ex.process(&front, &side).expect("process");
            for (view, mask) in [
                (View::Front, &res.masks.front),
                (View::Side, &res.masks.side),
            ] {
                let path = tdir
                    .join("masks")
                    .join(view.name())
                    .join(format!("{:06}.png", f.index));
                let t = image::open(&path).expect("truth mask").to_luma8();
                let truth_mask = Mask {
                    width: t.width(),
                    height: t.height(),
                    data: t.into_raw(),
                };
                let iou = mask.iou(&truth_mask);
                // SILHOUETTE_SYNTH_DUMP=dir keeps frame, our mask and the truth for a look.
                if let Some(d) = std::env::var_os("SILHOUETTE_SYNTH_DUMP") {
                    let d = PathBuf::from(d);
                    let _ = std::fs::create_dir_all(&d);
                    let tag = format!("s{seed}_{}_{}", f.index, view.name());
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
                println!(
                    "seed {seed} frame {} {}: IoU {iou:.4}",
                    f.index,
                    view.name()
                );
                worst_iou = worst_iou.min(iou);
            }
            let lm = &res.landmarks;
            println!("seed {seed} frame {}: verdicts {:?}", f.index, lm.verdicts);
            let ty = |k: &str| truth.landmarks.get(k).map(|p| p[1]);
            let pairs = [
                ("stature", Some(lm.stature_m), ty("head_top"), 0),
                (
                    "crotch",
                    lm.get(LandmarkName::Crotch).map(|p| p.station.y),
                    ty("crotch"),
                    1,
                ),
                (
                    "armpit_left",
                    lm.get(LandmarkName::ArmpitLeft).map(|p| p.station.y),
                    ty("left_armpit"),
                    2,
                ),
                (
                    "armpit_right",
                    lm.get(LandmarkName::ArmpitRight).map(|p| p.station.y),
                    ty("right_armpit"),
                    2,
                ),
            ];
            for (name, got, want, slot) in pairs {
                let (Some(g), Some(w)) = (got, want) else {
                    panic!("seed {seed}: {name} missing (ours {got:?}, truth {want:?})");
                };
                println!(
                    "seed {seed} frame {}: {name:<13} ours {g:.4} truth {w:.4} ({:+.1} mm)",
                    f.index,
                    (g - w) * 1e3
                );
                worst[slot] = worst[slot].max((g - w).abs());
            }
        }
        let _ = std::fs::remove_dir_all(&out);
        let _ = std::fs::remove_dir_all(&tdir);
    }
    println!(
        "worst: IoU {worst_iou:.4}, stature {:.1} mm, crotch {:.1} mm, armpits {:.1} mm",
        worst[0] * 1e3,
        worst[1] * 1e3,
        worst[2] * 1e3
    );
    assert!(worst_iou > MIN_IOU, "IoU {worst_iou}");
    assert!(
        worst[0] < MAX_HEIGHT_ERR_M && worst[1] < MAX_HEIGHT_ERR_M,
        "{worst:?}"
    );
}
