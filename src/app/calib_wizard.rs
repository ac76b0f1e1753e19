//! The operator's calibration wizard on the station screen, driving the same steps as
//! `fitstation calibrate` (`crate::calibrate`, procedure in `calib/README.md`) on live
//! camera frames:
//!
//! 1. **Lenses**: the operator moves the chessboard (or circle grid) in front of each
//!    camera; every frame is searched ([`LensSession::add_frame`]: sharp, new views are
//!    kept) and the found corners are drawn over the views; then Zhang's closed form and
//!    Levenberg-Marquardt give each camera's intrinsics ([`LensSession::calibrate`]). A
//!    camera with no views keeps the lens calibration of the loaded `station.yaml`.
//! 2. **Placement**: the board stands on the mark (turned 45 degrees toward the corner
//!    between the cameras, lowest inner-corner row at a measured height); both cameras
//!    must see it ([`place_camera`]).
//! 3. **Review**: the station checks ([`check_station`]: axis angle, heights, tilts,
//!    standing volume in view, mm per pixel, girth error per pixel); saving never
//!    replaces a `station.yaml` whose lens calibration is better (lower RMS by more than
//!    [`WORSE_RMS_FACTOR`]): the new one goes to `station.new.yaml` unless forced, and a
//!    replaced file is kept as `station.yaml.bak`.
//!
//! [`WizardCore`] is the synchronous state machine (tested on rendered boards);
//! [`CalibrationWizard`] runs it on its own thread so that board detection never stalls
//! the screen: the screen offers the newest frame pair, the worker searches it, and the
//! screen reads the latest [`WizardView`]. Pixels are each camera's own; metres in the
//! station frame (+Y up, +Z toward the front camera); RMS errors in pixels.

use super::operator::{BoardDetection, BoardDetections};
use crate::calibrate::board::{BoardSpec, Target};
use crate::calibrate::cli::WORSE_RMS_FACTOR;
use crate::calibrate::intrinsics::MIN_VIEWS;
use crate::calibrate::{
    check_station, place_camera, CameraPlacement, CornerDetector, FrameOutcome,
    IntrinsicsCalibration, LensSession, Placement, Progress, StationChecks,
};
use crate::camera::{Camera, StationCalibration, View};
use glam::DVec2;
use image::{GrayImage, RgbImage};
use std::path::{Path, PathBuf};
use std::sync::{mpsc, Arc, Mutex};
use std::thread::JoinHandle;

/// The board of `calib/README.md`: 9 x 6 inner corners, 75 mm squares.
pub const DEFAULT_BOARD: BoardSpec = BoardSpec {
    cols: 9,
    rows: 6,
    square_m: 0.075,
};
/// Default height of the placement board's lowest inner-corner row (metres).
pub const DEFAULT_BOARD_HEIGHT_M: f64 = 0.6;

/// What the wizard calibrates with and where it saves.
#[derive(Debug, Clone, PartialEq)]
pub struct WizardSettings {
    pub board: BoardSpec,
    pub target: Target,
    /// Height of the placement board's lowest row of inner corners above the floor (m).
    pub board_height_m: f64,
    /// Where "Save" writes `station.yaml`.
    pub out: PathBuf,
}

impl Default for WizardSettings {
    fn default() -> Self {
        WizardSettings {
            board: DEFAULT_BOARD,
            target: Target::Chessboard,
            board_height_m: DEFAULT_BOARD_HEIGHT_M,
            out: PathBuf::from("station.yaml"),
        }
    }
}

/// The wizard's step.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum WizardStep {
    /// Collecting board views for both lenses.
    #[default]
    Lenses,
    /// Looking for the placement board at the mark.
    Placement,
    /// A station is solved: checks shown, ready to save.
    Review,
}

/// What the operator asks for.
#[derive(Debug, Clone, PartialEq)]
pub enum WizardAction {
    /// Solve both lenses from the collected views (or keep the loaded ones).
    SolveLenses,
    /// Set the measured height of the placement board (millimetres).
    SetBoardHeightMm(f64),
    /// Place both cameras from the last frames that showed the placement board.
    PlaceCameras,
    /// Write `station.yaml` safely (`force`: replace even a better one, keeping a backup).
    Save { force: bool },
    /// Forget everything and start with the lenses again.
    Reset,
}

