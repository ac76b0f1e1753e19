//! Unit tests of the segmentation: shadows, bridges, exposure, holes and the edge score.

use super::*;
use crate::imgproc::MASK_ON;

/// An image whose pixel (x, y) is `colour(x, y, r)`, with `r` from a xorshift
/// sequence seeded by `seed` (the noise).
fn painted(
    w: u32,
    h: u32,
    seed: u32,
    mut colour: impl FnMut(u32, u32, u32) -> [u8; 3],
) -> RgbImage {
    let mut img = RgbImage::new(w, h);
    let mut s = seed.wrapping_mul(2654435761).wrapping_add(1);
    for (x, y, p) in img.enumerate_pixels_mut() {
        s ^= s << 13;
        s ^= s >> 17;
        s ^= s << 5;
        p.0 = colour(x, y, s);
    }
    img
}

/// A shadow zone of the rows from `y0` down (the floor's image).
fn zone_from_row(w: u32, h: u32, y0: u32) -> Mask {
    let mut zone = Mask::new(w, h);
    zone.data[(y0 * w) as usize..].fill(255);
    zone
}

fn scene(w: u32, h: u32, person: bool, shadow: bool, seed: u32) -> RgbImage {
    painted(w, h, seed, |x, y, s| {
        let n = (s % 7) as i32 - 3;
        let base = 150 + ((x / 8 + y / 8) % 2) as i32 * 20;
        let mut c = [base + n, base + 5 + n, base - 10 + n];
        if shadow && y > 80 && (30..90).contains(&x) {
            c = c.map(|v| v * 7 / 10);
        }
        if person && (40..70).contains(&x) && (20..90).contains(&y) {
            c = [200 + n, 120 + n, 90 + n];
        }
        c.map(|v| v.clamp(0, 255) as u8)
    })
}

#[test]
fn person_is_found_and_shadow_is_not() {
    let (w, h) = (120, 100);
    let mut m = BackgroundModel::new(w, h, SegmentOptions::default());
    for k in 0..5 {
        m.learn(&scene(w, h, false, false, k)).unwrap();
    }
    let mut mask = Mask::new(1, 1);
    let st = m.segment(&scene(w, h, true, true, 99), &mut mask).unwrap();
    let mut truth = Mask::new(w, h);
    for y in 20..90 {
        for x in 40..70 {
            truth.data[(y * w + x) as usize] = 255;
        }
    }
    let iou = mask.iou(&truth);
    assert!(iou > 0.97, "iou {iou}");
    assert_eq!(st.large_components, 1);
    assert_eq!(st.person_px, mask.area());
    assert!(!st.touches.bottom);
}

fn scaled(img: &RgbImage, gain: f32) -> RgbImage {
    let mut out = img.clone();
    for p in out.pixels_mut() {
        p.0 =
            p.0.map(|v| (v as f32 * gain).round().clamp(0.0, 255.0) as u8);
    }
    out
}

#[test]
fn the_model_follows_a_slow_light_drift_where_nobody_is() {
    let (w, h) = (120, 100);
    let opts = SegmentOptions {
        adapt_rate: 1.0,
        ..Default::default()
    };
    let mut adaptive = BackgroundModel::new(w, h, opts);
    let mut fixed = BackgroundModel::new(
        w,
        h,
        SegmentOptions {
            adapt_rate: 0.0,
            ..opts
        },
    );
    let empty = scene(w, h, false, false, 3);
    adaptive.learn(&empty).unwrap();
    fixed.learn(&empty).unwrap();
    let mut mask = Mask::new(1, 1);
    // Light rising in steps each within the brightness tolerance, a full sweep of
    // the adaptation's rows per step.
    for gain in [1.1f32, 1.2, 1.3, 1.4, 1.5] {
        for _ in 0..ADAPT_ROW_STRIDE {
            adaptive.segment(&scaled(&empty, gain), &mut mask).unwrap();
        }
    }
    let bright = scaled(&scene(w, h, true, false, 4), 1.5);
    let st = adaptive.segment(&bright, &mut mask).unwrap();
    let box_ = st.person_box.unwrap();
    assert!(
        box_.min_x >= 36 && box_.max_x <= 74 && box_.min_y >= 16 && box_.max_y <= 94,
        "{box_:?}"
    );
    // Without adaptation the whole brighter frame is foreground.
    let st = fixed.segment(&bright, &mut mask).unwrap();
    assert!(st.person_px > (w * h) as u64 / 2, "{}", st.person_px);
}

