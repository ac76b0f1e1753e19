//! The screen's pipeline threads: `capture` pulls frame pairs from the [`FrameSource`]
//! (paced to its nominal frame rate, paused/stepped by the operator, feeding the
//! recorder), a newest-wins [`LatestSlot`] hands them to `process` (the
//! [`FrameProcessor`]), whose [`FitSnapshot`]s go to another slot the screen reads.
//!
//! `capture` also prepares the camera frames of each pair for display
//! ([`super::display`]: box-filtered to the size of the view on screen, RGBA), for a
//! paced source while the pair waits for its time, so that neither the station's
//! processing nor the screen's own thread waits for it (the screen only uploads them).
//!
//! The screen never waits for either thread; a slow processor drops frames (counted),
//! a disconnected camera is shown and retried; a source that ends leaves the last
//! snapshot on screen.

use super::display::{display_factor, DisplayImage, Downscaler};
use super::record::Recorder;
use super::stats::RollingStats;
use crate::pipeline::{
    FitSnapshot, FramePair, FrameProcessor, FrameSource, LatestSlot, SourceError,
};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

/// How long the capture thread sleeps while paused or after a disconnect.
const PAUSED_POLL: Duration = Duration::from_millis(15);
const RECONNECT_POLL: Duration = Duration::from_millis(250);

/// What the capture thread last reported about its source.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct SourceStatus {
    /// A problem to show (disconnected camera, skipped frame), cleared by the next pair.
    pub problem: Option<String>,
    /// A finite source reached its end.
    pub ended: bool,
    /// The source failed for good.
    pub failed: bool,
    pub pairs: u64,
    pub last_index: Option<u64>,
}

/// Shared switches between the screen and the pipeline threads.
#[derive(Default)]
pub struct Controls {
    pub paused: AtomicBool,
    /// Pairs to let through while paused (the "step" button).
    pub steps: AtomicU64,
    /// Ask the processor to forget the subject before its next frame.
    pub reset_subject: AtomicBool,
    /// A processor to take over from the next frame on (a new calibration, a backdrop
    /// to learn again).
    pub replace_processor: Mutex<Option<Box<dyn FrameProcessor>>>,
    pub stop: AtomicBool,
    /// Times the capture thread found itself paused with no step to take.
    pub pause_polls: AtomicU64,
    pub recorder: Mutex<Option<Recorder>>,
    pub status: Mutex<SourceStatus>,
    /// Durations of `source` (reading one pair), `process` (one snapshot) and
    /// `display` (preparing its frames for the screen), ms.
    pub stats: Mutex<RollingStats>,
    /// Size of a camera view on screen (pixels), set by the screen: the frames are
    /// prepared for display at about that size.
    pub view_px: Mutex<Option<[f32; 2]>>,
    /// Snapshots put into the screen's slot so far.
    pub published: AtomicU64,
    /// The screen will not look at the snapshot slot again unless woken: the next
    /// snapshot calls `notify` (and clears this). Set by the screen at the end of each
    /// frame, after which it checks `published` itself; a snapshot that the screen
    /// takes in the frame it was put during therefore asks for no second frame.
    pub wake_wanted: AtomicBool,
    /// When the most recent pairs left the source (index, time), for the screen's
    /// arrival-to-screen latency.
    arrivals: Mutex<std::collections::VecDeque<(u64, Instant)>>,
}

/// Arrival times kept for the latency figure (pairs).
const ARRIVALS_KEPT: usize = 64;

impl Controls {
    pub fn status(&self) -> SourceStatus {
        self.status.lock().map(|s| s.clone()).unwrap_or_default()
    }
    /// Rolling statistics of the pipeline threads' own work.
    pub fn thread_stats(&self) -> RollingStats {
        self.stats.lock().map(|s| s.clone()).unwrap_or_default()
    }
    fn add_stat(&self, stage: &str, since: Instant) {
        if let Ok(mut s) = self.stats.lock() {
            s.add(stage, since.elapsed().as_secs_f64() * 1e3);
        }
    }
    /// When the pair `index` left the source, if it is among the recent ones.
    pub fn arrival(&self, index: u64) -> Option<Instant> {
        let a = self.arrivals.lock().ok()?;
        a.iter().rev().find(|(i, _)| *i == index).map(|(_, t)| *t)
    }
    fn note_arrival(&self, index: u64) {
        if let Ok(mut a) = self.arrivals.lock() {
            a.push_back((index, Instant::now()));
            while a.len() > ARRIVALS_KEPT {
                a.pop_front();
            }
        }
    }
    fn with_status(&self, f: impl FnOnce(&mut SourceStatus)) {
        if let Ok(mut s) = self.status.lock() {
            f(&mut s);
        }
    }
}