/// What the screen shows of the wizard.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct WizardView {
    pub step: WizardStep,
    /// Boards found in the last frames searched, for the overlay.
    pub detections: BoardDetections,
    /// One progress line per camera for the current step.
    pub lines: Vec<String>,
    /// The result of the last action (or why it failed), for the operator.
    pub status: String,
    /// The solved station (step Review).
    pub solved: Option<StationCalibration>,
    /// The station checks of the solved station, one line each; `actions` are what
    /// the operator should fix (empty when all is well).
    pub checks: Vec<String>,
    pub actions: Vec<String>,
    /// Where the last save went.
    pub saved: Option<PathBuf>,
    /// Frame pairs searched so far.
    pub frames_searched: u64,
}

/// Where a save went.
#[derive(Debug, Clone, PartialEq)]
pub enum SaveOutcome {
    /// Written to the target; a replaced file was kept at `backup`.
    Written {
        path: PathBuf,
        backup: Option<PathBuf>,
    },
    /// The existing file is better: the new station went to `new_path` instead.
    KeptBetter { new_path: PathBuf, reason: String },
}

/// The wizard's state machine (synchronous; see [`CalibrationWizard`] for the threaded
/// one the screen uses).
pub struct WizardCore {
    settings: WizardSettings,
    /// The calibration loaded at start (lens fallback, and what a save must not worsen).
    base: Option<StationCalibration>,
    detector: CornerDetector,
    sessions: [Option<LensSession>; 2],
    lenses: [Option<IntrinsicsCalibration>; 2],
    /// Placement-board corners last seen by each camera, with that frame's size.
    placement_corners: [Option<(Vec<DVec2>, [u32; 2])>; 2],
    grey: [GrayImage; 2],
    view: WizardView,
}

impl WizardCore {
    pub fn new(settings: WizardSettings, base: Option<StationCalibration>) -> Self {
        let detector = CornerDetector::for_target(settings.target);
        let mut w = WizardCore {
            settings,
            base,
            detector,
            sessions: [None, None],
            lenses: [None, None],
            placement_corners: [None, None],
            grey: [GrayImage::new(1, 1), GrayImage::new(1, 1)],
            view: WizardView::default(),
        };
        w.view.status = w.step_hint();
        w
    }

    pub fn settings(&self) -> &WizardSettings {
        &self.settings
    }

    pub fn view(&self) -> &WizardView {
        &self.view
    }

    fn step_hint(&self) -> String {
        match self.view.step {
            WizardStep::Lenses => format!(
                "Step 1, lenses: hold the {} board ({}x{} inner corners, {:.1} mm) in front of each camera, tilted 20-40 degrees, into every part of the picture; sharp new views are kept by themselves.",
                self.settings.target.name(),
                self.settings.board.cols,
                self.settings.board.rows,
                self.settings.board.square_m * 1e3
            ),
            WizardStep::Placement => format!(
                "Step 2, placement: stand the board upright on the mark, printed side toward the corner between the cameras, lowest inner-corner row {:.0} mm above the floor (set the height you measured).",
                self.settings.board_height_m * 1e3
            ),
            WizardStep::Review => {
                "Step 3, review: check the station, then save station.yaml.".into()
            }
        }
    }

