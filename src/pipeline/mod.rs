//! The pipeline runner shared by replay and the live station: a frame source on its own
//! thread, a bounded queue where the newest frame pair wins, a processing stage that turns
//! frame pairs into [`FitSnapshot`]s, and per-stage timing.
//!
//! The snapshot is deliberately made of plain data (pixels, station-frame points, mm),
//! so the screen, `report.json` and tests read it without knowing the stages' types.
//!
//! Threads: `capture` (runs the [`FrameSource`]) -> [`LatestSlot`] (capacity one, newest
//! wins, dropped frames counted) -> `process` (the caller's [`FrameProcessor`]) ->
//! [`LatestSlot`] of snapshots read by the screen or the replay loop.

pub mod smooth;
pub mod timing;

use crate::camera::StationCalibration;
use crate::mesh::TriMesh;
use glam::{DVec2, DVec3};
use image::RgbImage;
use std::sync::{Arc, Condvar, Mutex};

/// Two frames captured at the same moment.
#[derive(Debug, Clone)]
pub struct FramePair {
    /// Running index from the start of the source (recording frame index for replay).
    pub index: u64,
    /// Capture time in seconds from the start of the source.
    pub timestamp_s: f64,
    /// The frames are shared, not copied, with the screen's snapshot of this pair.
    pub front: Arc<RgbImage>,
    /// The side frame; an empty (0 x 0) image when the side camera gave nothing for this
    /// moment (lost, or a recording whose side folder stops early): the station then fits
    /// from the front view alone ([`FramePair::has_side`]).
    pub side: Arc<RgbImage>,
}

impl FramePair {
    /// False when the side camera gave no frame for this pair (an empty `side`).
    pub fn has_side(&self) -> bool {
        has_frame(&self.side)
    }
}

/// False for the empty image that stands for a frame a camera did not give.
pub fn has_frame(img: &RgbImage) -> bool {
    img.width() > 0 && img.height() > 0
}

/// Why a source could not give a frame pair.
#[derive(Debug, Clone, thiserror::Error)]
pub enum SourceError {
    /// A transient problem (a corrupt frame, a camera hiccup): skip and keep going.
    #[error("frame skipped: {0}")]
    Skipped(String),
    /// The device is gone (unplugged); the source may come back by itself.
    #[error("camera disconnected: {0}")]
    Disconnected(String),
    /// The source cannot continue.
    #[error("{0}")]
    Fatal(String),
}

/// Anything that yields frame pairs: a recording, two cameras, a test generator.
pub trait FrameSource: Send {
    /// The next pair, `Ok(None)` at the end of a finite source.
    fn next_pair(&mut self) -> Result<Option<FramePair>, SourceError>;
    /// The calibration the frames belong to, when known.
    fn calibration(&self) -> Option<&StationCalibration>;
    /// Nominal frame rate (frames per second), when known.
    fn fps(&self) -> Option<f64> {
        None
    }
    /// A short human-readable name ("recording demo", "cameras 0+1").
    fn describe(&self) -> String;
}

/// Where the fit is in its life, as shown to the shopper and the operator.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Phase {
    /// Learning the empty backdrop.
    LearningBackdrop,
    /// Backdrop known, nobody on the mark.
    WaitingForSubject,
    /// A subject is seen but the frame has a bad verdict (see `messages`).
    Guiding,
    /// Fitting frame after frame.
    Fitting,
    /// Measurements have settled.
    Settled,
}

/// One measurement as displayed: value in mm and its frame-to-frame stability.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct MeasurementValue {
    /// Report key, e.g. "chest_girth".
    pub name: String,
    pub value_mm: f64,
    /// Spread of the recent values (mm); small means settled.
    pub stability_mm: f64,
    /// How sure the station is: the value is within `± uncertainty_mm` of the truth
    /// (two standard deviations, `station::uncertainty`); infinite when unknown.
    #[serde(default = "unknown_uncertainty")]
    pub uncertainty_mm: f64,
    /// The uncertainty exceeds the measurement's ANSUR II observer tolerance: the station
    /// did not see this measurement well enough to vouch for it.
    #[serde(default)]
    pub uncertain: bool,
}

fn unknown_uncertainty() -> f64 {
    f64::INFINITY
}