#[test]
fn darker_same_hue_is_shadow_only_inside_the_shadow_zone() {
    let (w, h) = (120, 100);
    let empty = scene(w, h, false, false, 5);
    // A "person" of the backdrop's own hue at 70 % of its brightness.
    let mut frame = scene(w, h, false, false, 6);
    for y in 20..90 {
        for x in 40..70 {
            let p = frame.get_pixel_mut(x, y);
            p.0 = p.0.map(|v| (v as u32 * 7 / 10) as u8);
        }
    }
    let mut mask = Mask::new(1, 1);
    let mut m = BackgroundModel::new(w, h, SegmentOptions::default());
    m.learn(&empty).unwrap();
    // Whole frame zone (no calibration): explained as a cast shadow.
    assert_eq!(m.segment(&frame, &mut mask).unwrap().person_px, 0);
    // Zone on the bottom rows only (the floor): the figure is found, a shadow on the
    // floor rows is not.
    m.set_shadow_zone(&zone_from_row(w, h, 85)).unwrap();
    let st = m.segment(&frame, &mut mask).unwrap();
    let b = st.person_box.unwrap();
    assert!(
        b.min_y <= 22 && b.max_y >= 84 && b.min_x <= 42 && b.max_x >= 68,
        "{b:?}"
    );
    assert!(matches!(
        m.set_shadow_zone(&Mask::new(3, 3)),
        Err(SegmentError::ZoneSize { .. })
    ));
}

#[test]
fn a_dark_shoe_of_the_floors_hue_is_not_taken_for_its_shadow() {
    // A brown floor; a shadow at 60 % of its brightness; a shoe at the same brightness
    // whose colour is turned by 11 levels across the floor's (a greyer brown): within
    // the noise radius (14) at full brightness, beyond it at 60 % (8.4).
    let (w, h) = (120, 100);
    let floor = [150.0f32, 115.0, 80.0];
    let across = [-1.0f32, 0.5, 1.2]; // nearly orthogonal to the floor's colour
    let n = across.iter().map(|v| v * v).sum::<f32>().sqrt();
    let shoe = [0, 1, 2].map(|c| 0.6 * floor[c] + 11.0 * across[c] / n);
    // The floor with rectangles (columns, rows, colour) painted over it, plus noise.
    type Patch = (std::ops::Range<u32>, std::ops::Range<u32>, [f32; 3]);
    let paint = |seed: u32, patches: &[Patch]| {
        painted(w, h, seed, |x, y, s| {
            let n = (s % 5) as f32 - 2.0;
            let c = patches
                .iter()
                .find(|(xs, ys, _)| xs.contains(&x) && ys.contains(&y))
                .map_or(floor, |p| p.2);
            c.map(|v| (v + n).round().clamp(0.0, 255.0) as u8)
        })
    };
    let mut m = BackgroundModel::new(w, h, SegmentOptions::default());
    for k in 0..5 {
        m.learn(&paint(k, &[])).unwrap();
    }
    let mut mask = Mask::new(1, 1);
    // Whole frame zone (no calibration): a shadow may fall anywhere.
    let shadow = floor.map(|v| 0.6 * v);
    let frame = paint(9, &[(10..50, 40..70, shoe), (70..110, 40..70, shadow)]);
    let st = m.segment(&frame, &mut mask).unwrap();
    let b = st.person_box.expect("the shoe is found");
    assert!(
        b.min_x <= 12 && b.max_x >= 48 && b.min_y <= 42 && b.max_y >= 68 && b.max_x <= 54,
        "{b:?}"
    );
    let shoe_px = 40 * 30;
    assert!(
        st.person_px.abs_diff(shoe_px) < shoe_px / 20,
        "{} pixels for a shoe of {shoe_px}",
        st.person_px
    );
    // Outside the shadow zone only the exposure varies and the tolerance stays the
    // full noise radius: a patch at 90 % brightness turned by 12.8 levels (beyond
    // the angle's 12.6, within the radius's 14) is backdrop there, not person.
    let dim = [0, 1, 2].map(|c| 0.9 * floor[c] + 12.8 * across[c] / n);
    let frame = paint(11, &[(30..90, 20..60, dim)]);
    m.set_shadow_zone(&zone_from_row(w, h, 90)).unwrap();
    let st = m.segment(&frame, &mut mask).unwrap();
    assert_eq!(st.person_px, 0, "{:?}", st.person_box);
}