    /// Searches one frame pair for the board (what it does depends on the step).
    pub fn process_frames(&mut self, front: &RgbImage, side: &RgbImage) -> &WizardView {
        self.view.frames_searched += 1;
        let n = self.view.frames_searched;
        let mut detections = BoardDetections::default();
        let mut lines = Vec::new();
        for (k, (view, frame)) in [(View::Front, front), (View::Side, side)]
            .into_iter()
            .enumerate()
        {
            to_grey(frame, &mut self.grey[k]);
            let grey = &self.grey[k];
            let found = match self.view.step {
                WizardStep::Lenses => {
                    let board = self.settings.board;
                    let target = self.settings.target;
                    let session = self.sessions[k].get_or_insert_with(|| {
                        LensSession::new(view.name(), board, grey.width(), grey.height())
                            .with_target(target)
                    });
                    let fb = session.add_frame(&format!("live_{n:05}"), grey);
                    lines.push(format!(
                        "{} lens: {} views kept, {:.0}% of the picture covered{} — last frame: {}",
                        view.name(),
                        fb.accepted_views,
                        fb.coverage * 100.0,
                        if fb.ready { ", ready" } else { "" },
                        outcome_text(&fb.outcome)
                    ));
                    (!fb.corners.is_empty()).then(|| BoardDetection {
                        board: board_name(&self.settings),
                        corners_px: fb.corners,
                        note: outcome_text(&fb.outcome),
                    })
                }
                WizardStep::Placement => match self.detector.detect(grey, &self.settings.board) {
                    Ok(d) => {
                        lines.push(format!(
                            "{}: placement board found ({} corners, edge blur {:.1} px)",
                            view.name(),
                            d.corners.len(),
                            d.blur_sigma_px
                        ));
                        self.placement_corners[k] =
                            Some((d.corners.clone(), [grey.width(), grey.height()]));
                        Some(BoardDetection {
                            board: board_name(&self.settings),
                            corners_px: d.corners,
                            note: "placement board".into(),
                        })
                    }
                    Err(e) => {
                        lines.push(format!("{}: placement board not seen: {e}", view.name()));
                        self.placement_corners[k] = None;
                        None
                    }
                },
                WizardStep::Review => None,
            };
            let slot = if view == View::Front {
                &mut detections.front
            } else {
                &mut detections.side
            };
            slot.extend(found);
        }
        if self.view.step != WizardStep::Review {
            self.view.lines = lines;
        }
        self.view.detections = detections;
        &self.view
    }

    /// Carries out one operator action.
    pub fn act(&mut self, action: WizardAction) -> &WizardView {
        self.view.status = match action {
            WizardAction::Reset => {
                let settings = self.settings.clone();
                let base = self.base.take();
                *self = WizardCore::new(settings, base);
                self.view.status.clone()
            }
            WizardAction::SetBoardHeightMm(mm) => {
                if (0.0..3000.0).contains(&mm) {
                    self.settings.board_height_m = mm / 1e3;
                    format!("placement board height {mm:.0} mm")
                } else {
                    format!("{mm} mm is not a plausible board height (0-3000 mm)")
                }
            }
            WizardAction::SolveLenses => self.solve_lenses(),
            WizardAction::PlaceCameras => self.place_cameras(),
            WizardAction::Save { force } => match self.save(force) {
                Ok(SaveOutcome::Written { path, backup }) => {
                    self.view.saved = Some(path.clone());
                    match backup {
                        Some(b) => format!(
                            "saved {} (the previous one is kept as {})",
                            path.display(),
                            b.display()
                        ),
                        None => format!("saved {}", path.display()),
                    }
                }
                Ok(SaveOutcome::KeptBetter { new_path, reason }) => {
                    self.view.saved = Some(new_path.clone());
                    format!(
                        "NOT replacing {}: the new calibration is worse ({reason}); it is in {}. Collect more or sharper views, or save anyway.",
                        self.settings.out.display(),
                        new_path.display()
                    )
                }
                Err(e) => format!("cannot save: {e}"),
            },
        };
        &self.view
    }

    fn solve_lenses(&mut self) -> String {
        let mut notes = Vec::new();
        let mut quiet = |_: &Progress| {};
        for (k, view) in View::BOTH.into_iter().enumerate() {
            let views = self.sessions[k]
                .as_ref()
                .map(|s| {
                    s.views()
                        .views
                        .iter()
                        .filter(|v| v.detection.is_ok())
                        .count()
                })
                .unwrap_or(0);
            if views == 0 {
                match &self.base {
                    Some(b) => {
                        let i = b.camera(view).intrinsics;
                        notes.push(format!(
                            "{} lens: no views, keeping the loaded calibration ({}x{}, fx {:.1})",
                            view.name(),
                            i.width,
                            i.height,
                            i.fx
                        ));
                        self.lenses[k] = None;
                        continue;
                    }
                    None => {
                        return format!(
                            "{} lens: no board views yet and no station.yaml loaded: show the board to the {} camera ({MIN_VIEWS} views at least, 10-15 recommended)",
                            view.name(),
                            view.name()
                        )
                    }
                }
            }
            let Some(session) = self.sessions[k].as_ref() else {
                continue;
            };
            match session.calibrate(&mut quiet) {
                Ok(c) => {
                    notes.push(format!(
                        "{} lens: RMS {:.3} px over {} views, fx {:.1} fy {:.1}{}",
                        view.name(),
                        c.rms_px,
                        c.used_views,
                        c.intrinsics.fx,
                        c.intrinsics.fy,
                        if c.warnings.is_empty() {
                            String::new()
                        } else {
                            format!(" (WARNING: {})", c.warnings.join("; "))
                        }
                    ));
                    self.lenses[k] = Some(c);
                }
                Err(e) => return e.to_string(),
            }
        }
        self.view.step = WizardStep::Placement;
        self.view.lines = notes.clone();
        format!("{} {}", notes.join("; "), self.step_hint())
    }

