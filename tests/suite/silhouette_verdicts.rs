//! Every frame verdict is exercised by a frame that should trigger it and by frames that
//! should not (the good A-pose frame, and near misses).

use crate::silhouette_common;

use fitstation::camera::View;
use fitstation::imgproc::Mask;
use fitstation::landmarks::phantom::{Phantom, PhantomParams, SceneParams};
use fitstation::landmarks::{FrameEdge, Verdict};
use fitstation::silhouette::{SilhouetteExecutor, SilhouetteOptions, SilhouetteResult};
use glam::DVec3;
use image::RgbImage;
use silhouette_common::*;

fn run(people: &[Phantom], scene: SceneParams) -> SilhouetteResult {
    let mut ex = learned_executor(2);
    let p = render(people, scene);
    ex.process(&p.front, &p.side).expect("process")
}

fn has(r: &SilhouetteResult, f: impl Fn(&Verdict) -> bool) -> bool {
    r.landmarks.verdicts.iter().any(f)
}

fn scene(seed: u64) -> SceneParams {
    SceneParams {
        seed,
        ..Default::default()
    }
}

#[test]
fn a_good_frame_has_no_verdict() {
    let r = run(&[subject()], scene(11));
    assert!(
        r.landmarks.verdicts.is_empty(),
        "{:?}",
        r.landmarks.verdicts
    );
    assert!(r.landmarks.stature_m > 1.6);
}

#[test]
fn an_empty_scene_has_no_person() {
    let r = run(
        &[],
        SceneParams {
            shadow: false,
            ..scene(12)
        },
    );
    assert!(
        has(&r, |v| matches!(v, Verdict::NoPerson)),
        "{:?}",
        r.landmarks.verdicts
    );
    assert!(r.landmarks.points.is_empty());
}

#[test]
fn a_second_person_behind_is_seen() {
    let other = Phantom::new(PhantomParams {
        offset: DVec3::new(-1.2, 0.0, -0.6),
        scale: 0.95,
        arm_abduction_deg: 15.0,
        ..Default::default()
    });
    let r = run(&[subject(), other], scene(13));
    assert!(
        has(&r, |v| matches!(v, Verdict::MultiplePeople)),
        "{:?}",
        r.landmarks.verdicts
    );
}

#[test]
fn a_tall_subject_is_cut_off_at_the_top() {
    let tall = Phantom::new(PhantomParams {
        scale: 1.3,
        ..Default::default()
    });
    let r = run(&[tall], scene(14));
    assert!(
        has(&r, |v| matches!(
            v,
            Verdict::CutOff {
                view: View::Front,
                edge: FrameEdge::Top
            }
        )),
        "{:?}",
        r.landmarks.verdicts
    );
    assert!(!has(&r, |v| matches!(
        v,
        Verdict::CutOff {
            edge: FrameEdge::Bottom,
            ..
        }
    )));
}

#[test]
fn arms_against_the_body_are_reported_and_a_narrow_gap_is_not() {
    let down = Phantom::new(PhantomParams {
        arm_abduction_deg: 0.0,
        ..Default::default()
    });
    let r = run(&[down], scene(15));
    assert!(
        has(&r, |v| matches!(
            v,
            Verdict::ArmsTouchingTorso {
                left: true,
                right: true
            }
        )),
        "{:?}",
        r.landmarks.verdicts
    );
    let narrow = Phantom::new(PhantomParams {
        arm_abduction_deg: 16.0,
        ..Default::default()
    });
    let r = run(&[narrow], scene(16));
    assert!(
        !has(&r, |v| matches!(v, Verdict::ArmsTouchingTorso { .. })),
        "{:?}",
        r.landmarks.verdicts
    );
}

