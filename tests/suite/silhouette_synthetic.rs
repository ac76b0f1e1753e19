//! Segmentation and landmarks on phantom frames through a distorting station: mask IoU
//! against the rendered ground truth (noise, flicker, shadow at the feet) and landmark
//! heights against the phantom's exact landmarks.

use crate::silhouette_common;

use fitstation::camera::View;
use fitstation::landmarks::phantom::{Phantom, PhantomParams, SceneParams};
use fitstation::landmarks::{LandmarkName, Status, Verdict};
use glam::DVec3;
use silhouette_common::*;

/// Required mask IoU on synthetic frames (the target). Measured 0.995-0.997 in
/// both views; before the column bridging asked for foreground outside the shadow zone
/// above a bridge (segment module docs), the side view also took the shadowed floor
/// between the far and the near foot (IoU 0.974-0.978).
const MIN_IOU: f64 = 0.98;
/// Required landmark height accuracy, metres (issue 4 target).
const MAX_HEIGHT_ERR_M: f64 = 0.010;

/// A closed gap (here a ring held against the side of the trunk, in the segmentation's
/// terms the backdrop seen between an arm and the trunk) stays open in the output mask,
/// whose outer border is the sub-pixel contour's.
#[test]
fn the_backdrop_seen_through_a_closed_gap_stays_out_of_the_mask() {
    let mut ex = learned_executor(2);
    let mut p = render(std::slice::from_ref(&subject()), SceneParams::default());
    let truth = &p.side_truth;
    // The trunk's front edge at mid-height of the side view.
    let y = (0..truth.height)
        .filter(|&y| (0..truth.width).any(|x| truth.get(x as i64, y as i64)))
        .map(|y| y as i64)
        .collect::<Vec<_>>();
    let yc = (y[0] + y[y.len() - 1]) / 2;
    let x_front = (0..truth.width as i64)
        .find(|&x| truth.get(x, yc))
        .expect("trunk");
    // A 40 px square ring, 6 px thick, ending inside the trunk: its inside (28 px) shows
    // the backdrop and is enclosed by the ring and the trunk.
    let (x0, x1, y0, y1) = (x_front - 36, x_front + 4, yc - 20, yc + 20);
    for yy in y0..y1 {
        for xx in x0..x1 {
            let ring = xx < x0 + 6 || yy < y0 + 6 || yy >= y1 - 6;
            if ring {
                p.side
                    .put_pixel(xx as u32, yy as u32, image::Rgb([200, 40, 40]));
            }
        }
    }
    let r = ex.process(&p.front, &p.side).expect("process");
    let m = &r.masks.side;
    let inside = (x0 + 8..x_front - 2)
        .flat_map(|xx| (y0 + 8..y1 - 8).map(move |yy| (xx, yy)))
        // Two pixels clear of the trunk's edge (the border itself is re-tested per pixel).
        .filter(|&(xx, yy)| !(xx..=xx + 2).any(|x| truth.get(x, yy)))
        .collect::<Vec<_>>();
    assert!(
        inside.len() > 300,
        "{} backdrop pixels in the gap",
        inside.len()
    );
    let wrong = inside.iter().filter(|&&(xx, yy)| m.get(xx, yy)).count();
    assert_eq!(
        wrong,
        0,
        "{wrong} of {} gap pixels in the mask",
        inside.len()
    );
    // The ring itself is the person's.
    assert!(m.get(x0 + 3, yc) && m.get(x0 + 20, y0 + 3) && m.get(x0 + 20, y1 - 3));
    // And without the ring's closure the frame is as before: the trunk edge is kept.
    assert!(m.get(x_front + 3, yc));
}