#[test]
fn weak_cells_are_bridged_only_between_foreground_cells_of_their_column() {
    const F: u8 = MASK_ON;
    const W: u8 = WEAK;
    // Columns: a leg (thigh, shin of the floor's hue, shoe); the floor seen between
    // the legs (ends in lit floor); a shadow beside the feet (nothing above).
    #[rustfmt::skip]
    let mut c = vec![
        F, F, 0,
        W, W, 0,
        W, W, W,
        F, 0, W,
        0, 0, F,
    ];
    let (mut top, mut anchored) = (Vec::new(), Vec::new());
    let zone = vec![1; 15];
    bridge_columns(&mut c, &zone, 3, 5, true, &mut top, &mut anchored);
    #[rustfmt::skip]
    let want = vec![
        F, F, 0,
        BRIDGED, W, 0,
        BRIDGED, W, W,
        F, 0, W,
        0, 0, F,
    ];
    assert_eq!(c, want);
}

#[test]
fn a_bridge_needs_foreground_outside_the_shadow_zone_above_it() {
    const F: u8 = MASK_ON;
    const W: u8 = WEAK;
    // Columns: a shin of the floor's hue under a thigh seen against the backdrop
    // (row 0 is outside the zone); the shadowed floor of a side view between the far
    // foot (row 2, in the zone, lit floor above it) and the near foot (row 4).
    #[rustfmt::skip]
    let cells = vec![
        F, 0,
        W, 0,
        F, F,
        W, W,
        F, F,
    ];
    #[rustfmt::skip]
    let zone = vec![
        0, 0,
        1, 1,
        1, 1,
        1, 1,
        1, 1,
    ];
    let (mut top, mut anchored) = (Vec::new(), Vec::new());
    let mut c = cells.clone();
    bridge_columns(&mut c, &zone, 2, 5, false, &mut top, &mut anchored);
    #[rustfmt::skip]
    let want = vec![
        F, 0,
        BRIDGED, 0,
        F, F,
        BRIDGED, W,
        F, F,
    ];
    assert_eq!(c, want);
    // Without a calibration (zone everywhere) both columns are bridged.
    let mut c = cells;
    bridge_columns(&mut c, &[1; 10], 2, 5, true, &mut top, &mut anchored);
    assert_eq!(c[2 * 3 + 1], BRIDGED);
}