#[test]
fn legs_together_are_reported_and_slightly_apart_are_not() {
    let together = Phantom::new(PhantomParams {
        leg_spread_m: 0.0,
        hip_half_m: 0.06,
        ..Default::default()
    });
    let r = run(&[together], scene(17));
    assert!(
        has(&r, |v| matches!(v, Verdict::LegsTogether)),
        "{:?}",
        r.landmarks.verdicts
    );
    let apart = Phantom::new(PhantomParams {
        leg_spread_m: 0.0,
        hip_half_m: 0.085,
        ..Default::default()
    });
    let r = run(&[apart], scene(18));
    assert!(
        !has(&r, |v| matches!(v, Verdict::LegsTogether)),
        "{:?}",
        r.landmarks.verdicts
    );
}

#[test]
fn exposure_verdicts() {
    let r = run(
        &[subject()],
        SceneParams {
            gain: 0.15,
            ..scene(19)
        },
    );
    assert!(
        has(&r, |v| matches!(v, Verdict::UnderExposed { .. })),
        "{:?}",
        r.landmarks.verdicts
    );
    assert!(!has(&r, |v| matches!(v, Verdict::OverExposed { .. })));
    let r = run(
        &[subject()],
        SceneParams {
            gain: 2.2,
            ..scene(20)
        },
    );
    assert!(
        has(&r, |v| matches!(v, Verdict::OverExposed { .. })),
        "{:?}",
        r.landmarks.verdicts
    );
    assert!(!has(&r, |v| matches!(v, Verdict::UnderExposed { .. })));
    // A dimmer light within the model's tolerance is not a verdict.
    let r = run(
        &[subject()],
        SceneParams {
            gain: 0.9,
            ..scene(21)
        },
    );
    assert!(
        !has(&r, |v| matches!(
            v,
            Verdict::UnderExposed { .. } | Verdict::OverExposed { .. }
        )),
        "{:?}",
        r.landmarks.verdicts
    );
}

#[test]
fn off_the_mark_is_measured_and_near_the_mark_is_fine() {
    let off = Phantom::new(PhantomParams {
        offset: DVec3::new(0.06, 0.0, 0.14),
        ..Default::default()
    });
    let feet_z = off.feet_centre_z().expect("the phantom has feet");
    let r = run(&[off], scene(22));
    let v = r.landmarks.verdicts.iter().find_map(|v| match v {
        Verdict::OffMark { dx_m, dz_m } => Some((*dx_m, *dz_m)),
        _ => None,
    });
    let (dx, dz) = v.unwrap_or_else(|| panic!("no OffMark in {:?}", r.landmarks.verdicts));
    // x from the crotch, z from the feet (what stands on the mark; the phantom's feet
    // reach forward of its axis like a person's).
    assert!(feet_z > 0.14, "{feet_z}");
    assert!(
        (dx - 0.06).abs() < 0.02 && (dz - feet_z).abs() < 0.02,
        "dx {dx} dz {dz} (feet {feet_z})"
    );
    let near = Phantom::new(PhantomParams {
        offset: DVec3::new(0.03, 0.0, -0.04),
        ..Default::default()
    });
    let r = run(&[near], scene(23));
    assert!(
        !has(&r, |v| matches!(v, Verdict::OffMark { .. })),
        "{:?}",
        r.landmarks.verdicts
    );
}

