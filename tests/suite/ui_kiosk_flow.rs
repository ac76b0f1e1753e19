//! Every screen of the shopper's kiosk flow is reached replaying the bundled recording
//! through the real station processing: a visit scripted from `recordings/demo`
//! (`fitstation demo-ui --recording recordings/demo` shows the same on screen) is run
//! frame by frame on the recording's clock, and the flow must go learning the backdrop ->
//! empty scene -> pose guidance (feet cut off) -> hold still -> result card -> cleared by
//! the idle timeout back to the empty scene.

use fitstation::app::flow::{FlowConfig, FlowState};
use fitstation::app::session::{trace_kiosk, SessionSource};
use fitstation::pipeline::FrameSource;
use fitstation::station::default_library;
use fitstation::station::{StationOptions, StationProcessor, MEASUREMENT_KEYS};

fn kind(s: &FlowState) -> &'static str {
    match s {
        FlowState::LearningBackdrop => "learning",
        FlowState::EmptyScene => "empty",
        FlowState::Guiding { .. } => "guiding",
        FlowState::HoldStill { .. } => "hold",
        FlowState::Result { .. } => "result",
    }
}

#[test]
fn every_kiosk_state_is_reached_replaying_the_demo_recording() {
    let rec = concat!(env!("CARGO_MANIFEST_DIR"), "/recordings/demo");
    // Short timings keep the test quick; the script scales with them.
    let cfg = FlowConfig {
        countdown_s: 1.0,
        idle_timeout_s: 2.0,
        result_display_s: 30.0,
        settle_timeout_s: 1.0,
    };
    let opts = StationOptions::default();
    let mut source = SessionSource::open(std::path::Path::new(rec), &cfg, opts.backdrop_frames)
        .unwrap_or_else(|e| panic!("{e}"));
    let pairs = source.len();
    let cal = source.calibration().cloned().expect("calibration");
    let library = default_library().expect("shape library");
    let mut station = StationProcessor::new(cal, library, opts).expect("station");
    let trace = trace_kiosk(&mut source, &mut station, cfg, pairs);
    assert_eq!(trace.len(), pairs);

    let mut visited: Vec<&str> = Vec::new();
    for s in &trace {
        let k = kind(&s.state);
        if visited.last() != Some(&k) {
            visited.push(k);
        }
    }
    println!("states: {visited:?}");
    assert_eq!(
        visited,
        ["learning", "empty", "guiding", "hold", "result", "empty"],
        "the visit did not go through every screen in order"
    );

    // Pose guidance came from the frame verdicts about the cut-off feet.
    let guiding = trace
        .iter()
        .find(|s| matches!(s.state, FlowState::Guiding { .. }))
        .expect("guidance");
    println!("guidance: {:?}", guiding.messages);
    assert!(
        guiding
            .messages
            .iter()
            .any(|m| m.contains("cut off") && m.contains("bottom")),
        "{:?}",
        guiding.messages
    );
    let FlowState::Guiding { message } = &guiding.state else {
        unreachable!()
    };
    assert_eq!(Some(message), guiding.messages.first());

    // The result card holds every measurement, after at least the countdown.
    let (hold_start, result) = {
        let h = trace
            .iter()
            .find(|s| matches!(s.state, FlowState::HoldStill { .. }))
            .expect("hold");
        let r = trace
            .iter()
            .find(|s| matches!(s.state, FlowState::Result { .. }))
            .expect("result");
        (h.time_s, r)
    };
    assert!(result.time_s - hold_start >= cfg.countdown_s);
    assert!(result.time_s - hold_start <= cfg.countdown_s + cfg.settle_timeout_s + 0.1);
    let FlowState::Result { card, .. } = &result.state else {
        unreachable!()
    };
    let names: Vec<&str> = card.measurements.iter().map(|m| m.name.as_str()).collect();
    assert_eq!(names, MEASUREMENT_KEYS, "{card:?}");
    let stature = card.measurements[0].value_mm;
    assert!(
        (1000.0..2400.0).contains(&stature),
        "stature {stature} mm on the card"
    );

    // The privacy clear: once, at least the idle timeout after the shopper was last seen,
    // and the station forgot the shopper.
    let cleared: Vec<_> = trace.iter().filter(|s| s.cleared).collect();
    assert_eq!(cleared.len(), 1, "{cleared:?}");
    let last_seen = trace
        .iter()
        .take_while(|s| !s.cleared)
        .filter(|s| !matches!(s.state, FlowState::EmptyScene))
        .map(|s| s.time_s)
        .fold(f64::MIN, f64::max);
    assert!(cleared[0].time_s >= cfg.idle_timeout_s);
    assert!(cleared[0].time_s > last_seen);
    assert_eq!(cleared[0].state, FlowState::EmptyScene);
    assert!(station.avatar().is_none(), "the avatar survived the clear");
    assert!(station.measurements().is_empty());
}
