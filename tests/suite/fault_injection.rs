//! Fault injection (issue 21, item 2): the demo recording replayed in a loop through
//! [`FaultInjector`] into the real station, one fault at a time. For every fault: no
//! panic, the fault is reported, the last good measurements stay on the snapshots while
//! frames are skipped, results resume after the fault, the backdrop is learnt again only
//! when the scene changed, and no pair mixes a front and a side frame of different
//! moments. Plus the `fitstation replay --inject` command line.
//!
//! The demo is 24 pairs at 30 fps (0.4 s empty, then 0.4 s with the subject); looped,
//! the subject stands on the mark at 0.4-0.8 s, 1.2-1.6 s, 2.0-2.4 s, 2.8-3.2 s.

use fitstation::capture::inject::{parse_spec, FaultInjector};
use fitstation::cli::RecordingSource;
use fitstation::pipeline::{FramePair, FrameProcessor, FrameSource, Phase, SourceError};
use fitstation::station::default_library;
use fitstation::station::{StationOptions, StationProcessor};
use std::collections::{HashMap, HashSet};
use std::hash::{Hash, Hasher};
use std::path::PathBuf;
use std::process::Command;
use std::sync::{Arc, Mutex};

/// The tests run one at a time (the machine's two cores are shared).
static SERIAL: Mutex<()> = Mutex::new(());

/// Pairs read from the looped demo in a run (2.4 s: three times the subject).
const FRAMES: usize = 72;

fn demo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("recordings/demo")
}

fn frame_hash(img: &image::RgbImage) -> u64 {
    let mut h = std::collections::hash_map::DefaultHasher::new();
    (img.width(), img.height()).hash(&mut h);
    img.as_raw().hash(&mut h);
    h.finish()
}

/// Which recording frames each frame content was (frame hash -> positions in the
/// recording), filled by [`Ledger`] as pairs leave the recording.
type Seen = Arc<Mutex<HashMap<u64, HashSet<usize>>>>;

/// The looped recording, noting each frame's content and stopping after `limit` pairs.
struct Ledger {
    inner: RecordingSource,
    seen: Seen,
    given: usize,
    limit: usize,
}

impl FrameSource for Ledger {
    fn next_pair(&mut self) -> Result<Option<FramePair>, SourceError> {
        if self.given >= self.limit {
            return Ok(None);
        }
        let pair = self.inner.next_pair()?;
        if let Some(p) = &pair {
            let k = self.given % self.inner.recording().len();
            let mut seen = self.seen.lock().expect("ledger");
            for img in [&p.front, &p.side] {
                seen.entry(frame_hash(img)).or_default().insert(k);
            }
        }
        self.given += 1;
        Ok(pair)
    }
    fn calibration(&self) -> Option<&fitstation::camera::StationCalibration> {
        self.inner.calibration()
    }
    fn fps(&self) -> Option<f64> {
        self.inner.fps()
    }
    fn describe(&self) -> String {
        self.inner.describe()
    }
}

/// One snapshot as the tests look at it.
#[derive(Debug, Clone)]
struct Snap {
    t: f64,
    phase: Phase,
    faults: Vec<String>,
    measurements: Vec<(String, f64)>,
}

impl Snap {
    /// The pair was skipped for a fault (the snapshot repeats the last good result).
    fn skipped(&self) -> bool {
        self.faults
            .iter()
            .any(|f| f.contains("skipped") && !f.starts_with("Good frames again"))
    }
    fn fitted(&self) -> bool {
        matches!(self.phase, Phase::Fitting | Phase::Settled) && !self.skipped()
    }
}

/// What a run gave, call by call.
#[derive(Debug, Default)]
struct Run {
    snaps: Vec<Snap>,
    /// Source errors (lost camera) with the time of the last pair before them.
    errors: Vec<(f64, String)>,
    /// Pairs whose two frames were both found in the ledger (checked for mixing).
    checked_pairs: usize,
}