    /// Intrinsics of one camera: solved in this session or loaded.
    fn intrinsics(&self, k: usize, view: View) -> Option<crate::camera::Intrinsics> {
        self.lenses[k]
            .as_ref()
            .map(|c| c.intrinsics)
            .or_else(|| self.base.as_ref().map(|b| b.camera(view).intrinsics))
    }

    fn place_cameras(&mut self) -> String {
        if self.view.step == WizardStep::Lenses {
            return "solve the lenses first".into();
        }
        let placement = Placement {
            board: self.settings.board,
            lowest_row_height_m: self.settings.board_height_m,
        };
        let mut placed: Vec<CameraPlacement> = Vec::new();
        let mut intrs = Vec::new();
        for (k, view) in View::BOTH.into_iter().enumerate() {
            let Some(intr) = self.intrinsics(k, view) else {
                return format!("{} lens is not calibrated", view.name());
            };
            let Some((corners, size)) = &self.placement_corners[k] else {
                let other = if k == 0 { 1 } else { 0 };
                return if self.placement_corners[other].is_some() {
                    format!("the placement board is seen by the {} camera only: turn it 45 degrees so that its printed side faces the corner between the cameras (calib/README.md)", View::BOTH[other].name())
                } else {
                    "neither camera sees the placement board: stand it on the mark as in calib/README.md, light it evenly".into()
                };
            };
            if *size != [intr.width, intr.height] {
                return format!(
                    "{} camera frames are {}x{} but its lens calibration is for {}x{}",
                    view.name(),
                    size[0],
                    size[1],
                    intr.width,
                    intr.height
                );
            }
            match place_camera(view, &intr, corners, &placement) {
                Ok(p) => {
                    placed.push(p);
                    intrs.push(intr);
                }
                Err(e) => return e.to_string(),
            }
        }
        let (Some(front), Some(side)) = (placed.first(), placed.get(1)) else {
            return "placing the cameras failed".into();
        };
        let (Some(fi), Some(si)) = (intrs.first(), intrs.get(1)) else {
            return "placing the cameras failed".into();
        };
        let mut station = StationCalibration {
            front: Camera {
                intrinsics: *fi,
                camera_from_station: front.camera_from_station,
            },
            side: Camera {
                intrinsics: *si,
                camera_from_station: side.camera_from_station,
            },
            extra: Vec::new(),
        };
        self.record_extras(&mut station, &placed);
        let checks = check_station(&station);
        self.view.checks = checks_lines(&checks);
        self.view.actions = checks.actions.clone();
        self.view.lines = placed
            .iter()
            .map(|p| {
                let mut l = format!(
                    "{} camera placed: placement board RMS {:.3} px at {:.2} m",
                    p.view.name(),
                    p.rms_px,
                    p.board_distance_m
                );
                for w in &p.warnings {
                    l.push_str(&format!(" (WARNING: {w})"));
                }
                l
            })
            .collect();
        self.view.solved = Some(station);
        self.view.step = WizardStep::Review;
        if checks.all_ok() {
            "station solved; all checks pass. Save station.yaml.".into()
        } else {
            format!(
                "station solved; {} check(s) need attention (see below)",
                checks.actions.len()
            )
        }
    }

