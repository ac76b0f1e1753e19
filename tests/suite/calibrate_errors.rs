//! Bad calibration input gives messages that tell the operator what to do next
//! (issue 7): too few views, views too similar, blurred frames, duplicates, a board
//! that is not there. Small rendered frames keep this fast.

use fitstation::calibrate::board::BoardSpec;
use fitstation::calibrate::corners::CornerDetector;
use fitstation::calibrate::intrinsics::{
    calibrate_intrinsics, CameraViews, ViewInput, ViewOutcome,
};
use fitstation::calibrate::render::{rigs, Background, BoardRenderer, RenderOptions};
use fitstation::calibrate::{CalibError, Progress};
use fitstation::camera::{Intrinsics, Rigid};
use glam::{DMat3, DVec3};

fn camera() -> Intrinsics {
    Intrinsics {
        width: 640,
        height: 480,
        fx: 560.0,
        fy: 560.0,
        cx: 322.0,
        cy: 238.0,
        dist: [-0.08, 0.02, 0.0, 0.0, 0.0],
    }
}

fn board() -> BoardSpec {
    BoardSpec {
        cols: 7,
        rows: 5,
        square_m: 0.04,
    }
}

fn views(poses: &[Rigid], opts: &RenderOptions) -> CameraViews {
    let mut r = BoardRenderer::new(camera());
    let mut d = CornerDetector::new();
    let views = poses
        .iter()
        .enumerate()
        .map(|(i, p)| {
            let img = r.render(
                &board(),
                p,
                Background::Wall,
                &RenderOptions {
                    seed: i as u64 + 1,
                    ..*opts
                },
            );
            ViewInput {
                name: format!("img_{i}.png"),
                detection: d.detect(&img, &board()),
            }
        })
        .collect();
    CameraViews {
        camera: "front".into(),
        width: camera().width,
        height: camera().height,
        views,
    }
}

fn calibrate(v: &CameraViews) -> Result<fitstation::calibrate::IntrinsicsCalibration, CalibError> {
    calibrate_intrinsics(v, &board(), &mut |_: &Progress| {})
}

#[test]
fn too_few_views_say_how_many_more_and_how() {
    let poses = rigs::handheld_poses(&board(), &camera(), 3, 5);
    let e = calibrate(&views(&poses, &RenderOptions::default()))
        .unwrap_err()
        .to_string();
    println!("{e}");
    assert!(
        e.contains("only 3 usable board views") && e.contains("Take 10-15 photos"),
        "{e}"
    );
}

#[test]
fn parallel_views_are_too_similar() {
    // Five views, all facing the camera squarely, only moved sideways.
    let c = board().grid_centre();
    let poses: Vec<Rigid> = (0..5)
        .map(|k| {
            let rot = DMat3::from_rotation_z(0.02 * k as f64);
            Rigid {
                rotation: rot,
                translation: DVec3::new(-0.06 + 0.03 * k as f64, -0.02, 0.7)
                    - rot * DVec3::new(c.x, c.y, 0.0),
            }
        })
        .collect();
    let e = calibrate(&views(&poses, &RenderOptions::default())).unwrap_err();
    println!("{e}");
    assert!(matches!(e, CalibError::TooSimilarViews { .. }), "{e}");
    assert!(e.to_string().contains("Tilt the board"));
}

#[test]
fn blurred_frames_are_dropped_with_the_reason() {
    let poses = rigs::handheld_poses(&board(), &camera(), 5, 9);
    let sharp = views(&poses, &RenderOptions::default());
    let blurred = views(
        &poses[..3],
        &RenderOptions {
            blur_sigma_px: 4.0,
            ..RenderOptions::default()
        },
    );
    // Two sharp views and three blurred ones: not enough.
    let mut mixed = sharp.clone();
    mixed.views.truncate(2);
    mixed.views.extend(blurred.views.iter().cloned());
    let e = calibrate(&mixed).unwrap_err().to_string();
    println!("{e}");
    assert!(
        e.contains("blurred 3") || e.contains("looks blurred"),
        "{e}"
    );
    // With all five sharp views it works, and a blurred extra view is reported as such.
    let mut ok = sharp.clone();
    ok.views.push(blurred.views[0].clone());
    let cal = calibrate(&ok).unwrap_or_else(|e| panic!("{e}"));
    println!("{cal}");
    assert!(matches!(
        cal.views[5].outcome,
        ViewOutcome::Blurred { .. } | ViewOutcome::NotFound(_)
    ));
    assert_eq!(cal.used_views, 5);
    assert!(cal.to_string().contains("blurred"), "{cal}");
}

