//! The learned person mask fused with the backdrop model (issue 20, item 3), end to end
//! with real inference: a synthetic subject dressed in the backdrop's own colour
//! (`synth-set --camouflage`) replayed through the station with and without the person
//! model. Without it the backdrop model loses the clothing (the frames are refused or the
//! silhouette is far too small); with it the silhouettes match the truth and the frames
//! are fitted.

use fitstation::cli::{run_offline, RecordingSource};
use fitstation::recording::FrameFormat;
use fitstation::station::default_library;
use fitstation::station::{StationOptions, StationProcessor, ViewSet};
use fitstation::synth::scene::Clothing;
use fitstation::synth::{load_truth, render_recording, set_member, truth_dir};
use std::path::{Path, PathBuf};

/// A dev-range subject whose camouflaged clothing the backdrop model alone loses: every
/// frame refused (`synth-set --first-seed 20200 --count 12 --camouflage`, subject 4).
const FIRST_SEED: u64 = 20200;
const MEMBER: usize = 4;
const SET_COUNT: usize = 12;
/// Frames with the subject (after the ten empty ones the backdrop is learned on).
const SUBJECT_FRAMES: usize = 4;

fn tmp(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("fitstation-fusion-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).expect("temp dir");
    d
}

/// Renders member `member` of the set `synth-set --first-seed FIRST --count COUNT` (in
/// `clothing`) as a short recording `dir/name`: ten empty frames, then
/// [`SUBJECT_FRAMES`] with the subject.
fn member_recording(
    dir: &Path,
    name: &str,
    (first_seed, member, count): (u64, usize, usize),
    clothing: Option<Clothing>,
) -> PathBuf {
    let mut cfg = set_member(first_seed, member, count);
    if let Some(c) = clothing {
        cfg.clothing = c;
    }
    render_short(dir, name, cfg)
}

/// Renders `cfg` as a short recording `dir/name`: ten empty frames, then
/// [`SUBJECT_FRAMES`] with the subject.
fn render_short(dir: &Path, name: &str, mut cfg: fitstation::synth::SynthConfig) -> PathBuf {
    let rec = dir.join(name);
    cfg.empty_frames = 10;
    cfg.subject_frames = SUBJECT_FRAMES;
    cfg.format = FrameFormat::Png;
    render_recording(&cfg, &rec).unwrap_or_else(|e| panic!("render {name}: {e}"));
    rec
}

/// Renders the camouflaged subject's short recording into `dir`.
fn camouflage_recording(dir: &Path) -> PathBuf {
    member_recording(
        dir,
        "camo",
        (FIRST_SEED, MEMBER, SET_COUNT),
        Some(Clothing::Camouflage),
    )
}

/// What one replay gave: frames fitted, mean mask IoU per view over the subject frames,
/// and the chest girth error (mm) when a body was fitted.
struct Replay {
    fitted: u64,
    iou_front: f64,
    iou_side: f64,
    chest_error_mm: Option<f64>,
    report: serde_json::Value,
}

/// Replays `rec` through the station (person model on or off, from `views`) and scores it.
fn replay(rec: &Path, person_model: bool, views: ViewSet, masks: &Path) -> Replay {
    let mut src = RecordingSource::open(rec).expect("open the recording");
    let calib = src.recording().calibration().clone();
    let opts = StationOptions {
        person_model,
        views,
        masks_out: Some(masks.to_path_buf()),
        ..StationOptions::default()
    };
    let library = default_library().expect("shape library");
    let mut station = StationProcessor::new(calib, library, opts).expect("station");
    let summary = run_offline(&mut src, &mut station, None, false);
    let truth = load_truth(&truth_dir(rec)).expect("truth");
    let iou = |view: &str| mean_iou(&truth_dir(rec), masks, view, &truth);
    let chest_error_mm = summary.report["measurements_mm"]["chest_girth"]
        .as_f64()
        .zip(truth.measurements_mm.get("chest_girth"))
        .map(|(f, t)| f - t);
    Replay {
        fitted: summary.report["frames"]["fitted"].as_u64().unwrap_or(0),
        iou_front: iou("front"),
        iou_side: iou("side"),
        chest_error_mm,
        report: summary.report,
    }
}

/// Mean IoU of the station's masks with the true masks over the subject frames.
fn mean_iou(truth_dir: &Path, masks: &Path, view: &str, truth: &fitstation::synth::Truth) -> f64 {
    let ious = frame_ious(truth_dir, masks, view, truth);
    ious.iter().sum::<f64>() / ious.len().max(1) as f64
}

/// IoU of the station's mask with the true mask, per subject frame.
fn frame_ious(
    truth_dir: &Path,
    masks: &Path,
    view: &str,
    truth: &fitstation::synth::Truth,
) -> Vec<f64> {
    let mut ious = Vec::new();
    for f in truth.per_frame.iter().filter(|f| f.subject) {
        let name = format!("{:06}.png", f.index);
        let t = image::open(truth_dir.join("masks").join(view).join(&name))
            .expect("true mask")
            .to_luma8();
        let Ok(r) = image::open(masks.join(view).join(&name)) else {
            ious.push(0.0); // no mask written: nothing was segmented
            continue;
        };
        let r = r.to_luma8();
        let (mut i, mut u) = (0usize, 0usize);
        for (a, b) in t.as_raw().iter().zip(r.as_raw()) {
            let (a, b) = (*a > 127, *b > 127);
            i += (a && b) as usize;
            u += (a || b) as usize;
        }
        ious.push(i as f64 / u.max(1) as f64);
    }
    ious
}

/// A green top and leggings on a green wall (`synth-set --first-seed 62400 --count 12
/// --camouflage`, member 6): at its last frame the backdrop lost a band across the hips,
/// the legs (all inside the standing volume) outweighed the trunk with its arms out, and
/// the trunk, wider than the legs, was not taken as their piece: the front mask kept the
/// legs alone (IoU 0.52). A piece stacked on the body and spanning its columns is joined.
#[test]
fn a_trunk_wider_than_the_legs_chosen_as_the_body_is_joined_to_them() {
    let dir = tmp("stacked");
    let mut cfg = set_member(62400, 6, 12);
    cfg.clothing = Clothing::Camouflage;
    cfg.format = FrameFormat::Png;
    let rec = dir.join("camo06");
    render_recording(&cfg, &rec).expect("render");
    let masks = dir.join("masks");
    let r = replay(&rec, true, ViewSet::Both, &masks);
    let truth = load_truth(&truth_dir(&rec)).expect("truth");
    let front = frame_ious(&truth_dir(&rec), &masks, "front", &truth);
    let worst = front.iter().copied().fold(1.0, f64::min);
    println!("front IoU per frame {front:.3?}; fitted {}", r.fitted);
    assert!(front.len() >= 10, "{} subject frames", front.len());
    assert!(worst >= 0.9, "the worst front frame's IoU is {worst:.3}");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn the_person_mask_restores_clothing_in_the_backdrops_colour() {
    let dir = tmp("camo");
    let rec = camouflage_recording(&dir);
    let without = replay(&rec, false, ViewSet::Both, &dir.join("masks_off"));
    let with = replay(&rec, true, ViewSet::Both, &dir.join("masks_on"));
    println!(
        "without fusion: fitted {}, IoU front {:.3} side {:.3}, chest {:?} mm; messages {}",
        without.fitted,
        without.iou_front,
        without.iou_side,
        without.chest_error_mm,
        without.report["messages"]
    );
    println!(
        "with fusion: fitted {}, IoU front {:.3} side {:.3}, chest {:?} mm; timings {}",
        with.fitted, with.iou_front, with.iou_side, with.chest_error_mm, with.report["timings_ms"]
    );
    // The backdrop model alone: the clothing is lost.
    let lost = without.fitted == 0
        || without.iou_front.min(without.iou_side) < 0.8
        || without.chest_error_mm.is_none_or(|e| e.abs() > 60.0);
    assert!(
        lost,
        "the backdrop model alone was expected to lose the clothing"
    );
    // Fused: every subject frame fitted, silhouettes close to the truth, the chest near.
    assert_eq!(
        with.fitted, SUBJECT_FRAMES as u64,
        "{}",
        with.report["messages"]
    );
    assert!(
        with.iou_front >= 0.95 && with.iou_side >= 0.93,
        "IoU front {:.3}, side {:.3}",
        with.iou_front,
        with.iou_side
    );
    let chest = with.chest_error_mm.expect("a fitted chest");
    assert!(chest.abs() <= 30.0, "chest girth error {chest:+.1} mm");
    let _ = std::fs::remove_dir_all(&dir);
}

/// A subject in a white shirt on the pale wall (`synth-set --first-seed 41300 --count 12`,
/// subject 1; found in session 13's one-camera judgement, a regression case since): the
/// front camera alone sees a head, arms and legs with nothing person-sized between them.
/// The network must still be asked (issue 23, item 3: every subject fitted from one
/// camera), not only when the side view shows someone whole. Before, every frame said
/// "Nobody is on the mark".
#[test]
fn the_person_mask_runs_for_a_subject_in_pieces_seen_by_the_front_camera_alone() {
    let dir = tmp("pieces-front");
    let rec = member_recording(&dir, "white_shirt", (41300, 1, SET_COUNT), None);
    let front = replay(&rec, true, ViewSet::Front, &dir.join("masks"));
    println!(
        "front camera alone: fitted {}, IoU front {:.3}, chest {:?} mm; messages {}",
        front.fitted, front.iou_front, front.chest_error_mm, front.report["messages"]
    );
    assert!(front.fitted >= 1, "{}", front.report["messages"]);
    // 0.89 here (and with both cameras): the fused mask still loses some of the white
    // shirt, issue 20's open work; without the network it is empty.
    assert!(front.iou_front >= 0.85, "IoU front {:.3}", front.iou_front);
    assert_eq!(front.report["views"], serde_json::json!(["front"]));
    let _ = std::fs::remove_dir_all(&dir);
}

/// Replays `rec` with the person model and checks the person came out whole: at least one
/// frame fitted, the stature the truth's within 15 mm (the head is on the silhouette) and
/// the front view's mean IoU at least `min_iou_front`.
fn assert_fitted_whole(rec: &Path, dir: &Path, what: &str, min_iou_front: f64) {
    let both = replay(rec, true, ViewSet::Both, &dir.join("masks"));
    let truth = load_truth(&truth_dir(rec)).expect("truth");
    let stature = both.report["measurements_mm"]["stature"]
        .as_f64()
        .zip(truth.measurements_mm.get("stature"))
        .map(|(f, t)| f - t);
    println!(
        "{what}: fitted {}, IoU front {:.3} side {:.3}, stature {:?} mm, chest {:?} mm; messages {}",
        both.fitted, both.iou_front, both.iou_side, stature, both.chest_error_mm, both.report["messages"]
    );
    assert!(both.fitted >= 1, "{}", both.report["messages"]);
    let stature = stature.expect("a fitted stature");
    assert!(stature.abs() <= 15.0, "stature error {stature:+.1} mm");
    assert!(
        both.iou_front >= min_iou_front,
        "IoU front {:.3}",
        both.iou_front
    );
}

/// A shirt of the wall's own green (`synth-set --first-seed 43000 --count 24 --population
/// ansur`, subject 7; found in session 14's judgement, a regression case since; rendered
/// here with that seed's backdrop and clothing on the library body `set_member` draws): the
/// backdrop loses the shirt's top, the head comes apart from the body, and the station
/// kept only the largest piece, headless ("Hold both arms a little away from the body",
/// "The outline moves", every frame refused). The pieces the network says are the person
/// are now joined to the body.
#[test]
fn the_head_above_a_shirt_of_the_walls_colour_stays_with_the_body() {
    let dir = tmp("pieces-head");
    let rec = member_recording(&dir, "green_shirt", (43000, 7, 24), None);
    assert_fitted_whole(&rec, &dir, "green shirt", 0.8);
    let _ = std::fs::remove_dir_all(&dir);
}

/// The head cut off by a shirt of the wall's colour lost from the chin to the chest
/// (`synth-set --first-seed 46100 --count 24 --population ansur --stance varied`, subject
/// 4, found by session 15's check of those fresh seeds): the head was found as a piece
/// and joined on the coarse grid, but only across the rows between the two boxes, where
/// the shirt was lost in the head's columns too; at full resolution the head came off
/// again and every frame was refused ("Hold both arms a little away from the body").
/// The piece now walks down its columns to the body where the person prior says person,
/// and those cells are kept at full resolution.
#[test]
fn a_head_cut_off_down_to_the_chest_is_joined_to_the_body() {
    let dir = tmp("pieces-chest");
    let table = fitstation::synth::ansur::AnsurTable::load(
        &fitstation::synth::ansur::resolve_dir(None).expect("ANSUR II beside the checkout"),
    )
    .expect("ANSUR II");
    let mut cfg = fitstation::synth::ansur_member(&table, 46100, 4);
    cfg.subject.stance = Some(fitstation::synth::stance::Stance::sample(cfg.seed));
    let rec = render_short(&dir, "green_shirt_varied", cfg);
    assert_fitted_whole(&rec, &dir, "green shirt, varied stance", 0.9);
    let _ = std::fs::remove_dir_all(&dir);
}

/// A camouflaged subject seen by the front camera alone (`synth-set --first-seed 44300
/// --count 12 --camouflage`, subject 7; found by session 14's one-camera check of that
/// judgement, a regression case since): the front view gives targets to 148 of the 815
/// controls, a quarter of those the front view can give, and every frame was refused as
/// "too few silhouette correspondences" counted against both views' controls.
#[test]
fn the_front_camera_alone_is_asked_only_for_its_own_correspondences() {
    let dir = tmp("camo-front");
    let rec = member_recording(
        &dir,
        "camo",
        (44300, 7, SET_COUNT),
        Some(Clothing::Camouflage),
    );
    let front = replay(&rec, true, ViewSet::Front, &dir.join("masks"));
    println!(
        "camouflage, front camera alone: fitted {}, IoU front {:.3}, chest {:?} mm; messages {}",
        front.fitted, front.iou_front, front.chest_error_mm, front.report["messages"]
    );
    assert_eq!(
        front.fitted, SUBJECT_FRAMES as u64,
        "{}",
        front.report["messages"]
    );
    let chest = front.chest_error_mm.expect("a fitted chest");
    assert!(chest.abs() <= 60.0, "chest girth error {chest:+.1} mm");
    let _ = std::fs::remove_dir_all(&dir);
}

/// Side-view pixels of the station's masks that the truth does not hold, in the band of
/// the feet (the lowest 12 % of the true silhouette's height), as a share of the true
/// pixels there; mean over the subject frames.
fn feet_false_share(truth_dir: &Path, masks: &Path, truth: &fitstation::synth::Truth) -> f64 {
    let mut shares = Vec::new();
    for f in truth.per_frame.iter().filter(|f| f.subject) {
        let name = format!("{:06}.png", f.index);
        let t = image::open(truth_dir.join("masks").join("side").join(&name))
            .expect("true mask")
            .to_luma8();
        let r = image::open(masks.join("side").join(&name))
            .expect("station mask")
            .to_luma8();
        let rows: Vec<u32> = (0..t.height())
            .filter(|&y| (0..t.width()).any(|x| t.get_pixel(x, y)[0] > 127))
            .collect();
        let (Some(&top), Some(&bottom)) = (rows.first(), rows.last()) else {
            continue;
        };
        let from = bottom - (0.12 * (bottom - top) as f64) as u32;
        let (mut extra, mut truth_px) = (0usize, 0usize);
        for y in from..t.height() {
            for x in 0..t.width() {
                let (a, b) = (t.get_pixel(x, y)[0] > 127, r.get_pixel(x, y)[0] > 127);
                truth_px += a as usize;
                extra += (b && !a) as usize;
            }
        }
        shares.push(extra as f64 / truth_px.max(1) as f64);
    }
    shares.iter().sum::<f64>() / shares.len().max(1) as f64
}

/// The side view's floor between the two feet lies in the person's own shadow, inside
/// the network's blur of the feet: fused, it joined the feet into one block (library
/// subject `synth-set --first-seed 20250 --count 12`, subject 6: a third of the feet
/// band's true area added, 0.338, and side IoU 0.949 on this short recording; 0.018 and
/// 0.975 with the rule). On the shadow zone the floor's shadow now stays floor unless its
/// column hangs from the person.
#[test]
fn the_floor_between_the_feet_stays_floor_in_the_side_view() {
    let dir = tmp("feet");
    let rec = member_recording(&dir, "feet", (20250, 6, SET_COUNT), None);
    let run = replay(&rec, true, ViewSet::Both, &dir.join("masks"));
    let truth = load_truth(&truth_dir(&rec)).expect("truth");
    let share = feet_false_share(&truth_dir(&rec), &dir.join("masks"), &truth);
    println!(
        "fitted {}, IoU front {:.3} side {:.3}, feet band false share {share:.3}",
        run.fitted, run.iou_front, run.iou_side
    );
    assert_eq!(
        run.fitted, SUBJECT_FRAMES as u64,
        "{}",
        run.report["messages"]
    );
    assert!(share <= 0.15, "feet band false share {share:.3}");
    assert!(run.iou_side >= 0.965, "IoU side {:.3}", run.iou_side);
    let _ = std::fs::remove_dir_all(&dir);
}

/// White leggings on a pale wall (`synth-set --first-seed 59300 --count 12
/// --camouflage`, subject 7; found in session 24's look at session 23's judgement): the
/// backdrop model lost the subject's right leg from mid-thigh to the knee, and the lower
/// leg it still saw became a piece of its own whose foot stands on the floor row of the
/// other foot. The piece's box then spanned the body's lowest row, so it was taken as
/// lying beside the body, not below it, and never walked up its columns to the thigh:
/// the whole lower leg was dropped (front IoU 0.885 over the full recording). The
/// direction is now read in the piece's own columns (the body only above it: walk up).
#[test]
fn a_lower_leg_cut_off_at_the_knee_is_joined_to_the_body() {
    let dir = tmp("pieces-leg");
    let rec = member_recording(
        &dir,
        "white_leggings",
        (59300, 7, SET_COUNT),
        Some(Clothing::Camouflage),
    );
    assert_fitted_whole(&rec, &dir, "white leggings", 0.94);
    let _ = std::fs::remove_dir_all(&dir);
}

/// Dark green trousers on a dark green wall, and a green shirt (`synth-set --first-seed
/// 59300 --count 12 --camouflage`, subjects 11 and 1; found in session 24's look at
/// session 23's judgement). The selfie network, made for a face and shoulders near the
/// camera, gave the side view's legs of subject 11 a probability near nothing (its mask's
/// IoU 0.40 on the last frame; the side view was given up and the subject measured from
/// the front alone) and blurred subject 1's legs together (0.66); the pose network's mask,
/// made for a whole body, holds both (0.95). It is now the person prior of both views.
#[test]
fn the_whole_body_network_keeps_legs_of_the_walls_colour() {
    let dir = tmp("pose-prior");
    for (member, min_front, min_side) in [(11, 0.97, 0.95), (1, 0.97, 0.95)] {
        let rec = member_recording(
            &dir,
            &format!("camo_{member}"),
            (59300, member, SET_COUNT),
            Some(Clothing::Camouflage),
        );
        let r = replay(
            &rec,
            true,
            ViewSet::Both,
            &dir.join(format!("masks_{member}")),
        );
        println!(
            "camouflage {member}: fitted {}, IoU front {:.3} side {:.3}, chest {:?} mm; frames {}; messages {}",
            r.fitted, r.iou_front, r.iou_side, r.chest_error_mm, r.report["frames"], r.report["messages"]
        );
        assert_eq!(r.fitted, SUBJECT_FRAMES as u64, "{}", r.report["messages"]);
        assert_eq!(
            r.report["frames"]["fitted_front_only"].as_u64(),
            Some(0),
            "measured from the front alone: {}",
            r.report["messages"]
        );
        assert!(
            r.iou_front >= min_front && r.iou_side >= min_side,
            "subject {member}: IoU front {:.3}, side {:.3}",
            r.iou_front,
            r.iou_side
        );
        // The side view's arms come from the same run of the pose network.
        let t = &r.report["timings_ms"];
        assert!(t.get("person_mask").is_some(), "{t}");
        assert!(
            t.get("side_limbs").is_none(),
            "the pose network ran twice: {t}"
        );
    }
    let _ = std::fs::remove_dir_all(&dir);
}