/// Overlay data of one camera view, in that camera's (distorted) pixels.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ViewOverlay {
    /// Silhouette outline (ordered, closed).
    pub contour: Vec<DVec2>,
    /// Named contour parts with their points ("left arm", "torso front", ...).
    pub parts: Vec<(String, Vec<DVec2>)>,
    /// Named landmarks and joints.
    pub landmarks: Vec<(String, DVec2)>,
    /// Skeleton bones as pixel segments.
    pub bones: Vec<(DVec2, DVec2)>,
    /// The fitted avatar's projected silhouette outline, when the processor drew it.
    pub avatar_outline: Vec<DVec2>,
    /// This view's camera, when the avatar's outline is left to the screen: it draws
    /// [`avatar_outline`] of the snapshot's avatar only where an operator looks at it,
    /// on its own thread, instead of the fitting thread projecting it every pair.
    pub camera: Option<crate::camera::Camera>,
}

/// The outline of `av` as `cam` sees it, for the screen: per band of 6 pixel rows its
/// leftmost and rightmost projected vertex, down the left side and up the right side.
pub fn avatar_outline(av: &TriMesh, cam: &crate::camera::Camera) -> Vec<DVec2> {
    const BAND_PX: f64 = 6.0;
    let proj: Vec<DVec2> = av
        .positions
        .iter()
        .filter_map(|p| cam.project(*p))
        .collect();
    if proj.is_empty() {
        return Vec::new();
    }
    let miny = proj.iter().map(|p| p.y).fold(f64::MAX, f64::min);
    let maxy = proj.iter().map(|p| p.y).fold(f64::MIN, f64::max);
    let n = (((maxy - miny) / BAND_PX).ceil() as usize).clamp(1, 2000);
    let mut lo = vec![DVec2::splat(f64::MAX); n];
    let mut hi = vec![DVec2::splat(f64::MIN); n];
    for p in &proj {
        let k = (((p.y - miny) / BAND_PX) as usize).min(n - 1);
        if p.x < lo[k].x {
            lo[k] = *p;
        }
        if p.x > hi[k].x {
            hi[k] = *p;
        }
    }
    let mut out: Vec<DVec2> = lo.into_iter().filter(|p| p.x < f64::MAX).collect();
    out.extend(hi.into_iter().rev().filter(|p| p.x > f64::MIN));
    out
}

/// What processing one frame pair produced: everything the screen and reports show.
#[derive(Debug, Clone)]
pub struct FitSnapshot {
    pub frame_index: u64,
    pub phase: Phase,
    /// Messages for the shopper/operator (frame verdicts, errors), most important first.
    pub messages: Vec<String>,
    /// Faults of the source found on this pair (stall, lost camera, order, corrupt
    /// frame, exposure; `station::faults`), also in `messages`: for the screen and log.
    pub faults: Vec<String>,
    pub front: ViewOverlay,
    pub side: ViewOverlay,
    /// Named landmarks in the station frame (metres).
    pub landmarks_station: Vec<(String, DVec3)>,
    /// The current avatar (station frame, metres), shared to avoid copies.
    pub avatar: Option<Arc<TriMesh>>,
    pub measurements: Vec<MeasurementValue>,
    /// Per-stage durations of this frame, milliseconds, in pipeline order.
    pub timings_ms: Vec<(String, f64)>,
    /// The frames themselves (shared, never written anywhere unless recording).
    pub front_frame: Option<Arc<RgbImage>>,
    pub side_frame: Option<Arc<RgbImage>>,
}

impl FitSnapshot {
    pub fn empty(frame_index: u64, phase: Phase) -> Self {
        FitSnapshot {
            frame_index,
            phase,
            messages: Vec::new(),
            faults: Vec::new(),
            front: ViewOverlay::default(),
            side: ViewOverlay::default(),
            landmarks_station: Vec::new(),
            avatar: None,
            measurements: Vec::new(),
            timings_ms: Vec::new(),
            front_frame: None,
            side_frame: None,
        }
    }
}

/// The processing stage: frame pairs in, snapshots out. Owns all per-frame state.
pub trait FrameProcessor: Send {
    fn process(&mut self, pair: &FramePair) -> FitSnapshot;
    /// Forget the subject (idle timeout, privacy): keep the backdrop and calibration.
    fn reset_subject(&mut self) {}
}

/// A single-slot mailbox: `put` replaces whatever is there (newest wins, the replaced
/// item is counted as dropped), `take` waits for an item. Bounded by construction: a
/// slow consumer never makes the producer queue frames.
pub struct LatestSlot<T> {
    inner: Mutex<SlotState<T>>,
    ready: Condvar,
}

struct SlotState<T> {
    item: Option<T>,
    closed: bool,
    dropped: u64,
}