#[test]
fn masks_match_ground_truth_under_noise_and_flicker() {
    let mut ex = learned_executor(4);
    let body = subject();
    let mut worst = 1.0f64;
    // Exposure flicker of a few percent between frames, fresh noise each frame.
    for (k, gain) in [1.0, 1.04, 0.96, 1.02].into_iter().enumerate() {
        let p = render(
            std::slice::from_ref(&body),
            SceneParams {
                gain,
                seed: 7 + k as u64,
                ..Default::default()
            },
        );
        let r = ex.process(&p.front, &p.side).expect("process");
        let (fi, si) = (
            r.masks.front.iou(&p.front_truth),
            r.masks.side.iou(&p.side_truth),
        );
        println!(
            "frame {k} gain {gain}: IoU front {fi:.4} side {si:.4}; verdicts {:?}",
            r.landmarks.verdicts
        );
        worst = worst.min(fi).min(si);
        // SILHOUETTE_PHANTOM_DUMP=dir keeps the side frame, our mask and the truth.
        if let Some(d) = std::env::var_os("SILHOUETTE_PHANTOM_DUMP") {
            let d = std::path::PathBuf::from(d);
            let _ = std::fs::create_dir_all(&d);
            p.side.save(d.join(format!("{k}_side.png"))).expect("save");
            for (name, m) in [("ours", &r.masks.side), ("truth", &p.side_truth)] {
                image::GrayImage::from_raw(m.width, m.height, m.data.clone())
                    .expect("mask")
                    .save(d.join(format!("{k}_side_{name}.png")))
                    .expect("save");
            }
        }
    }
    println!("worst IoU {worst:.4}");
    assert!(worst > MIN_IOU, "worst IoU {worst}");
}