    /// The same record keys as `fitstation calibrate` writes.
    fn record_extras(&self, station: &mut StationCalibration, placed: &[CameraPlacement]) {
        let s = &self.settings;
        let e = &mut station.extra;
        e.push(("board".into(), format!("{}x{}", s.board.cols, s.board.rows)));
        e.push(("square_mm".into(), format!("{}", s.board.square_m * 1e3)));
        e.push(("target".into(), s.target.name().into()));
        for (k, view) in View::BOTH.into_iter().enumerate() {
            let (rms, n) = match &self.lenses[k] {
                Some(c) => (
                    Some(format!("{:.4}", c.rms_px)),
                    Some(c.used_views.to_string()),
                ),
                None => (
                    extra_of(self.base.as_ref(), &format!("{}_rms_px", view.name())),
                    extra_of(self.base.as_ref(), &format!("{}_views", view.name())),
                ),
            };
            if let Some(r) = rms {
                e.push((format!("{}_rms_px", view.name()), r));
            }
            if let Some(n) = n {
                e.push((format!("{}_views", view.name()), n));
            }
        }
        for p in placed {
            e.push((
                format!("{}_placement_rms_px", p.view.name()),
                format!("{:.4}", p.rms_px),
            ));
        }
        e.push((
            "board_height_mm".into(),
            format!("{}", s.board_height_m * 1e3),
        ));
        e.push((
            "extrinsics".into(),
            "placement board at the mark (station screen wizard)".into(),
        ));
        let now = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map(|d| d.as_secs())
            .unwrap_or(0);
        e.push(("calibrated_unix_s".into(), now.to_string()));
    }

    /// Writes the solved station to the settings' path without replacing a better one.
    ///
    /// # Errors
    /// Nothing solved yet, or the file cannot be written.
    pub fn save(&self, force: bool) -> Result<SaveOutcome, String> {
        let station = self
            .view
            .solved
            .as_ref()
            .ok_or("nothing to save yet: solve the lenses and place the cameras first")?;
        save_safely(station, &self.settings.out, force)
    }
}

/// Writes `station` to `out` unless `out` holds a calibration whose lens RMS is better
/// by more than [`WORSE_RMS_FACTOR`] (then `station` goes to `<out>.new.yaml`, unless
/// `force`); a replaced file is kept as `<out>.yaml.bak`. (The same rule as
/// `fitstation calibrate`, whose writer prints instead of returning an outcome.)
///
/// # Errors
/// The file cannot be written or backed up.
pub fn save_safely(
    station: &StationCalibration,
    out: &Path,
    force: bool,
) -> Result<SaveOutcome, String> {
    let err = |p: &Path, e: &dyn std::fmt::Display| format!("{}: {e}", p.display());
    if !out.exists() {
        station.save(out).map_err(|e| err(out, &e))?;
        return Ok(SaveOutcome::Written {
            path: out.to_path_buf(),
            backup: None,
        });
    }
    // An unreadable previous file is not "better": it is replaced, with a backup.
    let previous = StationCalibration::load(out).ok();
    let mut worse = Vec::new();
    for view in View::BOTH {
        let key = format!("{}_rms_px", view.name());
        let new = extra_of(Some(station), &key).and_then(|v| v.parse::<f64>().ok());
        let old = extra_of(previous.as_ref(), &key).and_then(|v| v.parse::<f64>().ok());
        if let (Some(o), Some(n)) = (old, new) {
            if n > o * WORSE_RMS_FACTOR {
                worse.push(format!("{} lens {n:.3} px vs {o:.3} px", view.name()));
            }
        }
    }
    if !worse.is_empty() && !force {
        let new_path = out.with_extension("new.yaml");
        station.save(&new_path).map_err(|e| err(&new_path, &e))?;
        return Ok(SaveOutcome::KeptBetter {
            new_path,
            reason: worse.join(", "),
        });
    }
    let backup = out.with_extension("yaml.bak");
    crate::io::atomic::copy(out, &backup).map_err(|e| err(&backup, &e.cause()))?;
    station.save(out).map_err(|e| err(out, &e))?;
    Ok(SaveOutcome::Written {
        path: out.to_path_buf(),
        backup: Some(backup),
    })
}

fn extra_of(cal: Option<&StationCalibration>, key: &str) -> Option<String> {
    cal?.extra
        .iter()
        .find(|(k, _)| k == key)
        .map(|(_, v)| v.clone())
}

fn board_name(s: &WizardSettings) -> String {
    format!("{} {}x{}", s.target.name(), s.board.cols, s.board.rows)
}

/// The station checks as lines for the panel.
pub fn checks_lines(c: &StationChecks) -> Vec<String> {
    c.to_string()
        .lines()
        .map(|l| l.trim().to_string())
        .filter(|l| !l.is_empty() && l != "Station checks")
        .collect()
}

