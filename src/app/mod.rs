//! The station on screen (egui + wgpu through eframe): both camera views with the
//! silhouette contour, contour parts, landmarks and skeleton drawn over them; the avatar
//! in 3-D; the measurements with their stability; per-stage timings and frame rates; the
//! shopper's kiosk flow ([`flow`]) and the operator's tools (calibration hook,
//! recording, replay controls, exports, hand edits of the avatar ([`edit_tool`]): a
//! primary-button drag on the avatar moves the surface and the measurements follow).
//!
//! Entry point: [`run`] with any [`FrameSource`] and [`FrameProcessor`]; `fitstation
//! demo-ui` runs it on the synthetic [`demo`] station. Threads: see [`runner`]. The
//! screen owns the displayed snapshot, the textures and the flow; it uploads a camera
//! frame to the GPU only when a new one arrives, box-filtered to the view's size on
//! screen ([`frame_view`] draws it without blending); panels have no fills and the
//! avatar's picture is drawn only over the body: on a software renderer every covered
//! pixel costs, every frame. Overlay coordinates are the cameras' pixels; the avatar is
//! in the station frame (metres).

pub mod avatar3d;
pub mod calib_wizard;
pub mod demo;
mod demo_ui;
pub mod display;
mod edit_tool;
pub mod export;
pub mod flow;
pub mod frame_view;
pub mod live;
pub mod operator;
mod orbit;
mod panels;
pub mod record;
pub mod runner;
pub mod session;
pub mod stats;
mod summary;
mod tools;
pub mod trace;
pub mod ui_script;
mod views;

pub use demo_ui::{run_demo_cli, DemoUiArgs};
pub use live::{run_live_cli, LiveArgs};
pub use summary::{thread_cpu_seconds, RunSummary};

use crate::camera::StationCalibration;
use crate::pipeline::{FitSnapshot, FrameProcessor, FrameSource, MeasurementValue, ViewOverlay};
use avatar3d::{AvatarCallback, AvatarJob, AvatarRenderer, OrbitCamera, ViewPreset};
use calib_wizard::{CalibrationWizard, WizardAction, WizardSettings, WizardStep, WizardView};
use egui::{Color32, Pos2, Rect, RichText, Stroke, Vec2};
use flow::{FlowAction, FlowConfig, FlowInput, FlowState, KioskFlow};
use runner::Runner;
use std::collections::VecDeque;
use std::path::{Path, PathBuf};
use std::sync::atomic::Ordering;
use std::sync::{Arc, Mutex};
use std::time::Instant;

/// The window's background (sRGB), drawn by the clear at no cost: panels have no fill
/// of their own (on a software renderer every filled pixel costs, every frame).
pub const SCREEN_BACKGROUND_RGB: [u8; 3] = [22, 23, 27];

/// A measurement whose recent spread is below this is shown as settled (mm).
pub const STABLE_MM: f64 = 3.0;
/// Spread above which a measurement is shown as unstable (mm).
pub const UNSTABLE_MM: f64 = 10.0;

/// How the screen starts and what it is connected to.
pub struct AppOptions {
    pub title: String,
    /// Start in operator mode (tools visible) instead of the kiosk.
    pub operator: bool,
    /// Save a screenshot of the window after `exit_after_frames` frames, then exit.
    pub screenshot: Option<PathBuf>,
    /// Close the window after this many frames (after the screenshot, if any).
    pub exit_after_frames: Option<u64>,
    pub flow: FlowConfig,
    /// Board, target and output path of the operator's calibration wizard.
    pub wizard: WizardSettings,
    /// Builds the station processor for a calibration: used when the operator puts a
    /// newly solved calibration to use, or asks to learn the backdrop again. `None`:
    /// the processor given to [`run`] stays.
    pub processor_factory: Option<ProcessorFactory>,
    /// Called once when the backdrop has been learnt (live cameras lock exposure and
    /// white balance then).
    pub on_backdrop_learned: Option<Box<dyn FnMut() + Send>>,
    /// Where the operator's recordings and exports go by default.
    pub record_dir: PathBuf,
    pub export_dir: PathBuf,
    /// Initial window size in points.
    pub window_size: [f32; 2],
    /// Scripted input for window tests ([`ui_script`]); empty: none.
    pub ui_script: Vec<ui_script::ScriptStep>,
    /// Where the screen's hand edits are written as JSON at exit (window tests).
    pub edits_out: Option<PathBuf>,
}