impl Run {
    fn reported(&self, words: &str) -> bool {
        self.snaps
            .iter()
            .any(|s| s.faults.iter().any(|f| f.contains(words)))
            || self.errors.iter().any(|(_, e)| e.contains(words))
    }
    fn relearnt(&self) -> bool {
        self.reported("learning the backdrop again")
    }
}

/// Replays `frames` pairs of the looped demo through the faults of `spec` (none when
/// `None`) into the station; panics on a pair that mixes two moments.
fn run(spec: Option<&str>, frames: usize) -> Run {
    let _serial = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    let mut rec = RecordingSource::open(&demo()).expect("open the demo recording");
    rec.looping = true;
    let calib = rec.recording().calibration().clone();
    let seen: Seen = Arc::default();
    let ledger = Ledger {
        inner: rec,
        seen: seen.clone(),
        given: 0,
        limit: frames,
    };
    let mut source: Box<dyn FrameSource> = match spec {
        Some(s) => Box::new(FaultInjector::new(
            Box::new(ledger),
            parse_spec(s).expect("spec"),
        )),
        None => Box::new(ledger),
    };
    let opts = StationOptions {
        person_model: false,
        ..StationOptions::default()
    };
    let mut station =
        StationProcessor::new(calib, default_library().expect("library"), opts).expect("station");
    let mut out = Run::default();
    let mut last_t = 0.0;
    loop {
        let pair = match source.next_pair() {
            Ok(Some(p)) => p,
            Ok(None) => break,
            Err(SourceError::Fatal(e)) => panic!("fatal source error: {e}"),
            Err(e) => {
                out.errors.push((last_t, e.to_string()));
                continue;
            }
        };
        last_t = pair.timestamp_s;
        let ledger = seen.lock().expect("ledger");
        let (f, s) = (
            ledger.get(&frame_hash(&pair.front)),
            ledger.get(&frame_hash(&pair.side)),
        );
        if let (Some(f), Some(s)) = (f, s) {
            assert!(
                !f.is_disjoint(s),
                "pair {} at {:.3} s mixes recording frames {f:?} (front) and {s:?} (side)",
                pair.index,
                pair.timestamp_s
            );
            out.checked_pairs += 1;
        }
        drop(ledger);
        let snap = station.process(&pair);
        check_timings(&snap.timings_ms, pair.index);
        // A fitted pair gives the screen what it needs to draw the avatar's outline (not
        // while the backdrop is learnt again, which keeps the last avatar on screen).
        if let (Some(av), false) = (&snap.avatar, snap.phase == Phase::LearningBackdrop) {
            for o in [&snap.front, &snap.side] {
                let cam = o
                    .camera
                    .as_ref()
                    .expect("the view's camera for the outline");
                assert!(fitstation::pipeline::avatar_outline(av, cam).len() > 20);
            }
        }
        out.snaps.push(Snap {
            t: pair.timestamp_s,
            phase: snap.phase,
            faults: snap.faults.clone(),
            measurements: snap
                .measurements
                .iter()
                .map(|m| (m.name.clone(), m.value_mm))
                .collect(),
        });
    }
    out
}

/// A processed pair's `total` is the sum of every stage timed on the station's thread,
/// from the fault screen that opens the pair to the screen's snapshot that closes it (a
/// stage ending in `_part` is a share of another and not added).
fn check_timings(timings: &[(String, f64)], index: u64) {
    let Some(total) = timings.iter().find(|(k, _)| k == "total").map(|t| t.1) else {
        return; // a skipped pair: no stages
    };
    let sum: f64 = timings
        .iter()
        .filter(|(k, _)| k != "total" && !k.ends_with("_part"))
        .map(|t| t.1)
        .sum();
    assert!(
        (total - sum).abs() < 1e-9,
        "pair {index}: total {total} ms, stages add up to {sum} ({timings:?})"
    );
    for stage in [
        fitstation::station::FAULT_SCREEN_STAGE,
        fitstation::station::SCREEN_STAGE,
    ] {
        assert!(
            timings.iter().any(|(k, _)| k == stage),
            "pair {index}: no {stage} stage in {timings:?}"
        );
    }
}