#[test]
fn duplicates_and_empty_frames_are_named() {
    let poses = rigs::handheld_poses(&board(), &camera(), 5, 13);
    let mut v = views(&poses, &RenderOptions::default());
    let dup = ViewInput {
        name: "again.png".into(),
        detection: v.views[1].detection.clone(),
    };
    v.views.push(dup);
    let wall = image::GrayImage::from_pixel(640, 480, image::Luma([170]));
    let none = CornerDetector::new().detect(&wall, &board());
    v.views.push(ViewInput {
        name: "wall.png".into(),
        detection: none,
    });
    let cal = calibrate(&v).unwrap_or_else(|e| panic!("{e}"));
    let text = cal.to_string();
    println!("{text}");
    assert!(matches!(&cal.views[5].outcome, ViewOutcome::Duplicate { of } if of == "img_1.png"));
    assert!(
        matches!(&cal.views[6].outcome, ViewOutcome::NotFound(m) if m.contains("board not found"))
    );
    assert!(text.contains("same as img_1.png"));
}

#[test]
fn a_bad_view_is_flagged_as_outlier_and_dropped() {
    let poses = rigs::handheld_poses(&board(), &camera(), 7, 21);
    let mut v = views(&poses, &RenderOptions::default());
    let clean = calibrate(&v).unwrap_or_else(|e| panic!("{e}"));
    // Corrupt one view as a bent or moving board would: corners off by ~1.5 px.
    let mut rng = fitstation::calibrate::render::SplitMix64(4);
    if let Ok(d) = &mut v.views[3].detection {
        for c in &mut d.corners {
            c.x += 1.5 * rng.gaussian();
            c.y += 1.5 * rng.gaussian();
        }
    }
    let cal = calibrate(&v).unwrap_or_else(|e| panic!("{e}"));
    println!("{cal}");
    assert!(
        matches!(cal.views[3].outcome, ViewOutcome::Outlier { rms_px } if rms_px > 1.0),
        "{cal}"
    );
    assert_eq!(cal.used_views, 6);
    // Dropping it restores the clean result.
    assert!((cal.intrinsics.fx - clean.intrinsics.fx).abs() / clean.intrinsics.fx < 0.002);
    assert!(cal.rms_px < 2.0 * clean.rms_px + 0.01);
}

#[test]
fn live_session_accepts_new_sharp_views_only() {
    use fitstation::calibrate::intrinsics::{FrameOutcome, LensSession};
    let poses = rigs::handheld_poses(&board(), &camera(), 6, 31);
    let mut r = BoardRenderer::new(camera());
    let mut s = LensSession::new("front", board(), 640, 480);
    let render = |r: &mut BoardRenderer, p: &Rigid, blur: f64| {
        r.render(
            &board(),
            p,
            Background::Wall,
            &RenderOptions {
                blur_sigma_px: blur,
                ..RenderOptions::default()
            },
        )
    };
    let first = render(&mut r, &poses[0], 0.6);
    assert_eq!(s.add_frame("f0", &first).outcome, FrameOutcome::Accepted);
    // The same pose again, a blurred frame, an empty frame, a frame of another size.
    assert!(
        matches!(s.add_frame("f0b", &first).outcome, FrameOutcome::TooSimilar { ref to } if to == "f0")
    );
    assert!(matches!(
        s.add_frame("blur", &render(&mut r, &poses[1], 4.0)).outcome,
        FrameOutcome::Blurred { .. }
    ));
    let wall = image::GrayImage::from_pixel(640, 480, image::Luma([170]));
    assert!(matches!(
        s.add_frame("wall", &wall).outcome,
        FrameOutcome::NotFound(_)
    ));
    assert!(matches!(
        s.add_frame("small", &image::GrayImage::new(320, 240))
            .outcome,
        FrameOutcome::WrongSize { .. }
    ));
    for (i, p) in poses.iter().enumerate().skip(1) {
        let fb = s.add_frame(&format!("f{i}"), &render(&mut r, p, 0.6));
        assert_eq!(fb.outcome, FrameOutcome::Accepted, "pose {i}");
        assert_eq!(fb.corners.len(), board().corner_count());
    }
    let cal = s
        .calibrate(&mut |_: &Progress| {})
        .unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(cal.used_views, 6);
    assert!((cal.intrinsics.fx / camera().fx - 1.0).abs() < 0.005);
}