fn outcome_text(o: &FrameOutcome) -> String {
    match o {
        FrameOutcome::Accepted => "kept".into(),
        FrameOutcome::NotFound(e) => format!("no board ({e})"),
        FrameOutcome::Blurred { sigma_px } => {
            format!("blurred (edge sigma {sigma_px:.1} px): hold the board still")
        }
        FrameOutcome::TooSimilar { to } => format!("same as {to}: move or tilt the board"),
        FrameOutcome::WrongSize { width, height } => {
            format!("frame is {width}x{height}, not the size this lens session started with")
        }
    }
}

/// Luma of an RGB frame into `out` (ITU-R BT.601 weights, as the corner detector's
/// photos are read), reusing its buffer.
fn to_grey(frame: &RgbImage, out: &mut GrayImage) {
    let (w, h) = frame.dimensions();
    if out.dimensions() != (w, h) {
        *out = GrayImage::new(w, h);
    }
    for (g, p) in out.pixels_mut().zip(frame.pixels()) {
        let [r, gr, b] = p.0;
        g.0[0] = ((299 * r as u32 + 587 * gr as u32 + 114 * b as u32 + 500) / 1000) as u8;
    }
}

enum Msg {
    Frames(Arc<RgbImage>, Arc<RgbImage>),
    Action(WizardAction),
    /// Answered once everything sent before has been handled.
    Sync(mpsc::Sender<()>),
}

/// The wizard on its own thread: frames and actions go in, the latest [`WizardView`]
/// comes out. Dropping it stops the thread.
pub struct CalibrationWizard {
    tx: Option<mpsc::Sender<Msg>>,
    view: Arc<Mutex<WizardView>>,
    settings: WizardSettings,
    worker: Option<JoinHandle<()>>,
}

impl CalibrationWizard {
    /// Starts the worker; `base` is the calibration in use (lens fallback, and the one a
    /// save must not silently worsen).
    pub fn start(
        settings: WizardSettings,
        base: Option<StationCalibration>,
    ) -> std::io::Result<Self> {
        let (tx, rx) = mpsc::channel::<Msg>();
        let mut core = WizardCore::new(settings.clone(), base);
        let view = Arc::new(Mutex::new(core.view().clone()));
        let out = view.clone();
        let worker = std::thread::Builder::new()
            .name("calibration".into())
            .spawn(move || {
                let publish = |core: &WizardCore| {
                    if let Ok(mut v) = out.lock() {
                        *v = core.view().clone();
                    }
                };
                while let Ok(first) = rx.recv() {
                    // Everything waiting, in order; of several frame pairs only the
                    // newest is searched (detection is slower than the cameras).
                    let mut batch = vec![first];
                    batch.extend(rx.try_iter());
                    let last_frames = batch.iter().rposition(|m| matches!(m, Msg::Frames(..)));
                    for (i, m) in batch.into_iter().enumerate() {
                        match m {
                            Msg::Frames(f, s) if Some(i) == last_frames => {
                                core.process_frames(&f, &s);
                            }
                            Msg::Frames(..) => {}
                            Msg::Action(a) => {
                                core.act(a);
                            }
                            Msg::Sync(done) => {
                                publish(&core);
                                let _ = done.send(());
                            }
                        }
                    }
                    publish(&core);
                }
            })?;
        Ok(CalibrationWizard {
            tx: Some(tx),
            view,
            settings,
            worker: Some(worker),
        })
    }

    pub fn settings(&self) -> &WizardSettings {
        &self.settings
    }

    fn send(&self, m: Msg) {
        if let Some(tx) = &self.tx {
            // A stopped worker (it never panics on data) only means no more updates.
            let _ = tx.send(m);
        }
    }

    /// Offers the newest frame pair for board detection.
    pub fn offer_frames(&self, front: Arc<RgbImage>, side: Arc<RgbImage>) {
        self.send(Msg::Frames(front, side));
    }

    pub fn act(&self, action: WizardAction) {
        self.send(Msg::Action(action));
    }

    /// The latest state.
    pub fn view(&self) -> WizardView {
        self.view.lock().map(|v| v.clone()).unwrap_or_default()
    }

    /// Waits until everything sent so far has been handled (tests, and a final save).
    pub fn sync(&self) {
        let (done_tx, done_rx) = mpsc::channel();
        self.send(Msg::Sync(done_tx));
        let _ = done_rx.recv();
    }
}

impl Drop for CalibrationWizard {
    fn drop(&mut self) {
        self.tx = None;
        if let Some(w) = self.worker.take() {
            let _ = w.join();
        }
    }
}