impl Default for AppOptions {
    fn default() -> Self {
        AppOptions {
            title: "fitstation".into(),
            operator: false,
            screenshot: None,
            exit_after_frames: None,
            flow: FlowConfig::default(),
            wizard: WizardSettings::default(),
            processor_factory: None,
            on_backdrop_learned: None,
            record_dir: PathBuf::from("recordings"),
            export_dir: PathBuf::from("fitstation-export"),
            window_size: [1600.0, 900.0],
            ui_script: Vec::new(),
            edits_out: None,
        }
    }
}

/// Builds a frame processor for a station calibration (or says why it cannot).
pub type ProcessorFactory =
    Box<dyn Fn(&StationCalibration) -> Result<Box<dyn FrameProcessor>, String> + Send>;

/// Why the screen could not run.
#[derive(Debug, thiserror::Error)]
pub enum AppError {
    #[error("cannot open the station window: {0} (is there a display? under CI use xvfb-run)")]
    Window(String),
    #[error("cannot start the pipeline threads: {0}")]
    Threads(#[from] std::io::Error),
}

/// Runs the station screen until the window closes.
///
/// # Errors
/// [`AppError::Window`] when no window/GPU adapter can be had (no display).
pub fn run(
    source: Box<dyn FrameSource>,
    processor: Box<dyn FrameProcessor>,
    opts: AppOptions,
) -> Result<RunSummary, AppError> {
    let native = eframe::NativeOptions {
        viewport: egui::ViewportBuilder::default()
            .with_title(opts.title.clone())
            .with_inner_size(opts.window_size),
        ..Default::default()
    };
    let mut native = native;
    // Dithering costs a little per pixel on software renderers and is invisible here.
    native.dithering = false;
    // The screen refreshes when snapshots arrive; waiting for vsync would only add latency.
    native.wgpu_options.surface.present_mode = wgpu::PresentMode::AutoNoVsync;
    let summary = Arc::new(Mutex::new(RunSummary::default()));
    let summary_out = summary.clone();
    let title = opts.title.clone();
    eframe::run_native(
        &title,
        native,
        Box::new(move |cc| {
            let rs = cc
                .wgpu_render_state
                .as_ref()
                .ok_or_else(|| AppError::Window("the wgpu renderer is not available".into()))?;
            rs.renderer
                .write()
                .callback_resources
                .insert(frame_view::FrameViewResources::new(
                    &rs.device,
                    rs.target_format,
                ));
            let ctx = cc.egui_ctx.clone();
            let mut app = StationApp::new(
                source,
                processor,
                opts,
                // A zero delay would make egui paint twice per snapshot (its
                // `request_repaint` always schedules a second pass); any non-zero
                // delay asks for exactly one.
                Box::new(move || ctx.request_repaint_after(SNAPSHOT_REPAINT_DELAY)),
                summary,
            )?;
            let ctx = cc.egui_ctx.clone();
            app.avatar = Some(AvatarRenderer::start(
                rs.device.clone(),
                rs.queue.clone(),
                rs.target_format,
                app.clock.clone(),
                // A new picture is shown by the next snapshot's frame; this one is
                // painted only when none comes sooner (see AVATAR_FALLBACK_S).
                Box::new(move || {
                    ctx.request_repaint_after(std::time::Duration::from_secs_f64(
                        AVATAR_PICTURE_REPAINT_S,
                    ))
                }),
            )?);
            Ok(Box::new(app))
        }),
    )
    .map_err(|e| AppError::Window(e.to_string()))?;
    let s = summary_out.lock().map(|s| s.clone()).unwrap_or_default();
    Ok(s)
}

/// Rates over the last second from event times.
#[derive(Debug, Default)]
struct RateMeter {
    times: VecDeque<f64>,
}

impl RateMeter {
    fn tick(&mut self, now_s: f64) {
        self.times.push_back(now_s);
        while self.times.front().is_some_and(|&t| now_s - t > 1.0) {
            self.times.pop_front();
        }
    }
    fn rate(&self, now_s: f64) -> f64 {
        self.times.iter().filter(|&&t| now_s - t <= 1.0).count() as f64
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Mode {
    Kiosk,
    Operator,
}

/// A camera view's display image ([`frame_view`] uploads it when `generation` changes)
/// and the size of the frame it came from.
struct ViewTexture {
    /// 0 front, 1 side.
    slot: usize,
    image: Arc<display::DisplayImage>,
    generation: u64,
    frame_size: [u32; 2],
}

enum ScreenshotState {
    None,
    Waiting(Arc<Mutex<Option<Arc<egui::ColorImage>>>>, PathBuf),
}

/// Where the views and the avatar were drawn (points), for the screenshot's layout file.
#[derive(Debug, Clone, Copy, Default)]
struct Layout {
    front: Option<Rect>,
    side: Option<Rect>,
    avatar: Option<Rect>,
}

/// The avatar's outlines on the operator's screen: (frame index, avatar), front and side.
type OutlineCache = ((u64, Option<usize>), [Vec<glam::DVec2>; 2]);

struct StationApp {
    runner: Runner,
    describe: String,
    calibration: Option<StationCalibration>,
    fps: Option<f64>,
    current: Option<FitSnapshot>,
    flow: KioskFlow,
    start: Instant,
    mode: Mode,
    front_tex: Option<ViewTexture>,
    side_tex: Option<ViewTexture>,
    /// Size of each camera view on screen at the last frame (pixels).
    view_px: Option<[f32; 2]>,
    avatar_generation: u64,
    /// The avatar's outline in the front and side views for the operator's screen, and
    /// the snapshot (frame index, avatar) it belongs to ([`StationApp::refresh_outlines`]).
    outlines: Option<OutlineCache>,
    /// The avatar drawn in the 3-D view (the newest fit, at most every
    /// [`AVATAR_PERIOD_S`]) and when it was taken.
    shown_avatar: Option<Arc<crate::mesh::TriMesh>>,
    avatar_shown_s: f64,
    orbit: OrbitCamera,
    /// Renders the avatar between frames (set once the window exists).
    avatar: Option<AvatarRenderer>,
    /// The picture drawn in the avatar view this frame shows a fitted avatar.
    avatar_on_screen: bool,
    /// The operator zoomed by hand: stop fitting the avatar into the view.
    user_zoomed: bool,
    ui_meter: RateMeter,
    snap_meter: RateMeter,
    ui_stats: stats::RollingStats,
    pipeline_stats: stats::RollingStats,
    /// Ends of the screen's frames (frame rate, latency to the present).
    clock: stats::FrameClock,
    /// The timings table as last summarised, and when (seconds since start).
    timings_table: Vec<(String, Option<f64>, stats::Summary)>,
    timings_table_s: f64,
    frames: u64,
    snapshots_shown: u64,
    screenshot_at: Option<u64>,
    auto_shot_requested: bool,
    screenshot_path: Option<PathBuf>,
    exit_after: Option<u64>,
    screenshot: ScreenshotState,
    layout: Layout,
    wizard_settings: WizardSettings,
    /// Started when the operator first turns on live board detection.
    wizard: Option<CalibrationWizard>,
    wizard_live: bool,
    wizard_view: WizardView,
    board_height_mm: f64,
    processor_factory: Option<ProcessorFactory>,
    on_backdrop_learned: Option<Box<dyn FnMut() + Send>>,
    record_dir: String,
    export_dir: String,
    operator_log: VecDeque<String>,
    summary: Arc<Mutex<RunSummary>>,
    closing: bool,
    /// Arrival time of the pair behind the snapshot taken this frame (latency figure).
    pending_arrival: Option<Instant>,
    /// Snapshots published by the process thread when the slot was last looked at.
    published_seen: u64,
    /// The last source fault the station reported and when (seconds since start).
    last_fault: Option<(String, f64)>,
    /// When the last snapshot came (seconds since start), for the stall warning.
    last_snapshot_s: f64,
    /// The operator's hand edits of the avatar ([`edit_tool`]).
    edit: edit_tool::EditTool,
    script: Option<ui_script::ScriptPlayer>,
    edits_out: Option<PathBuf>,
}

/// How long a source fault stays in the top bar after it was reported (seconds).
const FAULT_SHOWN_S: f64 = 3.0;
/// No snapshot for this long (seconds) while the source runs is shown as a stall.
const STALL_SHOWN_S: f64 = 1.0;

/// Frames an automatic screenshot waits beyond its frame for a fitted avatar.
const SCREENSHOT_GRACE_FRAMES: u64 = 600;

/// Shortest time between two renders of the 3-D avatar (seconds): it deforms live at
/// up to 10 renders a second, and the software renderer is spared a mesh pass per
/// snapshot.
pub const AVATAR_PERIOD_S: f64 = 0.1;
/// How much earlier than [`AVATAR_PERIOD_S`] a new avatar may be taken, so that with
/// snapshots every 1/30 s it is taken on every third one, not the fourth.
const AVATAR_PERIOD_SLACK_S: f64 = 0.015;
/// How long after a new avatar picture is ready a frame is painted for it alone, when
/// no snapshot's frame came in the meantime (seconds).
const AVATAR_PICTURE_REPAINT_S: f64 = 0.1;
/// How long after the avatar is due a frame is painted for it alone, when no snapshot
/// came in the meantime (paused or ended source). Longer than a source frame interval.
const AVATAR_FALLBACK_S: f64 = 0.1;

/// Station messages of the current snapshot shown to the operator.
const MESSAGES_SHOWN: usize = 4;

/// Lines kept in the operator's log.
const LOG_LINES: usize = 8;

impl StationApp {
    fn new(
        source: Box<dyn FrameSource>,
        processor: Box<dyn FrameProcessor>,
        opts: AppOptions,
        notify: Box<dyn Fn() + Send>,
        summary: Arc<Mutex<RunSummary>>,
    ) -> Result<Self, AppError> {
        let describe = source.describe();
        let calibration = source.calibration().cloned();
        let fps = source.fps();
        let runner = Runner::start(source, processor, notify)?;
        let exit_after = opts.exit_after_frames;
        Ok(StationApp {
            runner,
            describe,
            calibration,
            fps,
            current: None,
            flow: KioskFlow::new(opts.flow),
            start: Instant::now(),
            mode: if opts.operator {
                Mode::Operator
            } else {
                Mode::Kiosk
            },
            front_tex: None,
            side_tex: None,
            view_px: None,
            avatar_generation: 0,
            outlines: None,
            shown_avatar: None,
            avatar_shown_s: f64::NEG_INFINITY,
            orbit: OrbitCamera::default(),
            avatar: None,
            avatar_on_screen: false,
            user_zoomed: false,
            ui_meter: RateMeter::default(),
            snap_meter: RateMeter::default(),
            ui_stats: stats::RollingStats::default(),
            pipeline_stats: stats::RollingStats::default(),
            clock: stats::FrameClock::default(),
            timings_table: Vec::new(),
            timings_table_s: f64::NEG_INFINITY,
            frames: 0,
            snapshots_shown: 0,
            screenshot_at: opts.screenshot.as_ref().and(exit_after),
            auto_shot_requested: false,
            screenshot_path: opts.screenshot,
            exit_after,
            screenshot: ScreenshotState::None,
            layout: Layout::default(),
            board_height_mm: opts.wizard.board_height_m * 1e3,
            wizard_settings: opts.wizard,
            wizard: None,
            wizard_live: false,
            wizard_view: WizardView::default(),
            processor_factory: opts.processor_factory,
            on_backdrop_learned: opts.on_backdrop_learned,
            record_dir: opts.record_dir.display().to_string(),
            export_dir: opts.export_dir.display().to_string(),
            operator_log: VecDeque::new(),
            summary,
            closing: false,
            pending_arrival: None,
            published_seen: 0,
            last_fault: None,
            last_snapshot_s: 0.0,
            edit: {
                let mut e = edit_tool::EditTool::default();
                if opts.edits_out.is_some() {
                    e.keep_record();
                }
                e
            },
            script: (!opts.ui_script.is_empty())
                .then(|| ui_script::ScriptPlayer::new(opts.ui_script)),
            edits_out: opts.edits_out,
        })
    }

    fn now_s(&self) -> f64 {
        self.start.elapsed().as_secs_f64()
    }

    fn log(&mut self, line: String) {
        self.operator_log.push_back(line);
        while self.operator_log.len() > LOG_LINES {
            self.operator_log.pop_front();
        }
    }

    /// Takes the newest snapshot, feeds the flow, takes its display images.
    fn poll_snapshot(&mut self) {
        let now = self.now_s();
        self.published_seen = self.runner.controls.published.load(Ordering::SeqCst);
        if let Some(shown) = self.runner.snapshots.try_take() {
            let runner::ScreenSnapshot {
                snap,
                front_display,
                side_display,
            } = shown;
            self.snapshots_shown += 1;
            trace::ev("snapshot", snap.frame_index);
            self.note_faults(&snap.faults, now);
            self.snap_meter.tick(now);
            self.pipeline_stats.add_all(&snap.timings_ms);
            self.pending_arrival = self.runner.controls.arrival(snap.frame_index);
            let was_learning = matches!(self.flow.state(), FlowState::LearningBackdrop);
            let action = self.flow.on_snapshot(&FlowInput::from_snapshot(&snap), now);
            if was_learning && !matches!(self.flow.state(), FlowState::LearningBackdrop) {
                if let Some(f) = self.on_backdrop_learned.as_mut() {
                    f();
                }
            }
            if let Some(d) = front_display {
                show_image(&mut self.front_tex, 0, d);
            }
            if let Some(d) = side_display {
                show_image(&mut self.side_tex, 1, d);
            }
            if self.wizard_live {
                if let (Some(w), Some(f), Some(sd)) =
                    (&self.wizard, &snap.front_frame, &snap.side_frame)
                {
                    w.offer_frames(f.clone(), sd.clone());
                }
            }
            self.current = Some(snap);
            if action == Some(FlowAction::ClearSubject) {
                self.clear_subject();
            }
        } else if self.flow.on_tick(now) == Some(FlowAction::ClearSubject) {
            self.clear_subject();
        }
    }

    /// Privacy: forget everything about the shopper on screen and in the processor.
    /// Hand edits go too, unless the operator is editing (then they go with Discard
    /// edits or Reset shopper).
    fn clear_subject(&mut self) {
        if self.edit.frozen() && self.edit.on {
            self.log("the shopper was cleared: hand edits kept while editing".into());
        } else {
            if self.edit.frozen() {
                self.log("the shopper was cleared: hand edits discarded".into());
            }
            self.edit.discard();
        }
        self.runner
            .controls
            .reset_subject
            .store(true, Ordering::Relaxed);
        if let Some(s) = self.current.as_mut() {
            s.avatar = None;
            s.measurements.clear();
            s.landmarks_station.clear();
            s.front = ViewOverlay::default();
            s.side = ViewOverlay::default();
        }
    }

    /// Keeps the newest source fault for the top bar and the operator's log.
    fn note_faults(&mut self, faults: &[String], now: f64) {
        self.last_snapshot_s = now;
        for f in faults {
            self.log(format!("fault: {f}"));
            self.last_fault = Some((f.clone(), now));
        }
    }

    /// The source fault line of the top bar: a stall in progress, else the last fault
    /// reported in the past [`FAULT_SHOWN_S`].
    fn fault_line(&self, now: f64, st: &runner::SourceStatus) -> Option<String> {
        let quiet_s = now - self.last_snapshot_s;
        let paused = self.runner.controls.paused.load(Ordering::Relaxed);
        if self.snapshots_shown > 0 && quiet_s > STALL_SHOWN_S && !st.ended && !paused {
            return Some(format!(
                "No frames for {quiet_s:.0} s: last measurements kept"
            ));
        }
        self.last_fault
            .as_ref()
            .filter(|(_, t)| now - t < FAULT_SHOWN_S)
            .map(|(f, _)| f.clone())
    }

    fn request_screenshot(&mut self, ctx: &egui::Context, path: PathBuf) {
        let slot = Arc::new(Mutex::new(None));
        let s2 = slot.clone();
        ctx.request_screenshot(move |img| {
            if let Ok(mut s) = s2.lock() {
                *s = Some(img);
            }
        });
        self.screenshot = ScreenshotState::Waiting(slot, path);
    }

    /// Saves a finished screenshot; returns true when one was saved this frame.
    fn poll_screenshot(&mut self, ctx: &egui::Context) -> bool {
        let ScreenshotState::Waiting(slot, path) = &self.screenshot else {
            return false;
        };
        let img = slot.lock().ok().and_then(|mut s| s.take());
        let Some(img) = img else {
            ctx.request_repaint();
            return false;
        };
        let path = path.clone();
        self.screenshot = ScreenshotState::None;
        match save_screenshot(&path, &img, &self.layout, ctx.pixels_per_point()) {
            Ok(()) => {
                self.log(format!("screenshot {}", path.display()));
                if let Ok(mut s) = self.summary.lock() {
                    s.screenshot = Some(path);
                }
            }
            Err(e) => {
                eprintln!("screenshot failed: {e}");
                self.log(format!("screenshot failed: {e}"));
            }
        }
        true
    }

    /// Writes what the hand edits did to `--ui-edits-out` (window tests).
    fn write_edits_out(&self) {
        let Some(path) = &self.edits_out else {
            return;
        };
        let mut record = self.edit.record_json();
        if let Some(o) = record.as_object_mut() {
            // The avatar view's turn, so that a test can tell an orbit from an edit.
            o.insert("orbit_yaw_rad".into(), serde_json::json!(self.orbit.yaw));
            let view = self
                .layout
                .avatar
                .map(|r| [r.min.x, r.min.y, r.max.x, r.max.y]);
            o.insert("avatar_view_pt".into(), serde_json::json!(view));
        }
        let text = serde_json::to_string_pretty(&record).unwrap_or_default();
        if let Err(e) = crate::io::atomic::write(path, text) {
            eprintln!("cannot write {}: {e}", path.display());
        }
    }

    fn write_summary(&self) {
        let now = self.now_s();
        if let Ok(mut s) = self.summary.lock() {
            s.ui_frames = self.frames;
            s.seconds = now;
            s.snapshots_shown = self.snapshots_shown;
            s.dropped_pairs = self.runner.dropped_pairs();
            s.recent_snapshot_fps = self.snap_meter.rate(now);
            s.recent_ui_fps = self.ui_meter.rate(now);
            s.cpu_seconds = summary::process_cpu_seconds();
            s.thread_cpu = thread_cpu_seconds();
            let mut all = self.runner.controls.thread_stats().summary();
            all.extend(
                self.ui_stats
                    .summary()
                    .into_iter()
                    .map(|(n, v)| (format!("screen {n}"), v)),
            );
            s.ui_timings = all.into_iter().map(|(n, v)| (n, v.median, v.p95)).collect();
            let clock = self.clock.stats();
            s.presented_frames = self.clock.frames();
            s.frame_rate = clock
                .get(stats::FRAME_INTERVAL)
                .map(|i| stats::FrameRate::from_intervals(&i));
            s.frame_to_present = clock.get(stats::FRAME_TO_PRESENT);
            s.latency = clock.get(stats::ARRIVAL_TO_PRESENT);
        }
    }
}

impl eframe::App for StationApp {
    fn ui(&mut self, ui: &mut egui::Ui, _frame: &mut eframe::Frame) {
        let t0 = Instant::now();
        trace::ev("frame_start", self.frames);
        let ctx = ui.ctx().clone();
        if ctx.input(|i| i.viewport().close_requested()) {
            self.closing = true;
        }
        self.frames += 1;
        let now = self.now_s();
        self.ui_meter.tick(now);
        self.poll_snapshot();

        // Panels without fills: the clear colour is their background.
        let bare = || egui::Frame::NONE.inner_margin(PANEL_MARGIN);
        egui::Panel::top("top")
            .frame(bare())
            .show(ui, |ui| self.top_bar(ui));
        egui::Panel::bottom("kiosk")
            .frame(bare())
            .show(ui, |ui| self.kiosk_banner(ui));
        egui::Panel::right("measurements")
            .frame(bare())
            .default_size(320.0)
            .show(ui, |ui| self.measurements_panel(ui));
        if self.mode == Mode::Operator {
            egui::Panel::left("operator")
                .frame(bare())
                .default_size(340.0)
                .show(ui, |ui| self.operator_panel(ui));
        }
        // No panel fill behind the views: on a software renderer every covered pixel
        // costs (the window's clear colour is the background).
        egui::CentralPanel::no_frame().show(ui, |ui| self.views(ui));

        self.ui_stats.add("ui", t0.elapsed().as_secs_f64() * 1e3);
        trace::ev("ui_done", self.frames);
        // The end of this frame (its present) is noted when egui-wgpu drops this
        // callback; a 1-point rectangle in the window's corner, so it is not culled.
        let probe = self.clock.probe(t0, self.pending_arrival.take());
        ui.painter()
            .add(eframe::egui_wgpu::Callback::new_paint_callback(
                Rect::from_min_size(Pos2::ZERO, Vec2::splat(1.0)),
                stats::FrameEndCallback { probe },
            ));
        // Screenshot and exit handling (CLI --screenshot / --exit-after-frames): the
        // automatic screenshot is due after N frames and waits (at most
        // SCREENSHOT_GRACE_FRAMES more) for a frame that shows a fitted avatar.
        let has_avatar = self.avatar_on_screen;
        if let (Some(n), Some(p)) = (self.screenshot_at, self.screenshot_path.clone()) {
            let idle = matches!(self.screenshot, ScreenshotState::None);
            if idle
                && self.frames >= n
                && (has_avatar || self.frames >= n + SCREENSHOT_GRACE_FRAMES)
            {
                self.request_screenshot(&ctx, p);
                self.screenshot_at = None;
                self.auto_shot_requested = true;
            }
        }
        let saved = self.poll_screenshot(&ctx);
        if saved && self.auto_shot_requested {
            self.auto_shot_requested = false;
        }
        let waiting = matches!(self.screenshot, ScreenshotState::Waiting(..));
        let shot_outstanding = self.screenshot_at.is_some() || self.auto_shot_requested || waiting;
        let exit_due = self.exit_after.is_some_and(|n| self.frames >= n);
        // Never hang on a screenshot that does not come (a broken integration).
        let overdue = self
            .exit_after
            .is_some_and(|n| self.frames >= n + 2 * SCREENSHOT_GRACE_FRAMES);
        if exit_due && (!shot_outstanding || overdue) {
            self.write_summary();
            ctx.send_viewport_cmd(egui::ViewportCommand::Close);
        } else if exit_due {
            ctx.request_repaint();
        }
        if self.closing {
            self.write_summary();
        }
        // Keep the countdown, the timeouts and the recording light moving without
        // snapshots; otherwise the screen repaints only when something new arrives.
        let wake_ms = if matches!(self.flow.state(), FlowState::HoldStill { .. }) {
            COUNTDOWN_REPAINT_MS
        } else {
            IDLE_REPAINT_MS
        };
        ctx.request_repaint_after(std::time::Duration::from_millis(wake_ms));
        // The next snapshot wakes the screen; one published since the slot was looked at
        // (it found the flag still clear) is picked up by a frame asked for here.
        let c = &self.runner.controls;
        c.wake_wanted.store(true, Ordering::SeqCst);
        if c.published.load(Ordering::SeqCst) != self.published_seen {
            ctx.request_repaint_after(SNAPSHOT_REPAINT_DELAY);
        }
    }

    fn clear_color(&self, _visuals: &egui::Visuals) -> [f32; 4] {
        let [r, g, b] = SCREEN_BACKGROUND_RGB;
        Color32::from_rgb(r, g, b).to_normalized_gamma_f32()
    }

    fn raw_input_hook(&mut self, ctx: &egui::Context, raw_input: &mut egui::RawInput) {
        self.play_script(ctx, raw_input);
    }

    fn on_exit(&mut self) {
        self.write_edits_out();
        trace::dump();
        self.write_summary();
        self.stop_recording();
    }
}

/// Puts a new display image into `slot` (uploaded by the paint callback once).
fn show_image(slot: &mut Option<ViewTexture>, index: usize, image: Arc<display::DisplayImage>) {
    if slot.as_ref().is_some_and(|t| Arc::ptr_eq(&t.image, &image)) {
        return;
    }
    let generation = slot.as_ref().map_or(1, |t| t.generation + 1);
    *slot = Some(ViewTexture {
        slot: index,
        frame_size: image.frame_size,
        image,
        generation,
    });
}

/// Delay of the repaint asked for by a new snapshot (see [`run`]).
const SNAPSHOT_REPAINT_DELAY: std::time::Duration = std::time::Duration::from_micros(1);

/// Timings rows shown in Kiosk mode (Operator mode shows them all).
const KIOSK_TIMINGS: [&str; 3] = [
    "process",
    "screen ui to present",
    "screen arrival to screen",
];

/// How often the timings table is summarised again (seconds).
const TIMINGS_REFRESH_S: f64 = 0.5;

/// Repaint period while the hold-still countdown runs, and otherwise without new
/// snapshots (timeouts, the recording light), milliseconds.
const COUNTDOWN_REPAINT_MS: u64 = 100;
const IDLE_REPAINT_MS: u64 = 500;
/// Inner margin of the panels (points).
const PANEL_MARGIN: f32 = 6.0;

/// Writes the screenshot PNG and `<stem>.layout.json` with the pixel rects of the views.
fn save_screenshot(
    path: &Path,
    img: &egui::ColorImage,
    layout: &Layout,
    ppp: f32,
) -> Result<(), String> {
    let [w, h] = img.size;
    let mut rgb = image::RgbImage::new(w as u32, h as u32);
    for (px, c) in rgb.pixels_mut().zip(img.pixels.iter()) {
        *px = image::Rgb([c.r(), c.g(), c.b()]);
    }
    crate::io::atomic::save_image(path, &rgb).map_err(|e| e.to_string())?;
    let px =
        |r: Option<Rect>| r.map(|r| [r.min.x * ppp, r.min.y * ppp, r.max.x * ppp, r.max.y * ppp]);
    let json = serde_json::json!({
        "width": w, "height": h, "pixels_per_point": ppp,
        "front": px(layout.front), "side": px(layout.side), "avatar": px(layout.avatar),
        "avatar_rgb": avatar3d::AVATAR_RGB,
    });
    let lp = layout_path(path);
    crate::io::atomic::write(&lp, serde_json::to_string_pretty(&json).unwrap_or_default())
        .map_err(|e| e.to_string())?;
    Ok(())
}

/// Where the layout of a screenshot is written: `shot.png` -> `shot.layout.json`.
pub fn layout_path(screenshot: &Path) -> PathBuf {
    screenshot.with_extension("layout.json")
}

#[cfg(test)]
mod tests {
    use super::views::{screen_polyline, OUTLINE_MIN_SEGMENT};
    use super::*;

    #[test]
    fn rate_meter_counts_the_last_second() {
        let mut m = RateMeter::default();
        for k in 0..90 {
            m.tick(k as f64 / 30.0);
        }
        let now = 89.0 / 30.0;
        assert!((m.rate(now) - 31.0).abs() <= 1.0, "{}", m.rate(now));
    }

    #[test]
    fn outlines_keep_points_a_segment_apart() {
        let pts: Vec<Pos2> = (0..100).map(|k| Pos2::new(k as f32 * 0.5, 0.0)).collect();
        let kept = screen_polyline(pts.into_iter());
        assert_eq!(kept.first(), Some(&Pos2::new(0.0, 0.0)));
        assert_eq!(kept.len(), 20);
        assert!(kept
            .windows(2)
            .all(|w| w[0].distance(w[1]) >= OUTLINE_MIN_SEGMENT));
    }

    #[test]
    fn layout_path_sits_beside_the_screenshot() {
        assert_eq!(
            layout_path(Path::new("shots/a/shot.png")),
            PathBuf::from("shots/a/shot.layout.json")
        );
    }
}