/// A snapshot with its camera frames prepared for display.
#[derive(Debug, Clone)]
pub struct ScreenSnapshot {
    pub snap: FitSnapshot,
    pub front_display: Option<Arc<DisplayImage>>,
    pub side_display: Option<Arc<DisplayImage>>,
}

/// The running threads; dropping it stops them.
pub struct Runner {
    pub controls: Arc<Controls>,
    pub snapshots: Arc<LatestSlot<ScreenSnapshot>>,
    pairs: Arc<LatestSlot<SourcePair>>,
    process: Option<JoinHandle<()>>,
}

impl Runner {
    /// Starts both threads; `notify` is called after a new snapshot when the screen
    /// wants waking (see [`Controls::wake_wanted`]; always, if the screen never sets
    /// it, for the first snapshot only).
    pub fn start(
        mut source: Box<dyn FrameSource>,
        mut processor: Box<dyn FrameProcessor>,
        notify: Box<dyn Fn() + Send>,
    ) -> std::io::Result<Self> {
        let controls = Arc::new(Controls {
            // Nothing is on screen yet: the first snapshot wakes the screen.
            wake_wanted: AtomicBool::new(true),
            ..Controls::default()
        });
        let pairs = Arc::new(LatestSlot::<SourcePair>::new());
        let snapshots = Arc::new(LatestSlot::<ScreenSnapshot>::new());
        let fps = source.fps().filter(|f| f.is_finite() && *f > 0.0);
        {
            let controls = controls.clone();
            let pairs = pairs.clone();
            // Detached: a camera read may block; the thread ends at its next iteration.
            std::thread::Builder::new()
                .name("capture".into())
                .spawn(move || capture_loop(source.as_mut(), fps, &controls, &pairs))?;
        }
        let process = {
            let controls = controls.clone();
            let pairs = pairs.clone();
            let snapshots = snapshots.clone();
            std::thread::Builder::new()
                .name("process".into())
                .spawn(move || {
                    let mut downscaler = Downscaler::default();
                    while let Some(SourcePair { pair, display }) = pairs.take() {
                        if controls.stop.load(Ordering::Relaxed) {
                            break;
                        }
                        let replacement = controls
                            .replace_processor
                            .lock()
                            .ok()
                            .and_then(|mut r| r.take());
                        if let Some(p) = replacement {
                            processor = p;
                        }
                        if controls.reset_subject.swap(false, Ordering::Relaxed) {
                            processor.reset_subject();
                        }
                        let t0 = Instant::now();
                        super::trace::ev("process_start", pair.index);
                        let snap = processor.process(&pair);
                        super::trace::ev("process_end", pair.index);
                        controls.add_stat("process", t0);
                        // The snapshot shows its pair's frames, prepared for display by
                        // the capture thread; a frame of another size is prepared here.
                        let [front_display, side_display] = [
                            (&snap.front_frame, display[0].clone()),
                            (&snap.side_frame, display[1].clone()),
                        ]
                        .map(|(frame, ready)| {
                            let f = frame.as_ref()?;
                            match ready {
                                Some(d) if d.frame_size == [f.width(), f.height()] => Some(d),
                                _ => Some(prepare_display(&mut downscaler, f, &controls)),
                            }
                        });
                        snapshots.put(ScreenSnapshot {
                            snap,
                            front_display,
                            side_display,
                        });
                        let n = controls.published.fetch_add(1, Ordering::SeqCst);
                        super::trace::ev("published", n + 1);
                        if controls.wake_wanted.swap(false, Ordering::SeqCst) {
                            notify();
                        }
                    }
                    snapshots.close();
                })?
        };
        Ok(Runner {
            controls,
            snapshots,
            pairs,
            process: Some(process),
        })
    }