#[test]
fn a_trunk_side_of_the_backdrop_colour_is_reported_and_a_whole_trunk_is_not() {
    use fitstation::landmarks::LandmarkName;
    let mut ex = learned_executor(2);
    let p = render(&[subject()], scene(17));
    let good = ex.process(&p.front, &p.side).expect("process");
    assert!(
        good.landmarks.trunk_asymmetry.is_some_and(|a| a < 0.05),
        "{:?}",
        good.landmarks.trunk_asymmetry
    );
    assert!(!has(&good, |v| matches!(
        v,
        Verdict::BlendsIntoBackdrop { .. }
    )));
    // Paint the outer 40 % of one half of the trunk, between the crotch and the armpits,
    // with the empty backdrop: clothing that matches it exactly there.
    let (crotch, armpit) = (
        good.front.landmark(LandmarkName::Crotch).expect("crotch"),
        good.front
            .landmark(LandmarkName::ArmpitLeft)
            .expect("armpit"),
    );
    let empty = &empty_cached(0).front;
    let mask = &good.masks.front;
    let mut front = p.front.clone();
    let axis = crotch.x.round() as i64;
    for y in armpit.y.round() as u32..crotch.y.round() as u32 {
        // The trunk run around the axis in this row.
        let (mut x0, mut x1) = (axis, axis);
        while mask.get(x0 - 1, y as i64) {
            x0 -= 1;
        }
        while mask.get(x1 + 1, y as i64) {
            x1 += 1;
        }
        let cut = axis + (x1 - axis) * 6 / 10;
        for x in cut..=x1 + 2 {
            front.put_pixel(x as u32, y, *empty.get_pixel(x as u32, y));
        }
    }
    let r = ex.process(&front, &p.side).expect("process");
    assert!(
        has(&r, |v| matches!(
            v,
            Verdict::BlendsIntoBackdrop { view: View::Front }
        )),
        "asymmetry {:?}, verdicts {:?}",
        r.landmarks.trunk_asymmetry,
        r.landmarks.verdicts
    );
}

/// `img` with every pixel outside `person` (all of them without one) painted `level`
/// plus a little sensor noise: a white or black studio backdrop.
fn paint_backdrop(img: &RgbImage, person: Option<&Mask>, level: u8, seed: u64) -> RgbImage {
    let mut out = img.clone();
    let mut state = seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1;
    for (x, y, p) in out.enumerate_pixels_mut() {
        if person.is_some_and(|m| m.get(x as i64, y as i64)) {
            continue;
        }
        for c in p.0.iter_mut() {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            let noise = (state % 7) as i32 - 3;
            *c = (level as i32 + noise).clamp(0, 255) as u8;
        }
    }
    out
}

/// The exposure verdicts compare a frame with the learned empty scene: a backdrop that is
/// itself white (mostly clipped) or black (mostly crushed) is the scene, not a fault, and
/// the subject in front of it is fitted; the same white scene with its light at 15% is
/// under-exposed.
#[test]
fn a_white_or_black_backdrop_is_not_an_exposure_fault() {
    let exposure = |v: &Verdict| {
        matches!(
            v,
            Verdict::UnderExposed { .. } | Verdict::OverExposed { .. }
        )
    };
    for level in [255u8, 0] {
        let mut ex = SilhouetteExecutor::new(&rig().calib, SilhouetteOptions::default());
        for k in 0..2u64 {
            let e = empty_cached(k as usize);
            ex.learn_background(
                &paint_backdrop(&e.front, None, level, k),
                &paint_backdrop(&e.side, None, level, k + 7),
            )
            .expect("learn");
        }
        let p = render(&[subject()], scene(31));
        let front = paint_backdrop(&p.front, Some(&p.front_truth), level, 40);
        let side = paint_backdrop(&p.side, Some(&p.side_truth), level, 41);
        let r = ex.process(&front, &side).expect("process");
        assert!(
            !r.landmarks
                .verdicts
                .iter()
                .any(|v| exposure(v) || v.blocks_fit()),
            "backdrop {level}: {:?}",
            r.landmarks.verdicts
        );
        assert!(r.masks.front.iou(&p.front_truth) > 0.95);
        if level == 255 {
            let dim = |img: &RgbImage| {
                let mut d = img.clone();
                d.pixels_mut()
                    .for_each(|p| p.0 = p.0.map(|c| (c as f32 * 0.15) as u8));
                d
            };
            let r = ex.process(&dim(&front), &dim(&side)).expect("process");
            assert!(
                has(&r, |v| matches!(v, Verdict::UnderExposed { .. })),
                "{:?}",
                r.landmarks.verdicts
            );
        }
    }
}
