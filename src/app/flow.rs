//! The shopper's kiosk flow as a pure state machine, driven by fit snapshots and time.
//!
//! Screens, in order: learning the backdrop -> empty scene ("step onto the mark") ->
//! pose guidance (the frame verdicts of [`FitSnapshot::messages`]) -> a hold-still
//! countdown -> the result card. Privacy: when nobody has been on the mark for
//! [`FlowConfig::idle_timeout_s`], or the result card has been up for
//! [`FlowConfig::result_display_s`], everything about the shopper is cleared
//! ([`FlowAction::ClearSubject`]): the card, the avatar, the processor's subject state.
//!
//! Times are seconds on one monotonic clock chosen by the caller (the screen uses the
//! time since start); nothing here reads a clock, so every transition is unit-tested.

use crate::pipeline::{FitSnapshot, MeasurementValue, Phase};

/// Timing of the kiosk flow (seconds).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FlowConfig {
    /// Length of the hold-still countdown.
    pub countdown_s: f64,
    /// Nobody on the mark for this long clears the shopper's data.
    pub idle_timeout_s: f64,
    /// The result card stays at most this long, then is cleared.
    pub result_display_s: f64,
    /// After the countdown, the longest wait for the measurements to settle; then the
    /// card shows the current (median) values with their spread instead of keeping the
    /// shopper holding still for ever.
    pub settle_timeout_s: f64,
}

/// Default countdown: long enough to read, short enough to hold an A-pose.
pub const DEFAULT_COUNTDOWN_S: f64 = 3.0;
/// Default idle timeout after the shopper steps off.
pub const DEFAULT_IDLE_TIMEOUT_S: f64 = 10.0;
/// Default longest time a result card is shown.
pub const DEFAULT_RESULT_DISPLAY_S: f64 = 45.0;
/// Default longest wait for settled measurements after the countdown.
pub const DEFAULT_SETTLE_TIMEOUT_S: f64 = 4.0;

impl Default for FlowConfig {
    fn default() -> Self {
        FlowConfig {
            countdown_s: DEFAULT_COUNTDOWN_S,
            idle_timeout_s: DEFAULT_IDLE_TIMEOUT_S,
            result_display_s: DEFAULT_RESULT_DISPLAY_S,
            settle_timeout_s: DEFAULT_SETTLE_TIMEOUT_S,
        }
    }
}

/// The screen the shopper sees.
#[derive(Debug, Clone, PartialEq)]
pub enum FlowState {
    /// The station is learning the empty backdrop: keep the scene empty.
    LearningBackdrop,
    /// Backdrop known, nobody on the mark: "step onto the mark".
    EmptyScene,
    /// Somebody is seen but the pose needs correcting; `message` is the top verdict.
    Guiding { message: String },
    /// A good pose: counting down while the fit settles.
    HoldStill { started_s: f64 },
    /// The measurements, frozen when the countdown ended on settled values.
    Result { card: ResultCard, shown_s: f64 },
}

/// What the result card shows (values frozen at the moment it was taken).
#[derive(Debug, Clone, PartialEq)]
pub struct ResultCard {
    pub measurements: Vec<MeasurementValue>,
    pub frame_index: u64,
    /// The measurements had settled (false: shown after the settle timeout, with
    /// their spread).
    pub settled: bool,
}

/// Something the caller must do after a transition.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FlowAction {
    /// Forget the shopper: clear the card, the avatar, the processor's subject state.
    ClearSubject,
}

/// What one snapshot tells the flow (the parts of a [`FitSnapshot`] it reads).
#[derive(Debug, Clone, PartialEq)]
pub struct FlowInput<'a> {
    pub phase: Phase,
    pub messages: &'a [String],
    pub measurements: &'a [MeasurementValue],
    pub frame_index: u64,
}

impl<'a> FlowInput<'a> {
    pub fn from_snapshot(s: &'a FitSnapshot) -> Self {
        FlowInput {
            phase: s.phase,
            messages: &s.messages,
            measurements: &s.measurements,
            frame_index: s.frame_index,
        }
    }
}

