//! A second person walking behind the shopper (issue 20): `synth-set --passer-by`
//! renders one, and the station neither stops for it nor measures it.

use fitstation::camera::View;
use fitstation::recording::{FrameFormat, Recording};
use fitstation::synth::{load_truth, render_recording, set_member, truth_dir, SynthConfig};
use std::path::Path;

/// A development-range subject (seeds 20500+; never a judgement seed).
const FIRST_SEED: u64 = 20500;
const SET_COUNT: usize = 4;

use crate::common;

fn tmp(name: &str) -> common::TempDir {
    common::tmp_dir("passer", name)
}

fn config(member: usize, passer_by: bool, subject_frames: usize) -> SynthConfig {
    let mut cfg = set_member(FIRST_SEED, member, SET_COUNT);
    cfg.empty_frames = 10;
    cfg.subject_frames = subject_frames;
    cfg.format = FrameFormat::Png;
    cfg.passer_by = passer_by;
    cfg
}

fn frame(rec: &Path, view: View, k: usize) -> image::RgbImage {
    image::open(rec.join(view.name()).join(format!("{k:06}.png")))
        .expect("frame")
        .to_rgb8()
}

fn truth_mask(rec: &Path, view: View, k: usize) -> Vec<u8> {
    image::open(
        truth_dir(rec)
            .join("masks")
            .join(view.name())
            .join(format!("{k:06}.png")),
    )
    .expect("mask")
    .to_luma8()
    .into_raw()
}

/// Pixels that differ between two frames by more than the film's noise could make.
fn changed_px(a: &image::RgbImage, b: &image::RgbImage) -> usize {
    a.pixels()
        .zip(b.pixels())
        .filter(|(p, q)| (0..3).any(|c| p[c].abs_diff(q[c]) > 40))
        .count()
}

