//! No pocket where the arms meet the trunk (issue 19, item 4).
//!
//! Session 25's varied judgement subject 21 (`synth-set --first-seed 62100 --population
//! ansur --stance varied`, member 21, a man holding his arms in) was reported with a chest
//! 300 mm too large. Pose synchronisation had turned the arms toward the body and lifted
//! each armpit's apex 2.5-3 mm above all its neighbours: sliced just under it, the avatar
//! showed a small closed loop (110 and 124 mm) between arm and trunk, large enough for the
//! spec's arm test, so the armpit was put there, where the arms still joined the trunk,
//! and the chest under it took both arms in (1588 mm against the truth's 1106). Replayed
//! through its first five subject frames, the station's chest is now the trunk's.

use crate::common;

use fitstation::recording::FrameFormat;
use fitstation::station::StationOptions;
use fitstation::synth::{load_truth, render_recording, truth_dir};

#[test]
fn arms_held_in_leave_no_pocket_that_the_chest_takes_for_the_armpit() {
    let dir = common::tmp_dir("armpit", "varied21");
    let mut cfg = fitstation::synth::ansur_member(&common::ansur_table(), 62100, 21);
    cfg.subject.stance = Some(fitstation::synth::stance::Stance::sample(cfg.seed));
    cfg.subject_frames = 5;
    cfg.format = FrameFormat::Png;
    let rec = dir.join("rec");
    render_recording(&cfg, &rec).expect("render");

    let truth = load_truth(&truth_dir(&rec)).expect("truth");
    let true_chest = truth.measurements_mm["chest_girth"];
    // The fit as it is, and with the edges read at the control vertices' depth (the fit
    // the pocket was found on, session 26's; with the rims' depth this stance no longer
    // lifts the armpits' apexes, and the flood has nothing to do).
    for rim_depth in [true, false] {
        let mut opts = StationOptions::default();
        opts.fit.rim_depth = rim_depth;
        let report = &common::replay_report_with(&rec, opts);
        assert_eq!(report["frames"]["fitted"].as_u64(), Some(5), "{report}");
        // Every frame's chest (the series), not only the reported one: with the pocket
        // each was 470-480 mm over the truth.
        let series = common::series(report, "chest_girth");
        assert_eq!(series.len(), 5, "{report}");
        for c in &series {
            assert!(
                (c - true_chest).abs() < 60.0,
                "rim depth {rim_depth}: chest {c:.0} mm against the truth's {true_chest:.0}: {series:?}"
            );
        }
        if !rim_depth {
            // The fit says it brought the armpits' peaks down (this stance made them).
            assert!(
                report["fit"]["armpit_peaks"]
                    .as_u64()
                    .is_some_and(|n| n > 0),
                "this stance is the one whose armpits peak: {}",
                report["fit"]
            );
        }
    }
}
