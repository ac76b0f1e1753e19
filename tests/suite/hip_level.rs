//! The hip where the back is flat (issue 19, item 3: the girth from the person, not from a
//! draw of the avatar's surface).
//!
//! Session 26's ansur judgement subject 22 (`synth-set --first-seed 63000 --population
//! ansur`, member 22, a woman) was reported with a hip 112 mm too large. The spec's hip
//! level is where the torso reaches furthest back; her back lies within 3 mm of its
//! furthest point from 1.5 cm above the crotch to 12 cm above it, under a pixel of the
//! side camera at the subject (3.8 mm), and her girth falls by 120 mm over that stretch.
//! The avatar's back, fitted to the side view, reached its furthest 2.8 mm lower than
//! elsewhere on the stretch, at the thighs' tops, and the girth there was reported. The
//! station now reports the avatar's girths over the levels that may be the person's
//! furthest back, each by its chance (`station::uncertainty::hip_girth_over_levels_mm`).

use crate::common;

use fitstation::recording::FrameFormat;
use fitstation::synth::{load_truth, render_recording, truth_dir};

#[test]
fn a_back_flat_over_centimetres_does_not_put_the_hip_on_the_thighs_tops() {
    let dir = common::tmp_dir("hip", "ansur22");
    let mut cfg = fitstation::synth::ansur_member(&common::ansur_table(), 63000, 22);
    cfg.subject_frames = 5;
    cfg.format = FrameFormat::Png;
    let rec = dir.join("rec");
    render_recording(&cfg, &rec).expect("render");

    let report = common::replay_report(&rec);
    let truth = load_truth(&truth_dir(&rec)).expect("truth");
    assert_eq!(report["frames"]["fitted"].as_u64(), Some(5), "{report}");
    let true_hip = truth.measurements_mm["hip_girth"];
    let series = common::series(&report, "hip_girth");
    assert_eq!(series.len(), 5, "{report}");
    eprintln!("hip series {series:?} against the truth's {true_hip:.0}");
    for h in &series {
        assert!(
            (h - true_hip).abs() < 60.0,
            "hip {h:.0} mm against the truth's {true_hip:.0}: {series:?}"
        );
    }
}