/// The kiosk flow: current state plus the time the subject was last seen.
#[derive(Debug, Clone)]
pub struct KioskFlow {
    config: FlowConfig,
    state: FlowState,
    /// Last time a snapshot showed somebody on the mark (None: not since the last clear).
    subject_seen_s: Option<f64>,
}

/// Shown while the pose is wrong but the processor said nothing specific.
pub const DEFAULT_GUIDANCE: &str = "Stand on the mark, arms slightly away from the body";

impl KioskFlow {
    pub fn new(config: FlowConfig) -> Self {
        KioskFlow {
            config,
            state: FlowState::LearningBackdrop,
            subject_seen_s: None,
        }
    }

    pub fn state(&self) -> &FlowState {
        &self.state
    }

    pub fn config(&self) -> &FlowConfig {
        &self.config
    }

    /// Seconds left in the hold-still countdown (0 when over or not counting).
    pub fn countdown_left_s(&self, now_s: f64) -> f64 {
        match self.state {
            FlowState::HoldStill { started_s } => {
                (self.config.countdown_s - (now_s - started_s)).max(0.0)
            }
            _ => 0.0,
        }
    }

    /// Feeds one snapshot observed at `now_s`.
    pub fn on_snapshot(&mut self, input: &FlowInput<'_>, now_s: f64) -> Option<FlowAction> {
        let subject = matches!(
            input.phase,
            Phase::Guiding | Phase::Fitting | Phase::Settled
        );
        if subject {
            self.subject_seen_s = Some(now_s);
        }
        let next = match (&self.state, input.phase) {
            // The backdrop is being (re)learnt: nothing else can happen meanwhile.
            (FlowState::Result { .. }, Phase::LearningBackdrop) => {
                self.clear(FlowState::LearningBackdrop);
                return Some(FlowAction::ClearSubject);
            }
            (_, Phase::LearningBackdrop) => FlowState::LearningBackdrop,
            // The result card stays while the shopper looks at it; leaving is handled by
            // the idle timeout below.
            (FlowState::Result { .. }, _) => self.state.clone(),
            (FlowState::LearningBackdrop, Phase::WaitingForSubject) => FlowState::EmptyScene,
            (FlowState::EmptyScene, Phase::WaitingForSubject) => FlowState::EmptyScene,
            (FlowState::Guiding { .. } | FlowState::HoldStill { .. }, Phase::WaitingForSubject) => {
                // Stepped off before the result: keep waiting for the idle timeout to
                // clear, but show the empty-scene prompt again.
                FlowState::EmptyScene
            }
            (_, Phase::Guiding) => FlowState::Guiding {
                message: input
                    .messages
                    .first()
                    .cloned()
                    .unwrap_or_else(|| DEFAULT_GUIDANCE.to_string()),
            },
            (FlowState::HoldStill { started_s }, Phase::Fitting | Phase::Settled) => {
                let started_s = *started_s;
                let held = now_s - started_s;
                let settled = input.phase == Phase::Settled;
                let timed_out = held >= self.config.countdown_s + self.config.settle_timeout_s;
                if held >= self.config.countdown_s
                    && (settled || timed_out)
                    && !input.measurements.is_empty()
                {
                    FlowState::Result {
                        card: ResultCard {
                            measurements: input.measurements.to_vec(),
                            frame_index: input.frame_index,
                            settled,
                        },
                        shown_s: now_s,
                    }
                } else {
                    FlowState::HoldStill { started_s }
                }
            }
            (_, Phase::Fitting | Phase::Settled) => FlowState::HoldStill { started_s: now_s },
        };
        self.state = next;
        self.on_tick(now_s)
    }

    /// Lets time pass without a snapshot (the screen calls this every frame).
    pub fn on_tick(&mut self, now_s: f64) -> Option<FlowAction> {
        let idle = self
            .subject_seen_s
            .is_some_and(|seen| now_s - seen >= self.config.idle_timeout_s);
        let card_expired = matches!(self.state, FlowState::Result { shown_s, .. } if now_s - shown_s >= self.config.result_display_s);
        if idle || card_expired {
            let next = match self.state {
                FlowState::LearningBackdrop => FlowState::LearningBackdrop,
                _ => FlowState::EmptyScene,
            };
            self.clear(next);
            return Some(FlowAction::ClearSubject);
        }
        None
    }