/// A far foot joined to the near leg by a shaded heel: the coarse test samples the
/// heel's lit pixels (foreground), the full-resolution band sees mostly shadow-like
/// pixels between them. In the shadow zone the cell's changed pixels stay body, so the
/// mask stays one piece.
#[test]
fn a_shaded_heel_does_not_cut_the_foot_off_in_the_shadow_zone() {
    let (w, h) = (96u32, 90u32);
    let back = |x: u32, y: u32| -> [i32; 3] {
        let n = ((x * 7 + y * 13) % 5) as i32 - 2;
        [140 + n, 136 + n, 128 + n]
    };
    let frame = |person: bool| {
        RgbImage::from_fn(w, h, |x, y| {
            let mut c = back(x, y);
            if person {
                let leg = (60..68).contains(&x) && (10..80).contains(&y);
                let foot = (20..52).contains(&x) && (70..80).contains(&y);
                let heel = (52..60).contains(&x) && (74..78).contains(&y);
                if leg || foot || (heel && x % 2 == 0 && y % 2 == 0) {
                    c = [40, 50, 150];
                } else if heel {
                    c = c.map(|v| v * 7 / 10);
                }
            }
            image::Rgb(c.map(|v| v.clamp(0, 255) as u8))
        })
    };
    let mut m = BackgroundModel::new(w, h, SegmentOptions::default());
    for _ in 0..3 {
        m.learn(&frame(false)).unwrap();
    }
    // The floor (rows 60 and below) is the shadow zone.
    m.set_shadow_zone(&zone_from_row(w, h, 60)).unwrap();
    let mut mask = Mask::new(1, 1);
    m.segment(&frame(true), &mut mask).unwrap();
    let mut runs = RunComponents::default();
    runs.compute(&mask.data, w, h, true, true);
    assert_eq!(runs.components.len(), 1, "the foot is cut off");
    assert!(mask.get(30, 75), "the foot is lost");
    assert!(mask.get(55, 76), "the heel is not body");
}

#[test]
fn the_edge_score_is_linear_in_the_covered_fraction() {
    let back = [200u8, 180, 160];
    let mut m = BackgroundModel::new(4, 4, SegmentOptions::default());
    m.learn(&RgbImage::from_pixel(4, 4, image::Rgb(back)))
        .expect("learn");
    // Pixels covering a black person by 0, 1/4, 1/2 and 1: the lens mixes in linear
    // light, the camera encodes the mixture.
    let lut = srgb_to_linear();
    let encode = |l: f32| {
        let l = (l / 255.0).clamp(0.0, 1.0);
        let e = if l <= 0.0031308 {
            12.92 * l
        } else {
            1.055 * l.powf(1.0 / 2.4) - 0.055
        };
        (255.0 * e).round() as u8
    };
    let mut frame = RgbImage::from_pixel(4, 4, image::Rgb(back));
    for (x, f) in [0.0f32, 0.25, 0.5, 1.0].into_iter().enumerate() {
        let px = back.map(|v| encode((1.0 - f) * lut[v as usize]));
        frame.put_pixel(x as u32, 0, image::Rgb(px));
    }
    let s = m.edge_scorer(&frame).expect("same size");
    let full = s.score(3, 0);
    assert!(full > 100.0, "{full}");
    assert!(s.score(0, 0) < 1.0);
    for (x, f) in [(1, 0.25f32), (2, 0.5)] {
        let got = s.score(x, 0) / full;
        assert!((got - f).abs() < 0.02, "coverage {f}: score fraction {got}");
    }
    // In encoded levels the half-covered pixel would read as much less than half.
    let enc = |x: u32| {
        let p = frame.get_pixel(x, 0).0;
        (0..3)
            .map(|c| (p[c] as f32 - back[c] as f32).powi(2))
            .sum::<f32>()
            .sqrt()
    };
    assert!(enc(2) / enc(3) < 0.35, "{}", enc(2) / enc(3));
    // A frame of another size has no score.
    assert!(m.edge_scorer(&RgbImage::new(3, 4)).is_none());
}

#[test]
fn coarse_rows_are_gathered_whole_and_odd() {
    for w in [1usize, 2, 3, 7, 8, 9, 13, 16, 17, 33] {
        let row: Vec<u8> = (0..3 * w).map(|k| (k * 37 % 251) as u8).collect();
        let mut got = vec![0u32; w.div_ceil(2)];
        gather_coarse_row(&row, &mut got);
        let want: Vec<u32> = (0..w.div_ceil(2))
            .map(|k| {
                let i = 6 * k;
                u32::from_le_bytes([row[i], row[i + 1], row[i + 2], 0])
            })
            .collect();
        assert_eq!(got, want, "width {w}");
    }
}

