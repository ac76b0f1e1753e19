//! The station on screen (egui + wgpu through eframe): both camera views with the
//! silhouette contour, contour parts, landmarks and skeleton drawn over them; the avatar
//! in 3-D; the measurements with their stability; per-stage timings and frame rates; the
//! shopper's kiosk flow ([`flow`]) and the operator's tools (calibration hook,
//! recording, replay controls, exports).
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
pub mod display;
pub mod export;
pub mod flow;
pub mod frame_view;
pub mod live;
pub mod operator;
pub mod record;
pub mod runner;
pub mod session;
pub mod stats;
pub mod trace;

pub use live::{run_live_cli, LiveArgs};

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

/// Figures of a run, printed by the CLI at exit.
#[derive(Debug, Clone, Default)]
pub struct RunSummary {
    pub ui_frames: u64,
    pub seconds: f64,
    pub snapshots_shown: u64,
    pub dropped_pairs: u64,
    /// Frame-rate of new snapshots shown over the last second before exit.
    pub recent_snapshot_fps: f64,
    pub recent_ui_fps: f64,
    pub screenshot: Option<PathBuf>,
    /// Median / p95 of the screen's own work per frame (ms).
    pub ui_timings: Vec<(String, f64, f64)>,
    /// CPU time of the whole process (all threads: source, processor, screen, the
    /// software renderer), seconds, where the OS tells it.
    pub cpu_seconds: Option<f64>,
    /// CPU seconds per thread group (`capture`, `process`, the screen's main thread,
    /// `llvmpipe` for Mesa's software rasteriser...), live threads only.
    pub thread_cpu: Vec<(String, f64)>,
    /// Screen frames presented (see [`stats`]).
    pub presented_frames: u64,
    /// Frame rate from the intervals between presents (over the last
    /// [`stats::WINDOW`] frames).
    pub frame_rate: Option<stats::FrameRate>,
    /// From the start of the screen's work on a frame to its present (ms).
    pub frame_to_present: Option<stats::Summary>,
    /// From a frame pair leaving the source to the present of the screen frame that
    /// first shows its fit (ms).
    pub latency: Option<stats::Summary>,
}

/// User + system CPU seconds of this process from `/proc/self/stat` (Linux).
fn process_cpu_seconds() -> Option<f64> {
    let stat = std::fs::read_to_string("/proc/self/stat").ok()?;
    // Fields after the parenthesised command name; utime and stime are fields 14, 15.
    let rest = stat.get(stat.rfind(')')? + 2..)?;
    let f: Vec<&str> = rest.split_whitespace().collect();
    let utime: f64 = f.get(11)?.parse().ok()?;
    let stime: f64 = f.get(12)?.parse().ok()?;
    // Linux reports clock ticks of USER_HZ, 100 on every mainstream configuration.
    const USER_HZ: f64 = 100.0;
    Some((utime + stime) / USER_HZ)
}

impl std::fmt::Display for RunSummary {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let rate = |n: u64| {
            if self.seconds > 0.0 {
                n as f64 / self.seconds
            } else {
                0.0
            }
        };
        writeln!(
            f,
            "ui: {} frames in {:.2} s ({:.1} fps mean, {:.1} fps last second); snapshots shown {} ({:.1}/s mean, {:.1}/s last second); pairs dropped {}",
            self.ui_frames,
            self.seconds,
            rate(self.ui_frames),
            self.recent_ui_fps,
            self.snapshots_shown,
            rate(self.snapshots_shown),
            self.recent_snapshot_fps,
            self.dropped_pairs
        )?;
        if let Some(r) = &self.frame_rate {
            writeln!(
                f,
                "screen: {:.1} fps mean, {:.1} fps p5 (from {} presented frames){}",
                r.mean_fps,
                r.p5_fps,
                self.presented_frames,
                self.frame_to_present
                    .map(|s| format!(
                        "; start of work to present median {:.1} ms, p95 {:.1} ms",
                        s.median, s.p95
                    ))
                    .unwrap_or_default()
            )?;
        }
        if let Some(l) = &self.latency {
            writeln!(
                f,
                "latency, pair leaves the source to its fit presented: median {:.1} ms, p95 {:.1} ms ({} fits)",
                l.median, l.p95, l.count
            )?;
        }
        if let Some(cpu) = self.cpu_seconds {
            writeln!(
                f,
                "cpu: {cpu:.2} s over {:.2} s wall ({:.0}% of one core)",
                self.seconds,
                if self.seconds > 0.0 {
                    100.0 * cpu / self.seconds
                } else {
                    0.0
                }
            )?;
        }
        if !self.thread_cpu.is_empty() && self.ui_frames > 0 {
            let per: Vec<String> = self
                .thread_cpu
                .iter()
                .filter(|(_, c)| *c > 0.0)
                .map(|(n, c)| format!("{n} {:.1}", 1e3 * c / self.ui_frames as f64))
                .collect();
            writeln!(f, "cpu ms per screen frame by thread: {}", per.join(", "))?;
        }
        for (s, med, p95) in &self.ui_timings {
            writeln!(f, "stage {s}: median {med:.2} ms, p95 {p95:.2} ms")?;
        }
        if let Some(p) = &self.screenshot {
            writeln!(f, "screenshot: {}", p.display())?;
        }
        Ok(())
    }
}