/// The checks every fault must pass; `window` is the fault's `[start, end)` in seconds.
fn check_fault(spec: &str, window: (f64, f64), says: &str, relearn: bool) -> Run {
    let r = run(Some(spec), FRAMES);
    for s in &r.snaps {
        eprintln!("{:.3} {:?} {:?}", s.t, s.phase, s.faults);
    }
    // Fitted before the fault.
    assert!(
        r.snaps.iter().any(|s| s.t < window.0 && s.fitted()),
        "{spec}: no fit before the fault"
    );
    // The fault is reported.
    assert!(r.reported(says), "{spec}: '{says}' never reported: {r:#?}");
    // The last good measurements stay: from the first fit on, no snapshot is without
    // them, and a skipped pair's snapshot shows exactly the previous one's.
    let first = r
        .snaps
        .iter()
        .position(|s| s.fitted())
        .expect("a fitted frame");
    for w in r.snaps[first..].windows(2) {
        assert!(
            !w[1].measurements.is_empty(),
            "{spec}: measurements lost at {:.3} s: {:?}",
            w[1].t,
            w[1].faults
        );
        if w[1].skipped() {
            assert_eq!(
                w[1].measurements, w[0].measurements,
                "{spec}: a skipped pair changed the measurements at {:.3} s",
                w[1].t
            );
        }
    }
    // Results resume after the fault: good pairs fitted again.
    let resumed = r
        .snaps
        .iter()
        .filter(|s| s.t >= window.1 && s.fitted())
        .count();
    assert!(
        resumed >= 3,
        "{spec}: only {resumed} fitted pairs after the fault"
    );
    // The backdrop is learnt again only when the scene changed.
    assert_eq!(r.relearnt(), relearn, "{spec}: backdrop relearnt");
    if !relearn {
        assert!(
            r.snaps
                .iter()
                .filter(|s| s.t >= window.0)
                .all(|s| s.phase != Phase::LearningBackdrop),
            "{spec}: learning the backdrop again"
        );
    }
    assert!(
        r.checked_pairs > FRAMES / 2,
        "{spec}: {} pairs checked",
        r.checked_pairs
    );
    r
}

#[test]
fn without_faults_nothing_is_reported() {
    let r = run(None, FRAMES);
    assert!(r.errors.is_empty());
    let faults: Vec<&Snap> = r.snaps.iter().filter(|s| !s.faults.is_empty()).collect();
    assert!(faults.is_empty(), "{faults:#?}");
    assert!(r.snaps.iter().filter(|s| s.fitted()).count() >= 20);
}

#[test]
fn a_stall_is_reported_and_the_fit_resumes() {
    let r = check_fault("stall@1.25:0.3", (1.25, 1.55), "No frames for 0.3 s", false);
    assert!(r.snaps.iter().all(|s| !(1.25..1.55).contains(&s.t)));
}

#[test]
fn a_lost_camera_is_reported_and_never_paired_with_stale_frames() {
    let r = check_fault(
        "drop-side@1.25:0.3",
        (1.25, 1.55),
        "side camera lost",
        false,
    );
    assert!(r.reported("No frames for 0.3 s"));
    // No pair at all while the side camera was gone.
    assert!(r.snaps.iter().all(|s| !(1.25..1.55).contains(&s.t)));
    assert_eq!(r.errors.len(), 9, "{:?}", r.errors);
}

#[test]
fn reordered_pairs_are_skipped() {
    check_fault("reorder@1.3:0.15", (1.3, 1.45), "out of order", false);
}

#[test]
fn duplicated_pairs_are_skipped() {
    let r = check_fault("duplicate@1.3:0.15", (1.3, 1.45), "came twice", false);
    assert_eq!(r.snaps.iter().filter(|s| s.skipped()).count(), 5);
}

#[test]
fn a_corrupt_frame_is_skipped() {
    check_fault("corrupt-side@1.3:0.1", (1.3, 1.4), "random bytes", false);
}