impl<T> Default for LatestSlot<T> {
    fn default() -> Self {
        Self::new()
    }
}

impl<T> LatestSlot<T> {
    pub fn new() -> Self {
        LatestSlot {
            inner: Mutex::new(SlotState {
                item: None,
                closed: false,
                dropped: 0,
            }),
            ready: Condvar::new(),
        }
    }
    fn lock(&self) -> std::sync::MutexGuard<'_, SlotState<T>> {
        // A poisoned lock only means another thread panicked mid-put; the data is a
        // plain Option and stays usable.
        self.inner.lock().unwrap_or_else(|e| e.into_inner())
    }
    /// Puts an item, replacing (and counting) an unconsumed one.
    pub fn put(&self, item: T) {
        let mut s = self.lock();
        if s.item.replace(item).is_some() {
            s.dropped += 1;
        }
        self.ready.notify_all();
    }
    /// Waits for an item; `None` once closed and empty.
    pub fn take(&self) -> Option<T> {
        let mut s = self.lock();
        loop {
            if let Some(it) = s.item.take() {
                return Some(it);
            }
            if s.closed {
                return None;
            }
            s = self.ready.wait(s).unwrap_or_else(|e| e.into_inner());
        }
    }
    /// Takes an item if one is there, without waiting.
    pub fn try_take(&self) -> Option<T> {
        self.lock().item.take()
    }
    /// No more items will come.
    pub fn close(&self) {
        self.lock().closed = true;
        self.ready.notify_all();
    }
    pub fn is_closed(&self) -> bool {
        self.lock().closed
    }
    /// How many items were replaced before being taken.
    pub fn dropped(&self) -> u64 {
        self.lock().dropped
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A sphere on the mark seen by the nominal front camera: the outline goes down its
    /// left side and up its right, and spans the sphere's projected width and height.
    #[test]
    fn avatar_outline_follows_the_projected_sides() {
        let cal = StationCalibration::nominal(720, 1280, 1100.0, 3.0, 1.1, 1.0);
        let mut ball = crate::mesh::shapes::uv_sphere(0.3, 24, 48);
        for p in &mut ball.positions {
            p.y += 1.0;
        }
        let out = avatar_outline(&ball, &cal.front);
        let proj: Vec<DVec2> = ball
            .positions
            .iter()
            .filter_map(|p| cal.front.project(*p))
            .collect();
        let (x0, x1) = proj
            .iter()
            .fold((f64::MAX, f64::MIN), |(a, b), p| (a.min(p.x), b.max(p.x)));
        let (y0, y1) = proj
            .iter()
            .fold((f64::MAX, f64::MIN), |(a, b), p| (a.min(p.y), b.max(p.y)));
        let (ox0, ox1) = out
            .iter()
            .fold((f64::MAX, f64::MIN), |(a, b), p| (a.min(p.x), b.max(p.x)));
        assert_eq!((ox0, ox1), (x0, x1), "the outline reaches both sides");
        let n = out.len() / 2;
        assert!(
            out[..n].windows(2).all(|w| w[1].y >= w[0].y - 1e-9),
            "left side goes down"
        );
        assert!(
            out[n..].windows(2).all(|w| w[1].y <= w[0].y + 1e-9),
            "right side goes up"
        );
        assert!(out[0].y - y0 < 6.0 && y1 - out[n - 1].y < 6.0);
        // Every point lies on its band's side: none is inside the other side's x.
        assert!(out[..n]
            .iter()
            .zip(out[n..].iter().rev())
            .all(|(l, r)| l.x <= r.x));
        assert!(avatar_outline(&TriMesh::new(Vec::new(), Vec::new()), &cal.front).is_empty());
    }

    #[test]
    fn newest_wins_and_drops_are_counted() {
        let s = LatestSlot::new();
        s.put(1);
        s.put(2);
        s.put(3);
        assert_eq!(s.take(), Some(3));
        assert_eq!(s.dropped(), 2);
        s.close();
        assert_eq!(s.take(), None);
    }

    #[test]
    fn take_waits_for_a_producer() {
        let s = Arc::new(LatestSlot::new());
        let p = s.clone();
        let h = std::thread::spawn(move || {
            for i in 0..100 {
                p.put(i);
            }
            p.close();
        });
        let mut last = -1;
        while let Some(v) = s.take() {
            assert!(v > last);
            last = v;
        }
        h.join().ok();
        assert_eq!(last, 99);
    }
}