    /// An explicit reset (operator button): same as a timeout.
    pub fn reset(&mut self) -> FlowAction {
        let next = match self.state {
            FlowState::LearningBackdrop => FlowState::LearningBackdrop,
            _ => FlowState::EmptyScene,
        };
        self.clear(next);
        FlowAction::ClearSubject
    }

    fn clear(&mut self, next: FlowState) {
        self.state = next;
        self.subject_seen_s = None;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const CFG: FlowConfig = FlowConfig {
        countdown_s: 3.0,
        idle_timeout_s: 10.0,
        result_display_s: 45.0,
        settle_timeout_s: 4.0,
    };

    fn meas(v: f64) -> Vec<MeasurementValue> {
        vec![MeasurementValue {
            name: "chest_girth".into(),
            value_mm: v,
            stability_mm: 1.0,
            uncertainty_mm: 8.0,
            uncertain: false,
        }]
    }

    fn feed(
        f: &mut KioskFlow,
        phase: Phase,
        msgs: &[String],
        m: &[MeasurementValue],
        t: f64,
    ) -> Option<FlowAction> {
        f.on_snapshot(
            &FlowInput {
                phase,
                messages: msgs,
                measurements: m,
                frame_index: (t * 30.0) as u64,
            },
            t,
        )
    }

    /// Walks a flow to the result card; returns the time the card appeared.
    fn to_result(f: &mut KioskFlow) -> f64 {
        feed(f, Phase::WaitingForSubject, &[], &[], 1.0);
        feed(f, Phase::Fitting, &[], &meas(900.0), 2.0);
        feed(f, Phase::Settled, &[], &meas(1000.0), 5.5);
        assert!(
            matches!(f.state(), FlowState::Result { .. }),
            "{:?}",
            f.state()
        );
        5.5
    }

    #[test]
    fn starts_learning_and_stays_while_learning() {
        let mut f = KioskFlow::new(CFG);
        assert_eq!(f.state(), &FlowState::LearningBackdrop);
        assert_eq!(feed(&mut f, Phase::LearningBackdrop, &[], &[], 0.5), None);
        assert_eq!(f.state(), &FlowState::LearningBackdrop);
        // Time alone never leaves the learning screen.
        assert_eq!(f.on_tick(1000.0), None);
        assert_eq!(f.state(), &FlowState::LearningBackdrop);
    }

    #[test]
    fn learnt_backdrop_shows_the_empty_scene() {
        let mut f = KioskFlow::new(CFG);
        feed(&mut f, Phase::WaitingForSubject, &[], &[], 1.0);
        assert_eq!(f.state(), &FlowState::EmptyScene);
        feed(&mut f, Phase::WaitingForSubject, &[], &[], 100.0);
        assert_eq!(f.state(), &FlowState::EmptyScene);
    }

    #[test]
    fn a_bad_pose_shows_the_first_verdict_or_a_default() {
        let mut f = KioskFlow::new(CFG);
        feed(&mut f, Phase::WaitingForSubject, &[], &[], 1.0);
        let msgs = vec!["Lower your arms a little".to_string(), "second".to_string()];
        feed(&mut f, Phase::Guiding, &msgs, &[], 2.0);
        assert_eq!(
            f.state(),
            &FlowState::Guiding {
                message: msgs[0].clone()
            }
        );
        feed(&mut f, Phase::Guiding, &[], &[], 2.1);
        assert_eq!(
            f.state(),
            &FlowState::Guiding {
                message: DEFAULT_GUIDANCE.to_string()
            }
        );
    }

    #[test]
    fn a_good_pose_starts_the_countdown_and_a_bad_one_stops_it() {
        let mut f = KioskFlow::new(CFG);
        feed(&mut f, Phase::WaitingForSubject, &[], &[], 1.0);
        feed(&mut f, Phase::Fitting, &[], &[], 2.0);
        assert_eq!(f.state(), &FlowState::HoldStill { started_s: 2.0 });
        assert!((f.countdown_left_s(3.0) - 2.0).abs() < 1e-12);
        // Still fitting: the countdown keeps its start.
        feed(&mut f, Phase::Fitting, &[], &[], 3.0);
        assert_eq!(f.state(), &FlowState::HoldStill { started_s: 2.0 });
        // A bad verdict interrupts; a good pose afterwards restarts from zero.
        feed(
            &mut f,
            Phase::Guiding,
            &["Turn to face the front camera".to_string()],
            &[],
            3.5,
        );
        assert!(matches!(f.state(), FlowState::Guiding { .. }));
        assert_eq!(f.countdown_left_s(3.5), 0.0);
        feed(&mut f, Phase::Fitting, &[], &[], 4.0);
        assert_eq!(f.state(), &FlowState::HoldStill { started_s: 4.0 });
    }

    #[test]
    fn countdown_waits_for_both_time_and_settled_values() {
        let mut f = KioskFlow::new(CFG);
        feed(&mut f, Phase::WaitingForSubject, &[], &[], 1.0);
        // Settled early: the countdown still runs to its end.
        feed(&mut f, Phase::Settled, &[], &meas(1000.0), 2.0);
        feed(&mut f, Phase::Settled, &[], &meas(1000.0), 4.0);
        assert_eq!(f.state(), &FlowState::HoldStill { started_s: 2.0 });
        // Countdown over but not settled: still holding.
        feed(&mut f, Phase::Fitting, &[], &meas(990.0), 5.5);
        assert_eq!(f.state(), &FlowState::HoldStill { started_s: 2.0 });
        assert_eq!(f.countdown_left_s(5.5), 0.0);
        feed(&mut f, Phase::Settled, &[], &meas(1001.0), 6.0);
        match f.state() {
            FlowState::Result { card, shown_s } => {
                assert_eq!(card.measurements, meas(1001.0));
                assert!(card.settled);
                assert_eq!(*shown_s, 6.0);
            }
            s => panic!("expected the result card, got {s:?}"),
        }
    }

    #[test]
    fn unsettled_measurements_give_a_card_after_the_settle_timeout() {
        let mut f = KioskFlow::new(CFG);
        feed(&mut f, Phase::WaitingForSubject, &[], &[], 1.0);
        feed(&mut f, Phase::Fitting, &[], &meas(900.0), 2.0);
        let limit = 2.0 + CFG.countdown_s + CFG.settle_timeout_s;
        feed(&mut f, Phase::Fitting, &[], &meas(905.0), limit - 0.1);
        assert_eq!(f.state(), &FlowState::HoldStill { started_s: 2.0 });
        // No measurement yet: still holding, even after the timeout.
        feed(&mut f, Phase::Fitting, &[], &[], limit);
        assert_eq!(f.state(), &FlowState::HoldStill { started_s: 2.0 });
        feed(&mut f, Phase::Fitting, &[], &meas(907.0), limit + 0.1);
        match f.state() {
            FlowState::Result { card, .. } => {
                assert!(!card.settled);
                assert_eq!(card.measurements, meas(907.0));
            }
            s => panic!("expected the result card, got {s:?}"),
        }
    }

    #[test]
    fn result_card_is_frozen_while_the_shopper_stays() {
        let mut f = KioskFlow::new(CFG);
        let shown = to_result(&mut f);
        feed(&mut f, Phase::Guiding, &["x".to_string()], &[], shown + 1.0);
        feed(&mut f, Phase::Settled, &[], &meas(1200.0), shown + 2.0);
        match f.state() {
            FlowState::Result { card, .. } => assert_eq!(card.measurements, meas(1000.0)),
            s => panic!("{s:?}"),
        }
    }

    #[test]
    fn leaving_after_the_result_clears_after_the_idle_timeout() {
        let mut f = KioskFlow::new(CFG);
        let shown = to_result(&mut f);
        assert_eq!(
            feed(&mut f, Phase::WaitingForSubject, &[], &[], shown + 1.0),
            None
        );
        assert!(matches!(f.state(), FlowState::Result { .. }));
        // Last seen at `shown`; cleared once the idle timeout has passed.
        assert_eq!(f.on_tick(shown + CFG.idle_timeout_s - 0.1), None);
        assert_eq!(
            f.on_tick(shown + CFG.idle_timeout_s),
            Some(FlowAction::ClearSubject)
        );
        assert_eq!(f.state(), &FlowState::EmptyScene);
        // Cleared once only.
        assert_eq!(f.on_tick(shown + 100.0), None);
    }

    #[test]
    fn result_card_expires_even_with_the_shopper_on_the_mark() {
        let mut f = KioskFlow::new(CFG);
        let shown = to_result(&mut f);
        let mut t = shown;
        while t < shown + CFG.result_display_s - 1.0 {
            t += 1.0;
            assert_eq!(feed(&mut f, Phase::Settled, &[], &meas(1000.0), t), None);
        }
        let a = feed(
            &mut f,
            Phase::Settled,
            &[],
            &meas(1000.0),
            shown + CFG.result_display_s,
        );
        assert_eq!(a, Some(FlowAction::ClearSubject));
        assert_eq!(f.state(), &FlowState::EmptyScene);
    }

    #[test]
    fn stepping_off_mid_guidance_returns_to_the_prompt_then_clears() {
        let mut f = KioskFlow::new(CFG);
        feed(&mut f, Phase::WaitingForSubject, &[], &[], 1.0);
        feed(&mut f, Phase::Fitting, &[], &[], 2.0);
        feed(&mut f, Phase::WaitingForSubject, &[], &[], 3.0);
        assert_eq!(f.state(), &FlowState::EmptyScene);
        assert_eq!(
            f.on_tick(2.0 + CFG.idle_timeout_s),
            Some(FlowAction::ClearSubject)
        );
        assert_eq!(f.state(), &FlowState::EmptyScene);
    }

    #[test]
    fn idle_timeout_needs_the_subject_to_be_gone() {
        let mut f = KioskFlow::new(CFG);
        feed(&mut f, Phase::WaitingForSubject, &[], &[], 1.0);
        let mut t = 2.0;
        while t < 40.0 {
            assert_eq!(feed(&mut f, Phase::Guiding, &[], &[], t), None);
            t += 0.5;
        }
        assert!(matches!(f.state(), FlowState::Guiding { .. }));
    }

    #[test]
    fn relearning_the_backdrop_clears_a_result() {
        let mut f = KioskFlow::new(CFG);
        let shown = to_result(&mut f);
        assert_eq!(
            feed(&mut f, Phase::LearningBackdrop, &[], &[], shown + 1.0),
            Some(FlowAction::ClearSubject)
        );
        assert_eq!(f.state(), &FlowState::LearningBackdrop);
        // Learning from guidance simply shows the learning screen.
        let mut g = KioskFlow::new(CFG);
        feed(&mut g, Phase::WaitingForSubject, &[], &[], 1.0);
        feed(&mut g, Phase::Guiding, &[], &[], 2.0);
        feed(&mut g, Phase::LearningBackdrop, &[], &[], 3.0);
        assert_eq!(g.state(), &FlowState::LearningBackdrop);
    }

    #[test]
    fn explicit_reset_clears() {
        let mut f = KioskFlow::new(CFG);
        to_result(&mut f);
        assert_eq!(f.reset(), FlowAction::ClearSubject);
        assert_eq!(f.state(), &FlowState::EmptyScene);
        let mut g = KioskFlow::new(CFG);
        g.reset();
        assert_eq!(g.state(), &FlowState::LearningBackdrop);
    }

    #[test]
    fn from_snapshot_reads_the_fields() {
        let mut s = FitSnapshot::empty(7, Phase::Settled);
        s.messages.push("m".into());
        s.measurements = meas(3.0);
        let i = FlowInput::from_snapshot(&s);
        assert_eq!(i.phase, Phase::Settled);
        assert_eq!(i.frame_index, 7);
        assert_eq!(i.messages, &["m".to_string()]);
        assert_eq!(i.measurements, &meas(3.0)[..]);
    }
}