#[test]
fn the_passer_by_is_in_the_pictures_and_not_in_the_truth() {
    let dir = tmp("synth");
    let (plain, walked) = (dir.join("plain"), dir.join("walked"));
    render_recording(&config(0, false, 3), &plain).expect("render");
    render_recording(&config(0, true, 3), &walked).expect("render");
    let truth = load_truth(&truth_dir(&walked)).expect("truth");
    let path = truth
        .passer_by
        .expect("the passer-by's path is in truth.json");
    assert!(path.z_m <= -0.5 && path.from_x_m > path.to_x_m, "{path:?}");
    assert!(load_truth(&truth_dir(&plain))
        .expect("truth")
        .passer_by
        .is_none());
    assert_eq!(
        Recording::open(&walked).expect("recording").len(),
        Recording::open(&plain).expect("recording").len()
    );
    for view in View::BOTH {
        // The empty frames (the backdrop is learned on them) have nobody.
        assert_eq!(
            changed_px(&frame(&plain, view, 5), &frame(&walked, view, 5)),
            0
        );
        for k in 10..13 {
            // The truth is the subject's alone ...
            assert_eq!(truth_mask(&plain, view, k), truth_mask(&walked, view, k));
        }
    }
    // ... while the pictures show someone else walking by.
    let seen: usize = (10..13)
        .map(|k| {
            changed_px(
                &frame(&plain, View::Front, k),
                &frame(&walked, View::Front, k),
            )
        })
        .sum();
    assert!(
        seen > 5_000,
        "the passer-by covers {seen} px of the front frames"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// Girths may differ by this much between the subject replayed alone and with the
/// passer-by, mm: the passer-by's frames are not measured, so fewer frames settle the
/// values (dev subjects 20500-20505 moved by 0-10 mm, one waist by 25).
const MAX_GIRTH_CHANGE_MM: f64 = 12.0;

#[test]
fn a_person_walking_behind_neither_stops_the_fit_nor_is_measured() {
    let dir = tmp("station");
    let (plain, walked) = (dir.join("plain"), dir.join("walked"));
    render_recording(&config(0, false, 12), &plain).expect("render");
    render_recording(&config(0, true, 12), &walked).expect("render");
    let alone = common::replay_report(&plain);
    let with = common::replay_report(&walked);
    let messages = with["messages"].to_string();
    eprintln!(
        "frames alone {} / with the passer-by {}",
        alone["frames"], with["frames"]
    );
    eprintln!("messages: {messages}");
    // Fitted on the still frames before and after the walk ...
    let fitted = with["frames"]["fitted"].as_u64().unwrap_or(0);
    assert!(fitted >= 4, "only {fitted} frames fitted");
    // ... not on those where the passer-by merged with the outline ...
    assert!(
        fitted < alone["frames"]["fitted"].as_u64().unwrap_or(0),
        "every frame was measured, the passer-by's too"
    );
    assert!(
        messages.contains("waiting for a still picture"),
        "{messages}"
    );
    // ... and never taken for a second shopper in the booth.
    assert!(!messages.contains("More than one person"), "{messages}");
    for key in common::GIRTHS {
        let a = alone["measurements_mm"][key]
            .as_f64()
            .expect("measured alone");
        let b = with["measurements_mm"][key]
            .as_f64()
            .expect("measured with the passer-by");
        eprintln!("{key}: alone {a:.1}, with the passer-by {b:.1} mm");
        assert!(
            (a - b).abs() <= MAX_GIRTH_CHANGE_MM,
            "{key}: {a:.1} mm alone, {b:.1} mm with someone walking behind"
        );
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// The masks written by replaying `rec` with the frame sampled away from the person or
/// tested in full, as (file name, bytes) per view, and the report.
fn replay_masks(
    rec: &Path,
    sample: bool,
    masks: &Path,
) -> (Vec<(String, Vec<u8>)>, serde_json::Value) {
    let mut opts = fitstation::station::StationOptions {
        masks_out: Some(masks.to_path_buf()),
        ..Default::default()
    };
    opts.silhouette.segment.sample_outside_person = sample;
    let report = common::replay_report_with(rec, opts);
    let mut files = Vec::new();
    for view in View::BOTH {
        let mut names: Vec<_> = std::fs::read_dir(masks.join(view.name()))
            .expect("masks written")
            .map(|e| e.expect("entry").file_name().to_string_lossy().into_owned())
            .collect();
        names.sort();
        for n in names {
            let bytes = std::fs::read(masks.join(view.name()).join(&n)).expect("mask");
            files.push((format!("{}/{n}", view.name()), bytes));
        }
    }
    (files, report)
}

#[test]
fn sampling_away_from_the_person_gives_the_full_tests_masks() {
    // The segmentation tests every coarse cell only about the person's last box and
    // samples the rest, testing in full where a sample changed. On a recording whose
    // passer-by crosses the sampled part of both views, every mask (the passer-by's
    // frames too) and every measurement must be those of the full test.
    let dir = tmp("sampled");
    let rec = dir.join("walked");
    render_recording(&config(1, true, 12), &rec).expect("render");
    let (sampled, a) = replay_masks(&rec, true, &dir.join("masks_sampled"));
    let (full, b) = replay_masks(&rec, false, &dir.join("masks_full"));
    assert!(sampled.len() >= 2 * 12, "{} masks written", sampled.len());
    assert_eq!(
        sampled.iter().map(|f| &f.0).collect::<Vec<_>>(),
        full.iter().map(|f| &f.0).collect::<Vec<_>>()
    );
    for ((name, s), (_, f)) in sampled.iter().zip(&full) {
        assert!(
            s == f,
            "mask {name} differs between the sampled and the full test"
        );
    }
    assert_eq!(a["frames"], b["frames"]);
    assert_eq!(a["measurements_mm"], b["measurements_mm"]);
    assert!(
        a["measurements_mm"]["chest_girth"].as_f64().is_some(),
        "{}",
        a["frames"]
    );
    let _ = std::fs::remove_dir_all(&dir);
}