/// CPU seconds of this process's live threads grouped by name, numbered workers
/// together ("llvmpipe-0", "llvmpipe-1" -> "llvmpipe"), from `/proc/self/task` (Linux;
/// empty elsewhere). Sorted by CPU time, largest first.
pub fn thread_cpu_seconds() -> Vec<(String, f64)> {
    const USER_HZ: f64 = 100.0;
    let mut groups: Vec<(String, f64)> = Vec::new();
    let Ok(dir) = std::fs::read_dir("/proc/self/task") else {
        return groups;
    };
    for entry in dir.flatten() {
        let Ok(stat) = std::fs::read_to_string(entry.path().join("stat")) else {
            continue;
        };
        let (Some(open), Some(close)) = (stat.find('('), stat.rfind(')')) else {
            continue;
        };
        let name = stat.get(open + 1..close).unwrap_or("?");
        let group = name
            .trim_end_matches(|c: char| c.is_ascii_digit())
            .trim_end_matches(['-', ':', ' '])
            .to_string();
        let f: Vec<&str> = stat
            .get(close + 2..)
            .unwrap_or("")
            .split_whitespace()
            .collect();
        let ticks = |k: usize| f.get(k).and_then(|v| v.parse::<f64>().ok()).unwrap_or(0.0);
        let secs = (ticks(11) + ticks(12)) / USER_HZ;
        match groups.iter_mut().find(|(g, _)| *g == group) {
            Some((_, s)) => *s += secs,
            None => groups.push((group, secs)),
        }
    }
    groups.sort_by(|a, b| b.1.total_cmp(&a.1));
    groups
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
    fn clear_subject(&mut self) {
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

    fn top_bar(&mut self, ui: &mut egui::Ui) {
        let now = self.now_s();
        ui.horizontal_wrapped(|ui| {
            ui.heading("fitstation");
            ui.separator();
            ui.selectable_value(&mut self.mode, Mode::Kiosk, "Kiosk");
            ui.selectable_value(&mut self.mode, Mode::Operator, "Operator");
            ui.separator();
            ui.label(&self.describe);
            ui.separator();
            ui.label(format!(
                "screen {:.0} fps · snapshots {:.0}/s{} · dropped {}",
                self.ui_meter.rate(now),
                self.snap_meter.rate(now),
                self.fps
                    .map(|f| format!(" (source {f:.0})"))
                    .unwrap_or_default(),
                self.runner.dropped_pairs()
            ));
            let rec = self.runner.controls.recorder.lock().ok().and_then(|r| {
                r.as_ref().map(|r| {
                    (
                        r.stats().written.load(Ordering::Relaxed),
                        r.stats().dropped.load(Ordering::Relaxed),
                    )
                })
            });
            if let Some((w, d)) = rec {
                ui.separator();
                let blink = (now * 2.0) as u64 % 2 == 0;
                let (r, _) = ui.allocate_exact_size(Vec2::splat(14.0), egui::Sense::hover());
                if blink {
                    ui.painter().circle_filled(r.center(), 6.0, Color32::RED);
                } else {
                    ui.painter()
                        .circle_stroke(r.center(), 6.0, Stroke::new(2.0, Color32::RED));
                }
                ui.label(
                    RichText::new(format!("REC {w} pairs ({d} dropped)"))
                        .color(Color32::RED)
                        .strong(),
                );
            }
            let st = self.runner.controls.status();
            if let Some(p) = &st.problem {
                ui.separator();
                ui.label(
                    RichText::new(p)
                        .color(Color32::from_rgb(255, 140, 0))
                        .strong(),
                );
            }
            if let Some(f) = self.fault_line(now, &st) {
                ui.separator();
                ui.label(
                    RichText::new(f)
                        .color(Color32::from_rgb(255, 140, 0))
                        .strong(),
                );
            }
            if st.ended {
                ui.separator();
                ui.label("source ended");
            }
            if self.runner.controls.paused.load(Ordering::Relaxed) {
                ui.separator();
                ui.label(RichText::new("PAUSED").strong());
            }
        });
    }

    fn kiosk_banner(&mut self, ui: &mut egui::Ui) {
        let now = self.now_s();
        let (text, colour) = match self.flow.state() {
            FlowState::LearningBackdrop => (
                "Getting ready… please keep the area in front of the cameras empty".to_string(),
                Color32::LIGHT_BLUE,
            ),
            FlowState::EmptyScene => (
                "Step onto the mark and face the screen".to_string(),
                Color32::WHITE,
            ),
            FlowState::Guiding { message } => (message.clone(), Color32::from_rgb(255, 200, 80)),
            FlowState::HoldStill { .. } => {
                let left = self.flow.countdown_left_s(now);
                if left > 0.0 {
                    (
                        format!("Hold still… {}", left.ceil() as u64),
                        Color32::from_rgb(120, 230, 120),
                    )
                } else {
                    (
                        "Hold still… almost there".to_string(),
                        Color32::from_rgb(120, 230, 120),
                    )
                }
            }
            FlowState::Result { .. } => (
                "Your measurements are ready".to_string(),
                Color32::from_rgb(120, 230, 120),
            ),
        };
        ui.vertical_centered(|ui| {
            ui.add_space(6.0);
            ui.label(RichText::new(text).size(28.0).color(colour).strong());
            ui.add_space(6.0);
        });
    }

    fn measurements_panel(&mut self, ui: &mut egui::Ui) {
        if let FlowState::Result { card, .. } = self.flow.state() {
            ui.heading("Your result");
            egui::Grid::new("result_card").striped(true).show(ui, |ui| {
                for m in &card.measurements {
                    ui.label(pretty_name(&m.name));
                    // How sure the station is goes with the value; shown after the settle
                    // timeout, the frame-to-frame spread adds to it.
                    let pm = if card.settled {
                        m.uncertainty_mm
                    } else {
                        m.uncertainty_mm.max(m.stability_mm)
                    };
                    ui.label(
                        RichText::new(value_text(m.value_mm, pm))
                            .size(18.0)
                            .strong(),
                    );
                    uncertainty_flag(ui, m);
                    ui.end_row();
                }
            });
            ui.separator();
        }
        ui.heading("Measurements");
        // Fitted from one camera: said where the values are (their ± is the wider one).
        if let Some(m) = self.current.as_ref().and_then(|s| {
            s.messages
                .iter()
                .find(|m| *m == crate::station::ONE_VIEW_MESSAGE)
        }) {
            ui.label(RichText::new(m).color(egui::Color32::from_rgb(230, 160, 40)));
        }
        let measurements: Vec<MeasurementValue> = self
            .current
            .as_ref()
            .map(|s| s.measurements.clone())
            .unwrap_or_default();
        if measurements.is_empty() {
            ui.label("waiting for a fit…");
        } else {
            egui::Grid::new("measurements")
                .striped(true)
                .num_columns(4)
                .show(ui, |ui| {
                    for m in &measurements {
                        ui.label(pretty_name(&m.name));
                        fixed_cell(ui, VALUE_CELL_WIDTH, |ui| {
                            ui.label(
                                RichText::new(value_text(m.value_mm, m.uncertainty_mm)).monospace(),
                            );
                        });
                        stability_indicator(ui, m.stability_mm);
                        uncertainty_flag(ui, m);
                        ui.end_row();
                    }
                });
        }
        ui.separator();
        ui.heading("Timings");
        let now = self.now_s();
        if now - self.timings_table_s >= TIMINGS_REFRESH_S {
            self.timings_table_s = now;
            self.timings_table = self.timings_rows();
        }
        if let Some(s) = &self.current {
            if self.mode == Mode::Operator {
                egui::Grid::new("timings").num_columns(3).show(ui, |ui| {
                    ui.label("stage");
                    ui.label("now");
                    ui.label("median / p95");
                    ui.end_row();
                    for (stage, latest, sum) in &self.timings_table {
                        ui.label(stage);
                        // Fixed widths: see VALUE_CELL_WIDTH.
                        fixed_cell(ui, VALUE_CELL_WIDTH, |ui| {
                            ui.label(latest.map(|ms| format!("{ms:.2} ms")).unwrap_or_default());
                        });
                        fixed_cell(ui, STABILITY_CELL_WIDTH, |ui| {
                            ui.label(format!("{:.2} / {:.2} ms", sum.median, sum.p95));
                        });
                        ui.end_row();
                    }
                });
            } else {
                // The kiosk shows the main figures only: every covered pixel costs on a
                // software renderer, every frame (Operator mode has the whole table).
                for (stage, _, sum) in self
                    .timings_table
                    .iter()
                    .filter(|(n, _, _)| KIOSK_TIMINGS.contains(&n.as_str()))
                {
                    ui.label(
                        RichText::new(format!(
                            "{stage}: {:.1} / {:.1} ms (median / p95)",
                            sum.median, sum.p95
                        ))
                        .small(),
                    );
                }
            }
            ui.label(format!("frame {}  phase {:?}", s.frame_index, s.phase));
            if self.mode == Mode::Operator {
                for m in s.messages.iter().take(MESSAGES_SHOWN) {
                    ui.label(RichText::new(m).small());
                }
            }
        }
    }

    /// The timings table: the station's stages (with the current snapshot's value),
    /// the pipeline threads, the screen's own work and its frame clock.
    fn timings_rows(&self) -> Vec<(String, Option<f64>, stats::Summary)> {
        let latest = |stage: &str| {
            self.current
                .as_ref()
                .and_then(|s| s.timings_ms.iter().find(|(n, _)| n == stage))
                .map(|(_, ms)| *ms)
        };
        let mut rows: Vec<(String, Option<f64>, stats::Summary)> = self
            .pipeline_stats
            .summary()
            .into_iter()
            .map(|(n, v)| {
                let now = latest(&n);
                (n, now, v)
            })
            .collect();
        rows.extend(
            self.runner
                .controls
                .thread_stats()
                .summary()
                .into_iter()
                .map(|(n, v)| (n, None, v)),
        );
        rows.extend(
            self.ui_stats
                .summary()
                .into_iter()
                .chain(self.clock.stats().summary())
                .map(|(n, v)| (format!("screen {n}"), None, v)),
        );
        rows
    }

    fn operator_panel(&mut self, ui: &mut egui::Ui) {
        egui::ScrollArea::vertical().show(ui, |ui| {
            egui::CollapsingHeader::new("Calibration").default_open(true).show(ui, |ui| {
                self.calibration_section(ui);
            });
            egui::CollapsingHeader::new("Station").default_open(true).show(ui, |ui| {
                ui.label(RichText::new("Station checks").strong());
                let sizes = self.front_tex.as_ref().zip(self.side_tex.as_ref()).map(|(f, s)| (f.frame_size, s.frame_size));
                let mut checks = operator::station_checks(self.calibration.as_ref(), sizes);
                if let Some(cal) = &self.calibration {
                    checks.extend(calib_wizard::checks_lines(&crate::calibrate::check_station(cal)));
                }
                for c in checks {
                    let colour = if c.starts_with("PROBLEM") || c.starts_with("ACTION") || c.starts_with("No calibration") {
                        Color32::from_rgb(255, 140, 0)
                    } else {
                        ui.visuals().text_color()
                    };
                    ui.label(RichText::new(c).color(colour).small());
                }
                if self.processor_factory.is_some() && ui.button("Learn the backdrop again (scene empty!)").clicked() {
                    if let Some(cal) = self.calibration.clone() {
                        self.use_calibration(cal, "learning the backdrop again");
                    }
                }
            });
            egui::CollapsingHeader::new("Recording").default_open(true).show(ui, |ui| {
                ui.horizontal(|ui| {
                    ui.label("folder");
                    ui.text_edit_singleline(&mut self.record_dir);
                });
                let recording = self.runner.controls.recorder.lock().map(|r| r.is_some()).unwrap_or(false);
                if !recording {
                    if ui.button("Start recording").clicked() {
                        self.start_recording();
                    }
                    ui.label(RichText::new("Start with the empty scene (at least 10 frames), then let the subject in.").small());
                } else if ui.button("Stop recording").clicked() {
                    self.stop_recording();
                }
            });
            egui::CollapsingHeader::new("Replay").default_open(true).show(ui, |ui| {
                let c = &self.runner.controls;
                ui.horizontal(|ui| {
                    if ui.button("Play").clicked() {
                        c.paused.store(false, Ordering::Relaxed);
                    }
                    if ui.button("Pause").clicked() {
                        c.paused.store(true, Ordering::Relaxed);
                    }
                    if ui.button("Step").clicked() {
                        c.paused.store(true, Ordering::Relaxed);
                        c.steps.fetch_add(1, Ordering::Relaxed);
                    }
                });
                let st = c.status();
                ui.label(format!(
                    "pairs read {}, last index {}{}",
                    st.pairs,
                    st.last_index.map(|i| i.to_string()).unwrap_or_else(|| "-".into()),
                    if st.ended { ", ended" } else { "" }
                ));
                if ui.button("Reset shopper (clear data)").clicked() {
                    self.flow.reset();
                    self.clear_subject();
                }
            });
            egui::CollapsingHeader::new("Export").default_open(true).show(ui, |ui| {
                ui.horizontal(|ui| {
                    ui.label("folder");
                    ui.text_edit_singleline(&mut self.export_dir);
                });
                ui.horizontal(|ui| {
                    for f in export::AvatarFormat::ALL {
                        if ui.button(format!("Avatar .{}", f.extension())).clicked() {
                            let mesh = self.current.as_ref().and_then(|s| s.avatar.clone());
                            let r = export::export_avatar(Path::new(&self.export_dir), mesh.as_deref(), f);
                            self.log(match r {
                                Ok(p) => format!("wrote {}", p.display()),
                                Err(e) => format!("export failed: {e}"),
                            });
                        }
                    }
                });
                ui.horizontal(|ui| {
                    if ui.button("Measurements JSON + CSV").clicked() {
                        let m = self.current.as_ref().map(|s| s.measurements.clone()).unwrap_or_default();
                        let r = export::export_measurements(Path::new(&self.export_dir), &m);
                        self.log(match r {
                            Ok([j, c]) => format!("wrote {} and {}", j.display(), c.display()),
                            Err(e) => format!("export failed: {e}"),
                        });
                    }
                    if ui.button("Screenshot").clicked() {
                        let p = Path::new(&self.export_dir).join(format!("screen-{}.png", self.frames));
                        self.request_screenshot(ui.ctx(), p);
                    }
                });
            });
            ui.separator();
            for l in &self.operator_log {
                ui.label(RichText::new(l).small());
            }
        });
    }

    /// Installs a processor for `cal` (through the factory): the station learns the
    /// backdrop again and measures with that calibration from the next frame on.
    fn use_calibration(&mut self, cal: StationCalibration, why: &str) {
        let Some(factory) = &self.processor_factory else {
            self.log("this screen cannot change its processor".into());
            return;
        };
        match factory(&cal) {
            Ok(p) => {
                if let Ok(mut slot) = self.runner.controls.replace_processor.lock() {
                    *slot = Some(p);
                }
                self.calibration = Some(cal);
                self.flow.reset();
                self.clear_subject();
                self.log(format!(
                    "{why}: keep the scene empty while the backdrop is learnt"
                ));
            }
            Err(e) => self.log(format!("cannot use the calibration: {e}")),
        }
    }

    fn calibration_section(&mut self, ui: &mut egui::Ui) {
        let s = &self.wizard_settings;
        ui.label(format!(
            "{} {}x{} inner corners, {:.1} mm; saves to {}",
            s.target.name(),
            s.board.cols,
            s.board.rows,
            s.board.square_m * 1e3,
            s.out.display()
        ));
        let was_live = self.wizard_live;
        ui.checkbox(&mut self.wizard_live, "Live board detection");
        if self.wizard_live && !was_live && self.wizard.is_none() {
            match CalibrationWizard::start(self.wizard_settings.clone(), self.calibration.clone()) {
                Ok(w) => self.wizard = Some(w),
                Err(e) => {
                    self.wizard_live = false;
                    self.log(format!("cannot start the calibration wizard: {e}"));
                }
            }
        }
        if !self.wizard_live {
            self.wizard_view.detections = Default::default();
        }
        let Some(w) = &self.wizard else {
            ui.label(RichText::new("Turn on live board detection to calibrate.").small());
            return;
        };
        self.wizard_view = w.view();
        let v = &self.wizard_view;
        let step = match v.step {
            WizardStep::Lenses => "1 lenses",
            WizardStep::Placement => "2 placement",
            WizardStep::Review => "3 review",
        };
        ui.label(
            RichText::new(format!(
                "Step {step} · {} frame pairs searched",
                v.frames_searched
            ))
            .strong(),
        );
        for l in &v.lines {
            ui.label(RichText::new(l).small());
        }
        if !v.status.is_empty() {
            ui.label(RichText::new(&v.status).color(Color32::from_rgb(150, 200, 255)));
        }
        let mut actions = Vec::new();
        ui.horizontal_wrapped(|ui| {
            match v.step {
                WizardStep::Lenses => {
                    if ui.button("Solve lenses").clicked() {
                        actions.push(WizardAction::SolveLenses);
                    }
                }
                WizardStep::Placement | WizardStep::Review => {
                    ui.label("board height mm");
                    if ui
                        .add(egui::DragValue::new(&mut self.board_height_mm).range(0.0..=3000.0))
                        .changed()
                    {
                        actions.push(WizardAction::SetBoardHeightMm(self.board_height_mm));
                    }
                    if ui.button("Place cameras").clicked() {
                        actions.push(WizardAction::PlaceCameras);
                    }
                }
            }
            if v.solved.is_some() {
                if ui.button("Save station.yaml").clicked() {
                    actions.push(WizardAction::Save { force: false });
                }
                if ui.button("Save, replacing a better one").clicked() {
                    actions.push(WizardAction::Save { force: true });
                }
            }
            if ui.button("Start over").clicked() {
                actions.push(WizardAction::Reset);
            }
        });
        for a in &v.actions {
            ui.label(
                RichText::new(format!("PROBLEM: {a}"))
                    .color(Color32::from_rgb(255, 140, 0))
                    .small(),
            );
        }
        for c in &v.checks {
            ui.label(RichText::new(c).small());
        }
        let solved = v.solved.clone();
        for a in actions {
            w.act(a);
        }
        if let Some(cal) = solved {
            if self.processor_factory.is_some() && ui.button("Use this calibration now").clicked() {
                self.use_calibration(cal, "new calibration in use");
            }
        }
    }

    fn start_recording(&mut self) {
        // Each recording gets its own folder under the one in the field.
        let dir = record::session_dir(Path::new(&self.record_dir), std::time::SystemTime::now());
        match record::Recorder::start(&dir, self.calibration.as_ref(), self.fps) {
            Ok(r) => {
                if self.calibration.is_none() {
                    self.log("recording without station.yaml: no calibration is loaded".into());
                }
                self.log(format!("recording to {}", dir.display()));
                if let Ok(mut slot) = self.runner.controls.recorder.lock() {
                    *slot = Some(r);
                }
            }
            Err(e) => self.log(format!("cannot record: {e}")),
        }
    }

    fn stop_recording(&mut self) {
        let r = self
            .runner
            .controls
            .recorder
            .lock()
            .ok()
            .and_then(|mut s| s.take());
        if let Some(r) = r {
            let dir = r.dir().to_path_buf();
            let dropped = r.stats().dropped.load(Ordering::Relaxed);
            match r.finish() {
                Ok(n) => self.log(format!(
                    "recorded {n} pairs to {} ({dropped} dropped)",
                    dir.display()
                )),
                Err(e) => self.log(format!("recording failed: {e}")),
            }
        }
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

    fn write_summary(&self) {
        let now = self.now_s();
        if let Ok(mut s) = self.summary.lock() {
            s.ui_frames = self.frames;
            s.seconds = now;
            s.snapshots_shown = self.snapshots_shown;
            s.dropped_pairs = self.runner.dropped_pairs();
            s.recent_snapshot_fps = self.snap_meter.rate(now);
            s.recent_ui_fps = self.ui_meter.rate(now);
            s.cpu_seconds = process_cpu_seconds();
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

    fn views(&mut self, ui: &mut egui::Ui) {
        let avail = ui.available_rect_before_wrap().shrink(VIEW_MARGIN);
        let gap = 6.0;
        let w = (avail.width() - 2.0 * gap) / 3.0;
        let cols: Vec<Rect> = (0..3)
            .map(|k| {
                Rect::from_min_size(
                    Pos2::new(avail.min.x + k as f32 * (w + gap), avail.min.y),
                    Vec2::new(w, avail.height()),
                )
            })
            .collect();
        let painter = ui.painter_at(avail);
        let ppp = ui.ctx().pixels_per_point();
        let view_px = Some([w * ppp, avail.height() * ppp]);
        if self.view_px != view_px {
            // The process thread prepares the next frames at this size.
            self.view_px = view_px;
            if let Ok(mut v) = self.runner.controls.view_px.lock() {
                *v = view_px;
            }
        }
        let show_all = self.mode == Mode::Operator;
        let snap = self.current.as_ref();
        self.layout.front = draw_view(
            &painter,
            cols[0],
            "front",
            self.front_tex.as_ref(),
            snap.map(|s| &s.front),
            &self.wizard_view.detections.front,
            show_all,
        );
        self.layout.side = draw_view(
            &painter,
            cols[1],
            "side",
            self.side_tex.as_ref(),
            snap.map(|s| &s.side),
            &self.wizard_view.detections.side,
            show_all,
        );
        // The avatar view with orbit controls and presets.
        let avatar_rect = cols[2];
        let resp = ui.interact(
            avatar_rect,
            ui.scope_id().with("avatar_orbit"),
            egui::Sense::drag(),
        );
        if resp.dragged() || resp.hovered() {
            let d = resp.drag_delta();
            let scroll = if resp.hovered() {
                ui.input(|i| i.smooth_scroll_delta.y)
            } else {
                0.0
            };
            if d != Vec2::ZERO || scroll != 0.0 {
                self.orbit.drag(d.x, d.y, scroll);
            }
            if scroll != 0.0 {
                self.user_zoomed = true;
            }
        }
        // The newest fit replaces the one on screen at most every AVATAR_PERIOD_S (the
        // 3-D view is rendered again only then), in a frame that shows a new snapshot
        // anyway; a cleared avatar goes at once. A frame of its own is asked for only
        // as a fallback, later than the next snapshot would come: each frame costs a
        // whole window of software rendering and presenting.
        let latest = self.current.as_ref().and_then(|s| s.avatar.clone());
        let changed = match (&latest, &self.shown_avatar) {
            (Some(a), Some(b)) => !Arc::ptr_eq(a, b),
            (None, None) => false,
            _ => true,
        };
        let now = self.now_s();
        let since = now - self.avatar_shown_s;
        let due = since >= AVATAR_PERIOD_S - AVATAR_PERIOD_SLACK_S;
        let take = changed && (due || latest.is_none() || self.shown_avatar.is_none());
        if take {
            self.shown_avatar = latest;
            self.avatar_generation += 1;
            self.avatar_shown_s = now;
        } else if changed {
            ui.ctx()
                .request_repaint_after(std::time::Duration::from_secs_f64(
                    (AVATAR_PERIOD_S - since).max(0.0) + AVATAR_FALLBACK_S,
                ));
        }
        let mesh = self.shown_avatar.clone();
        if let (true, Some(m)) = (take, &mesh) {
            if let Some(b) = m.bounds() {
                let c = b.center();
                self.orbit.target = glam::Vec3::new(0.0, c.y as f32, 0.0);
                if !self.user_zoomed {
                    let size = b.size();
                    let aspect = avatar_rect.width() / avatar_rect.height().max(1.0);
                    self.orbit.fit(
                        glam::Vec3::new(size.x as f32, size.y as f32, size.z as f32),
                        aspect,
                    );
                }
            }
        }
        let has_mesh = mesh.is_some();
        let aspect = avatar_rect.width() / avatar_rect.height().max(1.0);
        let body_ndc = mesh
            .as_deref()
            .and_then(|m| avatar3d::ndc_bounds(m, &self.orbit, aspect));
        let ppp = ui.ctx().pixels_per_point();
        let job = AvatarJob {
            mesh,
            generation: self.avatar_generation,
            camera: self.orbit,
            size_px: [
                (avatar_rect.width() * ppp).round().max(1.0) as u32,
                (avatar_rect.height() * ppp).round().max(1.0) as u32,
            ],
            body_ndc,
        };
        let presented = self.clock.frames();
        self.avatar_on_screen = false;
        if let Some(r) = self.avatar.as_mut() {
            r.request(job, presented);
            // The newest finished picture (it may lag the request by a frame); none
            // at all once the avatar has been cleared.
            if let Some(picture) = r.picture().filter(|p| p.has_mesh && has_mesh) {
                self.avatar_on_screen = true;
                painter.add(eframe::egui_wgpu::Callback::new_paint_callback(
                    avatar_rect,
                    AvatarCallback { picture },
                ));
            }
        }
        self.layout.avatar = Some(avatar_rect);
        if !has_mesh {
            painter.text(
                avatar_rect.center(),
                egui::Align2::CENTER_CENTER,
                "no avatar yet",
                egui::FontId::proportional(18.0),
                Color32::GRAY,
            );
        }
        // Presets over the avatar view.
        let bar = Rect::from_min_size(
            avatar_rect.left_top() + Vec2::new(8.0, 8.0),
            Vec2::new(avatar_rect.width() - 16.0, 24.0),
        );
        ui.scope_builder(egui::UiBuilder::new().max_rect(bar), |ui| {
            ui.horizontal(|ui| {
                for (label, p) in [
                    ("Front", ViewPreset::Front),
                    ("Side", ViewPreset::Side),
                    ("3/4", ViewPreset::ThreeQuarter),
                ] {
                    if ui.small_button(label).clicked() {
                        self.orbit.preset(p);
                        self.user_zoomed = false;
                    }
                }
            });
        });
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

    fn on_exit(&mut self) {
        trace::dump();
        self.write_summary();
        self.stop_recording();
    }
}

/// Report key -> label ("chest_girth" -> "chest girth").
fn pretty_name(key: &str) -> String {
    key.replace('_', " ")
}

fn stability_indicator(ui: &mut egui::Ui, spread_mm: f64) {
    let (colour, word) = if spread_mm < STABLE_MM {
        (Color32::from_rgb(80, 200, 80), "settled")
    } else if spread_mm < UNSTABLE_MM {
        (Color32::from_rgb(230, 180, 40), "settling")
    } else {
        (Color32::from_rgb(230, 80, 60), "moving")
    };
    fixed_cell(ui, STABILITY_CELL_WIDTH, |ui| {
        let (r, _) = ui.allocate_exact_size(Vec2::splat(10.0), egui::Sense::hover());
        ui.painter().circle_filled(r.center(), 5.0, colour);
        ui.label(RichText::new(format!("{word}, spread {spread_mm:.1}")).small());
    });
}

/// A measurement's value with how sure the station is of it (`±` two standard deviations,
/// `station::uncertainty`), or the value alone while that is unknown.
fn value_text(value_mm: f64, pm_mm: f64) -> String {
    if pm_mm.is_finite() {
        format!("{value_mm:.0} ±{pm_mm:.0} mm")
    } else {
        format!("{value_mm:.0} mm")
    }
}

/// Flags a measurement the station did not see well enough to vouch for (its `±` beyond
/// the ANSUR II observer tolerance).
fn uncertain_flag_text(m: &MeasurementValue) -> Option<&'static str> {
    m.uncertain.then_some("not sure: check by hand")
}

fn uncertainty_flag(ui: &mut egui::Ui, m: &MeasurementValue) {
    match uncertain_flag_text(m) {
        Some(t) => {
            ui.label(
                RichText::new(t)
                    .small()
                    .color(Color32::from_rgb(230, 150, 40)),
            );
        }
        None => {
            ui.label("");
        }
    }
}

/// Widths of the measurement grid's value and stability cells (points): wide enough for
/// any value, and fixed, because a grid whose column widths change asks egui for one
/// more frame to lay itself out again (a whole extra frame of software rendering,
/// whenever a value gains a digit or a word changes).
const VALUE_CELL_WIDTH: f32 = 120.0;
const STABILITY_CELL_WIDTH: f32 = 130.0;

/// A grid cell exactly `width` points wide (unless its content is wider), laid out left
/// to right.
fn fixed_cell(ui: &mut egui::Ui, width: f32, content: impl FnOnce(&mut egui::Ui)) {
    let height = ui.spacing().interact_size.y;
    ui.allocate_ui_with_layout(
        Vec2::new(width, height),
        egui::Layout::left_to_right(egui::Align::Center),
        |ui| {
            ui.set_min_width(width);
            content(ui);
        },
    );
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

/// Margin around the views (points).
const VIEW_MARGIN: f32 = 6.0;

/// Colours of the overlay layers.
const CONTOUR_COLOUR: Color32 = Color32::from_rgb(255, 220, 0);
const BONE_COLOUR: Color32 = Color32::from_rgb(0, 230, 255);
const LANDMARK_COLOUR: Color32 = Color32::from_rgb(255, 60, 160);
const AVATAR_OUTLINE_COLOUR: Color32 = Color32::from_rgb(120, 255, 120);
const PART_COLOURS: [Color32; 6] = [
    Color32::from_rgb(255, 120, 0),
    Color32::from_rgb(80, 160, 255),
    Color32::from_rgb(200, 90, 255),
    Color32::from_rgb(255, 255, 255),
    Color32::from_rgb(0, 200, 120),
    Color32::from_rgb(255, 80, 80),
];

/// Draws one camera view fitted into `area` with its overlays; returns the image rect.
fn draw_view(
    painter: &egui::Painter,
    area: Rect,
    name: &str,
    tex: Option<&ViewTexture>,
    overlay: Option<&ViewOverlay>,
    boards: &[operator::BoardDetection],
    operator: bool,
) -> Option<Rect> {
    let Some(tex) = tex else {
        // No fill: on a software renderer every covered pixel costs each frame.
        painter.rect_stroke(
            area,
            4.0,
            Stroke::new(1.0, Color32::from_gray(60)),
            egui::StrokeKind::Inside,
        );
        painter.text(
            area.center(),
            egui::Align2::CENTER_CENTER,
            format!("{name}: no frames"),
            egui::FontId::proportional(18.0),
            Color32::GRAY,
        );
        return None;
    };
    let [fw, fh] = tex.frame_size;
    let scale = (area.width() / fw as f32).min(area.height() / fh as f32);
    let size = Vec2::new(fw as f32 * scale, fh as f32 * scale);
    let rect = Rect::from_center_size(area.center(), size);
    painter.add(eframe::egui_wgpu::Callback::new_paint_callback(
        rect,
        frame_view::FrameViewCallback {
            slot: tex.slot,
            image: tex.image.clone(),
            generation: tex.generation,
        },
    ));
    let to_screen = |p: glam::DVec2| {
        Pos2::new(
            rect.min.x + p.x as f32 * scale,
            rect.min.y + p.y as f32 * scale,
        )
    };
    if let Some(o) = overlay {
        if operator {
            for (k, (_, pts)) in o.parts.iter().enumerate() {
                let c = PART_COLOURS[k % PART_COLOURS.len()];
                // Dots closer than a segment overlap anyway.
                for p in screen_polyline(pts.iter().map(|p| to_screen(*p))) {
                    painter.circle_filled(p, 2.0, c);
                }
            }
            if o.avatar_outline.len() > 2 {
                let pts = screen_polyline(o.avatar_outline.iter().map(|p| to_screen(*p)));
                painter.add(egui::Shape::closed_line(
                    pts,
                    Stroke::new(1.0, AVATAR_OUTLINE_COLOUR),
                ));
            }
        }
        if o.contour.len() > 2 {
            let pts = screen_polyline(o.contour.iter().map(|p| to_screen(*p)));
            painter.add(egui::Shape::closed_line(
                pts,
                Stroke::new(2.0, CONTOUR_COLOUR),
            ));
        }
        for (a, b) in &o.bones {
            painter.line_segment(
                [to_screen(*a), to_screen(*b)],
                Stroke::new(2.0, BONE_COLOUR),
            );
        }
        for (_, p) in &o.landmarks {
            painter.circle_filled(to_screen(*p), 3.5, LANDMARK_COLOUR);
        }
    }
    for b in boards {
        for p in &b.corners_px {
            let c = to_screen(*p);
            painter.line_segment(
                [c - Vec2::new(3.0, 0.0), c + Vec2::new(3.0, 0.0)],
                Stroke::new(1.0, Color32::GREEN),
            );
            painter.line_segment(
                [c - Vec2::new(0.0, 3.0), c + Vec2::new(0.0, 3.0)],
                Stroke::new(1.0, Color32::GREEN),
            );
        }
    }
    painter.text(
        rect.left_top() + Vec2::new(6.0, 4.0),
        egui::Align2::LEFT_TOP,
        name,
        egui::FontId::proportional(16.0),
        Color32::WHITE,
    );
    Some(rect)
}

/// Shortest segment of an outline as drawn (points). The station's contours have a
/// point every pixel or two of the camera frame, several per screen pixel once the frame
/// is scaled into its view; every segment is a few triangles for the software
/// rasteriser, so points closer than this to the last one kept are left out.
const OUTLINE_MIN_SEGMENT: f32 = 2.5;

/// The points of a closed outline on screen, without those closer than
/// [`OUTLINE_MIN_SEGMENT`] to the previous point kept.
fn screen_polyline(points: impl Iterator<Item = Pos2>) -> Vec<Pos2> {
    let mut out: Vec<Pos2> = Vec::new();
    for p in points {
        match out.last() {
            Some(last) if last.distance(p) < OUTLINE_MIN_SEGMENT => {}
            _ => out.push(p),
        }
    }
    out
}

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

/// `fitstation demo-ui`: the screen on the synthetic demo station.
#[derive(clap::Args, Debug)]
pub struct DemoUiArgs {
    /// Save a screenshot of the window (PNG, with `<stem>.layout.json` giving where the
    /// views and the avatar are) after --exit-after-frames frames, at the first frame
    /// from then on that shows a fitted avatar (waiting at most 600 more frames).
    #[arg(long)]
    pub screenshot: Option<PathBuf>,
    /// Close after this many screen frames (and after the screenshot).
    #[arg(long)]
    pub exit_after_frames: Option<u64>,
    /// Start with the operator tools open.
    #[arg(long)]
    pub operator: bool,
    /// Window size in points, WIDTHxHEIGHT.
    #[arg(long, default_value = "1600x900", value_parser = parse_window_size)]
    pub window: [f32; 2],
    /// Instead of the synthetic figure: a whole kiosk visit scripted from this
    /// recording (empty scene, feet cut off, stepping in, holding still, the result,
    /// leaving until the idle timeout clears it), through the real station processing,
    /// in a loop. The recording must start with the empty scene.
    #[arg(long)]
    pub recording: Option<PathBuf>,
}

/// Parses "1600x900".
fn parse_window_size(s: &str) -> Result<[f32; 2], String> {
    let (w, h) = s
        .split_once(['x', 'X'])
        .ok_or_else(|| format!("{s}: expected WIDTHxHEIGHT"))?;
    let w: f32 = w.trim().parse().map_err(|_| format!("{s}: bad width"))?;
    let h: f32 = h.trim().parse().map_err(|_| format!("{s}: bad height"))?;
    if !(200.0..=10000.0).contains(&w) || !(200.0..=10000.0).contains(&h) {
        return Err(format!("{s}: window size out of range"));
    }
    Ok([w, h])
}

pub fn run_demo_cli(args: DemoUiArgs) -> anyhow::Result<()> {
    if let Some(rec) = &args.recording {
        return run_session_cli(&args, rec);
    }
    let source = demo::DemoSource::new(None);
    let cal = demo::demo_calibration();
    let opts = AppOptions {
        title: "fitstation demo".into(),
        operator: args.operator,
        window_size: args.window,
        exit_after_frames: args
            .exit_after_frames
            .or(args.screenshot.as_ref().map(|_| DEFAULT_SCREENSHOT_FRAMES)),
        screenshot: args.screenshot,
        ..Default::default()
    };
    let summary = run(
        Box::new(source),
        Box::new(demo::DemoProcessor::new(cal)),
        opts,
    )?;
    print!("{summary}");
    Ok(())
}

/// `demo-ui --recording REC`: a scripted kiosk visit through the station processor.
fn run_session_cli(args: &DemoUiArgs, rec: &Path) -> anyhow::Result<()> {
    use crate::station::{StationOptions, StationProcessor};
    let flow = FlowConfig::default();
    let mut station = StationOptions::default();
    let mut source = session::SessionSource::open(rec, &flow, station.backdrop_frames)?;
    source.looping = true;
    let cal = source
        .calibration()
        .cloned()
        .ok_or_else(|| anyhow::anyhow!("{}: no station.yaml", rec.display()))?;
    if let Ok(r) = crate::recording::Recording::open(rec) {
        station.stature_m = r.metadata().stature_m;
    }
    let library = crate::station::default_library()?;
    let processor = StationProcessor::new(cal, library, station.clone())?;
    let opts = AppOptions {
        title: format!("fitstation: kiosk session from {}", rec.display()),
        operator: args.operator,
        window_size: args.window,
        exit_after_frames: args
            .exit_after_frames
            .or(args.screenshot.as_ref().map(|_| DEFAULT_SCREENSHOT_FRAMES)),
        screenshot: args.screenshot.clone(),
        flow,
        processor_factory: Some(live::station_factory(station, 0)?),
        ..Default::default()
    };
    let summary = run(Box::new(source), Box::new(processor), opts)?;
    print!("{summary}");
    Ok(())
}

/// Frames before a screenshot when only --screenshot is given.
const DEFAULT_SCREENSHOT_FRAMES: u64 = 150;

#[cfg(test)]
mod tests {
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