#[test]
fn a_wrongly_sized_frame_is_skipped() {
    check_fault(
        "resize-front@1.3:0.1",
        (1.3, 1.4),
        "Corrupt front frame",
        false,
    );
}

#[test]
fn a_sudden_exposure_change_is_skipped_without_relearning() {
    check_fault(
        "exposure@1.3:0.15",
        (1.3, 1.45),
        "Sudden exposure change",
        false,
    );
}

#[test]
fn a_lasting_exposure_change_relearns_the_backdrop_and_keeps_the_result() {
    // From 1.4 s on the cameras stay brighter: after a second of skipped frames the
    // backdrop is learnt again (on the empty frames from 2.4 s) and the subject
    // (back at 2.8 s) is fitted against the new one.
    let r = run(Some("exposure=0.5@1.4:100"), 100);
    for s in &r.snaps {
        eprintln!("{:.3} {:?} {:?}", s.t, s.phase, s.faults);
    }
    assert!(r.reported("Sudden exposure change"));
    assert!(r.relearnt(), "never relearnt");
    let relearn_t = r
        .snaps
        .iter()
        .find(|s| {
            s.faults
                .iter()
                .any(|f| f.contains("learning the backdrop again"))
        })
        .map(|s| s.t)
        .expect("relearn");
    assert!((2.35..2.5).contains(&relearn_t), "relearnt at {relearn_t}");
    for s in r.snaps.iter().filter(|s| s.t >= 1.4 && s.t < 2.8) {
        assert!(
            !s.measurements.is_empty(),
            "measurements lost at {:.3} s",
            s.t
        );
    }
    assert!(
        r.snaps.iter().filter(|s| s.t >= 2.8 && s.fitted()).count() >= 3,
        "no fit against the new backdrop"
    );
}

fn fitstation(args: &[&str]) -> std::process::Output {
    let _serial = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    Command::new(env!("CARGO_BIN_EXE_fitstation"))
        .args(args)
        .output()
        .expect("run fitstation")
}

#[test]
fn replay_inject_logs_and_reports_the_faults() {
    let out = std::env::temp_dir().join(format!("fitstation-inject-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&out);
    let demo = demo();
    let o = fitstation(&[
        "replay",
        demo.to_str().expect("path"),
        "--inject",
        "corrupt-front@0.5:0.05,drop-side@0.6:0.1",
        "--no-person-model",
        "--json",
        "--out",
        out.to_str().expect("path"),
    ]);
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "replay failed: {stderr}");
    assert!(
        stderr.contains("inject: corrupt-front from 0.50 s"),
        "{stderr}"
    );
    assert!(
        stderr.contains("fault: source: camera disconnected: side camera lost"),
        "{stderr}"
    );
    assert!(
        stderr.contains("Corrupt front frame (random bytes"),
        "{stderr}"
    );
    let report: serde_json::Value =
        serde_json::from_slice(&o.stdout).expect("report JSON on stdout");
    let faults = report["faults"].as_array().expect("faults in the report");
    assert!(
        faults.iter().any(
            |f| f["source"] == "camera disconnected: side camera lost: no frames"
                && f["pairs"].as_u64().is_some_and(|n| (3..=4).contains(&n))
        ),
        "{faults:?}"
    );
    assert!(report["measurements_mm"]["chest_girth"].as_f64().is_some());
    let _ = std::fs::remove_dir_all(&out);

    // A bad SPEC is refused in one clear line, and --help explains the syntax.
    let o = fitstation(&[
        "replay",
        demo.to_str().expect("path"),
        "--inject",
        "wobble@1:2",
    ]);
    assert!(!o.status.success());
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(stderr.contains("unknown fault 'wobble'"), "{stderr}");
    let o = fitstation(&["replay", "--help"]);
    let help = String::from_utf8_lossy(&o.stdout);
    assert!(
        help.contains("KIND[=GAIN]@START:DURATION") && help.contains("drop-side"),
        "{help}"
    );
}