#[test]
fn the_frame_exposure_is_divided_out() {
    // The exposure drops by 10 % when the person steps in; the person wears the
    // backdrop's colour a third brighter than it. Against the unscaled model the
    // person is 1.2 times the backdrop (inside the highlight tolerance, so nothing is
    // found); against the model at the frame's exposure it is 1.33 times.
    let (w, h) = (120, 100);
    let empty = scene(w, h, false, false, 7);
    let mut frame = scaled(&scene(w, h, false, false, 8), 0.9);
    for y in 20..90 {
        for x in 40..70 {
            let e = empty.get_pixel(x, y).0;
            frame.put_pixel(x, y, image::Rgb(e.map(|v| (v as f32 * 1.2) as u8)));
        }
    }
    let mut m = BackgroundModel::new(w, h, SegmentOptions::default());
    m.learn(&empty).unwrap();
    let mut mask = Mask::new(1, 1);
    let st = m.segment(&frame, &mut mask).unwrap();
    assert!((st.gain - 0.9).abs() < 0.02, "gain {}", st.gain);
    let b = st.person_box.expect("person");
    assert!(
        b.min_x >= 38 && b.max_x <= 72 && b.min_y >= 18 && b.max_y <= 92,
        "{b:?}"
    );
    assert!(st.person_px > 30 * 70 * 9 / 10, "{}", st.person_px);
    // The same frame at the model's exposure: the gain is 1 and the person, 1.2 times
    // the backdrop, is within the exposure tolerance.
    let mut m = BackgroundModel::new(w, h, SegmentOptions::default());
    m.learn(&empty).unwrap();
    let st = m.segment(&scaled(&frame, 1.0 / 0.9), &mut mask).unwrap();
    assert!((st.gain - 1.0).abs() < 0.02, "gain {}", st.gain);
}

#[test]
fn empty_scene_gives_no_person() {
    let (w, h) = (120, 100);
    let mut m = BackgroundModel::new(w, h, SegmentOptions::default());
    m.learn(&scene(w, h, false, false, 1)).unwrap();
    let mut mask = Mask::new(1, 1);
    let st = m.segment(&scene(w, h, false, true, 2), &mut mask).unwrap();
    assert_eq!(st.person_px, 0);
    assert!(matches!(
        BackgroundModel::new(w, h, SegmentOptions::default())
            .segment(&scene(w, h, false, false, 1), &mut mask),
        Err(SegmentError::NotReady)
    ));
}

/// A floor mark the camera clips in one channel (saturated yellow, as the synthetic
/// station's tape): a shadow over it keeps the clipped red near the top while green and
/// blue fall, which no shadow does to an unclipped colour. It is not the person; a person
/// standing on it still is.
#[test]
fn a_shadow_on_a_clipped_floor_mark_is_no_person() {
    let (w, h) = (120, 100);
    let mark = |x: u32, y: u32| (30..90).contains(&x) && (84..96).contains(&y);
    let frame = |shadow: bool, person: bool, seed: u32| {
        painted(w, h, seed, move |x, y, s| {
            let n = (s % 5) as i32 - 2;
            let mut c = [150 + n, 155 + n, 140 + n];
            if mark(x, y) {
                // Red clipped: the tape's true red lies above 255.
                c = [255, 237 + n, 53 + n];
                if shadow {
                    c = [242 + n, 200 + n, 46 + n];
                }
            } else if shadow && y >= 80 {
                c = c.map(|v| v * 85 / 100);
            }
            if person && (50..70).contains(&x) && (10..92).contains(&y) {
                c = [60 + n, 90 + n, 200 + n];
            }
            c.map(|v| v.clamp(0, 255) as u8)
        })
    };
    let mut m = BackgroundModel::new(w, h, SegmentOptions::default());
    for k in 0..5 {
        m.learn(&frame(false, false, k)).unwrap();
    }
    m.set_shadow_zone(&zone_from_row(w, h, 80)).unwrap();
    let mut mask = Mask::new(1, 1);
    let st = m.segment(&frame(true, false, 50), &mut mask).unwrap();
    assert_eq!(st.person_px, 0, "the shadowed mark was taken for a person");
    m.segment(&frame(true, true, 51), &mut mask).unwrap();
    let mut truth = Mask::new(w, h);
    for y in 10..92 {
        for x in 50..70 {
            truth.data[(y * w + x) as usize] = 255;
        }
    }
    let iou = mask.iou(&truth);
    assert!(iou > 0.95, "iou {iou}");
}