fn check_landmarks(params: PhantomParams, label: &str) {
    let mut ex = learned_executor(4);
    let body = Phantom::new(params);
    let truth = body.truth();
    let p = render(
        std::slice::from_ref(&body),
        SceneParams {
            seed: 31,
            ..Default::default()
        },
    );
    let r = ex.process(&p.front, &p.side).expect("process");
    let lm = &r.landmarks;
    println!(
        "{label}: verdicts {:?}, timings {:?}",
        lm.verdicts, r.timings
    );
    println!(
        "{label}: stature {:.4} (truth {:.4})",
        lm.stature_m, truth.stature
    );
    let expect = [
        (LandmarkName::Crotch, truth.crotch.expect("crotch truth")),
        (
            LandmarkName::ArmpitLeft,
            truth.armpit_left.expect("armpit truth"),
        ),
        (
            LandmarkName::ArmpitRight,
            truth.armpit_right.expect("armpit truth"),
        ),
        (LandmarkName::AcromionLeft, truth.acromion_left),
        (LandmarkName::AcromionRight, truth.acromion_right),
    ];
    let mut worst = 0.0f64;
    for (name, t) in expect {
        let got = lm
            .get(name)
            .unwrap_or_else(|| panic!("{label}: {} missing", name.as_str()))
            .station;
        let dy = got.y - t.y;
        println!(
            "{label}: {:<15} y {:.4} truth {:.4} (err {:+.1} mm), x {:+.4} truth {:+.4}, z {:+.4}",
            name.as_str(),
            got.y,
            t.y,
            dy * 1e3,
            got.x,
            t.x,
            got.z
        );
        worst = worst.max(dy.abs());
    }
    assert!(
        worst < MAX_HEIGHT_ERR_M,
        "{label}: worst landmark height error {:.1} mm",
        worst * 1e3
    );
    // Depth: the phantom's trunk is centred on z = offset.z.
    let c = lm.get(LandmarkName::Crotch).unwrap().station;
    assert!(
        (c.z - params.offset.z).abs() < 0.03,
        "{label}: crotch z {}",
        c.z
    );
    assert!(
        (c.x - params.offset.x).abs() < 0.01,
        "{label}: crotch x {}",
        c.x
    );
    // The stature within a centimetre (the rim seen from below the head top is lower).
    assert!(
        (lm.stature_m - truth.stature).abs() < 0.012,
        "{label}: stature {}",
        lm.stature_m
    );
    assert!(!lm
        .verdicts
        .iter()
        .any(|v| matches!(v, Verdict::ArmsTouchingTorso { .. } | Verdict::LegsTogether)));
    // Joints: every one of both tables is there, in plausible places.
    for name in [
        LandmarkName::Hip,
        LandmarkName::Waist,
        LandmarkName::Chest,
        LandmarkName::Neck,
        LandmarkName::KneeLeft,
        LandmarkName::KneeRight,
        LandmarkName::AnkleLeft,
        LandmarkName::ElbowLeft,
        LandmarkName::ElbowRight,
        LandmarkName::WristLeft,
        LandmarkName::ShoulderLeft,
        LandmarkName::ShoulderRight,
        LandmarkName::HandRight,
    ] {
        let j = lm
            .get(name)
            .unwrap_or_else(|| panic!("{label}: joint {} missing", name.as_str()));
        assert!(j.front_px.is_some() && j.side_px.is_some());
        // Joints lie inside the body's silhouette in the front view.
        let px = j.front_px.unwrap();
        assert!(
            ex.target(View::Front).contains(px),
            "{label}: {} at {px} is outside the mask",
            name.as_str()
        );
    }
    // Left limbs on the +X side.
    for (l, rr) in [
        (LandmarkName::ElbowLeft, LandmarkName::ElbowRight),
        (LandmarkName::KneeLeft, LandmarkName::KneeRight),
    ] {
        assert!(lm.get(l).unwrap().station.x > lm.get(rr).unwrap().station.x);
    }
    // Parts: all five front parts with both statuses, and front/back side parts.
    for name in ["torso", "left_arm", "right_arm", "left_leg", "right_leg"] {
        for st in [Status::Left, Status::Right] {
            assert!(
                r.front
                    .parts
                    .iter()
                    .any(|p| p.name == name && p.status == st),
                "{label}: no {name} {st:?}"
            );
        }
    }
    for st in [Status::Front, Status::Back] {
        assert!(r
            .side
            .parts
            .iter()
            .any(|p| p.name == "side_torso" && p.status == st));
    }
    // Limb-axis correction: knee, elbow and wrist joints lie on the limb's axis (front
    // plane), whatever the limb's angle.
    for (side, knee, elbow, wrist) in [
        (
            1.0,
            LandmarkName::KneeLeft,
            LandmarkName::ElbowLeft,
            LandmarkName::WristLeft,
        ),
        (
            -1.0,
            LandmarkName::KneeRight,
            LandmarkName::ElbowRight,
            LandmarkName::WristRight,
        ),
    ] {
        let (arm, leg) = body.limb_axes(side);
        for (name, axes) in [(knee, &leg), (elbow, &arm), (wrist, &arm)] {
            let j = lm.get(name).unwrap().station;
            let d = axes
                .iter()
                .map(|&(a, b)| dist_to_segment_xy(j, a, b))
                .fold(f64::INFINITY, f64::min);
            println!(
                "{label}: {:<12} ({:+.4}, {:.4}) is {:.1} mm off the limb axis",
                name.as_str(),
                j.x,
                j.y,
                d * 1e3
            );
            assert!(
                d < MAX_AXIS_OFFSET_M,
                "{label}: {} is {:.1} mm off the limb axis",
                name.as_str(),
                d * 1e3
            );
        }
    }
}

/// Joints from cuts may sit this far from the limb's axis (front plane), metres.
const MAX_AXIS_OFFSET_M: f64 = 0.008;

fn dist_to_segment_xy(p: DVec3, a: DVec3, b: DVec3) -> f64 {
    let (p, a, b) = (
        glam::DVec2::new(p.x, p.y),
        glam::DVec2::new(a.x, a.y),
        glam::DVec2::new(b.x, b.y),
    );
    let t = ((p - a).dot(b - a) / (b - a).length_squared()).clamp(0.0, 1.0);
    (a + (b - a) * t).distance(p)
}

#[test]
fn landmark_heights_match_the_phantom() {
    check_landmarks(PhantomParams::default(), "default");
}

#[test]
fn landmark_heights_with_raised_arms_and_wide_legs() {
    check_landmarks(
        PhantomParams {
            arm_abduction_deg: 42.0,
            leg_spread_m: 0.12,
            offset: DVec3::new(0.03, 0.0, -0.04),
            ..Default::default()
        },
        "wide",
    );
}