    /// Pairs the processor could not keep up with.
    pub fn dropped_pairs(&self) -> u64 {
        self.pairs.dropped()
    }
}

/// A pair as handed from the capture thread to the process thread, with its frames
/// prepared for display (front, side).
struct SourcePair {
    pair: FramePair,
    display: [Option<Arc<DisplayImage>>; 2],
}

/// `frame` box-filtered to the size of its view on screen (see [`display_factor`]).
fn prepare_display(
    downscaler: &mut Downscaler,
    frame: &image::RgbImage,
    controls: &Controls,
) -> Arc<DisplayImage> {
    let target = controls.view_px.lock().ok().and_then(|v| *v);
    let factor = display_factor(frame.width(), frame.height(), target);
    downscaler.prepare(frame, factor)
}

/// Both frames of `pair` prepared for display.
fn display_pair(
    downscaler: &mut Downscaler,
    pair: &FramePair,
    controls: &Controls,
) -> [Option<Arc<DisplayImage>>; 2] {
    let t0 = Instant::now();
    let d = [&pair.front, &pair.side].map(|f| Some(prepare_display(downscaler, f, controls)));
    controls.add_stat("display", t0);
    d
}

/// What the capture thread does with one result of the source.
enum Read {
    /// A pair to hand on (at its time, for a paced source).
    Pair(FramePair),
    /// Nothing this time (a skipped frame, a disconnected camera): try again.
    Retry,
    /// The source has ended or failed for good.
    Stop,
}

/// Reads the source once and reports what happened in the shared status.
fn read_pair(source: &mut dyn FrameSource, controls: &Controls) -> Read {
    let t0 = Instant::now();
    super::trace::ev("read", 0);
    match source.next_pair() {
        Ok(Some(pair)) => {
            controls.add_stat("source", t0);
            Read::Pair(pair)
        }
        Ok(None) => {
            controls.with_status(|s| s.ended = true);
            Read::Stop
        }
        Err(SourceError::Skipped(m)) => {
            controls.with_status(|s| s.problem = Some(format!("frame skipped: {m}")));
            Read::Retry
        }
        Err(SourceError::Disconnected(m)) => {
            controls.with_status(|s| {
                s.problem = Some(format!(
                    "camera disconnected: {m} (waiting for it to come back)"
                ))
            });
            std::thread::sleep(RECONNECT_POLL);
            Read::Retry
        }
        Err(SourceError::Fatal(m)) => {
            controls.with_status(|s| {
                s.problem = Some(m);
                s.failed = true;
            });
            Read::Stop
        }
    }
}

/// The capture thread: hands the source's pairs to `pairs` until the source ends or
/// the runner stops.
///
/// A source with a frame rate (a recording, the demo) is paced to it like a camera:
/// the next pair is read (decoded) as soon as the previous one has been handed on and
/// is then held until its due time, so that every pair leaves the source on the
/// recording's clock however long its decoding took, and the decoding runs while the
/// station processes the previous pair rather than while the screen draws it. A pair
/// is never held past its due time (one that comes late goes at once) and at most one
/// is held: nothing stale queues up. A source without a frame rate (live cameras)
/// paces itself and each pair goes on as soon as it is read.
fn capture_loop(
    source: &mut dyn FrameSource,
    fps: Option<f64>,
    controls: &Controls,
    pairs: &LatestSlot<SourcePair>,
) {
    let period = fps.map(|f| Duration::from_secs_f64(1.0 / f));
    let mut next_due = Instant::now();
    let mut downscaler = Downscaler::default();
    // The pair read ahead of its time, prepared for display (paced sources only).
    let mut held: Option<SourcePair> = None;
    while !controls.stop.load(Ordering::Relaxed) {
        if controls.paused.load(Ordering::Relaxed) {
            let stepped = controls
                .steps
                .fetch_update(Ordering::Relaxed, Ordering::Relaxed, |s| s.checked_sub(1))
                .is_ok();
            if !stepped {
                controls.pause_polls.fetch_add(1, Ordering::SeqCst);
                std::thread::sleep(PAUSED_POLL);
                next_due = Instant::now();
                continue;
            }
        }
        let (pair, display) = match held.take() {
            Some(h) => (h.pair, Some(h.display)),
            None => match read_pair(source, controls) {
                Read::Pair(p) => (p, None),
                Read::Retry => continue,
                Read::Stop => break,
            },
        };
        if let Some(p) = period {
            let now = Instant::now();
            if next_due > now {
                std::thread::sleep(next_due - now);
            } else if now - next_due > p * 4 {
                // Far behind (a slow source): do not try to catch up.
                next_due = now;
            }
            next_due += p;
        }
        controls.note_arrival(pair.index);
        super::trace::ev("arrival", pair.index);
        if let Ok(r) = controls.recorder.lock() {
            if let Some(r) = r.as_ref() {
                r.push(&pair);
            }
        }
        controls.with_status(|s| {
            // A pair without its side frame: the side camera is lost past its stall
            // timeout and the station measures from the front camera alone.
            s.problem = (!crate::pipeline::has_frame(&pair.side))
                .then(|| "side camera lost: measuring from the front camera alone".to_string());
            s.pairs += 1;
            s.last_index = Some(pair.index);
        });
        // A pair read just now (a camera's) is prepared for display after its arrival
        // (that time counts in the latency); one read ahead was prepared while held.
        let display = display.unwrap_or_else(|| display_pair(&mut downscaler, &pair, controls));
        pairs.put(SourcePair { pair, display });
        // Read the next pair now, while the station works on this one, and prepare it
        // for display; it waits for its time above. Not while paused: a step then
        // reads its pair itself.
        if period.is_some() && !controls.paused.load(Ordering::Relaxed) {
            match read_pair(source, controls) {
                Read::Pair(pair) => {
                    let display = display_pair(&mut downscaler, &pair, controls);
                    held = Some(SourcePair { pair, display });
                }
                Read::Retry => {}
                Read::Stop => break,
            }
        }
    }
    pairs.close();
}