#[test]
fn only_a_clipped_channel_beside_unclipped_ones_is_left_out() {
    use super::classify::unclipped_weights;
    assert_eq!(unclipped_weights(255, 237, 53), [0, 1, 1]);
    assert_eq!(unclipped_weights(254, 254, 10), [0, 0, 1]);
    assert_eq!(unclipped_weights(255, 255, 255), [1, 1, 1]);
    assert_eq!(unclipped_weights(120, 130, 253), [1, 1, 1]);
}

/// A tall person at `x0..x0 + 40` (none without `x0`) and, with `walker`, a second figure
/// at the frame's far right, on a noisy two-tone backdrop.
fn sampled_scene(x0: Option<u32>, walker: bool, seed: u32) -> RgbImage {
    painted(400, 300, seed, |x, y, s| {
        let n = (s % 7) as i32 - 3;
        let base = 140 + ((x / 16 + y / 16) % 2) as i32 * 25;
        let mut c = [base + n, base + 4 + n, base - 8 + n];
        if x0.is_some_and(|x0| (x0..x0 + 40).contains(&x)) && (40..260).contains(&y) {
            c = [60 + n, 90 + n, 170 + n];
        }
        if walker && (320..370).contains(&x) && (90..200).contains(&y) {
            c = [210 + n, 100 + n, 60 + n];
        }
        c.map(|v| v.clamp(0, 255) as u8)
    })
}

#[test]
fn sampling_away_from_the_person_labels_what_the_full_test_does() {
    let full_opts = SegmentOptions {
        sample_outside_person: false,
        ..Default::default()
    };
    let mut sampled = BackgroundModel::new(400, 300, SegmentOptions::default());
    let mut full = BackgroundModel::new(400, 300, full_opts);
    for k in 0..4 {
        let empty = sampled_scene(None, false, k);
        sampled.learn(&empty).unwrap();
        full.learn(&empty).unwrap();
    }
    let (mut ms, mut mf) = (Mask::new(1, 1), Mask::new(1, 1));
    let cells = 200 * 150;
    // The first frame with a person is tested in full; then the frame is sampled away
    // from the last box, while a second figure walks in at the far right and the person
    // steps further than the margin about the last box (16 cells, 32 px).
    let frames = [
        (60, false),
        (60, false),
        (60, true),
        (130, true),
        (130, false),
    ];
    for (k, &(x0, walker)) in frames.iter().enumerate() {
        let frame = sampled_scene(Some(x0), walker, 100 + k as u32);
        let a = sampled.segment(&frame, &mut ms).unwrap();
        let b = full.segment(&frame, &mut mf).unwrap();
        assert!(ms.data == mf.data, "frame {k}: the masks differ");
        assert_eq!(a.large_components, b.large_components, "frame {k}");
        assert_eq!(a.second_px, b.second_px, "frame {k}");
        assert_eq!(a.person_box, b.person_box, "frame {k}");
        assert_eq!(b.tested_cells, cells);
        if k == 0 {
            assert_eq!(a.tested_cells, cells, "no last box: every cell");
        } else {
            assert!(
                a.tested_cells < cells / 2,
                "frame {k}: {} cells",
                a.tested_cells
            );
        }
        // The exposure is estimated from the samples away from the person.
        assert!(
            (a.exposure.mean_luma - b.exposure.mean_luma).abs() < 2.0,
            "frame {k}"
        );
        if walker {
            assert_eq!(a.large_components, 2, "frame {k}: the walker is seen");
        }
    }
}
