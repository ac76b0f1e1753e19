//! Issue 19, item 4: a small turn of the shopper on the mark must not move any girth by
//! more than a few millimetres. The same synthetic subject (same body, clothing, cameras,
//! light, sway) is rendered standing square and turned on the mark, both recordings are
//! replayed through the station, and the reported girths are compared with each other
//! (not with the truth: the turn alone must not move them).
//!
//! Girths of a horizontal section do not depend on a yaw (the spec's convex hulls), so any
//! change comes from the station: silhouettes seen at another angle, correspondences,
//! the level search.

use fitstation::recording::FrameFormat;
use fitstation::synth::stance::Stance;
use fitstation::synth::{render_recording, set_member};
use std::path::{Path, PathBuf};

/// A dev-range library subject (seeds 20000+ are the development range; never a
/// judgement seed).
const FIRST_SEED: u64 = 20400;
const MEMBER: usize = 3;
const SET_COUNT: usize = 12;
const SUBJECT_FRAMES: usize = 6;
/// The turns, degrees, either way: issue 19's varied stances turn by up to 4.
const TURNS_DEG: [f64; 2] = [4.0, -4.0];
/// "A few millimetres" (issue 19, item 4), per girth.
const MAX_CHANGE_MM: f64 = 6.0;

use crate::common;

fn tmp(name: &str) -> common::TempDir {
    common::tmp_dir("turn", name)
}

/// Renders the subject turned by `yaw_deg` (arms, elbows and legs at rest) into `dir`.
fn render(dir: &Path, yaw_deg: f64) -> PathBuf {
    let rec = dir.join(format!("yaw{yaw_deg}"));
    let mut cfg = set_member(FIRST_SEED, MEMBER, SET_COUNT);
    cfg.subject.stance = Some(Stance::turned(yaw_deg));
    cfg.empty_frames = 10;
    cfg.subject_frames = SUBJECT_FRAMES;
    cfg.format = FrameFormat::Png;
    render_recording(&cfg, &rec).expect("render");
    rec
}

/// The station's reported girths (mm) for a recording.
fn girths(rec: &Path) -> serde_json::Map<String, serde_json::Value> {
    common::replay_report(rec)["measurements_mm"]
        .as_object()
        .cloned()
        .expect("the subject is fitted and measured")
}

/// Fails today, by a little. Measured 2026-11-26, before the fit had a turn: chest +23.7,
/// waist +8.9, hip +1.4, thighs +14.4 / +13.1 mm for a turn of +4 degrees. Measured
/// 2026-11-28 with the candidate turned by what the side view's toes show (`fit::turn`;
/// read as 0.15 and 3.87 degrees, the truth 0.3 and 4.3), the avatar turned back before
/// the candidate is chosen again on it and the sections mapped in the body's own axes:
/// +4 degrees chest +3.8, waist -1.8, hip -0.7, thighs +5.7 / -0.8 (within); -4 degrees
/// chest +4.2, waist -0.7, hip -2.8, thighs +0.3 / -7.0 (the right thigh 1 mm over).
/// After cb867af (the toes' scans walk in half-pixel steps, the turns read on the
/// development sets no worse) another candidate is chosen: +4 degrees chest +2.4, waist
/// -0.2, hip -6.0, thighs -11.6 / +4.3; -4 degrees chest -1.8, waist +2.7, hip -3.0,
/// thighs -5.0 / -6.1. Run with `cargo test --release --test suite turn_on_the_mark:: --
/// --ignored`.
#[test]
#[ignore = "issue 19 item 4 not met yet: a +4 degree turn moves the left thigh by -11.6 mm, -4 the right thigh by -6.1"]
fn a_small_turn_on_the_mark_moves_no_girth_more_than_a_few_millimetres() {
    let dir = tmp("girths");
    let square = girths(&render(&dir, 0.0));
    let mut worst = (0.0f64, String::new(), 0.0f64);
    for turn in TURNS_DEG {
        let turned = girths(&render(&dir, turn));
        for key in common::GIRTHS {
            let a = square[key].as_f64().expect("girth");
            let b = turned[key].as_f64().expect("girth");
            eprintln!(
                "{key}: square {a:.1} mm, turned {turn} deg {b:.1} mm, change {:+.1}",
                b - a
            );
            if (b - a).abs() > worst.2.abs() {
                worst = (turn, key.to_string(), b - a);
            }
        }
    }
    assert!(
        worst.2.abs() <= MAX_CHANGE_MM,
        "a {} degree turn moved {} by {:+.1} mm",
        worst.0,
        worst.1,
        worst.2
    );
}