impl Drop for Runner {
    fn drop(&mut self) {
        self.controls.stop.store(true, Ordering::Relaxed);
        self.pairs.close();
        if let Some(p) = self.process.take() {
            let _ = p.join();
        }
        if let Ok(mut r) = self.controls.recorder.lock() {
            if let Some(r) = r.take() {
                let _ = r.finish();
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::StationCalibration;
    use crate::pipeline::Phase;

    struct Counting {
        n: u64,
        end: u64,
        fail_at: Option<u64>,
    }
    impl FrameSource for Counting {
        fn next_pair(&mut self) -> Result<Option<FramePair>, SourceError> {
            if Some(self.n) == self.fail_at {
                self.fail_at = None;
                return Err(SourceError::Disconnected("unplugged".into()));
            }
            if self.n >= self.end {
                return Ok(None);
            }
            self.n += 1;
            let img = image::RgbImage::new(2, 2);
            Ok(Some(FramePair {
                index: self.n - 1,
                timestamp_s: 0.0,
                front: img.clone().into(),
                side: img.into(),
            }))
        }
        fn calibration(&self) -> Option<&StationCalibration> {
            None
        }
        fn describe(&self) -> String {
            "counting".into()
        }
    }
    struct Echo;
    impl FrameProcessor for Echo {
        fn process(&mut self, pair: &FramePair) -> FitSnapshot {
            FitSnapshot::empty(pair.index, Phase::WaitingForSubject)
        }
    }

    #[test]
    fn runs_to_the_end_through_a_disconnect() {
        let r = Runner::start(
            Box::new(Counting {
                n: 0,
                end: 20,
                fail_at: Some(5),
            }),
            Box::new(Echo),
            Box::new(|| {}),
        )
        .expect("threads");
        let mut last = None;
        while let Some(s) = r.snapshots.take() {
            last = Some(s.snap.frame_index);
        }
        assert_eq!(last, Some(19));
        let st = r.controls.status();
        assert!(st.ended && !st.failed);
        assert_eq!(st.pairs, 20);
    }

    /// Waits until the capture thread has gone round its paused loop after `after`
    /// polls: everything it started before is then finished.
    fn wait_for_pause_poll(c: &Controls, after: u64) {
        for _ in 0..20_000 {
            if c.pause_polls.load(Ordering::SeqCst) > after {
                return;
            }
            std::thread::sleep(Duration::from_millis(1));
        }
        panic!("the capture thread never paused");
    }

    struct Tagged(Phase);
    impl FrameProcessor for Tagged {
        fn process(&mut self, pair: &FramePair) -> FitSnapshot {
            FitSnapshot::empty(pair.index, self.0)
        }
    }

    #[test]
    fn a_replacement_processor_takes_over() {
        let r = Runner::start(
            Box::new(Counting {
                n: 0,
                end: u64::MAX,
                fail_at: None,
            }),
            Box::new(Tagged(Phase::WaitingForSubject)),
            Box::new(|| {}),
        )
        .expect("threads");
        let first = r.snapshots.take().expect("a snapshot");
        assert_eq!(first.snap.phase, Phase::WaitingForSubject);
        if let Ok(mut slot) = r.controls.replace_processor.lock() {
            *slot = Some(Box::new(Tagged(Phase::LearningBackdrop)));
        }
        // Snapshots already under way may still come from the old processor.
        let mut swapped = false;
        for _ in 0..1000 {
            if r.snapshots.take().expect("a snapshot").snap.phase == Phase::LearningBackdrop {
                swapped = true;
                break;
            }
        }
        assert!(swapped, "the replacement never ran");
    }

    /// Passes the pair's frames through, as the station does.
    struct WithFrames;
    impl FrameProcessor for WithFrames {
        fn process(&mut self, pair: &FramePair) -> FitSnapshot {
            let mut s = FitSnapshot::empty(pair.index, Phase::WaitingForSubject);
            s.front_frame = Some(pair.front.clone());
            s.side_frame = Some(pair.side.clone());
            s
        }
    }

    struct Sized(u64);
    impl FrameSource for Sized {
        fn next_pair(&mut self) -> Result<Option<FramePair>, SourceError> {
            self.0 += 1;
            Ok(Some(FramePair {
                index: self.0,
                timestamp_s: 0.0,
                front: image::RgbImage::from_pixel(1280, 720, image::Rgb([10, 20, 30])).into(),
                side: image::RgbImage::from_pixel(720, 1280, image::Rgb([40, 50, 60])).into(),
            }))
        }
        fn calibration(&self) -> Option<&StationCalibration> {
            None
        }
        fn describe(&self) -> String {
            "sized".into()
        }
    }

    #[test]
    fn frames_come_prepared_for_the_view_size() {
        let r = Runner::start(Box::new(Sized(0)), Box::new(WithFrames), Box::new(|| {}))
            .expect("threads");
        if let Ok(mut v) = r.controls.view_px.lock() {
            *v = Some([420.0, 800.0]);
        }
        // Snapshots under way may still have the default size; a later one has the view's.
        let mut seen = None;
        for _ in 0..1000 {
            let s = r.snapshots.take().expect("a snapshot");
            let (Some(f), Some(sd)) = (s.front_display, s.side_display) else {
                panic!("no display images");
            };
            assert_eq!(f.frame_size, [1280, 720]);
            assert_eq!(sd.frame_size, [720, 1280]);
            assert_eq!(f.rgba.get(..4), Some(&[10u8, 20, 30, 255][..]));
            if f.size == [426, 240] {
                seen = Some(sd.size);
                break;
            }
        }
        // The side view: 720 x 1280 into 420 x 800 -> factor 1.6 -> 1, capped at 2 by
        // the display limit.
        assert_eq!(seen, Some([360, 640]));
        assert!(r.controls.thread_stats().get("display").is_some());
    }

    #[test]
    fn paused_source_only_steps() {
        let r = Runner::start(
            Box::new(Counting {
                n: 0,
                end: u64::MAX,
                fail_at: None,
            }),
            Box::new(Echo),
            Box::new(|| {}),
        );
        let r = r.expect("threads");
        let c = &r.controls;
        c.paused.store(true, Ordering::SeqCst);
        wait_for_pause_poll(c, c.pause_polls.load(Ordering::SeqCst));
        let before = c.status().pairs;
        c.steps.store(3, Ordering::SeqCst);
        while c.steps.load(Ordering::SeqCst) > 0 {
            std::thread::sleep(Duration::from_millis(1));
        }
        // The last step's pair is complete once the thread polls the pause again.
        wait_for_pause_poll(c, c.pause_polls.load(Ordering::SeqCst));
        assert_eq!(c.status().pairs, before + 3);
        assert!(!c.status().ended);
    }
}
